/*
 * canopen.c - CiA 301 NMT slave, heartbeat producer and SDO server
 * (canopen.h is the specification). The object dictionary table is
 * generated from protocol/canopen.toml (canopen_od.c).
 */
#include "canopen.h"

#include <string.h>

/* ---- transmit ring ---------------------------------------------------- */

static void tx_flush(co_t *co)
{
    while (co->txq_tail != co->txq_head) {
        const co_frame_t *f = &co->txq[co->txq_tail % CO_TX_RING];

        if (!co->tx(co->tx_ctx, f->id, f->data, f->len)) {
            return;
        }
        co->txq_tail++;
    }
}

void co_send(co_t *co, uint32_t id, const uint8_t *data, uint8_t len)
{
    co_frame_t *f;

    if ((uint8_t)(co->txq_head - co->txq_tail) >= CO_TX_RING) {
        co->stats.tx_dropped++;
        return;
    }
    f = &co->txq[co->txq_head % CO_TX_RING];
    f->id = id;
    f->len = len;
    memcpy(f->data, data, len);
    co->txq_head++;
    tx_flush(co);
}

/* ---- SDO server --------------------------------------------------------- */

static void sdo_send(co_t *co, uint8_t cmd, uint16_t index, uint8_t sub, const uint8_t *d4)
{
    uint8_t f[8] = {cmd, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};

    if (d4 != NULL) {
        memcpy(&f[4], d4, 4u);
    }
    co_send(co, CO_ID_TSDO + co->cfg.node_id, f, 8u);
}

static void sdo_abort(co_t *co, uint16_t index, uint8_t sub, uint32_t code)
{
    uint8_t d[4] = {(uint8_t)code, (uint8_t)(code >> 8), (uint8_t)(code >> 16),
                    (uint8_t)(code >> 24)};

    co->sdo_mode = 0u;
    co->stats.sdo_aborts++;
    sdo_send(co, 0x80u, index, sub, d);
}

static void written(co_t *co, uint16_t index, uint8_t sub)
{
    if (index >= 0x1400u && index < 0x1C00u) {
        co_pdo_written(co, index);
    } else if (index == 0x1016u) {
        co_hb_written(co, sub);
    }
    if (co->on_write != NULL) {
        co->on_write(co->hook_ctx, index, sub);
    }
}

static void sdo_initiate_download(co_t *co, const uint8_t *f, uint32_t now_us)
{
    uint16_t index = (uint16_t)(f[1] | (f[2] << 8));
    uint8_t sub = f[3];
    uint32_t abort = 0;
    const co_od_entry_t *e = co_od_find(index, sub, &abort);
    uint32_t cap;

    co->sdo_mode = 0u;
    if (e == NULL) {
        sdo_abort(co, index, sub, abort);
        return;
    }
    if ((e->access & CO_OD_RW) == 0u) {
        sdo_abort(co, index, sub, CO_ABORT_READONLY);
        return;
    }
    cap = e->type == CO_OD_STR ? CO_STR_MAX : e->type;
    if (f[0] & 0x02u) { /* expedited */
        uint32_t n = (f[0] & 0x01u) ? 4u - ((f[0] >> 2) & 3u) : (cap < 4u ? cap : 4u);

        if (e->type == CO_OD_STR && n > cap) {
            abort = CO_ABORT_LEN_HIGH;
        } else {
            abort = co_od_write(co, e, &f[4], n);
        }
        if (abort != 0u) {
            sdo_abort(co, index, sub, abort);
            return;
        }
        sdo_send(co, 0x60u, index, sub, NULL);
        written(co, index, sub);
        return;
    }
    co->sdo_size = 0u;
    if (f[0] & 0x01u) {
        co->sdo_size = (uint32_t)f[4] | ((uint32_t)f[5] << 8) | ((uint32_t)f[6] << 16) |
                       ((uint32_t)f[7] << 24);
        if (co->sdo_size > cap) {
            sdo_abort(co, index, sub, CO_ABORT_LEN_HIGH);
            return;
        }
    }
    co->sdo_mode = 1u;
    co->sdo_toggle = 0u;
    co->sdo_index = index;
    co->sdo_sub = sub;
    co->sdo_pos = 0u;
    co->sdo_last_us = now_us;
    sdo_send(co, 0x60u, index, sub, NULL);
}

