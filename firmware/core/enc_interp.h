/*
 * enc_interp.h - an encoder's position below the count, from the times of
 * its edges (issue 21: the measurement near an axis reversal).
 *
 * Specification
 * -------------
 * Counts are centred: count n stands for the positions [n - 1/2, n + 1/2)
 * (in counts), so an edge lies half a count from the count on either side
 * of it. The decoder (qdec.h, edge input) gives at each sample its count
 * n, its counted edges (nedge, wrapping), the direction of the last one
 * and that edge's time t_edge (ns, qdec's extended clock): a counted edge
 * is an exact point of the trajectory, (n - dir / 2, t_edge), in half
 * counts 2 n - dir. One event is kept per sample that saw counted edges
 * (its last edge; the ones before it in the same sample are not timed),
 * the newest three (enc_interp_step).
 *
 * The estimate is the quadratic through the three events (Lagrange form,
 * relative to the newest one):
 *   x(t) = E2 + e1 L1(u) + e0 L0(u),  u = t - T2, e_i = E_i - E2,
 *   L1 = u (u - d0) / (d1 (d1 - d0)),  L0 = u (u - d1) / (d0 (d0 - d1)),
 *   d_i = T_i - T2 (< 0),
 * which is exact for motion of constant acceleration: a decelerating
 * approach, and the reversal itself, where the same edge is crossed back
 * (events E, E at T1 < T2: the axis went past E by a (T2 - T1)^2 / 8 and
 * returned; with the edge before, E -+ 1 at T0, the three fix a, the peak
 * and the velocity -v at T2, and the quadratic follows the axis to the
 * next edge). Two events (the start, or the oldest too old): the line
 * through them. None, or no event within ENC_INTERP_SPAN_NS: the count
 * itself. The mean over a window W ending at the sample (enc_mean's tick,
 * drive.h) is the quadratic's exact mean, its value at the window's centre
 * m plus W^2 / 12 in each product: (m - a)(m - b) + W^2 / 12; W = 0 gives
 * the position at the sample.
 *
 * Held inside what the counts prove: the estimate is clamped to the cells
 * the axis can have been in, with W = 0 the count's own interval
 * [n - 1/2, n + 1/2]; with W > 0 the cells from the count at the previous
 * sample to n, widened by one cell per two counted edges that do not show
 * in the count difference (a return within the window). So
 *   |error| <= 1 count always (the count alone: 1/2), and, for a
 *   trajectory x with |x'''| <= J over [T0, t] and exact edge times,
 *   |error| <= J |u (u - d1) (u - d0)| / 6 (the interpolation remainder;
 *   0 at constant acceleration) plus the timestamps' resolution times the
 *   velocity (1 ns: 1e-9 v), before the clamp, which only reduces it.
 * Edge placement errors e (a fraction of a count: quadrature phase, duty
 * cycle) enter as e times sum |L_i| (<= 3 while u lies between the oldest
 * event and a span past the newest equal to the events' spacing).
 *
 * Fixed point: positions in half counts (int64), times in ns (int64);
 * the result in 2^-16 counts relative to n, two exact-rounding 128-bit
 * multiply-divides (fx_muldiv64) per quadratic; the span limit keeps every
 * time product below 2^54. Every counted edge moves the event ring; a
 * sample without a counted edge only evaluates.
 *
 * Context: tick (drive_inputs_sample); state private to it.
 */
#ifndef ENC_INTERP_H
#define ENC_INTERP_H

#include <stdbool.h>
#include <stdint.h>

/* Oldest event used, ns before the sample: beyond it the estimate uses
 * fewer events (2^26 ns, 67 ms: an axis that long inside one count is as
 * good as stopped; the products stay below 2^54). */
#define ENC_INTERP_SPAN_NS (1ll << 26)

typedef struct {
    int64_t e[3];   /* events, half counts (2 n - dir), [2] the newest  */
    int64_t t[3];   /* their times, ns (the decoder's extended clock)  */
    uint8_t n;      /* events held, 0..3                               */
    int64_t pos;    /* count at the last sample                        */
    uint32_t nedge; /* counted edges at the last sample (wrapping)     */
} enc_interp_t;

/* Start with no event at count pos, nedge counted edges. */
void enc_interp_reset(enc_interp_t *s, int64_t pos, uint32_t nedge);

/* One sample at now_ns with the decoder's count pos, counted edges nedge,
 * the last edge's direction dir (+1 / -1) and time t_edge_ns: records the
 * event when nedge changed, and returns the estimated position (mean over
 * the window_ns before now_ns; 0: at now_ns) minus pos, in 2^-16 counts,
 * clamped as above (within [-2^15, 2^15] when window_ns is 0). */
int64_t enc_interp_step(enc_interp_t *s, int64_t pos, uint32_t nedge, int8_t dir,
                        int64_t t_edge_ns, int64_t now_ns, uint32_t window_ns);

#endif /* ENC_INTERP_H */
