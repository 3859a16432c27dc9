/*
 * boot_mps2.c - the bootloader of the QEMU mps2-an386 board: the portable
 * bootloader (firmware/core/boot) on UART0, slot from boot_config_default
 * over the HAL flash region (header at 0x00010000, payload 0x00010200).
 */
#include "boot/boot.h"
#include "hal.h"
#include "mps2.h"
#include "port.h"

int main(void)
{
    boot_config_t cfg;

    mps2_board_init(1000u, NULL);
    boot_config_default(&cfg, BOOT_BOARD_QEMU);
    cfg.node_id = 1u;
    cfg.request_word = &mps2_boot_request_word;
    cfg.jump = cm4_boot_jump;
    cfg.reset = port_boot_reset;
    if (cfg.slot_base + BOOT_IMAGE_HDR_AREA != MPS2_APP_LOAD ||
        !port_boot_init(&cfg, true, false)) {
        for (;;) {
            cm4_wfi(); /* misbuilt: nothing sensible to do */
        }
    }
    for (;;) {
        port_boot_poll();
    }
}
