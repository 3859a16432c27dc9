/*
 * scurve_reach.c - the reach of scurve.h (sc_reach*: the highest speed from
 * which a distance still allows a given speed change): the distance checks,
 * the estimate-and-check path, the closed form of the reduced S-curve and
 * the bracketing Newton steps the others fall back to.
 */
#include "scurve.h"
#include "scurve_internal.h"
#include "scurve_test.h"

#include "fixmath.h"

#include <stddef.h>

static bool sc_fits_off; /* test hook: sc_test_dist_fits */

void sc_test_dist_fits(bool on)
{
    sc_fits_off = !on;
}

/* Whether sc_dist_q(lo, hi, lim, qc) fits in dq (nm * 2^16), i.e. the
 * reach's test `dd < INT64_MAX / 65536 && dd * 65536 <= dq`, decided by
 * one exact 128-bit comparison where sc_dist_q takes its reduced exact
 * branch: lim already resolved to the S-curve, 0 <= lo < hi,
 * hi - lo < qc, lo + hi <= SC_SQRT_INT64_MAX and df = floor(dq / 2^16)
 * < 2^31. There sc_dist_q returns ceil(D), D = (lo + hi) sqrt((hi - lo) / J)
 * (the exact ceiling whenever its quotient does not saturate, never below
 * it otherwise), so it fits iff D <= df iff (lo + hi)^2 (hi - lo) <=
 * df^2 J; and then (lo + hi)^2 (hi - lo) / J <= df^2 < 2^62, so the
 * quotient did not saturate. Outside these ranges sc_dist_q decides. */
static bool sc_dist_fits(int64_t lo, int64_t hi, int64_t dq, const sc_limits_t *lim, int64_t qc)
{
    int64_t dd, df = (dq > 0) ? dq / 65536 : 0; /* floor for dq >= 0 */

    if (!sc_fits_off && lim->shape == SC_SHAPE_SCURVE && lo >= 0 && hi > lo && qc >= 0 &&
        hi - lo < qc && lo + hi <= SC_SQRT_INT64_MAX && dq >= 0 && df < ((int64_t)1 << 31)) {
        uint64_t s = (uint64_t)(lo + hi);
        return sc_cmp_products(s * s, (uint64_t)(hi - lo), (uint64_t)(df * df),
                               (uint64_t)lim->j_max) <= 0;
    }
    dd = sc_dist_q(lo, hi, lim, qc);
    return dd < INT64_MAX / 65536 && dd * 65536 <= dq;
}

/* J w^2 (nm/s * 2^16) for a half-segment time w (ns), floor or ceil */
static int64_t sc_jw2(int64_t j, int64_t w, bool up)
{
    if (up) {
        return sc_muldiv_ceil(sc_muldiv_ceil(j * 65536, w, (int64_t)NS), w, (int64_t)NS);
    }
    return sc_muldiv(sc_muldiv(j * 65536, w, (int64_t)NS), w, (int64_t)NS);
}

/* ---- S-curve reach without the acceleration limit: estimate and check --------
 * An approximate root is computed with a small normalised binary format
 * (sc_mf_t: m * 2^e, 32-bit mantissa with bit 31 set, or m == 0 for 0;
 * each operation truncates, relative error below 2^-30), then lowered by a
 * margin and confirmed with sc_dist (the exact, rounded-up distance).
 * Only the confirmation decides what is returned, so the estimate's
 * arithmetic needs no error analysis for safety, only for tightness. */
typedef struct {
    uint32_t m;
    int32_t e;
} sc_mf_t;

/* x * 2^e0 */
static sc_mf_t sc_mf(uint64_t x, int32_t e0)
{
    sc_mf_t r;
    int32_t s;

    if (x == 0u) {
        r.m = 0u;
        r.e = 0;
        return r;
    }
    s = (int32_t)fx_bitlen64(x) - 32; /* bits above the 32-bit mantissa */
    r.m = (uint32_t)((s >= 0) ? (x >> s) : (x << -s));
    r.e = e0 + s;
    return r;
}

static sc_mf_t sc_mf_mul(sc_mf_t a, sc_mf_t b)
{
    return sc_mf((uint64_t)a.m * b.m, a.e + b.e);
}

