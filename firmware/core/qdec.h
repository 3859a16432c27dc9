/*
 * qdec.h - quadrature decoding and position feedback of one encoder channel.
 *
 * Specification
 * -------------
 * One qdec_t per encoder (servo axes and reference-scale inputs alike). It
 * turns either A/B(/Z) edge events or snapshots of a hardware counter into a
 * 64-bit position, a velocity estimate, an index latch and fault bits, then
 * scales the position to nanometres and passes it through the compensation
 * hook (comp.h).
 *
 * Inputs (choose one per decoder with cfg.input):
 *   QDEC_INPUT_EDGES    qdec_edge(q, lines, t_ns) once per edge event, with
 *                       the new levels of A, B (and Z) after the edge. The
 *                       decoder keeps a wrapping 32-bit count in the edge
 *                       context; qdec_sample(q, now_ns) extends it to 64 bits
 *                       once per control tick.
 *   QDEC_INPUT_COUNTER  qdec_sample_counter(q, raw, now_ns) once per tick with
 *                       the 16- or 32-bit (cfg.counter_bits) hardware counter
 *                       (timer in encoder mode: its own x4 decoding, so
 *                       cfg.mode is not used). Optional index capture by the
 *                       hardware: qdec_index_capture(q, raw_at_index, t_ns).
 *
 * Timestamps: every t_ns / now_ns given to one decoder is a uint32 nanosecond
 * count of ONE free-running clock, wrapping at 2^32 ns (4.29 s). Ports with a
 * microsecond clock pass t_us * 1000u (wraps consistently; resolution then
 * 1 us). The decoder extends times to 64 bits at each sample; this requires
 * samples less than 2^31 ns (2.1 s) apart and every edge timestamp within
 * 2^31 ns of the sample that first sees it (edges after the sample's time
 * read are fine). 1 ns timestamps resolve the 1000 ns edge spacing of
 * 10^6 counts/s to 0.1 %, per edge; across a window of many edges far better.
 *
 * Decoding (edge input). Levels: A = bit 0, B = bit 1, Z = bit 2 of `lines`.
 * Forward (+1) is A leading B: AB states 00 -> A -> AB -> B -> 00 (lines
 * 0, 1, 3, 2). A 16-entry table indexed by (old AB, new AB) gives the count:
 *   x4: every single-channel change counts +-1 (4 counts per cycle).
 *   x2: only changes of A count (A rising with B low, A falling with B high:
 *       +1 forward), 2 per cycle.
 *   x1: only the 00 <-> A transition counts (+1 forward), 1 per cycle.
 * In terms of the x4 position p of the same signal (from the same start):
 * x2 = floor((p + 1) / 2), x1 = floor((p + 3) / 4) (floor division).
 * An event with unchanged A/B counts nothing (e.g. a Z-only change). An event
 * where A and B both changed is ILLEGAL: it is counted in `illegal`, never
 * turned into a step; the decoder adopts the new state (the position may now
 * be off by +-2 x4 counts: that is why it is a fault, not a guess). When
 * cfg.illegal_limit illegal transitions fall within cfg.illegal_window_ns,
 * QDEC_FAULT_ILLEGAL latches. The window is evaluated at the samples, so
 * event times are taken as the time of the sample that saw them (+0/-1
 * tick).
 *
 * Rated speed (edge input): the decoder has no rate limit of its own; the
 * loop-back test runs at QDEC_RATED_CPS (10^7 counts/s, 100 ns edge spacing).
 * The port's edge interrupt is the practical limit.
 *
 * Counter extension (counter input): each sample adds the difference of the
 * raw counter, sign-extended from counter_bits, to the 64-bit position. It is
 * exact while the true change per sample stays within
 *   QDEC_MAX_DELTA(bits) = 2^(bits-1) - 1   (32767 for 16 bits),
 * i.e. 3.27e8 counts/s for a 16-bit counter at a 10 kHz tick. A change above
 * cfg.max_delta (default 2^(bits-2) - 1 = 16383 for 16 bits) latches
 * QDEC_FAULT_OVERSPEED; with that default every true change up to
 * 3 * 2^(bits-2) (49152) either counts exactly or raises the fault. Edge input
 * applies the same check to its 32-bit count (default limit 2^30 - 1).
 *
 * Index: the gated index is Z high AND (cfg.index_qual == QDEC_INDEX_UNGATED
 * or A/B equal to cfg.index_qual). On each rising edge of the gated index the
 * edge context latches the count, the edge time and the direction; the next
 * sample publishes it as out.index_pos (64-bit counts), out.index_t_ns and
 * out.index_dir and increments out.index_events. With a qualifying A/B state
 * the gated index is one x4 count wide, so the latched count is the same in
 * both directions of travel (no hysteresis). Homing / compensation: note
 * out.index_events, move, wait until it changes, read out.index_pos. Counter
 * input: the port's index capture interrupt calls qdec_index_capture().
 *
 * Velocity (out.vel, q32_32 counts/s; out.vel_nm_s, nm/s): mixed M/T method.
 * At each sample that saw new counted edges, the last counted edge (count P,
 * time T) is recorded; the estimate is (P - P0) / (T - T0) against the
 * oldest recorded edge (P0, T0) that is not older than cfg.vel_window_ns
 * before T, or else against the previous recorded edge. So:
 *   at speed (>= 1 count per sample): counts over a window of whole edge
 *     intervals of about one sample (or vel_window_ns), timed by the edge
 *     timestamps, not the sample times: exact for constant velocity up to
 *     the timestamp resolution;
 *   at low speed: 1 count / time between the last two edges (T method).
 * Between edges the estimate is limited to 1 count (vel_cycle: 1 cycle) /
 * (now - T) (if the axis were still moving faster, an edge would have
 * come), and it is 0 with
 * out.stopped set after cfg.zero_timeout_ns without an edge. The lowest speed
 * reported without a timeout is therefore 1e9 / zero_timeout_ns counts/s
 * (default 20 s: 0.05 counts/s).
 * Encoder edge placement errors (quadrature phase and duty-cycle error, a
 * fraction e of a count) enter a window that does not span whole cycles as
 * up to 2e counts / W. With cfg.vel_cycle (edge input) only cycle-aligned
 * edges (count = 0 mod counts-per-cycle: every 4th x4 edge, every 2nd x2
 * edge) are recorded, so the error of a periodic edge placement cancels
 * exactly; the price is a window of at least one cycle (4 x4 counts) at low
 * speed: 4x the delay and the minimum measurable speed.
 * Counter input has no edge times: T is the time of the sample that saw the
 * change, so the estimate has an uncertainty of one count per window
 * (1e4 counts/s with one 100 us sample; widen vel_window_ns to reduce it).
 * Error bound for constant velocity v (asserted by tests/unit/test_qdec.c;
 * figures in docs/quadrature.md), Ts the sample period, W the window used:
 *   edge input:    |err| <= |v| * 2 ns / W + 1e-6 counts/s, with W >= one
 *                  recorded-edge interval and >= Ts less one: at most 4e-5
 *                  relative at 10 kHz (ideal edges, 1 ns stamps);
 *   counter input: |err| < min(1 count, |v| Ts) / W, the counts being exact
 *                  at the sample times, W >= max(window - Ts, 1/|v| - Ts).
 * Delay: the estimate is the mean velocity over [T0, T], so it is centred
 * W/2 + (now - T) before the sample.
 *
 * Glitch filter (cfg.glitch_ns > 0, edge input only): a level change on A or
 * B is accepted only when the new level lasts at least glitch_ns. An edge is
 * held pending until the next edge on the same channel (a pulse shorter than
 * glitch_ns drops both edges and counts one in out.glitches) or until an
 * event or sample at least glitch_ns later confirms it; confirmed edges are
 * decoded in time order with their original timestamps (velocity and index
 * use those). Simultaneous (same timestamp) changes of A and B stay illegal.
 * Effect on counts: the count is exactly the decode of the signals with every
 * pulse shorter than glitch_ns removed from each channel. A dropped pulse is
 * a same-channel X -> Y -> X pair, worth 0 counts net, so real motion loses
 * nothing as long as same-channel edges are >= glitch_ns apart: in steady
 * motion they are 2 x4 counts apart, so the rated speed with the filter is
 * 2e9 / glitch_ns x4 counts/s (minus the encoder's duty-cycle error), and a
 * reversal shorter than glitch_ns (dither) is dropped as a whole: the count
 * after it is unchanged. At a sample the position lacks at most the pending
 * edges younger than glitch_ns (at most one per channel).
 *
 * Scaling and compensation: pos_nm_raw = round(pos * num / den) + offset_nm
 * exactly (no drift at any travel), with nm per count = num / den
 * (cfg.nm_per_count_num / _den); pos_nm = comp_correct(comp, pos_nm_raw,
 * dir) with dir the direction of the last count (the direction of approach).
 * vel_nm_s = vel * num / den rounded.
 *
 * Faults (out.faults, latched until qdec_clear_faults): QDEC_FAULT_*. The
 * position keeps being decoded while a fault is latched.
 *
 * Contexts
 *   qdec_edge(), qdec_index_capture()   edge interrupt (or the simulator's
 *       edge loop). They write only q->e. May preempt the tick.
 *   qdec_sample(), qdec_sample_counter()  tick only. They write q->out and
 *       the tick-private state, and read q->e under its sequence count (a
 *       preempting edge interrupt makes the read retry). qdec_edge() makes
 *       seq odd before its first store to a field the tick snapshots and
 *       even (+2) after its last; an event that changes none of them (A/B
 *       change not counted in x2/x1, or no change, without filter or Z)
 *       stores only e.ab, which the tick does not read without the filter.
 *       With the glitch filter on, qdec_sample() also confirms pending
 *       edges in q->e: the port must not run qdec_edge() concurrently with
 *       it (mask the edge interrupt around qdec_sample, or hold the port's
 *       lock).
 *   qdec_init(), qdec_clear_faults(), qdec_set_offset_nm() tick or main while
 *       the tick is not running for this decoder (init), or tick.
 *   qdec_set_comp()                      any (one pointer store).
 *   q->out                               read in tick context (others copy
 *       under the tick's own publication rules).
 *   Multi-core / threaded ports serialise qdec_edge and qdec_sample with a
 *   lock: the sequence count handles preemption on one core only.
 *
 * Sample cost (edge input, no filter, no vel_cycle: the drive's decoders).
 * qdec_sample takes a short path unless the sample is rare (time not
 * forward, a new illegal transition or index latch, seen as a change of
 * e.rare, which the edge context increments with either: then the
 * reference path, same results): the count difference since the last sample and the
 * last edge's time relative to the sample are 32-bit (|delta| < 2^31, edge
 * within 2^31 ns, as above); the 64-bit position and extended time take one
 * add each; pos_nm one 32x32->64 multiply (|pos| < 2^31, den 1). The
 * sample without a counted edge (nedge unchanged, so count and direction
 * unchanged) keeps the position, pos_nm_raw and the direction as they are
 * and only advances the time, the velocity's idle bound and the
 * compensation (pos_nm re-read through comp_correct: its table may change
 * between samples); qdec_set_offset_nm sends the next sample to the
 * reference path, which rescales. The velocity record of a sample with
 * edges stores the ring entry and counts it in
 * `rec` (the ring rising, vel_fast); ring_n, ring_mono and the pending
 * estimate are brought up to date from the count when they are next read
 * (qdec_velocity, an idle sample, the general record) or every 16 records.
 *
 * No floating point, no heap. Division only in the tick functions, through
 * fixmath (32-bit digits on 32-bit targets): the velocity estimate, and the
 * scaling to nm when nm_per_count_den is not 1.
 */
