/* G-code plain-line scanner (hil_sim/gcode_scan.c): numbers against strtod,
 * where it stops, arcs, and random bytes under the sanitizers. The
 * equivalence with the Python reader is tests/python/test_gcode_fastscan.py. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gcode_scan.h"
#include "unity.h"

#define CAP 64

static int8_t kind[CAP];
static double end[CAP * 6];
static double feeds[CAP];
static int8_t stops[CAP];
static int32_t lines[CAP];
static int64_t arc_row[CAP];
static double arc_centre[CAP * 3];
static gcode_scan_t st;

void setUp(void)
{
    memset(&st, 0, sizeof(st));
    st.scale = 1.0;
    st.feed = 100.0;
    st.tol = 0.002 + 1e-9;
    st.motion = 1;
    st.absolute = 1;
    st.cap = CAP;
    st.kind = kind;
    st.end = end;
    st.feeds = feeds;
    st.stops = stops;
    st.lines = lines;
    st.arc_row = arc_row;
    st.arc_centre = arc_centre;
}

void tearDown(void)
{
}

static size_t scan(const char *text)
{
    return gcode_scan(text, strlen(text), 0, &st);
}

static uint64_t bits(double v)
{
    uint64_t u;

    memcpy(&u, &v, sizeof(u));
    return u;
}

static void test_numbers_are_strtod_values(void)
{
    char num[64];
    char line[80];
    unsigned i;

    srand(7);
    for (i = 0; i < 200000u; i++) {
        int idig = rand() % 9; /* at most 15 digits: below 2^53, C converts them */
        int frac = rand() % 8;
        int k = 0;
        int j;

        if (rand() % 2) {
            num[k++] = '-';
        }
        for (j = 0; j < idig; j++) {
            num[k++] = (char)('0' + rand() % 10);
        }
        if (frac > 0 || idig == 0) {
            num[k++] = '.';
            for (j = 0; j < (frac > 0 ? frac : 1); j++) {
                num[k++] = (char)('0' + rand() % 10);
            }
        }
        num[k] = '\0';
        snprintf(line, sizeof(line), "X%s\n", num);
        st.rows = 0;
        TEST_ASSERT_EQUAL_size_t(strlen(line), scan(line));
        TEST_ASSERT_EQUAL_INT32(1, st.rows);
        /* X * scale + origin, as the interpreter writes it */
        TEST_ASSERT_EQUAL_UINT64(bits(strtod(num, NULL) * 1.0 + 0.0), bits(end[0]));
    }
}

static void test_long_numbers_are_left_to_python(void)
{
    /* above 2^53 or more than 19 digits or 22 after the point: not one
     * exact division, so Python converts them */
    TEST_ASSERT_EQUAL_size_t(0, scan("X9007199254740993\n"));
    TEST_ASSERT_EQUAL_size_t(0, scan("X1.2345678901234567890\n"));
    TEST_ASSERT_EQUAL_size_t(0, scan("X0.00000000000000000000001\n"));
    TEST_ASSERT_EQUAL_size_t(19, scan("X9007199254740992.\n"));
    TEST_ASSERT_EQUAL_size_t(26, scan("X0.0000000000000000000001\n"));
    TEST_ASSERT_EQUAL_UINT64(bits(1e-22), bits(end[6]));
}

static void test_stops_at_the_first_line_it_does_not_take(void)
{
    static const char *const other[] = {
        "X1 (c)\n",
        "X1.2.3\n",
        "X1e5\n",
        "M3\n",
        "X1 X2\n",
        "G1X1\n",
        "N1.5 X1\n",
        "#1=2\n",
        "X[1]\n",
        "G4 P1\n",
        "G17\n",
        "F0\n",
        "X1 R2\n",
        "x1\ty2\r\n",
        "I1\n",
        "G2 X1\n",
        "X\n",
        "X.\n",
        "X+-1\n",
        "X1\v\n",
        "N\n",
        "n1 X1\n",
        "%\n",
        "X1*\n",
        "N1234567890123456789012345678901 X1\n",
        "X0000000000000000000000000000001\n",
    };
    const char *good = "N10 G1 X1 Y2 Z3 F50\n\n  \t\nN20\n";
    char buf[128];
    unsigned i;

    for (i = 0; i < sizeof(other) / sizeof(other[0]); i++) {
        setUp();
        snprintf(buf, sizeof(buf), "%s%sX5\n", good, other[i]);
        TEST_ASSERT_EQUAL_size_t_MESSAGE(strlen(good), scan(buf), other[i]);
        TEST_ASSERT_EQUAL_INT32(1, st.rows);
        TEST_ASSERT_EQUAL_INT32(4, st.line); /* blank and N-only lines count */
        TEST_ASSERT_EQUAL_INT32(1, lines[0]);
        TEST_ASSERT_EQUAL_DOUBLE(50.0, st.feed);
    }
}