static sc_mf_t sc_mf_div(sc_mf_t a, sc_mf_t b) /* b != 0 */
{
    return sc_mf(((uint64_t)a.m << 32) / b.m, a.e - b.e - 32);
}

/* a + b (sign +1) or a - b (sign -1, a >= b: else 0), both >= 0 */
static sc_mf_t sc_mf_add(sc_mf_t a, sc_mf_t b, int sign)
{
    uint64_t x, y;
    int32_t d;

    if (b.m == 0u) {
        return a;
    }
    if (a.m == 0u) {
        return (sign > 0) ? b : a;
    }
    d = a.e - b.e;
    if (d >= 0) {
        x = (uint64_t)a.m << 30;
        y = (d >= 62) ? 0u : ((uint64_t)b.m << 30) >> d;
        d = a.e;
    } else {
        x = (-d >= 62) ? 0u : ((uint64_t)a.m << 30) >> -d;
        y = (uint64_t)b.m << 30;
        d = b.e;
    }
    if (sign > 0) {
        return sc_mf(x + y, d - 30);
    }
    return sc_mf((x > y) ? x - y : 0u, d - 30);
}

/* a > b for values >= 0 */
static bool sc_mf_gt(sc_mf_t a, sc_mf_t b)
{
    if (a.m == 0u || b.m == 0u) {
        return a.m > b.m;
    }
    return (a.e != b.e) ? (a.e > b.e) : (a.m > b.m);
}

/* value as int64 (>= 0, INT64_MAX above 2^62) */
static int64_t sc_mf_int(sc_mf_t a)
{
    if (a.m == 0u || a.e <= -32) {
        return 0;
    }
    if (a.e >= 31) {
        return INT64_MAX;
    }
    return (int64_t)((a.e >= 0) ? ((uint64_t)a.m << a.e) : ((uint64_t)a.m >> -a.e));
}

/* The reduced S-curve reach: the half-segment time w (s) solves
 * J w^3 + 2 v w = d (d = dq / 2^16 nm) and the speed gained is J w^2.
 * From rest w = cbrt(d / J): x = dq 2^k / J is formed with about 60 bits
 * (k such that 16 + k is a multiple of 3; its top 32 bits exact, from the
 * format's division), so c = floor(cbrt(x)) = w 2^((16+k)/3) has 20 bits
 * (1e-6). With v > 0, four Newton steps from
 * the upper bound min(d / 2v, cbrt(d / J)) (within a factor 1.26 of the
 * root; quadratic convergence to the format's resolution). The speed is
 * lowered by 1/4096 + 2 nm/s, capped at v_max, and returned only if
 * sc_dist confirms it (sc_dist(v, result) <= d, the guarantee of
 * sc_reach); otherwise -1 and the caller takes the bracketing path. Also
 * -1 when the estimate reaches A^2/J (the acceleration limit applies). */
