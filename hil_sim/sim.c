/*
 * sim.c - the simulator loop (see sim.h).
 */
#include "sim.h"
#include "field2d.h"

#include <math.h>
#include <string.h>

#include "app.h"
#include "boot_sim.h"
#include "drive.h"
#include "hal_sim.h"
#include "proto_msgs.h"
#include "qgen.h"

#define PI_D 3.14159265358979323846

static struct {
    int setup;   /* sim_setup called */
    int started; /* sim_start succeeded */
    unsigned axes;
    uint32_t tick_hz;
    uint64_t period_ns;
    double substep_max;
    unsigned nsub;
    uint64_t sub_ns[AXIS_SUBSTEP_MAX + 1]; /* start offset of each substep */
    axis_params_t par[SIM_AXES];
    axis_t ax[SIM_AXES];
    qgen_t gen[SIM_AXES];     /* quadrature generator per motor encoder */
    int64_t count0[SIM_AXES]; /* generator count when the decoder started */
    drive_config_t dcfg;      /* the drive's configuration (gains, limits) */
    int cec_mode;             /* drive_cec_mode_t applied at start        */
    uint64_t t_ns;
    uint64_t ticks;
    uint64_t mismatches;
    app_board_t board; /* the host link and identity (sim_set_link) */
    int boot;          /* board.boot is the simulated bootloader's slot */
    /* per axis: home switch and encoder index (sim_axis_set names below) */
    double home_switch[SIM_AXES]; /* switch edge, table position, m      */
    double home_side[SIM_AXES];   /* -1: active at or below the edge, +1:
                                   * at or above, 0: no switch           */
    double enc_index[SIM_AXES];   /* 1: an index pulse per motor turn    */
    double index_phase[SIM_AXES]; /* counts from position 0 to an index  */
    int enc_model;                /* SIM_ENC_*: how edges reach the decoder */
    /* reference scales with reading noise (ref_noise > 0, also set per
     * tick by the 2-D field) draw their reading at every tick's start, so
     * that the noise sequence does not depend on when the drive reads:
     * ref_per_tick (such a scale or the field; or sim_test_eager_inputs),
     * ref_drawn[i] (this tick's reading of axis i is ref_val[i]) */
    bool ref_per_tick;
    bool ref_drawn[SIM_AXES];
    uint32_t ref_val[SIM_AXES];
    double table[SIM_AXES]; /* axis_table_pos after the last substep,
                             * plus the 2-D field (sim_field2d) */
    field2d_t field;        /* 2-D error field of X and Y (off: field.on) */
    /* disturbances (sim.h "Disturbances"; all zero = off, no effect at all) */
    double cut_f_at[SIM_AXES];  /* N: F_at sign(v_ref) on this axis          */
    double cut_f_w;             /* N: cutting force F_w in the X-Y plane     */
    double cut_phi;             /* rad: phi of eq. 4.3 (default pi/4)        */
    double spring_k[SIM_AXES];  /* N/m: spring on the table                  */
    double spring_x0[SIM_AXES]; /* m: table position where it is relaxed    */
    int dist_on;                /* any of the above non-zero (sim_start)    */
    /* sim_inject: host buffer per axis, next index, length (0: off) */
    const double *inj[SIM_AXES];
    size_t inj_k[SIM_AXES];
    size_t inj_n[SIM_AXES];
    double inj_now[SIM_AXES]; /* V added over the current tick */
    bool inj_any;             /* an inj_n is not 0 */
    /* the mean reading (hal_encoder_mean) while the drive has enc_mean:
     * generator position at the start of the substep, count at the start
     * of the tick, integral of count - base over the tick so far (ns);
     * with sim_trace_table_mean also the table's (m ns) and its mean (m) */
    int mean;
    qgen_pos_t mean_x[SIM_AXES];
    int64_t mean_base[SIM_AXES];
    double mean_acc[SIM_AXES];
    int tmean_on;
    double tmean_acc[SIM_AXES];
    double tmean[SIM_AXES];
    /* sim_table_record: the host's buffer (rows of SIM_REC_COLS), its
     * capacity, rows recorded (counts past the capacity too), one row at
     * the end of every rec_m-th substep since sim_start */
    double *rec;
    size_t rec_cap;
    size_t rec_n;
    uint64_t rec_m;
} S;

/* With the 2-D field on, add it to X's and Y's true positions (S.table)
 * from their nominal ones: off, S.table stays axis_table_pos bit for bit. */
static void sim_apply_field(void)
{
    double e[2];
    if (!S.field.on || S.axes < 2) {
        return;
    }
    field2d_track(&S.field, S.table[0], S.table[1]);
    field2d_error(&S.field, S.table[0], S.table[1], e);
    S.ax[0].p.ref_noise = field2d_noise(&S.field, 0, S.table[0], S.table[1]);
    S.ax[1].p.ref_noise = field2d_noise(&S.field, 1, S.table[0], S.table[1]);
    S.table[0] += e[0];
    S.table[1] += e[1];
}

/* The simulator's own per-axis settings (not axis_model parameters). */
static double *sim_field(unsigned axis, const char *name)
{
    if (strcmp(name, "home_switch") == 0) {
        return &S.home_switch[axis];
    }
    if (strcmp(name, "home_side") == 0) {
        return &S.home_side[axis];
    }
    if (strcmp(name, "enc_index") == 0) {
        return &S.enc_index[axis];
    }
    if (strcmp(name, "index_phase") == 0) {
        return &S.index_phase[axis];
    }
    if (strcmp(name, "cut_f_at") == 0) {
        return &S.cut_f_at[axis];
    }
    if (strcmp(name, "cut_f_w") == 0) { /* the X-Y plane's: any axis */
        return &S.cut_f_w;
    }
    if (strcmp(name, "cut_phi") == 0) {
        return &S.cut_phi;
    }
    if (strcmp(name, "spring_k") == 0) {
        return &S.spring_k[axis];
    }
    if (strcmp(name, "spring_x0") == 0) {
        return &S.spring_x0[axis];
    }
    return NULL;
}

static int inputs_eager; /* sim_test_eager_inputs; sim_setup turns it off */

