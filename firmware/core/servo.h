/*
 * servo.h - the servo tick: feedback -> reference -> contour error controller
 * -> axis PIDs -> motor commands, with fault supervision.
 *
 * Specification
 * -------------
 * Each control tick the caller samples the decoders (qdec_sample /
 * qdec_sample_counter), fills a servo_fb_t (servo_fb_from_qdec does it from
 * qdec_t outputs) and calls servo_tick() with the interpolator's motion_ref_t
 * of the same tick. servo_tick():
 *   1. latches encoder faults (fb.enc_fault) and amplifier faults
 *      (io.amp_fault) of the axes in use;
 *   2. chooses the reference: the interpolator's (RUN; a NULL ref holds the
 *      last reference), or the servo's own stop ramp / hold point
 *      (STOPPING / HOLD);
 *   3. checks the following error |ref - pos| of every enabled axis against
 *      ferr_limit_nm;
 *   4. runs the contour error controller (cec.h) in RUN, adds its output to
 *      the axes and hands its integral over to the axis integrators when it
 *      stops or changes segment (bumpless);
 *   5. runs one pid_loop_t per axis with the reference velocity and
 *      acceleration as feed-forward;
 *   6. counts consecutive saturated ticks per axis against sat_limit_ticks;
 *   7. writes the commands (mV, clamped by each PID's out_max_mv) with
 *      io.set_mv for every axis in use (0 for disabled axes), or with one
 *      set_mv_all call when servo_set_io_all installed it; enable lines
 *      change through io.enable only on state changes.
 * (Implementation: steps 2 and 3 run in one pass over the axes and the
 * following-error reactions follow it in axis order; steps 5 and 6 run in
 * one pass; each reaction still sees the state left by the faults before
 * it, and every fault takes effect in the tick that raised it. The usual
 * tick - RUN with a reference, no fault input, the CEC off and quiet, no
 * following error over its limit - takes a short path: amplifier faults
 * read with one amp_fault_mask call when installed, reference position and
 * velocity (the acceleration is not kept: the loops have no feed-forward
 * there, the general path takes it from ref) and following errors in one
 * pass, then the loops with the PID's fast step (pid.h) inline while they
 * are ready; anything else takes the general path, with the same result.)
 *
 * States: OFF (outputs 0, enable lines off; the loops keep tracking the
 * feedback so enabling is bumpless) -> servo_enable -> HOLD (holds the
 * measured position) -> servo_run -> RUN (follows motion_ref_t) ->
 * servo_stop or a STOP fault -> STOPPING (own ramp) -> HOLD. servo_disable
 * -> OFF from anywhere. Before servo_run the interpolator must be set to the
 * hold position (servo_hold_pos), or the first RUN tick sees the difference
 * as a following error.
 *
 * Faults (latched in `faults`, axis bits in `fault_axes`, until
 * servo_clear_faults) and their reactions:
 *   SERVO_FAULT_FOLLOWING   |ref - pos| > ferr_limit_nm[axis]:
 *                           on_following (default SERVO_REACT_DISABLE).
 *   SERVO_FAULT_SATURATION  an axis output clamped for more than
 *                           sat_limit_ticks consecutive ticks:
 *                           on_saturation (default SERVO_REACT_STOP).
 *   SERVO_FAULT_ENCODER     fb.enc_fault bit (qdec fault latched): that axis
 *                           is disabled at once (its position is unknown),
 *                           the others make a controlled stop.
 *   SERVO_FAULT_AMPLIFIER   io.amp_fault(axis): as ENCODER.
 *   SERVO_FAULT_OSCILLATION the CEC's output has oscillated for 0.1 s (a
 *                           limit cycle, cec.h "Oscillation watch"; e.g.
 *                           the thesis's CEC gains at 10 kHz): on_saturation.
 * SERVO_REACT_DISABLE: every axis output 0 and enable off in the same tick,
 * state OFF. SERVO_REACT_STOP: controlled stop: from the last reference
 * position p0 and velocity v0, every axis decelerates linearly to rest in the
 * same N = max_axis ceil(|v0_i| * f / stop_decel_i) ticks (so the direction
 * of travel is kept and no axis exceeds its stop_decel), the position being
 * the exact sum of the velocities (integer remainder, no drift); then HOLD.
 * The CEC is off while stopping (its integral handed over). A STOP fault
 * during STOPPING/HOLD changes nothing more; a DISABLE fault always disables.
 * The planner/interpolator must read `faults` / `state` and abandon its job
 * when the servo leaves RUN.
 *
 * Units: positions nm, velocity nm/s, acceleration nm/s^2, commands mV
 * (+-160000 = +-160 V at the amplifier). Gains: pid.h (SI in q32_32,
 * converted for tick_hz by pid_config). servo_config overwrites the
 * tick_hz of every pid_params_t with servo_params_t.tick_hz.
 *
 * Position reset (index, homing): call servo_rebase(axis, offset) in the tick
 * in which the feedback frame moves by offset nm, with the interpolator's
 * reference moved by the same offset: no derivative or feed-forward step.
 *
 * Contexts: servo_tick, servo_rebase: tick. servo_init, servo_config,
 * servo_enable, servo_run, servo_stop, servo_disable, servo_clear_faults,
 * servo_set_cec_mode: main, never concurrently with servo_tick (a port
 * with a tick interrupt calls them with the tick masked, or queues them for
 * the tick). Everything in servo_t is written by these functions only; the
 * status fields may be read from any context between ticks.
 */
