/* Block batches (proto_batch.h): the record codec (round trips, the golden
 * vector shared with tests/python/test_stream_batch.py, malformed records)
 * and the drive's intake through the dispatcher against the simulated
 * drive: window accounting, a zero window, the replay cache and the
 * sequence check against duplicated blocks, version refusal at
 * session_open. */
#include <string.h>

#include "drive.h"
#include "proto_batch.h"
#include "proto_dispatch.h"
#include "sim.h"
#include "unity.h"
#include "dispatch_fixture.h"

void setUp(void)
{
    dispatch_fixture_start();
}

void tearDown(void)
{
}

static void run_ms(unsigned ms)
{
    unsigned k;

    for (k = 0; k < ms; k++) {
        TEST_ASSERT_TRUE(sim_run(10u, NULL, 0, 0) >= 0);
        now_us += 1000u;
        proto_dispatch_poll(&d, now_us, NULL, NULL);
    }
}

/* The golden batch of tests/python/test_stream_batch.py: an origin at
 * (1 mm, -2 mm), two 10 um lines at 6 m/min, a rapid with exact stop, a
 * dwell of 250 ms, a line back at 3 m/min. */
static const uint8_t golden[] = {0xCF, 0x80, 0x89, 0x7A, 0xFF, 0x91, 0xF4, 0x01, 0x00, 0x00, 0x11,
                                 0xA0, 0x9C, 0x01, 0x80, 0xC2, 0xD7, 0x2F, 0x01, 0xA0, 0x9C, 0x01,
                                 0x66, 0xA0, 0x9C, 0x01, 0x90, 0x4E, 0x90, 0xFA, 0x01, 0x17, 0xBF,
                                 0xB8, 0x02, 0x9F, 0x9C, 0x01, 0x8F, 0x4E, 0x80, 0xE1, 0xEB, 0x17};

static const proto_batch_block_t golden_blocks[] = {
    {PROTO_BATCH_KIND_LINE, false, {0}, {1010000, -2000000, 0, 0}, 100000000u},
    {PROTO_BATCH_KIND_LINE, false, {0}, {1020000, -2000000, 0, 0}, 100000000u},
    {PROTO_BATCH_KIND_RAPID, true, {0}, {1020000, -1990000, 5000, 0}, 0u},
    {PROTO_BATCH_KIND_DWELL, false, {0}, {1020000, -1990000, 5000, 0}, 250u},
    {PROTO_BATCH_KIND_LINE, false, {0}, {1000000, -2000000, 0, 0}, 50000000u},
};
#define GOLDEN_N (sizeof golden_blocks / sizeof golden_blocks[0])

static void test_golden_batch_encodes_and_decodes(void)
{
    uint8_t buf[PROTO_QUEUE_BATCH_MAX_LEN];
    int64_t pt[PROTO_MAX_AXES] = {1000000, -2000000, 0, 0};
    uint64_t feed = 0;
    size_t n = 0;
    unsigned i, a;
    proto_batch_rd_t rd;
    proto_batch_block_t b;
    const int64_t zero[PROTO_MAX_AXES] = {0, 0, 0, 0};

    for (i = 0; i < GOLDEN_N; i++) {
        size_t k = proto_batch_put(buf + n, sizeof buf - n, &golden_blocks[i], pt, &feed, i == 0);
        TEST_ASSERT_TRUE(k > 0u);
        n += k;
    }
    TEST_ASSERT_EQUAL_size_t(sizeof golden, n);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(golden, buf, n);
    proto_batch_rd_init(&rd, golden, sizeof golden, zero, 0);
    for (i = 0; i < GOLDEN_N; i++) {
        TEST_ASSERT_EQUAL_INT(1, proto_batch_rd_next(&rd, &b));
        TEST_ASSERT_EQUAL_UINT8(golden_blocks[i].kind, b.kind);
        TEST_ASSERT_EQUAL(golden_blocks[i].exact_stop, b.exact_stop);
        TEST_ASSERT_EQUAL_UINT64(golden_blocks[i].feed, b.feed);
        for (a = 0; a < PROTO_MAX_AXES; a++) {
            TEST_ASSERT_EQUAL_INT64(golden_blocks[i].target[a], b.target[a]);
        }
    }
    TEST_ASSERT_EQUAL_INT(0, proto_batch_rd_next(&rd, &b));
}