static void test_last_line_without_newline_and_the_row_cap(void)
{
    TEST_ASSERT_EQUAL_size_t(3, scan("X1\nX2"));
    setUp();
    st.cap = 1;
    /* at the cap it stops before the next line with words, not before blanks */
    TEST_ASSERT_EQUAL_size_t(7, scan("X1\n\nN5\nX2\n"));
    TEST_ASSERT_EQUAL_INT32(3, st.line);
    setUp();
    st.feed = NAN;
    TEST_ASSERT_EQUAL_size_t(0, scan("X1\n")); /* G1 without a feed: Python's */
    TEST_ASSERT_EQUAL_size_t(12, scan("G0 X1 Y2\nX1\n"));
    TEST_ASSERT_EQUAL_INT32(0, kind[0]);
    TEST_ASSERT_TRUE(isnan(feeds[0]));
}

static void test_arcs_and_modes(void)
{
    st.row_base = 100;
    st.pos[0] = 1.0;
    TEST_ASSERT_EQUAL_size_t(9, scan("G2 I1 J0\n"));
    TEST_ASSERT_EQUAL_INT32(2, st.motion);
    TEST_ASSERT_EQUAL_INT32(1, st.gseen);
    TEST_ASSERT_EQUAL_INT32(1, st.arcs);
    TEST_ASSERT_EQUAL_INT64(100, arc_row[0]);
    TEST_ASSERT_EQUAL_DOUBLE(2.0, arc_centre[0]);
    TEST_ASSERT_EQUAL_DOUBLE(0.0, arc_centre[1]);
    TEST_ASSERT_TRUE(isnan(arc_centre[2]));
    /* end off the circle, zero radius, K in G17: left to Python */
    TEST_ASSERT_EQUAL_size_t(0, scan("X5 I1\n"));
    TEST_ASSERT_EQUAL_size_t(0, scan("G3 I0 J0\n"));
    TEST_ASSERT_EQUAL_size_t(0, scan("G2 I1 K1\n"));
    setUp();
    st.plane = 1; /* G18: Z X */
    TEST_ASSERT_EQUAL_size_t(9, scan("G3 K1 I0\n"));
    TEST_ASSERT_EQUAL_DOUBLE(1.0, arc_centre[2]);
    TEST_ASSERT_EQUAL_DOUBLE(0.0, arc_centre[0]);
    TEST_ASSERT_EQUAL_INT8(3, kind[0]);
}

static void test_random_bytes_stay_inside_the_buffer(void)
{
    static const char alphabet[] = "0123456789.+-XYZABCIJKFGNn \t\n(#e";
    unsigned i;

    srand(11);
    for (i = 0; i < 20000u; i++) {
        size_t len = (size_t)(rand() % 40);
        char *buf = malloc(len + 1u); /* exactly len bytes are read */
        size_t j;
        size_t pos;

        TEST_ASSERT_NOT_NULL(buf);
        for (j = 0; j < len; j++) {
            buf[j] = alphabet[rand() % (int)(sizeof(alphabet) - 1u)];
        }
        setUp();
        st.motion = rand() % 4;
        st.plane = rand() % 3;
        st.cap = 1 + rand() % 3;
        pos = gcode_scan(buf, len, 0, &st);
        TEST_ASSERT_TRUE(pos <= len);
        TEST_ASSERT_TRUE(pos == 0 || buf[pos - 1] == '\n');
        TEST_ASSERT_TRUE(st.rows <= st.cap && st.arcs <= st.rows);
        free(buf);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_numbers_are_strtod_values);
    RUN_TEST(test_long_numbers_are_left_to_python);
    RUN_TEST(test_stops_at_the_first_line_it_does_not_take);
    RUN_TEST(test_last_line_without_newline_and_the_row_cap);
    RUN_TEST(test_arcs_and_modes);
    RUN_TEST(test_random_bytes_stay_inside_the_buffer);
    return UNITY_END();
}
