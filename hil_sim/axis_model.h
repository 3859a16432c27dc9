/*
 * axis_model.h - physical model of one machine axis for the HIL simulator.
 *
 * Specification
 * -------------
 * The fifth-order two-inertia model of ../shared/models/lacerda1998.md: a DC
 * motor under armature-voltage control drives a ball screw; the motor+screw
 * inertia I1 is coupled to the table inertia I2 (reflected to the screw) by a
 * stiffness K and a damping B. State z = [th1, w1, th2, w2, ia] (rad, rad/s,
 * rad, rad/s, A):
 *
 *   dth1/dt = w1
 *   dw1/dt  = (-K(th1-th2) - B(w1-w2) + kt ia - T1) / I1
 *   dth2/dt = w2
 *   dw2/dt  = ( K(th1-th2) + B(w1-w2) - T2) / I2
 *   dia/dt  = (sat(kx u, Vmax) - Ra ia - kb w1) / La
 *
 * u is the amplifier command (V at the amplifier input), T1 the torque on the
 * motor side (load torque + motor-side Coulomb friction), T2 the torque on the
 * table side (table Coulomb friction, force times l). The table position is
 * x = l th2 (+ pitch error), the motor encoder sees l th1.
 *
 * Integration: exact zero-order-hold discretisation. At init, for a substep h
 * the augmented matrix M = [[A, B], [0, 0]] (5 states + 3 inputs) is
 * exponentiated in double precision (scaling and squaring of a Taylor series),
 * giving Phi = e^{Ah} and Gamma = int_0^h e^{As} ds B. Each substep is then
 * z <- Phi z + Gamma [u, T1, T2] (row i: the products with z[0..4], u, T1,
 * T2 summed left to right; the T1, T2 terms are skipped when both are 0,
 * which leaves every bit of the result unchanged). The inputs are constant over a substep: the
 * command is constant over the control tick anyway (and the +-Vmax clamp acts
 * on it exactly), so with no nonlinear option configured the result is exact
 * for any substep length. Friction and backlash are evaluated once per
 * substep (choose a short substep when they are on):
 *
 *  - Coulomb friction (motor side, N m; table side, N at the table): a
 *    stick-slip law. The friction torque is the torque that would stop the
 *    body within one substep, clamped to +-Fc ("friction as a constraint"):
 *    it holds a body at rest while the net driving torque is below Fc and
 *    opposes motion with Fc otherwise. Deterministic, no chattering.
 *  - Backlash between screw and table (total lost motion b, metres at the
 *    table): the coupling K, B acts on th1-th2 minus the half gap b/(2l) in
 *    contact and is absent inside the gap. Two discretisations (engaged and
 *    free) are prepared; the contact offset enters as an extra torque pair.
 *  - Pitch error map: the true table position is l th2 + e(x, dir), e linear
 *    in x between map points (held beyond the ends), with one error column for
 *    motion in +x and one for -x; dir is the sign of the last table motion
 *    larger than the hysteresis band `pitch_dir_band` (m).
 *  - Load torque: constant T1 (N m).
 *  - Encoder: counts per motor revolution (4x the line count for quadrature)
 *    and optional Gaussian reading noise (counts rms) from a seeded
 *    deterministic generator; the reading is offset by enc_offset_counts
 *    (default 0.5: the decoder's count n covers n - 1/2 .. n + 1/2, centred
 *    on the machine position it reports, instead of a half-count bias);
 *    the reference scale reads the true table position at its own
 *    resolution, rounded to the nearest count.
 *
 * All functions are plain C99 with doubles (hil_sim/ may use floating point);
 * an axis_t is self-contained (no globals, no heap) and fully deterministic.
 */
#ifndef AXIS_MODEL_H
#define AXIS_MODEL_H

#include <complex.h>
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#define AXIS_NSTATE      5
#define AXIS_NINPUT      3
#define AXIS_PITCH_MAX   64
#define AXIS_SUBSTEP_MAX 1000
/* Largest encoder resolution and screw lead axis_init takes: the drive's
 * count scale (counts * 1000 and lead in pm, sim.c) must fit int64. */
