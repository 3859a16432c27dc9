/*
 * qdec.c - quadrature decoding and position feedback (specification in
 * qdec.h).
 */
#include "qdec.h"

#include <stddef.h>

#define QDEC_ILL 2 /* table entry: both channels changed */

#define QDEC_NS_PER_S 1000000000ull

/* Index: (old A/B << 2) | new A/B; A = bit 0, B = bit 1; forward 0,1,3,2. */
static const int8_t qdec_table_x4[16] = {
    0,        1,        -1,       QDEC_ILL, /* from 00 */
    -1,       0,        QDEC_ILL, 1,        /* from A  */
    1,        QDEC_ILL, 0,        -1,       /* from B  */
    QDEC_ILL, -1,       1,        0,        /* from AB */
};
static const int8_t qdec_table_x2[16] = {
    0,        1,        0,        QDEC_ILL, /* from 00 */
    -1,       0,        QDEC_ILL, 0,        /* from A  */
    0,        QDEC_ILL, 0,        -1,       /* from B  */
    QDEC_ILL, 0,        1,        0,        /* from AB */
};
static const int8_t qdec_table_x1[16] = {
    0,        1,        0,        QDEC_ILL, /* from 00 */
    -1,       0,        QDEC_ILL, 0,        /* from A  */
    0,        QDEC_ILL, 0,        0,        /* from B  */
    QDEC_ILL, 0,        0,        0,        /* from AB */
};

/* ---- helpers ----------------------------------------------------------------- */

/* Sign-extend the low `bits` bits of d (1..32: the result fits int32). */
static inline int32_t qdec_sext32(uint32_t d, uint8_t bits)
{
    uint32_t sign = 1u << (bits - 1u);
    uint32_t m = (sign - 1u) | sign;

    return (int32_t)(((d & m) ^ sign) - sign);
}

/* The decoder's count difference (counter_bits, 32 for edge input). */
static inline int32_t qdec_sx(const qdec_t *q, uint32_t d)
{
    return (q->bits == 32u) ? (int32_t)d : qdec_sext32(d, q->bits);
}

/* dp counts in dt ns (dt > 0) as q32_32 counts/s, truncated toward zero,
 * saturated at +-2^31 counts/s. */
static q32_32_t qdec_rate(int64_t dp, int64_t dt)
{
    uint64_t n = fx_uabs64(dp);
    uint64_t d = (uint64_t)dt;
    uint64_t num, ip, r, v;

    if (n >= (1ull << 33)) {
        return (dp < 0) ? -INT64_MAX : INT64_MAX;
    }
    num = n * QDEC_NS_PER_S;
    ip = fx_udivmod64(num, d, &r); /* fixmath: 32-bit digits on 32-bit targets */
    if (ip >= (1ull << 31)) {
        return (dp < 0) ? -INT64_MAX : INT64_MAX;
    }
    while (d >= (1ull << 31)) {
        d >>= 1;
        r >>= 1;
    }
    v = (ip << 32) + fx_udivmod64(r << 32, d, &r);
    return (dp < 0) ? -(int64_t)v : (int64_t)v;
}

/* ---- edge context -------------------------------------------------------------- */

static void qdec_index_eval(qdec_t *q, uint32_t t)
{
    qdec_edge_state_t *e = &q->e;
    uint8_t qual = q->cfg.index_qual;
    uint8_t gated = (uint8_t)(e->z && (qual == QDEC_INDEX_UNGATED || e->ab == qual));

    if (gated && !e->gated) {
        e->idx_raw = e->count;
        e->idx_t = t;
        e->idx_dir = e->dir;
        e->idx_events = e->idx_events + 1u;
        e->rare = e->rare + 1u;
    }
    e->gated = gated;
}

/* Count one decoded step d (QDEC_ILL or +-1, never 0) at time t: the
 * edge fields both edge paths write. */
static inline void qdec_count(const qdec_t *q, qdec_edge_state_t *e, int8_t d, uint32_t t)
{
    if (d == QDEC_ILL) {
        e->illegal = e->illegal + 1u;
        e->rare = e->rare + 1u;
    } else {
        uint32_t count = e->count + (uint32_t)(int32_t)d;

        e->count = count;
        e->nedge = e->nedge + 1u;
        e->t_last = t;
        e->dir = d;
        if ((count & q->cyc_mask) == 0u) {
            e->cyc_count = count;
            e->cyc_t = t;
            e->ncyc = e->ncyc + 1u;
        }
    }
}

