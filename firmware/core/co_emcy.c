/*
 * co_emcy.c - EMCY producer (co_emcy.h is the specification).
 */
#include "co_emcy.h"

#include "canopen.h"

#define ER_GENERIC 0x01u
#define ER_CURRENT 0x02u
#define ER_COMM    0x10u
#define ER_PROFILE 0x20u
#define ER_MFR     0x80u

/* Indexed by the bit number of DRIVE_FAULT_* (drive.h). */
static const struct {
    uint16_t code;
    uint8_t reg;
} emcy_table[] = {
    {0x8611u, ER_PROFILE}, /* following error */
    {0x7305u, ER_PROFILE}, /* encoder */
    {0xFF04u, ER_MFR},     /* output saturation */
    {0x5400u, ER_CURRENT}, /* amplifier */
    {0xFF10u, ER_MFR},     /* e-stop */
    {0x8100u, ER_COMM},    /* host link watchdog */
    {0xFF40u, ER_MFR},     /* homing */
    {0xFF80u, ER_MFR},     /* oscillation */
};

#define EMCY_COMM_BIT (1u << 5) /* DRIVE_FAULT_COMM */
#define EMCY_BITS     (sizeof emcy_table / sizeof emcy_table[0])

static unsigned bit_of(uint32_t b)
{
    unsigned i = 0;

    while (i < 32u && (b & (1u << i)) == 0u) {
        i++;
    }
    return i;
}

uint16_t co_emcy_code(uint32_t fault_bit)
{
    unsigned i = bit_of(fault_bit);

    return i < EMCY_BITS ? emcy_table[i].code : 0x1000u;
}

static uint8_t error_register(uint32_t bits)
{
    uint8_t reg = 0;
    unsigned i;

    for (i = 0; i < 32u; i++) {
        if ((bits & (1u << i)) != 0u) {
            reg |= (uint8_t)(ER_GENERIC | (i < EMCY_BITS ? emcy_table[i].reg : 0u));
        }
    }
    return reg;
}

uint32_t co_emcy_check(uint32_t value)
{
    uint32_t id = value & 0x7FFFFFFFu;

    return (id == 0u || id > 0x7FFu) ? CO_ABORT_VALUE : 0u;
}

void co_emcy_update(struct co_s *co, uint32_t faults, uint32_t now_us)
{
    co_emcy_t *m = &co->emcy;
    uint32_t diff = faults ^ m->reported;
    uint32_t low = diff & (~diff + 1u);
    uint8_t f[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    uint16_t code;

    if (diff == 0u) {
        return;
    }
    if (m->sent > 0u && now_us - m->last_us < (uint32_t)co->od.emcy_inhibit * 100u) {
        return;
    }
    m->reported ^= low;
    co->od.error_register = error_register(m->reported);
    code = (faults & low) != 0u ? co_emcy_code(low) : 0x0000u;
    if (low == EMCY_COMM_BIT) {
        if (code != 0u && m->comm_code != 0u) {
            code = m->comm_code; /* the heartbeat consumer's timeout */
        } else if (code == 0u) {
            m->comm_code = 0u;
        }
    }
    if (code == 0x0000u && m->reported != 0u) {
        return; /* one of several cleared: the reset comes with the last */
    }
    if (co->nmt == CO_NMT_STOPPED || (co->od.emcy_cobid & 0x80000000u) != 0u) {
        return;
    }
    f[0] = (uint8_t)code;
    f[1] = (uint8_t)(code >> 8);
    f[2] = co->od.error_register;
    f[3] = (uint8_t)faults;
    f[4] = (uint8_t)(faults >> 8);
    co_send(co, co->od.emcy_cobid & 0x7FFu, f, 8u);
    m->last_us = now_us;
    m->sent++;
}
