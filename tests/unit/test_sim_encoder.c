/*
 * test_sim_encoder.c - the simulator's fast encoder model (SIM_ENC_FAST:
 * each substep's edges as one run) against the edge-accurate reference
 * (SIM_ENC_EDGES), on the bench circle (three axes, 10 kHz, R 20 mm at
 * 10 m/min, full feed-forward, exact CEC) and on a homing to the encoder
 * index. The model claims exactness at every sample, so the tolerance is
 * zero: the decoders' states (count, edge count, last edge time,
 * direction, velocity, index latch) after every tick, every trace row and
 * the contour error figures are identical.
 */
#include <math.h>
#include <stdbool.h>
#include <string.h>

#include "drive.h"
#include "drive_test.h"
#include "hal_sim.h"
#include "sim.h"
#include "unity.h"

#define AXES      3u
#define MAX_TICKS 40000u

typedef struct {
    int64_t pos, vel, index_pos, refscale;
    uint32_t count, nedge, t_last, index_events;
    int8_t dir;
    uint8_t ab;
} enc_rec_t;

typedef struct {
    enc_rec_t enc[MAX_TICKS][AXES];
    double trace[MAX_TICKS][SIM_TRACE_COLS];
    double tab[MAX_TICKS][SIM_REC_COLS]; /* the instrument's rows (record) */
    unsigned ticks;
    uint64_t edges, run_edges, mismatches;
} run_rec_t;

static run_rec_t rec[2]; /* [SIM_ENC_EDGES], [SIM_ENC_FAST] */

static bool record;   /* the instrument (sim_table_record) on every tick */
static double rec_hz; /* its rate (0: 10 kHz, one sample per tick) */
static bool mean_on;  /* the drive's mean reading (enc_mean) */
static int option;    /* circle(): one of the plain loop's options, below */

void setUp(void)
{
    record = false; /* not left on by a test that failed */
    rec_hz = 0.0;
    mean_on = false;
    option = 0;
}

void tearDown(void)
{
}

/* One tick with its trace row, then every decoder's state (the velocity
 * from a copy: qdec_velocity brings the copy's lazy estimate up to date)
 * and, every 97th tick, the reference scales' positions of the drive's
 * status (a status request makes the next tick sample them: so that the
 * drive samples them every DRIVE_REF_SAMPLE_TICKS ticks in between). */
static void tick(run_rec_t *r)
{
    unsigned i;
    drive_status_t st = {0};
    bool status = r->ticks % 97u == 0u;
    TEST_ASSERT_TRUE(r->ticks < MAX_TICKS);
    if (record) {
        TEST_ASSERT_EQUAL_INT(0,
                              sim_table_record(r->tab[r->ticks], 1, rec_hz > 0.0 ? rec_hz : 1e4));
    }
    TEST_ASSERT_EQUAL_INT(1, sim_run(1, r->trace[r->ticks], 1, 1));
    if (status) {
        drive_status(&st);
    }
    for (i = 0; i < AXES; i++) {
        qdec_t d = *drive_test_encoder(i);
        enc_rec_t *e = &r->enc[r->ticks][i];
        e->pos = d.out.pos;
        e->vel = qdec_velocity(&d);
        e->index_pos = d.out.index_pos;
        e->refscale = status ? st.refscale[i] : 0;
        e->count = d.e.count;
        e->nedge = d.e.nedge;
        e->t_last = d.e.t_last;
        e->index_events = d.out.index_events;
        e->dir = d.out.dir;
        e->ab = d.e.ab;
    }
    r->ticks++;
}

static void finish(run_rec_t *r)
{
    uint32_t nedge = 0;
    unsigned i;
    /* every event the generators emitted reached a decoder (sim_edges
     * counts them from the generators) */
    for (i = 0; i < AXES; i++) {
        nedge += drive_test_encoder(i)->e.nedge;
    }
    TEST_ASSERT_EQUAL_UINT32(nedge, (uint32_t)sim_edges());
    r->edges = sim_edges();
    r->run_edges = sim_run_edges();
    r->mismatches = sim_edge_mismatches();
}

