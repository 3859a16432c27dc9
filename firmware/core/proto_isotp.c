/*
 * proto_isotp.c - ISO-TP on classic CAN (see proto_isotp.h).
 */
#include "proto_isotp.h"

enum { TX_IDLE = 0, TX_START, TX_WAIT_FC, TX_CF };

#define PCI_SF 0x0u
#define PCI_FF 0x1u
#define PCI_CF 0x2u
#define PCI_FC 0x3u

#define FC_CTS   0u
#define FC_WAIT  1u
#define FC_OVFLW 2u

void proto_isotp_init(proto_isotp_t *t, uint32_t rx_id, uint32_t tx_id)
{
    proto_isotp_stats_t zero = {0};

    t->rx_id = rx_id;
    t->tx_id = tx_id;
    t->rx_len = 0;
    t->rx_got = 0;
    t->rx_sn = 0;
    t->rx_active = false;
    t->rx_last_us = 0;
    t->fc_pending = false;
    t->fc_status = FC_CTS;
    t->tx_len = 0;
    t->tx_pos = 0;
    t->tx_sn = 0;
    t->tx_state = TX_IDLE;
    t->bs = 0;
    t->bs_left = 0;
    t->stmin_us = 0;
    t->tx_last_us = 0;
    t->stats = zero;
}

static void rx_abort(proto_isotp_t *t)
{
    if (t->rx_active) {
        t->stats.rx_errors++;
    }
    t->rx_active = false;
}

static uint32_t stmin_to_us(uint8_t st)
{
    if (st <= 0x7Fu) {
        return (uint32_t)st * 1000u;
    }
    if (st >= 0xF1u && st <= 0xF9u) {
        return (uint32_t)(st - 0xF0u) * 100u;
    }
    return 127000u;
}

static void rx_flow_control(proto_isotp_t *t, const uint8_t *data, uint8_t dlc, uint32_t now_us)
{
    uint8_t status;

    if (t->tx_state != TX_WAIT_FC) {
        return; /* not waiting for one: ignore */
    }
    if (dlc < 3u) {
        t->stats.rx_errors++;
        return;
    }
    status = data[0] & 0x0Fu;
    if (status == FC_CTS) {
        t->bs = data[1];
        t->bs_left = data[1];
        t->stmin_us = stmin_to_us(data[2]);
        t->tx_state = TX_CF;
        t->tx_last_us = now_us - t->stmin_us; /* first CF may go at once */
    } else if (status == FC_WAIT) {
        t->tx_last_us = now_us;
    } else {
        t->tx_state = TX_IDLE; /* overflow or invalid: abandon */
        t->stats.tx_aborts++;
    }
}

bool proto_isotp_rx(proto_isotp_t *t, const uint8_t *data, uint8_t dlc, uint32_t now_us,
                    const uint8_t **msg, size_t *len)
{
    uint8_t pci;
    uint16_t n;
    uint16_t i;

    if (dlc < 1u || dlc > 8u) {
        t->stats.rx_errors++;
        return false;
    }
    pci = (uint8_t)(data[0] >> 4);
    switch (pci) {
    case PCI_SF:
        n = data[0] & 0x0Fu;
        if (n == 0u || n > 7u || n + 1u > dlc) {
            t->stats.rx_errors++;
            return false;
        }
        rx_abort(t);
        for (i = 0; i < n; i++) {
            t->rx_buf[i] = data[1u + i];
        }
        t->stats.rx_msgs++;
        *msg = t->rx_buf;
        *len = n;
        return true;
    case PCI_FF:
        rx_abort(t);
        n = (uint16_t)(((uint16_t)(data[0] & 0x0Fu) << 8) | (dlc > 1u ? data[1] : 0u));
        if (dlc != 8u || n < 8u) {
            t->stats.rx_errors++;
            return false;
        }
        if (n > PROTO_ISOTP_MAX) {
            t->stats.rx_errors++;
            t->fc_pending = true;
            t->fc_status = FC_OVFLW;
            return false;
        }
        for (i = 0; i < 6u; i++) {
            t->rx_buf[i] = data[2u + i];
        }
        t->rx_len = n;
        t->rx_got = 6;
        t->rx_sn = 1;
        t->rx_active = true;
        t->rx_last_us = now_us;
        t->fc_pending = true;
        t->fc_status = FC_CTS;
        return false;
    case PCI_CF:
        if (!t->rx_active) {
            t->stats.rx_errors++; /* unexpected: ignore */
            return false;
        }
        if ((data[0] & 0x0Fu) != t->rx_sn) {
            rx_abort(t);
            return false;
        }
        n = (uint16_t)(t->rx_len - t->rx_got);
        if (n > 7u) {
            n = 7u;
        }
        if ((uint16_t)(dlc - 1u) < n) {
            rx_abort(t);
            return false;
        }
        for (i = 0; i < n; i++) {
            t->rx_buf[t->rx_got + i] = data[1u + i];
        }
        t->rx_got = (uint16_t)(t->rx_got + n);
        t->rx_sn = (uint8_t)((t->rx_sn + 1u) & 0x0Fu);
        t->rx_last_us = now_us;
        if (t->rx_got >= t->rx_len) {
            t->rx_active = false;
            t->stats.rx_msgs++;
            *msg = t->rx_buf;
            *len = t->rx_len;
            return true;
        }
        return false;
    case PCI_FC:
        rx_flow_control(t, data, dlc, now_us);
        return false;
    default:
        t->stats.rx_errors++;
        return false;
    }
}

