/*
 * scratch.h - one main-context scratch area for the drive's large
 * temporaries (a compensation table being decoded, a servo probe, the
 * parameter blob), which used to be a dozen function-local statics of 2 to
 * 3 KiB each.
 *
 * Specification
 * -------------
 *     p = scratch_claim(SCRATCH_CALIB, sizeof(comp_table_t));
 *     if (p == NULL) { refuse: the area is held }
 *     ... use p ...
 *     scratch_release(SCRATCH_CALIB);
 *
 * scratch_claim returns the area (scratch_bytes(): its largest user, a
 * servo_t, 3056 bytes on the Cortex-M4; aligned for any type the core uses) for `owner` when nobody
 * holds it and bytes <= scratch_bytes(); otherwise NULL, and the refusal is counted
 * (scratch_collisions): two users can never nest silently, the inner one fails with its own error.
 * scratch_release(owner) frees it only when `owner` holds it (a release by
 * another owner is counted as a collision too). Contents are undefined at
 * every claim. A user releases before calling anything that may claim it
 * (comp_store_clear, drive_set_servo_params, drive_param_commit,
 * param_store_*).
 *
 * Owners (each claims it only inside one call, never across calls):
 *   SCRATCH_CALIB        calib.c: a table loaded or decoded for comp_install
 *   SCRATCH_COMP_STORE   comp_store_clear: the empty table it writes
 *   SCRATCH_SERVO_PROBE  drive_servo_probe: servo_init of candidate gains
 *   SCRATCH_PARAM_STORE  param_store.c: the parameter blob
 *   SCRATCH_COMP2D       comp2d_link.c: a 2-D map record being checked
 *   SCRATCH_TEST         unit tests
 *
 * Context: main only (the tick and interrupts never use it). No heap.
 */
#ifndef SCRATCH_H
#define SCRATCH_H

#include <stddef.h>
#include <stdint.h>

typedef enum {
    SCRATCH_FREE = 0,
    SCRATCH_CALIB,
    SCRATCH_COMP_STORE,
    SCRATCH_SERVO_PROBE,
    SCRATCH_PARAM_STORE,
    SCRATCH_COMP2D,
    SCRATCH_TEST
} scratch_owner_t;

void *scratch_claim(scratch_owner_t owner, size_t bytes);
void scratch_release(scratch_owner_t owner);
scratch_owner_t scratch_owner(void);
size_t scratch_bytes(void);
/* Refused claims and foreign releases since start-up (diagnostics, tests). */
uint32_t scratch_collisions(void);

#endif /* SCRATCH_H */
