/*
 * pid.c - fixed-point PID loop with feed-forward; specification in pid.h.
 */
#include "pid.h"

#include <stddef.h>

#define U_PER_MV ((int64_t)1 << 32)

bool pid_coef_make(pid_coef_t *c, int64_t num, uint32_t mul, uint64_t den)
{
    uint64_t a = (num < 0) ? (uint64_t)0 - (uint64_t)num : (uint64_t)num;
    uint64_t lo, hi, r = 0;
    uint32_t w[3], mant = 0;
    int i, lead = 0, nbits = 0, sh;
    unsigned rnd = 0;

    c->m = 0;
    c->sh = 0;
    if (den == 0 || den >= ((uint64_t)1 << 62)) {
        return false;
    }
    /* 96-bit product a * mul in three words, w[2] most significant */
    lo = (a & 0xFFFFFFFFu) * mul;
    hi = (a >> 32) * mul + (lo >> 32);
    w[0] = (uint32_t)lo;
    w[1] = (uint32_t)hi;
    w[2] = (uint32_t)(hi >> 32);
    /* Bit-serial long division of the product by den, into 64 fraction bits;
     * keep the first 31 significant quotient bits and one rounding bit. */
    for (i = 95; i >= -64; i--) {
        unsigned b = (i >= 0) ? (w[i >> 5] >> (i & 31)) & 1u : 0u;
        unsigned q = 0;
        r = (r << 1) | b;
        if (r >= den) {
            r -= den;
            q = 1;
        }
        if (nbits == 0 && q == 0) {
            continue;
        }
        if (nbits == 0) {
            lead = i;
        }
        if (nbits < 31) {
            mant = (mant << 1) | q;
            nbits++;
        } else {
            rnd = q;
            break;
        }
    }
    if (nbits == 0) {
        return true; /* zero */
    }
    sh = (nbits - 1) - lead; /* value = mant * 2^-sh */
    mant += rnd;
    if (mant >= ((uint32_t)1 << 31)) {
        mant >>= 1;
        sh--;
    }
    if (sh > 62) {
        unsigned d = (unsigned)(sh - 62);
        mant = (d >= 32) ? 0u : (uint32_t)fx_round_shift64((int64_t)mant, d);
        sh = 62;
    }
    if (sh < -31) {
        return false;
    }
    c->m = (num < 0) ? -(int32_t)mant : (int32_t)mant;
    c->sh = (mant == 0) ? 0 : sh;
    return true;
}

static inline int64_t coef_apply(pid_coef_t c, int32_t x)
{
    int64_t p = (int64_t)x * c.m; /* |p| < 2^62: one SMULL */
    if (PID_COEF_PIECES && c.sh > 0 && c.sh < 32) {
        /* the same rounding with 32-bit shifts (the usual shifts: 4..20 for
         * the default gains at 5-10 kHz); |v| < 2^61 needs the clamp only
         * for sh == 1 */
        unsigned sh = (unsigned)c.sh;
        int64_t v = pid_coef_pieces(p, sh);
        return (sh >= 2u) ? v : fx_clamp_sym64(v, PID_TERM_LIM);
    }
    if (c.sh > 0) {
        /* round half up, as fx_round_shift64(): |p| + 2^(sh-1) < 2^63 never overflows */
        int64_t v = (p + ((int64_t)1 << (unsigned)(c.sh - 1))) >> (unsigned)c.sh;
        if (c.sh >= 2) {
            return v; /* |v| <= 2^62 / 4 = PID_TERM_LIM: inside the clamp */
        }
        return fx_clamp_sym64(v, PID_TERM_LIM);
    }
    if (c.sh < 0) {
        int64_t lim = PID_TERM_LIM >> (unsigned)(-c.sh);
        if (p > lim) {
            return PID_TERM_LIM;
        }
        if (p < -lim) {
            return -PID_TERM_LIM;
        }
        return p * ((int64_t)1 << (unsigned)(-c.sh));
    }
    return fx_clamp_sym64(p, PID_TERM_LIM);
}

/* coef_apply for a shift in 2..31 (coef_mid): the rounding with 32-bit
 * shifts, no clamp needed (|x * m| < 2^62, so |result| <= 2^60) */