#ifndef QDEC_H
#define QDEC_H

#include <stdbool.h>
#include <stdint.h>

#include "comp.h"
#include "fixmath.h"

#define QDEC_LINE_A 1u
#define QDEC_LINE_B 2u
#define QDEC_LINE_Z 4u

/* Edge rate the loop-back test proves (x4 counts/s, edge input). */
#define QDEC_RATED_CPS 10000000
/* Largest change per sample that counter extension resolves exactly. */
#define QDEC_MAX_DELTA(bits) ((uint32_t)((1ull << ((bits)-1)) - 1u))

#define QDEC_INDEX_UNGATED 0xFFu /* index_qual: latch on Z alone */

#define QDEC_ILLEGAL_MAX 16u /* largest illegal_limit */

#define QDEC_ZERO_TIMEOUT_DEFAULT_NS 20000000000ull /* 20 s */

#define QDEC_FAULT_ILLEGAL   (1u << 0) /* illegal_limit illegal transitions in the window  */
#define QDEC_FAULT_OVERSPEED (1u << 1) /* change per sample above max_delta: position suspect */
#define QDEC_FAULT_TIME      (1u << 2) /* sample time not after the previous one           */

typedef enum { QDEC_INPUT_EDGES = 0, QDEC_INPUT_COUNTER = 1 } qdec_input_t;

