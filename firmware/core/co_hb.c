/*
 * co_hb.c - heartbeat consumer (co_hb.h is the specification).
 */
#include "co_hb.h"

#include "canopen.h"

static uint8_t entry_node(uint32_t v)
{
    return (uint8_t)(v >> 16);
}

static bool entry_used(uint32_t v)
{
    return entry_node(v) != 0u && (v & 0xFFFFu) != 0u;
}

/* The used entry watching node id - 0x700, or -1. */
static int watcher(const co_t *co, uint32_t id)
{
    unsigned i;

    if (id <= CO_ID_HB || id > CO_ID_HB + 0x7Fu) {
        return -1;
    }
    for (i = 0; i < CO_HB_CONSUMERS; i++) {
        uint32_t v = co->od.hb_consumer[i];

        if (entry_used(v) && entry_node(v) == id - CO_ID_HB) {
            return (int)i;
        }
    }
    return -1;
}

bool co_hb_rx(co_t *co, uint32_t id, uint8_t len, uint32_t now_us)
{
    int i = watcher(co, id);

    if (i < 0 || len < 1u) {
        return false;
    }
    co->hb.last_us[i] = now_us;
    co->hb.active[i] = 1u;
    return true;
}

void co_hb_poll(co_t *co, uint32_t now_us)
{
    unsigned i;

    for (i = 0; i < CO_HB_CONSUMERS; i++) {
        uint32_t v = co->od.hb_consumer[i];

        if (co->hb.active[i] == 0u || !entry_used(v) ||
            now_us - co->hb.last_us[i] < (v & 0xFFFFu) * 1000u) {
            continue;
        }
        co->hb.active[i] = 0u;
        co->hb.lost++;
        if (co->od.comm_error == 0u && co->nmt == CO_NMT_OPERATIONAL) {
            co->nmt = CO_NMT_PREOP;
        } else if (co->od.comm_error == 2u) {
            co->nmt = CO_NMT_STOPPED;
            co->sdo_mode = 0u;
        }
    }
}

bool co_hb_alive(const co_t *co, uint32_t id)
{
    unsigned i;

    for (i = 0; i < CO_HB_CONSUMERS; i++) {
        if (entry_used(co->od.hb_consumer[i])) {
            return watcher(co, id) >= 0;
        }
    }
    return true;
}

uint32_t co_hb_check(const co_t *co, uint8_t sub, uint32_t value)
{
    unsigned i;

    if ((value & 0xFF000000u) != 0u || entry_node(value) > 0x7Fu) {
        return CO_ABORT_VALUE;
    }
    if (!entry_used(value)) {
        return 0u;
    }
    for (i = 0; i < CO_HB_CONSUMERS; i++) {
        uint32_t v = co->od.hb_consumer[i];

        if (i + 1u != sub && entry_used(v) && entry_node(v) == entry_node(value)) {
            return CO_ABORT_PARAM_INCOMP;
        }
    }
    return 0u;
}

void co_hb_written(co_t *co, uint8_t sub)
{
    if (sub >= 1u && sub <= CO_HB_CONSUMERS) {
        co->hb.active[sub - 1u] = 0u;
    }
}