static int eager; /* sim_test_eager_inputs of the next start */

static void start(int model)
{
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, AXES));
    TEST_ASSERT_EQUAL_INT(0, sim_encoder_model(model));
    sim_test_eager_inputs(eager); /* sim_setup turned it off */
}

/* The scenario of bench/bench_hil.c, 1.5 s; at tick switch_at the other
 * model takes over; rough: encoder reading noise (1 and 0.3 counts rms: the
 * reading goes back and forth within a tick) and Coulomb friction (ten
 * substeps per tick). */
static bool rough;
static bool ref_noise_x; /* reading noise on X's reference scale */
static bool field_noise; /* a 2-D field whose scale noise is 0 for y < 5 mm */

/* The option of circle() (option 1 to 9): each one that the plain loop
 * (sim.c run_plain) leaves to the general path. */
static void circle_option_before_start(void)
{
    static const double pos[2] = {-0.05, 0.05}, fwd[2] = {0.0, 2e-6}, rev[2] = {1e-6, 3e-6};
    switch (option) {
    case 1: /* a spring on X's table: a disturbance, load torque per tick */
        TEST_ASSERT_EQUAL_INT(0, sim_axis_set(0, "spring_k", 200.0));
        break;
    case 2: /* a load torque on Y: not linear only */
        TEST_ASSERT_EQUAL_INT(0, sim_axis_set(1, "load_torque", 0.005));
        break;
    case 3: /* a pitch map on X */
        TEST_ASSERT_EQUAL_INT(0, sim_axis_pitch(0, 2, pos, fwd, rev));
        break;
    case 4: /* reading noise on Y's encoder, one substep */
        TEST_ASSERT_EQUAL_INT(0, sim_axis_set(1, "enc_noise_counts", 0.3));
        break;
    case 5: /* reading noise on X's reference scale: drawn per tick */
        TEST_ASSERT_EQUAL_INT(0, sim_axis_set(0, "ref_noise", 20e-9));
        break;
    case 6: /* the trace's table as its mean over the tick */
        TEST_ASSERT_EQUAL_INT(0, sim_trace_table_mean(1));
        break;
    case 7: { /* a 2-D field, no noise */
        static const double col[16] = {1e-6, 0,    0,    1e-6, 1e-6, 0,    0,    1e-6,
                                       0,    1e-6, 1e-6, 0,    0,    1e-6, 1e-6, 0};
        static const double sig[8] = {0}, row[8] = {0};
        TEST_ASSERT_EQUAL_INT(
            0, sim_field2d(2, 2, -0.04, 0.04, -0.015, 0.04, col, sig, 2, -0.04, 0.04, row, 1e-6));
        break;
    }
    case 9: /* the instrument at 5 kHz: a sample every other substep */
        rec_hz = 5000.0;
        record = true;
        break;
    default: /* 8: sim_inject, after sim_start */
        break;
    }
}

