/*
 * stm32f4.h - the STM32F405/407 registers this port uses, written here from
 * the reference manual's register maps (RM0090); minimal, no vendor headers.
 *
 * Board wiring assumed by hal_stm32f4.c (one place to change for a PCB):
 *   HSE 8 MHz crystal -> PLL 168 MHz SYSCLK, APB1 42 MHz (timers 84 MHz),
 *   APB2 84 MHz (timers 168 MHz), flash 5 wait states.
 *   axis encoders   TIM2 (32 bit) PA15/PB3, TIM3 PA6/PA7, TIM4 PB6/PB7
 *                   (16 bit), encoder mode 3 (x4), input filter f/8 N=6
 *   reference scale TIM5 (32 bit) PA0/PA1 (channel 3 = axis 0's scale)
 *   motor commands  TIM1 CH1..CH3 PA8/PA9/PA10, 20 kHz centre-aligned PWM,
 *                   50 % = 0 V; the analogue stage maps 0..100 % to -10..+10 V
 *   enable lines    PE0..PE2 (push-pull, high = enabled)
 *   fault inputs    PE3..PE5 (pull-up, low = amplifier fault)
 *   home switches   PE6..PE8 (pull-up, low = on the switch: a switch
 *                   closing to ground; hal_home_switch)
 *   host UART       USART2 PA2/PA3, 115200 8N1, interrupt driven rings
 *   CAN             CAN1 PB8/PB9, 500 kbit/s, RX FIFO 0 interrupt into a ring
 *   watchdog        IWDG, ~4 s (application only; a 128 KiB sector erase,
 *                   up to 2 s, stalls the CPU: single-bank flash)
 * Flash (1 MiB): sectors 0..4 (16/16/16/16/64 KiB) bootloader, sectors
 * 5..11 (128 KiB each) the HAL region: application slot sectors 5..9
 * (640 KiB, header 0x08020000, payload 0x08020200), compensation store
 * sectors 10 and 11 (comp_store.h: its two banks, comp_store_bytes()).
 */
#ifndef STM32F4_H
#define STM32F4_H

#include <stdint.h>

#include "cm4.h"

#define F4_HSE_HZ          8000000u
#define F4_SYSCLK_HZ       168000000u
#define F4_APB1_HZ         42000000u
#define F4_APB2_HZ         84000000u
#define F4_HSI_HZ          16000000u /* the fallback when HSE or the PLL fails */
#define F4_CLOCK_POLLS     100000u   /* bounded waits on clock and CAN ready bits */
#define F4_HSI_TICK_HZ_MAX 250u      /* SysTick rate cap on the HSI fallback */

/* RCC */
#define F4_RCC         0x40023800u
#define F4_RCC_CR      CM4_REG(F4_RCC + 0x00u)
#define F4_RCC_PLLCFGR CM4_REG(F4_RCC + 0x04u)
#define F4_RCC_CFGR    CM4_REG(F4_RCC + 0x08u)
#define F4_RCC_AHB1ENR CM4_REG(F4_RCC + 0x30u)
#define F4_RCC_APB1ENR CM4_REG(F4_RCC + 0x40u)
#define F4_RCC_APB2ENR CM4_REG(F4_RCC + 0x44u)
#define F4_RCC_CSR     CM4_REG(F4_RCC + 0x74u)

/* FLASH interface */
#define F4_FLASH_ACR        CM4_REG(0x40023C00u)
#define F4_FLASH_KEYR       CM4_REG(0x40023C04u)
#define F4_FLASH_SR         CM4_REG(0x40023C0Cu)
#define F4_FLASH_CR         CM4_REG(0x40023C10u)
#define F4_FLASH_KEY1       0x45670123u
#define F4_FLASH_KEY2       0xCDEF89ABu
#define F4_FLASH_CR_PG      (1u << 0)
#define F4_FLASH_CR_SER     (1u << 1)
#define F4_FLASH_CR_SNB(n)  ((uint32_t)(n) << 3)
#define F4_FLASH_CR_PSIZE32 (2u << 8)
#define F4_FLASH_CR_STRT    (1u << 16)
#define F4_FLASH_CR_LOCK    (1u << 31)
#define F4_FLASH_SR_BSY     (1u << 16)
#define F4_FLASH_SR_ERRORS  0xF2u /* OPERR WRPERR PGAERR PGPERR PGSERR */

/* GPIO ports A..E: base 0x40020000 + 0x400 * n */
#define F4_GPIO(n)         (0x40020000u + 0x400u * (n))
#define F4_GPIO_MODER(g)   CM4_REG((g) + 0x00u)
#define F4_GPIO_OSPEEDR(g) CM4_REG((g) + 0x08u)
#define F4_GPIO_PUPDR(g)   CM4_REG((g) + 0x0Cu)
#define F4_GPIO_IDR(g)     CM4_REG((g) + 0x10u)
#define F4_GPIO_BSRR(g)    CM4_REG((g) + 0x18u)
#define F4_GPIO_AFR(g, i)  CM4_REG((g) + 0x20u + 4u * (i))
#define F4_PA              0u
#define F4_PB              1u
#define F4_PE              4u