/* Decode one committed A/B state. */
static void qdec_apply(qdec_t *q, uint32_t ab, uint32_t t)
{
    qdec_edge_state_t *e = &q->e;
    int8_t d = q->table[((uint32_t)e->ab << 2) | ab];

    if (d != 0) {
        qdec_count(q, e, d, t);
    }
    e->ab = (uint8_t)ab;
    if (e->z) {
        qdec_index_eval(q, t);
    } else {
        e->gated = 0;
    }
}

/* Glitch filter: commit the pending edges that are confirmed at time t (the
 * new level has lasted glitch_ns), oldest first; A and B pending with the
 * same time are one simultaneous (illegal) change. */
static void qdec_confirm(qdec_t *q, uint32_t t)
{
    qdec_edge_state_t *e = &q->e;
    int32_t g = (int32_t)q->cfg.glitch_ns;
    bool a_ok = (e->pend & QDEC_LINE_A) && (int32_t)(t - e->pend_t[0]) >= g;
    bool b_ok = (e->pend & QDEC_LINE_B) && (int32_t)(t - e->pend_t[1]) >= g;

    if (a_ok && b_ok) {
        int32_t ab_order = (int32_t)(e->pend_t[0] - e->pend_t[1]);
        if (ab_order == 0) {
            qdec_apply(q, e->ab ^ 3u, e->pend_t[0]);
        } else if (ab_order < 0) {
            qdec_apply(q, e->ab ^ QDEC_LINE_A, e->pend_t[0]);
            qdec_apply(q, e->ab ^ QDEC_LINE_B, e->pend_t[1]);
        } else {
            qdec_apply(q, e->ab ^ QDEC_LINE_B, e->pend_t[1]);
            qdec_apply(q, e->ab ^ QDEC_LINE_A, e->pend_t[0]);
        }
        e->pend = 0;
    } else if (a_ok) {
        qdec_apply(q, e->ab ^ QDEC_LINE_A, e->pend_t[0]);
        e->pend &= (uint8_t)~QDEC_LINE_A;
    } else if (b_ok) {
        qdec_apply(q, e->ab ^ QDEC_LINE_B, e->pend_t[1]);
        e->pend &= (uint8_t)~QDEC_LINE_B;
    }
}

static void qdec_filter_edge(qdec_t *q, uint32_t ab, uint32_t t)
{
    qdec_edge_state_t *e = &q->e;
    uint32_t changed;
    unsigned c;

    qdec_confirm(q, t);
    changed = ab ^ ((uint32_t)e->ab ^ e->pend);
    for (c = 0; c < 2u; c++) {
        uint8_t bit = (uint8_t)(1u << c);
        if ((changed & bit) == 0u) {
            continue;
        }
        if (e->pend & bit) {
            e->pend &= (uint8_t)~bit; /* pulse shorter than glitch_ns */
            e->glitches = e->glitches + 1u;
        } else {
            e->pend |= bit;
            e->pend_t[c] = t;
        }
    }
}

/* Out of line so that the fast path of qdec_edge() stays a leaf function
 * (no registers to save). */
#if defined(__GNUC__)
#define QDEC_NOINLINE __attribute__((noinline))
#else
#define QDEC_NOINLINE
#endif

/* General edge path: glitch filter on, or Z high before or after. */
static QDEC_NOINLINE void qdec_edge_slow(qdec_t *q, uint32_t lines, uint32_t t_ns)
{
    qdec_edge_state_t *e = &q->e;
    uint8_t z = (uint8_t)((lines >> 2) & 1u);
    uint32_t seq = e->seq;

    e->seq = seq + 1u;
    if (q->cfg.glitch_ns == 0u) {
        qdec_apply(q, lines & 3u, t_ns);
    } else {
        qdec_filter_edge(q, lines & 3u, t_ns);
    }
    if (z != e->z) {
        e->z = z;
        qdec_index_eval(q, t_ns);
    }
    e->seq = seq + 2u;
}

void qdec_edge(qdec_t *q, uint32_t lines, uint32_t t_ns)
{
    qdec_edge_state_t *e = &q->e;
    uint32_t ab = lines & 3u;
    uint32_t seq;
    int8_t d;

    if (q->cfg.glitch_ns != 0u || ((lines & QDEC_LINE_Z) | e->z) != 0u) {
        qdec_edge_slow(q, lines, t_ns);
        return;
    }
    /* Fast path: no filter, Z low before and after (so e->gated is 0 and
     * stays 0). The same result as qdec_apply(), with each shared field read
     * and written once. Only fields the tick snapshots are guarded by seq. */
    d = q->table[((uint32_t)e->ab << 2) | ab];
    if (d == 0) {
        e->ab = (uint8_t)ab; /* not counted (x2/x1) or no change */
        return;
    }
    seq = e->seq;
    e->seq = seq + 1u;
    qdec_count(q, e, d, t_ns);
    e->ab = (uint8_t)ab;
    e->seq = seq + 2u;
}

