/*
 * Calibration mode of the drive (calib.h) against the simulator: the ISO
 * 230-2 leg order, numbered and CRC-checked samples, errors equal to the
 * configured pitch error, flow control (a host that does not read stalls
 * the run, nothing is overwritten), the replay cache, every refusal, abort
 * and drive faults, and the compensation upload: activated only after the
 * flash copy is verified, the previous table kept on any failure, reloaded
 * at start-up.
 */
#include "calib.h"
#include "comp_store.h"
#include "crc.h"
#include "drive.h"
#include "hal_flash_sim.h"
#include "hal_sim.h"
#include "proto_msgs.h"
#include "sim.h"
#include "unity.h"

#include <string.h>

static uint8_t out[PROTO_MSG_MAX];
static size_t out_len;
static uint8_t seq_no;

/* Pitch error: e(x) = 2e-3 x on the Y axis, both directions (error =
 * encoder - reference = -e(x)). */
static void start_sim(void)
{
    static const double pos[2] = {-0.1, 0.1};
    static const double err[2] = {-0.1 * 2e-3, 0.1 * 2e-3};
    /* X (the cross axis of a Y run) reads 5 um short everywhere: error =
     * encoder - reference = -5 um (the samples' x* fields) */
    static const double xerr[2] = {5e-6, 5e-6};
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 2));
    TEST_ASSERT_EQUAL_INT(0, sim_axis_pitch(1, 2, pos, err, err));
    TEST_ASSERT_EQUAL_INT(0, sim_axis_pitch(0, 2, pos, xerr, xerr));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_EQUAL_INT(0, sim_enable(1));
    TEST_ASSERT_TRUE(sim_run(10, NULL, 0, 0) >= 0);
}

void setUp(void)
{
    TEST_ASSERT_TRUE(flash_sim_configure(FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE,
                                         FLASH_SIM_DEFAULT_PAGE, FLASH_SIM_DEFAULT_WRITE));
    calib_set_next_handler(NULL);
    start_sim();
}

void tearDown(void)
{
    flash_sim_power_cut_after(-1);
    flash_sim_power_on();
    hal_sim_set_amp_fault(1, false);
}

/* Send msg id with payload; the reply lands in out / out_len. */
static size_t req_seq(uint8_t id, uint8_t sq, const uint8_t *payload, size_t len)
{
    static uint8_t msg[PROTO_MSG_MAX];
    msg[0] = id;
    msg[1] = sq;
    if (len > 0) {
        memcpy(msg + 2, payload, len);
    }
    out_len = calib_handle(msg, len + 2, 0u, out, sizeof out);
    return out_len;
}

static size_t req(uint8_t id, const uint8_t *payload, size_t len)
{
    return req_seq(id, ++seq_no, payload, len);
}

static proto_calib_state_t state_of_reply(void)
{
    proto_calib_state_t s;
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_CALIB_STATE, out[0]);
    TEST_ASSERT_TRUE(proto_calib_state_decode(out + 2, out_len - 2, &s));
    return s;
}

static void expect_error(uint8_t code, uint16_t arg)
{
    proto_error_t e;
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ERROR, out[0]);
    TEST_ASSERT_TRUE(proto_error_decode(out + 2, out_len - 2, &e));
    TEST_ASSERT_EQUAL_UINT8(code, e.code);
    TEST_ASSERT_EQUAL_UINT16(arg, e.arg);
}

static proto_calib_state_t status(void)
{
    req(PROTO_MSG_CALIB_STATUS, NULL, 0);
    return state_of_reply();
}

static void setup_run(uint8_t axis, uint8_t flags, uint16_t points, uint8_t cycles,
                      uint16_t samples)
{
    proto_calib_setup_t m;
    uint8_t p[PROTO_CALIB_SETUP_LEN];
    memset(&m, 0, sizeof m);
    m.axis = axis;
    m.flags = flags;
    m.points = points;
    m.cycles = cycles;
    m.samples = samples;
    m.sample_ticks = 1;
    m.dwell_ms = 50;
    m.overrun = 500000;
    m.feed = 20000000;
    TEST_ASSERT_EQUAL_size_t(sizeof p, proto_calib_setup_encode(&m, p, sizeof p));
    req(PROTO_MSG_CALIB_SETUP, p, sizeof p);
}

