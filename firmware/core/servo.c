/*
 * servo.c - the servo tick and its fault supervision; specification in
 * servo.h.
 */
#include "servo.h"

#include <stddef.h>

#define SI(x) ((q32_32_t)(x) << 32) /* integer SI value to q32_32 */

#if defined(__GNUC__)
#define SERVO_NOINLINE __attribute__((noinline))
#else
#define SERVO_NOINLINE
#endif

/* 64-bit hosts (PID_HOST_INLINE): the axis loop of an active CEC's tick
 * unrolled (the loops' addresses become constants; x86 bench_hil: 44
 * instructions per tick) */
#if PID_HOST_INLINE && defined(__GNUC__) && !defined(__clang__)
#define SERVO_UNROLL_AXES _Pragma("GCC unroll 3")
#else
#define SERVO_UNROLL_AXES
#endif

void servo_params_default(servo_params_t *p, uint32_t tick_hz)
{
    unsigned i;
    pid_params_t a = {0};

    a.kp = SI(1500);
    a.ki = SI(8000);
    a.kd = SI(5);
    a.kt = SI(10);
    a.d_tau_us = 100;
    a.i_max_mv = 160000;
    a.out_max_mv = 160000;
    a.tick_hz = tick_hz;
    a.d_on_measurement = true;

    p->axes = CORE_AXES;
    p->tick_hz = tick_hz;
    for (i = 0; i < CORE_AXES; i++) {
        p->axis[i] = a;
        p->ferr_limit_nm[i] = 5000000;
        p->stop_decel_nm_s2[i] = 1000000000;
    }
    p->cec.mode = CEC_MODE_OFF;
    p->cec.handover = true;
    p->cec.pid = a;
    p->cec.pid.kp = SI(40000);
    p->cec.pid.ki = SI(2000000);
    p->cec.pid.kd = SI(100);
    p->cec.pid.d_on_measurement = false;
    p->cec.line_gains = false;
    p->cec.thesis_form = false;
    p->cec.lag_from_tangent = false;
    p->cec.pid_line = p->cec.pid;
    p->cec.curv_span_nm = 0;
    p->sat_limit_ticks = tick_hz / 2;
    p->on_following = SERVO_REACT_DISABLE;
    p->on_saturation = SERVO_REACT_STOP;
    p->ffl_rate = 0; /* feed-forward learning off */
}

servo_err_t servo_config(servo_t *s, const servo_params_t *p)
{
    pid_loop_t loops[CORE_AXES];
    cec_t cec;
    pid_params_t pp;
    cec_params_t cp;
    pid_err_t perr = PID_OK;
    cec_err_t cerr;
    unsigned i;

    if (s == NULL || p == NULL) {
        return SERVO_ERR_NULL;
    }
    if (p->axes < 1 || p->axes > CORE_AXES) {
        return SERVO_ERR_AXES;
    }
    if (p->tick_hz < PID_TICK_HZ_MIN || p->tick_hz > PID_TICK_HZ_MAX) {
        return SERVO_ERR_TICK_HZ;
    }
    if ((p->on_following != SERVO_REACT_DISABLE && p->on_following != SERVO_REACT_STOP) ||
        (p->on_saturation != SERVO_REACT_DISABLE && p->on_saturation != SERVO_REACT_STOP)) {
        return SERVO_ERR_REACTION;
    }
    for (i = 0; i < p->axes; i++) {
        if (p->ferr_limit_nm[i] < 0) {
            return SERVO_ERR_LIMIT;
        }
        if (p->stop_decel_nm_s2[i] <= 0 || p->stop_decel_nm_s2[i] > ((int64_t)1 << 40)) {
            return SERVO_ERR_DECEL;
        }
    }
    if (p->ffl_rate < 0 || p->ffl_rate > SERVO_FFL_RATE_MAX) {
        return SERVO_ERR_FFL;
    }
    for (i = 0; i < p->axes; i++) {
        loops[i] = s->pid[i];
        pp = p->axis[i];
        pp.tick_hz = p->tick_hz;
        perr = pid_config(&loops[i], &pp);
        if (perr != PID_OK) {
            s->err_axis = i;
            s->pid_err = perr;
            return SERVO_ERR_AXIS_PID;
        }
    }
    cec = s->cec;
    cp = p->cec;
    cp.pid.tick_hz = p->tick_hz;
    cerr = cec_config(&cec, &cp, &perr);
    if (cerr == CEC_ERR_MODE) {
        return SERVO_ERR_CEC_MODE;
    }
    if (cerr != CEC_OK) {
        s->pid_err = perr;
        return SERVO_ERR_CEC_PID;
    }
    /* all valid: apply */
    for (i = 0; i < p->axes; i++) {
        s->pid[i] = loops[i];
    }
    s->cec = cec;
    if (p->ffl_rate != s->p.ffl_rate) {
        for (i = 0; i < CORE_AXES; i++) {
            s->ffl_w[i] = 0;
        }
    }
    /* k = rate [1/s] / tick_hz in 2^-26: k * g (2^-14) is in 2^-40 */
    s->ffl_k = ((int64_t)p->ffl_rate << 26) / (int64_t)p->tick_hz;
    s->p = *p;
    for (i = 0; i < CORE_AXES; i++) {
        int32_t lim = (i < p->axes) ? p->ferr_limit_nm[i] : 0;
        s->ferr_max[i] = (lim > 0) ? (uint32_t)lim : 0x7FFFFFFFu;
    }
    s->sat_max = (p->sat_limit_ticks > 0) ? p->sat_limit_ticks : UINT32_MAX;
    return SERVO_OK;
}

