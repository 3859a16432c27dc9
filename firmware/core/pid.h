/*
 * pid.h - fixed-point PID loop with feed-forward, one per axis (and the
 * scalar loop of the contour error controller, cec.h).
 *
 * Specification
 * -------------
 * Control law, evaluated once per control tick (f = tick_hz, dt = 1/f):
 *
 *   e      = sat32(ref - meas)                       error, nm
 *   e_db   = e - sign(e)*deadband, 0 inside the band  (continuous deadband:
 *                                                     no output step at its edge)
 *   P      = Kp * e_db
 *   I     += Ki * dt * e_db                           then back-calculation and clamp
 *   D_raw  = Kd * (e - e_prev) / dt                   (d_on_measurement = false)
 *          = -Kd * (meas - meas_prev) / dt            (d_on_measurement = true)
 *   D     += alpha * (D_raw - D),  alpha = dt / (tau + dt)   first-order filter
 *                                                     (backward Euler; tau = 0: none)
 *   FF     = Kvff * vel + Kaff * acc                  feed-forward from the interpolator
 *   u_raw  = P + I + D + FF + extra                   extra: added by the caller (CEC)
 *   u      = clamp(u_raw, +-out_max)                  saturated = (u != u_raw)
 *   I     += Kt * dt * (u - u_raw)                    back-calculation anti-windup
 *   I      = clamp(I, +-i_max)
 *   output = round(u) in millivolts
 *
 * User parameters (pid_params_t) are rate-independent SI values in q32_32
 * (the real value times 2^32, exactly what `round(x * 2**32)` gives on the
 * host): Kp in V/m, Ki in V/(m*s), Kd in V*s/m, Kvff in V/(m/s),
 * Kaff in V/(m/s^2), Kt (back-calculation tracking rate) in 1/s. The thesis's
 * axis gains Kp 1.5e3, Ki 8e3, Kd 5 are therefore 1.5e3 * 2^32 etc. Any gain in
 * [0, 2^30) of these units is accepted (resolution 2^-32 = 2.3e-10).
 *
 * pid_config() is the conversion helper: it validates the parameters and turns
 * them into per-tick coefficients for the given tick rate, each a pseudo-float
 * pid_coef_t (31-bit mantissa m and a shift sh, value m * 2^-sh), so every
 * gain keeps 30 significant bits at any tick rate from 100 Hz to 100 kHz.
 * Internal unit of every term: "U" = millivolt * 2^-32 (int64). Terms are
 * clamped to +-2^28 mV before summing, so sums never overflow.
 *
 *   coefficient  input                              unit of the coefficient
 *   cp           e_db, int32 nm                     U per nm          = Kp * 1e-6 * 2^32
 *   ci           e_db, int32 nm, per tick           U per nm per tick = Ki * 1e-6 / f * 2^32
 *   cd           delta e, int32 nm per tick         U per nm/tick     = Kd * 1e-6 * f * 2^32
 *   cv           vel >> 2, int32 (4 nm/s units)     U per 4 nm/s      = Kvff * 4e-6 * 2^32
 *   ca           acc >> 10, int32 (1024 nm/s^2)     U per 1024 nm/s^2 = Kaff * 1.024e-3 * 2^32
 *   kt_q30       (u - u_raw) in U                   ratio per tick    = Kt / f, q1_30, <= 1
 *   alpha_q30    D filter                           ratio per tick    = 1 / (1 + tau * f), q1_30
 *
 * Ranges: vel is saturated to +-2^33 nm/s (8.5 m/s), acc to +-2^41 nm/s^2
 * (2.2e3 m/s^2), e to int32 (+-2.1 m), the D input to +-2^31 nm per tick.
 * Resolution of the integrator: 2^-32 mV. out_max_mv and i_max_mv are at most
 * PID_MV_MAX; the amplifier range of this product is +-160000 mV.
 *
 * Fast path (pid_step_fast*, taken by pid_step/pid_step_e whenever it applies):
 * P and the integrator exactly as above (64-bit, U: the same products,
 * rounding and clamps), the derivative in 32 bits, in units F = mV * 2^-11
 * (0.49 uV):
 *   Draw_F = round(de * Kd_F)                   |Draw_F| <= 2^30 - 2 F (524 V)
 *   D     += alpha * (Draw_F - floor(D))        D in F * 2^-31 (int64 pid->dq):
 *                                               one 32x32 multiply-accumulate
 *   u_raw  = P + I + floor(D) * 2^21 + extra    (then as above)
 * Kd_F = m * 2^-s with s in 1..31: the general path's mantissa of cd when its
 * shift + 21 is in range, else (Kd_F below 2^-1 F per nm/tick) a mantissa
 * rounded to s = 31. It applies when the loop is ready (pid->ready: fast
 * configuration, enabled, primed, not bumpless, D state handed over within
 * +-(2^30 - 2) F) and |de| <= pid->de_max (the largest D input keeping
 * |Draw_F| <= 2^30 - 2); otherwise the step takes the general path (the D
 * state converted back to dterm, then exact). A loop is fast when there is no
 * deadband, no feed-forward gain, cp's shift is in 2..31, ci's in 2..31 (or
 * Ki = 0) and cd's shift + 21 >= 1.
 * Error against the general (exact) path, for the same inputs: Draw_F * 2^21
 * is within 0.5 F (1 F with a rounded mantissa) of the exact D input; the
 * filter state e' = (1 - alpha) e + alpha (input error + floor loss < 1 F)
 * + the exact path's own rounding (0.5 U per tick, 0.5 U / alpha in total,
 * < 0.25 F for any alpha >= 2^-20) stays within 2.25 F of the exact filter,
 * and floor(D) loses less than 1 F more: |D_used - dterm_exact| < 4 F, so
 * |u_raw - u_raw_exact| < 4 F = 2^-9 mV (2 uV) and the output (mV, rounded)
 * differs by at most 1. Over a run the integrator has identical increments;
 * the back-calculation (Kt/f <= 1) and the clamps never widen a difference
 * beyond the D difference, so the integrator stays within 4 F as well.
 * tests/unit/test_pid.c runs the fast and the general path side by side
 * over random inputs, gains and tick rates and checks these bounds (out_mv
 * within 1 mV; u_raw, I and D within 4 F).
 *
 * Bumpless operation and resets:
 *   pid_enable(u_hold)   the first step after it outputs u_hold (the integrator
 *                        absorbs the difference, within its clamp) and has no
 *                        derivative kick. Disabled loops output 0 but keep
 *                        tracking their inputs, so enabling never kicks.
 *   pid_reset(bumpless)  bumpless: as pid_enable(last output); otherwise the
 *                        integrator and D filter are cleared (no D kick either).
 *   pid_config()         on a running loop: the integrator is re-computed so
 *                        that the output with the new gains and the last inputs
 *                        is unchanged (bumpless gain change).
 *   pid_rebase(offset)   the measured position frame moved by offset nm (index,
 *                        homing; the caller moves the reference by the same
 *                        offset in the same tick): the stored measurement is
 *                        moved so the derivative sees no step. Feed-forward is
 *                        taken from the interpolator's vel/acc, never from
 *                        differencing positions, so a reset cannot spike it.
 *   pid_add_integrator() bumpless hand-over of a correction into the integrator
 *                        (used when the contour error controller switches off).
 *
 * Contexts: pid_step, pid_rebase, pid_add_integrator: tick. pid_config,
 * pid_enable, pid_disable, pid_reset: main or tick, never concurrently with
 * pid_step on the same loop (the servo applies them inside its tick).
 * All fields of pid_loop_t are written only by these functions; the status
 * fields (err_nm, out_mv, saturated, sat_ticks, sat_total) may be read anywhere.
 */
