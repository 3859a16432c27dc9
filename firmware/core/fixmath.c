/*
 * fixmath.c - see fixmath.h for the specification and error bounds.
 *
 * Right shifts of negative values are arithmetic (GCC and Clang define this;
 * every target of the project uses one of them). Left shifts of values that
 * may be negative are written as multiplications to stay defined in C99.
 * Magnitudes are handled as uint64_t so that INT64_MIN needs no special case.
 */
#include "fixmath.h"

/* ---- saturation ----------------------------------------------------------- */

int32_t fx_sat32(int64_t v)
{
    if (v > INT32_MAX) {
        return INT32_MAX;
    }
    if (v < INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)v;
}

int32_t fx_sat_add32(int32_t a, int32_t b)
{
    return fx_sat32((int64_t)a + b);
}

int32_t fx_sat_sub32(int32_t a, int32_t b)
{
    return fx_sat32((int64_t)a - b);
}

int32_t fx_sat_neg32(int32_t a)
{
    return (a == INT32_MIN) ? INT32_MAX : -a;
}

int32_t fx_sat_abs32(int32_t a)
{
    return (a < 0) ? fx_sat_neg32(a) : a;
}

int64_t fx_sat_add64(int64_t a, int64_t b)
{
    if (b > 0 && a > INT64_MAX - b) {
        return INT64_MAX;
    }
    if (b < 0 && a < INT64_MIN - b) {
        return INT64_MIN;
    }
    return a + b;
}

int64_t fx_sat_sub64(int64_t a, int64_t b)
{
    if (b < 0 && a > INT64_MAX + b) {
        return INT64_MAX;
    }
    if (b > 0 && a < INT64_MIN + b) {
        return INT64_MIN;
    }
    return a - b;
}

int64_t fx_sat_neg64(int64_t a)
{
    return (a == INT64_MIN) ? INT64_MAX : -a;
}

int64_t fx_sat_abs64(int64_t a)
{
    return (a < 0) ? fx_sat_neg64(a) : a;
}

int32_t fx_clamp32(int32_t v, int32_t lo, int32_t hi)
{
    if (v < lo) {
        v = lo;
    }
    return (v > hi) ? hi : v;
}

int64_t fx_clamp64(int64_t v, int64_t lo, int64_t hi)
{
    if (v < lo) {
        v = lo;
    }
    return (v > hi) ? hi : v;
}

/* ---- shifts and multiplications -------------------------------------------- */

int64_t fx_round_shift64(int64_t v, unsigned s)
{
    if (s == 0) {
        return v;
    }
    if (s >= 64) {
        return 0; /* |v / 2^s| <= 1/2, and -1/2 rounds up to 0 */
    }
    /* floor(v / 2^s) plus the first dropped bit: round half up, no overflow */
    return (v >> s) + ((v >> (s - 1)) & 1);
}

int64_t fx_mul32_shift(int32_t a, int32_t b, unsigned s)
{
    return fx_round_shift64((int64_t)a * b, s);
}

int32_t fx_sat_mul32(int32_t a, int32_t b, unsigned s)
{
    return fx_sat32(fx_mul32_shift(a, b, s));
}

/* ---- 128-bit helpers (two's complement, hi:lo) ------------------------------ */

typedef struct {
    uint64_t hi;
    uint64_t lo;
} fx_u128_t;

static uint64_t fx_uabs64(int64_t v)
{
    return (v < 0) ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
}

/* full 64 x 64 -> 128 product from four 32 x 32 -> 64 products */
static inline fx_u128_t fx_umul64(uint64_t a, uint64_t b)
{
    uint64_t a_lo = a & 0xFFFFFFFFu, a_hi = a >> 32;
    uint64_t b_lo = b & 0xFFFFFFFFu, b_hi = b >> 32;
    uint64_t ll = a_lo * b_lo;
    uint64_t lh = a_lo * b_hi;
    uint64_t hl = a_hi * b_lo;
    uint64_t hh = a_hi * b_hi;
    uint64_t mid = (ll >> 32) + (lh & 0xFFFFFFFFu) + (hl & 0xFFFFFFFFu);
    fx_u128_t r;

    r.lo = (mid << 32) | (ll & 0xFFFFFFFFu);
    r.hi = hh + (lh >> 32) + (hl >> 32) + (mid >> 32);
    return r;
}

/* 64 x 32 -> 96 product (b < 2^32) from two 32 x 32 -> 64 products */
static fx_u128_t fx_umul64x32(uint64_t a, uint32_t b)
{
    uint64_t lo = (a & 0xFFFFFFFFu) * b;
    uint64_t hi = (a >> 32) * b;
    fx_u128_t r;

    r.lo = lo + (hi << 32);
    r.hi = (hi >> 32) + (r.lo < lo ? 1u : 0u);
    return r;
}

static fx_u128_t fx_add128(fx_u128_t a, fx_u128_t b)
{
    fx_u128_t r;

    r.lo = a.lo + b.lo;
    r.hi = a.hi + b.hi + (r.lo < a.lo ? 1u : 0u);
    return r;
}

static bool fx_le128(fx_u128_t a, fx_u128_t b)
{
    return (a.hi < b.hi) || (a.hi == b.hi && a.lo <= b.lo);
}

