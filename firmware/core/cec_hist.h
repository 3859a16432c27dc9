/*
 * cec_hist.h - the contour error controller's reference history (cec.h,
 * "Reference history"): internal to cec.c, not an interface.
 */
#ifndef CEC_HIST_H
#define CEC_HIST_H

#include "cec.h"

/* One tick of the history in the plane of normal axis w (0..2): samples
 * ref->pos when it has moved a span from the last sample, and with a new
 * sample sets hist_r and hist_s from the last three (cec_circle3). Tick. */
void cec_hist_step(cec_t *c, const motion_ref_t *ref, unsigned w);

#endif /* CEC_HIST_H */