static inline bool coef_mid(pid_coef_t c)
{
    return c.sh >= 2 && c.sh <= 31;
}

int64_t pid_coef_apply(pid_coef_t c, int32_t x)
{
    return coef_apply(c, x);
}

int64_t pid_coef_pieces_test(pid_coef_t c, int32_t x)
{
    int64_t v;
    if (c.sh <= 0 || c.sh >= 32) {
        return coef_apply(c, x);
    }
    v = pid_coef_pieces((int64_t)x * c.m, (unsigned)c.sh);
    return (c.sh >= 2) ? v : fx_clamp_sym64(v, PID_TERM_LIM);
}

/* The fast path's form of the D coefficient c (U per input unit): value
 * in F = 2^21 U as m * 2^-sh with sh in 1..31 (see pid.h), and the largest
 * |x| with |round(x * m * 2^-sh)| <= lim. False when the gain is too large
 * for the form (sh + 21 < 1). */
static bool fast_coef(pid_coef_t c, int32_t *m, uint8_t *sh, uint32_t *rnd, uint32_t *xmax,
                      uint32_t lim)
{
    int32_t s = c.sh + 21;
    int64_t mm = c.m;
    uint64_t q, r;

    if (c.m == 0) {
        s = 31;
    } else if (s < 1) {
        return false;
    } else if (s > 31) {
        unsigned d = (unsigned)(s - 31);
        mm = (d >= 32u) ? 0 : fx_round_shift64(mm, d);
        s = 31;
    }
    *m = (int32_t)mm;
    *sh = (uint8_t)s;
    *rnd = (uint32_t)1 << (unsigned)(s - 1);
    if (mm == 0) {
        *xmax = 0x7FFFFFFFu;
        return true;
    }
    /* |x| * |m| + 2^(s-1) < (lim + 1) * 2^s  <=>  |x| * |m| <= (lim + 1/2) * 2^s - 1 */
    q = fx_udivmod64((((uint64_t)lim << 1) + 1u) << (unsigned)(s - 1),
                     (uint64_t)((mm < 0) ? -mm : mm), &r);
    if (r == 0u) {
        q--;
    }
    *xmax = (q > 0x7FFFFFFFu) ? 0x7FFFFFFFu : (uint32_t)q;
    return true;
}

/* pid->fast and the fast path's coefficients (pid.h, Fast path). */
static void fast_config(pid_loop_t *pid)
{
    const pid_params_t *p = &pid->p;
    bool ok = pid->cv.m == 0 && pid->ca.m == 0 && p->deadband_nm == 0 &&
              (pid->ci.m == 0 || coef_mid(pid->ci)) && coef_mid(pid->cp);

    pid->fp_m = pid->cp.m;
    pid->fp_sh = (uint8_t)(coef_mid(pid->cp) ? pid->cp.sh : 2);
    pid->fp_rnd = (uint32_t)1 << (pid->fp_sh - 1u);
    ok = fast_coef(pid->cd, &pid->fd_m, &pid->fd_sh, &pid->fd_rnd, &pid->de_max, PID_FAST_D_MAX) &&
         ok;
    pid->fi_m = pid->ci.m;
    pid->fi_sh = (uint8_t)((pid->ci.m == 0 || !coef_mid(pid->ci)) ? 2 : pid->ci.sh);
    pid->fi_rnd = (uint32_t)1 << (pid->fi_sh - 1u);
    pid->dfilt = pid->alpha_q30 < FX_ONE_Q30;
    pid->alpha_q31 = pid->dfilt ? pid->alpha_q30 * 2 : 0;
    pid->i_max = p->i_max_mv;
    pid->o_max = p->out_max_mv;
    pid->fast = ok;
    pid->lean = !ok && p->deadband_nm == 0 && pid->cd.m != 0 && pid->alpha_q30 < FX_ONE_Q30 &&
                coef_mid(pid->cp) && coef_mid(pid->ci) && coef_mid(pid->cd) && coef_mid(pid->cv) &&
                coef_mid(pid->ca);
#if PID_HOST_INLINE
    if (pid->lean) { /* every shift in 2..31 */
        pid->lean_sh1[0] = (uint8_t)(pid->cp.sh - 1);
        pid->lean_sh1[1] = (uint8_t)(pid->cd.sh - 1);
        pid->lean_sh1[2] = (uint8_t)(pid->cv.sh - 1);
        pid->lean_sh1[3] = (uint8_t)(pid->ca.sh - 1);
        pid->lean_sh1[4] = (uint8_t)(pid->ci.sh - 1);
    }
#endif
}

