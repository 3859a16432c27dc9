/*
 * drive.h - the drive application: owns and wires the planner, the
 * interpolator, the encoder decoders and the servo loops of one drive.
 *
 * Specification
 * -------------
 * One drive per firmware image: the state is a single static instance inside
 * drive.c (no heap). A port calls drive_init() once at start-up, then
 * drive_tick() from its control-tick interrupt (or the simulator's step) and
 * drive_poll() from its background loop. The protocol dispatcher (main
 * context) calls the command functions below; they never block.
 *
 * Contexts
 *   drive_tick()                          tick only.
 *   drive_poll(), drive_queue_block(),
 *   drive_enable(), drive_stop(), drive_home(),
 *   drive_fault_reset(), drive_set_*()    main only.
 *   drive_estop(), drive_snapshot()       any context (estop only sets a
 *                                         flag acted on by the next tick;
 *                                         the snapshot is what the tick
 *                                         publishes under a sequence count).
 *   drive_status()                        main (the snapshot plus queue_free
 *                                         and queued_time_ns from main-owned
 *                                         queues; its state: a stop not yet
 *                                         applied counts as STOPPING, IDLE
 *                                         with blocks queued as RUNNING).
 *   drive_param_*(), drive_queue_free()   main.
 *   drive_arc_chords()                    any (pure).
 *   drive_encoder_edge(), _run()          edge interrupt / simulator, between
 *                                         ticks (never concurrently with tick
 *                                         on the simulator; on hardware the
 *                                         decoder's own rules apply).
 *
 * The tick owns the state (docs/tick-main.md): the main-context commands
 * post requests that a following tick applies and never write the state.
 *
 * Units (docs/conventions.md): positions nm (pos_nm_t), velocities nm/s,
 * times ns or ticks, motor command mV at the amplifier input.
 *
 * Modules: drive.c is the state machine (request mailbox, the tick, the
 * status snapshot); feed.c the feed path (host-block FIFO -> planner ->
 * interpolator, main context); arc_seg.c the chord segmentation (and
 * drive_arc_chords); arc_ref.c the arc reference of the tick;
 * drive_inputs.c the encoders and reference scales; drive_param.c the
 * configuration defaults and the parameter table; drive_home.c the homing
 * sequence (tick). drive_int.h is their
 * internal interface, drive_test.h holds the test hooks. The drive calls no
 * other subsystem's main or tick functions: calibration runs beside it (see
 * drive_tick).
 *
 * Motion: blocks are absolute end points with a programmed feed, queued in
 * a host-block FIFO of DRIVE_QUEUE_DEPTH entries (queue_free in the status)
 * that drive_poll() feeds into the planner (planner.h, straight blocks only):
 *   LINE   one planner block.
 *   DWELL  one planner dwell.
 *   ARC    in a plane (G17/G18/G19) about an absolute centre, sense +1 (G3,
 *          counter-clockwise seen from the plane normal) or -1 (G2); start and
 *          end radius may differ by up to DRIVE_ARC_RADIUS_TOL_NM (the radius
 *          then varies linearly with the swept angle); start == end is a full
 *          circle; the third axis moves linearly (helix). It is cut into
 *          chords of equal angle, the angle being the larger of the chord
 *          tolerance (cfg.arc_chord_nm) and DRIVE_ARC_SEG_TICKS ticks of
 *          travel at the programmed feed, and at most DRIVE_ARC_SEG_MAX_ANGLE.
 *          The planner times the chords; in the tick the drive maps the
 *          interpolator's position on a chord to the same fraction of the
 *          chord's angle on the true arc, so the reference position, the
 *          tangent, the velocity feed-forward (path speed scaled by arc /
 *          chord length) and the acceleration feed-forward (tangential plus
 *          centripetal v^2 / r) are those of the exact arc, and the
 *          motion_ref_t geometry is MOTION_GEOM_ARC (centre, current radius,
 *          sense) for the contour-error controller.
 *
 * The arc reference (the exact overlay and the recurrence that replaces it
 * on the interpolator's cruise fast-path ticks, with its error bound) is
 * specified in arc_ref.h, the chord segmentation in arc_seg.h.
 * A block is accepted only when the drive is enabled and not faulted; it is
 * validated before anything is queued (all or nothing). Blocks may be queued
 * right after drive_enable(true), before the tick has applied it.
 *
 * Feeding (drive_poll). Every waiting host block is pushed into the planner
 * before each pop (interp_refill pops one block), so a block is frozen with
 * the look-ahead plan_estimate() gives it. A block is popped into the
 * interpolator's FIFO (while it has room) when the planner is full, or when
 * the oldest block's plan is final (its exit speed can no longer change:
 * the next block's entry is final, or it ends in an exact stop or is a
 * dwell), or when no block is waiting and the interpolator would run short:
 * less than DRIVE_FEED_AHEAD_NS (5 ms) queued beyond its current segment,
 * or, with nothing in it (a job starting from rest), no block accepted for
 * cfg.start_delay_ms. A host that keeps the queue topped up therefore gets
 * exactly the estimator's plan (executed time = estimate within one tick per
 * block), and runs of blocks shorter than a tick never starve the
 * interpolator (up to INTERP_FIFO blocks per tick).
 *
 * Controlled stop (drive_stop, also the servo-independent part of the
 * watchdog): the interpolator's time runs at a scale k <= 1 chosen each tick
 * so that the path speed follows a cap that falls by cfg.stop_decel_nm_s2
 * per second and never exceeds the previous tick's speed: the axes stay on
 * the planned path, the speed never rises (also when the plan was
 * accelerating), and falls no faster than stop_decel unless the plan itself
 * slows down faster (it then follows the plan, e.g. into an exact stop).
 * At rest (cap 0, or the end of the queued path) the queues are flushed,
 * the reference holds and the drive is IDLE: the rest of the job is dropped
 * and new blocks start from the stop point.
 *
 * State machine (every transition made by the tick)
 *   DISABLED --enable--> IDLE <--> RUNNING (blocks queued / executing)
 *   RUNNING --stop--> STOPPING --(axes at rest, main flushed)--> IDLE
 *   any --estop / fault--> FAULT (outputs zero and disabled, queue flushed)
 *   FAULT --fault_reset (cause gone)--> DISABLED
 *   IDLE --home--> HOMING --(homed, or stop: at rest)--> STOPPING --> IDLE
 *   IDLE/RUNNING --disable--> DISABLED (outputs zero, queue flushed)
 */
