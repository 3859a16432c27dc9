/*
 * drive_test.h - test hooks of the drive (tests only; not part of the
 * drive's interface, drive.h).
 */
#ifndef DRIVE_TEST_H
#define DRIVE_TEST_H

#include <stdbool.h>

#include "motion_ref.h"
#include "qdec.h"

/* Test hook: when on, every tick rebuilds the reference from the
 * interpolator's in full (no pos-only copy on its fast-path ticks); the
 * outputs are the same. drive_init turns it off. Main, with the tick
 * stopped. */
void drive_test_full_ref(bool on);

/* Test hook: when on, every arc tick takes the exact overlay (the oracle of
 * the cruise recurrence, see arc_ref.h). drive_init
 * turns it off. Main, with the tick stopped. */
void drive_test_arc_exact(bool on);
/* Test hook: the reference the last tick handed the servo. */
const motion_ref_t *drive_test_ref(void);

/* Test hook: the decoder of encoder channel ch (NULL when out of range), to
 * compare its whole state. Main, with the tick stopped. */
const qdec_t *drive_test_encoder(unsigned ch);

#endif /* DRIVE_TEST_H */
