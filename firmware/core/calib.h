/*
 * calib.h - the drive's calibration mode and its compensation tables.
 *
 * Specification
 * -------------
 * Two services of the drive application (drive.h), one static instance:
 *
 * 1. Calibration run. The host sets up a run of one axis (calib_setup: n
 *    strictly increasing target positions, cycles, samples per point, sample
 *    interval, dwell, overrun, feed) and starts it. Each cycle is the
 *    bidirectional linear cycle of ISO 230-2:
 *      move to t[0] - overrun; then t[0], t[1], ..., t[n-1] approached moving
 *      +x; move to t[n-1] + overrun; then t[n-1], ..., t[0] approached moving
 *      -x;
 *    a "leg" is one target approached in one direction: the drive moves there
 *    (one exact-stop LINE block of the axis, the other axes hold their
 *    reference), waits until the planner is done, dwells dwell_ms, waits for
 *    room in the sample buffer, then takes `samples` samples, one every
 *    sample_ticks control ticks. A sample (CALIB_SAMPLE_BYTES on the wire,
 *    little-endian):
 *        u32 seq    running sample number from 0 at calib_setup
 *        u16 point  target index      u8 cycle
 *        u8  flags  bit 0 approached moving -x, bit 1 no reference (host
 *                   reference mode), bit 2 a drive fault was latched,
 *                   bit 3 no cross reference (x* fields 0)
 *        i32 enc    encoder position before compensation - target, nm
 *        i32 comp   encoder position after compensation (the feedback) -
 *                   target, nm
 *        i32 ref    reference-scale position - target, nm (0 in host
 *                   reference mode)
 *        i32 xenc   the cross axis (below): encoder before compensation
 *                   - its held position, nm
 *        i32 xcomp  the cross axis: encoder after compensation - held
 *        i32 xref   the cross axis: reference scale - held position, nm
 *    (differences saturate to int32). The reference scale is the axis's
 *    auxiliary quadrature input (drive.h: reference-scale channel, decoded
 *    by qdec with its own resolution); with CALIB_FLAG_HOST_REFERENCE the
 *    drive samples the encoder only and the host supplies the reference
 *    (an external instrument's readings).
 *    The cross axis is the other axis of the XY plane (X for a run of Y,
 *    Y for a run of X): a 2-D grid encoder (the KGM 101 of the thesis)
 *    reads both coordinates of the table, each on the reference-scale
 *    input of its axis, so every sample carries both coordinates read in
 *    the same tick (the error along the line and across it). Its held
 *    position is the cross axis's commanded position when the leg starts
 *    sampling. The x* fields are 0 and flag bit 3 (no cross reference) is
 *    set when the run is not of X or Y, the cross axis is not configured
 *    or has no reference scale, or in host reference mode.
 *    After the run (state DONE) single legs can be measured again
 *    (calib_point: approach the target from overrun away in the given
 *    direction), e.g. when the host could not recover some samples.
 *
 *    Transfer (pull, sample_pull.h): samples wait in a ring of CALIB_RING; the host reads
 *    them with calib_read(from_seq), which also releases every sample before
 *    from_seq. A leg starts sampling only when the ring has room for all its
 *    samples, so no sample is ever overwritten before the host released it:
 *    a run with a slow or lossy host just waits. Each calib_samples reply
 *    carries a CRC-32 of its sample bytes on top of the link's own check.
 *    Reading is idempotent (a retried read returns the same samples).
 *
 *    Faults: a drive fault or a disabled drive during a run ends it (state
 *    ERROR, reason drive_fault / drive_disabled); calib_abort stops the axes
 *    (drive_stop) and ends it (reason aborted). A host that goes silent
 *    ends it the same way: no calibration request for CALIB_HOST_TIMEOUT_MS
 *    of drive time (reason host_silent), or a new host session (reason
 *    new_session, from the composition root, app.c): a run never resumes
 *    motion for a host that did not start it. The samples taken stay
 *    readable.
 *
 * 2. Compensation tables (comp.h), per axis: the active table is installed
 *    in the axis's decoder (drive_set_comp) with a direction source that
 *    follows the commanded motion (comp_ramp_t fed with the reference
 *    velocity every tick, ramp time from the table). At calib_init the
 *    current table of every axis is loaded from the flash store
 *    (comp_store.h). A new table arrives as a comp record (comp_write into
 *    a staging buffer, comp_commit with its length and CRC-32): it is
 *    checked, written to the other flash slot, read back and verified, then
 *    loaded FROM FLASH into the inactive RAM buffer and swapped in (one
 *    pointer store). Any failure leaves the previous table active and
 *    current in flash. comp_clear stores and activates an empty table.
 *
 * Protocol: calib_handle() serves ids 0xA0..0xBF (protocol/contour.toml);
 * other ids go to the next handler (calib_set_next_handler, e.g. the
 * bootloader's application side) or get error{unknown_message}. Refusals
 * are error{code = calib, arg = calib_status, lo = detail}. Requests that
 * change state (setup, targets, start, point, abort, comp_write,
 * comp_commit, comp_clear) are answered from a one-entry replay cache when
 * the same (id, seq, payload) arrives again (a host retry), so they are
 * never executed twice; status, read and comp_get are idempotent and always
 * executed.
 *
 * Contexts
 *   calib_init()      main, after drive_init (drive stopped).
 *   calib_tick(st, v) tick, right after drive_tick(calib_sampling()) with
 *                     what it published (drive_tick_status(),
 *                     drive_tick_vel_ref()): direction ramps, sampling.
 *   calib_poll()      main, before drive_poll: the run's state machine.
 *   calib_handle()    main (the link's extension handler).
 *   Tick writes: ring entries, seq_next, the sampling flag, ramps. Main
 *   writes everything else; it arms sampling only while the tick is not
 *   sampling, and releases ring entries the tick no longer writes.
 * No heap, no floating point.
 */