#ifndef SERVO_H
#define SERVO_H

#include <stdbool.h>
#include <stdint.h>

#include "cec.h"
#include "core_config.h"
#include "fixmath.h"
#include "motion_ref.h"
#include "pid.h"
#include "qdec.h"

#define SERVO_FAULT_FOLLOWING   (1u << 0)
#define SERVO_FAULT_ENCODER     (1u << 1)
#define SERVO_FAULT_SATURATION  (1u << 2)
#define SERVO_FAULT_AMPLIFIER   (1u << 3)
#define SERVO_FAULT_OSCILLATION (1u << 7) /* DRIVE_FAULT_OSCILLATION (6: homing) */

#define SERVO_STOP_TICKS_MAX (1u << 24)         /* longest controlled stop, ticks */
#define SERVO_VEL_MAX        ((int64_t)1 << 34) /* |reference velocity| used by the stop ramp, nm/s */

typedef enum { SERVO_OFF = 0, SERVO_HOLD, SERVO_RUN, SERVO_STOPPING } servo_state_t;

typedef enum { SERVO_REACT_DISABLE = 0, SERVO_REACT_STOP = 1 } servo_reaction_t;

typedef enum {
    SERVO_OK = 0,
    SERVO_ERR_NULL,
    SERVO_ERR_AXES,     /* axes outside 1..CORE_AXES                     */
    SERVO_ERR_TICK_HZ,  /* tick_hz outside PID_TICK_HZ_MIN..MAX           */
    SERVO_ERR_AXIS_PID, /* an axis's gains were refused: see err_axis, pid_err */
    SERVO_ERR_CEC_PID,  /* the CEC gains were refused: see pid_err        */
    SERVO_ERR_CEC_MODE, /* unknown CEC mode                               */
    SERVO_ERR_LIMIT,    /* a negative ferr_limit_nm                       */
    SERVO_ERR_DECEL,    /* stop_decel_nm_s2 <= 0 or >= 2^40               */
    SERVO_ERR_REACTION, /* unknown reaction                               */
    SERVO_ERR_STATE,    /* not allowed in this state / with faults latched */
    SERVO_ERR_AXIS,     /* axis index out of range                        */
    SERVO_ERR_FFL       /* ffl_rate outside 0..SERVO_FFL_RATE_MAX        */
} servo_err_t;

/* Hardware access (hal.h functions on a port; fakes in tests). Any member
 * may be NULL: that access is skipped. */
typedef struct {
    void (*set_mv)(unsigned axis, int32_t millivolts);
    void (*enable)(unsigned axis, bool on);
    bool (*amp_fault)(unsigned axis);
} servo_io_t;

/* Optional one-call forms of set_mv and amp_fault (hal_motor_set_mv_all,
 * hal_amp_fault_mask), installed by servo_set_io_all: when set, used
 * instead of them (one call per tick for all axes, the same values in axis
 * order). */
typedef void (*servo_set_mv_all_fn)(const int32_t *millivolts, unsigned axes);
typedef uint32_t (*servo_amp_fault_mask_fn)(unsigned axes);

typedef struct {
    pos_nm_t pos[CORE_AXES]; /* measured position, nm                 */
    uint32_t enc_fault;      /* bit i: encoder of axis i is faulted   */
} servo_fb_t;

