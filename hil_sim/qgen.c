/* qgen.c - quadrature generator (specification in qgen.h). */
#include "qgen.h"

#include <stddef.h>

__extension__ typedef __int128 qgen_i128;
__extension__ typedef unsigned __int128 qgen_u128;

static const uint32_t qgen_ab[4] = {0u, QDEC_LINE_A, QDEC_LINE_A | QDEC_LINE_B, QDEC_LINE_B};

static int64_t qgen_floor_count(qgen_pos_t x)
{
    return x >> QGEN_FRAC_BITS; /* arithmetic shift: floor */
}

uint32_t qgen_lines_at(const qgen_t *g, int64_t c)
{
    uint32_t lines = qgen_ab[(uint64_t)c & 3u];

    if (g->has_index) {
        int64_t d = c - g->index_pos + (int64_t)g->z_before;
        int64_t w = (int64_t)g->z_before + (int64_t)g->z_after;
        if (g->index_period != 0u) {
            int64_t p = (int64_t)g->index_period;
            d %= p;
            if (d < 0) {
                d += p;
            }
        }
        if (d >= 0 && d <= w) {
            lines |= QDEC_LINE_Z;
        }
    }
    return lines;
}

/* The counts around g->count with Z low, as z_lo..z_hi (empty, z_lo >
 * z_hi, when Z is high at the count): one modulo, then two compares per
 * move while the count stays inside. */
static void qgen_z_span(qgen_t *g)
{
    int64_t c = g->count, d, w;

    g->z_lo = INT64_MIN;
    g->z_hi = INT64_MAX;
    if (!g->has_index) {
        return;
    }
    d = c - g->index_pos + (int64_t)g->z_before; /* as qgen_lines_at */
    w = (int64_t)g->z_before + (int64_t)g->z_after;
    if (g->index_period != 0u) {
        int64_t p = (int64_t)g->index_period;
        d %= p;
        if (d < 0) {
            d += p;
        }
    }
    if (d >= 0 && d <= w) {
        g->z_lo = INT64_MAX;
        g->z_hi = INT64_MIN;
        return;
    }
    if (g->index_period != 0u) {
        /* d in (w, p): the windows at c - (d - w) and c + (p - d) */
        g->z_lo = c - (d - w) + 1;
        g->z_hi = c + ((int64_t)g->index_period - d) - 1;
    } else if (d < 0) {
        g->z_hi = c - d - 1;
    } else {
        g->z_lo = c - (d - w) + 1;
    }
}

static bool qgen_z_low(const qgen_t *g, int64_t c)
{
    return c >= g->z_lo && c <= g->z_hi;
}

uint32_t qgen_lines(const qgen_t *g)
{
    return g->lines;
}

void qgen_init(qgen_t *g, qgen_pos_t x0, uint64_t t0_ns, qgen_emit_fn emit, void *ctx)
{
    *g = (qgen_t){0};
    g->x = x0;
    g->t = t0_ns;
    g->count = qgen_floor_count(x0);
    g->emit = emit;
    g->ctx = ctx;
    g->lines = qgen_lines_at(g, g->count);
    g->last_edge_t = t0_ns;
    qgen_z_span(g);
}

void qgen_set_run(qgen_t *g, qgen_run_fn run)
{
    g->run = run;
}

void qgen_set_index(qgen_t *g, int64_t index_pos, uint64_t period, uint32_t before, uint32_t after)
{
    g->has_index = true;
    g->index_pos = index_pos;
    g->index_period = period;
    g->z_before = before;
    g->z_after = after;
    g->lines = qgen_lines_at(g, g->count);
    qgen_z_span(g);
}

static void qgen_emit(qgen_t *g, uint32_t lines, uint64_t t)
{
    g->lines = lines;
    g->last_edge_t = t;
    if (g->emit != NULL) {
        g->emit(g->ctx, lines, (uint32_t)t);
    }
}

/* Position of the boundary between count b-1 and count b. */
static qgen_i128 qgen_boundary(const qgen_t *g, int64_t b)
{
    return (qgen_i128)b * QGEN_ONE + g->edge_off[(uint64_t)b & 3u];
}