typedef enum { QDEC_X4 = 0, QDEC_X2 = 1, QDEC_X1 = 2 } qdec_mode_t;

typedef struct {
    qdec_input_t input;
    qdec_mode_t mode;           /* edge input: counts per cycle                  */
    uint8_t counter_bits;       /* counter input: 8..32 (16 or 32 in practice)   */
    uint32_t max_delta;         /* overspeed limit per sample, counts; 0: default */
    uint8_t illegal_limit;      /* 0: never fault; 1..QDEC_ILLEGAL_MAX             */
    uint64_t illegal_window_ns; /* window for illegal_limit                       */
    uint32_t glitch_ns;         /* minimum pulse width, 0: filter off (edge input) */
    uint64_t zero_timeout_ns;   /* no edge for this long: velocity 0; 0: default  */
    uint64_t vel_window_ns;     /* velocity window; 0: one sample                 */
    bool vel_cycle;             /* velocity from whole cycles only (see above)    */
    uint8_t index_qual;         /* A/B state 0..3 gating Z, or QDEC_INDEX_UNGATED */
    int32_t nm_per_count_num;   /* scale nm/count = num / den; num != 0 (sign:     */
    int32_t nm_per_count_den;   /*   counting direction vs machine axis), den > 0 */
    pos_nm_t offset_nm;         /* machine position at count 0                    */
    const comp_table_t *comp;   /* compensation table, NULL: identity             */
} qdec_config_t;

