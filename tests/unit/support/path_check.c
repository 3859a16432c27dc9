/*
 * path_check.c - see path_check.h. Test support code (host only).
 */
#include "path_check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "estimator.h"
#include "interp.h"

plan_profile_t pc_profile(uint8_t shape)
{
    plan_profile_t p;
    int i;

    memset(&p, 0, sizeof(p));
    for (i = 0; i < CORE_AXES; i++) {
        p.v_max[i] = 500000000;
        p.a_max[i] = 2000000000;
        p.j_max[i] = 50000000000;
        p.corner_dv[i] = 5000000;
        p.corner_acc[i] = 300000000;
    }
    p.v_max[1] = 300000000;
    p.a_max[1] = 1000000000;
    p.j_max[1] = 20000000000;
    p.junction_dev_nm = 10000;
    p.min_block_ns = 500000;
    p.mbt_window = 4;
    p.corner = PLAN_CORNER_JD;
    p.shape = shape;
    return p;
}

static uint64_t pc_rs;

uint32_t pc_stall_every;
bool pc_smooth_paths;
bool pc_planar_xz;

static uint64_t pc_rnd(void)
{
    pc_rs ^= pc_rs << 13;
    pc_rs ^= pc_rs >> 7;
    pc_rs ^= pc_rs << 17;
    return pc_rs;
}

static double pc_uni(void)
{
    return (double)(pc_rnd() >> 11) / 9007199254740992.0;
}

static void pc_moves(plan_move_t *m, uint32_t n)
{
    double dir[3] = {1, 0, 0}, pos[3] = {0, 0, 0};
    double wander = pc_smooth_paths ? 0.01 : 0.3, turn = pc_smooth_paths ? 0.01 : 0.05;
    int64_t feed = 0;
    uint32_t k;
    int i;

    for (k = 0; k < n; k++) {
        double len = exp(log(0.02) + pc_uni() * (log(3.0) - log(0.02))); /* mm */
        double r = pc_uni(), nrm = 0;
        if (pc_smooth_paths) { /* CAM-like: short chords */
            len *= 0.1;
        }
        if (r < turn) { /* sharp turn or reversal */
            for (i = 0; i < 3; i++) {
                dir[i] = pc_uni() * 2 - 1;
            }
        } else { /* gentle wander */
            for (i = 0; i < 3; i++) {
                dir[i] += (pc_uni() * 2 - 1) * wander;
            }
        }
        if (pc_planar_xz && (k / 200u) % 2u == 1u) {
            dir[1] = 0; /* Y still */
        }
        for (i = 0; i < 3; i++) {
            nrm += dir[i] * dir[i];
        }
        nrm = sqrt(nrm) + 1e-12;
        memset(&m[k], 0, sizeof(m[k]));
        for (i = 0; i < 3; i++) {
            dir[i] /= nrm;
            pos[i] += dir[i] * len;
            m[k].target[i] = (int64_t)llround(pos[i] * 1e6);
        }
        if (!pc_smooth_paths || feed == 0 || pc_uni() < 0.01) {
            feed = (int64_t)((10 + pc_uni() * 290) * 1e6);
        }
        m[k].feed = feed;
        m[k].flags = (pc_rnd() % 50 == 0) ? PLAN_MOVE_EXACT_STOP : 0;
        m[k].tag = k;
    }
}

static int64_t pc_abs(int64_t v)
{
    return v < 0 ? -v : v;
}

void pc_run(uint32_t n, int64_t tick_ns, uint32_t seed, uint8_t shape, pc_result_t *r)
{
    plan_profile_t prof = pc_profile(shape);
    pc_run_profile(n, tick_ns, seed, &prof, r);
}

