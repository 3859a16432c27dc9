/*
 * co_drive.c - CiA 402 objects <-> drive (co_drive.h is the specification).
 */
#include "co_drive.h"

#include "co_param.h"
#include "drive.h"

#define MODE_CSP 8

static cia402_t ax[CO_DRIVE_AXES]; /* main */
static co_csp_t csp;
static co_pp_t pp[CO_DRIVE_AXES];
static uint64_t sync_tick;    /* main */
static uint32_t sync_count;   /* main */
static uint32_t hb_lost_seen; /* main: co->hb.lost acted on */
static bool hb_stopping;      /* main: controlled stop of a heartbeat loss */
static bool reset_pending;    /* main: fault reset posted, the tick not yet done */
static uint32_t poll_us;      /* main: time of the last co_drive_poll */
static uint32_t reset_us;     /* main: when the fault reset was posted */

/* The objects of 402 axis n: 0x6040.. for 0, 0x6840.. / 0x7040.. for 1, 2. */
static uint16_t *cw_of(co_t *co, unsigned n)
{
    return n == 0u ? &co->od.controlword : &co->od.ax_controlword[n - 1u];
}

static uint16_t *sw_of(co_t *co, unsigned n)
{
    return n == 0u ? &co->od.statusword : &co->od.ax_statusword[n - 1u];
}

static int8_t mode_of(const co_t *co, unsigned n)
{
    return n == 0u ? co->od.mode : co->od.ax_mode[n - 1u];
}

static int32_t target_of(const co_t *co, unsigned n)
{
    return n == 0u ? co->od.target_position : co->od.ax_target_position[n - 1u];
}

/* 402 axis of an object index (0x6000 + n * 0x800), or -1. */
static int axis_of(uint16_t index)
{
    unsigned n = index >= 0x6000u ? (index - 0x6000u) / 0x800u : CO_DRIVE_AXES;

    return n < CO_DRIVE_AXES ? (int)n : -1;
}

static bool powered(const cia402_t *s)
{
    return s->state == CIA402_OPERATION_ENABLED || s->state == CIA402_QUICK_STOP_ACTIVE;
}

/* Whether a 402 axis other than n holds the power stage on. */
static bool others_powered(unsigned n)
{
    unsigned i;

    for (i = 0; i < CO_DRIVE_AXES; i++) {
        if (i != n && powered(&ax[i])) {
            return true;
        }
    }
    return false;
}

static void fault_all(void)
{
    unsigned i;

    for (i = 0; i < CO_DRIVE_AXES; i++) {
        cia402_fault(&ax[i]);
        cia402_reaction_done(&ax[i]);
    }
}

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
        for (unsigned i = 0; i < CO_DRIVE_AXES; i++) {
            cia402_fault(&ax[i]);
        }
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
    unsigned n;

    for (n = 0; n < CO_DRIVE_AXES; n++) {
        bool on = ax[n].state == CIA402_OPERATION_ENABLED && mode_of(co, n) == MODE_CSP;
        bool is = (csp.axes & (1u << n)) != 0u;

        if (on && !is) {
            co_csp_start(&csp, n);
        } else if (!on && is) {
            co_csp_stop(&csp, n);
        }
    }
}

static void apply(unsigned n, cia402_state_t before)
{
    cia402_state_t now = ax[n].state;

    if (now == before) {
        return;
    }
    if (now == CIA402_OPERATION_ENABLED) {
        if (drive_enable(true) != DRIVE_OK) {
            fault_all();
        }
    } else if (now == CIA402_QUICK_STOP_ACTIVE) {
        drive_stop();
    } else if (before == CIA402_FAULT && now == CIA402_SWITCH_ON_DISABLED) {
        if (drive_fault_reset() != DRIVE_OK) {
            ax[n].state = CIA402_FAULT;
        } else {
            /* the tick clears the faults later: until then (at most
             * 100 ms) the snapshot's faults are the old ones */
            reset_pending = true;
            reset_us = poll_us;
        }
    } else if ((before == CIA402_OPERATION_ENABLED || before == CIA402_QUICK_STOP_ACTIVE) &&
               !others_powered(n)) {
        (void)drive_enable(false);
    }
}

