/*
 * drive.c - the drive application (specification in drive.h).
 *
 * Ownership of the state (docs/tick-main.md): every field of drv says which
 * context writes it.
 *   main  host-block FIFO (hq_*), planner, arc segmentation, seg[] entries of
 *         segments not yet handed to the interpolator, the interpolator's
 *         producer side, requests (req_* and their payload).
 *   tick  decoders, servo loops, motion reference, the state (state, halted,
 *         faults), status snapshot, interpolator consumer side.
 *   init  set by drive_init before the tick runs (ready gates the tick).
 * Main requests changes through the req_* flags (main sets a flag, the tick
 * clears it when it applies it) and reads the state from the snapshot; the
 * tick never waits for main. Main resets the interpolator (both sides) only
 * while the tick is parked: DISABLED or FAULT with no enable pending, or
 * STOPPING at rest (halted) with no resume pending; the tick leaves those
 * states only on a request from main.
 */
#include "drive.h"

#include "calib.h"
#include "hal.h"
#include "interp.h"
#include "motion_ref.h"
#include "preempt.h"
#include "qdec.h"

#define SEG_RING 128u /* > planner depth + interpolator FIFO + 1 */
/* Keep at least this much planned time in the interpolator's FIFO beyond the
 * current segment when no block is waiting and the planner is not full. */
#define DRIVE_FEED_AHEAD_NS ((int64_t)5000000)
#define ANGLE_K             683565276ll /* 2^32 / (2 pi): binary angle per radian */
#define Q30                 ((int64_t)1 << 30)

typedef struct {
    uint32_t host_tag;
    bool last; /* last segment of its host block */
    bool arc;
    uint8_t u, v;
    int8_t sense;
    pos_nm_t cu, cv;
    pos_nm_t r_a, r_b; /* radius at the chord's ends   */
    fx_angle_t th_a;   /* angle of the chord's start   */
    int64_t dth;       /* signed sweep of the chord    */
    pos_nm_t au, av;   /* chord start in the plane     */
    pos_nm_t bu, bv;   /* chord end in the plane       */
    q1_30_t k_arc;     /* arc length / chord length    */
} seg_info_t;

typedef struct {
    drive_block_t b;
    /* arc generation state */
    uint32_t n_seg;
    uint32_t done_seg;
    pos_nm_t start[CORE_AXES];
    fx_angle_t th_s;
    int64_t sweep;
    pos_nm_t r_s, r_e;
    uint8_t u, v, w;
} host_block_t;

/* Per-chord constants and per-value caches of the arc overlay (tick
 * context). arc_fast() gives bit for bit the result of arc_overlay()
 * (the exact formulas) with 32-bit products where the ranges allow, the
 * chord fraction's division by a per-chord reciprocal with an exact
 * remainder correction, and the square roots and the division of the
 * speed terms only when their inputs change (constant while cruising). */
typedef struct {
    bool valid;     /* the chord fields are those of segment `tag`        */
    bool fast;      /* chord within the fast ranges (see arc_fast_setup)  */
    uint32_t tag;   /* interpolator segment tag (seq number)              */
    int32_t du, dv; /* chord vector in the plane, nm                       */
    uint8_t den_sh; /* ratio_q30's normalising shift of num and den       */
    uint32_t den_s; /* (du^2 + dv^2) >> den_sh, in [1, 2^32)              */
    int64_t den;    /* du^2 + dv^2                                        */
    uint64_t rec;   /* floor(2^62 / den_s)                                */
    /* value caches: v_uv of (vel_u, vel_v); a_c of (v_uv, rad) */
    bool v_ok, ac_ok;
    int64_t v_key_u, v_key_v, v_uv;
    int64_t ac_key_v, ac_key_r, a_c;
} arc_fast_t;

/* Rotation recurrence of the arc overlay on cruise ticks (see drive.h,
 * "Arc overlay on cruise ticks"). Tick context. The angle's cosine and sine
 * (C, S, q62) are rotated each tick by the phase's constant step delta:
 *     C' = C - c (1 - cos delta) - s sin delta
 *     S' = S - s (1 - cos delta) + c sin delta
 * where c, s are C, S rounded to q30 (the outputs' values) and the two
 * constants are q62 split as h 2^31 + l (0 <= l < 2^31): two SMULL/SMLAL
 * pairs per component, constant shifts. */
typedef struct {
    bool on;       /* C, S hold the last tick's arc point          */
    uint32_t left; /* steps before the next exact anchor          */
    int64_t C, S;  /* cos and sin of the angle, q62               */
    q1_30_t c, s;  /* ... rounded to q30                           */
    int64_t R;     /* radius, q32 nm                               */
    int32_t rad;   /* radius, nm (circle: constant)                */
    int32_t v_uv;  /* path speed in the plane, nm/s                */
    /* output factors (q30 products with c or s): velocity -+v_uv,
     * acceleration -v_uv^2 / rad (circle: constant), tangent -+m */
    int32_t kvu, kvv, ka, kmu, kmv;
    uint8_t u, v;    /* the plane's axes                        */
    pos_nm_t cu, cv; /* the centre                              */
    /* step constants of a phase, and their key */
    bool k_ok;
    int64_t k_dth, k_ds, k_len, k_dr;
    int32_t dh, dl; /* sin delta, q62: dh 2^31 + dl             */
    int32_t eh, el; /* 1 - cos delta, q62: eh 2^31 + el         */
    int64_t dR;     /* radius change per tick, q32 nm (0: circle) */
} arc_rot_t;

static plan_block_t plan_store[PLAN_DEPTH_DEFAULT];

static struct {
    CORE_SHARED bool ready; /* init */
    /* init; main changes the planner fields, stop_decel, arc_chord and
     * start_delay only with the planner idle and no stop pending, and servo
     * with a gains request (the tick reads tick_hz, axes, enc_counter,
     * friction, and stop_decel when it applies a stop) */
    drive_config_t cfg;
    /* main only */
    plan_t plan;
    host_block_t hq[DRIVE_QUEUE_DEPTH];
    uint16_t hq_head, hq_count;
    pos_nm_t q_end[CORE_AXES]; /* end point of the last accepted block */
    uint32_t seq_next;         /* internal tag of the next planner block */
    uint32_t queued_at;        /* tick_lo when the last block was accepted */
    drive_cec_mode_t cec_mode;
    /* main, read by the tick */
    seg_info_t seg[SEG_RING];              /* written before the segment's interp slot */
    CORE_SHARED uint32_t blocks_done_main; /* blocks skipped by the planner */
    /* host blocks and planner blocks not yet in the interpolator (hq_count +
     * plan_count), updated after the interpolator's wr: the tick derives
     * RUNNING from it and the interpolator, with no IDLE gap in between */
    CORE_SHARED uint32_t main_queued;
    interp_t ip; /* producer side main, consumer side tick (interp.h) */
    /* Requests: main writes the payload, CORE_BARRIER(), sets the flag, then
     * req_any; the tick clears a flag when it applies it. */
    CORE_SHARED bool req_enable; /* main flushed (DISABLED): switch on    */
    CORE_SHARED bool req_resume; /* main flushed (halted): STOPPING->IDLE */
    CORE_SHARED bool req_disable, req_stop, req_estop, req_reset, req_gains, req_cec;
    CORE_SHARED bool req_ref; /* main (drive_status): sample the reference scales */
    CORE_SHARED uint32_t req_fault;
    /* some req_* above (except req_ref) may be set: main sets it after the
     * flag itself, the tick clears it before it reads the flags (and sets it
     * again while a request stays pending), so the tick skips
     * apply_requests on the usual tick */
    CORE_SHARED bool req_any;
    uint32_t rs_seq;      /* main, payload of req_enable / req_resume:
                           * seq_next at the flush */
    servo_params_t pend;  /* main, payload of req_gains */
    cec_mode_t pend_mode; /* main, payload of req_cec   */
    /* tick, read by main (the snapshot, or the state as main_state() reads it) */
    CORE_SHARED drive_state_t state;
    CORE_SHARED bool halted; /* controlled stop reached rest: reference held */
    /* tick only (main reads some inside the snapshot's sequence count) */
    qdec_t enc[CORE_AXES];
    qdec_t refs[CORE_AXES]; /* configuration and scaling only (see ref_*) */
    bool ref_on[CORE_AXES];
    /* Reference scales: only their position is ever read (published as
     * refscale), so the tick keeps just the counter's unwrapped count
     * (what qdec_sample_counter accumulates) and scales it. */
    uint32_t ref_raw[CORE_AXES]; /* counter value at the last sample   */
    int64_t ref_cnt[CORE_AXES];  /* counts since init                   */
    pos_nm_t ref_nm[CORE_AXES];  /* position, nm (published)            */
    servo_t servo;
    motion_ref_t ref;
    uint32_t faults;
    int64_t stop_v;  /* stopping: path speed cap, nm/s               */
    int64_t stop_dv; /* stopping: cap decrease per tick, nm/s        */
    int64_t v_plan;  /* interpolator's (unscaled) path speed, nm/s   */
    int64_t a_plan;  /* ... and tangential acceleration, nm/s^2      */
    /* The interpolator's (chord) reference of the last tick: written by
     * interp_tick only (a fast-path tick writes only its pos[]); drv.ref is
     * built from it (reference_step), then the arc overlay, the stop
     * scaling and the friction feed-forward adjust drv.ref. */
    motion_ref_t ch;
    /* drv.ref holds every field of ch except those the arc overlay rewrites
     * every tick of an arc segment (pos and the plane axes' vel, acc and
     * tangent, the geometry's arc fields): nothing else changed it since the
     * last full copy. A fast-path tick then copies only pos. */
    bool ref_synced;
    bool ref_full;                /* test hook (drive_test_full_ref): no pos-only copy */
    int64_t v_act;                /* path speed of the reference last tick, nm/s  */
    q1_30_t hyp_tu, hyp_tv;       /* arc overlay: last in-plane chord tangent ... */
    q1_30_t hyp_m;                /* ... and its length (constant per segment)   */
    arc_fast_t arc;               /* arc overlay: per-segment constants (tick)    */
    arc_rot_t rot;                /* arc overlay: cruise recurrence (tick)        */
    bool arc_exact;               /* test hook: no recurrence (drive_test_arc_exact) */
    bool ff_on;                   /* some cfg.friction_ff_mv[] != 0 (drive_init)  */
    bool enc_any_counter;         /* some axis in use has enc_counter (drive_init) */
    CORE_SHARED uint32_t tick_lo; /* low word of tick (main reads it) */
    uint32_t seen_done;           /* interpolator segments accounted */
    uint32_t seq_done;            /* internal tag of the next segment to complete */
    uint32_t blocks_done;
    uint32_t cur_tag;
    uint64_t tick;
    /* published snapshot (tick; main reads it under st_seq) */
    CORE_SHARED uint32_t st_seq;
    drive_status_t st;
} drv;

/* ---- helpers ------------------------------------------------------------- */

static int64_t abs64(int64_t v)
{
    return v < 0 ? -v : v;
}

/* round(num / den * 2^30) for 0 <= num, 0 < den; saturates at 2^30. */
static int64_t ratio_q30(int64_t num, int64_t den)
{
    if (den <= 0 || num <= 0) {
        return 0;
    }
    if (num >= den) {
        return Q30;
    }
    while (den >= ((int64_t)1 << 32)) {
        num >>= 1;
        den >>= 1;
    }
    if (den == 0) {
        return 0;
    }
    return fx_div_round64(num << 30, den);
}

