/*
 * arc_ref.h - the reference of an arc chord: the exact overlay and the
 * rotation recurrence of cruise ticks (tick context).
 *
 * Specification
 * -------------
 * The drive cuts an arc into chords (arc_seg.h) that the planner times as
 * straight blocks. On every tick of a chord the arc reference replaces the
 * interpolator's chord reference (position, velocity, acceleration and
 * tangent of the plane axes, the geometry) by the exact arc: the point at
 * the same fraction of the chord's angle as the chord point's projection,
 * the tangent of the arc, the velocity feed-forward (path speed scaled by
 * arc / chord length) and the acceleration feed-forward (tangential plus
 * centripetal v^2 / r), with MOTION_GEOM_ARC (centre, current radius,
 * sense) for the contour-error controller.
 *
 * Exact path. arc_ref_exact() computes this with the general fixmath
 * functions (the oracle). arc_ref_tick() gives the same result bit for bit
 * with 32-bit products where the ranges allow, the chord fraction's
 * division by a per-chord reciprocal with an exact remainder correction,
 * and the square roots and the division of the speed terms only when their
 * inputs change (constant while cruising); it takes arc_ref_exact() for a
 * chord or a value outside those ranges.
 *
 * Arc overlay on cruise ticks. The exact path runs on every tick on which
 * the interpolator leaves its cruise fast path (chord and phase starts,
 * accelerations, stops) and re-anchors a recurrence used on its fast-path
 * ticks (interp_pos_only()), whose chord advance per tick ds is constant
 * (interp_cruise_ds_q32()): the angle then advances by delta = dth ds / len
 * per tick, and arc_ref_step() rotates the point's cosine and sine (q62) by
 * delta (sin delta and 1 - cos delta once per phase: 4 SMULL/SMLAL pairs
 * per tick), advances the radius by a constant step (spiral arcs) and
 * writes position, velocity v (-s, c), acceleration -v^2/r (c, s) and
 * tangent from the rotated point (no projection, no division, no sine). It
 * is re-anchored exactly at least every ARC_REF_ROT_TICKS ticks. Used on
 * chords with plane coordinates, chord and radius below 2^31 nm,
 * |dth| <= ARC_REF_DTH_MAX, path speed below 2^30 nm/s and v^2/r below
 * ARC_REF_AC_MAX (2^31 - 1 nm/s^2, 2.1 m/s^2; below 2^30 nm/s^2 on
 * spirals, whose v^2/r is recomputed along the chord) (the exact path
 * otherwise). Error bound against the exact
 * path of the same tick, per plane axis, for any chord angle up to
 * ARC_REF_DTH_MAX and radius r < 2^31 nm, with eps = (2 nm + r 2^-28) / r:
 *     position <= 2 nm + r 2^-28 (2 nm at 5 mm, 10 nm at 2.1 m),
 *     velocity <= 2 + eps |v| nm/s, acceleration <= 2 + eps |a| nm/s^2,
 *     tangent <= 2 + eps 2^30 (q30).
 * Its sources are the exact path's own rounding, not the recurrence: its
 * angle comes from the projection of the 1-nm-rounded chord point (up to
 * 0.71 nm of arc, times arc / chord), is rounded to one binary-angle unit
 * (r 1.5e-9) and fx_sincos has < 1 LSB of q30 (r 2^-30), against the
 * recurrence's exact linear angle (step within 2^-62 rad, rounding of the
 * rotation below 2^-61 per step: < 2^-52 r over ARC_REF_ROT_TICKS steps;
 * the anchor takes fx_sincos's values). Measured by test_arc_ref (every
 * tick of the recurrence against arc_ref_exact on the same chord point):
 * 1 nm, 5 nm/s at r = 5 mm, 20 mm/s (a helix like the firmware
 * benchmark's); 6 nm at r = 1.9e9 nm over chords of the maximum angle.
 *
 * Use per tick (the drive's reference_step):
 *   arc_ref_stepping(a)  true: this fast-path tick is a recurrence step:
 *                        arc_ref_step() (false returned: the next tick is
 *                        exact again, the interpolator must write the plane
 *                        axes' positions: interp_set_fast_skip(ip, 0));
 *   otherwise            arc_ref_tick() on a chord of an arc (true
 *                        returned: anchored, the interpolator's fast-path
 *                        ticks may skip the plane axes: arc_ref_plane_mask).
 *   arc_ref_stop(a)      on every tick that is not a fast-path tick of the
 *                        same segment (the recurrence is only valid there).
 *
 * Contexts: every function is tick context (the state is the tick's).
 */
#ifndef ARC_REF_H
#define ARC_REF_H

#include <stdbool.h>
#include <stdint.h>

#include "core_config.h"
#include "fixmath.h"
#include "interp.h"
#include "motion_ref.h"

/* Largest |dth| of a chord the fast path and the recurrence take (binary
 * angle: pi/32, the drive's largest chord angle). */
#define ARC_REF_DTH_MAX ((uint32_t)1 << 26)
/* Largest centripetal acceleration v^2/r (nm/s^2, exclusive) the
 * recurrence takes: its acceleration factor is an int32 (it was 2^29,
 * 0.54 m/s^2, until 2026-11-26, which left the HIL bench circle, R 20 mm at
 * 10 m/min, 1.39 m/s^2, and most arcs a machine cuts at speed on the exact
 * path every tick). */
#define ARC_REF_AC_MAX ((int64_t)INT32_MAX)
/* The recurrence is re-anchored on the exact path at least this often. */
#define ARC_REF_ROT_TICKS 256u