#ifndef PID_H
#define PID_H

#include <stdbool.h>
#include <stdint.h>

#include "fixmath.h"

/* Host-only forms (64-bit hosts; docs/fast-paths.md): the servo's axis
 * step takes the lean step inline (pid_step_lean_inline; servo.c
 * axis_step) with its shifts - 1 kept (lean_sh1), and the fast step tests
 * its D input on the error with one compare; 32-bit targets keep their
 * forms and call pid_step_e (the Cortex-M4's tick keeps its figures). */
#ifndef PID_HOST_INLINE
#if UINTPTR_MAX > 0xFFFFFFFFu
#define PID_HOST_INLINE 1
#else
#define PID_HOST_INLINE 0
#endif
#endif

#define PID_MV_MAX       1000000 /* largest out_max_mv / i_max_mv accepted (1 kV) */
#define PID_TICK_HZ_MIN  100
#define PID_TICK_HZ_MAX  100000
#define PID_GAIN_MAX     ((q32_32_t)1 << 62) /* 2^30 in any gain unit, exclusive */
#define PID_DFILT_US_MAX 10000000u           /* D filter time constant limit: 10 s */
#define PID_TERM_LIM     ((int64_t)1 << 60)  /* 2^28 mV in U: clamp of each term  */
#define PID_FAST_D_MAX   0x3FFFFFFE          /* fast path: |Draw_F|, |D| bound, F    */

