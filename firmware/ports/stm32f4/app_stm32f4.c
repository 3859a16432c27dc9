/*
 * app_stm32f4.c - the drive application on the STM32F405/407 board: the
 * control tick (drive_tick; it reads the encoder timers as counters) in
 * the SysTick interrupt at F4_TICK_HZ; host link (USART2 and CAN1, node 1),
 * background work and the watchdog in main.
 *
 * Machine configuration: drive_config_default for three axes; encoder
 * scale 1250 nm per count (5 mm lead, 1000-line encoder x4) and a 1 nm
 * reference scale on axis 0 (TIM5) - edit here for another machine; the
 * amplifier input is limited to +-10 V (the PWM stage's range).
 */
#include "boot/boot.h"
#include "calib.h"
#include "drive.h"
#include "hal.h"
#include "port.h"
#include "stm32f4.h"

#define APP_AXES 3u

static boot_config_t boot_cfg;

static void tick(void)
{
    const drive_tick_out_t *t = drive_tick(calib_sampling());

    if (t != NULL) {
        calib_tick(t->st, t->vel_ref);
    }
}

int main(void)
{
    drive_config_t cfg;
    port_app_config_t pc;
    unsigned i;

    f4_board_init(F4_TICK_HZ, NULL);
    drive_config_default(&cfg, F4_TICK_HZ, APP_AXES);
    for (i = 0; i < APP_AXES; i++) {
        cfg.nm_per_count_num[i] = 1250;
        cfg.nm_per_count_den[i] = 1;
        cfg.enc_counter[i] = true; /* TIM2..4 counts (hal_encoder_counter) */
        cfg.servo.axis[i].out_max_mv = 10000;
        cfg.servo.axis[i].i_max_mv = 10000;
    }
    cfg.ref_nm_per_count_num[0] = 1;
    cfg.ref_nm_per_count_den[0] = 1;
    cfg.servo.cec.pid.out_max_mv = 10000;
    cfg.servo.cec.pid.i_max_mv = 10000;
    if (drive_init(&cfg) != DRIVE_OK) {
        hal_system_reset();
    }
    calib_init();
    boot_config_default(&boot_cfg, BOOT_BOARD_STM32F4);
    boot_cfg.slot_size = F4_APP_SLOT_SIZE; /* sectors 10, 11: the store */
    boot_cfg.node_id = 1u;
    boot_cfg.request_word = &f4_boot_request_word;
    pc.board_id = BOOT_BOARD_STM32F4;
    pc.node_id = 1u;
    pc.axes = APP_AXES;
    pc.serial = true;
    pc.can = true;
    pc.tick_hz = F4_TICK_HZ;
    pc.capabilities = 0u;
    pc.fw_version = 0u; /* not flashed through the bootloader */
    pc.boot = &boot_cfg;
    if (!port_app_init(&pc)) {
        hal_system_reset();
    }
    f4_watchdog_start();
    f4_set_tick_hook(tick);
    for (;;) {
        port_app_poll();
        cm4_wfi(); /* until the next tick, USART2 or CAN interrupt */
    }
}