#ifndef DRIVE_H
#define DRIVE_H

#include <stdbool.h>
#include <stdint.h>

#include "comp.h"
#include "core_config.h"
#include "fixmath.h"
#include "motion_ref.h"
#include "planner.h"
#include "servo.h"

/* Default chord tolerance for arcs segmented by the drive, nm. */
#ifndef DRIVE_ARC_CHORD_NM
#define DRIVE_ARC_CHORD_NM 100
#endif
/* Arc chords last at least this many ticks at the programmed feed. */
#define DRIVE_ARC_SEG_TICKS 32
/* Largest angle of one arc chord (binary angle: 2^32 per turn; pi/32): the
 * direction components of chords meeting at a quadrant point stay below the
 * planner's reversal threshold (sin(pi/64) < PLAN_REVERSAL_MIN_Q30 = 1/16). */
#define DRIVE_ARC_SEG_MAX_ANGLE ((uint32_t)1 << 26)
/* Largest difference of start and end radius of an arc, nm. */
#define DRIVE_ARC_RADIUS_TOL_NM 5000
/* Host blocks queued ahead of the planner. */
#define DRIVE_QUEUE_DEPTH 16
/* The reference scales are sampled at least every DRIVE_REF_SAMPLE_TICKS
 * ticks (a power of two; see drive_status_t.refscale). Wrap guard: the
 * 32-bit counter's change between samples is taken as int32, so a scale
 * must move less than 2^31 counts in that time: below
 * 2^31 / 64 * tick_hz = 33.5e6 * tick_hz counts/s: 3.3e9 counts/s at
 * PID_TICK_HZ_MIN (100 Hz), 1.67e11 at 5 kHz; at 1 nm per count 3.3 km/s
 * and 167 km/s, far above any axis. */
#define DRIVE_REF_SAMPLE_TICKS 64u
/* Default and largest start delay (drive_config_t.start_delay_ms), ms. */
#define DRIVE_START_DELAY_MS     50u
#define DRIVE_START_DELAY_MS_MAX 10000u
#define DRIVE_FF_ADVANCE_NS_MAX  10000000 /* ff_advance_ns: 10 ms */
#define DRIVE_FRICTION_FF_MV_MAX 100000   /* friction_ff_mv: 100 V */
/* Default in-position window and range of the soft limits, nm. */
#define DRIVE_IN_POS_NM     5000
#define DRIVE_IN_POS_NM_MAX 100000000
#define DRIVE_SOFT_LIMIT_NM ((int64_t)1 << 40)

typedef enum {
    DRIVE_OK = 0,
    DRIVE_E_FULL,       /* planner ring full: retry after blocks complete */
    DRIVE_E_INVALID,    /* malformed block or parameter (nothing changed)  */
    DRIVE_E_DISABLED,   /* the drive is not enabled                        */
    DRIVE_E_FAULTED,    /* a fault is latched: fault_reset first           */
    DRIVE_E_BUSY,       /* not allowed while moving (parameter changes)    */
    DRIVE_E_CAUSE,      /* fault_reset refused: the cause is still present */
    DRIVE_E_LIMIT,      /* a target outside the soft travel limits          */
    DRIVE_E_UNSUPPORTED /* the port cannot provide what it needs (enc_mean) */
} drive_result_t;

