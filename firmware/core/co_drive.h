/*
 * co_drive.h - ties the CiA 402 objects of the node to the drive (drive.h):
 * the power state machine (0x6040 / 0x6041, cia402.h), modes of operation
 * (0x6060 / 0x6061: 0 none, 8 CSP, co_csp.h), position actual 0x6064, and
 * the drive's faults as EMCY (co_emcy.h). Main context only.
 *
 * Specification
 * -------------
 * A controlword written by SDO or RPDO runs the state machine; entering
 * OPERATION ENABLED enables the drive (a refusal is a fault: FAULT REACTION
 * ACTIVE -> FAULT), leaving it for SWITCHED ON / READY / SWITCH ON DISABLED
 * disables it, QUICK STOP ACTIVE commands the drive's controlled stop and
 * ends (transition 12, drive disabled) once the drive is idle. co_drive_poll
 * latches a drive fault into FAULT (13, 14: the drive already disabled its
 * outputs), reports the drive's faults as EMCY and keeps 0x6041 (bit 4:
 * drive enabled, bit 12 in CSP: the drive follows the target) and 0x6064
 * up to date. Fault reset (15) calls drive_fault_reset; when the drive
 * refuses (cause present) the state machine stays in FAULT.
 * 0x6060 accepts 0, 1 (PP), 6 (homing) and 8 (CSP) (else abort
 * 0x06090030); 0x6061 shows it. CSP runs while the mode is 8 in OPERATION
 * ENABLED; PP and homing start on controlword bit 4 (co_pp.h). At each SYNC 0x6064 is
 * sampled (the drive's last published tick) before the TPDOs, and 0x607A
 * is applied (co_csp_sync) after the RPDOs.
 * A heartbeat consumer timeout (co_hb.h, co->hb.lost changed): FAULT
 * REACTION ACTIVE; a moving drive gets the controlled stop first, then
 * DRIVE_FAULT_COMM is raised (EMCY 0x8130) and the next poll enters FAULT.
 * After a fault reset the snapshot's faults are ignored until the tick has
 * cleared them (at most 100 ms). The parameter objects: co_param.h.
 *
 * Axes (CiA 402 multi-axis ranges, CO_DRIVE_AXES): 402 axis n's objects
 * are at 0x6000 + n * 0x800 (0x6840 / 0x6841 / 0x6860 / 0x6861 / 0x6864 /
 * 0x687A for axis 1 = Y, 0x7040 .. for axis 2 = Z), each with its own state
 * machine, mode (0, 1 PP or 8 CSP; homing 6 on axis 0 only), PP set-point
 * and CSP target. The drive has one power stage: it is enabled when some
 * axis enters OPERATION ENABLED and disabled when the last one leaves it;
 * quick stop stops the drive (every axis's motion); a drive fault or a
 * heartbeat loss puts every axis into FAULT; statusword bit 4 is the
 * drive's. The axes share one planner queue: a CSP SYNC queues one block
 * moving every axis in CSP; a PP set-point moves its axis alone and is
 * refused (bit 12 stays 0) while some axis is in CSP. The parameter
 * objects 0x6065 .. 0x6085 exist for axis 0 only.
 */
#ifndef CO_DRIVE_H
#define CO_DRIVE_H

#include "canopen.h"
#include "cia402.h"
#include "co_csp.h"
#include "co_pp.h"

#define CO_DRIVE_AXES 3u /* 402 axes: 0x6000, 0x6800, 0x7000 */

/* Attach to co (sets its write, check and SYNC hooks); the drive must be
 * initialised. */
void co_drive_init(co_t *co);
void co_drive_poll(co_t *co, uint32_t now_us);
const cia402_t *co_drive_state(void);
const co_csp_t *co_drive_csp(void);
/* The drive tick whose position the last SYNC sampled, the SYNCs sampled
 * and the CSP targets refused (figures of the simulator, tests). */
uint64_t co_drive_sync_tick(void);
uint32_t co_drive_sync_count(void);
uint32_t co_drive_csp_missed(void);

#endif
