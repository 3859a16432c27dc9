/*
 * drive_req.c - main's requests to the drive's tick (enable, disable,
 * stop, estop, fault and fault reset, CEC mode, servo gains) and the state
 * main acts on while they are pending (specification in drive.h; split
 * from drive.c). Main context: a request's payload is written first, then
 * its flag, then req_any (drive_post); the tick applies it and clears the
 * flag (drive.c, apply_requests).
 */
#include "drive.h"
#include "drive_int.h"

#include "hal.h"
#include "preempt.h"

/* Post a request: its payload is written; the flag, then req_any. */
void drive_post(CORE_SHARED bool *flag)
{
    CORE_BARRIER();
    *flag = true;
    PREEMPT_POINT();
    drv.req_any = true;
}

/* The state as main acts on it: the tick's, with the requests main posted
 * and the tick has not applied yet counted as applied (a pending stop of an
 * IDLE or RUNNING drive is STOPPING: no block is accepted that it would
 * drop). Flags read before the state: a tick between has applied them. */
drive_state_t drive_main_view(drive_state_t s, bool en, bool dis, bool stop)
{
    if (s == DRIVE_FAULT) {
        return s;
    }
    if (dis) {
        return DRIVE_DISABLED;
    }
    if (stop && (s == DRIVE_IDLE || s == DRIVE_RUNNING || s == DRIVE_HOMING)) {
        return DRIVE_STOPPING;
    }
    return (en && s == DRIVE_DISABLED) ? DRIVE_IDLE : s;
}

drive_state_t drive_main_state(void)
{
    bool en = drv.req_enable, dis = drv.req_disable, stop = drv.req_stop;
    bool home = drv.req_home, rst = drv.req_reset;
    /* a pending fault reset counts as done: an enable then waits for it */
    drive_state_t s = drive_main_view(drv.state_pub, en, dis, stop);
    s = (rst && s == DRIVE_FAULT) ? DRIVE_DISABLED : s;
    /* a pending home: HOMING (no block is queued under it) */
    return (home && s == DRIVE_IDLE) ? DRIVE_HOMING : s;
}

/* The tick does not touch the interpolator and leaves this state only on a
 * request from main (flags read before the state). */
bool drive_tick_parked(void)
{
    bool en = drv.req_enable, rs = drv.req_resume;
    drive_state_t s = drv.state_pub;
    if (s == DRIVE_DISABLED || s == DRIVE_FAULT) {
        return !en;
    }
    return s == DRIVE_STOPPING && !rs && drv.halted;
}

drive_result_t drive_enable(bool on)
{
    drive_status_t st;
    drive_state_t s = drive_main_state();
    if (!drv.ready) {
        return DRIVE_E_DISABLED;
    }
    if (s == DRIVE_FAULT) {
        return DRIVE_E_FAULTED;
    }
    if (!on) {
        drv.req_enable = false; /* cancel an enable not yet applied */
        PREEMPT_POINT();
        drive_post(&drv.req_disable);
        return DRIVE_OK;
    }
    PREEMPT_POINT();
    if (s != DRIVE_DISABLED) {
        return DRIVE_OK; /* enabled, or an enable is pending */
    }
    if (!drive_tick_parked()) {
        return DRIVE_E_BUSY; /* a disable the tick has not applied yet */
    }
    /* parked DISABLED: start from the measured position */
    drive_snapshot(&st);
    PREEMPT_POINT();
    drive_flush_all(st.pos);
    PREEMPT_POINT();
    drive_post(&drv.req_enable);
    return DRIVE_OK;
}

void drive_stop(void)
{
    drive_post(&drv.req_stop);
}

void drive_estop(void)
{
    drive_post(&drv.req_estop);
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
    if (drive_main_state() != DRIVE_FAULT) {
        return DRIVE_OK;
    }
    for (i = 0; i < drv.cfg.axes; i++) {
        if (hal_amp_fault(i)) {
            return DRIVE_E_CAUSE;
        }
    }
    PREEMPT_POINT();
    drive_post(&drv.req_reset);
    return DRIVE_OK;
}

bool drive_moving(void)
{
    drive_state_t s = drive_main_state();
    return s == DRIVE_RUNNING || s == DRIVE_STOPPING || s == DRIVE_HOMING;
}

drive_result_t drive_set_cec_mode(drive_cec_mode_t mode)
{
    static const cec_mode_t map[] = {CEC_MODE_OFF,       CEC_MODE_TANGENT, CEC_MODE_CURVATURE,
                                     CEC_MODE_EXACT,     CEC_MODE_KOREN,   CEC_MODE_CURV_HISTORY,
                                     CEC_MODE_CHUANG_LIU};
    if ((unsigned)mode >= (unsigned)DRIVE_CEC_COUNT) {
        return DRIVE_E_INVALID;
    }
    if (drive_moving()) {
        return DRIVE_E_BUSY;
    }
    drv.pend_mode = map[mode];
    drv.cec_mode = mode;
    drive_post(&drv.req_cec);
    return DRIVE_OK;
}

drive_result_t drive_set_servo_params(const servo_params_t *p)
{
    servo_params_t q;
    if (p == NULL || !drv.ready) {
        return DRIVE_E_INVALID;
    }
    q = *p;
    q.axes = drv.cfg.axes;
    q.tick_hz = drv.cfg.tick_hz;
    q.cec.mode = CEC_MODE_OFF;
    if (drive_servo_probe(&q) != DRIVE_OK) { /* scratch.h */
        return DRIVE_E_INVALID;
    }
    if (drive_moving()) {
        return DRIVE_E_BUSY;
    }
    drv.pend = q;
    drv.cfg.servo = q; /* main's copy; the tick applies pend */
    drive_post(&drv.req_gains);
    return DRIVE_OK;
}