/* floor(x) moved by the edge offsets: the largest b with boundary(b) <= x. */
static int64_t qgen_count_of(const qgen_t *g, qgen_pos_t x)
{
    int64_t c = qgen_floor_count(x);

    if ((qgen_i128)x < qgen_boundary(g, c)) {
        c--;
    } else if ((qgen_i128)x >= qgen_boundary(g, c + 1)) {
        c++;
    }
    return c;
}

bool qgen_set_edge_offsets(qgen_t *g, const qgen_pos_t off[4])
{
    unsigned i;

    for (i = 0; i < 4u; i++) {
        if (off[i] <= -QGEN_ONE / 2 || off[i] >= QGEN_ONE / 2) {
            return false;
        }
    }
    g->has_off = false;
    for (i = 0; i < 4u; i++) {
        g->edge_off[i] = off[i];
        g->has_off = g->has_off || off[i] != 0;
    }
    g->count = qgen_count_of(g, g->x);
    g->lines = qgen_lines_at(g, g->count);
    return true;
}

/* Quotient and remainder of num / den, with a 64-bit division when both fit. */
static void qgen_divmod(qgen_u128 num, qgen_u128 den, qgen_u128 *q, qgen_u128 *r)
{
    if ((num >> 64) == 0u && (den >> 64) == 0u) {
        uint64_t n64 = (uint64_t)num;
        uint64_t d64 = (uint64_t)den;
        *q = n64 / d64;
        *r = n64 % d64;
    } else {
        *q = num / den;
        *r = num % den;
    }
}

/*
 * The crossing time of boundary b is t0 + floor(|b - x0| * dt / |dx|) (the
 * boundaries lie between x0 and x1, so the signs agree and truncation is the
 * floor). Rather than divide per edge, keep that quotient and its remainder
 * and step both by |b' - b| * dt per boundary (one count: a quotient and
 * remainder computed once per move), carrying the remainder into the quotient
 * when it reaches |dx|. Same integers as the direct division, exactly.
 */

/* The crossing-time stepper of the fast path: t is the current crossing
 * time, rem its remainder (< den); each step adds one count's worth. */
typedef struct {
    uint64_t t, rem, q1, r1, den;
} qgen_edge_step_t;

static inline void qgen_step(uint64_t *t, uint64_t *rem, const qgen_edge_step_t *st)
{
    uint64_t r = *rem + st->r1;
    uint64_t carry = (uint64_t)(r >= st->den);

    *rem = r - (st->den & (0u - carry));
    *t += st->q1 + carry;
}

/* n events from count c + inc on; st->t ends as the last event's time.
 * Returns the last count (mod 2^32). The time and remainder stay in locals,
 * the per-count constants are read from the generator on each event (memory
 * operands rather than registers spilled around the callback); count, lines
 * and the counters are written back by the caller (the callback must not
 * read the generator). */
static inline uint32_t qgen_run_ideal(qgen_t *g, uint32_t c, uint32_t inc, uint64_t n,
                                      qgen_edge_step_t *st)
{
    uint64_t t = st->t, rem = st->rem, k;

    /* rem + r1 >= den as the sign of rem + r1 - den (|.| < den < 2^62; two's
     * complement and arithmetic shift, GCC/Clang as the rest of this file):
     * m = -1 (no carry) or 0 (carry) */
    g->step_q1 = st->q1 + 1u;
    g->step_r1 = st->r1 - st->den;
    g->step_den = st->den;
    c += inc;
    g->emit(g->ctx, qgen_ab[c & 3u], (uint32_t)t);
    for (k = n - 1u; k > 0u; k--) {
        uint64_t r = rem + g->step_r1;
        uint64_t m = (uint64_t)((int64_t)r >> 63);

        rem = r + (g->step_den & m);
        t += g->step_q1 + m;
        c += inc;
        g->emit(g->ctx, qgen_ab[c & 3u], (uint32_t)t);
    }
    st->t = t;
    return c;
}

