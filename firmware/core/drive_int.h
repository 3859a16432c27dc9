/*
 * drive_int.h - interfaces between the drive's own modules (drive.c, the
 * state machine, and drive_param.c, the parameter table); not for other
 * subsystems.
 */
#ifndef DRIVE_INT_H
#define DRIVE_INT_H

#include <stdbool.h>

#include "drive.h"

/* drive_init succeeded. Any. */
bool drive_ready(void);

/* Take the motion fields of c (plan, stop_decel_nm_s2, arc_chord_nm,
 * start_delay_ms, soft limits, in-position window, the feed-forward
 * corrections ff_advance_ns, friction_ff_mv, friction_ff_band_nm_s,
 * qg_comp (drive_ff.h); the others are ignored) if plan_check_profile accepts the
 * profile (else DRIVE_E_INVALID) and the planner is idle: nothing queued,
 * executing or stopping (else DRIVE_E_BUSY); the empty planner is then
 * re-initialised at its position. All or nothing. Main. */
drive_result_t drive_apply_config(const drive_config_t *c);

/* servo_init on a probe in the scratch area (scratch.h): DRIVE_OK when q
 * is a valid servo configuration, DRIVE_E_INVALID when not, DRIVE_E_BUSY
 * when the area is held. Main. */
drive_result_t drive_servo_probe(const servo_params_t *q);

#endif /* DRIVE_INT_H */