static uint32_t lcg = 12345u;

static uint32_t rnd(void)
{
    lcg = lcg * 1664525u + 1013904223u;
    return lcg >> 8;
}

static int64_t rnd64(void)
{
    return (int64_t)(((uint64_t)rnd() << 40) ^ ((uint64_t)rnd() << 16) ^ rnd());
}

/* Random blocks of every kind and size (deltas from 0 to +-2^62, feeds
 * that change or not) read back as written. */
static void test_random_blocks_round_trip(void)
{
    unsigned round;

    for (round = 0; round < 2000u; round++) {
        uint8_t buf[PROTO_QUEUE_BATCH_MAX_LEN];
        proto_batch_block_t w[64];
        int64_t pt[PROTO_MAX_AXES] = {0, 0, 0, 0};
        int64_t start[PROTO_MAX_AXES];
        uint64_t feed = 0;
        size_t n = 0;
        unsigned nb = 0, i, a;
        proto_batch_rd_t rd;
        proto_batch_block_t b;

        for (a = 0; a < PROTO_MAX_AXES; a++) {
            pt[a] = (rnd() % 4u == 0u) ? rnd64() >> (rnd() % 61u + 3u) : 0;
            start[a] = pt[a];
        }
        while (nb < 64u) {
            proto_batch_block_t *x = &w[nb];
            int64_t keep[PROTO_MAX_AXES];
            uint64_t keep_feed = feed;
            size_t k;

            memset(x, 0, sizeof *x);
            x->kind = (uint8_t)(rnd() % 3u);
            x->exact_stop = x->kind != PROTO_BATCH_KIND_DWELL && rnd() % 2u == 0u;
            for (a = 0; a < PROTO_MAX_AXES; a++) {
                keep[a] = pt[a];
                x->target[a] = pt[a];
                if (x->kind != PROTO_BATCH_KIND_DWELL && rnd() % 2u == 0u) {
                    x->target[a] = pt[a] + (rnd64() >> (rnd() % 56u + 8u));
                }
            }
            x->feed = x->kind == PROTO_BATCH_KIND_RAPID ? 0u
                      : (rnd() % 3u == 0u && feed != 0u && x->kind == PROTO_BATCH_KIND_LINE)
                          ? feed
                          : 1u + rnd() % 4000000000u;
            k = proto_batch_put(buf + n, sizeof buf - n, x, pt, &feed, nb == 0u);
            if (k == 0u) {
                for (a = 0; a < PROTO_MAX_AXES; a++) {
                    TEST_ASSERT_EQUAL_INT64(keep[a], pt[a]); /* untouched when full */
                }
                TEST_ASSERT_EQUAL_UINT64(keep_feed, feed);
                break;
            }
            n += k;
            nb++;
        }
        proto_batch_rd_init(&rd, buf, n, pt, 0); /* the origin record sets the point */
        for (i = 0; i < nb; i++) {
            TEST_ASSERT_EQUAL_INT(1, proto_batch_rd_next(&rd, &b));
            TEST_ASSERT_EQUAL_UINT8(w[i].kind, b.kind);
            TEST_ASSERT_EQUAL(w[i].exact_stop, b.exact_stop);
            if (w[i].kind != PROTO_BATCH_KIND_RAPID) {
                TEST_ASSERT_EQUAL_UINT64(w[i].feed, b.feed);
            }
            for (a = 0; a < PROTO_MAX_AXES; a++) {
                TEST_ASSERT_EQUAL_INT64(w[i].target[a], b.target[a]);
                TEST_ASSERT_EQUAL_INT64(i == 0 ? start[a] : w[i - 1].target[a], b.from[a]);
            }
        }
        TEST_ASSERT_EQUAL_INT(0, proto_batch_rd_next(&rd, &b));
    }
}

