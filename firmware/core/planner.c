/*
 * planner.c - look-ahead planner; see planner.h for the rules.
 */
#include "planner.h"
#include "planner_cont.h"
#include "planner_lim.h"
#include "planner_test.h"

#define NS_PER_S ((int64_t)1000000000)

static bool pl_same(const int64_t *lim);

static inline bool pl_cont(const plan_t *p)
{
    return p->prof.shape == SC_SHAPE_SCURVE_CONTINUOUS;
}

/* plan_push defers its passes on request, for a reach that never falls when
 * its start speed rises (then an entry, once final, stays final whatever
 * comes later): the trapezoid and the at-rest S-curve, not the S-curve
 * (planner.h); always for the continuous S-curve (its pass runs in
 * plan_pop: planner_cont.c). */
static void pl_pass_mode(plan_t *p)
{
    p->defer_passes = (p->deferred && p->prof.shape != SC_SHAPE_SCURVE) || pl_cont(p);
}

static plan_block_t *pl_at(const plan_t *p, uint16_t i)
{
    uint32_t idx = (uint32_t)p->tail + i;
    if (idx >= p->depth) {
        idx -= p->depth;
    }
    return &p->ring[idx];
}

plan_result_t plan_check_profile(const plan_profile_t *prof)
{
    int i;

    if (prof == NULL) {
        return PLAN_E_ARG;
    }
    for (i = 0; i < CORE_AXES; i++) {
        if (prof->v_max[i] < 1000 || prof->v_max[i] > SC_V_LIMIT) {
            return PLAN_E_PROFILE;
        }
        if (prof->a_max[i] < SC_A_MIN || prof->a_max[i] > SC_A_LIMIT) {
            return PLAN_E_PROFILE;
        }
        if (prof->j_max[i] < SC_J_MIN || prof->j_max[i] > SC_J_LIMIT) {
            return PLAN_E_PROFILE;
        }
        /* a/j <= SC_TJ_MAX_NS (only the S-curve uses jerk) */
        if (prof->shape != SC_SHAPE_TRAPEZOID &&
            sc_muldiv(prof->a_max[i], NS_PER_S, prof->j_max[i]) > SC_TJ_MAX_NS) {
            return PLAN_E_PROFILE;
        }
        if (prof->corner_dv[i] < 0 || prof->corner_dv[i] > SC_V_LIMIT) {
            return PLAN_E_PROFILE;
        }
        if (prof->corner_acc[i] < 0 || prof->corner_acc[i] > SC_A_LIMIT) {
            return PLAN_E_PROFILE;
        }
    }
    if (prof->junction_dev_nm < 0 || prof->junction_dev_nm > ((int64_t)1 << 40)) {
        return PLAN_E_PROFILE;
    }
    if (prof->min_block_ns < 0 || prof->min_block_ns > 10 * NS_PER_S) {
        return PLAN_E_PROFILE;
    }
    if (prof->mbt_window < 1 || prof->mbt_window > PLAN_WINDOW_MAX) {
        return PLAN_E_PROFILE;
    }
    if (prof->shape == SC_SHAPE_SCURVE_CONTINUOUS && !plan_cont_profile_ok(prof)) {
        return PLAN_E_PROFILE;
    }
    if (prof->corner > PLAN_CORNER_STOP || prof->shape > SC_SHAPE_SCURVE_CONTINUOUS ||
        (prof->shape == SC_SHAPE_SCURVE_CONTINUOUS && prof->corner == PLAN_CORNER_SMOOTH)) {
        return PLAN_E_PROFILE; /* (planner.h: no smoothed corner with the continuous shape) */
    }
    return PLAN_OK;
}

void plan_reset(plan_t *p, const pos_nm_t pos[CORE_AXES])
{
    int i;

    p->tail = 0;
    p->count = 0;
    p->planned = 0;
    p->fresh = 0;
    for (i = 0; i < CORE_AXES; i++) {
        p->pos[i] = pos[i];
        p->last_ratio_q62[i] = 0;
        p->last_q30[i] = 0;
    }
    p->last_len = 0;
    p->last_vmax = 0;
    p->last_stop = true;
    p->next_entry = 0;
    for (i = 0; i < PLAN_WINDOW_MAX; i++) {
        p->win_len[i] = 0;
    }
    p->win_pos = 0;
    p->win_n = 0;
    p->win_sum = 0;
    p->cruise_v = 0;
    p->cruise_rec = 0;
    plan_cont_reset(p);
}

/* The profile and what plan_push derives from it once (every field that
 * depends on the limits: a profile change must go through here). */
