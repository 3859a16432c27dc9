/* CiA 301 PDOs, SYNC and EMCY of the node (co_pdo.h, co_sync.h, co_emcy.h):
 * default mappings, the disable / reconfigure / enable sequence and its
 * abort codes, synchronous and event-driven transmission, RPDOs applied on
 * reception or at SYNC, EMCY per drive fault. */
#include <string.h>

#include "canopen.h"
#include "unity.h"

#define NODE 5u

static co_t co;
static co_frame_t sent[64];
static unsigned n_sent;
static unsigned hook_calls, sync_calls[2];
static uint16_t hook_index;

static bool tx(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    TEST_ASSERT_TRUE(n_sent < 64u);
    sent[n_sent].id = id;
    sent[n_sent].len = len;
    memcpy(sent[n_sent].data, data, len);
    n_sent++;
    return true;
}

static void on_write(void *ctx, uint16_t index, uint8_t sub)
{
    (void)ctx;
    (void)sub;
    hook_calls++;
    hook_index = index;
}

static void on_sync(void *ctx, int phase, uint32_t now_us)
{
    (void)ctx;
    (void)now_us;
    sync_calls[phase]++;
    if (phase == CO_SYNC_SAMPLE) {
        co.od.position_actual = -2; /* sampled before the TPDOs are built */
    }
}

static const co_config_t cfg = {NODE, 1u, 2u, 3u, 4u};

void setUp(void)
{
    co_init(&co, &cfg, tx, NULL, 0u);
    co_set_write_hook(&co, on_write, NULL);
    co_set_sync_hook(&co, on_sync);
    n_sent = 0;
    hook_calls = 0;
    sync_calls[0] = sync_calls[1] = 0;
}

void tearDown(void)
{
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

/* Expedited download; returns 0 or the abort code. */
static uint32_t wr(uint16_t index, uint8_t sub, uint32_t v, unsigned size)
{
    uint8_t c = (uint8_t)(0x23u | ((4u - size) << 2));
    uint8_t f[8] = {c,          (uint8_t)index,    (uint8_t)(index >> 8), sub,
                    (uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16),    (uint8_t)(v >> 24)};
    const co_frame_t *r;

    n_sent = 0;
    TEST_ASSERT_TRUE(co_rx(&co, 0x600u + NODE, f, 8u, 0u));
    TEST_ASSERT_EQUAL_UINT(1u, n_sent);
    r = &sent[0];
    n_sent = 0;
    return r->data[0] == 0x80u ? le32(&r->data[4]) : 0u;
}

static void start(void)
{
    uint8_t f[2] = {0x01u, NODE};
    TEST_ASSERT_TRUE(co_rx(&co, 0x000u, f, 2u, 0u));
    n_sent = 0;
}

static void sync_frame(uint32_t now_us)
{
    TEST_ASSERT_TRUE(co_rx(&co, 0x080u, NULL, 0u, now_us));
}

static const co_frame_t *find(uint32_t id)
{
    unsigned i;

    for (i = 0; i < n_sent; i++) {
        if (sent[i].id == id) {
            return &sent[i];
        }
    }
    return NULL;
}

static void test_default_tpdos_sync_and_event(void)
{
    const co_frame_t *f;

    co.od.statusword = 0x0237u;
    start();
    co_poll(&co, 0u); /* TPDO1 (event-driven statusword): once */
    f = find(0x180u + NODE);
    TEST_ASSERT_NOT_NULL(f);
    TEST_ASSERT_EQUAL_UINT8(2u, f->len);
    TEST_ASSERT_EQUAL_HEX8(0x37u, f->data[0]);
    n_sent = 0;
    co_poll(&co, 1000u);
    TEST_ASSERT_NULL(find(0x180u + NODE)); /* unchanged: nothing */
    co.od.statusword = 0x0233u;
    co_poll(&co, 2000u);
    TEST_ASSERT_NOT_NULL(find(0x180u + NODE));
    n_sent = 0;
    sync_frame(3000u); /* TPDO2 (type 1): statusword + position, sampled at SYNC */
    f = find(0x280u + NODE);
    TEST_ASSERT_NOT_NULL(f);
    TEST_ASSERT_EQUAL_UINT8(6u, f->len);
    TEST_ASSERT_EQUAL_HEX8(0x33u, f->data[0]);
    TEST_ASSERT_EQUAL_HEX32(0xFFFFFFFEu, le32(&f->data[2]));
    TEST_ASSERT_EQUAL_UINT(1u, sync_calls[CO_SYNC_SAMPLE]);
    TEST_ASSERT_EQUAL_UINT(1u, sync_calls[CO_SYNC_APPLY]);
}

static void test_no_pdo_or_sync_before_operational(void)
{
    sync_frame(0u);
    co_poll(&co, 0u);
    TEST_ASSERT_EQUAL_UINT(0u, n_sent);
    TEST_ASSERT_EQUAL_UINT(0u, sync_calls[0]);
}

static void test_reconfigure_sequence_and_aborts(void)
{
    const co_frame_t *f;

    /* TPDO3 starts invalid; TPDO1 is valid: its mapping is locked */
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_ACCESS, wr(0x1A00, 0, 0u, 1u));
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_ACCESS, wr(0x1800, 3, 10u, 2u)); /* inhibit */
    /* a valid PDO keeps its id */
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE, wr(0x1800, 1, 0x190u + NODE, 4u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1A02, 0, 0u, 1u));
    /* entries: no object, not mappable, wrong size */
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_NO_MAP, wr(0x1A02, 1, 0x12340020u, 4u));
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_NO_MAP, wr(0x1A02, 1, 0x10000020u, 4u));
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_NO_MAP, wr(0x1A02, 1, 0x60640010u, 4u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1A02, 1, 0x60640020u, 4u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1A02, 2, 0x607A0020u, 4u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1A02, 3, 0x60640020u, 4u));
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_MAP_LEN, wr(0x1A02, 0, 3u, 1u)); /* 96 bits */
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE_HIGH, wr(0x1A02, 0, 9u, 1u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1A02, 0, 2u, 1u));
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_ACCESS, wr(0x1A02, 1, 0x60410010u, 4u)); /* count != 0 */
    /* types: RTR-only and reserved ones refused */
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE, wr(0x1802, 2, 252u, 1u));
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE, wr(0x1802, 2, 241u, 1u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1802, 2, 2u, 1u)); /* every 2nd SYNC */
    /* ids: restricted, 29-bit, too high */
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE, wr(0x1802, 1, 0x601u, 4u));
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE, wr(0x1802, 1, 0x20000381u, 4u));
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE, wr(0x1802, 1, 0x800u, 4u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1802, 1, 0x40000390u, 4u)); /* RTR not allowed: fine */
    co.od.position_actual = 7;
    co.od.target_position = -1;
    start();
    sync_frame(0u);
    TEST_ASSERT_NULL(find(0x390u));
    sync_frame(1000u);
    f = find(0x390u);
    TEST_ASSERT_NOT_NULL(f);
    TEST_ASSERT_EQUAL_UINT8(8u, f->len);
    TEST_ASSERT_EQUAL_HEX32(0xFFFFFFFEu, le32(&f->data[0])); /* sampled at SYNC */
    TEST_ASSERT_EQUAL_HEX32(0xFFFFFFFFu, le32(&f->data[4]));
}