bool proto_isotp_send(proto_isotp_t *t, const uint8_t *msg, size_t len, uint32_t now_us)
{
    size_t i;

    if (t->tx_state != TX_IDLE || len < 1u || len > PROTO_ISOTP_MAX) {
        return false;
    }
    for (i = 0; i < len; i++) {
        t->tx_buf[i] = msg[i];
    }
    t->tx_len = (uint16_t)len;
    t->tx_pos = 0;
    t->tx_state = TX_START;
    t->tx_last_us = now_us;
    return true;
}

bool proto_isotp_busy(const proto_isotp_t *t)
{
    return t->tx_state != TX_IDLE;
}

static bool send_cf(proto_isotp_t *t, proto_can_tx_fn tx, void *ctx)
{
    uint8_t f[8];
    uint16_t n = (uint16_t)(t->tx_len - t->tx_pos);
    uint16_t i;

    if (n > 7u) {
        n = 7u;
    }
    f[0] = (uint8_t)((PCI_CF << 4) | t->tx_sn);
    for (i = 0; i < n; i++) {
        f[1u + i] = t->tx_buf[t->tx_pos + i];
    }
    if (!tx(ctx, t->tx_id, f, (uint8_t)(n + 1u))) {
        return false;
    }
    t->tx_pos = (uint16_t)(t->tx_pos + n);
    t->tx_sn = (uint8_t)((t->tx_sn + 1u) & 0x0Fu);
    return true;
}

void proto_isotp_poll(proto_isotp_t *t, uint32_t now_us, proto_can_tx_fn tx, void *ctx)
{
    uint8_t f[8];
    uint16_t i;

    if (t->rx_active && (uint32_t)(now_us - t->rx_last_us) > PROTO_ISOTP_TIMEOUT_US) {
        t->stats.rx_timeouts++;
        rx_abort(t);
    }
    if (t->fc_pending) {
        f[0] = (uint8_t)((PCI_FC << 4) | t->fc_status);
        f[1] = 0;
        f[2] = 0;
        if (!tx(ctx, t->tx_id, f, 3)) {
            return;
        }
        t->fc_pending = false;
    }
    switch (t->tx_state) {
    case TX_START:
        if (t->tx_len <= 7u) {
            f[0] = (uint8_t)t->tx_len;
            for (i = 0; i < t->tx_len; i++) {
                f[1u + i] = t->tx_buf[i];
            }
            if (tx(ctx, t->tx_id, f, (uint8_t)(t->tx_len + 1u))) {
                t->tx_state = TX_IDLE;
                t->stats.tx_msgs++;
            }
            return;
        }
        f[0] = (uint8_t)((PCI_FF << 4) | (t->tx_len >> 8));
        f[1] = (uint8_t)t->tx_len;
        for (i = 0; i < 6u; i++) {
            f[2u + i] = t->tx_buf[i];
        }
        if (tx(ctx, t->tx_id, f, 8)) {
            t->tx_pos = 6;
            t->tx_sn = 1;
            t->tx_state = TX_WAIT_FC;
            t->tx_last_us = now_us;
        }
        return;
    case TX_WAIT_FC:
        if ((uint32_t)(now_us - t->tx_last_us) > PROTO_ISOTP_TIMEOUT_US) {
            t->tx_state = TX_IDLE;
            t->stats.tx_aborts++;
        }
        return;
    case TX_CF:
        while (t->tx_state == TX_CF) {
            if (t->stmin_us != 0u && (uint32_t)(now_us - t->tx_last_us) < t->stmin_us) {
                return;
            }
            if (!send_cf(t, tx, ctx)) {
                return;
            }
            t->tx_last_us = now_us;
            if (t->tx_pos >= t->tx_len) {
                t->tx_state = TX_IDLE;
                t->stats.tx_msgs++;
                return;
            }
            if (t->bs != 0u && --t->bs_left == 0u) {
                t->tx_state = TX_WAIT_FC;
                return;
            }
            if (t->stmin_us != 0u) {
                return; /* next one after STmin */
            }
        }
        return;
    default:
        return;
    }
}