static void pl_derive(plan_t *p, const plan_profile_t *prof)
{
    p->prof = *prof;
    /* continuous S-curve: the blocks' own limits are S-curve limits */
    p->blk_shape =
        (prof->shape == SC_SHAPE_SCURVE_CONTINUOUS) ? (uint8_t)SC_SHAPE_SCURVE : prof->shape;
    pl_pass_mode(p);
    p->v_same = pl_same(prof->v_max);
    p->same_limits = p->v_same && pl_same(prof->a_max) && pl_same(prof->j_max);
    p->jd_amin_dev = sc_mul_sat(plan_cont_derive(p), prof->junction_dev_nm); /* saturated */
    {
        sc_limits_t l0;
        int64_t qc0;
        l0.v_max = prof->v_max[0];
        l0.a_max = prof->a_max[0];
        l0.j_max = prof->j_max[0];
        l0.shape = prof->shape;
        sc_limits_aaj(&l0, &p->aaj0, &qc0);
    }
}

plan_result_t plan_init(plan_t *p, plan_block_t *storage, uint16_t depth,
                        const plan_profile_t *prof, const pos_nm_t start[CORE_AXES])
{
    plan_result_t rc;

    if (p == NULL || storage == NULL || depth == 0 || start == NULL) {
        return PLAN_E_ARG;
    }
    rc = plan_check_profile(prof);
    if (rc != PLAN_OK) {
        return rc;
    }
    p->deferred = false;
    pl_derive(p, prof);
    p->ring = storage;
    p->depth = depth;
    p->jd_fast_off = false;
    plan_reset(p, start);
    return PLAN_OK;
}

plan_result_t plan_set_profile(plan_t *p, const plan_profile_t *prof)
{
    plan_result_t rc;

    if (p == NULL) {
        return PLAN_E_ARG;
    }
    rc = plan_check_profile(prof);
    if (rc != PLAN_OK) {
        return rc;
    }
    pl_derive(p, prof);
    plan_reset(p, p->pos);
    return PLAN_OK;
}

uint16_t plan_count(const plan_t *p)
{
    return p->count;
}

uint16_t plan_free_slots(const plan_t *p)
{
    return (uint16_t)(p->depth - p->count);
}

const plan_block_t *plan_peek(const plan_t *p, uint16_t i)
{
    return (i < p->count) ? pl_at(p, i) : NULL;
}

/* floor(a 2^62 / len) for 0 <= a < 2^63, len > 0 (saturated: INT64_MAX),
 * as sc_muldiv(a, 2^62, len): one 128/64 division of a 2^62 by len. */
static int64_t pl_ratio(int64_t a, int64_t len)
{
    uint64_t q, rem, hi = (uint64_t)a >> 2, lo = (uint64_t)a << 62;

    if (a <= 0) {
        return 0;
    }
    if (hi >= (uint64_t)len) {
        return INT64_MAX;
    }
    q = fx_udiv128(hi, lo, (uint64_t)len, &rem);
    return (q > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)q;
}

int64_t plan_test_muldiv(int64_t a, int64_t b, int64_t c)
{
    return plan_lim_muldiv(a, b, c);
}

int64_t plan_test_ratio(int64_t a, int64_t len)
{
    return pl_ratio(a, len);
}

/* Direction ratios from one reciprocal: with b the bit length of len
 * (1 <= len <= 2^40), inv = floor((2^(63+b) - 1) / len) in [2^63, 2^64)
 * (one 128/64 division), then floor(ad inv / 2^(b+1)) for each 0 <= ad <=
 * len (two to four 32 x 32 multiplies). Error: ad inv / 2^(b+1) is below
 * ad 2^62 / len by ad (1 / len + theta) / 2^(b+1) < 1 (theta < 1, ad <=
 * len < 2^b), so each ratio is floor(ad 2^62 / len) or one less (test:
 * test_ratio_reciprocal against pl_ratio); ad == len gives 2^62 exactly. */
typedef struct {
    uint64_t inv;
    uint64_t pow; /* 2^(63 - b) */
} pl_recip_t;

static inline pl_recip_t pl_recip(int64_t len)
{
    pl_recip_t r;
    uint64_t rem;
    unsigned b = 64u - fx_clz64((uint64_t)len);

    r.pow = (uint64_t)1 << (63u - b);
    if (b <= 31u) {
        /* a 95-bit numerator over a one-word divisor: two 64/32 digit
         * divisions (the same quotient) */
        uint32_t d = (uint32_t)len, q1, q0;
        uint64_t n1 = ((((uint64_t)1 << (b - 1u)) - 1u) << 32) | 0xFFFFFFFFu;
        q1 = fx_udiv64by32(n1, d); /* n1 / 2^32 < d */
        q0 = fx_udiv64by32(((n1 - (uint64_t)q1 * d) << 32) | 0xFFFFFFFFu, d);
        r.inv = ((uint64_t)q1 << 32) | q0;
        return r;
    }
    r.inv = fx_udiv128(((uint64_t)1 << (b - 1u)) - 1u, UINT64_MAX, (uint64_t)len, &rem);
    return r;
}