static void plane_axes(drive_plane_t p, uint8_t *u, uint8_t *v, uint8_t *w)
{
    switch (p) {
    case DRIVE_PLANE_ZX:
        *u = 2;
        *v = 0;
        *w = 1;
        break;
    case DRIVE_PLANE_YZ:
        *u = 1;
        *v = 2;
        *w = 0;
        break;
    default:
        *u = 0;
        *v = 1;
        *w = 2;
        break;
    }
}

/* The encoder, motor, reference, reference-scale, contour-error and block
 * fields of the status, from the state the tick owns (nothing else writes
 * it: qdec outputs, servo outputs, the reference handed to the servo, the
 * reference scales, the CEC estimate, blocks done and tag; drive_init
 * publishes after setting them) plus main's count of blocks it completed
 * (blocks_done_main: the snapshot runs in main). */
static CORE_NO_TSAN void status_live(drive_status_t *s)
{
    unsigned i;
    for (i = 0; i < drv.cfg.axes; i++) {
        const qdec_t *e = &drv.enc[i];
        s->ref[i] = drv.ref.pos[i];
        s->vel_ref[i] = drv.ref.vel[i];
        s->pos[i] = e->out.pos_nm;
        s->pos_raw[i] = e->out.pos_nm_raw;
        s->encoder_illegal[i] = e->out.illegal;
        s->motor_mv[i] = drv.servo.out_mv[i];
    }
    for (i = 0; i < CORE_AXES; i++) {
        s->refscale[i] = drv.ref_on[i] ? drv.ref_nm[i] : 0;
    }
    s->contour_error_nm = drv.servo.cec.active ? drv.servo.cec.ec_nm[0] : 0;
    s->blocks_done = drv.blocks_done + drv.blocks_done_main;
    s->tag = drv.cur_tag;
}

/* End of the tick's status update (drive_tick made st_seq odd at its
 * start). The fields status_live() gives are read by the snapshot from the
 * live state (the tick changes them only inside its odd st_seq window), and
 * copied here only while calibration samples them (calib_tick reads pos,
 * pos_raw and refscale); the rest is published every tick. Axes beyond
 * cfg.axes: all zero (drive_init zeroes st; cfg.axes is set only there). */
static void publish(bool sampling)
{
    drive_status_t *s = &drv.st;
    s->state = drv.state;
    s->faults = drv.faults;
    s->tick = drv.tick;
    if (sampling) {
        status_live(s);
    }
    drv.st_seq++;
}

/* ---- configuration --------------------------------------------------------- */

void drive_config_default(drive_config_t *cfg, uint32_t tick_hz, unsigned axes)
{
    drive_config_t zero = {0};
    unsigned i;
    *cfg = zero;
    cfg->tick_hz = tick_hz;
    cfg->axes = axes;
    for (i = 0; i < CORE_AXES; i++) {
        cfg->nm_per_count_num[i] = 1;
        cfg->nm_per_count_den[i] = 1;
        cfg->ref_nm_per_count_den[i] = 1;
        cfg->plan.v_max[i] = 1000000000;      /* 1 m/s      */
        cfg->plan.a_max[i] = 10000000000;     /* 10 m/s^2   */
        cfg->plan.j_max[i] = 1000000000000;   /* 1000 m/s^3 */
        cfg->plan.corner_dv[i] = 10000000;    /* 10 mm/s    */
        cfg->plan.corner_acc[i] = 1000000000; /* 1 m/s^2    */
    }
    cfg->plan.junction_dev_nm = 10000;
    cfg->plan.mbt_window = 1;
    cfg->plan.corner = PLAN_CORNER_JD;
    cfg->plan.shape = SC_SHAPE_SCURVE;
    servo_params_default(&cfg->servo, tick_hz);
    cfg->servo.axes = axes;
    cfg->stop_decel_nm_s2 = 1000000000;   /* 1 m/s^2 */
    cfg->friction_ff_band_nm_s = 1000000; /* 1 mm/s */
    cfg->arc_chord_nm = DRIVE_ARC_CHORD_NM;
    cfg->start_delay_ms = DRIVE_START_DELAY_MS;
}

static const servo_io_t drive_io = {hal_motor_set_mv, hal_motor_enable, hal_amp_fault};

drive_result_t drive_init(const drive_config_t *cfg)
{
    unsigned i;
    drive_status_t zero_st = {0};
    motion_ref_t zero_ref = {0};
    pos_nm_t origin[CORE_AXES] = {0};
    uint32_t now_ns;

    if (cfg == NULL || cfg->axes < 1 || cfg->axes > CORE_AXES || cfg->tick_hz < PID_TICK_HZ_MIN ||
        cfg->tick_hz > PID_TICK_HZ_MAX || cfg->stop_decel_nm_s2 <= 0 || cfg->arc_chord_nm < 0 ||
        cfg->start_delay_ms > DRIVE_START_DELAY_MS_MAX ||
        plan_check_profile(&cfg->plan) != PLAN_OK) {
        return DRIVE_E_INVALID;
    }
    drv.ready = false;
    drv.cfg = *cfg;
    drv.ff_on = false; /* friction_ff_mv and enc_counter are set only here */
    drv.enc_any_counter = false;
    for (i = 0; i < CORE_AXES; i++) {
        drv.ff_on = drv.ff_on || drv.cfg.friction_ff_mv[i] != 0;
        drv.enc_any_counter = drv.enc_any_counter || (i < cfg->axes && cfg->enc_counter[i]);
    }
    if (drv.cfg.arc_chord_nm == 0) {
        drv.cfg.arc_chord_nm = DRIVE_ARC_CHORD_NM;
    }
    now_ns = hal_time_us() * 1000u;
    for (i = 0; i < CORE_AXES; i++) {
        drv.ref_on[i] = false;
        if (i >= cfg->axes) {
            continue;
        }
        {
            qdec_config_t qc;
            uint32_t init;
            qdec_config_default(&qc);
            qc.nm_per_count_num = cfg->nm_per_count_num[i];
            qc.nm_per_count_den = cfg->nm_per_count_den[i];
            qc.illegal_limit = 1;
            qc.illegal_window_ns = 1000000000ull;
            init = cfg->enc_initial_lines[i];
            if (cfg->enc_counter[i]) {
                /* counter input: the port must have the counter */
                qc.input = QDEC_INPUT_COUNTER;
                qc.counter_bits = 32;
                if (!hal_encoder_counter(i, &init)) {
                    return DRIVE_E_INVALID;
                }
            }
            if (!qdec_init(&drv.enc[i], &qc, init, now_ns)) {
                return DRIVE_E_INVALID;
            }
        }
        if (cfg->ref_nm_per_count_num[i] != 0) {
            qdec_config_t qc;
            uint32_t raw;
            if (hal_encoder_counter(cfg->axes + i, &raw)) {
                qdec_config_default(&qc);
                qc.input = QDEC_INPUT_COUNTER;
                qc.counter_bits = 32;
                qc.nm_per_count_num = cfg->ref_nm_per_count_num[i];
                qc.nm_per_count_den = cfg->ref_nm_per_count_den[i];
                if (!qdec_init(&drv.refs[i], &qc, raw, now_ns)) {
                    return DRIVE_E_INVALID;
                }
                /* absolute: the counter's value is the scale's position */
                qdec_set_offset_nm(&drv.refs[i],
                                   qdec_counts_to_nm(&drv.refs[i], (int64_t)(int32_t)raw));
                drv.ref_raw[i] = raw;
                drv.ref_cnt[i] = 0;
                drv.ref_nm[i] = drv.refs[i].out.pos_nm; /* until the first sample */
                drv.ref_on[i] = true;
            }
        }
    }
    drv.cfg.servo.axes = cfg->axes;
    drv.cfg.servo.tick_hz = cfg->tick_hz;
    drv.cfg.servo.cec.mode = CEC_MODE_OFF;
    if (servo_init(&drv.servo, &drv.cfg.servo, &drive_io) != SERVO_OK) {
        return DRIVE_E_INVALID;
    }
    /* one HAL call per tick for all outputs and all fault inputs */
    servo_set_io_all(&drv.servo, hal_motor_set_mv_all, hal_amp_fault_mask);
    if (plan_init(&drv.plan, plan_store, PLAN_DEPTH_DEFAULT, &cfg->plan, origin) != PLAN_OK) {
        return DRIVE_E_INVALID;
    }
    interp_init(&drv.ip, (int64_t)(1000000000u / cfg->tick_hz), origin);
    drv.ref = zero_ref;
    drv.ch = zero_ref;
    drv.ref_synced = false;
    drv.ref_full = false;
    drv.hq_head = 0;
    drv.hq_count = 0;
    for (i = 0; i < CORE_AXES; i++) {
        drv.q_end[i] = 0;
    }
    drv.seq_next = 0;
    drv.queued_at = 0;
    drv.tick_lo = 0;
    drv.stop_v = drv.stop_dv = drv.v_plan = drv.a_plan = drv.v_act = 0;
    drv.hyp_tu = drv.hyp_tv = drv.hyp_m = 0; /* fx_hypot2(0, 0) == 0 */
    drv.arc.valid = drv.arc.v_ok = drv.arc.ac_ok = false;
    drv.rot.on = drv.rot.k_ok = false;
    drv.arc_exact = false;
    drv.seq_done = 0;
    drv.seen_done = 0;
    drv.blocks_done = 0;
    drv.cur_tag = 0;
    drv.req_enable = drv.req_disable = drv.req_stop = false;
    drv.req_estop = drv.req_reset = drv.req_gains = drv.req_cec = false;
    drv.req_fault = 0;
    drv.req_resume = false;
    drv.rs_seq = 0;
    drv.main_queued = 0;
    drv.blocks_done_main = 0;
    drv.req_any = false;
    drv.req_ref = false;
    drv.halted = false;
    drv.state = DRIVE_DISABLED;
    drv.faults = 0;
    drv.cec_mode = DRIVE_CEC_OFF;
    drv.tick = 0;
    drv.st = zero_st;
    drv.st_seq = 1; /* publish() below ends the update: 2 */
    for (i = 0; i < cfg->axes; i++) {
        hal_motor_enable(i, false);
        hal_motor_set_mv(i, 0);
    }
    drv.ready = true;
    publish(calib_sampling());
    calib_init();
    return DRIVE_OK;
}

const drive_config_t *drive_config(void)
{
    return &drv.cfg;
}

/* ---- tick ------------------------------------------------------------------ */

/* fx_mul64_shift(a, b, 0) (a * b saturated to int64), one SMULL when both
 * fit 32 bits (the product is then below 2^62: exact, no saturation). */
static inline int64_t mul_sat64(int64_t a, int64_t b)
{
    if (a == (int32_t)a && b == (int32_t)b) {
        return (int64_t)(int32_t)a * (int32_t)b;
    }
    return fx_mul64_shift(a, b, 0);
}

/* round(a * b / 2^30) (shift rule): fx_mul64x32_shift(a, b, 30), one SMULL
 * when a fits 32 bits (the product is then below 2^62: exact). */
static inline int64_t mul_q30(int64_t a, int32_t b)
{
    if (a == (int32_t)a) {
        return ((int64_t)(int32_t)a * b + ((int64_t)1 << 29)) >> 30;
    }
    return fx_mul64x32_shift(a, b, 30);
}

/* mul_q30 for an int32 a: one SMLAL. */
static inline int64_t mul32_q30(int32_t a, int32_t b)
{
    return ((int64_t)a * b + ((int64_t)1 << 29)) >> 30;
}

/* Per-chord constants of the fast arc overlay. The fast path needs the
 * chord start, end and vector in the plane and the radius within int32
 * (|.| < 2.1 m), a non-degenerate chord and |dth| <= the maximum chord
 * angle; other chords take arc_overlay() every tick. */
