/*
 * drive.c - the drive application (specification in drive.h).
 *
 * Ownership of the state (docs/tick-main.md): every field of drv says which
 * context writes it (main: the feed path and the requests; tick: the state,
 * decoders, servo, reference, snapshot; init: drive_init). Main posts
 * requests (req_*) and reads the snapshot; it resets the interpolator only
 * while the tick is parked (drive_tick_parked()).
 */
#include "drive.h"
#include "drive_int.h"
#include "drive_home.h"
#include "drive_ff.h"
#include "drive_inputs.h"
#include "drive_test.h"

#include "arc_ref.h"
#include "feed.h"
#include "hal.h"
#include "interp.h"
#include "motion_ref.h"
#include "preempt.h"
#include "qdec.h"

static plan_block_t plan_store[PLAN_DEPTH_DEFAULT];
/* The feed path (main: host FIFO, planner, producer side of the
 * interpolator; the tick reads the segment records it was handed and
 * feed.queued, feed.h), outside drv so that the tick's fields keep short
 * offsets. */
static feed_t feed;

/* The drive's state: its fields and who writes them in drive_int.h. */
drive_app_t drv;

/* main, payload of req_home (outside drv: see feed) */
static drive_home_t pend_home;

/* ---- helpers ------------------------------------------------------------- */

/* The encoder, motor, reference, reference-scale, contour-error and block
 * fields of the status, from the state the tick owns (nothing else writes
 * it: qdec outputs, servo outputs, the reference handed to the servo, the
 * reference scales, the CEC estimate, blocks done and tag; drive_init
 * publishes after setting them) plus main's count of blocks it completed
 * (feed_skipped: the snapshot runs in main). */
static CORE_NO_TSAN void status_live(drive_status_t *s)
{
    unsigned i;
    for (i = 0; i < drv.cfg.axes; i++) {
        const qdec_t *e = &drv.in.enc[i];
        s->ref[i] = drv.ref.pos[i];
        s->vel_ref[i] = drv.ref.vel[i];
        s->pos[i] = e->out.pos_nm;
        s->pos_raw[i] = e->out.pos_nm_raw;
        s->encoder_illegal[i] = e->out.illegal;
        s->motor_mv[i] = drv.servo.out_mv[i];
    }
    for (i = 0; i < CORE_AXES; i++) {
        s->refscale[i] = drv.in.ref_on[i] ? drv.in.ref_nm[i] : 0;
    }
    s->contour_error_nm = drv.servo.cec.active ? drv.servo.cec.ec_nm[0] : 0;
    s->blocks_done = drv.blocks_done + feed_skipped(&feed);
    s->tag = drv.cur_tag;
    s->homed = drv.homed;
    for (i = 0; i < CORE_AXES; i++) {
        s->home_shift[i] = drv.home.shift[i];
    }
}