static bool gain_ok(q32_32_t g)
{
    return g >= 0 && g < PID_GAIN_MAX;
}

pid_err_t pid_config(pid_loop_t *pid, const pid_params_t *p)
{
    pid_coef_t cp, ci, cd, cv, ca;
    uint64_t f;
    int64_t kt;

    if (pid == NULL || p == NULL) {
        return PID_ERR_NULL;
    }
    if (p->tick_hz < PID_TICK_HZ_MIN || p->tick_hz > PID_TICK_HZ_MAX) {
        return PID_ERR_TICK_HZ;
    }
    if (!gain_ok(p->kp) || !gain_ok(p->ki) || !gain_ok(p->kd) || !gain_ok(p->kvff) ||
        !gain_ok(p->kaff) || !gain_ok(p->kt)) {
        return PID_ERR_GAIN;
    }
    if (p->out_max_mv < 1 || p->out_max_mv > PID_MV_MAX) {
        return PID_ERR_OUT_MAX;
    }
    if (p->i_max_mv < 0 || p->i_max_mv > PID_MV_MAX) {
        return PID_ERR_I_MAX;
    }
    if (p->deadband_nm < 0 || p->deadband_nm > ((int32_t)1 << 30)) {
        return PID_ERR_DEADBAND;
    }
    if (p->d_tau_us > PID_DFILT_US_MAX) {
        return PID_ERR_D_FILTER;
    }
    f = p->tick_hz;
    if (!pid_coef_make(&cp, p->kp, 1, 1000000u) || !pid_coef_make(&ci, p->ki, 1, 1000000u * f) ||
        !pid_coef_make(&cd, p->kd, (uint32_t)f, 1000000u) ||
        !pid_coef_make(&cv, p->kvff, 4, 1000000u) || !pid_coef_make(&ca, p->kaff, 1024, 1000000u)) {
        return PID_ERR_GAIN;
    }
    /* everything validated: apply */
    pid->p = *p;
    pid->cp = cp;
    pid->ci = ci;
    pid->cd = cd;
    pid->cv = cv;
    pid->ca = ca;
    kt = fx_div_round64(p->kt, (int64_t)(4 * f)); /* Kt / f in q1_30 */
    pid->kt_q30 = (kt > FX_ONE_Q30) ? FX_ONE_Q30 : (q1_30_t)kt;
    pid->alpha_q30 = (q1_30_t)fx_div_round64((int64_t)FX_ONE_Q30 * 1000000,
                                             1000000 + (int64_t)p->d_tau_us * (int64_t)f);
    pid->i_lim = (int64_t)p->i_max_mv * U_PER_MV;
    pid->out_lim = (int64_t)p->out_max_mv * U_PER_MV;
    pid->deadband = p->deadband_nm;
    fast_config(pid);
    pid_rest_clear(pid);
    if (pid->enabled && pid->primed) {
        /* bumpless gain change: the next step continues from the last output */
        pid->hold_mv = pid->out_mv;
        pid->bumpless = true;
    }
    pid->integ = fx_clamp_sym64(pid->integ, pid->i_lim);
    pid_refresh_ready(pid);
    return PID_OK;
}

void pid_enable(pid_loop_t *pid, int32_t u_hold_mv)
{
    int64_t lim = (pid->out_lim > 0) ? pid->out_lim : 0;
    pid->hold_mv = (int32_t)(fx_clamp_sym64((int64_t)u_hold_mv * U_PER_MV, lim) / U_PER_MV);
    pid->bumpless = true;
    pid->enabled = true;
    pid->sat_ticks = 0;
    pid->sat_total = 0;
    pid_refresh_ready(pid);
}

