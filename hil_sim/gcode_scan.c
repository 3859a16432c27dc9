/* gcode_scan.c - plain CAM lines of a G-code file in C (see gcode_scan.h). */
#include "gcode_scan.h"

#include <math.h>
#include <string.h>

#define GS_X   1u
#define GS_Y   2u
#define GS_Z   4u
#define GS_F   8u
#define GS_G   16u
#define GS_IJK (32u | 64u | 128u)
/* Longer lines go to Python, which refuses those above its cap (lexer.LINE_CAP). */
#define GS_LINE_MAX 4096
#define GS_DIGITS   30 /* digits of a number (leading zeros too) it reads at most */
#define GS_AXES     (GS_X | GS_Y | GS_Z | 256u | 512u | 1024u) /* X Y Z A B C */

/* Exact powers of ten as doubles: 10^22 is the largest one. */
static const double gs_pow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                    1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                    1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static int gs_digit(char c)
{
    return c >= '0' && c <= '9';
}

static int gs_blank(char c)
{
    return c == ' ' || c == '\t';
}

/*
 * The number at p (before e) that ends a token: 1 with *v and *q (past it),
 * or 0 when it is not the plain form or not exactly convertible here.
 * m / 10^k with m < 2^53 and k <= 22 is one correctly rounded division of
 * two exact doubles: the correctly rounded value, as Python's float().
 */
static int gs_number(const char *p, const char *e, double *v, const char **q)
{
    uint64_t m = 0;
    int neg = 0;
    int sig = 0;
    int idig = 0;
    int frac = 0;

    if (p < e && (*p == '+' || *p == '-')) {
        neg = *p == '-';
        p++;
    }
    while (p < e && gs_digit(*p)) {
        if (m != 0 || *p != '0') {
            if (++sig > 19) {
                return 0;
            }
        }
        m = m * 10u + (uint64_t)(*p - '0');
        if (++idig > GS_DIGITS) {
            return 0;
        }
        p++;
    }
    if (p < e && *p == '.') {
        p++;
        while (p < e && gs_digit(*p)) {
            if (m != 0 || *p != '0') {
                if (++sig > 19) {
                    return 0;
                }
            }
            m = m * 10u + (uint64_t)(*p - '0');
            if (++frac > 22) {
                return 0;
            }
            p++;
        }
        if (idig == 0 && frac == 0) {
            return 0;
        }
    } else if (idig == 0) {
        return 0;
    }
    if (p < e && !gs_blank(*p)) {
        return 0; /* X1.2.3, X1e5, X5*: Python says what it is */
    }
    if (m > ((uint64_t)1 << 53)) {
        return 0;
    }
    *v = (double)m / gs_pow10[frac];
    if (neg) {
        *v = -*v;
    }
    *q = p;
    return 1;
}

/* The arc centre (u, v) of Interpreter.arc / arcs.centre_ijk, or 0 when
 * Python must read the line (out of range, or near an error threshold). */
static int gs_centre(const gcode_scan_t *s, const double *w, unsigned have, const double *t,
                     double *cu, double *cv)
{
    /* plane -> (u, v) axes and the I J K word (index in w) of each */
    static const int axis_u[3] = {0, 2, 1};
    static const int axis_v[3] = {1, 0, 2};
    static const int word_u[3] = {5, 7, 6};
    static const int word_v[3] = {6, 5, 7};
    const int pl = s->plane;
    const int u = axis_u[pl];
    const int v = axis_v[pl];
    const double su = s->pos[u];
    const double sv = s->pos[v];
    double ou;
    double ov;
    double r0;
    double r1;
    double lim;

    if ((have & (1u << (unsigned)(18 - word_u[pl] - word_v[pl]))) != 0u) {
        return 0; /* the offset letter of no axis of the plane: Python's error */
    }
    ou = ((have & (1u << (unsigned)word_u[pl])) != 0u ? w[word_u[pl]] : 0.0) * s->scale;
    ov = ((have & (1u << (unsigned)word_v[pl])) != 0u ? w[word_v[pl]] : 0.0) * s->scale;
    if (s->arc_abs) {
        *cu = ou + s->origin[u];
        *cv = ov + s->origin[v];
    } else {
        *cu = su + ou;
        *cv = sv + ov;
    }
    if (!(fabs(*cu) < 1e9 && fabs(*cv) < 1e9)) {
        return 0;
    }
    r0 = hypot(su - *cu, sv - *cv);
    r1 = hypot(t[u] - *cu, t[v] - *cv);
    lim = s->tol > 1e-3 * r0 ? s->tol : 1e-3 * r0;
    return r0 >= 1e-6 && fabs(r0 - r1) <= 0.5 * lim;
}