/* Edge-context state (written by qdec_edge / qdec_index_capture). */
typedef struct {
    volatile uint32_t seq;        /* +2 per change of snapshot fields, odd during */
    volatile uint32_t count;      /* wrapping count, mode units                  */
    volatile uint32_t nedge;      /* counted edges (wrapping)                    */
    volatile uint32_t t_last;     /* time of the last counted edge, ns           */
    volatile uint32_t cyc_count;  /* count at the last cycle-aligned edge        */
    volatile uint32_t cyc_t;      /* ... its time, ns                            */
    volatile uint32_t ncyc;       /* cycle-aligned edges (wrapping)              */
    volatile int8_t dir;          /* direction of the last counted edge          */
    volatile uint8_t ab;          /* decoded (committed) A/B state               */
    volatile uint8_t z;           /* Z level                                     */
    volatile uint8_t gated;       /* gated index level                           */
    volatile uint32_t illegal;    /* illegal transitions (wrapping)              */
    volatile uint32_t glitches;   /* pulses dropped by the filter (wrapping)     */
    volatile uint32_t idx_events; /* index latches (wrapping)                    */
    volatile uint32_t idx_raw;    /* count (or hardware counter) at the latch    */
    volatile uint32_t idx_t;      /* time of the latch, ns                       */
    volatile int8_t idx_dir;      /* direction at the latch                      */
    uint8_t pend;                 /* glitch filter: pending channels (A/B bits)  */
    uint32_t pend_t[2];           /* glitch filter: time of the pending A, B edge */
    volatile uint32_t rare;       /* illegal + idx_events (wrapping): the short
                                   * sample path checks only this one          */
} qdec_edge_state_t;

