/* gcode_scan.c - plain CAM lines of a G-code file in C (see gcode_scan.h). */
#include "gcode_scan.h"

#include <math.h>
#include <string.h>

#define GS_X 1u
#define GS_Y 2u
#define GS_Z 4u
#define GS_F 8u
#define GS_G 16u

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
        idig++;
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

/* One line [p, e) (without its '\n'): 1 when taken, 0 to leave it. */
static int gs_line(const char *p, const char *e, gcode_scan_t *s)
{
    double w[5] = {0.0, 0.0, 0.0, 0.0, 0.0}; /* X Y Z F G */
    unsigned have = 0;
    double feed;
    double *t;
    int32_t r;

    while (p < e && gs_blank(*p)) {
        p++;
    }
    if (p < e && *p == 'N') {
        p++;
        if (p >= e || !gs_digit(*p)) {
            return 0;
        }
        while (p < e && gs_digit(*p)) {
            p++;
        }
        if (p < e && !gs_blank(*p)) {
            return 0;
        }
    }
    for (;;) {
        unsigned bit;
        int k;

        while (p < e && gs_blank(*p)) {
            p++;
        }
        if (p >= e) {
            break;
        }
        switch (*p) {
        case 'X':
        case 'x':
            bit = GS_X;
            k = 0;
            break;
        case 'Y':
        case 'y':
            bit = GS_Y;
            k = 1;
            break;
        case 'Z':
        case 'z':
            bit = GS_Z;
            k = 2;
            break;
        case 'F':
        case 'f':
            bit = GS_F;
            k = 3;
            break;
        case 'G':
        case 'g':
            bit = GS_G;
            k = 4;
            break;
        default:
            return 0;
        }
        if ((have & bit) != 0u || !gs_number(p + 1, e, &w[k], &p)) {
            return 0;
        }
        have |= bit;
    }
    if (have == 0u) {
        s->line++; /* blank, or a line number alone: no block */
        return 1;
    }
    if (s->rows >= s->cap) {
        return 0; /* Python takes this block and splits the chunk */
    }
    if ((have & GS_G) != 0u && w[4] != (double)s->motion) {
        return 0; /* a change of motion mode (or G2, G80 ...) */
    }
    feed = s->feed;
    if ((have & GS_F) != 0u) {
        if (!(w[3] > 0.0)) {
            return 0; /* the error is Python's */
        }
        feed = w[3] * s->scale;
    }
    if (!(s->motion == 0 || (s->motion == 1 && feed == feed))) {
        return 0;
    }
    s->feed = feed;
    s->line++;
    if ((have & (GS_X | GS_Y | GS_Z)) == 0u) {
        return 1;
    }
    r = s->rows;
    t = &s->end[(size_t)r * 6u];
    memcpy(t, s->pos, sizeof(s->pos));
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
    s->kind[r] = (int8_t)s->motion;
    s->feeds[r] = s->motion != 0 ? feed : (double)NAN;
    s->stops[r] = (int8_t)(s->stop != 0);
    s->lines[r] = s->line;
    memcpy(s->pos, t, sizeof(s->pos));
    s->rows = r + 1;
    return 1;
}

size_t gcode_scan(const char *buf, size_t len, size_t pos, gcode_scan_t *s)
{
    if (buf == NULL || s == NULL || (s->motion != 0 && s->motion != 1)) {
        return pos;
    }
    while (pos < len) {
        const char *p = buf + pos;
        const char *nl = memchr(p, '\n', len - pos);

        if (nl == NULL || !gs_line(p, nl, s)) {
            break;
        }
        pos = (size_t)(nl - buf) + 1u;
    }
    return pos;
}
