/*
 * Calls one fixmath primitive N times on varied inputs, for callgrind
 * (bench/bench-fixmath.sh collects inside the fx_ function only, so the
 * loop and input generation are not counted).
 * Usage: bench_fixmath CASE N
 */
#include "fixmath.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static volatile int64_t sink;

/* well-mixed 64-bit input number i */
static uint64_t mix(uint64_t i)
{
    uint64_t z = (i + 1) * 0x9E3779B97F4A7C15ull;
    z ^= z >> 31;
    return z * 0xBF58476D1CE4E5B9ull;
}

static int64_t s64(uint64_t i, unsigned bits) /* signed, |v| < 2^bits */
{
    return (int64_t)mix(i) >> (64 - bits - 1);
}

#define BENCH(name, expr)                                                                          \
    static void bench_##name(uint64_t i)                                                           \
    {                                                                                              \
        sink += (int64_t)(expr);                                                                   \
    }

BENCH(sat_mul32, fx_sat_mul32((int32_t)s64(i, 31), (int32_t)s64(i + 1, 31), 16))
BENCH(mul64_shift, fx_mul64_shift(s64(i, 63), s64(i + 3, 40), 40))
BENCH(mul64x32_shift, fx_mul64x32_shift(s64(i, 63), (int32_t)s64(i + 3, 31), 30))
BENCH(div_sat32, fx_div_sat32(s64(i, 24), (int32_t)s64(i + 5, 24) | 1, 16))
BENCH(div_round64, fx_div_round64(s64(i, 63), s64(i + 5, 40) | 1))
BENCH(div_shift64_wide, fx_div_shift64(s64(i, 62), s64(i + 5, 63) | 1, 30))
BENCH(muldiv64, fx_muldiv64(s64(i, 40), s64(i + 1, 20), s64(i + 2, 40) | 1))
BENCH(muldiv64_wide, fx_muldiv64(s64(i, 62), s64(i + 1, 40), s64(i + 2, 62) | 1))
BENCH(recip_q16, fx_recip_q16((int32_t)s64(i, 31) | 1))
BENCH(isqrt32, fx_isqrt32((uint32_t)mix(i)))
BENCH(isqrt64, fx_isqrt64(mix(i)))
BENCH(icbrt64, fx_icbrt64(mix(i)))
BENCH(sin, fx_sin((fx_angle_t)mix(i)))
BENCH(cos, fx_cos((fx_angle_t)mix(i)))
BENCH(atan2, fx_atan2(s64(i, 43), s64(i + 7, 43)))
BENCH(hypot2, fx_hypot2(s64(i, 30), s64(i + 1, 30)))
BENCH(hypot3, fx_hypot3(s64(i, 30), s64(i + 1, 30), s64(i + 2, 30)))
BENCH(hypot2_wide, fx_hypot2(s64(i, 62), s64(i + 1, 62)))
BENCH(hypot3_wide, fx_hypot3(s64(i, 61), s64(i + 1, 61), s64(i + 2, 61)))

static void bench_sincos(uint64_t i)
{
    q1_30_t s, c;
    fx_sincos((fx_angle_t)mix(i), &s, &c);
    sink += s + c;
}

static const struct {
    const char *name;
    void (*run)(uint64_t i);
} cases[] = {
    {"sat_mul32", bench_sat_mul32},
    {"mul64_shift", bench_mul64_shift},
    {"mul64x32_shift", bench_mul64x32_shift},
    {"div_sat32", bench_div_sat32},
    {"div_round64", bench_div_round64},
    {"div_shift64_wide", bench_div_shift64_wide},
    {"muldiv64", bench_muldiv64},
    {"muldiv64_wide", bench_muldiv64_wide},
    {"recip_q16", bench_recip_q16},
    {"isqrt32", bench_isqrt32},
    {"isqrt64", bench_isqrt64},
    {"icbrt64", bench_icbrt64},
    {"sin", bench_sin},
    {"cos", bench_cos},
    {"sincos", bench_sincos},
    {"atan2", bench_atan2},
    {"hypot2", bench_hypot2},
    {"hypot3", bench_hypot3},
    {"hypot2_wide", bench_hypot2_wide},
    {"hypot3_wide", bench_hypot3_wide},
};

int main(int argc, char **argv)
{
    uint64_t i, n = (argc > 2) ? strtoull(argv[2], NULL, 10) : 1000;
    size_t k;

    for (k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        if (argc > 1 && strcmp(argv[1], cases[k].name) == 0) {
            for (i = 0; i < n; i++) {
                cases[k].run(i);
            }
            return 0;
        }
    }
    fprintf(stderr, "bench_fixmath: unknown case '%s'\n", argc > 1 ? argv[1] : "");
    return 2;
}