static void circle(int model, run_rec_t *r, unsigned switch_at)
{
    const int64_t feed = 166666667; /* 10 m/min */
    int64_t on_circle[3] = {0, 5000000, 0};
    int res = 0;
    unsigned k;

    memset(r, 0, sizeof *r);
    start(model);
    sim_gain_set(0, "kvff", 16.49);
    sim_gain_set(1, "kvff", 16.49);
    sim_gain_set(0, "kaff", 0.1247);
    sim_gain_set(1, "kaff", 0.1078);
    /* default.toml's CEC gains: the servo's defaults limit-cycle at 10 kHz
     * and fault (oscillation) 0.15 s in, after which the drive stands still */
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "kp", 2000.0));
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "ki", 2e5));
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "kd", 2.0));
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "d_tau", 1e-3));
    sim_cec_mode(DRIVE_CEC_EXACT);
    if (rough) {
        TEST_ASSERT_EQUAL_INT(0, sim_axis_set(0, "enc_noise_counts", 1.0));
        TEST_ASSERT_EQUAL_INT(0, sim_axis_set(1, "enc_noise_counts", 0.3));
        TEST_ASSERT_EQUAL_INT(0, sim_axis_set(0, "coulomb_motor", 0.01));
        TEST_ASSERT_EQUAL_INT(0, sim_axis_set(1, "coulomb_table", 10.0));
    }
    if (ref_noise_x) {
        TEST_ASSERT_EQUAL_INT(0, sim_axis_set(0, "ref_noise", 20e-9));
    }
    if (field_noise) {
        /* 2 x 2 grid over the circle, errors of 1 um, rms noise 0 below
         * the centre line and up to 30 nm above it, on both scales */
        static const double col[16] = {1e-6, 0,    0,    1e-6, 1e-6, 0,    0,    1e-6,
                                       0,    1e-6, 1e-6, 0,    0,    1e-6, 1e-6, 0};
        static const double sig[8] = {-30e-9, -30e-9, 30e-9, 30e-9, -30e-9, -30e-9, 30e-9, 30e-9};
        static const double row[8] = {0};
        TEST_ASSERT_EQUAL_INT(
            0, sim_field2d(2, 2, -0.04, 0.04, -0.015, 0.04, col, sig, 2, -0.04, 0.04, row, 1e-6));
    }
    circle_option_before_start();
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_EQUAL_INT(rough ? 10u : 1u, sim_substeps());
    if (mean_on) {
        TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_ENC_MEAN, 0, 1));
    }
    if (option == 8) { /* a voltage injected on X for 0.5 s from the start */
        static double volts[5000];
        for (k = 0; k < 5000u; k++) {
            volts[k] = 0.2 * sin((double)k * 0.01);
        }
        TEST_ASSERT_EQUAL_INT(0, sim_inject(0, volts, 5000u));
    }
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, sim_enable(1));
    TEST_ASSERT_EQUAL_INT(0, sim_queue_line(on_circle, feed, 1, 0, &res));
    for (k = 0; k < 15000u; k++) {
        while (sim_queue_arc(on_circle, feed, 0, -20000000, 5000000, 1, 2, &res) == 0) {
        }
        if (k == switch_at) {
            TEST_ASSERT_EQUAL_INT(0, sim_encoder_model(SIM_ENC_EDGES + SIM_ENC_FAST - model));
        }
        tick(r);
    }
    finish(r);
    /* the whole run on the circle: no fault, still running */
    {
        sim_status_t st;
        TEST_ASSERT_EQUAL_INT(0, sim_drive_status(&st));
        TEST_ASSERT_EQUAL_HEX32(0u, st.faults);
        TEST_ASSERT_EQUAL_INT(DRIVE_RUNNING, st.state);
    }
}

/* Max |radial error| of the table (trace columns 5, 9) about the circle's
 * centre (-20, 5) mm over the last second, and the CEC estimate's max. */
static void circle_figures(const run_rec_t *r, double *table_um, double *cec_um)
{
    unsigned k;
    *table_um = 0.0;
    *cec_um = 0.0;
    for (k = r->ticks - 10000u; k < r->ticks; k++) {
        double e = hypot(r->trace[k][5] + 0.020, r->trace[k][9] - 0.005) - 0.020;
        *table_um = fmax(*table_um, fabs(e) * 1e6);
        *cec_um = fmax(*cec_um, fabs(r->trace[k][3]) * 1e6);
    }
}

