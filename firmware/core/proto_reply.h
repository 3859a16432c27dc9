/*
 * proto_reply.h - the two replies every message handler sends: ack and
 * error. One implementation for the drive's dispatcher, the bootloader, the
 * calibration handler and the ports' bootloader-id handlers.
 *
 * A reply is a protocol message: out[0] = message id, out[1] = seq (the
 * request's, echoed), then the payload (proto_msgs.h). `out` must hold at
 * least PROTO_MSG_HDR + PROTO_ERROR_LEN bytes (any PROTO_MSG_MAX buffer
 * does). Both return the reply's length in bytes. Pure, any context.
 *
 *   proto_reply_ack    ack{req}: the request `req` was done.
 *   proto_reply_error  error{req, code, arg, lo, hi}: `req` was refused and
 *                      nothing was applied; code is a PROTO_ERROR_CODE_*,
 *                      arg / lo / hi its detail as documented for that code.
 */
#ifndef PROTO_REPLY_H
#define PROTO_REPLY_H

#include <stddef.h>
#include <stdint.h>

size_t proto_reply_ack(uint8_t *out, uint8_t seq, uint8_t req);
size_t proto_reply_error(uint8_t *out, uint8_t seq, uint8_t req, uint8_t code, uint16_t arg,
                         int64_t lo, int64_t hi);

#endif /* PROTO_REPLY_H */
