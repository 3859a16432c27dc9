/*
 * qgen.h - quadrature generator: turns a position trajectory in encoder
 * counts into A/B(/Z) edge events with nanosecond timestamps.
 *
 * Specification
 * -------------
 * The simulator feeds the firmware's decoder (qdec.h) with it, and the unit
 * tests use the same generator for the decoder's loop-back tests.
 *
 * Position: qgen_pos_t, counts (x4: one count per A/B state change) with
 * QGEN_FRAC_BITS fraction bits (int64: +-2^39 counts, resolution 6e-8
 * counts). The count is floor(x); the boundary between count c-1 and c lies
 * at x = c (plus the optional edge offset, qgen_set_edge_offsets). QGEN_COUNTS(n) converts whole
 * counts. Levels: QDEC_LINE_A (bit 0), QDEC_LINE_B (bit 1), QDEC_LINE_Z (bit 2), with A/B = {0, A,
 * A|B, B}[count mod 4] (forward = A leading B, as qdec decodes +1). Z is high for the counts c with
 * (c - index_pos) mod period in
 * [-before, after] (period 0: one index), changing in the same event as the
 * A/B change into / out of that window.
 *
 * Time: uint64_t nanoseconds inside, emitted as the low 32 bits (the
 * decoder's wrapping timestamp). Events are emitted in time order as long as
 * the caller's times do not go backwards.
 *
 * qgen_move_to(g, x1, t1): straight-line motion from the current (x, t) to
 * (x1, t1); each crossed boundary emits one event, at the crossing time
 * t + (boundary - x) * (t1 - t) / (x1 - x) rounded down to the ns (t1 == t:
 * all at t). A trajectory is a sequence of such calls (e.g. one per
 * simulator step). Crossings are exact integer arithmetic: the same
 * trajectory always gives the same events.
 *
 * Fault injection (for tests; not physical motion, the position is
 * unchanged afterwards):
 *   qgen_illegal(g, t, gap): A and B both flip at t and flip back at t + gap:
 *     two illegal transitions, counted in g->illegal.
 *   qgen_glitch(g, line, t, width): one pulse of `width` ns on A or B:
 *     two legal edges that cancel (x4 net 0), counted in g->glitches.
 *
 * No heap; uses 128-bit integer arithmetic (GCC/Clang) for crossing times
 * when 64 bits may not suffice. Cost: at most two divisions per
 * qgen_move_to (the first crossing and the time per count), then each further
 * crossing time is stepped by addition with exact remainder bookkeeping, so
 * the times equal the formula above to the ns (one division per edge only
 * with edge offsets). On the fast path (no edge offsets, no index, |x| <
 * 2^61, steps < 2^38 ns) the per-event loop keeps its state in locals and
 * brings count, lines, edges and last_edge_t up to date when qgen_move_to
 * returns: the callback gets the lines and the time and must not read or
 * change the generator. With a run callback (qgen_set_run) a move whose
 * events all have Z low costs one division and one call, whatever the
 * number of events; the index window is found from a cached range of
 * counts with Z low, not a modulo per event.
 */
#ifndef QGEN_H
#define QGEN_H

#include <stdbool.h>
#include <stdint.h>

#include "qdec.h"

#define QGEN_FRAC_BITS 24
#define QGEN_ONE       ((qgen_pos_t)1 << QGEN_FRAC_BITS)
#define QGEN_COUNTS(n) ((qgen_pos_t)(n)*QGEN_ONE)

typedef int64_t qgen_pos_t;

/* Receives each event: the new lines and the time (low 32 bits of ns). */
typedef void (*qgen_emit_fn)(void *ctx, uint32_t lines, uint32_t t_ns);

/* Receives a whole move as one run (qgen_set_run): steps (+-n) A/B events
 * in one direction with Z low throughout, the last at t_last_ns (low 32
 * bits); returns false to have them emitted one by one instead. */
typedef bool (*qgen_run_fn)(void *ctx, int32_t steps, uint32_t t_last_ns);

