/*
 * co_od.c - access to the object dictionary of the CANopen node: lookup,
 * read, and the checked write of the SDO server (canopen.h: limits, the
 * rules of the PDO / SYNC / EMCY objects, the check hook).
 */
#include <string.h>

#include "canopen.h"

const co_od_entry_t *co_od_find(uint16_t index, uint8_t sub, uint32_t *abort)
{
    size_t i;
    bool index_seen = false;

    for (i = 0; i < co_od_count; i++) {
        if (co_od_table[i].index == index) {
            index_seen = true;
            if (co_od_table[i].sub == sub) {
                return &co_od_table[i];
            }
        }
    }
    *abort = index_seen ? CO_ABORT_NO_SUB : CO_ABORT_NO_OBJECT;
    return NULL;
}

uint8_t *co_od_var(co_t *co, const co_od_entry_t *e)
{
    return (uint8_t *)&co->od + e->offset;
}

/* Current size of an object's value in bytes. */
uint32_t co_od_size(co_t *co, const co_od_entry_t *e)
{
    if (e->type == CO_OD_STR) {
        const char *s = (const char *)co_od_var(co, e);
        uint32_t n = 0;

        while (n < CO_STR_MAX && s[n] != '\0') {
            n++;
        }
        return n;
    }
    return e->type;
}

void co_od_read(co_t *co, const co_od_entry_t *e, uint8_t *out)
{
    const uint8_t *p = co_od_var(co, e);
    uint32_t v = 0;

    switch (e->type) {
    case CO_OD_U8:
        v = *p;
        break;
    case CO_OD_U16:
        v = *(const uint16_t *)(const void *)p;
        break;
    case CO_OD_U32:
        v = *(const uint32_t *)(const void *)p;
        break;
    default:
        memcpy(out, p, co_od_size(co, e));
        return;
    }
    out[0] = (uint8_t)v;
    out[1] = (uint8_t)(v >> 8);
    out[2] = (uint8_t)(v >> 16);
    out[3] = (uint8_t)(v >> 24);
}

/* Rules of objects beyond their limits (co_pdo.h, co_sync.h, co_emcy.h,
 * the check hook); 0 or the abort code. */
static uint32_t od_check(co_t *co, const co_od_entry_t *e, uint32_t v)
{
    if (e->index >= 0x1400u && e->index < 0x1C00u) {
        return co_pdo_check(co, e->index, e->sub, v);
    }
    if (e->index == 0x1005u || e->index == 0x1006u) {
        return co_sync_check(co, e->index, v);
    }
    if (e->index == 0x1016u) {
        return co_hb_check(co, e->sub, v);
    }
    if (e->index == 0x1014u) {
        return co_emcy_check(v);
    }
    return co->on_check != NULL ? co->on_check(co->hook_ctx, e->index, e->sub, v) : 0u;
}

/* v < lim, as signed numbers for a signed object (v sign-extended from its
 * size; the generator writes the limits sign-extended to 32 bits). */
static bool od_less(const co_od_entry_t *e, uint32_t v, uint32_t lim)
{
    if ((e->access & CO_OD_SIGNED) != 0u) {
        unsigned sh = 32u - 8u * e->type;

        return (int32_t)(v << sh) >> sh < (int32_t)lim;
    }
    return v < lim;
}

/* lim < v, the same way. */
static bool od_greater(const co_od_entry_t *e, uint32_t v, uint32_t lim)
{
    if ((e->access & CO_OD_SIGNED) != 0u) {
        unsigned sh = 32u - 8u * e->type;

        return (int32_t)(v << sh) >> sh > (int32_t)lim;
    }
    return v > lim;
}

/* Size checks happen at initiate; this checks the value and stores it. */
uint32_t co_od_write(co_t *co, const co_od_entry_t *e, const uint8_t *in, uint32_t n)
{
    uint8_t *p = co_od_var(co, e);
    uint32_t v = 0;
    uint32_t i;

    if (e->type == CO_OD_STR) {
        memset(p, 0, CO_STR_MAX);
        memcpy(p, in, n);
        return 0;
    }
    if (n != e->type) {
        return n > e->type ? CO_ABORT_LEN_HIGH : CO_ABORT_LEN_LOW;
    }
    for (i = 0; i < n; i++) {
        v |= (uint32_t)in[i] << (8u * i);
    }
    if (od_greater(e, v, e->max)) {
        return CO_ABORT_VALUE_HIGH;
    }
    if (od_less(e, v, e->min)) {
        return CO_ABORT_VALUE_LOW;
    }
    {
        uint32_t abort = od_check(co, e, v);

        if (abort != 0u) {
            return abort;
        }
    }
    if (e->type == CO_OD_U8) {
        *p = (uint8_t)v;
    } else if (e->type == CO_OD_U16) {
        *(uint16_t *)(void *)p = (uint16_t)v;
    } else {
        *(uint32_t *)(void *)p = v;
    }
    return 0;
}
