/*
 * comp_store.c - compensation tables in flash: two banks, a log of records
 * in the active one (see comp_store.h).
 */
#include "comp_store.h"

#include "crc.h"
#include "hal.h"

#define NO_OFF 0xFFFFFFFFu

static uint8_t rec[COMP_RECORD_MAX + 64u]; /* record + write-unit padding */

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static uint32_t pad(uint32_t len, uint32_t w)
{
    return (len + w - 1u) / w * w;
}

bool comp_store_layout(comp_store_layout_t *out)
{
    const hal_flash_layout_t *l = hal_flash_layout();
    uint64_t bank, end;
    if (out == NULL || l == NULL || l->page_size == 0u || l->write_size == 0u ||
        l->write_size > COMP_STORE_HDR_BYTES || COMP_STORE_HDR_BYTES % l->write_size != 0u) {
        return false;
    }
    bank =
        ((uint64_t)COMP_STORE_REGION_BYTES / 2u + l->page_size - 1u) / l->page_size * l->page_size;
    if (bank < COMP_STORE_HDR_BYTES + (uint64_t)CORE_AXES * pad(COMP_RECORD_MAX, l->write_size) ||
        4u * bank > l->size) {
        return false;
    }
    end = (uint64_t)l->base + l->size;
    out->base = (uint32_t)(end - 2u * bank);
    out->bank_bytes = (uint32_t)bank;
    out->write_size = l->write_size;
    return true;
}

uint32_t comp_store_bytes(void)
{
    comp_store_layout_t lay;
    return comp_store_layout(&lay) ? 2u * lay.bank_bytes : 0u;
}

uint32_t comp_store_bank_addr(unsigned bank)
{
    comp_store_layout_t lay;
    if (bank > 1u || !comp_store_layout(&lay)) {
        return 0u;
    }
    return lay.base + (uint32_t)bank * lay.bank_bytes;
}

/* Sequence number of a valid bank header; false when not valid. */
static bool bank_seq(const comp_store_layout_t *lay, unsigned bank, uint32_t *seq)
{
    uint8_t h[16];
    if (!hal_flash_read(lay->base + (uint32_t)bank * lay->bank_bytes, h, sizeof h)) {
        return false;
    }
    if (get32(h) != COMP_STORE_BANK_MAGIC || get32(h + 8) != lay->bank_bytes ||
        crc32_update(CRC32_INIT, h, 12) != get32(h + 12)) {
        return false;
    }
    *seq = get32(h + 4);
    return true;
}

/* Active bank (0/1) and its seq; -1 when neither bank is valid. */
static int active_bank(const comp_store_layout_t *lay, uint32_t *seq)
{
    uint32_t s0 = 0u, s1 = 0u;
    bool v0 = bank_seq(lay, 0u, &s0);
    bool v1 = bank_seq(lay, 1u, &s1);
    if (v1 && (!v0 || (int32_t)(s1 - s0) > 0)) {
        *seq = s1;
        return 1;
    }
    if (v0) {
        *seq = s0;
        return 0;
    }
    return -1;
}

typedef struct {
    uint32_t off;     /* offset of the chosen record in the bank, NO_OFF: none */
    uint32_t len;     /* its length (unpadded)                                 */
    uint32_t end;     /* clean end of the log, NO_OFF: dirty or full           */
    bool read_failed; /* hal_flash_read failed                                 */
} scan_t;

/* Walk the log of `bank`. With axis < CORE_AXES: choose that axis's record
 * with the highest (version, offset) below (lim_ver, lim_off) (lexicographic;
 * lim_off NO_OFF with lim_ver 0xFFFFFFFF: no limit). */
static void scan_bank(const comp_store_layout_t *lay, unsigned bank, unsigned axis,
                      uint32_t lim_ver, uint32_t lim_off, scan_t *s)
{
    uint32_t addr = lay->base + (uint32_t)bank * lay->bank_bytes;
    uint32_t off = COMP_STORE_HDR_BYTES, best_ver = 0u, i;
    uint8_t h[COMP_RECORD_HDR];
    size_t total;
    s->off = NO_OFF;
    s->len = 0u;
    s->end = NO_OFF;
    s->read_failed = false;
    while (off + COMP_RECORD_HDR <= lay->bank_bytes) {
        bool erased = true;
        uint32_t ver;
        if (!hal_flash_read(addr + off, h, sizeof h)) {
            s->read_failed = true;
            return;
        }
        for (i = 0; i < COMP_RECORD_HDR; i++) {
            erased = erased && h[i] == 0xFFu;
        }
        if (erased) {
            s->end = off;
            return;
        }
        if (comp_record_header(h, sizeof h, &total) != COMP_OK || total > lay->bank_bytes - off) {
            return; /* dirty end */
        }
        ver = get32(h + 8);
        if (h[6] == axis && (ver < lim_ver || (ver == lim_ver && off < lim_off)) &&
            (s->off == NO_OFF || ver >= best_ver)) {
            best_ver = ver;
            s->off = off;
            s->len = (uint32_t)total;
        }
        off += pad((uint32_t)total, lay->write_size);
    }
    /* full: no clean end */
}