static void check_same(const run_rec_t *a, const run_rec_t *b)
{
    unsigned k, i;
    TEST_ASSERT_EQUAL_UINT(a->ticks, b->ticks);
    TEST_ASSERT_EQUAL_UINT64(0, a->mismatches);
    TEST_ASSERT_EQUAL_UINT64(0, b->mismatches);
    TEST_ASSERT_EQUAL_UINT64(a->edges, b->edges);
    for (k = 0; k < a->ticks; k++) {
        for (i = 0; i < AXES; i++) {
            const enc_rec_t *x = &a->enc[k][i], *y = &b->enc[k][i];
            TEST_ASSERT_EQUAL_INT64(x->pos, y->pos);
            TEST_ASSERT_EQUAL_UINT32(x->count, y->count);
            TEST_ASSERT_EQUAL_UINT32(x->nedge, y->nedge);
            TEST_ASSERT_EQUAL_UINT32(x->t_last, y->t_last);
            TEST_ASSERT_EQUAL_INT8(x->dir, y->dir);
            TEST_ASSERT_EQUAL_UINT8(x->ab, y->ab);
            TEST_ASSERT_EQUAL_INT64(x->vel, y->vel);
            TEST_ASSERT_EQUAL_UINT32(x->index_events, y->index_events);
            TEST_ASSERT_EQUAL_INT64(x->index_pos, y->index_pos);
            TEST_ASSERT_EQUAL_INT64(x->refscale, y->refscale);
        }
        TEST_ASSERT_EQUAL_INT(0, memcmp(a->trace[k], b->trace[k], sizeof a->trace[k]));
        TEST_ASSERT_EQUAL_INT(0, memcmp(a->tab[k], b->tab[k], sizeof a->tab[k]));
    }
}

static void test_circle_same_in_both_models(void)
{
    double ta, ca, tb, cb;

    rough = false;
    circle(SIM_ENC_EDGES, &rec[0], MAX_TICKS);
    circle(SIM_ENC_FAST, &rec[1], MAX_TICKS);
    /* the runs did the work (the rest: substeps through the index) */
    TEST_ASSERT_EQUAL_UINT64(0, rec[0].run_edges);
    TEST_ASSERT_TRUE(rec[1].run_edges > rec[1].edges * 9u / 10u);
    TEST_ASSERT_TRUE(rec[0].edges > 100000u);
    check_same(&rec[0], &rec[1]);
    circle_figures(&rec[0], &ta, &ca);
    circle_figures(&rec[1], &tb, &cb);
    TEST_ASSERT_TRUE(ta > 1.0 && ca > 1.0); /* um: figures that can differ */
    TEST_ASSERT_EQUAL_DOUBLE(ta, tb);
    TEST_ASSERT_EQUAL_DOUBLE(ca, cb);
}

static void test_rough_circle_same_in_both_models(void)
{
    rough = true;
    circle(SIM_ENC_EDGES, &rec[0], MAX_TICKS);
    circle(SIM_ENC_FAST, &rec[1], MAX_TICKS);
    rough = false;
    TEST_ASSERT_TRUE(rec[1].run_edges > rec[1].edges / 2u);
    check_same(&rec[0], &rec[1]);
}

/* Homing of X to the index (switch at -21.3 mm, index at -20 mm, the
 * sequence of test_home.c), then a move back: the index window goes edge
 * by edge, the rest in runs. */
static void homing(int model, run_rec_t *r)
{
    drive_home_t h = {0};
    drive_status_t st;
    int64_t t[3] = {5000000, 0, 0};
    int res = 0;
    unsigned k;

    memset(r, 0, sizeof *r);
    start(model);
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, sim_enable(1));
    for (k = 0; k < 10u; k++) {
        tick(r);
    }
    h.axes = 1u;
    h.negative = 1u;
    h.index = 1u;
    h.search_nm_s = 20000000;
    h.latch_nm_s = 2000000;
    h.max_dist_nm = 100000000;
    h.home_pos[0] = -21000000;
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_home(&h));
    for (k = 0; k < 35000u; k++) {
        tick(r);
        drive_status(&st);
        if (st.state == DRIVE_IDLE && st.homed == 1u) {
            break;
        }
    }
    TEST_ASSERT_EQUAL_UINT32(1u, st.homed);
    TEST_ASSERT_EQUAL_INT(0, sim_queue_line(t, 20000000, 7, 1, &res));
    for (k = 0; k < 2500u; k++) {
        tick(r);
    }
    finish(r);
    /* the whole run on the circle: no fault, still running */
    {
        sim_status_t st;
        TEST_ASSERT_EQUAL_INT(0, sim_drive_status(&st));
        TEST_ASSERT_EQUAL_HEX32(0u, st.faults);
        TEST_ASSERT_EQUAL_INT(DRIVE_RUNNING, st.state);
    }
}

