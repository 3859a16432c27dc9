/*
 * drive_param.c - the drive's configuration defaults (drive_config_default)
 * and its parameters by id (specification in drive.h, "Parameters"): the
 * table of ranges and the fields they live in. Main context. A set builds
 * a candidate configuration and hands it to drive_apply_config (drive.c),
 * which applies it only while the planner is idle.
 */
#include "drive.h"
#include "drive_int.h"
#include "drive_inputs.h"
#include "scratch.h"

/* The candidate configuration of drive_param_set and of a begin / stage /
 * commit sequence (drive_param_set_all, param_store's load); main. */
static drive_config_t cand;

drive_result_t drive_servo_probe(const servo_params_t *q)
{
    servo_t *probe = scratch_claim(SCRATCH_SERVO_PROBE, sizeof *probe);
    servo_err_t e;
    if (probe == NULL) {
        return DRIVE_E_BUSY;
    }
    e = servo_init(probe, q, NULL);
    scratch_release(SCRATCH_SERVO_PROBE);
    return e == SERVO_OK ? DRIVE_OK : DRIVE_E_INVALID;
}

void drive_config_default(drive_config_t *cfg, uint32_t tick_hz, unsigned axes)
{
    drive_config_t zero = {0};
    unsigned i;
    *cfg = zero;
    cfg->tick_hz = tick_hz;
    cfg->axes = axes;
    for (i = 0; i < CORE_AXES; i++) {
        cfg->nm_per_count_num[i] = 1;
        cfg->nm_per_count_den[i] = 1;
        cfg->ref_nm_per_count_den[i] = 1;
        cfg->plan.v_max[i] = 1000000000;      /* 1 m/s      */
        cfg->plan.a_max[i] = 10000000000;     /* 10 m/s^2   */
        cfg->plan.j_max[i] = 1000000000000;   /* 1000 m/s^3 */
        cfg->plan.corner_dv[i] = 10000000;    /* 10 mm/s    */
        cfg->plan.corner_acc[i] = 1000000000; /* 1 m/s^2    */
    }
    cfg->plan.junction_dev_nm = 10000;
    cfg->plan.mbt_window = 1;
    cfg->plan.corner = PLAN_CORNER_JD;
    cfg->plan.shape = SC_SHAPE_SCURVE_CONTINUOUS;
    servo_params_default(&cfg->servo, tick_hz);
    cfg->servo.axes = axes;
    cfg->stop_decel_nm_s2 = 1000000000;   /* 1 m/s^2 */
    cfg->friction_ff_band_nm_s = 1000000; /* 1 mm/s */
    cfg->arc_chord_nm = DRIVE_ARC_CHORD_NM;
    cfg->start_delay_ms = DRIVE_START_DELAY_MS;
    for (i = 0; i < CORE_AXES; i++) {
        cfg->in_pos_nm[i] = DRIVE_IN_POS_NM; /* soft limits 0 / 0: off */
    }
}

