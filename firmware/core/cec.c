/*
 * cec.c - contour error estimates and the contour error controller;
 * specification in cec.h.
 */
#include "cec.h"
#include "cec_hist.h"
#include "cec_test.h"

#include <stddef.h>

/* Maclaurin coefficients of sec(g) - 1 divided by g^2, q1_30:
 * 1/2, 5/24, 61/720, 277/8064, 50521/3628800 (g <= 0.5: error < 2e-6 r). */
#define SEC_C0 536870912
#define SEC_C1 223696213
#define SEC_C2 90969793
#define SEC_C3 36883245
#define SEC_C4 14948884

#define GAMMA_MAX_Q30 ((int64_t)1 << 29) /* 0.5 rad */
#define PLUNGE_LEN2   ((int64_t)1 << 40) /* |t x e_w|^2 below (2^-10)^2 in q60 */
#define UNIT_TOL2     ((int64_t)1 << 33) /* |len^2 - 1| tolerated without normalising */
#define OFFPLANE_Q30  1024               /* |t_w| above 2^-20: second channel on */
#if defined(__GNUC__)
#define CEC_NOINLINE __attribute__((noinline))
#else
#define CEC_NOINLINE
#endif
/* cos 30 degrees, q60: a LINE join turning more restarts the history */
#define HIST_CORNER_COS_Q60 ((int64_t)998459311558907264)

/* ---- estimators ------------------------------------------------------------ */

/* fx_div_sat32(num, den, 30), the same value: for 0 < den and |num| < 2^33
 * the numerator fits 64 bits, so one 64-bit division: ties away from zero
 * as floor((|num| 2^30 + floor(den / 2)) / den) with num's sign (the
 * remainder r of |num| 2^30 / den rounds up exactly when 2 r >= den), which
 * C's truncating division of num 2^30 -+ floor(den / 2) gives directly. */
static inline int32_t div_q30(int64_t num, int32_t den)
{
    int64_t h = den >> 1;
    if (den <= 0 || fx_uabs64(num) >= ((uint64_t)1 << 33)) {
        return fx_div_sat32(num, den, 30);
    }
    return fx_sat32_fast((num * ((int64_t)1 << 30) + ((num < 0) ? -h : h)) / den);
}

/* The normals of a tangent off the plane normal (t x e_w at least 2^-10
 * long, len2 = |t x e_w|^2): c = t x e_w = (c_u, c_v) = (t_v, -t_u) in the
 * plane, n1_w = 0, no plunge. As the general path below computes them (the
 * same operations on the same values); n2 = n1 x t without its two zero
 * products when t_w = 0. tu, tv, tw: t's components. */
static PID_ALWAYS_INLINE void normals_plane(q1_30_t tu, q1_30_t tv, q1_30_t tw, unsigned w,
                                            unsigned u, unsigned v, int64_t len2, q1_30_t n1[3],
                                            q1_30_t n2[3], uint32_t *hint)
{
    int64_t cu = tv, cv = -(int64_t)tu, n1u, n1v;
    /* |len2 - 2^60| > UNIT_TOL2 (len2 - 2^60 >= -2^60: no overflow) */
    if ((uint64_t)(len2 - ((int64_t)1 << 60) + UNIT_TOL2) > 2u * (uint64_t)UNIT_TOL2) {
        int32_t len;
        /* scale short vectors up first so that the root keeps 30 bits:
         * while |c_u|, |c_v| < 2^29 (|c| <= 2^31 here, doubled below 2^30) */
        while ((uint64_t)(cu + ((int64_t)1 << 29) - 1) < ((uint64_t)1 << 30) - 1u &&
               (uint64_t)(cv + ((int64_t)1 << 29) - 1) < ((uint64_t)1 << 30) - 1u) {
            cu *= 2;
            cv *= 2;
        }
        *hint = fx_isqrt64_near((uint64_t)(cu * cu + cv * cv), *hint);
        len = (int32_t)*hint;
        if (len > 0) {
            /* div_q30 without its range tests: |c| <= 2^31 and len >=
             * |c_u|, |c_v| (the floor of a root over an integer), so the
             * quotient is at most 2^30 */
            int64_t h = len >> 1;
            n1u = (cu * ((int64_t)1 << 30) + ((cu < 0) ? -h : h)) / len;
            n1v = (cv * ((int64_t)1 << 30) + ((cv < 0) ? -h : h)) / len;
        } else {
            n1u = div_q30(cu, len);
            n1v = div_q30(cv, len);
        }
    } else {
        n1u = (q1_30_t)cu;
        n1v = (q1_30_t)cv;
    }
    n1[u] = (q1_30_t)n1u;
    n1[v] = (q1_30_t)n1v;
    n1[w] = 0;
    if (tw == 0) {
        n2[u] = 0;
        n2[v] = 0;
    } else {
        n2[u] = (q1_30_t)fx_round_shift64(n1v * tw, 30);
        n2[v] = (q1_30_t)fx_round_shift64(-n1u * tw, 30);
    }
    n2[w] = (q1_30_t)fx_round_shift64(n1u * tv - n1v * tu, 30);
}

