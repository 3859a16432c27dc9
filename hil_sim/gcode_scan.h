/*
 * gcode_scan.h - host-only fast path of the G-code reader for plain CAM
 * lines (host_tools/contour/gcode/fastscan.py calls it; not in the MCU image).
 *
 * Specification
 * -------------
 * gcode_scan(buf, len, pos, s) reads whole lines of the ASCII text
 * buf[pos..len) (each ending in '\n') and executes those that are plain
 * moves exactly as the Python interpreter does (its plain-move path in
 * contour.gcode.interp.Interpreter.run for G0/G1, the general path and
 * Interpreter.arc for G2/G3 with I J K), appending one row per move to the
 * arrays of `s`. It stops at the start of the first line it does not take,
 * and returns that offset; Python reads that line and calls again.
 *
 * A line it takes: blanks (space, tab) only, or blank-separated tokens: an
 * optional first `N<digits>` (at most 30 digits), then words `<letter><number>` with the letter
 * one of X Y Z A B C I J K F G (either case, each at most once) and the number
 * `[+-]?(digits[.digits]|.digits)` with at most 19 significant digits, 30
 * before the point and 22 after it (so that mantissa / 10^k is one correctly rounded
 * division, the value Python's float() gives). G is 0 1 2 3 (it sets the
 * motion mode; Python cancels the canned-cycle state when gseen), F > 0,
 * G1-G3 need a feed; I J K only on G2/G3 and only the plane's two; an arc
 * is taken when its centre is within 1e9 mm, its radius at least 1e-6 mm
 * and its end radius within half the tolerance Python allows (so that no
 * last-bit difference of hypot can change the verdict), otherwise Python
 * reads it (and gives its error). Anything else - R, P, other letters, comments,
 * parameters, other whitespace, a line without '\n' or longer than 4096
 * characters - is left to Python,
 * which gives the same rows or the same error. Every line it takes counts
 * one in s->line (blank and N-only lines too).
 *
 * Rows: kind (0 rapid, 1 feed, 2 3 arcs), end (6 doubles: the position with X Y Z
 * replaced by value * scale + origin (absolute) or added value * scale
 * (incremental), A B C the same without the scale; the same floating-point
 * operations as Python, so the same
 * bits), feed (mm/min, NaN for rapids), stop (s->stop), line; arcs also
 * arc_row and arc_centre (u, v as Interpreter.arc computes them). When
 * s->rows reaches s->cap it stops before the next line that has words, so
 * that Python sees the same block at which the interpreter splits a chunk.
 * Host only, main context.
 */
#ifndef GCODE_SCAN_H
#define GCODE_SCAN_H

#include <stddef.h>
#include <stdint.h>

typedef struct {
    double pos[6];      /* in/out: machine position, mm / deg */
    double origin[6];   /* in: the active total offset (machine - program) */
    double scale;       /* in: 1 (G21) or 25.4 (G20) */
    double feed;        /* in/out: mm/min, NaN: none yet */
    double tol;         /* in: arc end-point tolerance, mm (0.002 scale + 1e-9) */
    int64_t row_base;   /* in: the program row of rows[0] (for arc_row) */
    int32_t motion;     /* in/out: 0 1 2 3 (G0-G3); others: nothing is taken */
    int32_t absolute;   /* in: G90 (1) or G91 (0) */
    int32_t arc_abs;    /* in: G90.1 (1) or G91.1 (0) */
    int32_t plane;      /* in: 0 1 2 (G17 G18 G19) */
    int32_t stop;       /* in: exact stop modal (written to every row) */
    int32_t line;       /* in/out: the number of the last line read */
    int32_t rows;       /* in/out: rows written so far */
    int32_t cap;        /* in: room in the row arrays */
    int32_t arcs;       /* in/out: arc rows written so far (at most cap) */
    int32_t gseen;      /* out: a line with a G word was taken */
    int8_t *kind;       /* out rows: cap entries */
    double *end;        /* cap * 6 */
    double *feeds;      /* cap */
    int8_t *stops;      /* cap */
    int32_t *lines;     /* cap */
    int64_t *arc_row;   /* out arcs: row_base + row */
    double *arc_centre; /* 3 per arc: NaN off the plane's two axes */
} gcode_scan_t;

size_t gcode_scan(const char *buf, size_t len, size_t pos, gcode_scan_t *s);

#endif /* GCODE_SCAN_H */