static const struct {
    int64_t lo, hi;
    bool per_axis;
} param_info[DRIVE_PARAM_COUNT] = {
    [DRIVE_PARAM_V_MAX] = {1000, SC_V_LIMIT, true},
    [DRIVE_PARAM_A_MAX] = {SC_A_MIN, SC_A_LIMIT, true},
    [DRIVE_PARAM_J_MAX] = {SC_J_MIN, SC_J_LIMIT, true},
    [DRIVE_PARAM_CORNER_DV] = {0, SC_V_LIMIT, true},
    [DRIVE_PARAM_CORNER_ACC] = {0, SC_A_LIMIT, true},
    [DRIVE_PARAM_JUNCTION_DEV] = {0, (int64_t)1 << 40, false},
    [DRIVE_PARAM_CORNER] = {PLAN_CORNER_JD, PLAN_CORNER_STOP, false},
    [DRIVE_PARAM_SHAPE] = {SC_SHAPE_SCURVE, SC_SHAPE_SCURVE_CONTINUOUS, false},
    [DRIVE_PARAM_MIN_BLOCK_NS] = {0, 10 * SC_NS_PER_S, false},
    [DRIVE_PARAM_MBT_WINDOW] = {1, PLAN_WINDOW_MAX, false},
    [DRIVE_PARAM_STOP_DECEL] = {1000, SC_A_LIMIT, false},
    [DRIVE_PARAM_ARC_CHORD] = {1, 1000000000, false},
    [DRIVE_PARAM_START_DELAY_MS] = {0, DRIVE_START_DELAY_MS_MAX, false},
    [DRIVE_PARAM_KP] = {0, PID_GAIN_MAX - 1, true},
    [DRIVE_PARAM_KI] = {0, PID_GAIN_MAX - 1, true},
    [DRIVE_PARAM_KD] = {0, PID_GAIN_MAX - 1, true},
    [DRIVE_PARAM_KVFF] = {0, PID_GAIN_MAX - 1, true},
    [DRIVE_PARAM_KAFF] = {0, PID_GAIN_MAX - 1, true},
    [DRIVE_PARAM_FERR_LIMIT] = {0, INT32_MAX, true},
    [DRIVE_PARAM_SOFT_MIN] = {-DRIVE_SOFT_LIMIT_NM, DRIVE_SOFT_LIMIT_NM, true},
    [DRIVE_PARAM_SOFT_MAX] = {-DRIVE_SOFT_LIMIT_NM, DRIVE_SOFT_LIMIT_NM, true},
    [DRIVE_PARAM_IN_POS] = {1, DRIVE_IN_POS_NM_MAX, true},
    [DRIVE_PARAM_CEC_KP] = {0, PID_GAIN_MAX - 1, false},
    [DRIVE_PARAM_CEC_KI] = {0, PID_GAIN_MAX - 1, false},
    [DRIVE_PARAM_CEC_KD] = {0, PID_GAIN_MAX - 1, false},
    [DRIVE_PARAM_FRICTION_FF] = {0, DRIVE_FRICTION_FF_MV_MAX, true},
    [DRIVE_PARAM_FRICTION_BAND] = {1, SC_V_LIMIT, false},
    [DRIVE_PARAM_FF_ADVANCE] = {0, DRIVE_FF_ADVANCE_NS_MAX, false},
    [DRIVE_PARAM_QG_COMP] = {0, 1, false},
    [DRIVE_PARAM_FFL_RATE] = {0, SERVO_FFL_RATE_MAX, false},
    [DRIVE_PARAM_ENC_MEAN] = {0, 1, false},
};

/* Servo parameters: set through drive_set_servo_params (the tick applies). */
static bool param_is_servo(drive_param_t id)
{
    return (id >= DRIVE_PARAM_KP && id <= DRIVE_PARAM_FERR_LIMIT) ||
           (id >= DRIVE_PARAM_CEC_KP && id <= DRIVE_PARAM_CEC_KD) || id == DRIVE_PARAM_FFL_RATE;
}

/* The field of a configuration a parameter lives in. */
static const int64_t *param_field(const drive_config_t *c, drive_param_t id, unsigned axis)
{
    switch (id) {
    case DRIVE_PARAM_V_MAX:
        return &c->plan.v_max[axis];
    case DRIVE_PARAM_A_MAX:
        return &c->plan.a_max[axis];
    case DRIVE_PARAM_J_MAX:
        return &c->plan.j_max[axis];
    case DRIVE_PARAM_CORNER_DV:
        return &c->plan.corner_dv[axis];
    case DRIVE_PARAM_CORNER_ACC:
        return &c->plan.corner_acc[axis];
    case DRIVE_PARAM_JUNCTION_DEV:
        return &c->plan.junction_dev_nm;
    case DRIVE_PARAM_MIN_BLOCK_NS:
        return &c->plan.min_block_ns;
    case DRIVE_PARAM_STOP_DECEL:
        return &c->stop_decel_nm_s2;
    case DRIVE_PARAM_ARC_CHORD:
        return &c->arc_chord_nm;
    case DRIVE_PARAM_KP:
        return &c->servo.axis[axis].kp;
    case DRIVE_PARAM_KI:
        return &c->servo.axis[axis].ki;
    case DRIVE_PARAM_KD:
        return &c->servo.axis[axis].kd;
    case DRIVE_PARAM_KVFF:
        return &c->servo.axis[axis].kvff;
    case DRIVE_PARAM_KAFF:
        return &c->servo.axis[axis].kaff;
    case DRIVE_PARAM_SOFT_MIN:
        return &c->soft_min[axis];
    case DRIVE_PARAM_SOFT_MAX:
        return &c->soft_max[axis];
    case DRIVE_PARAM_IN_POS:
        return &c->in_pos_nm[axis];
    case DRIVE_PARAM_CEC_KP:
        return &c->servo.cec.pid.kp;
    case DRIVE_PARAM_CEC_KI:
        return &c->servo.cec.pid.ki;
    case DRIVE_PARAM_CEC_KD:
        return &c->servo.cec.pid.kd;
    case DRIVE_PARAM_FRICTION_BAND:
        return &c->friction_ff_band_nm_s;
    default:
        return NULL; /* narrower fields: see param_read / param_write */
    }
}