static void test_homing_to_index_same_in_both_models(void)
{
    homing(SIM_ENC_EDGES, &rec[0]);
    homing(SIM_ENC_FAST, &rec[1]);
    TEST_ASSERT_TRUE(rec[0].enc[rec[0].ticks - 1u][0].index_events > 0u);
    TEST_ASSERT_TRUE(rec[1].run_edges > 0u && rec[1].run_edges < rec[1].edges);
    check_same(&rec[0], &rec[1]);
}

/* Switching the model on a running simulator takes effect at once and
 * keeps the decoders exact; unknown models are refused. */
static void test_model_switch_while_running(void)
{
    rough = false;
    circle(SIM_ENC_EDGES, &rec[0], MAX_TICKS);
    circle(SIM_ENC_FAST, &rec[1], 7000u);
    TEST_ASSERT_EQUAL_INT(SIM_ENC_EDGES, sim_encoder_model_get());
    TEST_ASSERT_TRUE(rec[1].run_edges > 0u && rec[1].run_edges < rec[1].edges / 2u);
    check_same(&rec[0], &rec[1]);
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_encoder_model(2));
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_encoder_model(-1));
    TEST_ASSERT_EQUAL_INT(SIM_ENC_EDGES, sim_encoder_model_get());
}

/* The plant's tick with one substep, every axis stepped first and the
 * generators moved after (sim.c plant_tick1), against the general loop
 * axis by axis (sim_test_plant_split(0)): the bench circle with the fast
 * model, decoders and trace identical on every tick. */
static void test_plant_split_same_as_axis_by_axis(void)
{
    sim_test_plant_split(0);
    circle(SIM_ENC_FAST, &rec[0], ~0u);
    sim_test_plant_split(1);
    circle(SIM_ENC_FAST, &rec[1], ~0u);
    check_same(&rec[0], &rec[1]);
}

/* The plain loop (sim.c run_plain: no tests for the options that are
 * off) against the split plant with those tests (sim_test_plain(0)) and
 * against the general loop axis by axis (sim_test_plant_split(0)): the
 * bench circle with the instrument recording every tick, then again with
 * the drive's mean reading on (enc_mean, which the plain loop still tests
 * on every tick). Decoders, trace and instrument identical on every tick. */
static void test_plain_loop_same_as_general(void)
{
    unsigned m;
    record = true;
    for (m = 0; m < 2u; m++) {
        mean_on = m == 1u;
        circle(SIM_ENC_FAST, &rec[0], ~0u);
        /* recorded: a tick's sample is the next row's table, bit for bit */
        TEST_ASSERT_EQUAL_DOUBLE(rec[0].trace[14999][0], rec[0].tab[14998][0]);
        TEST_ASSERT_TRUE(memcmp(&rec[0].trace[14999][9], &rec[0].tab[14998][2], 8) == 0);
        sim_test_plain(0);
        circle(SIM_ENC_FAST, &rec[1], ~0u);
        sim_test_plain(1);
        check_same(&rec[0], &rec[1]);
        sim_test_plant_split(0);
        circle(SIM_ENC_FAST, &rec[1], ~0u);
        sim_test_plant_split(1);
        check_same(&rec[0], &rec[1]);
    }
    mean_on = false;
    record = false;
}

