/* The 2-D map applied in the tick: comp2d_live.h. */
#include "comp2d_live.h"

const comp2d_anchor_t *CORE_SHARED comp2d_live_pub; /* main */

static struct {
    comp2d_map_t map;       /* main only                              */
    bool have;              /* a map is in use                        */
    bool fresh;             /* no anchor published for this map yet   */
    comp2d_anchor_t buf[2]; /* main fills the one not published       */
    pos_nm_t lo[2], hi[2];  /* anchor's cell (or held region), nm     */
    pos_nm_t ax, ay;        /* anchor, nm                             */
    uint32_t anchors;
    /* direction of each axis: its command (see the header) */
    int8_t dir[2]; /* +1 / -1, 0: none yet                   */
    int32_t w[2];  /* weight, q1_30, ramping towards dir     */
    uint32_t t_us; /* time of the last poll                  */
    bool started;
} lv; /* main */

void comp2d_live_init(void)
{
    comp2d_live_pub = 0;
    lv.have = false;
    lv.fresh = true;
    lv.anchors = 0u;
    lv.started = false;
}

void comp2d_live_weights(int32_t w[2])
{
    w[0] = lv.w[0];
    w[1] = lv.w[1];
}

/* Follow one axis: the direction of its command (held at rest); the
 * weight ramps to a new direction at 2 / COMP2D_LIVE_RAMP_US per us (as
 * the 1-D tables' reversal ramp). */
static void track(unsigned a, int64_t v, uint32_t dt_us)
{
    int64_t step = (int64_t)dt_us * ((int64_t)2 * COMP_W_ONE / COMP2D_LIVE_RAMP_US);
    int64_t target, w = lv.w[a];
    if (v != 0) {
        lv.dir[a] = v > 0 ? 1 : -1;
    }
    target = (int64_t)lv.dir[a] * COMP_W_ONE;
    w = w < target ? (w + step < target ? w + step : target)
                   : (w - step > target ? w - step : target);
    lv.w[a] = (int32_t)w;
}

void comp2d_live_set(const comp2d_map_t *m)
{
    if (m == 0) {
        comp2d_live_pub = 0; /* stop correcting at once */
        lv.have = false;
        return;
    }
    lv.map = *m; /* the tick reads only the anchor: keeps the old one */
    lv.have = true;
    lv.fresh = true;
    lv.started = false; /* directions from the next motion on */
}

const comp2d_map_t *comp2d_live_map(void)
{
    return lv.have ? &lv.map : 0;
}

uint32_t comp2d_live_anchors(void)
{
    return lv.anchors;
}

/* the anchor's cell along one coordinate, or the region held beyond it */
static void cell(pos_nm_t p, pos_nm_t p0, uint32_t d, unsigned n, pos_nm_t *lo, pos_nm_t *hi)
{
    pos_nm_t end = p0 + (pos_nm_t)(n - 1u) * d;
    if (p < p0) {
        *lo = INT64_MIN;
        *hi = p0;
    } else if (p >= end) {
        *lo = end;
        *hi = INT64_MAX;
    } else {
        *lo = p0 + (p - p0) / d * d;
        *hi = *lo + d;
    }
}

static bool near(pos_nm_t p, pos_nm_t a, pos_nm_t lo, pos_nm_t hi, uint32_t step)
{
    pos_nm_t m = (pos_nm_t)(step / COMP2D_LIVE_MOVE_DIV);
    return p >= lo && p < hi && p - a <= m && a - p <= m;
}

void comp2d_live_poll(const pos_nm_t p[2], const int64_t v[2], uint32_t now_us)
{
    q1_30_t w[2];
    comp2d_lin_t l;
    comp2d_anchor_t *b;
    const comp2d_anchor_t *cur = comp2d_live_pub;
    unsigned c;
    if (!lv.started) {
        lv.started = true;
        lv.t_us = now_us;
        lv.dir[0] = lv.dir[1] = 0;
        lv.w[0] = lv.w[1] = 0;
    }
    track(0u, v[0], now_us - lv.t_us);
    track(1u, v[1], now_us - lv.t_us);
    lv.t_us = now_us;
    if (!lv.have) {
        return;
    }
    w[0] = lv.w[0];
    w[1] = lv.w[1];
    if (!lv.fresh && cur != 0 && w[0] == cur->wx && w[1] == cur->wy &&
        near(p[0], lv.ax, lv.lo[0], lv.hi[0], lv.map.dx) &&
        near(p[1], lv.ay, lv.lo[1], lv.hi[1], lv.map.dy)) {
        return;
    }
    comp2d_linearize(&lv.map, p, w, &l);
    b = cur == &lv.buf[0] ? &lv.buf[1] : &lv.buf[0];
    b->x0 = (int32_t)(uint32_t)p[0];
    PREEMPT_POINT();
    b->y0 = (int32_t)(uint32_t)p[1];
    b->wx = w[0];
    b->wy = w[1];
    PREEMPT_POINT();
    for (c = 0; c < 2u; c++) {
        /* k = mid + w * h (w q1_30 times 4 h: the high word) */
        b->k[c] =
            l.mid[c] + comp2d_live_mulhi(w[0], l.hx[c] * 4) + comp2d_live_mulhi(w[1], l.hy[c] * 4);
        PREEMPT_POINT();
        b->gx[c] = l.gx[c];
        b->gy[c] = l.gy[c];
        PREEMPT_POINT();
    }
    CORE_BARRIER();
    comp2d_live_pub = b;
    PREEMPT_POINT();
    lv.ax = p[0];
    lv.ay = p[1];
    cell(p[0], lv.map.x0, lv.map.dx, lv.map.nx, &lv.lo[0], &lv.hi[0]);
    cell(p[1], lv.map.y0, lv.map.dy, lv.map.ny, &lv.lo[1], &lv.hi[1]);
    lv.fresh = false;
    lv.anchors++;
}