static void sdo_download_segment(co_t *co, const uint8_t *f, uint32_t now_us)
{
    uint8_t t = (f[0] >> 4) & 1u;
    uint32_t n = 7u - ((f[0] >> 1) & 7u);
    uint32_t abort = 0;
    const co_od_entry_t *e;

    if (co->sdo_mode != 1u) {
        sdo_abort(co, co->sdo_index, co->sdo_sub, CO_ABORT_COMMAND);
        return;
    }
    if (t != co->sdo_toggle) {
        sdo_abort(co, co->sdo_index, co->sdo_sub, CO_ABORT_TOGGLE);
        return;
    }
    if (co->sdo_pos + n > sizeof co->sdo_buf ||
        (co->sdo_size != 0u && co->sdo_pos + n > co->sdo_size)) {
        sdo_abort(co, co->sdo_index, co->sdo_sub, CO_ABORT_LEN_HIGH);
        return;
    }
    memcpy(&co->sdo_buf[co->sdo_pos], &f[1], n);
    co->sdo_pos += n;
    co->sdo_last_us = now_us;
    if (f[0] & 0x01u) { /* last segment */
        if (co->sdo_size != 0u && co->sdo_pos != co->sdo_size) {
            sdo_abort(co, co->sdo_index, co->sdo_sub, CO_ABORT_LEN);
            return;
        }
        e = co_od_find(co->sdo_index, co->sdo_sub, &abort);
        if (e != NULL) {
            abort = co_od_write(co, e, co->sdo_buf, co->sdo_pos);
        }
        if (abort != 0u) {
            sdo_abort(co, co->sdo_index, co->sdo_sub, abort);
            return;
        }
        co->sdo_mode = 0u;
    }
    co->sdo_toggle ^= 1u;
    {
        uint8_t r[8] = {(uint8_t)(0x20u | (t << 4)), 0, 0, 0, 0, 0, 0, 0};

        co_send(co, CO_ID_TSDO + co->cfg.node_id, r, 8u);
    }
    if (co->sdo_mode == 0u) {
        written(co, co->sdo_index, co->sdo_sub);
    }
}

static void sdo_initiate_upload(co_t *co, const uint8_t *f, uint32_t now_us)
{
    uint16_t index = (uint16_t)(f[1] | (f[2] << 8));
    uint8_t sub = f[3];
    uint32_t abort = 0;
    const co_od_entry_t *e = co_od_find(index, sub, &abort);
    uint32_t n;
    uint8_t d[4] = {0, 0, 0, 0};

    co->sdo_mode = 0u;
    if (e == NULL) {
        sdo_abort(co, index, sub, abort);
        return;
    }
    n = co_od_size(co, e);
    co_od_read(co, e, co->sdo_buf);
    if (n <= 4u && n > 0u) {
        memcpy(d, co->sdo_buf, n);
        sdo_send(co, (uint8_t)(0x43u | ((4u - n) << 2)), index, sub, d);
        return;
    }
    d[0] = (uint8_t)n; /* n < 256 */
    co->sdo_mode = 2u;
    co->sdo_toggle = 0u;
    co->sdo_index = index;
    co->sdo_sub = sub;
    co->sdo_size = n;
    co->sdo_pos = 0u;
    co->sdo_last_us = now_us;
    sdo_send(co, 0x41u, index, sub, d);
}

