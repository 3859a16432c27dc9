/*
 * cm4_startup.c - reset handler and core helpers shared by the Cortex-M4
 * ports (the vector tables are per board: they differ in interrupt count).
 *
 * Linker-script symbols used (see the boards' *.ld):
 *   _sidata  load address of .data    _sdata/_edata  its RAM range
 *   _sbss/_ebss  .bss range           _estack        initial stack pointer
 */
#include <stdint.h>

#include "cm4.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss;
extern int main(void);

void cm4_reset_handler(void) __attribute__((noreturn));
void cm4_default_handler(void);

void cm4_reset_handler(void)
{
    const uint32_t *src = &_sidata;
    uint32_t *dst;

    /* cppcheck-suppress comparePointers ; linker symbols bound one region */
    for (dst = &_sdata; dst < &_edata;) {
        *dst++ = *src++;
    }
    /* cppcheck-suppress comparePointers */
    for (dst = &_sbss; dst < &_ebss;) {
        *dst++ = 0u;
    }
    (void)main();
    cm4_system_reset();
}

/* Unexpected interrupt or fault: reset (the bootloader decides what runs). */
void cm4_default_handler(void)
{
    cm4_system_reset();
}

void cm4_system_reset(void)
{
    __asm__ volatile("dsb" ::: "memory");
    CM4_SCB_AIRCR = CM4_AIRCR_SYSRESET;
    __asm__ volatile("dsb" ::: "memory");
    for (;;) {
        cm4_wfi();
    }
}

void cm4_start_image(uint32_t vtor)
{
    const volatile uint32_t *vec = (const volatile uint32_t *)(uintptr_t)vtor;
    uint32_t sp = vec[0], pc = vec[1];
    unsigned i;

    cm4_irq_disable();
    CM4_SYST_CSR = 0u;
    CM4_SCB_ICSR = CM4_ICSR_PENDSTCLR;
    for (i = 0; i < 8u; i++) {
        CM4_NVIC_ICER(i) = 0xFFFFFFFFu;
        CM4_NVIC_ICPR(i) = 0xFFFFFFFFu;
    }
    CM4_SCB_VTOR = vtor;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    __asm__ volatile("msr msp, %0\n\t"
                     "cpsie i\n\t"
                     "bx %1" ::"r"(sp),
                     "r"(pc)
                     : "memory");
    for (;;) {
    }
}