/* General-purpose / advanced timers */
#define F4_TIM1          0x40010000u
#define F4_TIM2          0x40000000u
#define F4_TIM3          0x40000400u
#define F4_TIM4          0x40000800u
#define F4_TIM5          0x40000C00u
#define F4_TIM_CR1(t)    CM4_REG((t) + 0x00u)
#define F4_TIM_SMCR(t)   CM4_REG((t) + 0x08u)
#define F4_TIM_EGR(t)    CM4_REG((t) + 0x14u)
#define F4_TIM_CCMR1(t)  CM4_REG((t) + 0x18u)
#define F4_TIM_CCMR2(t)  CM4_REG((t) + 0x1Cu)
#define F4_TIM_CCER(t)   CM4_REG((t) + 0x20u)
#define F4_TIM_CNT(t)    CM4_REG((t) + 0x24u)
#define F4_TIM_PSC(t)    CM4_REG((t) + 0x28u)
#define F4_TIM_ARR(t)    CM4_REG((t) + 0x2Cu)
#define F4_TIM_CCR(t, n) CM4_REG((t) + 0x30u + 4u * (n)) /* n = 1..4 */
#define F4_TIM_BDTR(t)   CM4_REG((t) + 0x44u)

/* USART2 */
#define F4_USART2           0x40004400u
#define F4_USART_SR(u)      CM4_REG((u) + 0x00u)
#define F4_USART_DR(u)      CM4_REG((u) + 0x04u)
#define F4_USART_BRR(u)     CM4_REG((u) + 0x08u)
#define F4_USART_CR1(u)     CM4_REG((u) + 0x0Cu)
#define F4_USART_SR_ORE     (1u << 3)
#define F4_USART_SR_RXNE    (1u << 5)
#define F4_USART_SR_TC      (1u << 6)
#define F4_USART_SR_TXE     (1u << 7)
#define F4_USART_CR1_RE     (1u << 2)
#define F4_USART_CR1_TE     (1u << 3)
#define F4_USART_CR1_RXNEIE (1u << 5)
#define F4_USART_CR1_TXEIE  (1u << 7)
#define F4_USART_CR1_UE     (1u << 13)

/* bxCAN 1 */
#define F4_CAN1        0x40006400u
#define F4_CAN_MCR     CM4_REG(F4_CAN1 + 0x000u)
#define F4_CAN_MSR     CM4_REG(F4_CAN1 + 0x004u)
#define F4_CAN_TSR     CM4_REG(F4_CAN1 + 0x008u)
#define F4_CAN_RF0R    CM4_REG(F4_CAN1 + 0x00Cu)
#define F4_CAN_IER     CM4_REG(F4_CAN1 + 0x014u)
#define F4_CAN_BTR     CM4_REG(F4_CAN1 + 0x01Cu)
#define F4_CAN_TIR(m)  CM4_REG(F4_CAN1 + 0x180u + 0x10u * (m))
#define F4_CAN_TDTR(m) CM4_REG(F4_CAN1 + 0x184u + 0x10u * (m))
#define F4_CAN_TDLR(m) CM4_REG(F4_CAN1 + 0x188u + 0x10u * (m))
#define F4_CAN_TDHR(m) CM4_REG(F4_CAN1 + 0x18Cu + 0x10u * (m))
#define F4_CAN_RI0R    CM4_REG(F4_CAN1 + 0x1B0u)
#define F4_CAN_RDT0R   CM4_REG(F4_CAN1 + 0x1B4u)
#define F4_CAN_RDL0R   CM4_REG(F4_CAN1 + 0x1B8u)
#define F4_CAN_RDH0R   CM4_REG(F4_CAN1 + 0x1BCu)
#define F4_CAN_FMR     CM4_REG(F4_CAN1 + 0x200u)
#define F4_CAN_FM1R    CM4_REG(F4_CAN1 + 0x204u)
#define F4_CAN_FS1R    CM4_REG(F4_CAN1 + 0x20Cu)
#define F4_CAN_FFA1R   CM4_REG(F4_CAN1 + 0x214u)
#define F4_CAN_FA1R    CM4_REG(F4_CAN1 + 0x21Cu)
#define F4_CAN_F0R1    CM4_REG(F4_CAN1 + 0x240u)
#define F4_CAN_F0R2    CM4_REG(F4_CAN1 + 0x244u)

/* IWDG */
#define F4_IWDG_KR  CM4_REG(0x40003000u)
#define F4_IWDG_PR  CM4_REG(0x40003004u)
#define F4_IWDG_RLR CM4_REG(0x40003008u)

/* Interrupt numbers */
#define F4_IRQ_CAN1_RX0 20u
#define F4_IRQ_USART2   38u
#define F4_IRQS         82u

/* HAL flash region */
#define F4_FLASH_REGION_BASE  0x08020000u
#define F4_FLASH_REGION_SIZE  (7u * 131072u)
#define F4_FLASH_SECTOR_SIZE  131072u
#define F4_FLASH_FIRST_SECTOR 5u
#define F4_APP_LOAD           (F4_FLASH_REGION_BASE + 512u)
/* Application slot: sectors 5..9; the store (two sectors) above it. Both
 * images set boot_config_t.slot_size to this (boot_config_default keeps
 * only one sector free at the top). */
#define F4_APP_SLOT_SIZE (5u * F4_FLASH_SECTOR_SIZE)
#define F4_STORE_BASE    (F4_FLASH_REGION_BASE + F4_APP_SLOT_SIZE)

#ifndef F4_TICK_HZ
#define F4_TICK_HZ 10000u
#endif

/* Board bring-up: clocks, GPIO, UART, CAN, encoder timers, PWM (outputs at
 * 0 V, amplifiers disabled), SysTick at tick_hz calling hook (NULL: time
 * base only). The watchdog is started separately (hal_watchdog_start). */
void f4_board_init(uint32_t tick_hz, void (*hook)(void));
void f4_set_tick_hook(void (*hook)(void));
/* False when the board runs on HSI because the crystal or the PLL did not
 * start: every axis then reports an amplifier fault (hal_amp_fault). */
bool f4_clock_ok(void);

/* The boot request word (linker script: last word of SRAM). */
extern volatile uint32_t f4_boot_request_word;

#endif /* STM32F4_H */
