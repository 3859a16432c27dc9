/*
 * co_pdo.c - PDOs of the CANopen node (co_pdo.h is the specification).
 */
#include "co_pdo.h"

#include <string.h>

#include "canopen.h"

#define COB_INVALID   0x80000000u
#define COB_FRAME29   0x20000000u
#define TYPE_SYNC_MAX 240u

typedef struct {
    uint32_t *cobid;
    uint8_t *type;
    uint8_t *count;
    uint32_t *map;
    co_pdo_ch_t *ch;
    bool tx;
} pdo_ref_t;

/* The configuration and state of PDO k of one direction. */
static pdo_ref_t pdo_ref(struct co_s *co, bool tx, unsigned k)
{
    pdo_ref_t r;

    r.tx = tx;
    if (tx) {
        r.cobid = &co->od.tpdo_cobid[k];
        r.type = &co->od.tpdo_type[k];
        r.count = &co->od.tpdo_map_count[k];
        r.map = co->od.tpdo_map[k];
        r.ch = &co->pdo.tx[k];
    } else {
        r.cobid = &co->od.rpdo_cobid[k];
        r.type = &co->od.rpdo_type[k];
        r.count = &co->od.rpdo_map_count[k];
        r.map = co->od.rpdo_map[k];
        r.ch = &co->pdo.rx[k];
    }
    return r;
}

/* A mapping entry -> its variable; 0 or CO_ABORT_NO_MAP. */
static uint32_t map_entry(uint32_t m, bool tx, co_pdo_slot_t *slot)
{
    uint32_t abort = 0;
    const co_od_entry_t *e = co_od_find((uint16_t)(m >> 16), (uint8_t)(m >> 8), &abort);

    if (e == NULL || (e->access & CO_OD_MAP) == 0u || (!tx && (e->access & CO_OD_RW) == 0u) ||
        e->type == CO_OD_STR || (m & 0xFFu) != 8u * e->type) {
        return CO_ABORT_NO_MAP;
    }
    slot->off = e->offset;
    slot->len = e->type;
    return 0u;
}

/* Entries 0..n-1 of a mapping; 0 or the abort code. */
static uint32_t map_resolve(const uint32_t *map, unsigned n, bool tx, co_pdo_ch_t *ch)
{
    unsigned j, len = 0;
    co_pdo_slot_t slot;

    for (j = 0; j < n; j++) {
        uint32_t abort = map_entry(map[j], tx, &slot);

        if (abort != 0u) {
            return abort;
        }
        len += slot.len;
        if (len > 8u) {
            return CO_ABORT_MAP_LEN;
        }
        if (ch != NULL) {
            ch->slot[j] = slot;
        }
    }
    if (ch != NULL) {
        ch->nslots = (uint8_t)n;
        ch->len = (uint8_t)len;
    }
    return 0u;
}

static void resolve(struct co_s *co, bool tx, unsigned k)
{
    pdo_ref_t r = pdo_ref(co, tx, k);

    memset(r.ch, 0, sizeof *r.ch);
    r.ch->valid = (*r.cobid & COB_INVALID) == 0u && *r.count <= CO_PDO_MAP_MAX &&
                  map_resolve(r.map, *r.count, tx, r.ch) == 0u;
}

void co_pdo_init(struct co_s *co)
{
    unsigned k;

    memset(&co->pdo, 0, sizeof co->pdo);
    for (k = 0; k < CO_PDO_N; k++) {
        resolve(co, false, k);
        resolve(co, true, k);
    }
}

static bool restricted(uint32_t id)
{
    return id <= 0x07Fu || (id >= 0x101u && id <= 0x180u) || (id >= 0x581u && id <= 0x5FFu) ||
           (id >= 0x601u && id <= 0x67Fu) || (id >= 0x6E0u && id <= 0x6FFu) || id >= 0x701u;
}

uint32_t co_pdo_check(const struct co_s *co, uint16_t index, uint8_t sub, uint32_t value)
{
    unsigned k = index & 0xFFu;
    bool tx = (index & 0x0800u) != 0u;
    bool map = (index & 0x0200u) != 0u;
    pdo_ref_t r;
    bool valid;

    if (k >= CO_PDO_N) {
        return 0u;
    }
    r = pdo_ref((struct co_s *)co, tx, k); /* read only here */
    valid = (*r.cobid & COB_INVALID) == 0u;
    if (map) {
        if (valid || (sub != 0u && *r.count != 0u)) {
            return CO_ABORT_ACCESS;
        }
        if (sub == 0u) {
            return value > CO_PDO_MAP_MAX ? CO_ABORT_VALUE_HIGH
                                          : map_resolve(r.map, value, tx, NULL);
        }
        return value == 0u ? 0u : map_resolve(&value, 1u, tx, NULL);
    }
    switch (sub) {
    case 1u:
        if ((value & COB_FRAME29) != 0u) {
            return CO_ABORT_VALUE;
        }
        if ((value & COB_INVALID) == 0u &&
            ((value & 0x1FFFF800u) != 0u || restricted(value & 0x7FFu) ||
             (valid && ((value ^ *r.cobid) & 0x7FFu) != 0u))) {
            return CO_ABORT_VALUE;
        }
        return 0u;
    case 2u:
        return (value <= TYPE_SYNC_MAX || value >= 254u) ? 0u : CO_ABORT_VALUE;
    case 3u:
        return valid ? CO_ABORT_ACCESS : 0u;
    default:
        return 0u;
    }
}

