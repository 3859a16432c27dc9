/*
 * arc_seg.h - chord segmentation of arc blocks (main context, and the
 * host's estimator through drive_arc_chords).
 *
 * Specification
 * -------------
 * An ARC block (drive.h, "Motion") in a plane about an absolute centre is
 * validated from its start point and cut into n chords of equal angle: the
 * angle is the larger of the chord tolerance's (sagitta = chord_nm) and
 * DRIVE_ARC_SEG_TICKS ticks of travel at the programmed feed, at most
 * DRIVE_ARC_SEG_MAX_ANGLE. Chord k (0..n-1) runs from point k to point
 * k + 1, point k being at the angle th_s + sweep k / n and the radius
 * r_s + (r_e - r_s) k / n, the third axis linear in k; point n is the
 * block's target exactly. arc_seg_chord also gives the constants of the
 * exact arc over the chord (arc_chord_t, arc_ref.h). Everything is pure:
 * the drive and the host's estimator (drive_arc_chords) cut every arc into
 * the same chords.
 *
 * Contexts: any (pure; the state is the caller's).
 */
#ifndef ARC_SEG_H
#define ARC_SEG_H

#include <stdbool.h>
#include <stdint.h>

#include "arc_ref.h"
#include "drive.h"

/* The segmentation of one arc block. */
typedef struct {
    uint32_t n_seg;            /* chords, >= 1                          */
    uint32_t done_seg;         /* chords handed on (the caller's cursor) */
    pos_nm_t start[CORE_AXES]; /* start point                           */
    fx_angle_t th_s;           /* angle of the start point              */
    int64_t sweep;             /* signed sweep, binary angle            */
    pos_nm_t r_s, r_e;         /* start and end radius                  */
    uint8_t u, v, w;           /* the plane's axes and the third axis   */
} arc_seg_t;

/* Validate arc block b (ARC fields; the targets of axes >= axes already
 * set to start) from start for a drive with `axes` axes at tick_hz and
 * chord tolerance chord_nm (> 0), and set a up with done_seg = 0. False
 * (a unusable) when drive_queue_block would refuse the arc. */
bool arc_seg_setup(arc_seg_t *a, const drive_block_t *b, const pos_nm_t start[CORE_AXES],
                   unsigned axes, uint32_t tick_hz, int64_t chord_nm);

/* Chord k (0 <= k < a->n_seg) of the arc block b that a was set up for:
 * its end point and, when c is not NULL, the exact arc over it. */
void arc_seg_chord(const arc_seg_t *a, const drive_block_t *b, uint32_t k, pos_nm_t end[CORE_AXES],
                   arc_chord_t *c);

#endif /* ARC_SEG_H */
