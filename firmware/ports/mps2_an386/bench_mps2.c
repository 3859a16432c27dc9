/*
 * bench_mps2.c - instruction counts of the real cross-compiled control code
 * on the Cortex-M4 instruction set, run under `qemu-system-arm -icount`
 * (bench/bench-firmware.sh; method in docs/ports.md).
 *
 * With -icount the virtual clock advances by a fixed time per executed
 * instruction, so the 25 MHz dual timer read before and after a call
 * measures the instructions in between. The ratio is calibrated in the
 * image itself on a loop of known length (CAL_INSTR instructions), the
 * cost of the two timer reads is measured and subtracted. SysTick is stopped (manual clock): no
 * interrupt falls inside a measurement.
 *
 * Workloads (three axes, the QEMU machine of app_mps2.c, default servo and
 * planner parameters (velocity_profile = scurve_continuous), CEC off):
 *   control tick  app_tick() while the drive runs a helix (full circle of
 *                 radius 5 mm in XY at 20 mm/s, Z rising 2 mm) with a full
 *                 12 x 12 2-D compensation map in use (bench_map), the axes
 *                 simulated between ticks (not measured); mean and maximum
 *                 over the RUNNING ticks.
 *   planner block plan_push() + plan_pop() per block with the look-ahead
 *                 ring full (64 blocks): 1000 chords of 0.2 mm around a
 *                 circle with a 3-axis component, feed 50 mm/s; again
 *                 with Z's a and j at half of X/Y's (a real machine's
 *                 slower Z: figures named *_unequal).
 *   helpers       sc_muldiv (128/64 multiply-divide), a 64-bit division and
 *                 fx_isqrt64 per call: where the tick and block costs go.
 *   both again with the per-block S-curve (velocity_profile = scurve, a =
 *                 0 at every block end): the same names with the suffix
 *                 _scurve.
 *   the control tick again with the interpolated measurement (drive.h
 *                 enc_interp: off in the default configuration, so not in
 *                 the figures above): the same names with the suffix
 *                 _interp.
 * Prints `name: value unit` lines on UART0, then exits QEMU (semihosting).
 */
#include "app.h"
#include "comp2d.h"
#include "comp2d_live.h"
#include "drive.h"
#include "hal.h"
#include "mps2.h"
#include "planner.h"
#include "plant_mps2.h"
#include "port.h"
#include "scurve.h"

#define AXES      3u
#define MAX_TICKS 40000u

/* profile mode: stop the tick workload after this many running ticks */
static uint32_t tick_limit = MAX_TICKS;

/* the tick workload with the interpolated measurement (drive.h
 * enc_interp, off in the default configuration): figures *_interp */
static bool tick_interp;

static void put(const char *s)
{
    size_t n = 0;

    while (s[n] != '\0') {
        n++;
    }
    while (n > 0u) {
        size_t w = hal_uart_write((const uint8_t *)s, n);
        s += w;
        n -= w;
    }
}

static void put_u32(uint32_t v)
{
    char buf[11];
    int i = 10;

    buf[i] = '\0';
    do {
        buf[--i] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v != 0u);
    put(&buf[i]);
}

/* the planner's velocity profile of the tick and planner workloads (the
 * drive's default unless set), and the suffix of their figure names */
static int shape_override = -1;
static const char *fig_suffix = "";

static void line(const char *name, uint32_t v, const char *unit)
{
    put(name);
    put(fig_suffix);
    put(": ");
    put_u32(v);
    put(" ");
    put(unit);
    put("\n");
}

/* The semihosting command line (QEMU: -semihosting-config arg=...): which
 * workload to run (bench/profile-m4.sh profiles one at a time). Empty when
 * none was given. */
static const char *semihost_cmdline(void)
{
    static char buf[64];
    static uint32_t block[2];
    register uint32_t r0 __asm__("r0") = 0x15u; /* SYS_GET_CMDLINE */
    register uint32_t r1 __asm__("r1") = (uint32_t)block;

    block[0] = (uint32_t)buf;
    block[1] = sizeof(buf) - 1u;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    if (r0 != 0u || block[1] >= sizeof(buf)) {
        return "";
    }
    buf[block[1]] = '\0';
    return buf;
}

