/*
 * co_csp.h - CiA 402 cyclic synchronous position (CSP, 0x6060 / 0x6860 /
 * 0x7060 = 8) of the drive's CANopen node's axes. Main context only.
 *
 * Specification
 * -------------
 * At each SYNC, after the synchronous RPDOs wrote 0x607A / 0x687A / 0x707A
 * (co_pdo.h), targets that differ from the last ones become one LINE block
 * of the drive's planner (drive_queue_block) moving every axis in CSP from
 * its last target to the new one, at the feed that covers the length in
 * one interpolation time period 0x60C2
 * (value x 10^index s; index -6..-3): the drive's own interpolator and
 * look-ahead run it, within its velocity, acceleration and jerk limits.
 * Axes not in CSP keep their last reference. A target the drive
 * refuses (queue full, not enabled, soft limit) counts in `missed` and is
 * retried at the next SYNC. co_csp_start takes the axis's current
 * reference as its last target (no jump); the master sets the target to
 * the position actual first.
 * Units: nm (0x607A, 0x6064 are INTEGER32: +-2.1 m).
 */
#ifndef CO_CSP_H
#define CO_CSP_H

#include <stdbool.h>
#include <stdint.h>

#include "drive.h"

typedef struct {
    bool active;              /* some axis in CSP */
    uint8_t axes;             /* the axes in CSP (bit n: axis n) */
    pos_nm_t last[CORE_AXES]; /* end of the last block queued */
    uint32_t queued;          /* blocks queued */
    uint32_t missed;          /* SYNCs whose new target was refused */
} co_csp_t;

void co_csp_start(co_csp_t *c, unsigned axis);
void co_csp_stop(co_csp_t *c, unsigned axis);
/* The SYNC's target (nm) with the period (ns) from 0x60C2. */
/* One LINE block moving every axis in CSP to its target (the others
 * hold), at the feed that covers its length in one period. */
void co_csp_sync(co_csp_t *c, const int32_t target[CORE_AXES], int64_t period_ns);
/* 0x60C2 as ns (value x 10^index s), 0 for an index out of -6..-3. */
int64_t co_csp_period_ns(uint8_t value, int8_t index);

#endif
