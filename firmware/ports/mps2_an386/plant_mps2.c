/* plant_mps2.c - simulated axes of the QEMU board (see plant_mps2.h). */
#include "plant_mps2.h"

#include <math.h>

#include "axis_model.h"
#include "hal.h"
#include "qdec.h"

#define PLANT_PI       3.14159265358979323846
#define PLANT_LEAD_M   0.005
#define PLANT_MV_LIMIT 160000
#define PLANT_SUB_MAX  8u
/* Home switch (hal_home_switch): active at table positions <= this, m; the
 * encoder index: one count per motor turn, at counts 0 mod PLANT_INDEX_PER
 * from position 0 (as the simulator's defaults, sim.h). */
#define PLANT_HOME_SWITCH_M (-0.0213)
#define PLANT_INDEX_PER     4000

/* X's pitch error map (plant_mps2.h): table position minus l th2, um, at
 * every PLANT_PITCH_STEP_MM from PLANT_PITCH_FROM_MM, both directions. */
#define PLANT_PITCH_AXIS    0u
#define PLANT_PITCH_FROM_MM (-20)
#define PLANT_PITCH_STEP_MM 10
#define PLANT_PITCH_N       8u
static const int8_t plant_pitch_um[PLANT_PITCH_N] = {-4, -2, 0, 12, 8, 15, 18, 14};

static struct {
    unsigned axes;
    unsigned nsub;
    uint32_t period_ns;
    axis_t ax[CORE_AXES];
    int64_t count[CORE_AXES];      /* encoder count last delivered (floor of the reading) */
    int64_t count0[CORE_AXES];     /* count at position 0 (an index) */
    uint32_t ref_count[CORE_AXES]; /* reference-scale counter, latched per plant step */
    double reading[CORE_AXES];     /* reading at the end of the last substep, counts */
    int32_t mv[HAL_MAX_AXES];
    bool on[HAL_MAX_AXES];
} pl;

/* A/B levels of count c (x4 quadrature, forward = A leading B: 0, A, AB, B),
 * as hil_sim/qgen.h generates them. (qgen itself needs 128-bit integers,
 * which 32-bit ARM lacks; the plant may use doubles instead.) */
static uint32_t lines_at(unsigned i, int64_t c)
{
    static const uint32_t ab[4] = {0u, QDEC_LINE_A, QDEC_LINE_A | QDEC_LINE_B, QDEC_LINE_B};

    return ab[(uint32_t)c & 3u] | (((c - pl.count0[i]) % PLANT_INDEX_PER) == 0 ? QDEC_LINE_Z : 0u);
}

/* Move axis i's encoder from the last reading to r over [t0, t1] ns: one
 * edge per crossed count boundary, at the linearly interpolated time. */
static void encoder_move(unsigned i, double r, uint64_t t0, uint64_t t1)
{
    double r0 = pl.reading[i];
    int64_t c = (int64_t)floor(r);

    while (pl.count[i] != c) {
        int64_t next = pl.count[i] < c ? pl.count[i] + 1 : pl.count[i] - 1;
        double boundary = (double)(next > pl.count[i] ? next : pl.count[i]);
        double f = r != r0 ? (boundary - r0) / (r - r0) : 1.0;
        uint64_t t;

        if (f < 0.0) {
            f = 0.0;
        } else if (f > 1.0) {
            f = 1.0;
        }
        t = t0 + (uint64_t)(f * (double)(t1 - t0));
        pl.count[i] = next;
        drive_encoder_edge(i, lines_at(i, next), (uint32_t)t);
    }
    pl.reading[i] = r;
}

static void plant_pitch_map(axis_params_t *p)
{
    unsigned k;

    p->pitch_n = PLANT_PITCH_N;
    for (k = 0; k < PLANT_PITCH_N; k++) {
        p->pitch_pos[k] = (PLANT_PITCH_FROM_MM + (int)k * PLANT_PITCH_STEP_MM) * 1e-3;
        p->pitch_err_fwd[k] = plant_pitch_um[k] * 1e-6;
        p->pitch_err_rev[k] = p->pitch_err_fwd[k];
    }
}

void plant_drive_config(drive_config_t *cfg, uint32_t tick_hz, unsigned axes)
{
    unsigned i;

    drive_config_default(cfg, tick_hz, axes);
    for (i = 0; i < CORE_AXES; i++) {
        cfg->servo.axis[i].out_max_mv = 10000;
        cfg->servo.axis[i].i_max_mv = 10000;
    }
    cfg->servo.cec.pid.out_max_mv = 10000;
    cfg->servo.cec.pid.i_max_mv = 10000;
}