static void on_write(void *ctx, uint16_t index, uint8_t sub)
{
    co_t *co = ctx;
    int n = axis_of(index);
    uint16_t obj = (uint16_t)(index - (n > 0 ? (unsigned)n * 0x800u : 0u));

    if (n >= 0 && obj == 0x6040u && sub == 0u) {
        cia402_state_t before = ax[n].state;
        co_pp_cmd_t c = {*cw_of(co, (unsigned)n), mode_of(co, (unsigned)n),
                         target_of(co, (unsigned)n)};

        (void)cia402_controlword(&ax[n], c.cw);
        apply((unsigned)n, before);
        /* one planner queue: no PP set-point while an axis follows CSP */
        co_pp_controlword(&pp[n], co, ax[n].state == CIA402_OPERATION_ENABLED && !csp.active, &c);
    } else if (index == 0x6060u) {
        co->od.mode_display = co->od.mode;
    } else if (n > 0 && obj == 0x6060u) {
        co->od.ax_mode_display[n - 1] = co->od.ax_mode[n - 1];
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
    if ((index == 0x6860u || index == 0x7060u) && value != 0u && value != 1u && value != MODE_CSP) {
        return CO_ABORT_VALUE; /* homing: axis 0 only */
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
    co->od.ax_position_actual[0] = (int32_t)st->pos[1];
    co->od.ax_position_actual[1] = (int32_t)st->pos[2];
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
        int32_t t[CORE_AXES] = {0};
        unsigned n;

        for (n = 0; n < CO_DRIVE_AXES && n < CORE_AXES; n++) {
            t[n] = target_of(co, n);
        }
        co_csp_sync(&csp, t, co_csp_period_ns(co->od.ipol_value, co->od.ipol_index));
    }
}

void co_drive_init(co_t *co)
{
    unsigned n;

    for (n = 0; n < CO_DRIVE_AXES; n++) {
        cia402_init(&ax[n]);
        pp[n] = (co_pp_t){0};
        pp[n].axis = (uint8_t)n;
    }
    csp.active = false;
    csp.axes = 0u;
    csp.queued = 0u;
    csp.missed = 0u;
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
    unsigned n;

    sample(co, &st);
    co_param_refresh(co);
    hb_watch(co, &st);
    poll_us = now_us;
    if (reset_pending &&
        ((st.faults == 0u && st.state != DRIVE_FAULT) || now_us - reset_us > 100000u)) {
        reset_pending = false;
    }
    if (!reset_pending && (st.faults != 0u || st.state == DRIVE_FAULT)) {
        fault_all();
    }
    for (n = 0; n < CO_DRIVE_AXES; n++) {
        cia402_state_t before = ax[n].state;

        if (ax[n].state == CIA402_QUICK_STOP_ACTIVE && st.state != DRIVE_STOPPING &&
            st.state != DRIVE_RUNNING) {
            cia402_quick_stop_done(&ax[n]);
            apply(n, before);
        }
    }
    csp_follow(co);
    co_emcy_update(co, st.faults, now_us);
    for (n = 0; n < CO_DRIVE_AXES; n++) {
        uint16_t sw =
            cia402_statusword(&ax[n], st.state != DRIVE_DISABLED && st.state != DRIVE_FAULT, false,
                              st.state == DRIVE_IDLE);

        if ((csp.axes & (1u << n)) != 0u) {
            sw |= 0x1000u; /* CSP: the axis follows the target */
        }
        sw |= co_pp_status(&pp[n], mode_of(co, n), &st); /* PP, homing: bits 12, 13 */
        if ((st.faults & DRIVE_FAULT_FOLLOWING) != 0u) {
            sw |= 0x2000u; /* following error */
        }
        *sw_of(co, n) = sw;
    }
}

const cia402_t *co_drive_state(void)
{
    return &ax[0];
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