static int read_all(const uint8_t *p, size_t n)
{
    const int64_t zero[PROTO_MAX_AXES] = {0, 0, 0, 0};
    proto_batch_rd_t rd;
    proto_batch_block_t b;
    int k;

    proto_batch_rd_init(&rd, p, n, zero, 0);
    while ((k = proto_batch_rd_next(&rd, &b)) == 1) {
    }
    return k;
}

static void test_malformed_records_are_refused(void)
{
    static const uint8_t truncated[] = {0x11, 0xA0, 0x9C}; /* delta ends early */
    static const uint8_t no_feed[] = {0x01, 0x02};         /* line, no feed yet */
    static const uint8_t two_origins[] = {0xC1, 0x02, 0xC1, 0x02, 0x10, 0x01};
    static const uint8_t dwell_delta[] = {0x91, 0x02, 0x05}; /* dwell with a delta */
    static const uint8_t dwell_no_time[] = {0x80};           /* dwell without time */
    static const uint8_t rapid_feed[] = {0x51, 0x02, 0x05};  /* rapid with a feed */
    static const uint8_t origin_flags[] = {0xD1, 0x02};      /* origin with feed */
    static const uint8_t long_varint[] = {0x11, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80,
                                          0x80, 0x80, 0x80, 0x80, 0x01, 0x01};
    static const uint8_t over_64[] = {0x11, 0x80, 0x80, 0x80, 0x80, 0x80,
                                      0x80, 0x80, 0x80, 0x80, 0x02, 0x01};
    static const uint8_t ok_64[] = {0x11, 0xFE, 0xFF, 0xFF, 0xFF, 0xFF,
                                    0xFF, 0xFF, 0xFF, 0xFF, 0x01, 0x01}; /* 2^64 - 2: -2^63 + ... */

    TEST_ASSERT_EQUAL_INT(-1, read_all(truncated, sizeof truncated));
    TEST_ASSERT_EQUAL_INT(-1, read_all(no_feed, sizeof no_feed));
    TEST_ASSERT_EQUAL_INT(-1, read_all(two_origins, sizeof two_origins));
    TEST_ASSERT_EQUAL_INT(-1, read_all(dwell_delta, sizeof dwell_delta));
    TEST_ASSERT_EQUAL_INT(-1, read_all(dwell_no_time, sizeof dwell_no_time));
    TEST_ASSERT_EQUAL_INT(-1, read_all(rapid_feed, sizeof rapid_feed));
    TEST_ASSERT_EQUAL_INT(-1, read_all(origin_flags, sizeof origin_flags));
    TEST_ASSERT_EQUAL_INT(-1, read_all(long_varint, sizeof long_varint));
    TEST_ASSERT_EQUAL_INT(-1, read_all(over_64, sizeof over_64));
    TEST_ASSERT_EQUAL_INT(0, read_all(ok_64, sizeof ok_64));
}

/* ---- intake through the dispatcher -------------------------------------------- */

static void enable(void)
{
    const uint8_t p[2] = {0x07, 1u};

    request(PROTO_MSG_ENABLE, p, 2);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ACK, out[0]);
    run_ms(1);
}

/* A queue_batch payload of n lines of `step` nm along X from x (an origin
 * record first when `origin`) at feed nm/s. */
static size_t batch_payload(uint8_t *p, uint32_t first, int64_t x, unsigned n, int64_t step,
                            uint64_t feed_nm_s, bool start, bool origin)
{
    proto_queue_batch_t q;
    proto_batch_block_t b;
    int64_t pt[PROTO_MAX_AXES] = {x, 0, 0, 0};
    uint64_t feed = origin ? 0u : feed_nm_s;
    unsigned i;

    memset(&b, 0, sizeof b);
    memset(&q, 0, sizeof q);
    q.first_seq = first;
    q.flags = start ? (uint8_t)(1u << PROTO_BATCH_FLAG_START) : 0u;
    b.kind = PROTO_BATCH_KIND_LINE;
    b.feed = feed_nm_s;
    for (i = 0; i < n; i++) {
        size_t k;

        b.target[0] = x + (int64_t)(i + 1u) * step;
        k = proto_batch_put(q.data + q.data_len, sizeof q.data - q.data_len, &b, pt, &feed,
                            origin && i == 0u);
        TEST_ASSERT_TRUE(k > 0u);
        q.data_len = (uint16_t)(q.data_len + k);
        q.count++;
    }
    return proto_queue_batch_encode(&q, p, PROTO_MAX_PAYLOAD);
}