/* v * 2^s for any s; false when the result needs more than 128 bits */
static bool fx_shl128(uint64_t v, unsigned s, fx_u128_t *r)
{
    r->hi = 0;
    r->lo = 0;
    if (v == 0) {
        return true;
    }
    if (s >= 128) {
        return false;
    }
    if (s >= 64) {
        if (s > 64 && (v >> (128 - s)) != 0) {
            return false;
        }
        r->hi = v << (s - 64);
    } else if (s > 0) {
        r->lo = v << s;
        r->hi = v >> (64 - s);
    } else {
        r->lo = v;
    }
    return true;
}

/* An int64 of magnitude m and sign neg, saturated; ok == false means the
 * magnitude exceeded 64 bits. */
static int64_t fx_signed_sat(bool ok, uint64_t m, bool neg)
{
    if (neg) {
        if (!ok || m > (uint64_t)INT64_MAX + 1u) {
            return INT64_MIN;
        }
        return (int64_t)((uint64_t)0 - m);
    }
    if (!ok || m > (uint64_t)INT64_MAX) {
        return INT64_MAX;
    }
    return (int64_t)m;
}

/* round(v / 2^s) by the shift rule (ties toward +inf) for v = +m or -m
 * (neg), saturated to int64. m <= 2^126 (a product of two int64 magnitudes).
 * Rounding half up on the signed value is floor((m + 2^(s-1)) / 2^s) for
 * v >= 0 and floor((m - 1 + 2^(s-1)) / 2^s) for v < 0 (a tie of the
 * magnitude goes down), and floor((x + 2^(s-1)) / 2^s) = floor((t + 1) / 2)
 * with t = floor(x / 2^(s-1)): one 128-bit shift, no mask of the dropped
 * bits. */
static inline int64_t fx_round_shift128_sat(fx_u128_t m, bool neg, unsigned s)
{
    uint64_t t, lo = m.lo, hi = m.hi;
    unsigned r;
    bool ok = true;

    if (s == 0) {
        return fx_signed_sat(hi == 0, lo, neg);
    }
    if (s >= 128) {
        return 0; /* |v| <= 2^126 < 2^(s-1) */
    }
    if (neg) {
        if (lo == 0) {
            if (hi == 0) {
                return 0;
            }
            hi--;
        }
        lo--;
    }
    r = s - 1;
    if (r >= 64) {
        t = hi >> (r - 64);
    } else if (hi == 0) {
        t = lo >> r;
    } else if (r == 0) {
        t = lo;
        ok = false;
    } else {
        t = (lo >> r) | (hi << (64 - r));
        ok = (hi >> r) == 0;
    }
    /* floor((t + 1) / 2) <= 2^63; !ok: the quotient is at least 2^63 */
    return fx_signed_sat(ok, (t >> 1) + (t & 1u), neg);
}

int64_t fx_mul64_shift(int64_t a, int64_t b, unsigned s)
{
    uint64_t ua = fx_uabs64(a), ub = fx_uabs64(b);
    fx_u128_t p;

    if (((ua | ub) >> 32) == 0) { /* one 32 x 32 -> 64 multiply */
        p.hi = 0;
        p.lo = ua * ub;
    } else {
        p = fx_umul64(ua, ub);
    }
    return fx_round_shift128_sat(p, (a < 0) != (b < 0), s);
}

int64_t fx_mul64x32_shift(int64_t a, int32_t b, unsigned s)
{
    uint64_t ua = fx_uabs64(a);
    uint32_t ub = (uint32_t)fx_uabs64(b);
    fx_u128_t p;

    if ((ua >> 32) == 0) { /* one 32 x 32 -> 64 multiply */
        p.hi = 0;
        p.lo = ua * ub;
    } else {
        p = fx_umul64x32(ua, ub);
    }

    return fx_round_shift128_sat(p, (a < 0) != (b < 0), s);
}

pos_nm_t fx_pos_scale_q16(pos_nm_t p, q16_16_t r)
{
    return fx_mul64x32_shift(p, r, 16);
}

pos_nm_t fx_pos_scale_q30(pos_nm_t p, q1_30_t r)
{
    return fx_mul64x32_shift(p, r, 30);
}

/* ---- conversions -------------------------------------------------------------- */

q16_16_t fx_q16_from_int(int32_t n)
{
    return fx_sat32((int64_t)n * 65536);
}

int32_t fx_q16_to_int(q16_16_t v)
{
    return (int32_t)fx_round_shift64(v, 16);
}

q1_30_t fx_q30_from_q16(q16_16_t v)
{
    return fx_sat32((int64_t)v * 16384);
}

q16_16_t fx_q16_from_q30(q1_30_t v)
{
    return (q16_16_t)fx_round_shift64(v, 14);
}

q32_32_t fx_q32_from_int(int64_t n)
{
    if (n > INT32_MAX) {
        return INT64_MAX;
    }
    if (n < INT32_MIN) {
        return INT64_MIN;
    }
    return n * FX_ONE_Q32;
}

int64_t fx_q32_to_int(q32_32_t v)
{
    return fx_round_shift64(v, 32);
}

q32_32_t fx_q32_from_q16(q16_16_t v)
{
    return (q32_32_t)v * 65536;
}

q16_16_t fx_q16_from_q32(q32_32_t v)
{
    return fx_sat32(fx_round_shift64(v, 16));
}

q32_32_t fx_q32_from_q30(q1_30_t v)
{
    return (q32_32_t)v * 4;
}

q1_30_t fx_q30_from_q32(q32_32_t v)
{
    return fx_sat32(fx_round_shift64(v, 2));
}

/* ---- division ---------------------------------------------------------------- */