/* The plain loop with fewer axes than SIM_AXES (its loops are unrolled
 * to SIM_AXES): one and two axes on a line, the trace, the instrument and
 * the edge count the general path's (sim_test_plain(0)). */
static unsigned few_axes_job(unsigned axes, bool plain, double (*trace)[SIM_TRACE_COLS],
                             double (*tab)[SIM_REC_COLS])
{
    int64_t t[3] = {3000000, -2000000, 0};
    int res = 0;
    unsigned k;

    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, axes));
    sim_test_plain(plain);
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, sim_enable(1));
    TEST_ASSERT_EQUAL_INT(0, sim_queue_line(t, 50000000, 3, 1, &res));
    for (k = 0; k < 3000u; k++) {
        TEST_ASSERT_EQUAL_INT(0, sim_table_record(tab[k], 1, 1e4));
        TEST_ASSERT_EQUAL_INT(1, sim_run(1, trace[k], 1, 1));
    }
    sim_test_plain(1);
    TEST_ASSERT_EQUAL_UINT64(0, sim_edge_mismatches());
    return (unsigned)sim_edges();
}

static void test_plain_loop_with_fewer_axes(void)
{
    unsigned axes;
    for (axes = 1; axes < SIM_AXES; axes++) {
        const unsigned n = 3000u; /* ticks */
        unsigned edges = few_axes_job(axes, true, rec[0].trace, rec[0].tab);
        TEST_ASSERT_EQUAL_UINT(edges, few_axes_job(axes, false, rec[1].trace, rec[1].tab));
        TEST_ASSERT_TRUE(edges > 1000u); /* it moved */
        TEST_ASSERT_EQUAL_INT(0, memcmp(rec[0].trace, rec[1].trace, sizeof rec[0].trace[0] * n));
        TEST_ASSERT_EQUAL_INT(0, memcmp(rec[0].tab, rec[1].tab, sizeof rec[0].tab[0] * n));
    }
}

/* Each option that the plain loop leaves to the general path (sim.c
 * run_plain: load torque, disturbance, pitch map, encoder or scale
 * reading noise, table mean, 2-D field, injection, the instrument at a
 * sample every other substep) changes the circle's trace, and the run is
 * the same with the plain loop allowed (the default) and not allowed
 * (sim_test_plain(0)). */
static bool runs_differ(const run_rec_t *a, const run_rec_t *b)
{
    return a->ticks != b->ticks || memcmp(a->enc, b->enc, sizeof a->enc[0] * a->ticks) != 0 ||
           memcmp(a->trace, b->trace, sizeof a->trace[0] * a->ticks) != 0 ||
           memcmp(a->tab, b->tab, sizeof a->tab[0] * a->ticks) != 0;
}

static void test_plain_loop_leaves_options_to_the_general_path(void)
{
    static run_rec_t none; /* no option */
    record = true;
    circle(SIM_ENC_FAST, &none, ~0u);
    for (option = 1; option <= 9; option++) {
        record = true;
        circle(SIM_ENC_FAST, &rec[0], ~0u);
        TEST_ASSERT_TRUE(runs_differ(&none, &rec[0]));
        record = true;
        sim_test_plain(0);
        circle(SIM_ENC_FAST, &rec[1], ~0u);
        sim_test_plain(1);
        check_same(&rec[0], &rec[1]);
        rec_hz = 0.0;
    }
    option = 0;
}

/* A refused setting (SIM_E_ARG) changes nothing: a running simulator runs
 * on (the refusal stopped it: sim_run SIM_E_STATE until sim_start), and a
 * refused CEC straight-path gain does not turn the gain switching on. A
 * setting taken still needs sim_start. */
