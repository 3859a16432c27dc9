/*
 * arc_ref.c - the reference of an arc chord (specification in arc_ref.h).
 */
#include "arc_ref.h"

void arc_ref_reset(arc_ref_t *a)
{
    a->fast.valid = a->fast.v_ok = a->fast.ac_ok = false;
    a->rot.on = a->rot.k_ok = false;
    a->hyp_tu = a->hyp_tv = a->hyp_m = 0; /* fx_hypot2(0, 0) == 0 */
}

/* Per-chord constants of the fast path. The fast path needs the chord
 * start, end and vector in the plane and the radius within int32
 * (|.| < 2.1 m), a non-degenerate chord and |dth| <= ARC_REF_DTH_MAX;
 * other chords take arc_ref_exact() every tick. */
static void arc_fast_setup(arc_fast_t *a, const arc_chord_t *g, uint32_t tag)
{
    int64_t du = g->bu - g->au, dv = g->bv - g->av, den;
    unsigned sh = 0;

    a->valid = true;
    a->tag = tag;
    a->fast = false;
    if (du != (int32_t)du || dv != (int32_t)dv || g->au != (int32_t)g->au ||
        g->av != (int32_t)g->av || g->r_a != (int32_t)g->r_a || g->r_b != (int32_t)g->r_b ||
        (g->r_b - g->r_a) != (int32_t)(g->r_b - g->r_a) ||
        fx_sat_abs64(g->dth) > (int64_t)ARC_REF_DTH_MAX) {
        return;
    }
    den = (int64_t)du * du + (int64_t)dv * dv; /* < 2^63: exact, as fx_mul64_sat */
    if (den <= 0) {
        return;
    }
    a->du = (int32_t)du;
    a->dv = (int32_t)dv;
    a->den = den;
    while ((den >> sh) >= ((int64_t)1 << 32)) {
        sh++;
    }
    a->den_sh = (uint8_t)sh;
    a->den_s = (uint32_t)(den >> sh);
    a->rec = fx_recip62(a->den_s);
    a->fast = true;
}

/* The reference's geometry: an arc in the plane (u, v) about (cu, cv). */
static inline void arc_geom(motion_ref_t *r, uint8_t u, uint8_t v, pos_nm_t cu, pos_nm_t cv,
                            int64_t rad, int8_t sense)
{
    r->geom.kind = MOTION_GEOM_ARC;
    r->geom.plane_u = u;
    r->geom.plane_v = v;
    r->geom.centre_u = cu;
    r->geom.centre_v = cv;
    r->geom.radius = rad;
    r->geom.sense = sense;
}

/* Length of the chord tangent's in-plane part (q30), recomputed only when
 * the tangent changes (once per segment). */
static inline q1_30_t chord_tangent_len(arc_ref_t *a, const motion_ref_t *ch, uint8_t u, uint8_t v)
{
    if (ch->geom.tangent[u] != a->hyp_tu || ch->geom.tangent[v] != a->hyp_tv) {
        a->hyp_tu = ch->geom.tangent[u];
        a->hyp_tv = ch->geom.tangent[v];
        a->hyp_m = (q1_30_t)fx_hypot2(a->hyp_tu, a->hyp_tv);
    }
    return a->hyp_m;
}

/* v^2 / rad (nm/s^2, division rule; 0 for rad <= 0) as arc_ref_exact()
 * computes it. */
static inline int64_t centripetal(int64_t v_uv, int64_t rad)
{
    if (v_uv < ((int64_t)1 << 31)) {
        return fx_div_round64(v_uv * v_uv, rad);
    }
    return fx_div_round64(fx_mul64_shift(v_uv, v_uv, 16), rad) << 16;
}

/* centripetal(), cached while v and rad are unchanged. */
static inline int64_t arc_centripetal(arc_fast_t *a, int64_t v_uv, int64_t rad)
{
    if (rad <= 0) {
        return 0;
    }
    if (!a->ac_ok || a->ac_key_v != v_uv || a->ac_key_r != rad) {
        a->ac_key_v = v_uv;
        a->ac_key_r = rad;
        a->a_c = centripetal(v_uv, rad);
        a->ac_ok = true;
    }
    return a->a_c;
}