int sim_setup(double tick_hz, unsigned axes)
{
    unsigned i;
    if (!(tick_hz >= 100.0 && tick_hz <= 100000.0) || axes < 1 || axes > SIM_AXES) {
        return SIM_E_ARG;
    }
    memset(&S, 0, sizeof S);
    inputs_eager = 0; /* a test's hook does not outlive its setup */
    S.axes = axes;
    S.tick_hz = (uint32_t)floor(tick_hz + 0.5);
    S.period_ns = (uint64_t)floor(1e9 / (double)S.tick_hz + 0.5);
    for (i = 0; i < SIM_AXES; i++) {
        axis_params_lacerda(&S.par[i], i == 1);
        S.par[i].l = 0.005 / (2.0 * PI_D); /* 5.00 mm lead exactly */
        S.par[i].seed = 0x5EEDu + i;
        S.home_switch[i] = SIM_HOME_SWITCH_M;
        S.home_side[i] = -1.0;
        S.enc_index[i] = 1.0;
        S.index_phase[i] = 0.0;
    }
    S.cut_phi = PI_D / 4.0; /* the thesis's phi = 45 deg */
    drive_config_default(&S.dcfg, S.tick_hz, axes);
    /* this amplifier: +-10 V input for +-160 V (vmax / kx) */
    for (i = 0; i < CORE_AXES; i++) {
        S.dcfg.servo.axis[i].out_max_mv = 10000;
        S.dcfg.servo.axis[i].i_max_mv = 10000;
    }
    S.dcfg.servo.cec.pid.out_max_mv = 10000;
    S.dcfg.servo.cec.pid.i_max_mv = 10000;
    S.enc_model = SIM_ENC_FAST;
    S.board.board_id = BOOT_BOARD_SIM;
    S.board.node_id = 1u;
    S.board.capabilities = 1u << PROTO_CAPABILITY_SIMULATED;
    S.setup = 1;
    return 0;
}

typedef struct {
    const char *name;
    size_t off;
} field_t;

#define F(x)                                                                                       \
    {                                                                                              \
#x, offsetof(axis_params_t, x)                                                             \
    }
static const field_t fields[] = {
    F(B),
    F(l),
    F(K),
    F(kb),
    F(kt),
    F(La),
    F(I1),
    F(I2),
    F(Ra),
    F(kx),
    F(vmax),
    F(load_torque),
    F(coulomb_motor),
    F(coulomb_table),
    F(backlash),
    F(pitch_dir_band),
    F(enc_counts_per_rev),
    F(enc_noise_counts),
    F(enc_offset_counts),
    F(ref_resolution),
    F(ref_noise),
};
#undef F

static double *field_ptr(axis_params_t *p, const char *name)
{
    size_t i;
    for (i = 0; i < sizeof fields / sizeof fields[0]; i++) {
        if (strcmp(fields[i].name, name) == 0) {
            return (double *)(void *)((char *)p + fields[i].off);
        }
    }
    return NULL;
}

int sim_axis_set(unsigned axis, const char *name, double value)
{
    double *f;
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (axis >= SIM_AXES || name == NULL || !isfinite(value)) {
        return SIM_E_ARG;
    }
    f = sim_field(axis, name);
    if (f != NULL) {
        if ((strcmp(name, "home_side") == 0 && value != -1.0 && value != 0.0 && value != 1.0) ||
            (strcmp(name, "enc_index") == 0 && value != 0.0 && value != 1.0)) {
            return SIM_E_ARG;
        }
        *f = value;
        S.started = 0;
        return 0;
    }
    if (strcmp(name, "lead") == 0) {
        if (!(value > 0.0)) {
            return SIM_E_ARG;
        }
        S.par[axis].l = value / (2.0 * PI_D);
        S.started = 0;
        return 0;
    }
    if (strcmp(name, "seed") == 0) {
        if (value < 0.0) {
            return SIM_E_ARG;
        }
        S.par[axis].seed = (uint64_t)value;
        S.started = 0;
        return 0;
    }
    f = field_ptr(&S.par[axis], name);
    if (f == NULL) {
        return SIM_E_ARG;
    }
    *f = value;
    S.started = 0;
    return 0;
}

int sim_axis_get(unsigned axis, const char *name, double *value)
{
    double *f;
    if (axis >= SIM_AXES || name == NULL || value == NULL) {
        return SIM_E_ARG;
    }
    if (strcmp(name, "lead") == 0) {
        *value = S.par[axis].l * 2.0 * PI_D;
        return 0;
    }
    f = sim_field(axis, name);
    if (f == NULL) {
        f = field_ptr(&S.par[axis], name);
    }
    if (f == NULL) {
        return SIM_E_ARG;
    }
    *value = *f;
    return 0;
}

int sim_axis_pitch(unsigned axis, unsigned n, const double *pos, const double *err_fwd,
                   const double *err_rev)
{
    unsigned i;
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (axis >= SIM_AXES || n > AXIS_PITCH_MAX || (n > 0 && (!pos || !err_fwd || !err_rev))) {
        return SIM_E_ARG;
    }
    for (i = 0; i < n; i++) {
        if (!isfinite(pos[i]) || !isfinite(err_fwd[i]) || !isfinite(err_rev[i]) ||
            (i > 0 && !(pos[i] > pos[i - 1]))) {
            return SIM_E_ARG;
        }
    }
    S.started = 0;
    S.par[axis].pitch_n = n;
    for (i = 0; i < n; i++) {
        S.par[axis].pitch_pos[i] = pos[i];
        S.par[axis].pitch_err_fwd[i] = err_fwd[i];
        S.par[axis].pitch_err_rev[i] = err_rev[i];
    }
    return 0;
}

int sim_field2d(unsigned nx, unsigned ny, double x0, double dx, double y0, double dy,
                const double *col, const double *sig, unsigned nr, double r0, double dr,
                const double *row, double band)
{
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (nx > 0 && S.axes < 2) {
        return SIM_E_ARG;
    }
    S.started = 0;
    return field2d_set(&S.field, nx, ny, x0, dx, y0, dy, col, sig, nr, r0, dr, row, band)
               ? 0
               : SIM_E_ARG;
}

int sim_set_substep(double max_s)
{
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (!(max_s >= 0.0) || (max_s > 0.0 && max_s < 1e-7)) {
        return SIM_E_ARG;
    }
    S.substep_max = max_s;
    S.started = 0;
    return 0;
}

/* nm per encoder count as a rational number num / den = lead (nm) / counts
 * per revolution, with the lead rounded to 1e-3 nm, reduced; false if it
 * does not fit the decoder's int32 scale. */
static int encoder_scale(double lead_m, double counts, int32_t *num, int32_t *den)
{
    int64_t n, d, g;
    /* both products must fit int64 before the casts (1e18 < 2^63) */
    if (!(lead_m > 0.0 && lead_m <= 1e6) || !(counts >= 1.0 && counts <= 1e15)) {
        return 0;
    }
    n = (int64_t)floor(lead_m * 1e12 + 0.5);
    d = (int64_t)floor(counts + 0.5) * 1000;
    if (n <= 0 || d <= 0) {
        return 0;
    }
    g = (int64_t)fx_gcd64((uint64_t)n, (uint64_t)d);
    n /= g;
    d /= g;
    while (n > INT32_MAX || d > INT32_MAX) {
        n = (n + 1) / 2;
        d = (d + 1) / 2;
    }
    *num = (int32_t)n;
    *den = (int32_t)(d > 0 ? d : 1);
    return 1;
}