/* Pseudo-float coefficient: value = m * 2^-sh (sh may be negative). */
typedef struct {
    int32_t m;
    int32_t sh;
} pid_coef_t;

typedef struct {
    q32_32_t kp;           /* V/m,          >= 0                                  */
    q32_32_t ki;           /* V/(m*s),      >= 0                                  */
    q32_32_t kd;           /* V*s/m,        >= 0                                  */
    q32_32_t kvff;         /* V/(m/s),      >= 0 velocity feed-forward            */
    q32_32_t kaff;         /* V/(m/s^2),    >= 0 acceleration feed-forward        */
    q32_32_t kt;           /* 1/s,          >= 0 back-calculation rate; 0: clamp only */
    uint32_t d_tau_us;     /* D filter time constant, us; 0: unfiltered           */
    int32_t deadband_nm;   /* 0..2^30                                           */
    int32_t i_max_mv;      /* integrator clamp, mV, 0..PID_MV_MAX                 */
    int32_t out_max_mv;    /* output clamp, mV, 1..PID_MV_MAX (160000 = amplifier) */
    uint32_t tick_hz;      /* control tick rate, PID_TICK_HZ_MIN..MAX             */
    bool d_on_measurement; /* D on -meas (no kick on reference steps) or on e  */
} pid_params_t;

typedef enum {
    PID_OK = 0,
    PID_ERR_NULL,
    PID_ERR_TICK_HZ,  /* tick_hz outside PID_TICK_HZ_MIN..MAX              */
    PID_ERR_GAIN,     /* a gain is negative or >= PID_GAIN_MAX             */
    PID_ERR_OUT_MAX,  /* out_max_mv outside 1..PID_MV_MAX                  */
    PID_ERR_I_MAX,    /* i_max_mv outside 0..PID_MV_MAX                    */
    PID_ERR_DEADBAND, /* deadband_nm outside 0..2^30                       */
    PID_ERR_D_FILTER  /* d_tau_us > PID_DFILT_US_MAX                       */
} pid_err_t;

