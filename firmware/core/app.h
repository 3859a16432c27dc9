/*
 * app.h - the composition root: the one place that builds the drive
 * application. Every target calls it - the STM32F4 and QEMU boards, the
 * Linux port, the simulator (hil_sim/sim.c) and through it the host tool's
 * simulated drive - so a message, a handler or a calibration service works
 * on one target exactly when it works on all. A port differs only in its HAL
 * and in the app_board_t it passes.
 *
 * Specification
 * -------------
 * app_init(board), main context, interrupts (the tick) not yet running:
 *   1. drive_init(board->drive) - the machine: axes, tick, scales, gains;
 *      then calib_init - the calibration service and its compensation
 *      tables from flash, installed in the drive's decoders;
 *   2. the identity identify reports: fw_version and build id from this
 *      image's header in flash (board->boot, boot_check_app), else
 *      board->fw_version / board->build_id (an image loaded by a debugger,
 *      the Linux process, the simulator without a flash image);
 *      capabilities TELEMETRY, JOG, CALIBRATION, SERIAL/CAN as served,
 *      BOOTLOADER when board->boot is set, plus board->capabilities;
 *   3. the host link when board->serial or board->can (proto_link_init) with
 *      the one handler chain: ids 0x00..0x7F the dispatcher
 *      (proto_dispatch.h); 0xA0..0xBF the calibration (calib_handle); the
 *      rest app_boot_handle: boot_enter -> estop, ack, the boot request
 *      word set, reset once the ack has left (hal_uart_tx_idle, at most
 *      APP_RESET_DELAY_US later: a CAN reply needs a few polls); other
 *      bootloader ids 0x80..0x8F -> error{boot, bad_state, lo = 1}
 *      ("application running", or no bootloader); anything else ->
 *      error{unknown_message};
 *   4. hal_watchdog_start().
 *   Returns APP_OK, or what refused (nothing is running then: the port
 *   resets or exits).
 *
 * app_tick(), tick context (the board's timer interrupt or thread): one
 *   control tick - drive_tick(calib_sampling()), then calib_tick with the
 *   status and reference velocities the drive just published (the drive
 *   calls no calibration function).
 *
 * app_poll(), main context, as often as the board's main loop runs (at
 *   least once per tick): calib_poll (the calibration run), drive_poll (the
 *   feed path), the host link (proto_link_poll; a new host session ends a
 *   calibration run: calib_host_gone), hal_watchdog_kick, a pending reset.
 *
 * The tick/main contract these functions live under is docs/architecture.md.
 */
#ifndef APP_H
#define APP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "boot/boot.h"
#include "drive.h"

/* Longest wait for a reply to leave before a requested reset, us. */
#define APP_RESET_DELAY_US 50000u

typedef struct {
    uint32_t board_id;           /* BOOT_BOARD_* */
    uint8_t node_id;             /* CAN node id, 1..PROTO_CAN_NODE_MAX */
    bool serial;                 /* serve the UART link */
    bool can;                    /* serve the CAN link */
    uint32_t capabilities;       /* extra 1 << PROTO_CAPABILITY_* bits */
    const boot_config_t *boot;   /* this image's slot; NULL: no bootloader */
    uint32_t fw_version;         /* reported when `boot` holds no valid image */
    uint32_t build_id;           /* ... and its build id */
    const drive_config_t *drive; /* the machine (axes and tick_hz included) */
} app_board_t;

typedef enum {
    APP_OK = 0,
    APP_E_ARG,   /* no board or no drive configuration */
    APP_E_DRIVE, /* drive_init refused the configuration */
    APP_E_LINK,  /* proto_link_init refused the identity */
} app_result_t;

app_result_t app_init(const app_board_t *board);
void app_tick(void);
void app_poll(void);
/* fw_version reported in identify. */
uint32_t app_fw_version(void);
/* The handler after calibration in the chain (see above); exported for the
 * tests. */
size_t app_boot_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out, size_t cap);

#endif /* APP_H */
