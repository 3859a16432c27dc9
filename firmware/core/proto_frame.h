/*
 * proto_frame.h - serial framing of protocol messages (drive and host side).
 *
 * Specification
 * -------------
 * On the wire a frame is
 *
 *     0x00 COBS( msg | crc16_be ) 0x00
 *
 * where msg = msg_id | seq | payload (PROTO_MSG_HDR..PROTO_MSG_MAX bytes, see
 * proto_msgs.h) and crc16 is CRC-16/CCITT-FALSE (crc.h) over msg, sent
 * big-endian. COBS (consistent overhead byte stuffing) removes every 0x00
 * from the frame body, so 0x00 only ever delimits frames: after garbage, a
 * cut frame or a lost byte the decoder is back in step at the next 0x00.
 * The leading 0x00 ends whatever garbage preceded the frame, so a frame
 * after noise on the line is never lost; empty frames (two delimiters in a
 * row) are ignored.
 *
 * Limits: a body (msg + crc) is at most PROTO_FRAME_BODY_MAX = 254 bytes; its
 * COBS encoding at most 255 bytes; with both delimiters PROTO_FRAME_MAX = 257.
 *
 * Receiver (proto_frame_rx_t, main context, one per link): bytes are fed one
 * at a time; a complete frame that passes every check is returned, and every
 * rejected frame is counted by its reason and dropped:
 *   oversized  more than 255 bytes before a delimiter (dropped up to the
 *              next 0x00, never buffered beyond PROTO_FRAME_MAX)
 *   short      body shorter than msg header + crc (includes empty frames
 *              other than back-to-back delimiters, which are ignored)
 *   cobs       invalid COBS code (a code byte points past the frame end)
 *   crc        CRC mismatch
 * No heap, no floating point, no libc.
 */
#ifndef PROTO_FRAME_H
#define PROTO_FRAME_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "proto_msgs.h"

#define PROTO_FRAME_CRC_LEN  2u
#define PROTO_FRAME_BODY_MAX (PROTO_MSG_MAX + PROTO_FRAME_CRC_LEN) /* 254 */
#define PROTO_FRAME_ENC_MAX  (PROTO_FRAME_BODY_MAX + 1u)           /* 255 */
#define PROTO_FRAME_MAX      (PROTO_FRAME_ENC_MAX + 2u)            /* 257 */

typedef struct {
    uint32_t frames;    /* valid frames delivered */
    uint32_t oversized; /* dropped: longer than PROTO_FRAME_ENC_MAX */
    uint32_t short_len; /* dropped: body too short */
    uint32_t cobs;      /* dropped: invalid COBS */
    uint32_t crc;       /* dropped: CRC mismatch */
} proto_frame_stats_t;

typedef struct {
    uint8_t buf[PROTO_FRAME_ENC_MAX]; /* encoded bytes, decoded in place */
    uint16_t len;                     /* bytes in buf */
    bool discarding;                  /* oversized: skip to next 0x00 */
    proto_frame_stats_t stats;
} proto_frame_rx_t;

void proto_frame_rx_init(proto_frame_rx_t *rx);

/* Feed one received byte. Returns true when it completed a valid frame:
 * *msg points to msg_id | seq | payload inside rx (valid until the next
 * call) and *len is its length (>= PROTO_MSG_HDR). */
bool proto_frame_rx_byte(proto_frame_rx_t *rx, uint8_t byte, const uint8_t **msg, size_t *len);

/* Total dropped frames (sum of every rejection counter). */
uint32_t proto_frame_rx_errors(const proto_frame_rx_t *rx);

/* Frame msg (len PROTO_MSG_HDR..PROTO_MSG_MAX) into out (delimiter
 * included). Returns the frame length, 0 when len is out of range or cap is
 * too small (len + 5 bytes are needed; PROTO_FRAME_MAX always suffices). */
size_t proto_frame_encode(const uint8_t *msg, size_t len, uint8_t *out, size_t cap);

#endif /* PROTO_FRAME_H */