static void semihost_exit(void)
{
    register uint32_t r0 __asm__("r0") = 0x18u;    /* SYS_EXIT */
    register uint32_t r1 __asm__("r1") = 0x20026u; /* ADP_Stopped_ApplicationExit */

    __asm__ volatile("bkpt 0xab" : : "r"(r0), "r"(r1) : "memory");
}

static uint32_t counts_empty;   /* two timer reads back to back */
static uint32_t counts_per_cal; /* CAL_INSTR instructions, minus counts_empty */

/* CAL_LOOPS iterations of 16 nops + subs + bne: exactly CAL_INSTR
 * instructions between the two timer reads (plus the two that load r0). */
#define CAL_LOOPS 50000u
#define CAL_INSTR (18u * CAL_LOOPS + 2u)

static void calibrate(void)
{
    uint32_t c0, c1, best = 0xFFFFFFFFu;
    unsigned i;

    for (i = 0; i < 8u; i++) {
        c0 = mps2_counter();
        c1 = mps2_counter();
        if (c0 - c1 < best) {
            best = c0 - c1;
        }
    }
    counts_empty = best;
    c0 = mps2_counter();
    __asm__ volatile("movw r0, #:lower16:50000\n\t"
                     "movt r0, #:upper16:50000\n"
                     "1:\n\t"
                     "nop\n\tnop\n\tnop\n\tnop\n\tnop\n\tnop\n\tnop\n\tnop\n\t"
                     "nop\n\tnop\n\tnop\n\tnop\n\tnop\n\tnop\n\tnop\n\tnop\n\t"
                     "subs r0, r0, #1\n\t"
                     "bne 1b" ::
                         : "r0", "cc", "memory");
    c1 = mps2_counter();
    counts_per_cal = c0 - c1 - counts_empty;
}

/* instructions for a sum of `calls` measurements of `counts` (rounded) */
static uint32_t instr(uint64_t counts, uint32_t calls)
{
    uint64_t net = counts - (uint64_t)counts_empty * calls;

    if (counts < (uint64_t)counts_empty * calls || calls == 0u || counts_per_cal == 0u) {
        return 0u;
    }
    return (uint32_t)((net * CAL_INSTR + (uint64_t)counts_per_cal * calls / 2u) /
                      ((uint64_t)counts_per_cal * calls));
}

/* The 2-D compensation map (comp2d.h, issue 22): a full 12 x 12 map over
 * +-82.5 mm, node values spread over +-40 um. The helix runs with it in
 * use (comp2d_live.h: the tick adds the published linearisation, main
 * re-anchors in app_poll), and comp2d_correct alone is timed at 256
 * positions over and beyond it (what main pays per anchor, three times). */
static comp2d_map_t bench_map;

static bool bench_map_build(void)
{
    static const pos_nm_t lo[2] = {-100000000, -100000000}, hi[2] = {100000000, 100000000};
    unsigned a, g, i;
    bench_map.version = COMP2D_VERSION;
    bench_map.nx = 12;
    bench_map.ny = 12;
    bench_map.x0 = -82500000;
    bench_map.y0 = -82500000;
    bench_map.dx = 15000000;
    bench_map.dy = 15000000;
    bench_map.shift = 2;
    for (a = 0; a < 2; a++) {
        for (g = 0; g < 3; g++) {
            for (i = 0; i < COMP2D_NODES_MAX; i++) {
                bench_map.g[a][g][i] = (int16_t)((int)(i * 7919u % 20001u) - 10000);
            }
        }
    }
    if (comp2d_check(&bench_map, lo, hi) != COMP2D_OK) {
        return false; /* no figure: the bench fails on the missing line */
    }
    comp2d_prepare(&bench_map);
    return true;
}

/* The control tick as the ports run it: the drive, then the calibration
 * with what the drive published (what drive_tick did before the split). */
