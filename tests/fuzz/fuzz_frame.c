/*
 * libFuzzer harness: the serial frame decoder and the ISO-TP receiver.
 *
 * The input is fed byte by byte to proto_frame_rx_byte; every frame it
 * accepts must re-encode to a frame that decodes to the same message
 * (round trip). The same input, cut into CAN frames (first byte of each
 * chunk = DLC), goes to proto_isotp_rx with a clock that advances, and the
 * transmit side is polled; nothing may crash, overrun or loop.
 */
#include <stdint.h>
#include <string.h>

#include "proto_frame.h"
#include "proto_isotp.h"

static bool tx_ok(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    (void)id;
    (void)data;
    return len <= 8u;
}

static void check_round_trip(const uint8_t *msg, size_t len)
{
    uint8_t f[PROTO_FRAME_MAX];
    proto_frame_rx_t rx;
    size_t n = proto_frame_encode(msg, len, f, sizeof f);
    size_t i;
    int got = 0;

    if (n == 0u) {
        __builtin_trap(); /* every accepted message must be encodable */
    }
    proto_frame_rx_init(&rx);
    for (i = 0; i < n; i++) {
        const uint8_t *m;
        size_t l;

        if (proto_frame_rx_byte(&rx, f[i], &m, &l)) {
            if (l != len || memcmp(m, msg, len) != 0) {
                __builtin_trap();
            }
            got++;
        }
    }
    if (got != 1) {
        __builtin_trap();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static proto_frame_rx_t rx;
    static proto_isotp_t tp;
    uint8_t copy[PROTO_MSG_MAX];
    size_t i;
    uint32_t now = 0;

    proto_frame_rx_init(&rx);
    for (i = 0; i < size; i++) {
        const uint8_t *m;
        size_t len;

        if (proto_frame_rx_byte(&rx, data[i], &m, &len)) {
            if (len < PROTO_MSG_HDR || len > PROTO_MSG_MAX) {
                __builtin_trap();
            }
            memcpy(copy, m, len);
            check_round_trip(copy, len);
        }
    }

    proto_isotp_init(&tp, 0x81u, 0xC1u);
    i = 0;
    while (i < size) {
        uint8_t dlc = (uint8_t)(data[i] & 0x0Fu);
        const uint8_t *m;
        size_t len;

        i++;
        if (dlc > size - i) {
            dlc = (uint8_t)(size - i);
        }
        now += (uint32_t)(data[i - 1] >> 4) * 100000u;
        if (proto_isotp_rx(&tp, data + i, dlc, now, &m, &len)) {
            if (len < 1u || len > PROTO_ISOTP_MAX) {
                __builtin_trap();
            }
            (void)proto_isotp_send(&tp, m, len, now);
        }
        proto_isotp_poll(&tp, now, tx_ok, NULL);
        i += dlc;
    }
    return 0;
}
