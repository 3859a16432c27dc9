/*
 * co_param.h - the CiA 402 objects that are drive parameters (drive.h
 * drive_param_*): read from the drive, written through the same
 * drive_param_set the own protocol's set_param uses. Main context only.
 *
 * Specification
 * -------------
 *   object      drive parameter (axis 0)  unit of the object
 *   0x6065      FERR_LIMIT               nm; 0xFFFFFFFF = off (the drive's 0)
 *   0x6066      (none)                   ms; only 0: the drive faults at the
 *                                        first tick beyond the window
 *   0x607D:1/2  SOFT_MIN / SOFT_MAX      nm; 0 / 0 = off (the drive's rule)
 *   0x607F      V_MAX                    nm/s
 *   0x6083      A_MAX                    um/s^2 (one a_max: the planner's
 *   0x6084      A_MAX                    um/s^2  profile is symmetric)
 *   0x6085      STOP_DECEL               um/s^2 (quick stop = drive_stop)
 * co_param_check (the node's check hook, SDO downloads): the value scaled
 * to the drive's unit; above / below drive_param_range -> 0x06090031 /
 * 0x06090032; drive_param_set: DRIVE_E_BUSY -> 0x08000022 (the planner is
 * not idle), another refusal -> 0x06090030; 0 when the drive took it (the
 * node then stores the object). co_param_written (write hook: RPDOs) sets
 * the drive when the object differs from it; a refusal is silent (an RPDO
 * has no answer) and co_param_refresh puts the drive's value back.
 * 0x1010:1 = "save" (0x65766173) -> param_store_save, 0x1011:1 = "load"
 * (0x64616F6C) -> param_store_save_defaults (the defaults at the next
 * start): another value -> 0x08000020, the drive not disabled ->
 * 0x08000022, the flash failed -> 0x06060000. Both read 1 (save on
 * command). The CiA 301 objects (PDO mapping, 0x1016, 0x1017) are not
 * stored: a master configures them after boot-up.
 * co_param_refresh (every main pass) copies the drive's values into the
 * objects (a value beyond the object's type saturates), so a change made
 * by the own protocol or param_store shows at once.
 */
#ifndef CO_PARAM_H
#define CO_PARAM_H

#include "canopen.h"

#define CO_ABORT_STATE 0x08000022u /* not in the present device state */

/* 0: not a parameter object or the drive took it; else the abort code. */
uint32_t co_param_check(co_t *co, uint16_t index, uint8_t sub, uint32_t value);
void co_param_written(co_t *co, uint16_t index, uint8_t sub);
void co_param_refresh(co_t *co);

#endif
