/*
 * co_pp.h - CiA 402 profile position (PP, 0x6060 = 1) and homing (0x6060 =
 * 6) of one axis of the drive's CANopen node (co_pp_t.axis; homing on
 * axis 0 only). Main context only.
 *
 * Specification
 * -------------
 * Both start on a rising edge of controlword bit 4 in OPERATION ENABLED
 * (co_pp_controlword, called after every controlword write):
 *   PP: 0x607A (absolute, or relative to the last set-point with bit 6) as
 *       one LINE block of the drive's planner at 0x6081 (nm/s), stopping at
 *       its end; the drive's acceleration and jerk limits apply (0x6083 /
 *       0x6084 are not built). Accepted: statusword bit 12 (set-point
 *       acknowledge) until bit 4 falls; refused (busy, limit, queue):
 *       counted, bit 12 stays 0. Bit 5 (change immediately) is not
 *       supported: a new set-point queues after the running one.
 *   Homing: drive_home on axis 0 (drive.h): methods 1 / 2 (negative /
 *       positive switch, then the encoder index), 17 / 18 (the same without
 *       the index), with the drive's home switch standing for the limit
 *       switch; search at 0x6099:1, back-off and index at 0x6099:2 (nm/s),
 *       the reference point becomes 0x607C (nm); at most CO_PP_HOME_MAX_NM
 *       per phase. Statusword bit 12 (homing attained) once axis 0 is homed
 *       and the drive at rest, bit 13 (homing error) with
 *       DRIVE_FAULT_HOMING or a refused start. Other methods: 0x06090030.
 * Bit 10 (target reached) is the drive at rest with nothing queued, as in
 * every mode.
 */
#ifndef CO_PP_H
#define CO_PP_H

#include <stdbool.h>
#include <stdint.h>

#include "canopen.h"
#include "drive.h"

#define CO_PP_HOME_MAX_NM 2000000000 /* 2 m per homing phase */

typedef struct {
    bool bit4;        /* controlword bit 4 as last seen */
    bool ack;         /* PP: set-point acknowledged */
    bool home_failed; /* homing: refused start */
    pos_nm_t last;    /* PP: last set-point, nm */
    uint32_t refused; /* set-points / homing starts the drive refused */
    uint8_t axis;     /* the drive axis of this 402 axis (0x6000 + axis * 0x800) */
} co_pp_t;

/* The axis's controlword, mode and target position (0x6040 / 0x6060 /
 * 0x607A, or 0x6840 .. for axis 1). */
typedef struct {
    uint16_t cw;
    int8_t mode;
    int32_t target;
} co_pp_cmd_t;

void co_pp_controlword(co_pp_t *p, co_t *co, bool enabled, const co_pp_cmd_t *c);
/* Statusword bits 12, 13 of the mode (0 in other modes). */
uint16_t co_pp_status(const co_pp_t *p, int8_t mode, const drive_status_t *st);
/* 0 or 0x06090030 for a homing method that is not supported. */
uint32_t co_pp_check_method(int32_t method);

#endif