void co_pdo_written(struct co_s *co, uint16_t index)
{
    unsigned k = index & 0xFFu;

    if (k < CO_PDO_N) {
        resolve(co, (index & 0x0800u) != 0u, k);
    }
}

/* RPDO data -> the mapped variables, each through the write hook. */
static void rpdo_apply(struct co_s *co, pdo_ref_t *r, const uint8_t *d)
{
    unsigned j, pos = 0;

    for (j = 0; j < r->ch->nslots; j++) {
        const co_pdo_slot_t *s = &r->ch->slot[j];
        uint8_t *p = (uint8_t *)&co->od + s->off;
        uint32_t v = 0;
        unsigned b;

        for (b = 0; b < s->len; b++) {
            v |= (uint32_t)d[pos + b] << (8u * b);
        }
        pos += s->len;
        if (s->len == 1u) {
            *p = (uint8_t)v;
        } else if (s->len == 2u) {
            *(uint16_t *)(void *)p = (uint16_t)v;
        } else {
            *(uint32_t *)(void *)p = v;
        }
        if (co->on_write != NULL) {
            co->on_write(co->hook_ctx, (uint16_t)(r->map[j] >> 16), (uint8_t)(r->map[j] >> 8));
        }
    }
}

bool co_pdo_rx(struct co_s *co, uint32_t id, const uint8_t *data, uint8_t len)
{
    unsigned k;

    for (k = 0; k < CO_PDO_N; k++) {
        pdo_ref_t r = pdo_ref(co, false, k);

        if (!r.ch->valid || (*r.cobid & 0x7FFu) != id) {
            continue;
        }
        if (co->nmt != CO_NMT_OPERATIONAL) {
            return true;
        }
        if (len < r.ch->len) {
            co->pdo.rpdo_short++;
            return true;
        }
        if (*r.type <= TYPE_SYNC_MAX) {
            if (r.ch->pending) {
                co->pdo.rpdo_overrun++;
            }
            memcpy(r.ch->data, data, r.ch->len);
            r.ch->pending = true;
        } else {
            rpdo_apply(co, &r, data);
        }
        return true;
    }
    return false;
}

static void tpdo_build(struct co_s *co, const co_pdo_ch_t *ch, uint8_t *d)
{
    unsigned j, pos = 0;

    for (j = 0; j < ch->nslots; j++) {
        const uint8_t *p = (const uint8_t *)&co->od + ch->slot[j].off;
        uint32_t v;
        unsigned b;

        if (ch->slot[j].len == 1u) {
            v = *p;
        } else if (ch->slot[j].len == 2u) {
            v = *(const uint16_t *)(const void *)p;
        } else {
            v = *(const uint32_t *)(const void *)p;
        }
        for (b = 0; b < ch->slot[j].len; b++) {
            d[pos++] = (uint8_t)(v >> (8u * b));
        }
    }
}

static void tpdo_send(struct co_s *co, pdo_ref_t *r, const uint8_t *d, uint32_t now_us)
{
    co_send(co, *r->cobid & 0x7FFu, d, r->ch->len);
    memcpy(r->ch->data, d, r->ch->len);
    r->ch->pending = true;
    r->ch->last_us = now_us;
    co->pdo.tpdo_sent++;
}

void co_pdo_sync(struct co_s *co, uint32_t now_us)
{
    unsigned k;
    uint8_t d[8];

    if (co->on_sync != NULL) {
        co->on_sync(co->hook_ctx, CO_SYNC_SAMPLE, now_us);
    }
    for (k = 0; k < CO_PDO_N; k++) {
        pdo_ref_t r = pdo_ref(co, true, k);

        if (!r.ch->valid || *r.type > TYPE_SYNC_MAX) {
            continue;
        }
        tpdo_build(co, r.ch, d);
        if (*r.type == 0u) {
            if (!r.ch->pending || memcmp(d, r.ch->data, r.ch->len) != 0) {
                tpdo_send(co, &r, d, now_us);
            }
        } else if (++r.ch->syncs >= *r.type) {
            r.ch->syncs = 0u;
            tpdo_send(co, &r, d, now_us);
        }
    }
    for (k = 0; k < CO_PDO_N; k++) {
        pdo_ref_t r = pdo_ref(co, false, k);

        if (r.ch->valid && *r.type <= TYPE_SYNC_MAX && r.ch->pending) {
            r.ch->pending = false;
            rpdo_apply(co, &r, r.ch->data);
        }
    }
    if (co->on_sync != NULL) {
        co->on_sync(co->hook_ctx, CO_SYNC_APPLY, now_us);
    }
}

void co_pdo_poll(struct co_s *co, uint32_t now_us)
{
    unsigned k;
    uint8_t d[8];

    if (co->nmt != CO_NMT_OPERATIONAL) {
        return;
    }
    for (k = 0; k < CO_PDO_N; k++) {
        pdo_ref_t r = pdo_ref(co, true, k);
        uint32_t since = now_us - r.ch->last_us;
        uint32_t ev = (uint32_t)co->od.tpdo_event_ms[k] * 1000u;
        bool due;

        if (!r.ch->valid || *r.type <= TYPE_SYNC_MAX) {
            continue;
        }
        if (r.ch->pending && since < (uint32_t)co->od.tpdo_inhibit[k] * 100u) {
            continue;
        }
        tpdo_build(co, r.ch, d);
        due = !r.ch->pending || memcmp(d, r.ch->data, r.ch->len) != 0 || (ev != 0u && since >= ev);
        if (due) {
            tpdo_send(co, &r, d, now_us);
        }
    }
}