/* Current record of `axis` in `bank` decoded into t (its raw bytes stay in
 * rec[0..*len)); *off_out gets its offset. */
static comp_store_result_t find(const comp_store_layout_t *lay, unsigned bank, unsigned axis,
                                comp_table_t *t, uint32_t *off_out, uint32_t *len_out)
{
    uint32_t addr = lay->base + (uint32_t)bank * lay->bank_bytes;
    uint32_t lim_ver = 0xFFFFFFFFu, lim_off = NO_OFF;
    scan_t s;
    for (;;) {
        scan_bank(lay, bank, axis, lim_ver, lim_off, &s);
        if (s.read_failed) {
            return COMP_STORE_E_FLASH;
        }
        if (s.off == NO_OFF) {
            return COMP_STORE_EMPTY;
        }
        if (!hal_flash_read(addr + s.off, rec, s.len)) {
            return COMP_STORE_E_FLASH;
        }
        if (comp_record_decode(rec, s.len, t) == COMP_OK && t->axis == axis) {
            *off_out = s.off;
            *len_out = s.len;
            return COMP_STORE_OK;
        }
        lim_ver = get32(rec + 8); /* damaged: the one before it */
        lim_off = s.off;
    }
}

/* Current table of axis: bank, offset, length; t decoded, rec holds it. */
static comp_store_result_t current(const comp_store_layout_t *lay, unsigned axis, comp_table_t *t,
                                   unsigned *bank, uint32_t *off, uint32_t *len)
{
    uint32_t seq;
    int b = active_bank(lay, &seq);
    if (b < 0) {
        return COMP_STORE_EMPTY;
    }
    *bank = (unsigned)b;
    return find(lay, (unsigned)b, axis, t, off, len);
}

comp_store_result_t comp_store_load(unsigned axis, comp_table_t *table, unsigned *slot)
{
    static comp_table_t t;
    comp_store_layout_t lay;
    unsigned b = 0u;
    uint32_t off, len;
    comp_store_result_t r;
    if (axis >= CORE_AXES || table == NULL) {
        return COMP_STORE_E_ARG;
    }
    if (!comp_store_layout(&lay)) {
        return COMP_STORE_E_LAYOUT;
    }
    r = current(&lay, axis, &t, &b, &off, &len);
    if (r != COMP_STORE_OK) {
        return r;
    }
    *table = t;
    table->dir_src = NULL;
    if (slot != NULL) {
        *slot = b;
    }
    return COMP_STORE_OK;
}

uint32_t comp_store_record_addr(unsigned axis)
{
    static comp_table_t t;
    comp_store_layout_t lay;
    unsigned b = 0u;
    uint32_t off, len;
    if (axis >= CORE_AXES || !comp_store_layout(&lay) ||
        current(&lay, axis, &t, &b, &off, &len) != COMP_STORE_OK) {
        return 0u;
    }
    return lay.base + (uint32_t)b * lay.bank_bytes + off;
}

/* True when [addr, addr + len) reads all 0xFF. */
static bool erased(uint32_t addr, uint32_t len)
{
    uint8_t buf[64];
    uint32_t done = 0u, n, i;
    while (done < len) {
        n = len - done < sizeof buf ? len - done : (uint32_t)sizeof buf;
        if (!hal_flash_read(addr + done, buf, n)) {
            return false;
        }
        for (i = 0; i < n; i++) {
            if (buf[i] != 0xFFu) {
                return false;
            }
        }
        done += n;
    }
    return true;
}

/* Encode t into rec padded to the write unit; 0 when invalid. */
static uint32_t encode(const comp_store_layout_t *lay, const comp_table_t *t)
{
    size_t len = comp_record_encode(t, rec, COMP_RECORD_MAX);
    uint32_t padded, i;
    if (len == 0u) {
        return 0u;
    }
    padded = pad((uint32_t)len, lay->write_size);
    for (i = (uint32_t)len; i < padded; i++) {
        rec[i] = 0xFFu;
    }
    return padded;
}

/* The current record of axis in bank matches `want` (version and content). */
static comp_store_result_t verify(const comp_store_layout_t *lay, unsigned bank, unsigned axis,
                                  const comp_table_t *want)
{
    static comp_table_t back;
    uint32_t off, len, i;
    comp_store_result_t r = find(lay, bank, axis, &back, &off, &len);
    if (r == COMP_STORE_E_FLASH) {
        return r;
    }
    if (r != COMP_STORE_OK || back.version != want->version || back.n != want->n ||
        back.ramp_us != want->ramp_us) {
        return COMP_STORE_E_VERIFY;
    }
    for (i = 0; i < back.n; i++) {
        if (back.pos[i] != want->pos[i] || back.fwd[i] != want->fwd[i] ||
            back.rev[i] != want->rev[i]) {
            return COMP_STORE_E_VERIFY;
        }
    }
    return COMP_STORE_OK;
}