static int64_t sc_reach_fast(int64_t v, int64_t dq, int64_t q, int64_t qc, const sc_limits_t *lim)
{
    int64_t j = lim->j_max, x, dv, r;
    unsigned sh, bj, m, e;
    sc_mf_t w, mj, md, m2v;
    int k;

    if (j < 32 || dq <= 0) { /* j >= 32: the exponent m below stays >= 1 */
        return -1;
    }
    sh = 63u - fx_bitlen64((uint64_t)dq);
    bj = fx_bitlen64((uint64_t)j);
    /* x = (dq << sh) * 2^m / J, about 2^60; 16 + sh + m = 3 e */
    m = bj - 3u;
    m -= (16u + sh + m) % 3u;
    e = (16u + sh + m) / 3u;
    mj = sc_mf((uint64_t)j, 0);
    x = sc_mf_int(sc_mf_div(sc_mf((uint64_t)dq << sh, (int32_t)m), mj)); /* 32 bits exact */
    if (x <= 0 || x == INT64_MAX) {
        return -1;
    }
    w = sc_mf(fx_icbrt64((uint64_t)x), -(int32_t)e);
    if (v > 0) {
        sc_mf_t wv;
        md = sc_mf((uint64_t)dq, -16);
        m2v = sc_mf((uint64_t)v, 1);
        wv = sc_mf_div(md, m2v);
        if (sc_mf_gt(w, wv)) {
            w = wv;
        }
        for (k = 0; k < 4; k++) {
            /* f = (J w^2 + 2 v) w - d >= 0 above the root, f' = 3 J w^2 + 2 v */
            sc_mf_t jw2 = sc_mf_mul(mj, sc_mf_mul(w, w));
            sc_mf_t fw = sc_mf_mul(sc_mf_add(jw2, m2v, 1), w);
            sc_mf_t fp = sc_mf_add(sc_mf_mul(jw2, sc_mf(3u, 0)), m2v, 1);
            if (!sc_mf_gt(fw, md)) {
                break;
            }
            w = sc_mf_add(w, sc_mf_div(sc_mf_add(fw, md, -1), fp), -1);
        }
    }
    dv = sc_mf_int(sc_mf_mul(mj, sc_mf_mul(w, w)));
    if (dv >= q) {
        return -1; /* the acceleration limit is reached: not this case */
    }
    dv -= dv / 4096 + 2;
    if (dv <= 0) {
        return -1;
    }
    r = (dv >= lim->v_max - v) ? lim->v_max : v + dv;
    return sc_dist_fits(v, r, dq, lim, qc) ? r : -1;
}

/* ---- S-curve reach without the acceleration limit: closed form ----------------
 * Where sc_dist_fits decides by one comparison (df = floor(d) < 2^31 nm,
 * lo + hi <= SC_SQRT_INT64_MAX, hi - lo below A^2/J), the speed hi is
 * reachable from lo iff (lo + hi)^2 (hi - lo) <= K = df^2 J. With the start
 * speed v and the gain x = hi - v: x (2v + x)^2 <= K. K is formed exactly
 * (128 bits); the estimates below use its top 32 bits.
 *   From rest: x = cbrt(K): a seed from a 56-entry table (within 2 %), one
 *   Halley step (cubic convergence: within 5.4e-6), lowered by 2^-16 of
 *   itself + 1 nm/s.
 *   From v > 0: with c = K / (8 v^3), x = 2v t where t (1 + t)^2 = c, and
 *   t = c R with R (1 + c R)^2 = 1. For c <= 3/8 (a gain up to about 0.29
 *   of 2v) R is the Pade [2/2] approximant (11 + 54c + 26c^2) /
 *   (11 + 76c + 101c^2) (within 5e-3 there) refined by one Newton step
 *   (within 4e-6 in exact arithmetic), in 32-bit fixed point (c with a
 *   32-bit mantissa, R in q30: about 1e-6 more); lowered by 2^-14 of itself
 *   + 2 nm/s. v_max is tried first (one comparison).
 * Either result, capped at v_max, is returned only if the exact comparison
 * confirms it (otherwise, and for larger c, the paths below run): gain at
 * least 1 - 2^-14 - 2e-5 of the exact root, minus 3 nm/s (test_scurve
 * test_reach_closed_form against the exact reach). d below 8192 nm is left
 * to the other paths: the comparison uses whole nm, and the fraction of d
 * would cost up to 2/3 of 1/8192 of the gain. */

static bool sc_closed_off; /* test hook: sc_test_reach_closed */

void sc_test_reach_closed(bool on)
{
    sc_closed_off = !on;
}

/* (lo + hi)^2 (hi - lo) <= k for lo < hi, lo + hi <= SC_SQRT_INT64_MAX */
static inline bool sc_fits_k(uint32_t lo, uint32_t hi, fx_u128_t k)
{
    uint32_t s = lo + hi, g = hi - lo;

    return fx_cmp128(fx_umul64x32((uint64_t)s * s, g), k) <= 0;
}

/* shortest distance for the closed form: 8192 nm (it uses whole nm, the
 * fraction of d costs up to 2/3 of 1/8192 of the gain) */
#define SC_CLOSED_DMIN ((int64_t)8192)

