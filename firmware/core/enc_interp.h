/*
 * enc_interp.h - an encoder's position below the count, from the times of
 * its edges (issue 21: the measurement near an axis reversal).
 *
 * Specification
 * -------------
 * Counts are centred: count n stands for the positions [n - 1/2, n + 1/2)
 * (counts), so each edge lies half a count from the counts on either side
 * of it. The decoder (qdec.h, edge input) gives at each sample its count
 * n, its counted edges (nedge, wrapping), the direction of the last one
 * and that edge's time t_edge (ns, qdec's extended clock, the one of the
 * sample times): a counted edge is an exact point of the trajectory,
 * (n - dir / 2, t_edge), 2 n - dir in half counts. enc_interp_update
 * keeps one such event per sample that saw counted edges (its last edge:
 * the ones before it in the same sample are not timed), the newest
 * ENC_INTERP_EVENTS (16).
 *
 * The model is the quadratic through three of them (Lagrange form,
 * relative to the newest one, E2 at T2):
 *   x(t) = E2 + e1 L1(u) + e0 L0(u),  u = t - T2,  e_i = E_i - E2,
 *   L1 = u (u - d0) / (d1 (d1 - d0)),  L0 = u (u - d1) / (d0 (d0 - d1)),
 *   d_i = T_i - T2 (< 0),
 * exact for motion of constant acceleration: a decelerating approach and
 * the reversal itself, where the same edge is crossed back (events E, E at
 * T1 < T2: the axis went a (T2 - T1)^2 / 8 past E and returned; with the
 * edge before, E -+ 1 at T0, the three fix a, the peak and the velocity
 * at T2, and the quadratic follows the axis to its next edge, which is
 * where the count alone says nothing for longest). Two events (the start,
 * or the third newest more than ENC_INTERP_SPAN_NS before the sample):
 * the line through them. Fewer: nothing below the count (the count
 * itself).
 *
 * What the edges prove, and for how long (issue 21, slow reversals):
 * the events fix the axis at their times; after the newest, only the
 * cell (no edge since: the axis has not left the count's cell, which
 * holds every estimate) and, through the fit, the curve's continuation.
 * An extrapolation u past the newest event amplifies an error p of the
 * events (edge placement, or a motion that departs from the quadratic:
 * a ripple of the loop) by L(u) = |L1| + |L0| + |1 - L1 - L0|, which for
 * nodes spanning S grows as (u / S)^2: with the newest three alone (4-14
 * ms apart near a reversal at 2 m/min) and u up to 27 ms, more than 15
 * (a 0.01-count ripple at 30 Hz read 0.17 count off). So the nodes are
 * chosen: E2 the newest; E0 the newest kept event at least
 * ENC_INTERP_REACH (2) u before it (u = t - T2 of the estimate), else the
 * oldest kept one within the span; E1 the kept event nearest the middle
 * of T0 and T2 (the third and second newest where they reach: every
 * moving axis, an edge per tick or more, is fitted as before). With the
 * reach met and equally spaced nodes L <= 7 (u = S / 2); beyond what
 * the kept events reach (an axis inside its count for longer than half
 * the time its kept events span) the error grows again, held by the
 * cell. Measured (Unity test_enc_interp, R 100 mm 2 m/min reversal, 8889
 * counts/s^2, 0.01-count ripple at 30 Hz, eight phases): worst 0.083
 * count at a sample and in the tick's mean (0.078 where the reach is
 * met), against 0.173 with the newest three (0.141 with 8 kept).
 *
 * enc_interp_pos: the model at the sample, held inside the count's cell,
 * [-1/2, +1/2] count from n.
 * enc_interp_mean_residual, for a drive that reads the count's mean over
 * the tick (hal_encoder_mean, drive.h enc_mean): what that mean misses,
 * the mean over the tick of y - round(y) (round: the centred count), y
 * the piecewise line from the model at the previous sample (held inside
 * that sample's cell, [n - 1/2, n + 1/2 - 2^-16]: at n + 1/2 round()
 * would read the next count, a whole count off) through the tick's last edge, when the tick has
 * one (exact), to the model at this sample (inside this one's cell),
 * evaluated exactly (the integral of the centred count along a line in
 * closed form, one division per segment that crosses an edge). The
 * count's mean plus it is the mean of the position: where the axis
 * crosses many counts in a tick the sawtooth averages out and the count's
 * mean stands (its boxcar, which removes what the sample would alias, is
 * kept); where it crosses none, near a reversal, it is the model's mean
 * position in the count. 0 after a return within the tick (more edges
 * than the count moved: no line stands for it).
 *
 * Error bounds (counts; exact edge times; x the true position, J the
 * largest |x'''| over [T0, t], T the tick):
 *   enc_interp_pos: |error| <= 1 always (held in the cell; the count
 *     alone: 1/2), and <= J |u (u - d1) (u - d0)| / 6 (the interpolation
 *     remainder: 0 at constant acceleration), which the hold only reduces;
 *   enc_interp_mean_residual, added to the count's exact mean: the
 *     sawtooth's mean along y instead of x. Where both lie in one cell
 *     they differ by x - y: the bound above at the two samples plus
 *     |x''| T^2 / 8 between the knots (R 50 mm, 10 m/min at 10 kHz:
 *     0.56 m/s^2, 5.6e-4 counts of 1.25 um; in the mean T^2 / 12). The
 *     tick's last edge is a knot, so with at most one edge in the tick
 *     the cells agree; each earlier edge of a tick moves its crossing by
 *     |x - y| / |v| and adds |x - y| / (|v| T), below |x - y| since such
 *     a tick crosses more than a count. Always within 1/2, also when the
 *     tick's last edge is stamped after the sample (qdec.h allows edges
 *     after the sample's time read): the knot is then taken at the
 *     sample. 0 when the count moved more than ENC_INTERP_MOVE_MAX in
 *     the tick.
 * Timestamps of resolution r add |v| r (1 ns); edge placement errors p (a
 * fraction of a count: quadrature phase, duty cycle) add p times
 * |L1| + |L0| + |1 - L1 - L0| (equally spaced events: 1 at an event, 3.5
 * half a spacing past the newest, 7 a whole spacing past it). An axis
 * that stops inside a cell is extrapolated for up to ENC_INTERP_SPAN_NS
 * (the model turns it back to a cell edge, held there: within the first
 * bound), then it is the count.
 *
 * Fixed point: positions in half counts (int64), times in ns (int64),
 * results in 2^-16 counts relative to n; each Lagrange term is
 * round(e 2^15 a / c) exactly as fx_muldiv64 rounds (ties away from zero;
 * enc_interp_muldiv, tested against it), the span keeping every time
 * product below 2^54. Where |e| < 2^16, |e a| < 2^48, |c| < 2^56 and the
 * quotient is below 2^32 (the usual operands: a few counts between
 * events within a few ms), the quotient is estimated without a long
 * division: c
 * normalised to 32 bits, 2^63 / c from a 16-bit hardware quotient and one
 * Newton step (relative error < 2^-28), the estimate within [q - 15,
 * q + 2], then corrected on the exact 64-bit remainder; elsewhere
 * fx_muldiv64 (128-bit). The sawtooth's integral is exact while a tick
 * moves less than 2^23 counts. No floating point, no heap.
 * Cost on the Cortex-M4 (bash bench/bench-firmware.sh: the helix of three
 * axes at 5 kHz with enc_interp on, enc_interp_update + enc_interp_pos
 * per axis and tick, X and Y with an edge in most ticks):
 * control_tick_instructions_m4_interp 3089 against 1483 without (2907
 * with the newest three events only, 3787 with two fx_muldiv64 per
 * quadratic), about 535 per axis; the worst tick
 * (control_tick_instructions_m4_max_interp) 6000 against 5840 with the
 * newest three: a slow axis walks the ring for its nodes and its wider
 * time products take fx_muldiv64's 128-bit path. Measured (2907 figures)
 * apart on typical operands (three events 200 us apart, 3 counts each):
 * enc_interp_pos about 360 (the two quotients about 100 each, the rest
 * the 64-bit times and positions), enc_interp_update about 90 with an
 * edge; the rest of the 475 is the out-of-line sample and the lag's
 * scaling (drive_inputs.c).
 *
 * Context: tick (drive_inputs_sample_slow); the state is the tick's.
 */