static q32_32_t si_q32(double v)
{
    return (q32_32_t)floor(v * 4294967296.0 + 0.5);
}

static int in_range(double v, double lo, double hi)
{
    return isfinite(v) && v >= lo && v <= hi;
}

int sim_gain_set(int loop, const char *name, double v)
{
    pid_params_t *p;
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (name == NULL || loop < -2 || loop >= (int)CORE_AXES) {
        return SIM_E_ARG;
    }
    /* -2: the CEC's straight-path gains (cec.h "Gain switching"), which turns
     * the switching on */
    p = loop == -2 ? &S.dcfg.servo.cec.pid_line
        : loop < 0 ? &S.dcfg.servo.cec.pid
                   : &S.dcfg.servo.axis[loop];
    if (strcmp(name, "kp") == 0 || strcmp(name, "ki") == 0 || strcmp(name, "kd") == 0 ||
        strcmp(name, "kvff") == 0 || strcmp(name, "kaff") == 0 || strcmp(name, "kt") == 0) {
        q32_32_t q;
        if (!in_range(v, 0.0, 1e9)) {
            return SIM_E_ARG;
        }
        q = si_q32(v);
        switch (name[1]) {
        case 'p':
            p->kp = q;
            break;
        case 'i':
            p->ki = q;
            break;
        case 'd':
            p->kd = q;
            break;
        case 't':
            p->kt = q;
            break;
        default:
            if (name[1] == 'v') {
                p->kvff = q;
            } else {
                p->kaff = q;
            }
            break;
        }
    } else if (strcmp(name, "d_tau") == 0 && in_range(v, 0.0, 10.0)) {
        p->d_tau_us = (uint32_t)floor(v * 1e6 + 0.5);
    } else if (strcmp(name, "deadband") == 0 && in_range(v, 0.0, 1.0)) {
        p->deadband_nm = (int32_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "i_max") == 0 && in_range(v, 0.0, 1000.0)) {
        p->i_max_mv = (int32_t)floor(v * 1e3 + 0.5);
    } else if (strcmp(name, "out_max") == 0 && in_range(v, 0.001, 1000.0)) {
        p->out_max_mv = (int32_t)floor(v * 1e3 + 0.5);
    } else if (strcmp(name, "d_on_measurement") == 0) {
        p->d_on_measurement = v != 0.0;
    } else {
        return SIM_E_ARG;
    }
    /* taken: a refused value changes nothing (no restart needed) */
    if (loop == -2) {
        S.dcfg.servo.cec.line_gains = true;
    }
    S.started = 0;
    return 0;
}

int sim_servo_set(unsigned axis, const char *name, double v)
{
    servo_params_t *p = &S.dcfg.servo;
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (name == NULL || axis >= CORE_AXES) {
        return SIM_E_ARG;
    }
    if (strcmp(name, "ferr_limit") == 0 && in_range(v, 0.0, 2.0)) {
        p->ferr_limit_nm[axis] = (int32_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "stop_decel") == 0 && in_range(v, 1e-6, 1000.0)) {
        p->stop_decel_nm_s2[axis] = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "sat_limit") == 0 && in_range(v, 0.0, 100.0)) {
        p->sat_limit_ticks = (uint32_t)floor(v * (double)S.tick_hz + 0.5);
    } else if (strcmp(name, "on_following") == 0 && (v == 0.0 || v == 1.0)) {
        p->on_following = v != 0.0 ? SERVO_REACT_STOP : SERVO_REACT_DISABLE;
    } else if (strcmp(name, "on_saturation") == 0 && (v == 0.0 || v == 1.0)) {
        p->on_saturation = v != 0.0 ? SERVO_REACT_STOP : SERVO_REACT_DISABLE;
    } else if (strcmp(name, "friction_ff") == 0 && in_range(v, -100.0, 100.0)) {
        S.dcfg.friction_ff_mv[axis] = (int32_t)floor(v * 1e3 + 0.5);
    } else if (strcmp(name, "friction_ff_band") == 0 && in_range(v, 1e-9, 1.0)) {
        S.dcfg.friction_ff_band_nm_s = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "ff_advance") == 0 && in_range(v, 0.0, 0.01)) {
        S.dcfg.ff_advance_ns = (int32_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "qg_comp") == 0 && (v == 0.0 || v == 1.0)) {
        S.dcfg.qg_comp = v != 0.0;
    } else if (strcmp(name, "enc_mean") == 0 && (v == 0.0 || v == 1.0)) {
        S.dcfg.enc_mean = v != 0.0;
    } else if (strcmp(name, "enc_interp") == 0 && (v == 0.0 || v == 1.0)) {
        S.dcfg.enc_interp = v != 0.0;
    } else if (strcmp(name, "ffl_rate") == 0 && in_range(v, 0.0, SERVO_FFL_RATE_MAX)) {
        p->ffl_rate = (int32_t)floor(v + 0.5);
    } else if (strcmp(name, "handover") == 0) {
        p->cec.handover = v != 0.0;
    } else if (strcmp(name, "cec_thesis_form") == 0 && (v == 0.0 || v == 1.0)) {
        p->cec.thesis_form = v != 0.0;
    } else {
        return SIM_E_ARG;
    }
    S.started = 0;
    return 0;
}

int sim_plan_set(unsigned axis, const char *name, double v)
{
    plan_profile_t *p = &S.dcfg.plan;
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (name == NULL || axis >= CORE_AXES) {
        return SIM_E_ARG;
    }
    if (strcmp(name, "v_max") == 0 && in_range(v, 1e-9, 4.29)) {
        p->v_max[axis] = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "a_max") == 0 && in_range(v, 1e-6, 1000.0)) {
        p->a_max[axis] = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "j_max") == 0 && in_range(v, 1e-6, 1e5)) {
        p->j_max[axis] = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "corner_dv") == 0 && in_range(v, 0.0, 4.29)) {
        p->corner_dv[axis] = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "corner_acc") == 0 && in_range(v, 0.0, 1000.0)) {
        p->corner_acc[axis] = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "junction_dev") == 0 && in_range(v, 0.0, 1.0)) {
        p->junction_dev_nm = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "corner") == 0 && in_range(v, 0.0, 3.0)) {
        p->corner = (uint8_t)v;
    } else if (strcmp(name, "shape") == 0 && in_range(v, 0.0, 1.0)) {
        p->shape = (uint8_t)v;
    } else if (strcmp(name, "min_block") == 0 && in_range(v, 0.0, 10.0)) {
        p->min_block_ns = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "mbt_window") == 0 && in_range(v, 1.0, PLAN_WINDOW_MAX)) {
        p->mbt_window = (uint16_t)v;
    } else if (strcmp(name, "stop_decel") == 0 && in_range(v, 1e-6, 1000.0)) {
        S.dcfg.stop_decel_nm_s2 = (int64_t)floor(v * 1e9 + 0.5);
    } else if (strcmp(name, "arc_chord") == 0 && in_range(v, 1e-9, 1.0)) {
        S.dcfg.arc_chord_nm = (int64_t)floor(v * 1e9 + 0.5);
    } else {
        return SIM_E_ARG;
    }
    S.started = 0;
    return 0;
}