/* One chord of an arc (from arc_seg_chord), in the plane (u, v). */
typedef struct {
    uint8_t u, v;      /* the plane's axes                */
    int8_t sense;      /* +1 counter-clockwise, -1 cw     */
    pos_nm_t cu, cv;   /* centre                          */
    pos_nm_t r_a, r_b; /* radius at the chord's ends      */
    fx_angle_t th_a;   /* angle of the chord's start      */
    int64_t dth;       /* signed sweep of the chord       */
    pos_nm_t au, av;   /* chord start in the plane        */
    pos_nm_t bu, bv;   /* chord end in the plane          */
    q1_30_t k_arc;     /* arc length / chord length       */
} arc_chord_t;

/* Per-chord constants and per-value caches of the exact fast path. */
typedef struct {
    bool valid;     /* the chord fields are those of segment `tag`        */
    bool fast;      /* chord within the fast ranges (see arc_fast_setup)  */
    uint32_t tag;   /* interpolator segment tag                           */
    int32_t du, dv; /* chord vector in the plane, nm                       */
    uint8_t den_sh; /* fx_ratio_q30's normalising shift of num and den     */
    uint32_t den_s; /* (du^2 + dv^2) >> den_sh, in [1, 2^32)              */
    int64_t den;    /* du^2 + dv^2                                        */
    uint64_t rec;   /* floor(2^62 / den_s)                                */
    /* value caches: v_uv of (vel_u, vel_v); a_c of (v_uv, rad) */
    bool v_ok, ac_ok;
    int64_t v_key_u, v_key_v, v_uv;
    int64_t ac_key_v, ac_key_r, a_c;
} arc_fast_t;

/* Rotation recurrence of cruise ticks. The angle's cosine and sine (C, S,
 * q62) are rotated each tick by the phase's constant step delta:
 *     C' = C - c (1 - cos delta) - s sin delta
 *     S' = S - s (1 - cos delta) + c sin delta
 * where c, s are C, S rounded to q30 (the outputs' values) and the two
 * constants are q62 split as h 2^31 + l (0 <= l < 2^31): two SMULL/SMLAL
 * pairs per component, constant shifts. */
typedef struct {
    bool on;       /* C, S hold the last tick's arc point          */
    uint32_t left; /* steps before the next exact anchor          */
    int64_t C, S;  /* cos and sin of the angle, q62               */
    q1_30_t c, s;  /* ... rounded to q30                           */
    int64_t R;     /* radius, q32 nm                               */
    int32_t rad;   /* radius, nm (circle: constant)                */
    int32_t v_uv;  /* path speed in the plane, nm/s                */
    /* output factors (q30 products with c or s): velocity -+v_uv,
     * acceleration -v_uv^2 / rad (circle: constant), tangent -+m */
    int32_t kvu, kvv, ka, kmu, kmv;
    uint8_t u, v;    /* the plane's axes                        */
    int8_t sense;    /* the chord's sense (geometry)            */
    pos_nm_t cu, cv; /* the centre                              */
    /* step constants of a phase, and their key */
    bool k_ok;
    int64_t k_dth, k_ds, k_len, k_dr;
    int32_t dh, dl; /* sin delta, q62: dh 2^31 + dl             */
    int32_t eh, el; /* 1 - cos delta, q62: eh 2^31 + el         */
    int64_t dR;     /* radius change per tick, q32 nm (0: circle) */
} arc_rot_t;

typedef struct {
    arc_fast_t fast;
    arc_rot_t rot;
    /* the chord tangent's in-plane components and length (q30), cached */
    q1_30_t hyp_tu, hyp_tv, hyp_m;
    bool exact; /* test hook (drive_test_arc_exact): no recurrence */
} arc_ref_t;

/* Forget every cache and the recurrence (the exact-path hook stays). */
void arc_ref_reset(arc_ref_t *a);

/* The exact arc of chord g at the chord point of ch: r's plane axes
 * (pos, vel, acc, tangent) and geometry (the oracle). Only a's tangent
 * length cache changes. */
void arc_ref_exact(arc_ref_t *a, motion_ref_t *r, const motion_ref_t *ch, const arc_chord_t *g);

/* A tick of chord g (interpolator segment `tag`) that is not a recurrence
 * step: writes what arc_ref_exact() writes (geom_kept: r->geom holds what
 * this module wrote for the same segment last tick, only the radius is
 * rewritten), then anchors the recurrence when the interpolator's next
 * ticks may be cruise fast-path ticks of ip. True when anchored. */
bool arc_ref_tick(arc_ref_t *a, motion_ref_t *r, const motion_ref_t *ch, const arc_chord_t *g,
                  uint32_t tag, bool geom_kept, const interp_t *ip);

/* A fast-path tick of the anchored chord: rotate and write the outputs
 * (see above). False when the anchor is used up (the next tick must be
 * exact). */
bool arc_ref_step(arc_ref_t *a, motion_ref_t *r, bool geom_kept);

/* True when the next fast-path tick is a recurrence step. */
static inline bool arc_ref_stepping(const arc_ref_t *a)
{
    return a->rot.on && a->rot.left != 0u;
}

/* The recurrence no longer applies (a tick that is not a fast-path tick of
 * the anchored segment). */
static inline void arc_ref_stop(arc_ref_t *a)
{
    a->rot.on = false;
}

/* The plane axes of chord g as an interp_set_fast_skip() mask. */
static inline uint8_t arc_ref_plane_mask(const arc_chord_t *g)
{
    return (uint8_t)((1u << g->u) | (1u << g->v));
}

#endif /* ARC_REF_H */