static void arc_fast_setup(arc_fast_t *a, const seg_info_t *g)
{
    int64_t du = g->bu - g->au, dv = g->bv - g->av, den;
    unsigned sh = 0;

    a->valid = true;
    a->tag = drv.ip.tag;
    a->fast = false;
    if (du != (int32_t)du || dv != (int32_t)dv || g->au != (int32_t)g->au ||
        g->av != (int32_t)g->av || g->r_a != (int32_t)g->r_a || g->r_b != (int32_t)g->r_b ||
        (g->r_b - g->r_a) != (int32_t)(g->r_b - g->r_a) ||
        abs64(g->dth) > (int64_t)DRIVE_ARC_SEG_MAX_ANGLE) {
        return;
    }
    den = (int64_t)du * du + (int64_t)dv * dv; /* < 2^63: exact, as mul_sat64 */
    if (den <= 0) {
        return;
    }
    a->du = (int32_t)du;
    a->dv = (int32_t)dv;
    a->den = den;
    while ((den >> sh) >= ((int64_t)1 << 32)) {
        sh++;
    }
    a->den_sh = (uint8_t)sh;
    a->den_s = (uint32_t)(den >> sh);
    a->rec = fx_recip62(a->den_s);
    a->fast = true;
}

/* The reference's geometry: the arc of chord g at radius rad. */
static inline void arc_geom(motion_ref_t *r, const seg_info_t *g, int64_t rad)
{
    r->geom.kind = MOTION_GEOM_ARC;
    r->geom.plane_u = g->u;
    r->geom.plane_v = g->v;
    r->geom.centre_u = g->cu;
    r->geom.centre_v = g->cv;
    r->geom.radius = rad;
    r->geom.sense = g->sense;
}

/* Length of the chord tangent's in-plane part (q30), recomputed only when
 * the tangent changes (once per segment). */
static inline q1_30_t chord_tangent_len(const motion_ref_t *ch, uint8_t u, uint8_t v)
{
    if (ch->geom.tangent[u] != drv.hyp_tu || ch->geom.tangent[v] != drv.hyp_tv) {
        drv.hyp_tu = ch->geom.tangent[u];
        drv.hyp_tv = ch->geom.tangent[v];
        drv.hyp_m = (q1_30_t)fx_hypot2(drv.hyp_tu, drv.hyp_tv);
    }
    return drv.hyp_m;
}

/* v^2 / rad (nm/s^2, division rule; 0 for rad <= 0) as arc_overlay()
 * computes it, cached while v and rad are unchanged. */
static inline int64_t arc_centripetal(arc_fast_t *a, int64_t v_uv, int64_t rad)
{
    if (rad <= 0) {
        return 0;
    }
    if (!a->ac_ok || a->ac_key_v != v_uv || a->ac_key_r != rad) {
        a->ac_key_v = v_uv;
        a->ac_key_r = rad;
        if (v_uv < ((int64_t)1 << 31)) {
            a->a_c = fx_div_round64(v_uv * v_uv, rad);
        } else {
            a->a_c = fx_div_round64(fx_mul64_shift(v_uv, v_uv, 16), rad) << 16;
        }
        a->ac_ok = true;
    }
    return a->a_c;
}

/* arc_overlay() for a chord with arc_fast_t.fast: the same result, bit for
 * bit (see arc_fast_t). False (nothing written) when a value leaves the
 * fast ranges; the caller then runs arc_overlay(). geom_kept: r->geom holds
 * what the arc code wrote for chord g last tick (a pos-only reference copy
 * of the same segment): only the radius can differ. */
static bool arc_fast(motion_ref_t *r, const motion_ref_t *ch, const seg_info_t *g, arc_fast_t *a,
                     bool geom_kept, q1_30_t *so, q1_30_t *co, int64_t *rado)
{
    uint8_t u = g->u, v = g->v;
    int64_t pu = ch->pos[u] - g->au, pv = ch->pos[v] - g->av;
    int64_t num, f, p, rad, v_uv, a_t, a_c;
    fx_angle_t th;
    q1_30_t s, c, m, tu, tv;

    if (pu != (int32_t)pu || pv != (int32_t)pv) {
        return false;
    }
    /* f = ratio_q30(num, den): round(num_s * 2^30 / den_s) after the same
     * normalising shift, by the reciprocal and an exact remainder */
    num = (int64_t)(int32_t)pu * a->du + (int64_t)(int32_t)pv * a->dv;
    if (num <= 0) {
        f = 0;
    } else if (num >= a->den) {
        f = Q30;
    } else {
        /* num < den: num >> den_sh <= den_s < 2^32 */
        f = fx_div_q30_rec((uint32_t)(num >> a->den_sh), a->den_s, a->rec);
    }
    p = (int64_t)(int32_t)g->dth * f; /* |.| < 2^57 */
    th = g->th_a + (fx_angle_t)(uint64_t)((p >> 30) + ((p >> 29) & 1));
    if (g->r_b == g->r_a) {
        rad = g->r_a; /* a circle: round(0 * f / 2^30) == 0 */
    } else {
        p = (int64_t)(int32_t)(g->r_b - g->r_a) * f;
        rad = g->r_a + ((p >> 30) + ((p >> 29) & 1));
    }
    fx_sincos(th, &s, &c);
    /* rad lies between r_a and r_b, both int32 (arc_fast_setup) */
    r->pos[u] = g->cu + mul32_q30((int32_t)rad, c);
    r->pos[v] = g->cv + mul32_q30((int32_t)rad, s);
    /* unit tangent in the plane, scaled by the chord tangent's in-plane part */
    m = chord_tangent_len(ch, u, v);
    tu = (q1_30_t)(g->sense > 0 ? -s : s);
    tv = (q1_30_t)(g->sense > 0 ? c : -c);
    /* path speed and tangential acceleration in the plane (arc / chord) */
    if (!a->v_ok || a->v_key_u != ch->vel[u] || a->v_key_v != ch->vel[v]) {
        a->v_key_u = ch->vel[u];
        a->v_key_v = ch->vel[v];
        a->v_uv = fx_mul64x32_shift(fx_hypot2(ch->vel[u], ch->vel[v]), g->k_arc, 30);
        a->v_ok = true;
    }
    v_uv = a->v_uv;
    if (ch->acc[u] == 0 && ch->acc[v] == 0) {
        a_t = 0; /* fx_hypot2(0, 0) */
    } else {
        int64_t dot = fx_sat_add64(fx_mul64x32_shift(ch->acc[u], ch->geom.tangent[u], 30),
                                   fx_mul64x32_shift(ch->acc[v], ch->geom.tangent[v], 30));
        a_t = fx_mul64x32_shift(fx_hypot2(ch->acc[u], ch->acc[v]), g->k_arc, 30);
        if (dot < 0) {
            a_t = -a_t;
        }
    }
    a_c = arc_centripetal(a, v_uv, rad);
    *so = s;
    *co = c;
    *rado = rad;
    r->vel[u] = mul_q30(v_uv, tu);
    r->vel[v] = mul_q30(v_uv, tv);
    if (a_t == 0) { /* cruising: mul_q30(0, x) == 0 */
        r->acc[u] = -mul_q30(a_c, c);
        r->acc[v] = -mul_q30(a_c, s);
    } else {
        r->acc[u] = mul_q30(a_t, tu) - mul_q30(a_c, c);
        r->acc[v] = mul_q30(a_t, tv) - mul_q30(a_c, s);
    }
    r->geom.tangent[u] = (q1_30_t)mul32_q30(tu, m);
    r->geom.tangent[v] = (q1_30_t)mul32_q30(tv, m);
    if (geom_kept) {
        r->geom.radius = rad;
    } else {
        arc_geom(r, g, rad);
    }
    return true;
}

/* Replace the interpolator's chord reference by the exact arc. */
static void arc_overlay(motion_ref_t *r, const motion_ref_t *ch, const seg_info_t *g)
{
    uint8_t u = g->u, v = g->v;
    int64_t du = g->bu - g->au, dv = g->bv - g->av;
    int64_t pu = ch->pos[u] - g->au, pv = ch->pos[v] - g->av;
    int64_t num = fx_sat_add64(mul_sat64(pu, du), mul_sat64(pv, dv));
    int64_t den = fx_sat_add64(mul_sat64(du, du), mul_sat64(dv, dv));
    int64_t f = ratio_q30(num, den);
    fx_angle_t th = g->th_a + (fx_angle_t)(uint64_t)fx_round_shift64(g->dth * f, 30);
    int64_t rad = g->r_a + fx_round_shift64((g->r_b - g->r_a) * f, 30);
    q1_30_t s, c, m, tu, tv;
    int64_t v_uv, a_t, a_c, dot;

    fx_sincos(th, &s, &c);
    r->pos[u] = g->cu + fx_mul64x32_shift(rad, c, 30);
    r->pos[v] = g->cv + fx_mul64x32_shift(rad, s, 30);
    /* unit tangent in the plane, scaled by the chord tangent's in-plane part */
    m = chord_tangent_len(ch, u, v);
    tu = (q1_30_t)(g->sense > 0 ? -s : s);
    tv = (q1_30_t)(g->sense > 0 ? c : -c);
    /* path speed and tangential acceleration in the plane (arc / chord) */
    v_uv = fx_mul64x32_shift(fx_hypot2(ch->vel[u], ch->vel[v]), g->k_arc, 30);
    dot = fx_sat_add64(fx_mul64x32_shift(ch->acc[u], ch->geom.tangent[u], 30),
                       fx_mul64x32_shift(ch->acc[v], ch->geom.tangent[v], 30));
    a_t = fx_mul64x32_shift(fx_hypot2(ch->acc[u], ch->acc[v]), g->k_arc, 30);
    if (dot < 0) {
        a_t = -a_t;
    }
    if (rad > 0) {
        if (v_uv < ((int64_t)1 << 31)) {
            a_c = fx_div_round64(v_uv * v_uv, rad);
        } else {
            a_c = fx_div_round64(fx_mul64_shift(v_uv, v_uv, 16), rad) << 16;
        }
    } else {
        a_c = 0;
    }
    r->vel[u] = fx_mul64x32_shift(v_uv, tu, 30);
    r->vel[v] = fx_mul64x32_shift(v_uv, tv, 30);
    r->acc[u] = fx_mul64x32_shift(a_t, tu, 30) - fx_mul64x32_shift(a_c, c, 30);
    r->acc[v] = fx_mul64x32_shift(a_t, tv, 30) - fx_mul64x32_shift(a_c, s, 30);
    r->geom.tangent[u] = (q1_30_t)fx_mul64x32_shift(tu, m, 30);
    r->geom.tangent[v] = (q1_30_t)fx_mul64x32_shift(tv, m, 30);
    arc_geom(r, g, rad);
}

/* ---- arc overlay: rotation recurrence on cruise ticks ----------------------- */

#define PI_HALF_Q61   3622009729038561421ll  /* round(pi / 2 * 2^61) */
#define RECIP_1E9_Q64 18446744073ull         /* floor(2^64 / 1e9) */
#define RECIP_6_Q64   3074457345618258602ull /* floor(2^64 / 6) */
#define RECIP_24_Q64  768614336404564650ull  /* floor(2^64 / 24) */
#define RECIP_120_Q64 153722867280912930ull  /* floor(2^64 / 120) */
#define RECIP_720_Q64 25620477880152155ull   /* floor(2^64 / 720) */

