/*
 * cec.h - cross-coupled contour error controller (Lacerda 1998, after
 * Koren 1980 and Kulkarni & Srinivasan 1989).
 *
 * Specification
 * -------------
 * Notation (docs/servo.md has the figures): axial error E = R - P (reference
 * minus measured, nm, int32 per axis, saturated), unit tangent t of the path
 * at the reference point (motion_ref_t.geom.tangent, q1_30), active plane
 * (u, v) with normal axis w (G17: 0,1 -> w = 2; G18: 2,0 -> w = 1; G19:
 * 1,2 -> w = 0; lines without a valid plane use G17).
 *
 *   n1 = normalise(t x e_w)   first normal: the right-hand normal of the path
 *                             in the active plane, (sin a, -cos a) in the
 *                             thesis's 2-D notation when t = (cos a, sin a).
 *                             If t is within 2^-10 of +-e_w (plunge), n1 is
 *                             e_u made orthogonal to t.
 *   n2 = n1 x t               second normal (= e_w for an in-plane tangent).
 *
 * Contour error estimates of the first channel, EC1 (nm, int32; positive
 * when the machine is on the -n1 side of the path, i.e. along E):
 *   TANGENT    EC1 = E . n1                           (Kulkarni & Srinivasan)
 *   KOREN      LINE: EC1 = E . n_k with n_k the right-hand normal of R - start
 *              in the plane = (Ry Ex - Rx Ey) / |R| about the segment start;
 *              ARC: as TANGENT.                       (Koren, straight line)
 *   CURVATURE  ARC: the distance of P from the circle of curvature at the
 *              reference point, centre C = R + s r n1, radius r:
 *                EC1 = s (|P_uv - C| - r) = (s |E_uv|^2 + 2 r (E . n1)) / (|P_uv - C| + r)
 *              with s = +1 when the centre lies on the +n1 side of the
 *              reference point (clockwise travel) and -1 otherwise
 *              (counter-clockwise), taken from the centre's position, so both
 *              directions of travel are right (the circle form; within 2 nm
 *              of EXACT on an arc, for any lag and radial deviation).
 *              With thesis_form (Lacerda 1998, its proposal): EC1 = E . n1 + s r
 *              (sec g - 1), g = |E_uv| / r limited to 0.5 rad: a series that
 *              is exact only to |E|^4 / (4 r^3) for a pure lag, a bias that
 *              the CEC's integrator then holds as a radial error (without
 *              feed-forward at a lag of 0.4 R: 84 um on R 10 mm).
 *              With thesis_form and lag_from_tangent, g = |E . t| / r: a
 *              radial deviation d then no longer adds its own ~ d^2 / (2 r)
 *              to the estimate, and the pure-lag error drops from
 *              ~5|E|^4/(24 r^3) to ~|E|^4/(12 r^3). LINE: as TANGENT.
 *              LINE (or any segment in CURV_HISTORY): r and the side from
 *              the reference history (below), same form (the centre C on
 *              the estimated normal at r); TANGENT while it has fewer
 *              than three samples or the path is straight.
 *   CURV_HISTORY as CURVATURE with r and s always from the reference
 *              history, also on an ARC (the thesis's `calcr` block).
 *   CHUANG_LIU EC1 = E . n1 + s * |E_uv|^2 / (2 r) (Chuang & Liu 1991: the
 *              second-order term of the same geometry; exact for a pure lag
 *              on a circle, since E . n1 = -s |E|^2 / (2 r) there); r, s
 *              as in CURVATURE (arc geometry, or the history on a LINE).
 *   EXACT      LINE: EC1 = (start - P) . n1 (distance of P from the line).
 *              ARC:  EC1 = s * (|P_uv - C| - r)  (radial deviation).
 * Errors against the exact value on a circle, pure lag |E| (tests assert):
 *   tangent = -s |E|^2 / (2 r) exactly, curvature within 2 nm, with
 *   thesis_form within |E|^4 / (4 r^3) (+ quantisation, 3 nm); with a
 *   radial deviation d as well: curvature within 2 nm, thesis form within
 *   d^2 / (2 r) + |E|^4 / (4 r^3), lag_from_tangent within
 *   |d| g^2 + |E|^4 / (4 r^3).
 * Reference history (CURVATURE on a LINE, CURV_HISTORY): the reference
 * point is sampled in the plane (u, v) each time it has moved at least
 * span = p.curv_span_nm (0: CEC_CURV_SPAN_NM) from the last sample (path
 * length, not time, so the estimate does not depend on the feed); from the
 * last three samples a, b, c: r = |b-a| |c-b| |c-a| / (2 |(b-a) x (c-b)|)
 * (circumscribed circle), s = -1 for a left turn ((b-a) x (c-b) > 0, the
 * centre on the -n1 side) and +1 for a right turn. r above CEC_CURV_R_MAX
 * counts as straight (no correction). Computed only when a sample is taken
 * (on a circle of G1 chords the samples lie within the chords' sagitta of
 * the circle: R 20 mm, 720 chords, span 1 mm: r within 1 %). The history
 * restarts when the CEC stops, the mode or plane changes, or a LINE's
 * tangent turns by more than 30 degrees at a join (a corner, not a curve).
 * Cost: the per-tick check is a few multiplies; a sample ~600 cycles
 * (three roots and a division); every tick of CURVATURE one root (from the
 * last) and one division (thesis_form on a LINE: a division for g). CEC
 * off (control_tick_instructions_m4) is not affected.
 * The second channel (only when the segment leaves the plane: |t_w| > 2^-20,
 * a three-axis line or helix) uses EC2 = E . n2 (EXACT on a LINE:
 * (start - P) . n2), so the controlled error is the whole part of E
 * orthogonal to t. Axes beyond the third are not part of the contour.
 *
 * Controller: each channel runs a pid_loop_t (pid.h) with the CEC gains on
 * its EC (reference 0, D on the error, no feed-forward), and its clamped
 * output u_k (U = mV * 2^-32) is distributed along its normal:
 *   out_u[axis] = u1 * n1[axis] + u2 * n2[axis]
 * (Ux += u sin a, Uy -= u cos a in the thesis's 2-D notation). The servo adds
 * out_u to the axis loops before their output clamp. The CEC's own clamps are
 * those of its pid_params_t (i_max_mv, out_max_mv); `saturated` is set when
 * either channel's output was clamped this tick.
 *
 * Activity: the CEC runs when mode != OFF, ref->active and the geometry is a
 * valid LINE or ARC; otherwise (rest, no path, bad geometry: counted in
 * bad_geom) its output is zero. On every change of segment (kind, plane,
 * LINE start or tangent, ARC centre, radius or sense) and of mode, the
 * channels' integral, as a vector I = I1 n1 + I2 n2, is projected onto the new
 * normals (tangent-continuous joins keep it whole) and the derivative restarts
 * without a kick. With handover = true, what does not project (the component
 * along the new tangent, or all of it when the CEC stops) is put in
 * handover_u[axis] for the servo to add to the axis integrators, so the sum
 * of the commands does not step; with handover = false it is dropped.
 * Within an ARC the integrals turn with the normal (scalar integrators).
 *
 * Gain switching (the thesis's line and curve gain sets), with
 * p.line_gains: the channels run p.pid_line's gains while the path is
 * straight (a LINE whose curvature is not known from the history: always
 * in TANGENT, EXACT and KOREN, and in the history modes while hist_r is 0)
 * and p.pid's on curves (an ARC, or hist_r > 0). A switch is bumpless: the
 * loop with the other gains continues from the output of the last tick
 * (pid_reset bumpless) with its derivative restarted. The other set waits in
 * spare[] (same validation by cec_config; nothing changes on error).
 *
 * Oscillation watch (a sustained limit cycle is a fault, not a result):
 * while active, avg = the mean of |u1(k) - 2 u1(k-1) + u1(k-2)| (first
 * channel's output, mV; exponential, 2^CEC_OSC_SHIFT ticks). Slow
 * corrections have a tiny second difference (R 20 mm at 30 m/min, default
 * gains: 5-7 mV on the axis commands), a limit cycle a large one (the
 * thesis's CEC gains at 10 kHz: a 666 Hz cycle, 800-1600 mV). avg above
 * CEC_OSC_LIMIT_MV for more than tick_hz / 10 ticks in a row (0.1 s) sets
 * `oscillating` (latched until cec_config or cec_set_mode); the servo
 * raises SERVO_FAULT_OSCILLATION.
 *
 * Units and Q formats: positions nm (pos_nm_t), errors int32 nm, unit vectors
 * q1_30, outputs U (int64, mV * 2^-32). Internally u_k is taken at 2^-10 mV
 * resolution for the distribution.
 *
 * Contexts: cec_step: tick. cec_config, cec_set_mode: main or tick, applied
 * by the servo between ticks. The estimator functions are pure.
 */
