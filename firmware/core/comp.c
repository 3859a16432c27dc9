/*
 * comp.c - compensation table: correction, ramp, record codec (see comp.h).
 */
#include "comp.h"

#include "crc.h"

/* ---- correction ------------------------------------------------------------- */

/* Index i of the segment [pos[i], pos[i+1]] holding x, for n >= 2 and
 * pos[0] < x < pos[n-1]. */
static uint16_t find_segment(const comp_table_t *t, pos_nm_t x)
{
    uint16_t lo = 0, hi = (uint16_t)(t->n - 1u);
    while ((unsigned)(hi - lo) > 1u) {
        uint16_t mid = (uint16_t)((lo + hi) / 2u);
        if (t->pos[mid] <= x) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

/* c0 + (x - p0) * (c1 - c0) / (p1 - p0), rounded; 0 <= x - p0 <= p1 - p0. */
static int64_t lerp(pos_nm_t p0, pos_nm_t p1, int32_t c0, int32_t c1, pos_nm_t x)
{
    int64_t dc = (int64_t)c1 - (int64_t)c0;
    if (dc == 0) {
        return c0;
    }
    /* |x - p0| <= 2^40, |dc| <= 2^21: the product fits in 64 bits */
    return (int64_t)c0 + fx_div_round64((x - p0) * dc, p1 - p0);
}

int64_t comp_correction(const comp_table_t *t, pos_nm_t x, int32_t w)
{
    int64_t cf, cr;
    if (t == NULL || t->n == 0u) {
        return 0;
    }
    if (w > COMP_W_ONE) {
        w = COMP_W_ONE;
    } else if (w < -COMP_W_ONE) {
        w = -COMP_W_ONE;
    }
    if (t->n == 1u || x <= t->pos[0]) {
        cf = t->fwd[0];
        cr = t->rev[0];
    } else if (x >= t->pos[t->n - 1u]) {
        cf = t->fwd[t->n - 1u];
        cr = t->rev[t->n - 1u];
    } else {
        uint16_t i = find_segment(t, x);
        cf = lerp(t->pos[i], t->pos[i + 1u], t->fwd[i], t->fwd[i + 1u], x);
        cr = lerp(t->pos[i], t->pos[i + 1u], t->rev[i], t->rev[i + 1u], x);
    }
    /* cr + (cf - cr) (w + 1) / 2: |cf - cr| <= 2^21, w + 1 <= 2^31 */
    return cr + fx_round_shift64((cf - cr) * ((int64_t)w + COMP_W_ONE), 31);
}

pos_nm_t comp_correct_w(const comp_table_t *table, pos_nm_t pos_nm, int32_t w_q30)
{
    if (table == NULL || table->n == 0u) {
        return pos_nm;
    }
    return fx_sat_add64(pos_nm, comp_correction(table, pos_nm, w_q30));
}

pos_nm_t comp_correct(const comp_table_t *table, pos_nm_t pos_nm, comp_dir_t dir)
{
    int32_t w;
    if (table == NULL || table->n == 0u) {
        return pos_nm;
    }
    if (table->dir_src != NULL) {
        w = table->dir_src->w_q30;
    } else {
        w = dir == COMP_DIR_POS ? COMP_W_ONE : (dir == COMP_DIR_NEG ? -COMP_W_ONE : 0);
    }
    return comp_correct_w(table, pos_nm, w);
}

comp_result_t comp_table_check(const comp_table_t *t)
{
    uint16_t i;
    if (t == NULL) {
        return COMP_E_ARG;
    }
    if (t->n > COMP_POINTS_MAX) {
        return COMP_E_COUNT;
    }
    if (t->ramp_us > COMP_RAMP_MAX_US) {
        return COMP_E_RANGE;
    }
    for (i = 0; i < t->n; i++) {
        if (t->pos[i] > COMP_POS_LIMIT_NM || t->pos[i] < -COMP_POS_LIMIT_NM ||
            t->fwd[i] > COMP_CORR_MAX_NM || t->fwd[i] < -COMP_CORR_MAX_NM ||
            t->rev[i] > COMP_CORR_MAX_NM || t->rev[i] < -COMP_CORR_MAX_NM) {
            return COMP_E_RANGE;
        }
        if (i > 0u &&
            (t->pos[i] <= t->pos[i - 1u] || t->pos[i] - t->pos[i - 1u] > COMP_SPAN_MAX_NM)) {
            return COMP_E_ORDER;
        }
    }
    return COMP_OK;
}

/* ---- direction ramp ------------------------------------------------------------ */

void comp_ramp_set_time(comp_ramp_t *r, uint32_t ramp_us, uint32_t tick_hz)
{
    uint64_t ticks;
    if (r == NULL) {
        return;
    }
    if (ramp_us > COMP_RAMP_MAX_US) {
        ramp_us = COMP_RAMP_MAX_US;
    }
    /* ticks of the ramp, at least 1; a full swing is 2 * ONE */
    ticks = ((uint64_t)ramp_us * tick_hz + 999999u) / 1000000u;
    if (ticks == 0u) {
        ticks = 1u; /* a full swing in one tick */
    }
    r->step_q30 = (uint32_t)((2u * (uint64_t)COMP_W_ONE + ticks - 1u) / ticks);
}

void comp_ramp_init(comp_ramp_t *r, uint32_t ramp_us, uint32_t tick_hz)
{
    if (r == NULL) {
        return;
    }
    r->w_q30 = 0;
    r->dir = 0;
    comp_ramp_set_time(r, ramp_us, tick_hz);
}

void comp_ramp_step(comp_ramp_t *r, int64_t vel_nm_s)
{
    int64_t w, target;
    if (r == NULL) {
        return;
    }
    if (vel_nm_s > 0) {
        r->dir = 1;
    } else if (vel_nm_s < 0) {
        r->dir = -1;
    }
    if (r->dir == 0) {
        return;
    }
    target = r->dir > 0 ? COMP_W_ONE : -COMP_W_ONE;
    w = r->w_q30;
    if (w < target) {
        w += (int64_t)r->step_q30;
        if (w > target) {
            w = target;
        }
    } else if (w > target) {
        w -= (int64_t)r->step_q30;
        if (w < target) {
            w = target;
        }
    }
    r->w_q30 = (int32_t)w;
}

/* ---- record codec ------------------------------------------------------------------ */

static void put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void put32(uint8_t *p, uint32_t v)
{
    put16(p, (uint16_t)v);
    put16(p + 2, (uint16_t)(v >> 16));
}

static void put64(uint8_t *p, uint64_t v)
{
    put32(p, (uint32_t)v);
    put32(p + 4, (uint32_t)(v >> 32));
}

static uint16_t get16(const uint8_t *p)
{
    return (uint16_t)(p[0] | ((uint16_t)p[1] << 8));
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)get16(p) | ((uint32_t)get16(p + 2) << 16);
}

static uint64_t get64(const uint8_t *p)
{
    return (uint64_t)get32(p) | ((uint64_t)get32(p + 4) << 32);
}

size_t comp_record_len(uint16_t n)
{
    return COMP_RECORD_HDR + (size_t)COMP_POINT_BYTES * n;
}

size_t comp_record_encode(const comp_table_t *t, uint8_t *buf, size_t cap)
{
    size_t len, i;
    uint8_t *p;
    if (t == NULL || buf == NULL || comp_table_check(t) != COMP_OK) {
        return 0;
    }
    len = comp_record_len(t->n);
    if (cap < len) {
        return 0;
    }
    for (i = 0; i < COMP_RECORD_HDR; i++) {
        buf[i] = 0;
    }
    put32(buf, COMP_RECORD_MAGIC);
    put16(buf + 4, COMP_RECORD_FORMAT);
    buf[6] = t->axis;
    buf[7] = t->flags;
    put32(buf + 8, t->version);
    put16(buf + 12, t->n);
    put32(buf + 16, t->ramp_us);
    p = buf + COMP_RECORD_HDR;
    for (i = 0; i < t->n; i++) {
        put64(p, (uint64_t)t->pos[i]);
        put32(p + 8, (uint32_t)t->fwd[i]);
        put32(p + 12, (uint32_t)t->rev[i]);
        p += COMP_POINT_BYTES;
    }
    put32(buf + 20, crc32_update(CRC32_INIT, buf + COMP_RECORD_HDR, len - COMP_RECORD_HDR));
    put32(buf + 28, crc32_update(CRC32_INIT, buf, 28));
    return len;
}

comp_result_t comp_record_header(const uint8_t *buf, size_t len, size_t *total)
{
    uint16_t n;
    if (buf == NULL || len < COMP_RECORD_HDR) {
        return COMP_E_ARG;
    }
    if (get32(buf) != COMP_RECORD_MAGIC || get16(buf + 4) != COMP_RECORD_FORMAT) {
        return COMP_E_MAGIC;
    }
    if (crc32_update(CRC32_INIT, buf, 28) != get32(buf + 28)) {
        return COMP_E_CRC;
    }
    n = get16(buf + 12);
    if (n > COMP_POINTS_MAX) {
        return COMP_E_COUNT;
    }
    if (total != NULL) {
        *total = comp_record_len(n);
    }
    return COMP_OK;
}

comp_result_t comp_record_decode(const uint8_t *buf, size_t len, comp_table_t *table)
{
    size_t total, i;
    const uint8_t *p;
    comp_result_t r;
    if (table == NULL) {
        return COMP_E_ARG;
    }
    r = comp_record_header(buf, len, &total);
    if (r != COMP_OK) {
        return r;
    }
    if (len != total) {
        return COMP_E_COUNT;
    }
    if (crc32_update(CRC32_INIT, buf + COMP_RECORD_HDR, len - COMP_RECORD_HDR) != get32(buf + 20)) {
        return COMP_E_CRC;
    }
    if (buf[7] != 0u) {
        return COMP_E_RANGE; /* flags */
    }
    /* in place (no 2 KiB copy): from here a refusal leaves the table
     * holding the refused record (comp.h) */
    table->axis = buf[6];
    table->flags = buf[7];
    table->version = get32(buf + 8);
    table->n = get16(buf + 12);
    table->ramp_us = get32(buf + 16);
    table->data_crc = get32(buf + 20);
    table->dir_src = NULL;
    p = buf + COMP_RECORD_HDR;
    for (i = 0; i < table->n; i++) {
        table->pos[i] = (pos_nm_t)get64(p);
        table->fwd[i] = (int32_t)get32(p + 8);
        table->rev[i] = (int32_t)get32(p + 12);
        p += COMP_POINT_BYTES;
    }
    return comp_table_check(table);
}