/* arc_ref_exact() for a chord with arc_fast_t.fast: the same result, bit
 * for bit. False (nothing written) when a value leaves the fast ranges; the
 * caller then runs arc_ref_exact(). geom_kept: see arc_ref_tick. */
static bool arc_fast(arc_ref_t *ar, motion_ref_t *r, const motion_ref_t *ch, const arc_chord_t *g,
                     bool geom_kept, q1_30_t *so, q1_30_t *co, int64_t *rado)
{
    arc_fast_t *a = &ar->fast;
    uint8_t u = g->u, v = g->v;
    int64_t pu = ch->pos[u] - g->au, pv = ch->pos[v] - g->av;
    int64_t num, f, p, rad, v_uv, a_t, a_c;
    fx_angle_t th;
    q1_30_t s, c, m, tu, tv;

    if (pu != (int32_t)pu || pv != (int32_t)pv) {
        return false;
    }
    /* f = fx_ratio_q30(num, den): round(num_s * 2^30 / den_s) after the
     * same normalising shift, by the reciprocal and an exact remainder */
    num = (int64_t)(int32_t)pu * a->du + (int64_t)(int32_t)pv * a->dv;
    if (num <= 0) {
        f = 0;
    } else if (num >= a->den) {
        f = FX_ONE_Q30;
    } else {
        /* num < den: num >> den_sh <= den_s < 2^32 */
        f = fx_div_q30_rec((uint32_t)(num >> a->den_sh), a->den_s, a->rec);
    }
    p = (int64_t)(int32_t)g->dth * f; /* |.| < 2^57 */
    th = g->th_a + (fx_angle_t)(uint64_t)((p >> 30) + ((p >> 29) & 1));
    if (g->r_b == g->r_a) {
        rad = g->r_a; /* a circle: round(0 * f / 2^30) == 0 */
    } else {
        p = (int64_t)(int32_t)(g->r_b - g->r_a) * f;
        rad = g->r_a + ((p >> 30) + ((p >> 29) & 1));
    }
    fx_sincos(th, &s, &c);
    /* rad lies between r_a and r_b, both int32 (arc_fast_setup) */
    r->pos[u] = g->cu + fx_mul32_q30((int32_t)rad, c);
    r->pos[v] = g->cv + fx_mul32_q30((int32_t)rad, s);
    /* unit tangent in the plane, scaled by the chord tangent's in-plane part */
    m = chord_tangent_len(ar, ch, u, v);
    tu = (q1_30_t)(g->sense > 0 ? -s : s);
    tv = (q1_30_t)(g->sense > 0 ? c : -c);
    /* path speed and tangential acceleration in the plane (arc / chord) */
    if (!a->v_ok || a->v_key_u != ch->vel[u] || a->v_key_v != ch->vel[v]) {
        a->v_key_u = ch->vel[u];
        a->v_key_v = ch->vel[v];
        a->v_uv = fx_mul64x32_shift(fx_hypot2(ch->vel[u], ch->vel[v]), g->k_arc, 30);
        a->v_ok = true;
    }
    v_uv = a->v_uv;
    if (ch->acc[u] == 0 && ch->acc[v] == 0) {
        a_t = 0; /* fx_hypot2(0, 0) */
    } else {
        int64_t dot = fx_sat_add64(fx_mul64x32_shift(ch->acc[u], ch->geom.tangent[u], 30),
                                   fx_mul64x32_shift(ch->acc[v], ch->geom.tangent[v], 30));
        a_t = fx_mul64x32_shift(fx_hypot2(ch->acc[u], ch->acc[v]), g->k_arc, 30);
        if (dot < 0) {
            a_t = -a_t;
        }
    }
    a_c = arc_centripetal(a, v_uv, rad);
    *so = s;
    *co = c;
    *rado = rad;
    r->vel[u] = fx_mul64x32_shift30(v_uv, tu);
    r->vel[v] = fx_mul64x32_shift30(v_uv, tv);
    if (a_t == 0) { /* cruising: fx_mul64x32_shift30(0, x) == 0 */
        r->acc[u] = -fx_mul64x32_shift30(a_c, c);
        r->acc[v] = -fx_mul64x32_shift30(a_c, s);
    } else {
        r->acc[u] = fx_mul64x32_shift30(a_t, tu) - fx_mul64x32_shift30(a_c, c);
        r->acc[v] = fx_mul64x32_shift30(a_t, tv) - fx_mul64x32_shift30(a_c, s);
    }
    r->geom.tangent[u] = (q1_30_t)fx_mul32_q30(tu, m);
    r->geom.tangent[v] = (q1_30_t)fx_mul32_q30(tv, m);
    if (geom_kept) {
        r->geom.radius = rad;
    } else {
        arc_geom(r, u, v, g->cu, g->cv, rad, g->sense);
    }
    return true;
}