static void send_targets(uint16_t first, const int64_t *t, unsigned n)
{
    proto_calib_targets_t m;
    uint8_t p[PROTO_CALIB_TARGETS_MAX_LEN];
    unsigned i, b;
    size_t len;
    m.first = first;
    m.data_len = (uint16_t)(8 * n);
    for (i = 0; i < n; i++) {
        for (b = 0; b < 8; b++) {
            m.data[8 * i + b] = (uint8_t)((uint64_t)t[i] >> (8 * b));
        }
    }
    len = proto_calib_targets_encode(&m, p, sizeof p);
    req(PROTO_MSG_CALIB_TARGETS, p, len);
}

/* Run the drive for `ticks` as a host that polls calib_status every 10 ms
 * (it is there: the calibration's host watchdog stays quiet). */
static void run_polled(uint32_t ticks)
{
    uint32_t k;
    for (k = 0; k < ticks; k += 100) {
        TEST_ASSERT_TRUE(sim_run(100, NULL, 0, 0) >= 0);
        (void)status();
    }
}

static void run_until(calib_state_t want, uint32_t max_ticks)
{
    uint32_t k;
    for (k = 0; k < max_ticks && calib_state() != want; k += 100) {
        run_polled(100);
    }
    TEST_ASSERT_EQUAL_INT(want, calib_state());
}

typedef struct {
    uint32_t seq;
    uint16_t point;
    uint8_t cycle, flags;
    int32_t enc, comp, ref;
    int32_t xenc, xcomp, xref;
} smp_t;

static int32_t rd32(const uint8_t *p)
{
    return (int32_t)((uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
                     ((uint32_t)p[3] << 24));
}

/* Read every sample from `from` on (also releases them). */
static unsigned read_all(uint32_t from, smp_t *dst, unsigned cap)
{
    unsigned n = 0;
    for (;;) {
        proto_calib_read_t r;
        proto_calib_samples_t s;
        uint8_t p[PROTO_CALIB_READ_LEN];
        unsigned i;
        r.from_seq = from;
        r.max = CALIB_READ_MAX;
        proto_calib_read_encode(&r, p, sizeof p);
        req(PROTO_MSG_CALIB_READ, p, sizeof p);
        TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_CALIB_SAMPLES, out[0]);
        TEST_ASSERT_TRUE(proto_calib_samples_decode(out + 2, out_len - 2, &s));
        TEST_ASSERT_EQUAL_UINT32(from, s.from_seq);
        TEST_ASSERT_EQUAL_UINT32(crc32_update(CRC32_INIT, s.data, s.data_len), s.crc);
        TEST_ASSERT_EQUAL_UINT16(CALIB_SAMPLE_BYTES * s.count, s.data_len);
        if (s.count == 0) {
            return n;
        }
        for (i = 0; i < s.count && n < cap; i++, n++) {
            const uint8_t *b = s.data + CALIB_SAMPLE_BYTES * i;
            dst[n].seq = (uint32_t)rd32(b);
            dst[n].point = (uint16_t)(b[4] | (b[5] << 8));
            dst[n].cycle = b[6];
            dst[n].flags = b[7];
            dst[n].enc = rd32(b + 8);
            dst[n].comp = rd32(b + 12);
            dst[n].ref = rd32(b + 16);
            dst[n].xenc = rd32(b + 20);
            dst[n].xcomp = rd32(b + 24);
            dst[n].xref = rd32(b + 28);
            TEST_ASSERT_EQUAL_UINT32(from + i, dst[n].seq);
        }
        from += s.count;
    }
}

static const int64_t T3[3] = {-2000000, 0, 2000000};
static smp_t S[2048];

