/*
 * fixmath_div.c - the divisions of fixmath.h (specification there): the
 * unsigned 64- and 128-bit primitives with their 32-bit-digit long division
 * for targets without a 64-bit divider, and the signed rounding and
 * saturating divisions built on them, and the integer roots (Newton
 * iterations that divide).
 */
#include "fixmath.h"
#include "fixmath_test.h"

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

/* The 64/32 step of the tick's own callers (fx_isqrt64, fx_udiv64by32), the
 * same contract: the hardware's 64-bit divider where it exists (one
 * instruction instead of two 16-bit digit estimates; the same quotient),
 * the digits above on 32-bit targets. The long divisions below keep the
 * digit step on every host: their test hooks are what 32-bit targets run. */
static inline uint32_t fx_div64by32q(uint32_t u1, uint32_t u0, uint32_t v)
{
#ifdef FX_NATIVE_DIV
    return (uint32_t)((((uint64_t)u1 << 32) | u0) / v);
#else
    uint32_t rem;
    return fx_div64by32n(u1, u0, v, &rem);
#endif
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
    uint32_t r0, q;

    if (v <= UINT32_MAX) {
        return fx_isqrt32((uint32_t)v);
    }
    sh = fx_clz64(v) & ~1u;
    x = v << sh;
    r0 = (fx_isqrt32((uint32_t)(x >> 32)) << 16) | 0xFFFFu;
    if ((uint32_t)(x >> 32) >= r0) {
        return UINT32_MAX >> (sh / 2u); /* only when R = 2^32 - 1 */
    }
    q = fx_div64by32q((uint32_t)(x >> 32), (uint32_t)x, r0);
    y = ((uint64_t)r0 + q) >> 1;
    if (y > UINT32_MAX) {
        y = UINT32_MAX;
    }
    if (y * y > x) {
        y--;
    }
    return (uint32_t)y >> (sh / 2u);
}

/* floor(sqrt(n)) of a 128-bit value (the root is < 2^64). Below 2^126: the
 * root of the top 64 bits of n / 4^k rounded up and scaled back is an
 * estimate from above within a factor 1 + 2^-31; one Newton step (a 128/64
 * division) and squares decide. From 2^126: the low 32 bits of the root one
 * at a time by squaring the candidate (no division, no overflow). */
uint64_t fx_isqrt128(fx_u128_t n)
{
    uint64_t r, rem;
    unsigned k;
    int b;

    if (n.hi == 0) {
        return fx_isqrt64(n.lo);
    }
    if (n.hi < ((uint64_t)1 << 62)) {
        k = (fx_bitlen64(n.hi) + 1u) / 2u;                 /* n / 4^k < 2^64 */
        r = (n.lo >> (2u * k)) | (n.hi << (64u - 2u * k)); /* 1 <= k <= 31 */
        r = ((uint64_t)fx_isqrt64(r) + 1u) << k;           /* > sqrt(n), <= 2^63 */
        r = (r >> 1) + (fx_udiv128(n.hi, n.lo, r, &rem) >> 1) + 1u;
        while (fx_cmp128(fx_umul64(r, r), n) > 0) {
            r--;
        }
        while (fx_cmp128(fx_umul64(r + 1u, r + 1u), n) <= 0) {
            r++;
        }
        return r;
    }
    r = (uint64_t)fx_isqrt64(n.hi) << 32;
    for (b = 31; b >= 0; b--) {
        uint64_t c = r | ((uint64_t)1 << b);
        if (fx_cmp128(fx_umul64(c, c), n) <= 0) {
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

/* ---- division by a constant with its reciprocal ---------------------------- */

uint64_t fx_recip62(uint32_t d)
{
    return d == 0u ? 0u : ((uint64_t)1 << 62) / d;
}

uint32_t fx_udiv64by32(uint64_t n, uint32_t d)
{
    uint32_t nh = (uint32_t)(n >> 32);
    unsigned s;

    if (nh >= d) { /* quotient >= 2^32, or d == 0 */
        return UINT32_MAX;
    }
    if (nh == 0u) { /* the hardware divider */
        return (uint32_t)n / d;
    }
    s = fx_clz32(d); /* nh < d: the shifted numerator's top word stays below d */
    n <<= s;
    return fx_div64by32q((uint32_t)(n >> 32), (uint32_t)n, d << s);
}