/* One line [p, e) (without its '\n'): 1 when taken, 0 to leave it. */
static int gs_line(const char *p, const char *e, gcode_scan_t *s)
{
    double w[11] = {0.0}; /* X Y Z F G I J K A B C */
    unsigned have = 0;
    int32_t motion = s->motion;
    double feed;
    double cu = 0.0;
    double cv = 0.0;
    double *t;
    int32_t r;

    while (p < e && gs_blank(*p)) {
        p++;
    }
    if (p < e && *p == 'N') {
        const char *d = ++p;

        while (p < e && gs_digit(*p)) {
            p++;
        }
        if (p == d || p - d > GS_DIGITS) {
            return 0; /* N alone, or long enough for Python to look closer */
        }
        if (p < e && !gs_blank(*p)) {
            return 0;
        }
    }
    for (;;) {
        int k;

        while (p < e && gs_blank(*p)) {
            p++;
        }
        if (p >= e) {
            break;
        }
        switch (*p | 0x20) {
        case 'x':
            k = 0;
            break;
        case 'y':
            k = 1;
            break;
        case 'z':
            k = 2;
            break;
        case 'f':
            k = 3;
            break;
        case 'g':
            k = 4;
            break;
        case 'i':
            k = 5;
            break;
        case 'j':
            k = 6;
            break;
        case 'k':
            k = 7;
            break;
        case 'a':
        case 'b':
        case 'c':
            k = 8 + ((*p | 0x20) - 'a');
            break;
        default:
            return 0;
        }
        if ((have & (1u << k)) != 0u || !gs_number(p + 1, e, &w[k], &p)) {
            return 0;
        }
        have |= 1u << k;
    }
    if (have == 0u) {
        s->line++; /* blank, or a line number alone: no block */
        return 1;
    }
    if (s->rows >= s->cap) {
        return 0; /* Python takes this block and splits the chunk */
    }
    if ((have & GS_G) != 0u) {
        if (w[4] == 0.0 || w[4] == 1.0 || w[4] == 2.0 || w[4] == 3.0) {
            motion = (int32_t)w[4];
        } else {
            return 0; /* G80, G4, G17 ...: Python */
        }
    }
    if ((have & GS_IJK) != 0u ? motion < 2 : motion >= 2) {
        return 0; /* I J K unused, or an arc without them (R form): Python */
    }
    feed = s->feed;
    if ((have & GS_F) != 0u) {
        if (!(w[3] > 0.0)) {
            return 0; /* the error is Python's */
        }
        feed = w[3] * s->scale;
    }
    if (!(motion == 0 || feed == feed)) {
        return 0; /* a feed move without a feed: Python's error or --feed */
    }
    if ((have & GS_AXES) == 0u && motion >= 2 && (have & GS_G) == 0u) {
        return 0; /* I J K without an axis word or G2/G3: Python's error */
    }
    if ((have & GS_AXES) == 0u && motion < 2) {
        s->motion = motion;
        s->gseen |= (have & GS_G) != 0u;
        s->feed = feed;
        s->line++;
        return 1;
    }
    t = &s->end[(size_t)s->rows * 6u];
    memcpy(t, s->pos, sizeof(s->pos));
    for (r = 0; r < 3; r++) {
        /* A B C: degrees, not scaled (MotionExecutor.target_of) */
        if ((have & (256u << (unsigned)r)) != 0u) {
            t[3 + r] = s->absolute ? w[8 + r] + s->origin[3 + r] : t[3 + r] + w[8 + r];
        }
    }
    if (s->absolute) {
        if ((have & GS_X) != 0u) {
            t[0] = w[0] * s->scale + s->origin[0];
        }
        if ((have & GS_Y) != 0u) {
            t[1] = w[1] * s->scale + s->origin[1];
        }
        if ((have & GS_Z) != 0u) {
            t[2] = w[2] * s->scale + s->origin[2];
        }
    } else {
        if ((have & GS_X) != 0u) {
            t[0] = t[0] + w[0] * s->scale;
        }
        if ((have & GS_Y) != 0u) {
            t[1] = t[1] + w[1] * s->scale;
        }
        if ((have & GS_Z) != 0u) {
            t[2] = t[2] + w[2] * s->scale;
        }
    }
    if (motion >= 2) {
        double *c = &s->arc_centre[(size_t)s->arcs * 3u];
        static const int axis_u[3] = {0, 2, 1};
        static const int axis_v[3] = {1, 0, 2};

        if (!gs_centre(s, w, have, t, &cu, &cv)) {
            return 0;
        }
        c[0] = (double)NAN;
        c[1] = (double)NAN;
        c[2] = (double)NAN;
        c[axis_u[s->plane]] = cu;
        c[axis_v[s->plane]] = cv;
        s->arc_row[s->arcs] = s->row_base + s->rows;
        s->arcs++;
    }
    s->motion = motion;
    s->gseen |= (have & GS_G) != 0u;
    s->feed = feed;
    s->line++;
    r = s->rows;
    s->kind[r] = (int8_t)motion;
    s->feeds[r] = motion != 0 ? feed : (double)NAN;
    s->stops[r] = (int8_t)(s->stop != 0);
    s->lines[r] = s->line;
    memcpy(s->pos, t, sizeof(s->pos));
    s->rows = r + 1;
    return 1;
}

size_t gcode_scan(const char *buf, size_t len, size_t pos, gcode_scan_t *s)
{
    if (buf == NULL || s == NULL || s->motion < 0 || s->motion > 3 || s->plane < 0 ||
        s->plane > 2) {
        return pos;
    }
    while (pos < len) {
        const char *p = buf + pos;
        const char *nl = memchr(p, '\n', len - pos);

        if (nl == NULL || nl - p > GS_LINE_MAX || !gs_line(p, nl, s)) {
            break;
        }
        pos = (size_t)(nl - buf) + 1u;
    }
    return pos;
}