/* floor(a * b / 2^64), exact (four 32 x 32 -> 64 products). */
static uint64_t umulhi64(uint64_t a, uint64_t b)
{
    uint64_t al = (uint32_t)a, ah = a >> 32, bl = (uint32_t)b, bh = b >> 32;
    uint64_t p0 = al * bl, p1 = al * bh, p2 = ah * bl, p3 = ah * bh;
    uint64_t mid = (p0 >> 32) + (uint32_t)p1 + (uint32_t)p2;

    return p3 + (p1 >> 32) + (p2 >> 32) + (mid >> 32);
}

/* v (q62, |v| < 2^61) as h 2^31 + l with 0 <= l < 2^31. */
static void rot_split(int64_t v, int32_t *h, int32_t *l)
{
    *h = (int32_t)(v >> 31);
    *l = (int32_t)(v & 0x7FFFFFFF);
}

/* floor((x (h 2^31 + l) + y (h2 2^31 + l2)) / 2^30) to within 1: the sum of
 * two q30 values (|x|, |y| <= 2^30) times split q62 constants (|h|, |h2|
 * <= 2^30), in q62. */
static inline int64_t rot_mul2(int32_t x, int32_t h, int32_t l, int32_t y, int32_t h2, int32_t l2)
{
    int64_t hi = (int64_t)x * h + (int64_t)y * h2; /* |.| <= 2^61 */
    int64_t lo = (int64_t)x * l + (int64_t)y * l2; /* |.| < 2^62  */

    return hi * 2 + (lo >> 30);
}

/* Step constants of the interpolator's cruise phase on chord g (segment
 * length len, nm): the path advances by ds = (cr_dq + cr_dr / 1e9) * 2^16
 * * (1 + corr / 2^32) q32 nm per fast-path tick (to within 2 q16 units,
 * not accumulated: see interp.h), the chord fraction by ds / (len 2^32),
 * the angle by delta = dth ds / len (binary angle * 2^32, rounded) and the
 * radius by dR = (r_b - r_a) ds / len (q32 nm). sin and 1 - cos of delta
 * (|delta| <= pi/32 rad) by their Taylor series to x^5 and x^6 (remainders
 * below x^7 / 5040 and x^8 / 40320: 2e-11 and 3e-13 at pi/32), in q62.
 * Cached while the key (dth, ds, len, r_b - r_a) is unchanged. False when
 * out of range (no recurrence). */
static bool arc_rot_consts(arc_rot_t *t, const seg_info_t *g, int64_t len)
{
    const interp_t *ip = &drv.ip;
    int64_t ds, d;
    uint64_t x, x2, x3, x4, sn, e;
    int64_t dr = g->r_b - g->r_a;

    if (ip->cr_dq >= ((uint64_t)1 << 46) || len <= 0) {
        return false;
    }
    /* cr_dr / 1e9 * 2^16 (< 2^16) by the reciprocal: within 1 of the exact
     * floor, 2.3e-10 nm */
    ds = (int64_t)(ip->cr_dq << 16) + (int64_t)umulhi64((uint64_t)ip->cr_dr << 16, RECIP_1E9_Q64);
    ds += fx_mul64x32_shift(ds, (int32_t)ip->corr_q32, 32);
    if (t->k_ok && t->k_dth == g->dth && t->k_ds == ds && t->k_len == len && t->k_dr == dr) {
        return true;
    }
    t->k_ok = false;
    d = fx_muldiv64(g->dth, ds, len);
    if (abs64(d) > ((int64_t)DRIVE_ARC_SEG_MAX_ANGLE << 32)) {
        return false;
    }
    /* |delta| in rad, q64 (< 2^61), and the series in q64 by high products
     * (each within 2 units of q64 of the exact floor: 1e-19) */
    x = (uint64_t)fx_mul64_shift(abs64(d), PI_HALF_Q61, 61) << 2;
    x2 = umulhi64(x, x);
    x3 = umulhi64(x2, x);
    x4 = umulhi64(x2, x2);
    sn = x - umulhi64(x3, RECIP_6_Q64) + umulhi64(umulhi64(x4, x), RECIP_120_Q64);
    e = (x2 >> 1) - umulhi64(x4, RECIP_24_Q64) + umulhi64(umulhi64(x4, x2), RECIP_720_Q64);
    sn >>= 2; /* q62 */
    e >>= 2;
    rot_split(d < 0 ? -(int64_t)sn : (int64_t)sn, &t->dh, &t->dl);
    rot_split((int64_t)e, &t->eh, &t->el);
    t->dR = dr == 0 ? 0 : fx_muldiv64(dr, ds, len);
    t->k_dth = g->dth;
    t->k_ds = ds;
    t->k_len = len;
    t->k_dr = dr;
    t->k_ok = true;
    return true;
}

/* Anchor the recurrence on this tick's exact arc point (sine s, cosine c,
 * radius rad from arc_fast) when the interpolator's next ticks may take
 * its cruise fast path (interp_t.cr_fast). */
static void arc_rot_anchor(arc_rot_t *t, const seg_info_t *g, q1_30_t s, q1_30_t c, int64_t rad)
{
    int64_t v_uv = drv.arc.v_uv, a_c = drv.arc.a_c;

    t->on = false;
    /* arc_fast filled the caches for this v_uv and rad; 32-bit products
     * below need v_uv and v_uv^2 / r (here and along the chord) < 2^31 */
    if (drv.arc_exact || !drv.ip.cr_fast || g->r_a >= INT32_MAX - 1 || g->r_b >= INT32_MAX - 1 ||
        rad <= 0 || rad >= INT32_MAX - 1 || v_uv < 0 || v_uv >= ((int64_t)1 << 30) ||
        !drv.arc.ac_ok || a_c < 0 || a_c >= ((int64_t)1 << 29) ||
        !arc_rot_consts(t, g, drv.ip.fifo[drv.ip.rd & (INTERP_FIFO - 1)].len)) {
        return;
    }
    if (t->dR != 0 && (v_uv * v_uv) / (g->r_a < g->r_b ? g->r_a : g->r_b) >= ((int64_t)1 << 30)) {
        return; /* a spiral: v^2 / r along the chord must stay < 2^31 */
    }
    t->C = (int64_t)c * ((int64_t)1 << 32);
    t->S = (int64_t)s * ((int64_t)1 << 32);
    t->c = c;
    t->s = s;
    t->R = rad * ((int64_t)1 << 32);
    t->rad = (int32_t)rad;
    t->v_uv = (int32_t)v_uv;
    /* tu = -s, tv = c counter-clockwise (s, -c clockwise), as arc_fast */
    t->kvu = g->sense > 0 ? -(int32_t)v_uv : (int32_t)v_uv;
    t->kvv = -t->kvu;
    t->ka = -(int32_t)a_c;
    t->kmu = g->sense > 0 ? -drv.hyp_m : drv.hyp_m;
    t->kmv = -t->kmu;
    t->u = g->u;
    t->v = g->v;
    t->cu = g->cu;
    t->cv = g->cv;
    t->left = DRIVE_ARC_ROT_TICKS;
    t->on = true;
    /* the recurrence rewrites the plane axes' positions without reading
     * them: the interpolator's fast path may skip them */
    drv.ip.fast_skip = (uint8_t)((1u << g->u) | (1u << g->v));
}

/* A cruise fast-path tick of an anchored chord: rotate (C, S) by delta and
 * write what arc_fast() writes, from the rotated point (see drive.h for
 * the error bound against arc_fast). The path speed v_uv, the chord
 * tangent's in-plane length and v^2 / r come from the caches arc_fast
 * filled at the anchor (the chord reference's velocity and tangent are
 * constant in the phase, its acceleration 0). */
#if defined(__GNUC__)
#define DRV_NOINLINE __attribute__((noinline))
#else
#define DRV_NOINLINE
#endif

/* Out of line: a small frame of its own (inlined into drive_tick, its
 * values spill to the stack). */
static DRV_NOINLINE void arc_rot_step(motion_ref_t *r, arc_rot_t *t, bool geom_kept)
{
    uint8_t u = t->u, v = t->v;
    q1_30_t c = t->c, s = t->s;
    int64_t C = t->C - rot_mul2(c, t->eh, t->el, s, t->dh, t->dl);
    int64_t S = t->S - rot_mul2(s, t->eh, t->el, -c, t->dh, t->dl);
    int32_t rad = t->rad;

    t->C = C;
    t->S = S;
    /* round(C / 2^32) from the two words (32-bit values for SMULL below) */
    c = (q1_30_t)((int32_t)(C >> 32) + (int32_t)((uint32_t)C >> 31));
    s = (q1_30_t)((int32_t)(S >> 32) + (int32_t)((uint32_t)S >> 31));
    t->c = c;
    t->s = s;
    if (--t->left == 0u) {
        drv.ip.fast_skip = 0; /* the next tick is exact: it reads them */
    }
    if (t->dR != 0) { /* a spiral */
        t->R += t->dR;
        rad = (int32_t)((t->R + ((int64_t)1 << 31)) >> 32);
        t->rad = rad;
        t->ka = -(int32_t)arc_centripetal(&drv.arc, t->v_uv, rad);
    }
#if defined(__GNUC__)
    /* re-read c and s as 32-bit fields: GCC then multiplies them with one
     * SMULL each (it widens the registers' values to 64 x 64 otherwise) */
    __asm__ volatile("" ::: "memory");
    c = t->c;
    s = t->s;
    rad = t->rad;
#endif
    r->pos[u] = t->cu + mul32_q30(rad, c);
    r->pos[v] = t->cv + mul32_q30(rad, s);
    r->vel[u] = mul32_q30(t->kvu, s);
    r->vel[v] = mul32_q30(t->kvv, c);
    r->acc[u] = mul32_q30(t->ka, c);
    r->acc[v] = mul32_q30(t->ka, s);
    r->geom.tangent[u] = (q1_30_t)mul32_q30(t->kmu, s);
    r->geom.tangent[v] = (q1_30_t)mul32_q30(t->kmv, c);
    if (geom_kept) {
        r->geom.radius = rad;
    } else {
        arc_geom(r, &drv.seg[drv.ip.tag % SEG_RING], rad);
    }
}

/* Account completed interpolator segments (host blocks done, current tag). */
static void track_segments(void)
{
    uint32_t done = drv.ip.blocks_done;
    while (drv.seen_done != done) {
        const seg_info_t *g = &drv.seg[drv.seq_done % SEG_RING];
        if (g->last) {
            drv.blocks_done++;
        }
        drv.seq_done++;
        drv.seen_done++;
    }
    if (drv.ip.busy) {
        drv.cur_tag = drv.seg[drv.ip.tag % SEG_RING].host_tag;
    }
}

/* Path speed of a velocity vector, nm/s. */
static int64_t path_speed(const int64_t v[CORE_AXES])
{
    return fx_hypot3(v[0], CORE_AXES > 1 ? v[1] : 0, CORE_AXES > 2 ? v[2] : 0);
}

/* Controlled stop: the time scale k (q30) of this tick. The speed cap falls
 * by stop_dv per tick and never exceeds the speed of the last tick (so the
 * path never speeds up, also where the plan accelerates, and it follows the
 * plan where that slows down faster, e.g. into an exact stop); k makes the
 * predicted path speed k * (v + a k h) meet the cap (first order: k = cap /
 * (v + a h)), never above 1. Rest (halted) when the cap reaches 0. */
