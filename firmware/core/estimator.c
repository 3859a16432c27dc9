/*
 * estimator.c - the planner over a whole array of moves; see estimator.h.
 */
#include "estimator.h"

size_t plan_block_sizeof(void)
{
    return sizeof(plan_block_t);
}

size_t plan_est_sizeof(void)
{
    return sizeof(plan_est_t);
}

size_t plan_move_sizeof(void)
{
    return sizeof(plan_move_t);
}

size_t plan_profile_sizeof(void)
{
    return sizeof(plan_profile_t);
}

static void est_record(const plan_seg_t *seg, const plan_move_t *moves, plan_est_t *r)
{
    r->len_nm = seg->len;
    r->tag = moves[seg->tag].tag;
    r->flags = seg->flags;
    r->t_total_ns = seg->total_ns;
    if (seg->dwell_ns > 0) {
        r->v_entry = r->v_peak = r->v_exit = r->v_max = 0;
        r->t_acc_ns = r->t_cruise_ns = r->t_dec_ns = 0;
        r->t_mbt_ns = 0;
        return;
    }
    r->v_entry = seg->prof.v0;
    r->v_peak = seg->prof.vp;
    r->v_exit = seg->prof.v1;
    r->t_acc_ns = sc_time_accel(&seg->prof);
    r->t_cruise_ns = sc_time_cruise(&seg->prof);
    r->t_dec_ns = sc_time_decel(&seg->prof);
    r->t_mbt_ns = (seg->flags & PLAN_BF_MBT) ? seg->total_ns : 0;
}

/* Pop the oldest block and record its frozen plan, with its final speed
 * limit (a smoothed-corner cap may have lowered it after it was queued). */
static void est_pop(plan_t *p, const plan_move_t *moves, plan_est_t *out)
{
    plan_seg_t seg;
    int64_t vmax = plan_peek(p, 0)->lim.v_max;

    (void)plan_pop(p, &seg);
    out[seg.tag].v_max = vmax;
    est_record(&seg, moves, &out[seg.tag]);
}

int plan_estimate(const plan_profile_t *prof, const pos_nm_t start[CORE_AXES],
                  const plan_move_t *moves, uint32_t n, plan_block_t *storage, uint16_t depth,
                  plan_est_t *out, uint32_t *bad_index)
{
    plan_t p;
    plan_result_t rc;
    uint32_t i;

    if (bad_index != NULL) {
        *bad_index = 0;
    }
    if (moves == NULL || out == NULL || (n > 0 && storage == NULL)) {
        return PLAN_E_ARG;
    }
    rc = plan_init(&p, storage, depth, prof, start);
    if (rc != PLAN_OK) {
        return rc;
    }
    plan_set_deferred(&p, true); /* same segments, passes batched */
    for (i = 0; i < n; i++) {
        plan_move_t m = moves[i];
        m.tag = i;
        rc = plan_push(&p, &m);
        if (rc == PLAN_E_FULL) {
            est_pop(&p, moves, out);
            rc = plan_push(&p, &m);
        }
        if (rc == PLAN_SKIPPED) {
            plan_est_t *r = &out[i];
            r->len_nm = 0;
            r->v_entry = r->v_peak = r->v_exit = r->v_max = 0;
            r->t_acc_ns = r->t_cruise_ns = r->t_dec_ns = r->t_total_ns = r->t_mbt_ns = 0;
            r->tag = moves[i].tag;
            r->flags = PLAN_EST_SKIPPED;
        } else if (rc != PLAN_OK) {
            if (bad_index != NULL) {
                *bad_index = i;
            }
            return rc;
        }
    }
    while (plan_count(&p) > 0) {
        est_pop(&p, moves, out);
    }
    return PLAN_OK;
}
