/*
 * libFuzzer harness: the drive's dispatcher with the real drive in the
 * simulator. The input is a sequence of messages, each prefixed by its
 * length byte; between messages the simulator runs (byte value & 0x3 ticks)
 * and the dispatcher's cyclic output and watchdog are polled. Every reply
 * must be a well-formed message of the table (or nothing), never longer than
 * PROTO_MSG_MAX; an error reply must name the request's id.
 */
#include <stdint.h>
#include <string.h>

#include "drive.h"
#include "proto_dispatch.h"
#include "sim.h"

static proto_dispatch_t d;

static bool emit(void *ctx, const uint8_t *msg, size_t len, uint8_t can_func)
{
    const proto_msg_info_t *info = proto_msg_info(msg[0]);

    (void)ctx;
    if (info == NULL || info->can_func != can_func || len - PROTO_MSG_HDR != info->min_len) {
        __builtin_trap();
    }
    return true;
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    if (sim_setup(10000.0, 3) != 0 || sim_start() != 0) {
        __builtin_trap();
    }
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const proto_identity_t id = {0x000100u, 1u, 0x7Fu, 10000u, 1u, 0u, 1u, 3u};
    uint8_t out[PROTO_MSG_MAX];
    uint32_t now = 0;
    size_t i = 0;

    if (!proto_dispatch_init(&d, &id, now)) {
        __builtin_trap();
    }
    d.heartbeat_on = true;
    /* each input starts from a drive at rest and without faults */
    drive_stop();
    (void)drive_enable(false);
    (void)sim_run(2, NULL, 0, 0);
    (void)drive_fault_reset();
    while (i < size) {
        size_t len = data[i++];
        size_t r;

        if (len > size - i) {
            len = size - i;
        }
        r = proto_dispatch_handle(&d, data + i, len, now, out, sizeof out);
        if (r > 0u) {
            const proto_msg_info_t *info = proto_msg_info(out[0]);

            if (r < PROTO_MSG_HDR || r > PROTO_MSG_MAX || info == NULL ||
                info->dir != PROTO_DIR_D2H || r - PROTO_MSG_HDR < info->min_len ||
                r - PROTO_MSG_HDR > info->max_len || out[1] != data[i + 1]) {
                __builtin_trap();
            }
            if (out[0] == PROTO_MSG_ERROR && out[2] != data[i]) {
                __builtin_trap();
            }
        } else if (len >= PROTO_MSG_HDR) {
            __builtin_trap(); /* every well-formed request gets a reply */
        }
        i += len;
        if (len > 0u) {
            (void)sim_run(data[i - 1] & 0x3u, NULL, 0, 0);
            now += (uint32_t)(data[i - 1] & 0x3u) * 100u;
        }
        proto_dispatch_poll(&d, now, emit, NULL);
    }
    return 0;
}
