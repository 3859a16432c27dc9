/* Serial framing: round trips at every length, resynchronisation after
 * garbage, and every rejection (crc, short, oversized, bad COBS) counted. */
#include <string.h>

#include "proto_frame.h"
#include "unity.h"

void setUp(void)
{
}

void tearDown(void)
{
}

static proto_frame_rx_t rx;
static uint8_t got[PROTO_MSG_MAX];
static size_t got_len;
static unsigned got_count;

static void feed(const uint8_t *b, size_t n)
{
    size_t i;

    for (i = 0; i < n; i++) {
        const uint8_t *m;
        size_t len;

        if (proto_frame_rx_byte(&rx, b[i], &m, &len)) {
            memcpy(got, m, len);
            got_len = len;
            got_count++;
        }
    }
}

static uint32_t lcg = 12345u;
static uint8_t rnd(void)
{
    lcg = lcg * 1103515245u + 12345u;
    return (uint8_t)(lcg >> 16);
}

static size_t make_frame(uint8_t *f, const uint8_t *msg, size_t len)
{
    size_t n = proto_frame_encode(msg, len, f, PROTO_FRAME_MAX);
    TEST_ASSERT_TRUE(n > 0);
    TEST_ASSERT_TRUE(n <= PROTO_FRAME_MAX);
    return n;
}