#define AXIS_ENC_COUNTS_MAX 1e12
#define AXIS_LEAD_MAX_M     1e3

typedef struct {
    /* plant, SI units (names as in the model spec) */
    double B, l, K, kb, kt, La, I1, I2, Ra, kx, vmax;
    /* options: all zero = off */
    double load_torque;                   /* N m on the motor side                       */
    double coulomb_motor;                 /* N m, motor + screw bearings                 */
    double coulomb_table;                 /* N at the table (guides)                     */
    double backlash;                      /* m, total lost motion at the table           */
    unsigned pitch_n;                     /* points in the pitch error map (0 = off)     */
    double pitch_pos[AXIS_PITCH_MAX];     /* m, strictly increasing      */
    double pitch_err_fwd[AXIS_PITCH_MAX]; /* m, error moving toward +x   */
    double pitch_err_rev[AXIS_PITCH_MAX]; /* m, error moving toward -x   */
    double pitch_dir_band;                /* m, direction hysteresis     */
    /* sensors */
    double enc_counts_per_rev; /* quadrature counts per motor revolution  */
    double enc_offset_counts;  /* reading at th1 = 0, counts (0.5: count 0
                                * spans -1/2..+1/2 count, so the decoded
                                * position has no mean bias)              */
    double enc_noise_counts;   /* rms reading noise, counts (0 = off)     */
    double ref_resolution;     /* m per reference-scale count             */
    double ref_noise;          /* m rms reference reading noise (0 = off),
                                * own seeded generator (axis_ref_reading) */
    uint64_t seed;             /* noise generator seed                    */
} axis_params_t;

typedef struct {
    axis_params_t p;
    double h; /* substep, s */
    double phi[AXIS_NSTATE][AXIS_NSTATE];
    double gam[AXIS_NSTATE][AXIS_NINPUT];
    double phi_free[AXIS_NSTATE][AXIS_NSTATE]; /* backlash gap open */
    double gam_free[AXIS_NSTATE][AXIS_NINPUT];
    /* the same as phi and gam's u column, by columns, one padding row:
     * lin[j][i] = phi[i][j] (j < 5), lin[5][i] = gam[i][0]; lin[j][5] = 0.
     * The substep with only u acting (T1 = T2 = 0, gap closed) uses it:
     * the same products summed in the same order as the full update (the
     * dropped T1, T2 terms are exact zeros), so the same bits, in a form the
     * compiler can vectorise. */
    double lin[AXIS_NSTATE + 1][AXIS_NSTATE + 1];
    double z[AXIS_NSTATE];
    /* rest: the last substep was the linear update (only u acting) and left
     * z bit for bit as it was, with command rest_u (same bits). That update
     * is a function of z and u alone, so the same command leaves z as it is
     * again: axis_substep skips it (an axis standing still, e.g. Z on the
     * bench circle). Cleared by axis_init and axis_set_position. */
    bool rest;
    uint64_t rest_u;   /* the bits of that command (a double) */
    bool lin_only;     /* only u acts: no load torque, friction or backlash
                        * (axis_init, axis_set_load_torque) */
    double enc_scale;  /* encoder counts per rad of th1 (cpr / 2 pi)  */
    double v_applied;  /* motor voltage of the last substep, V    */
    int pitch_dir;     /* +1 / -1: direction for the pitch map      */
    double pitch_turn; /* table position where dir last changed     */
    uint64_t rng;
    uint64_t ref_rng; /* reference-scale noise generator */
    /* axis_ref_reading_at without noise is a function of x and the
     * resolution: its last arguments (bits) and result, reused when both
     * are the same (an axis standing still); ref_memo cleared by
     * axis_init */
    bool ref_memo;
    uint64_t ref_x, ref_res;
    int64_t ref_count;
} axis_t;

/* floor(x) as an int64 (x finite, |x| < 2^63): for |x| < 2^53 by a
 * truncating conversion and a correction (the same value as floor, without
 * a call to the C library's floor), otherwise floor itself. */