static proto_batch_reply_t reply(void)
{
    proto_batch_reply_t r;

    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_BATCH_REPLY, out[0]);
    TEST_ASSERT_TRUE(proto_batch_reply_decode(out + 2, out_len - 2, &r));
    return r;
}

static proto_batch_reply_t window(uint32_t first)
{
    uint8_t p[PROTO_MSG_MAX];

    request(PROTO_MSG_QUEUE_BATCH, p, batch_payload(p, first, 0, 0, 0, 1, false, false));
    return reply();
}

static drive_status_t status(void)
{
    drive_status_t st;

    drive_status(&st);
    return st;
}

/* A job of 1500 lines (more than the FIFO, planner and ring hold at once):
 * the window in each reply is the ring's room; batches sent only into it
 * are taken whole; every block runs once, in order. */
static void test_window_accounting_runs_every_block_once(void)
{
    uint8_t p[PROTO_MSG_MAX];
    uint32_t next = 0;
    unsigned rounds = 0, full = 0;
    uint16_t room = PROTO_BATCH_RING;
    drive_status_t st;

    enable();
    while (next < 1500u && rounds++ < 20000u) {
        unsigned n = 1500u - next < 50u ? 1500u - next : 50u;
        size_t len =
            batch_payload(p, next, (int64_t)next * 10000, n, 10000, 20000000u, next == 0u, true);
        proto_batch_reply_t r;

        if (len - PROTO_QUEUE_BATCH_LEN > room) {
            full++;
            run_ms(1);
            room = window(next).free_bytes;
            continue;
        }
        request(PROTO_MSG_QUEUE_BATCH, p, len);
        r = reply();
        TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_NONE, r.status);
        TEST_ASSERT_EQUAL_UINT8(n, r.accepted);
        TEST_ASSERT_EQUAL_UINT32(next + n, r.next_seq);
        TEST_ASSERT_TRUE(r.free_bytes <= room);
        next = r.next_seq;
        room = r.free_bytes;
        run_ms(1);
    }
    TEST_ASSERT_TRUE(full > 0u); /* the window closed on the way */
    for (rounds = 0; rounds < 20000u && status().state != DRIVE_IDLE; rounds++) {
        run_ms(1);
    }
    st = status();
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(1500u, st.blocks_done);
    TEST_ASSERT_EQUAL_UINT32(1499u, st.tag);
    TEST_ASSERT_EQUAL_INT64(15000000, st.ref[0]);
}

/* A drive whose ring is full takes nothing of a batch and says so; the
 * blocks it did take stay in order (the rest is sent again from next_seq). */
static void test_a_full_ring_takes_nothing_more(void)
{
    uint8_t p[PROTO_MSG_MAX];
    proto_batch_reply_t r;
    uint32_t next = 0;
    unsigned i;

    enable();
    /* feed 1 mm/s: nothing leaves the queue meanwhile */
    for (i = 0; i < 40u; i++) {
        request(
            PROTO_MSG_QUEUE_BATCH, p,
            batch_payload(p, next, (int64_t)next * 10000, 50, 10000, 1000000u, next == 0u, true));
        r = reply();
        next = r.next_seq;
        if (r.status == PROTO_ERROR_CODE_QUEUE_FULL) {
            break;
        }
        TEST_ASSERT_EQUAL_UINT8(50, r.accepted);
    }
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_QUEUE_FULL, r.status);
    TEST_ASSERT_TRUE(r.free_bytes < 250u);
    request(PROTO_MSG_QUEUE_BATCH, p,
            batch_payload(p, next, (int64_t)next * 10000, 50, 10000, 1000000u, false, true));
    r = reply();
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_QUEUE_FULL, r.status);
    TEST_ASSERT_EQUAL_UINT8(0, r.accepted);
    TEST_ASSERT_EQUAL_UINT32(next, r.next_seq);
}