static void bench_tick(void)
{
    drive_config_t cfg;
    drive_block_t b = {0};
    drive_status_t st;
    uint64_t sum = 0;
    uint32_t n = 0, worst = 0, k;

    app_board_t board = {0};

    plant_drive_config(&cfg, MPS2_TICK_HZ, AXES);
    cfg.enc_interp = tick_interp;
    if (shape_override >= 0) {
        cfg.plan.shape = (uint8_t)shape_override;
    }
    board.board_id = BOOT_BOARD_QEMU;
    board.node_id = 1u;
    board.drive = &cfg; /* no link: the tick and the planner alone */
    if (!plant_init(MPS2_TICK_HZ, AXES, &cfg) || app_init(&board) != APP_OK || !bench_map_build() ||
        drive_enable(true) != DRIVE_OK) {
        put("bench: drive refused its configuration\n");
        return;
    }
    comp2d_live_set(&bench_map); /* the helix runs with the 2-D map */
    for (k = 0; k < 10u; k++) {  /* enable takes effect in the tick */
        mps2_clock_advance();
        app_tick();
        plant_step(mps2_ticks());
        app_poll();
    }
    b.kind = DRIVE_BLOCK_ARC;
    b.tag = 1;
    b.target[0] = 0;
    b.target[1] = 0;
    b.target[2] = 2000000;
    b.feed_nm_s = 20000000;
    b.plane = DRIVE_PLANE_XY;
    b.centre_u = 5000000;
    b.centre_v = 0;
    b.sense = 1;
    if (drive_queue_block(&b) != DRIVE_OK) {
        put("bench: arc refused\n");
        return;
    }
    for (k = 0; k < MAX_TICKS; k++) {
        uint32_t c0, c1;

        mps2_clock_advance();
        c0 = mps2_counter();
        app_tick();
        c1 = mps2_counter();
        plant_step(mps2_ticks());
        app_poll();
        drive_snapshot(&st);
        if (st.state == DRIVE_RUNNING) {
            sum += c0 - c1;
            n++;
            if (c0 - c1 > worst) {
                worst = c0 - c1;
            }
        } else if (n > 0u) {
            break;
        }
        if (n >= tick_limit) {
            break;
        }
    }
    drive_status(&st);
    if (n >= tick_limit) {
        return; /* profile run: partial helix, no figures */
    }
    if (st.faults != 0u || n == 0u) {
        put("bench: the helix did not run (faults ");
        put_u32(st.faults);
        put(")\n");
        return;
    }
    if (comp2d_live_anchors() == 0u) {
        put("bench: the 2-D map was not applied\n");
        return;
    }
    line("control_tick_instructions_m4", instr(sum, n), "instr");
    line("control_tick_instructions_m4_max", instr(worst, 1u), "instr");
    line("control_tick_count_m4", n, "ticks");
    line("control_tick_comp2d_anchors_m4", comp2d_live_anchors(), "anchors");
}

static plan_block_t ring[PLAN_DEPTH_DEFAULT];

/* the planner workload on a machine with a slower Z (a and j at half of
 * X/Y's): the figures named *_unequal */
static bool plan_unequal;

static void bench_planner(void)
{
    drive_config_t cfg;
    plan_t p;
    plan_seg_t seg;
    pos_nm_t origin[CORE_AXES] = {0};
    uint64_t sum = 0;
    uint32_t n = 0, k;
    /* 0.2 mm chords around a 32 mm circle: cos/sin by rotation (integer) */
    int64_t x = 5000000, y = 0;

    plant_drive_config(&cfg, MPS2_TICK_HZ, AXES);
    cfg.enc_interp = tick_interp;
    if (shape_override >= 0) {
        cfg.plan.shape = (uint8_t)shape_override;
    }
    if (plan_unequal) {
        cfg.plan.a_max[2] /= 2;
        cfg.plan.j_max[2] /= 2;
    }
    if (plan_init(&p, ring, PLAN_DEPTH_DEFAULT, &cfg.plan, origin) != PLAN_OK) {
        put("bench: plan_init refused\n");
        return;
    }
    for (k = 0; k < 1000u + PLAN_DEPTH_DEFAULT; k++) {
        plan_move_t m = {0};
        uint32_t c0, c1;
        int64_t nx = x - y / 25, ny = y + x / 25; /* ~2.3 degrees per chord */

        x = nx;
        y = ny;
        m.target[0] = x;
        m.target[1] = y;
        m.target[2] = (int64_t)k * 1000;
        m.feed = 50000000;
        m.tag = k;
        c0 = mps2_counter();
        if (plan_free_slots(&p) == 0u) {
            (void)plan_pop(&p, &seg);
        }
        (void)plan_push(&p, &m);
        c1 = mps2_counter();
        if (k >= PLAN_DEPTH_DEFAULT) { /* steady state: one pop + one push */
            sum += c0 - c1;
            n++;
        }
    }
    line(plan_unequal ? "planner_block_instructions_m4_unequal" : "planner_block_instructions_m4",
         instr(sum, n), "instr");
}

