/* Axis model: eigenvalues against the spec, exactness of the ZOH
 * discretisation, voltage limit, friction, backlash, pitch map, determinism. */
#include "axis_model.h"
#include "unity.h"

#include <math.h>
#include <string.h>

void setUp(void)
{
}

void tearDown(void)
{
}

static void test_x_axis_eigenvalues_match_spec(void)
{
    axis_params_t p;
    double complex ev[AXIS_NSTATE];
    axis_params_lacerda(&p, false);
    axis_model_eigenvalues(&p, ev);
    /* sorted by real part: -1190, -149, -2.11 -/+ 4170j, 0 */
    TEST_ASSERT_DOUBLE_WITHIN(5.0, -1190.0, creal(ev[0]));
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0, cimag(ev[0]));
    TEST_ASSERT_DOUBLE_WITHIN(0.5, -149.0, creal(ev[1]));
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0, cimag(ev[1]));
    TEST_ASSERT_DOUBLE_WITHIN(0.01, -2.11, creal(ev[2]));
    TEST_ASSERT_DOUBLE_WITHIN(0.01, -2.11, creal(ev[3]));
    TEST_ASSERT_DOUBLE_WITHIN(5.0, -4170.0, cimag(ev[2]));
    TEST_ASSERT_DOUBLE_WITHIN(5.0, 4170.0, cimag(ev[3]));
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0, cabs(ev[4]));
}

static void test_y_axis_has_stiffer_table_mode(void)
{
    axis_params_t p;
    double complex ev[AXIS_NSTATE];
    axis_params_lacerda(&p, true);
    axis_model_eigenvalues(&p, ev);
    /* lighter table: sqrt(K (1/I1 + 1/I2)) = 5958 rad/s, plus the motor circuit */
    TEST_ASSERT_DOUBLE_WITHIN(10.0, 5960.0, cimag(ev[3]));
}

static void test_expm_of_rotation_generator(void)
{
    /* e^{[[0,w],[-w,0]] t} = [[cos, sin], [-sin, cos]] */
    const double m[4] = {0.0, 4170.0, -4170.0, 0.0};
    double e[4];
    axis_expm(2, m, 1e-3, e);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, cos(4.17), e[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, sin(4.17), e[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, -sin(4.17), e[2]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, cos(4.17), e[3]);
}

/* A machine file's encoder_lines = 1e19 or a huge lead is refused here,
 * before the drive's int64 count scale (sim.c) could overflow. */
static void test_init_refuses_an_encoder_or_lead_out_of_range(void)
{
    axis_params_t p;
    axis_t a;
    axis_params_lacerda(&p, false);
    p.enc_counts_per_rev = AXIS_ENC_COUNTS_MAX;
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-4));
    p.enc_counts_per_rev = 4e19;
    TEST_ASSERT_FALSE(axis_init(&a, &p, 1e-4));
    p.enc_counts_per_rev = 4000.0;
    p.l = 1e6;
    TEST_ASSERT_FALSE(axis_init(&a, &p, 1e-4));
}

/* One step of h*n equals n steps of h (exact discretisation). */
static void test_one_long_step_equals_many_short_steps(void)
{
    axis_params_t p;
    axis_t a, b;
    unsigned i, k;
    axis_params_lacerda(&p, false);
    TEST_ASSERT_TRUE(axis_init(&a, &p, 3e-3));
    TEST_ASSERT_TRUE(axis_init(&b, &p, 1e-4));
    for (k = 0; k < 20; k++) {
        double u = 2.0 * sin(0.7 * k);
        axis_substep(&a, u);
        for (i = 0; i < 30; i++) {
            axis_substep(&b, u);
        }
        for (i = 0; i < AXIS_NSTATE; i++) {
            double scale = fabs(a.z[i]) + 1e-6;
            TEST_ASSERT_DOUBLE_WITHIN(1e-8 * scale, a.z[i], b.z[i]);
        }
    }
}

