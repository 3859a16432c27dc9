/* proto_replay.c - one-entry replay cache (specification in proto_replay.h). */
#include "proto_replay.h"

#include "crc.h"

void proto_replay_reset(proto_replay_t *c)
{
    c->valid = false;
    c->len = 0;
}

void proto_replay_key(proto_replay_key_t *k, const uint8_t *msg, size_t len)
{
    size_t plen = len > PROTO_MSG_HDR ? len - PROTO_MSG_HDR : 0u;

    k->id = msg[0];
    k->seq = msg[1];
    k->plen = (uint16_t)plen;
    k->crc = crc32_update(CRC32_INIT, msg + PROTO_MSG_HDR, plen);
}

size_t proto_replay_lookup(const proto_replay_t *c, const proto_replay_key_t *k, uint8_t *out,
                           size_t cap)
{
    size_t i;

    if (!c->valid || c->key.id != k->id || c->key.seq != k->seq || c->key.plen != k->plen ||
        c->key.crc != k->crc || c->len == 0u || c->len > cap) {
        return 0;
    }
    for (i = 0; i < c->len; i++) {
        out[i] = c->reply[i];
    }
    return c->len;
}

void proto_replay_store(proto_replay_t *c, const proto_replay_key_t *k, const uint8_t *reply,
                        size_t len)
{
    size_t i;

    if (len == 0u || len > sizeof c->reply) {
        c->valid = false;
        return;
    }
    for (i = 0; i < len; i++) {
        c->reply[i] = reply[i];
    }
    c->key = *k;
    c->len = (uint16_t)len;
    c->valid = true;
}

size_t proto_replay_answer(proto_replay_t *c, const uint8_t *msg, size_t len, uint8_t *out,
                           size_t cap, proto_replay_exec_t exec, void *ctx)
{
    proto_replay_key_t k;
    size_t n;

    proto_replay_key(&k, msg, len);
    n = proto_replay_lookup(c, &k, out, cap);
    if (n != 0u) {
        return n;
    }
    n = exec(ctx, msg, len, out);
    proto_replay_store(c, &k, out, n);
    return n;
}