/*
 * Unsigned division primitives. Hosts with a 64-bit divider (those whose
 * compiler has __int128) use it; 32-bit targets (Cortex-M4: UDIV 32/32 and
 * UMULL 32 x 32 -> 64, no 64-bit divider) run the digit code below, which the
 * test hooks fx_udivmod64_digits / fx_udiv128_digits expose on every host.
 * The digit code is Knuth's long division (algorithm D) with a normalised
 * divisor: quotient digits of 32 bits are estimated from the divisor's top
 * digit and corrected with its second digit, which makes each estimate exact
 * for a three-by-two digit step, so no add-back step exists. Estimating a 32-bit
 * digit needs a 64/32 division, done the same way with 16-bit digits and the
 * 32/32 hardware divider (at most two corrections per 16-bit digit).
 */
#if defined(__SIZEOF_INT128__) && !defined(FX_PORTABLE_ONLY)
#define FX_NATIVE_DIV 1
__extension__ typedef unsigned __int128 fx_native_u128;
#endif

/* number of leading zero bits of v != 0 */
static unsigned fx_clz32(uint32_t v)
{
#if defined(__GNUC__)
    return (unsigned)__builtin_clz(v);
#else
    unsigned n = 0;

    if (v < ((uint32_t)1 << 16)) {
        n += 16;
        v <<= 16;
    }
    if (v < ((uint32_t)1 << 24)) {
        n += 8;
        v <<= 8;
    }
    if (v < ((uint32_t)1 << 28)) {
        n += 4;
        v <<= 4;
    }
    if (v < ((uint32_t)1 << 30)) {
        n += 2;
        v <<= 2;
    }
    if (v < ((uint32_t)1 << 31)) {
        n += 1;
    }
    return n;
#endif
}

/* number of leading zero bits of v != 0 */
static unsigned fx_clz64(uint64_t v)
{
    uint32_t hi = (uint32_t)(v >> 32);

    return (hi != 0u) ? fx_clz32(hi) : 32u + fx_clz32((uint32_t)v);
}

/* floor((u1 * 2^32 + u0) / v) and the remainder for a normalised v (bit 31
 * set) and u1 < v (the quotient fits 32 bits): two 16-bit quotient digits. */
static uint32_t fx_div64by32n(uint32_t u1, uint32_t u0, uint32_t v, uint32_t *rem)
{
    uint32_t vh = v >> 16, vl = v & 0xFFFFu;
    uint32_t qh, ql, r, t;

    /* first digit: (u1 : top half of u0) / v */
    qh = u1 / vh;
    r = u1 - qh * vh;
    while (qh > 0xFFFFu || qh * vl > ((r << 16) | (u0 >> 16))) {
        qh--;
        r += vh;
        if (r > 0xFFFFu) {
            break;
        }
    }
    t = (u1 << 16) + (u0 >> 16) - qh * v; /* the partial remainder, < v */
    /* second digit: (t : bottom half of u0) / v */
    ql = t / vh;
    r = t - ql * vh;
    while (ql > 0xFFFFu || ql * vl > ((r << 16) | (u0 & 0xFFFFu))) {
        ql--;
        r += vh;
        if (r > 0xFFFFu) {
            break;
        }
    }
    *rem = (t << 16) + (u0 & 0xFFFFu) - ql * v;
    return (qh << 16) | ql;
}

/* The same for a divisor with a precomputed reciprocal v = floor((2^64 - 1)
 * / d) - 2^32 (Moller and Granlund, "Improved division by invariant
 * integers", 2011, algorithm 4): one multiply, at most two corrections. */
static uint32_t fx_div64by32_pre(uint32_t u1, uint32_t u0, uint32_t d, uint32_t v, uint32_t *rem)
{
    uint64_t p = (uint64_t)v * u1 + (((uint64_t)u1 << 32) | u0);
    uint32_t q = (uint32_t)(p >> 32) + 1u;
    uint32_t r = u0 - q * d;

    if (r > (uint32_t)p) {
        q--;
        r += d;
    }
    if (r >= d) {
        q++;
        r -= d;
    }
    *rem = r;
    return q;
}

/* 10^9 (ns per second, the most frequent divisor of the planner) normalised,
 * and its reciprocal for fx_div64by32_pre */
#define FX_NS_NORM  4000000000u /* 10^9 * 4 */
#define FX_NS_RECIP 316718722u  /* floor((2^64 - 1) / FX_NS_NORM) - 2^32 */

/* floor((u * 2^32 + w) / d) and the remainder for d = dh * 2^32 + dl with
 * dh normalised (bit 31 set) and u < d: one exact 32-bit quotient digit. */
static uint32_t fx_div96by64n(uint64_t u, uint32_t w, uint32_t dh, uint32_t dl, uint64_t *rem)
{
    uint32_t uh = (uint32_t)(u >> 32), q, r32;
    uint64_t r;

    /* estimate from the top digits (never below the true digit) */
    if (uh >= dh) { /* uh == dh: the digit is at most 2^32 - 1 */
        q = 0xFFFFFFFFu;
        r = (uint64_t)(uint32_t)u + dh;
    } else {
        q = fx_div64by32n(uh, (uint32_t)u, dh, &r32);
        r = r32;
    }
    /* correct with the second divisor digit: exact for three by two digits */
    while (r <= 0xFFFFFFFFu && (uint64_t)q * dl > ((r << 32) | w)) {
        q--;
        r += dh;
    }
    /* the remainder is below d < 2^64: arithmetic modulo 2^64 is exact */
    *rem = ((u << 32) | w) - (uint64_t)q * dl - (((uint64_t)q * dh) << 32);
    return q;
}