#ifndef CALIB_H
#define CALIB_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "comp.h"
#include "core_config.h"
#include "drive.h"
#include "excite.h"

#ifndef CALIB_RING
#define CALIB_RING 512u /* samples held for the host */
#endif
#define CALIB_POINTS_MAX   COMP_POINTS_MAX
#define CALIB_CYCLES_MAX   20u
#define CALIB_SAMPLE_BYTES 32u
#define CALIB_READ_MAX     7u          /* samples per calib_samples reply      */
#define CALIB_OVERRUN_MAX  1000000000u /* 1 m                                 */
#define CALIB_DWELL_MAX_MS 60000u
/* A run with no calibration request for this long is aborted (host gone). */
#define CALIB_HOST_TIMEOUT_MS 3000u
#define CALIB_POS_LIMIT_NM    ((pos_nm_t)1 << 48) /* |target| and target +- overrun */

#define CALIB_FLAG_HOST_REFERENCE 0x01u

#define CALIB_SAMPLE_NEG     0x01u
#define CALIB_SAMPLE_NO_REF  0x02u
#define CALIB_SAMPLE_FAULT   0x04u
#define CALIB_SAMPLE_NO_XREF 0x08u

typedef enum {
    CALIB_IDLE = 0,
    CALIB_SETUP = 1,
    CALIB_RUNNING = 2,
    CALIB_DONE = 3,
    CALIB_ERROR = 4
} calib_state_t;

typedef struct {
    uint32_t seq;
    uint16_t point;
    uint8_t cycle;
    uint8_t flags; /* CALIB_SAMPLE_* */
    int32_t enc;   /* nm, relative to the target */
    int32_t comp;
    int32_t ref;
    int32_t xenc; /* cross axis, nm, relative to its held position */
    int32_t xcomp;
    int32_t xref;
} calib_sample_t;

/* Extension handler: same contract as proto_link_handler_fn. */
typedef size_t (*calib_handler_fn)(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                                   size_t cap);

void calib_init(void);
/* The host of a running run is gone (reason: PROTO_CALIB_STATUS_HOST_SILENT,
 * _NEW_SESSION or _ABORTED): the axes stop (drive_stop) and the run ends in
 * ERROR with that reason; nothing moves again without a new calib_start or
 * calib_point. No effect when no run is in progress. Main. */
void calib_host_gone(uint8_t reason);
void calib_tick(const drive_status_t *st, const int64_t vel_ref[CORE_AXES]);
/* True while sampling is armed: calib_tick then reads pos, pos_raw,
 * refscale (of the axis and of the cross axis) and faults of the status (otherwise only vel_ref,
 * the reference velocities the ramps follow, nm/s; the status's own vel_ref field is not read).
 * Tick. */
bool calib_sampling(void);
void calib_poll(void);
size_t calib_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out, size_t cap);
void calib_set_next_handler(calib_handler_fn fn);

/* The sample buffer, for a commissioning excitation (drive_excite.h): the
 * two runs exclude each other (RAM: the buffers are one union). NULL while
 * a calibration run is set up or running; otherwise the samples of a
 * finished run are dropped (state IDLE) and, until calib_excite_give(),
 * calib_setup, _targets, _start, _read and _point are refused with
 * calib_status `excite`. Main. */
#define CALIB_EXCITE_SAMPLES 1024u /* a power of two; fits CALIB_RING samples */
excite_sample_t *calib_excite_take(void);
void calib_excite_give(void);

/* Read-outs (tests, simulator). */
calib_state_t calib_state(void);
/* Active table of an axis (NULL: none). */
const comp_table_t *calib_comp_active(unsigned axis);
/* Encode one sample in the wire format (CALIB_SAMPLE_BYTES). */
void calib_sample_encode(const calib_sample_t *s, uint8_t *buf);

#endif /* CALIB_H */