typedef struct {
    qgen_pos_t x;   /* current position                               */
    uint64_t t;     /* current time, ns                                */
    int64_t count;  /* floor(x)                                        */
    uint32_t lines; /* current levels                                  */
    qgen_emit_fn emit;
    void *ctx;
    bool has_index;
    int64_t index_pos;
    uint64_t index_period;
    uint32_t z_before, z_after;
    uint64_t edges;         /* A/B events emitted by motion                  */
    uint64_t run_edges;     /* of edges, those in runs taken (qgen_set_run)  */
    uint64_t illegal;       /* illegal transitions injected                  */
    uint64_t glitches;      /* pulses injected                               */
    uint64_t last_edge_t;   /* time of the last event emitted, ns          */
    qgen_pos_t edge_off[4]; /* edge placement errors (qgen_set_edge_offsets) */
    bool has_off;           /* internal: an edge_off is not 0               */
    /* internal (fast path): time per count of the current move, quotient + 1,
     * remainder - divisor (mod 2^64) and divisor */
    uint64_t step_q1, step_r1, step_den;
    qgen_run_fn run; /* qgen_set_run; NULL: every event through emit     */
    /* internal: counts z_lo..z_hi all have Z low (a cache: recomputed when
     * the count is outside it; z_lo > z_hi: Z high at the count) */
    int64_t z_lo, z_hi;
    /* internal: x, t and count before a run handed to the callback */
    qgen_pos_t undo_x;
    uint64_t undo_t;
    int64_t undo_count;
} qgen_t;

/* Start at position x0, time t0, no index. Emits nothing. */
void qgen_init(qgen_t *g, qgen_pos_t x0, uint64_t t0_ns, qgen_emit_fn emit, void *ctx);

/* Index pulse around count index_pos, repeating every period counts
 * (0: once); Z high from index_pos - before to index_pos + after inclusive.
 * Updates the current levels without emitting. */
void qgen_set_index(qgen_t *g, int64_t index_pos, uint64_t period, uint32_t before, uint32_t after);

/* Current levels (e.g. the initial state for qdec_init). */
uint32_t qgen_lines(const qgen_t *g);

/* Levels at count c (A/B and Z). */
uint32_t qgen_lines_at(const qgen_t *g, int64_t c);

/* Edge placement errors, as real encoders have (quadrature phase error,
 * duty cycle): the boundary into count c lies at c + off[c mod 4] instead of
 * c, |off| < 1/2 count. Default all 0 (ideal). Call before moving; it
 * re-derives the current count without emitting. False (nothing changed)
 * when an offset is out of range. */
bool qgen_set_edge_offsets(qgen_t *g, const qgen_pos_t off[4]);

/* Whole moves as runs: a move on the fast path (no edge offsets) whose
 * events all have Z low and number at most 2^31 - 1 goes to run(ctx,
 * steps, t_last) instead of emit, with t_last the time the per-event path
 * would give its last event (the same formula, one division); count,
 * lines, edges and last_edge_t end as after the events. NULL: off. */
void qgen_set_run(qgen_t *g, qgen_run_fn run);

/* Move to x1 arriving at t1_ns (>= current time; earlier is taken as the
 * current time). Returns the number of events emitted. Inline: a move to
 * the same position only advances the time (qgen_move_changed: the rest). */
uint64_t qgen_move_changed(qgen_t *g, qgen_pos_t x1, uint64_t t1_ns);

static inline uint64_t qgen_move_to(qgen_t *g, qgen_pos_t x1, uint64_t t1_ns)
{
    if (x1 == g->x) {
        if (t1_ns > g->t) {
            g->t = t1_ns;
        }
        return 0u;
    }
    return qgen_move_changed(g, x1, t1_ns);
}

/* Inject a pair of illegal transitions at t_ns and t_ns + gap_ns. */
void qgen_illegal(qgen_t *g, uint64_t t_ns, uint32_t gap_ns);

/* Inject a pulse of width_ns on line QDEC_LINE_A or QDEC_LINE_B at t_ns. */
void qgen_glitch(qgen_t *g, uint32_t line, uint64_t t_ns, uint32_t width_ns);

#endif /* QGEN_H */