uint64_t fx_udiv128_digits(uint64_t hi, uint64_t lo, uint64_t d, uint64_t *rem)
{
    unsigned s;
    uint64_t r;
    uint32_t q1, q0;

    if (hi >= d) { /* quotient >= 2^64, or d == 0 */
        *rem = 0;
        return UINT64_MAX;
    }
    if (hi == 0) {
        return fx_udivmod64_digits(lo, d, rem);
    }
    if ((d >> 32) == 0) {
        /* one-digit divisor: 0 < hi < d < 2^32, a 96-bit numerator */
        uint32_t v = (uint32_t)d, r32;
        uint32_t u2, u1, u0;

        s = fx_clz32(v);
        v <<= s;
        u2 = (uint32_t)hi << s;
        u1 = (uint32_t)(lo >> 32) << s;
        u0 = (uint32_t)lo << s;
        if (s != 0) {
            u2 |= (uint32_t)(lo >> 32) >> (32 - s);
            u1 |= (uint32_t)lo >> (32 - s);
        }
        if (v == FX_NS_NORM) {
            q1 = fx_div64by32_pre(u2, u1, v, FX_NS_RECIP, &r32);
            q0 = fx_div64by32_pre(r32, u0, v, FX_NS_RECIP, &r32);
        } else {
            q1 = fx_div64by32n(u2, u1, v, &r32);
            q0 = fx_div64by32n(r32, u0, v, &r32);
        }
        *rem = r32 >> s;
        return ((uint64_t)q1 << 32) | q0;
    }
    /* two-digit divisor: normalise, then two 96/64 digit steps */
    s = fx_clz32((uint32_t)(d >> 32));
    if (s != 0) {
        d <<= s;
        hi = (hi << s) | (lo >> (64 - s));
        lo <<= s;
    }
    q1 = fx_div96by64n(hi, (uint32_t)(lo >> 32), (uint32_t)(d >> 32), (uint32_t)d, &r);
    q0 = fx_div96by64n(r, (uint32_t)lo, (uint32_t)(d >> 32), (uint32_t)d, &r);
    *rem = r >> s;
    return ((uint64_t)q1 << 32) | q0;
}

uint64_t fx_udivmod64_digits(uint64_t n, uint64_t d, uint64_t *rem)
{
    uint32_t nh = (uint32_t)(n >> 32), nl = (uint32_t)n;
    uint32_t dh = (uint32_t)(d >> 32), dl = (uint32_t)d;
    uint32_t q, r32;
    uint64_t r;
    unsigned s;

    if (dh == 0) {
        uint32_t qh = 0, u1, u0, dn;

        if (dl == 0) {
            *rem = 0;
            return UINT64_MAX;
        }
        if (nh == 0) { /* the hardware divider */
            *rem = nl % dl;
            return nl / dl;
        }
        if (nh >= dl) { /* high quotient digit, then nh < dl */
            qh = nh / dl;
            nh -= qh * dl;
        }
        s = fx_clz32(dl); /* 0..31 */
        u1 = nh << s;
        u0 = nl << s;
        if (s != 0) {
            u1 |= nl >> (32 - s);
        }
        dn = dl << s;
        if (dn == FX_NS_NORM) {
            q = fx_div64by32_pre(u1, u0, dn, FX_NS_RECIP, &r32);
        } else {
            q = fx_div64by32n(u1, u0, dn, &r32);
        }
        *rem = r32 >> s;
        return ((uint64_t)qh << 32) | q;
    }
    if (n < d) {
        *rem = n;
        return 0;
    }
    /* d >= 2^32: one exact digit step on the normalised 96-bit numerator */
    s = fx_clz32(dh);
    if (s != 0) {
        dh = (dh << s) | (dl >> (32 - s));
        dl <<= s;
        q = fx_div96by64n(((uint64_t)(nh >> (32 - s)) << 32) | (nh << s) | (nl >> (32 - s)),
                          nl << s, dh, dl, &r);
    } else {
        q = fx_div96by64n(nh, nl, dh, dl, &r);
    }
    *rem = r >> s;
    return q;
}

uint64_t fx_udiv128(uint64_t hi, uint64_t lo, uint64_t d, uint64_t *rem)
{
#ifdef FX_NATIVE_DIV
    if (hi >= d) {
        *rem = 0;
        return UINT64_MAX;
    }
    if (hi == 0) {
        *rem = lo % d;
        return lo / d;
    }
    {
        fx_native_u128 n = ((fx_native_u128)hi << 64) | lo;
        uint64_t q = (uint64_t)(n / d);
        *rem = lo - q * d;
        return q;
    }
#else
    return fx_udiv128_digits(hi, lo, d, rem);
#endif
}

uint64_t fx_udivmod64(uint64_t n, uint64_t d, uint64_t *rem)
{
#ifdef FX_NATIVE_DIV
    if (d == 0) {
        *rem = 0;
        return UINT64_MAX;
    }
    *rem = n % d;
    return n / d;
#else
    return fx_udivmod64_digits(n, d, rem);
#endif
}

/* floor(n / d) and n mod d for 0 < d and n.hi < d (the quotient fits in 64
 * bits). */