#ifndef ENC_INTERP_H
#define ENC_INTERP_H

#include <stdbool.h>
#include <stdint.h>

/* Oldest event used, ns before the sample: beyond it the estimate uses
 * fewer events (2^26 ns, 67 ms: an axis that long inside one count is as
 * good as stopped; the products stay below 2^54). */
#define ENC_INTERP_SPAN_NS (1ll << 26)

/* Largest move between two samples, counts, for which
 * enc_interp_mean_residual evaluates the sawtooth (beyond it the result is
 * 0: along a line across N cells its mean is at most 1 / (8 N) counts,
 * below the result's 2^-16 from N = 2^13 on; the integral's int64 terms
 * hold up to 2^23). The decoder itself accepts up to 2^30 - 1 per sample. */
#define ENC_INTERP_MOVE_MAX (1ll << 23)

/* Events kept (a power of two), the newest last: the fit's oldest node
 * is chosen among them (enc_interp_pos). */
#define ENC_INTERP_EVENTS 16u

/* The fit's reach: its oldest node at least this many times the
 * extrapolation (the time from the newest event to the estimate) before
 * the newest, where the kept events allow. */
#define ENC_INTERP_REACH 2

typedef struct {
    int64_t e[ENC_INTERP_EVENTS]; /* events, half counts (2 n - dir), a ring */
    int64_t t[ENC_INTERP_EVENTS]; /* their times, ns (the decoder's clock)   */
    uint8_t n;                    /* events held, 0..ENC_INTERP_EVENTS       */
    uint8_t head;                 /* index of the newest                     */
    bool edged;                   /* the last sample saw counted edges               */
    bool back;                    /* ... more than its count moved: back and forth    */
    int64_t pos;                  /* count at the last sample                        */
    int64_t prev;                 /* count at the sample before                      */
    uint32_t nedge;               /* counted edges at the last sample (wrapping)     */
} enc_interp_t;