typedef enum {
    DRIVE_DISABLED = 0,
    DRIVE_IDLE,
    DRIVE_RUNNING,
    DRIVE_STOPPING,
    DRIVE_FAULT,
    DRIVE_HOMING /* the homing sequence runs (drive_home) */
} drive_state_t;

/* Fault bits (latched until drive_fault_reset); the first four are the
 * servo's (servo.h SERVO_FAULT_*, same values), with its reactions:
 * following error, encoder and amplifier faults disable, saturation makes a
 * controlled stop. ESTOP disables at once. */
#define DRIVE_FAULT_FOLLOWING   (1u << 0) /* following error over its limit   */
#define DRIVE_FAULT_ENCODER     (1u << 1) /* decoder reported illegal edges    */
#define DRIVE_FAULT_SATURATION  (1u << 2) /* output saturated too long         */
#define DRIVE_FAULT_AMPLIFIER   (1u << 3) /* amplifier fault input             */
#define DRIVE_FAULT_ESTOP       (1u << 4) /* emergency stop requested          */
#define DRIVE_FAULT_COMM        (1u << 5) /* host link watchdog (protocol)     */
#define DRIVE_FAULT_HOMING      (1u << 6) /* home switch or index not found    */
#define DRIVE_FAULT_OSCILLATION (1u << 7) /* CEC limit cycle (servo.h)        */

typedef enum {
    DRIVE_BLOCK_LINE = 1,
    DRIVE_BLOCK_ARC = 2,
    DRIVE_BLOCK_DWELL = 3
} drive_block_kind_t;

typedef enum {
    DRIVE_PLANE_XY = 0, /* G17: u = X, v = Y */
    DRIVE_PLANE_ZX = 1, /* G18: u = Z, v = X */
    DRIVE_PLANE_YZ = 2  /* G19: u = Y, v = Z */
} drive_plane_t;

typedef struct {
    drive_block_kind_t kind;
    uint32_t tag;                /* host's id, echoed in the status         */
    pos_nm_t target[CORE_AXES];  /* LINE/ARC: absolute end point, nm        */
    int64_t feed_nm_s;           /* LINE/ARC: programmed feed, nm/s, > 0    */
    bool exact_stop;             /* stop at the end of this block (G61/G9)  */
    drive_plane_t plane;         /* ARC only                                */
    pos_nm_t centre_u, centre_v; /* ARC: absolute centre in the plane, nm   */
    int8_t sense;                /* ARC: +1 counter-clockwise, -1 clockwise */
    uint32_t dwell_ms;           /* DWELL only                              */
} drive_block_t;

/* Contour-error controller selection (per job). */
typedef enum {
    DRIVE_CEC_OFF = 0,
    DRIVE_CEC_TANGENT,
    DRIVE_CEC_CURVATURE,
    DRIVE_CEC_EXACT,
    DRIVE_CEC_KOREN,        /* Koren's straight-line estimate (cec.h)            */
    DRIVE_CEC_CURV_HISTORY, /* curvature from the reference history only (calcr) */
    DRIVE_CEC_CHUANG_LIU,   /* Chuang & Liu's second-order estimate (cec.h)     */
    DRIVE_CEC_COUNT
} drive_cec_mode_t;

typedef struct {
    drive_state_t state;
    uint32_t faults;            /* DRIVE_FAULT_* bits latched             */
    uint64_t tick;              /* ticks since init                       */
    pos_nm_t pos[CORE_AXES];    /* measured position, nm                  */
    pos_nm_t ref[CORE_AXES];    /* reference position, nm                 */
    int64_t vel_ref[CORE_AXES]; /* reference velocity, nm/s               */
    int32_t motor_mv[CORE_AXES];
    int64_t contour_error_nm; /* CEC's estimate (0 when the CEC is off) */
    uint32_t queue_free;      /* free planner slots                     */
    int64_t queued_time_ns;   /* planned time still queued: planner plus
                               * the interpolator's remainder (blocks
                               * in the host FIFO not yet planned are
                               * not counted); drive_status only, main */
    uint32_t blocks_done;     /* blocks completed since init            */
    uint32_t tag;             /* tag of the block executing (or last)   */
    /* Reference-scale positions, nm (0 without a scale), as of the last
     * sample: every tick while calibration samples (drive_tick's
     * ref_sampling), the
     * tick after each drive_status() call, and otherwise every
     * DRIVE_REF_SAMPLE_TICKS ticks (the counters are read by the tick only:
     * a status reply reports the sample of the tick after the previous
     * drive_status(), at most DRIVE_REF_SAMPLE_TICKS ticks old). */
    pos_nm_t refscale[CORE_AXES];
    uint32_t encoder_illegal[CORE_AXES]; /* illegal transitions seen      */
    pos_nm_t pos_raw[CORE_AXES];         /* measured position before the
                                          * compensation table, nm       */
    uint32_t homed;                      /* bit i: axis i homed (drive_home) since init */
    /* per axis: how far its last homing moved the position frame, nm
     * (home_pos minus what the reference point read before: 0 when the
     * frame was already right) */
    pos_nm_t home_shift[CORE_AXES];
} drive_status_t;