static inline uint64_t fx_udiv128_n(fx_u128_t n, uint64_t d, uint64_t *rem)
{
#ifdef FX_NATIVE_DIV
    return fx_udiv128(n.hi, n.lo, d, rem);
#else
    return fx_udiv128_digits(n.hi, n.lo, d, rem);
#endif
}

/* round(n / d) of magnitudes, ties away from zero, then signed and saturated */
static inline int64_t fx_div128_sat(fx_u128_t n, uint64_t d, bool neg)
{
    uint64_t q, r;

    if (n.hi >= d) {
        return neg ? INT64_MIN : INT64_MAX; /* quotient >= 2^64 */
    }
    q = fx_udiv128_n(n, d, &r);
    if (r >= d - r) {
        if (q == UINT64_MAX) {
            return neg ? INT64_MIN : INT64_MAX;
        }
        q++;
    }
    return fx_signed_sat(true, q, neg);
}

/* saturated value for a zero divisor: toward the sign of the numerator */
static int64_t fx_div_zero(bool zero_num, bool neg)
{
    if (zero_num) {
        return 0;
    }
    return neg ? INT64_MIN : INT64_MAX;
}

int64_t fx_div_shift64(int64_t num, int64_t den, unsigned s)
{
    fx_u128_t n;
    bool neg = (num < 0) != (den < 0);

    if (den == 0) {
        return fx_div_zero(num == 0, num < 0);
    }
    if (!fx_shl128(fx_uabs64(num), s, &n)) {
        return neg ? INT64_MIN : INT64_MAX; /* |num| * 2^s >= 2^128 */
    }
    return fx_div128_sat(n, fx_uabs64(den), neg);
}

int64_t fx_div_round64(int64_t num, int64_t den)
{
    uint64_t d = fx_uabs64(den), q, r;
    bool neg = (num < 0) != (den < 0);

    if (den == 0) {
        return fx_div_zero(num == 0, num < 0);
    }
    /* fx_div_shift64(num, den, 0) without the 128-bit numerator */
#ifdef FX_NATIVE_DIV
    q = fx_udivmod64(fx_uabs64(num), d, &r);
#else
    q = fx_udivmod64_digits(fx_uabs64(num), d, &r);
#endif
    if (r >= d - r) {
        q++; /* q <= 2^63 before: no wrap */
    }
    return fx_signed_sat(true, q, neg);
}

int32_t fx_div_sat32(int64_t num, int32_t den, unsigned s)
{
    return fx_sat32(fx_div_shift64(num, den, s));
}

int64_t fx_muldiv64(int64_t a, int64_t b, int64_t c)
{
    bool neg = ((a < 0) != (b < 0)) != (c < 0);

    if (c == 0) {
        return fx_div_zero(a == 0 || b == 0, (a < 0) != (b < 0));
    }
    return fx_div128_sat(fx_umul64(fx_uabs64(a), fx_uabs64(b)), fx_uabs64(c), neg);
}

q16_16_t fx_recip_q16(q16_16_t x)
{
    return fx_div_sat32(FX_ONE_Q16, x, 16);
}

/* ---- roots ------------------------------------------------------------------ */

/* Square roots by Newton's iteration from above, seeded from a table:
 * for x = v * 4^k normalised to [2^30, 2^32), fx_sqrt_seed[(x >> 26) - 16]
 * is ceil(sqrt(((x >> 26) + 1) * 2^26)), at most 3 % above sqrt(x). */
static const uint32_t fx_sqrt_seed[48] = {
    33777u, 34756u, 35709u, 36636u, 37541u, 38424u, 39288u, 40133u, 40960u, 41772u, 42567u, 43348u,
    44116u, 44870u, 45612u, 46341u, 47060u, 47768u, 48465u, 49152u, 49830u, 50499u, 51160u, 51811u,
    52455u, 53091u, 53719u, 54340u, 54954u, 55561u, 56162u, 56756u, 57344u, 57927u, 58503u, 59074u,
    59639u, 60199u, 60754u, 61304u, 61849u, 62389u, 62924u, 63455u, 63982u, 64504u, 65022u, 65536u,
};

/* From any r >= floor(sqrt(v)), r' = floor((r + floor(v / r)) / 2) is again
 * >= floor(sqrt(v)) and below r while r > floor(sqrt(v)); floor(v / r) >= r
 * only at r = floor(sqrt(v)). From the 3 % seed: three or four 32-bit
 * divisions. */
uint32_t fx_isqrt32(uint32_t v)
{
    unsigned sh;
    uint32_t r, q;

    if (v == 0) {
        return 0;
    }
    sh = fx_clz32(v) & ~1u;
    r = (fx_sqrt_seed[((v << sh) >> 26) - 16u] >> (sh / 2u)) + 1u;
    for (;;) {
        q = v / r;
        if (q >= r) {
            return r;
        }
        r = (r + q) >> 1;
    }
}

/* v >= 2^32: with x = v * 4^k in [2^62, 2^64), s = floor(sqrt(x / 2^32))
 * puts floor(sqrt(x)) = R in [s * 2^16, s * 2^16 + 2^16 - 1]; one Newton step
 * from the top of that range (a 64/32 division) lands on R or R + 1 (the
 * start is less than 2^16 off and at least 2^31: the step's error is below
 * one), and a square decides. floor(sqrt(v)) = floor(R / 2^k). */