/* Constant command: speed settles at kx u / kb, current at zero (no load). */
static void test_steady_speed_from_back_emf(void)
{
    axis_params_t p;
    axis_t a;
    unsigned k;
    axis_params_lacerda(&p, false);
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-4));
    for (k = 0; k < 60000; k++) {
        axis_substep(&a, 1.0);
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 16.0 / 0.21, a.z[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 16.0 / 0.21, a.z[3]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0, a.z[4]);
}

static void test_voltage_limit_clamps_command(void)
{
    axis_params_t p;
    axis_t a, b;
    unsigned k;
    axis_params_lacerda(&p, false);
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-4));
    TEST_ASSERT_TRUE(axis_init(&b, &p, 1e-4));
    for (k = 0; k < 100; k++) {
        axis_substep(&a, -50.0);
        axis_substep(&b, -10.0);
    }
    TEST_ASSERT_EQUAL_DOUBLE(b.z[1], a.z[1]);
    TEST_ASSERT_EQUAL_DOUBLE(-160.0, a.v_applied);
}

/* Coulomb friction holds the axis below breakaway and opposes motion above. */
static void test_coulomb_friction_sticks_and_slips(void)
{
    axis_params_t p;
    axis_t a;
    unsigned k;
    axis_params_lacerda(&p, false);
    p.coulomb_motor = 0.05; /* N m: breakaway current 0.25 A, 2.25 V */
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-5));
    for (k = 0; k < 200000; k++) {
        axis_substep(&a, 2.0 / 16.0);
    }
    /* at rest within 1 nm of travel after 2 s */
    TEST_ASSERT_DOUBLE_WITHIN(1e-9 / p.l, 0.0, a.z[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0, a.z[1]);
    for (k = 0; k < 100000; k++) {
        axis_substep(&a, 4.0 / 16.0);
    }
    /* slipping: steady speed where kt ia = Fc, (4 - Ra ia) / kb */
    TEST_ASSERT_DOUBLE_WITHIN(1e-2, (4.0 - 9.0 * 0.25) / 0.21, a.z[1]);
}

/* Reversing the motor moves the table only after the gap is taken up. */
static void test_backlash_lost_motion(void)
{
    axis_params_t p;
    axis_t a;
    double x_motor0, x_table0, x_motor1, x_table1;
    unsigned k;
    axis_params_lacerda(&p, false);
    p.backlash = 10e-6;
    p.coulomb_table = 20.0; /* the table stays where the screw leaves it */
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-5));
    for (k = 0; k < 20000; k++) {
        axis_substep(&a, k < 10000 ? 0.2 : 0.0);
    }
    x_motor0 = p.l * a.z[0];
    x_table0 = axis_table_pos(&a);
    TEST_ASSERT_TRUE(x_table0 > 1e-4);
    /* back off by less than the gap: the table does not move */
    for (k = 0; k < 2000; k++) {
        axis_substep(&a, k < 100 ? -0.1 : 0.0);
    }
    x_motor1 = p.l * a.z[0];
    x_table1 = axis_table_pos(&a);
    TEST_ASSERT_TRUE(x_motor0 - x_motor1 > 1e-6);
    TEST_ASSERT_TRUE(x_motor0 - x_motor1 < 9e-6);
    TEST_ASSERT_DOUBLE_WITHIN(5e-8, x_table0, x_table1);
}

static void test_pitch_map_per_direction(void)
{
    axis_params_t p;
    axis_t a;
    axis_params_lacerda(&p, false);
    p.pitch_n = 2;
    p.pitch_pos[0] = 0.0;
    p.pitch_pos[1] = 0.1;
    p.pitch_err_fwd[0] = 0.0;
    p.pitch_err_fwd[1] = 20e-6;
    p.pitch_err_rev[0] = 4e-6;
    p.pitch_err_rev[1] = 24e-6;
    p.pitch_dir_band = 1e-6;
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-4));
    axis_set_position(&a, 0.05);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.05 + 10e-6, axis_table_pos(&a));
    a.z[2] -= 2e-6 / p.l; /* move 2 um toward -x: beyond the band */
    axis_substep(&a, 0.0);
    TEST_ASSERT_EQUAL_INT(-1, a.pitch_dir);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, p.l * a.z[2] + 14e-6, axis_table_pos(&a));
    TEST_ASSERT_EQUAL_INT64((int64_t)floor(axis_table_pos(&a) / 1e-9 + 0.5), axis_ref_count(&a));
}