/* Outputs, written by the tick functions. */
typedef struct {
    int64_t pos;           /* position, counts (mode units), from 0 at init   */
    q32_32_t vel;          /* velocity, counts/s, q32_32: see qdec_velocity() */
    pos_nm_t pos_nm_raw;   /* scaled position, nm, before compensation         */
    pos_nm_t pos_nm;       /* compensated position, nm (the feedback)          */
    int64_t vel_nm_s;      /* velocity, nm/s: see qdec_velocity()             */
    int8_t dir;            /* direction of the last count (+1/-1; 0: none yet) */
    bool stopped;          /* zero-speed timeout expired                       */
    uint32_t faults;       /* QDEC_FAULT_* latched                             */
    uint32_t illegal;      /* illegal transitions since init (wrapping)        */
    uint32_t glitches;     /* pulses dropped by the glitch filter              */
    uint32_t index_events; /* index latches since init (wrapping)              */
    int64_t index_pos;     /* latched position, counts                         */
    uint32_t index_t_ns;   /* time of the latched index edge                   */
    int8_t index_dir;      /* direction of travel at the latch                 */
} qdec_out_t;

/* Recorded edges for the velocity window: it spans at most RING-1 samples. */
#define QDEC_VEL_RING 16u

typedef struct {
    qdec_config_t cfg;
    qdec_edge_state_t e;
    qdec_out_t out;
    const int8_t *table; /* decode table of cfg.mode (set by init)          */
    /* tick-private */
    uint32_t last_raw; /* raw count (edge or hardware) at the last sample */
    uint32_t last_nedge;
    uint32_t last_ncyc;
    uint32_t last_illegal;
    uint32_t last_idx_events;
    uint32_t max_delta; /* overspeed limit, <= 2^31 - 1 (qdec_init)          */
    uint8_t bits;
    bool nm_fast;     /* nm_per_count_den == 1 and |offset_nm| < 2^62 (init, set_offset) */
    bool fast;        /* edge input, no filter, no vel_cycle: qdec_sample's short path
                       * (set by init; false forces the reference path: tests) */
    uint8_t cyc_mask; /* counts per cycle - 1 (3, 1, 0 for x4, x2, x1)   */
    int64_t now;      /* extended sample time, ns                        */
    uint32_t now_raw;
    int64_t t_edge;                /* extended time of the last counted edge          */
    int64_t ring_p[QDEC_VEL_RING]; /* recorded last edges: position           */
    int64_t ring_t[QDEC_VEL_RING]; /* ... and extended time                   */
    uint32_t rec;                  /* edges recorded (wrapping): the newest at ring[rec % RING] */
    int64_t t_rec;                 /* ring_t[rec % RING], the newest recorded time (with rec) */
    uint32_t rec_norm; /* rec when ring_n, ring_mono and vel_* were last brought up to date */
    uint8_t ring_n;
    bool vel_fast; /* ring_n > 0 and ring_mono + 1 >= ring_n: the short record applies */
    /* velocity evaluated on demand (qdec_velocity): the newest estimate's
     * counts and time (divided when asked) and the idle bound's time */
    bool vel_pending;
    bool vel_lazy;                   /* estimate at ring_head, anchor not searched yet */
    uint8_t ring_mono;               /* ring entries head-ring_mono..head rise strictly */
    int64_t vel_dp, vel_dt;          /* pending estimate: vel_dp counts in vel_dt ns */
    int64_t vel_since;               /* > 0: clamp to 1 count (cycle) / vel_since ns */
    int64_t ill_t[QDEC_ILLEGAL_MAX]; /* times of the last illegal transitions  */
    uint8_t ill_head;
    uint8_t ill_n;
    bool run_ok; /* no filter, x4, no vel_cycle: qdec_edge_run may count (init; in padding) */
    uint32_t last_rare; /* e.rare at the last sample (with last_illegal, last_idx_events) */
} qdec_t;

/* Fill cfg with defaults: edge input, x4, 32-bit, no illegal fault, no
 * filter, default timeout, one-sample window, ungated index, 1 nm/count. */
void qdec_config_default(qdec_config_t *cfg);

/* Validate cfg and start the decoder at position 0. `initial` is the A/B/Z
 * lines (edge input) or the raw counter (counter input); now_ns the clock.
 * Returns false (q untouched) on an invalid configuration: unknown input or
 * mode, counter_bits outside 8..32, illegal_limit > QDEC_ILLEGAL_MAX,
 * index_qual not 0..3 or UNGATED, num == 0 or den <= 0, glitch_ns with
 * counter input, or max_delta > QDEC_MAX_DELTA(bits). */