/* A retried batch (same id, seq and bytes) is answered from the replay
 * cache; once another batch came after it, the retry fails the sequence
 * check and its next_seq tells how much was taken - the start batch too
 * (it does not start the stream again): no block twice. */
static void test_a_retried_batch_never_queues_twice(void)
{
    uint8_t a[PROTO_MSG_MAX], b[PROTO_MSG_MAX];
    size_t na, nb;
    proto_batch_reply_t r1, r2;
    drive_status_t st;
    unsigned k;

    enable();
    na = batch_payload(a, 0, 0, 30, 10000, 20000000u, true, true);
    nb = batch_payload(b, 30, 300000, 30, 10000, 20000000u, false, true);
    request_seq(PROTO_MSG_QUEUE_BATCH, 7, a, na);
    r1 = reply();
    request_seq(PROTO_MSG_QUEUE_BATCH, 7, a, na); /* the reply was lost: again */
    r2 = reply();
    TEST_ASSERT_EQUAL_MEMORY(&r1, &r2, sizeof r1);
    TEST_ASSERT_EQUAL_UINT32(30u, r2.next_seq);
    request_seq(PROTO_MSG_QUEUE_BATCH, 8, b, nb);
    TEST_ASSERT_EQUAL_UINT32(60u, reply().next_seq);
    request_seq(PROTO_MSG_QUEUE_BATCH, 7, a, na); /* a late retry of the first */
    r2 = reply();
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_SEQUENCE, r2.status);
    TEST_ASSERT_EQUAL_UINT8(0, r2.accepted);
    TEST_ASSERT_EQUAL_UINT32(60u, r2.next_seq);
    for (k = 0; k < 20000u && status().state != DRIVE_IDLE; k++) {
        run_ms(1);
    }
    st = status();
    TEST_ASSERT_EQUAL_UINT32(60u, st.blocks_done);
    TEST_ASSERT_EQUAL_INT64(600000, st.ref[0]);
}

/* Refusals: a disabled drive takes nothing; a block beyond the soft limit
 * ends the batch there (the blocks before it are taken); a malformed batch
 * or a wrong count changes nothing. */
static void test_refusals_name_the_block(void)
{
    uint8_t p[PROTO_MSG_MAX];
    proto_batch_reply_t r;
    proto_error_t e;
    drive_param_value_t lim[2] = {{DRIVE_PARAM_SOFT_MIN, 0, -1000000},
                                  {DRIVE_PARAM_SOFT_MAX, 0, 55000}};

    request(PROTO_MSG_QUEUE_BATCH, p, batch_payload(p, 0, 0, 5, 10000, 20000000u, true, true));
    r = reply();
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_DISABLED, r.status);
    TEST_ASSERT_EQUAL_UINT8(0, r.accepted);
    enable();
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set_all(lim, 2));
    request(PROTO_MSG_QUEUE_BATCH, p, batch_payload(p, 0, 0, 10, 10000, 20000000u, true, true));
    r = reply();
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_OUT_OF_RANGE, r.status);
    TEST_ASSERT_EQUAL_UINT16(0, r.arg); /* axis X */
    TEST_ASSERT_EQUAL_UINT8(5, r.accepted);
    TEST_ASSERT_EQUAL_UINT32(5u, r.next_seq); /* block 5 ends at 60 um */
    {
        proto_queue_batch_t q;

        memset(&q, 0, sizeof q);
        q.first_seq = 5;
        q.count = 2;
        q.data_len = 2;
        q.data[0] = 0x01; /* a delta that never ends */
        q.data[1] = 0x80;
        request(PROTO_MSG_QUEUE_BATCH, p, proto_queue_batch_encode(&q, p, sizeof p));
        TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ERROR, out[0]);
        TEST_ASSERT_TRUE(proto_error_decode(out + 2, out_len - 2, &e));
        TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_BAD_VALUE, e.code);
        q.data[1] = 0x02; /* well-formed, but one block, not two */
        request(PROTO_MSG_QUEUE_BATCH, p, proto_queue_batch_encode(&q, p, sizeof p));
        TEST_ASSERT_TRUE(proto_error_decode(out + 2, out_len - 2, &e));
        TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_BAD_LENGTH, e.code);
    }
    TEST_ASSERT_EQUAL_UINT32(5u, window(5).next_seq);
}

