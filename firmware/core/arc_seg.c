/*
 * arc_seg.c - chord segmentation of arc blocks (specification in arc_seg.h;
 * drive_arc_chords in drive.h).
 */
#include "arc_seg.h"

/* arc chords stay within the arc reference's fast range */
typedef char arc_seg_angle_ok[DRIVE_ARC_SEG_MAX_ANGLE <= ARC_REF_DTH_MAX ? 1 : -1];

#define ARC_SEG_ANGLE_K 683565276ll /* 2^32 / (2 pi): binary angle per radian */

static void plane_axes(drive_plane_t p, uint8_t *u, uint8_t *v, uint8_t *w)
{
    switch (p) {
    case DRIVE_PLANE_ZX:
        *u = 2;
        *v = 0;
        *w = 1;
        break;
    case DRIVE_PLANE_YZ:
        *u = 1;
        *v = 2;
        *w = 0;
        break;
    default:
        *u = 0;
        *v = 1;
        *w = 2;
        break;
    }
}

/* Chord angle for an arc of radius r at the programmed feed. */
static int64_t arc_seg_angle(int64_t r, int64_t feed, int64_t tol, uint32_t tick_hz)
{
    int64_t a_tol, a_tick, x, dist;
    if (r <= tol) {
        return DRIVE_ARC_SEG_MAX_ANGLE;
    }
    /* sagitta r (1 - cos(a/2)) ~ r a^2 / 8 = tol: a = sqrt(8 tol / r) rad */
    x = fx_div_shift64(8 * tol, r, 40); /* exact 128-bit numerator (tol up to 1e9) */
    a_tol = (int64_t)fx_isqrt64((uint64_t)x) * 651899 / 1000; /* * 2^32/(2 pi) / 2^20 */
    dist = feed * DRIVE_ARC_SEG_TICKS / (int64_t)tick_hz;
    a_tick = fx_mul64_shift(dist, ARC_SEG_ANGLE_K, 0) / r;
    if (a_tick > a_tol) {
        a_tol = a_tick;
    }
    if (a_tol > (int64_t)DRIVE_ARC_SEG_MAX_ANGLE) {
        a_tol = DRIVE_ARC_SEG_MAX_ANGLE;
    }
    return a_tol < 1 ? 1 : a_tol;
}

/* d * k / n for 0 <= k <= n, truncated as C divides; a product that would
 * overflow (a span of thousands of km, or of many turns) takes the 128-bit
 * path, which rounds to nearest instead. */
static int64_t arc_lerp(int64_t d, uint32_t k, int64_t n)
{
    int64_t lim = INT64_MAX / n;

    if (d > lim || d < -lim) {
        return fx_muldiv64(d, (int64_t)k, n);
    }
    return d * (int64_t)k / n;
}

/* Point k of n of the arc, its angle and radius. */
static void arc_point(const arc_seg_t *a, const drive_block_t *b, uint32_t k,
                      pos_nm_t out[CORE_AXES], fx_angle_t *th, pos_nm_t *rad)
{
    unsigned i;
    int64_t n = a->n_seg;
    q1_30_t s, c;
    for (i = 0; i < CORE_AXES; i++) {
        out[i] = a->start[i] + arc_lerp(b->target[i] - a->start[i], k, n);
    }
    *th = a->th_s + (fx_angle_t)(uint64_t)arc_lerp(a->sweep, k, n);
    *rad = a->r_s + arc_lerp(a->r_e - a->r_s, k, n);
    if (k == a->n_seg) {
        for (i = 0; i < CORE_AXES; i++) {
            out[i] = b->target[i];
        }
        return;
    }
    fx_sincos(*th, &s, &c);
    out[a->u] = b->centre_u + fx_mul64x32_shift(*rad, c, 30);
    out[a->v] = b->centre_v + fx_mul64x32_shift(*rad, s, 30);
}

