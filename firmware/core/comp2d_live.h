/*
 * comp2d_live.h - the 2-D compensation map (comp2d.h) applied in the
 * control tick (issue 22) at a cost the Cortex-M4 tick can pay.
 *
 * Specification
 * -------------
 * The full bilinear evaluation (comp2d_correct, ~260 M4 instructions) runs
 * in the main context. comp2d_live_poll (main) linearises the map at the
 * axes' position p = (X, Y) (after the 1-D tables, before the map) with the
 * direction weights w = (wx, wy) (q1_30, below) and publishes the anchor;
 * the tick (comp2d_live_apply, inside drive_inputs_sample) adds to X and Y
 *
 *     corr_c = k_c + gx_c * dx + gy_c * dy                  (dx = X - x0 ...)
 *
 * k: the correction at the anchor with the weights it was made with;
 * gx, gy: the slopes of that correction in the anchor's cell (q32 nm/nm).
 * At the anchor and at rest this is the bilinear map itself (within 2 nm
 * of rounding); moving, it differs from the map with the published
 * weights by at most
 *     |cross_c| * |dx| * |dy|        (the cell's bilinear twist)
 *   + |slope change| * (way past a cell edge before main re-anchors)
 * and from the map with the weights of this very moment by |dw| * |h|
 * more while a direction ramps (20 ms) and main has not polled yet. Main
 * re-anchors when X or Y has moved more than COMP2D_LIVE_MOVE_DIV-th of the
 * node spacing from the anchor, left the anchor's cell, or a weight
 * changed, so with main polling once a tick the difference stays below
 * 0.05 um at 20 mm/s on a field steeper than the thesis's
 * (tests/unit/test_comp2d_live.c: 16 nm).
 *
 * Directions: each axis has the direction of its command (reference
 * velocity v, held while v = 0), as the 1-D tables; the weight ramps to a
 * new direction over COMP2D_LIVE_RAMP_US (the feedback changes by at most
 * |2h| / ramp). Before the first commanded motion: w = 0, the mean of both
 * directions. (An axis standing still is moved by the map's own
 * straightness correction while the other travels, and a table whose
 * error depends on that axis's direction changes state with that motion:
 * the grid calibration measures the nodes a second time with the first
 * map in use and corrects it, so the map holds what the table does with
 * the compensation on; docs/calibration.md.)
 *
 * dx, dy are taken from the low 32 bits and held at +-2^24 nm (16.8 mm):
 * a main context stalled for longer than that much travel leaves the
 * correction extrapolated by at most that.
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
#define COMP2D_LIVE_RAMP_US  20000     /* direction ramp, us                 */

typedef struct {
    int32_t x0, y0;       /* anchor: low 32 bits of X and Y, nm            */
    int32_t k[2];         /* correction at the anchor with the weights wp  */
    int32_t gx[2], gy[2]; /* its slopes in the anchor's cell, q32 nm / nm  */
    int32_t wx, wy;       /* the weights wp (main's record), q1_30         */
} comp2d_anchor_t;

/* The published anchor (main writes, one pointer store; tick reads). NULL:
 * no map. */
extern const comp2d_anchor_t *CORE_SHARED comp2d_live_pub;

/* No map, no direction yet. Main, before the tick runs. */
void comp2d_live_init(void);

/* The direction weights main uses now (q1_30; tests, diagnostics). Main. */
void comp2d_live_weights(int32_t w[2]);

/* Use map m (checked and prepared: comp2d_check, comp2d_prepare; copied)
 * from the next comp2d_live_poll on; NULL: no map, the tick stops
 * correcting at once. Main. */
void comp2d_live_set(const comp2d_map_t *m);

/* The map in use (NULL: none). Main. */
const comp2d_map_t *comp2d_live_map(void);

/* Follow the directions and re-anchor at p (X, Y before the map, nm) when
 * needed (see top); v: X and Y's reference velocities (the sign counts);
 * now_us: a free-running microsecond clock. Main, every main-loop pass. */
void comp2d_live_poll(const pos_nm_t p[2], const int64_t v[2], uint32_t now_us);

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