static bool param_ok(drive_param_t id, unsigned axis)
{
    if (!drive_ready() || (unsigned)id >= (unsigned)DRIVE_PARAM_COUNT) {
        return false;
    }
    return param_info[id].per_axis ? axis < drive_config()->axes : axis == 0;
}

static int64_t param_read(const drive_config_t *c, drive_param_t id, unsigned axis)
{
    const int64_t *f = param_field(c, id, axis);
    if (f != NULL) {
        return *f;
    }
    switch (id) {
    case DRIVE_PARAM_CORNER:
        return c->plan.corner;
    case DRIVE_PARAM_SHAPE:
        return c->plan.shape;
    case DRIVE_PARAM_MBT_WINDOW:
        return c->plan.mbt_window;
    case DRIVE_PARAM_FERR_LIMIT:
        return c->servo.ferr_limit_nm[axis];
    case DRIVE_PARAM_FRICTION_FF:
        return c->friction_ff_mv[axis];
    case DRIVE_PARAM_FF_ADVANCE:
        return c->ff_advance_ns;
    case DRIVE_PARAM_QG_COMP:
        return c->qg_comp ? 1 : 0;
    case DRIVE_PARAM_FFL_RATE:
        return c->servo.ffl_rate;
    case DRIVE_PARAM_ENC_MEAN:
        return c->enc_mean ? 1 : 0;
    default:
        return c->start_delay_ms;
    }
}

static void param_write(drive_config_t *c, drive_param_t id, unsigned axis, int64_t v)
{
    int64_t *f = (int64_t *)param_field(c, id, axis); /* c is writable */
    if (f != NULL) {
        *f = v;
        return;
    }
    switch (id) {
    case DRIVE_PARAM_CORNER:
        c->plan.corner = (uint8_t)v;
        break;
    case DRIVE_PARAM_SHAPE:
        c->plan.shape = (uint8_t)v;
        break;
    case DRIVE_PARAM_MBT_WINDOW:
        c->plan.mbt_window = (uint16_t)v;
        break;
    case DRIVE_PARAM_FERR_LIMIT:
        c->servo.ferr_limit_nm[axis] = (int32_t)v;
        break;
    case DRIVE_PARAM_FRICTION_FF:
        c->friction_ff_mv[axis] = (int32_t)v;
        break;
    case DRIVE_PARAM_FF_ADVANCE:
        c->ff_advance_ns = (int32_t)v;
        break;
    case DRIVE_PARAM_QG_COMP:
        c->qg_comp = v != 0;
        break;
    case DRIVE_PARAM_FFL_RATE:
        c->servo.ffl_rate = (int32_t)v;
        break;
    case DRIVE_PARAM_ENC_MEAN:
        c->enc_mean = v != 0;
        break;
    default:
        c->start_delay_ms = (uint32_t)v;
        break;
    }
}

/* drive_apply_config, after the port's check of enc_mean: a port that
 * cannot measure the mean refuses it, never ignores it. */
static drive_result_t apply(const drive_config_t *c)
{
    if (c->enc_mean && !drive_inputs_mean_ok(c->axes)) {
        return DRIVE_E_UNSUPPORTED;
    }
    /* the measured position moves by half a tick's travel: only with the
     * power stage off (a FAULT may still run the servo's stop ramp, IDLE an
     * excitation) */
    if (c->enc_mean != drive_config()->enc_mean && drive_main_state() != DRIVE_DISABLED) {
        return DRIVE_E_BUSY;
    }
    return drive_apply_config(c);
}

drive_result_t drive_param_get(drive_param_t id, unsigned axis, int64_t *value)
{
    if (value == NULL || !param_ok(id, axis)) {
        return DRIVE_E_INVALID;
    }
    *value = param_read(drive_config(), id, axis);
    return DRIVE_OK;
}

