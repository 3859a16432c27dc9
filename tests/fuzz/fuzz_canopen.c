/*
 * libFuzzer harness: the CiA 301 SDO server and NMT slave (canopen.c).
 *
 * The input is cut into CAN frames: per frame one byte selects the id
 * (bit 7: NMT 0x000, else the node's SDO request id) and the DLC (low
 * nibble, 0..15, above 8 taken as 8), then the data bytes; a time step of
 * the next byte (ms) runs co_poll. Every frame the server sends must be a
 * classic CAN frame on its own ids, every SDO response DLC 8, and the
 * transfer state must stay within the buffer; nothing may crash or loop.
 */
#include <stdint.h>
#include <string.h>

#include "canopen.h"

#define NODE 7u

static uint32_t calls;

static bool tx_check(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    (void)data;
    if (len > 8u) {
        __builtin_trap();
    }
    if (id == CO_ID_TSDO + NODE) {
        if (len != 8u) {
            __builtin_trap();
        }
    } else if (id != CO_ID_HB + NODE || len != 1u) {
        __builtin_trap();
    }
    return ++calls % 5u != 0u; /* now and then a full mailbox */
}

int LLVMFuzzerTestOneInput(const uint8_t *in, size_t n);

int LLVMFuzzerTestOneInput(const uint8_t *in, size_t n)
{
    static const co_config_t cfg = {NODE, 1u, 2u, 3u, 4u};
    static co_t co;
    uint32_t now = 0;
    size_t i = 0;

    co_init(&co, &cfg, tx_check, NULL, now);
    while (i < n) {
        uint8_t sel = in[i++];
        uint8_t len = (uint8_t)(sel & 0x0Fu);
        uint8_t f[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        uint32_t id = (sel & 0x80u) ? CO_ID_NMT : CO_ID_RSDO + NODE;

        if (len > 8u) {
            len = 8u;
        }
        if (n - i < len) {
            len = (uint8_t)(n - i);
        }
        memcpy(f, &in[i], len);
        i += len;
        (void)co_rx(&co, id, f, len, now);
        if (i < n) {
            now += (uint32_t)in[i++] * 1000u;
        }
        co_poll(&co, now);
        if (co.sdo_pos > sizeof co.sdo_buf || co.sdo_mode > 2u) {
            __builtin_trap();
        }
    }
    return 0;
}