/* cec_normals; *hint: the last root of this caller (fx_isqrt64_near). */
static bool normals_near(const q1_30_t t[3], unsigned w, q1_30_t n1[3], q1_30_t n2[3],
                         uint32_t *hint)
{
    int64_t c[3], len2;
    int k;

    if (w < 3u) {
        unsigned u = (w == 2u) ? 0u : w + 1u, v = (w == 0u) ? 2u : w - 1u;
        int64_t cu = t[v], cv = -(int64_t)t[u];
        len2 = cu * cu + cv * cv;
        if (len2 >= PLUNGE_LEN2) {
            normals_plane(t[u], t[v], t[w], w, u, v, len2, n1, n2, hint);
            return true;
        }
    }
    if (t[0] == 0 && t[1] == 0 && t[2] == 0) {
        return false;
    }
    /* c = t x e_w */
    if (w == 0) {
        c[0] = 0;
        c[1] = t[2];
        c[2] = -(int64_t)t[1];
    } else if (w == 1) {
        c[0] = -(int64_t)t[2];
        c[1] = 0;
        c[2] = t[0];
    } else {
        c[0] = t[1];
        c[1] = -(int64_t)t[0];
        c[2] = 0;
    }
    len2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    if (len2 < PLUNGE_LEN2) {
        /* travel along the plane normal: n1 = e_u made orthogonal to t */
        unsigned u = (w + 1u) % 3u;
        for (k = 0; k < 3; k++) {
            c[k] = -(int64_t)(int32_t)fx_mul32_shift(t[u], t[k], 30);
        }
        c[u] += FX_ONE_Q30;
        len2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    }
    if (fx_sat_abs64(len2 - ((int64_t)1 << 60)) > UNIT_TOL2) {
        int32_t len;
        if (len2 == 0) {
            return false;
        }
        /* scale short vectors up first so that the root keeps 30 bits */
        while (fx_sat_abs64(c[0]) < ((int64_t)1 << 29) && fx_sat_abs64(c[1]) < ((int64_t)1 << 29) &&
               fx_sat_abs64(c[2]) < ((int64_t)1 << 29)) {
            c[0] *= 2;
            c[1] *= 2;
            c[2] *= 2;
        }
        len2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
        *hint = fx_isqrt64_near((uint64_t)len2, *hint);
        len = (int32_t)*hint;
        for (k = 0; k < 3; k++) {
            /* 0 / len is 0 (len >= 1): the plane normal's component of an
             * in-plane tangent needs no division */
            n1[k] = (c[k] == 0) ? 0 : div_q30(c[k], len);
        }
    } else {
        for (k = 0; k < 3; k++) {
            n1[k] = (q1_30_t)c[k];
        }
    }
    /* n2 = n1 x t */
    n2[0] = (q1_30_t)fx_round_shift64((int64_t)n1[1] * t[2] - (int64_t)n1[2] * t[1], 30);
    n2[1] = (q1_30_t)fx_round_shift64((int64_t)n1[2] * t[0] - (int64_t)n1[0] * t[2], 30);
    n2[2] = (q1_30_t)fx_round_shift64((int64_t)n1[0] * t[1] - (int64_t)n1[1] * t[0], 30);
    return true;
}

bool cec_normals(const q1_30_t t[3], unsigned w, q1_30_t n1[3], q1_30_t n2[3])
{
    uint32_t hint = 0;
    return normals_near(t, w, n1, n2, &hint);
}

int32_t cec_dot(const int32_t e[3], const q1_30_t n[3])
{
    int64_t s = (int64_t)e[0] * n[0] + (int64_t)e[1] * n[1] + (int64_t)e[2] * n[2];
    return fx_sat32_fast(fx_round_shift64(s, 30));
}

int32_t cec_est_koren(int32_t ex, int32_t ey, int64_t rx, int64_t ry)
{
    int64_t num, den;
    while (fx_sat_abs64(rx) >= ((int64_t)1 << 30) || fx_sat_abs64(ry) >= ((int64_t)1 << 30)) {
        rx /= 2;
        ry /= 2;
    }
    den = fx_hypot2(rx, ry);
    if (den == 0) {
        return 0;
    }
    num = ry * ex - rx * ey;
    return fx_sat32_fast(fx_div_round64(num, den));
}

/* r (sec g - 1) for g = x = e / r (q1_30), e = e_abs > 0, r > 0. */
static int32_t curv_corr_x(int32_t e_abs, pos_nm_t r, int64_t x)
{
    int64_t x2, h, xh, e_eff = e_abs;
    if (x > GAMMA_MAX_Q30) {
        x = GAMMA_MAX_Q30;
        e_eff = (r / 2 < e_abs) ? r / 2 : e_abs;
    }
    x2 = fx_round_shift64(x * x, 30);
    h = SEC_C4;
    h = SEC_C3 + fx_round_shift64(x2 * h, 30);
    h = SEC_C2 + fx_round_shift64(x2 * h, 30);
    h = SEC_C1 + fx_round_shift64(x2 * h, 30);
    h = SEC_C0 + fx_round_shift64(x2 * h, 30);
    xh = fx_round_shift64(x * h, 30); /* r (sec g - 1) / e, q1_30 */
    return (int32_t)fx_round_shift64(e_eff * xh, 30);
}

static int32_t curv_corr(int32_t e_abs, pos_nm_t r, pid_coef_t inv_r)
{
    if (e_abs <= 0 || r <= 0) {
        return 0;
    }
    return curv_corr_x(e_abs, r, pid_coef_apply(inv_r, e_abs)); /* e / r, q1_30 */
}