typedef struct {
    /* configuration (pid_config) */
    pid_params_t p;
    pid_coef_t cp, ci, cd, cv, ca;
    q1_30_t kt_q30;
    q1_30_t alpha_q30;
    int64_t i_lim;   /* U */
    int64_t out_lim; /* U */
    int32_t deadband;
    bool fast;       /* pid_config: the fast path applies (see Fast path) */
    bool dfilt;      /* fast: D filter on (alpha < 1)                       */
    bool lean;       /* pid_config: the lean general step applies (below)   */
    uint8_t fp_sh;   /* fast: P = round(e * fp_m * 2^-fp_sh) U (as cp), 2..31 */
    uint8_t fd_sh;   /* fast: Draw_F = round(de * fd_m * 2^-fd_sh), 1..31   */
    uint8_t fi_sh;   /* fast: integrator increment shift (ci.sh, 2..31)     */
    int32_t fp_m;    /* fast: cp.m; each mantissa next to its rounding  */
    uint32_t fp_rnd; /* constant 2^(shift - 1) (one paired load)         */
    int32_t fd_m;    /* fast: D mantissa, F per nm/tick * 2^fd_sh        */
    uint32_t fd_rnd;
    int32_t fi_m; /* fast: ci.m (0 when Ki = 0)                          */
    uint32_t fi_rnd;
    int32_t alpha_q31; /* fast: alpha_q30 * 2 (dfilt)         */
    uint32_t de_max;   /* fast: largest |de| with |Draw_F| <= 2^30 - 2        */
    int32_t i_max;     /* fast: i_max_mv                                      */
    int32_t o_max;     /* fast: out_max_mv                                    */
    /* state (tick) */
    int64_t integ; /* U */
    int64_t dterm; /* U, filtered derivative term (stale while dq_live:
                    * pid_dterm() reads either) */
    int64_t dq;    /* fast path's D state, F * 2^-31 = mV * 2^-42 (dq_live) */
    int64_t ff;    /* U, last feed-forward (0 while ready: not written by
                    * the short path) */
    int64_t extra; /* U, last extra input (not written by pid_step_fast0) */
    int64_t out;   /* U, last clamped output */
    pos_nm_t meas_prev;
    int32_t hold_mv; /* output to continue from on the next step (bumpless) */
    bool enabled;
    bool primed;   /* meas_prev/err_nm valid: no D kick             */
    bool bumpless; /* next enabled step re-computes the integrator     */
    bool dq_live;  /* the D state is dq (fast path), not dterm: set by a
                    * general step that hands over to the fast path (D
                    * within range), cleared when the general path takes
                    * the state back (it converts dq to dterm first) */
    bool ready;    /* cached fast && primed && enabled && !bumpless &&
                    * dq_live: re-derived (pid_refresh_ready) by every
                    * function that writes one of them, so the tick reads
                    * one flag; a copy that pokes fast must call it too */
    bool lean_rdy; /* cached lean && enabled && primed && !bumpless &&
                    * !dq_live (the lean step applies), kept as ready */
#if PID_HOST_INLINE
    uint8_t lean_sh1[5]; /* pid_config, 64-bit hosts: the lean step's shifts
                          * - 1 (cp, cd, cv, ca, ci; lean only): the
                          * products' rounding without a decrement each */
#endif
    bool rest; /* 64-bit hosts (PID_REST): the last write was a rest
                * step, so the rest step's conditions on the state
                * hold (see pid_rest_cached); every other pid.h/pid.c
                * writer clears it. Always false on 32-bit targets. */
    /* status (read anywhere) */
    int32_t err_nm;     /* last error before the deadband                  */
    int32_t out_mv;     /* last output, mV                                 */
    bool saturated;     /* last output was clamped                         */
    uint32_t sat_ticks; /* consecutive saturated ticks                   */
    uint32_t sat_total; /* saturated ticks since configuration           */
} pid_loop_t;

/* Coefficient value = num * mul / den (real division), normalised to a 31-bit
 * mantissa. den > 0 and < 2^62. False when |value| >= 2^31 * 2^31 (too large);
 * values below 2^-62 become 0. Configuration context (it loops ~160 times). */
bool pid_coef_make(pid_coef_t *c, int64_t num, uint32_t mul, uint64_t den);
/* round(x * value), clamped to +-PID_TERM_LIM. */
int64_t pid_coef_apply(pid_coef_t c, int32_t x);
/* Test hook: pid_coef_apply by the 32-bit-pieces form (the one 32-bit
 * targets compile, PID_COEF_PIECES in pid.c) whatever the target. */
int64_t pid_coef_pieces_test(pid_coef_t c, int32_t x);