static int64_t stop_scale(void)
{
    int64_t cap = drv.stop_v - drv.stop_dv;
    int64_t den;
    unsigned i;
    /* the plan's own path speed and tangential acceleration (chord) */
    drv.v_plan = path_speed(drv.ch.vel);
    drv.a_plan = 0;
    for (i = 0; i < CORE_AXES; i++) {
        drv.a_plan =
            fx_sat_add64(drv.a_plan, fx_mul64x32_shift(drv.ch.acc[i], drv.ch.geom.tangent[i], 30));
    }
    if (drv.v_act < cap) {
        cap = drv.v_act; /* the plan itself slowed down more */
    }
    drv.stop_v = cap < 0 ? 0 : cap;
    if (drv.stop_v == 0 || interp_idle(&drv.ip)) {
        drv.halted = true;
        return 0;
    }
    den = drv.v_plan + drv.a_plan / (int64_t)drv.cfg.tick_hz;
    if (den <= drv.stop_v) {
        return Q30;
    }
    return ratio_q30(drv.stop_v, den);
}

static void reference_step(void)
{
    unsigned i;
    int64_t k = Q30;
    bool pos_only, stepped;
    if (drv.state == DRIVE_STOPPING && !drv.halted) {
        k = stop_scale();
        drv.ip.tick_ns = fx_round_shift64((int64_t)(1000000000u / drv.cfg.tick_hz) * k, 30);
    }
    if (drv.halted) {
        drv.v_act = 0;
        for (i = 0; i < CORE_AXES; i++) {
            drv.ref.vel[i] = 0;
            drv.ref.acc[i] = 0;
        }
        drv.ref.active = false;
        drv.ref.geom.kind = MOTION_GEOM_NONE;
        drv.ref_synced = false;
        return;
    }
    interp_tick(&drv.ip, &drv.ch);
    if (!drv.ip.ref_pos_only) {
        /* a fast-path tick ends no segment and keeps the tag */
        track_segments();
        drv.rot.on = false; /* anchored again below if on an arc */
    }
    pos_only = drv.ip.ref_pos_only && drv.ref_synced && !drv.ref_full;
    stepped = drv.rot.on && drv.rot.left != 0u;
    if (stepped) {
        /* a cruise fast-path tick of the anchored arc phase (rot.on: every
         * tick since the anchor was one, in the same segment) */
        if (pos_only) {
            unsigned skip = drv.ip.fast_skip; /* the plane axes */
            for (i = 0; i < CORE_AXES; i++) {
                if ((skip & (1u << i)) == 0u) {
                    drv.ref.pos[i] = drv.ch.pos[i];
                }
            }
        } else {
            drv.ref = drv.ch;
            drv.ref_synced = true;
        }
        arc_rot_step(&drv.ref, &drv.rot, pos_only);
    } else if (pos_only) {
        /* same segment and phase as the last tick: only pos changed in ch,
         * and the arc overlay (if any) rewrites its fields below */
        for (i = 0; i < CORE_AXES; i++) {
            drv.ref.pos[i] = drv.ch.pos[i];
        }
    } else {
        drv.ref = drv.ch;
        drv.ref_synced = true;
    }
    if (!stepped && drv.ref.active && drv.ip.busy) {
        const seg_info_t *g = &drv.seg[drv.ip.tag % SEG_RING];
        if (g->arc) {
            if (!drv.arc.valid || drv.arc.tag != drv.ip.tag) {
                arc_fast_setup(&drv.arc, g);
                drv.rot.on = false;
            }
            {
                q1_30_t s, c;
                int64_t rad;
                drv.rot.on = false;
                drv.ip.fast_skip = 0;
                if (drv.arc.fast &&
                    arc_fast(&drv.ref, &drv.ch, g, &drv.arc, pos_only, &s, &c, &rad)) {
                    arc_rot_anchor(&drv.rot, g, s, c, rad);
                } else {
                    arc_overlay(&drv.ref, &drv.ch, g);
                }
            }
        }
    }
    if (drv.state == DRIVE_STOPPING) {
        /* time runs at k: velocity * k, acceleration * k^2 */
        for (i = 0; i < CORE_AXES; i++) {
            drv.ref.vel[i] = fx_mul64x32_shift(drv.ref.vel[i], (int32_t)k, 30);
            drv.ref.acc[i] = fx_mul64x32_shift(fx_mul64x32_shift(drv.ref.acc[i], (int32_t)k, 30),
                                               (int32_t)k, 30);
        }
        /* only the stop ramp reads it (req_stop sets it when a stop starts) */
        drv.v_act = path_speed(drv.ref.vel);
        drv.ref_synced = false;
    }
}

/* Friction feed-forward as an extra reference acceleration (see drive.h). */
static void friction_ff(void)
{
    unsigned i;
    if (!drv.ff_on) {
        return;
    }
    drv.ref_synced = false; /* drv.ref.acc may change below */
    for (i = 0; i < drv.cfg.axes; i++) {
        int64_t f, v, band, kaff, u;
        if (drv.cfg.friction_ff_mv[i] == 0) {
            continue; /* the usual case: nothing else to load */
        }
        f = drv.cfg.friction_ff_mv[i];
        v = drv.ref.vel[i];
        kaff = drv.servo.p.axis[i].kaff >> 16;
        if (kaff <= 0 || v == 0) {
            continue;
        }
        band = drv.cfg.friction_ff_band_nm_s > 0 ? drv.cfg.friction_ff_band_nm_s : 1;
        if (v >= band) {
            u = f;
        } else if (v <= -band) {
            u = -f;
        } else {
            u = fx_div_round64(f * v, band);
        }
        /* mV -> nm/s^2: u * 1e-3 V / (kaff V/(m/s^2)) * 1e9 = u * 1e6 / kaff */
        drv.ref.acc[i] = fx_sat_add64(drv.ref.acc[i], fx_div_round64(u * 1000000 * 65536, kaff));
    }
}

/* Main flushed its queues and the interpolator (req_enable, req_resume):
 * account segments from the flush on, nominal time, reference not held. */
static void restart(void)
{
    drv.halted = false;
    drv.seen_done = drv.ip.blocks_done;
    drv.seq_done = drv.rs_seq;
    drv.ip.tick_ns = (int64_t)(1000000000u / drv.cfg.tick_hz);
}

static void apply_requests(const servo_fb_t *fb)
{
    unsigned i;
    if (!drv.req_any) {
        return; /* the usual tick: no request */
    }
    drv.req_any = false;
    if (drv.req_gains) {
        servo_params_t q = drv.pend;
        q.axes = drv.cfg.axes;
        q.tick_hz = drv.cfg.tick_hz;
        q.cec.mode = drv.servo.p.cec.mode;
        (void)servo_config(&drv.servo, &q); /* main checked them */
        drv.req_gains = false;
    }
    if (drv.req_cec) {
        servo_set_cec_mode(&drv.servo, drv.pend_mode);
        drv.req_cec = false;
    }
    if (drv.req_estop) {
        drv.req_estop = false;
        drv.faults |= DRIVE_FAULT_ESTOP;
        servo_disable(&drv.servo);
    }
    if (drv.req_fault != 0) {
        drv.faults |= drv.req_fault;
        drv.req_fault = 0;
        servo_stop(&drv.servo);
    }
    if (drv.req_reset) {
        if (drv.servo.state != SERVO_STOPPING) {
            drv.req_reset = false;
            for (i = 0; i < drv.cfg.axes; i++) {
                qdec_clear_faults(&drv.enc[i]);
            }
            servo_clear_faults(&drv.servo);
            servo_disable(&drv.servo);
            drv.faults = 0;
            drv.state = DRIVE_DISABLED;
        } else {
            drv.req_any = true; /* retried next tick */
        }
    }
    if (drv.req_disable) {
        drv.req_disable = false;
        drv.req_enable = false;
        servo_disable(&drv.servo);
        if (drv.state != DRIVE_FAULT) {
            drv.state = DRIVE_DISABLED;
        }
    }
    if (drv.req_enable) {
        drv.req_enable = false;
        /* never after a fault latched in this same tick (e.g. an e-stop
         * that arrived together with the enable); a refused enable leaves
         * the drive DISABLED (main then drops what was queued) */
        if (drv.faults == 0 && drv.state == DRIVE_DISABLED && drv.servo.state == SERVO_OFF &&
            servo_enable(&drv.servo, fb) == SERVO_OK) {
            servo_run(&drv.servo);
            restart();
            drv.state = DRIVE_IDLE; /* RUNNING below if blocks are queued */
        }
    }
    if (drv.req_resume) {
        drv.req_resume = false;
        if (drv.state == DRIVE_STOPPING && drv.halted) {
            restart();
            drv.state = DRIVE_IDLE;
        }
    }
    if (drv.req_stop) {
        drv.req_stop = false;
        if (drv.state == DRIVE_RUNNING || drv.state == DRIVE_IDLE) {
            drv.state = DRIVE_STOPPING;
            drv.v_act = path_speed(drv.ref.vel);
            drv.stop_v = drv.v_act;
            drv.stop_dv = drv.cfg.stop_decel_nm_s2 / (int64_t)drv.cfg.tick_hz;
            if (drv.stop_dv < 1) {
                drv.stop_dv = 1;
            }
        }
    }
}

/* Sample the reference scales (see drive_status_t.refscale): the counter's
 * change since the last sample, taken as int32, is added to the count, so
 * samples must come while the scale moves less than 2^31 counts between
 * them (DRIVE_REF_SAMPLE_TICKS). A drive_status() request (req_ref) is
 * cleared before the counters are read: a request set after that gets the
 * next tick. */
static void ref_scales_sample(void)
{
    unsigned i;
    drv.req_ref = false;
    for (i = 0; i < drv.cfg.axes; i++) {
        uint32_t raw;
        if (drv.ref_on[i] && hal_encoder_counter(drv.cfg.axes + i, &raw)) {
            drv.ref_cnt[i] += (int32_t)(raw - drv.ref_raw[i]);
            drv.ref_raw[i] = raw;
            drv.ref_nm[i] = qdec_counts_to_nm(&drv.refs[i], drv.ref_cnt[i]);
        }
    }
}

void drive_tick(void)
{
    unsigned i;
    uint32_t now_ns;
    servo_fb_t fb;
    uint32_t enc_fault = 0;
    bool moving_ok, sampling;

    if (!drv.ready) {
        return;
    }
    drv.st_seq++; /* odd: the status is being updated (publish ends it) */
    now_ns = hal_time_us() * 1000u;
    /* sample the encoders and fill fb in the same pass (what
     * servo_fb_from_qdec gives: pos_nm, fault bit, 0 beyond the axes) */
    for (i = 0; i < CORE_AXES; i++) {
        qdec_t *q = &drv.enc[i];
        if (i >= drv.cfg.axes) {
            fb.pos[i] = 0;
            continue;
        }
        if (!drv.enc_any_counter) { /* the usual configuration */
            qdec_sample(q, now_ns);
        } else if (drv.cfg.enc_counter[i]) {
            uint32_t raw = q->last_raw; /* no snapshot: no change */
            (void)hal_encoder_counter(i, &raw);
            qdec_sample_counter(q, raw, now_ns);
        } else {
            qdec_sample(q, now_ns);
        }
        fb.pos[i] = q->out.pos_nm;
        if (q->out.faults != 0) {
            enc_fault |= 1u << i;
        }
    }
    fb.enc_fault = enc_fault;
    /* calib_tick (the end of this tick) is the only writer besides main */
    sampling = calib_sampling();
    if (sampling || drv.req_ref || ((uint32_t)drv.tick & (DRIVE_REF_SAMPLE_TICKS - 1u)) == 0u) {
        ref_scales_sample();
    }
    apply_requests(&fb);
    moving_ok =
        drv.state == DRIVE_IDLE || drv.state == DRIVE_RUNNING || drv.state == DRIVE_STOPPING;
    if (moving_ok && drv.servo.state == SERVO_RUN) {
        reference_step();
        friction_ff();
        servo_tick(&drv.servo, &drv.ref, &fb);
    } else {
        servo_tick(&drv.servo, NULL, &fb);
        for (i = 0; i < CORE_AXES; i++) {
            drv.ref.pos[i] = drv.servo.ref_pos[i];
            drv.ref.vel[i] = 0;
            drv.ref.acc[i] = 0;
        }
        drv.ref.active = false;
        drv.ref.geom.kind = MOTION_GEOM_NONE;
        drv.ref_synced = false;
    }
    drv.faults |= drv.servo.faults;
    if (drv.faults != 0) {
        drv.state = DRIVE_FAULT;
    } else if (drv.state == DRIVE_IDLE || drv.state == DRIVE_RUNNING) {
        /* !interp_idle(), busy first: the usual tick has a segment */
        bool busy = drv.ip.busy || drv.ip.wr != drv.ip.rd || drv.main_queued != 0u;
        drv.state = busy ? DRIVE_RUNNING : DRIVE_IDLE;
    }
    drv.tick++;
    drv.tick_lo = (uint32_t)drv.tick;
    publish(sampling);
    calib_tick(&drv.st, drv.ref.vel);
}