/* A stop empties the ring: later batches get busy until a new stream. */
static void test_a_stop_ends_the_stream(void)
{
    uint8_t p[PROTO_MSG_MAX];
    proto_batch_reply_t r;
    unsigned i;

    enable();
    for (i = 0; i < 4u; i++) {
        request(PROTO_MSG_QUEUE_BATCH, p,
                batch_payload(p, 50u * i, 500000 * (int64_t)i, 50, 10000, 1000000u, i == 0u, true));
    }
    TEST_ASSERT_TRUE(d.batch.used > 0u);
    request(PROTO_MSG_STOP, NULL, 0);
    TEST_ASSERT_EQUAL_UINT16(0, d.batch.used);
    r = window(200);
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_BUSY, r.status);
    TEST_ASSERT_TRUE(r.next_seq < 200u); /* back to the first block not queued */
    for (i = 0; i < 20000u && status().state != DRIVE_IDLE; i++) {
        run_ms(1);
    }
    run_ms(200);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, status().state); /* nothing of the ring ran */
    request(PROTO_MSG_QUEUE_BATCH, p,
            batch_payload(p, 1000, status().ref[0], 3, 10000, 20000000u, true, true));
    r = reply();
    TEST_ASSERT_EQUAL_UINT8(3, r.accepted);
    TEST_ASSERT_EQUAL_UINT32(1003u, r.next_seq);
}

/* session_open carries the host's protocol version: a host of version 1
 * (no version field) or another version is refused with not_supported and
 * this drive's version; the same version opens a session that reports it. */
static void test_session_open_refuses_another_protocol_version(void)
{
    uint8_t p[8] = {1, 2, 3, 4, 0, 0};
    proto_error_t e;
    proto_session_reply_t s;

    request(PROTO_MSG_SESSION_OPEN, p, 4); /* protocol 1 */
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ERROR, out[0]);
    TEST_ASSERT_TRUE(proto_error_decode(out + 2, out_len - 2, &e));
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_NOT_SUPPORTED, e.code);
    TEST_ASSERT_EQUAL_UINT16(PROTO_VERSION, e.arg);
    p[4] = (uint8_t)(PROTO_VERSION + 1u);
    request(PROTO_MSG_SESSION_OPEN, p, 6);
    TEST_ASSERT_TRUE(proto_error_decode(out + 2, out_len - 2, &e));
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_NOT_SUPPORTED, e.code);
    TEST_ASSERT_EQUAL_UINT32(0, d.sessions);
    p[4] = (uint8_t)PROTO_VERSION;
    request(PROTO_MSG_SESSION_OPEN, p, 6);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_SESSION_REPLY, out[0]);
    TEST_ASSERT_TRUE(proto_session_reply_decode(out + 2, out_len - 2, &s));
    TEST_ASSERT_EQUAL_UINT16(PROTO_VERSION, s.protocol_version);
    TEST_ASSERT_EQUAL_UINT32(0x04030201u, s.nonce);
}

static void set_comm_timeout(uint32_t ms)
{
    proto_param_set_t ps = {PROTO_PARAM_COMM_TIMEOUT_MS, (int64_t)ms};
    uint8_t p[PROTO_MAX_PAYLOAD];

    request(PROTO_MSG_PARAM_SET, p, proto_param_set_encode(&ps, p, sizeof p));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, out[0]);
}

/* The watchdog of a streamed job listens to the streaming host only: a
 * second host that reads the status does not keep the job of a host that
 * died running; window polls do. A jog taken afterwards is the watcher's
 * own motion again: its status requests keep it alive. */