int sim_cec_mode(int mode)
{
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (mode < (int)DRIVE_CEC_OFF || mode >= (int)DRIVE_CEC_COUNT) {
        return SIM_E_ARG;
    }
    S.cec_mode = mode;
    if (S.started && drive_set_cec_mode((drive_cec_mode_t)mode) != DRIVE_OK) {
        return SIM_E_DRIVE;
    }
    return 0;
}

int sim_enable(int on)
{
    if (!S.started) {
        return SIM_E_STATE;
    }
    return (int)drive_enable(on != 0);
}

static void emit_edge(void *ctx, uint32_t lines, uint32_t t_ns)
{
    drive_encoder_edge((unsigned)(uintptr_t)ctx, lines, t_ns);
}

static bool run_edges(void *ctx, int32_t steps, uint32_t t_last_ns)
{
    return drive_encoder_run((unsigned)(uintptr_t)ctx, steps, t_last_ns);
}

int sim_encoder_model(int model)
{
    unsigned i;
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (model != SIM_ENC_EDGES && model != SIM_ENC_FAST) {
        return SIM_E_ARG;
    }
    S.enc_model = model;
    for (i = 0; S.started && i < S.axes; i++) {
        qgen_set_run(&S.gen[i], model == SIM_ENC_FAST ? run_edges : NULL);
    }
    return 0;
}

int sim_encoder_model_get(void)
{
    return S.enc_model;
}

int sim_trace_table_mean(int on)
{
    if (!S.setup) {
        return SIM_E_STATE;
    }
    S.tmean_on = on != 0;
    return 0;
}

int sim_table_record(double *buf, size_t rows_cap, double min_hz)
{
    double f_sub;
    if (!S.started) {
        return SIM_E_STATE;
    }
    if (buf == NULL || rows_cap == 0) {
        S.rec = NULL;
        return 0;
    }
    if (!(min_hz > 0.0 && isfinite(min_hz))) {
        return SIM_E_ARG;
    }
    f_sub = (double)S.nsub * 1e9 / (double)S.period_ns;
    S.rec = buf;
    S.rec_cap = rows_cap;
    S.rec_n = 0;
    S.rec_m = f_sub > min_hz ? (uint64_t)floor(f_sub / min_hz) : 1u;
    return 0;
}

size_t sim_table_recorded(void)
{
    return S.rec != NULL ? S.rec_n : 0;
}

double sim_table_record_hz(void)
{
    if (!S.started || S.rec == NULL) {
        return 0.0;
    }
    return (double)S.nsub * 1e9 / (double)S.period_ns / (double)S.rec_m;
}

static qgen_pos_t to_qgen(double counts)
{
    return (qgen_pos_t)axis_floor_i64(counts * (double)QGEN_ONE);
}

int sim_set_link(unsigned node_id, int serial, int can, uint32_t capabilities, uint32_t fw_version,
                 uint32_t build_id, int boot)
{
    if (!S.setup) {
        return SIM_E_STATE;
    }
    if (node_id < 1u || node_id > PROTO_CAN_NODE_MAX) {
        return SIM_E_ARG;
    }
    S.board.node_id = (uint8_t)node_id;
    S.board.serial = serial != 0;
    S.board.can = can != 0;
    S.board.capabilities = capabilities | (1u << PROTO_CAPABILITY_SIMULATED);
    S.board.fw_version = fw_version;
    S.board.build_id = build_id;
    S.boot = boot != 0;
    return 0;
}

void sim_test_eager_inputs(int on)
{
    inputs_eager = on;
}

/* The home switch of an axis from the table position (hal_home_switch's
 * source). The firmware reads its inputs in the tick and in the main
 * context after it, before the plant moves (sim.h step 1): S.table is then
 * the table of the tick's start, so computing a value when it is read
 * gives what setting it at the tick's start gave, without the work on the
 * ticks that do not read it. */
static bool sim_home_read(void *ctx, unsigned axis)
{
    double x;
    (void)ctx;
    if (axis >= S.axes) {
        return false;
    }
    x = S.table[axis] - S.home_switch[axis];
    return (S.home_side[axis] < 0.0 && x <= 0.0) || (S.home_side[axis] > 0.0 && x >= 0.0);
}

/* The reference scale's counter of an axis without reading noise (channel
 * axes + i's source; as sim_home_read). With noise, each tick draws a
 * reading (run_ticks sets it), so that the noise sequence does not depend
 * on when the drive samples. */
static uint32_t sim_ref_read(void *ctx, unsigned ch)
{
    unsigned i = ch - S.axes;
    (void)ctx;
    if (S.ref_drawn[i]) {
        return S.ref_val[i];
    }
    return (uint32_t)(uint64_t)axis_ref_reading_at(&S.ax[i], S.table[i]);
}