typedef struct {
    uint32_t tick_hz; /* control tick rate, Hz (PID_TICK_HZ_MIN..MAX)       */
    unsigned axes;    /* axes in use, 1..CORE_AXES                         */
    /* Encoder scale per axis: nanometres per count num / den (e.g. 5 mm
     * per 4000 counts: 1250 / 1); the sign gives the counting direction. */
    int32_t nm_per_count_num[CORE_AXES];
    int32_t nm_per_count_den[CORE_AXES];
    uint32_t enc_initial_lines[CORE_AXES]; /* A/B/Z levels at drive_init      */
    /* Axis i read as a 32-bit hardware counter (hal_encoder_counter(i),
     * polled at the top of each tick, qdec counter input) instead of edges:
     * drive_encoder_edge on such an axis is ignored and enc_initial_lines
     * is unused; the count starts from 0 = position 0 at drive_init.
     * Default false (drive_config_default). */
    bool enc_counter[CORE_AXES];
    /* Reference-scale inputs (hal_encoder_counter channels axes + i, 32-bit
     * counters): nm per count num / den; num == 0: no reference scale. */
    int32_t ref_nm_per_count_num[CORE_AXES];
    int32_t ref_nm_per_count_den[CORE_AXES];
    plan_profile_t plan;  /* planner limits and cornering rule          */
    servo_params_t servo; /* axis loops, CEC gains, fault limits and
                           * reactions (servo.h); axes and tick_hz are
                           * overwritten from the fields above; the CEC
                           * mode is chosen per job (drive_set_cec_mode) */
    /* Coulomb friction feed-forward per axis: F * clamp(v_ref / band, -1, 1)
     * mV added to the command (0: off). The servo has no friction term: it
     * is applied through the acceleration feed-forward channel as an extra
     * reference acceleration F / Kaff (so it needs Kaff > 0; off otherwise). */
    int32_t friction_ff_mv[CORE_AXES];
    int64_t friction_ff_band_nm_s; /* velocity of full friction feed-forward */
    /* Velocity feed-forward time advance, ns (0: off, at most 10 ms): the
     * servo gets vel + acc * advance. The command computed at t_k is held
     * over the whole tick, so the velocity it should feed forward is the
     * mean over [t_k, t_k + T], v(t_k + T / 2): half a tick is the
     * zero-order hold's delay (more: the amplifier's own). Without it a
     * circle is fed forward a phase w T / 2 late, which leaves a radial
     * command Kvff v w T / 2 the PIDs can only answer with an error:
     * R 20 mm, 10 m/min, 3 ms: 29 um of radius (docs/simulator.md). */
    int32_t ff_advance_ns;
    /* Quadrant-glitch compensation (needs a friction_ff_mv): at each
     * reversal of an axis's reference velocity the axis integrator jumps,
     * toward the new direction, by the friction step learned across the
     * reversals: the step of what the loops hold from a window before to
     * the same window after each one, which the path's smooth content (the
     * feed-forward errors) does not make (drive_ff.h; at most 2
     * friction_ff_mv). Read as what the last two reversals differed by,
     * the feed-forward gain error's part was taken for friction and the
     * jumps hit the bound (realistic.toml R 20 mm 20 m/min, CEC settled:
     * 24.47 um, 5.92 without the compensation; now 5.09). What
     * the friction feed-forward misses (a friction value off by 10 %) the
     * integrator holds with the sign of the motion; at a reversal it must
     * swing by twice that, which takes it tens of ms from the error alone
     * (the quadrant glitch: realistic.toml, R 20 mm, 10 m/min: +9.6 um
     * with the PIDs, +6 um with the CEC). Learned at every reversal, so
     * it follows a friction that changes. With the CEC
     * active, what the loops hold is the axis integrator plus what the CEC's integrators
     * hold on the axis (along the normal, which at a reversal is this
     * axis: part of the friction is held there); read from the axis
     * integrator alone the jump was too small and the compensation did
     * little or harm with the CEC (realistic.toml, R 100 mm, 2 m/min:
     * 14.2 -> 15.2 um; with both 14.2 -> 4.3 um). Default false. */
    bool qg_comp;
    /* Mean measurement (issue 21): the loops see each axis's encoder as
     * its mean over the tick (hal_encoder_mean) instead of its count at the
     * sample, and compare it with the reference at the same mean time,
     * t_k - T/2 (drive_ff.h "Mean alignment"): half a tick of measurement
     * delay that is not a tracking error. The boxcar removes what the
     * sample aliases (at 3 ms the X table's 662.6 Hz mode, excited by the
     * zero-order hold at 2 x 333 Hz, read 3.4 Hz from DC) and resolves
     * below one count on a moving axis. Default false; a port whose
     * hal_encoder_mean returns false refuses it: drive_init and the
     * parameter return DRIVE_E_UNSUPPORTED, nothing changes. */
    bool enc_mean;
    /* Interpolated measurement (issue 21): each axis's position below the
     * count from its edge times (enc_interp.h: the quadratic through the
     * last three edge events, held inside what the counts prove), at the
     * sample, or with enc_mean the mean over the tick in place of
     * hal_encoder_mean's. Where the count says least, near an axis
     * reversal (less than about two counts per tick), it tells where in
     * the count the axis is. Needs edge input on every axis (an
     * enc_counter axis has no edge times: drive_init returns
     * DRIVE_E_UNSUPPORTED). Default false; set at drive_init only. On
     * the Cortex-M4 about 535 instructions per axis and tick
     * (control_tick_instructions_m4_interp: 3089 against 1483 for the
     * three-axis helix): the 1500 budget holds with it off only. */
    bool enc_interp;
    int64_t stop_decel_nm_s2; /* drive_stop: path deceleration, > 0          */
    int64_t arc_chord_nm;     /* arc segmentation tolerance, 0: default      */
    uint32_t start_delay_ms;  /* start of motion from rest: see "Feeding",
                               * 0..DRIVE_START_DELAY_MS_MAX              */
    /* Soft travel limits per axis, nm: a line, arc or jog whose end point
     * on a moving axis lies outside [soft_min, soft_max] is refused
     * (DRIVE_E_LIMIT) before it is queued. Off while soft_min >= soft_max
     * (default 0 / 0). Arcs: the end point and every extreme point
     * (centre +- radius along a plane axis) the sweep passes. */
    pos_nm_t soft_min[CORE_AXES];
    pos_nm_t soft_max[CORE_AXES];
    /* In-position window per axis, nm (default DRIVE_IN_POS_NM): not used
     * by the drive; the host waits until |ref - pos| is inside it. */
    int64_t in_pos_nm[CORE_AXES];
} drive_config_t;

