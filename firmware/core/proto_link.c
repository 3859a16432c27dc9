/*
 * proto_link.c - serial and CAN host link of the drive (see proto_link.h).
 */
#include "proto_link.h"

#include "canopen.h"
#include "co_drive.h"
#include "hal.h"

typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t data[8];
} can_frame_t;

static struct {
    bool ready;
    bool serial;
    bool can;
    proto_link_handler_fn ext;
    bool ext_all; /* bootloader mode: every message to ext, no cyclic output */
    proto_dispatch_t disp;
    proto_frame_rx_t frx;
    proto_isotp_t tp;
    /* serial transmit ring */
    uint8_t utx[PROTO_LINK_UART_TX];
    uint16_t utx_head; /* next byte to send */
    uint16_t utx_len;  /* bytes queued */
    /* cyclic CAN frames */
    can_frame_t ctx[PROTO_LINK_CAN_TX];
    uint16_t ctx_head;
    uint16_t ctx_len;
    /* ISO-TP replies waiting for the transmitter */
    uint8_t rq[PROTO_LINK_REPLY_MAX][PROTO_MSG_MAX];
    uint16_t rq_len[PROTO_LINK_REPLY_MAX];
    uint8_t rq_head;
    uint8_t rq_count;
    proto_link_stats_t stats;
    co_t co; /* CiA 301 on the same bus (docs/canopen.md) */
} lk;

static bool can_tx(void *ctx, uint32_t id, const uint8_t *data, uint8_t len);

bool proto_link_init(const proto_identity_t *ident, bool serial, bool can)
{
    proto_link_stats_t zero = {0};
    uint32_t now = hal_time_us();

    lk.ready = false;
    if (!proto_dispatch_init(&lk.disp, ident, now)) {
        return false;
    }
    lk.disp.heartbeat_on = can;
    lk.serial = serial;
    lk.can = can;
    lk.ext = NULL;
    lk.ext_all = false;
    proto_frame_rx_init(&lk.frx);
    proto_isotp_init(&lk.tp, PROTO_CAN_ID(PROTO_CAN_FUNC_REQUEST, ident->node_id),
                     PROTO_CAN_ID(PROTO_CAN_FUNC_RESPONSE, ident->node_id));
    lk.utx_head = 0;
    lk.utx_len = 0;
    lk.ctx_head = 0;
    lk.ctx_len = 0;
    lk.rq_head = 0;
    lk.rq_count = 0;
    lk.stats = zero;
    if (can) {
        co_config_t co_cfg = {ident->node_id, 0u, ident->board_id, ident->fw_version,
                              ident->build_id};

        co_init(&lk.co, &co_cfg, can_tx, NULL, now);
        co_drive_init(&lk.co);
    }
    lk.ready = true;
    return true;
}

void proto_link_set_ext_handler(proto_link_handler_fn fn)
{
    lk.ext = fn;
}

void proto_link_set_ext_exclusive(bool on)
{
    lk.ext_all = on;
}

const proto_link_stats_t *proto_link_stats(void)
{
    return &lk.stats;
}

const proto_frame_stats_t *proto_link_frame_stats(void)
{
    return &lk.frx.stats;
}

const proto_isotp_stats_t *proto_link_isotp_stats(void)
{
    return &lk.tp.stats;
}

proto_dispatch_t *proto_link_dispatch(void)
{
    return &lk.disp;
}

static size_t handle(const uint8_t *msg, size_t len, uint32_t now, uint8_t *out)
{
    /* counters up to date for a status_get in the same batch of bytes */
    lk.disp.rx_errors = proto_frame_rx_errors(&lk.frx) + lk.tp.stats.rx_errors;
    if (lk.ext != NULL && len >= 1u && (lk.ext_all || msg[0] >= 0x80u)) {
        lk.disp.last_rx_us = now; /* still a sign of life */
        return lk.ext(msg, len, now, out, PROTO_MSG_MAX);
    }
    return proto_dispatch_handle(&lk.disp, msg, len, now, out, PROTO_MSG_MAX);
}

/* ---- serial -------------------------------------------------------------------- */

static bool uart_queue_msg(const uint8_t *msg, size_t len)
{
    uint8_t f[PROTO_FRAME_MAX];
    size_t n = proto_frame_encode(msg, len, f, sizeof(f));
    size_t i;

    if (n == 0u || n > (size_t)(PROTO_LINK_UART_TX - lk.utx_len)) {
        lk.stats.uart_tx_dropped++;
        return false;
    }
    for (i = 0; i < n; i++) {
        lk.utx[(lk.utx_head + lk.utx_len + i) % PROTO_LINK_UART_TX] = f[i];
    }
    lk.utx_len = (uint16_t)(lk.utx_len + n);
    return true;
}

static void uart_drain(void)
{
    while (lk.utx_len > 0u) {
        size_t chunk = PROTO_LINK_UART_TX - lk.utx_head;
        size_t w;

        if (chunk > lk.utx_len) {
            chunk = lk.utx_len;
        }
        w = hal_uart_write(&lk.utx[lk.utx_head], chunk);
        if (w == 0u) {
            return;
        }
        if (w > chunk) {
            w = chunk;
        }
        lk.utx_head = (uint16_t)((lk.utx_head + w) % PROTO_LINK_UART_TX);
        lk.utx_len = (uint16_t)(lk.utx_len - w);
    }
}