static void test_noise_is_deterministic_per_seed(void)
{
    axis_params_t p;
    axis_t a, b;
    unsigned k;
    int differ = 0;
    axis_params_lacerda(&p, false);
    p.enc_noise_counts = 0.3;
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-4));
    TEST_ASSERT_TRUE(axis_init(&b, &p, 1e-4));
    for (k = 0; k < 100; k++) {
        double ra = axis_encoder_reading(&a);
        TEST_ASSERT_EQUAL_DOUBLE(ra, axis_encoder_reading(&b));
        differ += ra != 0.0;
    }
    TEST_ASSERT_TRUE(differ > 90);
}

static void test_invalid_parameters_refused(void)
{
    axis_params_t p;
    axis_t a;
    axis_params_lacerda(&p, false);
    p.I2 = 0.0;
    TEST_ASSERT_FALSE(axis_init(&a, &p, 1e-4));
    axis_params_lacerda(&p, false);
    TEST_ASSERT_FALSE(axis_init(&a, &p, 0.0));
    p.pitch_n = 2; /* positions not increasing */
    TEST_ASSERT_FALSE(axis_init(&a, &p, 1e-4));
}

/* The substep's fast path (only u acting: the column-wise update) gives the
 * bits of the full update z <- Phi z + Gamma [u, T1, T2] summed row by row,
 * left to right; with a load torque (full update) too. */
static void ref_substep(const axis_t *a, double *z, double u, double t1)
{
    double in[3], nz[AXIS_NSTATE];
    unsigned i;
    in[0] = fmin(fmax(u * a->p.kx, -a->p.vmax), a->p.vmax) / a->p.kx;
    in[1] = t1;
    in[2] = 0.0;
    for (i = 0; i < AXIS_NSTATE; i++) {
        nz[i] = a->phi[i][0] * z[0] + a->phi[i][1] * z[1] + a->phi[i][2] * z[2] +
                a->phi[i][3] * z[3] + a->phi[i][4] * z[4] + a->gam[i][0] * in[0] +
                a->gam[i][1] * in[1] + a->gam[i][2] * in[2];
    }
    for (i = 0; i < AXIS_NSTATE; i++) {
        z[i] = nz[i];
    }
}

static void test_substep_fast_path_is_bit_exact(void)
{
    axis_params_t p;
    axis_t a;
    double z[AXIS_NSTATE];
    unsigned i, k, run;
    for (run = 0; run < 2; run++) {
        axis_params_lacerda(&p, run == 1);
        p.load_torque = run == 1 ? 0.013 : 0.0;
        TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-4));
        axis_set_position(&a, 0.0123);
        for (i = 0; i < AXIS_NSTATE; i++) {
            z[i] = a.z[i];
        }
        for (k = 0; k < 3000; k++) {
            /* beyond the clamp (+-10 V) now and then */
            double u = 12.0 * sin(0.013 * k) * cos(0.0021 * k);
            axis_substep(&a, u);
            ref_substep(&a, z, u, p.load_torque);
            for (i = 0; i < AXIS_NSTATE; i++) {
                TEST_ASSERT_TRUE(z[i] == a.z[i]);
            }
        }
        TEST_ASSERT_TRUE(fabs(a.z[1]) > 1.0); /* it moved */
    }
}

/* The load torque changed at run time (axis_set_load_torque, as the
 * simulator's disturbances do every tick): the substep follows the torque
 * of the moment, bit for bit against the full update, through changes
 * from 0 to a torque and back (axis_t.lin_only re-derived each time), also
 * from rest. */