bool qdec_init(qdec_t *q, const qdec_config_t *cfg, uint32_t initial, uint32_t now_ns);

/* Edge input: new levels (QDEC_LINE_* bits) at time t_ns. Edge context. */
void qdec_edge(qdec_t *q, uint32_t lines, uint32_t t_ns);

/* Edge input: a run of |steps| (1 .. 2^31 - 1) legal x4 edges in one
 * direction (steps > 0: forward), Z low before, during and after it, the
 * last one at t_last_ns. Leaves every field a sample reads (count, nedge,
 * t_last, dir, ab; seq odd, then even) as the |steps| qdec_edge() calls of
 * that run would, whatever their earlier times: with no filter, x4 and no
 * vel_cycle a sample reads only the last counted edge's time. The
 * cycle-aligned fields (cyc_*, ncyc), read only with vel_cycle, are left
 * as they are. Returns false and changes nothing when it cannot stand for
 * the run: steps 0, glitch filter on, mode not x4, vel_cycle, or Z high
 * now; the caller then delivers the edges one by one. For a source that
 * knows the count and the last edge's time without the edges (the
 * simulator's encoder; a timer in encoder mode with a capture of the last
 * edge). Edge context. */
bool qdec_edge_run(qdec_t *q, int32_t steps, uint32_t t_last_ns);

/* Counter input: hardware captured `raw` at the index edge at t_ns. The
 * direction is taken from the last sample. Edge/capture context. */
void qdec_index_capture(qdec_t *q, uint32_t raw, uint32_t t_ns);

/* Once per tick. Edge input: */
void qdec_sample(qdec_t *q, uint32_t now_ns);
/* Counter input, with the counter snapshot taken at now_ns: */
void qdec_sample_counter(qdec_t *q, uint32_t raw, uint32_t now_ns);

/* The velocity estimate as of the last sample (see Velocity above), q32_32
 * counts/s; also brings out.vel and out.vel_nm_s up to date. The samples
 * only record the estimate's inputs (the division is done here, on demand:
 * nothing in the tick reads it), so out.vel / out.vel_nm_s are valid only
 * after this call. Tick context (or main while the tick is not running). */
q32_32_t qdec_velocity(qdec_t *q);

/* Clear latched faults (the illegal-window history too). Tick. */
void qdec_clear_faults(qdec_t *q);

/* Machine position at count 0 (homing). Applies from the next sample. Tick. */
void qdec_set_offset_nm(qdec_t *q, pos_nm_t offset_nm);

/* Install or remove (NULL) the compensation table. Any context. */
void qdec_set_comp(qdec_t *q, const comp_table_t *comp);

/* Scale a count value with this decoder's scale and offset (no comp):
 * round(counts * num / den) + offset_nm, saturated. Pure.
 * qdec_counts_to_nm_any is the general form (64-bit division when den != 1);
 * the inline one takes the tick's usual case, den == 1, |counts| < 2^31
 * and |offset_nm| < 2^62, with one 32x32->64 multiply (|counts * num| <=
 * 2^62, so the sum cannot overflow): the same result. */
pos_nm_t qdec_counts_to_nm_any(const qdec_t *q, int64_t counts);

/* |delta| > max_delta, for max_delta <= 2^31 - 1 (fx_in_range32's one add
 * and one unsigned compare). */
static inline bool qdec_overspeed(int32_t delta, uint32_t max_delta)
{
    return !fx_in_range32(delta, max_delta);
}

static inline pos_nm_t qdec_counts_to_nm(const qdec_t *q, int64_t counts)
{
    /* nm_fast: den == 1 and |offset_nm| < 2^62, kept by qdec_init and
     * qdec_set_offset_nm (the only writers of the scale and offset) */
    if (q->nm_fast && counts == (int64_t)(int32_t)counts) {
        return (int64_t)(int32_t)counts * (int64_t)q->cfg.nm_per_count_num + q->cfg.offset_nm;
    }
    return qdec_counts_to_nm_any(q, counts);
}

#endif /* QDEC_H */
