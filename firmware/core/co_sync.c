/*
 * co_sync.c - SYNC consumer (co_sync.h is the specification).
 */
#include "co_sync.h"

#include "canopen.h"

#define SYNC_GEN   0x40000000u /* 0x1005 bit 30: this node produces SYNC */
#define SYNC_FRAME 0x20000000u /* 0x1005 bit 29: 29-bit id              */

uint32_t co_sync_check(const struct co_s *co, uint16_t index, uint32_t value)
{
    (void)co;
    if (index == 0x1005u &&
        ((value & (SYNC_GEN | SYNC_FRAME)) != 0u || (value & 0x1FFFFFFFu) > 0x7FFu)) {
        return CO_ABORT_VALUE;
    }
    return 0u;
}

bool co_sync_rx(struct co_s *co, uint32_t id, uint8_t len, uint32_t now_us)
{
    co_sync_t *s = &co->sync;
    uint32_t gap;

    if (id != (co->od.sync_cobid & 0x7FFu)) {
        return false;
    }
    if (len > 1u) {
        s->bad_len++;
        return true;
    }
    if (co->nmt != CO_NMT_OPERATIONAL) {
        return true;
    }
    gap = now_us - s->last_us;
    if (s->count > 0u) {
        if (gap > s->gap_max_us) {
            s->gap_max_us = gap;
        }
        if (co->od.sync_period_us != 0u &&
            gap > co->od.sync_period_us + co->od.sync_period_us / 2u) {
            s->late++;
        }
    }
    s->count++;
    s->last_us = now_us;
    co_pdo_sync(co, now_us);
    return true;
}