/* cbrt((i + 1/2) 2^57), i = 8..63: the seed of sc_cbrt_k (within 2 %) */
static const uint32_t sc_cbrt_seed[56] = {
    1069981u, 1110396u, 1148065u, 1183412u, 1216765u, 1248383u, 1278476u, 1307215u,
    1334744u, 1361181u, 1386630u, 1411177u, 1434899u, 1457861u, 1480122u, 1501732u,
    1522738u, 1543180u, 1563094u, 1582514u, 1601468u, 1619983u, 1638085u, 1655796u,
    1673135u, 1690123u, 1706775u, 1723109u, 1739139u, 1754878u, 1770341u, 1785537u,
    1800480u, 1815178u, 1829642u, 1843881u, 1857904u, 1871718u, 1885331u, 1898750u,
    1911982u, 1925034u, 1937910u, 1950618u, 1963163u, 1975549u, 1987782u, 1999866u,
    2011806u, 2023606u, 2035269u, 2046801u, 2058204u, 2069482u, 2080638u, 2091676u};

/* cbrt(K) for K = mk 2^e, mk in [2^31, 2^32) (K's top 32 bits), within
 * 6e-6 (not a bound: the caller confirms). With r = (e - 29) mod 3,
 * m = mk 2^(29 + r) is in [2^60, 2^63) and K = m 2^(3s); the seed from m's
 * top 6 bits (within 2 %), then one Halley step y (y^3 + 2m) / (2y^3 + m)
 * (cubic convergence: 2 % -> 5.4e-6), the ratio in q31 from one 64/32
 * division. */
static int64_t sc_cbrt_k(uint32_t mk, int32_t e)
{
    int32_t r = (e - 29) % 3, s;
    uint64_t m, y3, num, den;
    uint32_t y, q;

    r += (r < 0) ? 3 : 0;
    s = (e - 29 - r) / 3;
    m = (uint64_t)mk << (29 + r);
    y = sc_cbrt_seed[(m >> 57) - 8u];
    y3 = ((uint64_t)y * y) * y;                    /* below 2^63 */
    num = (y3 >> 2) + (m >> 1);                    /* (y^3 + 2m) / 4, below 2^63 */
    den = (y3 >> 1) + (m >> 2);                    /* (2y^3 + m) / 4 */
    q = fx_udiv64by32(num, (uint32_t)(den >> 31)); /* about 2^31 */
    y = (uint32_t)(((uint64_t)y * q) >> 31);
    return (s >= 0) ? ((int64_t)y << s) : (int64_t)(y >> (unsigned)(-s));
}

/* c = X / (2v) above which the closed form gives way to the estimate: 3/8 */
#define SC_CLOSED_CMAX_Q32 ((uint32_t)3 << 29)

void sc_reach_k_init(sc_reach_k_t *rk, int64_t d, const sc_limits_t *lim, int64_t q, int64_t qc)
{
    fx_u128_t k;
    unsigned bk;

    rk->d = d;
    rk->q = q;
    rk->qc = qc;
    rk->bk = 0;
    if (lim->shape != SC_SHAPE_SCURVE || q <= 0 || d < SC_CLOSED_DMIN || d >= ((int64_t)1 << 31)) {
        return; /* not the closed form's case */
    }
    k = fx_umul64((uint64_t)(d * d), (uint64_t)lim->j_max); /* < 2^109 */
    bk = (k.hi != 0u) ? 64u + fx_bitlen64(k.hi) : fx_bitlen64(k.lo);
    if (bk >= 96u) {
        rk->mk = (uint32_t)(k.hi >> (bk - 96u));
    } else if (bk > 64u) {
        rk->mk = (uint32_t)((k.hi << (96u - bk)) | (k.lo >> (bk - 32u)));
    } else if (bk > 32u) {
        rk->mk = (uint32_t)(k.lo >> (bk - 32u));
    } else {
        rk->mk = (uint32_t)(k.lo << (32u - bk));
    }
    rk->k_hi = k.hi;
    rk->k_lo = k.lo;
    rk->bk = (int32_t)bk;
}