static void test_run_order_samples_and_errors(void)
{
    static const uint16_t order_pt[6] = {0, 1, 2, 2, 1, 0};
    proto_calib_state_t s;
    unsigned n, leg, k;
    setup_run(1, 0, 3, 1, 20);
    s = state_of_reply();
    TEST_ASSERT_EQUAL_UINT8(CALIB_SETUP, s.state);
    TEST_ASSERT_EQUAL_UINT16(6, s.legs_total);
    send_targets(0, T3, 3);
    TEST_ASSERT_EQUAL_UINT16(3, state_of_reply().targets_loaded);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    TEST_ASSERT_EQUAL_UINT8(CALIB_RUNNING, state_of_reply().state);
    run_until(CALIB_DONE, 200000);
    s = status();
    TEST_ASSERT_EQUAL_UINT16(6, s.legs_done);
    TEST_ASSERT_EQUAL_UINT32(120, s.seq_next);
    n = read_all(0, S, 2048);
    TEST_ASSERT_EQUAL_UINT(120, n);
    for (leg = 0; leg < 6; leg++) {
        double sum = 0.0, xsum = 0.0, xref = 0.0, want;
        for (k = 0; k < 20; k++) {
            const smp_t *x = &S[leg * 20 + k];
            TEST_ASSERT_EQUAL_UINT16(order_pt[leg], x->point);
            TEST_ASSERT_EQUAL_UINT8(leg < 3 ? 0 : CALIB_SAMPLE_NEG, x->flags);
            TEST_ASSERT_EQUAL_INT32(x->enc, x->comp); /* no table */
            TEST_ASSERT_EQUAL_INT32(x->xenc, x->xcomp);
            sum += (double)(x->enc - x->ref);
            xsum += (double)(x->xenc - x->xref);
            xref += (double)x->xref;
        }
        /* error = -e(x) = -2e-3 x: +4 um at -2 mm, -4 um at +2 mm; the
         * encoder counts 1.25 um */
        want = -2e-3 * (double)T3[order_pt[leg]];
        TEST_ASSERT_DOUBLE_WITHIN(1500.0, want, sum / 20.0);
        /* the cross axis X, held at 0 (encoder there), is at +5 um on its
         * reference: the same at every point of the Y run */
        TEST_ASSERT_DOUBLE_WITHIN(1500.0, -5000.0, xsum / 20.0);
        TEST_ASSERT_DOUBLE_WITHIN(1500.0, 5000.0, xref / 20.0);
    }
    /* everything read and released: a read from the end returns nothing */
    TEST_ASSERT_EQUAL_UINT(0, read_all(120, S, 2048));
    TEST_ASSERT_EQUAL_UINT32(120, status().seq_oldest);
}

/* The wire format of a sample (calib.h): every field at its offset,
 * little-endian, CALIB_SAMPLE_BYTES in all. */
static void test_sample_wire_format(void)
{
    static const uint8_t want[CALIB_SAMPLE_BYTES] = {
        0x04, 0x03, 0x02, 0x01, 0x06, 0x05, 0x07, 0x0B, 0xFF, 0xFF, 0xFF,
        0xFF, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x11, 0x22,
        0x33, 0x44, 0xFE, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x7F};
    uint8_t b[CALIB_SAMPLE_BYTES + 1];
    calib_sample_t x;
    proto_calib_samples_t r;
    TEST_ASSERT_EQUAL_UINT(32, CALIB_SAMPLE_BYTES);
    /* a reply of CALIB_READ_MAX samples fits the protocol's payload */
    TEST_ASSERT_TRUE(CALIB_READ_MAX * CALIB_SAMPLE_BYTES <= sizeof r.data);
    x.seq = 0x01020304u;
    x.point = 0x0506u;
    x.cycle = 7u;
    x.flags = CALIB_SAMPLE_NEG | CALIB_SAMPLE_NO_REF | CALIB_SAMPLE_NO_XREF;
    x.enc = -1;
    x.comp = 2;
    x.ref = INT32_MIN;
    x.xenc = 0x44332211;
    x.xcomp = -2;
    x.xref = INT32_MAX;
    b[CALIB_SAMPLE_BYTES] = 0xA5u;
    calib_sample_encode(&x, b);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(want, b, CALIB_SAMPLE_BYTES);
    TEST_ASSERT_EQUAL_HEX8(0xA5u, b[CALIB_SAMPLE_BYTES]); /* nothing beyond */
}

/* Host reference mode: no reference read on the drive, neither the axis's
 * nor the cross axis's (flags say so, the fields are 0). */
static void test_host_reference_samples_carry_no_reference(void)
{
    unsigned n, k;
    setup_run(1, CALIB_FLAG_HOST_REFERENCE, 3, 1, 5);
    send_targets(0, T3, 3);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    run_until(CALIB_DONE, 200000);
    n = read_all(0, S, 2048);
    TEST_ASSERT_EQUAL_UINT(30, n);
    for (k = 0; k < n; k++) {
        TEST_ASSERT_EQUAL_HEX8(CALIB_SAMPLE_NO_REF | CALIB_SAMPLE_NO_XREF,
                               S[k].flags & (CALIB_SAMPLE_NO_REF | CALIB_SAMPLE_NO_XREF));
        TEST_ASSERT_EQUAL_INT32(0, S[k].ref);
        TEST_ASSERT_EQUAL_INT32(0, S[k].xenc);
        TEST_ASSERT_EQUAL_INT32(0, S[k].xcomp);
        TEST_ASSERT_EQUAL_INT32(0, S[k].xref);
    }
}