int sim_start(void)
{
    drive_config_t cfg;
    unsigned i, nonlinear = 0;
    double period, hmax;
    if (!S.setup) {
        return SIM_E_STATE;
    }
    S.started = 0;
    period = (double)S.period_ns * 1e-9;
    for (i = 0; i < S.axes; i++) {
        if (S.par[i].coulomb_motor > 0.0 || S.par[i].coulomb_table > 0.0 ||
            S.par[i].backlash > 0.0) {
            nonlinear = 1;
        }
    }
    hmax = S.substep_max > 0.0 ? S.substep_max : (nonlinear ? 10e-6 : 100e-6);
    S.nsub = (unsigned)ceil(period / hmax - 1e-9);
    if (S.nsub < 1) {
        S.nsub = 1;
    }
    if (S.nsub >= AXIS_SUBSTEP_MAX) {
        return SIM_E_ARG;
    }
    for (i = 0; i <= S.nsub; i++) {
        S.sub_ns[i] = S.period_ns * i / S.nsub;
    }
    hal_sim_reset();
    hal_sim_set_time_ns(0);
    S.t_ns = 0;
    S.ticks = 0;
    S.rec = NULL;
    for (i = 0; i < SIM_AXES; i++) {
        S.gen[i].edges = 0; /* sim_edges: also after a failed start */
    }
    S.mismatches = 0;
    cfg = S.dcfg;
    cfg.tick_hz = S.tick_hz;
    cfg.axes = S.axes;
    for (i = 0; i < S.axes; i++) {
        if (!axis_init(&S.ax[i], &S.par[i], period / (double)S.nsub)) {
            return SIM_E_MODEL;
        }
        axis_set_position(&S.ax[i], 0.0);
        S.table[i] = axis_table_pos(&S.ax[i]);
        /* the decoder's zero is the true position 0, not a noisy reading */
        qgen_init(&S.gen[i], to_qgen(axis_encoder_counts(&S.ax[i])), 0, emit_edge,
                  (void *)(uintptr_t)i);
        S.count0[i] = S.gen[i].count;
        if (S.enc_index[i] != 0.0) {
            /* one index pulse per motor turn, one count wide */
            uint64_t per = (uint64_t)floor(S.par[i].enc_counts_per_rev + 0.5);
            qgen_set_index(&S.gen[i], S.count0[i] + (int64_t)floor(S.index_phase[i] + 0.5), per, 0,
                           0);
        }
        qgen_set_run(&S.gen[i], S.enc_model == SIM_ENC_FAST ? run_edges : NULL);
        cfg.enc_initial_lines[i] = qgen_lines(&S.gen[i]);
        hal_sim_set_counter(S.axes + i, (uint32_t)(uint64_t)axis_ref_count(&S.ax[i]), true);
        if (!encoder_scale(S.par[i].l * 2.0 * PI_D, S.par[i].enc_counts_per_rev,
                           &cfg.nm_per_count_num[i], &cfg.nm_per_count_den[i]) ||
            !encoder_scale(S.par[i].ref_resolution, 1.0, &cfg.ref_nm_per_count_num[i],
                           &cfg.ref_nm_per_count_den[i])) {
            return SIM_E_MODEL;
        }
    }
    S.dist_on = S.cut_f_w != 0.0;
    for (i = 0; i < S.axes; i++) {
        if (S.cut_f_at[i] != 0.0 || S.spring_k[i] != 0.0) {
            S.dist_on = 1;
        }
    }
    if (S.field.on && S.axes >= 2) {
        field2d_reset(&S.field, S.table[0], S.table[1]);
        sim_apply_field();
        for (i = 0; i < 2; i++) {
            hal_sim_set_counter(
                S.axes + i,
                (uint32_t)(uint64_t)(int64_t)floor(S.table[i] / S.par[i].ref_resolution + 0.5),
                true);
        }
    }
    for (i = 0; i < SIM_AXES; i++) {
        S.inj_n[i] = 0;
        S.inj_any = false;
        S.inj_k[i] = 0;
        S.inj_now[i] = 0.0;
    }
    S.board.drive = &cfg;
    S.board.boot = S.boot ? boot_sim_config() : NULL;
    if (app_init(&S.board) != APP_OK) {
        S.board.drive = NULL;
        return SIM_E_DRIVE;
    }
    S.board.drive = NULL; /* cfg is gone after this call */
    if (drive_set_cec_mode((drive_cec_mode_t)S.cec_mode) != DRIVE_OK) {
        return SIM_E_DRIVE;
    }
    S.ref_per_tick = inputs_eager != 0 || (S.field.on && S.axes >= 2);
    for (i = 0; i < S.axes; i++) {
        S.ref_drawn[i] = false;
        S.ref_per_tick = S.ref_per_tick || S.ax[i].p.ref_noise > 0.0;
        if (!inputs_eager) {
            hal_sim_set_counter_source(S.axes + i, sim_ref_read, NULL);
        }
    }
    if (!inputs_eager) {
        hal_sim_set_home_source(sim_home_read, NULL);
    }
    /* the drive started at time 0; the first tick comes one period later */
    S.t_ns = S.period_ns;
    S.started = 1;
    return 0;
}

static inline __attribute__((always_inline)) void write_row(double *row, bool plain)
{
    drive_trace_t st;
    unsigned i;
    drive_trace_read(&st); /* drive_snapshot's fields, a fraction of its cost */
    /* the columns of absent axes are 0 (each written column is written
     * below: no memset call per traced tick) */
    for (i = 4u + 4u * S.axes; i < SIM_TRACE_COLS; i++) {
        row[i] = 0.0;
    }
    row[0] = (double)S.t_ns * 1e-9;
    row[1] = (double)st.state;
    row[2] = (double)st.faults;
    row[3] = (double)st.contour_error_nm * 1e-9;
    for (i = 0; i < S.axes; i++) {
        row[4 + 4 * i] = (double)st.ref[i] * 1e-9;
        row[5 + 4 * i] = S.table[i];
        row[6 + 4 * i] = (double)st.pos[i] * 1e-9;
        row[7 + 4 * i] = (double)hal_sim_motor_mv(i) * 1e-3;
    }
    for (i = 0; !plain && (S.tmean_on || S.inj_any) && i < S.axes; i++) {
        if (S.tmean_on) {
            row[5 + 4 * i] = S.tmean[i];
        }
        if (S.inj_n[i] > 0) {
            row[7 + 4 * i] += S.inj_now[i];
        }
    }
}

/* The injected voltage of this tick per axis (sim_inject); off: nothing. */
static void inject_tick(void)
{
    unsigned i;
    for (i = 0; S.inj_any && i < S.axes; i++) {
        if (S.inj_n[i] == 0) {
            continue;
        }
        if (S.inj_k[i] < S.inj_n[i] && hal_sim_motor_enabled(i)) {
            S.inj_now[i] = S.inj[i][S.inj_k[i]];
        } else {
            S.inj_now[i] = 0.0;
        }
        if (S.inj_k[i] < S.inj_n[i]) {
            S.inj_k[i]++;
        }
    }
}

int sim_inject(unsigned axis, const double *volts, size_t n)
{
    unsigned i;
    if (!S.started) {
        return SIM_E_STATE;
    }
    if (axis >= S.axes) {
        return SIM_E_ARG;
    }
    S.inj[axis] = volts;
    S.inj_n[axis] = volts != NULL ? n : 0;
    S.inj_any = false;
    for (i = 0; i < SIM_AXES; i++) {
        S.inj_any = S.inj_any || S.inj_n[i] > 0;
    }
    S.inj_k[axis] = 0;
    S.inj_now[axis] = 0.0;
    return 0;
}

size_t sim_inject_left(unsigned axis)
{
    if (axis >= SIM_AXES) {
        return 0;
    }
    return S.inj_n[axis] - S.inj_k[axis];
}

static double sgn(double v)
{
    return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0);
}

/* The disturbance force on each axis (N, opposing +x when positive) from the
 * reference velocity of this tick and the table position, applied as the
 * load torque l F on the motor side (the thesis's Tc) for the coming tick. */
