/*
 * comp.h - the compensation table of one axis (pitch error and backlash
 * measured by calibration, docs/calibration.md) and the position-correction
 * hook the decoder calls.
 *
 * Specification
 * -------------
 * The decoder (qdec.h) scales encoder counts to a machine position in nm
 * (pos_nm_raw) and then calls
 *
 *     pos_nm = comp_correct(table, pos_nm_raw, dir);
 *
 * which returns the best estimate of the true position (as the reference
 * scale would read it) for an encoder reading of pos_nm_raw reached while
 * travelling in direction dir (the direction of approach: hysteresis and
 * backlash maps differ per direction).
 *
 *   table  the compensation table, or NULL: no table, identity (returns
 *          pos_nm unchanged). A table in use is never modified: the owner
 *          builds a new one and swaps the pointer (one store, see
 *          qdec_set_comp()). A table with n == 0 is the identity too.
 *   pos_nm encoder reading, nm (pos_nm_t, any value).
 *   dir    COMP_DIR_POS / COMP_DIR_NEG: direction of the last count;
 *          COMP_DIR_NONE: unknown (no motion since start) - the table uses
 *          the mean of its two directions. Ignored when the table has a
 *          direction source (table->dir_src, below).
 *   return corrected position, nm, saturated to the pos_nm_t range. Outside
 *          the table's span the end correction is held constant; it never
 *          fails and never blocks.
 *
 * Table (struct comp_table): n points pos[0] < pos[1] < ... < pos[n-1] (nm,
 * encoder reading), and per point the correction added to the reading when
 * the axis approached it moving forward (fwd[], +x) and moving in reverse
 * (rev[], -x), nm. Correction = reference - encoder = -(calibration error),
 * with error = encoder - reference as in ../shared/data/README.md. Between
 * points both columns are interpolated linearly (exact: round to nearest of
 * the 64-bit rational value), beyond the ends held.
 *
 * Direction: a correction that jumped by the hysteresis (tens of um) at every
 * sign change of a noisy encoder would shake the axis. So the drive gives
 * the table a direction source (dir_src): a comp_ramp_t that follows the
 * COMMANDED motion (the sign of the reference velocity; at rest the last
 * direction is held, i.e. the direction of approach) and, on a reversal,
 * moves a blend weight w linearly from one column to the other over
 * ramp_us (q1_30: w = +1 forward column, -1 reverse column, 0 their mean):
 *
 *     corr(x) = rev(x) + (fwd(x) - rev(x)) * (w + 1) / 2
 *
 * The change of the feedback during a reversal is therefore at most
 * |fwd - rev| / ramp_us per unit time: no step. A table without dir_src
 * uses `dir` (POS: w = +1, NEG: w = -1, NONE: w = 0).
 *
 * Limits (comp_table_check): 0 <= n <= COMP_POINTS_MAX; |pos| <=
 * COMP_POS_LIMIT_NM; consecutive positions strictly increasing and at most
 * COMP_SPAN_MAX_NM apart; |fwd|, |rev| <= COMP_CORR_MAX_NM; ramp_us <=
 * COMP_RAMP_MAX_US. Under these limits every intermediate fits in 64 bits
 * (no overflow, one 64/64 division per column).
 *
 * Record (flash and wire, little-endian; comp_record_encode/decode), 32-byte
 * header then n points of 16 bytes:
 *   0  u32 magic "CCMP" (0x504D4343)   4  u16 format (1)   6  u8 axis
 *   7  u8 flags (0)    8  u32 version   12 u16 n   14 u16 reserved (0)
 *   16 u32 ramp_us     20 u32 data_crc (crc32 of the n points)
 *   24 u32 reserved (0)                 28 u32 header_crc (crc32 of 0..27)
 *   32 + 16 i: i64 pos, i32 fwd, i32 rev
 * COMP_RECORD_MAX = 32 + 16 * COMP_POINTS_MAX = 2048 bytes (one 2 KiB page).
 *
 * Contexts: comp_correct and comp_correct_w are called from the tick
 * (qdec_sample*): pure with respect to the table, reentrant, bounded time
 * (binary search, O(log n)), integer only. comp_ramp_step: tick (it writes
 * the ramp the tables read in the same context). Everything else: main.
 * No heap, no floating point.
 */
#ifndef COMP_H
#define COMP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "fixmath.h"

typedef enum { COMP_DIR_NEG = -1, COMP_DIR_NONE = 0, COMP_DIR_POS = 1 } comp_dir_t;

#define COMP_POINTS_MAX   126
#define COMP_POS_LIMIT_NM ((pos_nm_t)1 << 50) /* 1126 km                    */
#define COMP_SPAN_MAX_NM  ((pos_nm_t)1 << 40) /* 1.1 km between points      */
#define COMP_CORR_MAX_NM  1000000             /* |correction| <= 1 mm       */
#define COMP_RAMP_MAX_US  1000000u            /* reversal ramp <= 1 s       */
#define COMP_W_ONE        ((int32_t)1 << 30)  /* q1_30 1.0 of the blend     */

