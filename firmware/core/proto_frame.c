/*
 * proto_frame.c - COBS + CRC-16 serial framing (see proto_frame.h).
 */
#include "proto_frame.h"

#include "crc.h"

void proto_frame_rx_init(proto_frame_rx_t *rx)
{
    proto_frame_stats_t zero = {0};

    rx->len = 0;
    rx->discarding = false;
    rx->stats = zero;
}

uint32_t proto_frame_rx_errors(const proto_frame_rx_t *rx)
{
    return rx->stats.oversized + rx->stats.short_len + rx->stats.cobs + rx->stats.crc;
}

/* Decode rx->buf[0..n) in place; returns the body length or -1 on bad COBS. */
static int cobs_decode_in_place(uint8_t *buf, size_t n)
{
    size_t in = 0;
    size_t out = 0;

    while (in < n) {
        uint8_t code = buf[in];
        size_t i;

        if (code == 0u || in + code > n) {
            return -1;
        }
        in++;
        for (i = 1; i < code; i++) {
            buf[out++] = buf[in++];
        }
        if (code != 0xFFu && in < n) {
            buf[out++] = 0;
        }
    }
    return (int)out;
}

static bool frame_complete(proto_frame_rx_t *rx, const uint8_t **msg, size_t *len)
{
    int body;
    uint16_t crc;
    size_t mlen;

    body = cobs_decode_in_place(rx->buf, rx->len);
    if (body < 0) {
        rx->stats.cobs++;
        return false;
    }
    if ((size_t)body < PROTO_MSG_HDR + PROTO_FRAME_CRC_LEN) {
        rx->stats.short_len++;
        return false;
    }
    mlen = (size_t)body - PROTO_FRAME_CRC_LEN;
    crc = crc16_update(CRC16_INIT, rx->buf, mlen);
    if (rx->buf[mlen] != (uint8_t)(crc >> 8) || rx->buf[mlen + 1u] != (uint8_t)crc) {
        rx->stats.crc++;
        return false;
    }
    rx->stats.frames++;
    *msg = rx->buf;
    *len = mlen;
    return true;
}

bool proto_frame_rx_byte(proto_frame_rx_t *rx, uint8_t byte, const uint8_t **msg, size_t *len)
{
    bool ok = false;

    if (byte != 0u) {
        if (rx->discarding) {
            return false;
        }
        if (rx->len >= PROTO_FRAME_ENC_MAX) {
            rx->discarding = true;
            rx->stats.oversized++;
            rx->len = 0;
            return false;
        }
        rx->buf[rx->len++] = byte;
        return false;
    }
    /* delimiter */
    if (rx->discarding) {
        rx->discarding = false;
    } else if (rx->len > 0u) {
        ok = frame_complete(rx, msg, len);
    }
    rx->len = 0;
    return ok;
}

size_t proto_frame_encode(const uint8_t *msg, size_t len, uint8_t *out, size_t cap)
{
    uint16_t crc;
    size_t code_at = 1;
    size_t o = 2;
    uint8_t code = 1;
    size_t i;

    /* body <= 254 bytes: one COBS overhead byte, plus two delimiters */
    if (len < PROTO_MSG_HDR || len > PROTO_MSG_MAX || cap < len + PROTO_FRAME_CRC_LEN + 3u) {
        return 0;
    }
    out[0] = 0;
    crc = crc16_update(CRC16_INIT, msg, len);
    for (i = 0; i < len + PROTO_FRAME_CRC_LEN; i++) {
        uint8_t b;

        if (i < len) {
            b = msg[i];
        } else if (i == len) {
            b = (uint8_t)(crc >> 8);
        } else {
            b = (uint8_t)crc;
        }
        if (b == 0u) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
        } else {
            out[o++] = b;
            code++;
            if (code == 0xFFu && i + 1u < len + PROTO_FRAME_CRC_LEN) {
                out[code_at] = code;
                code_at = o++;
                code = 1;
            }
        }
    }
    out[code_at] = code;
    out[o++] = 0;
    return o;
}
