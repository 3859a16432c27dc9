/*
 * libFuzzer harness: the 2-D map record parser (comp2d_decode, what
 * comp2d_commit runs on uploaded bytes). Any input: no read past it; a
 * record it accepts encodes back to the same bytes; one comp2d_check
 * accepts is evaluated (comp2d_correct, comp2d_linearize) at positions
 * over and beyond the grid without overflow (UBSan) and the tick's
 * linearisation at its anchor stays within the rounding of comp2d_correct
 * (its weights in q13) of it.
 */
#include <stdint.h>
#include <string.h>

#include "comp2d.h"
#include "comp2d_live.h"

static comp2d_map_t m;
static uint8_t again[COMP2D_RECORD_MAX];

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const pos_nm_t lo[2] = {-((pos_nm_t)1 << 50), -((pos_nm_t)1 << 50)};
    static const pos_nm_t hi[2] = {(pos_nm_t)1 << 50, (pos_nm_t)1 << 50};
    uint32_t n;
    int k;
    if (size > 4096u || comp2d_decode(data, (uint32_t)size, &m) != COMP2D_OK) {
        return 0;
    }
    n = comp2d_encode(&m, again, sizeof again);
    if (n != size || memcmp(again, data, size) != 0) {
        __builtin_trap();
    }
    if (comp2d_check(&m, lo, hi) != COMP2D_OK) {
        return 0;
    }
    comp2d_prepare(&m);
    comp2d_live_init();
    comp2d_live_set(&m);
    for (k = -2; k <= (int)m.nx + 1; k++) {
        pos_nm_t p[2], f[2], t[2], x, y;
        q1_30_t w[2];
        const int64_t v[2] = {k & 1, -(k & 2)};
        /* comp2d_correct rounds the weights to q13: 2 x 32767 x 2^shift
         * nm / 8192 while a weight ramps, plus its own 1 nm + 2^shift */
        const int64_t tol = 3 + 9 * ((int64_t)1 << m.shift);
        p[0] = m.x0 + (pos_nm_t)k * m.dx + (pos_nm_t)(m.dx / 3u);
        p[1] = m.y0 + (pos_nm_t)(k % ((int)m.ny + 1)) * m.dy - (pos_nm_t)(m.dy / 7u);
        comp2d_live_poll(p, v, (uint32_t)k * 100u);
        w[0] = comp2d_live_pub->wx;
        w[1] = comp2d_live_pub->wy;
        comp2d_correct(&m, p, w, f);
        x = p[0];
        y = p[1];
        comp2d_live_apply(&x, &y, &t[0], &t[1]);
        if (t[0] - f[0] > tol || f[0] - t[0] > tol || t[1] - f[1] > tol || f[1] - t[1] > tol) {
            __builtin_trap();
        }
    }
    return 0;
}
