/*
 * sample_pull.h - chunked transfers between host and drive: one piece of
 * code for the three shapes the calibration, the 2-D map and the
 * commissioning excitation share. The messages themselves are defined in
 * protocol/contour.toml; this module only fills and checks them.
 *
 * Specification
 * -------------
 * 1. Pull of numbered samples (calib_read -> calib_samples, excite_read ->
 *    excite_samples). A producer numbers its samples 0, 1, 2, ... (mod
 *    2^32) and keeps them in a ring: `written` is the number of the next
 *    sample, `released` the oldest one still held. A read names from_seq
 *    and max:
 *      - sample_pull_seq_ok(): from_seq must lie in [released, written];
 *        otherwise the service refuses (its own seq refusal, detail
 *        released) and changes nothing;
 *      - the service then releases everything before from_seq;
 *      - sample_pull_reply() answers min(max, written - from_seq) samples
 *        from from_seq on, laid out (little-endian) as
 *            from_seq u32 | count u8 | written u32 | crc u32 | data
 *        with crc = crc32 of data (crc.h), each sample `size` bytes as the
 *        service's encoder writes it. This is the layout of both
 *        calib_samples and excite_samples (SAMPLE_PULL_HDR bytes before
 *        data). The reply is written in place: no copy of the data in RAM.
 *    A read of the same from_seq returns the same samples (idempotent), so
 *    the host reads again after a lost or garbled reply.
 *    Contexts: the producer (tick) writes a sample, then advances
 *    `written`; main reads `written` once per read and passes that value
 *    to both calls, and reads only samples below it, so a sample being
 *    recorded while a chunk is read is not in that chunk (the next read
 *    gets it). `released` is written by main only; the producer never
 *    overwrites a sample at or after it.
 *
 * 2. Staging of a record written at offset (comp_write, comp2d_write): the
 *    host sends the record in chunks, the drive collects them in a
 *    staging buffer, and a commit names the length and the CRC-32 of the
 *    whole record (sample_pull_stage_crc). A chunk that would end past the
 *    buffer is refused (range) and changes nothing; a fresh record (the
 *    service decides: offset 0, or another axis) starts from an erased
 *    buffer (0xFF). `staged` is the highest end written since the record
 *    started. Main context only (chunk_stage_t is not shared).
 *
 * 3. Read of a stored record at offset (comp2d_read -> comp2d_data):
 *    sample_pull_copy copies bytes from offset on, at most max; none at or
 *    past the end.
 *
 * No state of its own (a stage is its owner's); the services call it from
 * main.
 */
#ifndef SAMPLE_PULL_H
#define SAMPLE_PULL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define SAMPLE_PULL_HDR 13u /* from_seq, count, written, crc */

/* Encode sample number seq of src into dst (the sample's wire bytes). */
typedef void (*sample_pull_enc_fn)(const void *src, uint32_t seq, uint8_t *dst);

/* True when from_seq lies in [released, written] (mod 2^32). */
bool sample_pull_seq_ok(uint32_t released, uint32_t written, uint32_t from_seq);

/* The reply message (id, seq: the request's) to a read from from_seq of at
 * most max samples of size bytes into out (PROTO_MSG_MAX bytes); returns
 * its length. from_seq passed sample_pull_seq_ok(.., written, ..); max *
 * size must fit the message's data. */
size_t sample_pull_reply(uint8_t *out, uint8_t id, uint8_t seq, uint32_t from_seq, uint32_t max,
                         uint32_t written, size_t size, sample_pull_enc_fn enc, const void *src);

/* A staging buffer (main). */
typedef struct {
    uint8_t *buf;    /* the owner's buffer              */
    uint16_t cap;    /* its size                        */
    uint16_t staged; /* highest end written (see above) */
} sample_pull_stage_t;

void sample_pull_stage_init(sample_pull_stage_t *s, uint8_t *buf, uint16_t cap);
/* Write data[0..len) at offset; fresh: erase the buffer and start a new
 * record first. False (nothing changed) when offset + len > cap. */
bool sample_pull_stage_write(sample_pull_stage_t *s, uint32_t offset, const uint8_t *data,
                             uint32_t len, bool fresh);
/* crc32 of the first len staged bytes (len <= cap). */
uint32_t sample_pull_stage_crc(const sample_pull_stage_t *s, uint32_t len);

/* Copy buf[offset..len) to dst, at most max bytes; the count copied. */
uint32_t sample_pull_copy(uint8_t *dst, uint32_t max, const uint8_t *buf, uint32_t len,
                          uint32_t offset);

#endif /* SAMPLE_PULL_H */