static void sdo_upload_segment(co_t *co, const uint8_t *f, uint32_t now_us)
{
    uint8_t t = (f[0] >> 4) & 1u;
    uint8_t r[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    uint32_t n;

    if (co->sdo_mode != 2u) {
        sdo_abort(co, co->sdo_index, co->sdo_sub, CO_ABORT_COMMAND);
        return;
    }
    if (t != co->sdo_toggle) {
        sdo_abort(co, co->sdo_index, co->sdo_sub, CO_ABORT_TOGGLE);
        return;
    }
    n = co->sdo_size - co->sdo_pos;
    if (n > 7u) {
        n = 7u;
    }
    memcpy(&r[1], &co->sdo_buf[co->sdo_pos], n);
    co->sdo_pos += n;
    r[0] = (uint8_t)((t << 4) | ((7u - n) << 1));
    if (co->sdo_pos >= co->sdo_size) {
        r[0] |= 0x01u;
        co->sdo_mode = 0u;
    }
    co->sdo_toggle ^= 1u;
    co->sdo_last_us = now_us;
    co_send(co, CO_ID_TSDO + co->cfg.node_id, r, 8u);
}

static void sdo_rx(co_t *co, const uint8_t *f, uint8_t len, uint32_t now_us)
{
    if (len < 8u) {
        co->stats.sdo_short++;
        return;
    }
    switch (f[0] >> 5) {
    case 0u:
        sdo_download_segment(co, f, now_us);
        break;
    case 1u:
        sdo_initiate_download(co, f, now_us);
        break;
    case 2u:
        sdo_initiate_upload(co, f, now_us);
        break;
    case 3u:
        sdo_upload_segment(co, f, now_us);
        break;
    case 4u: /* abort from the client: no answer */
        co->sdo_mode = 0u;
        break;
    default: /* block transfers (5, 6) and 7 */
        sdo_abort(co, (uint16_t)(f[1] | (f[2] << 8)), f[3], CO_ABORT_COMMAND);
        break;
    }
}

/* ---- NMT ---------------------------------------------------------------- */

static void nmt_boot(co_t *co, bool comm_only, uint32_t now_us)
{
    uint8_t b = 0u;

    co_od_defaults(&co->od, &co->cfg, comm_only);
    co_pdo_init(co);
    memset(&co->sync, 0, sizeof co->sync);
    memset(&co->hb.active, 0, sizeof co->hb.active);
    co->emcy.reported = 0u; /* the faults still present are reported again */
    co->sdo_mode = 0u;
    co->nmt = CO_NMT_PREOP;
    co->hb_last_us = now_us;
    co_send(co, CO_ID_HB + co->cfg.node_id, &b, 1u);
}

void co_init(co_t *co, const co_config_t *cfg, co_tx_fn tx, void *ctx, uint32_t now_us)
{
    memset(co, 0, sizeof *co);
    co->cfg = *cfg;
    co->tx = tx;
    co->tx_ctx = ctx;
    co->nmt = CO_NMT_INIT;
    nmt_boot(co, false, now_us);
}

static void nmt_rx(co_t *co, const uint8_t *f, uint8_t len, uint32_t now_us)
{
    if (len != 2u || (f[1] != 0u && f[1] != co->cfg.node_id)) {
        if (len != 2u) {
            co->stats.nmt_ignored++;
        }
        return;
    }
    switch (f[0]) {
    case 0x01u:
        co->nmt = CO_NMT_OPERATIONAL;
        co_pdo_init(co); /* event TPDOs send their data once */
        break;
    case 0x02u:
        co->nmt = CO_NMT_STOPPED;
        co->sdo_mode = 0u;
        break;
    case 0x80u:
        co->nmt = CO_NMT_PREOP;
        break;
    case 0x81u:
        nmt_boot(co, false, now_us);
        break;
    case 0x82u:
        nmt_boot(co, true, now_us);
        break;
    default:
        co->stats.nmt_ignored++;
        break;
    }
}

bool co_rx(co_t *co, uint32_t id, const uint8_t *data, uint8_t len, uint32_t now_us)
{
    if (id == CO_ID_NMT) {
        nmt_rx(co, data, len, now_us);
        return true;
    }
    if (id == CO_ID_RSDO + co->cfg.node_id) {
        if (co->nmt != CO_NMT_STOPPED) {
            sdo_rx(co, data, len, now_us);
        }
        return true;
    }
    if (id > 0x7FFu) {
        return false; /* 29-bit: not CANopen */
    }
    return co_sync_rx(co, id, len, now_us) || co_pdo_rx(co, id, data, len) ||
           co_hb_rx(co, id, len, now_us);
}

void co_poll(co_t *co, uint32_t now_us)
{
    tx_flush(co);
    co_pdo_poll(co, now_us);
    co_hb_poll(co, now_us);
    if (co->sdo_mode != 0u && now_us - co->sdo_last_us >= CO_SDO_TIMEOUT_US) {
        sdo_abort(co, co->sdo_index, co->sdo_sub, CO_ABORT_TIMEOUT);
    }
    if (co->od.heartbeat_ms != 0u &&
        now_us - co->hb_last_us >= (uint32_t)co->od.heartbeat_ms * 1000u) {
        uint8_t s = (uint8_t)co->nmt;

        co->hb_last_us = now_us;
        co_send(co, CO_ID_HB + co->cfg.node_id, &s, 1u);
    }
}

co_nmt_state_t co_nmt_state(const co_t *co)
{
    return co->nmt;
}

void co_set_error_register(co_t *co, uint8_t reg)
{
    co->od.error_register = reg;
}

void co_set_write_hook(co_t *co, co_write_hook_fn fn, void *ctx)
{
    co->on_write = fn;
    co->hook_ctx = ctx;
}

void co_set_sync_hook(co_t *co, co_sync_hook_fn fn)
{
    co->on_sync = fn;
}

void co_set_check_hook(co_t *co, co_check_hook_fn fn)
{
    co->on_check = fn;
}