void arc_ref_exact(arc_ref_t *a, motion_ref_t *r, const motion_ref_t *ch, const arc_chord_t *g)
{
    uint8_t u = g->u, v = g->v;
    int64_t du = g->bu - g->au, dv = g->bv - g->av;
    int64_t pu = ch->pos[u] - g->au, pv = ch->pos[v] - g->av;
    int64_t num = fx_sat_add64(fx_mul64_sat(pu, du), fx_mul64_sat(pv, dv));
    int64_t den = fx_sat_add64(fx_mul64_sat(du, du), fx_mul64_sat(dv, dv));
    int64_t f = fx_ratio_q30(num, den);
    fx_angle_t th = g->th_a + (fx_angle_t)(uint64_t)fx_round_shift64(g->dth * f, 30);
    int64_t rad = g->r_a + fx_round_shift64((g->r_b - g->r_a) * f, 30);
    q1_30_t s, c, m, tu, tv;
    int64_t v_uv, a_t, a_c, dot;

    fx_sincos(th, &s, &c);
    r->pos[u] = g->cu + fx_mul64x32_shift(rad, c, 30);
    r->pos[v] = g->cv + fx_mul64x32_shift(rad, s, 30);
    /* unit tangent in the plane, scaled by the chord tangent's in-plane part */
    m = chord_tangent_len(a, ch, u, v);
    tu = (q1_30_t)(g->sense > 0 ? -s : s);
    tv = (q1_30_t)(g->sense > 0 ? c : -c);
    /* path speed and tangential acceleration in the plane (arc / chord) */
    v_uv = fx_mul64x32_shift(fx_hypot2(ch->vel[u], ch->vel[v]), g->k_arc, 30);
    dot = fx_sat_add64(fx_mul64x32_shift(ch->acc[u], ch->geom.tangent[u], 30),
                       fx_mul64x32_shift(ch->acc[v], ch->geom.tangent[v], 30));
    a_t = fx_mul64x32_shift(fx_hypot2(ch->acc[u], ch->acc[v]), g->k_arc, 30);
    if (dot < 0) {
        a_t = -a_t;
    }
    a_c = rad > 0 ? centripetal(v_uv, rad) : 0;
    r->vel[u] = fx_mul64x32_shift(v_uv, tu, 30);
    r->vel[v] = fx_mul64x32_shift(v_uv, tv, 30);
    r->acc[u] = fx_mul64x32_shift(a_t, tu, 30) - fx_mul64x32_shift(a_c, c, 30);
    r->acc[v] = fx_mul64x32_shift(a_t, tv, 30) - fx_mul64x32_shift(a_c, s, 30);
    r->geom.tangent[u] = (q1_30_t)fx_mul64x32_shift(tu, m, 30);
    r->geom.tangent[v] = (q1_30_t)fx_mul64x32_shift(tv, m, 30);
    arc_geom(r, u, v, g->cu, g->cv, rad, g->sense);
}

/* ---- rotation recurrence on cruise ticks ------------------------------------ */

/* v (q62, |v| < 2^61) as h 2^31 + l with 0 <= l < 2^31. */
static void rot_split(int64_t v, int32_t *h, int32_t *l)
{
    *h = (int32_t)(v >> 31);
    *l = (int32_t)(v & 0x7FFFFFFF);
}

/* floor((x (h 2^31 + l) + y (h2 2^31 + l2)) / 2^30) to within 1: the sum of
 * two q30 values (|x|, |y| <= 2^30) times split q62 constants (|h|, |h2|
 * <= 2^30), in q62. */
