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

#include <stdbool.h>
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
    COMP2D_E_FIELD = 4,
    COMP2D_E_MAGIC = 5,  /* comp2d_decode: not a map record      */
    COMP2D_E_LENGTH = 6, /* comp2d_decode: length != the grid's  */
    COMP2D_E_CRC = 7     /* the link: CRC-32 of the record      */
};

/* The record (wire and flash, little-endian; comp2d_encode / _decode):
 *   0 u32 magic "C2DM"  4 u16 version (COMP2D_VERSION)  6 u8 nx  7 u8 ny
 *   8 u8 shift  9..11 0  12 i64 x0 nm  20 i64 y0 nm  28 u32 dx nm
 *   32 u32 dy nm  36 i16 nodes g[axis][mid, hx, hy][iy * nx + ix]
 * length COMP2D_RECORD_HDR + 12 * nx * ny (at most COMP2D_RECORD_MAX). */
#define COMP2D_RECORD_MAGIC 0x4D443243u /* "C2DM" */
#define COMP2D_RECORD_HDR   36u
#define COMP2D_RECORD_MAX   (COMP2D_RECORD_HDR + 12u * COMP2D_NODES_MAX)

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

/* Record bytes of m into buf (cap bytes); the length, 0 when it does not
 * fit or nx * ny > COMP2D_NODES_MAX. */
uint32_t comp2d_encode(const comp2d_map_t *m, uint8_t *buf, uint32_t cap);

/* Parse a record of exactly len bytes into m (any bytes: the upload
 * parser, fuzzed): COMP2D_E_MAGIC (magic, reserved bytes), _VERSION,
 * _MEMORY (nx, ny out of 2..: more than COMP2D_NODES_MAX nodes; checked
 * before the length), _LENGTH, or COMP2D_OK; then comp2d_check for the
 * spacing and the field. m may hold part of the record after a refusal. */
int comp2d_decode(const uint8_t *buf, uint32_t len, comp2d_map_t *m);

/* The reciprocals; only on a map comp2d_check accepted. */
void comp2d_prepare(comp2d_map_t *m);

/* out = raw + the map's corrections (above). m NULL: out = raw. */
void comp2d_correct(const comp2d_map_t *m, const pos_nm_t raw[2], const q1_30_t w[2],
                    pos_nm_t out[2]);

/* The map linearised at p for the tick (comp2d_live.h): per axis a the
 * mean correction mid, the direction terms hx, hy at p (nm, each as
 * comp2d_correct gives it: with w = (0, 0), (1, 0), (0, 1)), and the slopes
 * of the whole correction with the weights w in p's cell, q32 nm per nm
 * (0 along a coordinate held beyond the grid's edge), saturated at +-1/2
 * nm per nm (a calibration map is a thousand times flatter). Main. */
typedef struct {
    int32_t mid[2], hx[2], hy[2];
    int32_t gx[2], gy[2];
} comp2d_lin_t;
void comp2d_linearize(const comp2d_map_t *m, const pos_nm_t p[2], const q1_30_t w[2],
                      comp2d_lin_t *out);

#endif /* COMP2D_H */
