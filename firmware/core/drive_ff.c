/*
 * drive_ff.c - velocity feed-forward advance, friction feed-forward and
 * quadrant-glitch compensation of the reference (specification in
 * drive_ff.h; what and why in drive.h, drive_config_t).
 */
#include "drive_ff.h"

#include "fixmath.h"
#include "pid.h"
#include "preempt.h"

void drive_ff_config(drive_ff_t *f, const drive_config_t *cfg, unsigned axes)
{
    unsigned i;
    bool on = cfg->ff_advance_ns != 0 || cfg->enc_mean;
    bool restart = cfg->qg_comp != f->qg;
    int64_t hz = cfg->tick_hz > 0 ? (int64_t)cfg->tick_hz : 1;

    f->on = false; /* the reference is at rest (drive_ff.h): no tick uses it */
    CORE_BARRIER();
    f->adv_q32 = (int32_t)(((int64_t)cfg->ff_advance_ns << 32) / 1000000000);
    f->band_nm_s = cfg->friction_ff_band_nm_s > 0 ? cfg->friction_ff_band_nm_s : 1;
    for (i = 0; i < CORE_AXES; i++) {
        int32_t mv = i < axes ? cfg->friction_ff_mv[i] : 0;
        restart = restart || mv != f->fric_mv[i];
        f->fric_mv[i] = mv;
        on = on || mv != 0;
    }
    f->qg = cfg->qg_comp;
    f->mean = cfg->enc_mean;
    f->k_half = (int32_t)(((int64_t)1 << 31) / hz);
    f->k_tick = (int32_t)((((int64_t)1 << 32) - 1) / hz);
    f->k_sixth = (int32_t)(((int64_t)1 << 32) / (6 * hz));
    for (i = 0; i < CORE_AXES && restart; i++) {
        f->qgs[i].sign = 0;
        f->qgs[i].phase = DRIVE_FF_QG_IDLE;
        f->qgs[i].jump = 0;
    }
    CORE_BARRIER(); /* the fields above before `on` */
    f->on = on;
}

/* What the CEC's integrators hold on axis i, U: part of the axis's
 * integral action while the CEC is active (it hands it to the axis
 * integrator when it stops: cec.h handover), 0 while it is not. */
static int64_t cec_held(const cec_t *c, unsigned i)
{
    int64_t u;
    if (!c->active || i >= 3u) {
        return 0;
    }
    u = fx_mul64x32_shift(c->ch[0].integ, c->n[0][i], 30);
    if (c->ch2_on) {
        u += fx_mul64x32_shift(c->ch[1].integ, c->n[1][i], 30);
    }
    return u;
}

/* What the loops hold on axis i, U: the axis integrator and, along the
 * normal (at a reversal: this axis), the CEC's. */
static int64_t qg_held(servo_t *servo, unsigned i)
{
    return servo->pid[i].integ + cec_held(&servo->cec, i);
}

/* Quadrant-glitch compensation of axis i (drive_ff.h "Quadrant-glitch
 * compensation"): v, a the reference velocity and acceleration, fr the
 * friction feed-forward (mV, > 0 or < 0). */
static void qg_step(drive_ff_t *f, servo_t *servo, unsigned i, int64_t v, int64_t a, int64_t fr)
{
    drive_ff_qg_t *q = &f->qgs[i];
    int8_t sg = v > 0 ? 1 : (v < 0 ? -1 : 0);
    int8_t old = q->sign;
    int64_t lim, jc;

    if (q->phase != DRIVE_FF_QG_IDLE) {
        q->n++;
    }
    if (sg == 0 || sg == old) {
        if (q->phase == DRIVE_FF_QG_AFTER && q->n >= q->win) {
            /* the second difference over equal windows: the step the
             * loops made across the reversal (the jump included); what
             * is smooth there (the feed-forward errors) cancels to first
             * order */
            int64_t d2 = qg_held(servo, i) - 2 * q->i0 + q->ib;
            lim = (fr < 0 ? -fr : fr) << 33; /* 2 |fr| mV in U */
            jc = fx_clamp_sym64(q->jump, lim);
            d2 = (old > 0 ? d2 : -d2) - jc; /* what the jump missed, as seen */
            q->jump = fx_clamp_sym64(jc + d2 + (d2 >> 1), lim);
            q->phase = DRIVE_FF_QG_IDLE;
        } else if (q->phase == DRIVE_FF_QG_BEFORE && q->n > 2 * q->win) {
            q->phase = DRIVE_FF_QG_IDLE; /* no reversal came: a stop */
        } else if (q->phase == DRIVE_FF_QG_IDLE && sg != 0 && (v ^ a) < 0) {
            /* decelerating: the reversal in |v| / |a| s; take the sample
             * before it once that is within the window, two integral
             * times Kp / Ki (drive_ff.h) */
            const pid_params_t *pp = &servo->p.axis[i];
            int64_t va = v < 0 ? -v : v, aa = a < 0 ? -a : a, win;
            if (pp->ki <= 0) {
                return;
            }
            win = fx_muldiv64(pp->kp, (int64_t)servo->p.tick_hz, pp->ki);
            win =
                2 * (win < 1 ? 1 : (win > DRIVE_FF_QG_WIN_MAX / 2 ? DRIVE_FF_QG_WIN_MAX / 2 : win));
            if (va * (int64_t)servo->p.tick_hz <= aa * win) {
                q->win = (int32_t)win;
                q->n = 0;
                q->ib = qg_held(servo, i);
                q->phase = DRIVE_FF_QG_BEFORE;
            }
        }
        return;
    }
    q->sign = sg;
    if (old == 0) {
        return;
    }
    lim = (fr < 0 ? -fr : fr) << 33;
    jc = fx_clamp_sym64(q->jump, lim);
    if (q->phase == DRIVE_FF_QG_BEFORE && q->n <= 2 * q->win) {
        q->i0 = qg_held(servo, i);
        q->win = q->n; /* the window after: as long as the one before */
        q->n = 0;
        q->phase = DRIVE_FF_QG_AFTER;
    } else {
        q->phase = DRIVE_FF_QG_IDLE;
    }
    pid_add_integrator(&servo->pid[i], sg > 0 ? jc : -jc);
}