servo_err_t servo_init(servo_t *s, const servo_params_t *p, const servo_io_t *io)
{
    static const servo_t zero;
    servo_err_t err;
    if (s == NULL || p == NULL) {
        return SERVO_ERR_NULL;
    }
    *s = zero;
    if (io != NULL) {
        s->io = *io;
    }
    err = servo_config(s, p);
    if (err != SERVO_OK) {
        servo_io_t keep = s->io;
        *s = zero;
        s->io = keep;
    }
    return err;
}

void servo_set_io_all(servo_t *s, servo_set_mv_all_fn set_mv_all,
                      servo_amp_fault_mask_fn amp_fault_mask)
{
    s->set_mv_all = set_mv_all;
    s->amp_fault_mask = amp_fault_mask;
}

static void set_line(servo_t *s, unsigned i, bool on)
{
    if (s->lines_on[i] != on || !on) {
        s->lines_on[i] = on;
        if (s->io.enable != NULL) {
            s->io.enable(i, on);
        }
    }
}

static void axis_off(servo_t *s, unsigned i)
{
    s->off_mask |= 1u << i;
    pid_disable(&s->pid[i]);
    s->out_mv[i] = 0;
    set_line(s, i, false);
}

static void disable_all(servo_t *s)
{
    unsigned i;
    for (i = 0; i < s->p.axes; i++) {
        axis_off(s, i);
    }
    s->state = SERVO_OFF;
}

static void start_stop(servo_t *s)
{
    uint64_t n = 0;
    unsigned i;
    for (i = 0; i < s->p.axes; i++) {
        int64_t v = 0;
        if (!(s->off_mask & (1u << i))) {
            uint64_t f = s->p.tick_hz, a = (uint64_t)s->p.stop_decel_nm_s2[i];
            uint64_t ni;
            v = fx_clamp_sym64(s->ref_vel[i], SERVO_VEL_MAX);
            ni = (fx_uabs64(v) * f + a - 1u) / a;
            n = (ni > n) ? ni : n;
        }
        s->stop_v0[i] = v;
        s->stop_pos[i] = s->ref_pos[i];
        s->stop_rem[i] = 0;
    }
    s->stop_n = (uint32_t)((n > SERVO_STOP_TICKS_MAX) ? SERVO_STOP_TICKS_MAX : n);
    s->stop_k = 0;
    s->state = (s->stop_n > 0) ? SERVO_STOPPING : SERVO_HOLD;
}

/* Advance the stop ramp one tick into rp/rv/ra. */
static void stop_advance(servo_t *s, pos_nm_t *rp, int64_t *rv, int64_t *ra)
{
    int64_t n = s->stop_n, f = s->p.tick_hz, den = n * f;
    int64_t left;
    unsigned i;
    s->stop_k++;
    left = n - (int64_t)s->stop_k;
    for (i = 0; i < s->p.axes; i++) {
        int64_t v0 = s->stop_v0[i], dp;
        s->stop_rem[i] += v0 * left;
        dp = s->stop_rem[i] / den;
        s->stop_rem[i] -= dp * den;
        s->stop_pos[i] += dp;
        rp[i] = s->stop_pos[i];
        rv[i] = v0 * left / n;
        ra[i] = (left > 0) ? -(v0 * f) / n : 0;
    }
    if (left <= 0) {
        s->state = SERVO_HOLD;
    }
}