void pid_disable(pid_loop_t *pid)
{
    pid_rest_clear(pid);
    pid->enabled = false;
    pid->bumpless = false;
    pid->ready = false;
    pid->lean_rdy = false;
    pid->dq_live = false;
    pid->integ = 0;
    pid->dterm = 0;
    pid->dq = 0;
    pid->out = 0;
    pid->out_mv = 0;
    pid->saturated = false;
    pid->sat_ticks = 0;
}

void pid_reset(pid_loop_t *pid, bool bumpless)
{
    pid_rest_clear(pid);
    if (bumpless) {
        pid->hold_mv = pid->out_mv;
        pid->bumpless = pid->enabled;
        pid_refresh_ready(pid);
        return;
    }
    pid->integ = 0;
    pid->dterm = 0;
    pid->dq = 0;
    pid->dq_live = false;
    pid->primed = false;
    pid->bumpless = false;
    pid->ready = false;
    pid->lean_rdy = false;
    pid->sat_ticks = 0;
}

void pid_rebase(pid_loop_t *pid, pos_nm_t offset_nm)
{
    pid_rest_clear(pid);
    pid->meas_prev += offset_nm;
}

void pid_add_integrator(pid_loop_t *pid, int64_t delta_u)
{
    pid_rest_clear(pid);
    pid->integ = fx_clamp_sym64(pid->integ + fx_clamp_sym64(delta_u, PID_TERM_LIM), pid->i_lim);
}

static int32_t deadband(int32_t e, int32_t db)
{
    if (e > db) {
        return e - db;
    }
    if (e < -db) {
        return e + db;
    }
    return 0;
}

int32_t pid_step(pid_loop_t *pid, pos_nm_t ref, pos_nm_t meas, int64_t vel, int64_t acc,
                 int64_t extra)
{
    return pid_step_e(pid, fx_sat_diff32(ref, meas), meas, vel, acc, extra);
}

/* The end of a step, common to both paths: output clamp, saturation
 * count, back-calculation, integrator clamp, outputs. */
static inline int32_t pid_finish_raw(pid_loop_t *pid, int64_t raw, int64_t integ)
{
    int64_t u = fx_clamp_sym64(raw, pid->out_lim);

    pid_rest_clear(pid);
    if (u != raw) {
        pid->saturated = true;
        pid->sat_ticks++;
        pid->sat_total++;
        if (pid->kt_q30 != 0) {
            integ = fx_clamp_sym64(
                integ + fx_mul_q30_pos(fx_clamp_sym64(u - raw, (int64_t)1 << 61), pid->kt_q30),
                pid->i_lim);
        }
    } else {
        pid->saturated = false;
        pid->sat_ticks = 0;
    } /* the integrator is within its clamp on every path */
    pid->integ = integ;
    pid->out = u;
    pid->out_mv = (int32_t)fx_round_shift64(u, 32);
    return pid->out_mv;
}

#if defined(__GNUC__)
#define PID_NOINLINE __attribute__((noinline))
#else
#define PID_NOINLINE
#endif

int32_t pid_fast_saturated(pid_loop_t *pid, int64_t raw, int64_t integ)
{
    return pid_finish_raw(pid, raw, integ);
}

int32_t pid_step_fast(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t extra)
{
    return pid_step_fast_inline(pid, e, meas, extra, true);
}

int32_t pid_step_fast0(pid_loop_t *pid, int32_t e, pos_nm_t meas)
{
    return pid_step_fast_inline(pid, e, meas, 0, false);
}

int64_t pid_dterm(const pid_loop_t *pid)
{
    return pid->dq_live ? fx_round_shift64(pid->dq, 10) : pid->dterm;
}

/* Largest |dterm| (U) handed to the fast path: |floor(D)| <= 2^30 - 2 F. */
#define PID_FAST_DTERM_MAX ((int64_t)PID_FAST_D_MAX << 21)

