/*
 * libFuzzer harness: block batches (proto_batch.h). The input is batch
 * records. The decoder must never read past them, and what it reads must
 * survive a round trip: the blocks written again by proto_batch_put (from
 * the same point) read back identical. Then the same records go to the
 * drive in the simulator as a queue_batch (start flag, count = the blocks
 * read) through the dispatcher, twice, with the link polled between: every
 * reply is a batch_reply or an error naming queue_batch, accepted never
 * exceeds the count, next_seq advances by accepted, and the ring's free
 * bytes never exceed its size.
 */
#include <stdint.h>
#include <string.h>

#include "drive.h"
#include "proto_batch.h"
#include "proto_dispatch.h"
#include "sim.h"

#define MAX_BLOCKS 1100u

static proto_dispatch_t d;
static proto_batch_block_t blocks[MAX_BLOCKS];
static uint8_t again[MAX_BLOCKS * PROTO_BATCH_RECORD_MAX + PROTO_BATCH_RECORD_MAX];

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    if (sim_setup(10000.0, 3) != 0 || sim_start() != 0) {
        __builtin_trap();
    }
    return 0;
}

static void round_trip(const uint8_t *data, size_t size)
{
    static const int64_t zero[PROTO_MAX_AXES] = {0, 0, 0, 0};
    proto_batch_rd_t rd;
    proto_batch_block_t b;
    int64_t pt[PROTO_MAX_AXES] = {0, 0, 0, 0};
    uint64_t feed = 0;
    unsigned n = 0, i, a;
    size_t len = 0;
    int k;

    proto_batch_rd_init(&rd, data, size, zero, 0);
    while ((k = proto_batch_rd_next(&rd, &b)) == 1) {
        if (n >= MAX_BLOCKS || rd.left > size) {
            __builtin_trap();
        }
        blocks[n++] = b;
    }
    if (k != 0 && k != -1) {
        __builtin_trap();
    }
    if (k == -1 || n == 0u) {
        return;
    }
    for (a = 0; a < PROTO_MAX_AXES; a++) {
        pt[a] = blocks[0].from[a];
    }
    for (i = 0; i < n; i++) {
        size_t w = proto_batch_put(again + len, sizeof again - len, &blocks[i], pt, &feed, i == 0);

        if (w == 0u) {
            __builtin_trap();
        }
        len += w;
    }
    proto_batch_rd_init(&rd, again, len, zero, 0);
    for (i = 0; i < n; i++) {
        if (proto_batch_rd_next(&rd, &b) != 1 || b.kind != blocks[i].kind ||
            b.exact_stop != (blocks[i].exact_stop && blocks[i].kind != PROTO_BATCH_KIND_DWELL)) {
            __builtin_trap();
        }
        if (b.kind != PROTO_BATCH_KIND_RAPID && b.feed != blocks[i].feed) {
            __builtin_trap();
        }
        for (a = 0; a < PROTO_MAX_AXES && b.kind != PROTO_BATCH_KIND_DWELL; a++) {
            if (b.target[a] != blocks[i].target[a]) { /* a dwell's is no target */
                __builtin_trap();
            }
        }
    }
}

static void intake(const uint8_t *data, size_t size, unsigned count)
{
    static const proto_identity_t id = {0x000100u, 1u, 0x7Fu, 10000u, 1u, 0u, 1u, 3u};
    proto_queue_batch_t q;
    uint8_t in[PROTO_MSG_MAX];
    uint8_t out[PROTO_MSG_MAX];
    uint32_t now = 0;
    unsigned rep;

    if (!proto_dispatch_init(&d, &id, now)) {
        __builtin_trap();
    }
    drive_stop();
    (void)drive_enable(false);
    (void)sim_run(2, NULL, 0, 0);
    (void)drive_fault_reset();
    (void)sim_run(1, NULL, 0, 0);
    (void)drive_enable(true);
    (void)sim_run(2, NULL, 0, 0);
    memset(&q, 0, sizeof q);
    q.first_seq = 77u;
    q.count = (uint8_t)(count > 255u ? 255u : count);
    q.flags = 1u << PROTO_BATCH_FLAG_START;
    q.data_len = (uint16_t)(size > sizeof q.data ? sizeof q.data : size);
    memcpy(q.data, data, q.data_len);
    for (rep = 0; rep < 2u; rep++) {
        size_t n;
        proto_batch_reply_t r;

        in[0] = PROTO_MSG_QUEUE_BATCH;
        in[1] = (uint8_t)(1u + rep); /* a new request each time: no replay */
        n = proto_queue_batch_encode(&q, in + 2, sizeof in - 2);
        n = proto_dispatch_handle(&d, in, n + 2u, now, out, sizeof out);
        if (n < PROTO_MSG_HDR || n > PROTO_MSG_MAX) {
            __builtin_trap();
        }
        if (out[0] == PROTO_MSG_BATCH_REPLY) {
            if (!proto_batch_reply_decode(out + 2, n - 2, &r) || r.accepted > q.count ||
                r.free_bytes > PROTO_BATCH_RING) {
                __builtin_trap();
            }
            if (r.status == PROTO_ERROR_CODE_NONE && r.next_seq != q.first_seq + r.accepted) {
                __builtin_trap();
            }
            q.first_seq = r.next_seq;
            q.flags = 0;
        } else if (out[0] != PROTO_MSG_ERROR || out[2] != PROTO_MSG_QUEUE_BATCH) {
            __builtin_trap();
        }
        (void)sim_run(5, NULL, 0, 0);
        now += 500u;
        proto_dispatch_poll(&d, now, NULL, NULL);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const int64_t zero[PROTO_MAX_AXES] = {0, 0, 0, 0};
    proto_batch_rd_t rd;
    proto_batch_block_t b;
    unsigned count = 0;

    round_trip(data, size);
    proto_batch_rd_init(&rd, data, size, zero, 0);
    while (proto_batch_rd_next(&rd, &b) == 1) {
        count++;
    }
    intake(data, size, count);
    return 0;
}
