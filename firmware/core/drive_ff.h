/*
 * drive_ff.h - the drive's reference feed-forward corrections: the velocity
 * feed-forward advance, the Coulomb friction feed-forward and the
 * quadrant-glitch compensation (drive_config_t ff_advance_ns,
 * friction_ff_mv, friction_ff_band_nm_s, qg_comp; drive.h has what each
 * does and why).
 *
 * Specification
 * -------------
 * drive_ff_config(f, cfg): takes the settings from cfg: on = ff_advance_ns
 * != 0 or some friction_ff_mv[] != 0; advance in s * 2^32; the quadrant
 * state is restarted when qg_comp or a friction value changes (and on the
 * first call, f zeroed). Main (drive_init, drive_apply_config: the planner
 * is idle, so the reference is at rest and every correction below is zero
 * while the fields change; `on` is written last).
 * drive_ff_step(f, cfg, servo, ref), when f->on: per axis in use
 *   ref.vel += ref.acc * advance;
 *   friction_ff_mv F != 0: qg_comp: at a reversal of ref.vel the axis
 *   integrator jumps by I(+ -> -) - I(- -> +) of the last two reversals
 *   toward the new direction (at most 2 |F|); then with Kaff > 0 the
 *   friction F * clamp(v / band, -1, 1) mV is added as the reference
 *   acceleration F / Kaff.
 * Tick. Cost: nothing while `on` is false (the caller tests it).
 */
#ifndef DRIVE_FF_H
#define DRIVE_FF_H

#include <stdbool.h>
#include <stdint.h>

#include "core_config.h"
#include "drive.h"

typedef struct {
    bool on;         /* some correction is set (main writes, tick reads)   */
    int32_t adv_q32; /* ff_advance_ns in s * 2^32 (main)                   */
    bool qg;         /* qg_comp (main)                                     */
    /* quadrant state (tick): sign of the reference velocity last tick (0:
     * none yet), axis integrator before the last reversal out of + ([0])
     * and out of - ([1]), U; qg_have bit 0 / 1: that one is known */
    int8_t qg_sign[CORE_AXES];
    uint8_t qg_have[CORE_AXES];
    int64_t qg_ipre[CORE_AXES][2];
    int32_t fric_mv[CORE_AXES]; /* friction_ff_mv in use (main)         */
    int64_t band_nm_s;          /* friction_ff_band_nm_s, > 0 (main)    */
} drive_ff_t;

void drive_ff_config(drive_ff_t *f, const drive_config_t *cfg, unsigned axes);
void drive_ff_step(drive_ff_t *f, servo_t *servo, motion_ref_t *ref, unsigned axes);

#endif /* DRIVE_FF_H */