bool qdec_edge_run(qdec_t *q, int32_t steps, uint32_t t_last_ns)
{
    qdec_edge_state_t *e = &q->e;
    uint32_t n = (steps < 0) ? 0u - (uint32_t)steps : (uint32_t)steps;
    uint32_t seq, i;

    if (n == 0u || !q->run_ok || e->z != 0u) {
        return false;
    }
    /* position in the forward cycle 00, A, AB, B: the Gray code's value */
    i = (uint32_t)e->ab ^ ((uint32_t)e->ab >> 1);
    i = (i + (uint32_t)steps) & 3u;
    seq = e->seq;
    e->seq = seq + 1u;
    e->count = e->count + (uint32_t)steps;
    e->nedge = e->nedge + n;
    e->t_last = t_last_ns;
    e->dir = (int8_t)((steps > 0) ? 1 : -1);
    e->ab = (uint8_t)(i ^ (i >> 1));
    e->seq = seq + 2u;
    return true;
}

void qdec_index_capture(qdec_t *q, uint32_t raw, uint32_t t_ns)
{
    qdec_edge_state_t *e = &q->e;

    e->seq = e->seq + 1u;
    e->idx_raw = raw;
    e->idx_t = t_ns;
    e->idx_dir = q->out.dir;
    e->idx_events = e->idx_events + 1u;
    e->rare = e->rare + 1u;
    e->seq = e->seq + 1u;
}

/* ---- tick context ---------------------------------------------------------------- */

typedef struct {
    uint32_t raw;
    uint32_t nedge;
    uint32_t t_last;
    uint32_t cyc_count;
    uint32_t cyc_t;
    uint32_t ncyc;
    int8_t dir;
    uint32_t illegal;
    uint32_t glitches;
    uint32_t idx_events;
    uint32_t rare;
    uint32_t idx_raw;
    uint32_t idx_t;
    int8_t idx_dir;
} qdec_snap_t;

/* Only the fields the sample will use: the cycle-aligned edge with
 * vel_cycle, the glitch count with the filter (else it stays 0), the index
 * latch when a new one came. */
#if defined(__GNUC__)
#define QDEC_INLINE inline __attribute__((always_inline))
#else
#define QDEC_INLINE inline
#endif

static QDEC_INLINE void qdec_snapshot_k(const qdec_t *q, qdec_snap_t *s, bool cyc, bool filt)
{
    const qdec_edge_state_t *e = &q->e;
    uint32_t seq;

    do {
        seq = e->seq;
        s->raw = e->count;
        s->nedge = e->nedge;
        s->t_last = e->t_last;
        if (cyc) {
            s->cyc_count = e->cyc_count;
            s->cyc_t = e->cyc_t;
            s->ncyc = e->ncyc;
        }
        s->dir = e->dir;
        s->illegal = e->illegal;
        s->glitches = filt ? e->glitches : 0u;
        s->idx_events = e->idx_events;
        s->rare = e->rare;
        if (s->idx_events != q->last_idx_events) {
            s->idx_raw = e->idx_raw;
            s->idx_t = e->idx_t;
            s->idx_dir = e->idx_dir;
        }
    } while (seq != e->seq || (seq & 1u) != 0u);
}

static void qdec_snapshot(const qdec_t *q, qdec_snap_t *s)
{
    qdec_snapshot_k(q, s, q->cfg.vel_cycle, q->cfg.glitch_ns != 0u);
}

/* Anchor of the estimate at ring entry `head` (n entries): the oldest
 * entry within the window, at least the previous one; its index. */
static unsigned qdec_vel_anchor(const qdec_t *q, unsigned head, unsigned n)
{
    int64_t window = (int64_t)q->cfg.vel_window_ns;
    int64_t t_edge = q->ring_t[head];
    unsigned k = 1, i;

    for (i = 2; i < n; i++) {
        unsigned idx = (head + QDEC_VEL_RING - i) % QDEC_VEL_RING;
        if (t_edge - q->ring_t[idx] > window) {
            break;
        }
        k = i;
    }
    return (head + QDEC_VEL_RING - k) % QDEC_VEL_RING;
}

/* Fold the short records (qdec_velocity_edge's usual case: ring entry and
 * q->rec only) into the ring's bookkeeping: each one added an entry to a
 * strictly rising ring and left the new estimate for later (lazy), with no
 * clamp. Called before anything reads or changes ring_n, ring_mono or the
 * vel_* fields; q->rec - q->rec_norm <= QDEC_VEL_RING (the short record
 * folds when the ring index wraps). */
