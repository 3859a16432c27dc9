/*
 * mps2.h - the QEMU mps2-an386 board (Arm MPS2 FPGA image AN386: Cortex-M4,
 * CMSDK APB peripherals), as this port uses it. Register definitions written
 * here from the CMSDK peripheral descriptions; addresses of QEMU's model.
 *
 * Memory map used:
 *   0x00000000  ZBT SSRAM1, 4 MiB, code region (RAM in QEMU):
 *               0x00000000..0x0000FFFF  bootloader image (vectors at 0)
 *               0x00010000..0x0008FFFF  "flash" managed by the HAL (512 KiB,
 *                                       4 KiB pages, 8-byte write unit,
 *                                       NOR rules enforced in software):
 *                                       application slot 480 KiB (header at
 *                                       0x00010000, payload / vectors at
 *                                       0x00010200), parameter store 32 KiB
 *   0x20000000  ZBT SSRAM2/3, 4 MiB: .data, .bss, stack of either image;
 *               the last word is the boot request word (never initialised by
 *               either image, survives a warm reset).
 *   0x40000000  APB peripherals: UART0 0x40004000 (RX irq 0, TX irq 1),
 *               dual timer 0x40002000, watchdog 0x40008000 (a stub in QEMU).
 * Clocks: 25 MHz system clock (SysTick with the processor clock source).
 */
#ifndef MPS2_H
#define MPS2_H

#include <stdbool.h>
#include <stdint.h>

#include "cm4.h"

#define MPS2_SYSCLK_HZ 25000000u

/* CMSDK APB UART */
#define MPS2_UART0             0x40004000u
#define MPS2_UART_DATA(b)      CM4_REG((b) + 0x00u)
#define MPS2_UART_STATE(b)     CM4_REG((b) + 0x04u)
#define MPS2_UART_CTRL(b)      CM4_REG((b) + 0x08u)
#define MPS2_UART_INT(b)       CM4_REG((b) + 0x0Cu) /* status / write 1 to clear */
#define MPS2_UART_BAUDDIV(b)   CM4_REG((b) + 0x10u)
#define MPS2_UART_STATE_TXFULL (1u << 0)
#define MPS2_UART_STATE_RXFULL (1u << 1)
#define MPS2_UART_CTRL_TXEN    (1u << 0)
#define MPS2_UART_CTRL_RXEN    (1u << 1)
#define MPS2_UART_CTRL_TXINT   (1u << 2)
#define MPS2_UART_CTRL_RXINT   (1u << 3)
#define MPS2_UART_INT_TX       (1u << 0)
#define MPS2_UART_INT_RX       (1u << 1)
#define MPS2_IRQ_UART0_RX      0u
#define MPS2_IRQ_UART0_TX      1u
#define MPS2_IRQS              32u

/* CMSDK APB dual timer, timer 1 (free-running 32-bit down counter) */
#define MPS2_TIMER1_LOAD      CM4_REG(0x40002000u)
#define MPS2_TIMER1_VALUE     CM4_REG(0x40002004u)
#define MPS2_TIMER1_CTRL      CM4_REG(0x40002008u)
#define MPS2_TIMER_CTRL_EN    (1u << 7)
#define MPS2_TIMER_CTRL_32BIT (1u << 1)

/* CMSDK APB watchdog */
#define MPS2_WDOG_LOAD   CM4_REG(0x40008000u)
#define MPS2_WDOG_CTRL   CM4_REG(0x40008008u)
#define MPS2_WDOG_INTCLR CM4_REG(0x4000800Cu)
#define MPS2_WDOG_LOCK   CM4_REG(0x40008C00u)
#define MPS2_WDOG_UNLOCK 0x1ACCE551u

/* "Flash" (RAM of the code region, managed with NOR rules) */
#define MPS2_FLASH_BASE  0x00010000u
#define MPS2_FLASH_SIZE  (512u * 1024u)
#define MPS2_FLASH_PAGE  4096u
#define MPS2_FLASH_WRITE 8u
#define MPS2_APP_LOAD    (MPS2_FLASH_BASE + 512u)

/* Control tick of the application image (Hz). */
#ifndef MPS2_TICK_HZ
#define MPS2_TICK_HZ 5000u
#endif

/* Board set-up shared by both images: UART0 (interrupt driven rings),
 * SysTick time base at tick_hz calling hook (may be NULL) from its
 * interrupt, watchdog. */
void mps2_board_init(uint32_t tick_hz, void (*hook)(void));
/* Install (or remove: NULL) the function the SysTick interrupt calls. */
void mps2_set_tick_hook(void (*hook)(void));
/* SysTick periods that started while the previous hook was still running. */
uint32_t mps2_tick_overruns(void);
/* Ticks since mps2_board_init. */
uint32_t mps2_ticks(void);

/* Benchmarks: stop SysTick; time then advances one tick period per
 * mps2_clock_advance() (no interrupts disturb a measurement). */
void mps2_clock_manual(void);
void mps2_clock_advance(void);

/* Free-running 32-bit down counter at the system clock (dual timer 1). */
void mps2_counter_start(void);
static inline uint32_t mps2_counter(void)
{
    return MPS2_TIMER1_VALUE;
}

/* The boot request word (linker script symbol: last word of SSRAM2/3). */
extern volatile uint32_t mps2_boot_request_word;

#endif /* MPS2_H */
