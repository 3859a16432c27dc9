/*
 * co_drive.h - ties the CiA 402 power state machine of the node (0x6040 /
 * 0x6041, cia402.h) to the drive (drive.h). Main context only.
 *
 * Specification
 * -------------
 * A controlword written by SDO runs the state machine; entering OPERATION
 * ENABLED enables the drive (a refusal is a fault: FAULT REACTION ACTIVE ->
 * FAULT), leaving it for SWITCHED ON / READY / SWITCH ON DISABLED disables
 * it, QUICK STOP ACTIVE commands the drive's controlled stop and ends
 * (transition 12, drive disabled) once the drive is idle. co_drive_poll
 * latches a drive fault into FAULT (13, 14: the drive already disabled its
 * outputs) and keeps 0x6041 up to date (bit 4: drive enabled). Fault reset
 * (15) calls drive_fault_reset; when the drive refuses (cause present) the
 * state machine stays in FAULT.
 */
#ifndef CO_DRIVE_H
#define CO_DRIVE_H

#include "canopen.h"
#include "cia402.h"

/* Attach to co (sets its write hook); the drive must be initialised. */
void co_drive_init(co_t *co);
void co_drive_poll(co_t *co);
const cia402_t *co_drive_state(void);

#endif