/* As curv_corr for a radius that changes in the tick: one division. */
static int32_t curv_corr_div(int32_t e_abs, pos_nm_t r)
{
    if (e_abs <= 0 || r <= 0) {
        return 0;
    }
    return curv_corr_x(e_abs, r, fx_div_round64((int64_t)e_abs << 30, r));
}

int32_t cec_curv_correction(int32_t e_abs, pos_nm_t radius)
{
    pid_coef_t inv;
    if (radius <= 0 || e_abs <= 0 || !pid_coef_make(&inv, FX_ONE_Q30, 1, (uint64_t)radius)) {
        return 0;
    }
    return curv_corr(e_abs, radius, inv);
}

/* floor(sqrt(v)) for v = |P - C|^2 < 2^63 of a point near the arc of radius r
 * (0 < r < 2^31), without a division on the usual tick: s = r + (v - r^2) /
 * (2 r) from inv ~ 2^30 / r (the segment's inv_r, 15 of its bits), then
 * checked, s^2 <= v < (s + 1)^2, one step either way (the estimate is
 * within one of the root for |v - r^2| up to about r 2^14). Otherwise (far
 * from the arc, no inv) fx_isqrt64_near from *hint. Exact for any inv:
 * test_cec.c, test_exact_arc_root. */
static inline uint32_t arc_root(uint64_t v, pos_nm_t r, pid_coef_t inv, uint32_t *hint)
{
    if ((uint64_t)r - 1u < (uint64_t)INT32_MAX - 1u) {
        int64_t d = (int64_t)v - r * r; /* v < 2^63, r^2 < 2^62 */
        /* any shift is exact (only the estimate depends on it): inv of
         * 0 < r < 2^31 has inv.sh + 15 in 15..46 */
        unsigned sh = (unsigned)(inv.sh + 15) & 63u;
        bool near = (uint64_t)d + ((uint64_t)1 << 40) < ((uint64_t)1 << 41); /* |d| < 2^40 */
        int64_t dn = near ? d : 0;
        uint64_t s = (uint64_t)(r + ((dn * (inv.m >> 16)) >> sh)), sq = s * s; /* |dn m| < 2^55 */

        if (near && s - 1u < (uint64_t)UINT32_MAX - 1u) { /* 1 <= s < 2^32 - 1 */
            if (sq > v) {
                s--;
                sq = s * s;
                if (sq <= v) {
                    *hint = (uint32_t)s; /* v < (s + 1)^2: the step above */
                    return (uint32_t)s;
                }
            } else if (v - sq <= 2u * s) { /* v < (s + 1)^2 */
                *hint = (uint32_t)s;
                return (uint32_t)s;
            } else if (v - sq - 2u * s - 1u <= 2u * s + 2u) { /* (s + 1)^2 <= v < (s + 2)^2 */
                *hint = (uint32_t)s + 1u;
                return (uint32_t)s + 1u;
            }
        }
    }
    *hint = fx_isqrt64_near(v, *hint);
    return *hint;
}

/* cec_exact_arc; *hint: the last root of this caller (fx_isqrt64_near,
 * taken where fx_hypot2 takes its one 64-bit root); inv: 2^30 / radius
 * (arc_root; m = 0: none). */
static PID_ALWAYS_INLINE int32_t exact_arc_near(pos_nm_t pu, pos_nm_t pv, pos_nm_t cu, pos_nm_t cv,
                                                pos_nm_t radius, int s, uint32_t *hint,
                                                pid_coef_t inv)
{
    int64_t x = pu - cu, y = pv - cv, rho, d;
    uint64_t ax = fx_uabs64(x), ay = fx_uabs64(y);
    if ((ax | ay) < ((uint64_t)1 << 31)) {
        rho = arc_root(ax * ax + ay * ay, radius, inv, hint);
    } else {
        rho = fx_hypot2(x, y);
    }
    d = rho - radius;
    return fx_sat32_fast((s < 0) ? -d : d);
}

/* Test hook: div_q30 (cec_test.h). */
int32_t cec_div_q30_test(int64_t num, int32_t den)
{
    return div_q30(num, den);
}

/* Test hook: arc_root (cec_test.h). */
uint32_t cec_arc_root_test(uint64_t v, pos_nm_t r, pid_coef_t inv, uint32_t *hint)
{
    return arc_root(v, r, inv, hint);
}

int32_t cec_exact_arc(pos_nm_t pu, pos_nm_t pv, pos_nm_t cu, pos_nm_t cv, pos_nm_t radius, int s)
{
    uint32_t hint = 0;
    pid_coef_t none = {0, 0};
    return exact_arc_near(pu, pv, cu, cv, radius, s, &hint, none);
}

#define CIRCLE_E_MAX ((int64_t)1 << 30) /* E's plane components clamped (1.07 m) */

/* cec_curv_circle; *hint: the last root of this caller (as exact_arc_near).
 * s (rho - r) = (s |E|^2 + 2 r (E . n1)) / (rho + r): the difference of
 * the squares is exact, so rho (from the rounded r n1) only scales it. */
