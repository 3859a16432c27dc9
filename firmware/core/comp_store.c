/*
 * comp_store.c - compensation tables in flash (see comp_store.h).
 */
#include "comp_store.h"

#include "hal.h"

static uint8_t rec[COMP_RECORD_MAX + 64u]; /* record + write-unit padding */

bool comp_store_layout(comp_store_layout_t *out)
{
    const hal_flash_layout_t *l = hal_flash_layout();
    uint64_t slot, need, end;
    if (out == NULL || l == NULL || l->page_size == 0u || l->write_size == 0u ||
        l->write_size > 64u || l->size < COMP_STORE_REGION_BYTES) {
        return false;
    }
    slot = ((uint64_t)COMP_RECORD_MAX + l->page_size - 1u) / l->page_size * l->page_size;
    need = slot * 2u * CORE_AXES;
    if (need > COMP_STORE_REGION_BYTES) {
        return false;
    }
    end = (uint64_t)l->base + l->size;
    out->base = (uint32_t)(end - need);
    out->slot_bytes = (uint32_t)slot;
    out->write_size = l->write_size;
    return true;
}

uint32_t comp_store_slot_addr(unsigned axis, unsigned slot)
{
    comp_store_layout_t lay;
    if (axis >= CORE_AXES || slot > 1u || !comp_store_layout(&lay)) {
        return 0u;
    }
    return lay.base + (uint32_t)(2u * axis + slot) * lay.slot_bytes;
}

/* Read and decode slot (axis, s) into t. */
static comp_store_result_t read_slot(unsigned axis, unsigned s, comp_table_t *t)
{
    uint32_t addr = comp_store_slot_addr(axis, s);
    size_t total;
    if (addr == 0u) {
        return COMP_STORE_E_LAYOUT;
    }
    if (!hal_flash_read(addr, rec, COMP_RECORD_HDR)) {
        return COMP_STORE_E_FLASH;
    }
    if (comp_record_header(rec, COMP_RECORD_HDR, &total) != COMP_OK) {
        return COMP_STORE_EMPTY;
    }
    if (!hal_flash_read(addr, rec, total)) {
        return COMP_STORE_E_FLASH;
    }
    if (comp_record_decode(rec, total, t) != COMP_OK || t->axis != axis) {
        return COMP_STORE_EMPTY;
    }
    return COMP_STORE_OK;
}

/* Versions of both slots (0 = none) without keeping the tables. */
static comp_store_result_t current(unsigned axis, comp_table_t *t, unsigned *slot_out)
{
    static comp_table_t other;
    comp_store_result_t r0, r1;
    r0 = read_slot(axis, 0u, t);
    if (r0 == COMP_STORE_E_LAYOUT || r0 == COMP_STORE_E_FLASH) {
        return r0;
    }
    r1 = read_slot(axis, 1u, &other);
    if (r1 == COMP_STORE_E_FLASH) {
        return r1;
    }
    if (r1 == COMP_STORE_OK && (r0 != COMP_STORE_OK || other.version > t->version)) {
        *t = other;
        *slot_out = 1u;
        return COMP_STORE_OK;
    }
    *slot_out = 0u;
    return r0;
}

comp_store_result_t comp_store_load(unsigned axis, comp_table_t *table, unsigned *slot)
{
    static comp_table_t t;
    unsigned s = 0u;
    comp_store_result_t r;
    if (axis >= CORE_AXES || table == NULL) {
        return COMP_STORE_E_ARG;
    }
    r = current(axis, &t, &s);
    if (r != COMP_STORE_OK) {
        return r;
    }
    *table = t;
    table->dir_src = NULL;
    if (slot != NULL) {
        *slot = s;
    }
    return COMP_STORE_OK;
}

static bool erase_slot(const comp_store_layout_t *lay, uint32_t addr)
{
    const hal_flash_layout_t *l = hal_flash_layout();
    uint32_t off;
    for (off = 0; off < lay->slot_bytes; off += l->page_size) {
        if (!hal_flash_erase_page(addr + off)) {
            return false;
        }
    }
    return true;
}

comp_store_result_t comp_store_write(unsigned axis, const comp_table_t *table, uint32_t *version,
                                     unsigned *slot)
{
    static comp_table_t cur, back, tmp;
    comp_store_layout_t lay;
    comp_store_result_t r;
    unsigned cs = 0u, target;
    uint32_t addr, ver;
    size_t len, padded, i;

    if (axis >= CORE_AXES || table == NULL || table->axis != axis ||
        comp_table_check(table) != COMP_OK) {
        return COMP_STORE_E_ARG;
    }
    if (!comp_store_layout(&lay)) {
        return COMP_STORE_E_LAYOUT;
    }
    r = current(axis, &cur, &cs);
    if (r == COMP_STORE_OK) {
        target = cs ^ 1u;
        ver = cur.version + 1u;
    } else if (r == COMP_STORE_EMPTY) {
        target = 0u;
        ver = 1u;
    } else {
        return r;
    }
    tmp = *table;
    tmp.version = ver;
    len = comp_record_encode(&tmp, rec, COMP_RECORD_MAX);
    if (len == 0u) {
        return COMP_STORE_E_ARG;
    }
    padded = (len + lay.write_size - 1u) / lay.write_size * lay.write_size;
    for (i = len; i < padded; i++) {
        rec[i] = 0xFFu;
    }
    addr = lay.base + (uint32_t)(2u * axis + target) * lay.slot_bytes;
    if (!erase_slot(&lay, addr) || !hal_flash_write(addr, rec, padded)) {
        return COMP_STORE_E_FLASH;
    }
    /* verify: read back, decode, compare */
    r = read_slot(axis, target, &back);
    if (r == COMP_STORE_E_FLASH) {
        return r;
    }
    if (r != COMP_STORE_OK || back.version != ver || back.n != tmp.n ||
        back.ramp_us != tmp.ramp_us) {
        return COMP_STORE_E_VERIFY;
    }
    for (i = 0; i < back.n; i++) {
        if (back.pos[i] != tmp.pos[i] || back.fwd[i] != tmp.fwd[i] || back.rev[i] != tmp.rev[i]) {
            return COMP_STORE_E_VERIFY;
        }
    }
    if (version != NULL) {
        *version = ver;
    }
    if (slot != NULL) {
        *slot = target;
    }
    return COMP_STORE_OK;
}

comp_store_result_t comp_store_clear(unsigned axis, uint32_t *version)
{
    static comp_table_t empty;
    empty.n = 0u;
    empty.axis = (uint8_t)axis;
    empty.flags = 0u;
    empty.ramp_us = 0u;
    empty.dir_src = NULL;
    return comp_store_write(axis, &empty, version, NULL);
}
