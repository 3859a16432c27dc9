/*
 * excite.h - bounded excitation experiment of one axis (commissioning).
 *
 * Specification
 * -------------
 * With the axis enabled at rest, an experiment adds a pseudo-random binary
 * sequence (PRBS) of +-amp_mv to the axis's motor command for n_ticks
 * control ticks and records one sample per tick for the host. It is the
 * generator and its supervisor only: the drive adds excite_tick's output to
 * the axis command and calls drive_stop when the experiment aborts (the
 * wiring into drive.c, the protocol messages and the sample transfer are
 * not built yet; docs/commissioning.md).
 *
 * PRBS: maximal-length Fibonacci LFSR of `bits` (7..16) bits, seed 1,
 * period 2^bits - 1 chips, each chip held `hold` ticks (1..255: moves the
 * band down to tick_hz / hold). A chip of 1 gives +amp_mv, 0 gives -amp_mv.
 *
 * Limits (the user's; all checked every tick, before the output): the
 * position relative to the position at the first tick (|pos - pos0| <=
 * travel_nm), the measured velocity (|vel| <= vel_nm_s) and the total
 * command the drive applied last tick (|cmd| <= cmd_mv). The first
 * violation aborts: output 0 from that tick on, state ABORTED, reason set.
 * A drive fault or estop (in->fault, in->estop) aborts the same way.
 *
 * Host watchdog: main calls excite_host_alive() on every request of the
 * host; the tick aborts (reason HOST_SILENT) when no call came for
 * host_timeout_ticks ticks. Killing the host thus stops the axis.
 *
 * Samples: one per running tick, {seq, cmd_mv, pos_nm} with seq from 0,
 * into a ring of EXCITE_RING. The host frees them with excite_release(seq)
 * (everything before seq). A full ring aborts (reason OVERRUN) instead of
 * overwriting: the host never gets a record with a hole it cannot see,
 * and its check of seq continuity detects a loss on the link.
 *
 * Contexts
 *   excite_setup(), excite_start(), excite_abort(), excite_host_alive(),
 *   excite_release(), excite_sample() : main.
 *   excite_tick() : tick.
 * Fields: cfg (main, before start; read by the tick after req_start),
 * req_start / req_abort / host_seen / released (main), the rest (tick).
 * 32-bit aligned stores are atomic on every target (preempt.h).
 */
#ifndef EXCITE_H
#define EXCITE_H

#include <stdbool.h>
#include <stdint.h>

#define EXCITE_RING 1024u /* samples, power of two */

enum excite_state { EXCITE_IDLE = 0, EXCITE_RUNNING, EXCITE_DONE, EXCITE_ABORTED };

enum excite_reason {
    EXCITE_REASON_NONE = 0,
    EXCITE_REASON_TRAVEL,
    EXCITE_REASON_VELOCITY,
    EXCITE_REASON_COMMAND,
    EXCITE_REASON_FAULT,
    EXCITE_REASON_ESTOP,
    EXCITE_REASON_HOST_SILENT,
    EXCITE_REASON_OVERRUN,
    EXCITE_REASON_ABORTED,
};

typedef struct {
    uint8_t axis;
    uint8_t bits;                /* LFSR length, 7..16                   */
    uint8_t hold;                /* ticks per chip, 1..255               */
    int32_t amp_mv;              /* PRBS amplitude, 1 .. cmd_mv          */
    uint32_t n_ticks;            /* experiment length, >= 1              */
    int64_t travel_nm;           /* > 0                                  */
    int64_t vel_nm_s;            /* > 0                                  */
    int32_t cmd_mv;              /* > 0                                  */
    uint32_t host_timeout_ticks; /* > 0                                  */
} excite_cfg_t;

typedef struct {
    int64_t pos_nm;   /* axis position (feedback)               */
    int64_t vel_nm_s; /* measured velocity                      */
    int32_t cmd_mv;   /* total command applied over the last tick */
    bool fault;       /* a drive fault is latched               */
    bool estop;       /* estop input or request                 */
} excite_in_t;

typedef struct {
    uint32_t seq;
    int32_t cmd_mv;
    int64_t pos_nm;
} excite_sample_t;

typedef struct {
    excite_cfg_t cfg;                  /* main, before start          */
    volatile uint32_t req_start;       /* main: incremented to start  */
    volatile uint32_t req_abort;       /* main: incremented to abort  */
    volatile uint32_t host_seen;       /* main: incremented per host request */
    volatile uint32_t released;        /* main: samples before it are free */
    uint32_t ack_start, ack_abort;     /* tick */
    uint32_t host_last, host_ticks;    /* tick */
    volatile uint32_t state;           /* tick (enum excite_state)    */
    volatile uint32_t reason;          /* tick (enum excite_reason)   */
    volatile uint32_t written;         /* tick: samples written       */
    uint32_t k;                        /* tick: ticks run             */
    uint32_t lfsr;                     /* tick                        */
    uint32_t chip_left;                /* tick                        */
    int32_t out_mv;                    /* tick: output of this tick   */
    int64_t pos0;                      /* tick                        */
    excite_sample_t ring[EXCITE_RING]; /* tick writes, main reads below written */
} excite_t;

void excite_init(excite_t *ex);
/* Checks and stores cfg (IDLE, DONE or ABORTED only); false when refused. */
bool excite_setup(excite_t *ex, const excite_cfg_t *cfg);
void excite_start(excite_t *ex);
void excite_abort(excite_t *ex);
void excite_host_alive(excite_t *ex);
/* Frees every sample before seq (seq <= written). */
void excite_release(excite_t *ex, uint32_t seq);
/* Copies sample seq when it was written and not released. */
bool excite_sample(const excite_t *ex, uint32_t seq, excite_sample_t *out);

/* One control tick: returns the millivolts to add to the axis command. */
int32_t excite_tick(excite_t *ex, const excite_in_t *in);

#endif /* EXCITE_H */