#define COMP_RECORD_MAGIC  0x504D4343u /* "CCMP" little-endian */
#define COMP_RECORD_FORMAT 1u
#define COMP_RECORD_HDR    32u
#define COMP_POINT_BYTES   16u
#define COMP_RECORD_MAX    (COMP_RECORD_HDR + COMP_POINT_BYTES * COMP_POINTS_MAX)

typedef enum {
    COMP_OK = 0,
    COMP_E_ARG,   /* NULL pointer or buffer too small                  */
    COMP_E_COUNT, /* n > COMP_POINTS_MAX or record length mismatch      */
    COMP_E_ORDER, /* positions not strictly increasing / span too long */
    COMP_E_RANGE, /* position, correction or ramp beyond its limit     */
    COMP_E_MAGIC, /* not a compensation record (magic, format)         */
    COMP_E_CRC,   /* header or data CRC mismatch                       */
    COMP_E_AXIS   /* record for another axis                           */
} comp_result_t;

/* Direction source: commanded direction and reversal ramp of one axis.
 * Written by comp_ramp_step (tick), read by comp_correct (tick). */
typedef struct {
    volatile int32_t w_q30; /* blend, -COMP_W_ONE (reverse) .. +COMP_W_ONE */
    uint32_t step_q30;      /* change of w per tick (2 * ONE: at once)     */
    int8_t dir;             /* last commanded direction, 0: none yet       */
} comp_ramp_t;

typedef struct comp_table {
    uint32_t version;           /* store version (0: not from the store)      */
    uint16_t n;                 /* points in use, 0..COMP_POINTS_MAX          */
    uint8_t axis;               /* axis the table belongs to                  */
    uint8_t flags;              /* reserved, 0                                */
    uint32_t ramp_us;           /* reversal ramp, us (0: switch at once)      */
    uint32_t data_crc;          /* crc32 of the record's points (set by decode) */
    const comp_ramp_t *dir_src; /* direction source, NULL: the `dir` argument */
    pos_nm_t pos[COMP_POINTS_MAX];
    int32_t fwd[COMP_POINTS_MAX]; /* correction moving +x, nm */
    int32_t rev[COMP_POINTS_MAX]; /* correction moving -x, nm */
} comp_table_t;

/* The decoder's hook (see top). */
pos_nm_t comp_correct(const comp_table_t *table, pos_nm_t pos_nm, comp_dir_t dir);

/* Same with an explicit blend w (q1_30, clamped to [-1, +1]); ignores
 * table->dir_src. NULL or n == 0: identity. */
pos_nm_t comp_correct_w(const comp_table_t *table, pos_nm_t pos_nm, int32_t w_q30);

/* Correction alone (corrected - pos_nm, before saturation), nm. */
int64_t comp_correction(const comp_table_t *table, pos_nm_t pos_nm, int32_t w_q30);

/* Validate a table against the limits above. */
comp_result_t comp_table_check(const comp_table_t *table);

/* Start a ramp: no direction yet (w = 0, the mean), ramp of ramp_us at a
 * tick of tick_hz (> 0). ramp_us == 0 switches at once. */
void comp_ramp_init(comp_ramp_t *r, uint32_t ramp_us, uint32_t tick_hz);
/* Change the ramp time, keeping the direction and w. */
void comp_ramp_set_time(comp_ramp_t *r, uint32_t ramp_us, uint32_t tick_hz);
/* One tick: vel_nm_s is the commanded (reference) velocity of the axis.
 * Its sign sets the direction (0 keeps the last one); w moves toward it by
 * at most step_q30. */
void comp_ramp_step(comp_ramp_t *r, int64_t vel_nm_s);

/* Record length for n points. */
size_t comp_record_len(uint16_t n);
/* Encode the table as a record (version and axis from the table); returns
 * the length written, 0 when cap is too small or the table is invalid. The
 * table's data_crc is not read (computed). */
size_t comp_record_encode(const comp_table_t *table, uint8_t *buf, size_t cap);
/* Decode and validate a record of exactly len bytes into table (dir_src set
 * to NULL). A record refused by its header, length, CRCs or flags leaves
 * the table untouched; one refused by its points' limits (COMP_E_RANGE /
 * COMP_E_ORDER from comp_table_check) leaves it holding those points, so
 * decode into a table that is not in use (scratch.h, comp_store). */
comp_result_t comp_record_decode(const uint8_t *buf, size_t len, comp_table_t *table);
/* Header only: check magic, format, header CRC and n (0 when len < 32);
 * *total gets the whole record length. */
comp_result_t comp_record_header(const uint8_t *buf, size_t len, size_t *total);

#endif /* COMP_H */