static void qdec_vel_fold(qdec_t *q)
{
    uint32_t d = q->rec - q->rec_norm;

    if (d != 0u) {
        uint32_t n = q->ring_n + d, mono = q->ring_mono + d;

        q->ring_n = (uint8_t)((n < QDEC_VEL_RING) ? n : QDEC_VEL_RING);
        q->ring_mono = (uint8_t)((mono < QDEC_VEL_RING - 1u) ? mono : QDEC_VEL_RING - 1u);
        q->vel_lazy = true;
        q->vel_pending = false;
        q->vel_since = 0;
        q->rec_norm = q->rec;
    }
}

/* Bring out.vel up to the last sample: the pending estimate (its anchor and
 * division), then the bound between edges: still moving at vel, the next
 * recorded edge would have come within `since`. */
static void qdec_vel_resolve(qdec_t *q)
{
    qdec_vel_fold(q);
    if (q->vel_lazy) {
        /* recorded at the newest ring entry, the ring unchanged since */
        unsigned head = q->rec % QDEC_VEL_RING;
        unsigned idx = qdec_vel_anchor(q, head, q->ring_n);
        q->vel_dp = q->ring_p[head] - q->ring_p[idx];
        q->vel_dt = q->ring_t[head] - q->ring_t[idx]; /* > 0: see qdec_velocity_edge */
        q->vel_lazy = false;
        q->vel_pending = true;
    }
    if (q->vel_pending) {
        q->out.vel = qdec_rate(q->vel_dp, q->vel_dt);
        q->vel_pending = false;
    }
    if (q->vel_since > 0 && q->out.vel != 0) {
        q32_32_t bound = qdec_rate(q->cfg.vel_cycle ? (int64_t)q->cyc_mask + 1 : 1, q->vel_since);
        if (q->out.vel > bound) {
            q->out.vel = bound;
        } else if (q->out.vel < -bound) {
            q->out.vel = -bound;
        }
    }
    q->vel_since = 0;
}

q32_32_t qdec_velocity(qdec_t *q)
{
    qdec_vel_resolve(q);
    q->out.vel_nm_s = fx_mul64_shift(q->out.vel, q->cfg.nm_per_count_num, 32);
    if (q->cfg.nm_per_count_den != 1) { /* round(x / 1) is x */
        q->out.vel_nm_s = fx_div_round64(q->out.vel_nm_s, q->cfg.nm_per_count_den);
    }
    return q->out.vel;
}

static QDEC_NOINLINE void qdec_velocity_edge_slow(qdec_t *q, int64_t p_edge, int64_t t_edge);

/* Record a new edge for the velocity estimate. The usual case here (inline
 * in the sample): the ring rises strictly (vel_fast: ring_n > 0 and
 * ring_mono + 1 >= ring_n, which such a record keeps) and t_edge is above
 * the newest entry, so the new estimate exists (dt > 0 for any anchor) and
 * replaces the pending one: store the entry and count it in q->rec;
 * qdec_vel_fold does the rest when the ring is next read. The rest in
 * qdec_velocity_edge_slow. */
static QDEC_INLINE void qdec_velocity_edge(qdec_t *q, int64_t p_edge, int64_t t_edge)
{
    uint32_t rec = q->rec;

    if (q->vel_fast && t_edge > q->t_rec) {
        unsigned head = (rec + 1u) % QDEC_VEL_RING;

        q->ring_p[head] = p_edge;
        q->ring_t[head] = t_edge;
        q->t_rec = t_edge;
        q->rec = rec + 1u;
        if (head == 0u) {
            qdec_vel_fold(q); /* keeps rec - rec_norm <= QDEC_VEL_RING */
        }
        return;
    }
    qdec_velocity_edge_slow(q, p_edge, t_edge);
}