static int32_t curv_circle_near(int32_t eu, int32_t ev, q1_30_t n1u, q1_30_t n1v, pos_nm_t r, int s,
                                uint32_t *hint)
{
    int64_t ecu = fx_clamp_sym64(eu, CIRCLE_E_MAX), ecv = fx_clamp_sym64(ev, CIRCLE_E_MAX);
    int64_t a = fx_round_shift64(ecu * n1u + ecv * n1v, 30);             /* E . n1 */
    int64_t xu = ecu + ((s < 0) ? -1 : 1) * fx_mul64x32_shift30(r, n1u); /* C - P */
    int64_t xv = ecv + ((s < 0) ? -1 : 1) * fx_mul64x32_shift30(r, n1v);
    uint64_t ax = fx_uabs64(xu), ay = fx_uabs64(xv);
    int64_t rho, den, e2 = ecu * ecu + ecv * ecv;
    if (r <= 0) {
        return 0;
    }
    if ((ax | ay) < ((uint64_t)1 << 31)) {
        *hint = fx_isqrt64_near(ax * ax + ay * ay, *hint);
        rho = *hint;
    } else {
        rho = fx_hypot2(xu, xv);
    }
    den = rho + r;
    if (r < ((int64_t)1 << 31) && fx_uabs64(a) < ((uint64_t)1 << 30)) {
        /* |2 r a| < 2^62 and e2 < 2^61: one division */
        return fx_sat32_fast(fx_div_round64(((s < 0) ? -e2 : e2) + 2 * r * a, den));
    }
    return fx_sat32_fast(
        fx_sat_add64(fx_div_round64((s < 0) ? -e2 : e2, den), fx_muldiv64(2 * a, r, den)));
}

int32_t cec_curv_circle(int32_t eu, int32_t ev, q1_30_t n1u, q1_30_t n1v, pos_nm_t radius, int s)
{
    uint32_t hint = 0;
    return curv_circle_near(eu, ev, n1u, n1v, radius, s, &hint);
}

int32_t cec_exact_line(const pos_nm_t p[3], const pos_nm_t start[3], const q1_30_t n[3])
{
    int32_t d32[3];
    int64_t d[3], sum = 0;
    bool small = true;
    int k;
    for (k = 0; k < 3; k++) {
        d[k] = start[k] - p[k];
        d32[k] = fx_sat32_fast(d[k]);
        small = small && (d32[k] == d[k]);
    }
    if (small) {
        return cec_dot(d32, n);
    }
    for (k = 0; k < 3; k++) {
        sum = fx_sat_add64(sum, fx_mul64x32_shift(d[k], n[k], 30));
    }
    return fx_sat32_fast(sum);
}

/* ---- controller -------------------------------------------------------------- */

cec_err_t cec_config(cec_t *c, const cec_params_t *p, pid_err_t *pid_err)
{
    pid_params_t pp, pl;
    pid_loop_t tmp[2], spare[2];
    pid_err_t err;
    int k;

    if (c == NULL || p == NULL) {
        return CEC_ERR_NULL;
    }
    if ((unsigned)p->mode >= (unsigned)CEC_MODE_COUNT) {
        return CEC_ERR_MODE;
    }
    pp = p->pid;
    pp.kvff = 0;
    pp.kaff = 0;
    pp.d_on_measurement = false;
    pl = p->line_gains ? p->pid_line : pp;
    pl.kvff = 0;
    pl.kaff = 0;
    pl.d_on_measurement = false;
    if (!p->line_gains && c->on_line) {
        /* back to one gain set: ch[] takes the curve gains below */
        c->on_line = false;
    }
    for (k = 0; k < 2; k++) {
        tmp[k] = c->ch[k];
        spare[k] = c->spare[k];
        err = pid_config(&tmp[k], c->on_line ? &pl : &pp);
        if (err == PID_OK) {
            err = pid_config(&spare[k], c->on_line ? &pp : &pl);
        }
        if (err != PID_OK) {
            if (pid_err != NULL) {
                *pid_err = err;
            }
            return CEC_ERR_PID;
        }
        if (!tmp[k].enabled) {
            pid_enable(&tmp[k], 0);
            pid_reset(&tmp[k], false);
        }
        if (!spare[k].enabled) {
            pid_enable(&spare[k], 0);
            pid_reset(&spare[k], false);
        }
    }
    c->ch[0] = tmp[0];
    c->ch[1] = tmp[1];
    c->spare[0] = spare[0];
    c->spare[1] = spare[1];
    c->idle = false;
    if (c->p.mode != p->mode) {
        c->reseg = true;
        c->hist_n = 0;
    }
    c->p = *p;
    c->oscillating = false;
    c->osc_ticks = 0;
    return CEC_OK;
}

cec_err_t cec_set_mode(cec_t *c, cec_mode_t mode)
{
    if ((unsigned)mode >= (unsigned)CEC_MODE_COUNT) {
        return CEC_ERR_MODE;
    }
    if (c->p.mode != mode) {
        c->p.mode = mode;
        c->reseg = true;
        c->hist_n = 0;
    }
    c->oscillating = false;
    c->osc_ticks = 0;
    return CEC_OK;
}