/* ---- main -------------------------------------------------------------------- */

/* Drop every queued block and hold pos. Only while the tick is parked
 * (tick_parked()): interp_reset writes the consumer side too. The tick
 * takes over the segment count (rs_seq) with req_enable / req_resume. */
static void flush_all(const pos_nm_t pos[CORE_AXES])
{
    unsigned i;
    drv.hq_count = 0;
    drv.hq_head = 0;
    plan_reset(&drv.plan, pos);
    interp_reset(&drv.ip, pos);
    drv.rs_seq = drv.seq_next;
    drv.main_queued = 0;
    for (i = 0; i < CORE_AXES; i++) {
        drv.q_end[i] = pos[i];
    }
}

/* Chord angle for an arc of radius r at the programmed feed. */
static int64_t arc_seg_angle(int64_t r, int64_t feed, int64_t tol, uint32_t tick_hz)
{
    int64_t a_tol, a_tick, x, dist;
    if (r <= tol) {
        return DRIVE_ARC_SEG_MAX_ANGLE;
    }
    /* sagitta r (1 - cos(a/2)) ~ r a^2 / 8 = tol: a = sqrt(8 tol / r) rad */
    x = fx_div_shift64(8 * tol, r, 40); /* exact 128-bit numerator (tol up to 1e9) */
    a_tol = (int64_t)fx_isqrt64((uint64_t)x) * 651899 / 1000; /* * 2^32/(2 pi) / 2^20 */
    dist = feed * DRIVE_ARC_SEG_TICKS / (int64_t)tick_hz;
    a_tick = fx_mul64_shift(dist, ANGLE_K, 0) / r;
    if (a_tick > a_tol) {
        a_tol = a_tick;
    }
    if (a_tol > (int64_t)DRIVE_ARC_SEG_MAX_ANGLE) {
        a_tol = DRIVE_ARC_SEG_MAX_ANGLE;
    }
    return a_tol < 1 ? 1 : a_tol;
}

/* Point of the arc at segment k of n. */
static void arc_point(const host_block_t *h, uint32_t k, pos_nm_t out[CORE_AXES], fx_angle_t *th,
                      pos_nm_t *rad)
{
    unsigned i;
    int64_t n = h->n_seg;
    q1_30_t s, c;
    for (i = 0; i < CORE_AXES; i++) {
        out[i] = h->start[i] + (h->b.target[i] - h->start[i]) * (int64_t)k / n;
    }
    *th = h->th_s + (fx_angle_t)(uint64_t)(h->sweep * (int64_t)k / n);
    *rad = h->r_s + (h->r_e - h->r_s) * (int64_t)k / n;
    if (k == h->n_seg) {
        for (i = 0; i < CORE_AXES; i++) {
            out[i] = h->b.target[i];
        }
        return;
    }
    fx_sincos(*th, &s, &c);
    out[h->u] = h->b.centre_u + fx_mul64x32_shift(*rad, c, 30);
    out[h->v] = h->b.centre_v + fx_mul64x32_shift(*rad, s, 30);
}

/* Push the next planner block of the oldest host block. False when the
 * planner is full. */
static bool feed_one(void)
{
    host_block_t *h = &drv.hq[drv.hq_head];
    plan_move_t m = {0};
    seg_info_t g = {0};
    plan_result_t r;
    unsigned i;
    bool last = true;

    if (plan_free_slots(&drv.plan) == 0) {
        return false;
    }
    m.tag = drv.seq_next;
    m.feed = h->b.feed_nm_s;
    g.host_tag = h->b.tag;
    if (h->b.kind == DRIVE_BLOCK_DWELL) {
        m.dwell_ns = (int64_t)h->b.dwell_ms * 1000000;
    } else if (h->b.kind == DRIVE_BLOCK_LINE) {
        for (i = 0; i < CORE_AXES; i++) {
            m.target[i] = h->b.target[i];
        }
        m.flags = h->b.exact_stop ? PLAN_MOVE_EXACT_STOP : 0;
    } else {
        pos_nm_t a[CORE_AXES], b[CORE_AXES];
        fx_angle_t tha, thb;
        pos_nm_t ra, rb;
        int64_t chord, arclen;
        arc_point(h, h->done_seg, a, &tha, &ra);
        arc_point(h, h->done_seg + 1, b, &thb, &rb);
        for (i = 0; i < CORE_AXES; i++) {
            m.target[i] = b[i];
        }
        last = h->done_seg + 1 == h->n_seg;
        m.flags = (last && h->b.exact_stop) ? PLAN_MOVE_EXACT_STOP : 0;
        g.arc = true;
        g.u = h->u;
        g.v = h->v;
        g.sense = h->b.sense;
        g.cu = h->b.centre_u;
        g.cv = h->b.centre_v;
        g.r_a = ra;
        g.r_b = rb;
        g.th_a = tha;
        g.dth = h->sweep / (int64_t)h->n_seg;
        g.au = a[h->u];
        g.av = a[h->v];
        g.bu = b[h->u];
        g.bv = b[h->v];
        chord = fx_hypot2(b[h->u] - a[h->u], b[h->v] - a[h->v]);
        /* arc length = r * |dth| * 2 pi / 2^32 = r * (|dth| * pi/2 * 2^30) >> 30 */
        arclen = fx_mul64_shift((ra + rb) / 2, fx_round_shift64(abs64(g.dth) * 1686629713, 30), 30);
        g.k_arc = chord > 0 ? (q1_30_t)fx_div_round64(fx_mul64_shift(arclen, Q30, 0), chord)
                            : (q1_30_t)Q30;
    }
    r = plan_push(&drv.plan, &m);
    if (r == PLAN_E_FULL) {
        return false;
    }
    if (r == PLAN_OK) {
        g.last = last;
        drv.seg[drv.seq_next % SEG_RING] = g;
        drv.seq_next++;
    } else if (last && h->b.kind != DRIVE_BLOCK_ARC) {
        /* skipped (zero length) or refused: the block counts as done */
        drv.blocks_done_main++;
    }
    if (h->b.kind == DRIVE_BLOCK_ARC) {
        h->done_seg++;
    }
    if (last) {
        drv.hq_head = (uint16_t)((drv.hq_head + 1u) % DRIVE_QUEUE_DEPTH);
        drv.hq_count--;
    }
    return true;
}

/* True when the oldest planner block's exit speed is final (the next
 * block's entry can no longer change, or it ends in a stop): freezing it now
 * gives the plan it would get with any later look-ahead. */
static bool oldest_final(void)
{
    const plan_block_t *b = plan_peek(&drv.plan, 0);
    if (b == NULL) {
        return false;
    }
    if (plan_count(&drv.plan) >= 2) {
        return drv.plan.planned >= 2;
    }
    return (b->flags & (PLAN_BF_EXACT_STOP | PLAN_BF_DWELL)) != 0;
}

/* Planned time in the interpolator's FIFO after the oldest segment, ns
 * (slots rd+1 .. wr-1: main wrote them; the tick only reads them). */
static int64_t interp_ahead_ns(void)
{
    uint16_t rd = drv.ip.rd, wr = drv.ip.wr, i;
    int64_t sum = 0;
    if ((uint16_t)(wr - rd) > INTERP_FIFO) {
        return 0;
    }
    for (i = (uint16_t)(rd + 1u); i != wr && rd != wr; i++) {
        sum += drv.ip.fifo[i & (INTERP_FIFO - 1)].total_ns;
    }
    return sum;
}

/* No input is waiting and the planner is not full: freeze a block anyway
 * only when the interpolator would otherwise run short (less than
 * DRIVE_FEED_AHEAD_NS beyond its current segment), or, with nothing in the
 * interpolator, when no block arrived for cfg.start_delay_ms (a job starts
 * once its look-ahead has filled or the host has paused). */
static bool interp_needs_block(void)
{
    uint32_t delay;
    if (!interp_idle(&drv.ip)) {
        return interp_ahead_ns() < DRIVE_FEED_AHEAD_NS;
    }
    delay = (uint32_t)(((uint64_t)drv.cfg.start_delay_ms * drv.cfg.tick_hz + 999u) / 1000u);
    return (uint32_t)(drv.tick_lo - drv.queued_at) >= delay;
}

/* The state as main acts on it: the tick's, with the requests main posted
 * and the tick has not applied yet counted as applied (a pending disable:
 * DISABLED; a pending enable of a DISABLED drive: IDLE; a pending stop of
 * an IDLE or RUNNING drive: STOPPING, so no block is accepted that the stop
 * would drop). The flags are read before the state: a tick between the
 * reads has applied them. */
static drive_state_t main_view(drive_state_t s, bool en, bool dis, bool stop)
{
    if (s == DRIVE_FAULT) {
        return s;
    }
    if (dis) {
        return DRIVE_DISABLED;
    }
    if (stop && (s == DRIVE_IDLE || s == DRIVE_RUNNING)) {
        return DRIVE_STOPPING;
    }
    return (en && s == DRIVE_DISABLED) ? DRIVE_IDLE : s;
}

static drive_state_t main_state(void)
{
    bool en = drv.req_enable, dis = drv.req_disable, stop = drv.req_stop;
    return main_view(drv.state, en, dis, stop);
}

/* The tick does not touch the interpolator and leaves this state only on a
 * request from main: DISABLED or FAULT with no enable pending, or STOPPING
 * at rest with no resume pending (flags read before the state). */
static bool tick_parked(void)
{
    bool en = drv.req_enable, rs = drv.req_resume;
    drive_state_t s = drv.state;
    if (s == DRIVE_DISABLED || s == DRIVE_FAULT) {
        return !en;
    }
    return s == DRIVE_STOPPING && !rs && drv.halted;
}

/* Blocks not yet handed to the interpolator, for the tick (see main_queued). */
static void publish_queued(void)
{
    drv.main_queued = (uint32_t)drv.hq_count + plan_count(&drv.plan);
}

/* The reference the tick holds (published). */
static void held_ref(pos_nm_t pos[CORE_AXES])
{
    drive_status_t st;
    unsigned i;
    drive_snapshot(&st);
    for (i = 0; i < CORE_AXES; i++) {
        pos[i] = st.ref[i];
    }
}