#ifndef CEC_H
#define CEC_H

#include <stdbool.h>
#include <stdint.h>

#include "core_config.h"
#include "fixmath.h"
#include "motion_ref.h"
#include "pid.h"

typedef enum {
    CEC_MODE_OFF = 0,
    CEC_MODE_TANGENT = 1,
    CEC_MODE_CURVATURE = 2,
    CEC_MODE_EXACT = 3,
    CEC_MODE_KOREN = 4,
    CEC_MODE_CURV_HISTORY = 5,
    CEC_MODE_CHUANG_LIU = 6,
    CEC_MODE_COUNT
} cec_mode_t;

typedef enum {
    CEC_OK = 0,
    CEC_ERR_NULL,
    CEC_ERR_MODE, /* mode outside cec_mode_t           */
    CEC_ERR_PID   /* the gains were refused: see pid_err */
} cec_err_t;

typedef struct {
    cec_mode_t mode;
    pid_params_t pid;      /* CEC gains (SI, q32_32: Kp V/m, Ki V/(m*s), Kd V*s/m),
                            * clamps, deadband, D filter; kvff/kaff/d_on_measurement
                            * are ignored (no feed-forward; D on the error). */
    bool handover;         /* hand the integral to the axis loops (bumpless)    */
    bool thesis_form;      /* CURVATURE, CURV_HISTORY: the thesis's series
                            * E . n1 + s r (sec g - 1) instead of the circle
                            * form (see above)                             */
    bool lag_from_tangent; /* thesis_form: g = |E . t| / r (the lag only) instead
                            * of the thesis's |E_uv| / r; see below        */
    int32_t curv_span_nm;  /* history sample spacing, nm (0: CEC_CURV_SPAN_NM) */
    bool line_gains;       /* use pid_line on straight path (see Gain switching) */
    pid_params_t pid_line; /* CEC gains on straight path, as pid                 */
} cec_params_t;