/* the planner workload with equal axis limits, then with Z at half */
static void bench_planners(void)
{
    plan_unequal = false;
    bench_planner();
    plan_unequal = true;
    bench_planner();
    plan_unequal = false;
}

/* Where the time goes: the building blocks the tick and the planner call
 * (128/64-bit multiply-divide, 64-bit divide and square root) per call. */
static volatile int64_t sink, va, vb, vc; /* volatile: nothing moves out of the timed region */

static void bench_helpers(void)
{
    uint64_t s1 = 0, s2 = 0, s3 = 0;
    uint32_t k, c0, c1;

    for (k = 0; k < 256u; k++) {
        va = 3000000000ll + (int64_t)k * 7919;
        vb = ((int64_t)1 << 32) + k;
        vc = 700000001ll + (int64_t)k * 104729;
        c0 = mps2_counter();
        sink = sc_muldiv(va, vb, vc);
        c1 = mps2_counter();
        s1 += c0 - c1;
        c0 = mps2_counter();
        sink = va * 1000 / vc;
        c1 = mps2_counter();
        s2 += c0 - c1;
        c0 = mps2_counter();
        sink = (int64_t)fx_isqrt64((uint64_t)va * 1000u);
        c1 = mps2_counter();
        s3 += c0 - c1;
    }
    /* the volatile operand loads are inside the timed region: a few
     * instructions of each figure are theirs */
    line("sc_muldiv_instructions_m4", instr(s1, 256u), "instr");
    line("int64_div_instructions_m4", instr(s2, 256u), "instr");
    line("isqrt64_instructions_m4", instr(s3, 256u), "instr");
}

static void bench_comp2d(void)
{
    uint64_t s = 0;
    uint32_t k, c0, c1;
    if (!bench_map_build()) {
        return;
    }
    for (k = 0; k < 256u; k++) {
        pos_nm_t raw[2], out[2];
        q1_30_t w[2];
        raw[0] = -90000000 + (pos_nm_t)k * 703001;
        raw[1] = 90000000 - (pos_nm_t)k * 611003;
        w[0] = (k & 1u) ? FX_ONE_Q30 : -FX_ONE_Q30;
        w[1] = (k & 2u) ? FX_ONE_Q30 / 3 : -FX_ONE_Q30;
        c0 = mps2_counter();
        comp2d_correct(&bench_map, raw, w, out);
        c1 = mps2_counter();
        s += c0 - c1;
        sink = out[0] + out[1];
    }
    line("comp2d_correct_instructions_m4", instr(s, 256u), "instr");
}

int main(void)
{
    const char *cmd;

    mps2_board_init(MPS2_TICK_HZ, NULL);
    mps2_clock_manual();
    mps2_counter_start();
    calibrate();
    cmd = semihost_cmdline();
    if (cmd[0] == 'p') { /* "planner": profile the planner workload only */
        bench_planner();
    } else if (cmd[0] == 's') { /* "splanner": the same, per-block S-curve */
        shape_override = SC_SHAPE_SCURVE;
        bench_planner();
    } else if (cmd[0] == 'u') { /* "uplanner": the planner, Z at half */
        plan_unequal = true;
        bench_planner();
    } else if (cmd[0] == 'v') { /* "vplanner": the same, per-block S-curve */
        plan_unequal = true;
        shape_override = SC_SHAPE_SCURVE;
        bench_planner();
    } else if (cmd[0] == 't') { /* "tick": the first 1500 running ticks */
        tick_limit = 1500u;
        bench_tick();
    } else {
        bench_planners();
        bench_tick();
        bench_helpers();
        bench_comp2d();
        /* the same tick and planner workloads with the per-block S-curve
         * (figures named *_scurve) */
        shape_override = SC_SHAPE_SCURVE;
        fig_suffix = "_scurve";
        bench_planners();
        bench_tick();
        /* the tick with the interpolated measurement on (its cost where a
         * machine turns it on; the figures above are the default's) */
        shape_override = -1;
        fig_suffix = "_interp";
        tick_interp = true;
        bench_tick();
    }
    while (!hal_uart_tx_idle()) {
    }
    semihost_exit();
    for (;;) {
    }
}