static void test_round_trip_every_length_and_pattern(void)
{
    uint8_t msg[PROTO_MSG_MAX], f[PROTO_FRAME_MAX];
    size_t len, i, n;
    unsigned pattern;

    proto_frame_rx_init(&rx);
    for (pattern = 0; pattern < 4; pattern++) {
        for (len = PROTO_MSG_HDR; len <= PROTO_MSG_MAX; len++) {
            for (i = 0; i < len; i++) {
                msg[i] = pattern == 0 ? 0u : pattern == 1 ? 0xFFu : pattern == 2 ? rnd() : 0x11u;
            }
            n = make_frame(f, msg, len);
            /* only the two delimiters are zero */
            TEST_ASSERT_EQUAL_UINT8(0, f[0]);
            for (i = 1; i + 1 < n; i++) {
                TEST_ASSERT_NOT_EQUAL(0, f[i]);
            }
            TEST_ASSERT_EQUAL_UINT8(0, f[n - 1]);
            got_count = 0;
            feed(f, n);
            TEST_ASSERT_EQUAL_UINT(1, got_count);
            TEST_ASSERT_EQUAL_size_t(len, got_len);
            TEST_ASSERT_EQUAL_MEMORY(msg, got, len);
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0, proto_frame_rx_errors(&rx));
}

static void test_encode_refuses_bad_lengths_and_small_buffers(void)
{
    uint8_t msg[PROTO_MSG_MAX + 1] = {0}, f[PROTO_FRAME_MAX + 8];

    TEST_ASSERT_EQUAL_size_t(0, proto_frame_encode(msg, 1, f, sizeof f));
    TEST_ASSERT_EQUAL_size_t(0, proto_frame_encode(msg, PROTO_MSG_MAX + 1, f, sizeof f));
    TEST_ASSERT_EQUAL_size_t(0, proto_frame_encode(msg, 10, f, 14));
    TEST_ASSERT_EQUAL_size_t(15, proto_frame_encode(msg, 10, f, 15));
}

static void test_resynchronises_after_garbage(void)
{
    uint8_t msg[] = {0x01, 0x07, 0x00, 0x42};
    uint8_t f[PROTO_FRAME_MAX], g[100];
    size_t n = make_frame(f, msg, sizeof msg), i;

    proto_frame_rx_init(&rx);
    got_count = 0;
    for (i = 0; i < sizeof g; i++) {
        g[i] = (uint8_t)(rnd() | 1u);
    }
    g[40] = 0; /* garbage with a delimiter inside */
    feed(g, sizeof g);
    feed(f, n);
    TEST_ASSERT_EQUAL_UINT(1, got_count);
    TEST_ASSERT_EQUAL_MEMORY(msg, got, sizeof msg);
    TEST_ASSERT_TRUE(proto_frame_rx_errors(&rx) >= 1);
}

static void test_corrupt_frame_is_counted_and_next_one_passes(void)
{
    uint8_t msg[] = {0x03, 0x01, 0x01, 0x00, 0x10, 0x27, 0, 0, 0, 0, 0, 0};
    uint8_t f[PROTO_FRAME_MAX];
    size_t n = make_frame(f, msg, sizeof msg), i;

    for (i = 1; i + 1 < n; i++) {
        uint8_t bad[PROTO_FRAME_MAX];

        memcpy(bad, f, n);
        bad[i] ^= 0x20; /* never produces 0x00 from a non-zero byte */
        if (bad[i] == 0) {
            continue;
        }
        proto_frame_rx_init(&rx);
        got_count = 0;
        feed(bad, n);
        TEST_ASSERT_EQUAL_UINT(0, got_count);
        TEST_ASSERT_EQUAL_UINT32(1, rx.stats.crc + rx.stats.cobs + rx.stats.short_len);
        feed(f, n);
        TEST_ASSERT_EQUAL_UINT(1, got_count);
    }
}

static void test_truncated_frame_is_dropped(void)
{
    uint8_t msg[] = {0x0A, 0x02, 0x55, 0x66};
    uint8_t f[PROTO_FRAME_MAX];
    size_t n = make_frame(f, msg, sizeof msg);
    uint8_t zero = 0;

    proto_frame_rx_init(&rx);
    got_count = 0;
    feed(f, n - 3); /* cut: lost bytes, the next delimiter ends it */
    feed(&zero, 1);
    (void)zero;
    TEST_ASSERT_EQUAL_UINT(0, got_count);
    TEST_ASSERT_EQUAL_UINT32(1, proto_frame_rx_errors(&rx));
    feed(f, n);
    TEST_ASSERT_EQUAL_UINT(1, got_count);
}

static void test_short_and_empty_frames(void)
{
    const uint8_t shortf[] = {0x02, 0x05, 0x00}; /* one body byte */
    const uint8_t empties[] = {0x00, 0x00, 0x00};

    proto_frame_rx_init(&rx);
    got_count = 0;
    feed(empties, sizeof empties);
    TEST_ASSERT_EQUAL_UINT32(0, proto_frame_rx_errors(&rx));
    feed(shortf, sizeof shortf);
    TEST_ASSERT_EQUAL_UINT32(1, rx.stats.short_len);
    TEST_ASSERT_EQUAL_UINT(0, got_count);
}

static void test_oversized_is_dropped_without_overrun(void)
{
    uint8_t big[1000];
    uint8_t msg[] = {0x01, 0x09};
    uint8_t f[PROTO_FRAME_MAX];
    size_t n = make_frame(f, msg, sizeof msg);

    memset(big, 0x33, sizeof big);
    proto_frame_rx_init(&rx);
    got_count = 0;
    feed(big, sizeof big);
    feed(f, n); /* its leading delimiter ends the oversized run */
    TEST_ASSERT_EQUAL_UINT32(1, rx.stats.oversized);
    TEST_ASSERT_EQUAL_UINT(1, got_count);
    TEST_ASSERT_EQUAL_MEMORY(msg, got, sizeof msg);
}

static void test_bad_cobs_code_is_counted(void)
{
    const uint8_t bad[] = {0x09, 0x01, 0x02, 0x00}; /* code points past the end */
    uint8_t msg[] = {0x0B, 0x07, 0x00, 0x42};
    uint8_t f[PROTO_FRAME_MAX];
    size_t n = make_frame(f, msg, sizeof msg);

    proto_frame_rx_init(&rx);
    got_count = 0;
    feed(bad, sizeof bad);
    TEST_ASSERT_EQUAL_UINT32(1, rx.stats.cobs);
    TEST_ASSERT_EQUAL_UINT32(1, proto_frame_rx_errors(&rx)); /* counted once, as COBS only */
    TEST_ASSERT_EQUAL_UINT(0, got_count);                    /* nothing delivered */
    feed(f, n);                                              /* and the link resynchronises */
    TEST_ASSERT_EQUAL_UINT(1, got_count);
    TEST_ASSERT_EQUAL_size_t(sizeof msg, got_len);
    TEST_ASSERT_EQUAL_MEMORY(msg, got, sizeof msg);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_round_trip_every_length_and_pattern);
    RUN_TEST(test_encode_refuses_bad_lengths_and_small_buffers);
    RUN_TEST(test_resynchronises_after_garbage);
    RUN_TEST(test_corrupt_frame_is_counted_and_next_one_passes);
    RUN_TEST(test_truncated_frame_is_dropped);
    RUN_TEST(test_short_and_empty_frames);
    RUN_TEST(test_oversized_is_dropped_without_overrun);
    RUN_TEST(test_bad_cobs_code_is_counted);
    return UNITY_END();
}