static void test_flow_control_never_overwrites(void)
{
    proto_calib_state_t s;
    setup_run(1, 0, 3, 1, CALIB_RING);
    send_targets(0, T3, 3);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    run_polled(60000); /* 6 s, the host polls but reads nothing */
    s = status();
    TEST_ASSERT_EQUAL_UINT8(CALIB_RUNNING, s.state);
    TEST_ASSERT_EQUAL_UINT16(1, s.legs_done); /* waits for room */
    TEST_ASSERT_EQUAL_UINT32(CALIB_RING, s.seq_next);
    TEST_ASSERT_EQUAL_UINT32(0, s.seq_oldest);
    TEST_ASSERT_EQUAL_UINT(CALIB_RING, read_all(0, S, 2048)); /* all still there */
    run_polled(20000);
    s = status();
    TEST_ASSERT_TRUE(s.legs_done >= 2);
    /* released samples are gone: reading them again is refused */
    {
        proto_calib_read_t r = {0, 5};
        uint8_t p[PROTO_CALIB_READ_LEN];
        proto_calib_read_encode(&r, p, sizeof p);
        req(PROTO_MSG_CALIB_READ, p, sizeof p);
        expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_SEQ);
    }
}

/* A host that goes silent mid-run (killed): the drive aborts the run after
 * CALIB_HOST_TIMEOUT_MS, stops the axes, and a later read - the next host
 * pulling the samples - never resumes motion. */
static void test_silent_host_aborts_the_run_and_nothing_resumes(void)
{
    proto_calib_state_t s;
    drive_status_t st;
    pos_nm_t y;
    uint16_t legs;

    setup_run(1, 0, 3, 1, CALIB_RING);
    send_targets(0, T3, 3);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    run_polled(5000); /* under way, the ring filling */
    TEST_ASSERT_EQUAL_UINT8(CALIB_RUNNING, status().state);
    TEST_ASSERT_TRUE(sim_run((CALIB_HOST_TIMEOUT_MS + 200u) * 10u, NULL, 0, 0) >= 0);
    s = status();
    TEST_ASSERT_EQUAL_UINT8(CALIB_ERROR, s.state);
    TEST_ASSERT_EQUAL_UINT8(PROTO_CALIB_STATUS_HOST_SILENT, s.reason);
    legs = s.legs_done;
    TEST_ASSERT_TRUE(sim_run(5000, NULL, 0, 0) >= 0); /* come to rest */
    drive_snapshot(&st);
    y = st.pos[1];
    TEST_ASSERT_EQUAL_UINT(CALIB_RING, read_all(0, S, 2048)); /* samples kept */
    run_polled(30000);
    drive_snapshot(&st);
    s = status();
    TEST_ASSERT_EQUAL_UINT8(CALIB_ERROR, s.state);
    TEST_ASSERT_EQUAL_UINT16(legs, s.legs_done);
    TEST_ASSERT_INT64_WITHIN(2500, y, st.pos[1]); /* 2 encoder counts */
    TEST_ASSERT_TRUE(st.state == DRIVE_IDLE);
}

/* The composition root ends a run when another host session starts. */
static void test_host_gone_stops_a_run_and_is_a_no_op_otherwise(void)
{
    calib_host_gone(PROTO_CALIB_STATUS_NEW_SESSION); /* no run: nothing */
    TEST_ASSERT_EQUAL_UINT8(CALIB_IDLE, status().state);
    setup_run(1, 0, 3, 1, 20);
    send_targets(0, T3, 3);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    run_polled(2000);
    calib_host_gone(PROTO_CALIB_STATUS_NEW_SESSION);
    TEST_ASSERT_EQUAL_UINT8(CALIB_ERROR, status().state);
    TEST_ASSERT_EQUAL_UINT8(PROTO_CALIB_STATUS_NEW_SESSION, state_of_reply().reason);
}