static void react(servo_t *s, servo_reaction_t r)
{
    if (r == SERVO_REACT_DISABLE) {
        disable_all(s);
    } else if (s->state == SERVO_RUN) {
        start_stop(s);
    }
}

static void raise_fault(servo_t *s, uint32_t fault, unsigned axis, bool escalate)
{
    s->faults |= fault;
    s->fault_axes |= 1u << axis;
    switch (fault) {
    case SERVO_FAULT_ENCODER:
    case SERVO_FAULT_AMPLIFIER:
        if (!(s->off_mask & (1u << axis))) {
            axis_off(s, axis);
        }
        if (s->off_mask == (1u << s->p.axes) - 1u) {
            s->state = SERVO_OFF;
        } else {
            react(s, SERVO_REACT_STOP);
        }
        break;
    case SERVO_FAULT_FOLLOWING:
        react(s, escalate ? SERVO_REACT_DISABLE : s->p.on_following);
        break;
    default:
        react(s, escalate ? SERVO_REACT_DISABLE : s->p.on_saturation);
        break;
    }
}

servo_err_t servo_enable(servo_t *s, const servo_fb_t *fb)
{
    unsigned i;
    if (s == NULL || fb == NULL) {
        return SERVO_ERR_NULL;
    }
    if (s->state != SERVO_OFF || s->faults != 0) {
        return SERVO_ERR_STATE;
    }
    s->off_mask = 0;
    for (i = 0; i < s->p.axes; i++) {
        s->stop_pos[i] = fb->pos[i];
        s->ref_pos[i] = fb->pos[i];
        s->ref_vel[i] = 0;
        pid_enable(&s->pid[i], 0);
        set_line(s, i, true);
    }
    s->state = SERVO_HOLD;
    return SERVO_OK;
}

servo_err_t servo_run(servo_t *s)
{
    if (s->state != SERVO_HOLD || s->faults != 0 || s->off_mask != 0) {
        return SERVO_ERR_STATE;
    }
    s->state = SERVO_RUN;
    return SERVO_OK;
}

void servo_stop(servo_t *s)
{
    if (s->state == SERVO_RUN) {
        start_stop(s);
    }
}

void servo_disable(servo_t *s)
{
    disable_all(s);
}

servo_err_t servo_clear_faults(servo_t *s)
{
    if (s->state == SERVO_STOPPING) {
        return SERVO_ERR_STATE;
    }
    s->faults = 0;
    s->fault_axes = 0;
    s->cec.oscillating = false;
    s->cec.osc_ticks = 0;
    return SERVO_OK;
}

servo_err_t servo_set_cec_mode(servo_t *s, cec_mode_t mode)
{
    if (cec_set_mode(&s->cec, mode) != CEC_OK) {
        return SERVO_ERR_CEC_MODE;
    }
    s->p.cec.mode = mode;
    return SERVO_OK;
}

servo_err_t servo_rebase(servo_t *s, unsigned axis, pos_nm_t offset_nm)
{
    if (axis >= s->p.axes) {
        return SERVO_ERR_AXIS;
    }
    pid_rebase(&s->pid[axis], offset_nm);
    s->ref_pos[axis] += offset_nm;
    s->stop_pos[axis] += offset_nm;
    return SERVO_OK;
}

pos_nm_t servo_hold_pos(const servo_t *s, unsigned axis)
{
    return (axis < CORE_AXES) ? s->stop_pos[axis] : 0;
}

void servo_fb_from_qdec(servo_fb_t *fb, const qdec_t *const enc[CORE_AXES], unsigned axes)
{
    unsigned i;
    uint32_t fault = 0;
    for (i = 0; i < CORE_AXES; i++) {
        const qdec_t *q = (i < axes) ? enc[i] : NULL;
        if (q != NULL) {
            fb->pos[i] = q->out.pos_nm;
            if (q->out.faults != 0) {
                fault |= 1u << i;
            }
        } else {
            fb->pos[i] = 0;
        }
    }
    fb->enc_fault = fault;
}

/* Step 2 outside RUN (or RUN without a reference): hold, stop ramp or
 * track the feedback; acc: this tick's reference acceleration. */