bool arc_seg_setup(arc_seg_t *a, const drive_block_t *b, const pos_nm_t start[CORE_AXES],
                   unsigned axes, uint32_t tick_hz, int64_t chord_nm)
{
    int64_t su, sv, eu, ev, sw, seg;
    fx_angle_t the;
    uint32_t d;
    unsigned i;
    if (b->feed_nm_s <= 0 || b->feed_nm_s > SC_V_LIMIT || (b->sense != 1 && b->sense != -1) ||
        (unsigned)b->plane > DRIVE_PLANE_YZ || tick_hz == 0 || chord_nm <= 0) {
        return false;
    }
    plane_axes(b->plane, &a->u, &a->v, &a->w);
    if (a->u >= axes || a->v >= axes) {
        return false;
    }
    for (i = 0; i < CORE_AXES; i++) {
        a->start[i] = start[i];
    }
    su = a->start[a->u] - b->centre_u;
    sv = a->start[a->v] - b->centre_v;
    eu = b->target[a->u] - b->centre_u;
    ev = b->target[a->v] - b->centre_v;
    if (fx_sat_abs64(su) >= SC_LEN_MAX || fx_sat_abs64(sv) >= SC_LEN_MAX ||
        fx_sat_abs64(eu) >= SC_LEN_MAX || fx_sat_abs64(ev) >= SC_LEN_MAX) {
        return false;
    }
    a->r_s = fx_hypot2(su, sv);
    a->r_e = fx_hypot2(eu, ev);
    if (a->r_s <= 0 || a->r_e <= 0 || fx_sat_abs64(a->r_s - a->r_e) > DRIVE_ARC_RADIUS_TOL_NM) {
        return false;
    }
    a->th_s = fx_atan2(sv, su);
    the = fx_atan2(ev, eu);
    d = b->sense > 0 ? (uint32_t)(the - a->th_s) : (uint32_t)(a->th_s - the);
    sw = d == 0 ? ((int64_t)1 << 32) : (int64_t)d;
    a->sweep = b->sense > 0 ? sw : -sw;
    seg = arc_seg_angle((a->r_s + a->r_e) / 2, b->feed_nm_s, chord_nm, tick_hz);
    a->n_seg = (uint32_t)((sw + seg - 1) / seg);
    if (a->n_seg < 1) {
        a->n_seg = 1;
    }
    a->done_seg = 0;
    return true;
}

void arc_seg_chord(const arc_seg_t *a, const drive_block_t *b, uint32_t k, pos_nm_t end[CORE_AXES],
                   arc_chord_t *c)
{
    pos_nm_t p[CORE_AXES];
    fx_angle_t tha, thb;
    pos_nm_t ra, rb;
    int64_t chord, arclen;

    arc_point(a, b, k + 1u, end, &thb, &rb);
    if (c == NULL) {
        return;
    }
    arc_point(a, b, k, p, &tha, &ra);
    c->u = a->u;
    c->v = a->v;
    c->sense = b->sense;
    c->cu = b->centre_u;
    c->cv = b->centre_v;
    c->r_a = ra;
    c->r_b = rb;
    c->th_a = tha;
    c->dth = a->sweep / (int64_t)a->n_seg;
    c->au = p[a->u];
    c->av = p[a->v];
    c->bu = end[a->u];
    c->bv = end[a->v];
    chord = fx_hypot2(end[a->u] - p[a->u], end[a->v] - p[a->v]);
    /* arc length = r * |dth| * 2 pi / 2^32 = r * (|dth| * pi/2 * 2^30) >> 30 */
    arclen =
        fx_mul64_shift((ra + rb) / 2, fx_round_shift64(fx_sat_abs64(c->dth) * 1686629713, 30), 30);
    c->k_arc = chord > 0 ? (q1_30_t)fx_div_round64(fx_mul64_shift(arclen, FX_ONE_Q30, 0), chord)
                         : (q1_30_t)FX_ONE_Q30;
}

uint32_t drive_arc_chords(const drive_block_t *b, const pos_nm_t start[CORE_AXES], unsigned axes,
                          uint32_t tick_hz, int64_t chord_nm, pos_nm_t *out, uint32_t cap)
{
    drive_block_t bb;
    arc_seg_t a;
    uint32_t k;
    unsigned i;
    if (b == NULL || start == NULL || b->kind != DRIVE_BLOCK_ARC || axes < 1 || axes > CORE_AXES) {
        return 0;
    }
    bb = *b;
    for (i = axes; i < CORE_AXES; i++) {
        bb.target[i] = start[i];
    }
    if (!arc_seg_setup(&a, &bb, start, axes, tick_hz,
                       chord_nm == 0 ? DRIVE_ARC_CHORD_NM : chord_nm)) {
        return 0;
    }
    for (k = 0; k < a.n_seg && k < cap && out != NULL; k++) {
        arc_seg_chord(&a, &bb, k, &out[k * CORE_AXES], NULL);
    }
    return a.n_seg;
}
