/*
 * app_mps2.c - the drive application on the QEMU mps2-an386 board: the
 * control tick (drive_tick, then the simulated axes) in the SysTick
 * interrupt at MPS2_TICK_HZ, the host link and background work in main
 * (once per interrupt: the main loop sleeps in WFI in between).
 * Machine configuration: drive_config_default for three axes, amplifier
 * input +-10 V (as the simulator's machine), encoder scales from the plant.
 */
#include "boot/boot.h"
#include "calib.h"
#include "drive.h"
#include "hal.h"
#include "mps2.h"
#include "plant_mps2.h"
#include "port.h"

#define APP_AXES 3u

static boot_config_t boot_cfg;

static void tick(void)
{
    const drive_tick_out_t *t = drive_tick(calib_sampling());

    if (t != NULL) {
        calib_tick(t->st, t->vel_ref);
    }
    plant_step(mps2_ticks());
}

int main(void)
{
    drive_config_t cfg;
    port_app_config_t pc;

    mps2_board_init(MPS2_TICK_HZ, NULL);
    plant_drive_config(&cfg, MPS2_TICK_HZ, APP_AXES);
    if (!plant_init(MPS2_TICK_HZ, APP_AXES, &cfg) || drive_init(&cfg) != DRIVE_OK) {
        hal_system_reset();
    }
    calib_init();
    boot_config_default(&boot_cfg, BOOT_BOARD_QEMU);
    boot_cfg.request_word = &mps2_boot_request_word;
    pc.board_id = BOOT_BOARD_QEMU;
    pc.node_id = 1u;
    pc.axes = APP_AXES;
    pc.serial = true;
    pc.can = false;
    pc.tick_hz = MPS2_TICK_HZ;
    pc.capabilities = 0u;
    pc.fw_version = 0u; /* not flashed through the bootloader */
    pc.boot = &boot_cfg;
    if (!port_app_init(&pc)) {
        hal_system_reset();
    }
    mps2_set_tick_hook(tick);
    for (;;) {
        port_app_poll();
        cm4_wfi(); /* until the next tick or UART interrupt: QEMU idles the host CPU */
    }
}