/* Validate p (see pid_err_t); on success apply it (bumpless when enabled).
 * On failure nothing changes. A loop must be configured before use; a zeroed
 * pid_loop_t is a disabled loop that outputs 0. */
pid_err_t pid_config(pid_loop_t *pid, const pid_params_t *p);

void pid_enable(pid_loop_t *pid, int32_t u_hold_mv);
void pid_disable(pid_loop_t *pid);
void pid_reset(pid_loop_t *pid, bool bumpless);
void pid_rebase(pid_loop_t *pid, pos_nm_t offset_nm);
/* Add delta (U) to the integrator, clamped to i_max. */
void pid_add_integrator(pid_loop_t *pid, int64_t delta_u);

/* One tick. ref, meas: nm; vel: nm/s; acc: nm/s^2; extra: U (mV * 2^32),
 * added before the output clamp. Returns the output in mV (0 when disabled).
 * The clamped output in U is in pid->out. */
int32_t pid_step(pid_loop_t *pid, pos_nm_t ref, pos_nm_t meas, int64_t vel, int64_t acc,
                 int64_t extra);
/* pid_step with the error already computed: e = sat32(ref - meas) (as the
 * servo's following-error check has it); the same result as pid_step. */
int32_t pid_step_e(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t vel, int64_t acc,
                   int64_t extra);
/* The fast path of pid_step_e (see Fast path), valid only while
 * pid_fast_ready(pid); inputs out of its range take the general path.
 * vel and acc are not needed (no feed-forward). */
int32_t pid_step_fast(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t extra);
/* pid_step_fast with extra = 0 (the servo's axes while the contour error
 * controller is quiet): the same results, one 64-bit argument less. */
int32_t pid_step_fast0(pid_loop_t *pid, int32_t e, pos_nm_t meas);
/* The general (exact) path, whatever pid->ready says (the oracle of the
 * fast path in tests; pid_step_e uses it when the fast path does not
 * apply).
 *
 * Lean general step (exact): pid->lean (pid_config: not fast, i.e. with
 * feed-forward, no deadband, the D filter on, every
 * coefficient's shift in 2..31) and a usual step (enabled, primed, not
 * bumpless, the D state not with the fast path): pid_step_e takes the
 * general path's operations in its order without the tests for the cases
 * that cannot arise, the same output and state bit for bit (test_pid.c:
 * test_lean_step_equals_general). The X and Y loops of a circle with
 * feed-forward take it on every tick (host simulator).
 *
 * Rest step (exact, 64-bit hosts only, PID_REST): a ready loop
 * (fast path) whose step would leave every field as it is returns at once
 * from pid_step_e: e == 0 and the last e == 0 and meas == meas_prev (no D
 * input in either form), the D state at its fixed point (dq / 2^31 == 0
 * with the filter, dq == 0 without), the clamped extra input equal to the
 * last one, and the last output unsaturated (sat_ticks 0) and equal to
 * integ + extra inside the output clamp: then P, D and the integrator's
 * increment are 0 and the fast step would write the same values again
 * (out_mv is re-derived from out as the fast step derives it). An axis
 * standing still (Z on a circle in the X-Y plane) takes it on every tick
 * (test_pid.c: test_rest_step_equals_fast). The rest step sets pid->rest;
 * while nothing else has written the loop, pid_rest_cached tests only the
 * step's own inputs (the servo's axes with the contour error controller
 * on: test_pid.c test_rest_cached_equals_step, test_servo.c
 * test_cec_tick_axis_steps_equal_pid_step_e). */
int32_t pid_step_general(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t vel, int64_t acc,
                         int64_t extra);
/* The saturated end of a fast step (out of line: rare). raw: u_raw in U;
 * integ: the integrator after this step's increment and clamp. */
int32_t pid_fast_saturated(pid_loop_t *pid, int64_t raw, int64_t integ);

/* The filtered D term in U, from whichever state is live. */
int64_t pid_dterm(const pid_loop_t *pid);

/* The rest step (see pid_step_general, Rest step) and its cached form:
 * on 64-bit hosts only (the Cortex-M4 tick keeps its instructions). */