/* Fast path: ideal edges (no offsets), |x0|, |x1| < 2^61 and dt < 2^38 ns, so
 * every product and sum fits in 64 bits; boundary b lies at b * QGEN_ONE.
 * (Both shifted positions below 2^62, a power of two: their OR is.) */
static bool qgen_fast_ok(const qgen_t *g, qgen_pos_t x1, uint64_t dt)
{
    const uint64_t lim = (uint64_t)1 << 61;

    return dt < ((uint64_t)1 << 38) && (((uint64_t)g->x + lim) | ((uint64_t)x1 + lim)) < 2u * lim &&
           !g->has_off;
}

/* The fast path's set-up for a move to x1 (x1 != x) over dt: the number of
 * events, the first crossing time and the stepper. */
static uint64_t qgen_ideal_setup(const qgen_t *g, qgen_pos_t x1, uint64_t dt, qgen_edge_step_t *st)
{
    qgen_pos_t x0 = g->x;
    bool fwd = x1 > x0;
    uint64_t den = fwd ? (uint64_t)(x1 - x0) : (uint64_t)(x0 - x1);
    uint64_t frac = (uint64_t)x0 & (uint64_t)(QGEN_ONE - 1);
    int64_t c1 = qgen_floor_count(x1);
    uint64_t n = fwd ? (uint64_t)(c1 - g->count) : (uint64_t)(g->count - c1);
    uint64_t num;

    if (n == 0u) {
        return 0u;
    }
    num = (fwd ? (uint64_t)QGEN_ONE - frac : frac) * dt;
    st->t = g->t + num / den; /* the first crossing */
    st->rem = num % den;
    st->den = den;
    st->q1 = 0u;
    st->r1 = 0u;
    if (n > 1u) {
        st->q1 = ((uint64_t)QGEN_ONE * dt) / den;
        st->r1 = ((uint64_t)QGEN_ONE * dt) % den;
    }
    return n;
}

/* The fast path with the callback. Without an index window, the loop keeps
 * everything in locals and writes the generator's fields back once at the
 * end (the callback must not read them; it gets the lines and the time). */
static uint64_t qgen_move_ideal(qgen_t *g, qgen_pos_t x1, uint64_t dt)
{
    qgen_edge_step_t st;
    uint64_t n, k, t, rem;
    bool fwd = x1 > g->x;

    n = qgen_ideal_setup(g, x1, dt, &st);
    if (n == 0u) {
        return 0u;
    }
    if (!g->has_index && g->emit != NULL) {
        uint32_t c = (uint32_t)(uint64_t)g->count; /* only c mod 4 matters here */

        c = fwd ? qgen_run_ideal(g, c, 1u, n, &st) : qgen_run_ideal(g, c, 0xFFFFFFFFu, n, &st);
        g->count += fwd ? (int64_t)n : -(int64_t)n;
        g->lines = qgen_ab[c & 3u];
        g->last_edge_t = st.t;
        g->edges += n;
        return n;
    }
    t = st.t;
    rem = st.rem;
    if (g->has_index && !qgen_z_low(g, g->count)) {
        qgen_z_span(g);
    }
    for (k = n; k > 0u; k--) {
        int64_t c = g->count + (fwd ? 1 : -1);

        g->count = c;
        /* Z from the cached span where it holds, else the modulo */
        qgen_emit(g, qgen_z_low(g, c) ? qgen_ab[(uint64_t)c & 3u] : qgen_lines_at(g, c), t);
        g->edges++;
        qgen_step(&t, &rem, &st);
    }
    return n;
}