/* End of the tick's status update (drive_tick made st_seq odd at its
 * start). The fields status_live() gives are read by the snapshot from the
 * live state (the tick changes them only inside its odd st_seq window), and
 * copied here only while the caller samples them (drive_tick's
 * ref_sampling: calib_tick reads pos, pos_raw and refscale of the
 * published status); the rest is published every tick. Axes beyond
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

static const servo_io_t drive_io = {hal_motor_set_mv, hal_motor_enable, hal_amp_fault};

drive_result_t drive_init(const drive_config_t *cfg)
{
    unsigned i;
    drive_status_t zero_st = {0};
    motion_ref_t zero_ref = {0};
    pos_nm_t origin[CORE_AXES] = {0};

    if (cfg == NULL || cfg->axes < 1 || cfg->axes > CORE_AXES || cfg->tick_hz < PID_TICK_HZ_MIN ||
        cfg->tick_hz > PID_TICK_HZ_MAX || cfg->stop_decel_nm_s2 <= 0 || cfg->arc_chord_nm < 0 ||
        cfg->start_delay_ms > DRIVE_START_DELAY_MS_MAX || cfg->ff_advance_ns < 0 ||
        cfg->ff_advance_ns > DRIVE_FF_ADVANCE_NS_MAX || plan_check_profile(&cfg->plan) != PLAN_OK) {
        return DRIVE_E_INVALID;
    }
    if (cfg->enc_mean && !drive_inputs_mean_ok(cfg->axes)) {
        return DRIVE_E_UNSUPPORTED;
    }
    for (i = 0; cfg->enc_interp && i < cfg->axes; i++) {
        if (cfg->enc_counter[i]) {
            return DRIVE_E_UNSUPPORTED; /* no edge times */
        }
    }
    drv.ready = false;
    drv.enc_edges = 0;
    drv.cfg = *cfg;
    drv.ff = (drive_ff_t){0};
    drive_ff_config(&drv.ff, cfg, cfg->axes);
    if (drv.cfg.arc_chord_nm == 0) {
        drv.cfg.arc_chord_nm = DRIVE_ARC_CHORD_NM;
    }
    if (!drive_inputs_init(&drv.in, cfg, hal_time_us() * 1000u)) {
        return DRIVE_E_INVALID;
    }
    drv.cfg.servo.axes = cfg->axes;
    drv.cfg.servo.tick_hz = cfg->tick_hz;
    drv.cfg.servo.cec.mode = CEC_MODE_OFF;
    if (servo_init(&drv.servo, &drv.cfg.servo, &drive_io) != SERVO_OK) {
        return DRIVE_E_INVALID;
    }
    /* one HAL call per tick for all outputs and all fault inputs */
    servo_set_io_all(&drv.servo, hal_motor_set_mv_all, hal_amp_fault_mask);
    if (!feed_init(&feed, &drv.cfg, &drv.ip, plan_store, PLAN_DEPTH_DEFAULT, origin)) {
        return DRIVE_E_INVALID;
    }
    drv.ref = zero_ref;
    drv.ch = zero_ref;
    drv.ref_synced = false;
    drv.ref_full = false;
    drv.tick_lo = 0;
    drv.stop_v = drv.stop_dv = drv.v_plan = drv.a_plan = drv.v_act = 0;
    arc_ref_reset(&drv.arc);
    drv.arc.exact = false;
    drv.seq_done = 0;
    drv.seen_done = 0;
    drv.blocks_done = 0;
    drv.cur_tag = 0;
    drv.req_enable = drv.req_disable = drv.req_stop = false;
    drv.req_estop = drv.req_reset = drv.req_gains = drv.req_cec = false;
    drv.req_fault = drv.rs_seq = 0;
    drv.req_resume = drv.req_any = drv.req_ref = drv.req_home = false;
    drv.homed = 0;
    for (i = 0; i < CORE_AXES; i++) {
        drv.home.shift[i] = 0;
    }
    drv.halted = false;
    drv.state = DRIVE_DISABLED;
    drv.state_pub = DRIVE_DISABLED;
    drv.faults = 0;
    drv.cec_mode = DRIVE_CEC_OFF;
    drv.tick = 0;
    drv.st = zero_st;
    drv.st_seq = 1; /* publish() below ends the update: 2 */
    for (i = 0; i < cfg->axes; i++) {
        hal_motor_enable(i, false);
        hal_motor_set_mv(i, 0);
    }
    for (i = 0; i < cfg->axes; i++) {
        drv.enc_edges |= (uint8_t)(cfg->enc_counter[i] ? 0u : 1u << i);
    }
    drv.ready = true;
    publish(false); /* the next tick's ref_sampling decides what is copied */
    return DRIVE_OK;
}

const drive_config_t *drive_config(void)
{
    return &drv.cfg;
}

/* ---- tick ------------------------------------------------------------------ */

