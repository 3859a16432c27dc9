/*
 * bench_hil.c - realtime factor of the HIL simulator: simulated seconds per
 * wall-clock second, three axes at 10 kHz, the circle scenario (R 20 mm at
 * 10 m/min, full feed-forward, exact CEC, trace of every tick written).
 * Best of three runs of 20 simulated seconds.
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>

#include "drive.h"
#include "sim.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double one_run(double sim_s)
{
    static double row[4000 * SIM_TRACE_COLS];
    const int64_t feed = 166666667; /* 10 m/min */
    int64_t on_circle[3] = {0, 5000000, 0};
    double t0, t1;
    int r = 0;
    uint64_t ticks = (uint64_t)(sim_s * 10000.0), done = 0;

    sim_setup(10000.0, 3);
    sim_gain_set(0, "kvff", 16.49);
    sim_gain_set(1, "kvff", 16.49);
    sim_gain_set(0, "kaff", 0.1247);
    sim_gain_set(1, "kaff", 0.1078);
    sim_cec_mode(DRIVE_CEC_EXACT);
    if (sim_start() != 0 || sim_enable(1) != 0) {
        return -1.0;
    }
    t0 = now();
    sim_queue_line(on_circle, feed, 1, 0, &r);
    while (done < ticks) {
        /* keep full circles queued */
        while (sim_queue_arc(on_circle, feed, 0, -20000000, 5000000, 1, 2, &r) == 0) {
        }
        sim_run(4000, row, 4000, 1);
        done += 4000;
    }
    t1 = now();
    if (sim_edge_mismatches() != 0) {
        return -1.0;
    }
    return (double)done / 10000.0 / (t1 - t0);
}

int main(void)
{
    double best = 0.0;
    int i;
    for (i = 0; i < 3; i++) {
        double f = one_run(20.0);
        if (f < 0) {
            fprintf(stderr, "bench_hil: simulator failed\n");
            return 1;
        }
        if (f > best) {
            best = f;
        }
    }
    printf("hil_realtime_factor: %.0f x\n", best);
    return 0;
}