typedef struct {
    unsigned axes;                       /* axes in use, 1..CORE_AXES          */
    uint32_t tick_hz;                    /* control tick rate                  */
    pid_params_t axis[CORE_AXES];        /* per axis loop (pid.h)              */
    cec_params_t cec;                    /* contour error controller (cec.h)   */
    int32_t ferr_limit_nm[CORE_AXES];    /* following error limit; 0: off      */
    uint32_t sat_limit_ticks;            /* saturated longer: fault; 0: off    */
    int64_t stop_decel_nm_s2[CORE_AXES]; /* controlled stop deceleration, > 0  */
    servo_reaction_t on_following;
    servo_reaction_t on_saturation;
    /* Feed-forward learning rate (see "Feed-forward learning"), 1/s;
     * 0: off (the default). 0..SERVO_FFL_RATE_MAX. */
    int32_t ffl_rate;
} servo_params_t;

/* Feed-forward learning (with the CEC; off while ffl_rate is 0).
 * A velocity feed-forward gain that is a few percent off on one axis
 * (identified Kvff, a load not in the model) leaves, on a curve, a contour
 * error that follows the path: X 2 % low and Y 2 % high make a circle an
 * ellipse (R 20 mm, 10 m/min, realistic.toml: 4.6 um of 2nd harmonic with
 * the PIDs alone, 2.3 um with the CEC, whose gain at the path frequency is
 * bounded by its margins). The CEC's output u1 holds (in phase, where the
 * loops' gain is high) what must be added along n1 to cancel it; the
 * learning moves it into a velocity gain w_i per axis by a normalised LMS
 * step each tick the CEC is active:
 *   w_i += (ffl_rate / tick_hz) * u1 * n1_i * v_i / (|v|^2 + v_min^2)
 *   (v the reference velocity, v_min = SERVO_FFL_V_MIN * 2^10 nm/s,
 *   |w_i| <= SERVO_FFL_W_MAX), and adds w_i * v_i to axis i's command with
 * the CEC's output. Since n1 . v = 0 the step is always a difference
 * across the axes: w learns the X / Y mismatch of the velocity gains, the
 * only part the contour sees (a common error only lags along the path).
 * Time constant about 1 / ffl_rate while the path turns. The step is
 * taken only while the path frequency |a| / |v| is at most
 * SERVO_FFL_W_PATH: u1 is in phase with the disturbance only well below
 * the CEC's crossover (150-190 rad/s on the shipped sets); above it the
 * loops' phase turns the step the wrong way (default.toml, R 10 mm at
 * 20 m/min, 33 rad/s, rate 100/s: 2.4 -> 15 um). w is kept while the
 * CEC is off, reset by servo_config when ffl_rate changes. Cost: the
 * CEC-active ticks only (one division per axis); CEC off
 * (control_tick_instructions_m4) is not affected. */
#define SERVO_FFL_RATE_MAX 1000               /* 1/s */
#define SERVO_FFL_W_PATH   20                 /* rad/s: learn below this path frequency */
#define SERVO_FFL_V_MIN    977                /* 2^10 nm/s: 1 mm/s */
#define SERVO_FFL_V_MAX    (1 << 20)          /* 2^10 nm/s: 1.07 m/s */
#define SERVO_FFL_W_MAX    ((int64_t)1 << 24) /* U per 2^10 nm/s: 3.8 V/(m/s) */