static int64_t pl_ratio_rec(int64_t ad, int64_t len, const pl_recip_t *r)
{
    uint64_t x;
    uint32_t x0, x1, i0 = (uint32_t)r->inv, i1 = (uint32_t)(r->inv >> 32);
    uint64_t mid;

    if (ad >= len) { /* 0 <= ad <= len; ad == 0 gives 0 below */
        return (int64_t)1 << 62;
    }
    /* (ad inv) >> (b + 1) = high word of (ad 2^(63 - b)) inv, the shifted
     * ad below 2^63 (ad < len < 2^b): no bit is lost */
    if ((r->pow >> 32) != 0u) {
        /* len < 2^31: the shifted ad is x1 2^32 with x1 = ad 2^(31 - b)
         * below 2^31 (the same sum with the low word zero) */
        x1 = (uint32_t)ad * (uint32_t)(r->pow >> 32);
        return (int64_t)((uint64_t)x1 * i1 + (((uint64_t)x1 * i0) >> 32));
    }
    x = (uint64_t)ad * r->pow; /* ad 2^(63 - b) < 2^63: exact */
    x0 = (uint32_t)x;
    x1 = (uint32_t)(x >> 32);
    mid =
        (((uint64_t)x0 * i0) >> 32) + (uint32_t)((uint64_t)x0 * i1) + (uint32_t)((uint64_t)x1 * i0);
    return (int64_t)((uint64_t)x1 * i1 + (((uint64_t)x0 * i1) >> 32) + (((uint64_t)x1 * i0) >> 32) +
                     (mid >> 32));
}

int64_t plan_test_ratio_rec(int64_t a, int64_t len)
{
    pl_recip_t r = pl_recip(len);
    return pl_ratio_rec(a, len, &r);
}

/* f = floor(len 2^31 / dm) or less (a lower bound, within 2^-30 of it):
 * 0 < dm <= len <= 2 dm (the longest of three components), len <= 2^41.
 * Operands above 31 bits are cut to 31 bits, len down and dm up; then
 * f = floor(l 2^31 / d) exactly, without a division helper: with d
 * normalised to [2^30, 2^31), a reciprocal y <= 2^62 / d from one 32-bit
 * UDIV (within 2^-15) and one Newton step (within about 2^-30, still a
 * lower bound), q = l y / 2^31 <= f, and the remainder l 2^31 - q d brings
 * q up to the floor (a few steps at most). */
static uint32_t pl_len_factor(int64_t len, int64_t dm)
{
    unsigned b = 64u - fx_clz64((uint64_t)dm), s;
    uint64_t l = (uint64_t)len, d = (uint64_t)dm, e, rem;
    uint32_t y, q, dn, ln;

    if (b > 31u) {
        l >>= b - 31u;
        d = (d >> (b - 31u)) + 1u;
        if (d == ((uint64_t)1 << 31)) {
            return (uint32_t)l; /* floor(l 2^31 / 2^31) */
        }
    }
    s = (unsigned)__builtin_clz((uint32_t)d) - 1u; /* d < 2^31: d << s in [2^30, 2^31) */
    dn = (uint32_t)d << s;
    ln = (uint32_t)(l << s);                                    /* l / d < 2: below 2^32 */
    y = (0xFFFFFFFFu / ((dn >> 15) + 1u)) << 15;                /* < 2^62 / dn, within 2^-15 */
    e = ((uint64_t)1 << 62) - (uint64_t)dn * y;                 /* >= 0, below 2^47.4 */
    y += (uint32_t)(((uint64_t)y * (uint32_t)(e >> 16)) >> 46); /* y e / 2^62, down */
    q = (uint32_t)(((uint64_t)ln * y) >> 31);
    rem = ((uint64_t)ln << 31) - (uint64_t)q * dn;
    while (rem >= dn) {
        q++;
        rem -= dn;
    }
    return q;
}

uint32_t plan_test_len_factor(int64_t len, int64_t dm)
{
    return pl_len_factor(len, dm);
}

/* floor(lim f / 2^31) for 0 <= lim < 2^63 / 2^32: at most floor(lim len /
 * dm), at least that minus lim / 2^30 + 1 */
