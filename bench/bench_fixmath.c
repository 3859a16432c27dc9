/* Calls one fixmath primitive N times on varied inputs, for callgrind. */
#include "fixmath.h"

#include <stdlib.h>
#include <string.h>

static volatile int64_t sink;

#define BENCH(name, expr)                                                                          \
    __attribute__((noinline)) static void bench_##name(uint64_t i)                                 \
    {                                                                                              \
        sink += (int64_t)(expr);                                                                   \
    }

static uint64_t mix(uint64_t i)
{
    return (i + 1) * 0x9E3779B97F4A7C15ull;
}

BENCH(isqrt64, fx_isqrt64(mix(i)))
BENCH(icbrt64, fx_icbrt64(mix(i)))
BENCH(sin, fx_sin((fx_angle_t)mix(i)))
BENCH(atan2, fx_atan2((int64_t)mix(i) >> 20, (int64_t)mix(i + 7) >> 20))
BENCH(hypot3,
      fx_hypot3((int64_t)mix(i) >> 34, (int64_t)mix(i + 1) >> 34, (int64_t)mix(i + 2) >> 34))
BENCH(mul64_shift, fx_mul64_shift((int64_t)mix(i), (int64_t)mix(i + 3) >> 20, 40))
BENCH(div_sat32, fx_div_sat32((int64_t)mix(i) >> 40, (int32_t)(mix(i + 5) >> 40) | 1, 16))

int main(int argc, char **argv)
{
    uint64_t i, n = (argc > 2) ? strtoull(argv[2], NULL, 10) : 1000;
    const char *fn = (argc > 1) ? argv[1] : "";
    for (i = 0; i < n; i++) {
        if (!strcmp(fn, "isqrt64")) {
            bench_isqrt64(i);
        } else if (!strcmp(fn, "icbrt64")) {
            bench_icbrt64(i);
        } else if (!strcmp(fn, "sin")) {
            bench_sin(i);
        } else if (!strcmp(fn, "atan2")) {
            bench_atan2(i);
        } else if (!strcmp(fn, "hypot3")) {
            bench_hypot3(i);
        } else if (!strcmp(fn, "mul64_shift")) {
            bench_mul64_shift(i);
        } else if (!strcmp(fn, "div_sat32")) {
            bench_div_sat32(i);
        }
    }
    return 0;
}
