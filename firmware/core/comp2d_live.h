/*
 * comp2d_live.h - the 2-D compensation map (comp2d.h) applied in the
 * control tick (issue 22) at a cost the Cortex-M4 tick can pay.
 *
 * Specification
 * -------------
 * The full bilinear evaluation (comp2d_correct, ~260 M4 instructions) runs
 * in the main context. comp2d_live_poll (main) linearises the map at the
 * axes' position p = (X, Y) (after the 1-D tables, before the map) with the
 * current direction weights w = (wx, wy) (the 1-D tables' reversal ramps,
 * comp_ramp_t, q1_30) and publishes the anchor below; the tick
 * (comp2d_live_apply, inside drive_inputs_sample) adds to X and Y
 *
 *     corr_c = k_c + gx_c * dx + gy_c * dy                  (dx = X - x0 ...)
 *              [+ (wx - wpx) * hx_c + (wy - wpy) * hy_c      w != wp only]
 *
 * k: the correction at the anchor with the weights wp it was made with;
 * gx, gy: the slopes of that correction in the anchor's cell (q32 nm/nm);
 * hx, hy: the direction terms at the anchor. At the anchor and at rest
 * this is the bilinear map itself (within 2 nm of rounding); moving, it
 * differs from it by
 *     |cross_c| * |dx| * |dy|        (the cell's bilinear twist)
 *   + |slope change| * (way past a cell edge before main re-anchors)
 *   + |w - wp| * |d(hx, hy)| * |d|   (a reversal ramp between anchors)
 * main re-anchors when X or Y has moved more than COMP2D_LIVE_MOVE_DIV-th
 * of the node spacing from the anchor, left the anchor's cell, or the
 * weights differ from wp, so with main polling once a tick the difference
 * stays below 0.05 um on the thesis field at 20 mm/s
 * (tests/unit/test_comp2d_live.c). dx, dy are taken from the low 32 bits
 * and held at +-2^24 nm (16.8 mm): a main context stalled for longer than
 * that much travel leaves the correction extrapolated by at most that.
 *
 * Cost in the tick (map loaded, weights as published): 2 x 2 multiplies,
 * about 40 M4 instructions (control_tick_instructions_m4); without a map
 * one load and a branch.
 *
 * Contexts: the map is main's (the tick never reads it: replacing it needs
 * no second copy). Anchors: double-buffered; main fills the one not
 * published, CORE_BARRIER(), then stores the pointer comp2d_live_pub (one
 * store); the tick reads the pointer once per tick and then only that
 * buffer, which main does not write until it has published the other one
 * (the tick runs to completion before main resumes: one core). The weights
 * are the ramps' (written by calib_tick, tick). No heap, no floating point.
 */
#ifndef COMP2D_LIVE_H
#define COMP2D_LIVE_H

#include <stdbool.h>
#include <stdint.h>
#if defined(__ARM_FEATURE_SAT)
#include <arm_acle.h>
#endif

#include "comp.h"
#include "comp2d.h"
#include "preempt.h"
#include "servo.h"

#define COMP2D_LIVE_MOVE_DIV 128       /* re-anchor after node spacing / 128 */
#define COMP2D_LIVE_SPAN     (1 << 24) /* |dx|, |dy| held here, nm */

typedef struct {
    int32_t x0, y0;       /* anchor: low 32 bits of X and Y, nm            */
    int32_t k[2];         /* correction at the anchor with the weights wp  */
    int32_t gx[2], gy[2]; /* its slopes in the anchor's cell, q32 nm / nm  */
    int32_t wx, wy;       /* the weights wp (main's record), q1_30         */
} comp2d_anchor_t;

/* The published anchor (main writes, one pointer store; tick reads). NULL:
 * no map. */
extern const comp2d_anchor_t *CORE_SHARED comp2d_live_pub;
/* The direction weights of X and Y (comp2d_live_init; never NULL). */
extern const volatile int32_t *comp2d_live_w[2];

/* No map; weights from rx, ry (NULL: 0, the mean of both directions).
 * Main, before the tick runs. */
void comp2d_live_init(const comp_ramp_t *rx, const comp_ramp_t *ry);

/* Use map m (checked and prepared: comp2d_check, comp2d_prepare; copied)
 * from the next comp2d_live_poll on; NULL: no map, the tick stops
 * correcting at once. Main. */
void comp2d_live_set(const comp2d_map_t *m);

/* The map in use (NULL: none). Main. */
const comp2d_map_t *comp2d_live_map(void);

/* Re-anchor at p (X, Y before the map, nm) when needed (see top). Main. */
void comp2d_live_poll(const pos_nm_t p[2]);

/* Re-anchors published since init (tests, diagnostics). Main. */
uint32_t comp2d_live_anchors(void);

/* hi word of a * b: one SMULL on the M4 */
static inline int32_t comp2d_live_mulhi(int32_t a, int32_t b)
{
    return (int32_t)(((int64_t)a * b) >> 32);
}

/* d held at +-COMP2D_LIVE_SPAN (one SSAT on the M4) */
static inline int32_t comp2d_live_hold(int32_t d)
{
#if defined(__ARM_FEATURE_SAT)
    return __ssat(d, 25);
#else
    return d > COMP2D_LIVE_SPAN - 1 ? COMP2D_LIVE_SPAN - 1
                                    : (d < -COMP2D_LIVE_SPAN ? -COMP2D_LIVE_SPAN : d);
#endif
}

/* Add the published correction to X and Y: *px, *py before the map ->
 * after it, and the same into *fx, *fy. Tick. */
static inline void comp2d_live_apply(pos_nm_t *px, pos_nm_t *py, pos_nm_t *fx, pos_nm_t *fy)
{
    const comp2d_anchor_t *a = comp2d_live_pub;
    pos_nm_t x, y;
    int32_t dx, dy;
    if (a == 0) {
        return;
    }
    x = *px;
    y = *py;
    dx = comp2d_live_hold((int32_t)((uint32_t)x - (uint32_t)a->x0));
    dy = comp2d_live_hold((int32_t)((uint32_t)y - (uint32_t)a->y0));
    x += a->k[0] + comp2d_live_mulhi(a->gx[0], dx) + comp2d_live_mulhi(a->gy[0], dy);
    y += a->k[1] + comp2d_live_mulhi(a->gx[1], dx) + comp2d_live_mulhi(a->gy[1], dy);
    *px = *fx = x;
    *py = *fy = y;
}

#endif /* COMP2D_LIVE_H */
