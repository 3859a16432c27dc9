/*
 * port_ring.h - the byte ring between a UART interrupt and main context,
 * shared by the MCU ports (stm32f4, mps2_an386).
 *
 * Single producer, single consumer: one context only calls the producer side
 * (port_ring_put, port_ring_write), the other only the consumer side
 * (port_ring_get, port_ring_read); either may call port_ring_empty. The
 * indices are free-running uint32_t (used = head - tail, wrap-safe); the
 * size must be a power of two so that the wrap of the indices keeps the slot
 * index continuous. Nothing is overwritten: a put into a full ring fails
 * (the caller counts the drop), a write stores what fits.
 *
 * Initialise with PORT_RING_INIT(buffer) or port_ring_init().
 */
#ifndef PORT_RING_H
#define PORT_RING_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct {
    uint8_t *buf;
    uint32_t size;          /* bytes, power of two */
    volatile uint32_t head; /* next slot to fill: written by the producer only */
    volatile uint32_t tail; /* next slot to empty: written by the consumer only */
} port_ring_t;

#define PORT_RING_INIT(array)                                                                      \
    {                                                                                              \
        (array), (uint32_t)sizeof(array), 0u, 0u                                                   \
    }

/* Keeps the compiler from moving a slot access across an index update. */
#define PORT_RING_BARRIER() __asm__ volatile("" ::: "memory")

static inline void port_ring_init(port_ring_t *r)
{
    r->head = 0u;
    r->tail = 0u;
}

static inline bool port_ring_empty(const port_ring_t *r)
{
    return r->head == r->tail;
}

static inline bool port_ring_put(port_ring_t *r, uint8_t c)
{
    uint32_t h = r->head;

    if (h - r->tail >= r->size) {
        return false;
    }
    r->buf[h % r->size] = c;
    PORT_RING_BARRIER();
    r->head = h + 1u;
    return true;
}

static inline bool port_ring_get(port_ring_t *r, uint8_t *c)
{
    uint32_t t = r->tail;

    if (t == r->head) {
        return false;
    }
    PORT_RING_BARRIER();
    *c = r->buf[t % r->size];
    PORT_RING_BARRIER();
    r->tail = t + 1u;
    return true;
}

static inline size_t port_ring_write(port_ring_t *r, const uint8_t *data, size_t len)
{
    size_t n = 0;

    while (n < len && port_ring_put(r, data[n])) {
        n++;
    }
    return n;
}

static inline size_t port_ring_read(port_ring_t *r, uint8_t *data, size_t cap)
{
    size_t n = 0;

    while (n < cap && port_ring_get(r, &data[n])) {
        n++;
    }
    return n;
}

#endif /* PORT_RING_H */