/* x * y in q1_30 */
static int32_t q30_mul(int32_t x, int32_t y)
{
    return (int32_t)fx_round_shift64((int64_t)x * y, 30);
}

/* The reference at the mean time (drive_ff.h "Mean alignment") into
 * f->mref (pos, tangent), from ref before the feed-forward corrections;
 * fb's plane axes on an ARC moved out by th^2 / 6. */
static void mean_align(drive_ff_t *f, const motion_ref_t *ref, servo_fb_t *fb, unsigned axes)
{
    int64_t d[CORE_AXES] = {0};
    const motion_geom_t *g = &ref->geom;
    unsigned i;
    for (i = 0; i < axes; i++) {
        int64_t at2 = fx_mul64x32_shift32(ref->acc[i], f->k_tick); /* a T, nm/s */
        d[i] = fx_mul64x32_shift32(at2, f->k_sixth) -              /* a T^2 / 6 */
               fx_mul64x32_shift32(ref->vel[i], f->k_half);        /* v T / 2   */
        f->mref.pos[i] = ref->pos[i] + d[i];
        f->mref.geom.tangent[i] = g->tangent[i];
    }
    /* radius^2 must fit int64: larger arcs keep the straight shift (2 nm
     * from the arc's at R 4 m) */
    if (g->kind == MOTION_GEOM_ARC && g->radius > 0 && g->radius < INT32_MAX && g->plane_u < axes &&
        g->plane_v < axes) {
        unsigned u = g->plane_u, v = g->plane_v;
        int64_t au = ref->pos[u] - g->centre_u, av = ref->pos[v] - g->centre_v;
        int64_t th64 = fx_muldiv64(au * d[v] - av * d[u], (int64_t)1 << 30, g->radius * g->radius);
        int32_t th = (int32_t)fx_clamp_sym64(th64, (int64_t)1 << 28); /* 0.25 rad */
        int32_t th2 = q30_mul(th, th);
        int32_t sn = th - q30_mul(th, th2) / 6;
        int32_t cs = (1 << 30) - th2 / 2 + q30_mul(th2, th2) / 24;
        int32_t q = th2 / 6;
        int32_t tu = g->tangent[u], tv = g->tangent[v];
        f->mref.pos[u] =
            g->centre_u + fx_mul64x32_shift(au, cs, 30) - fx_mul64x32_shift(av, sn, 30);
        f->mref.pos[v] =
            g->centre_v + fx_mul64x32_shift(au, sn, 30) + fx_mul64x32_shift(av, cs, 30);
        f->mref.geom.tangent[u] = q30_mul(tu, cs) - q30_mul(tv, sn);
        f->mref.geom.tangent[v] = q30_mul(tu, sn) + q30_mul(tv, cs);
        fb->pos[u] += fx_mul64x32_shift(fb->pos[u] - g->centre_u, q, 30);
        fb->pos[v] += fx_mul64x32_shift(fb->pos[v] - g->centre_v, q, 30);
    }
}

const motion_ref_t *drive_ff_step(drive_ff_t *f, servo_t *servo, motion_ref_t *ref, servo_fb_t *fb,
                                  unsigned axes)
{
    unsigned i;
    if (f->mean) {
        f->mref = *ref; /* vel and acc are taken again below */
        mean_align(f, ref, fb, axes);
    }
    for (i = 0; i < axes; i++) {
        int64_t fr, v, kaff, u;
        if (f->adv_q32 != 0) {
            ref->vel[i] += fx_mul64x32_shift32(ref->acc[i], f->adv_q32);
        }
        if (f->fric_mv[i] == 0) {
            continue; /* the usual case: nothing else to load */
        }
        fr = f->fric_mv[i];
        v = ref->vel[i];
        if (f->qg) {
            qg_step(f, servo, i, v, ref->acc[i], fr);
        }
        kaff = servo->p.axis[i].kaff >> 16;
        if (kaff <= 0 || v == 0) {
            continue;
        }
        if (v >= f->band_nm_s) {
            u = fr;
        } else if (v <= -f->band_nm_s) {
            u = -fr;
        } else {
            u = fx_div_round64(fr * v, f->band_nm_s);
        }
        /* mV -> nm/s^2: u * 1e-3 V / (kaff V/(m/s^2)) * 1e9 = u * 1e6 / kaff */
        ref->acc[i] = fx_sat_add64(ref->acc[i], fx_div_round64(u * 1000000 * 65536, kaff));
    }
    if (!f->mean) {
        return ref;
    }
    for (i = 0; i < axes; i++) { /* the feed-forward: the command's */
        f->mref.vel[i] = ref->vel[i];
        f->mref.acc[i] = ref->acc[i];
    }
    return &f->mref;
}