static QDEC_NOINLINE void qdec_velocity_edge_slow(qdec_t *q, int64_t p_edge, int64_t t_edge)
{
    unsigned n, head, idx;
    int64_t dt;
    bool rising;

    qdec_vel_fold(q);
    n = q->ring_n;
    head = q->rec % QDEC_VEL_RING;
    rising = n > 0u && t_edge > q->t_rec; /* the newest recorded time */
    if (q->vel_lazy) {
        qdec_vel_resolve(q); /* before the ring changes (keeps the clamp) */
    }
    /* record the newest edge */
    head = (head + 1u) % QDEC_VEL_RING;
    q->ring_p[head] = p_edge;
    q->ring_t[head] = t_edge;
    q->t_rec = t_edge;
    if (n < QDEC_VEL_RING) {
        n++;
    }
    q->rec++;
    q->rec_norm = q->rec;
    q->ring_n = (uint8_t)n;
    q->ring_mono = rising ? (uint8_t)(q->ring_mono + 1u) : 0u; /* < n - 1 here */
    q->vel_fast = q->ring_mono + 1u >= n;

    if (n < 2u) {
        qdec_vel_resolve(q); /* no new estimate: the last one stays */
        return;
    }
    idx = qdec_vel_anchor(q, head, n);
    dt = t_edge - q->ring_t[idx];
    if (dt > 0) {
        /* the new estimate replaces everything before it: keep its inputs,
         * divide when someone asks (qdec_velocity) */
        q->vel_dp = p_edge - q->ring_p[idx];
        q->vel_dt = dt;
        q->vel_pending = true;
        q->vel_since = 0;
    } else {
        qdec_vel_resolve(q); /* no new estimate: the last one stays */
    }
}

static QDEC_INLINE void qdec_velocity_idle(qdec_t *q)
{
    int64_t since;

    if (q->rec != q->rec_norm) {
        qdec_vel_fold(q);
    }
    since = q->now - q->t_rec; /* the newest recorded edge */

    if (q->now - q->t_edge >= (int64_t)q->cfg.zero_timeout_ns) {
        q->out.vel = 0;
        q->vel_pending = false;
        q->vel_lazy = false;
        q->vel_since = 0;
        q->out.stopped = true;
        return;
    }
    if (since > 0) {
        /* the bound falls with `since`: only the last one matters */
        q->vel_since = since;
    }
}

static void qdec_illegal_window(qdec_t *q, uint32_t new_illegal)
{
    unsigned lim = q->cfg.illegal_limit;
    unsigned i, oldest;

    if (lim == 0u || new_illegal == 0u) {
        return;
    }
    if (new_illegal > lim) {
        new_illegal = lim;
    }
    for (i = 0; i < new_illegal; i++) {
        q->ill_t[q->ill_head] = q->now;
        q->ill_head = (uint8_t)((q->ill_head + 1u) % QDEC_ILLEGAL_MAX);
        if (q->ill_n < QDEC_ILLEGAL_MAX) {
            q->ill_n++;
        }
    }
    if (q->ill_n >= lim) {
        oldest = (q->ill_head + QDEC_ILLEGAL_MAX - lim) % QDEC_ILLEGAL_MAX;
        if ((uint64_t)(q->now - q->ill_t[oldest]) <= q->cfg.illegal_window_ns) {
            q->out.faults |= QDEC_FAULT_ILLEGAL;
        }
    }
}

/* Common part of both sample functions. `edges`: new counted edges since the
 * last sample, the last one at s->t_last (raw clock); `vel_edge`: a new edge
 * for the velocity estimate, the last one at (s->cyc_count, s->cyc_t). */
/* Inlined into the sample functions: the snapshot stays in registers.
 * Constant flags for the edge fast path: bits32 (q->bits is 32: the count
 * difference needs no sign extension), last_is_cyc (the velocity edge is
 * the last counted edge: s->cyc_count == s->raw, s->cyc_t == s->t_last). */
static QDEC_INLINE void qdec_update_k(qdec_t *q, const qdec_snap_t *s, bool edges, bool vel_edge,
                                      uint32_t now_ns, bool bits32, bool last_is_cyc)
{
    int32_t dt = (int32_t)(now_ns - q->now_raw);
    int32_t delta;
    const comp_table_t *comp = q->cfg.comp;

    if (dt > 0) {
        q->now += dt;
        q->now_raw = now_ns;
    } else {
        q->out.faults |= QDEC_FAULT_TIME;
    }

    delta = bits32 ? (int32_t)(s->raw - q->last_raw) : qdec_sx(q, s->raw - q->last_raw);
    q->last_raw = s->raw;
    q->out.pos += delta;
    if (qdec_overspeed(delta, q->max_delta)) {
        q->out.faults |= QDEC_FAULT_OVERSPEED;
    }
    if (s->dir != 0) {
        q->out.dir = s->dir;
    }

    if (edges) {
        q->t_edge = q->now + (int32_t)(s->t_last - q->now_raw);
        q->out.stopped = false;
    }
    if (vel_edge && last_is_cyc) {
        /* vel_edge implies edges here: t_edge is this edge's time */
        qdec_velocity_edge(q, q->out.pos, q->t_edge);
    } else if (vel_edge) {
        qdec_velocity_edge(q, q->out.pos - qdec_sx(q, s->raw - s->cyc_count),
                           q->now + (int32_t)(s->cyc_t - q->now_raw));
    } else {
        qdec_velocity_idle(q);
    }

    if (s->illegal != q->last_illegal) {
        qdec_illegal_window(q, s->illegal - q->last_illegal);
    }
    q->last_illegal = s->illegal;
    q->out.illegal = s->illegal;
    q->out.glitches = s->glitches;

    if (s->idx_events != q->last_idx_events) {
        q->last_idx_events = s->idx_events;
        q->out.index_pos = q->out.pos - (bits32 ? (int32_t)(s->raw - s->idx_raw)
                                                : qdec_sx(q, s->raw - s->idx_raw));
        q->out.index_t_ns = s->idx_t;
        q->out.index_dir = s->idx_dir;
        q->out.index_events = s->idx_events;
    }

    q->out.pos_nm_raw = qdec_counts_to_nm(q, q->out.pos);
    q->out.pos_nm = (comp == NULL) ? q->out.pos_nm_raw
                                   : comp_correct(comp, q->out.pos_nm_raw, (comp_dir_t)q->out.dir);
}

