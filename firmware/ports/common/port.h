/*
 * port.h - what the real-target ports (stm32f4, mps2_an386, linux) share on
 * top of the HAL: the application's background loop and the bootloader's
 * serving loop. The control law, protocol and bootloader logic stay in
 * firmware/core; this is only wiring.
 *
 * Application (port_app_*, main context):
 *   port_app_init   identity for the protocol (fw_version and build id read
 *                   from this image's header in flash via boot_check_app;
 *                   c->fw_version when there is no image header, e.g. an
 *                   image loaded by a debugger, or the Linux process), proto_link_init, and the
 *                   extension handler for the bootloader ids 0x80..0x8F:
 *                   boot_enter -> ack, request word set (boot_request_enter),
 *                   reset once the ack has left (port_uart_tx_idle, at most
 *                   PORT_RESET_DELAY_US later: a CAN reply needs a few
 *                   polls); every other bootloader id -> error{boot,
 *                   bad_state} ("application running", lo = 1).
 *   port_app_poll   drive_poll(), proto_link_poll(), hal_watchdog_kick(),
 *                   the pending reset. Call it continuously from main().
 *   The control tick (drive_tick) is the board's interrupt (or timer
 *   thread), not this loop.
 *
 * Bootloader (port_boot_*, main context, no interrupts needed except the
 * board's UART / time base):
 *   port_boot_init  boot_init + boot_start (the boot decision); serves serial
 *                   frames (proto_frame) and/or CAN ISO-TP (proto_isotp, node
 *                   cfg->node_id) afterwards.
 *   port_boot_poll  one request at a time: a received message goes to
 *                   boot_handle, its reply is framed and sent before the next
 *                   request is read (bytes wait in the UART receive ring);
 *                   then boot_poll (jump after the connect window, reset
 *                   after a REBOOT reply: the board's reset hook should call
 *                   port_boot_reset, which lets the reply leave first).
 *
 * Board obligations (in addition to hal.h):
 *   port_uart_tx_idle()  true when every byte given to hal_uart_write has
 *                        left the transmitter.
 */
#ifndef PORT_H
#define PORT_H

#include <stdbool.h>
#include <stdint.h>

#include "boot/boot.h"

/* Longest wait for a reply to leave before a requested reset, us. */
#define PORT_RESET_DELAY_US 50000u

typedef struct {
    uint32_t board_id;         /* BOOT_BOARD_* */
    uint8_t node_id;           /* CAN node id, 1..PROTO_CAN_NODE_MAX */
    uint8_t axes;              /* axes in use */
    bool serial;               /* serve the UART link */
    bool can;                  /* serve the CAN link */
    uint32_t tick_hz;          /* control tick rate */
    uint32_t capabilities;     /* extra 1 << PROTO_CAPABILITY_* bits */
    const boot_config_t *boot; /* slot of this image (version, boot_enter); may be NULL */
    uint32_t fw_version;       /* reported when `boot` holds no valid image header */
} port_app_config_t;

bool port_app_init(const port_app_config_t *c);
void port_app_poll(void);
/* fw_version reported in identify (from the image header; 0 if none). */
uint32_t port_app_fw_version(void);

bool port_boot_init(const boot_config_t *cfg, bool serial, bool can);
void port_boot_poll(void);
/* Reset hook body for boot_config_t.reset: let the reply leave, reset. */
void port_boot_reset(void *ctx);
const boot_t *port_boot_state(void);

/* Board side. */
bool port_uart_tx_idle(void);

#endif /* PORT_H */