#ifndef PID_REST
#if UINTPTR_MAX > 0xFFFFFFFFu
#define PID_REST 1
#else
#define PID_REST 0
#endif
#endif

/* Every write to a loop but the rest step's: pid->rest no longer holds. */
static inline void pid_rest_clear(pid_loop_t *pid)
{
    if (PID_REST) {
        pid->rest = false;
    }
}

/* The rest step with its conditions on the state cached (pid->rest, set by
 * pid_step_e's rest step): true when pid_step_e(pid, e, meas, vel, acc,
 * extra) would be a rest step again, which writes nothing and returns
 * pid->out_mv (the rest step before wrote it). The per-step conditions
 * are tested here: e == 0, meas == meas_prev and extra == pid->extra
 * (pid->extra is clamped, so this is the rest step's test on the clamped
 * extra input; an extra input that clamps to it is left to pid_step_e).
 * Only for loops written by pid.c and pid.h alone (the servo's axes: the
 * contour error controller writes its channels' outputs itself, which
 * would not clear pid->rest). False on 32-bit targets. */
static inline bool pid_rest_cached(const pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t extra)
{
    return PID_REST && pid->rest && e == 0 && meas == pid->meas_prev && extra == pid->extra;
}

/* Re-derive pid->ready and pid->lean_rdy from their inputs. */
static inline void pid_refresh_ready(pid_loop_t *pid)
{
    pid->ready = pid->fast && pid->primed && pid->enabled && !pid->bumpless && pid->dq_live;
    pid->lean_rdy = pid->lean && pid->primed && pid->enabled && !pid->bumpless && !pid->dq_live;
    pid_rest_clear(pid);
}

/* The cached pid->ready. */
static inline bool pid_fast_ready(const pid_loop_t *pid)
{
    return pid->ready;
}

/* An int32 the compiler must keep as a plain 32-bit register (so that
 * widening products stay single SMULL/SMLAL instructions); no effect on
 * the value. */
static inline int32_t pid_opaque32(int32_t v)
{
    return fx_opaque32(v);
}

/* The fast step (see Fast path) for the servo's inline use: the same as
 * pid_step_fast (has_extra) or pid_step_fast0. Valid only while
 * pid_fast_ready(pid). */
#if defined(__GNUC__)
#define PID_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define PID_ALWAYS_INLINE inline
#endif