#define CEC_CURV_SPAN_NM 1000000            /* 1 mm */
#define CEC_CURV_R_MAX   ((int64_t)1 << 32) /* 4.3 m: straight above */
#define CEC_OSC_SHIFT    6                  /* oscillation watch: mean over 2^6 ticks */
#define CEC_OSC_LIMIT_MV 200                /* mean |second difference| of u1, mV */

typedef struct {
    cec_params_t p;
    pid_loop_t ch[2];
    pid_loop_t spare[2]; /* the other gain set (line_gains) */
    bool on_line;        /* ch[] holds the line gains (tick) */
    /* tick outputs */
    bool active;
    bool saturated;
    int32_t ec_nm[2];              /* EC1, EC2 this tick (0 when inactive)   */
    int64_t out_u[CORE_AXES];      /* command added to each axis, U          */
    int64_t handover_u[CORE_AXES]; /* to add to the axis integrators, U      */
    q1_30_t n[2][3];               /* the normals used this tick             */
    uint32_t bad_geom;             /* ticks refused for invalid geometry     */
    /* segment tracking (tick) */
    bool ch2_on;
    bool reseg;
    motion_geom_kind_t kind;
    unsigned w;
    q1_30_t key_t[3];
    pos_nm_t key_p[3];
    pos_nm_t key_r;
    int8_t key_sense;
    uint8_t key_u, key_v; /* the geometry's plane_u, plane_v (same_segment) */
    pid_coef_t inv_r;     /* 2^30 / radius */
    int8_t s;             /* side of the centre: +1 on +n1 */
    bool idle;            /* inactive and the channels reset, untouched since:
                           * the next inactive tick has nothing to do (tick) */
    bool out_zero;        /* idle, and out_u / handover_u already 0: an inactive
                           * tick returns at once (tick) */
    /* reference history (tick): samples h[0] newest .. h[2], in the plane
     * (u, v) of normal axis hist_w; hist_r 0: no curvature known */
    uint8_t hist_n;
    uint8_t hist_w;
    int8_t hist_s;
    pos_nm_t hist[3][2];
    pos_nm_t hist_r;
    /* oscillation watch (tick) */
    int32_t osc_u[2];   /* u1 of the last two ticks, mV            */
    uint8_t osc_n;      /* ticks in osc_u (0..2)                   */
    int64_t osc_avg;    /* mean |second difference|, mV * 2^8      */
    uint32_t osc_ticks; /* consecutive ticks over the limit        */
    bool oscillating;   /* latched: a sustained limit cycle        */
    /* last roots of the normalisation and the exact arc distance (tick):
     * starting points of fx_isqrt64_near only, any value is correct (the
     * exact arc distance first tries one step about the radius with
     * inv_r, without a division; cec.c, arc_root) */
    uint32_t len_hint;
    uint32_t rho_hint;
} cec_t;

