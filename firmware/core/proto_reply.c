/* proto_reply.c - see proto_reply.h. */
#include "proto_reply.h"

#include "proto_msgs.h"

size_t proto_reply_ack(uint8_t *out, uint8_t seq, uint8_t req)
{
    proto_ack_t a;

    a.req = req;
    out[0] = (uint8_t)PROTO_MSG_ACK;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_ack_encode(&a, out + PROTO_MSG_HDR, PROTO_ACK_LEN);
}

size_t proto_reply_error(uint8_t *out, uint8_t seq, uint8_t req, uint8_t code, uint16_t arg,
                         int64_t lo, int64_t hi)
{
    proto_error_t e;

    e.req = req;
    e.code = code;
    e.arg = arg;
    e.lo = lo;
    e.hi = hi;
    out[0] = (uint8_t)PROTO_MSG_ERROR;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_error_encode(&e, out + PROTO_MSG_HDR, PROTO_ERROR_LEN);
}