static SERVO_NOINLINE void tick_reference(servo_t *s, const servo_fb_t *fb, int64_t acc[CORE_AXES])
{
    const unsigned n = s->p.axes;
    unsigned i;

    for (i = 0; i < n; i++) { /* the position holds unless set below */
        s->ref_vel[i] = 0;
        acc[i] = 0;
    }
    switch (s->state) {
    case SERVO_RUN: /* without a reference: hold the last one */
        break;
    case SERVO_STOPPING:
        stop_advance(s, s->ref_pos, s->ref_vel, acc);
        break;
    case SERVO_HOLD:
        for (i = 0; i < n; i++) {
            s->ref_pos[i] = s->stop_pos[i];
        }
        break;
    default: /* OFF: the loops track the feedback */
        for (i = 0; i < n; i++) {
            s->ref_pos[i] = fb->pos[i];
        }
        break;
    }
}

/* Step 3's reactions, in axis order, for the axes whose following error
 * may be over the limit (over: bit mask of candidates; an axis with the
 * check off is skipped here). Whether an axis is checked and whether the
 * fault escalates depend on the state left by the faults of the axes
 * before it, exactly as if each were raised as it was found. */
static void tick_ferr_faults(servo_t *s, uint32_t over)
{
    unsigned i;

    for (i = 0; i < s->p.axes; i++) {
        int32_t lim = s->p.ferr_limit_nm[i];
        int32_t fe = s->ferr_nm[i];

        if ((over & (1u << i)) && lim > 0 && (fe > lim || fe < -lim) && s->state != SERVO_OFF &&
            !(s->off_mask & (1u << i))) {
            bool esc = s->state != SERVO_RUN && (fe / 2 > lim || fe / 2 < -lim);
            raise_fault(s, SERVO_FAULT_FOLLOWING, i, esc);
        }
    }
}

/* Step 1: encoder and amplifier faults, each raised at once (the state they
 * leave decides step 2). amp: the amplifier fault bits when the port reads
 * them at once (io.amp_fault_mask), else the per-axis callback is asked. */
static void tick_input_faults(servo_t *s, uint32_t enc_fault, uint32_t amp, bool per_axis)
{
    bool (*const amp_fault)(unsigned axis) = s->io.amp_fault;
    unsigned i;

    for (i = 0; i < s->p.axes; i++) {
        if (enc_fault & (1u << i)) {
            raise_fault(s, SERVO_FAULT_ENCODER, i, false);
        }
        if (per_axis ? (amp_fault != NULL && amp_fault(i)) : (amp & (1u << i)) != 0u) {
            raise_fault(s, SERVO_FAULT_AMPLIFIER, i, false);
        }
    }
}

/* Feed-forward learning, step 4 (servo.h "Feed-forward learning"): move
 * the velocity gains w_i toward what the CEC's output holds (NLMS). */
static SERVO_NOINLINE void ffl_learn(servo_t *s, const int64_t *vel, const int64_t *acc)
{
    int64_t v[3], norm = (int64_t)SERVO_FFL_V_MIN * SERVO_FFL_V_MIN; /* 2^20 nm^2/s^2 */
    int64_t a2 = 0;
    int64_t u = s->cec.ch[0].out >> 28; /* mV * 2^4, |u| < 2^22 */
    unsigned i;

    for (i = 0; i < 3 && i < CORE_AXES; i++) {
        int64_t vi = (i < s->p.axes) ? vel[i] >> 10 : 0; /* 2^10 nm/s */

        vi = vi > SERVO_FFL_V_MAX ? SERVO_FFL_V_MAX
                                  : (vi < -SERVO_FFL_V_MAX ? -SERVO_FFL_V_MAX : vi);
        v[i] = vi;
        norm += vi * vi;
        if (i < s->p.axes) {
            int64_t ai = fx_clamp_sym64(acc[i] >> 10, (int64_t)1 << 26); /* 2^10 nm/s^2 */
            a2 += ai * ai;
        }
    }
    /* path frequency |a| / |v| above SERVO_FFL_W_PATH: no step */
    if (a2 > (int64_t)SERVO_FFL_W_PATH * SERVO_FFL_W_PATH * norm) {
        return;
    }
    for (i = 0; i < 3 && i < CORE_AXES; i++) {
        /* u n1_i v_i / |v|^2: mV per 2^10 nm/s, in 2^-18 (|u v n| < 2^57) */
        int64_t g = fx_div_round64(u * v[i] * (int64_t)(s->cec.n[0][i] >> 16), norm);
        int64_t w = s->ffl_w[i] + ((s->ffl_k * g) >> 12); /* U per 2^10 nm/s */

        s->ffl_w[i] =
            w > SERVO_FFL_W_MAX ? SERVO_FFL_W_MAX : (w < -SERVO_FFL_W_MAX ? -SERVO_FFL_W_MAX : w);
    }
}