/* Fill cfg with working defaults for `axes` axes at tick_hz: 1 nm per
 * count, no reference scale, servo_params_default(), planner 1 m/s,
 * 10 m/s^2, 1000 m/s^3 per axis, junction deviation 10 um, stop 1 m/s^2. */
void drive_config_default(drive_config_t *cfg, uint32_t tick_hz, unsigned axes);

/* Initialise everything (planner, interpolator, decoders, servo) with the
 * given configuration; the drive starts DISABLED with all commands zero.
 * Returns DRIVE_E_INVALID (and stays uninitialised) on bad values. Main. */
drive_result_t drive_init(const drive_config_t *cfg);

/* What drive_tick publishes for the tick-context consumer that runs right
 * after it (calib_tick); valid until the next drive_tick. */
typedef struct {
    const drive_status_t *st; /* the status; its live fields (pos, pos_raw,
                               * refscale ...) only when ref_sampling    */
    const int64_t *vel_ref;   /* reference velocities handed to the servo,
                               * nm/s, CORE_AXES                         */
} drive_tick_out_t;

/* One control tick: decode, interpolate, servo, motor commands, then the
 * status is published. ref_sampling: the caller's calibration samples this
 * tick (calib_sampling()): the reference scales are read and the live
 * fields copied into the published status. NULL (nothing done) before a
 * successful drive_init. Tick. */
const drive_tick_out_t *drive_tick(bool ref_sampling);

/* Background work: re-planning, state housekeeping. Main. */
void drive_poll(void);

drive_result_t drive_queue_block(const drive_block_t *b);
/* Whether drive_queue_block would take a valid block now, queue room
 * aside: DRIVE_OK, DRIVE_E_DISABLED, DRIVE_E_FAULTED or DRIVE_E_BUSY (main's
 * view: pending requests count as applied). Main. */
drive_result_t drive_accepting(void);
/* Free host-block slots (the status's queue_free, without the O(queued)
 * planned time). Main. */
uint32_t drive_queue_free(void);