/* Validate and apply (nothing changes on error; *pid_err gets the detail
 * when CEC_ERR_PID, may be NULL). A zeroed cec_t is an inactive CEC. */
cec_err_t cec_config(cec_t *c, const cec_params_t *p, pid_err_t *pid_err);
/* Select the estimate for the next job; bumpless (see Activity). */
cec_err_t cec_set_mode(cec_t *c, cec_mode_t mode);

/* One tick: fills active, ec_nm, out_u, handover_u, saturated.
 * meas: measured positions, nm. */
void cec_step(cec_t *c, const motion_ref_t *ref, const pos_nm_t meas[CORE_AXES]);

/* ---- estimators (pure; three-component vectors, axis order x, y, z) ---- */

/* n1, n2 from a unit tangent t (q1_30) and the plane's normal axis w (0..2).
 * False when t is the zero vector. */
bool cec_normals(const q1_30_t t[3], unsigned w, q1_30_t n1[3], q1_30_t n2[3]);
/* round(e . n), nm. */
int32_t cec_dot(const int32_t e[3], const q1_30_t n[3]);
/* Koren's estimate in a plane: (ry*ex - rx*ey) / |r|, r = R - start. */
int32_t cec_est_koren(int32_t ex, int32_t ey, int64_t rx, int64_t ry);
/* r * (sec g - 1) with g = min(e_abs / r, 0.5 rad), nm, rounded; 0 if r <= 0. */
int32_t cec_curv_correction(int32_t e_abs, pos_nm_t radius);
/* The circle form of CURVATURE: s (|P - C| - r) for C = R + s r n1, from
 * E's plane components (eu, ev), n1's (n1u, n1v, q1_30) and r, nm (0 if
 * r <= 0). */
int32_t cec_curv_circle(int32_t eu, int32_t ev, q1_30_t n1u, q1_30_t n1v, pos_nm_t radius, int s);
/* s * (|P - C| - r) in the plane, nm (|P - C| to the nearest nm below). */
int32_t cec_exact_arc(pos_nm_t pu, pos_nm_t pv, pos_nm_t cu, pos_nm_t cv, pos_nm_t radius, int s);
/* Radius (nm, 0: straight or degenerate) and side s (+1 right turn, -1
 * left turn) of the circle through a, b, c (plane points, nm, in order of
 * travel). */
pos_nm_t cec_circle3(const pos_nm_t a[2], const pos_nm_t b[2], const pos_nm_t c[2], int8_t *s);
/* (start - p) . n, nm. */
int32_t cec_exact_line(const pos_nm_t p[3], const pos_nm_t start[3], const q1_30_t n[3]);

#endif /* CEC_H */