static QDEC_INLINE void qdec_update(qdec_t *q, const qdec_snap_t *s, bool edges, bool vel_edge,
                                    uint32_t now_ns)
{
    qdec_update_k(q, s, edges, vel_edge, now_ns, false, false);
}

/* The reference sample path (every configuration of edge input): the
 * usual case on 32-bit counts below, the rest through qdec_update. */
static QDEC_NOINLINE void qdec_sample_ref(qdec_t *q, uint32_t now_ns)
{
    qdec_snap_t s = {0};

    if (q->cfg.glitch_ns == 0u && !q->cfg.vel_cycle) {
        /* no filter, every counted edge is a velocity edge, 32-bit count */
        bool edges;

        qdec_snapshot_k(q, &s, false, false);
        edges = s.nedge != q->last_nedge;
        qdec_update_k(q, &s, edges, edges, now_ns, true, true);
        q->last_rare = s.rare; /* with last_illegal, last_idx_events: for the short path */
        q->last_nedge = s.nedge;
        q->last_ncyc = s.nedge;
        return;
    }
    if (q->cfg.glitch_ns != 0u) {
        q->e.seq = q->e.seq + 1u;
        qdec_confirm(q, now_ns);
        q->e.seq = q->e.seq + 1u;
    }
    qdec_snapshot(q, &s);
    if (!q->cfg.vel_cycle) {
        s.cyc_count = s.raw;
        s.cyc_t = s.t_last;
        s.ncyc = s.nedge;
    }
    qdec_update(q, &s, s.nedge != q->last_nedge, s.ncyc != q->last_ncyc, now_ns);
    q->last_nedge = s.nedge;
    q->last_ncyc = s.ncyc;
}

/* The tick's usual sample (q->fast: edge input, no filter, no vel_cycle)
 * when nothing rare happened: time forward (0 < dt < 2^31 ns), no new
 * illegal transition, no new index latch. Reads only the count, the edge
 * counter, the last edge time and direction; the count difference and the
 * edge time relative to the sample are 32-bit, the 64-bit values (position,
 * extended time) take one add each; position in nm by one 32x32 multiply.
 * Returns false before writing anything when the sample needs the
 * reference path (qdec_sample_ref), which then gives the same result. */
static QDEC_INLINE bool qdec_sample_fast(qdec_t *q, uint32_t now_ns)
{
    const qdec_edge_state_t *e = &q->e;
    uint32_t seq, raw, nedge, t_last;
    int32_t dt, delta;
    int8_t dir;
    int64_t pos;
    const comp_table_t *comp;

    do {
        seq = e->seq;
        raw = e->count;
        nedge = e->nedge;
        t_last = e->t_last;
        dir = e->dir;
        if (e->rare != q->last_rare) {
            return false;
        }
    } while (seq != e->seq || (seq & 1u) != 0u);
    dt = (int32_t)(now_ns - q->now_raw);
    if (dt <= 0) {
        return false;
    }
    q->now += dt;
    q->now_raw = now_ns;
    if (nedge == q->last_nedge) {
        /* no counted edge: the count (it changes only with nedge) and the
         * direction are unchanged, so are the position and pos_nm_raw
         * (scale and offset change only through qdec_set_offset_nm, which
         * sends the next sample to the reference path); only the
         * compensation is re-read (its table may change between samples) */
        qdec_velocity_idle(q);
        comp = q->cfg.comp;
        q->out.pos_nm = (comp == NULL)
                            ? q->out.pos_nm_raw
                            : comp_correct(comp, q->out.pos_nm_raw, (comp_dir_t)q->out.dir);
        return true;
    }

    delta = (int32_t)(raw - q->last_raw);
    q->last_raw = raw;
    pos = q->out.pos + delta;
    q->out.pos = pos;
    if (qdec_overspeed(delta, q->max_delta)) {
        q->out.faults |= QDEC_FAULT_OVERSPEED;
    }
    if (dir != 0) {
        q->out.dir = dir;
    }
    {
        /* the last counted edge: within 2^31 ns of this sample (see Timestamps) */
        int64_t t_edge = q->now + (int32_t)(t_last - now_ns);

        q->last_nedge = nedge;
        q->last_ncyc = nedge;
        q->t_edge = t_edge;
        q->out.stopped = false;
        qdec_velocity_edge(q, pos, t_edge);
    }
    /* out.illegal and out.glitches are unchanged (equal to e's: filter off) */
    comp = q->cfg.comp;
    q->out.pos_nm_raw = qdec_counts_to_nm(q, pos);
    q->out.pos_nm = (comp == NULL) ? q->out.pos_nm_raw
                                   : comp_correct(comp, q->out.pos_nm_raw, (comp_dir_t)q->out.dir);
    return true;
}

