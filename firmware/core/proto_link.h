/*
 * proto_link.h - the drive's host link: ties the serial framing
 * (proto_frame) and CAN ISO-TP (proto_isotp) to the HAL byte stream and CAN
 * frames, and both to the dispatcher (proto_dispatch). One instance per
 * firmware (static state, no heap); main context only.
 *
 * Specification
 * -------------
 * proto_link_poll() (call it often from the background loop; the simulator
 * server calls it between tick chunks) does, in order:
 *   1. reads every waiting UART byte (hal_uart_read) into the frame decoder;
 *      each valid frame is handled and its reply framed into the serial
 *      transmit ring;
 *   2. reads every waiting CAN frame (hal_can_receive); CANopen NMT and
 *      the node's SDO requests go to the CiA 301 slave (canopen.h, not in
 *      bootloader mode), frames on PROTO_CAN_ID(PROTO_CAN_FUNC_REQUEST, node)
 *      feed ISO-TP, others are ignored (other nodes' traffic); replies go
 *      to the ISO-TP reply queue;
 *   3. runs the dispatcher's watchdog and cyclic output (to both links)
 *      and the CANopen heartbeat / SDO timeout (co_poll);
 *   4. drains the serial ring (hal_uart_write, partial writes kept) and the
 *      CAN queues (ISO-TP first, then cyclic frames; a full mailbox leaves
 *      the frame for the next poll).
 * A message whose id is >= 0x80 goes to the extension handler when one is
 * set (bootloader / calibration messages), otherwise to the dispatcher.
 * Overflowing queues drop whole frames and count them (never half a frame).
 */
#ifndef PROTO_LINK_H
#define PROTO_LINK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "proto_dispatch.h"
#include "proto_frame.h"
#include "proto_isotp.h"

#define PROTO_LINK_UART_TX   2048u /* serial transmit ring, bytes */
#define PROTO_LINK_CAN_TX    64u   /* cyclic CAN frames queued */
#define PROTO_LINK_REPLY_MAX 4u    /* ISO-TP replies queued */

/* Extension handler: same contract as proto_dispatch_handle (reply written
 * to out, length returned, 0 = no reply). */
typedef size_t (*proto_link_handler_fn)(const uint8_t *msg, size_t len, uint32_t now_us,
                                        uint8_t *out, size_t cap);

typedef struct {
    uint32_t uart_tx_dropped; /* frames not queued: serial ring full */
    uint32_t can_tx_dropped;  /* cyclic frames or replies not queued */
    uint32_t can_ignored;     /* frames for other ids */
} proto_link_stats_t;

/* serial / can: which links to serve. False for an invalid identity. */
bool proto_link_init(const proto_identity_t *ident, bool serial, bool can);
void proto_link_set_ext_handler(proto_link_handler_fn fn);
/* Bootloader mode of a port whose bootloader shares this link (the
 * simulator): when on, EVERY message goes to the extension handler (none to
 * the dispatcher) and no cyclic output, heartbeat or watchdog runs. Off after
 * proto_link_init. */
void proto_link_set_ext_exclusive(bool on);
void proto_link_poll(void);

const proto_link_stats_t *proto_link_stats(void);
const proto_frame_stats_t *proto_link_frame_stats(void);
const proto_isotp_stats_t *proto_link_isotp_stats(void);
proto_dispatch_t *proto_link_dispatch(void);

#endif /* PROTO_LINK_H */