static void test_refused_setting_changes_nothing(void)
{
    static double row[SIM_TRACE_COLS];
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 2));
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_gain_set(-2, "kq", 1.0));
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_gain_set(-2, "kp", -1.0));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_FALSE(drive_config()->servo.cec.line_gains);
    TEST_ASSERT_EQUAL_INT(1, sim_run(1, row, 1, 1));
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_gain_set(0, "kp", -1.0));
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_servo_set(0, "qg_comp", 2.0));
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_plan_set(0, "v_max", 0.0));
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_axis_set(0, "home_side", 2.0));
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_axis_set(0, "lead", -1.0));
    TEST_ASSERT_EQUAL_INT(SIM_E_ARG, sim_axis_set(0, "no_such_field", 1.0));
    TEST_ASSERT_EQUAL_INT(1, sim_run(1, row, 1, 1));
    TEST_ASSERT_EQUAL_INT(0, sim_servo_set(0, "qg_comp", 1.0));
    TEST_ASSERT_EQUAL_INT(SIM_E_STATE, sim_run(1, row, 1, 1));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_TRUE(drive_config()->qg_comp);
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-2, "kp", 100.0));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_TRUE(drive_config()->servo.cec.line_gains);
}

/* The home switches and reference scales computed when the firmware reads
 * them (HAL sources, the default) against set at every tick's start
 * (sim_test_eager_inputs(1)): the homing (the switch ends the search), the
 * circle with reading noise on X's scale (X drawn every tick, Y and Z
 * read) and with a 2-D field whose noise is 0 on half the circle (drawn
 * on the ticks with noise only); decoders, the drive's reference-scale
 * positions and the trace identical on every tick. */
static void test_inputs_read_when_read_same_as_every_tick(void)
{
    unsigned k;
    bool moved = false;
    eager = 1;
    homing(SIM_ENC_FAST, &rec[0]);
    eager = 0;
    homing(SIM_ENC_FAST, &rec[1]);
    check_same(&rec[0], &rec[1]);
    rough = false;
    ref_noise_x = true;
    eager = 1;
    circle(SIM_ENC_FAST, &rec[0], ~0u);
    eager = 0;
    circle(SIM_ENC_FAST, &rec[1], ~0u);
    ref_noise_x = false;
    check_same(&rec[0], &rec[1]);
    field_noise = true;
    eager = 1;
    circle(SIM_ENC_FAST, &rec[0], ~0u);
    eager = 0;
    circle(SIM_ENC_FAST, &rec[1], ~0u);
    field_noise = false;
    TEST_ASSERT_EQUAL_INT(0, sim_field2d(0, 0, 0, 0, 0, 0, NULL, NULL, 0, 0, 0, NULL, 0));
    check_same(&rec[0], &rec[1]);
    /* the scales moved: the drive sampled them along the circle */
    for (k = 97u; k < rec[1].ticks; k += 97u) {
        moved = moved || rec[1].enc[k][1].refscale != rec[1].enc[0][1].refscale;
    }
    TEST_ASSERT_TRUE(moved);
}

/* A job run by sim_run_until_idle(stretch, 10) calls against sim_run(10)
 * and a status poll after each, the loop of contour sim circle: the same
 * ticks (a multiple of 10, past the end of the move), the same trace. */
static unsigned idle_job(bool one_call, double (*trace)[SIM_TRACE_COLS])
{
    int64_t t[3] = {30000000, -20000000, 0};
    int res = 0;
    unsigned ticks = 0;
    sim_status_t st;

    start(SIM_ENC_FAST);
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, sim_enable(1));
    TEST_ASSERT_EQUAL_INT(0, sim_queue_line(t, 100000000, 3, 1, &res));
    for (;;) {
        if (one_call) {
            uint64_t ran = 0;
            long n = sim_run_until_idle(1000u, 10u, trace[ticks], MAX_TICKS - ticks, 1, &ran);
            TEST_ASSERT_EQUAL_INT((long)ran, n);
            ticks += (unsigned)ran;
        } else {
            TEST_ASSERT_EQUAL_INT(10, sim_run(10u, trace[ticks], MAX_TICKS - ticks, 1));
            ticks += 10u;
        }
        TEST_ASSERT_EQUAL_INT(0, sim_drive_status(&st));
        if (st.faults != 0u || st.state == DRIVE_IDLE || ticks + 1000u > MAX_TICKS) {
            break;
        }
    }
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    return ticks;
}