static void test_load_torque_set_at_run_time(void)
{
    axis_params_t p;
    axis_t a;
    double z[AXIS_NSTATE];
    unsigned i, k;
    axis_params_lacerda(&p, false);
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-4));
    TEST_ASSERT_TRUE(a.lin_only);
    axis_set_position(&a, 0.0);
    for (i = 0; i < AXIS_NSTATE; i++) {
        z[i] = a.z[i];
    }
    for (k = 0; k < 3000; k++) {
        /* at rest (u = 0) until 500, then moving; the torque on in
         * stretches of 100 substeps, off again in between */
        double u = (k < 500) ? 0.0 : 3.0 * sin(0.007 * k);
        double t = ((k / 100u) % 2u == 1u) ? 0.02 * cos(0.003 * k) : 0.0;
        axis_set_load_torque(&a, t);
        TEST_ASSERT_TRUE(a.lin_only == (t == 0.0));
        axis_substep(&a, u);
        ref_substep(&a, z, u, t);
        for (i = 0; i < AXIS_NSTATE; i++) {
            TEST_ASSERT_TRUE(z[i] == a.z[i]);
        }
    }
    TEST_ASSERT_TRUE(fabs(a.z[1]) > 1.0); /* it moved */
}

/* The rest skip (axis_t.rest): an axis standing still with an unchanged
 * command is not updated. Against the same axis updated every substep (rest
 * cleared before each), bit for bit: z, v_applied, and the return value
 * (z unchanged); commands that break the rest (a tiny one, -0.0, a real
 * one) and a return to rest. */
static void test_rest_skip_is_bit_exact(void)
{
    axis_params_t p;
    axis_t a, b;
    double before[AXIS_NSTATE];
    unsigned k, skipped = 0, th1_still = 0;
    axis_params_lacerda(&p, false);
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-4));
    axis_set_position(&a, 0.0);
    b = a;
    for (k = 0; k < 4000; k++) {
        double u = 0.0;
        bool same;
        if (k >= 100 && k < 110) {
            u = 1e-300;
        } else if (k >= 200 && k < 205) {
            u = -0.0;
        } else if (k >= 300 && k < 400) {
            u = 0.5;
        }
        memcpy(before, a.z, sizeof before);
        skipped += a.rest && k != 100 && k != 200 && k != 300 && k != 400;
        same = axis_substep(&a, u);
        b.rest = false;
        (void)axis_substep(&b, u);
        TEST_ASSERT_EQUAL_MEMORY(b.z, a.z, sizeof a.z);
        TEST_ASSERT_EQUAL_MEMORY(&b.v_applied, &a.v_applied, sizeof a.v_applied);
        TEST_ASSERT_TRUE((memcmp(before, a.z, sizeof before) == 0) == same);
    }
    TEST_ASSERT_TRUE(skipped > 50);  /* the skip was taken */
    TEST_ASSERT_TRUE(a.z[0] != 0.0); /* and the 0.5 V moved the axis */
    /* th1 standing while the rest of z moves (a small current with the
     * axis far out: th1's change below its ulp): not at rest (lin_update
     * looks at th1 first, then at the rest) */
    axis_set_position(&a, 1e3);
    a.z[4] = 1e-9;
    for (k = 0; k < 50; k++) {
        bool same;
        memcpy(before, a.z, sizeof before);
        same = axis_substep(&a, 0.0);
        TEST_ASSERT_TRUE((memcmp(before, a.z, sizeof before) == 0) == same);
        th1_still += before[0] == a.z[0] && !same;
    }
    TEST_ASSERT_EQUAL_UINT(50, th1_still);
}

/* axis_floor_i64 against floor on integers, halves, the neighbours of
 * both (nextafter), -0.0, both ends of the conversion's range and beyond,
 * and random values of every magnitude; axis_ref_reading_at's memo against
 * the reading's formula on a sequence that stands still, moves by single
 * ulps and changes the resolution (fails when the memo ignores x's low
 * bits or the resolution). */
