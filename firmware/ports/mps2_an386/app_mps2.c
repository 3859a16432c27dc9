/*
 * app_mps2.c - the drive application on the QEMU mps2-an386 board: the
 * control tick (app_tick, then the simulated axes) in the SysTick
 * interrupt at MPS2_TICK_HZ, the host link and background work in main
 * (once per interrupt: the main loop sleeps in WFI in between).
 * Machine configuration: drive_config_default for three axes, amplifier
 * input +-10 V (as the simulator's machine), encoder scales from the plant.
 */
#include "app.h"
#include "hal.h"
#include "mps2.h"
#include "plant_mps2.h"

#define APP_AXES 3u

static boot_config_t boot_cfg;

static void tick(void)
{
    app_tick();
    plant_step(mps2_ticks());
}

int main(void)
{
    drive_config_t cfg;
    app_board_t board = {0};

    mps2_board_init(MPS2_TICK_HZ, NULL);
    plant_drive_config(&cfg, MPS2_TICK_HZ, APP_AXES);
    if (!plant_init(MPS2_TICK_HZ, APP_AXES, &cfg)) {
        hal_system_reset();
    }
    boot_config_default(&boot_cfg, BOOT_BOARD_QEMU);
    boot_cfg.request_word = &mps2_boot_request_word;
    board.board_id = BOOT_BOARD_QEMU;
    board.node_id = 1u;
    board.serial = true;
    board.boot = &boot_cfg;
    board.drive = &cfg;
    if (app_init(&board) != APP_OK) {
        hal_system_reset();
    }
    mps2_set_tick_hook(tick);
    for (;;) {
        app_poll();
        cm4_wfi(); /* until the next tick or UART interrupt: QEMU idles the host CPU */
    }
}
