/*
 * cia402.c - CiA 402 power state machine (cia402.h is the specification).
 */
#include "cia402.h"

enum {
    CMD_NONE = 0,
    CMD_SHUTDOWN,
    CMD_SWITCH_ON,
    CMD_ENABLE, /* switch on + enable operation */
    CMD_DISABLE_VOLTAGE,
    CMD_QUICK_STOP,
};

static int decode(uint16_t cw)
{
    if ((cw & 0x0082u) == 0x0000u) {
        return CMD_DISABLE_VOLTAGE;
    }
    if ((cw & 0x0086u) == 0x0002u) {
        return CMD_QUICK_STOP;
    }
    if ((cw & 0x0087u) == 0x0006u) {
        return CMD_SHUTDOWN;
    }
    if ((cw & 0x008Fu) == 0x0007u) {
        return CMD_SWITCH_ON;
    }
    if ((cw & 0x008Fu) == 0x000Fu) {
        return CMD_ENABLE;
    }
    return CMD_NONE;
}

void cia402_init(cia402_t *s)
{
    s->state = CIA402_NOT_READY;
    s->controlword = 0u;
    s->state = CIA402_SWITCH_ON_DISABLED; /* 1: self-test passed */
}

cia402_state_t cia402_controlword(cia402_t *s, uint16_t cw)
{
    bool reset_edge = (cw & 0x0080u) != 0u && (s->controlword & 0x0080u) == 0u;
    int cmd = decode(cw);

    s->controlword = cw;
    switch (s->state) {
    case CIA402_SWITCH_ON_DISABLED:
        if (cmd == CMD_SHUTDOWN) {
            s->state = CIA402_READY_TO_SWITCH_ON; /* 2 */
        }
        break;
    case CIA402_READY_TO_SWITCH_ON:
        if (cmd == CMD_SWITCH_ON) {
            s->state = CIA402_SWITCHED_ON; /* 3 */
        } else if (cmd == CMD_ENABLE) {
            s->state = CIA402_OPERATION_ENABLED; /* 3 + 4 */
        } else if (cmd == CMD_DISABLE_VOLTAGE || cmd == CMD_QUICK_STOP) {
            s->state = CIA402_SWITCH_ON_DISABLED; /* 7 */
        }
        break;
    case CIA402_SWITCHED_ON:
        if (cmd == CMD_ENABLE) {
            s->state = CIA402_OPERATION_ENABLED; /* 4 */
        } else if (cmd == CMD_SHUTDOWN) {
            s->state = CIA402_READY_TO_SWITCH_ON; /* 6 */
        } else if (cmd == CMD_DISABLE_VOLTAGE || cmd == CMD_QUICK_STOP) {
            s->state = CIA402_SWITCH_ON_DISABLED; /* 10 */
        }
        break;
    case CIA402_OPERATION_ENABLED:
        if (cmd == CMD_SWITCH_ON) {
            s->state = CIA402_SWITCHED_ON; /* 5 */
        } else if (cmd == CMD_SHUTDOWN) {
            s->state = CIA402_READY_TO_SWITCH_ON; /* 8 */
        } else if (cmd == CMD_DISABLE_VOLTAGE) {
            s->state = CIA402_SWITCH_ON_DISABLED; /* 9 */
        } else if (cmd == CMD_QUICK_STOP) {
            s->state = CIA402_QUICK_STOP_ACTIVE; /* 11 */
        }
        break;
    case CIA402_QUICK_STOP_ACTIVE:
        if (cmd == CMD_DISABLE_VOLTAGE) {
            s->state = CIA402_SWITCH_ON_DISABLED; /* 12 */
        } else if (cmd == CMD_ENABLE) {
            s->state = CIA402_OPERATION_ENABLED; /* 16 */
        }
        break;
    case CIA402_FAULT:
        if (reset_edge) {
            s->state = CIA402_SWITCH_ON_DISABLED; /* 15 */
        }
        break;
    default: /* NOT READY, FAULT REACTION ACTIVE: no command applies */
        break;
    }
    return s->state;
}

void cia402_fault(cia402_t *s)
{
    if (s->state != CIA402_FAULT && s->state != CIA402_FAULT_REACTION_ACTIVE) {
        s->state = CIA402_FAULT_REACTION_ACTIVE; /* 13 */
    }
}

void cia402_reaction_done(cia402_t *s)
{
    if (s->state == CIA402_FAULT_REACTION_ACTIVE) {
        s->state = CIA402_FAULT; /* 14 */
    }
}

void cia402_quick_stop_done(cia402_t *s)
{
    if (s->state == CIA402_QUICK_STOP_ACTIVE) {
        s->state = CIA402_SWITCH_ON_DISABLED; /* 12 */
    }
}

uint16_t cia402_statusword(const cia402_t *s, bool voltage, bool warning, bool target_reached)
{
    static const uint16_t bits[] = {
        [CIA402_NOT_READY] = 0x0000u,
        [CIA402_SWITCH_ON_DISABLED] = 0x0040u,
        [CIA402_READY_TO_SWITCH_ON] = 0x0021u,
        [CIA402_SWITCHED_ON] = 0x0023u,
        [CIA402_OPERATION_ENABLED] = 0x0027u,
        [CIA402_QUICK_STOP_ACTIVE] = 0x0007u,
        [CIA402_FAULT_REACTION_ACTIVE] = 0x000Fu,
        [CIA402_FAULT] = 0x0008u,
    };
    uint16_t sw = (uint16_t)(bits[s->state] | 0x0200u);

    if (voltage) {
        sw |= 0x0010u;
    }
    if (warning) {
        sw |= 0x0080u;
    }
    if (target_reached) {
        sw |= 0x0400u;
    }
    return sw;
}
