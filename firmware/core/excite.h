/*
 * excite.h - bounded excitation experiment of one axis (commissioning).
 *
 * Specification
 * -------------
 * With the axis enabled at rest, an experiment adds a pseudo-random binary
 * sequence (PRBS) of +-amp_mv to the axis's motor command and records
 * whole periods of command and position for the host. It is the generator
 * and its supervisor only; drive_excite.h wires it into the drive (the
 * tick, the protocol messages, the sample buffer shared with calib.c).
 *
 * PRBS: maximal-length Fibonacci LFSR of `bits` (7..16) bits, seed 1,
 * period 2^bits - 1 chips, each chip held `hold` ticks (1..255: moves the
 * band down to tick_hz / hold). A chip of 1 gives +amp_mv, 0 gives -amp_mv.
 * The period P = (2^bits - 1) * hold ticks must fit the sample buffer.
 *
 * Recording: the excitation is periodic, so once the loop settled every
 * period is the same experiment. A window of P samples starts at a period
 * boundary at or after skip_ticks when the buffer has room for all of it
 * (the host released enough); periods without room are excited but not
 * recorded. A sample of tick k is {cmd_mv: the drive's command of tick k
 * plus the excitation = what the amplifier gets over tick k, pos_nm: the
 * position at the start of tick k - the position at the first tick}
 * (saturated to int32). Sample j of the run is window j / P, phase j % P.
 * The run ends DONE after `windows` windows; still running after n_ticks
 * ticks it aborts (reason DURATION): a host that reads too slowly cannot
 * keep the axis moving for longer than the user allowed.
 *
 * Limits (the user's; all checked every tick, before the output): the
 * position relative to the first tick's (|pos - pos0| <= travel_nm), the
 * velocity over EXCITE_VEL_TICKS ticks (<= vel_nm_s) and the total command
 * (|drive command + excitation| <= cmd_mv). The first violation aborts:
 * output 0 from that tick on, state ABORTED, reason set. A drive fault,
 * estop or a drive that is not IDLE (disabled, a job, a stop) aborts the
 * same way.
 *
 * Host watchdog: main calls excite_host_alive() on every request of the
 * host; the tick aborts (reason HOST_SILENT) when no call came for
 * host_timeout_ticks ticks. Killing the host thus stops the axis.
 *
 * Contexts
 *   excite_setup(), excite_start(), excite_abort(), excite_host_alive(),
 *   excite_release(), excite_sample() : main.
 *   excite_tick() : tick.
 * Fields: cfg, buf, buf_n (main, before start; read by the tick after
 * req_start), req_start / req_abort / host_seen / released (main), the
 * rest (tick). 32-bit aligned stores are atomic on every target
 * (preempt.h).
 */
#ifndef EXCITE_H
#define EXCITE_H

#include <stdbool.h>
#include <stdint.h>

#define EXCITE_VEL_TICKS 4u /* velocity: position change over this many ticks */

enum excite_state { EXCITE_IDLE = 0, EXCITE_RUNNING, EXCITE_DONE, EXCITE_ABORTED };

/* The same values as protocol/contour.toml's excite_reason. */
enum excite_reason {
    EXCITE_REASON_NONE = 0,
    EXCITE_REASON_TRAVEL,
    EXCITE_REASON_VELOCITY,
    EXCITE_REASON_COMMAND,
    EXCITE_REASON_FAULT,
    EXCITE_REASON_ESTOP,
    EXCITE_REASON_HOST_SILENT,
    EXCITE_REASON_DURATION,
    EXCITE_REASON_ABORTED,
    EXCITE_REASON_DRIVE_STATE,
    EXCITE_REASON_NEW_SESSION,
};

typedef struct {
    uint8_t axis;
    uint8_t bits;                /* LFSR length, 7..16                     */
    uint8_t hold;                /* ticks per chip, 1..255                 */
    uint16_t windows;            /* periods to record, >= 1                */
    int32_t amp_mv;              /* PRBS amplitude, 1 .. cmd_mv            */
    uint32_t skip_ticks;         /* no recording before (loop settling)    */
    uint32_t n_ticks;            /* longest run, >= 1                      */
    int64_t travel_nm;           /* > 0                                    */
    int32_t cmd_mv;              /* > 0                                    */
    int64_t vel_dpos_nm;         /* velocity limit as the position change
                                    over EXCITE_VEL_TICKS ticks, > 0       */
    uint32_t host_timeout_ticks; /* > 0                                    */
} excite_cfg_t;

typedef struct {
    int64_t pos_nm; /* axis position (feedback) at the start of the tick  */
    int32_t cmd_mv; /* the drive's own command of this tick               */
    bool fault;     /* a drive fault is latched                           */
    bool estop;     /* the latched fault is an estop                      */
    bool idle;      /* the drive is IDLE (enabled, at rest, nothing queued) */
} excite_in_t;

typedef struct {
    int32_t cmd_mv;
    int32_t pos_nm;
} excite_sample_t;

typedef struct {
    excite_cfg_t cfg;               /* main, before start            */
    excite_sample_t *buf;           /* main, before start            */
    uint32_t buf_mask;              /* main: buffer samples - 1      */
    uint32_t period;                /* main: P                       */
    volatile uint32_t req_start;    /* main: incremented to start    */
    volatile uint32_t req_abort;    /* main: incremented to abort    */
    volatile uint32_t abort_reason; /* main, before req_abort        */
    volatile uint32_t host_seen;    /* main: incremented per request */
    volatile uint32_t released;     /* main: samples before it are free */
    uint32_t ack_start, ack_abort;  /* tick */
    uint32_t host_last, host_ticks; /* tick */
    volatile uint32_t state;        /* tick (enum excite_state)      */
    volatile uint32_t reason;       /* tick (enum excite_reason)     */
    volatile uint32_t written;      /* tick: samples written         */
    volatile uint32_t k;            /* tick: ticks run               */
    uint32_t phase;                 /* tick: k % period              */
    uint32_t rec_left;              /* tick: samples left in the window */
    uint32_t windows_done;          /* tick                          */
    uint32_t lfsr;                  /* tick                          */
    uint32_t chip_left;             /* tick                          */
    int64_t pos0;                   /* tick                          */
    int64_t hist[EXCITE_VEL_TICKS]; /* tick: last positions          */
} excite_t;

void excite_init(excite_t *ex);
/* Checks and stores cfg and the sample buffer (n samples, a power of two
 * >= the period) while not RUNNING and no start is pending; false when
 * refused. */
bool excite_setup(excite_t *ex, const excite_cfg_t *cfg, excite_sample_t *buf, uint32_t n);
void excite_start(excite_t *ex);
/* Ends a run at the next tick with `reason` (EXCITE_REASON_ABORTED,
 * _NEW_SESSION). */
void excite_abort(excite_t *ex, uint32_t reason);
void excite_host_alive(excite_t *ex);
/* Frees every sample before seq (seq <= written). */
void excite_release(excite_t *ex, uint32_t seq);
/* Copies sample seq when it was written and not released. */
bool excite_sample(const excite_t *ex, uint32_t seq, excite_sample_t *out);

/* One control tick: returns the millivolts to add to the axis command. */
int32_t excite_tick(excite_t *ex, const excite_in_t *in);

#endif /* EXCITE_H */