/* the closed form with K prepared (rk->bk > 0); v >= 0 */
static inline int64_t sc_reach_closed_k(int64_t v, const sc_reach_k_t *rk, int64_t q,
                                        const sc_limits_t *lim)
{
    int64_t vmax = lim->v_max, x;
    uint32_t mk = rk->mk, mv, m3, qc, c, c24, c2, num, den, r30, t30, u, u2, ru, hp;
    int32_t h, corr, ec;
    unsigned bk = (unsigned)rk->bk, bv, b3;
    uint64_t n;
    fx_u128_t k;

    if (vmax > SC_SQRT_INT64_MAX - v || v >= vmax) {
        return -1;
    }
    k.hi = rk->k_hi;
    k.lo = rk->k_lo;
    if (v == 0) {
        x = sc_cbrt_k(mk, (int32_t)bk - 32);
        x -= (x >> 16) + 1;
        if (x <= 0 || x >= q) {
            return -1;
        }
        x = (x >= vmax) ? vmax : x;
        return sc_fits_k(0u, (uint32_t)x, k) ? x : -1;
    }
    if (vmax - v < q && sc_fits_k((uint32_t)v, (uint32_t)vmax, k)) {
        return vmax; /* the cap itself is reachable: no root to find */
    }
    /* 32-bit mantissas: K ~ mk 2^(bk - 32) (above), v^3 ~ m3 2^e3 */
    n = (uint64_t)(uint32_t)v * (uint32_t)v;
    bv = fx_bitlen64(n);
    mv = (bv > 32u) ? (uint32_t)(n >> (bv - 32u)) : (uint32_t)(n << (32u - bv));
    n = (uint64_t)mv * (uint32_t)v; /* v^3 = n 2^(bv - 32) */
    b3 = fx_bitlen64(n);
    m3 = (b3 > 32u) ? (uint32_t)(n >> (b3 - 32u)) : (uint32_t)(n << (32u - b3));
    /* c = K / (8 v^3) ~ qc 2^ec, qc = floor(mk 2^31 / m3) in [2^30, 2^32);
     * c in q32 is qc 2^(ec + 32), so c <= 3/8 needs ec + 32 <= 0 */
    qc = fx_udiv64by32((uint64_t)mk << 31, m3);
    ec = (int32_t)bk - (int32_t)b3 - (int32_t)bv - 2;
    if (ec + 32 > 0) {
        return -1; /* c >= 1 */
    }
    c = (-(ec + 32) < 32) ? qc >> -(ec + 32) : 0u;
    if (c > SC_CLOSED_CMAX_Q32 || -ec - 1 > 63) {
        return -1;
    }
    /* Pade [2/2] of R(c) in q16 (c in q24), then one Newton step in q30 */
    c24 = c >> 8;
    c2 = (uint32_t)(((uint64_t)c24 * c24) >> 24);
    num = (11u << 24) + 54u * c24 + 26u * c2;
    den = (11u << 24) + 76u * c24 + 101u * c2;
    r30 = ((num << 2) / (den >> 14)) << 14;
    t30 = (uint32_t)(((uint64_t)c * r30) >> 32); /* t = c R */
    u = (1u << 30) + t30;
    u2 = (uint32_t)(((uint64_t)u * u) >> 30);
    ru = (uint32_t)(((uint64_t)r30 * u2) >> 30);
    h = (int32_t)(ru - (1u << 30));                                 /* R (1 + t)^2 - 1 */
    hp = (uint32_t)(((uint64_t)u * ((1u << 30) + 3u * t30)) >> 30); /* (1 + t)(1 + 3t) */
    if (h >= (1 << 24) || h <= -(1 << 24)) {
        return -1;
    }
    corr = (h * 128) / (int32_t)(hp >> 16); /* q23 */
    r30 = (uint32_t)((int32_t)r30 - corr * 128);
    /* x = 2 v t = 2 v c R = v (qc R) 2^(ec + 1), qc R below 2^32 */
    n = ((uint64_t)qc * r30) >> 30;
    x = (int64_t)(((uint64_t)(uint32_t)v * (uint32_t)n) >> (-ec - 1));
    if (x >= q) {
        return -1; /* the acceleration limit applies */
    }
    if (x >= vmax - v) {
        return -1; /* the cap was not reachable: an estimate error */
    }
    x -= (x >> 14) + 2;
    if (x <= 0) {
        return -1;
    }
    return sc_fits_k((uint32_t)v, (uint32_t)(v + x), k) ? v + x : -1;
}