/* The range of a value in configuration c (drive_param_range). */
static drive_result_t range_in(const drive_config_t *c, drive_param_t id, unsigned axis,
                               int64_t *lo, int64_t *hi)
{
    const plan_profile_t *p = &c->plan;
    if (lo == NULL || hi == NULL || !param_ok(id, axis)) {
        return DRIVE_E_INVALID;
    }
    *lo = param_info[id].lo;
    *hi = param_info[id].hi;
    /* S-curve: a_max / j_max <= SC_TJ_MAX_NS (3 s) per axis */
    if (p->shape != SC_SHAPE_TRAPEZOID && id == DRIVE_PARAM_A_MAX &&
        p->j_max[axis] <= SC_A_LIMIT / 3) {
        *hi = p->j_max[axis] * (SC_TJ_MAX_NS / SC_NS_PER_S); /* j * 3 s */
    }
    if (p->shape != SC_SHAPE_TRAPEZOID && id == DRIVE_PARAM_J_MAX) {
        int64_t tj_s = SC_TJ_MAX_NS / SC_NS_PER_S; /* whole seconds (3) */
        int64_t j = (p->a_max[axis] + tj_s - 1) / tj_s;
        *lo = j > *lo ? j : *lo;
    }
    return DRIVE_OK;
}

drive_result_t drive_param_range(drive_param_t id, unsigned axis, int64_t *lo, int64_t *hi)
{
    return range_in(drive_config(), id, axis, lo, hi);
}

drive_result_t drive_param_staged_range(drive_param_t id, unsigned axis, int64_t *lo, int64_t *hi)
{
    return range_in(&cand, id, axis, lo, hi);
}

drive_result_t drive_param_set(drive_param_t id, unsigned axis, int64_t value)
{
    int64_t lo, hi;
    if (drive_param_range(id, axis, &lo, &hi) != DRIVE_OK || value < lo || value > hi) {
        return DRIVE_E_INVALID;
    }
    cand = *drive_config();
    param_write(&cand, id, axis, value);
    if (param_is_servo(id)) {
        return drive_set_servo_params(&cand.servo);
    }
    return apply(&cand);
}

drive_result_t drive_param_begin(void)
{
    if (!drive_ready()) {
        return DRIVE_E_INVALID;
    }
    cand = *drive_config();
    return DRIVE_OK;
}

drive_result_t drive_param_stage(drive_param_t id, unsigned axis, int64_t value)
{
    if (!param_ok(id, axis) || value < param_info[id].lo || value > param_info[id].hi) {
        return DRIVE_E_INVALID;
    }
    param_write(&cand, id, axis, value);
    return DRIVE_OK;
}

drive_result_t drive_param_commit(void)
{
    servo_params_t q = cand.servo;
    drive_result_t r;
    q.cec.mode = CEC_MODE_OFF;
    if (plan_check_profile(&cand.plan) != PLAN_OK) {
        return DRIVE_E_INVALID;
    }
    r = drive_servo_probe(&q);
    if (r != DRIVE_OK) {
        return r;
    }
    r = apply(&cand); /* checks the port, then that the planner is idle */
    if (r != DRIVE_OK) {
        return r;
    }
    return drive_set_servo_params(&cand.servo); /* validated, not moving: OK */
}

drive_result_t drive_param_set_all(const drive_param_value_t *v, unsigned n)
{
    unsigned k;
    if (v == NULL || drive_param_begin() != DRIVE_OK) {
        return DRIVE_E_INVALID;
    }
    for (k = 0; k < n; k++) {
        if (drive_param_stage(v[k].id, v[k].axis, v[k].value) != DRIVE_OK) {
            return DRIVE_E_INVALID;
        }
    }
    return drive_param_commit();
}

static unsigned limit_axis; /* main: axis of the last DRIVE_E_LIMIT */

drive_result_t drive_soft_limit_check(const pos_nm_t target[CORE_AXES],
                                      const pos_nm_t from[CORE_AXES])
{
    const drive_config_t *c = drive_config();
    unsigned i;
    for (i = 0; i < c->axes; i++) {
        if (c->soft_min[i] < c->soft_max[i] && target[i] != from[i] &&
            (target[i] < c->soft_min[i] || target[i] > c->soft_max[i])) {
            limit_axis = i;
            return DRIVE_E_LIMIT;
        }
    }
    return DRIVE_OK;
}

void drive_soft_limit_refused(unsigned *axis, int64_t *lo, int64_t *hi)
{
    const drive_config_t *c = drive_config();
    *axis = limit_axis;
    *lo = c->soft_min[limit_axis];
    *hi = c->soft_max[limit_axis];
}

drive_result_t drive_set_plan_profile(const plan_profile_t *prof)
{
    static drive_config_t cand;
    if (prof == NULL || !drive_ready()) {
        return DRIVE_E_INVALID;
    }
    cand = *drive_config();
    cand.plan = *prof;
    return apply(&cand);
}
