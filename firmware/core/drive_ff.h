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
 * != 0, some friction_ff_mv[] != 0 or enc_mean; advance in s * 2^32; the quadrant
 * state is restarted when qg_comp or a friction value changes (and on the
 * first call, f zeroed). Main (drive_init, drive_apply_config: the planner
 * is idle, so the reference is at rest and every correction below is zero
 * while the fields change; `on` is written last).
 * drive_ff_step(f, cfg, servo, ref), when f->on: per axis in use
 *   ref.vel += ref.acc * advance;
 *   friction_ff_mv F != 0: qg_comp: at a reversal of ref.vel the axis
 *   integrator jumps by J toward the new direction ("Quadrant-glitch
 *   compensation" below); then with Kaff > 0 the
 *   friction F * clamp(v / band, -1, 1) mV is added as the reference
 *   acceleration F / Kaff.
 * Quadrant-glitch compensation: J is the friction step the feed-forward
 * misses, learned from what the loops hold, H = the axis integrator plus,
 * while the CEC is active, its integrators' part on the axis. Coulomb
 * friction is the only term of the axis's command that steps when the
 * velocity changes sign; what else H holds there follows the path
 * smoothly (the velocity and acceleration feed-forward errors, the
 * integrated ellipse: on a circle opposite at the two reversals, as the
 * friction is, so the difference of the last two reversals read them as
 * friction: R 20 mm 20 m/min with Kvff 2 % off, 83-90 mV for a 10 mV
 * step). So the step is read across each reversal: H a window W before
 * it (taken when |v| <= |a| W, decelerating), at it (before the jump) and
 * the same time after it: d = s (H(+) - 2 H(0) + H(-)), s the new
 * direction; anything smooth cancels to first order, a Coulomb step (the
 * jump included) does not. W = 2 Kp / Ki of the axis loop (two integral
 * times, at most DRIVE_FF_QG_WIN_MAX): the integrator has taken up a
 * step and the stick transient's overshoot back by then (one integral
 * time read 15.5 mV for the 10.1 mV step of realistic.toml with exact
 * feed-forward gains, two 11.2). d - J is what the jump missed as the
 * loops had taken it up in W: J += 3/2 (d - J) (they take up a part of
 * a step in W, 0.56-0.58 measured in one integral time; the learning
 * converges for any part below 4/3). |J| <= 2 |F|
 * (the friction at most twice the value fed forward). No learning for a
 * reversal without the sample before (from rest, a corner, a stop longer
 * than 2 W: H no longer the path's), and Ki = 0 learns nothing.
 * Mean alignment (cfg->enc_mean; drive.h): fb then holds each axis's mean
 * over the tick that ends at t_k (drive_inputs.h), so the reference it is
 * compared with is moved to the same mean, p_m = mean of p over
 * [t_k - T, t_k] = p + d, d = -v T / 2 + a T^2 / 6 (v, a: the reference's,
 * before the advance and the friction term; exact for a quadratic path).
 * On an ARC the plane axes are instead turned about the centre by the mean
 * angle th = (A x d) / r^2 (A = p - centre; sin, cos to th^3, th^4), so the
 * point stays on the arc and the tangent turns with it (a tangent left at
 * t_k would read the lag E . t as contour error, E_t th), and the plane
 * axes of fb are moved away from the centre by th^2 / 6 of their radius:
 * the mean of a circle traced at constant speed lies r th^2 / 6 inside it
 * (4.2 um at R 10 mm, 20 m/min, 3 ms), which EXACT would take for a
 * deviation. The feed-forward (vel, acc) stays the command's: it is for
 * the coming tick, not compared with anything. drive_ff_step then returns
 * the moved copy (f->mref) for the servo; ref itself keeps t_k (the
 * status, calibration). The servo's own stop ramp and the homing sequence
 * are not moved (half a tick of lag, v T / 2, while they run).
 * Tick. Cost: nothing while `on` is false (the caller tests it).
 */
#ifndef DRIVE_FF_H
#define DRIVE_FF_H

#include <stdbool.h>
#include <stdint.h>

#include "core_config.h"
#include "drive.h"

/* Longest window of the quadrant-glitch reading, ticks (1 s at 10 kHz). */
#define DRIVE_FF_QG_WIN_MAX 10000

enum { DRIVE_FF_QG_IDLE = 0, DRIVE_FF_QG_BEFORE, DRIVE_FF_QG_AFTER };

/* Quadrant-glitch state of one axis (tick; drive_ff_config restarts it). */
typedef struct {
    int8_t sign;   /* sign of the reference velocity last tick (0: none yet) */
    uint8_t phase; /* DRIVE_FF_QG_*: idle, sampled before, sampled at      */
    int32_t win;   /* window, ticks                                         */
    int32_t n;     /* ticks since the last sample                           */
    int64_t ib;    /* held a window before the reversal, U                  */
    int64_t i0;    /* held at the reversal (before the jump), U             */
    int64_t jump;  /* the friction step learned, toward the new direction, U */
} drive_ff_qg_t;

typedef struct {
    bool on;                      /* some correction is set (main writes, tick reads)   */
    int32_t adv_q32;              /* ff_advance_ns in s * 2^32 (main)                   */
    bool qg;                      /* qg_comp (main)                                     */
    drive_ff_qg_t qgs[CORE_AXES]; /* quadrant state (tick) */
    int32_t fric_mv[CORE_AXES];   /* friction_ff_mv in use (main)         */
    int64_t band_nm_s;            /* friction_ff_band_nm_s, > 0 (main)    */
    /* mean alignment (main): enc_mean; 2^32 / (2 f), 2^32 / f, 2^32 / (6 f) */
    bool mean;
    int32_t k_half, k_tick, k_sixth;
    motion_ref_t mref; /* the reference moved to the mean time (tick) */
} drive_ff_t;

void drive_ff_config(drive_ff_t *f, const drive_config_t *cfg, unsigned axes);
/* The reference for the servo: ref, or f->mref with the mean alignment. */
const motion_ref_t *drive_ff_step(drive_ff_t *f, servo_t *servo, motion_ref_t *ref, servo_fb_t *fb,
                                  unsigned axes);

#endif /* DRIVE_FF_H */