void qdec_sample(qdec_t *q, uint32_t now_ns)
{
    if (q->fast && qdec_sample_fast(q, now_ns)) {
        return;
    }
    qdec_sample_ref(q, now_ns);
}

void qdec_sample_counter(qdec_t *q, uint32_t raw, uint32_t now_ns)
{
    qdec_snap_t s = {0};
    int32_t delta = qdec_sx(q, raw - q->last_raw);

    qdec_snapshot(q, &s);
    s.raw = raw;
    s.t_last = now_ns;
    s.cyc_count = raw;
    s.cyc_t = now_ns;
    s.dir = (int8_t)((delta > 0) - (delta < 0));
    qdec_update_k(q, &s, delta != 0, delta != 0, now_ns, false, true);
}

/* ---- configuration and scaling ------------------------------------------------------ */

static bool qdec_nm_fast(const qdec_config_t *cfg)
{
    return cfg->nm_per_count_den == 1 && cfg->offset_nm > -((int64_t)1 << 62) &&
           cfg->offset_nm < ((int64_t)1 << 62);
}

void qdec_config_default(qdec_config_t *cfg)
{
    cfg->input = QDEC_INPUT_EDGES;
    cfg->mode = QDEC_X4;
    cfg->counter_bits = 32;
    cfg->max_delta = 0;
    cfg->illegal_limit = 0;
    cfg->illegal_window_ns = 0;
    cfg->glitch_ns = 0;
    cfg->zero_timeout_ns = 0;
    cfg->vel_window_ns = 0;
    cfg->vel_cycle = false;
    cfg->index_qual = QDEC_INDEX_UNGATED;
    cfg->nm_per_count_num = 1;
    cfg->nm_per_count_den = 1;
    cfg->offset_nm = 0;
    cfg->comp = NULL;
}