uint32_t fx_isqrt64(uint64_t v)
{
    unsigned sh;
    uint64_t x, y;
    uint32_t r0, q, rem;

    if (v <= UINT32_MAX) {
        return fx_isqrt32((uint32_t)v);
    }
    sh = fx_clz64(v) & ~1u;
    x = v << sh;
    r0 = (fx_isqrt32((uint32_t)(x >> 32)) << 16) | 0xFFFFu;
    if ((uint32_t)(x >> 32) >= r0) {
        return UINT32_MAX >> (sh / 2u); /* only when R = 2^32 - 1 */
    }
    q = fx_div64by32n((uint32_t)(x >> 32), (uint32_t)x, r0, &rem);
    y = ((uint64_t)r0 + q) >> 1;
    if (y > UINT32_MAX) {
        y = UINT32_MAX;
    }
    if (y * y > x) {
        y--;
    }
    return (uint32_t)y >> (sh / 2u);
}

/* floor(sqrt(n)) of a 128-bit value (< 2^128, so the root is < 2^64): the top
 * 32 bits of the root from fx_isqrt64 of the high word, then the low 32 bits
 * one at a time by squaring the candidate (no division). */
static uint64_t fx_isqrt128(fx_u128_t n)
{
    uint64_t r;
    int b;

    if (n.hi == 0) {
        return fx_isqrt64(n.lo);
    }
    r = (uint64_t)fx_isqrt64(n.hi) << 32;
    for (b = 31; b >= 0; b--) {
        uint64_t c = r | ((uint64_t)1 << b);
        if (fx_le128(fx_umul64(c, c), n)) {
            r = c;
        }
    }
    return r;
}

/* Cube roots by Newton's iteration from above, as the square roots: from
 * any r >= floor(cbrt(v)), r' = floor((2 r + floor(v / r^2)) / 3) is again
 * >= floor(cbrt(v)) (arithmetic-geometric mean of r, r, v / r^2) and below r
 * while r > floor(cbrt(v)). 32-bit values: from a power of two at most twice
 * the root, five or six 32-bit divisions. */
static uint32_t fx_icbrt32(uint32_t v)
{
    uint32_t r, y;

    if (v == 0) {
        return 0;
    }
    r = (uint32_t)1 << ((32u - fx_clz32(v) + 2u) / 3u); /* r^3 >= 2^bits > v */
    for (;;) {
        y = (2u * r + v / (r * r)) / 3u;
        if (y >= r) {
            return r;
        }
        r = y;
    }
}

/* v >= 2^32: y = floor(cbrt(v / 8^t)) for v / 8^t in [2^29, 2^32) puts the
 * root below r = (y + 1) 2^t, less than 2^t (a 812th of r) above it; one
 * Newton step (a 64-bit division) lands within 3 of floor(cbrt(v)), from
 * above, and cubes decide. */
uint32_t fx_icbrt64(uint64_t v)
{
    unsigned t;
    uint64_t r, rem;
    uint32_t y;

    if (v <= UINT32_MAX) {
        return fx_icbrt32((uint32_t)v);
    }
    t = (64u - fx_clz64(v) - 30u) / 3u;
    r = (uint64_t)(fx_icbrt32((uint32_t)(v >> (3u * t))) + 1u) << t;
    y = (uint32_t)((2u * r + fx_udivmod64(v, r * r, &rem)) / 3u);
    if (y > 2642245u) {
        y = 2642245u; /* floor(cbrt(2^64 - 1)): y^3 below fits 64 bits */
    }
    while ((uint64_t)y * y * y > v) {
        y--;
    }
    return y;
}

/* ---- trigonometry ------------------------------------------------------------- */

/*
 * The angle is folded into [0, 45] degrees; there sin and cos are Taylor
 * series evaluated in unsigned Q0.32 (x < pi/4 < 1), every product rounded,
 * every bracket of the Horner form positive. Truncation after x^11 (sin) and
 * x^12 (cos) is below 1.2e-10 on [0, pi/4], an eighth of a q1_30 LSB.
 */
#define FX_2PI_Q29 3373259426u /* 2 pi * 2^29: quadrant fraction (2^30) to rad Q0.32 */

/* 1/n! in Q0.32, rounded */
#define FX_INV_FACT2  2147483648u
#define FX_INV_FACT3  715827883u
#define FX_INV_FACT4  178956971u
#define FX_INV_FACT5  35791394u
#define FX_INV_FACT6  5965232u
#define FX_INV_FACT7  852176u
#define FX_INV_FACT8  106522u
#define FX_INV_FACT9  11836u
#define FX_INV_FACT10 1184u
#define FX_INV_FACT11 108u
#define FX_INV_FACT12 9u

/* round(a * b / 2^32): one 32 x 32 -> 64 multiply */
static uint32_t fx_mulhi32(uint32_t a, uint32_t b)
{
    return (uint32_t)(((uint64_t)a * b + 0x80000000u) >> 32);
}

/* sin(x) in q1_30 for x in Q0.32, 0 <= x <= pi/4, z = x^2 */
static q1_30_t fx_sin_poly(uint32_t x, uint32_t z)
{
    uint32_t t = FX_INV_FACT11;

    t = FX_INV_FACT9 - fx_mulhi32(z, t);
    t = FX_INV_FACT7 - fx_mulhi32(z, t);
    t = FX_INV_FACT5 - fx_mulhi32(z, t);
    t = FX_INV_FACT3 - fx_mulhi32(z, t);
    t = x - fx_mulhi32(fx_mulhi32(z, x), t); /* x - x^3 (1/3! - ...) */
    return (q1_30_t)((t + 2u) >> 2);
}

