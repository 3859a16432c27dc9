/*
 * motion_ref.h - the reference the interpolator hands the servo loops each tick.
 *
 * Written by the interpolator (interp_, tick context) once per tick and read
 * by the servo tick (servo_) in the same tick; nothing else writes it.
 * On a cruise fast-path tick (interp_t.ref_pos_only) interp_tick writes only
 * pos[]: vel, acc and geom are constant within the phase and stay as the
 * tick before wrote them, so the writer keeps one motion_ref_t per
 * interpolator and changes none of its fields. The drive copies it (all
 * fields, or pos only on such ticks) into the reference it adjusts (arc
 * overlay, stop scaling, friction feed-forward) and hands the servo.
 * Units are those of docs/conventions.md.
 */
#ifndef MOTION_REF_H
#define MOTION_REF_H

#include "core_config.h"
#include "fixmath.h"

typedef enum {
    MOTION_GEOM_NONE = 0, /* at rest or no path: the CEC holds its output at zero */
    MOTION_GEOM_LINE,     /* straight segment through `start` along `tangent`     */
    MOTION_GEOM_ARC       /* arc in the plane (plane_u, plane_v) about `centre`   */
} motion_geom_kind_t;

typedef struct {
    motion_geom_kind_t kind;
    /* Unit tangent of the path at the reference point, q1_30 per axis
     * (direction of travel). Zero vector when kind == MOTION_GEOM_NONE. */
    q1_30_t tangent[CORE_AXES];
    /* LINE: a point on the line (the segment start), nm. */
    pos_nm_t start[CORE_AXES];
    /* ARC: the two axes of the active plane (G17: 0,1; G18: 2,0; G19: 1,2),
     * the centre in that plane (nm), the radius (nm) and the sense:
     * +1 counter-clockwise (G3) or -1 clockwise (G2) seen from +normal. */
    uint8_t plane_u;
    uint8_t plane_v;
    pos_nm_t centre_u;
    pos_nm_t centre_v;
    pos_nm_t radius;
    int8_t sense;
} motion_geom_t;

typedef struct {
    pos_nm_t pos[CORE_AXES]; /* reference position, nm                        */
    int64_t vel[CORE_AXES];  /* reference velocity, nm/s (feed-forward)       */
    int64_t acc[CORE_AXES];  /* reference acceleration, nm/s^2 (feed-forward) */
    motion_geom_t geom;      /* geometry of the current segment               */
    bool active;             /* a block is being executed this tick           */
} motion_ref_t;

#endif /* MOTION_REF_H */