void drive_poll(void)
{
    drive_state_t s;
    if (!drv.ready) {
        return;
    }
    calib_poll();
    PREEMPT_POINT();
    s = main_state();
    if (s == DRIVE_DISABLED || s == DRIVE_FAULT || s == DRIVE_STOPPING) {
        PREEMPT_POINT();
        if (tick_parked() && (drv.hq_count > 0 || plan_count(&drv.plan) > 0 ||
                              !interp_idle(&drv.ip) || drv.state == DRIVE_STOPPING)) {
            pos_nm_t pos[CORE_AXES];
            held_ref(pos);
            PREEMPT_POINT();
            flush_all(pos);
            PREEMPT_POINT();
            if (drv.state == DRIVE_STOPPING) {
                /* at rest: the tick goes IDLE when it sees the request */
                CORE_BARRIER();
                drv.req_resume = true;
                PREEMPT_POINT();
                drv.req_any = true;
            }
        }
        return;
    }
    /* Push every waiting block before each pop (interp_refill pops one), so
     * that a block is frozen with the look-ahead plan_estimate() gives it;
     * pop while the interpolator has room and the planner is full, or the
     * oldest block's plan is final, or the interpolator runs short. */
    for (;;) {
        while (drv.hq_count > 0 && feed_one()) {
            PREEMPT_POINT();
        }
        PREEMPT_POINT();
        if (interp_room(&drv.ip) == 0 || plan_count(&drv.plan) == 0 ||
            !(plan_free_slots(&drv.plan) == 0 || oldest_final() || interp_needs_block())) {
            break;
        }
        if (interp_refill(&drv.ip, &drv.plan) == 0) {
            break;
        }
        PREEMPT_POINT();
    }
    publish_queued();
}

/* Validate an arc (h->b, with the targets of unused axes already set) from
 * start and set up its segmentation. False when invalid. */
static bool arc_setup(host_block_t *h, const pos_nm_t start[CORE_AXES], unsigned axes,
                      uint32_t tick_hz, int64_t chord_nm)
{
    const drive_block_t *b = &h->b;
    int64_t su, sv, eu, ev, sw, seg;
    fx_angle_t the;
    uint32_t d;
    unsigned i;
    if (b->feed_nm_s <= 0 || b->feed_nm_s > SC_V_LIMIT || (b->sense != 1 && b->sense != -1) ||
        (unsigned)b->plane > DRIVE_PLANE_YZ || tick_hz == 0 || chord_nm <= 0) {
        return false;
    }
    plane_axes(b->plane, &h->u, &h->v, &h->w);
    if (h->u >= axes || h->v >= axes) {
        return false;
    }
    for (i = 0; i < CORE_AXES; i++) {
        h->start[i] = start[i];
    }
    su = h->start[h->u] - b->centre_u;
    sv = h->start[h->v] - b->centre_v;
    eu = b->target[h->u] - b->centre_u;
    ev = b->target[h->v] - b->centre_v;
    if (abs64(su) >= SC_LEN_MAX || abs64(sv) >= SC_LEN_MAX || abs64(eu) >= SC_LEN_MAX ||
        abs64(ev) >= SC_LEN_MAX) {
        return false;
    }
    h->r_s = fx_hypot2(su, sv);
    h->r_e = fx_hypot2(eu, ev);
    if (h->r_s <= 0 || h->r_e <= 0 || abs64(h->r_s - h->r_e) > DRIVE_ARC_RADIUS_TOL_NM) {
        return false;
    }
    h->th_s = fx_atan2(sv, su);
    the = fx_atan2(ev, eu);
    d = b->sense > 0 ? (uint32_t)(the - h->th_s) : (uint32_t)(h->th_s - the);
    sw = d == 0 ? ((int64_t)1 << 32) : (int64_t)d;
    h->sweep = b->sense > 0 ? sw : -sw;
    seg = arc_seg_angle((h->r_s + h->r_e) / 2, b->feed_nm_s, chord_nm, tick_hz);
    h->n_seg = (uint32_t)((sw + seg - 1) / seg);
    if (h->n_seg < 1) {
        h->n_seg = 1;
    }
    h->done_seg = 0;
    return true;
}

uint32_t drive_arc_chords(const drive_block_t *b, const pos_nm_t start[CORE_AXES], unsigned axes,
                          uint32_t tick_hz, int64_t chord_nm, pos_nm_t *out, uint32_t cap)
{
    static host_block_t h; /* static: no large stack frame */
    host_block_t zero = {0};
    uint32_t k;
    unsigned i;
    if (b == NULL || start == NULL || b->kind != DRIVE_BLOCK_ARC || axes < 1 || axes > CORE_AXES) {
        return 0;
    }
    h = zero;
    h.b = *b;
    for (i = axes; i < CORE_AXES; i++) {
        h.b.target[i] = start[i];
    }
    if (!arc_setup(&h, start, axes, tick_hz, chord_nm == 0 ? DRIVE_ARC_CHORD_NM : chord_nm)) {
        return 0;
    }
    for (k = 1; k <= h.n_seg && k <= cap && out != NULL; k++) {
        fx_angle_t th;
        pos_nm_t rad;
        arc_point(&h, k, &out[(k - 1) * CORE_AXES], &th, &rad);
    }
    return h.n_seg;
}

uint32_t drive_queue_free(void)
{
    return (uint32_t)(DRIVE_QUEUE_DEPTH - drv.hq_count);
}

static drive_result_t accept_check(void)
{
    drive_state_t s;
    if (!drv.ready) {
        return DRIVE_E_DISABLED;
    }
    s = main_state();
    if (s == DRIVE_FAULT) {
        return DRIVE_E_FAULTED;
    }
    if (s == DRIVE_DISABLED) {
        return DRIVE_E_DISABLED;
    }
    if (s == DRIVE_STOPPING) {
        return DRIVE_E_BUSY;
    }
    return DRIVE_OK;
}

drive_result_t drive_queue_block(const drive_block_t *b)
{
    host_block_t h;
    host_block_t zero = {0};
    drive_result_t r;
    unsigned i;
    if (b == NULL) {
        return DRIVE_E_INVALID;
    }
    r = accept_check();
    if (r != DRIVE_OK) {
        return r;
    }
    PREEMPT_POINT();
    h = zero;
    h.b = *b;
    for (i = drv.cfg.axes; i < CORE_AXES; i++) {
        h.b.target[i] = drv.q_end[i];
    }
    switch (b->kind) {
    case DRIVE_BLOCK_DWELL:
        if (b->dwell_ms == 0 || b->dwell_ms > 86400000u) {
            return DRIVE_E_INVALID;
        }
        break;
    case DRIVE_BLOCK_LINE:
        if (b->feed_nm_s <= 0 || b->feed_nm_s > SC_V_LIMIT) {
            return DRIVE_E_INVALID;
        }
        for (i = 0; i < CORE_AXES; i++) {
            if (abs64(h.b.target[i] - drv.q_end[i]) >= SC_LEN_MAX) {
                return DRIVE_E_INVALID;
            }
        }
        break;
    case DRIVE_BLOCK_ARC:
        if (!arc_setup(&h, drv.q_end, drv.cfg.axes, drv.cfg.tick_hz, drv.cfg.arc_chord_nm)) {
            return DRIVE_E_INVALID;
        }
        break;
    default:
        return DRIVE_E_INVALID;
    }
    if (drv.hq_count >= DRIVE_QUEUE_DEPTH) {
        return DRIVE_E_FULL;
    }
    drv.hq[(drv.hq_head + drv.hq_count) % DRIVE_QUEUE_DEPTH] = h;
    PREEMPT_POINT();
    drv.hq_count++;
    PREEMPT_POINT();
    drv.queued_at = drv.tick_lo;
    /* plan it now (main context, like drive_poll): the caller's status then
     * counts its planned time; drive_poll decides when it is frozen */
    while (drv.hq_count > 0 && feed_one()) {
        PREEMPT_POINT();
    }
    if (b->kind != DRIVE_BLOCK_DWELL) {
        for (i = 0; i < CORE_AXES; i++) {
            drv.q_end[i] = h.b.target[i];
        }
    }
    PREEMPT_POINT();
    publish_queued(); /* the tick makes the drive RUNNING */
    return DRIVE_OK;
}

drive_result_t drive_enable(bool on)
{
    drive_status_t st;
    drive_state_t s;
    if (!drv.ready) {
        return DRIVE_E_DISABLED;
    }
    s = main_state();
    if (s == DRIVE_FAULT) {
        return DRIVE_E_FAULTED;
    }
    if (!on) {
        drv.req_disable = true;
        PREEMPT_POINT();
        drv.req_any = true;
        return DRIVE_OK;
    }
    PREEMPT_POINT();
    if (s != DRIVE_DISABLED) {
        return DRIVE_OK; /* enabled, or an enable is pending */
    }
    if (!tick_parked()) {
        return DRIVE_E_BUSY; /* a disable the tick has not applied yet */
    }
    /* parked DISABLED: start from the measured position */
    drive_snapshot(&st);
    PREEMPT_POINT();
    flush_all(st.pos);
    PREEMPT_POINT();
    CORE_BARRIER();
    drv.req_enable = true;
    PREEMPT_POINT();
    drv.req_any = true;
    return DRIVE_OK;
}

void drive_stop(void)
{
    drv.req_stop = true;
    PREEMPT_POINT();
    drv.req_any = true;
}

void drive_estop(void)
{
    drv.req_estop = true;
    PREEMPT_POINT();
    drv.req_any = true;
}

void drive_raise_fault(uint32_t fault_bits)
{
    drv.req_fault |= fault_bits;
    PREEMPT_POINT();
    drv.req_any = true;
}

drive_result_t drive_fault_reset(void)
{
    unsigned i;
    if (!drv.ready) {
        return DRIVE_E_DISABLED;
    }
    if (main_state() != DRIVE_FAULT) {
        return DRIVE_OK;
    }
    for (i = 0; i < drv.cfg.axes; i++) {
        if (hal_amp_fault(i)) {
            return DRIVE_E_CAUSE;
        }
    }
    PREEMPT_POINT();
    drv.req_reset = true;
    PREEMPT_POINT();
    drv.req_any = true;
    return DRIVE_OK;
}

/* Keeps the compiler from moving plain loads across the st_seq reads (a
 * volatile access orders only other volatile accesses). Only main needs
 * it: the tick is an interrupt (or the same thread), so main never sees
 * the tick half way; the tick's own stores need no ordering. */
static inline void snapshot_barrier(void)
{
#if defined(__GNUC__)
    __asm__ volatile("" ::: "memory");
#endif
}

static CORE_NO_TSAN void snapshot(drive_status_t *out, uint16_t *ip_rd, int64_t *ip_rem)
{
    uint32_t s;
    do {
        s = drv.st_seq;
        snapshot_barrier();
        *out = drv.st;
        PREEMPT_POINT();
        status_live(out);
        PREEMPT_POINT();
        /* the interpolator's read index and the time left in its current
         * segment (-1: none): the tick changes them only inside its odd
         * st_seq window; main, which runs this, is the only writer of the
         * FIFO slots and does not write the current one */
        *ip_rd = drv.ip.rd;
        *ip_rem = -1;
        if (drv.ip.busy) {
            *ip_rem = drv.ip.fifo[*ip_rd & (INTERP_FIFO - 1)].total_ns - drv.ip.t_ns;
            if (*ip_rem < 0) {
                *ip_rem = 0;
            }
        }
        snapshot_barrier();
    } while ((s & 1u) != 0 || s != drv.st_seq);
}

void drive_snapshot(drive_status_t *out)
{
    uint16_t rd;
    int64_t rem;
    if (out == NULL) {
        return;
    }
    snapshot(out, &rd, &rem);
}

