/*
 * dispatch_fixture.h - the dispatcher against the real drive inside the
 * simulator, shared by the protocol unit tests (test_proto_*.c).
 *
 * Include once per test file: it defines the file's dispatcher `d`, the last
 * reply `out` / `out_len`, the dispatcher's clock `now_us` and the header
 * sequence `next_seq`. dispatch_fixture_start() sets up a 3-axis drive at
 * 10 kHz and a fresh dispatcher at time 0; request() sends one message with
 * the next sequence number, request_seq() with a given one (a retry repeats
 * it); expect_error() checks that the reply is the error `code`.
 */
#ifndef DISPATCH_FIXTURE_H
#define DISPATCH_FIXTURE_H

#include <string.h>

#include "proto_dispatch.h"
#include "sim.h"
#include "unity.h"

static proto_dispatch_t d;
static uint8_t out[PROTO_MSG_MAX];
static size_t out_len;
static uint32_t now_us;
static uint8_t next_seq;

static inline void dispatch_fixture_start(void)
{
    proto_identity_t id = {0x000100u, 0xABCDu, 7u, 10000u, 1u, 0u, 5u, 3u};

    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 3));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    now_us = 0;
    TEST_ASSERT_TRUE(proto_dispatch_init(&d, &id, now_us));
}

static inline size_t request_seq(uint8_t id, uint8_t seq, const uint8_t *payload, size_t n)
{
    uint8_t m[PROTO_MSG_MAX];

    m[0] = id;
    m[1] = seq;
    if (n > 0) {
        memcpy(m + 2, payload, n);
    }
    out_len = proto_dispatch_handle(&d, m, n + 2, now_us, out, sizeof out);
    return out_len;
}

static inline size_t request(uint8_t id, const uint8_t *payload, size_t n)
{
    return request_seq(id, ++next_seq, payload, n);
}

static inline proto_error_t expect_error(size_t len, uint8_t code)
{
    proto_error_t e;

    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ERROR, out[0]);
    TEST_ASSERT_TRUE(proto_error_decode(out + 2, len - 2, &e));
    TEST_ASSERT_EQUAL_UINT8(code, e.code);
    return e;
}

#endif