static inline int64_t rot_mul2(int32_t x, int32_t h, int32_t l, int32_t y, int32_t h2, int32_t l2)
{
    int64_t hi = (int64_t)x * h + (int64_t)y * h2; /* |.| <= 2^61 */
    int64_t lo = (int64_t)x * l + (int64_t)y * l2; /* |.| < 2^62  */

    return hi * 2 + (lo >> 30);
}

/* Step constants of the interpolator's cruise phase on chord g (segment
 * length len, nm): the path advances by ds q32 nm per fast-path tick
 * (interp_cruise_ds_q32), the chord fraction by ds / (len 2^32), the angle
 * by delta = dth ds / len (binary angle * 2^32, rounded) and the radius by
 * dR = (r_b - r_a) ds / len (q32 nm); sin and 1 - cos of delta
 * (fx_sin_vers_small). Cached while the key (dth, ds, len, r_b - r_a)
 * is unchanged. False when out of range (no recurrence). */
static bool arc_rot_consts(arc_rot_t *t, const arc_chord_t *g, const interp_t *ip)
{
    int64_t len = interp_seg_len(ip);
    int64_t ds = interp_cruise_ds_q32(ip);
    int64_t d;
    uint64_t sn, e;
    int64_t dr = g->r_b - g->r_a;

    if (ds < 0 || len <= 0) {
        return false;
    }
    if (t->k_ok && t->k_dth == g->dth && t->k_ds == ds && t->k_len == len && t->k_dr == dr) {
        return true;
    }
    t->k_ok = false;
    d = fx_muldiv64(g->dth, ds, len);
    if (fx_sat_abs64(d) > ((int64_t)ARC_REF_DTH_MAX << 32)) {
        return false;
    }
    fx_sin_vers_small(fx_uabs64(d), &sn, &e);
    rot_split(d < 0 ? -(int64_t)sn : (int64_t)sn, &t->dh, &t->dl);
    rot_split((int64_t)e, &t->eh, &t->el);
    t->dR = dr == 0 ? 0 : fx_muldiv64(dr, ds, len);
    t->k_dth = g->dth;
    t->k_ds = ds;
    t->k_len = len;
    t->k_dr = dr;
    t->k_ok = true;
    return true;
}

/* Anchor the recurrence on this tick's exact arc point (sine s, cosine c,
 * radius rad from arc_fast) when the interpolator's next ticks may take
 * its cruise fast path. True when anchored. */
static bool arc_rot_anchor(arc_ref_t *a, const arc_chord_t *g, q1_30_t s, q1_30_t c, int64_t rad,
                           const interp_t *ip)
{
    arc_rot_t *t = &a->rot;
    int64_t v_uv = a->fast.v_uv, a_c = a->fast.a_c;

    t->on = false;
    /* arc_fast filled the caches for this v_uv and rad; 32-bit products
     * below need v_uv and v_uv^2 / r (here and along the chord) < 2^31 */
    if (a->exact || !interp_cruise_next(ip) || g->r_a >= INT32_MAX - 1 || g->r_b >= INT32_MAX - 1 ||
        rad <= 0 || rad >= INT32_MAX - 1 || v_uv < 0 || v_uv >= ((int64_t)1 << 30) ||
        !a->fast.ac_ok || a_c < 0 || a_c >= ARC_REF_AC_MAX || !arc_rot_consts(t, g, ip)) {
        return false;
    }
    if (t->dR != 0 && (v_uv * v_uv) / (g->r_a < g->r_b ? g->r_a : g->r_b) >= ((int64_t)1 << 30)) {
        return false; /* a spiral: v^2 / r along the chord must stay < 2^31 */
    }
    t->C = (int64_t)c * ((int64_t)1 << 32);
    t->S = (int64_t)s * ((int64_t)1 << 32);
    t->c = c;
    t->s = s;
    t->R = rad * ((int64_t)1 << 32);
    t->rad = (int32_t)rad;
    t->v_uv = (int32_t)v_uv;
    /* tu = -s, tv = c counter-clockwise (s, -c clockwise), as arc_fast */
    t->kvu = g->sense > 0 ? -(int32_t)v_uv : (int32_t)v_uv;
    t->kvv = -t->kvu;
    t->ka = -(int32_t)a_c;
    t->kmu = g->sense > 0 ? -a->hyp_m : a->hyp_m;
    t->kmv = -t->kmu;
    t->u = g->u;
    t->v = g->v;
    t->sense = g->sense;
    t->cu = g->cu;
    t->cv = g->cv;
    t->left = ARC_REF_ROT_TICKS;
    t->on = true;
    return true;
}

