/*
 * co_drive.c - CiA 402 state machine <-> drive (co_drive.h is the specification).
 */
#include "co_drive.h"

#include "drive.h"

static cia402_t ax;

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
    }
}

void co_drive_init(co_t *co)
{
    cia402_init(&ax);
    co_set_write_hook(co, on_write, co);
    co_drive_poll(co);
}

void co_drive_poll(co_t *co)
{
    drive_status_t st;
    cia402_state_t before = ax.state;

    drive_snapshot(&st);
    if (st.faults != 0u || st.state == DRIVE_FAULT) {
        cia402_fault(&ax);
        cia402_reaction_done(&ax);
    } else if (ax.state == CIA402_QUICK_STOP_ACTIVE && st.state != DRIVE_STOPPING &&
               st.state != DRIVE_RUNNING) {
        cia402_quick_stop_done(&ax);
        apply(before);
    }
    co->od.statusword = cia402_statusword(
        &ax, st.state != DRIVE_DISABLED && st.state != DRIVE_FAULT, false, st.state == DRIVE_IDLE);
}

const cia402_t *co_drive_state(void)
{
    return &ax;
}
