/*
 * estimator.h - host-facing block-time estimator: the drive's own planner run
 * over a whole array of moves in one call (ctypes: contour/planner.py).
 *
 * Specification
 * -------------
 * plan_estimate() queues the moves into a planner of the given depth exactly
 * as the drive's main loop does when the host keeps its queue full: push
 * until the ring is full, then pop the oldest block (freezing its plan) and
 * push the next, and pop the rest at the end. Each popped block's frozen
 * profile is reported, so the estimate is the plan the interpolator would
 * execute: the drive's executed time is the sum of total_ns rounded up to
 * whole ticks (the interpolator carries the fraction of a tick from block
 * to block).
 *
 * out[i] belongs to moves[i] (zero-length moves: flags PLAN_EST_SKIPPED,
 * times 0). Speeds nm/s, times ns, lengths nm. t_mbt_ns is the block's time
 * when its speed limit came from the minimum block time (else 0).
 *
 * Errors: the first invalid move stops the run; the function returns its
 * plan_result_t and *bad_index = its index; out[] before it is valid.
 * Contexts: host only (no real-time use); storage supplied by the caller
 * (plan_block_sizeof() bytes per block).
 */
#ifndef ESTIMATOR_H
#define ESTIMATOR_H

#include <stddef.h>
#include <stdint.h>

#include "planner.h"

#define PLAN_EST_SKIPPED 0x100u

typedef struct {
    int64_t len_nm;
    int64_t v_entry; /* nm/s */
    int64_t v_peak;  /* cruise (highest) speed, nm/s */
    int64_t v_exit;  /* nm/s */
    int64_t v_max;   /* the block's final speed limit (feed, axes, mbt, corner cap), nm/s */
    int64_t t_acc_ns;
    int64_t t_cruise_ns;
    int64_t t_dec_ns;
    int64_t t_total_ns; /* includes dwell time */
    int64_t t_mbt_ns;
    uint32_t tag;
    uint32_t flags; /* PLAN_BF_* | PLAN_EST_SKIPPED */
} plan_est_t;

size_t plan_block_sizeof(void);
size_t plan_est_sizeof(void);
size_t plan_move_sizeof(void);
size_t plan_profile_sizeof(void);

int plan_estimate(const plan_profile_t *prof, const pos_nm_t start[CORE_AXES],
                  const plan_move_t *moves, uint32_t n, plan_block_t *storage, uint16_t depth,
                  plan_est_t *out, uint32_t *bad_index);

#endif /* ESTIMATOR_H */
