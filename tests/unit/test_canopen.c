/* CiA 301 on the drive: NMT, boot-up, heartbeat, SDO server and its abort codes. */
#include <string.h>

#include "canopen.h"
#include "unity.h"

#define NODE 5u

static co_t co;
static co_frame_t sent[64];
static unsigned n_sent;
static bool mailbox_full;

static bool tx(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    if (mailbox_full) {
        return false;
    }
    TEST_ASSERT_TRUE(n_sent < 64u);
    sent[n_sent].id = id;
    sent[n_sent].len = len;
    memcpy(sent[n_sent].data, data, len);
    n_sent++;
    return true;
}

static const co_config_t cfg = {NODE, 0x00000A5Au, 0x00C0A001u, 0x00010002u, 0x12345678u};

void setUp(void)
{
    n_sent = 0;
    mailbox_full = false;
    co_init(&co, &cfg, tx, NULL, 0u);
}

void tearDown(void)
{
}

static const co_frame_t *last(void)
{
    TEST_ASSERT_TRUE(n_sent > 0u);
    return &sent[n_sent - 1u];
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

/* Send one SDO request (DLC 8) and return the response. */
static const co_frame_t *sdo(uint8_t c, uint16_t index, uint8_t sub, uint32_t d)
{
    uint8_t f[8] = {c,          (uint8_t)index,    (uint8_t)(index >> 8), sub,
                    (uint8_t)d, (uint8_t)(d >> 8), (uint8_t)(d >> 16),    (uint8_t)(d >> 24)};
    unsigned before = n_sent;

    TEST_ASSERT_TRUE(co_rx(&co, CO_ID_RSDO + NODE, f, 8u, 0u));
    TEST_ASSERT_EQUAL_UINT(before + 1u, n_sent);
    TEST_ASSERT_EQUAL_HEX32(CO_ID_TSDO + NODE, last()->id);
    TEST_ASSERT_EQUAL_UINT8(8u, last()->len);
    return last();
}

static const co_frame_t *seg(const uint8_t *f8)
{
    unsigned before = n_sent;

    TEST_ASSERT_TRUE(co_rx(&co, CO_ID_RSDO + NODE, f8, 8u, 0u));
    TEST_ASSERT_EQUAL_UINT(before + 1u, n_sent);
    return last();
}

static void assert_abort(const co_frame_t *r, uint16_t index, uint8_t sub, uint32_t code)
{
    TEST_ASSERT_EQUAL_HEX8(0x80u, r->data[0]);
    TEST_ASSERT_EQUAL_HEX8((uint8_t)index, r->data[1]);
    TEST_ASSERT_EQUAL_HEX8((uint8_t)(index >> 8), r->data[2]);
    TEST_ASSERT_EQUAL_HEX8(sub, r->data[3]);
    TEST_ASSERT_EQUAL_HEX32(code, le32(&r->data[4]));
}

static void test_boot_up_then_pre_operational(void)
{
    TEST_ASSERT_EQUAL_UINT(1u, n_sent);
    TEST_ASSERT_EQUAL_HEX32(0x700u + NODE, sent[0].id);
    TEST_ASSERT_EQUAL_UINT8(1u, sent[0].len);
    TEST_ASSERT_EQUAL_HEX8(0x00u, sent[0].data[0]);
    TEST_ASSERT_EQUAL_INT(CO_NMT_PREOP, co_nmt_state(&co));
}

static void nmt(uint8_t cs, uint8_t node)
{
    uint8_t f[2] = {cs, node};
    TEST_ASSERT_TRUE(co_rx(&co, 0x000u, f, 2u, 0u));
}

static void test_nmt_transitions_and_addressing(void)
{
    nmt(0x01u, NODE);
    TEST_ASSERT_EQUAL_INT(CO_NMT_OPERATIONAL, co_nmt_state(&co));
    nmt(0x80u, NODE + 1u); /* another node: ignored */
    TEST_ASSERT_EQUAL_INT(CO_NMT_OPERATIONAL, co_nmt_state(&co));
    nmt(0x02u, 0u); /* broadcast */
    TEST_ASSERT_EQUAL_INT(CO_NMT_STOPPED, co_nmt_state(&co));
    nmt(0x80u, NODE);
    TEST_ASSERT_EQUAL_INT(CO_NMT_PREOP, co_nmt_state(&co));
    {
        uint8_t bad[3] = {0x01u, NODE, 0u};
        co_rx(&co, 0x000u, bad, 3u, 0u); /* DLC 3: ignored */
        co_rx(&co, 0x000u, bad, 1u, 0u); /* truncated: ignored */
    }
    nmt(0x77u, NODE); /* unknown command */
    TEST_ASSERT_EQUAL_INT(CO_NMT_PREOP, co_nmt_state(&co));
    TEST_ASSERT_EQUAL_UINT32(3u, co.stats.nmt_ignored);
}

static void test_reset_communication_sends_boot_up_and_restores_heartbeat(void)
{
    sdo(0x2Bu, 0x1017, 0, 250u);
    nmt(0x01u, NODE);
    n_sent = 0;
    nmt(0x82u, NODE);
    TEST_ASSERT_EQUAL_UINT(1u, n_sent);
    TEST_ASSERT_EQUAL_HEX32(0x700u + NODE, sent[0].id);
    TEST_ASSERT_EQUAL_HEX8(0x00u, sent[0].data[0]);
    TEST_ASSERT_EQUAL_INT(CO_NMT_PREOP, co_nmt_state(&co));
    TEST_ASSERT_EQUAL_UINT16(1000u, co.od.heartbeat_ms);
}

static unsigned count_id(uint32_t id)
{
    unsigned i, n = 0;

    for (i = 0; i < n_sent; i++) {
        n += sent[i].id == id;
    }
    return n;
}

static void test_heartbeat_period_and_state(void)
{
    sdo(0x2Bu, 0x1017, 0, 100u); /* 100 ms */
    nmt(0x01u, NODE);
    n_sent = 0;
    co_poll(&co, 99999u); /* (TPDO1, event-driven, sends its statusword once) */
    TEST_ASSERT_EQUAL_UINT(0u, count_id(0x700u + NODE));
    n_sent = 0;
    co_poll(&co, 100000u);
    TEST_ASSERT_EQUAL_UINT(1u, n_sent);
    TEST_ASSERT_EQUAL_HEX32(0x700u + NODE, sent[0].id);
    TEST_ASSERT_EQUAL_HEX8(0x05u, sent[0].data[0]);
    co_poll(&co, 150000u);
    TEST_ASSERT_EQUAL_UINT(1u, n_sent);
    sdo(0x2Bu, 0x1017, 0, 0u); /* off */
    n_sent = 0;
    co_poll(&co, 10000000u);
    TEST_ASSERT_EQUAL_UINT(0u, n_sent);
}

static void test_expedited_upload_of_device_type_and_identity(void)
{
    const co_frame_t *r = sdo(0x40u, 0x1000, 0, 0u);
    TEST_ASSERT_EQUAL_HEX8(0x43u, r->data[0]);
    TEST_ASSERT_EQUAL_HEX32(0x00020192u, le32(&r->data[4]));
    r = sdo(0x40u, 0x1018, 0, 0u);
    TEST_ASSERT_EQUAL_HEX8(0x4Fu, r->data[0]); /* 1 byte: n = 3 */
    TEST_ASSERT_EQUAL_HEX8(4u, r->data[4]);
    r = sdo(0x40u, 0x1018, 4, 0u);
    TEST_ASSERT_EQUAL_HEX32(0x12345678u, le32(&r->data[4]));
    r = sdo(0x40u, 0x1018, 1, 0u);
    TEST_ASSERT_EQUAL_HEX32(0x00000A5Au, le32(&r->data[4]));
    co_set_error_register(&co, 0x81u);
    r = sdo(0x40u, 0x1001, 0, 0u);
    TEST_ASSERT_EQUAL_HEX8(0x4Fu, r->data[0]);
    TEST_ASSERT_EQUAL_HEX8(0x81u, r->data[4]);
}

static void test_segmented_upload_with_toggle(void)
{
    const char *name = "contour axis drive";
    char got[40];
    unsigned pos = 0;
    uint8_t t = 0;
    const co_frame_t *r = sdo(0x40u, 0x1008, 0, 0u);

    TEST_ASSERT_EQUAL_HEX8(0x41u, r->data[0]);
    TEST_ASSERT_EQUAL_UINT32(strlen(name), le32(&r->data[4]));
    for (;;) {
        uint8_t f[8] = {(uint8_t)(0x60u | (t << 4)), 0, 0, 0, 0, 0, 0, 0};
        unsigned n;

        r = seg(f);
        TEST_ASSERT_EQUAL_HEX8(t << 4, r->data[0] & 0xF0u);
        n = 7u - ((r->data[0] >> 1) & 7u);
        memcpy(&got[pos], &r->data[1], n);
        pos += n;
        t ^= 1u;
        if (r->data[0] & 1u) {
            break;
        }
        TEST_ASSERT_TRUE(pos < sizeof got);
    }
    TEST_ASSERT_EQUAL_UINT(strlen(name), pos);
    TEST_ASSERT_EQUAL_MEMORY(name, got, pos);
}

static void test_upload_toggle_error_aborts(void)
{
    uint8_t f[8] = {0x60u, 0, 0, 0, 0, 0, 0, 0};

    sdo(0x40u, 0x1008, 0, 0u);
    seg(f);                                           /* toggle 0: fine */
    assert_abort(seg(f), 0x1008, 0, CO_ABORT_TOGGLE); /* toggle 0 again */
    /* the transfer is over: a further segment is an unknown command */
    f[0] = 0x70u;
    assert_abort(seg(f), 0x1008, 0, CO_ABORT_COMMAND);
}

static void test_segmented_download_of_label(void)
{
    const char *label = "X axis, bay 2";
    uint8_t f[8];
    size_t n = strlen(label), pos = 0;
    uint8_t t = 0;
    const co_frame_t *r = sdo(0x21u, 0x2000, 0, (uint32_t)n);

    TEST_ASSERT_EQUAL_HEX8(0x60u, r->data[0]);
    while (pos < n) {
        size_t k = n - pos > 7u ? 7u : n - pos;
        bool lastseg = pos + k == n;

        memset(f, 0, sizeof f);
        f[0] = (uint8_t)((t << 4) | ((7u - k) << 1) | (lastseg ? 1u : 0u));
        memcpy(&f[1], label + pos, k);
        r = seg(f);
        TEST_ASSERT_EQUAL_HEX8(0x20u | (t << 4), r->data[0]);
        pos += k;
        t ^= 1u;
    }
    TEST_ASSERT_EQUAL_STRING(label, co.od.device_label);
}

static void test_download_toggle_error_and_too_long(void)
{
    uint8_t f[8] = {0x00u, 'a', 'b', 'c', 'd', 'e', 'f', 'g'};

    sdo(0x21u, 0x2000, 0, 20u);
    seg(f);
    assert_abort(seg(f), 0x2000, 0, CO_ABORT_TOGGLE);
    /* more than indicated */
    sdo(0x21u, 0x2000, 0, 10u);
    seg(f);
    f[0] = 0x10u;
    assert_abort(seg(f), 0x2000, 0, CO_ABORT_LEN_HIGH);
    /* last segment before the indicated size */
    sdo(0x21u, 0x2000, 0, 10u);
    f[0] = 0x01u;
    assert_abort(seg(f), 0x2000, 0, CO_ABORT_LEN);
    /* indicated size above the object's */
    assert_abort(sdo(0x21u, 0x2000, 0, CO_STR_MAX + 1u), 0x2000, 0, CO_ABORT_LEN_HIGH);
    TEST_ASSERT_EQUAL_STRING("", co.od.device_label);
}

static void test_access_and_existence_aborts(void)
{
    assert_abort(sdo(0x40u, 0x1234, 0, 0u), 0x1234, 0, CO_ABORT_NO_OBJECT);
    assert_abort(sdo(0x40u, 0x1018, 9, 0u), 0x1018, 9, CO_ABORT_NO_SUB);
    assert_abort(sdo(0x23u, 0x1000, 0, 1u), 0x1000, 0, CO_ABORT_READONLY);
    TEST_ASSERT_EQUAL_HEX32(0x00020192u, co.od.device_type);
    assert_abort(sdo(0x2Fu, 0x1018, 1, 1u), 0x1018, 1, CO_ABORT_READONLY);
}

static void test_expedited_length_and_range_aborts(void)
{
    /* u16 written with 4 and 1 bytes */
    assert_abort(sdo(0x23u, 0x1017, 0, 5u), 0x1017, 0, CO_ABORT_LEN_HIGH);
    assert_abort(sdo(0x2Fu, 0x1017, 0, 5u), 0x1017, 0, CO_ABORT_LEN_LOW);
    TEST_ASSERT_EQUAL_UINT16(1000u, co.od.heartbeat_ms);
    /* 0x1029:01 takes 0..2 */
    TEST_ASSERT_EQUAL_HEX8(0x60u, sdo(0x2Fu, 0x1029, 1, 2u)->data[0]);
    TEST_ASSERT_EQUAL_UINT8(2u, co.od.comm_error);
    assert_abort(sdo(0x2Fu, 0x1029, 1, 3u), 0x1029, 1, CO_ABORT_VALUE_HIGH);
    TEST_ASSERT_EQUAL_UINT8(2u, co.od.comm_error);
    /* expedited without size indication takes the object's size */
    TEST_ASSERT_EQUAL_HEX8(0x60u, sdo(0x22u, 0x1017, 0, 0xFFFF0123u)->data[0]);
    TEST_ASSERT_EQUAL_UINT16(0x0123u, co.od.heartbeat_ms);
}

static void test_bad_command_specifiers(void)
{
    /* block download / upload (not implemented) and ccs 7 */
    assert_abort(sdo(0xC6u, 0x1000, 0, 0u), 0x1000, 0, CO_ABORT_COMMAND);
    assert_abort(sdo(0xA0u, 0x1000, 0, 0u), 0x1000, 0, CO_ABORT_COMMAND);
    assert_abort(sdo(0xE0u, 0x1000, 0, 0u), 0x1000, 0, CO_ABORT_COMMAND);
    /* a segment without a transfer */
    {
        uint8_t f[8] = {0x00u, 1, 2, 3, 4, 5, 6, 7};
        TEST_ASSERT_EQUAL_HEX8(0x80u, seg(f)->data[0]);
        TEST_ASSERT_EQUAL_HEX32(CO_ABORT_COMMAND, le32(&last()->data[4]));
    }
}

static void test_truncated_frames_are_ignored_then_timeout(void)
{
    uint8_t f[8] = {0x40u, 0x00u, 0x10u, 0u, 0, 0, 0, 0};
    unsigned len;

    for (len = 0; len < 8u; len++) {
        TEST_ASSERT_TRUE(co_rx(&co, CO_ID_RSDO + NODE, f, (uint8_t)len, 0u));
    }
    TEST_ASSERT_EQUAL_UINT(1u, n_sent); /* only the boot-up */
    TEST_ASSERT_EQUAL_UINT32(8u, co.stats.sdo_short);
    /* a segmented transfer with no further segment times out */
    sdo(0x2Bu, 0x1017, 0, 0u); /* heartbeat off: the abort is the last frame */
    sdo(0x21u, 0x2000, 0, 20u);
    co_poll(&co, CO_SDO_TIMEOUT_US - 1u);
    TEST_ASSERT_EQUAL_HEX8(0x60u, last()->data[0]);
    co_poll(&co, CO_SDO_TIMEOUT_US);
    assert_abort(last(), 0x2000, 0, CO_ABORT_TIMEOUT);
}

static void test_client_abort_ends_transfer_silently(void)
{
    uint8_t f[8] = {0x80u, 0x08u, 0x10u, 0u, 0, 0, 0x04u, 0x05u};
    unsigned before;

    sdo(0x40u, 0x1008, 0, 0u);
    before = n_sent;
    TEST_ASSERT_TRUE(co_rx(&co, CO_ID_RSDO + NODE, f, 8u, 0u));
    TEST_ASSERT_EQUAL_UINT(before, n_sent);
    co_poll(&co, 5u * CO_SDO_TIMEOUT_US);
    TEST_ASSERT_EQUAL_HEX32(0x700u + NODE, last()->id); /* heartbeat, no timeout abort */
}

static void test_stopped_ignores_sdo_and_other_ids_are_not_ours(void)
{
    uint8_t f[8] = {0x40u, 0x00u, 0x10u, 0u, 0, 0, 0, 0};

    nmt(0x02u, NODE);
    n_sent = 0;
    TEST_ASSERT_TRUE(co_rx(&co, CO_ID_RSDO + NODE, f, 8u, 0u));
    TEST_ASSERT_EQUAL_UINT(0u, n_sent);
    TEST_ASSERT_FALSE(co_rx(&co, CO_ID_RSDO + NODE + 1u, f, 8u, 0u));
    TEST_ASSERT_FALSE(co_rx(&co, 0x181u, f, 8u, 0u));
}

static void test_full_mailbox_queues_then_drops(void)
{
    unsigned i;

    mailbox_full = true;
    n_sent = 0;
    for (i = 0; i < CO_TX_RING + 2u; i++) {
        uint8_t f[8] = {0x40u, 0x00u, 0x10u, 0u, 0, 0, 0, 0};
        co_rx(&co, CO_ID_RSDO + NODE, f, 8u, 0u);
    }
    TEST_ASSERT_EQUAL_UINT(0u, n_sent);
    TEST_ASSERT_EQUAL_UINT32(2u, co.stats.tx_dropped);
    mailbox_full = false;
    co_poll(&co, 1u);
    TEST_ASSERT_EQUAL_UINT(CO_TX_RING, n_sent);
    TEST_ASSERT_EQUAL_HEX8(0x43u, sent[0].data[0]);
}

static unsigned hook_calls;
static uint16_t hook_index;

static void hook(void *ctx, uint16_t index, uint8_t sub)
{
    (void)ctx;
    (void)sub;
    hook_calls++;
    hook_index = index;
}

static void test_write_hook_after_stored_writes_only(void)
{
    uint8_t f[8] = {0x09u, 'a', 'b', 'c', 0, 0, 0, 0}; /* last, 3 bytes */

    hook_calls = 0;
    co_set_write_hook(&co, hook, NULL);
    sdo(0x2Bu, 0x6040, 0, 0x0006u);
    TEST_ASSERT_EQUAL_UINT(1u, hook_calls);
    TEST_ASSERT_EQUAL_HEX16(0x6040u, hook_index);
    TEST_ASSERT_EQUAL_HEX16(0x0006u, co.od.controlword);
    assert_abort(sdo(0x2Fu, 0x1029, 1, 3u), 0x1029, 1, CO_ABORT_VALUE_HIGH);
    assert_abort(sdo(0x2Bu, 0x6041, 0, 1u), 0x6041, 0, CO_ABORT_READONLY);
    TEST_ASSERT_EQUAL_UINT(1u, hook_calls);
    sdo(0x21u, 0x2000, 0, 3u);
    TEST_ASSERT_EQUAL_UINT(1u, hook_calls); /* not before the last segment */
    seg(f);
    TEST_ASSERT_EQUAL_UINT(2u, hook_calls);
    TEST_ASSERT_EQUAL_HEX16(0x2000u, hook_index);
    TEST_ASSERT_EQUAL_STRING("abc", co.od.device_label);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_boot_up_then_pre_operational);
    RUN_TEST(test_nmt_transitions_and_addressing);
    RUN_TEST(test_reset_communication_sends_boot_up_and_restores_heartbeat);
    RUN_TEST(test_heartbeat_period_and_state);
    RUN_TEST(test_expedited_upload_of_device_type_and_identity);
    RUN_TEST(test_segmented_upload_with_toggle);
    RUN_TEST(test_upload_toggle_error_aborts);
    RUN_TEST(test_segmented_download_of_label);
    RUN_TEST(test_download_toggle_error_and_too_long);
    RUN_TEST(test_access_and_existence_aborts);
    RUN_TEST(test_expedited_length_and_range_aborts);
    RUN_TEST(test_bad_command_specifiers);
    RUN_TEST(test_truncated_frames_are_ignored_then_timeout);
    RUN_TEST(test_client_abort_ends_transfer_silently);
    RUN_TEST(test_stopped_ignores_sdo_and_other_ids_are_not_ours);
    RUN_TEST(test_full_mailbox_queues_then_drops);
    RUN_TEST(test_write_hook_after_stored_writes_only);
    return UNITY_END();
}