void pc_run_profile(uint32_t n, int64_t tick_ns, uint32_t seed, const plan_profile_t *pp,
                    pc_result_t *r)
{
    static plan_block_t store[PLAN_DEPTH_DEFAULT], store2[PLAN_DEPTH_DEFAULT];
    static interp_t ip;
    plan_profile_t prof = *pp;
    uint8_t shape = prof.shape;
    plan_move_t *mv = calloc(n, sizeof(*mv));
    plan_est_t *est = malloc(sizeof(*est) * n);
    int64_t *cum = malloc(sizeof(*cum) * n);
    int64_t *blk_a = malloc(sizeof(*blk_a) * n), *blk_j = malloc(sizeof(*blk_j) * n);
    const pos_nm_t origin[CORE_AXES] = {0, 0, 0};
    pos_nm_t p1[CORE_AXES], p2[CORE_AXES];
    int64_t acc1[CORE_AXES];
    uint32_t next = 0, bad = 0, done_prev = 0, id1 = 0, id2 = 0, k, stall_at = 0, pid = 0;
    int64_t pa_prev = 0, amin = prof.a_max[0];
    bool pa_ok = false, stalled = false;
    double h = (double)tick_ns * 1e-9;
    plan_t p;
    motion_ref_t ref;
    int i;

    memset(r, 0, sizeof(*r));
    if (mv == NULL || est == NULL || cum == NULL || blk_a == NULL || blk_j == NULL) {
        r->limit_violations = 1u << 30;
        goto out;
    }
    pc_rs = 0x9E3779B97F4A7C15ull ^ ((uint64_t)seed * 0xD1B54A32D192ED03ull);
    pc_moves(mv, n);
    if (plan_estimate(&prof, origin, mv, n, store2, PLAN_DEPTH_DEFAULT, est, &bad) != PLAN_OK) {
        r->limit_violations = 1u << 30;
        goto out;
    }
    for (k = 0; k < n; k++) {
        r->est_total_ns += est[k].t_total_ns;
        cum[k] = r->est_total_ns;
        if (est[k].flags & PLAN_BF_CORNER) {
            r->corner_capped++;
        }
    }
    for (i = 1; i < CORE_AXES; i++) {
        amin = (prof.a_max[i] < amin) ? prof.a_max[i] : amin;
    }
    /* the continuous S-curve's path limits: the smallest a and j of the
     * axes a block moves */
    for (k = 0; k < n; k++) {
        blk_a[k] = INT64_MAX;
        blk_j[k] = INT64_MAX;
        for (i = 0; i < CORE_AXES; i++) {
            if (mv[k].target[i] != ((k > 0) ? mv[k - 1].target[i] : origin[i])) {
                blk_a[k] = (prof.a_max[i] < blk_a[k]) ? prof.a_max[i] : blk_a[k];
                blk_j[k] = (prof.j_max[i] < blk_j[k]) ? prof.j_max[i] : blk_j[k];
            }
        }
    }
    if (pc_stall_every > 0) {
        stall_at = pc_stall_every;
    }
    plan_init(&p, store, PLAN_DEPTH_DEFAULT, &prof, origin);
    interp_init(&ip, tick_ns, origin);
    for (i = 0; i < CORE_AXES; i++) {
        p1[i] = p2[i] = 0;
        acc1[i] = 0;
    }
    for (;;) {
        uint32_t id;
        while (interp_room(&ip) > 0) {
            if (stalled && interp_idle(&ip) && plan_count(&p) == 0) {
                stalled = false; /* at rest at the end of what was queued */
                stall_at = next + pc_stall_every;
            }
            while (!stalled && next < n && plan_free_slots(&p) > 0) {
                (void)plan_push(&p, &mv[next]);
                next++;
                if (stall_at > 0 && next == stall_at && next < n) {
                    stalled = true;
                    r->stalls++;
                }
            }
            if (!interp_refill(&ip, &p)) {
                break;
            }
        }
        if (next == n && plan_count(&p) == 0 && interp_idle(&ip)) {
            break;
        }
        interp_tick(&ip, &ref);
        r->ticks++;
        /* block ends this tick: (ticks - 1) h < cumulative estimate <= ticks h */
        for (k = done_prev; k < interp_blocks_done(&ip) && k < n; k++) {
            int64_t now = (int64_t)r->ticks * tick_ns;
            int64_t err = now - cum[k];
            if (err < 0 || err >= tick_ns) {
                r->time_violations++;
            }
            if (pc_abs(err) > r->max_block_err_ns) {
                r->max_block_err_ns = pc_abs(err);
            }
        }
        if (shape == SC_SHAPE_SCURVE_CONTINUOUS && interp_busy(&ip)) {
            int64_t pa = ip.a_q16 / 65536;
            uint32_t cur = interp_blocks_done(&ip);
            int64_t la, lj;
            double ar;
            cur = (cur < n) ? cur : n - 1u;
            pid = pa_ok ? pid : cur;
            la = (blk_a[cur] > blk_a[pid]) ? blk_a[cur] : blk_a[pid];
            lj = (blk_j[cur] > blk_j[pid]) ? blk_j[cur] : blk_j[pid];
            ar = (double)pc_abs(pa) / (double)la;
            if (ar > r->max_path_a_ratio) {
                r->max_path_a_ratio = ar;
            }
            if ((double)pc_abs(pa) / (double)amin > r->max_path_a_min_ratio) {
                r->max_path_a_min_ratio = (double)pc_abs(pa) / (double)amin;
            }
            pid = cur;
            if (pa_ok) {
                double jr = ((double)pc_abs(pa - pa_prev) - 1.0) / ((double)lj * h);
                if (jr > r->max_path_j_ratio) {
                    r->max_path_j_ratio = jr;
                }
                if (jr > 1.0) {
                    r->limit_violations++;
                }
            }
            if (ar > 1.0) {
                r->limit_violations++;
            }
            if (interp_blocks_done(&ip) != done_prev && pc_abs(pa) * 10 >= amin) {
                r->joins_accel++;
            }
            pa_prev = pa;
            pa_ok = true;
        } else {
            pa_ok = false;
        }
        done_prev = interp_blocks_done(&ip);
        id = interp_busy(&ip) ? interp_blocks_done(&ip) : 0xFFFFFFFFu;
        for (i = 0; i < CORE_AXES; i++) {
            double vr = (double)pc_abs(ref.pos[i] - p1[i]) - 1.0;
            vr /= (double)prof.v_max[i] * h;
            if (vr > r->max_v_ratio) {
                r->max_v_ratio = vr;
            }
            if (vr > 1.0 || pc_abs(ref.vel[i]) > prof.v_max[i] + 1 ||
                pc_abs(ref.acc[i]) > prof.a_max[i] + 1) {
                r->limit_violations++;
            }
            if (id != 0xFFFFFFFFu && id == id1 && id1 == id2 && r->ticks > 2) {
                double ar = (double)pc_abs(ref.pos[i] - 2 * p1[i] + p2[i]) - 2.0;
                ar /= (double)prof.a_max[i] * h * h;
                if (ar > r->max_a_ratio) {
                    r->max_a_ratio = ar;
                }
                if (ar > 1.0) {
                    r->limit_violations++;
                }
            }
            if (id != 0xFFFFFFFFu && id == id1 && id < n &&
                (shape == SC_SHAPE_SCURVE || shape == SC_SHAPE_SCURVE_CONTINUOUS ||
                 (shape == SC_SHAPE_SCURVE_AT_REST &&
                  (est[id].v_entry == 0 || est[id].v_exit == 0)))) {
                r->jerk_checks++;
                double jr = (double)pc_abs(ref.acc[i] - acc1[i]) - 1.0;
                jr /= (double)prof.j_max[i] * h;
                if (jr > r->max_j_ratio) {
                    r->max_j_ratio = jr;
                }
                if (jr > 1.0) {
                    r->limit_violations++;
                }
            }
            p2[i] = p1[i];
            p1[i] = ref.pos[i];
            acc1[i] = ref.acc[i];
        }
        id2 = id1;
        id1 = id;
    }
    r->blocks = interp_blocks_done(&ip);
    r->underruns = interp_underruns(&ip);
    r->cont_kept = p.cont_kept;
    r->cont_forced = p.cont_forced;
    r->final_exact = true;
    for (i = 0; i < CORE_AXES; i++) {
        if (ip.pos[i] != mv[n - 1].target[i]) {
            r->final_exact = false;
        }
    }
    r->total_ticks_ok = r->ticks == (uint64_t)((r->est_total_ns + tick_ns - 1) / tick_ns);
out:
    free(blk_a);
    free(blk_j);
    free(mv);
    free(est);
    free(cum);
}