static int64_t pl_scale31(int64_t lim, uint32_t f)
{
    uint64_t lo = (uint64_t)(uint32_t)lim * f;
    uint64_t hi = (uint64_t)(uint32_t)((uint64_t)lim >> 32) * f + (lo >> 32);

    return (int64_t)((hi << 1) | ((uint32_t)lo >> 31));
}

/* floor(sqrt(sum delta_i^2)), scaled so that the squares cannot overflow */
static int64_t pl_length(const int64_t *ad)
{
    uint64_t a[CORE_AXES], m = 0, sum = 0;
    unsigned k = 0;
    int i;

    for (i = 0; i < CORE_AXES; i++) {
        m |= (uint64_t)ad[i];
        sum += (uint64_t)(uint32_t)ad[i] * (uint32_t)ad[i]; /* used below 2^29 */
    }
    if (m < ((uint64_t)1 << 29)) { /* the usual case: no scaling */
        return (int64_t)fx_isqrt64(sum);
    }
    sum = 0;
    for (i = 0; i < CORE_AXES; i++) {
        a[i] = (uint64_t)ad[i];
    }
    while (m >= ((uint64_t)1 << 29)) {
        m >>= 1;
        k++;
    }
    for (i = 0; i < CORE_AXES; i++) {
        uint32_t s = (uint32_t)(a[i] >> k); /* below 2^29 */
        sum += (uint64_t)s * s;
    }
    return (int64_t)((uint64_t)fx_isqrt64(sum) << k);
}

/* every axis has the same limit */
static bool pl_same(const int64_t *lim)
{
    int i;

    for (i = 1; i < CORE_AXES; i++) {
        if (lim[i] != lim[0]) {
            return false;
        }
    }
    return true;
}

void plan_test_jd_fast(plan_t *p, bool on)
{
    p->jd_fast_off = !on;
}

/* Junction deviation: true when the corner speed cannot be below vcap, so
 * the full computation below can be skipped. With h = floor(c1 / 2) (q30,
 * h <= 2^30) the computed s_q = isqrt(h 2^30) >= h, a_j >= min_i a_i, and
 * t = floor(a_j s_q / (2^30 - s_q)) >= floor(a_min h / (2^30 - h)) >= K for
 * K = ceil(vcap^2 / dev) whenever a_min h dev >= (vcap^2 + dev) (2^30 - h);
 * then t dev >= vcap^2 and v = isqrt(t dev) >= vcap. The left product is
 * saturated down, the right one up (both exact 128-bit products). */
static bool pl_jd_above(const plan_t *p, int64_t c1, int64_t vcap)
{
    int64_t dev = p->prof.junction_dev_nm;
    uint64_t vv;
    uint32_t h = (uint32_t)(c1 / 2);

    /* (jd_amin_dev > 0 iff dev > 0; vcap - 1 wraps for vcap <= 0) */
    if (p->jd_fast_off || p->jd_amin_dev <= 0 || (uint64_t)vcap - 1u >= (uint64_t)SC_V_LIMIT ||
        c1 > ((int64_t)1 << 31) + 1) {
        return false;
    }
    vv = (uint64_t)(uint32_t)vcap * (uint32_t)vcap; /* vcap < 2^32 */
    vv = (vv > UINT64_MAX - (uint64_t)dev) ? UINT64_MAX : vv + (uint64_t)dev;
    /* the exact comparison of the two 96-bit products */
    return fx_cmp128(fx_umul64x32((uint64_t)p->jd_amin_dev, h),
                     fx_umul64x32(vv, ((uint32_t)1 << 30) - h)) >= 0;
}

/* Junction speed limit between the last queued move and a new one (nm/s,
 * INT64_MAX when the rule sets no limit). *smooth receives the smoothed-corner
 * speed of the junction for the block cap (PLAN_CORNER_SMOOTH only, before
 * the reversal clamp; INT64_MAX when the junction adds no cap: other rules,
 * collinear, reversal, or a zero corner speed, which is a stop). vcap: the
 * caller's other limit (min of both blocks' v_max); the junction-deviation
 * rule returns INT64_MAX early when it provably cannot go below it. */
