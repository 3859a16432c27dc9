/*
 * proto_replay.h - the one-entry replay cache of a request handler.
 *
 * Specification
 * -------------
 * A host that lost a reply sends the same request again (same message id
 * and seq); the handler must answer it with the reply it already gave and
 * not execute it twice. The cache keys a request on the request itself:
 * (message id, seq, payload length, CRC-32 of the payload). A different
 * request that happens to reuse the last (id, seq) - a new host session
 * whose seq counter starts where the last one stopped, or another payload
 * under the same seq - misses the cache and is executed.
 *
 * Use (one handler, one cache):
 *     n = proto_replay_answer(&cache, msg, len, out, cap, execute, ctx);
 * answers msg from the cache when it is the cached request (execute is not
 * called), else with execute(ctx, msg, len, out) and caches that reply.
 * The parts, for a handler that counts hits (the dispatcher):
 *     proto_replay_key(&k, msg, len);
 *     n = proto_replay_lookup(&cache, &k, out, cap);
 *     if (n == 0) { n = execute(...); proto_replay_store(&cache, &k, out, n); }
 * A reply longer than PROTO_MSG_MAX is not cached (the next retry executes).
 * proto_replay_reset forgets the entry (after a reset of the handler).
 *
 * Users: the dispatcher (proto_dispatch.c, the parts), the bootloader
 * (boot.c) and, for their state-changing requests only, the calibration
 * (calib.c), 2-D compensation (comp2d_link.c) and excitation
 * (drive_excite.c) handlers.
 * Context: the handler's (main). No heap.
 */
#ifndef PROTO_REPLAY_H
#define PROTO_REPLAY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "proto_msgs.h"

typedef struct {
    uint8_t id;
    uint8_t seq;
    uint16_t plen; /* payload length */
    uint32_t crc;  /* CRC-32 of the payload */
} proto_replay_key_t;

typedef struct {
    bool valid;
    proto_replay_key_t key;
    uint16_t len;
    uint8_t reply[PROTO_MSG_MAX];
} proto_replay_t;

void proto_replay_reset(proto_replay_t *c);
/* Key of the request msg[0..len) (len >= PROTO_MSG_HDR). */
void proto_replay_key(proto_replay_key_t *k, const uint8_t *msg, size_t len);
/* The cached reply copied to out when k matches (and fits cap): its length;
 * else 0. */
size_t proto_replay_lookup(const proto_replay_t *c, const proto_replay_key_t *k, uint8_t *out,
                           size_t cap);
/* Remember reply[0..len) as the answer to k. */
void proto_replay_store(proto_replay_t *c, const proto_replay_key_t *k, const uint8_t *reply,
                        size_t len);

/* Executes the request msg[0..len) (len >= PROTO_MSG_HDR) for the handler
 * whose state is ctx: writes the reply to out (room for PROTO_MSG_MAX
 * bytes), returns its length (0: no reply). */
typedef size_t (*proto_replay_exec_t)(void *ctx, const uint8_t *msg, size_t len, uint8_t *out);

/* The reply to msg[0..len) (len >= PROTO_MSG_HDR, cap >= PROTO_MSG_MAX):
 * the cached one when msg is the cached request, else exec's, cached. */
size_t proto_replay_answer(proto_replay_t *c, const uint8_t *msg, size_t len, uint8_t *out,
                           size_t cap, proto_replay_exec_t exec, void *ctx);

#endif /* PROTO_REPLAY_H */