static PID_ALWAYS_INLINE int32_t pid_step_fast_inline(pid_loop_t *pid, int32_t e, pos_nm_t meas,
                                                      int64_t extra, bool has_extra)
{
    int32_t de, df, dn, ih, rh;
    int64_t integ, raw, dq;

    if (pid->p.d_on_measurement) {
        uint64_t a = (uint64_t)pid->meas_prev, b = (uint64_t)meas;
        uint64_t d = a - b;
        uint32_t ah = (uint32_t)(a >> 32), bh = (uint32_t)(b >> 32), dh = (uint32_t)(d >> 32);

        de = (int32_t)(uint32_t)d;
        if ((int32_t)((ah ^ bh) & (ah ^ dh)) < 0 || (int32_t)dh != (de >> 31)) {
            return pid_step_general(pid, e, meas, 0, 0, extra); /* |de| >= 2^31 */
        }
        if (PID_HOST_INLINE && !fx_in_range32(de, pid->de_max)) {
            return pid_step_general(pid, e, meas, 0, 0, extra);
        }
    } else {
        int64_t d = (int64_t)e - pid->err_nm; /* err_nm: the previous step's e */
        /* 64-bit hosts: |d| <= de_max (< 2^31) as one unsigned compare (|d| <
         * 2^32), no second test; the M4 keeps its form (this one cost its
         * tick 30 instructions: code generation of the axes' steps) */
        if (PID_HOST_INLINE ? (uint64_t)(d + (int64_t)pid->de_max) > 2u * (uint64_t)pid->de_max
                            : d > (int64_t)pid->de_max || d < -(int64_t)pid->de_max) {
            return pid_step_general(pid, e, meas, 0, 0, extra);
        }
        de = (int32_t)d;
    }
    if (!PID_HOST_INLINE && !fx_in_range32(de, pid->de_max)) {
        return pid_step_general(pid, e, meas, 0, 0, extra);
    }
    dn = fx_mul_rsh32(de, pid->fd_m, pid->fd_sh, pid->fd_rnd);
    dq = pid->dq;
    if (pid->dfilt) {
        df = (int32_t)(dq >> 31);
        dq += (int64_t)(dn - df) * pid->alpha_q31;
    } else {
        dq = (int64_t)((uint64_t)(int64_t)dn << 31);
    }
    df = (int32_t)(dq >> 31);
    pid_rest_clear(pid);
    pid->dq = dq;
    pid->meas_prev = meas;
    pid->err_nm = e;
    integ = pid->integ + fx_mul_rsh64(e, pid->fi_m, pid->fi_sh, pid->fi_rnd);
    ih = (int32_t)(integ >> 32);
    if (!((uint32_t)ih + (uint32_t)pid->i_max < 2u * (uint32_t)pid->i_max)) {
        /* |I| may exceed i_max: the exact clamp */
        int64_t lim = pid->i_lim;
        integ = (integ > lim) ? lim : (integ < -lim) ? -lim : integ;
    }
    raw = integ + fx_mul_rsh64(e, pid->fp_m, pid->fp_sh, pid->fp_rnd);
    raw += (int64_t)df * pid_opaque32((int32_t)1 << 21); /* floor(D) in U: one SMLAL */
    if (has_extra) {
        int64_t ex = extra;
        ex = (ex > PID_TERM_LIM) ? PID_TERM_LIM : (ex < -PID_TERM_LIM) ? -PID_TERM_LIM : ex;
        pid->extra = ex;
        raw += ex;
    }
    rh = (int32_t)(raw >> 32);
    if (!((uint32_t)rh + (uint32_t)pid->o_max < 2u * (uint32_t)pid->o_max)) {
        return pid_fast_saturated(pid, raw, integ); /* |u_raw| may exceed out_max */
    }
    pid->integ = integ;
    pid->out = raw;
    pid->saturated = false;
    pid->sat_ticks = 0;
    rh += (int32_t)((uint32_t)raw >> 31); /* round(u / 2^32) */
    pid->out_mv = rh;
    return rh;
}

/* Shifts 1..31 in 32-bit pieces on 32-bit targets (the Cortex-M4 has no
 * 64-bit shift); a 64-bit host shifts the product in one instruction (the
 * general form in pid.c, the same value: round half up of p / 2^sh), which
 * saves it about 25 instructions per term (x86 bench_hil: 8 terms, 235 per
 * simulated tick). test_pid.c: test_coef_pieces_equal_wide. */
#ifndef PID_COEF_PIECES
#if UINTPTR_MAX > 0xFFFFFFFFu
#define PID_COEF_PIECES 0
#else
#define PID_COEF_PIECES 1
#endif
#endif

/* round(p / 2^sh) half up for sh in 1..31 with 32-bit shifts; |p| < 2^62 */
static inline int64_t pid_coef_pieces(int64_t p, unsigned sh)
{
    uint64_t u = (uint64_t)p + ((uint32_t)1 << (sh - 1u));
    uint32_t lo = (uint32_t)u, hi = (uint32_t)(u >> 32);
    uint32_t rlo = (lo >> sh) | (hi << (32u - sh));
    uint32_t rhi = (uint32_t)((int32_t)hi >> sh);
    return (int64_t)(((uint64_t)rhi << 32) | rlo);
}

/* pid_coef_apply for a shift in 2..31: the same value, no tests (|x m| <
 * 2^62, so |result| <= 2^60: no clamp) */