static int64_t pl_corner(const plan_t *p, const int32_t *w2, int64_t len2, int64_t vcap,
                         int64_t *smooth)
{
    const plan_profile_t *pr = &p->prof;
    const int32_t *w1 = p->last_q30; /* q1_30 of the two directions */
    int64_t du[CORE_AXES], v = INT64_MAX;
    bool straight = true;
    int i;

    *smooth = INT64_MAX;
    for (i = 0; i < CORE_AXES; i++) {
        /* opposite signs, both at least PLAN_REVERSAL_MIN_Q30 in q30 (the
         * q30 value has the sign of the q62 one once it is that large) */
        if ((w1[i] ^ w2[i]) < 0) {
            int32_t a1 = (w1[i] < 0) ? -w1[i] : w1[i], a2 = (w2[i] < 0) ? -w2[i] : w2[i];
            if (a1 >= PLAN_REVERSAL_MIN_Q30 && a2 >= PLAN_REVERSAL_MIN_Q30) {
                return 0; /* axis reversal: stop */
            }
        }
        straight = straight && w1[i] == w2[i];
    }
    if (pr->corner == PLAN_CORNER_STOP) {
        return 0;
    }
    if (straight) {
        return INT64_MAX;
    }
    if (pr->corner != PLAN_CORNER_JD) {
        for (i = 0; i < CORE_AXES; i++) {
            du[i] = (int64_t)fx_uabs64((int64_t)w2[i] - w1[i]); /* |u2 - u1| per axis, q30 */
        }
    }
    switch (pr->corner) {
    case PLAN_CORNER_VSTEP:
        for (i = 0; i < CORE_AXES; i++) {
            if (du[i] != 0) {
                v = fx_min64(v, sc_muldiv(pr->corner_dv[i], (int64_t)1 << 30, du[i]));
            }
        }
        break;
    case PLAN_CORNER_SMOOTH: {
        int64_t l = (p->last_len + len2) / 2;
        for (i = 0; i < CORE_AXES; i++) {
            if (du[i] != 0) {
                int64_t m = sc_muldiv(pr->corner_acc[i], (int64_t)1 << 30, du[i]);
                int64_t v2 = sc_mul_sat(m, l);
                if (v2 < INT64_MAX) {
                    v = fx_min64(v, (int64_t)fx_isqrt64((uint64_t)v2));
                }
            }
        }
        if (v > 0) {
            *smooth = v;
        }
        break;
    }
    default: { /* junction deviation */
        int64_t dot = 0, e2 = 0, e, s, aj, c1, t, v2, de[CORE_AXES];
        for (i = 0; i < CORE_AXES; i++) {
            /* |w2 - w1| < 2^31: a larger step is a reversal, handled above */
            int32_t d = w2[i] - w1[i];
            dot += (int64_t)w1[i] * w2[i];
            e2 += (int64_t)d * d;
        }
        /* 1 - cos(theta) = 1 + u1.u2, q30; sin(theta/2) = sqrt of half of it */
        c1 = ((int64_t)1 << 30) + dot / ((int64_t)1 << 30);
        if (c1 < 2) {
            return 0; /* 180 degrees: reversal */
        }
        if (pl_jd_above(p, c1, vcap)) {
            return INT64_MAX; /* cannot limit: the caller's min is vcap */
        }
        s = (int64_t)fx_isqrt64((uint64_t)(c1 / 2) << 30);
        if (s >= ((int64_t)1 << 30) - 1) {
            return INT64_MAX; /* collinear within resolution */
        }
        e = (int64_t)fx_isqrt64((uint64_t)e2); /* |u2 - u1|, q30 */
        for (i = 0; i < CORE_AXES; i++) {
            de[i] = (int64_t)w2[i] - w1[i];
        }
        aj = plan_axis_limit(pr->a_max, de, e);
        t = sc_muldiv(aj, s, ((int64_t)1 << 30) - s);
        v2 = sc_mul_sat(t, pr->junction_dev_nm);
        if (v2 < INT64_MAX) {
            v = (int64_t)fx_isqrt64((uint64_t)v2);
        }
        break;
    }
    }
    return v;
}

/* Reverse and forward passes over the blocks whose entry can still change:
 * indices planned .. count-1 (index 0, the oldest, is fixed). Blocks from
 * index `fresh` on were queued since the last pass (placeholder entries). */
