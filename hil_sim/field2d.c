/* 2-D error field of the simulated table: field2d.h. */
#include "field2d.h"

#include <math.h>
#include <string.h>

static bool all_finite(const double *v, unsigned n)
{
    unsigned i;
    for (i = 0; i < n; i++) {
        if (!isfinite(v[i])) {
            return false;
        }
    }
    return true;
}

bool field2d_set(field2d_t *f, unsigned nx, unsigned ny, double x0, double dx, double y0, double dy,
                 const double *col, const double *sig, unsigned nr, double r0, double dr,
                 const double *row, double band)
{
    unsigned g = nx * ny, c, d;
    f->on = false;
    if (nx == 0) {
        return true;
    }
    if (ny == 0 || nr == 0 || g > FIELD2D_GRID_MAX || nr > FIELD2D_ROW_MAX || !col || !sig ||
        !row || !(dx > 0.0) || !(dy > 0.0) || !(dr > 0.0) || !isfinite(x0) || !isfinite(y0) ||
        !isfinite(r0) || !(band >= 0.0) || !isfinite(dx) || !isfinite(dy) || !isfinite(dr) ||
        !all_finite(col, 4 * g) || !all_finite(sig, 2 * g) || !all_finite(row, 4 * nr)) {
        return false;
    }
    f->nx = nx;
    f->ny = ny;
    f->nr = nr;
    f->x0 = x0;
    f->dx = dx;
    f->y0 = y0;
    f->dy = dy;
    f->r0 = r0;
    f->dr = dr;
    f->band = band;
    for (c = 0; c < 2; c++) {
        for (d = 0; d < 2; d++) {
            memcpy(f->col[c][d], col + (c * 2 + d) * g, g * sizeof *col);
            memcpy(f->row[c][d], row + (c * 2 + d) * nr, nr * sizeof *row);
        }
        memcpy(f->sig[c], sig + c * g, g * sizeof *sig);
    }
    f->on = true;
    field2d_reset(f, 0.0, 0.0);
    return true;
}

void field2d_reset(field2d_t *f, double x, double y)
{
    f->dir[0] = 1;
    f->dir[1] = 1;
    f->turn[0] = x;
    f->turn[1] = y;
}

static void track(int *dir, double *turn, double p, double band)
{
    if (*dir > 0) {
        if (p > *turn) {
            *turn = p;
        } else if (p < *turn - band) {
            *dir = -1;
            *turn = p;
        }
    } else {
        if (p < *turn) {
            *turn = p;
        } else if (p > *turn + band) {
            *dir = 1;
            *turn = p;
        }
    }
}

void field2d_track(field2d_t *f, double x, double y)
{
    track(&f->dir[0], &f->turn[0], x, f->band);
    track(&f->dir[1], &f->turn[1], y, f->band);
}

/* Cell index and fraction along one grid axis, held beyond the ends. */
static unsigned cell(double p, double p0, double dp, unsigned n, double *frac)
{
    double u = (p - p0) / dp;
    unsigned i;
    if (n < 2 || !(u > 0.0)) {
        *frac = 0.0;
        return 0;
    }
    if (u >= (double)(n - 1)) {
        *frac = 1.0;
        return n - 2;
    }
    i = (unsigned)u;
    *frac = u - (double)i;
    return i;
}

static double bilinear(const field2d_t *f, const double *g, double x, double y)
{
    double fx, fy, a, b;
    unsigned ix = cell(x, f->x0, f->dx, f->nx, &fx);
    unsigned iy = cell(y, f->y0, f->dy, f->ny, &fy);
    unsigned ix1 = f->nx > 1 ? ix + 1 : ix, iy1 = f->ny > 1 ? iy + 1 : iy;
    a = g[iy * f->nx + ix] + fx * (g[iy * f->nx + ix1] - g[iy * f->nx + ix]);
    b = g[iy1 * f->nx + ix] + fx * (g[iy1 * f->nx + ix1] - g[iy1 * f->nx + ix]);
    return a + fy * (b - a);
}

static double linear(const field2d_t *f, const double *r, double x)
{
    double fr;
    unsigned i = cell(x, f->r0, f->dr, f->nr, &fr);
    unsigned i1 = f->nr > 1 ? i + 1 : i;
    return r[i] + fr * (r[i1] - r[i]);
}

void field2d_error(const field2d_t *f, double x, double y, double e[2])
{
    unsigned c;
    int dy = f->dir[1] > 0 ? 0 : 1, dx = f->dir[0] > 0 ? 0 : 1;
    for (c = 0; c < 2; c++) {
        e[c] = bilinear(f, f->col[c][dy], x, y) + linear(f, f->row[c][dx], x);
    }
}

double field2d_noise(const field2d_t *f, unsigned c, double x, double y)
{
    double s = bilinear(f, f->sig[c & 1u], x, y);
    return s > 0.0 ? s : 0.0;
}
