/*
 * sim.h - the hardware-in-the-loop simulator: the unchanged firmware (the
 * drive application, firmware/core/drive.h, through the sim HAL port) closed
 * in a loop with the axis models of axis_model.h.
 *
 * Specification
 * -------------
 * One simulator per process (like the drive it runs: static state, no heap).
 * Configure, start, then step any number of control ticks:
 *
 *   sim_setup(tick_hz, axes)        defaults: the thesis's X axis on axis 0,
 *                                   Y on axis 1, X parameters on Z; all options
 *                                   off; substep <= 100 us (10 us when friction
 *                                   or backlash is configured).
 *   sim_axis_set(axis, name, val)   any axis_params_t field by name (SI), plus
 *                                   "lead" (m per motor revolution: sets l).
 *                                   The simulator's own, per axis:
 *                                   "home_switch" (m, default
 *                                   SIM_HOME_SWITCH_M) and "home_side" (-1:
 *                                   the switch is active at table positions
 *                                   <= home_switch, +1: >=, 0: none; default
 *                                   -1): hal_home_switch (of the table at
 *                                   the tick, computed when read);
 *                                   "enc_index" (1: default, one index pulse
 *                                   per motor turn, one count wide, at
 *                                   "index_phase" counts from position 0 and
 *                                   every enc_counts_per_rev counts; 0: none).
 *                                   Disturbances (below): "cut_f_at" (N),
 *                                   "spring_k" (N/m), "spring_x0" (m) per
 *                                   axis; "cut_f_w" (N) and "cut_phi" (rad,
 *                                   default pi/4) of the X-Y plane (any axis
 *                                   index sets the one value).
 *   sim_axis_pitch(axis, n, ...)    the pitch error map.
 *   sim_field2d(nx, ny, ...)        the 2-D error field of X and Y
 *                                   (field2d.h; nx = 0: off, the default).
 *   sim_set_substep(max_s)          substep length bound (0: the default).
 *   sim_start()                     discretise (matrix exponentials), reset
 *                                   the HAL, drive_init(), axes at position 0
 *                                   and at rest.
 *   sim_run(ticks, trace, ...)      the loop below, optionally writing a
 *                                   trace row every `every` ticks.
 *
 * One tick k at time t_k = (k + 1) * period (period = round(1e9 / tick_hz) ns;
 * drive_init ran at time 0):
 *   1. the HAL clock reads t_k; reference-scale counters are published on
 *      channels axes..2*axes-1 (hal_encoder_counter, 32-bit wrapping;
 *      axis_ref_reading: with the model's reference noise, if any) and the
 *      home switches (hal_home_switch), both of the table at t_k; without
 *      reference noise both are computed when the firmware reads them
 *      (HAL sources, hal_sim.h: the same values, as the firmware reads its
 *      inputs in steps 2 and 5 only, before the table moves);
 *   2. drive_tick(calib_sampling()) runs (decode, interpolate, servo,
 *      hal_motor_set_mv), then calib_tick with what it published;
 *   3. every axis's decoded count is compared with the count the model
 *      emitted (sim_edge_mismatches() counts ticks where any differ);
 *   4. the trace row is written (state at t_k, command just computed,
 *      plus the injected voltage of this tick, if any: sim_inject);
 *   5. calib_poll() and drive_poll() run (background work between ticks);
 *   6. each axis model advances over [t_k, t_k+1) in substeps with the motor
 *      command held (ZOH); after each substep the encoder reading (counts,
 *      with noise when configured) is quantised (floor) and every count
 *      change is a quadrature edge, time-stamped by linear interpolation of
 *      the reading within the substep (ns clock, wrapping uint32), that
 *      reaches the firmware as the encoder model says (sim_encoder_model):
 *      one by one through drive_encoder_edge(), or the substep's edges as
 *      one run through drive_encoder_run() (the same decoder state).
 * Disturbances (all 0 by default: then step 5b does not run and every trace
 * is bit-identical to a simulator without them): after step 5,
 *   5b. a force F_i (N, positive pushes the table toward -x) per axis from the
 *       drive's reference velocity v (drive_status_t.vel_ref) of this tick and
 *       the table position x_i, the thesis's eq. 4.3 plus a spring:
 *         F_x = cut_f_at_x sgn(v_x) + cut_f_w cos(cut_phi - a) + k_x (x - x0)
 *         F_y = cut_f_at_y sgn(v_y) - cut_f_w sin(cut_phi - a) + k_y (y - y0)
 *       with a = atan2(v_y, v_x) the path angle; the cut_f_w terms act only
 *       while the reference moves (sgn 0 = 0). It acts over the coming tick
 *       as the load torque T1 = l F on the motor side (the thesis's Tc; the
 *       axis's own load_torque is added).
 * The motor command is read as millivolts at the amplifier input
 * (hal_sim_motor_mv: 0 when the amplifier is disabled); the model applies
 * the amplifier gain kx and the +-vmax limit.
 *
 * Deterministic: the same configuration and command sequence give
 * bit-identical traces (no clocks, no threads, seeded noise).
 *
 * Trace row (doubles, SIM_TRACE_COLS per row):
 *   [0] t (s)  [1] drive state  [2] fault bits  [3] CEC estimate (m)
 *   then per axis i (4 columns from 4 + 4 i): reference (m), true table
 *   position (m), position the drive measured (m), command (V at the
 *   amplifier input).
 *
 * All functions return 0 on success and a negative SIM_E_* code otherwise
 * (sim_run returns rows written or a negative code). A setting taken by
 * sim_axis_set, sim_gain_set, sim_servo_set or sim_plan_set acts from the
 * next sim_start (until then sim_run returns SIM_E_STATE); a refused one
 * (SIM_E_ARG) changes nothing, and a running simulator runs on.
 */
