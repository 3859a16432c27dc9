/*
 * test_port_common.c - the MCU ports' shared pieces that need no hardware:
 * the 16/32-bit counter extension (port_counter.h) and the UART byte ring
 * (port_ring.h).
 */
#include <string.h>

#include "ports/common/port_counter.h"
#include "ports/common/port_ring.h"
#include "unity.h"

void setUp(void)
{
}

void tearDown(void)
{
}

static uint32_t lcg(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s;
}

/* A 16-bit timer followed through forward and backward wraps with steps up
 * to +-32767 per read: the extended count equals the true count modulo
 * 2^32, from any start value. */
static void test_counter16_follows_the_true_count_across_wraps(void)
{
    static const uint32_t starts[] = {0u, 1u, 0x7FFFu, 0x8000u, 0xFFFFu};
    unsigned k, n;

    for (k = 0; k < sizeof starts / sizeof starts[0]; k++) {
        port_counter_t c;
        int64_t truth = 0;
        uint32_t seed = 7u + k;

        port_counter_init(&c, starts[k], 16u);
        for (n = 0; n < 20000u; n++) {
            int32_t step = (int32_t)(lcg(&seed) % 65535u) - 32767; /* -32767..32767 */
            if (n % 1000u < 10u) {
                step = (n & 1u) ? 32767 : -32767; /* the extremes */
            }
            truth += step;
            TEST_ASSERT_EQUAL_HEX32(
                (uint32_t)truth, port_counter_update(&c, (starts[k] + (uint32_t)truth) & 0xFFFFu));
        }
    }
}

/* One step of 32768 counts or more between reads is ambiguous for a 16-bit
 * counter: it is taken as the shorter way round (the documented limit). */
static void test_counter16_limit_is_half_the_range(void)
{
    port_counter_t c;
    port_counter_init(&c, 0u, 16u);
    TEST_ASSERT_EQUAL_HEX32(0xFFFF8000u, port_counter_update(&c, 0x8000u));
    port_counter_init(&c, 0u, 16u);
    TEST_ASSERT_EQUAL_HEX32((uint32_t)-32767, port_counter_update(&c, 32769u)); /* +32769 */
}

/* A 32-bit timer passes through unchanged (relative to its start), also
 * across its own wrap. */
static void test_counter32_is_the_timer_relative_to_its_start(void)
{
    port_counter_t c;
    port_counter_init(&c, 0xFFFFFFF0u, 32u);
    TEST_ASSERT_EQUAL_HEX32(0x10u, port_counter_update(&c, 0u));
    TEST_ASSERT_EQUAL_HEX32(0x80000010u, port_counter_update(&c, 0x80000000u));
    TEST_ASSERT_EQUAL_HEX32(0xFFFFFFF0u, port_counter_update(&c, 0xFFFFFFE0u));
}

/* The ring: a full ring refuses (nothing overwritten), a write stores what
 * fits, the bytes come out in order across the wrap of the free-running
 * indices. */
static void test_ring_refuses_when_full_and_keeps_order_across_wraps(void)
{
    static uint8_t buf[8];
    port_ring_t r = PORT_RING_INIT(buf);
    uint8_t in[5], out[8], c;
    uint32_t next_in = 0u, next_out = 0u;
    unsigned n, i;
    size_t got;

    r.head = r.tail = 0xFFFFFFFCu; /* the indices wrap during the test */
    TEST_ASSERT_TRUE(port_ring_empty(&r));
    for (n = 0; n < 200u; n++) {
        for (i = 0; i < sizeof in; i++) {
            in[i] = (uint8_t)(next_in + i);
        }
        next_in += (uint32_t)port_ring_write(&r, in, sizeof in);
        TEST_ASSERT_TRUE(r.head - r.tail <= sizeof buf);
        if (r.head - r.tail == sizeof buf) {
            TEST_ASSERT_FALSE(port_ring_put(&r, 0xEEu)); /* full: refused */
        }
        got = port_ring_read(&r, out, 3u);
        for (i = 0; i < got; i++) {
            TEST_ASSERT_EQUAL_UINT8((uint8_t)next_out, out[i]);
            next_out++;
        }
    }
    while (port_ring_get(&r, &c)) {
        TEST_ASSERT_EQUAL_UINT8((uint8_t)next_out, c);
        next_out++;
    }
    TEST_ASSERT_EQUAL_UINT32(next_in, next_out);
    TEST_ASSERT_TRUE(port_ring_empty(&r));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_counter16_follows_the_true_count_across_wraps);
    RUN_TEST(test_counter16_limit_is_half_the_range);
    RUN_TEST(test_counter32_is_the_timer_relative_to_its_start);
    RUN_TEST(test_ring_refuses_when_full_and_keeps_order_across_wraps);
    return UNITY_END();
}