/* The reach by the closed form, or -1 (the caller's other paths decide).
 * q: floor(A^2/J) or any lower bound of it. */
static int64_t sc_reach_closed(int64_t v, int64_t dq, int64_t q, const sc_limits_t *lim)
{
    sc_reach_k_t rk;

    if (sc_closed_off || v < 0) {
        return -1;
    }
    sc_reach_k_init(&rk, dq >> 16, lim, q, -1);
    return (rk.bk > 0) ? sc_reach_closed_k(v, &rk, q, lim) : -1;
}

int64_t sc_test_reach_closed_only(int64_t v, int64_t d, const sc_limits_t *lim)
{
    int64_t q, qc;

    sc_aaj(lim->a_max, lim->j_max, &q, &qc);
    if (d <= 0 || d > INT64_MAX / 65536 || v >= lim->v_max) {
        return -1;
    }
    return sc_reach_closed(v, d * 65536, q, lim);
}

/* sc_reach with the distance in nm * 2^16; q, qc: floor and ceil of A^2/J
 * (qc < 0: computed here) */
static bool sc_fast_off; /* test hook: sc_reach_bracket */

int64_t sc_reach_q16(int64_t v, int64_t dq, const sc_limits_t *lim, int64_t q, int64_t qc,
                     bool closed)
{
    int64_t vmax = lim->v_max, a = lim->a_max, j = lim->j_max, dv;
    sc_limits_t tmp;

    if (v < 0) {
        v = 0;
    }
    lim = sc_resolve(lim, v, &tmp);
    if (dq <= 0 || v >= vmax) {
        return v;
    }
    if (lim->shape == SC_SHAPE_TRAPEZOID) {
        /* v^2 + 2 A d */
        fx_u128_t x = sc_mul((uint64_t)(2 * a), (uint64_t)dq);
        uint64_t r;
        x.lo = (x.lo >> 16) | (x.hi << 48);
        x.hi >>= 16;
        r = fx_isqrt128(fx_add128(sc_mul((uint64_t)v, (uint64_t)v), x));
        return (r >= (uint64_t)vmax) ? vmax : fx_max64(v, (int64_t)r);
    }
    {
        int64_t dfull;

        if (q < 0) {
            sc_aaj(a, j, &q, &qc); /* floor and ceil of A^2/J */
        }
        dv = (sc_fast_off || !closed) ? -1 : sc_reach_closed(v, dq, q, lim);
        if (dv > 0) {
            return dv; /* lower bound by construction or confirmed */
        }
        if (qc < 0) {
            sc_aaj(a, j, &q, &qc); /* q was a lower bound: the exact values */
        }
        if (v > 0 && sc_dist_fits(v, vmax, dq, lim, qc)) {
            /* from rest the estimate below checks the cap itself */
            return vmax; /* the cap itself is reachable: no root to find */
        }
        dv = sc_fast_off ? -1 : sc_reach_fast(v, dq, q, qc, lim);
        if (dv > 0) {
            return dv; /* confirmed by sc_dist, at most vmax */
        }
        dfull = (q < vmax) ? sc_dist_q(v, v + q, lim, qc) : INT64_MAX;

        if (dfull < INT64_MAX / 65536 && dq >= dfull * 65536) {
            /* acceleration limit reached: stable root of the quadratic */
            int64_t vaj = sc_muldiv_ceil(v * 65536, a, j); /* v A / J, nm * 2^16 */
            int64_t num = dq - vaj, t1 = 2 * v - q, t2 = 2 * v - qc, t, den;
            fx_u128_t y, ad = sc_mul((uint64_t)(8 * a), (uint64_t)dq);
            fx_u128_t one = {0u, 1u};
            ad.lo = (ad.lo >> 16) | (ad.hi << 48);
            ad.hi >>= 16;
            ad = fx_add128(ad, one); /* 8 A d, rounded up */
            if (t1 < 0) {
                t1 = -t1;
            }
            if (t2 < 0) {
                t2 = -t2;
            }
            t = fx_max64(t1, t2);
            y = fx_add128(sc_mul((uint64_t)t, (uint64_t)t), ad);
            den = (int64_t)sc_isqrt128_ceil(y) + 2 * v + qc;
            dv = (num > 0) ? sc_muldiv(4 * a, num, den * 65536) : q;
        } else {
            /* reduced: J w^3 + 2 v w = d, w = sqrt(dv / J) in ns */
            int64_t w = INT64_MAX, x;
            int k;
            if (v > 0) {
                w = sc_muldiv_ceil(dq, (int64_t)NS, 2 * v * 65536);
            }
            x = sc_muldiv_ceil(dq, (int64_t)1000000000000000, j * 65536); /* (10 us)^3 */
            if (x < INT64_MAX) {
                w = fx_min64(w, ((int64_t)fx_icbrt64((uint64_t)x) + 1) * 10000);
            }
            for (k = 0; k < 3; k++) { /* Newton from above: stays above the root */
                /* f(w) = (2 v + J w^2) w - d and f'(w) = 2 v + 3 J w^2, * 2^16 */
                int64_t f =
                    sc_muldiv(fx_sat_add64(2 * v * 65536, sc_jw2(j, w, false)), w, (int64_t)NS) -
                    dq;
                int64_t fp = fx_sat_add64(2 * v * 65536, 3 * sc_jw2(j, w, true));
                if (f <= 0) {
                    break;
                }
                w -= sc_muldiv(f, (int64_t)NS, fp);
            }
            /* chord through the origin: a lower bound of the root */
            w = sc_muldiv(dq, (int64_t)NS, fx_sat_add64(2 * v * 65536, sc_jw2(j, w, true)));
            dv = fx_min64(sc_jw2(j, w, false) / 65536, q);
        }
    }
    return fx_min64(vmax, fx_max64(v, fx_sat_add64(v, dv)));
}