bool plant_init(uint32_t tick_hz, unsigned axes, drive_config_t *cfg)
{
    unsigned i;
    double period;

    if (axes < 1u || axes > CORE_AXES || tick_hz == 0u || cfg == NULL) {
        return false;
    }
    pl.axes = axes;
    pl.period_ns = 1000000000u / tick_hz;
    pl.nsub = (pl.period_ns + 99999u) / 100000u;
    if (pl.nsub > PLANT_SUB_MAX) {
        return false;
    }
    period = (double)pl.period_ns * 1e-9;
    for (i = 0; i < axes; i++) {
        axis_params_t p;

        axis_params_lacerda(&p, i == 1u);
        p.l = PLANT_LEAD_M / (2.0 * PLANT_PI);
        if (i == PLANT_PITCH_AXIS) {
            plant_pitch_map(&p);
        }
        if (!axis_init(&pl.ax[i], &p, period / (double)pl.nsub)) {
            return false;
        }
        axis_set_position(&pl.ax[i], 0.0);
        pl.ref_count[i] = (uint32_t)(uint64_t)axis_ref_count(&pl.ax[i]);
        pl.reading[i] = axis_encoder_reading(&pl.ax[i]);
        pl.count[i] = (int64_t)floor(pl.reading[i]);
        pl.count0[i] = pl.count[i];
        cfg->enc_initial_lines[i] = lines_at(i, pl.count[i]);
        /* 5 mm per 4000 counts = 1250 nm per count; reference scale 1 nm */
        cfg->nm_per_count_num[i] = (int32_t)llround(PLANT_LEAD_M * 1e9 / p.enc_counts_per_rev);
        cfg->nm_per_count_den[i] = 1;
        cfg->ref_nm_per_count_num[i] = (int32_t)llround(p.ref_resolution * 1e9);
        cfg->ref_nm_per_count_den[i] = 1;
        pl.mv[i] = 0;
        pl.on[i] = false;
    }
    return true;
}

void plant_step(uint32_t tick)
{
    uint64_t t0 = (uint64_t)tick * pl.period_ns;
    unsigned i, s;

    for (i = 0; i < pl.axes; i++) {
        double u = pl.on[i] ? (double)pl.mv[i] * 1e-3 : 0.0;

        for (s = 0; s < pl.nsub; s++) {
            axis_substep(&pl.ax[i], u);
            encoder_move(i, axis_encoder_reading(&pl.ax[i]),
                         t0 + (uint64_t)pl.period_ns * s / pl.nsub,
                         t0 + (uint64_t)pl.period_ns * (s + 1u) / pl.nsub);
        }
        /* the scale's counter as a timer register holds it: computed here,
         * read in the tick for the price of a register read */
        pl.ref_count[i] = (uint32_t)(uint64_t)axis_ref_count(&pl.ax[i]);
    }
}

int64_t plant_table_nm(unsigned axis)
{
    return axis < pl.axes ? (int64_t)llround(axis_table_pos(&pl.ax[axis]) * 1e9) : 0;
}

/* ---- hal.h: motors and encoders ------------------------------------------------ */

void hal_motor_set_mv(unsigned axis, int32_t millivolts)
{
    if (axis >= HAL_MAX_AXES) {
        return;
    }
    if (millivolts > PLANT_MV_LIMIT) {
        millivolts = PLANT_MV_LIMIT;
    } else if (millivolts < -PLANT_MV_LIMIT) {
        millivolts = -PLANT_MV_LIMIT;
    }
    pl.mv[axis] = millivolts;
}

void hal_motor_enable(unsigned axis, bool on)
{
    if (axis < HAL_MAX_AXES) {
        pl.on[axis] = on;
    }
}

bool hal_home_switch(unsigned axis)
{
    return axis < pl.axes && axis_table_pos(&pl.ax[axis]) <= PLANT_HOME_SWITCH_M;
}

bool hal_amp_fault(unsigned axis)
{
    (void)axis;
    return false;
}

void hal_motor_set_mv_all(const int32_t *mv, unsigned n)
{
    const int32_t *end = mv + ((n < HAL_MAX_AXES) ? n : HAL_MAX_AXES);
    int32_t *out = pl.mv;

    while (mv != end) {
        int32_t v = *mv++;

        if ((uint32_t)v + PLANT_MV_LIMIT > 2u * PLANT_MV_LIMIT) { /* |v| above the limit */
            v = (v > 0) ? PLANT_MV_LIMIT : -PLANT_MV_LIMIT;
        }
        *out++ = v;
    }
}

uint32_t hal_amp_fault_mask(unsigned n)
{
    (void)n;
    return 0;
}

bool hal_encoder_counter(unsigned ch, uint32_t *count)
{
    if (count == NULL || ch < pl.axes || ch >= 2u * pl.axes) {
        return false;
    }
    *count = pl.ref_count[ch - pl.axes];
    return true;
}

bool hal_encoder_mean(unsigned axis, int64_t *lag_q16)
{
    (void)axis;
    (void)lag_q16;
    return false; /* the plant steps once per tick: enc_mean refused */
}