int32_t pid_step_general(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t vel, int64_t acc,
                         int64_t extra)
{
    int32_t edb, e_prev;
    int64_t pterm, dterm, ff, ex, integ;

    if (pid->dq_live) { /* take the D state back from the fast path */
        pid->dterm = fx_round_shift64(pid->dq, 10);
        pid->dq_live = false;
        pid->ready = false;
    }
    e_prev = pid->err_nm; /* the previous step's error (D on the error) */
    pid->err_nm = e;
    if (!pid->primed) {
        pid->meas_prev = meas;
        e_prev = e;
        pid->dterm = 0;
        pid->primed = true;
    }
    if (!pid->enabled) {
        pid->meas_prev = meas;
        pid->out = 0;
        pid->out_mv = 0;
        pid->saturated = false;
        pid->sat_ticks = 0;
        return 0;
    }
    edb = deadband(e, pid->deadband);
    pterm = coef_apply(pid->cp, edb);

    /* derivative, filtered in output units */
    dterm = 0;
    if (pid->cd.m != 0) {
        int32_t de = pid->p.d_on_measurement ? fx_sat_diff32(pid->meas_prev, meas)
                                             : fx_sat_diff32(e, e_prev);
        int64_t draw = coef_apply(pid->cd, de);
        dterm = draw;
        if (pid->alpha_q30 < FX_ONE_Q30) {
            dterm = pid->dterm + fx_mul_q30_pos(draw - pid->dterm, pid->alpha_q30);
        }
    }
    pid->dterm = dterm;
    pid->meas_prev = meas;

    /* feed-forward from the interpolator's velocity and acceleration */
    ff = 0;
    if (pid->cv.m != 0) {
        ff += coef_apply(pid->cv, fx_sat32_fast(fx_round_shift64(vel, 2)));
    }
    if (pid->ca.m != 0) {
        ff += coef_apply(pid->ca, fx_sat32_fast(fx_round_shift64(acc, 10)));
    }
    pid->ff = ff;
    ex = (extra == 0) ? 0 : fx_clamp_sym64(extra, PID_TERM_LIM);
    pid->extra = ex;

    if (pid->bumpless) {
        /* continue from hold_mv: the integrator takes the difference */
        int64_t hold = (int64_t)pid->hold_mv * U_PER_MV;
        integ = fx_clamp_sym64(hold - (pterm + dterm + ff + ex), pid->i_lim);
        pid->bumpless = false;
    } else {
        integ = fx_clamp_sym64(pid->integ + coef_apply(pid->ci, edb), pid->i_lim);
    }
    /* hand the D state over to the fast path when it can take it */
    if (pid->fast && dterm >= -PID_FAST_DTERM_MAX && dterm <= PID_FAST_DTERM_MAX) {
        pid->dq = (int64_t)((uint64_t)dterm << 10);
        pid->dq_live = true;
    }
    pid_refresh_ready(pid);
    return pid_finish_raw(pid, pterm + integ + dterm + ff + ex, integ);
}

/* The lean general step (pid.h): pid_step_lean_inline out of line. */
static int32_t step_lean(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t vel, int64_t acc,
                         int64_t extra)
{
    return pid_step_lean_inline(pid, e, meas, vel, acc, extra);
}

/* A fast step at rest would write every field as it is (pid.h): no
 * error, no D input (both forms), the D state inside its fixed point, the
 * same extra input and an unsaturated last output equal to I + extra. */
static inline bool step_is_rest(const pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t ex)
{
    return e == 0 && pid->err_nm == 0 && meas == pid->meas_prev && ex == pid->extra &&
           (uint64_t)pid->dq < (pid->dfilt ? ((uint64_t)1 << 31) : 1u) && !pid->saturated &&
           pid->sat_ticks == 0 && pid->out == pid->integ + ex && pid->out <= pid->out_lim &&
           pid->out >= -pid->out_lim;
}

int32_t pid_step_e(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t vel, int64_t acc,
                   int64_t extra)
{
    if (pid_fast_ready(pid)) {
        if (PID_REST) {
            int64_t ex = fx_clamp_sym64(extra, PID_TERM_LIM);
            if (step_is_rest(pid, e, meas, ex)) {
                /* round(out / 2^32) as the fast step writes it */
                pid->out_mv = (int32_t)(pid->out >> 32) + (int32_t)((uint32_t)pid->out >> 31);
                pid->rest = true; /* pid_rest_cached */
                return pid->out_mv;
            }
        }
        return pid_step_fast_inline(pid, e, meas, extra, true);
    }
    if (pid->lean_rdy) {
        return step_lean(pid, e, meas, vel, acc, extra);
    }
    return pid_step_general(pid, e, meas, vel, acc, extra);
}
