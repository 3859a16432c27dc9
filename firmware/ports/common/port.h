/*
 * port.h - what the real-target ports (stm32f4, mps2_an386, linux) share on
 * top of the HAL: the bootloader's serving loop. The application is built by
 * the composition root (firmware/core/app.h) on every target; the control
 * law, protocol and bootloader logic stay in firmware/core; this is only
 * wiring.
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
 */
#ifndef PORT_H
#define PORT_H

#include <stdbool.h>
#include <stdint.h>

#include "boot/boot.h"

/* Longest wait for a reply to leave before a requested reset, us. */
#define PORT_RESET_DELAY_US 50000u

bool port_boot_init(const boot_config_t *cfg, bool serial, bool can);
void port_boot_poll(void);
/* Reset hook body for boot_config_t.reset: let the reply leave, reset. */
void port_boot_reset(void *ctx);
const boot_t *port_boot_state(void);

#endif /* PORT_H */