bool qdec_init(qdec_t *q, const qdec_config_t *cfg, uint32_t initial, uint32_t now_ns)
{
    uint8_t bits = (cfg->input == QDEC_INPUT_COUNTER) ? cfg->counter_bits : 32u;
    const int8_t *table;
    unsigned i;

    if (cfg->input != QDEC_INPUT_EDGES && cfg->input != QDEC_INPUT_COUNTER) {
        return false;
    }
    switch (cfg->mode) {
    case QDEC_X4:
        table = qdec_table_x4;
        break;
    case QDEC_X2:
        table = qdec_table_x2;
        break;
    case QDEC_X1:
        table = qdec_table_x1;
        break;
    default:
        return false;
    }
    if (bits < 8u || bits > 32u || cfg->illegal_limit > QDEC_ILLEGAL_MAX ||
        (cfg->index_qual > 3u && cfg->index_qual != QDEC_INDEX_UNGATED) ||
        cfg->nm_per_count_num == 0 || cfg->nm_per_count_den <= 0 ||
        (cfg->glitch_ns != 0u && cfg->input != QDEC_INPUT_EDGES) || cfg->glitch_ns > 0x7FFFFFFFu ||
        cfg->max_delta > QDEC_MAX_DELTA(bits)) {
        return false;
    }

    *q = (qdec_t){0};
    q->cfg = *cfg;
    if (q->cfg.zero_timeout_ns == 0u) {
        q->cfg.zero_timeout_ns = QDEC_ZERO_TIMEOUT_DEFAULT_NS;
    }
    if (q->cfg.zero_timeout_ns > (uint64_t)INT64_MAX) {
        q->cfg.zero_timeout_ns = (uint64_t)INT64_MAX;
    }
    if (q->cfg.vel_window_ns > (uint64_t)INT64_MAX) {
        q->cfg.vel_window_ns = (uint64_t)INT64_MAX;
    }
    q->table = table;
    q->cyc_mask = (cfg->mode == QDEC_X4) ? 3u : (cfg->mode == QDEC_X2) ? 1u : 0u;
    q->bits = bits;
    q->max_delta = cfg->max_delta ? cfg->max_delta : QDEC_MAX_DELTA(bits - 1u);
    q->now_raw = now_ns;
    q->now = 0;
    q->t_edge = 0;
    q->ring_n = 0; /* the first counted edge gives no estimate yet */
    q->rec = 0;
    q->t_rec = 0; /* ring_t[0] */
    q->rec_norm = 0;
    q->vel_fast = false;
    for (i = 0; i < QDEC_ILLEGAL_MAX; i++) {
        q->ill_t[i] = 0;
    }
    if (cfg->input == QDEC_INPUT_COUNTER) {
        q->last_raw = initial;
    } else {
        q->e.ab = (uint8_t)(initial & 3u);
        q->e.z = (uint8_t)((initial >> 2) & 1u);
        q->e.gated = (uint8_t)(q->e.z && (cfg->index_qual == QDEC_INDEX_UNGATED ||
                                          q->e.ab == cfg->index_qual));
        q->e.t_last = now_ns;
    }
    q->nm_fast = qdec_nm_fast(&q->cfg);
    q->fast = cfg->input == QDEC_INPUT_EDGES && cfg->glitch_ns == 0u && !cfg->vel_cycle;
    q->run_ok = cfg->glitch_ns == 0u && cfg->mode == QDEC_X4 && !cfg->vel_cycle;
    q->out.pos_nm_raw = qdec_counts_to_nm(q, 0);
    q->out.pos_nm = comp_correct(cfg->comp, q->out.pos_nm_raw, COMP_DIR_NONE);
    return true;
}

void qdec_clear_faults(qdec_t *q)
{
    q->out.faults = 0;
    q->ill_n = 0;
}

void qdec_set_offset_nm(qdec_t *q, pos_nm_t offset_nm)
{
    q->cfg.offset_nm = offset_nm;
    q->nm_fast = qdec_nm_fast(&q->cfg);
    q->last_rare--; /* the next sample takes the reference path: pos_nm_raw again */
}

void qdec_set_comp(qdec_t *q, const comp_table_t *comp)
{
    q->cfg.comp = comp;
}

pos_nm_t qdec_counts_to_nm_any(const qdec_t *q, int64_t counts)
{
    int64_t num = q->cfg.nm_per_count_num;
    int64_t den = q->cfg.nm_per_count_den; /* > 0 (qdec_init) */
    int64_t whole = counts, rem = 0;
    uint64_t uw, ur;
    int64_t nm;

    if (counts == (int64_t)(int32_t)counts && q->cfg.offset_nm > -((int64_t)1 << 62) &&
        q->cfg.offset_nm < ((int64_t)1 << 62)) {
        /* |counts * num| <= 2^62 and |offset| < 2^62: nothing saturates, and
         * rounding the whole quotient equals whole * num + round(rem * num /
         * den) below (whole and rem share the sign of counts: the same
         * half-away-from-zero rounding of the same value) */
        nm = (int64_t)(int32_t)counts * num;
        if (den != 1) {
            nm = fx_div_round64(nm, den);
        }
        return nm + q->cfg.offset_nm;
    }
    if (den != 1) { /* C division (toward zero), without the 64-bit divider */
        uw = fx_udivmod64(fx_uabs64(counts), (uint64_t)den, &ur);
        whole = (int64_t)((counts < 0) ? (uint64_t)0 - uw : uw);
        rem = (int64_t)((counts < 0) ? (uint64_t)0 - ur : ur);
    }
    uw = fx_uabs64(whole);
    /* |whole| * |num| > INT64_MAX; both below 2^31 never is */
    if (whole != 0 && ((uw | fx_uabs64(num)) >> 31) != 0 &&
        uw > (uint64_t)INT64_MAX / fx_uabs64(num)) {
        return ((whole < 0) != (num < 0)) ? INT64_MIN : INT64_MAX;
    }
    nm = whole * num;
    if (rem != 0) {
        nm = fx_sat_add64(nm, fx_div_round64(rem * num, den));
    }
    return fx_sat_add64(nm, q->cfg.offset_nm);
}
