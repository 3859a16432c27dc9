/* 2-D error field of the simulated X-Y table (issue 22).
 *
 * The true table position of X and Y is the nominal one (l th2, plus the
 * axis's own pitch map) plus e_X(x, y) and e_Y(x, y): positioning error
 * along an axis and straightness across it, as a 2-D grid encoder such as
 * the HEIDENHAIN KGM 101 sees them. Each axis's reference scale (its
 * auxiliary input) reads that true position, so the drive reads both
 * coordinates of the table.
 *
 * The field is given in two parts (host_tools/contour/sim/field2d.py builds
 * them from the thesis's lines, docs/calibration.md "The 2-D field"):
 *  - col: per component c (0 = X error, 1 = Y error) and direction of Y
 *    (0 = moving +y, 1 = moving -y), a regular grid nx x ny from (x0, y0)
 *    with steps dx, dy, interpolated bilinearly and held beyond its edges;
 *  - row: per component and direction of X, a regular 1-D table nr from r0
 *    step dr over x, linear, held beyond its ends, added to the grid.
 * Plus sig: per component, a grid like col, the rms reading noise of the
 * reference scale at (x, y) (replaces the axis's ref_noise while on).
 *
 * The direction of each axis is tracked like the pitch map's: it turns when
 * the axis has moved back by more than `band` (m).
 *
 * All lengths in m. Off (field2d_on false) unless field2d_set succeeded.
 */
#ifndef FIELD2D_H
#define FIELD2D_H

#include <stdbool.h>

#define FIELD2D_GRID_MAX 256u
#define FIELD2D_ROW_MAX  64u

typedef struct {
    bool on;
    unsigned nx, ny, nr;
    double x0, dx, y0, dy, r0, dr, band;
    double col[2][2][FIELD2D_GRID_MAX]; /* [comp][dir y][iy * nx + ix] */
    double sig[2][FIELD2D_GRID_MAX];    /* [comp][iy * nx + ix]        */
    double row[2][2][FIELD2D_ROW_MAX];  /* [comp][dir x][i]            */
    int dir[2];                         /* +1 / -1 per axis            */
    double turn[2];                     /* where the direction last changed */
} field2d_t;

/* Check and copy a field (col: 2*2*ny*nx, sig: 2*ny*nx, row: 2*2*nr values,
 * in that order, row-major). false (field left off) on bad sizes, steps
 * <= 0 or values that are not finite; nx = 0 turns the field off. */
bool field2d_set(field2d_t *f, unsigned nx, unsigned ny, double x0, double dx, double y0, double dy,
                 const double *col, const double *sig, unsigned nr, double r0, double dr,
                 const double *row, double band);

/* Start tracking directions at nominal (x, y) moving +x, +y. */
void field2d_reset(field2d_t *f, double x, double y);

/* Track the directions with the nominal position (x, y). */
void field2d_track(field2d_t *f, double x, double y);

/* e[0] = X error, e[1] = Y error at nominal (x, y), tracked directions. */
void field2d_error(const field2d_t *f, double x, double y, double e[2]);

/* Reference reading noise (rms, m) of component c at (x, y). */
double field2d_noise(const field2d_t *f, unsigned c, double x, double y);

#endif
