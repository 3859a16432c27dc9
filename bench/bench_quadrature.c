/*
 * Quadrature decoder figures.
 *   bench_quadrature edge N         N edge events (x4, no filter) for callgrind
 *   bench_quadrature sample N       N counter snapshots + velocity updates
 *   bench_quadrature sample_edge N  N edge-input samples (4 edges between each)
 *   bench_quadrature figures        velocity error / delay / noise table
 */
#include "qdec.h"
#include "qgen.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TS_NS 100000u

static qdec_t dec;

static void emit(void *ctx, uint32_t lines, uint32_t t_ns)
{
    qdec_edge(ctx, lines, t_ns);
}

static void run_edges(unsigned long n)
{
    static const uint32_t ab[4] = {0, 1, 3, 2};
    qdec_config_t c;
    unsigned long i;
    qdec_config_default(&c);
    qdec_init(&dec, &c, 0, 0);
    for (i = 0; i < n; i++) {
        /* forward, with a reversal every 64 edges */
        unsigned long p = (i & 64u) ? 64u - (i & 63u) : (i & 63u) + 1u;
        qdec_edge(&dec, ab[p & 3u], (uint32_t)(i * 250u));
    }
}

static void run_samples(unsigned long n)
{
    qdec_config_t c;
    unsigned long i;
    uint32_t raw = 0;
    qdec_config_default(&c);
    c.input = QDEC_INPUT_COUNTER;
    c.counter_bits = 16;
    c.nm_per_count_num = 5000000;
    c.nm_per_count_den = 4096;
    qdec_init(&dec, &c, 0, 0);
    for (i = 0; i < n; i++) {
        raw += 37u + (uint32_t)(i & 3u); /* ~ 3.8e5 counts/s at 10 kHz */
        qdec_sample_counter(&dec, raw & 0xFFFFu, (uint32_t)((i + 1) * TS_NS));
    }
}

static void run_edge_samples(unsigned long n)
{
    static const uint32_t ab[4] = {0, 1, 3, 2};
    qdec_config_t c;
    unsigned long i, k, p = 0;
    qdec_config_default(&c);
    qdec_init(&dec, &c, 0, 0);
    for (i = 0; i < n; i++) {
        for (k = 0; k < 4; k++) {
            p++;
            qdec_edge(&dec, ab[p & 3u], (uint32_t)(i * TS_NS + k * 20000u));
        }
        qdec_sample(&dec, (uint32_t)((i + 1) * TS_NS));
    }
}

/* Constant velocity v (counts/s), optional acceleration a (counts/s^2) and
 * edge offsets; returns worst |error| (and rms) after the start-up, in
 * counts/s, comparing against the true velocity at the sample time. */
typedef struct {
    double worst, rms, mean;
} stat_t;

static stat_t run_vel(double v, double a, bool counter, uint64_t window_ns, bool cycle,
                      const qgen_pos_t *off)
{
    qgen_t g;
    qdec_config_t c;
    double av = fabs(v), ts = TS_NS * 1e-9;
    double dur = fmax(8.0 / av, 0.2), start = 6.0 / av + 0.01 + (double)window_ns * 1e-9;
    uint64_t t0 = 1000, k, n, cnt = 0;
    double sum2 = 0, sum = 0;
    stat_t s = {0, 0, 0};

    qdec_config_default(&c);
    if (counter) {
        c.input = QDEC_INPUT_COUNTER;
        c.counter_bits = 16;
    }
    c.vel_window_ns = window_ns;
    c.vel_cycle = cycle;
    qgen_init(&g, QGEN_ONE / 2, t0, counter ? NULL : emit, &dec);
    if (off != NULL) {
        qgen_set_edge_offsets(&g, off);
    }
    qdec_init(&dec, &c, counter ? (uint32_t)g.count : qgen_lines(&g), (uint32_t)t0);
    n = (uint64_t)(dur / ts);
    for (k = 1; k <= n; k++) {
        double tt = (double)k * ts, x = v * tt + 0.5 * a * tt * tt, err;
        uint64_t t = t0 + k * TS_NS;
        qgen_move_to(&g, QGEN_ONE / 2 + (qgen_pos_t)llround(x * (double)QGEN_ONE), t);
        if (counter) {
            qdec_sample_counter(&dec, (uint32_t)(g.count & 0xFFFF), (uint32_t)t);
        } else {
            qdec_sample(&dec, (uint32_t)t);
        }
        if (tt < start) {
            continue;
        }
        err = (double)qdec_velocity(&dec) / 4294967296.0 - (v + a * tt);
        sum += err;
        sum2 += err * err;
        cnt++;
        if (fabs(err) > s.worst) {
            s.worst = fabs(err);
        }
    }
    s.rms = sqrt(sum2 / (double)cnt);
    s.mean = sum / (double)cnt;
    return s;
}

