/*
 * comp2d.h - the 2-D compensation map of an X-Y table (issue 22): both
 * axes' corrections as functions of (X, Y), measured over a grid by a 2-D
 * reference (docs/calibration.md "The 2-D field").
 *
 * Specification
 * -------------
 *     comp2d_correct(map, raw, w, out);
 *
 * raw[0], raw[1]: the X and Y encoder readings, nm (after the 1-D tables,
 * if any). w[0], w[1]: the direction weights of X and Y (q1_30: +1 moving
 * +x / +y, -1 moving -x / -y, 0 unknown or halfway through a reversal ramp
 * - comp_ramp_t's weight). out[c] = raw[c] + corr_c with
 *
 *     corr_c = mid_c(x, y) + w_x * hx_c(x, y) + w_y * hy_c(x, y)
 *
 * mid: the mean correction of the four directions of approach; hx: half the
 * difference (+x approach - -x approach) and hy the same for Y, nm. Each of
 * the 6 grids has nx * ny nodes from (x0, y0) every (dx, dy) nm, node
 * (ix, iy) at index iy * nx + ix, stored as int16 in units of 2^shift nm
 * (shift <= COMP2D_SHIFT_MAX: +-32767 * 2^shift nm). Between nodes bilinear
 * interpolation, outside the grid the edge value held (clamped). Fixed
 * point: the weights are taken in q13 (steps of 1/8192 of a hysteresis
 * term), node values in q13 of 2^shift nm, fractions in q16 from a
 * precomputed reciprocal (no 64-bit division: comp2d_prepare), one
 * rounding at the end: within 1 nm + 2^shift / 8192 nm of the exact value.
 *
 * Limits (comp2d_check), each with its own refusal:
 *   version == COMP2D_VERSION                       COMP2D_E_VERSION
 *   2 <= nx, ny and nx * ny <= COMP2D_NODES_MAX       COMP2D_E_MEMORY
 *     (12 x 12: the map is 6 x 144 x 2 = 1728 bytes of RAM, which the
 *     STM32F4's 4 KiB of free RAM holds once; see comp2d_map_t)
 *   COMP2D_STEP_MIN_NM < dx, dy <= COMP2D_STEP_MAX_NM  COMP2D_E_STEP
 *   shift <= COMP2D_SHIFT_MAX                         COMP2D_E_STEP
 *   the grid inside the drive's field lo[a]..hi[a]     COMP2D_E_FIELD
 *
 * Contexts: comp2d_check / comp2d_prepare main (before the map is
 * published); comp2d_correct tick, read-only on a prepared map.
 * No heap, no floating point.
 */
#ifndef COMP2D_H
#define COMP2D_H

#include <stdint.h>

#include "fixmath.h"

#define COMP2D_VERSION     1u
#define COMP2D_NODES_MAX   144u
#define COMP2D_STEP_MIN_NM 65536u      /* 2^16 nm: the q16 reciprocal fits 32 bits */
#define COMP2D_STEP_MAX_NM 1000000000u /* 1 m */
#define COMP2D_SHIFT_MAX   8u

enum {
    COMP2D_OK = 0,
    COMP2D_E_VERSION = 1,
    COMP2D_E_MEMORY = 2,
    COMP2D_E_STEP = 3,
    COMP2D_E_FIELD = 4
};

enum { COMP2D_MID = 0, COMP2D_HX = 1, COMP2D_HY = 2 };

typedef struct {
    uint16_t version;
    uint8_t nx, ny;
    uint8_t shift;
    pos_nm_t x0, y0;                   /* first node, nm                        */
    uint32_t dx, dy;                   /* node spacing, nm                      */
    uint32_t inv_dx, inv_dy;           /* floor(2^48 / d): comp2d_prepare */
    int16_t g[2][3][COMP2D_NODES_MAX]; /* [axis][COMP2D_MID/HX/HY][node] */
} comp2d_map_t;

/* COMP2D_OK or the first refusal above. lo, hi: the drive's field per
 * axis, nm. */
int comp2d_check(const comp2d_map_t *m, const pos_nm_t lo[2], const pos_nm_t hi[2]);

/* The reciprocals; only on a map comp2d_check accepted. */
void comp2d_prepare(comp2d_map_t *m);

/* out = raw + the map's corrections (above). m NULL: out = raw. */
void comp2d_correct(const comp2d_map_t *m, const pos_nm_t raw[2], const q1_30_t w[2],
                    pos_nm_t out[2]);

#endif /* COMP2D_H */