/* cos(x) in q1_30 for x in Q0.32, 0 <= x <= pi/4, z = x^2 */
static q1_30_t fx_cos_poly(uint32_t z)
{
    uint32_t t = FX_INV_FACT12;

    t = FX_INV_FACT10 - fx_mulhi32(z, t);
    t = FX_INV_FACT8 - fx_mulhi32(z, t);
    t = FX_INV_FACT6 - fx_mulhi32(z, t);
    t = FX_INV_FACT4 - fx_mulhi32(z, t);
    t = FX_INV_FACT2 - fx_mulhi32(z, t);
    t = fx_mulhi32(z, t); /* 1 - cos(x) in Q0.32 */
    /* round((2^32 - t) / 4), ties up */
    return (q1_30_t)(((uint32_t)1 << 30) - ((t + 1u) >> 2));
}

/* x = t * (pi/2) / 2^30 rad in Q0.32, for t in [0, 2^29] */
static uint32_t fx_quad_to_rad(uint32_t t)
{
    return (uint32_t)(((uint64_t)t * FX_2PI_Q29 + ((uint32_t)1 << 28)) >> 29);
}

/* sin of t / 2^30 quarter turns, t in [0, 2^30]. cos is sin(2^30 - t), which
 * makes the two exactly symmetric about 45 degrees. */
static q1_30_t fx_sin_quad(uint32_t t)
{
    uint32_t x;

    if (t <= ((uint32_t)1 << 29)) {
        x = fx_quad_to_rad(t);
        return fx_sin_poly(x, fx_mulhi32(x, x));
    }
    x = fx_quad_to_rad(((uint32_t)1 << 30) - t);
    return fx_cos_poly(fx_mulhi32(x, x));
}

/* *s = fx_sin_quad(t), *c = fx_sin_quad(2^30 - t), sharing x and x^2 */
static void fx_sincos_quad(uint32_t t, q1_30_t *s, q1_30_t *c)
{
    uint32_t u = (t <= ((uint32_t)1 << 29)) ? t : ((uint32_t)1 << 30) - t;
    uint32_t x = fx_quad_to_rad(u), z = fx_mulhi32(x, x);
    q1_30_t sn = fx_sin_poly(x, z);
    q1_30_t cs = (u == ((uint32_t)1 << 29)) ? sn : fx_cos_poly(z);

    if (u == t) {
        *s = sn;
        *c = cs;
    } else {
        *s = cs;
        *c = sn;
    }
}

q1_30_t fx_sin(fx_angle_t a)
{
    uint32_t t = a & 0x3FFFFFFFu;

    switch (a >> 30) {
    case 0:
        return fx_sin_quad(t);
    case 1:
        return fx_sin_quad(((uint32_t)1 << 30) - t);
    case 2:
        return -fx_sin_quad(t);
    default:
        return -fx_sin_quad(((uint32_t)1 << 30) - t);
    }
}

q1_30_t fx_cos(fx_angle_t a)
{
    return fx_sin(a + FX_ANGLE_90);
}

void fx_sincos(fx_angle_t a, q1_30_t *s, q1_30_t *c)
{
    q1_30_t sq, cq; /* sin and cos of the angle within its quadrant */

    fx_sincos_quad(a & 0x3FFFFFFFu, &sq, &cq);
    switch (a >> 30) {
    case 0:
        *s = sq;
        *c = cq;
        break;
    case 1:
        *s = cq;
        *c = -sq;
        break;
    case 2:
        *s = -sq;
        *c = -cq;
        break;
    default:
        *s = -cq;
        *c = sq;
        break;
    }
}

/* atan(2^-i) in units of 2^-56 turn (binary angle with 24 extra bits),
 * i = 1..33, rounded from a 70-digit evaluation. */
#define FX_ATAN_FRAC  24
#define FX_ATAN_STEPS 33
static const int64_t fx_cordic_atan[FX_ATAN_STEPS + 1] = {
    0, /* i = 0 is not used: the input is already within 45 degrees */
    5317260203651848,
    2809494260081567,
    1426143154396570,
    715839029270683,
    358268477703266,
    179177955010598,
    89594445026371,
    44797906047171,
    22399038468267,
    11199529914810,
    5599766292493,
    2799883313132,
    1399941677427,
    699970841321,
    349985420986,
    174992710534,
    87496355272,
    43748177637,
    21874088818,
    10937044409,
    5468522205,
    2734261102,
    1367130551,
    683565276,
    341782638,
    170891319,
    85445659,
    42722830,
    21361415,
    10680707,
    5340354,
    2670177,
    1335088};

/* atan(v / u) as a binary angle, 0 < v < u: CORDIC vectoring with the
 * vector scaled to [2^60, 2^61) (growth 1.17 and sqrt(2) stay below 2^63).
 * After step i the residual angle is below atan(2^-i); 33 steps leave
 * 0.08 LSB, the final rounding 0.5 LSB. */
static uint32_t fx_atan_octant(uint64_t u, uint64_t v)
{
    unsigned lz = fx_clz64(u);
    int64_t x, y, z = 0;
    int i;

    if (lz > 3) {
        u <<= lz - 3;
        v <<= lz - 3;
    } else {
        u >>= 3 - lz;
        v >>= 3 - lz;
    }
    x = (int64_t)u;
    y = (int64_t)v;
    for (i = 1; i <= FX_ATAN_STEPS && y != 0; i++) {
        int64_t xs = x >> i, ys = y >> i;
        if (y > 0) {
            x += ys;
            y -= xs;
            z += fx_cordic_atan[i];
        } else {
            x -= ys;
            y += xs;
            z -= fx_cordic_atan[i];
        }
    }
    return (uint32_t)((z + ((int64_t)1 << (FX_ATAN_FRAC - 1))) >> FX_ATAN_FRAC);
}