/* Start with no event at count pos, nedge counted edges. */
void enc_interp_reset(enc_interp_t *s, int64_t pos, uint32_t nedge);

/* Once per sample, after the decoder's: its count pos, counted edges
 * nedge, the last edge's direction dir (+1 / -1) and time t_edge_ns;
 * records the event when nedge changed. */
void enc_interp_update(enc_interp_t *s, int64_t pos, uint32_t nedge, int8_t dir, int64_t t_edge_ns);

/* The position at the sample now_ns minus the count, 2^-16 counts, in
 * [-2^15, 2^15] (0 without two events in the span). */
int64_t enc_interp_pos(const enc_interp_t *s, int64_t now_ns);

/* What the count's mean over the tick (tick_ns ending at the sample
 * now_ns, the previous sample at its start) misses: the mean of
 * y - round(y) along the line from the estimate at the previous sample
 * through the tick's last edge to the one at this sample (each held in
 * its sample's count), 2^-16 counts, within [-2^15, 2^15]; 0 without two
 * events in the span or after a return within the tick. */
int64_t enc_interp_mean_residual(const enc_interp_t *s, int64_t now_ns, uint32_t tick_ns);

/* fx_muldiv64(e 2^15, ab, c), the same result for every argument: the
 * model's Lagrange terms (e half counts, ab the time product, c the
 * events' one), with a 64/32 long division (fx_udiv64by32) and an exact
 * remainder correction where |e| < 2^16, |e ab| < 2^48, |c| < 2^60 and
 * the quotient is below 2^32; fx_muldiv64 otherwise. Pure. */
int64_t enc_interp_muldiv(int64_t e, int64_t ab, int64_t c);

#endif /* ENC_INTERP_H */
