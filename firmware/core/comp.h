/*
 * comp.h - the position-correction hook of the calibration compensation
 * table (the table itself is built by the calibration issue).
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
 *          pos_nm unchanged). comp_table_t is opaque here; its layout is
 *          defined by the table implementation (comp.c and, if it needs one,
 *          a comp_table.h), which also provides the functions that build and
 *          validate a table. A table in use is never modified: the owner
 *          builds a new one and swaps the pointer (one store, see
 *          qdec_set_comp()).
 *   pos_nm encoder reading, nm (pos_nm_t, any value).
 *   dir    COMP_DIR_POS / COMP_DIR_NEG: direction of the last count;
 *          COMP_DIR_NONE: unknown (no motion since start) - the table uses
 *          the mean of its two directions.
 *   return corrected position, nm, saturated to the pos_nm_t range. Outside
 *          the table's span the table defines the behaviour (it holds its
 *          end correction constant); it never fails and never blocks.
 *
 * Context: tick (called from qdec_sample*). Pure with respect to the table:
 * reentrant, bounded time (O(log n) in the table length at most), integer
 * only.
 */
#ifndef COMP_H
#define COMP_H

#include "fixmath.h"

typedef enum { COMP_DIR_NEG = -1, COMP_DIR_NONE = 0, COMP_DIR_POS = 1 } comp_dir_t;

typedef struct comp_table comp_table_t;

pos_nm_t comp_correct(const comp_table_t *table, pos_nm_t pos_nm, comp_dir_t dir);

#endif /* COMP_H */