fx_angle_t fx_atan2(int64_t y, int64_t x)
{
    uint64_t ax = fx_uabs64(x), ay = fx_uabs64(y);
    fx_angle_t a; /* angle of (|x|, |y|), in [0, 90] degrees */

    if (ay == 0) {
        a = 0; /* also (0, 0) */
    } else if (ax == 0) {
        a = FX_ANGLE_90;
    } else if (ax == ay) {
        a = FX_ANGLE_45;
    } else if (ay < ax) {
        a = fx_atan_octant(ax, ay);
    } else {
        a = FX_ANGLE_90 - fx_atan_octant(ay, ax);
    }
    if (x < 0) {
        a = FX_ANGLE_180 - a;
    }
    if (y < 0) {
        a = (fx_angle_t)0 - a;
    }
    return a;
}

/* ---- vector length -------------------------------------------------------------- */

static int64_t fx_sat_u64(uint64_t v)
{
    return (v > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)v;
}

int64_t fx_hypot2(int64_t x, int64_t y)
{
    uint64_t ax = fx_uabs64(x), ay = fx_uabs64(y);

    if ((ax | ay) < ((uint64_t)1 << 31)) {
        return (int64_t)fx_isqrt64(ax * ax + ay * ay);
    }
    return fx_sat_u64(fx_isqrt128(fx_add128(fx_umul64(ax, ax), fx_umul64(ay, ay))));
}

int64_t fx_hypot3(int64_t x, int64_t y, int64_t z)
{
    uint64_t ax = fx_uabs64(x), ay = fx_uabs64(y), az = fx_uabs64(z);
    fx_u128_t n;

    if ((ax | ay | az) < ((uint64_t)1 << 31)) {
        return (int64_t)fx_isqrt64(ax * ax + ay * ay + az * az);
    }
    n = fx_add128(fx_umul64(ax, ax), fx_umul64(ay, ay));
    return fx_sat_u64(fx_isqrt128(fx_add128(n, fx_umul64(az, az))));
}

int64_t fx_ratio_q30(int64_t num, int64_t den)
{
    if (den <= 0 || num <= 0) {
        return 0;
    }
    if (num >= den) {
        return FX_ONE_Q30;
    }
    while (den >= ((int64_t)1 << 32)) {
        num >>= 1;
        den >>= 1;
    }
    if (den == 0) {
        return 0;
    }
    return fx_div_round64(num << 30, den);
}

#define FX_PI_HALF_Q61   3622009729038561421ll  /* round(pi / 2 * 2^61) */
#define FX_RECIP_6_Q64   3074457345618258602ull /* floor(2^64 / 6) */
#define FX_RECIP_24_Q64  768614336404564650ull  /* floor(2^64 / 24) */
#define FX_RECIP_120_Q64 153722867280912930ull  /* floor(2^64 / 120) */
#define FX_RECIP_720_Q64 25620477880152155ull   /* floor(2^64 / 720) */

void fx_sin_1mcos_small_q62(int64_t d, int64_t *sin_q62, int64_t *omc_q62)
{
    uint64_t x, x2, x3, x4, sn, e;

    if (d > ((int64_t)1 << 58) || d < -((int64_t)1 << 58)) {
        *sin_q62 = 0;
        *omc_q62 = 0;
        return;
    }
    /* |d| in rad, q64 (< 2^61): |d| * 2 pi / 2^64 * 2^64 = |d| * pi/2 * 4 */
    x = (uint64_t)fx_mul64_shift(fx_sat_abs64(d), FX_PI_HALF_Q61, 61) << 2;
    x2 = fx_umulhi64(x, x);
    x3 = fx_umulhi64(x2, x);
    x4 = fx_umulhi64(x2, x2);
    sn = x - fx_umulhi64(x3, FX_RECIP_6_Q64) + fx_umulhi64(fx_umulhi64(x4, x), FX_RECIP_120_Q64);
    e = (x2 >> 1) - fx_umulhi64(x4, FX_RECIP_24_Q64) +
        fx_umulhi64(fx_umulhi64(x4, x2), FX_RECIP_720_Q64);
    sn >>= 2; /* q62 */
    e >>= 2;
    *sin_q62 = d < 0 ? -(int64_t)sn : (int64_t)sn;
    *omc_q62 = (int64_t)e;
}

uint64_t fx_recip62(uint32_t d)
{
    return d == 0u ? 0u : ((uint64_t)1 << 62) / d;
}

uint32_t fx_udiv64by32(uint64_t n, uint32_t d)
{
    uint32_t nh = (uint32_t)(n >> 32), rem;
    unsigned s;

    if (nh >= d) { /* quotient >= 2^32, or d == 0 */
        return UINT32_MAX;
    }
    if (nh == 0u) { /* the hardware divider */
        return (uint32_t)n / d;
    }
    s = fx_clz32(d); /* nh < d: the shifted numerator's top word stays below d */
    n <<= s;
    return fx_div64by32n((uint32_t)(n >> 32), (uint32_t)n, d << s, &rem);
}
