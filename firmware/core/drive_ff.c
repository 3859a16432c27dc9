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
    bool on = cfg->ff_advance_ns != 0;
    bool restart = cfg->qg_comp != f->qg;

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
    for (i = 0; i < CORE_AXES && restart; i++) {
        f->qg_sign[i] = 0;
        f->qg_have[i] = 0;
    }
    CORE_BARRIER(); /* the fields above before `on` */
    f->on = on;
}

/* Quadrant-glitch compensation of axis i: v the reference velocity, fr
 * the friction feed-forward (mV, > 0 or < 0). */
static void qg_step(drive_ff_t *f, pid_loop_t *pid, unsigned i, int64_t v, int64_t fr)
{
    int8_t sg = v > 0 ? 1 : (v < 0 ? -1 : 0);
    int8_t old = f->qg_sign[i];

    if (sg == 0 || sg == old) {
        return;
    }
    f->qg_sign[i] = sg;
    if (old != 0) {
        unsigned k = old > 0 ? 0u : 1u; /* out of + or out of - */

        f->qg_ipre[i][k] = pid->integ;
        f->qg_have[i] |= (uint8_t)(1u << k);
        if (f->qg_have[i] == 3u) {
            /* I(+ -> -) - I(- -> +) = twice the friction the integrator
             * held, toward the new direction; at most 2 |fr| */
            int64_t lim = (fr < 0 ? -fr : fr) << 33; /* 2 |fr| mV in U */
            int64_t d = f->qg_ipre[i][0] - f->qg_ipre[i][1];

            d = d > lim ? lim : (d < -lim ? -lim : d);
            pid_add_integrator(pid, sg > 0 ? d : -d);
        }
    }
}

void drive_ff_step(drive_ff_t *f, servo_t *servo, motion_ref_t *ref, unsigned axes)
{
    unsigned i;
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
            qg_step(f, &servo->pid[i], i, v, fr);
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
}