static void pl_replan(plan_t *p)
{
    uint16_t i, first, from, count = p->count, fresh = p->fresh, planned, depth = p->depth;
    plan_block_t *ring = p->ring, *b, *n;
    uint32_t k; /* ring index of block i */
    int64_t exit = 0;

    if (p->planned < 1) {
        p->planned = 1;
    }
    if (count < 2) {
        p->planned = count;
        p->fresh = count;
        return;
    }
    first = p->planned;
    from = (uint16_t)(first - 1);
    /* reverse: newest back to the first changeable block; an entry that
     * comes out unchanged (of a block planned by an earlier pass) leaves
     * every entry before it unchanged */
    k = (uint32_t)p->tail + count - 1u;
    if (k >= depth) {
        k -= depth;
    }
    for (i = count; i-- > first;) {
        int64_t e;
        b = &ring[k];
        k = (k == 0u) ? depth - 1u : k - 1u;
        /* sc_reach returns its start speed from v_max on: no call */
        e = (exit >= b->lim.v_max && b->len > 0) ? exit : sc_reach_k(exit, &b->lim, &b->rk);
        e = fx_min64(b->v_junction, e);
        if (e == b->v_entry && i < fresh) {
            from = i;
            break;
        }
        b->v_entry = e;
        exit = e;
    }
    p->fresh = count;
    /* forward, from the block before the first changed entry (before it
     * nothing changed, so nothing there became final either): a block whose
     * entry is at its junction limit, or limited by accelerating from its
     * predecessor, is final and so is everything before it */
    planned = p->planned;
    k = (uint32_t)p->tail + from;
    if (k >= depth) {
        k -= depth;
    }
    b = &ring[k];
    for (i = from; i + 1 < count; i++) {
        k = (k + 1u == depth) ? 0u : k + 1u;
        n = &ring[k];
        if (b->v_entry < n->v_entry) {
            int64_t r = sc_reach_k(b->v_entry, &b->lim, &b->rk);
            if (r < n->v_entry) {
                n->v_entry = r;
                planned = (uint16_t)(i + 2);
            }
        }
        if (n->v_entry == n->v_junction) {
            planned = (uint16_t)(i + 2);
        }
        b = n;
    }
    p->planned = planned;
}

void plan_set_deferred(plan_t *p, bool on)
{
    p->deferred = on;
    pl_pass_mode(p);
    if (!p->defer_passes && p->fresh != p->count) {
        pl_replan(p);
    }
}

void plan_update(plan_t *p)
{
    if (p->fresh != p->count && !pl_cont(p)) {
        pl_replan(p);
    }
}

