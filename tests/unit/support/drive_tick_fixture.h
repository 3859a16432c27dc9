/*
 * drive_tick_fixture.h - the drive ticked directly on the sim HAL (no plant),
 * shared by the drive unit tests that step the tick by hand
 * (test_drive_counter.c, test_drive_mean.c, test_drive_interp.c).
 *
 * Include once per test file: it defines the file's Unity setUp/tearDown
 * (a fresh sim HAL at t = 1 ms), the HAL clock `t_ns` and tick(), which
 * advances the clock by TICK_NS (10 kHz) and runs one drive_tick with the
 * calibration sampler fed as the application does.
 */
#ifndef DRIVE_TICK_FIXTURE_H
#define DRIVE_TICK_FIXTURE_H

#include <stdint.h>

#include "calib.h"
#include "drive.h"
#include "hal_sim.h"

#define TICK_NS 100000ull /* 10 kHz */

static uint64_t t_ns;

void setUp(void)
{
    hal_sim_reset();
    t_ns = 1000000;
    hal_sim_set_time_ns(t_ns);
}

void tearDown(void)
{
}

static void tick(void)
{
    const drive_tick_out_t *t;

    t_ns += TICK_NS;
    hal_sim_set_time_ns(t_ns);
    t = drive_tick(calib_sampling());
    if (t != NULL) {
        calib_tick(t->st, t->vel_ref);
    }
}

#endif /* DRIVE_TICK_FIXTURE_H */