typedef struct {
    servo_params_t p;
    servo_io_t io;
    servo_set_mv_all_fn set_mv_all;         /* servo_set_io_all; NULL: io.set_mv    */
    servo_amp_fault_mask_fn amp_fault_mask; /* servo_set_io_all; NULL: io.amp_fault */
    pid_loop_t pid[CORE_AXES];
    cec_t cec;
    /* state (tick) */
    servo_state_t state;
    uint32_t off_mask;            /* axes whose outputs are disabled          */
    pos_nm_t ref_pos[CORE_AXES];  /* reference used in the last tick, nm      */
    int64_t ref_vel[CORE_AXES];   /* ... nm/s (the stop ramp starts from it;
                                   * the acceleration is not kept: the loops
                                   * take it from the tick's reference)      */
    uint32_t ferr_max[CORE_AXES]; /* servo_config: ferr limit, 2^31 - 1 when off */
    uint32_t sat_max;             /* servo_config: sat_limit_ticks, or UINT32_MAX when off */
    pos_nm_t stop_pos[CORE_AXES]; /* stop ramp / hold position, nm            */
    int64_t stop_v0[CORE_AXES];   /* velocity at the start of the stop, nm/s  */
    int64_t stop_rem[CORE_AXES];  /* position remainder, nm * N * f           */
    uint32_t stop_n;              /* ramp length, ticks                       */
    uint32_t stop_k;              /* ticks done                               */
    bool lines_on[CORE_AXES];     /* enable line state written to io          */
    /* status (read between ticks) */
    uint32_t faults;            /* SERVO_FAULT_* latched                    */
    uint32_t fault_axes;        /* bit i: axis i raised a fault             */
    int32_t out_mv[CORE_AXES];  /* commands written this tick               */
    int32_t ferr_nm[CORE_AXES]; /* following error this tick                */
    uint64_t ticks;
    /* feed-forward learning (tick): w_i, U per 2^10 nm/s, and the rate */
    int64_t ffl_w[CORE_AXES];
    int64_t ffl_k; /* ffl_rate / tick_hz in 2^-26 (servo_config) */
    /* detail of the last configuration error */
    unsigned err_axis;
    pid_err_t pid_err;
} servo_t;

/* Defaults for tick_hz: the thesis's axis gains (Kp 1.5e3 V/m, Ki 8e3
 * V/(m*s), Kd 5 V*s/m, no feed-forward, D on measurement, 0.1 ms D filter,
 * clamps 160 V, back-calculation Kt = 10/s) and CEC gains (Kp 4e4, Ki 2e6,
 * Kd 100; mode off; handover on): a starting point, not a tuning (the
 * simulator ships tuned sets). Following error limit 5 mm, saturation limit
 * 0.5 s, stop deceleration 1 m/s^2, following error disables, saturation
 * stops. All CORE_AXES axes in use. */
void servo_params_default(servo_params_t *p, uint32_t tick_hz);

/* Validate everything, then apply (nothing changes on error). Bumpless on a
 * running servo. */
servo_err_t servo_config(servo_t *s, const servo_params_t *p);

/* Zero s, install io, configure; state OFF. */
servo_err_t servo_init(servo_t *s, const servo_params_t *p, const servo_io_t *io);
/* Install (or remove, NULL) the one-call output and fault-input forms
 * (after servo_init, which clears them). Main context, tick not running. */
void servo_set_io_all(servo_t *s, servo_set_mv_all_fn set_mv_all,
                      servo_amp_fault_mask_fn amp_fault_mask);

/* OFF -> HOLD at fb's positions, outputs on (bumpless from 0 mV).
 * SERVO_ERR_STATE when faults are latched or the state is not OFF. */
servo_err_t servo_enable(servo_t *s, const servo_fb_t *fb);
/* HOLD -> RUN (no faults latched). */
servo_err_t servo_run(servo_t *s);
/* RUN -> STOPPING (controlled stop); HOLD/STOPPING unchanged. */
void servo_stop(servo_t *s);
/* Any -> OFF: outputs 0 and enable lines off at once. */
void servo_disable(servo_t *s);
/* Clear the latched faults (SERVO_ERR_STATE while STOPPING). Axes disabled
 * by a fault stay disabled until servo_disable + servo_enable. */
servo_err_t servo_clear_faults(servo_t *s);
servo_err_t servo_set_cec_mode(servo_t *s, cec_mode_t mode);
/* The feedback frame of `axis` moved by offset_nm in this tick. */
servo_err_t servo_rebase(servo_t *s, unsigned axis, pos_nm_t offset_nm);
/* Position held in HOLD (and the end of a stop ramp), nm. */
pos_nm_t servo_hold_pos(const servo_t *s, unsigned axis);

/* One control tick (see above). ref: the interpolator's output this tick. */
void servo_tick(servo_t *s, const motion_ref_t *ref, const servo_fb_t *fb);

/* fb from decoder outputs: pos = out.pos_nm, enc_fault bit = out.faults != 0.
 * enc[i] NULL: position 0, no fault. */
void servo_fb_from_qdec(servo_fb_t *fb, const qdec_t *const enc[CORE_AXES], unsigned axes);

#endif /* SERVO_H */