#ifndef SIM_H
#define SIM_H

#include <stddef.h>
#include <stdint.h>

#include "axis_model.h"
#include "core_config.h"
#include "fixmath.h"

#define SIM_AXES       CORE_AXES
#define SIM_TRACE_COLS (4 + 4 * SIM_AXES)

/* Default home switch edge: 21.3 mm below the start position (the next
 * index above it, with index_phase 0 and a 5 mm lead, is at -20 mm). */
#define SIM_HOME_SWITCH_M (-0.0213)

#define SIM_E_ARG   (-1) /* bad argument / unknown name        */
#define SIM_E_STATE (-2) /* not set up / not started            */
#define SIM_E_MODEL (-3) /* axis parameters refused             */
#define SIM_E_DRIVE (-4) /* drive_init or a drive call refused  */
#define SIM_E_FULL  (-5) /* planner full                        */

int sim_setup(double tick_hz, unsigned axes);
int sim_axis_set(unsigned axis, const char *name, double value);
int sim_axis_get(unsigned axis, const char *name, double *value);
int sim_axis_pitch(unsigned axis, unsigned n, const double *pos, const double *err_fwd,
                   const double *err_rev);
int sim_field2d(unsigned nx, unsigned ny, double x0, double dx, double y0, double dy,
                const double *col, const double *sig, unsigned nr, double r0, double dr,
                const double *row, double band);
int sim_set_substep(double max_s);

/* How the encoder edges reach the firmware's decoder (docs/simulator.md,
 * "Encoder models"); sim_setup sets SIM_ENC_FAST; takes effect at once.
 *   SIM_ENC_EDGES  the reference: every edge through drive_encoder_edge.
 *   SIM_ENC_FAST   each substep's edges as one run (drive_encoder_run:
 *                  the count and the last edge's time the edges would
 *                  leave, computed from the reading), edge by edge only
 *                  where Z changes or the decoder refuses a run. The
 *                  decoder's state at every sample, and so every trace,
 *                  is bit-identical to SIM_ENC_EDGES. */
#define SIM_ENC_EDGES 0
#define SIM_ENC_FAST  1
int sim_encoder_model(int model);
int sim_encoder_model_get(void);

/* Diagnostic (docs/simulator.md, "The 3 ms tick"): on, the trace's table
 * columns hold each table's mean position over the tick (the substeps,
 * without the 2-D field) instead of its position at the tick, so a table
 * mode above half the tick rate is not aliased into the score. Off after
 * sim_setup. SIM_E_STATE before sim_setup. */