static void test_a_watcher_does_not_keep_a_dead_stream_running(void)
{
    uint8_t p[PROTO_MSG_MAX];
    proto_jog_t j = {0u, 10000000u, 20000000};
    unsigned ms;

    set_comm_timeout(100);
    enable();
    request(PROTO_MSG_QUEUE_BATCH, p, batch_payload(p, 0, 0, 40, 500000, 10000000u, true, true));
    TEST_ASSERT_EQUAL_UINT8(40, reply().accepted);
    for (ms = 0; ms < 300; ms += 10) { /* the streamer polls its window */
        run_ms(10);
        (void)window(40);
    }
    TEST_ASSERT_EQUAL_UINT8(DRIVE_RUNNING, status().state);
    for (ms = 0; ms < 300; ms += 10) { /* it died; a watcher reads the status */
        run_ms(10);
        request(PROTO_MSG_STATUS_GET, NULL, 0);
    }
    TEST_ASSERT_EQUAL_UINT32(1, d.stats.watchdog_stops);
    for (ms = 0; ms < 3000 && status().state != DRIVE_FAULT; ms += 10) {
        run_ms(10);
        request(PROTO_MSG_STATUS_GET, NULL, 0);
    }
    TEST_ASSERT_EQUAL_UINT8(DRIVE_FAULT, status().state);
    request(PROTO_MSG_FAULT_RESET, NULL, 0);
    run_ms(1);
    enable();
    request(PROTO_MSG_JOG, p, proto_jog_encode(&j, p, sizeof p));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, out[0]);
    for (ms = 0; ms < 500; ms += 10) {
        run_ms(10);
        request(PROTO_MSG_STATUS_GET, NULL, 0);
    }
    TEST_ASSERT_EQUAL_UINT8(DRIVE_RUNNING, status().state);
    TEST_ASSERT_EQUAL_UINT32(1, d.stats.watchdog_stops);
}

/* A stream's job that ended gives the motion back: what moves next without
 * a request of its own (a calibration run, CANopen) is kept alive by the
 * status requests of its host, as before any stream. */
static void test_an_ended_stream_leaves_the_next_motion_to_any_request(void)
{
    uint8_t p[PROTO_MSG_MAX];
    drive_block_t b;
    unsigned ms;

    set_comm_timeout(100);
    enable();
    request(PROTO_MSG_QUEUE_BATCH, p, batch_payload(p, 0, 0, 4, 100000, 10000000u, true, true));
    TEST_ASSERT_EQUAL_UINT8(4, reply().accepted);
    for (ms = 0; ms < 3000 && status().state != DRIVE_IDLE; ms += 10) {
        run_ms(10);
        (void)window(4);
    }
    TEST_ASSERT_EQUAL_UINT8(DRIVE_IDLE, status().state);
    run_ms(10);
    request(PROTO_MSG_STATUS_GET, NULL, 0);
    memset(&b, 0, sizeof b);
    b.kind = DRIVE_BLOCK_LINE;
    b.target[0] = 400000 + 20000000;
    b.feed_nm_s = 10000000;
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_queue_block(&b)); /* as calib_poll queues a leg */
    for (ms = 0; ms < 500; ms += 10) {
        run_ms(10);
        request(PROTO_MSG_STATUS_GET, NULL, 0);
    }
    TEST_ASSERT_EQUAL_UINT8(DRIVE_RUNNING, status().state);
    TEST_ASSERT_EQUAL_UINT32(0, d.stats.watchdog_stops);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_golden_batch_encodes_and_decodes);
    RUN_TEST(test_random_blocks_round_trip);
    RUN_TEST(test_malformed_records_are_refused);
    RUN_TEST(test_window_accounting_runs_every_block_once);
    RUN_TEST(test_a_full_ring_takes_nothing_more);
    RUN_TEST(test_a_retried_batch_never_queues_twice);
    RUN_TEST(test_refusals_name_the_block);
    RUN_TEST(test_a_stop_ends_the_stream);
    RUN_TEST(test_session_open_refuses_another_protocol_version);
    RUN_TEST(test_a_watcher_does_not_keep_a_dead_stream_running);
    RUN_TEST(test_an_ended_stream_leaves_the_next_motion_to_any_request);
    return UNITY_END();
}