/* The chords an arc block is cut into (see Motion above), for a drive with
 * `axes` axes at tick_hz and chord tolerance chord_nm (0: the default), the
 * arc starting at `start`: writes the end points of chords 1..min(n, cap)
 * to out[(k - 1) * CORE_AXES + axis] (the last is the target, exactly) and
 * returns n, or 0 for an arc drive_queue_block would refuse. Pure (the
 * host's estimator plans exactly the drive's chords). Any. */
uint32_t drive_arc_chords(const drive_block_t *b, const pos_nm_t start[CORE_AXES], unsigned axes,
                          uint32_t tick_hz, int64_t chord_nm, pos_nm_t *out, uint32_t cap);
/* Enable (the next tick switches the servo on at the measured position) or
 * disable. DRIVE_E_BUSY: enable while a disable is not yet applied (retry
 * after a tick); DRIVE_E_FAULTED: a fault is latched. Main. */
drive_result_t drive_enable(bool on);
/* Controlled stop: decelerate on the path, flush the queue, stay enabled. */
void drive_stop(void);
/* Emergency stop: outputs to zero and disabled at the next tick, FAULT. */
void drive_estop(void);
/* Latch a fault from outside the drive (e.g. DRIVE_FAULT_COMM). Any. */
void drive_raise_fault(uint32_t fault_bits);
drive_result_t drive_fault_reset(void);
void drive_status(drive_status_t *out);
/* The tick's published snapshot only: queue_free and queued_time_ns are left
 * 0 (drive_status computes the planned time, O(queued blocks)). Any. */
void drive_snapshot(drive_status_t *out);
/* The fields of the snapshot a per-tick trace reads (the simulator's
 * sim_run rows), read as drive_snapshot reads them: each equals the field
 * of the same name of a drive_snapshot() at the same point. Without the
 * rest of the status (copied and then overwritten by the snapshot) it is
 * a fraction of the cost. Any. */
typedef struct {
    drive_state_t state;
    uint32_t faults;
    int64_t contour_error_nm;
    pos_nm_t pos[CORE_AXES];
    pos_nm_t ref[CORE_AXES];
} drive_trace_t;
void drive_trace_read(drive_trace_t *out);

/* Deliver one encoder edge to channel ch (axes 0..axes-1, then the
 * reference-scale inputs): the new line levels (QDEC_LINE_A/B/Z bits) and
 * the edge time in ns of the tick clock (uint32, wrapping; see qdec.h).
 * Channels out of range, and axes read as counters (enc_counter), are
 * ignored. */
void drive_encoder_edge(unsigned ch, uint32_t lines, uint32_t t_ns);

/* A run of |steps| encoder edges in one direction on channel ch, the last
 * at t_last_ns (qdec_edge_run: Z low throughout). False when the channel
 * cannot take it as a run (out of range or a counter: ignored as
 * drive_encoder_edge ignores it; or qdec_edge_run refuses): deliver the
 * edges one by one instead. Same context as drive_encoder_edge. */
bool drive_encoder_run(unsigned ch, int32_t steps, uint32_t t_last_ns);

/* Decoded position of channel ch in counts (0 for a channel not in use). */
int64_t drive_encoder_count(unsigned ch);

/* Calibration (calib.h) is not called by the drive: the composition root
 * runs, per tick,
 *     const drive_tick_out_t *t = drive_tick(calib_sampling());
 *     if (t != NULL)
 *         calib_tick(t->st, t->vel_ref);
 * and in the main loop calib_poll() then drive_poll(); calib_init() after
 * a successful drive_init().
 * The reference-scale decoders read the absolute counter value at init
 * (position = counter * scale), like the encoder counts from 0 = position 0.
 *
 * Install (or remove, NULL) the compensation table of an axis's encoder
 * decoder (qdec_set_comp: one pointer store). Main. */
void drive_set_comp(unsigned axis, const comp_table_t *table);
/* True when the axis has a reference-scale input in use. Any. */
bool drive_has_refscale(unsigned axis);
/* Homing (the sequence: drive_home.h). Every axis of `axes` searches its
 * home switch, backs off to the switch edge and, for an axis in `index`,
 * goes on to the next encoder index; its position there becomes home_pos.
 * Feeds in nm/s (latch_nm_s <= search_nm_s), distances in nm. */
typedef struct {
    uint32_t axes;                /* bit i: home axis i (non-zero, < 1 << axes) */
    uint32_t negative;            /* bit i: the switch is toward -             */
    uint32_t index;               /* bit i: reference = index after the edge   */
    int64_t search_nm_s;          /* toward the switch, > 0                    */
    int64_t latch_nm_s;           /* back-off and index search, > 0            */
    int64_t max_dist_nm;          /* per phase, > 0: else DRIVE_FAULT_HOMING  */
    pos_nm_t home_pos[CORE_AXES]; /* position at the reference point, nm       */
} drive_home_t;