static void test_replay_cache_does_not_execute_twice(void)
{
    uint8_t first[PROTO_MSG_MAX];
    size_t first_len;
    uint8_t p[PROTO_CALIB_SETUP_LEN];
    proto_calib_setup_t m;
    memset(&m, 0, sizeof m);
    m.axis = 1;
    m.points = 3;
    m.cycles = 1;
    m.samples = 4;
    m.sample_ticks = 1;
    m.feed = 1000000;
    proto_calib_setup_encode(&m, p, sizeof p);
    req_seq(PROTO_MSG_CALIB_SETUP, 77, p, sizeof p);
    send_targets(0, T3, 3);
    TEST_ASSERT_EQUAL_UINT16(3, state_of_reply().targets_loaded);
    /* a setup under a new seq is executed (and resets the targets) */
    req_seq(PROTO_MSG_CALIB_SETUP, 78, p, sizeof p);
    TEST_ASSERT_EQUAL_UINT16(0, state_of_reply().targets_loaded);
    send_targets(0, T3, 3);
    req_seq(PROTO_MSG_CALIB_START, 200, NULL, 0);
    TEST_ASSERT_EQUAL_UINT8(CALIB_RUNNING, state_of_reply().state);
    memcpy(first, out, out_len);
    first_len = out_len;
    TEST_ASSERT_TRUE(sim_run(5000, NULL, 0, 0) >= 0);
    /* a retry of the last request (its reply was lost): the cached reply,
     * not a second execution (which would be refused as busy) */
    req_seq(PROTO_MSG_CALIB_START, 200, NULL, 0);
    TEST_ASSERT_EQUAL_size_t(first_len, out_len);
    TEST_ASSERT_EQUAL_MEMORY(first, out, out_len);
    req_seq(PROTO_MSG_CALIB_START, 201, NULL, 0);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_BUSY);
    /* same seq, other payload: not a retry, executed */
    req_seq(PROTO_MSG_CALIB_SETUP, 201, p, 3);
    expect_error(PROTO_ERROR_CODE_BAD_LENGTH, 3);
}

static void test_refusals(void)
{
    proto_calib_read_t r;
    uint8_t p[PROTO_CALIB_READ_LEN];
    static const int64_t down[3] = {0, -1000, 1000};
    setup_run(2, 0, 3, 1, 10);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_BAD_AXIS);
    setup_run(1, 0x80, 3, 1, 10);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_BAD_SETUP);
    setup_run(1, 0, 0, 1, 10);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_BAD_SETUP);
    setup_run(1, 0, 3, 0, 10);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_BAD_SETUP);
    setup_run(1, 0, 3, 1, CALIB_RING + 1);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_BAD_SETUP);
    req(PROTO_MSG_CALIB_SETUP, out, 5);
    expect_error(PROTO_ERROR_CODE_BAD_LENGTH, 5);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_NOT_READY);
    setup_run(1, 0, 3, 1, 10);
    send_targets(2, T3, 2); /* beyond the point count */
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_TARGETS);
    send_targets(0, T3, 2);
    req(PROTO_MSG_CALIB_START, NULL, 0); /* one target missing */
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_TARGETS);
    send_targets(0, down, 3);
    req(PROTO_MSG_CALIB_START, NULL, 0); /* not increasing */
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_TARGETS);
    send_targets(0, T3, 3);
    TEST_ASSERT_EQUAL_INT(0, sim_enable(0));
    TEST_ASSERT_TRUE(sim_run(10, NULL, 0, 0) >= 0);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_DRIVE_DISABLED);
    {
        proto_calib_point_t pt = {0, 1, 0};
        uint8_t q[PROTO_CALIB_POINT_LEN];
        proto_calib_point_encode(&pt, q, sizeof q);
        req(PROTO_MSG_CALIB_POINT, q, sizeof q); /* before the run is done */
        expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_NOT_READY);
    }
    r.from_seq = 5; /* nothing taken yet */
    r.max = 3;
    proto_calib_read_encode(&r, p, sizeof p);
    req(PROTO_MSG_CALIB_READ, p, sizeof p);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_SEQ);
    r.from_seq = 0;
    r.max = 0;
    proto_calib_read_encode(&r, p, sizeof p);
    req(PROTO_MSG_CALIB_READ, p, sizeof p);
    expect_error(PROTO_ERROR_CODE_OUT_OF_RANGE, 1);
    req(0xAF, NULL, 0);
    expect_error(PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0);
    req(0x85, NULL, 0); /* a bootloader id, no next handler */
    expect_error(PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0);
    TEST_ASSERT_EQUAL_size_t(0, calib_handle(out, 1, 0u, out, sizeof out)); /* too short */
}

static int next_called;
static size_t next_handler(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *o, size_t cap)
{
    (void)len;
    (void)now_us;
    (void)cap;
    next_called++;
    o[0] = PROTO_MSG_ACK;
    o[1] = msg[1];
    o[2] = msg[0];
    return 3;
}

static void test_other_ids_go_to_next_handler(void)
{
    calib_set_next_handler(next_handler);
    TEST_ASSERT_EQUAL_size_t(3, req(0x87, NULL, 0));
    TEST_ASSERT_EQUAL_INT(1, next_called);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ACK, out[0]);
    req(PROTO_MSG_CALIB_STATUS, NULL, 0); /* ours: not passed on */
    TEST_ASSERT_EQUAL_INT(1, next_called);
}