static void test_floor_and_ref_memo_exact(void)
{
    static const double edge[] = {0.0,
                                  -0.0,
                                  0.5,
                                  -0.5,
                                  1.0,
                                  -1.0,
                                  1.5,
                                  -1.5,
                                  2.5,
                                  -2.5,
                                  4503599627370496.0,
                                  -4503599627370496.0,
                                  9007199254740991.0,
                                  -9007199254740991.0,
                                  9007199254740992.0,
                                  -9007199254740992.0,
                                  9007199254740994.0,
                                  -9007199254740994.0,
                                  4.0e18,
                                  -4.0e18,
                                  1e-300,
                                  -1e-300};
    axis_params_t p;
    axis_t a;
    uint64_t s = 0x9E3779B97F4A7C15u;
    double x = 0.0123456789;
    unsigned i, k, hits = 0;

    for (i = 0; i < sizeof edge / sizeof edge[0]; i++) {
        double v[3] = {edge[i], nextafter(edge[i], INFINITY), nextafter(edge[i], -INFINITY)};
        for (k = 0; k < 3; k++) {
            TEST_ASSERT_EQUAL_INT64((int64_t)floor(v[k]), axis_floor_i64(v[k]));
        }
    }
    for (k = 0; k < 2000000u; k++) {
        double v;
        uint64_t b;
        s = s * 6364136223846793005u + 1442695040888963407u;
        b = s ^ (s >> 29);
        v = ldexp((double)(int64_t)b, -(int)(b % 70u)); /* |v| up to 2^63 */
        if (!(fabs(v) < 9.2e18)) {
            continue;
        }
        TEST_ASSERT_EQUAL_INT64((int64_t)floor(v), axis_floor_i64(v));
    }

    axis_params_lacerda(&p, false);
    TEST_ASSERT_TRUE(axis_init(&a, &p, 1e-4));
    for (k = 0; k < 30000u; k++) {
        int64_t want;
        unsigned sel = k % 7u;
        if (sel == 3u) {
            x = nextafter(x, 1.0); /* one ulp: the same reading, mostly */
        } else if (sel == 5u) {
            x += 7.3e-10 * (double)(k % 13u);
        }
        if (k % 5000u == 4999u) {
            a.p.ref_resolution *= (k % 10000u == 9999u) ? 0.5 : 3.0;
        }
        want = (int64_t)floor(x / a.p.ref_resolution + 0.5);
        hits += a.ref_memo && !(sel == 3u || sel == 5u);
        TEST_ASSERT_EQUAL_INT64(want, axis_ref_reading_at(&a, x));
        /* half a count away from a boundary: the low bits decide */
        {
            double c = (floor(x / a.p.ref_resolution) + 0.5) * a.p.ref_resolution;
            double n = nextafter(c, 0.0);
            TEST_ASSERT_EQUAL_INT64((int64_t)floor(c / a.p.ref_resolution + 0.5),
                                    axis_ref_reading_at(&a, c));
            TEST_ASSERT_EQUAL_INT64((int64_t)floor(n / a.p.ref_resolution + 0.5),
                                    axis_ref_reading_at(&a, n));
            TEST_ASSERT_EQUAL_INT64(want, axis_ref_reading_at(&a, x));
        }
    }
    TEST_ASSERT_TRUE(hits > 10000u);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_x_axis_eigenvalues_match_spec);
    RUN_TEST(test_y_axis_has_stiffer_table_mode);
    RUN_TEST(test_expm_of_rotation_generator);
    RUN_TEST(test_init_refuses_an_encoder_or_lead_out_of_range);
    RUN_TEST(test_one_long_step_equals_many_short_steps);
    RUN_TEST(test_steady_speed_from_back_emf);
    RUN_TEST(test_voltage_limit_clamps_command);
    RUN_TEST(test_coulomb_friction_sticks_and_slips);
    RUN_TEST(test_backlash_lost_motion);
    RUN_TEST(test_pitch_map_per_direction);
    RUN_TEST(test_noise_is_deterministic_per_seed);
    RUN_TEST(test_invalid_parameters_refused);
    RUN_TEST(test_substep_fast_path_is_bit_exact);
    RUN_TEST(test_load_torque_set_at_run_time);
    RUN_TEST(test_rest_skip_is_bit_exact);
    RUN_TEST(test_floor_and_ref_memo_exact);
    return UNITY_END();
}
