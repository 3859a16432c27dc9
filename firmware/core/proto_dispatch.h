/*
 * proto_dispatch.h - drive side of the protocol: decode a request message,
 * check it, call the drive application (drive.h), build the reply; emit the
 * cyclic status / telemetry; run the communication watchdog.
 *
 * Specification
 * -------------
 * Messages are msg_id | seq | payload (proto_msgs.h); transports
 * (proto_frame on serial, proto_isotp on CAN, tied to the HAL by proto_link)
 * hand complete messages to proto_dispatch_handle() and send what it returns.
 *
 * Requests (ids and layouts from protocol/contour.toml):
 *   - Every field is checked before anything is applied; a refused request
 *     gets error{req, code, arg, lo, hi} and changes nothing (codes:
 *     PROTO_ERROR_CODE_*, e.g. bad_length, unknown_param, out_of_range with
 *     the allowed lo/hi, read_only, queue_full, disabled, faulted, bad_axis).
 *   - Unknown ids and drive-to-host ids get error{unknown_message}; a
 *     message shorter than its header gets no reply (counted `ignored`).
 *   - Replays: the last request (id, seq, payload length and CRC) and its
 *     reply are cached (proto_replay.h); the same request again (a host
 *     retry after a lost reply, or a replayed frame) is answered with the
 *     cached reply and NOT executed again (counted `replayed`). Another
 *     request under the same (id, seq) is executed. Hosts change seq every
 *     request.
 *   - Sessions: session_open{nonce} forgets the replay cache and answers
 *     session_reply{nonce, sessions}. A host opens every session with it and
 *     discards everything that arrives before the reply carrying its nonce:
 *     the drive's transmit backlog and replies to an earlier session's
 *     requests can then never be taken for this session's (the link is
 *     FIFO per direction).
 *   - Versions: session_open carries the host's PROTO_VERSION; another
 *     version, or a session_open without one (a host of protocol 1), is
 *     refused with error{not_supported, arg = PROTO_VERSION, lo = hi =
 *     PROTO_VERSION} and opens no session. session_reply and identify
 *     carry the drive's version.
 *   - param_begin / _stage / _commit / _abort: all-or-nothing parameter
 *     transactions (proto_ptxn.h); a session_open aborts an open one.
 *   - queue_batch: proto_batch.h. The stream is the drive's, not a
 *     session's: a second host opening a session (to watch a job) does not
 *     end it; a new job starts it again (start flag).
 *   - Rapid blocks are queued at PROTO_RAPID_FEED_NM_S; the planner's axis
 *     limits cap it. Target positions must lie within +-PROTO_POS_LIMIT_NM.
 *   - Parameters: the table in proto_msgs.c gives type, range and access;
 *     `link` parameters live here, `drive` parameters map to drive.h.
 *
 * Cyclic messages (proto_dispatch_poll): every telem_period_ms a full cycle
 * (status, progress, path, pos_n and ferr_n for each axis), otherwise every
 * status_period_ms a status cycle (status, progress); all frames of one
 * cycle carry the same 16-bit cycle seq, incremented by one per cycle. On
 * CAN a heartbeat every heartbeat_period_ms.
 *
 * Communication watchdog: when comm_timeout_ms != 0 and the drive is RUNNING
 * (motion queued or executing) and no valid request arrived for
 * comm_timeout_ms, the dispatcher commands a controlled stop (drive_stop);
 * once the axes are at rest it latches DRIVE_FAULT_COMM (reported as fault
 * bit comm_timeout; fault_reset clears it). Any valid request is a sign of
 * life; status_get is the idle keep-alive. While the motion is a block
 * stream's (queue_batch took blocks, and no jog, home or single block was
 * accepted nor the drive came to rest since), only queue_batch frames are: the streaming host polls
 * its window with them, and a second host that watches the job (status,
 * monitor) must not keep the job of a host that died running.
 *
 * Context: main only. No heap, no floating point. Times are hal_time_us()
 * values (uint32 us, wrapping).
 */