static void test_abort_and_drive_fault_end_the_run(void)
{
    drive_status_t st;
    setup_run(1, 0, 3, 1, 20);
    send_targets(0, T3, 3);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    TEST_ASSERT_TRUE(sim_run(1500, NULL, 0, 0) >= 0);
    req(PROTO_MSG_CALIB_ABORT, NULL, 0);
    TEST_ASSERT_EQUAL_UINT8(CALIB_ERROR, state_of_reply().state);
    TEST_ASSERT_EQUAL_UINT8(PROTO_CALIB_STATUS_ABORTED, state_of_reply().reason);
    TEST_ASSERT_TRUE(sim_run(10000, NULL, 0, 0) >= 0);
    drive_snapshot(&st);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state); /* stopped, still enabled */
    /* a new run, then an amplifier fault in the middle of it */
    setup_run(1, 0, 3, 1, 20);
    send_targets(0, T3, 3);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    TEST_ASSERT_EQUAL_UINT8(CALIB_RUNNING, state_of_reply().state);
    TEST_ASSERT_TRUE(sim_run(1500, NULL, 0, 0) >= 0);
    hal_sim_set_amp_fault(1, true);
    TEST_ASSERT_TRUE(sim_run(100, NULL, 0, 0) >= 0);
    TEST_ASSERT_EQUAL_UINT8(CALIB_ERROR, status().state);
    TEST_ASSERT_EQUAL_UINT8(PROTO_CALIB_STATUS_DRIVE_FAULT, status().reason);
}

/* ---- compensation upload ------------------------------------------------------- */

static uint8_t rec[COMP_RECORD_MAX];
static comp_table_t TB;

static size_t make_record(int32_t fwd0)
{
    memset(&TB, 0, sizeof TB);
    TB.n = 3;
    TB.axis = 1;
    TB.ramp_us = 10000;
    TB.pos[0] = -2000000;
    TB.pos[1] = 0;
    TB.pos[2] = 2000000;
    TB.fwd[0] = fwd0;
    TB.fwd[1] = 500;
    TB.fwd[2] = -4000;
    TB.rev[0] = 3000;
    TB.rev[1] = -500;
    TB.rev[2] = -5000;
    return comp_record_encode(&TB, rec, sizeof rec);
}

/* Disable the drive and let the tick apply it (tables are written only
 * with the drive disabled). */
static void drive_off(void)
{
    drive_status_t st;
    TEST_ASSERT_EQUAL_INT(0, sim_enable(0));
    TEST_ASSERT_TRUE(sim_run(2, NULL, 0, 0) >= 0);
    drive_snapshot(&st);
    TEST_ASSERT_EQUAL_INT(DRIVE_DISABLED, st.state);
}

static void drive_on(void)
{
    TEST_ASSERT_EQUAL_INT(0, sim_enable(1));
    TEST_ASSERT_TRUE(sim_run(10, NULL, 0, 0) >= 0);
}

static void commit(size_t len, uint32_t crc)
{
    proto_comp_commit_t c;
    uint8_t p[PROTO_COMP_COMMIT_LEN];
    c.axis = 1;
    c.length = (uint16_t)len;
    c.crc = crc;
    proto_comp_commit_encode(&c, p, sizeof p);
    req(PROTO_MSG_COMP_COMMIT, p, sizeof p);
}

static void stage(const uint8_t *r, size_t len)
{
    size_t off;
    for (off = 0; off < len; off += 200) {
        proto_comp_write_t w;
        uint8_t p[PROTO_COMP_WRITE_MAX_LEN];
        size_t n = len - off < 200 ? len - off : 200, plen;
        w.axis = 1;
        w.offset = (uint16_t)off;
        w.data_len = (uint16_t)n;
        memcpy(w.data, r + off, n);
        plen = proto_comp_write_encode(&w, p, sizeof p);
        req(PROTO_MSG_COMP_WRITE, p, plen);
        TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_COMP_WRITTEN, out[0]);
    }
}

/* stage and commit a record with the drive disabled */
static void upload(const uint8_t *r, size_t len, uint32_t crc)
{
    drive_off();
    stage(r, len);
    commit(len, crc);
}

static proto_comp_info_t info_of_reply(void)
{
    proto_comp_info_t m;
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_COMP_INFO, out[0]);
    TEST_ASSERT_TRUE(proto_comp_info_decode(out + 2, out_len - 2, &m));
    return m;
}

/* calib_tick steps a table's direction ramp only when the direction turns
 * or w has not reached its end: the same w and direction as comp_ramp_step
 * on every tick (the reference), over reversals, rests and a ramp cut short
 * by a reversal. */