static void uart_receive(uint32_t now)
{
    uint8_t in[64];
    uint8_t out[PROTO_MSG_MAX];
    size_t n;
    size_t i;

    while ((n = hal_uart_read(in, sizeof(in))) > 0u) {
        for (i = 0; i < n && i < sizeof(in); i++) {
            const uint8_t *msg;
            size_t len;

            if (proto_frame_rx_byte(&lk.frx, in[i], &msg, &len)) {
                size_t r = handle(msg, len, now, out);

                if (r > 0u) {
                    (void)uart_queue_msg(out, r);
                }
            }
        }
    }
}

/* ---- CAN ------------------------------------------------------------------------- */

static bool can_tx(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    return hal_can_send(id, data, len);
}

static void can_queue_reply(const uint8_t *msg, size_t len)
{
    uint8_t slot;
    size_t i;

    if (lk.rq_count >= PROTO_LINK_REPLY_MAX) {
        lk.stats.can_tx_dropped++;
        return;
    }
    slot = (uint8_t)((lk.rq_head + lk.rq_count) % PROTO_LINK_REPLY_MAX);
    for (i = 0; i < len; i++) {
        lk.rq[slot][i] = msg[i];
    }
    lk.rq_len[slot] = (uint16_t)len;
    lk.rq_count++;
}

static void can_receive(uint32_t now)
{
    uint32_t id;
    uint8_t data[8];
    uint8_t dlc;
    uint8_t out[PROTO_MSG_MAX];

    while (hal_can_receive(&id, data, &dlc)) {
        const uint8_t *msg;
        size_t len;

        if (dlc > 8u) {
            dlc = 8u;
        }
        if (!lk.ext_all && co_rx(&lk.co, id, data, dlc, now)) {
            /* a CANopen master driving the node is the host the link
             * watchdog waits for: its heartbeat when 0x1016 watches it,
             * else any of its frames (co_hb.h) */
            if (co_hb_alive(&lk.co, id)) {
                lk.disp.last_rx_us = now;
            }
            continue;
        }
        if (id != lk.tp.rx_id) {
            lk.stats.can_ignored++;
            continue;
        }
        if (dlc > 8u) {
            dlc = 8u;
        }
        if (proto_isotp_rx(&lk.tp, data, dlc, now, &msg, &len)) {
            size_t r = handle(msg, len, now, out);

            if (r > 0u) {
                can_queue_reply(out, r);
            }
        }
    }
}

static void can_drain(uint32_t now)
{
    if (!proto_isotp_busy(&lk.tp) && lk.rq_count > 0u) {
        (void)proto_isotp_send(&lk.tp, lk.rq[lk.rq_head], lk.rq_len[lk.rq_head], now);
        lk.rq_head = (uint8_t)((lk.rq_head + 1u) % PROTO_LINK_REPLY_MAX);
        lk.rq_count--;
    }
    proto_isotp_poll(&lk.tp, now, can_tx, NULL);
    while (lk.ctx_len > 0u) {
        const can_frame_t *f = &lk.ctx[lk.ctx_head];

        if (!hal_can_send(f->id, f->data, f->len)) {
            return;
        }
        lk.ctx_head = (uint16_t)((lk.ctx_head + 1u) % PROTO_LINK_CAN_TX);
        lk.ctx_len--;
    }
}

/* ---- cyclic output ----------------------------------------------------------------- */

static bool emit(void *ctx, const uint8_t *msg, size_t len, uint8_t can_func)
{
    bool ok = true;

    (void)ctx;
    if (lk.serial && can_func != PROTO_CAN_FUNC_HEARTBEAT) {
        ok = uart_queue_msg(msg, len) && ok;
    }
    if (lk.can && len >= PROTO_MSG_HDR && len - PROTO_MSG_HDR <= 8u) {
        if (lk.ctx_len >= PROTO_LINK_CAN_TX) {
            lk.stats.can_tx_dropped++;
            ok = false;
        } else {
            can_frame_t *f = &lk.ctx[(lk.ctx_head + lk.ctx_len) % PROTO_LINK_CAN_TX];
            size_t i;

            f->id = PROTO_CAN_ID(can_func, lk.disp.ident.node_id);
            f->len = (uint8_t)(len - PROTO_MSG_HDR);
            for (i = 0; i < f->len; i++) {
                f->data[i] = msg[PROTO_MSG_HDR + i];
            }
            lk.ctx_len++;
        }
    }
    return ok;
}

void proto_link_poll(void)
{
    uint32_t now;

    if (!lk.ready) {
        return;
    }
    now = hal_time_us();
    if (lk.serial) {
        uart_receive(now);
    }
    if (lk.can) {
        can_receive(now);
    }
    lk.disp.rx_errors = proto_frame_rx_errors(&lk.frx) + lk.tp.stats.rx_errors;
    if (!lk.ext_all) {
        proto_dispatch_poll(&lk.disp, now, emit, NULL);
    }
    if (lk.serial) {
        uart_drain();
    }
    if (lk.can) {
        if (!lk.ext_all) {
            co_drive_poll(&lk.co, now);
            co_poll(&lk.co, now);
        }
        can_drain(now);
    }
}