/* The channels' integral as a vector in axis space, U. */
static void integral_vector(const cec_t *c, int64_t iv[3])
{
    int k;
    for (k = 0; k < 3; k++) {
        iv[k] = fx_mul64x32_shift(c->ch[0].integ, c->n[0][k], 30);
        if (c->ch2_on) {
            iv[k] += fx_mul64x32_shift(c->ch[1].integ, c->n[1][k], 30);
        }
    }
}

static void hand_over(cec_t *c, const int64_t rem[3])
{
    int k;
    if (!c->p.handover) {
        return;
    }
    for (k = 0; k < 3 && k < CORE_AXES; k++) {
        c->handover_u[k] += rem[k];
    }
}

static void deactivate(cec_t *c)
{
    if (c->idle) {
        return; /* the state below is already there */
    }
    c->idle = true;
    if (c->active) {
        int64_t iv[3];
        integral_vector(c, iv);
        hand_over(c, iv);
    }
    pid_reset(&c->ch[0], false);
    pid_reset(&c->ch[1], false);
    c->ch[0].out = 0;
    c->ch[1].out = 0;
    c->ch[0].out_mv = 0;
    c->ch[1].out_mv = 0;
    c->active = false;
    c->ch2_on = false;
    c->hist_n = 0;
    c->osc_n = 0;
    c->osc_avg = 0;
    c->osc_ticks = 0;
    c->ec_nm[0] = 0;
    c->ec_nm[1] = 0;
}

/* Plane normal axis of the geometry; false when an ARC has no valid plane. */
static bool geom_plane(const motion_geom_t *g, unsigned *w)
{
    unsigned u = g->plane_u, v = g->plane_v;
    bool ok = u < 3 && v < 3 && u != v;
    if (g->kind == MOTION_GEOM_ARC) {
        if (!ok || u >= CORE_AXES || v >= CORE_AXES || g->radius <= 0) {
            return false;
        }
    }
    *w = ok ? 3u - u - v : 2u;
    return true;
}

static bool segment_changed(const cec_t *c, const motion_geom_t *g, unsigned w)
{
    int k;
    if (!c->active || c->reseg || c->kind != g->kind || c->w != w) {
        return true;
    }
    if (g->kind == MOTION_GEOM_LINE) {
        for (k = 0; k < 3 && k < CORE_AXES; k++) {
            if (c->key_t[k] != g->tangent[k] || c->key_p[k] != g->start[k]) {
                return true;
            }
        }
        return false;
    }
    return c->key_p[0] != g->centre_u || c->key_p[1] != g->centre_v || c->key_r != g->radius ||
           c->key_sense != g->sense;
}

/* The tick's shortcut past geom_plane and segment_changed: the geometry
 * is the active segment's (kind, plane_u and plane_v as given, the LINE's
 * start and tangent, the ARC's centre, radius and sense), so it is valid
 * and unchanged with the plane normal c->w (both depend on these fields
 * alone). False sends the tick the general way. */
static inline bool same_segment(const cec_t *c, const motion_geom_t *g)
{
    int k;
    if (!c->active || c->reseg || c->kind != g->kind || c->key_u != g->plane_u ||
        c->key_v != g->plane_v) {
        return false;
    }
    if (g->kind == MOTION_GEOM_ARC) {
        return c->key_p[0] == g->centre_u && c->key_p[1] == g->centre_v && c->key_r == g->radius &&
               c->key_sense == g->sense;
    }
    for (k = 0; k < 3 && k < CORE_AXES; k++) {
        if (c->key_t[k] != g->tangent[k] || c->key_p[k] != g->start[k]) {
            return false;
        }
    }
    return true;
}

static void new_segment(cec_t *c, const motion_ref_t *ref, unsigned w, const q1_30_t n1[3],
                        const q1_30_t n2[3], bool ch2)
{
    const motion_geom_t *g = &ref->geom;
    int64_t i1 = 0, i2 = 0;
    int k;
    bool keep = false;

    if (c->active && c->kind == MOTION_GEOM_LINE && g->kind == MOTION_GEOM_LINE) {
        int64_t dot = 0;
        for (k = 0; k < 3 && k < CORE_AXES; k++) {
            dot += (int64_t)c->key_t[k] * g->tangent[k];
        }
        if (dot < HIST_CORNER_COS_Q60) {
            c->hist_n = 0; /* a corner: the samples before it are not a curve */
        } else if (!ch2 && !c->ch2_on && c->w == w && !c->reseg) {
            /* a join of a curve cut into lines: the integral turns with the
             * normal as on an arc (projecting it would hand sin(turn) of it
             * to the axes at every join, which over a revolution cancels
             * the CEC's whole integral) */
            keep = true;
            i1 = c->ch[0].integ;
        }
    }
    if (c->active && !keep) {
        int64_t iv[3], rem[3];
        integral_vector(c, iv);
        for (k = 0; k < 3; k++) {
            i1 += fx_mul64x32_shift(iv[k], n1[k], 30);
            if (ch2) {
                i2 += fx_mul64x32_shift(iv[k], n2[k], 30);
            }
        }
        for (k = 0; k < 3; k++) {
            rem[k] = iv[k] - fx_mul64x32_shift(i1, n1[k], 30) - fx_mul64x32_shift(i2, n2[k], 30);
        }
        hand_over(c, rem);
    }
    pid_reset(&c->ch[0], false);
    pid_reset(&c->ch[1], false);
    pid_add_integrator(&c->ch[0], i1);
    pid_add_integrator(&c->ch[1], i2);

    c->kind = g->kind;
    c->w = w;
    c->reseg = false;
    c->s = 0;
    for (k = 0; k < 3; k++) {
        c->key_t[k] = (k < CORE_AXES) ? g->tangent[k] : 0;
        c->key_p[k] = (k < CORE_AXES) ? g->start[k] : 0;
    }
    c->key_r = 0;
    c->key_sense = 0;
    c->key_u = g->plane_u;
    c->key_v = g->plane_v;
    if (g->kind == MOTION_GEOM_ARC) {
        unsigned u = g->plane_u, v = g->plane_v;
        int64_t du = g->centre_u - ref->pos[u], dv = g->centre_v - ref->pos[v], dot;
        c->key_p[0] = g->centre_u;
        c->key_p[1] = g->centre_v;
        c->key_p[2] = 0;
        c->key_r = g->radius;
        c->key_sense = g->sense;
        while (fx_sat_abs64(du) >= ((int64_t)1 << 31) || fx_sat_abs64(dv) >= ((int64_t)1 << 31)) {
            du /= 2;
            dv /= 2;
        }
        dot = du * n1[u] + dv * n1[v];
        c->s = (int8_t)((dot > 0) ? 1 : (dot < 0) ? -1 : ((g->sense > 0) ? -1 : 1));
        if (!pid_coef_make(&c->inv_r, FX_ONE_Q30, 1, (uint64_t)g->radius)) {
            c->inv_r.m = 0;
            c->inv_r.sh = 0;
        }
    }
}