static void disturbance_tick(void)
{
    drive_status_t st;
    double f[SIM_AXES] = {0.0}, vx, vy;
    unsigned i;
    drive_snapshot(&st);
    for (i = 0; i < S.axes; i++) {
        f[i] = S.cut_f_at[i] * sgn((double)st.vel_ref[i]) +
               S.spring_k[i] * (S.table[i] - S.spring_x0[i]);
    }
    vx = (double)st.vel_ref[0];
    vy = S.axes > 1 ? (double)st.vel_ref[1] : 0.0;
    if (S.cut_f_w != 0.0 && S.axes > 1 && (vx != 0.0 || vy != 0.0)) {
        double alpha = atan2(vy, vx);
        f[0] += S.cut_f_w * cos(S.cut_phi - alpha);
        f[1] -= S.cut_f_w * sin(S.cut_phi - alpha);
    }
    for (i = 0; i < S.axes; i++) {
        axis_set_load_torque(&S.ax[i], S.par[i].load_torque + S.par[i].l * f[i]);
    }
}

/* Integral of H(u) = floor from 0 to u: n (n - 1) / 2 + n (u - n). */
static double floor_integral(double u)
{
    double n = floor(u);
    return n * (n - 1.0) * 0.5 + n * (u - n);
}

/* The mean reading of axis i: s < 0 starts a tick; s >= 0 adds substep s
 * (the generator moved linearly from mean_x to its x, emitting the count
 * floor(x): qgen.h, no edge offsets in the simulator); s == nsub - 1 also
 * hands the tick's mean minus the count at its end to the HAL, in
 * 2^-16 counts. Exact but for the ns rounding of the edge times. */
static void sim_mean_step(unsigned i, int s)
{
    qgen_pos_t x1 = S.gen[i].x;
    double u0, u1, dt;
    if (s < 0) {
        S.mean_x[i] = x1;
        S.mean_base[i] = S.gen[i].count;
        S.mean_acc[i] = 0.0;
        S.tmean_acc[i] = 0.0;
        return;
    }
    /* relative to the count at the start of the tick: exact in a double */
    u0 = (double)(S.mean_x[i] - S.mean_base[i] * QGEN_ONE) / (double)QGEN_ONE;
    u1 = (double)(x1 - S.mean_base[i] * QGEN_ONE) / (double)QGEN_ONE;
    dt = (double)(S.sub_ns[s + 1] - S.sub_ns[s]);
    if (floor(u0) == floor(u1)) {
        S.mean_acc[i] += floor(u0) * dt;
    } else {
        S.mean_acc[i] += (floor_integral(u1) - floor_integral(u0)) / (u1 - u0) * dt;
    }
    S.mean_x[i] = x1;
    if (S.tmean_on) {
        S.tmean_acc[i] += axis_table_pos(&S.ax[i]) * dt;
    }
    if ((unsigned)s + 1u == S.nsub) {
        S.tmean[i] = S.tmean_acc[i] / (double)S.period_ns;
        double lag =
            S.mean_acc[i] / (double)S.period_ns - (double)(S.gen[i].count - S.mean_base[i]);
        hal_sim_set_encoder_mean(i, (int64_t)floor(lag * 65536.0 + 0.5));
    }
}

/* The instrument (sim_table_record): after substep s of axis i, that
 * axis's table position if the substep ends a sample. */
static void sim_record_step(unsigned i, unsigned s)
{
    uint64_t g0 = S.ticks * S.nsub, g = g0 + s + 1u;
    size_t row;
    if (S.rec_m == 1u) { /* every substep a sample: no divisions */
        row = S.rec_n + s;
        if (row < S.rec_cap) {
            double *r = S.rec + row * SIM_REC_COLS;
            r[0] = (double)(S.t_ns + S.sub_ns[s + 1]) * 1e-9;
            r[1 + i] = axis_table_pos(&S.ax[i]);
        }
        return;
    }
    if (g % S.rec_m != 0u) {
        return;
    }
    row = S.rec_n + (size_t)(g / S.rec_m - g0 / S.rec_m) - 1u;
    if (row < S.rec_cap) {
        double *r = S.rec + row * SIM_REC_COLS;
        r[0] = (double)(S.t_ns + S.sub_ns[s + 1]) * 1e-9;
        r[1 + i] = axis_table_pos(&S.ax[i]);
    }
}

/* sim_record_tick with one substep per tick and a sample per substep: one
 * sample, at the tick's end: its time, and the table below (plant_tick1
 * leaves the sample to this). */
static inline void sim_record_tick1(void)
{
    if (S.rec_n < S.rec_cap) {
        double *r = S.rec + S.rec_n * SIM_REC_COLS;
        unsigned i;
        r[0] = (double)(S.t_ns + S.sub_ns[1]) * 1e-9;
        for (i = 0; i < S.axes; i++) {
            r[1 + i] = S.table[i];
        }
    }
    S.rec_n++;
}

/* After the tick's substeps and the 2-D field: a sample at the tick's end
 * is the next trace row's table (bit for bit); earlier ones get the field
 * at the direction tracked so far. */
static void sim_record_tick(void)
{
    uint64_t g0 = S.ticks * S.nsub, g1 = g0 + S.nsub;
    size_t n, k, last;
    if (S.rec_m == 1u && S.nsub == 1u) {
        sim_record_tick1();
        return;
    }
    if (S.rec_m == 1u) { /* as below with m = 1 */
        n = S.nsub;
        last = n - 1u;
    } else {
        n = (size_t)(g1 / S.rec_m - g0 / S.rec_m);
        last = g1 % S.rec_m == 0u ? n - 1u : n;
    }
    for (k = 0; k < n && S.rec_n + k < S.rec_cap; k++) {
        double *r = S.rec + (S.rec_n + k) * SIM_REC_COLS;
        unsigned i;
        if (k == last) {
            for (i = 0; i < S.axes; i++) {
                r[1 + i] = S.table[i];
            }
        } else if (S.field.on && S.axes >= 2) {
            double e[2];
            field2d_error(&S.field, r[1], r[2], e);
            r[1] += e[0];
            r[2] += e[1];
        }
    }
    S.rec_n += n;
}

/* The plant's tick with one substep (the loop below for nsub == 1): every
 * axis's substep and reading first, then the generators' moves in axis
 * order. The same operations on the same values as substep and move axis
 * by axis (a move changes only its generator and the drive's decoder,
 * which no substep reads), with the axes' plant chains independent of
 * the moves' callbacks, so that they overlap. */
static int plant_split_off; /* sim_test_plant_split */

void sim_test_plant_split(int on)
{
    plant_split_off = !on;
}