/* Step 5 for one axis outside the inline case (CEC active, or the loop not
 * on its fast path). */
static PID_ALWAYS_INLINE int32_t axis_step(servo_t *s, unsigned i, int32_t e, pos_nm_t meas,
                                           int64_t vel, int64_t acc, bool quiet)
{
    pid_loop_t *pid = &s->pid[i];
    int64_t extra = 0;

    if (!quiet && i < 3 && i < CORE_AXES) {
        if (s->cec.handover_u[i] != 0) {
            pid_add_integrator(pid, s->cec.handover_u[i]);
        }
        extra = s->cec.out_u[i];
        if (s->ffl_w[i] != 0 && s->cec.active) {
            extra += s->ffl_w[i] * (fx_clamp_sym64(vel >> 10, SERVO_FFL_V_MAX));
        }
    }
    if (PID_HOST_INLINE && !quiet) {
        if (pid->lean_rdy) {
            return pid_step_lean_inline(pid, e, meas, vel, acc, extra);
        }
        if (pid_rest_cached(pid, e, meas, extra)) {
            return pid->out_mv;
        }
    }
    return pid_step_e(pid, e, meas, vel, acc, extra);
}

/* Step 6's fault for axis i (its loop saturated longer than the limit). */
static SERVO_NOINLINE void sat_fault(servo_t *s, unsigned i)
{
    bool esc = s->state != SERVO_RUN && s->pid[i].sat_ticks / 2 > s->p.sat_limit_ticks;
    raise_fault(s, SERVO_FAULT_SATURATION, i, esc);
}

/* Steps 5 and 6 for the axes whose loop is ready (pid.h) while the CEC is
 * quiet, in axis order, with the PID's fast step inline: returns the first
 * axis not done (a loop not ready, or the axis after a saturation fault,
 * whose reaction may change the loops after it). */
static inline unsigned axes_fast(servo_t *s, const pos_nm_t *pos, unsigned n)
{
    const uint32_t sat_max = s->sat_max;
    unsigned i;

    for (i = 0; i < n && i < CORE_AXES; i++) {
        pid_loop_t *pid = &s->pid[i];

        if (!pid_fast_ready(pid)) {
            return i;
        }
        s->out_mv[i] = pid_step_fast_inline(pid, s->ferr_nm[i], pos[i], 0, false);
        if (pid->sat_ticks > sat_max) {
            sat_fault(s, i);
            return i + 1u;
        }
    }
    return i;
}

/* Step 7: outputs (after every loop: a fault of a later axis may still
 * zero an earlier one). */
static inline void tick_outputs(servo_t *s)
{
    const unsigned n = s->p.axes;
    unsigned i;

    if (s->state == SERVO_OFF) {
        for (i = 0; i < n; i++) {
            s->out_mv[i] = 0;
        }
    } else if (s->off_mask != 0) {
        for (i = 0; i < n; i++) {
            if (s->off_mask & (1u << i)) {
                s->out_mv[i] = 0;
            }
        }
    }
    if (s->set_mv_all != NULL) {
        s->set_mv_all(s->out_mv, n);
    } else if (s->io.set_mv != NULL) {
        void (*const set_mv)(unsigned axis, int32_t mv) = s->io.set_mv;
        for (i = 0; i < n; i++) {
            set_mv(i, s->out_mv[i]);
        }
    }
}

/* Steps 2 to 7 (after the input faults of step 1): every case. run: RUN
 * with a reference at the start of the tick. */