bool arc_ref_tick(arc_ref_t *a, motion_ref_t *r, const motion_ref_t *ch, const arc_chord_t *g,
                  uint32_t tag, bool geom_kept, const interp_t *ip)
{
    q1_30_t s, c;
    int64_t rad;

    if (!a->fast.valid || a->fast.tag != tag) {
        arc_fast_setup(&a->fast, g, tag);
    }
    a->rot.on = false;
    if (a->fast.fast && arc_fast(a, r, ch, g, geom_kept, &s, &c, &rad)) {
        return arc_rot_anchor(a, g, s, c, rad, ip);
    }
    arc_ref_exact(a, r, ch, g);
    return false;
}

/* Keeps GCC from loading every output factor before the first store (it
 * then runs out of registers and spills): outputs in pairs. */
#if defined(__GNUC__)
#define ARC_REF_SEQ() __asm__ volatile("" ::: "memory")
#else
#define ARC_REF_SEQ()
#endif

/* A cruise fast-path tick of an anchored chord: rotate (C, S) by delta and
 * write what arc_fast() writes, from the rotated point. The path speed
 * v_uv, the chord tangent's in-plane length and v^2 / r come from the
 * caches arc_fast filled at the anchor (the chord reference's velocity and
 * tangent are constant in the phase, its acceleration 0). */
bool arc_ref_step(arc_ref_t *a, motion_ref_t *r, bool geom_kept)
{
    arc_rot_t *t = &a->rot;
    uint8_t u, v;
    q1_30_t c = t->c, s = t->s;
    int64_t C = t->C - rot_mul2(c, t->eh, t->el, s, t->dh, t->dl);
    int64_t S = t->S - rot_mul2(s, t->eh, t->el, -c, t->dh, t->dl);
    int32_t rad = t->rad;

    t->C = C;
    t->S = S;
    /* round(C / 2^32) from the two words (32-bit values for SMULL below) */
    c = (q1_30_t)((int32_t)(C >> 32) + (int32_t)((uint32_t)C >> 31));
    s = (q1_30_t)((int32_t)(S >> 32) + (int32_t)((uint32_t)S >> 31));
    t->c = c;
    t->s = s;
    t->left--;
    if (t->dR != 0) { /* a spiral */
        t->R += t->dR;
        rad = (int32_t)((t->R + ((int64_t)1 << 31)) >> 32);
        t->rad = rad;
        t->ka = -(int32_t)arc_centripetal(&a->fast, t->v_uv, rad);
    }
#if defined(__GNUC__)
    /* re-read c and s as 32-bit fields: GCC then multiplies them with one
     * SMULL each (it widens the registers' values to 64 x 64 otherwise) */
    __asm__ volatile("" ::: "memory");
    c = t->c;
    s = t->s;
    rad = t->rad;
#endif
    u = t->u;
    v = t->v;
    r->pos[u] = t->cu + fx_mul32_q30(rad, c);
    r->pos[v] = t->cv + fx_mul32_q30(rad, s);
    ARC_REF_SEQ();
    r->vel[u] = fx_mul32_q30(t->kvu, s);
    r->vel[v] = fx_mul32_q30(t->kvv, c);
    ARC_REF_SEQ();
    r->acc[u] = fx_mul32_q30(t->ka, c);
    r->acc[v] = fx_mul32_q30(t->ka, s);
    ARC_REF_SEQ();
    r->geom.tangent[u] = (q1_30_t)fx_mul32_q30(t->kmu, s);
    r->geom.tangent[v] = (q1_30_t)fx_mul32_q30(t->kmv, c);
    if (geom_kept) {
        r->geom.radius = rad;
    } else {
        arc_geom(r, u, v, t->cu, t->cv, rad, t->sense);
    }
    return t->left != 0u;
}
