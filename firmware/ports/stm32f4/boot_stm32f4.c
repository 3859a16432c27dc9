/*
 * boot_stm32f4.c - the STM32F4 bootloader: the portable bootloader
 * (firmware/core/boot) on USART2 and CAN1 (node 1), slot sectors 5..9
 * (F4_APP_SLOT_SIZE), compensation store sectors 10 and 11 (never touched).
 * No watchdog here: a sector erase takes up to 2 s.
 */
#include "boot/boot.h"
#include "hal.h"
#include "port.h"
#include "stm32f4.h"

int main(void)
{
    boot_config_t cfg;

    f4_board_init(1000u, NULL);
    boot_config_default(&cfg, BOOT_BOARD_STM32F4);
    cfg.slot_size = F4_APP_SLOT_SIZE; /* sectors 10, 11: the store */
    cfg.node_id = 1u;
    cfg.request_word = &f4_boot_request_word;
    cfg.jump = cm4_boot_jump;
    cfg.reset = port_boot_reset;
    if (cfg.slot_base + BOOT_IMAGE_HDR_AREA != F4_APP_LOAD || !port_boot_init(&cfg, true, true)) {
        for (;;) {
            cm4_wfi();
        }
    }
    for (;;) {
        port_boot_poll();
        cm4_wfi(); /* until the next SysTick (1 kHz), USART2 or CAN interrupt */
    }
}