/* General path: edge offsets, huge positions or times (128-bit arithmetic). */
__attribute__((noinline)) static uint64_t qgen_move_general(qgen_t *g, qgen_pos_t x1, uint64_t dt)
{
    qgen_pos_t x0 = g->x;
    uint64_t t0 = g->t;
    qgen_i128 dx = (qgen_i128)x1 - (qgen_i128)x0;
    bool fwd = dx > 0;
    qgen_u128 den = (qgen_u128)(fwd ? dx : -dx);
    qgen_u128 quo = 0u, rem = 0u; /* floor(|b - x0| * dt / den), remainder */
    qgen_i128 b, prev_b;
    uint64_t n = 0;

    if (dx != 0) {
        b = qgen_boundary(g, fwd ? g->count + 1 : g->count);
        if (fwd ? (qgen_i128)x1 >= b : (qgen_i128)x1 < b) {
            qgen_u128 q_one = 0u, r_one = 0u; /* the same for one whole count */
            bool have_one = false;

            qgen_divmod((qgen_u128)(fwd ? b - x0 : x0 - b) * dt, den, &quo, &rem);
            for (;;) {
                qgen_u128 step, q, r;

                g->count += fwd ? 1 : -1;
                qgen_emit(g, qgen_lines_at(g, g->count), t0 + (uint64_t)quo);
                g->edges++;
                n++;
                prev_b = b;
                b = qgen_boundary(g, fwd ? g->count + 1 : g->count);
                if (fwd ? (qgen_i128)x1 < b : (qgen_i128)x1 >= b) {
                    break;
                }
                step = (qgen_u128)(fwd ? b - prev_b : prev_b - b);
                if (step == (qgen_u128)QGEN_ONE) {
                    if (!have_one) {
                        qgen_divmod((qgen_u128)QGEN_ONE * dt, den, &q_one, &r_one);
                        have_one = true;
                    }
                    q = q_one;
                    r = r_one;
                } else {
                    qgen_divmod(step * dt, den, &q, &r); /* only with edge offsets */
                }
                quo += q;
                rem += r;
                if (rem >= den) {
                    rem -= den;
                    quo++;
                }
            }
        }
    }
    return n;
}

/* A move by events (qgen_move_ideal's loops or the general path), and the
 * position and time updated. */
__attribute__((noinline)) static uint64_t qgen_move_events(qgen_t *g, qgen_pos_t x1, uint64_t dt)
{
    uint64_t n;

    /* x1 == x (qgen_move_to's test): no boundary crossed on either path */
    if (qgen_fast_ok(g, x1, dt)) {
        n = qgen_move_ideal(g, x1, dt);
    } else {
        n = qgen_move_general(g, x1, dt);
    }
    g->x = x1;
    g->t += dt;
    return n;
}

/* The fast path as one run (qgen_set_run): the move by events when it has
 * an event with Z high, more than 2^31 - 1 events, or the callback refuses
 * it. The count's change d = c1 - c0 has the move's sign (boundaries lie
 * at whole counts), so it is the run's steps. The last crossing is of
 * boundary c1 (forward) or c1 + 1 (backward), at the time the stepper
 * reaches: t + floor(distance * dt / |dx|). */

/* The run of d steps (d != 0) with its last event at t_last: the state
 * after it is written before the callback (which must not read the
 * generator) and the one before it kept in undo_*, so that only the
 * generator lives across the call; a refusal restores it and the events
 * come one by one (lines and last_edge_t then the events' own). */
static inline __attribute__((always_inline)) uint64_t
qgen_run_commit(qgen_t *g, qgen_pos_t x1, uint64_t dt, int64_t d, uint64_t t_last)
{
    int64_t c1 = g->count + d;

    g->undo_x = g->x;
    g->undo_t = g->t;
    g->undo_count = g->count;
    g->x = x1;
    g->t += dt;
    g->count = c1;
    g->lines = qgen_ab[(uint64_t)c1 & 3u];
    g->last_edge_t = t_last;
    if (!g->run(g->ctx, (int32_t)d, (uint32_t)t_last)) {
        x1 = g->x;
        dt = g->t - g->undo_t;
        g->x = g->undo_x;
        g->t = g->undo_t;
        g->count = g->undo_count;
        return qgen_move_events(g, x1, dt);
    }
    d = g->count - g->undo_count; /* nothing but g kept across the call */
    g->edges += (uint64_t)(d > 0 ? d : -d);
    g->run_edges += (uint64_t)(d > 0 ? d : -d);
    return (uint64_t)(d > 0 ? d : -d);
}

/* A run from x0 to x1 ending in count c1 (d = its signed count change, not
 * 0): returns the run's length |x1 - x0|; *dist the distance from x0 to the
 * last edge crossed (the run's direction decides which side of c1 it is). */