static void plant_tick1(void)
{
    qgen_pos_t x1[SIM_AXES];
    unsigned i;
    for (i = 0; i < S.axes; i++) {
        double u = (double)hal_sim_motor_mv(i) * 1e-3;
        if (S.inj_any && S.inj_n[i] > 0) {
            u += S.inj_now[i];
        }
        /* z unchanged and no reading noise: the reading is the one the
         * generator has (qgen_move_to keeps the last x1) */
        x1[i] = (axis_substep(&S.ax[i], u) && S.ax[i].p.enc_noise_counts == 0.0)
                    ? S.gen[i].x
                    : to_qgen(axis_encoder_reading(&S.ax[i]));
        S.table[i] = axis_table_pos(&S.ax[i]);
    }
    /* every substep a sample (rec_m 1): sim_record_tick takes it whole */
    if (!S.mean && (S.rec == NULL || S.rec_m == 1u)) {
        for (i = 0; i < S.axes; i++) {
            (void)qgen_move_to(&S.gen[i], x1[i], S.t_ns + S.sub_ns[1]);
        }
        return;
    }
    for (i = 0; i < S.axes; i++) {
        if (S.mean) {
            sim_mean_step(i, -1);
        }
        (void)qgen_move_to(&S.gen[i], x1[i], S.t_ns + S.sub_ns[1]);
        if (S.mean) {
            sim_mean_step(i, 0);
        }
        if (S.rec != NULL) {
            sim_record_step(i, 0);
        }
    }
}

/* The plain path (run_ticks): one substep per tick with the split above,
 * and no option that needs a test per tick or per axis: every axis linear
 * only (no load torque, friction, backlash; so no disturbances) without a
 * pitch map or encoder reading noise, no injection, no 2-D field, no
 * reference scale drawn per tick, no table mean, the instrument off or
 * sampling every substep. Only sim_start and the calls between runs change
 * these, so run_ticks decides once per call; plant_tick_plain is
 * plant_tick1 with the tests of those options left out (the drive's
 * enc_mean, a parameter, is still tested per tick: plant_tick1 takes it). */
static int plain_off; /* sim_test_plain */

void sim_test_plain(int on)
{
    plain_off = !on;
}

static bool run_plain(void)
{
    unsigned i;
    /* the 2-D field sets ref_per_tick (sim_start) */
    if (plain_off || S.nsub != 1u || plant_split_off || S.inj_any || S.dist_on || S.ref_per_tick ||
        S.tmean_on || (S.rec != NULL && S.rec_m != 1u)) {
        return false;
    }
    for (i = 0; i < S.axes; i++) {
        if (!S.ax[i].lin_only || S.ax[i].p.pitch_n > 0 || S.ax[i].p.enc_noise_counts != 0.0) {
            return false;
        }
    }
    return true;
}

static inline __attribute__((always_inline)) void plant_tick_plain(void)
{
    qgen_pos_t x1[SIM_AXES];
    unsigned i;
    /* a constant trip count: the compiler unrolls the loop (each axis's
     * fields at fixed addresses, no pointers to step) */
    for (i = 0; i < SIM_AXES; i++) {
        if (i < S.axes) {
            axis_t *ax = &S.ax[i];
            double u = (double)hal_sim_motor_mv(i) * 1e-3;
            /* z unchanged: the reading is the one the generator has */
            x1[i] = axis_substep_lin(ax, u) ? S.gen[i].x : to_qgen(axis_encoder_counts(ax));
            S.table[i] = axis_table_pos_nomap(ax);
        }
    }
    for (i = 0; i < SIM_AXES; i++) {
        if (i < S.axes) {
            (void)qgen_move_to(&S.gen[i], x1[i], S.t_ns + S.sub_ns[1]);
        }
    }
}

/* After a tick of sim_run_until_free / _until_idle: true to stop there. */
static __attribute__((noinline)) bool run_stop(unsigned min_free, unsigned idle_step,
                                               unsigned *idle_in)
{
    if (min_free > 0 && drive_queue_free() >= min_free) {
        return true;
    }
    if (idle_step > 0 && --*idle_in == 0) {
        drive_status_t st;
        *idle_in = idle_step;
        drive_status(&st);
        return st.faults != 0 || st.state == DRIVE_IDLE;
    }
    return false;
}

/* The plant's tick, any options: the substeps, generators, mean reading,
 * 2-D field and instrument. */
static void plant_tick(void)
{
    unsigned i, s;
    bool split = S.nsub == 1u && !plant_split_off;
    if (split) {
        plant_tick1();
    }
    for (i = 0; !split && i < S.axes; i++) {
        double u = (double)hal_sim_motor_mv(i) * 1e-3;
        if (S.inj_n[i] > 0) {
            u += S.inj_now[i];
        }
        if (S.mean) {
            sim_mean_step(i, -1);
        }
        for (s = 0; s < S.nsub; s++) {
            /* z unchanged and no reading noise: the reading is the one
             * the generator has (qgen_move_to keeps the last x1) */
            qgen_pos_t x1 = (axis_substep(&S.ax[i], u) && S.ax[i].p.enc_noise_counts == 0.0)
                                ? S.gen[i].x
                                : to_qgen(axis_encoder_reading(&S.ax[i]));
            (void)qgen_move_to(&S.gen[i], x1, S.t_ns + S.sub_ns[s + 1]);
            if (S.mean) {
                sim_mean_step(i, (int)s);
            }
            if (S.rec != NULL) {
                sim_record_step(i, s);
            }
        }
        S.table[i] = axis_table_pos(&S.ax[i]);
    }
    sim_apply_field();
    if (S.rec != NULL) {
        sim_record_tick();
    }
}

/* The tick loop; plain (run_plain) leaves out the tests of the options
 * that are off (two copies of the loop, one per value). */
static inline __attribute__((always_inline)) long run_loop(const bool plain, uint64_t ticks,
                                                           double *trace, size_t rows_cap,
                                                           unsigned every, unsigned min_free,
                                                           unsigned idle_step, uint64_t *ran)
{
    bool stops = min_free > 0 || idle_step > 0;
    uint64_t k;
    size_t rows = 0;
    unsigned i, row_in;           /* row_in: ticks until S.ticks % every == 0 */
    unsigned idle_in = idle_step; /* ticks until the next status poll */
    row_in = (unsigned)(S.ticks % every);
    row_in = row_in == 0 ? 0 : every - row_in;
    for (k = 0; k < ticks; k++) {
        hal_sim_set_time_ns(S.t_ns);
        /* the home switches and the reference scales are read through
         * their sources (sim_home_read, sim_ref_read); a noisy scale's
         * reading is drawn here, every tick */
        for (i = 0; !plain && S.ref_per_tick && i < S.axes; i++) {
            S.ref_drawn[i] = S.ax[i].p.ref_noise > 0.0 && !inputs_eager;
            if (S.ref_drawn[i]) {
                S.ref_val[i] = (uint32_t)(uint64_t)axis_ref_reading_at(&S.ax[i], S.table[i]);
            }
            if (inputs_eager) { /* the reference for the sources */
                int64_t rc = axis_ref_reading_at(&S.ax[i], S.table[i]);
                double x = S.table[i] - S.home_switch[i];
                hal_sim_set_counter(S.axes + i, (uint32_t)(uint64_t)rc, true);
                hal_sim_set_home_switch(i, (S.home_side[i] < 0.0 && x <= 0.0) ||
                                               (S.home_side[i] > 0.0 && x >= 0.0));
            }
        }
        app_tick();
        if (!plain) {
            inject_tick();
        }
        for (i = 0; i < S.axes; i++) {
            if (drive_encoder_count(i) + S.count0[i] != S.gen[i].count) {
                S.mismatches++;
                break;
            }
        }
        if (row_in == 0) {
            if (trace != NULL && rows < rows_cap) {
                write_row(trace + rows * SIM_TRACE_COLS, plain);
                rows++;
            }
            row_in = every;
        }
        row_in--;
        app_poll();
        if (!plain && S.dist_on) {
            disturbance_tick();
        }
        /* after main: a parameter write */
        S.mean = drive_config()->enc_mean || (!plain && S.tmean_on);
        if (plain && !S.mean) {
            plant_tick_plain();
            if (S.rec != NULL) {
                sim_record_tick1();
            }
        } else {
            plant_tick();
        }
        S.t_ns += S.period_ns;
        S.ticks++;
        if (stops && run_stop(min_free, idle_step, &idle_in)) {
            k++;
            break;
        }
    }
    *ran = k;
    return (long)rows;
}