static void figures(void)
{
    static const double speeds[] = {0.1,    0.37, 1,     4.1,   10,    33.3, 100,   271, 1e3,
                                    3333.3, 9999, 10001, 15000, 33333, 1e5,  3.7e5, 1e6};
    const qgen_pos_t off[4] = {0, QGEN_ONE / 10, -QGEN_ONE / 10, QGEN_ONE / 20};
    double worst_rel = 0, worst_rel_cnt = 0;
    unsigned i;
    stat_t s;

    printf("quadrature_counter16_max_delta: %u counts/sample\n", QDEC_MAX_DELTA(16));
    printf("quadrature_counter16_max_rate_10khz: %llu counts/s\n",
           (unsigned long long)QDEC_MAX_DELTA(16) * 10000ull);
    printf("quadrature_velocity_q32_resolution: %.3g counts/s\n", 1.0 / 4294967296.0);
    for (i = 0; i < sizeof(speeds) / sizeof(speeds[0]); i++) {
        stat_t e = run_vel(speeds[i], 0, false, 0, false, NULL);
        stat_t cn = run_vel(speeds[i], 0, true, 0, false, NULL);
        if (e.worst / speeds[i] > worst_rel) {
            worst_rel = e.worst / speeds[i];
        }
        if (cn.worst / speeds[i] > worst_rel_cnt) {
            worst_rel_cnt = cn.worst / speeds[i];
        }
    }
    printf("quadrature_vel_edge_worst_rel_error_0.1_to_1e6: %.3g ppm\n", worst_rel * 1e6);
    s = run_vel(0.1, 0, false, 0, false, NULL);
    printf("quadrature_vel_edge_error_at_0.1cps: %.3g counts/s\n", s.worst);
    s = run_vel(1.2345e6, 0, false, 0, false, NULL);
    printf("quadrature_vel_edge_error_at_1.2345e6cps: %.3g counts/s\n", s.worst);
    s = run_vel(1.2345e5, 0, true, 0, false, NULL);
    printf("quadrature_vel_counter_1tick_error_at_1.2345e5cps: %.4g counts/s\n", s.worst);
    s = run_vel(1.2345e5, 0, true, 1000000, false, NULL);
    printf("quadrature_vel_counter_1ms_error_at_1.2345e5cps: %.4g counts/s\n", s.worst);
    s = run_vel(123.4, 0, true, 0, false, NULL);
    printf("quadrature_vel_counter_1tick_error_at_123.4cps: %.4g counts/s\n", s.worst);
    /* edge placement error +-0.1 count: noise of the default and cycle modes */
    s = run_vel(1.2345e5, 0, false, 0, false, off);
    printf("quadrature_vel_noise_phase_err_0.1_at_1.2345e5cps: %.4g counts/s rms\n", s.rms);
    s = run_vel(1.2345e5, 0, false, 0, true, off);
    printf("quadrature_vel_noise_phase_err_0.1_cycle_at_1.2345e5cps: %.4g counts/s rms\n", s.rms);
    s = run_vel(1234.5, 0, false, 0, false, off);
    printf("quadrature_vel_noise_phase_err_0.1_at_1234.5cps: %.4g counts/s rms\n", s.rms);
    s = run_vel(1234.5, 0, false, 0, true, off);
    printf("quadrature_vel_noise_phase_err_0.1_cycle_at_1234.5cps: %.4g counts/s rms\n", s.rms);
    /* delay: mean error under constant acceleration / acceleration */
    s = run_vel(2e5, 1e7, false, 0, false, NULL);
    printf("quadrature_vel_delay_edge_at_2e5cps: %.1f us\n", -s.mean / 1e7 * 1e6);
    s = run_vel(2e3, 1e5, false, 0, false, NULL);
    printf("quadrature_vel_delay_edge_at_2e3cps: %.1f us\n", -s.mean / 1e5 * 1e6);
    s = run_vel(2e5, 1e7, true, 0, false, NULL);
    printf("quadrature_vel_delay_counter_1tick_at_2e5cps: %.1f us\n", -s.mean / 1e7 * 1e6);
    s = run_vel(2e5, 1e7, true, 1000000, false, NULL);
    printf("quadrature_vel_delay_counter_1ms_at_2e5cps: %.1f us\n", -s.mean / 1e7 * 1e6);
}

int main(int argc, char **argv)
{
    unsigned long n = (argc > 2) ? strtoul(argv[2], NULL, 10) : 1000;
    const char *what = (argc > 1) ? argv[1] : "figures";

    if (!strcmp(what, "edge")) {
        run_edges(n);
    } else if (!strcmp(what, "sample")) {
        run_samples(n);
    } else if (!strcmp(what, "sample_edge")) {
        run_edge_samples(n);
    } else {
        figures();
    }
    return 0;
}