static void test_run_until_idle_same_as_polling(void)
{
    unsigned a = idle_job(false, rec[0].trace), b = idle_job(true, rec[1].trace);
    TEST_ASSERT_EQUAL_UINT(a, b);
    TEST_ASSERT_EQUAL_UINT(0u, a % 10u);
    TEST_ASSERT_TRUE(a > 1000u); /* more than one call of 1000 ticks */
    TEST_ASSERT_EQUAL_INT(0, memcmp(rec[0].trace, rec[1].trace, sizeof rec[0].trace[0] * a));
}

static bool home_source_on(void *ctx, unsigned axis)
{
    (void)ctx;
    (void)axis;
    return true;
}

static uint32_t counter_source_7(void *ctx, unsigned ch)
{
    (void)ctx;
    (void)ch;
    return 7u;
}

/* A value set on the simulated HAL after a source was installed is what the
 * firmware reads (the setter clears the source), for the counters and the
 * home switches alike: not ignored silently. */
static void test_hal_sim_set_after_a_source_is_read(void)
{
    uint32_t count = 0;

    hal_sim_reset();
    hal_sim_set_counter_source(1, counter_source_7, NULL);
    TEST_ASSERT_TRUE(hal_encoder_counter(1, &count));
    TEST_ASSERT_EQUAL_UINT32(7u, count);
    hal_sim_set_counter(1, 3u, true);
    TEST_ASSERT_TRUE(hal_encoder_counter(1, &count));
    TEST_ASSERT_EQUAL_UINT32(3u, count);
    hal_sim_set_home_source(home_source_on, NULL);
    TEST_ASSERT_TRUE(hal_home_switch(0));
    TEST_ASSERT_TRUE(hal_home_switch(1));
    hal_sim_set_home_switch(0, false);
    TEST_ASSERT_FALSE(hal_home_switch(0));
    TEST_ASSERT_FALSE(hal_home_switch(1)); /* its last value set: none */
    hal_sim_reset();
}

/* sim_setup turns sim_test_eager_inputs off: a test that leaves it on does
 * not change the next one. Seen before the first tick: with the sources
 * (the default) a home switch the table stands on reads on at once; set
 * eagerly, it reads off until the first tick sets it. */
static void test_sim_setup_turns_eager_inputs_off(void)
{
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, AXES));
    sim_test_eager_inputs(1);
    TEST_ASSERT_EQUAL_INT(0, sim_axis_set(0, "home_switch", 0.001));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_FALSE(hal_home_switch(0));
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, AXES)); /* the next test's */
    TEST_ASSERT_EQUAL_INT(0, sim_axis_set(0, "home_switch", 0.001));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_TRUE(hal_home_switch(0));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_circle_same_in_both_models);
    RUN_TEST(test_rough_circle_same_in_both_models);
    RUN_TEST(test_homing_to_index_same_in_both_models);
    RUN_TEST(test_model_switch_while_running);
    RUN_TEST(test_plant_split_same_as_axis_by_axis);
    RUN_TEST(test_plain_loop_same_as_general);
    RUN_TEST(test_plain_loop_leaves_options_to_the_general_path);
    RUN_TEST(test_plain_loop_with_fewer_axes);
    RUN_TEST(test_refused_setting_changes_nothing);
    RUN_TEST(test_inputs_read_when_read_same_as_every_tick);
    RUN_TEST(test_run_until_idle_same_as_polling);
    RUN_TEST(test_hal_sim_set_after_a_source_is_read);
    RUN_TEST(test_sim_setup_turns_eager_inputs_off);
    return UNITY_END();
}
