/*
 * comp_store.c - compensation tables in flash: two banks, a log of records
 * in the active one (see comp_store.h).
 */
#include "comp_store.h"

#include "crc.h"
#include "hal.h"
#include "scratch.h"

#define NO_OFF 0xFFFFFFFFu

static uint8_t rec[COMP_RECORD_MAX + 64u]; /* record + write-unit padding */
/* The one table the store decodes into (finds, loads, read-back checks run
 * one after the other, never nested); main. */
static comp_table_t st;

/* What a read-back must find: version, n and data CRC; for an axis's table
 * also its ramp and points (t; NULL for a blob, whose data CRC covers it). */
typedef struct {
    uint32_t version;
    uint32_t data_crc;
    uint16_t n;
    const comp_table_t *t;
} expect_t;

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

static int active_bank(const comp_store_layout_t *lay, uint32_t *seq);

uint8_t comp_store_active_bank(void)
{
    comp_store_layout_t lay;
    uint32_t seq;
    int b = comp_store_layout(&lay) ? active_bank(&lay, &seq) : -1;
    return b < 0 ? 0xFFu : (uint8_t)b;
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
    if (bank < COMP_STORE_HDR_BYTES +
                   (uint64_t)COMP_STORE_SLOTS * pad(COMP_RECORD_MAX, l->write_size) ||
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

/* A blob record (slot COMP_STORE_SLOT_BLOB): the comp record header, data
 * CRC over the padded data, byte length (offset 14) within the last unit;
 * t gets axis, version, n, data_crc. */
static comp_result_t blob_decode(const uint8_t *buf, size_t len, comp_table_t *t)
{
    size_t total;
    uint16_t blen = (uint16_t)(buf[14] | (buf[15] << 8));
    comp_result_t r = comp_record_header(buf, len, &total);
    if (r != COMP_OK) {
        return r;
    }
    if (len != total || blen > total - COMP_RECORD_HDR ||
        blen + COMP_POINT_BYTES <= total - COMP_RECORD_HDR) {
        return COMP_E_COUNT;
    }
    if (crc32_update(CRC32_INIT, buf + COMP_RECORD_HDR, len - COMP_RECORD_HDR) != get32(buf + 20)) {
        return COMP_E_CRC;
    }
    t->axis = buf[6];
    t->version = get32(buf + 8);
    t->n = (uint16_t)(buf[12] | (buf[13] << 8));
    t->data_crc = get32(buf + 20);
    return COMP_OK;
}

static comp_result_t decode(const uint8_t *buf, size_t len, unsigned slot, comp_table_t *t)
{
    return slot >= COMP_STORE_SLOT_BLOB ? blob_decode(buf, len, t)
                                        : comp_record_decode(buf, len, t);
}

/* Current record of `axis` (a slot: an axis or COMP_STORE_SLOT_BLOB) in
 * `bank` decoded into t (its raw bytes stay in rec[0..*len)); *off_out gets
 * its offset. */
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
        if (decode(rec, s.len, axis, t) == COMP_OK && t->axis == axis) {
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
    r = current(&lay, axis, &st, &b, &off, &len);
    if (r != COMP_STORE_OK) {
        return r;
    }
    *table = st;
    table->dir_src = NULL;
    if (slot != NULL) {
        *slot = b;
    }
    return COMP_STORE_OK;
}

uint32_t comp_store_record_addr(unsigned axis)
{
    comp_store_layout_t lay;
    unsigned b = 0u;
    uint32_t off, len;
    if (axis >= CORE_AXES || !comp_store_layout(&lay) ||
        current(&lay, axis, &st, &b, &off, &len) != COMP_STORE_OK) {
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

/* Encode t with `version` into rec padded to the write unit; 0 when
 * invalid. */
static uint32_t encode(const comp_store_layout_t *lay, const comp_table_t *t, uint32_t version)
{
    size_t len = comp_record_encode(t, rec, COMP_RECORD_MAX);
    uint32_t padded, i;
    if (len == 0u) {
        return 0u;
    }
    put32(rec + 8, version); /* the header CRC covers it */
    put32(rec + 28, crc32_update(CRC32_INIT, rec, 28));
    padded = pad((uint32_t)len, lay->write_size);
    for (i = (uint32_t)len; i < padded; i++) {
        rec[i] = 0xFFu;
    }
    return padded;
}

/* The current record of axis in bank matches `want` (version and content). */
static comp_store_result_t verify(const comp_store_layout_t *lay, unsigned bank, unsigned axis,
                                  const expect_t *want)
{
    const comp_table_t *t = want->t;
    uint32_t off, len, i;
    comp_store_result_t r = find(lay, bank, axis, &st, &off, &len);
    if (r == COMP_STORE_E_FLASH) {
        return r;
    }
    if (t == NULL) {
        return r == COMP_STORE_OK && st.version == want->version && st.n == want->n &&
                       st.data_crc == want->data_crc
                   ? COMP_STORE_OK
                   : COMP_STORE_E_VERIFY;
    }
    if (r != COMP_STORE_OK || st.version != want->version || st.n != t->n ||
        st.ramp_us != t->ramp_us) {
        return COMP_STORE_E_VERIFY;
    }
    for (i = 0; i < st.n; i++) {
        if (st.pos[i] != t->pos[i] || st.fwd[i] != t->fwd[i] || st.rev[i] != t->rev[i]) {
            return COMP_STORE_E_VERIFY;
        }
    }
    return COMP_STORE_OK;
}

/* Slot k of the store: the axes, then the blob. */
static unsigned slot_of(unsigned k)
{
    return k < CORE_AXES ? k : COMP_STORE_SLOT_BLOB + (k - CORE_AXES);
}

/* Copy the live records into the other bank, then make it active. The new
 * record of `slot` (want: what verify expects) is in rec[0..padded). */
static comp_store_result_t compact(const comp_store_layout_t *lay, int from, uint32_t seq,
                                   unsigned slot, uint32_t padded, const expect_t *want)
{
    static uint32_t vers[COMP_STORE_SLOTS];
    static bool have[COMP_STORE_SLOTS];
    const hal_flash_layout_t *l = hal_flash_layout();
    unsigned to = from < 0 ? 0u : (unsigned)from ^ 1u, a;
    uint32_t to_addr = lay->base + (uint32_t)to * lay->bank_bytes;
    uint32_t at = COMP_STORE_HDR_BYTES, off, len;
    uint8_t h[COMP_STORE_HDR_BYTES];
    comp_store_result_t r;

    for (off = 0u; off < lay->bank_bytes; off += l->page_size) {
        if (!hal_flash_erase_page(to_addr + off)) {
            return COMP_STORE_E_FLASH;
        }
    }
    if (!hal_flash_write(to_addr + at, rec, padded)) {
        return COMP_STORE_E_FLASH;
    }
    at += padded;
    for (a = 0; a < COMP_STORE_SLOTS; a++) {
        have[a] = false;
        if (slot_of(a) == slot || from < 0) {
            continue;
        }
        r = find(lay, (unsigned)from, slot_of(a), &st, &off, &len);
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
        vers[a] = st.version;
    }
    r = verify(lay, to, slot, want);
    if (r != COMP_STORE_OK) {
        return r;
    }
    for (a = 0; a < COMP_STORE_SLOTS; a++) {
        if (have[a] && (find(lay, to, slot_of(a), &st, &off, &len) != COMP_STORE_OK ||
                        st.version != vers[a])) {
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

/* Append the record in rec[0..padded) (slot, want: see compact) to the
 * active bank act (-1: none), or compact when it does not fit. */
static comp_store_result_t put_record(const comp_store_layout_t *lay, int act, uint32_t seq,
                                      unsigned slot, uint32_t padded, const expect_t *want,
                                      unsigned *bank)
{
    uint32_t bank_addr = act >= 0 ? lay->base + (uint32_t)act * lay->bank_bytes : 0u;
    scan_t s;
    s.end = NO_OFF;
    if (act >= 0) {
        scan_bank(lay, (unsigned)act, CORE_AXES, 0u, 0u, &s);
        if (s.read_failed) {
            return COMP_STORE_E_FLASH;
        }
    }
    if (act >= 0 && s.end != NO_OFF && padded <= lay->bank_bytes - s.end &&
        erased(bank_addr + s.end, padded)) {
        /* append */
        *bank = (unsigned)act;
        if (!hal_flash_write(bank_addr + s.end, rec, padded)) {
            return COMP_STORE_E_FLASH;
        }
        return verify(lay, *bank, slot, want);
    }
    *bank = act < 0 ? 0u : (unsigned)act ^ 1u;
    return compact(lay, act, seq, slot, padded, want);
}

comp_store_result_t comp_store_write(unsigned axis, const comp_table_t *table, uint32_t *version,
                                     unsigned *slot)
{
    expect_t want;
    comp_store_layout_t lay;
    comp_store_result_t r;
    uint32_t seq = 0u, off, len, padded;
    unsigned cb = 0u, bank = 0u;
    int act;

    if (axis >= CORE_AXES || table == NULL || table->axis != axis ||
        comp_table_check(table) != COMP_OK) {
        return COMP_STORE_E_ARG;
    }
    if (!comp_store_layout(&lay)) {
        return COMP_STORE_E_LAYOUT;
    }
    act = active_bank(&lay, &seq);
    r = act < 0 ? COMP_STORE_EMPTY : current(&lay, axis, &st, &cb, &off, &len);
    if (r != COMP_STORE_OK && r != COMP_STORE_EMPTY) {
        return r;
    }
    want.version = r == COMP_STORE_OK ? st.version + 1u : 1u;
    want.n = table->n;
    want.data_crc = 0u;
    want.t = table;
    padded = encode(&lay, table, want.version);
    if (padded == 0u) {
        return COMP_STORE_E_ARG;
    }
    r = put_record(&lay, act, seq, axis, padded, &want, &bank);
    if (r != COMP_STORE_OK) {
        return r;
    }
    if (version != NULL) {
        *version = want.version;
    }
    if (slot != NULL) {
        *slot = bank;
    }
    return COMP_STORE_OK;
}

comp_store_result_t comp_store_blob_write(const uint8_t *data, uint16_t len, uint32_t *version)
{
    return comp_store_slot_write(COMP_STORE_SLOT_BLOB, data, len, version);
}

comp_store_result_t comp_store_blob_load(uint8_t *data, uint16_t cap, uint16_t *len,
                                         uint32_t *version)
{
    return comp_store_slot_load(COMP_STORE_SLOT_BLOB, data, cap, len, version);
}

static bool blob_slot(unsigned slot)
{
    return slot >= COMP_STORE_SLOT_BLOB &&
           slot < COMP_STORE_SLOT_BLOB + COMP_STORE_SLOTS - CORE_AXES;
}

comp_store_result_t comp_store_slot_write(unsigned slot, const uint8_t *data, uint16_t len,
                                          uint32_t *version)
{
    expect_t want;
    comp_store_layout_t lay;
    comp_store_result_t r;
    uint32_t seq = 0u, off, rlen, padded, i, dlen;
    unsigned cb = 0u, bank = 0u;
    int act;

    if (!blob_slot(slot) || (data == NULL && len > 0u) || len > COMP_STORE_BLOB_MAX) {
        return COMP_STORE_E_ARG;
    }
    if (!comp_store_layout(&lay)) {
        return COMP_STORE_E_LAYOUT;
    }
    act = active_bank(&lay, &seq);
    r = act < 0 ? COMP_STORE_EMPTY : current(&lay, slot, &st, &cb, &off, &rlen);
    if (r != COMP_STORE_OK && r != COMP_STORE_EMPTY) {
        return r;
    }
    /* the comp record header with the blob's slot, its length at 14 */
    want.version = r == COMP_STORE_OK ? st.version + 1u : 1u;
    want.t = NULL;
    want.n = (uint16_t)((len + COMP_POINT_BYTES - 1u) / COMP_POINT_BYTES);
    dlen = (uint32_t)want.n * COMP_POINT_BYTES;
    for (i = 0; i < COMP_RECORD_HDR + dlen; i++) {
        rec[i] = 0u;
    }
    for (i = 0; i < len; i++) {
        rec[COMP_RECORD_HDR + i] = data[i];
    }
    put32(rec, COMP_RECORD_MAGIC);
    rec[4] = (uint8_t)COMP_RECORD_FORMAT;
    rec[6] = (uint8_t)slot;
    put32(rec + 8, want.version);
    rec[12] = (uint8_t)want.n;
    rec[13] = (uint8_t)(want.n >> 8);
    rec[14] = (uint8_t)len;
    rec[15] = (uint8_t)(len >> 8);
    want.data_crc = crc32_update(CRC32_INIT, rec + COMP_RECORD_HDR, dlen);
    put32(rec + 20, want.data_crc);
    put32(rec + 28, crc32_update(CRC32_INIT, rec, 28));
    padded = pad(COMP_RECORD_HDR + dlen, lay.write_size);
    for (i = COMP_RECORD_HDR + dlen; i < padded; i++) {
        rec[i] = 0xFFu;
    }
    r = put_record(&lay, act, seq, slot, padded, &want, &bank);
    if (r == COMP_STORE_OK && version != NULL) {
        *version = want.version;
    }
    return r;
}

comp_store_result_t comp_store_slot_load(unsigned slot, uint8_t *data, uint16_t cap, uint16_t *len,
                                         uint32_t *version)
{
    comp_store_layout_t lay;
    comp_store_result_t r;
    unsigned b = 0u;
    uint32_t off, rlen, i, seq = 0u;
    uint16_t blen;

    if (!blob_slot(slot) || data == NULL || len == NULL) {
        return COMP_STORE_E_ARG;
    }
    if (!comp_store_layout(&lay)) {
        return COMP_STORE_E_LAYOUT;
    }
    r = current(&lay, slot, &st, &b, &off, &rlen);
    if (r == COMP_STORE_EMPTY && active_bank(&lay, &seq) >= 0) {
        scan_t s;
        /* a blob record is there but none decodes: damaged, not absent */
        scan_bank(&lay, b, slot, 0xFFFFFFFFu, NO_OFF, &s);
        if (s.off != NO_OFF) {
            return COMP_STORE_E_VERIFY;
        }
    }
    if (r != COMP_STORE_OK) {
        return r;
    }
    blen = (uint16_t)(rec[14] | (rec[15] << 8));
    if (blen > cap) {
        return COMP_STORE_E_ARG;
    }
    for (i = 0; i < blen; i++) {
        data[i] = rec[COMP_RECORD_HDR + i];
    }
    *len = blen;
    if (version != NULL) {
        *version = st.version;
    }
    return COMP_STORE_OK;
}

comp_store_result_t comp_store_clear(unsigned axis, uint32_t *version)
{
    comp_table_t *empty = scratch_claim(SCRATCH_COMP_STORE, sizeof *empty);
    comp_store_result_t r;
    if (empty == NULL) {
        return COMP_STORE_E_BUSY;
    }
    empty->n = 0u;
    empty->axis = (uint8_t)axis;
    empty->flags = 0u;
    empty->version = 0u;
    empty->ramp_us = 0u;
    empty->dir_src = NULL;
    r = comp_store_write(axis, empty, version, NULL);
    scratch_release(SCRATCH_COMP_STORE);
    return r;
}
