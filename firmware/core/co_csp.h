/*
 * co_csp.h - CiA 402 cyclic synchronous position (CSP, 0x6060 = 8) of axis
 * 0 of the drive's CANopen node. Main context only.
 *
 * Specification
 * -------------
 * At each SYNC, after the synchronous RPDOs wrote 0x607A (co_pdo.h), a
 * target that differs from the last one becomes one LINE block of the
 * drive's planner (drive_queue_block) from the last target to it, at the
 * feed that covers the distance in one interpolation time period 0x60C2
 * (value x 10^index s; index -6..-3): the drive's own interpolator and
 * look-ahead run it, within its velocity, acceleration and jerk limits.
 * Axes 1.. keep the reference they had when CSP started. A target the drive
 * refuses (queue full, not enabled, soft limit) counts in `missed` and is
 * retried at the next SYNC. co_csp_start takes the current reference as
 * the last target (no jump); the master sets 0x607A to 0x6064 first.
 * Units: nm (0x607A, 0x6064 are INTEGER32: +-2.1 m).
 */
#ifndef CO_CSP_H
#define CO_CSP_H

#include <stdbool.h>
#include <stdint.h>

#include "drive.h"

typedef struct {
    bool active;
    pos_nm_t last[CORE_AXES]; /* end of the last block queued */
    uint32_t queued;          /* blocks queued */
    uint32_t missed;          /* SYNCs whose new target was refused */
} co_csp_t;

void co_csp_start(co_csp_t *c);
void co_csp_stop(co_csp_t *c);
/* The SYNC's target (nm) with the period (ns) from 0x60C2. */
void co_csp_sync(co_csp_t *c, int32_t target, int64_t period_ns);
/* 0x60C2 as ns (value x 10^index s), 0 for an index out of -6..-3. */
int64_t co_csp_period_ns(uint8_t value, int8_t index);

#endif