int64_t sc_reach(int64_t v, int64_t d, const sc_limits_t *lim)
{
    return sc_reach_pre(v, d, lim, -1, -1);
}

int64_t sc_reach_bracket(int64_t v, int64_t d, const sc_limits_t *lim)
{
    int64_t r;

    sc_fast_off = true;
    r = sc_reach(v, d, lim);
    sc_fast_off = false;
    return r;
}

void sc_limits_aaj(const sc_limits_t *lim, int64_t *q, int64_t *qc)
{
    sc_aaj(lim->a_max, lim->j_max, q, qc);
}

int64_t sc_reach_pre(int64_t v, int64_t d, const sc_limits_t *lim, int64_t q, int64_t qc)
{
    bool tried = false;

    if (d > INT64_MAX / 65536) {
        d = INT64_MAX / 65536;
    }
    /* the planner's usual case first: the closed form, as sc_reach_q16
     * would try it (the S-curve, 0 <= v < v_max, A^2/J supplied) */
    if (lim->shape == SC_SHAPE_SCURVE && q > 0 && v >= 0 && v < lim->v_max && !sc_fast_off) {
        int64_t r = sc_reach_closed(v, d * 65536, q, lim);
        if (r > 0) {
            return r;
        }
        tried = true; /* not again in sc_reach_q16 */
    }
    return sc_reach_q16(v, d * 65536, lim, q, qc, !tried);
}

/* sc_reach_k's other paths (closed: whether the closed form is still to
 * be tried) */
static int64_t sc_reach_k_rest(int64_t v, const sc_limits_t *lim, const sc_reach_k_t *rk,
                               bool closed)
{
    int64_t d = (rk->d > INT64_MAX / 65536) ? INT64_MAX / 65536 : rk->d;

    return sc_reach_q16(v, d * 65536, lim, rk->q, rk->qc, closed);
}

int64_t sc_reach_k(int64_t v, const sc_limits_t *lim, const sc_reach_k_t *rk)
{
    if (rk->bk > 0 && v >= 0 && !sc_closed_off && !sc_fast_off) {
        int64_t r = sc_reach_closed_k(v, rk, rk->q, lim);
        return (r > 0) ? r : sc_reach_k_rest(v, lim, rk, false);
    }
    return sc_reach_k_rest(v, lim, rk, true);
}