plan_result_t plan_push(plan_t *p, const plan_move_t *m)
{
    plan_block_t *b;
    int64_t d[CORE_AXES], ratio[CORE_AXES], len = 0, vmax, amax, jmax, vj, aaj;
    int32_t u30[CORE_AXES];
    int64_t ad[CORE_AXES], dm; /* |d|, the largest of them */
    int64_t vc = INT64_MAX;    /* smoothed-corner speed of the entry junction */
    uint8_t flags = 0;
    int i;

    if (p == NULL || m == NULL) {
        return PLAN_E_ARG;
    }
    if (m->dwell_ns < 0) {
        return PLAN_E_ARG;
    }
    if (m->dwell_ns == 0) {
        if (m->feed < 1000 || m->feed > SC_V_LIMIT) {
            return PLAN_E_FEED;
        }
        for (i = 0; i < CORE_AXES; i++) {
            const uint64_t lim = (uint64_t)1 << 61;
            /* |target| <= 2^61 and |d| <= SC_LEN_MAX, each as one compare */
            if ((uint64_t)m->target[i] + lim > 2u * lim) {
                return PLAN_E_RANGE;
            }
            d[i] = m->target[i] - p->pos[i];
            if ((uint64_t)d[i] + (uint64_t)SC_LEN_MAX > 2u * (uint64_t)SC_LEN_MAX) {
                return PLAN_E_RANGE;
            }
            ad[i] = (int64_t)fx_uabs64(d[i]);
        }
        len = pl_length(ad);
        if (len == 0) {
            return PLAN_SKIPPED;
        }
        if (len > SC_LEN_MAX) {
            return PLAN_E_RANGE;
        }
    } else if (m->dwell_ns > 1000000 * NS_PER_S) {
        return PLAN_E_ARG;
    }
    if (p->count >= p->depth) {
        return PLAN_E_FULL;
    }

    b = pl_at(p, p->count);
    b->tag = m->tag;
    if (m->dwell_ns > 0) {
        for (i = 0; i < CORE_AXES; i++) {
            b->start[i] = p->pos[i];
            b->end[i] = p->pos[i];
            b->ratio_q62[i] = 0;
        }
        b->len = 0;
        b->dwell_ns = m->dwell_ns;
        b->lim.v_max = 0;
        b->lim.a_max = p->prof.a_max[0];
        b->lim.j_max = p->prof.j_max[0];
        b->lim.shape = p->blk_shape;
        b->cont_cls = 0;
        b->v_junction = 0;
        b->v_corner_in = INT64_MAX;
        sc_reach_k_init(&b->rk, 0, &b->lim, -1, -1);
        b->v_entry = 0;
        b->flags = PLAN_BF_DWELL | PLAN_BF_EXACT_STOP;
        p->last_stop = true;
        p->count++;
        if (!p->defer_passes) {
            pl_replan(p);
        }
        return PLAN_OK;
    }

    /* block limits: axis limits projected on the direction */
    {
        pl_recip_t rc = pl_recip(len);
        for (i = 0; i < CORE_AXES; i++) {
            int64_t r = pl_ratio_rec(ad[i], len, &rc);
            int32_t w = (int32_t)(r >> 32); /* q1_30 of the q2_62 ratio */
            ratio[i] = (d[i] < 0) ? -r : r;
            u30[i] = (d[i] < 0) ? -w : w; /* truncated toward 0 */
        }
    }
    aaj = -1;
    dm = ad[0];
    for (i = 1; i < CORE_AXES; i++) {
        dm = (ad[i] > dm) ? ad[i] : dm;
    }
    if (p->same_limits && dm < ((int64_t)1 << 31)) {
        /* equal limits on every axis: the longest component limits all
         * three (what plan_axis_limit picks), by one factor f = len / dm in
         * q31 (rounded down: each limit at most its exact floor and at
         * most lim / 2^30 + 1 below it); a lower bound of A^2/J from the
         * profile's a^2/j: (a f - 1)^2 / (j f) > a^2 f / j - 2 a / j and
         * a / j <= 3 s. Components of 2^31 nm (2.1 m) and more take the
         * exact path below: pl_len_factor cuts them to 31 bits, which
         * loosens that bound. */
        uint32_t f = pl_len_factor(len, dm);
        vmax = fx_min64(m->feed, pl_scale31(p->prof.v_max[0], f));
        amax = fx_min64(SC_A_LIMIT, pl_scale31(p->prof.a_max[0], f));
        jmax = fx_min64(SC_J_LIMIT, pl_scale31(p->prof.j_max[0], f));
        if (amax < SC_A_LIMIT && jmax < SC_J_LIMIT && p->aaj0 < ((int64_t)1 << 62)) {
            aaj = pl_scale31(p->aaj0, f) - 7;
        }
    } else {
        int64_t lim[2];
        vmax = plan_limits_exact(p, b, d, len, m->feed, lim);
        amax = lim[0];
        jmax = lim[1];
    }
    /* minimum block time: throughput window over this block and the W-1
     * before it */
    if (p->prof.min_block_ns > 0) {
        uint16_t w = p->prof.mbt_window;
        int64_t cap;
        if (p->win_n == w) {
            p->win_sum -= p->win_len[p->win_pos];
        } else {
            p->win_n++;
        }
        p->win_len[p->win_pos] = len;
        p->win_sum += len;
        p->win_pos = (uint16_t)((p->win_pos + 1u) % w);
        cap = sc_muldiv(p->win_sum, NS_PER_S, (int64_t)p->win_n * p->prof.min_block_ns);
        if (cap < 1) {
            cap = 1;
        }
        if (cap < vmax) {
            vmax = cap;
            flags |= PLAN_BF_MBT;
        }
    }
    if (m->flags & PLAN_MOVE_EXACT_STOP) {
        flags |= PLAN_BF_EXACT_STOP;
    }

    /* junction with the previous move */
    if (p->last_stop || p->last_len == 0) {
        vj = 0;
    } else {
        vj = fx_min64(vmax, p->last_vmax);
        if (m->flags & PLAN_MOVE_ARC_JOIN) {
            /* inside an arc the centripetal limit holds along the chord too */
            vmax = fx_min64(vmax, plan_arc_corner(p, u30, d, len, jmax));
            vj = fx_min64(vj, vmax);
        } else {
            vj = fx_min64(vj, pl_corner(p, u30, len, vj, &vc));
        }
        /* smoothed corner: the previous move (the newest queued block, if
         * it has not been popped) now knows its exit corner; its speed is
         * capped by the larger of its two corner speeds. The cap is never
         * below either junction speed, so no planned entry changes. */
        if (vc < INT64_MAX && p->count > 0) {
            plan_block_t *q = pl_at(p, (uint16_t)(p->count - 1));
            int64_t cap = (q->v_corner_in > vc) ? q->v_corner_in : vc;
            if (cap < q->lim.v_max) {
                q->lim.v_max = cap;
                q->flags = (uint8_t)((q->flags & ~PLAN_BF_MBT) | PLAN_BF_CORNER);
            }
        }
    }

    for (i = 0; i < CORE_AXES; i++) {
        b->start[i] = p->pos[i];
        b->end[i] = m->target[i];
        b->ratio_q62[i] = ratio[i];
        p->pos[i] = m->target[i];
        p->last_ratio_q62[i] = ratio[i];
        p->last_q30[i] = u30[i];
    }
    b->len = len;
    b->dwell_ns = 0;
    b->lim.v_max = vmax;
    b->lim.a_max = amax;
    b->lim.j_max = jmax;
    b->lim.shape = p->blk_shape;
    if (pl_cont(p)) {
        /* the continuous S-curve reaches over runs, not blocks: no rk */
    } else if (aaj > 0) {
        /* lower bound; the exact values when needed */
        sc_reach_k_init(&b->rk, len, &b->lim, aaj, -1);
    } else {
        int64_t q, qc;
        sc_limits_aaj(&b->lim, &q, &qc);
        sc_reach_k_init(&b->rk, len, &b->lim, q, qc);
    }
    b->v_junction = vj;
    if (!p->same_limits && pl_cont(p)) {
        plan_cont_class(p, b);
    }
    b->v_corner_in = vc;
    b->v_entry = (p->count == 0) ? fx_min64(p->next_entry, vj) : 0;
    b->flags = flags;
    p->last_len = len;
    p->last_vmax = vmax;
    p->last_stop = (flags & PLAN_BF_EXACT_STOP) != 0;
    p->count++;
    if (!p->defer_passes) {
        pl_replan(p);
    }
    return PLAN_OK;
}