/* Start homing: only IDLE with nothing queued (DRIVE_E_BUSY otherwise,
 * DRIVE_E_DISABLED / DRIVE_E_FAULTED as drive_queue_block); feeds over an
 * axis's planner v_max or a bad mask: DRIVE_E_INVALID. The drive is
 * HOMING until every axis is homed, then (through STOPPING at rest) IDLE,
 * the axes' bits set in drive_status_t.homed. drive_stop aborts it (ramp
 * to rest, IDLE, unfinished axes not homed); a fault or e-stop ends it as
 * usual (FAULT); a switch or index not found latches DRIVE_FAULT_HOMING
 * (controlled stop, FAULT). Blocks are refused (BUSY) while homing. Main. */
drive_result_t drive_home(const drive_home_t *h);

/* Select the contour-error controller (refused while moving). Main. */
drive_result_t drive_set_cec_mode(drive_cec_mode_t mode);

/* Replace the servo parameters (gains, limits; validated with
 * servo_config; refused while moving; applied by the next tick; the CEC mode
 * in p is ignored: drive_set_cec_mode). Main. */
drive_result_t drive_set_servo_params(const servo_params_t *p);

/* The configuration in use (read-only). Any. */
const drive_config_t *drive_config(void);

/* Parameters: the planner's limits and rules (plan_profile_t, planner.h),
 * the controlled stop, arc segmentation and start delay, by id. Units are
 * those of drive_config_t / plan_profile_t. Per-axis ids take an axis
 * 0..axes-1, the others axis 0 (else DRIVE_E_INVALID).
 *   get    any time (the value in use).
 *   range  the values a set would accept now: the static range, narrowed by
 *          the S-curve's a_max / j_max <= SC_TJ_MAX_NS rule of the axis.
 *   set    only while the planner is idle: nothing queued or executing and
 *          not stopping (DISABLED, FAULT, or IDLE with empty queues), else
 *          DRIVE_E_BUSY; a value outside range, or a profile that
 *          plan_check_profile refuses (e.g. a shape change that breaks the
 *          a / j rule), gives DRIVE_E_INVALID. On any refusal nothing
 *          changes; on success the new profile is in use for the next block
 *          (the empty planner is re-initialised at its position).
 * drive_set_plan_profile replaces the whole profile the same way (all or
 * nothing). Main.
 * The servo parameters (KP .. FERR_LIMIT, CEC_KP .. CEC_KD: the CEC's
 * pid gains, FFL_RATE; appended so the ids param_store saved stay) change
 * servo_params_t of the axis
 * through drive_set_servo_params (validated with servo_config, refused with
 * DRIVE_E_BUSY while moving, applied by the tick's gains request); the
 * others (soft limits, in-position window, the feed-forward corrections
 * FRICTION_FF .. QG_COMP, drive_ff.h; ENC_MEAN, which a port without
 * hal_encoder_mean refuses with DRIVE_E_UNSUPPORTED) like the planner's. */