/* Swap in the other gain set, continuing from the last outputs (cec.h). */
static void switch_gains(cec_t *c)
{
    int k;
    for (k = 0; k < 2; k++) {
        pid_loop_t old = c->ch[k];
        c->ch[k] = c->spare[k];
        c->spare[k] = old;
        c->ch[k].out = old.out;
        c->ch[k].out_mv = old.out_mv;
        c->ch[k].integ = old.integ;
        c->ch[k].primed = false; /* no derivative kick */
        pid_reset(&c->ch[k], true);
    }
    c->on_line = !c->on_line;
}

/* The oscillation watch of one active tick (cec.h). */
static void osc_watch(cec_t *c)
{
    int32_t u = c->ch[0].out_mv;
    if (c->osc_n == 2) {
        int64_t d2 = fx_sat_abs64((int64_t)u - 2 * (int64_t)c->osc_u[0] + c->osc_u[1]);
        c->osc_avg += ((d2 << 8) - c->osc_avg) / (1 << CEC_OSC_SHIFT);
        if (c->osc_avg > ((int64_t)CEC_OSC_LIMIT_MV << 8)) {
            if (++c->osc_ticks > c->ch[0].p.tick_hz / 10u) {
                c->oscillating = true;
            }
        } else {
            c->osc_ticks = 0;
        }
    } else {
        c->osc_n++;
    }
    c->osc_u[1] = c->osc_u[0];
    c->osc_u[0] = u;
}

/* The usual tick of the EXACT estimate on an arc, taken when it applies and
 * returning false otherwise before it writes anything: the active segment
 * (same_segment), a tangent in the plane (t_w = 0: no second channel, now
 * or last tick) off the plane normal and the channel's PID on its fast
 * path (the curve gains are in place: the ARC's last tick left them). The
 * general path's operations for that case in its order, without its tests
 * for the cases that cannot arise: the same results (test_cec.c,
 * test_exact_arc_tick_equals_general). */
static inline bool exact_arc_tick(cec_t *c, const motion_geom_t *g, const pos_nm_t meas[CORE_AXES])
{
    unsigned w = c->w, u = (w == 2u) ? 0u : w + 1u, v = (w == 0u) ? 2u : w - 1u;
    q1_30_t tu, tv;
    int64_t len2;
    int32_t ec1, u1;
    int k;

    if (g->kind != MOTION_GEOM_ARC || !same_segment(c, g) || g->tangent[w] != 0 || c->ch2_on ||
        !pid_fast_ready(&c->ch[0])) {
        return false;
    }
    tu = g->tangent[u];
    tv = g->tangent[v];
    len2 = (int64_t)tv * tv + (int64_t)tu * tu;
    if (len2 < PLUNGE_LEN2) {
        return false;
    }
    for (k = 0; k < CORE_AXES; k++) {
        c->handover_u[k] = 0;
    }
    c->out_zero = false;
    normals_plane(tu, tv, 0, w, u, v, len2, c->n[0], c->n[1], &c->len_hint);
    c->idle = false;
    ec1 = exact_arc_near(meas[g->plane_u], meas[g->plane_v], g->centre_u, g->centre_v, g->radius,
                         c->s, &c->rho_hint, c->inv_r);
    c->ec_nm[0] = ec1;
    c->ec_nm[1] = 0;
    pid_step_fast_inline(&c->ch[0], ec1, -(pos_nm_t)ec1, 0, true);
    c->ch[1].out = 0;
    c->ch[1].saturated = false;
    c->saturated = c->ch[0].saturated;
    osc_watch(c);
    u1 = (int32_t)fx_round_shift64(c->ch[0].out, 22); /* mV q10 */
    for (k = 0; k < 3 && k < CORE_AXES; k++) {
        c->out_u[k] = fx_round_shift64((int64_t)u1 * c->n[0][k], 8);
    }
    for (k = 3; k < CORE_AXES; k++) {
        c->out_u[k] = 0;
    }
    return true;
}

