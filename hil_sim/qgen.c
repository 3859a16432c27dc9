/* qgen.c - quadrature generator (specification in qgen.h). */
#include "qgen.h"

#include <stddef.h>

__extension__ typedef __int128 qgen_i128;

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
}

void qgen_set_index(qgen_t *g, int64_t index_pos, uint64_t period, uint32_t before, uint32_t after)
{
    g->has_index = true;
    g->index_pos = index_pos;
    g->index_period = period;
    g->z_before = before;
    g->z_after = after;
    g->lines = qgen_lines_at(g, g->count);
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
    for (i = 0; i < 4u; i++) {
        g->edge_off[i] = off[i];
    }
    g->count = qgen_count_of(g, g->x);
    g->lines = qgen_lines_at(g, g->count);
    return true;
}

uint64_t qgen_move_to(qgen_t *g, qgen_pos_t x1, uint64_t t1_ns)
{
    qgen_pos_t x0 = g->x;
    uint64_t t0 = g->t;
    uint64_t dt = (t1_ns > t0) ? t1_ns - t0 : 0u;
    qgen_i128 dx = (qgen_i128)x1 - (qgen_i128)x0;
    uint64_t n = 0;

    for (;;) {
        int64_t next;
        qgen_i128 b;
        uint64_t t;

        if (dx > 0) {
            b = qgen_boundary(g, g->count + 1);
            if ((qgen_i128)x1 < b) {
                break;
            }
            next = g->count + 1;
        } else if (dx < 0) {
            b = qgen_boundary(g, g->count);
            if ((qgen_i128)x1 >= b) {
                break;
            }
            next = g->count - 1;
        } else {
            break;
        }
        t = t0 + (uint64_t)((b - (qgen_i128)x0) * (qgen_i128)dt / dx);
        g->count = next;
        qgen_emit(g, qgen_lines_at(g, g->count), t);
        g->edges++;
        n++;
    }
    g->x = x1;
    g->t = t0 + dt;
    return n;
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
