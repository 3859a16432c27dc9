/*
 * proto_ptxn.h - parameter transactions on the wire: param_begin,
 * param_stage, param_commit, param_abort (protocol/contour.toml;
 * protocol/README.md, "Parameter transactions").
 *
 * Specification
 * -------------
 * begin opens a transaction and answers its id (u16, never 0); any
 * transaction still open is aborted (txn_status superseded: the drive
 * cannot tell whose begin it is, so the newest wins). stage checks each
 * (parameter id, value) pair of a frame like param_set (unknown_param,
 * bad_axis, read_only, out_of_range against the table) and stages the
 * whole frame or, on the first refused pair, nothing of it; a parameter
 * staged again takes the later value; at most PROTO_PTXN_MAX values.
 * Nothing is applied before commit.
 *
 * commit checks, in this order, before anything changes:
 *   1. the drive is not moving (running, stopping, homing) when a drive
 *      parameter is staged: busy, arg = the first staged one, lo = state;
 *   2. every staged drive value against its range narrowed by the other
 *      staged values (drive_param_staged_range): out_of_range, arg = it;
 *   3. encoder_mean changed while the drive is not disabled: busy;
 *   4. the whole candidate (drive_param_commit: profile, servo
 *      parameters, the port): bad_value (profile or servo) / not_supported
 *      (encoder_mean) / busy, arg = the first staged parameter of that kind;
 * then applies the drive values (drive_param_commit), cec_mode and the
 * link parameters, which can no longer be refused. A refused commit
 * applies nothing and leaves the transaction open (abort or commit again).
 * A commit of the last transaction committed answers param_txn again and
 * applies nothing (a retry whose reply was lost after the replay cache
 * moved on), also after another session began one since. Another
 * request of another session may run between two requests of a
 * transaction, never inside one: the commit is one call in main context;
 * the tick changes the drive state only on requests main posted, which
 * drive_main_state already counts, so its checks hold until its writes.
 *
 * A transaction belongs to the session that began it and is aborted
 * (nothing applied; its next request answers error{txn, arg = reason,
 * lo = id}) by: a session_open (new_session), a param_begin (superseded),
 * or no request of it (begin, stage) for comm_timeout_ms when that is not
 * 0 (link_timeout, proto_ptxn_poll). A request naming another id answers
 * not_open. param_abort answers ack whether or not it was open.
 *
 * Context: main only (every field below is main's). No heap.
 */
#ifndef PROTO_PTXN_H
#define PROTO_PTXN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Writable (parameter, axis) pairs of a 4-axis drive: 81 today. */
#define PROTO_PTXN_MAX 96u

typedef enum {
    PROTO_PTXN_NONE = 0, /* no transaction since start-up, or aborted */
    PROTO_PTXN_OPEN,
    PROTO_PTXN_COMMITTED,
} proto_ptxn_state_t;

typedef struct {
    uint16_t id;      /* the current (or last) transaction */
    uint8_t state;    /* proto_ptxn_state_t of id */
    uint8_t lost_why; /* PROTO_TXN_STATUS_* of lost_id */
    uint16_t lost_id; /* the last transaction aborted by someone else, 0 */
    uint16_t n;       /* values staged */
    uint16_t done_id; /* the last transaction committed, 0: none */
    uint16_t done_n;  /* values it applied */
    uint32_t last_us; /* the transaction's last begin / stage */
    uint16_t param[PROTO_PTXN_MAX];
    int64_t value[PROTO_PTXN_MAX];
} proto_ptxn_t;

struct proto_dispatch;

void proto_ptxn_reset(proto_ptxn_t *t);
/* Abort the open transaction for reason (PROTO_TXN_STATUS_*); no-op when
 * none is open. */
void proto_ptxn_lose(proto_ptxn_t *t, uint8_t reason);
/* The link timeout (poll often). */
void proto_ptxn_poll(struct proto_dispatch *d, uint32_t now_us);
/* A param_begin / _stage / _commit / _abort whose length was checked:
 * writes the reply into out, returns its length. */
size_t proto_ptxn_request(struct proto_dispatch *d, uint8_t id, uint8_t seq, const uint8_t *p,
                          size_t n, uint32_t now_us, uint8_t *out);

#endif /* PROTO_PTXN_H */
