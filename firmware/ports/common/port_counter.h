/*
 * port_counter.h - a hardware counter of 16 or 32 bits (an encoder timer)
 * extended to a free-running 32-bit count, shared by the MCU ports.
 *
 * Each read adds the counter's signed change since the previous read, taken
 * modulo 2^bits: exact while the counter moves by less than 2^(bits - 1)
 * counts between two reads (16 bits: 32767 counts per read; read once per
 * control tick, 3.2e8 counts/s at 10 kHz). The extended count wraps modulo
 * 2^32 like a 32-bit timer, which is what the decoder's counter input
 * expects (qdec.h, QDEC_INPUT_COUNTER). Single context (the control tick,
 * or main before the tick runs).
 */
#ifndef PORT_COUNTER_H
#define PORT_COUNTER_H

#include <stdint.h>

typedef struct {
    uint32_t last;  /* raw counter value at the previous read */
    uint32_t count; /* extended count (wraps modulo 2^32)     */
    uint8_t bits;   /* counter width: 16 or 32                 */
} port_counter_t;

/* Start at count 0 from the counter's present value raw. */
static inline void port_counter_init(port_counter_t *c, uint32_t raw, uint8_t bits)
{
    c->last = raw;
    c->count = 0u;
    c->bits = bits;
}

/* The extended count after a read of raw (the counter's value now). */
static inline uint32_t port_counter_update(port_counter_t *c, uint32_t raw)
{
    uint32_t d = raw - c->last;

    if (c->bits == 16u) {
        d = (uint32_t)(int32_t)(int16_t)(uint16_t)d; /* signed 16-bit change */
    }
    c->last = raw;
    c->count += d;
    return c->count;
}

#endif /* PORT_COUNTER_H */