static inline uint64_t qgen_run_den(qgen_pos_t x0, qgen_pos_t x1, int64_t c1, int64_t d,
                                    uint64_t *dist)
{
    if (d > 0) {
        *dist = (uint64_t)(c1 * QGEN_ONE - x0);
        return (uint64_t)(x1 - x0);
    }
    *dist = (uint64_t)(x0 - (c1 + 1) * QGEN_ONE);
    return (uint64_t)(x0 - x1);
}

/* Any run: the index window's span recomputed when the count left it, a
 * 128-bit division when the product needs it. */
__attribute__((noinline)) static uint64_t qgen_move_run_any(qgen_t *g, qgen_pos_t x1, uint64_t dt)
{
    qgen_pos_t x0 = g->x;
    int64_t c0 = g->count, c1 = qgen_floor_count(x1), d = c1 - c0;
    uint64_t den, dist;
    qgen_u128 q, r;

    if (d == 0) {
        g->x = x1;
        g->t += dt;
        return 0u;
    }
    if (d > INT32_MAX || d < -INT32_MAX) {
        return qgen_move_events(g, x1, dt);
    }
    if (!qgen_z_low(g, c0)) {
        qgen_z_span(g);
    }
    if (!qgen_z_low(g, c0) || !qgen_z_low(g, c1)) {
        /* the span is contiguous: both ends inside, all inside */
        return qgen_move_events(g, x1, dt);
    }
    den = qgen_run_den(x0, x1, c1, d, &dist);
    qgen_divmod((qgen_u128)dist * dt, den, &q, &r);
    return qgen_run_commit(g, x1, dt, d, g->t + (uint64_t)q);
}

/* The usual run: both ends inside the cached span, the product in 64
 * bits, one division (the rest: qgen_move_run_any). */
static inline uint64_t qgen_move_run(qgen_t *g, qgen_pos_t x1, uint64_t dt)
{
    qgen_pos_t x0 = g->x;
    int64_t c0 = g->count, c1 = qgen_floor_count(x1), d = c1 - c0;
    uint64_t den, dist;
    qgen_u128 p;

    if (d == 0) {
        g->x = x1;
        g->t += dt;
        return 0u;
    }
    if (d > INT32_MAX || d < -INT32_MAX || !qgen_z_low(g, c0) || !qgen_z_low(g, c1)) {
        return qgen_move_run_any(g, x1, dt);
    }
    den = qgen_run_den(x0, x1, c1, d, &dist);
    p = (qgen_u128)dist * dt;
    if ((p >> 64) != 0u) {
        return qgen_move_run_any(g, x1, dt);
    }
    return qgen_run_commit(g, x1, dt, d, g->t + (uint64_t)p / den);
}

uint64_t qgen_move_changed(qgen_t *g, qgen_pos_t x1, uint64_t t1_ns)
{
    uint64_t dt = (t1_ns > g->t) ? t1_ns - g->t : 0u;

    if (g->run != NULL && qgen_fast_ok(g, x1, dt)) {
        return qgen_move_run(g, x1, dt);
    }
    return qgen_move_events(g, x1, dt);
}

void qgen_illegal(qgen_t *g, uint64_t t_ns, uint32_t gap_ns)
{
    uint32_t normal = g->lines;

    qgen_emit(g, normal ^ (QDEC_LINE_A | QDEC_LINE_B), t_ns);
    qgen_emit(g, normal, t_ns + gap_ns);
    g->illegal += 2u;
    if (g->t < t_ns + gap_ns) {
        g->t = t_ns + gap_ns;
    }
}

void qgen_glitch(qgen_t *g, uint32_t line, uint64_t t_ns, uint32_t width_ns)
{
    uint32_t normal = g->lines;

    qgen_emit(g, normal ^ (line & (QDEC_LINE_A | QDEC_LINE_B)), t_ns);
    qgen_emit(g, normal, t_ns + width_ns);
    g->glitches++;
    if (g->t < t_ns + width_ns) {
        g->t = t_ns + width_ns;
    }
}