void pc_print(const char *prefix, const pc_result_t *r)
{
    printf("%s_blocks: %u blocks\n", prefix, r->blocks);
    printf("%s_ticks: %llu ticks\n", prefix, (unsigned long long)r->ticks);
    printf("%s_estimated_time: %.6f s\n", prefix, (double)r->est_total_ns * 1e-9);
    printf("%s_max_block_end_error: %lld ns\n", prefix, (long long)r->max_block_err_ns);
    printf("%s_time_violations: %u ticks\n", prefix, r->time_violations);
    printf("%s_limit_violations: %u ticks\n", prefix, r->limit_violations);
    printf("%s_max_speed_ratio: %.4f of limit\n", prefix, r->max_v_ratio);
    printf("%s_max_acc_ratio: %.4f of limit\n", prefix, r->max_a_ratio);
    printf("%s_max_jerk_ratio: %.4f of limit\n", prefix, r->max_j_ratio);
    printf("%s_final_position_exact: %d bool\n", prefix, r->final_exact ? 1 : 0);
    printf("%s_total_ticks_match: %d bool\n", prefix, r->total_ticks_ok ? 1 : 0);
    if (r->max_path_a_ratio > 0) {
        printf("%s_max_path_acc_ratio: %.4f of limit\n", prefix, r->max_path_a_ratio);
        printf("%s_max_path_jerk_ratio: %.4f of limit\n", prefix, r->max_path_j_ratio);
        printf("%s_joins_accelerating: %u blocks\n", prefix, r->joins_accel);
        printf("%s_stalls: %u\n", prefix, r->stalls);
        printf("%s_plans_kept: %u pops\n", prefix, r->cont_kept);
    }
}
