/* CiA 301 heartbeat consumer of the node (co_hb.h): 0x1016 entry rules and
 * abort codes, monitoring from the first heartbeat, one timeout per loss,
 * the 0x1029 reaction, which frames are a sign of life, NMT reset. */
#include <string.h>

#include "canopen.h"
#include "unity.h"

#define NODE   5u
#define MASTER 0x7Eu

static co_t co;

static bool tx(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    (void)id;
    (void)data;
    (void)len;
    return true;
}

static const co_config_t cfg = {NODE, 1u, 2u, 3u, 4u};

void setUp(void)
{
    co_init(&co, &cfg, tx, NULL, 0u);
}

void tearDown(void)
{
}

/* Expedited download of 4 bytes: 0 or the abort code. */
static uint32_t wr(uint16_t index, uint8_t sub, uint32_t v)
{
    uint8_t f[8] = {0x23u,      (uint8_t)index,    (uint8_t)(index >> 8), sub,
                    (uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16),    (uint8_t)(v >> 24)};
    uint32_t tail = co.txq_head;

    TEST_ASSERT_TRUE(co_rx(&co, 0x600u + NODE, f, 8u, 0u));
    {
        const co_frame_t *r = &co.txq[tail % CO_TX_RING];
        const uint8_t *d = r->data;

        return d[0] == 0x80u ? ((uint32_t)d[4] | (uint32_t)d[5] << 8 | (uint32_t)d[6] << 16 |
                                (uint32_t)d[7] << 24)
                             : 0u;
    }
}

static bool beat(uint8_t node, uint32_t now_us)
{
    uint8_t s = 0x05u;

    return co_rx(&co, 0x700u + node, &s, 1u, now_us);
}

static void nmt(uint8_t cs)
{
    uint8_t f[2] = {cs, NODE};

    TEST_ASSERT_TRUE(co_rx(&co, 0x000u, f, 2u, 0u));
}

static void test_entry_rules_and_abort_codes(void)
{
    TEST_ASSERT_EQUAL_HEX32(0x06090030u, wr(0x1016u, 1u, 0x01000000u | MASTER << 16 | 100u));
    TEST_ASSERT_EQUAL_HEX32(0x06090030u, wr(0x1016u, 1u, 0x80u << 16 | 100u)); /* node 128 */
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1016u, 1u, MASTER << 16 | 100u));
    TEST_ASSERT_EQUAL_HEX32(0x06040043u, wr(0x1016u, 2u, MASTER << 16 | 50u));
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1016u, 2u, MASTER << 16));        /* time 0: unused */
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1016u, 1u, MASTER << 16 | 200u)); /* rewrite itself */
    TEST_ASSERT_EQUAL_HEX32(0x06090011u, wr(0x1016u, 5u, 0u));
}

static void test_timeout_once_per_loss_from_the_first_heartbeat(void)
{
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1016u, 1u, MASTER << 16 | 100u));
    nmt(0x01u);
    co_poll(&co, 500000u); /* nothing heard yet: not watching */
    TEST_ASSERT_EQUAL_UINT32(0u, co.hb.lost);
    TEST_ASSERT_FALSE(beat(MASTER + 1u, 500000u)); /* another node: not consumed */
    TEST_ASSERT_TRUE(beat(MASTER, 500000u));
    co_poll(&co, 599000u);
    TEST_ASSERT_EQUAL_UINT32(0u, co.hb.lost);
    TEST_ASSERT_EQUAL_INT(CO_NMT_OPERATIONAL, co_nmt_state(&co));
    co_poll(&co, 600000u);
    TEST_ASSERT_EQUAL_UINT32(1u, co.hb.lost);
    TEST_ASSERT_EQUAL_INT(CO_NMT_PREOP, co_nmt_state(&co)); /* 0x1029 = 0 */
    co_poll(&co, 900000u);
    TEST_ASSERT_EQUAL_UINT32(1u, co.hb.lost); /* once */
    TEST_ASSERT_TRUE(beat(MASTER, 1000000u));
    co_poll(&co, 1100000u);
    TEST_ASSERT_EQUAL_UINT32(2u, co.hb.lost);
}

static void test_error_behaviour_stopped_or_unchanged(void)
{
    uint8_t f[8] = {0x2Fu, 0x29u, 0x10u, 1u, 2u, 0u, 0u, 0u}; /* 0x1029:1 = 2 */

    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1016u, 3u, MASTER << 16 | 10u));
    TEST_ASSERT_TRUE(co_rx(&co, 0x600u + NODE, f, 8u, 0u));
    nmt(0x01u);
    TEST_ASSERT_TRUE(beat(MASTER, 0u));
    co_poll(&co, 10000u);
    TEST_ASSERT_EQUAL_INT(CO_NMT_STOPPED, co_nmt_state(&co));
    f[4] = 1u; /* 1: no change */
    nmt(0x01u);
    TEST_ASSERT_TRUE(co_rx(&co, 0x600u + NODE, f, 8u, 0u));
    TEST_ASSERT_TRUE(beat(MASTER, 20000u));
    co_poll(&co, 30000u);
    TEST_ASSERT_EQUAL_UINT32(2u, co.hb.lost);
    TEST_ASSERT_EQUAL_INT(CO_NMT_OPERATIONAL, co_nmt_state(&co));
}

static void test_sign_of_life_and_reset_communication(void)
{
    TEST_ASSERT_TRUE(co_hb_alive(&co, 0x080u)); /* unused: any frame */
    TEST_ASSERT_EQUAL_HEX32(0u, wr(0x1016u, 1u, MASTER << 16 | 100u));
    TEST_ASSERT_FALSE(co_hb_alive(&co, 0x080u));
    TEST_ASSERT_FALSE(co_hb_alive(&co, 0x600u + NODE));
    TEST_ASSERT_TRUE(co_hb_alive(&co, 0x700u + MASTER));
    TEST_ASSERT_TRUE(beat(MASTER, 0u));
    nmt(0x82u); /* reset communication: entries cleared */
    TEST_ASSERT_EQUAL_HEX32(0u, co.od.hb_consumer[0]);
    TEST_ASSERT_TRUE(co_hb_alive(&co, 0x080u));
    co_poll(&co, 1000000u);
    TEST_ASSERT_EQUAL_UINT32(0u, co.hb.lost);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_entry_rules_and_abort_codes);
    RUN_TEST(test_timeout_once_per_loss_from_the_first_heartbeat);
    RUN_TEST(test_error_behaviour_stopped_or_unchanged);
    RUN_TEST(test_sign_of_life_and_reset_communication);
    return UNITY_END();
}