static void test_rpdo_on_reception_and_at_sync(void)
{
    uint8_t cw[2] = {0x0Fu, 0x00u};
    uint8_t both[6] = {0x06u, 0x00u, 0x10u, 0x20u, 0x30u, 0x40u};

    co_rx(&co, 0x200u + NODE, cw, 2u, 0u); /* pre-operational: ignored */
    TEST_ASSERT_EQUAL_HEX16(0u, co.od.controlword);
    start();
    TEST_ASSERT_TRUE(co_rx(&co, 0x200u + NODE, cw, 2u, 0u)); /* RPDO1, type 255 */
    TEST_ASSERT_EQUAL_HEX16(0x000Fu, co.od.controlword);
    TEST_ASSERT_EQUAL_UINT(1u, hook_calls);
    TEST_ASSERT_EQUAL_HEX16(0x6040u, hook_index);
    TEST_ASSERT_TRUE(co_rx(&co, 0x300u + NODE, both, 5u, 0u)); /* short */
    TEST_ASSERT_EQUAL_UINT32(1u, co.pdo.rpdo_short);
    TEST_ASSERT_TRUE(co_rx(&co, 0x300u + NODE, both, 6u, 0u)); /* RPDO2, type 1 */
    both[2] = 0x11u;
    TEST_ASSERT_TRUE(co_rx(&co, 0x300u + NODE, both, 6u, 0u));
    TEST_ASSERT_EQUAL_UINT32(1u, co.pdo.rpdo_overrun);
    TEST_ASSERT_EQUAL_HEX16(0x000Fu, co.od.controlword); /* not before the SYNC */
    TEST_ASSERT_EQUAL_INT32(0, co.od.target_position);
    sync_frame(0u);
    TEST_ASSERT_EQUAL_HEX16(0x0006u, co.od.controlword);
    TEST_ASSERT_EQUAL_HEX32(0x40302011u, (uint32_t)co.od.target_position);
    TEST_ASSERT_EQUAL_UINT(3u, hook_calls);
    TEST_ASSERT_FALSE(co_rx(&co, 0x400u + NODE, both, 6u, 0u)); /* RPDO3 invalid */
}