static PID_ALWAYS_INLINE void tick_general_body(servo_t *s, const motion_ref_t *ref,
                                                const servo_fb_t *fb, bool run)
{
    const unsigned n = s->p.axes;
    const int64_t *vel, *acc;
    int64_t acc_own[CORE_AXES];
    uint32_t over = 0;
    unsigned i;
    bool quiet;

    /* 2. reference and 3. following error in one pass (the reactions after
     * it: a controlled stop starts from this tick's reference of every
     * axis). In RUN only the position and velocity are kept (the stop ramp
     * starts from them); the loops take vel/acc from ref. */
    if (run && s->state == SERVO_RUN) {
        for (i = 0; i < n && i < CORE_AXES; i++) {
            pos_nm_t rp = ref->pos[i];
            int32_t fe = fx_sat_diff32(rp, fb->pos[i]);

            s->ref_pos[i] = rp;
            s->ref_vel[i] = ref->vel[i];
            s->ferr_nm[i] = fe;
            if (!fx_in_range32(fe, s->ferr_max[i])) {
                over |= 1u << i;
            }
        }
        vel = ref->vel;
        acc = ref->acc;
    } else {
        tick_reference(s, fb, acc_own);
        for (i = 0; i < n && i < CORE_AXES; i++) {
            int32_t fe = fx_sat_diff32(s->ref_pos[i], fb->pos[i]);

            s->ferr_nm[i] = fe;
            if (!fx_in_range32(fe, s->ferr_max[i])) {
                over |= 1u << i;
            }
        }
        vel = s->ref_vel;
        acc = acc_own;
    }
    if (over != 0) {
        tick_ferr_faults(s, over);
    }
    /* 4. contour error controller (RUN only); an idle CEC that is off with
     * its outputs at 0 has nothing to do (cec_step would return at once) */
    if (!(s->cec.p.mode == CEC_MODE_OFF && s->cec.idle && s->cec.out_zero)) {
        cec_step(&s->cec, (s->state == SERVO_RUN && run) ? ref : NULL, fb->pos);
        if (s->cec.oscillating && !(s->faults & SERVO_FAULT_OSCILLATION)) {
            raise_fault(s, SERVO_FAULT_OSCILLATION, 0, false);
        }
        if (s->ffl_k != 0 && s->cec.active) {
            ffl_learn(s, vel, acc);
        }
    }
    /* idle with outputs known to be 0 (cec.h): nothing to read */
    quiet = s->cec.idle && s->cec.out_zero;
    /* 5. axis loops and 6. saturation supervision, per axis (n <=
     * CORE_AXES: servo_config; the second bound is for the compiler).
     * ferr_nm[i] is sat32(ref_pos[i] - fb->pos[i]) of this tick (step 3;
     * nothing since changes either). The usual case, a ready loop with a
     * quiet CEC, runs the PID's fast step inline. */
    if (quiet) {
        for (i = axes_fast(s, fb->pos, n); i < n && i < CORE_AXES; i++) {
            s->out_mv[i] = axis_step(s, i, s->ferr_nm[i], fb->pos[i], vel[i], acc[i], true);
            if (s->pid[i].sat_ticks > s->sat_max) {
                sat_fault(s, i);
            }
        }
    } else {
        SERVO_UNROLL_AXES
        for (i = 0; i < n && i < CORE_AXES; i++) {
            s->out_mv[i] = axis_step(s, i, s->ferr_nm[i], fb->pos[i], vel[i], acc[i], false);
            if (s->pid[i].sat_ticks > s->sat_max) {
                sat_fault(s, i);
            }
        }
    }
    tick_outputs(s);
}

static SERVO_NOINLINE void tick_general(servo_t *s, const motion_ref_t *ref, const servo_fb_t *fb,
                                        bool run)
{
    tick_general_body(s, ref, fb, run);
}

/* tick_fast's pass 2 from axis i on, when axis i's loop is not ready or
 * has just saturated beyond the limit (done: stepped, out_mv[i] written):
 * the general step per axis, saturation supervision in axis order. */
static SERVO_NOINLINE void tick_fast_rest(servo_t *s, const motion_ref_t *ref, const servo_fb_t *fb,
                                          unsigned i, bool done)
{
    const unsigned n = s->p.axes;

    for (; i < n && i < CORE_AXES; i++) {
        if (!done) {
            s->out_mv[i] =
                pid_step_e(&s->pid[i], s->ferr_nm[i], fb->pos[i], ref->vel[i], ref->acc[i], 0);
        }
        done = false;
        if (s->pid[i].sat_ticks > s->sat_max) {
            sat_fault(s, i);
        }
    }
}

