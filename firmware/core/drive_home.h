/*
 * drive_home.h - the homing sequence of the drive's axes (tick context).
 *
 * Specification
 * -------------
 * Every axis of the request's mask runs, at the same time and independently,
 * the machine-tool sequence:
 *   SEARCH   toward the switch (dir) at search_nm_s until hal_home_switch
 *            is active, then decelerate to rest (the switch is a region:
 *            it stays active). Already on the switch: straight to BACKOFF.
 *   BACKOFF  away from the switch at latch_nm_s until it releases (the
 *            switch edge).
 *   INDEX    on at latch_nm_s, in the same direction, to the next encoder
 *            index the decoder latches after the edge (qdec out.index_*);
 *            an axis not in index_mask takes the measured position at the
 *            switch edge instead.
 *   STOP     decelerate to rest; then the axis's frame is rebased so that
 *            the reference point (index or edge) reads home_pos_nm: the
 *            decoder's offset (qdec_set_offset_nm), this tick's feedback,
 *            the servo (servo_rebase) and the reference all move by the
 *            same amount in the same tick, so the loop sees no step.
 * Velocity changes are ramps of the axis's planner a_max. An axis that
 * travels more than max_dist_nm in SEARCH (switch not found), or in BACKOFF
 * + INDEX (switch never released, no index) makes home_tick return
 * HOME_FAULT (the drive latches DRIVE_FAULT_HOMING). home_abort (a stop
 * request) ramps every axis to rest; home_tick then returns HOME_ABORTED.
 * Axes outside the mask hold their reference. With a compensation table
 * the rebase shifts the raw position (the table is read at the new one).
 *
 * Contexts: every function runs in the tick (the drive's apply_requests and
 * drive_tick); the request payload is main's, copied by the tick when it
 * starts the sequence.
 */
#ifndef DRIVE_HOME_H
#define DRIVE_HOME_H

#include <stdbool.h>
#include <stdint.h>

#include "drive.h"
#include "motion_ref.h"
#include "qdec.h"
#include "servo.h"

typedef enum {
    HOME_IDLE = 0, /* not homing (axis not in the mask, or done) */
    HOME_SEARCH,
    HOME_TOUCHED, /* on the switch: decelerating to rest */
    HOME_BACKOFF,
    HOME_INDEX,
    HOME_STOP
} home_phase_t;

typedef enum {
    HOME_MOVING = 0, /* keep calling home_tick */
    HOME_DONE,       /* every axis homed and at rest */
    HOME_ABORTED,    /* home_abort: every axis at rest, not homed */
    HOME_FAULT       /* an axis over max_dist: fault_axes says which */
} home_result_t;

typedef struct {
    drive_home_t req;
    home_phase_t phase[CORE_AXES];
    int64_t v[CORE_AXES];      /* reference velocity, nm/s */
    int64_t rem[CORE_AXES];    /* position remainder, nm * tick_hz */
    int64_t dv[CORE_AXES];     /* velocity change per tick, nm/s */
    pos_nm_t pos[CORE_AXES];   /* reference position, nm */
    pos_nm_t start[CORE_AXES]; /* where the phase's distance is counted from */
    pos_nm_t mark[CORE_AXES];  /* reference point in the old frame, nm */
    uint32_t idx_ev[CORE_AXES];
    uint32_t fault_axes; /* axes over max_dist_nm */
    uint32_t done;       /* axes homed (rebased) */
    /* per axis: the frame shift of its last homing, nm (kept across
     * homings of other axes; zeroed by drive_init) */
    pos_nm_t shift[CORE_AXES];
    bool aborting;
} home_t;

/* The request is valid for a drive of configuration cfg (drive_home's
 * DRIVE_E_INVALID rules, drive.h). Pure. */
bool home_check(const drive_home_t *req, const drive_config_t *cfg);

/* Start the sequence of req (validated by drive_home) from the reference
 * position ref_pos; dv from the planner's a_max per axis and tick_hz. */
void home_start(home_t *h, const drive_home_t *req, const pos_nm_t ref_pos[CORE_AXES],
                const int64_t a_max[CORE_AXES], uint32_t tick_hz);

/* One tick: advance every axis, write the reference (ref: pos, vel, acc;
 * active, geometry none), rebase a finished axis (enc, fb, servo). */
home_result_t home_tick(home_t *h, uint32_t tick_hz, qdec_t enc[CORE_AXES], servo_fb_t *fb,
                        servo_t *servo, motion_ref_t *ref);

/* Ramp every axis to rest (a stop request). */
void home_abort(home_t *h);

#endif /* DRIVE_HOME_H */
