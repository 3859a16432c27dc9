/*
 * cia402.h - the CiA 402 power state machine of one axis: controlword
 * (0x6040) in, state and statusword (0x6041) out. Pure logic; the caller
 * acts on state changes (enable / disable the axis, controlled stop).
 *
 * Specification (CiA 402-2, figure "state machine"; transition numbers)
 * ------------------------------------------------------------------------
 * cia402_init: NOT READY TO SWITCH ON, then at once (1) SWITCH ON DISABLED.
 * Controlword commands (bits 7 3 2 1 0; x = any):
 *   shutdown           0 x 1 1 0   2, 6, 8
 *   switch on          0 0 1 1 1   3 (5 from OPERATION ENABLED)
 *   switch on + enable 0 1 1 1 1   3 + 4 from READY TO SWITCH ON, 4, 16
 *   disable voltage    0 x x 0 x   7, 9, 10, 12
 *   quick stop         0 x 0 1 x   7, 10, 11
 *   fault reset        0 -> 1 edge of bit 7: 15 (FAULT only)
 * A command that names no transition from the current state is ignored.
 * cia402_fault (13) from any state but FAULT / FAULT REACTION ACTIVE;
 * cia402_reaction_done (14) FAULT REACTION ACTIVE -> FAULT;
 * cia402_quick_stop_done (12) QUICK STOP ACTIVE -> SWITCH ON DISABLED
 * (quick stop option code 2: stop on the quick-stop ramp, then disable).
 *
 * Statusword: bits 0..6 as CiA 402 for the state, bit 4 voltage enabled
 * (the caller's power stage), bit 9 remote (always: the drive is controlled
 * over the bus), bit 10 target reached (caller), bit 7 warning (caller).
 *
 * Context: main only (the SDO server and the PDO copy at SYNC call it).
 */
#ifndef CIA402_H
#define CIA402_H

#include <stdbool.h>
#include <stdint.h>

typedef enum {
    CIA402_NOT_READY = 0,
    CIA402_SWITCH_ON_DISABLED,
    CIA402_READY_TO_SWITCH_ON,
    CIA402_SWITCHED_ON,
    CIA402_OPERATION_ENABLED,
    CIA402_QUICK_STOP_ACTIVE,
    CIA402_FAULT_REACTION_ACTIVE,
    CIA402_FAULT,
} cia402_state_t;

typedef struct {
    cia402_state_t state;
    uint16_t controlword; /* last one written */
} cia402_t;

void cia402_init(cia402_t *s);
/* Apply a controlword; returns the new state. */
cia402_state_t cia402_controlword(cia402_t *s, uint16_t cw);
void cia402_fault(cia402_t *s);
void cia402_reaction_done(cia402_t *s);
void cia402_quick_stop_done(cia402_t *s);
uint16_t cia402_statusword(const cia402_t *s, bool voltage, bool warning, bool target_reached);

#endif
