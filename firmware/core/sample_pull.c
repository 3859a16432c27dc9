/* Chunked transfers between host and drive: sample_pull.h. */
#include "sample_pull.h"

#include "crc.h"
#include "proto_msgs.h"

/* the two replies this writes share one layout (sample_pull.h) */
typedef char sample_pull_calib_layout[PROTO_CALIB_SAMPLES_LEN == SAMPLE_PULL_HDR ? 1 : -1];
typedef char sample_pull_excite_layout[PROTO_EXCITE_SAMPLES_LEN == SAMPLE_PULL_HDR ? 1 : -1];

bool sample_pull_seq_ok(uint32_t released, uint32_t written, uint32_t from_seq)
{
    return (uint32_t)(from_seq - released) <= (uint32_t)(written - released);
}

size_t sample_pull_reply(uint8_t *out, uint8_t id, uint8_t seq, uint32_t from_seq, uint32_t max,
                         uint32_t written, size_t size, sample_pull_enc_fn enc, const void *src)
{
    uint8_t *hdr = out + PROTO_MSG_HDR;
    uint8_t *data = hdr + SAMPLE_PULL_HDR;
    uint32_t avail = written - from_seq;
    uint32_t n = avail < max ? avail : max;
    uint32_t i;

    for (i = 0; i < n; i++) {
        enc(src, from_seq + i, data + size * i);
    }
    proto_put_le(hdr, from_seq, 4u);
    hdr[4] = (uint8_t)n;
    proto_put_le(hdr + 5, written, 4u);
    proto_put_le(hdr + 9, crc32_update(CRC32_INIT, data, size * n), 4u);
    out[0] = id;
    out[1] = seq;
    return PROTO_MSG_HDR + SAMPLE_PULL_HDR + size * n;
}

void sample_pull_stage_init(sample_pull_stage_t *s, uint8_t *buf, uint16_t cap)
{
    s->buf = buf;
    s->cap = cap;
    s->staged = 0u;
}

bool sample_pull_stage_write(sample_pull_stage_t *s, uint32_t offset, const uint8_t *data,
                             uint32_t len, bool fresh)
{
    uint32_t i;

    if ((uint64_t)offset + len > s->cap) {
        return false;
    }
    if (fresh) {
        for (i = 0; i < s->cap; i++) {
            s->buf[i] = 0xFFu;
        }
        s->staged = 0u;
    }
    for (i = 0; i < len; i++) {
        s->buf[offset + i] = data[i];
    }
    if (offset + len > s->staged) {
        s->staged = (uint16_t)(offset + len);
    }
    return true;
}

uint32_t sample_pull_stage_crc(const sample_pull_stage_t *s, uint32_t len)
{
    return crc32_update(CRC32_INIT, s->buf, len);
}

uint32_t sample_pull_copy(uint8_t *dst, uint32_t max, const uint8_t *buf, uint32_t len,
                          uint32_t offset)
{
    uint32_t n = 0u;

    while (offset + n < len && n < max) {
        dst[n] = buf[offset + n];
        n++;
    }
    return n;
}
