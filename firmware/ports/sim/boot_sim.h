/*
 * boot_sim.h - the simulated drive's bootloader wiring (no hal_ functions).
 *
 * The simulated drive runs the portable bootloader (firmware/core/boot)
 * unchanged against the flash file of hal_flash_sim.c. A simulated reset
 * (power-on, hal_system_reset, or a REBOOT) re-runs the boot decision against
 * the same flash file: boot_sim_reset().
 *
 *   boot_sim_init      geometry = hal_flash_sim defaults, flash file attached
 *                      (NULL: RAM only), slot = boot_config_default (board
 *                      BOOT_BOARD_SIM), then boot_sim_reset().
 *   boot_sim_reset     boot_init + boot_start at hal_time_us(); mode becomes
 *                      BOOT_SIM_APP when a valid application is found and the
 *                      connect window (window_us) has passed without a host,
 *                      BOOT_SIM_BOOTLOADER otherwise.
 *   boot_sim_poll      call from the server loop: ends the window (-> APP),
 *                      performs a pending REBOOT (-> boot_sim_reset).
 *   boot_sim_handle    bootloader mode: every message goes to boot_handle.
 *                      Application mode: ids 0x80..0x8F are the application's
 *                      bootloader messages (boot_sim_app_handle); others
 *                      return 0 (the application dispatcher's job).
 *   boot_sim_link_handle  boot_sim_handle with proto_link's extension
 *                      handler signature: the handler of the bootloader mode
 *                      (proto_link_set_ext_exclusive(true): every message).
 *   boot_sim_app_handle  the application side, fits proto_link's extension
 *                      handler (or calib_set_next_handler): boot_enter sets
 *                      the request word (RAM that survives a simulated reset,
 *                      not a process restart) and resets into the bootloader
 *                      (hal_system_reset and boot_sim_reset); other boot ids
 *                      0x80..0x8F get error{boot, bad_state, lo = 1}
 *                      ("application running"); any other id error{
 *                      unknown_message} (it is the last handler of a chain).
 *   boot_sim_app_version  fw_version of the valid image in flash (what the
 *                      simulated application reports in identify), 0 if none.
 *   boot_sim_app_build_id  its build id's first 4 bytes, little-endian (the
 *                      identify build_id), 0 if none.
 *
 *   boot_sim_serve_link  bootloader mode: the host link (serial and CAN)
 *                      with boot_sim_link_handle answering every message
 *                      (the application's link is app_init's, app.h).
 *
 * For in-process tests of the host tool, boot_sim_drive_handle answers as a
 * whole drive would: boot_sim_handle, plus `identify` in application mode
 * (fw_version = boot_sim_app_version, axes = 3). Main context only.
 */
#ifndef BOOT_SIM_H
#define BOOT_SIM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "boot/boot.h"

#define BOOT_SIM_BOOTLOADER 0
#define BOOT_SIM_APP        1

bool boot_sim_init(const char *flash_path, uint8_t node_id, uint32_t window_us);
int boot_sim_reset(void);
int boot_sim_mode(void);
int boot_sim_reason(void);
void boot_sim_poll(void);
size_t boot_sim_handle(const uint8_t *msg, size_t len, uint8_t *out, size_t cap);
size_t boot_sim_link_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                            size_t cap);
size_t boot_sim_app_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                           size_t cap);
uint32_t boot_sim_app_version(void);
uint32_t boot_sim_app_build_id(void);
size_t boot_sim_drive_handle(const uint8_t *msg, size_t len, uint8_t *out, size_t cap);
bool boot_sim_serve_link(void);
const boot_config_t *boot_sim_config(void);
/* Simulated resets done so far (power-on excluded). */
uint32_t boot_sim_resets(void);

#endif /* BOOT_SIM_H */
