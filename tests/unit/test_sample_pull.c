/* sample_pull: the pull of numbered samples (window, layout, CRC, a
 * sample recorded while a chunk is read), the staging of a record at
 * offset (range refusal, fresh record, CRC) and the read at offset. */
#include <string.h>

#include "crc.h"
#include "proto_msgs.h"
#include "sample_pull.h"
#include "unity.h"

void setUp(void)
{
}

void tearDown(void)
{
}

/* A producer of 4-byte samples (value = 1000 + seq) in a ring of 8; the
 * encoder may record one more sample while it runs, as the tick would. */
static struct {
    uint32_t ring[8];
    uint32_t written;
    bool record_during_read;
} prod;

static void produce(void)
{
    prod.ring[prod.written % 8u] = 1000u + prod.written;
    prod.written++;
}

static void enc(const void *src, uint32_t seq, uint8_t *dst)
{
    TEST_ASSERT_EQUAL_PTR(&prod, src);
    if (prod.record_during_read) {
        prod.record_during_read = false;
        produce();
    }
    proto_put_le(dst, prod.ring[seq % 8u], 4u);
}

static uint32_t get_le(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void test_seq_window_and_wrap(void)
{
    TEST_ASSERT_TRUE(sample_pull_seq_ok(10u, 15u, 10u));
    TEST_ASSERT_TRUE(sample_pull_seq_ok(10u, 15u, 15u));       /* nothing new: empty reply */
    TEST_ASSERT_FALSE(sample_pull_seq_ok(10u, 15u, 9u));       /* released already */
    TEST_ASSERT_FALSE(sample_pull_seq_ok(10u, 15u, 16u));      /* not recorded yet */
    TEST_ASSERT_TRUE(sample_pull_seq_ok(0xFFFFFFFEu, 3u, 1u)); /* across 2^32 */
    TEST_ASSERT_FALSE(sample_pull_seq_ok(0xFFFFFFFEu, 3u, 0xFFFFFFFDu));
    TEST_ASSERT_FALSE(sample_pull_seq_ok(0xFFFFFFFEu, 3u, 4u));
}

static void test_reply_layout_count_and_crc(void)
{
    uint8_t out[PROTO_MSG_MAX];
    proto_calib_samples_t r;
    size_t n;
    unsigned i;

    memset(&prod, 0, sizeof prod);
    for (i = 0; i < 6u; i++) {
        produce();
    }
    n = sample_pull_reply(out, 0xB1u, 0x42u, 2u, 3u, prod.written, 4u, enc, &prod);
    TEST_ASSERT_EQUAL_UINT32(PROTO_MSG_HDR + SAMPLE_PULL_HDR + 12u, n);
    TEST_ASSERT_EQUAL_HEX8(0xB1u, out[0]);
    TEST_ASSERT_EQUAL_HEX8(0x42u, out[1]);
    /* the generated decoder of calib_samples reads it as the drive meant */
    TEST_ASSERT_TRUE(proto_calib_samples_decode(out + PROTO_MSG_HDR, n - PROTO_MSG_HDR, &r));
    TEST_ASSERT_EQUAL_UINT32(2u, r.from_seq);
    TEST_ASSERT_EQUAL_UINT8(3u, r.count);
    TEST_ASSERT_EQUAL_UINT32(6u, r.seq_next);
    TEST_ASSERT_EQUAL_UINT16(12u, r.data_len);
    for (i = 0; i < 3u; i++) {
        TEST_ASSERT_EQUAL_UINT32(1002u + i, get_le(r.data + 4u * i));
    }
    TEST_ASSERT_EQUAL_HEX32(crc32_update(CRC32_INIT, r.data, r.data_len), r.crc);

    /* fewer than max left: only those; none left: an empty chunk, CRC of nothing */
    n = sample_pull_reply(out, 0xB1u, 1u, 4u, 7u, prod.written, 4u, enc, &prod);
    TEST_ASSERT_EQUAL_UINT32(PROTO_MSG_HDR + SAMPLE_PULL_HDR + 8u, n);
    TEST_ASSERT_EQUAL_UINT8(2u, out[PROTO_MSG_HDR + 4]);
    n = sample_pull_reply(out, 0xB1u, 1u, 6u, 7u, prod.written, 4u, enc, &prod);
    TEST_ASSERT_EQUAL_UINT32(PROTO_MSG_HDR + SAMPLE_PULL_HDR, n);
    TEST_ASSERT_EQUAL_UINT8(0u, out[PROTO_MSG_HDR + 4]);
    TEST_ASSERT_EQUAL_HEX32(0u, get_le(out + PROTO_MSG_HDR + 9));
}

static void test_sample_recorded_while_read_waits_for_next_chunk(void)
{
    uint8_t out[PROTO_MSG_MAX], again[PROTO_MSG_MAX];
    uint32_t written;
    size_t n, m;

    memset(&prod, 0, sizeof prod);
    produce();
    produce();
    written = prod.written; /* main reads it once */
    prod.record_during_read = true;
    n = sample_pull_reply(out, 0xD9u, 7u, 0u, 5u, written, 4u, enc, &prod);
    TEST_ASSERT_EQUAL_UINT32(3u, prod.written); /* the tick recorded one meanwhile */
    TEST_ASSERT_EQUAL_UINT8(2u, out[PROTO_MSG_HDR + 4]);
    TEST_ASSERT_EQUAL_UINT32(2u, get_le(out + PROTO_MSG_HDR + 5));
    TEST_ASSERT_EQUAL_HEX32(crc32_update(CRC32_INIT, out + PROTO_MSG_HDR + SAMPLE_PULL_HDR, 8u),
                            get_le(out + PROTO_MSG_HDR + 9));
    /* a retried read of the same snapshot is the same reply (idempotent) */
    m = sample_pull_reply(again, 0xD9u, 7u, 0u, 5u, written, 4u, enc, &prod);
    TEST_ASSERT_EQUAL_UINT32(n, m);
    TEST_ASSERT_EQUAL_MEMORY(out, again, n);
    /* the next read from where this one ended gets the new sample */
    n = sample_pull_reply(out, 0xD9u, 8u, 2u, 5u, prod.written, 4u, enc, &prod);
    TEST_ASSERT_EQUAL_UINT8(1u, out[PROTO_MSG_HDR + 4]);
    TEST_ASSERT_EQUAL_UINT32(1002u, get_le(out + PROTO_MSG_HDR + SAMPLE_PULL_HDR));
}

static void test_stage_chunks_at_offset_range_and_crc(void)
{
    uint8_t buf[16], rec[16];
    sample_pull_stage_t s;
    unsigned i;

    for (i = 0; i < sizeof rec; i++) {
        rec[i] = (uint8_t)(3u * i + 1u);
    }
    memset(buf, 0x55, sizeof buf);
    sample_pull_stage_init(&s, buf, (uint16_t)sizeof buf);
    /* a record in two chunks, then the first again (a retry) */
    TEST_ASSERT_TRUE(sample_pull_stage_write(&s, 0u, rec, 6u, true));
    TEST_ASSERT_EQUAL_HEX8(0xFFu, buf[15]); /* erased */
    TEST_ASSERT_EQUAL_UINT16(6u, s.staged);
    TEST_ASSERT_TRUE(sample_pull_stage_write(&s, 6u, rec + 6, 6u, false));
    TEST_ASSERT_EQUAL_UINT16(12u, s.staged);
    TEST_ASSERT_TRUE(sample_pull_stage_write(&s, 0u, rec, 6u, false)); /* a repeat */
    TEST_ASSERT_EQUAL_UINT16(12u, s.staged);
    TEST_ASSERT_EQUAL_MEMORY(rec, buf, 12u);
    TEST_ASSERT_EQUAL_HEX32(crc32_update(CRC32_INIT, rec, 12u), sample_pull_stage_crc(&s, 12u));

    /* a chunk ending past the buffer is refused and changes nothing */
    TEST_ASSERT_FALSE(sample_pull_stage_write(&s, 12u, rec, 5u, false));
    TEST_ASSERT_FALSE(sample_pull_stage_write(&s, 0xFFFFu, rec, 1u, true));
    TEST_ASSERT_FALSE(sample_pull_stage_write(&s, 0xFFFFFFFFu, rec, 2u, true));
    TEST_ASSERT_EQUAL_UINT16(12u, s.staged);
    TEST_ASSERT_EQUAL_MEMORY(rec, buf, 12u);
    TEST_ASSERT_TRUE(sample_pull_stage_write(&s, 12u, rec + 12, 4u, false)); /* up to the end */
    TEST_ASSERT_EQUAL_UINT16(16u, s.staged);

    /* a fresh record forgets the old one */
    TEST_ASSERT_TRUE(sample_pull_stage_write(&s, 2u, rec, 2u, true));
    TEST_ASSERT_EQUAL_UINT16(4u, s.staged);
    TEST_ASSERT_EQUAL_HEX8(0xFFu, buf[0]);
    TEST_ASSERT_EQUAL_HEX8(0xFFu, buf[4]);
    TEST_ASSERT_NOT_EQUAL(crc32_update(CRC32_INIT, rec, 12u), sample_pull_stage_crc(&s, 12u));
}

static void test_copy_at_offset(void)
{
    const uint8_t rec[10] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
    uint8_t dst[10];

    memset(dst, 0xEE, sizeof dst);
    TEST_ASSERT_EQUAL_UINT32(4u, sample_pull_copy(dst, 4u, rec, 10u, 3u));
    TEST_ASSERT_EQUAL_MEMORY(rec + 3, dst, 4u);
    TEST_ASSERT_EQUAL_HEX8(0xEEu, dst[4]);
    TEST_ASSERT_EQUAL_UINT32(3u, sample_pull_copy(dst, 8u, rec, 10u, 7u)); /* the tail */
    TEST_ASSERT_EQUAL_MEMORY(rec + 7, dst, 3u);
    TEST_ASSERT_EQUAL_UINT32(0u, sample_pull_copy(dst, 8u, rec, 10u, 10u));  /* at the end */
    TEST_ASSERT_EQUAL_UINT32(0u, sample_pull_copy(dst, 8u, rec, 10u, 200u)); /* past it */
    TEST_ASSERT_EQUAL_UINT32(0u, sample_pull_copy(dst, 0u, rec, 10u, 0u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_seq_window_and_wrap);
    RUN_TEST(test_reply_layout_count_and_crc);
    RUN_TEST(test_sample_recorded_while_read_waits_for_next_chunk);
    RUN_TEST(test_stage_chunks_at_offset_range_and_crc);
    RUN_TEST(test_copy_at_offset);
    return UNITY_END();
}