#ifndef PROTO_DISPATCH_H
#define PROTO_DISPATCH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "drive.h"
#include "proto_batch.h"
#include "proto_msgs.h"
#include "proto_ptxn.h"
#include "proto_replay.h"

#define PROTO_RAPID_FEED_NM_S 4000000000u
#define PROTO_POS_LIMIT_NM    ((int64_t)1000000000000000) /* 1000 km */
#define PROTO_DWELL_MAX_MS    3600000u

/* What identify reports; filled by the port. */
typedef struct {
    uint32_t fw_version; /* major << 16 | minor << 8 | patch */
    uint32_t build_id;
    uint32_t capabilities; /* 1 << PROTO_CAPABILITY_* */
    uint32_t tick_hz;
    uint32_t board_id;      /* BOOT_BOARD_* */
    uint16_t planner_slots; /* 0: read from the drive at init */
    uint8_t node_id;        /* 1..PROTO_CAN_NODE_MAX */
    uint8_t axes;           /* 1..PROTO_MAX_AXES */
} proto_identity_t;

typedef struct {
    uint32_t requests;       /* requests executed (replies built)          */
    uint32_t replayed;       /* answered from the replay cache             */
    uint32_t unknown;        /* unknown or drive-to-host message ids       */
    uint32_t bad_length;     /* payload length wrong for the message       */
    uint32_t refused;        /* error replies of any kind                  */
    uint32_t ignored;        /* shorter than the message header            */
    uint32_t watchdog_stops; /* controlled stops commanded by the watchdog */
    uint32_t cycles;         /* status / telemetry cycles emitted          */
} proto_dispatch_stats_t;

/* Sends one unsolicited message (msg_id | seq | payload); can_func is the
 * raw CAN function of a cyclic message (the payload alone is the CAN frame).
 * Returns false when the link had no room (the message is dropped). */
typedef bool (*proto_emit_fn)(void *ctx, const uint8_t *msg, size_t len, uint8_t can_func);

typedef struct proto_dispatch {
    proto_identity_t ident;
    /* link parameters (PROTO_PARAM_*, owner link) */
    uint32_t comm_timeout_ms;
    uint16_t status_period_ms;
    uint16_t telem_period_ms;
    uint16_t heartbeat_period_ms;
    bool heartbeat_on; /* set by the link: true on CAN */
    uint8_t cec_mode;
    proto_replay_t replay; /* last request and its reply (proto_replay.h) */
    uint16_t sessions;     /* session_open requests executed (wraps) */
    proto_batch_t batch;   /* the host's block stream (queue_batch) */
    proto_ptxn_t ptxn;     /* the open parameter transaction (proto_ptxn.h) */
    /* watchdog (main) */
    uint32_t last_rx_us;     /* any valid request */
    uint32_t stream_rx_us;   /* the last queue_batch request */
    bool stream_owns_motion; /* the motion was queued by the block stream */
    bool wd_stopping;
    /* cyclic output */
    uint16_t cycle_seq;
    uint8_t tx_seq;
    uint32_t last_cycle_us;
    uint32_t last_hb_us;
    /* transport drop counters, written by the link (reported in drive_state) */
    uint32_t rx_errors;
    proto_dispatch_stats_t stats;
} proto_dispatch_t;

/* Defaults from the parameter table; returns false for an invalid identity
 * (node id or axes out of range). */
bool proto_dispatch_init(proto_dispatch_t *d, const proto_identity_t *ident, uint32_t now_us);

/* Handle one received message. Writes the reply message into out (cap >=
 * PROTO_MSG_MAX) and returns its length; 0 = no reply. */
size_t proto_dispatch_handle(proto_dispatch_t *d, const uint8_t *msg, size_t len, uint32_t now_us,
                             uint8_t *out, size_t cap);

/* The protocol's state enum of a drive status. */
uint8_t proto_dispatch_state(const drive_status_t *st);

/* Watchdog and cyclic messages; call often from the main loop. */
void proto_dispatch_poll(proto_dispatch_t *d, uint32_t now_us, proto_emit_fn emit, void *ctx);

#endif /* PROTO_DISPATCH_H */
