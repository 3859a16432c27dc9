/*
 * pid.c - fixed-point PID loop with feed-forward; specification in pid.h.
 */
#include "pid.h"

#include <stddef.h>

#define U_PER_MV ((int64_t)1 << 32)

static int64_t clamp64(int64_t v, int64_t lim)
{
    if (v > lim) {
        return lim;
    }
    if (v < -lim) {
        return -lim;
    }
    return v;
}

/* Inline forms of the fixmath helpers for the tick path (same results). */
static inline int64_t rsh(int64_t v, unsigned s)
{
    return (v >> s) + ((v >> (s - 1)) & 1); /* round half up, s >= 1 */
}

/* An int32 value the compiler must treat as a plain 32-bit register, so
 * the widening products below stay single SMULL/UMULL instructions (GCC
 * otherwise keeps some sign-extended values as 64-bit pairs and emits a
 * 64x64 multiply). No effect on the value. */
static inline int32_t opaque32(int32_t v)
{
#if defined(__GNUC__)
    __asm__("" : "+r"(v));
#endif
    return v;
}

/* round(a * b / 2^30) for |a| <= 2^61 and 0 <= b <= 2^30, without a 128-bit
 * product: a = ah * 2^32 + al with al unsigned; a * b = ah * b * 2^32 + al * b
 * (ah * b: one SMULL, al * b: one UMULL). */
static inline int64_t mul_q30_pos(int64_t a, q1_30_t b)
{
    int32_t ah = opaque32((int32_t)(a >> 32)); /* |ah| <= 2^29 */
    uint32_t al = (uint32_t)a;
    int64_t h = (int64_t)ah * b;              /* |h| <= 2^59 */
    uint64_t lo = (uint64_t)al * (uint32_t)b; /* < 2^62 */
    return (int64_t)((uint64_t)h << 2) + (int64_t)((lo + ((uint64_t)1 << 29)) >> 30);
}

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
    if (c.sh > 0 && c.sh < 32) {
        /* the same rounding with 32-bit shifts (the usual shifts: 4..20 for
         * the default gains at 5-10 kHz); |v| < 2^61 needs the clamp only
         * for sh == 1 */
        unsigned sh = (unsigned)c.sh;
        uint64_t u = (uint64_t)p + ((uint32_t)1 << (sh - 1u));
        uint32_t lo = (uint32_t)u, hi = (uint32_t)(u >> 32);
        uint32_t rlo = (lo >> sh) | (hi << (32u - sh));
        uint32_t rhi = (uint32_t)((int32_t)hi >> sh);
        int64_t v = (int64_t)(((uint64_t)rhi << 32) | rlo);
        return (sh >= 2u) ? v : clamp64(v, PID_TERM_LIM);
    }
    if (c.sh > 0) {
        /* round half up, as rsh(): |p| + 2^(sh-1) < 2^63 never overflows */
        int64_t v = (p + ((int64_t)1 << (unsigned)(c.sh - 1))) >> (unsigned)c.sh;
        if (c.sh >= 2) {
            return v; /* |v| <= 2^62 / 4 = PID_TERM_LIM: inside the clamp */
        }
        return clamp64(v, PID_TERM_LIM);
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
    return clamp64(p, PID_TERM_LIM);
}

/* coef_apply for a shift in 2..31, with its rounding constant rnd = 2^(sh - 1) given
 * (pid_config keeps it in pid->rnd[]) */
static inline int64_t coef_apply_rnd(pid_coef_t c, int32_t x, uint32_t rnd)
{
    unsigned sh = (unsigned)c.sh;
    uint64_t u = (uint64_t)((int64_t)opaque32(x) * c.m) + rnd;
    uint32_t lo = (uint32_t)u, hi = (uint32_t)(u >> 32);
    uint32_t rlo = (lo >> sh) | (hi << (32u - sh));
    uint32_t rhi = (uint32_t)((int32_t)hi >> sh);

    return (int64_t)(((uint64_t)rhi << 32) | rlo);
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
    pid->fast = coef_mid(cp) && coef_mid(ci) && coef_mid(cd) && cv.m == 0 && ca.m == 0 &&
                p->deadband_nm == 0;
    pid->rnd[0] = pid->fast ? (uint32_t)1 << (unsigned)(cp.sh - 1) : 0u;
    pid->rnd[1] = pid->fast ? (uint32_t)1 << (unsigned)(ci.sh - 1) : 0u;
    pid->rnd[2] = pid->fast ? (uint32_t)1 << (unsigned)(cd.sh - 1) : 0u;
    if (pid->enabled && pid->primed) {
        /* bumpless gain change: the next step continues from the last output */
        pid->hold_mv = pid->out_mv;
        pid->bumpless = true;
    }
    pid->integ = clamp64(pid->integ, pid->i_lim);
    pid_refresh_ready(pid);
    return PID_OK;
}