static void test_ramp_skip_matches_stepping_every_tick(void)
{
    static const int64_t seq[][2] = {
        /* velocity, ticks */
        {0, 5},
        {1000, 3},
        {0, 40},
        {-1, 10},
        {5, 2},
        {0, 400},
        {-7, 120},
        {3, 300},
        {-1, 5},
        {0, 10},
        {1, 5},
        {0, 300},
        {1, 2},
        {INT64_MIN, 1},
        {INT64_MAX, 300},
        {0, 3},
        {-((int64_t)1 << 32), 50},
        {((int64_t)1 << 32), 1},
        {-1, 500},
        {1, 3},
    };
    static drive_status_t s;
    const comp_table_t *act;
    comp_ramp_t ref;
    size_t len = make_record(4000), k;
    uint32_t n;

    upload(rec, len, crc32_update(CRC32_INIT, rec, len));
    act = calib_comp_active(1);
    TEST_ASSERT_NOT_NULL(act);
    TEST_ASSERT_NOT_NULL(act->dir_src);
    ref = *act->dir_src;
    memset(&s, 0, sizeof s);
    for (k = 0; k < sizeof seq / sizeof seq[0]; k++) {
        for (n = 0; n < (uint32_t)seq[k][1]; n++) {
            s.vel_ref[1] = seq[k][0];
            comp_ramp_step(&ref, seq[k][0]);
            calib_tick(&s, s.vel_ref);
            TEST_ASSERT_EQUAL_INT32(ref.w_q30, act->dir_src->w_q30);
            TEST_ASSERT_EQUAL_INT8(ref.dir, act->dir_src->dir);
        }
    }
}

static void test_compensation_upload_verify_and_fallbacks(void)
{
    size_t len = make_record(4000);
    proto_comp_info_t m;
    const comp_table_t *act;
    drive_status_t st;

    TEST_ASSERT_NULL(calib_comp_active(1));
    upload(rec, len, crc32_update(CRC32_INIT, rec, len));
    m = info_of_reply();
    TEST_ASSERT_EQUAL_UINT8(1, m.active);
    TEST_ASSERT_EQUAL_UINT16(3, m.n);
    TEST_ASSERT_EQUAL_UINT32(1, m.version);
    TEST_ASSERT_EQUAL_UINT32(crc32_update(CRC32_INIT, rec + 32, len - 32), m.data_crc);
    act = calib_comp_active(1);
    TEST_ASSERT_NOT_NULL(act);
    TEST_ASSERT_EQUAL_INT32(4000, act->fwd[0]);
    /* the feedback now carries the correction: at rest at 0 with no motion
     * yet, the mean of the two columns (0) */
    TEST_ASSERT_TRUE(sim_run(10, NULL, 0, 0) >= 0);
    drive_snapshot(&st);
    TEST_ASSERT_EQUAL_INT64(st.pos_raw[1] + comp_correct_w(act, st.pos_raw[1], 0) - st.pos_raw[1],
                            st.pos[1]);

    /* wrong CRC: refused, the active table unchanged */
    len = make_record(1111);
    upload(rec, len, 0xDEADBEEFu);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_RECORD_CRC);
    TEST_ASSERT_EQUAL_INT32(4000, calib_comp_active(1)->fwd[0]);
    /* invalid content with a matching CRC: refused by the record check */
    rec[32] ^= 1u; /* first position changes: data CRC in the header no longer fits */
    upload(rec, len, crc32_update(CRC32_INIT, rec, len));
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_RECORD);
    TEST_ASSERT_EQUAL_INT32(4000, calib_comp_active(1)->fwd[0]);
    /* flash fails half way: refused, previous table active AND current in flash */
    len = make_record(2222);
    flash_sim_power_cut_after(40); /* inside the 80-byte record appended to the log */
    upload(rec, len, crc32_update(CRC32_INIT, rec, len));
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_FLASH);
    flash_sim_power_cut_after(-1);
    flash_sim_power_on();
    TEST_ASSERT_EQUAL_INT32(4000, calib_comp_active(1)->fwd[0]);
    /* a good second table: version 2, the other slot */
    upload(rec, len, crc32_update(CRC32_INIT, rec, len));
    m = info_of_reply();
    TEST_ASSERT_EQUAL_UINT32(2, m.version);
    TEST_ASSERT_EQUAL_INT32(2222, calib_comp_active(1)->fwd[0]);
    /* a restart of the drive reloads it from flash */
    start_sim();
    TEST_ASSERT_NOT_NULL(calib_comp_active(1));
    TEST_ASSERT_EQUAL_INT32(2222, calib_comp_active(1)->fwd[0]);
    TEST_ASSERT_EQUAL_UINT32(2, calib_comp_active(1)->version);
    {
        uint8_t a = 1;
        req(PROTO_MSG_COMP_GET, &a, 1);
        TEST_ASSERT_EQUAL_UINT32(2, info_of_reply().version);
        drive_off();
        req(PROTO_MSG_COMP_CLEAR, &a, 1);
        m = info_of_reply();
        TEST_ASSERT_EQUAL_UINT8(0, m.active);
        TEST_ASSERT_EQUAL_UINT32(3, m.version);
        TEST_ASSERT_NULL(calib_comp_active(1));
        a = 5;
        req(PROTO_MSG_COMP_GET, &a, 1);
        expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_BAD_AXIS);
    }
    start_sim();
    TEST_ASSERT_NULL(calib_comp_active(1)); /* the empty table is current */
}

