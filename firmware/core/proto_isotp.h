/*
 * proto_isotp.h - ISO 15765-2 (ISO-TP) segmentation of protocol messages on
 * classic CAN, drive side. Normal addressing, 11-bit identifiers:
 * requests arrive on rx_id = PROTO_CAN_ID(PROTO_CAN_FUNC_REQUEST, node),
 * responses and our flow control go out on tx_id =
 * PROTO_CAN_ID(PROTO_CAN_FUNC_RESPONSE, node); the host's flow control for
 * our multi-frame responses arrives on rx_id.
 *
 * Specification
 * -------------
 * Frames (first byte = protocol control information):
 *   single      0x0L data[L]            L = 1..7
 *   first       0x1H LL data[6]         length 8..PROTO_ISOTP_MAX (12 bit)
 *   consecutive 0x2N data[<=7]          N = 1, 2, .. 15, 0, 1 ..
 *   flow ctrl   0x3S BS STmin           S: 0 continue, 1 wait, 2 overflow
 * Transmitted frames are not padded (DLC = used bytes); received frames may
 * be padded. The receiver answers a first frame with flow control
 * BS = 0, STmin = 0 (send everything), or overflow when the message is
 * longer than PROTO_ISOTP_MAX. The sender honours the host's BS and STmin
 * (0..127 ms, 0xF1..0xF9 = 100..900 us, reserved values = 127 ms).
 *
 * Errors (counted in stats, the transfer is abandoned, nothing wedges):
 * unexpected consecutive frame, wrong sequence number, short frame, bad
 * length, overflow, N_Cr timeout (no consecutive frame for
 * PROTO_ISOTP_TIMEOUT_US) and N_Bs timeout (no flow control). A new single
 * or first frame during a reception abandons the old one (ISO 15765-2).
 *
 * Context: main only (one instance per node). No heap, no floating point.
 * Times are hal_time_us() values (uint32, wrapping).
 */
#ifndef PROTO_ISOTP_H
#define PROTO_ISOTP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "proto_msgs.h"

#define PROTO_ISOTP_MAX        PROTO_MSG_MAX
#define PROTO_ISOTP_TIMEOUT_US 1000000u

/* Transmit one CAN frame; false when the transmit mailbox is full (the
 * frame is offered again at the next poll). */
typedef bool (*proto_can_tx_fn)(void *ctx, uint32_t id, const uint8_t *data, uint8_t len);

typedef struct {
    uint32_t rx_msgs;     /* complete messages received */
    uint32_t rx_errors;   /* abandoned receptions / malformed frames */
    uint32_t rx_timeouts; /* N_Cr timeouts (also counted in rx_errors) */
    uint32_t tx_msgs;     /* messages completely sent */
    uint32_t tx_aborts;   /* N_Bs timeout or overflow from the host */
} proto_isotp_stats_t;

typedef struct {
    uint32_t rx_id;
    uint32_t tx_id;
    /* receiver */
    uint8_t rx_buf[PROTO_ISOTP_MAX];
    uint16_t rx_len; /* announced length */
    uint16_t rx_got;
    uint8_t rx_sn; /* next expected sequence number */
    bool rx_active;
    uint32_t rx_last_us;
    bool fc_pending;
    uint8_t fc_status;
    /* sender */
    uint8_t tx_buf[PROTO_ISOTP_MAX];
    uint16_t tx_len;
    uint16_t tx_pos;
    uint8_t tx_sn;
    uint8_t tx_state; /* internal */
    uint8_t bs;       /* block size granted, 0 = unlimited */
    uint8_t bs_left;
    uint32_t stmin_us;
    uint32_t tx_last_us;
    proto_isotp_stats_t stats;
} proto_isotp_t;

void proto_isotp_init(proto_isotp_t *t, uint32_t rx_id, uint32_t tx_id);

/* One frame received on rx_id (dlc 0..8). Returns true when it completed a
 * message: *msg points into t (valid until the next rx call), *len its
 * length. Flow control to send is left for proto_isotp_poll. */
bool proto_isotp_rx(proto_isotp_t *t, const uint8_t *data, uint8_t dlc, uint32_t now_us,
                    const uint8_t **msg, size_t *len);

/* Queue a message (1..PROTO_ISOTP_MAX bytes) for transmission; false when a
 * transmission is still in progress or len is out of range. */
bool proto_isotp_send(proto_isotp_t *t, const uint8_t *msg, size_t len, uint32_t now_us);

/* True while a message is being transmitted. */
bool proto_isotp_busy(const proto_isotp_t *t);

/* Timeouts, pending flow control and the frames of the current
 * transmission that may go now. */
void proto_isotp_poll(proto_isotp_t *t, uint32_t now_us, proto_can_tx_fn tx, void *ctx);

#endif /* PROTO_ISOTP_H */