typedef enum {
    DRIVE_PARAM_V_MAX = 0,      /* per axis, nm/s          1000 .. SC_V_LIMIT   */
    DRIVE_PARAM_A_MAX,          /* per axis, nm/s^2   SC_A_MIN .. SC_A_LIMIT    */
    DRIVE_PARAM_J_MAX,          /* per axis, nm/s^3   SC_J_MIN .. SC_J_LIMIT    */
    DRIVE_PARAM_CORNER_DV,      /* per axis, nm/s             0 .. SC_V_LIMIT   */
    DRIVE_PARAM_CORNER_ACC,     /* per axis, nm/s^2           0 .. SC_A_LIMIT   */
    DRIVE_PARAM_JUNCTION_DEV,   /* nm                         0 .. 2^40         */
    DRIVE_PARAM_CORNER,         /* plan_corner_t              0 .. 3            */
    DRIVE_PARAM_SHAPE,          /* sc_shape_t                 0 .. 3            */
    DRIVE_PARAM_MIN_BLOCK_NS,   /* ns                         0 .. 10 s         */
    DRIVE_PARAM_MBT_WINDOW,     /* blocks                     1 .. PLAN_WINDOW_MAX */
    DRIVE_PARAM_STOP_DECEL,     /* nm/s^2 (drive_stop)     1000 .. SC_A_LIMIT   */
    DRIVE_PARAM_ARC_CHORD,      /* nm                         1 .. 1e9          */
    DRIVE_PARAM_START_DELAY_MS, /* ms                         0 .. DRIVE_START_DELAY_MS_MAX */
    DRIVE_PARAM_KP,             /* per axis, V/m q32_32       0 .. PID_GAIN_MAX - 1 */
    DRIVE_PARAM_KI,             /* per axis, V/(m*s) q32_32   0 .. PID_GAIN_MAX - 1 */
    DRIVE_PARAM_KD,             /* per axis, V*s/m q32_32     0 .. PID_GAIN_MAX - 1 */
    DRIVE_PARAM_KVFF,           /* per axis, V/(m/s) q32_32   0 .. PID_GAIN_MAX - 1 */
    DRIVE_PARAM_KAFF,           /* per axis, V/(m/s^2) q32_32 0 .. PID_GAIN_MAX - 1 */
    DRIVE_PARAM_FERR_LIMIT,     /* per axis, nm, 0: off       0 .. 2^31 - 1     */
    DRIVE_PARAM_SOFT_MIN,       /* per axis, nm   +-DRIVE_SOFT_LIMIT_NM          */
    DRIVE_PARAM_SOFT_MAX,       /* per axis, nm   +-DRIVE_SOFT_LIMIT_NM          */
    DRIVE_PARAM_IN_POS,         /* per axis, nm               1 .. DRIVE_IN_POS_NM_MAX */
    DRIVE_PARAM_CEC_KP,         /* CEC, V/m q32_32            0 .. PID_GAIN_MAX - 1 */
    DRIVE_PARAM_CEC_KI,         /* CEC, V/(m*s) q32_32        0 .. PID_GAIN_MAX - 1 */
    DRIVE_PARAM_CEC_KD,         /* CEC, V*s/m q32_32          0 .. PID_GAIN_MAX - 1 */
    DRIVE_PARAM_FRICTION_FF,    /* per axis, mV (friction_ff_mv) 0 .. DRIVE_FRICTION_FF_MV_MAX */
    DRIVE_PARAM_FRICTION_BAND,  /* nm/s (friction_ff_band_nm_s)  1 .. SC_V_LIMIT */
    DRIVE_PARAM_FF_ADVANCE,     /* ns (ff_advance_ns)         0 .. DRIVE_FF_ADVANCE_NS_MAX */
    DRIVE_PARAM_QG_COMP,        /* 0 / 1 (qg_comp)                               */
    DRIVE_PARAM_FFL_RATE,       /* 1/s (servo ffl_rate)       0 .. SERVO_FFL_RATE_MAX */
    DRIVE_PARAM_ENC_MEAN,       /* 0 / 1 (enc_mean; 1 refused: DRIVE_E_UNSUPPORTED) */
    DRIVE_PARAM_COUNT
} drive_param_t;

drive_result_t drive_param_get(drive_param_t id, unsigned axis, int64_t *value);
drive_result_t drive_param_range(drive_param_t id, unsigned axis, int64_t *lo, int64_t *hi);
drive_result_t drive_param_set(drive_param_t id, unsigned axis, int64_t value);
drive_result_t drive_set_plan_profile(const plan_profile_t *prof);

/* Set many parameters at once (param_store's load): every value checked
 * against its static range, the whole planner profile (plan_check_profile)
 * and the servo parameters (servo_config) before anything changes; then
 * applied like drive_param_set. All or nothing: DRIVE_E_INVALID or
 * DRIVE_E_BUSY (planner not idle) change nothing. Main. */
typedef struct {
    drive_param_t id;
    unsigned axis;
    int64_t value;
} drive_param_value_t;
drive_result_t drive_param_set_all(const drive_param_value_t *v, unsigned n);
/* The same one value at a time (param_store's load, no array): begin takes
 * the current configuration as the candidate, stage checks one value's
 * range and writes it into the candidate, commit checks and applies the
 * whole candidate as drive_param_set_all does. Main; set_all and
 * drive_param_set use the same candidate, so no other parameter call
 * between begin and commit. */
drive_result_t drive_param_begin(void);
drive_result_t drive_param_stage(drive_param_t id, unsigned axis, int64_t value);
drive_result_t drive_param_commit(void);
/* The range a staged value must lie in for commit to accept it: as
 * drive_param_range, narrowed by the candidate's values instead of those in
 * use (a staged max_jerk bounds a staged max_acceleration). Between begin
 * and commit only. Main. */
drive_result_t drive_param_staged_range(drive_param_t id, unsigned axis, int64_t *lo, int64_t *hi);

/* Soft travel limits (drive_config_t.soft_min / soft_max): DRIVE_E_LIMIT
 * when an axis that moves (target != from) ends outside the limits of the
 * axis; the axis is kept for drive_soft_limit_refused. Main. */
drive_result_t drive_soft_limit_check(const pos_nm_t target[CORE_AXES],
                                      const pos_nm_t from[CORE_AXES]);
/* Axis and limits of the last DRIVE_E_LIMIT refusal. Main. */
void drive_soft_limit_refused(unsigned *axis, int64_t *lo, int64_t *hi);

#endif /* DRIVE_H */
