/*
 * co_drive.c - CiA 402 objects <-> drive (co_drive.h is the specification).
 */
#include "co_drive.h"

#include "co_param.h"
#include "drive.h"

#define MODE_CSP 8

static cia402_t ax;
static co_csp_t csp;
static co_pp_t pp;
static uint64_t sync_tick;    /* main */
static uint32_t sync_count;   /* main */
static uint32_t hb_lost_seen; /* main: co->hb.lost acted on */
static bool hb_stopping;      /* main: controlled stop of a heartbeat loss */
static bool reset_pending;    /* main: fault reset posted, the tick not yet done */
static uint32_t poll_us;      /* main: time of the last co_drive_poll */
static uint32_t reset_us;     /* main: when the fault reset was posted */

static bool moving(const drive_status_t *st)
{
    return st->state == DRIVE_RUNNING || st->state == DRIVE_HOMING || st->state == DRIVE_STOPPING;
}

static void hb_raise(co_t *co, const drive_status_t *st)
{
    if (st->state != DRIVE_FAULT) {
        co->emcy.comm_code = 0x8130u; /* life guard / heartbeat error */
        drive_raise_fault(DRIVE_FAULT_COMM);
    }
}

/* The master's heartbeat lost (co_hb.h): what the own protocol's watchdog
 * does (controlled stop, then DRIVE_FAULT_COMM), 402 FAULT REACTION ACTIVE
 * until the fault is latched. */
static void hb_watch(co_t *co, const drive_status_t *st)
{
    if (co->hb.lost != hb_lost_seen) {
        hb_lost_seen = co->hb.lost;
        cia402_fault(&ax);
        if (moving(st)) {
            drive_stop();
            hb_stopping = true;
        } else {
            hb_raise(co, st);
        }
    } else if (hb_stopping && !moving(st)) {
        hb_stopping = false;
        hb_raise(co, st);
    }
}

static void csp_follow(co_t *co)
{
    bool on = ax.state == CIA402_OPERATION_ENABLED && co->od.mode == MODE_CSP;

    if (on && !csp.active) {
        co_csp_start(&csp);
    } else if (!on && csp.active) {
        co_csp_stop(&csp);
    }
}

static void apply(cia402_state_t before)
{
    cia402_state_t now = ax.state;

    if (now == before) {
        return;
    }
    if (now == CIA402_OPERATION_ENABLED) {
        if (drive_enable(true) != DRIVE_OK) {
            cia402_fault(&ax);
            cia402_reaction_done(&ax);
        }
    } else if (now == CIA402_QUICK_STOP_ACTIVE) {
        drive_stop();
    } else if (before == CIA402_FAULT && now == CIA402_SWITCH_ON_DISABLED) {
        if (drive_fault_reset() != DRIVE_OK) {
            ax.state = CIA402_FAULT;
        } else {
            /* the tick clears the faults later: until then (at most
             * 100 ms) the snapshot's faults are the old ones */
            reset_pending = true;
            reset_us = poll_us;
        }
    } else if (before == CIA402_OPERATION_ENABLED || before == CIA402_QUICK_STOP_ACTIVE) {
        (void)drive_enable(false);
    }
}

static void on_write(void *ctx, uint16_t index, uint8_t sub)
{
    co_t *co = ctx;
    cia402_state_t before = ax.state;

    if (index == 0x6040u && sub == 0u) {
        (void)cia402_controlword(&ax, co->od.controlword);
        apply(before);
        co_pp_controlword(&pp, co, ax.state == CIA402_OPERATION_ENABLED);
    } else if (index == 0x6060u) {
        co->od.mode_display = co->od.mode;
    } else {
        co_param_written(co, index, sub);
    }
    csp_follow(co);
}

static uint32_t on_check(void *ctx, uint16_t index, uint8_t sub, uint32_t value)
{
    if (index == 0x6060u && value != 0u && value != 1u && value != 6u && value != MODE_CSP) {
        return CO_ABORT_VALUE;
    }
    if (index == 0x6098u) {
        return co_pp_check_method((int8_t)value);
    }
    return co_param_check(ctx, index, sub, value);
}

static void sample(co_t *co, drive_status_t *st)
{
    drive_snapshot(st);
    co->od.position_actual = (int32_t)st->pos[0];
}

static void on_sync(void *ctx, int phase, uint32_t now_us)
{
    co_t *co = ctx;
    drive_status_t st;

    (void)now_us;
    if (phase == CO_SYNC_SAMPLE) {
        sample(co, &st);
        sync_tick = st.tick;
        sync_count++;
    } else {
        co_csp_sync(&csp, co->od.target_position,
                    co_csp_period_ns(co->od.ipol_value, co->od.ipol_index));
    }
}

void co_drive_init(co_t *co)
{
    cia402_init(&ax);
    csp.active = false;
    csp.queued = 0u;
    csp.missed = 0u;
    pp = (co_pp_t){0};
    sync_tick = 0u;
    sync_count = 0u;
    hb_lost_seen = co->hb.lost;
    hb_stopping = false;
    reset_pending = false;
    co_set_write_hook(co, on_write, co);
    co_set_check_hook(co, on_check);
    co_set_sync_hook(co, on_sync);
    co_drive_poll(co, 0u);
}

void co_drive_poll(co_t *co, uint32_t now_us)
{
    drive_status_t st;
    cia402_state_t before = ax.state;
    uint16_t sw;

    sample(co, &st);
    co_param_refresh(co);
    hb_watch(co, &st);
    poll_us = now_us;
    if (reset_pending &&
        ((st.faults == 0u && st.state != DRIVE_FAULT) || now_us - reset_us > 100000u)) {
        reset_pending = false;
    }
    if (!reset_pending && (st.faults != 0u || st.state == DRIVE_FAULT)) {
        cia402_fault(&ax);
        cia402_reaction_done(&ax);
    } else if (ax.state == CIA402_QUICK_STOP_ACTIVE && st.state != DRIVE_STOPPING &&
               st.state != DRIVE_RUNNING) {
        cia402_quick_stop_done(&ax);
        apply(before);
    }
    csp_follow(co);
    co_emcy_update(co, st.faults, now_us);
    sw = cia402_statusword(&ax, st.state != DRIVE_DISABLED && st.state != DRIVE_FAULT, false,
                           st.state == DRIVE_IDLE);
    if (csp.active) {
        sw |= 0x1000u; /* CSP: the drive follows the target */
    }
    sw |= co_pp_status(&pp, co, &st); /* PP, homing: bits 12, 13 */
    if ((st.faults & DRIVE_FAULT_FOLLOWING) != 0u) {
        sw |= 0x2000u; /* following error */
    }
    co->od.statusword = sw;
}

const cia402_t *co_drive_state(void)
{
    return &ax;
}

const co_csp_t *co_drive_csp(void)
{
    return &csp;
}

uint64_t co_drive_sync_tick(void)
{
    return sync_tick;
}

uint32_t co_drive_sync_count(void)
{
    return sync_count;
}

uint32_t co_drive_csp_missed(void)
{
    return csp.missed;
}
