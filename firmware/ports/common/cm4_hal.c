/*
 * cm4_hal.c - the HAL pieces that are the same on every Cortex-M4 board
 * whose flash region is memory-mapped (stm32f4, mps2_an386): the bounds
 * check of the board's flash layout, flash read, system reset, the SysTick
 * time base reading, and the bootloader's jump into the application.
 * See cm4.h.
 */
#include <stddef.h>

#include "cm4.h"
#include "hal.h"

bool cm4_flash_in_region(uint32_t addr, size_t len)
{
    const hal_flash_layout_t *l = hal_flash_layout();

    return addr >= l->base && len <= l->size && addr - l->base <= l->size - len;
}

bool hal_flash_read(uint32_t addr, uint8_t *data, size_t len)
{
    const volatile uint8_t *p = (const volatile uint8_t *)(uintptr_t)addr;
    size_t i;

    if (data == NULL || !cm4_flash_in_region(addr, len)) {
        return false;
    }
    for (i = 0; i < len; i++) {
        data[i] = p[i];
    }
    return true;
}

void hal_system_reset(void)
{
    cm4_system_reset();
}

uint32_t cm4_systick_time_us(const volatile uint32_t *ticks, uint32_t load, uint32_t period_us,
                             uint32_t clk_per_us)
{
    uint32_t t1, t2, val, sub;

    do {
        t1 = *ticks;
        val = CM4_SYST_CVR;
        t2 = *ticks;
        /* a wrap not yet counted (interrupt pending or masked): take the
         * start of the period */
        if (CM4_SCB_ICSR & CM4_ICSR_PENDSTSET) {
            val = load;
        }
    } while (t1 != t2);
    sub = (load - val) / clk_per_us;
    if (sub >= period_us) {
        sub = period_us - 1u;
    }
    return t1 * period_us + sub;
}

void cm4_boot_jump(uint32_t load_addr, void *ctx)
{
    (void)ctx;
    cm4_start_image(load_addr);
}