void drive_status(drive_status_t *out)
{
    uint16_t rd, wr, i;
    int64_t rem, sum;
    bool en, dis, stop;
    if (out == NULL) {
        return;
    }
    en = drv.req_enable; /* before the snapshot: see main_state() */
    dis = drv.req_disable;
    stop = drv.req_stop;
    snapshot(out, &rd, &rem);
    drv.req_ref = true; /* the next tick samples the reference scales */
    PREEMPT_POINT();
    /* main's view: requests not yet applied count as applied, blocks
     * queued since the tick's last state update as RUNNING */
    out->state = main_view(out->state, en, dis, stop);
    if (out->state == DRIVE_IDLE && (drv.main_queued != 0u || !interp_idle(&drv.ip))) {
        out->state = DRIVE_RUNNING;
    }
    out->queue_free = (uint32_t)(DRIVE_QUEUE_DEPTH - drv.hq_count);
    /* planner, then the interpolator's FIFO from the published read index
     * (segments loaded since are counted; a current one by its remainder) */
    sum = plan_queued_ns(&drv.plan);
    wr = drv.ip.wr;
    if ((uint16_t)(wr - rd) <= INTERP_FIFO) {
        for (i = rd; i != wr; i++) {
            sum += (i == rd && rem >= 0) ? rem : drv.ip.fifo[i & (INTERP_FIFO - 1)].total_ns;
        }
    }
    out->queued_time_ns = sum;
}

void drive_encoder_edge(unsigned ch, uint32_t lines, uint32_t t_ns)
{
    if (drv.ready && ch < drv.cfg.axes && !drv.cfg.enc_counter[ch]) {
        qdec_edge(&drv.enc[ch], lines, t_ns);
    }
}

int64_t drive_encoder_count(unsigned ch)
{
    if (!drv.ready || ch >= drv.cfg.axes) {
        return 0;
    }
    return drv.enc[ch].out.pos;
}

static bool moving(void)
{
    drive_state_t s = main_state();
    return s == DRIVE_RUNNING || s == DRIVE_STOPPING;
}

drive_result_t drive_set_cec_mode(drive_cec_mode_t mode)
{
    static const cec_mode_t map[] = {CEC_MODE_OFF, CEC_MODE_TANGENT, CEC_MODE_CURVATURE,
                                     CEC_MODE_EXACT};
    if ((unsigned)mode > (unsigned)DRIVE_CEC_EXACT) {
        return DRIVE_E_INVALID;
    }
    if (moving()) {
        return DRIVE_E_BUSY;
    }
    drv.pend_mode = map[mode];
    drv.cec_mode = mode;
    CORE_BARRIER();
    drv.req_cec = true;
    PREEMPT_POINT();
    drv.req_any = true;
    return DRIVE_OK;
}

drive_result_t drive_set_servo_params(const servo_params_t *p)
{
    static servo_t probe;
    servo_params_t q;
    if (p == NULL || !drv.ready) {
        return DRIVE_E_INVALID;
    }
    q = *p;
    q.axes = drv.cfg.axes;
    q.tick_hz = drv.cfg.tick_hz;
    q.cec.mode = CEC_MODE_OFF;
    if (servo_init(&probe, &q, NULL) != SERVO_OK) {
        return DRIVE_E_INVALID;
    }
    if (moving()) {
        return DRIVE_E_BUSY;
    }
    drv.pend = q;
    drv.cfg.servo = q; /* main's copy; the tick applies pend */
    CORE_BARRIER();
    drv.req_gains = true;
    PREEMPT_POINT();
    drv.req_any = true;
    return DRIVE_OK;
}

void drive_set_comp(unsigned axis, const comp_table_t *table)
{
    if (drv.ready && axis < drv.cfg.axes) {
        qdec_set_comp(&drv.enc[axis], table);
    }
}

void drive_test_full_ref(bool on)
{
    drv.ref_full = on;
}

void drive_test_arc_exact(bool on)
{
    drv.arc_exact = on;
    drv.rot.on = false;
    drv.ip.fast_skip = 0;
}

const motion_ref_t *drive_test_ref(void)
{
    return &drv.ref;
}

bool drive_has_refscale(unsigned axis)
{
    return drv.ready && axis < drv.cfg.axes && drv.ref_on[axis];
}

/* ---- parameters ------------------------------------------------------------- */

static const struct {
    int64_t lo, hi;
    bool per_axis;
} param_info[DRIVE_PARAM_COUNT] = {
    [DRIVE_PARAM_V_MAX] = {1000, SC_V_LIMIT, true},
    [DRIVE_PARAM_A_MAX] = {SC_A_MIN, SC_A_LIMIT, true},
    [DRIVE_PARAM_J_MAX] = {SC_J_MIN, SC_J_LIMIT, true},
    [DRIVE_PARAM_CORNER_DV] = {0, SC_V_LIMIT, true},
    [DRIVE_PARAM_CORNER_ACC] = {0, SC_A_LIMIT, true},
    [DRIVE_PARAM_JUNCTION_DEV] = {0, (int64_t)1 << 40, false},
    [DRIVE_PARAM_CORNER] = {PLAN_CORNER_JD, PLAN_CORNER_STOP, false},
    [DRIVE_PARAM_SHAPE] = {SC_SHAPE_SCURVE, SC_SHAPE_SCURVE_AT_REST, false},
    [DRIVE_PARAM_MIN_BLOCK_NS] = {0, 10 * SC_NS_PER_S, false},
    [DRIVE_PARAM_MBT_WINDOW] = {1, PLAN_WINDOW_MAX, false},
    [DRIVE_PARAM_STOP_DECEL] = {1000, SC_A_LIMIT, false},
    [DRIVE_PARAM_ARC_CHORD] = {1, 1000000000, false},
    [DRIVE_PARAM_START_DELAY_MS] = {0, DRIVE_START_DELAY_MS_MAX, false},
};

/* The field of a configuration a parameter lives in. */
static int64_t *param_field(drive_config_t *c, drive_param_t id, unsigned axis)
{
    switch (id) {
    case DRIVE_PARAM_V_MAX:
        return &c->plan.v_max[axis];
    case DRIVE_PARAM_A_MAX:
        return &c->plan.a_max[axis];
    case DRIVE_PARAM_J_MAX:
        return &c->plan.j_max[axis];
    case DRIVE_PARAM_CORNER_DV:
        return &c->plan.corner_dv[axis];
    case DRIVE_PARAM_CORNER_ACC:
        return &c->plan.corner_acc[axis];
    case DRIVE_PARAM_JUNCTION_DEV:
        return &c->plan.junction_dev_nm;
    case DRIVE_PARAM_MIN_BLOCK_NS:
        return &c->plan.min_block_ns;
    case DRIVE_PARAM_STOP_DECEL:
        return &c->stop_decel_nm_s2;
    case DRIVE_PARAM_ARC_CHORD:
        return &c->arc_chord_nm;
    default:
        return NULL; /* narrower fields: see param_read / param_write */
    }
}

static bool param_ok(drive_param_t id, unsigned axis)
{
    if (!drv.ready || (unsigned)id >= (unsigned)DRIVE_PARAM_COUNT) {
        return false;
    }
    return param_info[id].per_axis ? axis < drv.cfg.axes : axis == 0;
}

static int64_t param_read(drive_config_t *c, drive_param_t id, unsigned axis)
{
    int64_t *f = param_field(c, id, axis);
    if (f != NULL) {
        return *f;
    }
    switch (id) {
    case DRIVE_PARAM_CORNER:
        return c->plan.corner;
    case DRIVE_PARAM_SHAPE:
        return c->plan.shape;
    case DRIVE_PARAM_MBT_WINDOW:
        return c->plan.mbt_window;
    default:
        return c->start_delay_ms;
    }
}

static void param_write(drive_config_t *c, drive_param_t id, unsigned axis, int64_t v)
{
    int64_t *f = param_field(c, id, axis);
    if (f != NULL) {
        *f = v;
        return;
    }
    switch (id) {
    case DRIVE_PARAM_CORNER:
        c->plan.corner = (uint8_t)v;
        break;
    case DRIVE_PARAM_SHAPE:
        c->plan.shape = (uint8_t)v;
        break;
    case DRIVE_PARAM_MBT_WINDOW:
        c->plan.mbt_window = (uint16_t)v;
        break;
    default:
        c->start_delay_ms = (uint32_t)v;
        break;
    }
}

drive_result_t drive_param_get(drive_param_t id, unsigned axis, int64_t *value)
{
    if (value == NULL || !param_ok(id, axis)) {
        return DRIVE_E_INVALID;
    }
    *value = param_read(&drv.cfg, id, axis);
    return DRIVE_OK;
}

drive_result_t drive_param_range(drive_param_t id, unsigned axis, int64_t *lo, int64_t *hi)
{
    const plan_profile_t *p = &drv.cfg.plan;
    if (lo == NULL || hi == NULL || !param_ok(id, axis)) {
        return DRIVE_E_INVALID;
    }
    *lo = param_info[id].lo;
    *hi = param_info[id].hi;
    /* S-curve: a_max / j_max <= SC_TJ_MAX_NS (3 s) per axis */
    if (p->shape != SC_SHAPE_TRAPEZOID && id == DRIVE_PARAM_A_MAX &&
        p->j_max[axis] <= SC_A_LIMIT / 3) {
        *hi = p->j_max[axis] * (SC_TJ_MAX_NS / SC_NS_PER_S); /* j * 3 s */
    }
    if (p->shape != SC_SHAPE_TRAPEZOID && id == DRIVE_PARAM_J_MAX) {
        int64_t tj_s = SC_TJ_MAX_NS / SC_NS_PER_S; /* whole seconds (3) */
        int64_t j = (p->a_max[axis] + tj_s - 1) / tj_s;
        *lo = j > *lo ? j : *lo;
    }
    return DRIVE_OK;
}

/* Nothing queued, executing or stopping (parameters may change). */
static bool planner_idle(void)
{
    return !moving() && !drv.req_stop && drv.hq_count == 0 && plan_count(&drv.plan) == 0 &&
           interp_idle(&drv.ip);
}

static drive_result_t apply_config(const drive_config_t *c)
{
    if (plan_check_profile(&c->plan) != PLAN_OK) {
        return DRIVE_E_INVALID;
    }
    if (!planner_idle()) {
        return DRIVE_E_BUSY;
    }
    PREEMPT_POINT();
    drv.cfg.plan = c->plan;
    drv.cfg.stop_decel_nm_s2 = c->stop_decel_nm_s2;
    drv.cfg.arc_chord_nm = c->arc_chord_nm;
    drv.cfg.start_delay_ms = c->start_delay_ms;
    drv.plan.prof = c->plan;
    plan_reset(&drv.plan, drv.plan.pos);
    return DRIVE_OK;
}

drive_result_t drive_param_set(drive_param_t id, unsigned axis, int64_t value)
{
    static drive_config_t cand; /* static: no large stack frame */
    int64_t lo, hi;
    if (drive_param_range(id, axis, &lo, &hi) != DRIVE_OK || value < lo || value > hi) {
        return DRIVE_E_INVALID;
    }
    cand = drv.cfg;
    param_write(&cand, id, axis, value);
    return apply_config(&cand);
}

drive_result_t drive_set_plan_profile(const plan_profile_t *prof)
{
    static drive_config_t cand;
    if (prof == NULL || !drv.ready) {
        return DRIVE_E_INVALID;
    }
    cand = drv.cfg;
    cand.plan = *prof;
    return apply_config(&cand);
}