static inline int64_t axis_floor_i64(double x)
{
    if (x > -9007199254740992.0 && x < 9007199254740992.0) {
        int64_t i = (int64_t)x; /* toward zero */
        return i - (int64_t)(x < (double)i);
    }
    return (int64_t)floor(x);
}

/* Parameters of the thesis's X (y_axis false) or Y axis, options off, encoder
 * 1000 lines x4 (offset 0.5 count), reference scale 1 nm. */
void axis_params_lacerda(axis_params_t *p, bool y_axis);

/* Continuous-time matrices of the linear part (gap closed). B columns are
 * [u, T1, T2]. */
void axis_model_matrices(const axis_params_t *p, double a[AXIS_NSTATE][AXIS_NSTATE],
                         double b[AXIS_NSTATE][AXIS_NINPUT]);

/* Eigenvalues of A (rad/s), sorted by increasing real part then imaginary. */
void axis_model_eigenvalues(const axis_params_t *p, double complex ev[AXIS_NSTATE]);

/* e^{M t} of an n x n row-major matrix (n <= 16) in double precision. */
void axis_expm(unsigned n, const double *m, double t, double *out);

/* Prepare the discretisation for substep h (s) and zero the state.
 * Returns false on invalid parameters (non-positive masses, h <= 0, ...). */
bool axis_init(axis_t *ax, const axis_params_t *p, double h);

/* Change the load torque (N m) of an initialised axis (p.load_torque: the
 * other parameters are fixed by axis_init). */
void axis_set_load_torque(axis_t *ax, double t);

/* Advance one substep with amplifier command u (V). Returns true when z is
 * bit for bit what it was before (an axis at rest: see axis_t.rest), so the
 * encoder reading without noise is the one of the previous substep. */
bool axis_substep(axis_t *ax, double u);
/* The same for an axis with lin_only and no pitch map (pitch_n 0): the
 * substep without those two tests. */
bool axis_substep_lin(axis_t *ax, double u);

/* Motor encoder position in counts (continuous, no noise) and the reading
 * the encoder reports (noise added, still continuous: the caller quantises;
 * axis_encoder_noisy: the reading with the noise drawn, the path of
 * axis_encoder_reading with noise on). Inline: read every substep. */
double axis_encoder_noisy(axis_t *ax);

static inline double axis_encoder_counts(const axis_t *ax)
{
    return ax->z[0] * ax->enc_scale + ax->p.enc_offset_counts;
}

static inline double axis_encoder_reading(axis_t *ax)
{
    return ax->p.enc_noise_counts > 0.0 ? axis_encoder_noisy(ax) : axis_encoder_counts(ax);
}

/* The pitch error map's error at table position x, moving in direction dir
 * (0 without a map). */
double axis_pitch_error(const axis_params_t *p, double x, int dir);

/* True table position, m (l th2 + pitch error; without a map x + 0.0, as
 * with one: -0.0 reads +0.0). */
static inline double axis_table_pos(const axis_t *ax)
{
    double x = ax->p.l * ax->z[2];
    return x + (ax->p.pitch_n > 0 ? axis_pitch_error(&ax->p, x, ax->pitch_dir) : 0.0);
}

/* The same without a pitch map (p.pitch_n 0). */
static inline double axis_table_pos_nomap(const axis_t *ax)
{
    return ax->p.l * ax->z[2] + 0.0;
}

/* Reference scale count: true table position / resolution, rounded to the
 * nearest count (no mean bias). */
int64_t axis_ref_count(const axis_t *ax);

/* What the reference scale reports: the count of the true table position
 * plus the reading noise (ref_noise, Gaussian, independent per call). The
 * same as axis_ref_count when ref_noise is 0. */
int64_t axis_ref_reading(axis_t *ax);
/* The same with the true table position x = axis_table_pos(ax) the caller
 * already has (the simulator computes it once per tick). */
int64_t axis_ref_reading_at(axis_t *ax, double x);

/* Place both inertias at table position x (m), at rest, current zero. */
void axis_set_position(axis_t *ax, double x);

#endif /* AXIS_MODEL_H */