/* Copy the live records into the other bank, then make it active. */
static comp_store_result_t compact(const comp_store_layout_t *lay, int from, uint32_t seq,
                                   const comp_table_t *tmp)
{
    static comp_table_t t;
    static uint32_t vers[CORE_AXES];
    static bool have[CORE_AXES];
    const hal_flash_layout_t *l = hal_flash_layout();
    unsigned to = from < 0 ? 0u : (unsigned)from ^ 1u, a;
    uint32_t to_addr = lay->base + (uint32_t)to * lay->bank_bytes;
    uint32_t at = COMP_STORE_HDR_BYTES, off, len, padded;
    uint8_t h[COMP_STORE_HDR_BYTES];
    comp_store_result_t r;

    for (off = 0u; off < lay->bank_bytes; off += l->page_size) {
        if (!hal_flash_erase_page(to_addr + off)) {
            return COMP_STORE_E_FLASH;
        }
    }
    padded = encode(lay, tmp);
    if (padded == 0u) {
        return COMP_STORE_E_ARG;
    }
    if (!hal_flash_write(to_addr + at, rec, padded)) {
        return COMP_STORE_E_FLASH;
    }
    at += padded;
    for (a = 0; a < CORE_AXES; a++) {
        have[a] = false;
        if (a == tmp->axis || from < 0) {
            continue;
        }
        r = find(lay, (unsigned)from, a, &t, &off, &len);
        if (r == COMP_STORE_E_FLASH) {
            return r;
        }
        if (r != COMP_STORE_OK) {
            continue; /* nothing (readable) to carry over */
        }
        padded = pad(len, lay->write_size);
        for (off = len; off < padded; off++) {
            rec[off] = 0xFFu;
        }
        if (at + padded > lay->bank_bytes || !hal_flash_write(to_addr + at, rec, padded)) {
            return COMP_STORE_E_FLASH;
        }
        at += padded;
        have[a] = true;
        vers[a] = t.version;
    }
    r = verify(lay, to, tmp->axis, tmp);
    if (r != COMP_STORE_OK) {
        return r;
    }
    for (a = 0; a < CORE_AXES; a++) {
        if (have[a] &&
            (find(lay, to, a, &t, &off, &len) != COMP_STORE_OK || t.version != vers[a])) {
            return COMP_STORE_E_VERIFY;
        }
    }
    for (off = 0; off < sizeof h; off++) {
        h[off] = 0xFFu;
    }
    put32(h, COMP_STORE_BANK_MAGIC);
    put32(h + 4, from < 0 ? 1u : seq + 1u);
    put32(h + 8, lay->bank_bytes);
    put32(h + 12, crc32_update(CRC32_INIT, h, 12));
    if (!hal_flash_write(to_addr, h, sizeof h)) {
        return COMP_STORE_E_FLASH;
    }
    if (active_bank(lay, &seq) != (int)to) {
        return COMP_STORE_E_VERIFY;
    }
    return COMP_STORE_OK;
}

comp_store_result_t comp_store_write(unsigned axis, const comp_table_t *table, uint32_t *version,
                                     unsigned *slot)
{
    static comp_table_t cur, tmp;
    comp_store_layout_t lay;
    comp_store_result_t r;
    uint32_t seq = 0u, off, len, padded, bank_addr;
    unsigned cb = 0u, bank;
    int act;
    scan_t s;

    if (axis >= CORE_AXES || table == NULL || table->axis != axis ||
        comp_table_check(table) != COMP_OK) {
        return COMP_STORE_E_ARG;
    }
    if (!comp_store_layout(&lay)) {
        return COMP_STORE_E_LAYOUT;
    }
    act = active_bank(&lay, &seq);
    r = act < 0 ? COMP_STORE_EMPTY : current(&lay, axis, &cur, &cb, &off, &len);
    if (r != COMP_STORE_OK && r != COMP_STORE_EMPTY) {
        return r;
    }
    tmp = *table;
    tmp.version = r == COMP_STORE_OK ? cur.version + 1u : 1u;
    padded = encode(&lay, &tmp);
    if (padded == 0u) {
        return COMP_STORE_E_ARG;
    }
    s.end = NO_OFF;
    if (act >= 0) {
        scan_bank(&lay, (unsigned)act, CORE_AXES, 0u, 0u, &s);
        if (s.read_failed) {
            return COMP_STORE_E_FLASH;
        }
    }
    bank_addr = act >= 0 ? lay.base + (uint32_t)act * lay.bank_bytes : 0u;
    if (act >= 0 && s.end != NO_OFF && padded <= lay.bank_bytes - s.end &&
        erased(bank_addr + s.end, padded)) {
        /* append */
        bank = (unsigned)act;
        if (!hal_flash_write(bank_addr + s.end, rec, padded)) {
            return COMP_STORE_E_FLASH;
        }
        r = verify(&lay, bank, axis, &tmp);
    } else {
        bank = act < 0 ? 0u : (unsigned)act ^ 1u;
        r = compact(&lay, act, seq, &tmp);
    }
    if (r != COMP_STORE_OK) {
        return r;
    }
    if (version != NULL) {
        *version = tmp.version;
    }
    if (slot != NULL) {
        *slot = bank;
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
