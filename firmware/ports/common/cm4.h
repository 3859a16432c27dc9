/*
 * cm4.h - the few Cortex-M4 core registers the MCU ports use (ARMv7-M
 * architecture reference: System Control Space at 0xE000E000). Written
 * here, minimal; no vendor headers.
 *
 * Used by firmware/ports/stm32f4 and firmware/ports/mps2_an386 (and their
 * bootloaders). Everything is register access or a single instruction.
 */
#ifndef PORT_CM4_H
#define PORT_CM4_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define CM4_REG(addr) (*(volatile uint32_t *)(uintptr_t)(addr))

/* SysTick */
#define CM4_SYST_CSR           CM4_REG(0xE000E010u)
#define CM4_SYST_RVR           CM4_REG(0xE000E014u)
#define CM4_SYST_CVR           CM4_REG(0xE000E018u)
#define CM4_SYST_CSR_ENABLE    (1u << 0)
#define CM4_SYST_CSR_TICKINT   (1u << 1)
#define CM4_SYST_CSR_CLKSOURCE (1u << 2) /* processor clock */
#define CM4_SYST_CSR_COUNTFLAG (1u << 16)

/* NVIC: enable / clear-enable / clear-pending banks, byte priorities */
#define CM4_NVIC_ISER(n)  CM4_REG(0xE000E100u + 4u * (n))
#define CM4_NVIC_ICER(n)  CM4_REG(0xE000E180u + 4u * (n))
#define CM4_NVIC_ICPR(n)  CM4_REG(0xE000E280u + 4u * (n))
#define CM4_NVIC_IPR(irq) (*(volatile uint8_t *)(uintptr_t)(0xE000E400u + (irq)))

/* System control block */
#define CM4_SCB_ICSR       CM4_REG(0xE000ED04u)
#define CM4_SCB_VTOR       CM4_REG(0xE000ED08u)
#define CM4_SCB_AIRCR      CM4_REG(0xE000ED0Cu)
#define CM4_SCB_SHPR3      CM4_REG(0xE000ED20u) /* SysTick / PendSV priorities */
#define CM4_SCB_CPACR      CM4_REG(0xE000ED88u)
#define CM4_ICSR_PENDSTSET (1u << 26)
#define CM4_ICSR_PENDSTCLR (1u << 25)
#define CM4_AIRCR_SYSRESET 0x05FA0004u /* VECTKEY | SYSRESETREQ */

static inline void cm4_irq_disable(void)
{
    __asm__ volatile("cpsid i" ::: "memory");
}

static inline void cm4_irq_enable(void)
{
    __asm__ volatile("cpsie i" ::: "memory");
}

static inline uint32_t cm4_irq_save(void)
{
    uint32_t primask;
    __asm__ volatile("mrs %0, primask\n\tcpsid i" : "=r"(primask)::"memory");
    return primask;
}

static inline void cm4_irq_restore(uint32_t primask)
{
    __asm__ volatile("msr primask, %0" ::"r"(primask) : "memory");
}

static inline void cm4_wfi(void)
{
    __asm__ volatile("wfi" ::: "memory");
}

static inline void cm4_nvic_enable(unsigned irq, uint8_t prio)
{
    CM4_NVIC_IPR(irq) = prio;
    CM4_NVIC_ISER(irq / 32u) = 1u << (irq % 32u);
}

/* Request a system reset; never returns. */
void cm4_system_reset(void) __attribute__((noreturn));

/* Start an image whose vector table is at vtor: interrupts off, SysTick
 * stopped, NVIC cleared, VTOR set, MSP loaded from vtor[0], jump to vtor[1].
 * Never returns. */
void cm4_start_image(uint32_t vtor) __attribute__((noreturn));

/* cm4_hal.c (boards with a memory-mapped flash region; they provide
 * hal_flash_layout, and get hal_flash_read and hal_system_reset from there):
 * cm4_flash_in_region  [addr, addr + len) lies inside hal_flash_layout()'s
 *                      region (overflow-safe).
 * cm4_boot_jump        boot_config_t.jump of the MCU bootloaders:
 *                      cm4_start_image(load_addr); ctx unused. */
bool cm4_flash_in_region(uint32_t addr, size_t len);
void cm4_boot_jump(uint32_t load_addr, void *ctx);

/* hal_time_us of a SysTick time base: *ticks (incremented by the SysTick
 * handler, reload value `load`, period_us per tick) times period_us plus the
 * microseconds elapsed in the current period (clk_per_us SysTick clocks per
 * us), at most period_us - 1; a wrap whose interrupt is still pending reads
 * as the start of the period. Consistent against the handler (re-reads until
 * *ticks is stable). Main context or lower-priority interrupts. */
uint32_t cm4_systick_time_us(const volatile uint32_t *ticks, uint32_t load, uint32_t period_us,
                             uint32_t clk_per_us);

#endif /* PORT_CM4_H */