static long run_ticks(uint64_t ticks, double *trace, size_t rows_cap, unsigned every,
                      unsigned min_free, unsigned idle_step, uint64_t *ran)
{
    if (!S.started) {
        return SIM_E_STATE;
    }
    if (every == 0) {
        every = 1;
    }
    if (run_plain()) {
        return run_loop(true, ticks, trace, rows_cap, every, min_free, idle_step, ran);
    }
    return run_loop(false, ticks, trace, rows_cap, every, min_free, idle_step, ran);
}

long sim_run(uint64_t ticks, double *trace, size_t rows_cap, unsigned every)
{
    uint64_t ran;
    return run_ticks(ticks, trace, rows_cap, every, 0, 0, &ran);
}

long sim_run_until_free(uint64_t ticks, unsigned min_free, double *trace, size_t rows_cap,
                        unsigned every, uint64_t *ran)
{
    uint64_t n = 0;
    long rows = run_ticks(ticks, trace, rows_cap, every, min_free, 0, &n);
    if (ran != NULL) {
        *ran = n;
    }
    return rows;
}

long sim_run_until_idle(uint64_t ticks, unsigned step, double *trace, size_t rows_cap,
                        unsigned every, uint64_t *ran)
{
    uint64_t n = 0;
    long rows = run_ticks(ticks, trace, rows_cap, every, 0, step > 0 ? step : 1u, &n);
    if (ran != NULL) {
        *ran = n;
    }
    return rows;
}

unsigned sim_trace_cols(void)
{
    return SIM_TRACE_COLS;
}

uint32_t sim_tick_hz(void)
{
    return S.tick_hz;
}

uint64_t sim_ticks(void)
{
    return S.ticks;
}

double sim_time_s(void)
{
    return (double)S.t_ns * 1e-9;
}

/* The generators' counts of the events they emitted by motion (each
 * qgen_move_to's result), not kept apart per tick. */
uint64_t sim_edges(void)
{
    uint64_t n = 0;
    unsigned i;
    for (i = 0; i < S.axes; i++) {
        n += S.gen[i].edges;
    }
    return n;
}

uint64_t sim_run_edges(void)
{
    uint64_t n = 0;
    unsigned i;
    for (i = 0; S.started && i < S.axes; i++) {
        n += S.gen[i].run_edges;
    }
    return n;
}

uint64_t sim_edge_mismatches(void)
{
    return S.mismatches;
}

unsigned sim_substeps(void)
{
    return S.nsub;
}

double sim_table_pos(unsigned axis)
{
    if (!S.started || axis >= S.axes) {
        return 0.0;
    }
    return S.table[axis];
}

int sim_drive_status(sim_status_t *out)
{
    drive_status_t st;
    if (out == NULL) {
        return SIM_E_ARG;
    }
    if (!S.started) {
        return SIM_E_STATE;
    }
    drive_status(&st);
    out->state = (int)st.state;
    out->faults = st.faults;
    out->queue_free = st.queue_free;
    out->blocks_done = st.blocks_done;
    out->tag = st.tag;
    out->tick = st.tick;
    out->queued_time_ns = st.queued_time_ns;
    return 0;
}

int sim_queue_line(const int64_t *target_nm, int64_t feed_nm_s, uint32_t tag, int exact_stop,
                   int *result)
{
    drive_block_t b;
    drive_result_t r;
    unsigned i;
    if (!S.started) {
        return SIM_E_STATE;
    }
    if (target_nm == NULL) {
        return SIM_E_ARG;
    }
    memset(&b, 0, sizeof b);
    b.kind = DRIVE_BLOCK_LINE;
    b.tag = tag;
    for (i = 0; i < CORE_AXES; i++) {
        b.target[i] = target_nm[i];
    }
    b.feed_nm_s = feed_nm_s;
    b.exact_stop = exact_stop != 0;
    r = drive_queue_block(&b);
    if (result != NULL) {
        *result = (int)r;
    }
    return r == DRIVE_OK ? 0 : (r == DRIVE_E_FULL ? SIM_E_FULL : SIM_E_DRIVE);
}

int sim_queue_dwell(uint32_t ms, uint32_t tag, int *result)
{
    drive_block_t b;
    drive_result_t r;
    if (!S.started) {
        return SIM_E_STATE;
    }
    memset(&b, 0, sizeof b);
    b.kind = DRIVE_BLOCK_DWELL;
    b.tag = tag;
    b.dwell_ms = ms;
    r = drive_queue_block(&b);
    if (result != NULL) {
        *result = (int)r;
    }
    return r == DRIVE_OK ? 0 : (r == DRIVE_E_FULL ? SIM_E_FULL : SIM_E_DRIVE);
}

int sim_queue_arc(const int64_t *target_nm, int64_t feed_nm_s, int plane, int64_t centre_u,
                  int64_t centre_v, int sense, uint32_t tag, int *result)
{
    drive_block_t b;
    drive_result_t r;
    unsigned i;
    if (!S.started) {
        return SIM_E_STATE;
    }
    if (target_nm == NULL || plane < 0 || plane > 2 || (sense != 1 && sense != -1)) {
        return SIM_E_ARG;
    }
    memset(&b, 0, sizeof b);
    b.kind = DRIVE_BLOCK_ARC;
    b.tag = tag;
    for (i = 0; i < CORE_AXES; i++) {
        b.target[i] = target_nm[i];
    }
    b.feed_nm_s = feed_nm_s;
    b.plane = (drive_plane_t)plane;
    b.centre_u = centre_u;
    b.centre_v = centre_v;
    b.sense = (int8_t)sense;
    r = drive_queue_block(&b);
    if (result != NULL) {
        *result = (int)r;
    }
    return r == DRIVE_OK ? 0 : (r == DRIVE_E_FULL ? SIM_E_FULL : SIM_E_DRIVE);
}