const char *pid_strerror(pid_err_t err)
{
    switch (err) {
    case PID_OK:
        return "ok";
    case PID_ERR_NULL:
        return "missing loop or parameters";
    case PID_ERR_TICK_HZ:
        return "tick_hz out of range 100..100000";
    case PID_ERR_GAIN:
        return "gain negative or >= 2^30 (q32_32 SI units)";
    case PID_ERR_OUT_MAX:
        return "out_max_mv out of range 1..1000000";
    case PID_ERR_I_MAX:
        return "i_max_mv out of range 0..1000000";
    case PID_ERR_DEADBAND:
        return "deadband_nm out of range 0..2^30";
    case PID_ERR_D_FILTER:
        return "d_tau_us above 10 s";
    }
    return "unknown pid error";
}

void pid_enable(pid_loop_t *pid, int32_t u_hold_mv)
{
    int64_t lim = (pid->out_lim > 0) ? pid->out_lim : 0;
    pid->hold_mv = (int32_t)(clamp64((int64_t)u_hold_mv * U_PER_MV, lim) / U_PER_MV);
    pid->bumpless = true;
    pid->enabled = true;
    pid->sat_ticks = 0;
    pid->sat_total = 0;
    pid_refresh_ready(pid);
}

void pid_disable(pid_loop_t *pid)
{
    pid->enabled = false;
    pid->bumpless = false;
    pid->ready = false;
    pid->integ = 0;
    pid->dterm = 0;
    pid->out = 0;
    pid->out_mv = 0;
    pid->saturated = false;
    pid->sat_ticks = 0;
}

void pid_reset(pid_loop_t *pid, bool bumpless)
{
    if (bumpless) {
        pid->hold_mv = pid->out_mv;
        pid->bumpless = pid->enabled;
        pid_refresh_ready(pid);
        return;
    }
    pid->integ = 0;
    pid->dterm = 0;
    pid->primed = false;
    pid->bumpless = false;
    pid->ready = false;
    pid->sat_ticks = 0;
}

void pid_rebase(pid_loop_t *pid, pos_nm_t offset_nm)
{
    pid->meas_prev += offset_nm;
}