static inline int64_t pid_coef_mid_apply(pid_coef_t c, int32_t x)
{
    int64_t p = (int64_t)x * c.m;
    if (PID_COEF_PIECES) {
        return pid_coef_pieces(p, (unsigned)c.sh);
    }
    /* floor((p + 2^(sh-1)) / 2^sh) == floor((floor(p / 2^(sh-1)) + 1) / 2):
     * no rounding constant to build from the shift */
    return ((p >> (unsigned)(c.sh - 1)) + 1) >> 1;
}

/* pid_coef_mid_apply with the shift - 1 at hand (64-bit hosts' form) */
static inline int64_t pid_coef_mid_sh1(int32_t m, unsigned sh1, int32_t x)
{
    return ((((int64_t)x * m) >> sh1) + 1) >> 1;
}

/* fx_sat32_fast(v) with one compare on the usual path (an int32 value) */
static inline int32_t pid_sat32_usual(int64_t v)
{
    if (v == (int64_t)(int32_t)v) {
        return (int32_t)v;
    }
    return (v < 0) ? INT32_MIN : INT32_MAX;
}

/* The lean general step (see pid_step_general), valid only while
 * pid->lean_rdy: pid_step_general's operations for pid->lean and a usual
 * step (deadband 0: edb = e; the D filter on; not fast: no hand-over,
 * ready stays false); a saturated output ends in pid_fast_saturated (the
 * general path's end). pid_step_e takes it out of line; the servo's axis
 * step inline on 64-bit hosts (PID_HOST_INLINE, servo.c). */
static PID_ALWAYS_INLINE int32_t pid_step_lean_inline(pid_loop_t *pid, int32_t e, pos_nm_t meas,
                                                      int64_t vel, int64_t acc, int64_t extra)
{
    int32_t de = pid->p.d_on_measurement ? fx_sat_diff32(pid->meas_prev, meas)
                                         : fx_sat_diff32(e, pid->err_nm);
#if PID_HOST_INLINE
    int64_t pterm = pid_coef_mid_sh1(pid->cp.m, pid->lean_sh1[0], e);
    int64_t draw = pid_coef_mid_sh1(pid->cd.m, pid->lean_sh1[1], de);
    int64_t ff =
        pid_coef_mid_sh1(pid->cv.m, pid->lean_sh1[2], pid_sat32_usual(fx_round_shift64(vel, 2))) +
        pid_coef_mid_sh1(pid->ca.m, pid->lean_sh1[3], pid_sat32_usual(fx_round_shift64(acc, 10)));
    int64_t ii = pid_coef_mid_sh1(pid->ci.m, pid->lean_sh1[4], e);
#else
    int64_t pterm = pid_coef_mid_apply(pid->cp, e);
    int64_t draw = pid_coef_mid_apply(pid->cd, de);
    int64_t ff = pid_coef_mid_apply(pid->cv, pid_sat32_usual(fx_round_shift64(vel, 2))) +
                 pid_coef_mid_apply(pid->ca, pid_sat32_usual(fx_round_shift64(acc, 10)));
    int64_t ii = pid_coef_mid_apply(pid->ci, e);
#endif
    int64_t dterm = pid->dterm + fx_mul_q30_pos(draw - pid->dterm, pid->alpha_q30);
    int64_t ex = (extra == 0) ? 0 : fx_clamp_sym64(extra, PID_TERM_LIM);
    int64_t integ = fx_clamp_sym64(pid->integ + ii, pid->i_lim);
    int64_t raw, lim;

    pid->err_nm = e;
    pid->dterm = dterm;
    pid->meas_prev = meas;
    pid->ff = ff;
    pid->extra = ex;
    raw = pterm + integ + dterm + ff + ex;
    lim = pid->out_lim;
    if (raw > lim || raw < -lim) {
        return pid_fast_saturated(pid, raw, integ);
    }
    /* pid->rest is false already: lean_rdy excludes ready, which it needs */
    pid->saturated = false;
    pid->sat_ticks = 0;
    pid->integ = integ;
    pid->out = raw;
    pid->out_mv = (int32_t)fx_round_shift64(raw, 32);
    return pid->out_mv;
}

#endif /* PID_H */