plan_result_t plan_pop(plan_t *p, plan_seg_t *out)
{
    plan_block_t *b;
    int64_t exit;
    int i;

    if (p == NULL || out == NULL) {
        return PLAN_E_ARG;
    }
    if (p->count == 0) {
        return PLAN_E_EMPTY;
    }
    if (p->count > 1 && p->planned < 2 && p->fresh != p->count && !pl_cont(p)) {
        pl_replan(p); /* deferred passes: the next entry is not final yet */
    }
    b = pl_at(p, 0);
    exit = (p->count > 1) ? pl_at(p, 1)->v_entry : 0;
    for (i = 0; i < CORE_AXES; i++) {
        out->start[i] = b->start[i];
        out->end[i] = b->end[i];
        out->ratio_q62[i] = b->ratio_q62[i];
    }
    out->len = b->len;
    out->dwell_ns = b->dwell_ns;
    out->tag = b->tag;
    out->flags = b->flags;
    if (b->dwell_ns > 0) {
        int ph;
        for (ph = 0; ph < SC_PHASES; ph++) {
            out->prof.t_ns[ph] = 0;
        }
        out->prof.v0 = out->prof.vp = out->prof.v1 = 0;
        out->prof.len = 0;
        out->prof.total_ns = 0;
        out->prof.s_end_q16 = 0;
        out->total_ns = b->dwell_ns;
    } else if (pl_cont(p)) {
        plan_cont_pop(p, out);
    } else {
        if (b->v_entry == exit && exit >= 1 && exit >= b->lim.v_max) {
            /* cruise only: the reciprocal of its speed kept while it stays */
            if (p->cruise_v != exit) {
                p->cruise_v = exit;
                p->cruise_rec = sc_cruise_recip(exit);
            }
            sc_plan_cruise_rec(&out->prof, b->len, exit, &b->lim, p->cruise_rec);
        } else {
            sc_plan(&out->prof, b->len, b->v_entry, exit, &b->lim);
        }
        out->total_ns = out->prof.total_ns;
    }
    p->tail = (uint16_t)((p->tail + 1u) % p->depth);
    p->count--;
    if (p->planned > 0) {
        p->planned--;
    }
    if (p->fresh > 0) {
        p->fresh--;
    }
    if (p->planned == 0 && p->count > 0) {
        p->planned = 1; /* the new oldest block's entry is fixed */
    }
    p->next_entry = 0;
    return PLAN_OK;
}

int64_t plan_queued_ns(const plan_t *p)
{
    int64_t sum = 0;
    uint16_t i;

    if (pl_cont(p)) {
        return plan_cont_queued_ns(p);
    }
    for (i = 0; i < p->count; i++) {
        const plan_block_t *b = pl_at(p, i);
        if (b->dwell_ns > 0) {
            sum += b->dwell_ns;
        } else {
            sc_profile_t pr;
            int64_t exit = (i + 1 < p->count) ? pl_at(p, (uint16_t)(i + 1))->v_entry : 0;
            sc_plan(&pr, b->len, b->v_entry, exit, &b->lim);
            sum += pr.total_ns;
        }
    }
    return sum;
}