int sim_trace_table_mean(int on);

/* The instrument (docs/simulator.md, "Circle scenario and scoring"): the
 * true table positions as the plant has them, independent of the drive's
 * tick, for scores of the path the table really traces. After
 * sim_table_record(buf, rows_cap, min_hz) each substep end at which the
 * number of substeps since sim_start is a multiple of
 * m = max(1, floor(f_sub / min_hz)) (f_sub = substeps per second) writes a
 * row of SIM_REC_COLS doubles to the host's buffer: [0] t (s), then table
 * position (m) of axis 0..axes-1, 2-D field included (a sample at a tick's
 * end is the next trace row's table bit for bit; earlier ones take the
 * field at the direction tracked at that tick's start); the columns of
 * absent axes are not written. The rate f_sub / m
 * (sim_table_record_hz) is >= min_hz while f_sub >= min_hz (the default
 * substep bound, 100 us, gives f_sub >= 10 kHz at any tick); one row per
 * substep below it. Rows past rows_cap are counted, not written
 * (sim_table_recorded() > rows_cap: lost). Each call restarts the count;
 * buf NULL or rows_cap 0: off (sim_start turns it off; the host keeps the
 * buffer alive while on). Off, no trace changes at all. SIM_E_STATE
 * before sim_start. */
#define SIM_REC_COLS (1 + SIM_AXES)
int sim_table_record(double *buf, size_t rows_cap, double min_hz);
size_t sim_table_recorded(void);
double sim_table_record_hz(void);

/* The drive's configuration before sim_start (SI units, converted here):
 *   sim_gain_set(loop, name, v)  loop 0..axes-1: that axis's PID, -1: the
 *       CEC's PID, -2: the CEC's straight-path gains (turns the line/curve
 *       gain switching on). kp (V/m), ki (V/(m s)), kd (V s/m), kvff (V/(m/s)),
 *       kaff (V/(m/s^2)), kt (1/s), d_tau (s), deadband (m), i_max (V),
 *       out_max (V), d_on_measurement (0/1). Volts at the amplifier input.
 *   sim_servo_set(axis, name, v)  ferr_limit (m, 0 off), stop_decel (m/s^2),
 *       sat_limit (s, 0 off; axis ignored), on_following / on_saturation
 *       (0 disable, 1 stop; axis ignored), handover (0/1; axis ignored),
 *       friction_ff (V at the amplifier input), friction_ff_band (m/s; axis
 *       ignored), ff_advance (s, drive.h ff_advance_ns; axis ignored),
 *       qg_comp (0/1, drive.h; axis ignored), ffl_rate (1/s, servo.h
 *       "Feed-forward learning"; axis ignored), cec_thesis_form (0/1,
 *       cec.h thesis_form; axis ignored), enc_mean / enc_interp (0/1,
 *       drive.h; axis ignored).
 *   sim_plan_set(axis, name, v)   v_max (m/s), a_max (m/s^2), j_max (m/s^3),
 *       corner_dv (m/s), corner_acc (m/s^2); axis ignored: junction_dev (m),
 *       corner (plan_corner_t), shape (sc_shape_t), min_block (s),
 *       mbt_window (blocks), stop_decel (m/s^2, drive_stop), arc_chord (m).
 *   sim_cec_mode(mode)            drive_cec_mode_t applied at start (and at
 *       once when started and idle). */
int sim_gain_set(int loop, const char *name, double value);
int sim_servo_set(unsigned axis, const char *name, double value);
int sim_plan_set(unsigned axis, const char *name, double value);
int sim_cec_mode(int mode);

/* The host link of the simulated drive, set up by sim_start through the
 * composition root (app.h): CAN node id, serial and/or CAN served, extra
 * capability bits (SIMULATED is always set), fw_version and build id
 * reported without a flash image, and boot != 0 when the simulated
 * bootloader's slot (boot_sim.h) holds this application (identity from its
 * image, boot_enter served). sim_setup turns the link off (the simulator
 * alone: circle tests, benchmarks). */