/* Steps 2 to 7 in the usual case: RUN with a reference, no input fault,
 * the CEC off and quiet (cec_step would return at once). Pass 1: reference
 * and following error; when an axis is over its limit it returns false
 * having written only what tick_general writes again from the same inputs
 * (ref_pos, ref_vel, ferr_nm). Pass 2: the loops (the PID's fast step inline
 * while ready, else the general step with the reference's feed-forward),
 * saturation supervision (after a saturation fault the remaining axes take
 * the general step: the reaction may have disabled them), outputs. */
static inline bool tick_fast(servo_t *s, const motion_ref_t *ref, const servo_fb_t *fb)
{
    const unsigned n = (s->p.axes < CORE_AXES) ? s->p.axes : CORE_AXES; /* (servo_config) */
    const uint32_t sat_max = s->sat_max;
    unsigned i;

    for (i = 0; i < n; i++) {
        pos_nm_t rp = ref->pos[i];
        int32_t fe = fx_sat_diff32(rp, fb->pos[i]);

        s->ref_pos[i] = rp;
        s->ref_vel[i] = ref->vel[i];
        s->ferr_nm[i] = fe;
        if (!fx_in_range32(fe, s->ferr_max[i])) {
            return false; /* tick_general writes all of it again */
        }
    }
    {
        bool done = false;
        pid_loop_t *pid = s->pid;
        const pos_nm_t *pos = fb->pos;
        const int32_t *fe = s->ferr_nm;
        int32_t *out = s->out_mv;

        for (i = 0; i < n; i++, pid++, pos++, fe++, out++) {
            if (!pid_fast_ready(pid)) {
                break;
            }
            int32_t u = pid_step_fast_inline(pid, *fe, *pos, 0, false);

            if (pid->sat_ticks > sat_max) { /* known 0 on the unsaturated path */
                *out = u;
                done = true;
                break;
            }
            *out = u;
        }
        if (i < n) {
            tick_fast_rest(s, ref, fb, i, done);
        }
    }
    tick_outputs(s);
    return true;
}

/* Step 1: input faults; fb and the fault inputs are read once (neither
 * changes during the tick). */
static inline void tick_inputs(servo_t *s, const servo_fb_t *fb)
{
    const uint32_t enc_fault = fb->enc_fault;

    if (s->amp_fault_mask != NULL) {
        uint32_t amp = s->amp_fault_mask(s->p.axes);
        if ((amp | enc_fault) != 0u) {
            tick_input_faults(s, enc_fault, amp, false);
        }
    } else if (s->io.amp_fault != NULL || enc_fault != 0u) {
        tick_input_faults(s, enc_fault, 0, true);
    }
}

/* servo_tick with the contour error controller's mode not OFF (no input
 * fault changes the mode, so tick_fast is out): one function with the
 * general steps inline, on 64-bit hosts (PID_HOST_INLINE; x86 bench_hil:
 * servo_tick's frame for tick_fast is not built on such ticks). */
static SERVO_NOINLINE void tick_cec_on(servo_t *s, const motion_ref_t *ref, const servo_fb_t *fb)
{
    const bool run = s->state == SERVO_RUN && ref != NULL;

    s->ticks++;
    tick_inputs(s, fb);
    tick_general_body(s, ref, fb, run);
}

/* servo_tick in every case (the M4's: inline); out of line on 64-bit
 * hosts, so that servo_tick itself builds no frame for tick_cec_on's ticks */
#if PID_HOST_INLINE
#define SERVO_HOST_NOINLINE SERVO_NOINLINE
#else
#define SERVO_HOST_NOINLINE inline
#endif
static SERVO_HOST_NOINLINE void tick_any(servo_t *s, const motion_ref_t *ref, const servo_fb_t *fb)
{
    const bool run = s->state == SERVO_RUN && ref != NULL;

    s->ticks++;
    tick_inputs(s, fb);
    if (run && s->state == SERVO_RUN && s->cec.p.mode == CEC_MODE_OFF && s->cec.idle &&
        s->cec.out_zero && tick_fast(s, ref, fb)) {
        return;
    }
    tick_general(s, ref, fb, run);
}

void servo_tick(servo_t *s, const motion_ref_t *ref, const servo_fb_t *fb)
{
    if (PID_HOST_INLINE && s->cec.p.mode != CEC_MODE_OFF) {
        tick_cec_on(s, ref, fb);
        return;
    }
    tick_any(s, ref, fb);
}
