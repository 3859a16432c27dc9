/* One full servo tick for three axes, for callgrind: decode (qdec_sample of
 * three edge-input decoders), references (the interpolator's motion_ref_t of
 * a 20 mm circle at 10 m/min in G17, handed over by copy), contour error
 * controller and three axis PIDs with feed-forward, motor command writes.
 * The encoder edges (the port's edge interrupt) and the reference
 * generation are outside the measured function bench_tick.
 * Usage: bench_servo MODE TICKS  (MODE: off tangent curvature exact koren) */
#include "qgen.h"
#include "servo.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define HZ        10000
#define NM_PER_CT 100
#define R_NM      20000000.0
#define V_NM_S    (10.0 / 60.0 * 1e9) /* 10 m/min */

static qdec_t dec[3];
static qgen_t gen[3];
static servo_t sv;
static volatile int32_t sink[CORE_AXES];

static void emit(void *ctx, uint32_t lines, uint32_t t_ns)
{
    qdec_edge((qdec_t *)ctx, lines, t_ns);
}

static void set_mv(unsigned axis, int32_t mv)
{
    sink[axis] = mv;
}

static void circle_ref(motion_ref_t *ref, double t)
{
    double w = V_NM_S / R_NM, th = w * t;
    memset(ref, 0, sizeof *ref);
    ref->active = true;
    ref->pos[0] = llround(R_NM * cos(th));
    ref->pos[1] = llround(R_NM * sin(th));
    ref->vel[0] = llround(-V_NM_S * sin(th));
    ref->vel[1] = llround(V_NM_S * cos(th));
    ref->acc[0] = llround(-V_NM_S * w * cos(th));
    ref->acc[1] = llround(-V_NM_S * w * sin(th));
    ref->geom.kind = MOTION_GEOM_ARC;
    ref->geom.tangent[0] = (q1_30_t)lround(-sin(th) * 1073741824.0);
    ref->geom.tangent[1] = (q1_30_t)lround(cos(th) * 1073741824.0);
    ref->geom.plane_u = 0;
    ref->geom.plane_v = 1;
    ref->geom.radius = (pos_nm_t)R_NM;
    ref->geom.sense = 1;
}

__attribute__((noinline)) void bench_tick(const motion_ref_t *next, uint32_t now_ns)
{
    static const qdec_t *const enc[CORE_AXES] = {&dec[0], &dec[1], &dec[2]};
    servo_fb_t fb;
    motion_ref_t ref;
    unsigned i;
    for (i = 0; i < 3; i++) {
        qdec_sample(&dec[i], now_ns);
    }
    servo_fb_from_qdec(&fb, enc, 3);
    ref = *next;
    servo_tick(&sv, &ref, &fb);
}

int main(int argc, char **argv)
{
    static const char *names[] = {"off", "tangent", "curvature", "exact", "koren"};
    const char *mode = (argc > 1) ? argv[1] : "exact";
    unsigned long n = (argc > 2) ? strtoul(argv[2], NULL, 10) : 10000, k;
    servo_params_t p;
    servo_io_t io = {set_mv, NULL, NULL};
    qdec_config_t cfg;
    servo_fb_t fb;
    motion_ref_t ref;
    const qdec_t *enc[CORE_AXES] = {&dec[0], &dec[1], &dec[2]};
    unsigned i, m;

    servo_params_default(&p, HZ);
    for (i = 0; i < 3; i++) {
        p.axis[i].kvff = (q32_32_t)25 << 32;
        p.axis[i].kaff = (q32_32_t)1 << 28;
    }
    for (m = 0; m < 5; m++) {
        if (strcmp(mode, names[m]) == 0) {
            p.cec.mode = (cec_mode_t)m;
        }
    }
    qdec_config_default(&cfg);
    cfg.nm_per_count_num = NM_PER_CT;
    circle_ref(&ref, 0.0);
    for (i = 0; i < 3; i++) {
        qgen_init(&gen[i], QGEN_COUNTS(ref.pos[i] / NM_PER_CT), 0, emit, &dec[i]);
        cfg.offset_nm = (ref.pos[i] / NM_PER_CT) * NM_PER_CT; /* machine position at count 0 */
        if (!qdec_init(&dec[i], &cfg, qgen_lines(&gen[i]), 0)) {
            return 1;
        }
        qdec_sample(&dec[i], 1000);
    }
    if (servo_init(&sv, &p, &io) != SERVO_OK) {
        return 1;
    }
    servo_fb_from_qdec(&fb, enc, 3);
    servo_enable(&sv, &fb);
    servo_run(&sv);
    for (k = 1; k <= n; k++) {
        double t = (double)k / HZ;
        uint64_t t_ns = (uint64_t)k * (1000000000u / HZ);
        motion_ref_t lag;
        /* the machine lags 0.5 ms along the circle, 5 um outside */
        circle_ref(&ref, t);
        circle_ref(&lag, t - 0.0005);
        for (i = 0; i < 2; i++) {
            double x = (double)lag.pos[i] * (1.0 + 5000.0 / R_NM);
            qgen_move_to(&gen[i], (qgen_pos_t)llround(x / NM_PER_CT * QGEN_ONE), t_ns - 1000);
        }
        bench_tick(&ref, (uint32_t)t_ns);
    }
    if (sv.faults != 0 || sv.state != SERVO_RUN || (p.cec.mode != CEC_MODE_OFF && !sv.cec.active)) {
        fprintf(stderr, "bench_servo: unexpected state %d faults %u\n", sv.state, sv.faults);
        return 1;
    }
    return 0;
}
