/* CiA 402 power state machine: every transition, statusword bits, ignored commands. */
#include "cia402.h"
#include "unity.h"

static cia402_t s;

void setUp(void)
{
    cia402_init(&s);
}

void tearDown(void)
{
}

#define SHUTDOWN   0x0006u
#define SWITCH_ON  0x0007u
#define ENABLE     0x000Fu
#define DISABLE_V  0x0000u
#define QUICK_STOP 0x0002u
#define RESET      0x0080u

static uint16_t sw(void)
{
    return cia402_statusword(&s, false, false, false);
}

static void test_starts_switch_on_disabled(void)
{
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCH_ON_DISABLED, s.state);
    TEST_ASSERT_EQUAL_HEX16(0x0240u, sw());
}

static void test_enable_sequence_and_statuswords(void)
{
    TEST_ASSERT_EQUAL_INT(CIA402_READY_TO_SWITCH_ON, cia402_controlword(&s, SHUTDOWN));
    TEST_ASSERT_EQUAL_HEX16(0x0221u, sw());
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCHED_ON, cia402_controlword(&s, SWITCH_ON));
    TEST_ASSERT_EQUAL_HEX16(0x0223u, sw());
    TEST_ASSERT_EQUAL_INT(CIA402_OPERATION_ENABLED, cia402_controlword(&s, ENABLE));
    TEST_ASSERT_EQUAL_HEX16(0x0227u, sw());
    TEST_ASSERT_EQUAL_HEX16(0x06B7u, cia402_statusword(&s, true, true, true));
    /* 5, 4, 8 */
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCHED_ON, cia402_controlword(&s, SWITCH_ON));
    TEST_ASSERT_EQUAL_INT(CIA402_OPERATION_ENABLED, cia402_controlword(&s, ENABLE));
    TEST_ASSERT_EQUAL_INT(CIA402_READY_TO_SWITCH_ON, cia402_controlword(&s, SHUTDOWN));
    /* 3 + 4 at once (0x0F from READY TO SWITCH ON), then 9 */
    TEST_ASSERT_EQUAL_INT(CIA402_OPERATION_ENABLED, cia402_controlword(&s, ENABLE));
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCH_ON_DISABLED, cia402_controlword(&s, DISABLE_V));
}

static void test_commands_out_of_order_are_ignored(void)
{
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCH_ON_DISABLED, cia402_controlword(&s, ENABLE));
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCH_ON_DISABLED, cia402_controlword(&s, SWITCH_ON));
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCH_ON_DISABLED, cia402_controlword(&s, RESET));
    cia402_controlword(&s, SHUTDOWN);
    cia402_controlword(&s, SWITCH_ON);
    /* switched on: shutdown (6), disable voltage / quick stop (10) */
    TEST_ASSERT_EQUAL_INT(CIA402_READY_TO_SWITCH_ON, cia402_controlword(&s, SHUTDOWN));
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCH_ON_DISABLED, cia402_controlword(&s, QUICK_STOP)); /* 7 */
    cia402_controlword(&s, SHUTDOWN);
    cia402_controlword(&s, SWITCH_ON);
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCH_ON_DISABLED, cia402_controlword(&s, QUICK_STOP)); /* 10 */
}

static void test_quick_stop_then_disable_or_back(void)
{
    cia402_controlword(&s, SHUTDOWN);
    cia402_controlword(&s, ENABLE);
    TEST_ASSERT_EQUAL_INT(CIA402_QUICK_STOP_ACTIVE, cia402_controlword(&s, QUICK_STOP));
    TEST_ASSERT_EQUAL_HEX16(0x0207u, sw());
    TEST_ASSERT_EQUAL_INT(CIA402_OPERATION_ENABLED, cia402_controlword(&s, ENABLE)); /* 16 */
    cia402_controlword(&s, QUICK_STOP);
    TEST_ASSERT_EQUAL_INT(CIA402_QUICK_STOP_ACTIVE, cia402_controlword(&s, SHUTDOWN));
    cia402_quick_stop_done(&s); /* 12 */
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCH_ON_DISABLED, s.state);
}

static void test_fault_reaction_fault_and_reset_on_edge_only(void)
{
    cia402_controlword(&s, SHUTDOWN);
    cia402_controlword(&s, ENABLE);
    cia402_fault(&s);
    TEST_ASSERT_EQUAL_INT(CIA402_FAULT_REACTION_ACTIVE, s.state);
    TEST_ASSERT_EQUAL_HEX16(0x020Fu, sw());
    TEST_ASSERT_EQUAL_INT(CIA402_FAULT_REACTION_ACTIVE, cia402_controlword(&s, RESET));
    cia402_reaction_done(&s);
    TEST_ASSERT_EQUAL_INT(CIA402_FAULT, s.state);
    TEST_ASSERT_EQUAL_HEX16(0x0208u, sw());
    /* bit 7 was already set: no edge, no reset; commands do nothing */
    TEST_ASSERT_EQUAL_INT(CIA402_FAULT, cia402_controlword(&s, RESET));
    TEST_ASSERT_EQUAL_INT(CIA402_FAULT, cia402_controlword(&s, ENABLE));
    TEST_ASSERT_EQUAL_INT(CIA402_SWITCH_ON_DISABLED, cia402_controlword(&s, RESET)); /* 15 */
    /* a second fault while reacting does not restart anything */
    cia402_fault(&s);
    cia402_fault(&s);
    TEST_ASSERT_EQUAL_INT(CIA402_FAULT_REACTION_ACTIVE, s.state);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_starts_switch_on_disabled);
    RUN_TEST(test_enable_sequence_and_statuswords);
    RUN_TEST(test_commands_out_of_order_are_ignored);
    RUN_TEST(test_quick_stop_then_disable_or_back);
    RUN_TEST(test_fault_reaction_fault_and_reset_on_edge_only);
    return UNITY_END();
}