void pid_add_integrator(pid_loop_t *pid, int64_t delta_u)
{
    pid->integ = clamp64(pid->integ + clamp64(delta_u, PID_TERM_LIM), pid->i_lim);
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
static inline int32_t pid_finish(pid_loop_t *pid, int64_t pterm, int64_t integ, int64_t dterm,
                                 int64_t ff, int64_t ex)
{
    int64_t raw = pterm + integ + dterm + ff + ex;
    int64_t u = clamp64(raw, pid->out_lim);

    if (u != raw) {
        pid->saturated = true;
        pid->sat_ticks++;
        pid->sat_total++;
        if (pid->kt_q30 != 0) {
            integ = clamp64(integ + mul_q30_pos(clamp64(u - raw, (int64_t)1 << 61), pid->kt_q30),
                            pid->i_lim);
        }
    } else {
        pid->saturated = false;
        pid->sat_ticks = 0;
    } /* the integrator is within its clamp on every path */
    pid->integ = integ;
    pid->out = u;
    pid->out_mv = (int32_t)rsh(u, 32);
    return pid->out_mv;
}

#if defined(__GNUC__)
#define PID_NOINLINE __attribute__((noinline))
#else
#define PID_NOINLINE
#endif

/* The short path (pid_fast_ready): the general path below with edb = e,
 * cd != 0, ff = 0 and coef_apply_rnd for coef_apply; the same results. */
/* sat32(a - b) of two int32 in 32-bit arithmetic (wrapped difference; on
 * overflow the true difference has the sign of a) */
static inline int32_t sat_diff32_32(int32_t a, int32_t b)
{
    int32_t d = (int32_t)((uint32_t)a - (uint32_t)b);

    if (((a ^ b) & (a ^ d)) < 0) {
        return (a < 0) ? INT32_MIN : INT32_MAX;
    }
    return d;
}

#if defined(__GNUC__)
#define PID_INLINE __attribute__((always_inline)) inline
#else
#define PID_INLINE inline
#endif

static PID_INLINE int32_t step_fast(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t extra)
{
    int32_t de = pid->p.d_on_measurement ? fx_sat_diff32(pid->meas_prev, meas)
                                         : sat_diff32_32(e, pid->err_prev);
    int64_t pterm = coef_apply_rnd(pid->cp, e, pid->rnd[0]);
    int64_t dterm = coef_apply_rnd(pid->cd, de, pid->rnd[2]);
    int64_t ex, integ;

    pid->err_nm = e;
    if (pid->alpha_q30 < FX_ONE_Q30) {
        dterm = pid->dterm + mul_q30_pos(dterm - pid->dterm, pid->alpha_q30);
    }
    pid->dterm = dterm;
    pid->meas_prev = meas;
    pid->err_prev = e;
    /* pid->ff is already 0: ready is only set by an enabled general step
     * under the current configuration, which has no feed-forward gains */
    ex = (extra == 0) ? 0 : clamp64(extra, PID_TERM_LIM);
    pid->extra = ex;
    integ = clamp64(pid->integ + coef_apply_rnd(pid->ci, e, pid->rnd[1]), pid->i_lim);
    return pid_finish(pid, pterm, integ, dterm, 0, ex);
}

int32_t pid_step_fast(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t extra)
{
    return step_fast(pid, e, meas, extra);
}

int32_t pid_step_fast0(pid_loop_t *pid, int32_t e, pos_nm_t meas)
{
    return step_fast(pid, e, meas, 0);
}

static PID_NOINLINE int32_t pid_step_general(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t vel,
                                             int64_t acc, int64_t extra)
{
    int32_t edb;
    int64_t pterm, dterm, ff, ex, integ;

    pid->err_nm = e;
    if (!pid->primed) {
        pid->meas_prev = meas;
        pid->err_prev = e;
        pid->dterm = 0;
        pid->primed = true;
    }
    if (!pid->enabled) {
        pid->meas_prev = meas;
        pid->err_prev = e;
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
                                             : fx_sat_diff32(e, pid->err_prev);
        int64_t draw = coef_apply(pid->cd, de);
        dterm = draw;
        if (pid->alpha_q30 < FX_ONE_Q30) {
            dterm = pid->dterm + mul_q30_pos(draw - pid->dterm, pid->alpha_q30);
        }
    }
    pid->dterm = dterm;
    pid->meas_prev = meas;
    pid->err_prev = e;

    /* feed-forward from the interpolator's velocity and acceleration */
    ff = 0;
    if (pid->cv.m != 0) {
        ff += coef_apply(pid->cv, fx_sat32_fast(rsh(vel, 2)));
    }
    if (pid->ca.m != 0) {
        ff += coef_apply(pid->ca, fx_sat32_fast(rsh(acc, 10)));
    }
    pid->ff = ff;
    ex = (extra == 0) ? 0 : clamp64(extra, PID_TERM_LIM);
    pid->extra = ex;

    if (pid->bumpless) {
        /* continue from hold_mv: the integrator takes the difference */
        int64_t hold = (int64_t)pid->hold_mv * U_PER_MV;
        integ = clamp64(hold - (pterm + dterm + ff + ex), pid->i_lim);
        pid->bumpless = false;
    } else {
        integ = clamp64(pid->integ + coef_apply(pid->ci, edb), pid->i_lim);
    }
    pid_refresh_ready(pid);
    return pid_finish(pid, pterm, integ, dterm, ff, ex);
}

int32_t pid_step_e(pid_loop_t *pid, int32_t e, pos_nm_t meas, int64_t vel, int64_t acc,
                   int64_t extra)
{
    if (pid_fast_ready(pid)) {
        return pid_step_fast(pid, e, meas, extra);
    }
    return pid_step_general(pid, e, meas, vel, acc, extra);
}