/* Account completed interpolator segments (host blocks done, current tag). */
static void track_segments(void)
{
    uint32_t done = interp_blocks_done(&drv.ip);
    while (drv.seen_done != done) {
        const feed_seg_t *g = feed_seg(&feed, drv.seq_done);
        if (g->last) {
            drv.blocks_done++;
        }
        drv.seq_done++;
        drv.seen_done++;
    }
    if (interp_busy(&drv.ip)) {
        drv.cur_tag = feed_seg(&feed, interp_tag(&drv.ip))->host_tag;
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
        return FX_ONE_Q30;
    }
    return fx_ratio_q30(drv.stop_v, den);
}

static void reference_step(void)
{
    unsigned i;
    int64_t k = FX_ONE_Q30;
    bool pos_only, stepped;
    if (drv.state == DRIVE_STOPPING && !drv.halted) {
        k = stop_scale();
        interp_set_tick_ns(&drv.ip,
                           fx_round_shift64((int64_t)(1000000000u / drv.cfg.tick_hz) * k, 30));
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
    if (!interp_pos_only(&drv.ip)) {
        /* a fast-path tick ends no segment and keeps the tag */
        track_segments();
        arc_ref_stop(&drv.arc); /* anchored again below if on an arc */
    }
    pos_only = interp_pos_only(&drv.ip) && drv.ref_synced && !drv.ref_full;
    stepped = arc_ref_stepping(&drv.arc);
    if (stepped) {
        /* a cruise fast-path tick of the anchored arc phase (rot.on: every
         * tick since the anchor was one, in the same segment) */
        if (pos_only) {
            unsigned skip = interp_fast_skip(&drv.ip); /* the plane axes */
            for (i = 0; i < CORE_AXES; i++) {
                if ((skip & (1u << i)) == 0u) {
                    drv.ref.pos[i] = drv.ch.pos[i];
                }
            }
        } else {
            drv.ref = drv.ch;
            drv.ref_synced = true;
        }
        if (!arc_ref_step(&drv.arc, &drv.ref, pos_only)) {
            interp_set_fast_skip(&drv.ip, 0); /* the next tick is exact: it reads them */
        }
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
    if (!stepped && drv.ref.active && interp_busy(&drv.ip)) {
        uint32_t tag = interp_tag(&drv.ip);
        const feed_seg_t *g = feed_seg(&feed, tag);
        if (g->arc) {
            /* the recurrence rewrites the plane axes' positions without
             * reading them: the interpolator's fast path may skip them */
            bool anchored =
                arc_ref_tick(&drv.arc, &drv.ref, &drv.ch, &g->c, tag, pos_only, &drv.ip);
            interp_set_fast_skip(&drv.ip, anchored ? arc_ref_plane_mask(&g->c) : 0u);
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

/* Velocity feed-forward advance, friction feed-forward as an extra
 * reference acceleration and the mean alignment (see drive.h): the
 * reference the servo compares fb with. */
static const motion_ref_t *friction_ff(servo_fb_t *fb)
{
    if (drv.ff.on) {
        drv.ref_synced = false; /* drv.ref.vel / acc may change */
        return drive_ff_step(&drv.ff, &drv.servo, &drv.ref, fb, drv.cfg.axes);
    }
    return &drv.ref;
}

/* A state change of the tick, published for main at once. */
static void set_state(drive_state_t s)
{
    drv.state = s;
    drv.state_pub = s;
}

/* Main flushed its queues and the interpolator (req_enable, req_resume):
 * account segments from the flush on, nominal time, reference not held. */
static void restart(void)
{
    drv.halted = false;
    drv.seen_done = interp_blocks_done(&drv.ip);
    drv.seq_done = drv.rs_seq;
    interp_set_tick_ns(&drv.ip, (int64_t)(1000000000u / drv.cfg.tick_hz));
}

#if defined(__GNUC__)
#define DRV_NOINLINE __attribute__((noinline))
#else
#define DRV_NOINLINE
#endif

/* Apply the requests main posted (out of line: the usual tick only tests
 * req_any). A flag is cleared after its effect, so main, reading flags
 * before the state, never sees a request gone and its effect not there;
 * the tick clears only flags it applied (main cancels its own). */
static DRV_NOINLINE void apply_requests(const servo_fb_t *fb)
{
    unsigned i;
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
        drv.faults |= DRIVE_FAULT_ESTOP;
        servo_disable(&drv.servo);
        drv.req_estop = false;
    }
    if (drv.req_fault != 0) {
        uint32_t bits = drv.req_fault;
        drv.faults |= bits;
        servo_stop(&drv.servo);
        drv.req_fault &= ~bits; /* bits main added meanwhile stay */
    }
    if (drv.req_reset) {
        if (drv.servo.state != SERVO_STOPPING) {
            for (i = 0; i < drv.cfg.axes; i++) {
                qdec_clear_faults(&drv.in.enc[i]);
            }
            servo_clear_faults(&drv.servo);
            servo_disable(&drv.servo);
            drv.faults = 0;
            set_state(DRIVE_DISABLED);
            drv.req_reset = false;
        } else {
            drv.req_any = true; /* retried next tick */
        }
    }
    if (drv.req_disable) {
        servo_disable(&drv.servo);
        if (drv.state != DRIVE_FAULT) {
            set_state(DRIVE_DISABLED);
        }
        drv.req_disable = false;
    }
    if (drv.req_enable && !drv.req_reset) { /* a deferred reset retries both */
        /* never after a fault latched in this same tick (e.g. an e-stop
         * that arrived together with the enable); a refused enable leaves
         * the drive DISABLED (main then drops what was queued) */
        if (drv.faults == 0 && drv.state == DRIVE_DISABLED && drv.servo.state == SERVO_OFF &&
            servo_enable(&drv.servo, fb) == SERVO_OK) {
            servo_run(&drv.servo);
            restart();
            set_state(DRIVE_IDLE); /* RUNNING below if blocks are queued */
        }
        drv.req_enable = false;
    }
    if (drv.req_resume) {
        if (drv.state == DRIVE_STOPPING && drv.halted) {
            restart();
            set_state(DRIVE_IDLE);
        }
        drv.req_resume = false;
    }
    if (drv.req_home) {
        /* main checked IDLE with nothing queued; an enable, stop or fault
         * applied since wins */
        if (drv.state == DRIVE_IDLE && !feed_busy(&feed) && drv.faults == 0) {
            home_start(&drv.home, &pend_home, drv.ref.pos, drv.cfg.plan.a_max, drv.cfg.tick_hz);
            drv.homed &= ~pend_home.axes;
            set_state(DRIVE_HOMING);
        }
        drv.req_home = false;
    }
    if (drv.req_stop) {
        if (drv.state == DRIVE_HOMING) {
            home_abort(&drv.home); /* HOMING until at rest (home_step) */
        } else if (drv.state == DRIVE_RUNNING || drv.state == DRIVE_IDLE) {
            set_state(DRIVE_STOPPING);
            drv.v_act = path_speed(drv.ref.vel);
            drv.stop_v = drv.v_act;
            drv.stop_dv = drv.cfg.stop_decel_nm_s2 / (int64_t)drv.cfg.tick_hz;
            if (drv.stop_dv < 1) {
                drv.stop_dv = 1;
            }
        }
        drv.req_stop = false;
    }
}

/* One tick of the homing sequence and the servo (out of line: only while
 * HOMING). At its
 * end the drive is STOPPING at rest (halted): main flushes its queues at
 * the new reference and resumes, as after a stop. */
static DRV_NOINLINE void home_step(servo_fb_t *fb)
{
    home_result_t r = home_tick(&drv.home, drv.cfg.tick_hz, drv.in.enc, fb, &drv.servo, &drv.ref);
    drv.ref_synced = false;
    drv.homed |= drv.home.done;
    if (r == HOME_FAULT) {
        drv.faults |= DRIVE_FAULT_HOMING;
        servo_stop(&drv.servo);
    } else if (r != HOME_MOVING) {
        drv.halted = true;
        drv.v_act = 0;
        set_state(DRIVE_STOPPING);
    }
    servo_tick(&drv.servo, &drv.ref, fb);
}

/* The tick of a drive that is not IDLE, RUNNING or STOPPING with its
 * servo running (out of line: the usual tick does not pay for it): the
 * homing sequence, or the servo holding / off with the reference on its
 * hold position. */
static DRV_NOINLINE void tick_still(servo_fb_t *fb)
{
    unsigned i;
    if (drv.state == DRIVE_HOMING && drv.servo.state == SERVO_RUN) {
        home_step(fb); /* reference and servo tick */
        return;
    }
    servo_tick(&drv.servo, NULL, fb);
    for (i = 0; i < CORE_AXES; i++) {
        drv.ref.pos[i] = drv.servo.ref_pos[i];
        drv.ref.vel[i] = 0;
        drv.ref.acc[i] = 0;
    }
    drv.ref.active = false;
    drv.ref.geom.kind = MOTION_GEOM_NONE;
    drv.ref_synced = false;
}

/* drive_tick's result: constant pointers into drv */
static const drive_tick_out_t tick_out = {&drv.st, drv.ref.vel};

const drive_tick_out_t *drive_tick(bool ref_sampling)
{
    servo_fb_t fb;
    bool moving_ok;

    if (!drv.ready) {
        return NULL;
    }
    drv.st_seq++; /* odd: the status is being updated (publish ends it) */
    drive_inputs_sample(&drv.in, &drv.cfg, hal_time_us() * 1000u, &fb);
    if (ref_sampling || drv.req_ref || ((uint32_t)drv.tick & (DRIVE_REF_SAMPLE_TICKS - 1u)) == 0u) {
        /* a drive_status() request (req_ref) is cleared before the counters
         * are read: a request set after that gets the next tick */
        drv.req_ref = false;
        drive_inputs_ref_sample(&drv.in, drv.cfg.axes);
    }
    if (drv.req_any) {
        apply_requests(&fb);
    }
    moving_ok =
        drv.state == DRIVE_IDLE || drv.state == DRIVE_RUNNING || drv.state == DRIVE_STOPPING;
    if (moving_ok && drv.servo.state == SERVO_RUN) {
        reference_step();
        servo_tick(&drv.servo, friction_ff(&fb), &fb);
    } else {
        tick_still(&fb);
    }
    drv.faults |= drv.servo.faults;
    if (drv.faults != 0) {
        drv.state = DRIVE_FAULT;
    } else if (drv.state == DRIVE_IDLE || drv.state == DRIVE_RUNNING) {
        drv.state = feed_busy(&feed) ? DRIVE_RUNNING : DRIVE_IDLE;
    }
    drv.state_pub = drv.state;
    drv.tick++;
    drv.tick_lo = (uint32_t)drv.tick;
    publish(ref_sampling);
    return &tick_out;
}

/* ---- main -------------------------------------------------------------------- */

/* Drop the queued job and hold pos. Only while the tick is parked
 * (drive_tick_parked()): the interpolator is reset on both sides. The tick takes
 * over the segment count (rs_seq) with req_enable / req_resume. */
void drive_flush_all(const pos_nm_t pos[CORE_AXES])
{
    feed_flush(&feed, pos);
    drv.rs_seq = feed_seq_next(&feed);
}

void drive_poll(void)
{
    drive_state_t s = drive_main_state();
    if (!drv.ready) {
        return;
    }
    if (s == DRIVE_HOMING) {
        return; /* nothing queued; the tick makes the motion */
    }
    if (s == DRIVE_DISABLED || s == DRIVE_FAULT || s == DRIVE_STOPPING) {
        PREEMPT_POINT();
        if (drive_tick_parked() && (!feed_idle(&feed) || drv.state_pub == DRIVE_STOPPING)) {
            drive_status_t st;
            drive_snapshot(&st); /* hold the published reference */
            PREEMPT_POINT();
            drive_flush_all(st.ref);
            PREEMPT_POINT();
            if (drv.state_pub == DRIVE_STOPPING) {
                drive_post(&drv.req_resume); /* at rest: the tick goes IDLE */
            }
        }
        return;
    }
    feed_poll(&feed, drv.tick_lo);
}

uint32_t drive_queue_free(void)
{
    return feed_free(&feed);
}

static drive_result_t accept_check(void)
{
    drive_state_t s = drive_main_state();
    if (!drv.ready) {
        return DRIVE_E_DISABLED;
    }
    if (s == DRIVE_FAULT) {
        return DRIVE_E_FAULTED;
    }
    if (s == DRIVE_DISABLED) {
        return DRIVE_E_DISABLED;
    }
    if (s == DRIVE_STOPPING || s == DRIVE_HOMING) {
        return DRIVE_E_BUSY;
    }
    return DRIVE_OK;
}

drive_result_t drive_accepting(void)
{
    return accept_check();
}

drive_result_t drive_queue_block(const drive_block_t *b)
{
    drive_result_t r;
    if (b == NULL) {
        return DRIVE_E_INVALID;
    }
    r = accept_check();
    if (r != DRIVE_OK) {
        return r;
    }
    PREEMPT_POINT();
    /* the tick makes the drive RUNNING (feed.queued) */
    return feed_queue(&feed, b, drv.tick_lo);
}

drive_result_t drive_home(const drive_home_t *h)
{
    drive_result_t r;
    if (h == NULL || !home_check(h, &drv.cfg)) {
        return DRIVE_E_INVALID;
    }
    r = accept_check();
    if (r != DRIVE_OK) {
        return r;
    }
    PREEMPT_POINT();
    if (drive_main_state() != DRIVE_IDLE || !feed_idle(&feed)) {
        return DRIVE_E_BUSY; /* a job or jog is queued or executing */
    }
    pend_home = *h;
    drive_post(&drv.req_home);
    return DRIVE_OK;
}

static CORE_NO_TSAN void snapshot(drive_status_t *out, uint16_t *ip_rd, int64_t *ip_rem)
{
    uint32_t s;
    do {
        s = drv.st_seq;
        CORE_BARRIER(); /* no plain load moves across the st_seq reads */
        *out = drv.st;
        PREEMPT_POINT();
        status_live(out);
        PREEMPT_POINT();
        /* the interpolator's read index and the time left in its current
         * segment (-1: none): the tick changes them only inside its odd
         * st_seq window; main, which runs this, is the only writer of the
         * FIFO slots and does not write the current one */
        *ip_rd = interp_rd(&drv.ip);
        *ip_rem = interp_left_ns(&drv.ip);
        CORE_BARRIER();
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

/* drive_snapshot's state, faults, contour error, ref and pos, each from
 * where snapshot() takes it (status_live's sources for the live ones) */
CORE_NO_TSAN void drive_trace_read(drive_trace_t *out)
{
    uint32_t s;
    unsigned i;
    do {
        s = drv.st_seq;
        CORE_BARRIER(); /* no plain load moves across the st_seq reads */
        out->state = drv.st.state;
        out->faults = drv.st.faults;
        out->contour_error_nm = drv.servo.cec.active ? drv.servo.cec.ec_nm[0] : 0;
        for (i = 0; i < CORE_AXES; i++) {
            bool live = i < drv.cfg.axes;
            out->ref[i] = live ? drv.ref.pos[i] : drv.st.ref[i];
            out->pos[i] = live ? drv.in.enc[i].out.pos_nm : drv.st.pos[i];
        }
        PREEMPT_POINT();
        CORE_BARRIER();
    } while ((s & 1u) != 0 || s != drv.st_seq);
}

void drive_status(drive_status_t *out)
{
    uint16_t rd;
    int64_t rem;
    bool stop = drv.req_stop; /* before the snapshot (see drive_main_state()) */
    bool home = drv.req_home;
    if (out == NULL) {
        return;
    }
    snapshot(out, &rd, &rem);
    drv.req_ref = true; /* the next tick samples the reference scales */
    PREEMPT_POINT();
    /* a pending stop: STOPPING (no stale IDLE after a stop); IDLE with
     * blocks queued since the last tick: RUNNING (docs/tick-main.md) */
    out->state = drive_main_view(out->state, false, false, stop);
    if (home && out->state == DRIVE_IDLE) {
        out->state = DRIVE_HOMING; /* a home not yet started */
    }
    if (out->state == DRIVE_IDLE && !feed_idle(&feed)) {
        out->state = DRIVE_RUNNING;
    }
    out->queue_free = feed_free(&feed);
    /* planner, then the interpolator's FIFO from the published read index
     * (segments loaded since are counted; a current one by its remainder) */
    out->queued_time_ns = feed_queued_ns(&feed, rd, rem);
}

#if CORE_AXES > 8
#error "drv.enc_edges holds one bit per axis"
#endif

void drive_encoder_edge(unsigned ch, uint32_t lines, uint32_t t_ns)
{
    if (ch < CORE_AXES && (drv.enc_edges & (1u << ch)) != 0u) {
        qdec_edge(&drv.in.enc[ch], lines, t_ns);
    }
}

bool drive_encoder_run(unsigned ch, int32_t steps, uint32_t t_last_ns)
{
    return ch < CORE_AXES && (drv.enc_edges & (1u << ch)) != 0u &&
           qdec_edge_run(&drv.in.enc[ch], steps, t_last_ns);
}

int64_t drive_encoder_count(unsigned ch)
{
    if (!drv.ready || ch >= drv.cfg.axes) {
        return 0;
    }
    return drv.in.enc[ch].out.pos;
}

void drive_set_comp(unsigned axis, const comp_table_t *table)
{
    if (drv.ready && axis < drv.cfg.axes) {
        qdec_set_comp(&drv.in.enc[axis], table);
    }
}

void drive_test_full_ref(bool on)
{
    drv.ref_full = on;
}

void drive_test_arc_exact(bool on)
{
    drv.arc.exact = on;
    arc_ref_stop(&drv.arc);
    interp_set_fast_skip(&drv.ip, 0);
}

const qdec_t *drive_test_encoder(unsigned ch)
{
    return (ch < CORE_AXES) ? &drv.in.enc[ch] : NULL;
}

const motion_ref_t *drive_test_ref(void)
{
    return &drv.ref;
}

bool drive_has_refscale(unsigned axis)
{
    return drv.ready && axis < drv.cfg.axes && drv.in.ref_on[axis];
}

/* ---- parameters (the table: drive_param.c) ----------------------------------- */

bool drive_ready(void)
{
    return drv.ready;
}

/* Nothing queued, executing or stopping (parameters may change). */
static bool planner_idle(void)
{
    return !drive_moving() && !drv.req_stop && feed_idle(&feed);
}

drive_result_t drive_apply_config(const drive_config_t *c)
{
    unsigned i;
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
    drv.cfg.ff_advance_ns = c->ff_advance_ns;
    drv.cfg.qg_comp = c->qg_comp;
    drv.cfg.enc_mean = c->enc_mean; /* main checked the port (drive_param.c) */
    drive_inputs_set_mean(&drv.in, c->enc_mean);
    drv.cfg.friction_ff_band_nm_s = c->friction_ff_band_nm_s;
    for (i = 0; i < CORE_AXES; i++) {
        drv.cfg.friction_ff_mv[i] = c->friction_ff_mv[i];
        drv.cfg.soft_min[i] = c->soft_min[i];
        drv.cfg.soft_max[i] = c->soft_max[i];
        drv.cfg.in_pos_nm[i] = c->in_pos_nm[i];
    }
    drive_ff_config(&drv.ff, &drv.cfg, drv.cfg.axes);
    feed_set_profile(&feed, &c->plan);
    return DRIVE_OK;
}