/* cec_step for every case (exact_arc_tick: its usual one). */
static CEC_NOINLINE void step_general(cec_t *c, const motion_ref_t *ref,
                                      const pos_nm_t meas[CORE_AXES])
{
    const motion_geom_t *g;
    q1_30_t t[3], s1[3], s2[3];
    const q1_30_t *n1 = c->n[0], *n2 = c->n[1];
    q1_30_t *o1 = c->n[0], *o2 = c->n[1]; /* where normals_near writes */
    int32_t e[3], ec1, ec2 = 0;
    unsigned w = 2;
    bool ch2, changed;
    int k;

    if (c->p.mode == CEC_MODE_OFF || ref == NULL || !ref->active ||
        ref->geom.kind == MOTION_GEOM_NONE) {
        if (c->idle && c->out_zero) {
            return; /* outputs 0, saturated false since the last idle tick */
        }
        for (k = 0; k < CORE_AXES; k++) {
            c->out_u[k] = 0;
            c->handover_u[k] = 0;
        }
        c->saturated = false;
        c->out_zero = c->idle; /* idle already: deactivate writes nothing */
        deactivate(c);
        return;
    }
    for (k = 0; k < CORE_AXES; k++) {
        c->out_u[k] = 0;
        c->handover_u[k] = 0;
    }
    c->saturated = false;
    c->out_zero = false;
    g = &ref->geom;
    for (k = 0; k < 3; k++) {
        t[k] = (k < CORE_AXES) ? g->tangent[k] : 0;
    }
    if (same_segment(c, g)) {
        /* a LINE's normals are last tick's (its tangent is in the key) */
        w = c->w;
        if (g->kind != MOTION_GEOM_LINE && !normals_near(t, w, c->n[0], c->n[1], &c->len_hint)) {
            c->bad_geom++;
            deactivate(c);
            return;
        }
        c->idle = false;
        ch2 = w < CORE_AXES && (t[w] > OFFPLANE_Q30 || t[w] < -OFFPLANE_Q30);
        if (c->ch2_on && !ch2) {
            /* (a LINE's tangent is part of its key: only reached on an ARC) */
            pid_reset(&c->ch[1], false);
        }
    } else {
        if ((g->kind != MOTION_GEOM_LINE && g->kind != MOTION_GEOM_ARC) || !geom_plane(g, &w)) {
            c->bad_geom++;
            deactivate(c);
            return;
        }
        /* Within a segment the normals go straight into c->n (normals_near
         * writes nothing when it fails). A new segment needs last tick's
         * normals (new_segment projects the integral from them): the new
         * ones wait in s1, s2 until it has run. */
        changed = segment_changed(c, g, w);
        if (changed) {
            o1 = s1;
            o2 = s2;
        }
        if (!normals_near(t, w, o1, o2, &c->len_hint)) {
            c->bad_geom++;
            deactivate(c);
            return;
        }
        c->idle = false; /* the channels run (or are reset) below */
        ch2 = w < CORE_AXES && (t[w] > OFFPLANE_Q30 || t[w] < -OFFPLANE_Q30);
        if (changed) {
            new_segment(c, ref, w, s1, s2, ch2);
            for (k = 0; k < 3; k++) {
                c->n[0][k] = s1[k];
                c->n[1][k] = s2[k];
            }
        } else if (c->ch2_on && !ch2) {
            /* (a LINE's tangent is part of its key: only reached on an ARC) */
            pid_reset(&c->ch[1], false);
        }
    }
    c->active = true;
    c->ch2_on = ch2;
    /* the axes' errors: every estimate but the exact one, which reads the
     * measurement alone (an ARC's second channel takes them too) */
    if (c->p.mode != CEC_MODE_EXACT || (ch2 && g->kind == MOTION_GEOM_ARC)) {
        for (k = 0; k < 3; k++) {
            e[k] = (k < CORE_AXES) ? fx_sat_diff32(ref->pos[k], meas[k]) : 0;
        }
    }

    switch (c->p.mode) {
    case CEC_MODE_EXACT:
        if (g->kind == MOTION_GEOM_ARC) {
            ec1 = exact_arc_near(meas[g->plane_u], meas[g->plane_v], g->centre_u, g->centre_v,
                                 g->radius, c->s, &c->rho_hint, c->inv_r);
        } else {
            pos_nm_t p3[3], s3[3];
            for (k = 0; k < 3; k++) {
                p3[k] = (k < CORE_AXES) ? meas[k] : 0;
                s3[k] = (k < CORE_AXES) ? g->start[k] : 0;
            }
            ec1 = cec_exact_line(p3, s3, n1);
            if (ch2) {
                ec2 = cec_exact_line(p3, s3, n2);
            }
        }
        break;
    case CEC_MODE_CHUANG_LIU: {
        unsigned u = (w + 1u) % 3u, v = (w + 2u) % 3u;
        pos_nm_t rr = 0;
        int s = 0;
        ec1 = cec_dot(e, n1);
        if (g->kind == MOTION_GEOM_ARC) {
            rr = g->radius;
            s = c->s;
        } else {
            cec_hist_step(c, ref, w);
            rr = c->hist_r;
            s = c->hist_s;
        }
        if (rr > 0) {
            int64_t e2 = (int64_t)e[u] * e[u] + (int64_t)e[v] * e[v];
            int32_t corr = fx_sat32_fast(fx_div_round64(e2, 2 * rr));
            ec1 = fx_sat_add32(ec1, (s > 0) ? corr : -corr);
        }
        break;
    }
    case CEC_MODE_CURVATURE:
    case CEC_MODE_CURV_HISTORY:
        ec1 = cec_dot(e, n1);
        if (g->kind == MOTION_GEOM_ARC && c->p.mode == CEC_MODE_CURVATURE && !c->p.thesis_form) {
            ec1 = curv_circle_near(e[g->plane_u], e[g->plane_v], n1[g->plane_u], n1[g->plane_v],
                                   g->radius, c->s, &c->rho_hint);
        } else if (g->kind == MOTION_GEOM_ARC && c->p.mode == CEC_MODE_CURVATURE) {
            int64_t eabs = c->p.lag_from_tangent ? fx_sat_abs64(cec_dot(e, t))
                                                 : fx_hypot2(e[g->plane_u], e[g->plane_v]);
            int32_t corr = curv_corr(fx_sat32_fast(eabs), g->radius, c->inv_r);
            ec1 = fx_sat_add32(ec1, (c->s > 0) ? corr : -corr);
        } else {
            cec_hist_step(c, ref, w);
            if (c->hist_r > 0 && !c->p.thesis_form) {
                unsigned u = (w + 1u) % 3u, v = (w + 2u) % 3u;
                ec1 =
                    curv_circle_near(e[u], e[v], n1[u], n1[v], c->hist_r, c->hist_s, &c->rho_hint);
            } else if (c->hist_r > 0) {
                unsigned u = (w + 1u) % 3u, v = (w + 2u) % 3u;
                int64_t eabs =
                    c->p.lag_from_tangent ? fx_sat_abs64(cec_dot(e, t)) : fx_hypot2(e[u], e[v]);
                int32_t corr = curv_corr_div(fx_sat32_fast(eabs), c->hist_r);
                ec1 = fx_sat_add32(ec1, (c->hist_s > 0) ? corr : -corr);
            }
        }
        break;
    case CEC_MODE_KOREN:
        if (g->kind == MOTION_GEOM_LINE) {
            unsigned u = (w + 1u) % 3u, v = (w + 2u) % 3u;
            int64_t ru = (u < CORE_AXES) ? ref->pos[u] - g->start[u] : 0;
            int64_t rv = (v < CORE_AXES) ? ref->pos[v] - g->start[v] : 0;
            ec1 = cec_est_koren(e[u], e[v], ru, rv);
        } else {
            ec1 = cec_dot(e, n1);
        }
        break;
    default: /* TANGENT */
        ec1 = cec_dot(e, n1);
        break;
    }
    if (ch2 && !(c->p.mode == CEC_MODE_EXACT && g->kind == MOTION_GEOM_LINE)) {
        ec2 = cec_dot(e, n2);
    }
    c->ec_nm[0] = ec1;
    c->ec_nm[1] = ec2;
    if (c->p.line_gains) {
        bool line = g->kind == MOTION_GEOM_LINE && c->hist_r == 0;
        if (line != c->on_line) {
            switch_gains(c);
        }
    }

    if (pid_fast_ready(&c->ch[0])) {
        /* pid_step's fast step, inline: e = sat32(0 - -ec1) = ec1; its rest
         * step (pid.h) would return the same */
        pid_step_fast_inline(&c->ch[0], ec1, -(pos_nm_t)ec1, 0, true);
    } else {
        pid_step(&c->ch[0], 0, -(pos_nm_t)ec1, 0, 0, 0);
    }
    if (ch2) {
        pid_step(&c->ch[1], 0, -(pos_nm_t)ec2, 0, 0, 0);
    } else {
        c->ch[1].out = 0;
        c->ch[1].saturated = false;
    }
    c->saturated = c->ch[0].saturated || c->ch[1].saturated;
    osc_watch(c);
    {
        int32_t u1 = (int32_t)fx_round_shift64(c->ch[0].out, 22); /* mV q10 */
        int32_t u2 = (int32_t)fx_round_shift64(c->ch[1].out, 22);
        for (k = 0; k < 3 && k < CORE_AXES; k++) {
            int64_t a = (int64_t)u1 * n1[k] + (ch2 ? (int64_t)u2 * n2[k] : 0);
            c->out_u[k] = fx_round_shift64(a, 8); /* q10 * q30 = q40 -> U (q32) */
        }
    }
}

void cec_step(cec_t *c, const motion_ref_t *ref, const pos_nm_t meas[CORE_AXES])
{
    if (ref != NULL && c->p.mode == CEC_MODE_EXACT && ref->active &&
        exact_arc_tick(c, &ref->geom, meas)) {
        return;
    }
    step_general(c, ref, meas);
}

/* Test hook: the general path alone (cec_test.h). */
void cec_step_general_test(cec_t *c, const motion_ref_t *ref, const pos_nm_t meas[CORE_AXES])
{
    step_general(c, ref, meas);
}