int sim_set_link(unsigned node_id, int serial, int can, uint32_t capabilities, uint32_t fw_version,
                 uint32_t build_id, int boot);
int sim_start(void);
/* drive_enable(on) of the running drive; returns the drive_result_t. */
int sim_enable(int on);
long sim_run(uint64_t ticks, double *trace, size_t rows_cap, unsigned every);
/* sim_run that also stops after the first tick (and its drive_poll) that
 * leaves at least min_free free slots in the drive's host-block queue
 * (drive_queue_free; 0: never early), so a host can top the queue up in
 * time and keep the planner's look-ahead full. *ran (may be NULL): ticks
 * run. Returns rows written or a negative code. */
long sim_run_until_free(uint64_t ticks, unsigned min_free, double *trace, size_t rows_cap,
                        unsigned every, uint64_t *ran);
/* As sim_run, in steps of `step` ticks (0: 1), stopping after the first
 * step that ends with the drive idle (DRIVE_IDLE) or faulted
 * (drive_status): what a host that runs `step` ticks at a time and polls
 * the drive's status after each would run, in one call (contour sim
 * circle). *ran (may be NULL): ticks run. Returns rows written or a
 * negative code. */
long sim_run_until_idle(uint64_t ticks, unsigned step, double *trace, size_t rows_cap,
                        unsigned every, uint64_t *ran);

/* An additive motor command per axis (V at the amplifier input), one value
 * per tick from `volts` (the host keeps the buffer alive): tick j after
 * this call adds volts[j] to the drive's command, for j < n, while the
 * amplifier is enabled (hal_sim_motor_enabled); the trace's command column
 * shows the sum. The excitation injection point of commissioning (docs/
 * commissioning.md), in the simulator, not the drive. n = 0 or volts NULL:
 * off (the default after sim_start; no effect at all on any trace).
 * sim_inject_left(axis): values not yet applied. */
int sim_inject(unsigned axis, const double *volts, size_t n);
size_t sim_inject_left(unsigned axis);

/* Read-outs. */
unsigned sim_trace_cols(void);
uint32_t sim_tick_hz(void);
uint64_t sim_ticks(void);
double sim_time_s(void);
uint64_t sim_edges(void);
/* Of sim_edges(), those delivered in runs (SIM_ENC_FAST; 0 with edges). */
uint64_t sim_run_edges(void);
uint64_t sim_edge_mismatches(void);
unsigned sim_substeps(void);
/* Test hook: with one substep per tick the loop steps every axis's plant
 * first and then the generators (sim.c plant_tick1); off (0), it takes the
 * general loop, axis by axis, as with several substeps. Default on. */
void sim_test_plant_split(int on);
/* Test hook: off (0), the loop takes the general path also when no option
 * needs it (sim.c run_plain: the plain path leaves out their tests).
 * Default on. */
void sim_test_plain(int on);
/* Test hook: on (1), the simulator sets every home switch and reference
 * scale counter at the start of every tick, as a port without sources
 * would, instead of computing them when the firmware reads them (the
 * default, 0; sim.c sim_home_read). Call it between sim_setup, which turns
 * it off, and sim_start, where it takes effect. */
void sim_test_eager_inputs(int on);
double sim_table_pos(unsigned axis);

/* The drive's status in a fixed layout for the host (ctypes). */
typedef struct {
    int state; /* drive_state_t */
    uint32_t faults;
    uint32_t queue_free;
    uint32_t blocks_done;
    uint32_t tag;
    uint64_t tick;
    int64_t queued_time_ns;
} sim_status_t;
int sim_drive_status(sim_status_t *out);

/* Convenience wrappers of drive_queue_block for the host (nm, nm/s). They
 * return 0 or a negative SIM_E_* code; *result gets the drive_result_t. */
int sim_queue_line(const int64_t *target_nm, int64_t feed_nm_s, uint32_t tag, int exact_stop,
                   int *result);
int sim_queue_dwell(uint32_t ms, uint32_t tag, int *result);
int sim_queue_arc(const int64_t *target_nm, int64_t feed_nm_s, int plane, int64_t centre_u,
                  int64_t centre_v, int sense, uint32_t tag, int *result);

#endif /* SIM_H */