/* With the drive enabled, commit and clear are refused before anything
 * reaches flash (a flash write stalls a single-bank MCU's control tick):
 * the active table and the flash stay as they were, and the staged record
 * is kept, so a commit after disabling succeeds without re-sending it. */
static void test_compensation_written_only_with_the_drive_disabled(void)
{
    size_t len = make_record(4000);
    uint32_t crc = crc32_update(CRC32_INIT, rec, len);
    uint8_t a = 1;
    drive_status_t st;

    drive_snapshot(&st);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state); /* setUp enabled it */
    stage(rec, len);
    commit(len, crc);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_DRIVE_ENABLED);
    TEST_ASSERT_NULL(calib_comp_active(1));
    start_sim(); /* a restart finds nothing in flash either */
    TEST_ASSERT_NULL(calib_comp_active(1));

    stage(rec, len);
    commit(len, crc);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_DRIVE_ENABLED);
    drive_off();
    commit(len, crc); /* the staged record was kept */
    TEST_ASSERT_EQUAL_UINT8(1, info_of_reply().active);
    TEST_ASSERT_EQUAL_INT32(4000, calib_comp_active(1)->fwd[0]);

    drive_on();
    req(PROTO_MSG_COMP_CLEAR, &a, 1);
    expect_error(PROTO_ERROR_CODE_CALIB, PROTO_CALIB_STATUS_DRIVE_ENABLED);
    TEST_ASSERT_NOT_NULL(calib_comp_active(1));
    drive_off();
    req(PROTO_MSG_COMP_CLEAR, &a, 1);
    TEST_ASSERT_EQUAL_UINT8(0, info_of_reply().active);
    TEST_ASSERT_NULL(calib_comp_active(1));
}

static void test_samples_carry_the_compensated_position(void)
{
    size_t len = make_record(4000);
    unsigned n, i;
    upload(rec, len, crc32_update(CRC32_INIT, rec, len));
    TEST_ASSERT_EQUAL_UINT8(1, info_of_reply().active);
    drive_on();
    setup_run(1, 0, 3, 1, 10);
    send_targets(0, T3, 3);
    req(PROTO_MSG_CALIB_START, NULL, 0);
    run_until(CALIB_DONE, 200000);
    n = read_all(0, S, 2048);
    TEST_ASSERT_EQUAL_UINT(60, n);
    for (i = 0; i < n; i++) {
        int neg = (S[i].flags & CALIB_SAMPLE_NEG) != 0;
        pos_nm_t raw = T3[S[i].point] + S[i].enc;
        int64_t corr = comp_correction(calib_comp_active(1), raw, neg ? -COMP_W_ONE : COMP_W_ONE);
        /* the correction in the feedback is the direction of approach's
         * column, interpolated where the encoder is */
        TEST_ASSERT_EQUAL_INT64(corr, (int64_t)S[i].comp - S[i].enc);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_run_order_samples_and_errors);
    RUN_TEST(test_sample_wire_format);
    RUN_TEST(test_host_reference_samples_carry_no_reference);
    RUN_TEST(test_flow_control_never_overwrites);
    RUN_TEST(test_silent_host_aborts_the_run_and_nothing_resumes);
    RUN_TEST(test_host_gone_stops_a_run_and_is_a_no_op_otherwise);
    RUN_TEST(test_replay_cache_does_not_execute_twice);
    RUN_TEST(test_refusals);
    RUN_TEST(test_other_ids_go_to_next_handler);
    RUN_TEST(test_abort_and_drive_fault_end_the_run);
    RUN_TEST(test_compensation_upload_verify_and_fallbacks);
    RUN_TEST(test_ramp_skip_matches_stepping_every_tick);
    RUN_TEST(test_compensation_written_only_with_the_drive_disabled);
    RUN_TEST(test_samples_carry_the_compensated_position);
    return UNITY_END();
}