static void test_sync_object_and_period(void)
{
    uint8_t two[2] = {1u, 2u};

    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE, wr(0x1005, 0, 0x40000080u, 4u)); /* producer */
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE, wr(0x1005, 0, 0x20000080u, 4u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1005, 0, 0x081u, 4u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1006, 0, 1000u, 4u));
    start();
    TEST_ASSERT_TRUE(co_rx(&co, 0x081u, two, 2u, 0u)); /* DLC 2: ignored */
    TEST_ASSERT_EQUAL_UINT32(1u, co.sync.bad_len);
    TEST_ASSERT_TRUE(co_rx(&co, 0x081u, two, 1u, 0u)); /* with a counter */
    TEST_ASSERT_TRUE(co_rx(&co, 0x081u, NULL, 0u, 1400u));
    TEST_ASSERT_EQUAL_UINT32(0u, co.sync.late);
    TEST_ASSERT_TRUE(co_rx(&co, 0x081u, NULL, 0u, 3000u)); /* 1.6 periods */
    TEST_ASSERT_EQUAL_UINT32(1u, co.sync.late);
    TEST_ASSERT_EQUAL_UINT32(3u, co.sync.count);
    TEST_ASSERT_EQUAL_UINT32(1600u, co.sync.gap_max_us);
}

static void test_emcy_per_fault_and_reset(void)
{
    const co_frame_t *f;

    co_emcy_update(&co, 0x01u | 0x20u, 0u); /* following error + link watchdog */
    TEST_ASSERT_EQUAL_UINT(1u, n_sent);
    f = &sent[0];
    TEST_ASSERT_EQUAL_HEX32(0x080u + NODE, f->id);
    TEST_ASSERT_EQUAL_UINT8(8u, f->len);
    TEST_ASSERT_EQUAL_HEX8(0x11u, f->data[0]);
    TEST_ASSERT_EQUAL_HEX8(0x86u, f->data[1]);
    TEST_ASSERT_EQUAL_HEX8(0x21u, f->data[2]); /* generic + device profile */
    TEST_ASSERT_EQUAL_HEX8(0x21u, f->data[3]);
    co_emcy_update(&co, 0x21u, 10u);
    TEST_ASSERT_EQUAL_UINT(2u, n_sent);
    TEST_ASSERT_EQUAL_HEX8(0x00u, sent[1].data[0]);
    TEST_ASSERT_EQUAL_HEX8(0x81u, sent[1].data[1]);
    TEST_ASSERT_EQUAL_HEX8(0x31u, co.od.error_register);
    co_emcy_update(&co, 0x21u, 20u);
    TEST_ASSERT_EQUAL_UINT(2u, n_sent); /* nothing new */
    co_emcy_update(&co, 0u, 30u);       /* one cleared: no frame yet */
    co_emcy_update(&co, 0u, 40u);       /* the last: error reset */
    TEST_ASSERT_EQUAL_UINT(3u, n_sent);
    TEST_ASSERT_EQUAL_HEX8(0x00u, sent[2].data[0]);
    TEST_ASSERT_EQUAL_HEX8(0x00u, sent[2].data[1]);
    TEST_ASSERT_EQUAL_HEX8(0x00u, co.od.error_register);
    TEST_ASSERT_EQUAL_HEX16(0x7305u, co_emcy_code(0x02u));
    TEST_ASSERT_EQUAL_HEX16(0x1000u, co_emcy_code(1u << 20));
}

static void test_emcy_inhibit_and_invalid_id(void)
{
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1015, 0, 10u, 2u)); /* 1 ms */
    co_emcy_update(&co, 0x01u, 0u);
    co_emcy_update(&co, 0x03u, 500u); /* inhibited */
    TEST_ASSERT_EQUAL_UINT(1u, n_sent);
    co_emcy_update(&co, 0x03u, 1000u);
    TEST_ASSERT_EQUAL_UINT(2u, n_sent);
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE, wr(0x1014, 0, 0x800u, 4u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1014, 0, 0x80000085u, 4u));
    co_emcy_update(&co, 0x07u, 5000u);
    TEST_ASSERT_EQUAL_UINT(0u, n_sent);
    TEST_ASSERT_EQUAL_HEX8(0xA1u, co.od.error_register); /* still follows: generic, profile, mfr */
}

static void test_signed_limits(void)
{
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE_HIGH, wr(0x60C2, 2, 0xFEu, 1u)); /* -2 */
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE_LOW, wr(0x60C2, 2, 0xF9u, 1u));  /* -7 */
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x60C2, 2, 0xFCu, 1u));                  /* -4 */
    TEST_ASSERT_EQUAL_INT8(-4, co.od.ipol_index);
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x607A, 0, 0x80000000u, 4u)); /* INT32_MIN */
    TEST_ASSERT_EQUAL_HEX32(CO_ABORT_VALUE_LOW, wr(0x60C2, 1, 0u, 1u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_default_tpdos_sync_and_event);
    RUN_TEST(test_no_pdo_or_sync_before_operational);
    RUN_TEST(test_reconfigure_sequence_and_aborts);
    RUN_TEST(test_rpdo_on_reception_and_at_sync);
    RUN_TEST(test_sync_object_and_period);
    RUN_TEST(test_emcy_per_fault_and_reset);
    RUN_TEST(test_emcy_inhibit_and_invalid_id);
    RUN_TEST(test_signed_limits);
    return UNITY_END();
}
