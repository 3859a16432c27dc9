/*
 * hal_stm32f4.c - HAL of the STM32F405/407 drive (wiring in stm32f4.h).
 *
 * Contexts: SysTick runs the tick hook (control tick); USART2 and CAN1 RX0
 * interrupts fill / empty byte and frame rings (single producer, single
 * consumer, volatile indices); the rest is main context.
 *
 * Axis encoders: the timers count in hardware (encoder mode 3, x4) and the
 * drive reads them as counters (drive_config_t.enc_counter, set by
 * app_stm32f4.c): hal_encoder_counter(0..2) returns a 32-bit count (TIM2
 * as is; TIM3/TIM4 16-bit counts extended by their signed 16-bit change
 * since the previous read, which holds while the axis moves less than
 * 32767 counts between two reads: one read per control tick, e.g. 3.2e8
 * counts/s at 10 kHz). Channel 3 is axis 0's reference scale (TIM5,
 * 32-bit). Called from the tick, and from main before the tick hook runs
 * (drive_init).
 */
#include <stddef.h>

#include "hal.h"
#include "port.h"
#include "port_counter.h"
#include "port_ring.h"
#include "stm32f4.h"

#define AXES     3u
#define PWM_HZ   20000u /* centre-aligned: ARR = f_tim / 2 / PWM_HZ */
#define MV_FULL  10000  /* +-10 V at 0 / 100 % duty */
#define RX_RING  1024u
#define TX_RING  2048u
#define CAN_RING 32u

static const uint32_t enc_tim[AXES] = {F4_TIM2, F4_TIM3, F4_TIM4};
static const uint8_t enc_bits[AXES] = {32u, 16u, 16u};

typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t data[8];
} can_frame_t;

static uint8_t rx_buf[RX_RING], tx_buf[TX_RING];

static struct {
    port_ring_t rx; /* producer: USART2 ISR, consumer: main */
    port_ring_t tx; /* producer: main, consumer: USART2 ISR */
    uint32_t overruns;
    uint32_t rx_dropped;
} uart = {PORT_RING_INIT(rx_buf), PORT_RING_INIT(tx_buf), 0u, 0u};

static struct {
    can_frame_t q[CAN_RING];
    volatile uint32_t head, tail;
    uint32_t dropped;
} canrx;

/* The clock tree actually running (clocks()): the PLL from HSE, or HSI
 * when the crystal or the PLL did not start (hse_ok false). Written once at
 * bring-up, before any interrupt is enabled. */
static struct {
    uint32_t sysclk_hz, apb1_hz, tim1_hz;
    bool hse_ok;
    bool can_ok;
    uint32_t pwm_arr;
} clk;

static struct {
    uint32_t load, period_us;
    volatile uint32_t ticks;
    void (*hook)(void);
} tb;

static port_counter_t enc[AXES]; /* the axis timers, extended to 32 bits */

/* ---- time base ----------------------------------------------------------------- */

void f4_systick_handler(void);
void f4_systick_handler(void)
{
    tb.ticks++;
    if (tb.hook != NULL) {
        tb.hook();
    }
}

void f4_set_tick_hook(void (*hook)(void))
{
    tb.hook = hook;
}

uint32_t hal_time_us(void)
{
    return cm4_systick_time_us(&tb.ticks, tb.load, tb.period_us, clk.sysclk_hz / 1000000u);
}

/* ---- encoders -------------------------------------------------------------------- */

bool hal_encoder_counter(unsigned ch, uint32_t *count)
{
    if (count == NULL) {
        return false;
    }
    if (ch < AXES) {
        *count = port_counter_update(&enc[ch], F4_TIM_CNT(enc_tim[ch]));
        return true;
    }
    if (ch == AXES) { /* axis 0's reference scale */
        *count = F4_TIM_CNT(F4_TIM5);
        return true;
    }
    return false;
}

bool hal_encoder_mean(unsigned axis, int64_t *lag_q16)
{
    (void)axis;
    (void)lag_q16;
    return false; /* the timers are read once per tick: enc_mean refused */
}

/* ---- motor outputs and lines -------------------------------------------------------- */

static bool motor_on[AXES];

void hal_motor_set_mv(unsigned axis, int32_t mv)
{
    int64_t duty;

    if (axis >= AXES) {
        return;
    }
    if (!motor_on[axis]) {
        mv = 0;
    }
    if (mv > MV_FULL) {
        mv = MV_FULL;
    } else if (mv < -MV_FULL) {
        mv = -MV_FULL;
    }
    duty = ((int64_t)(mv + MV_FULL) * clk.pwm_arr + MV_FULL) / (2 * MV_FULL);
    F4_TIM_CCR(F4_TIM1, axis + 1u) = (uint32_t)duty;
}

void hal_motor_enable(unsigned axis, bool on)
{
    if (axis >= AXES) {
        return;
    }
    motor_on[axis] = on;
    if (!on) {
        F4_TIM_CCR(F4_TIM1, axis + 1u) = clk.pwm_arr / 2u;
    }
    F4_GPIO_BSRR(F4_GPIO(F4_PE)) = on ? (1u << axis) : (1u << (axis + 16u));
}

/* A board running on HSI (crystal or PLL failed) reports an amplifier
 * fault on every axis: the drive then refuses to enable, and a fault reset
 * is refused while the cause persists. The loops must not run on a time
 * base that is 1 % off (HSI) and unverified. */
bool hal_amp_fault(unsigned axis)
{
    if (axis >= AXES) {
        return false;
    }
    return !clk.hse_ok || !(F4_GPIO_IDR(F4_GPIO(F4_PE)) & (1u << (axis + 3u)));
}

/* Home switches on PE6..PE8, active low (stm32f4.h). */
bool hal_home_switch(unsigned axis)
{
    if (axis >= AXES) {
        return false;
    }
    return !(F4_GPIO_IDR(F4_GPIO(F4_PE)) & (1u << (axis + 6u)));
}

void hal_motor_set_mv_all(const int32_t *mv, unsigned n)
{
    hal_generic_set_mv_all(mv, n < AXES ? n : AXES);
}

uint32_t hal_amp_fault_mask(unsigned n)
{
    uint32_t m;

    if (n > AXES) {
        n = AXES;
    }
    m = (1u << n) - 1u;
    if (!clk.hse_ok) {
        return m;
    }
    return ~(F4_GPIO_IDR(F4_GPIO(F4_PE)) >> 3u) & m; /* fault inputs active low, PE3.. */
}

bool f4_clock_ok(void)
{
    return clk.hse_ok;
}

/* ---- USART2 ----------------------------------------------------------------------------- */

void f4_usart2_handler(void);
void f4_usart2_handler(void)
{
    uint32_t sr = F4_USART_SR(F4_USART2);

    if (sr & (F4_USART_SR_RXNE | F4_USART_SR_ORE)) {
        uint8_t c = (uint8_t)F4_USART_DR(F4_USART2); /* also clears ORE */

        if (sr & F4_USART_SR_ORE) {
            uart.overruns++;
        }
        if (!port_ring_put(&uart.rx, c)) {
            uart.rx_dropped++;
        }
    }
    if ((sr & F4_USART_SR_TXE) && (F4_USART_CR1(F4_USART2) & F4_USART_CR1_TXEIE)) {
        uint8_t c;

        if (port_ring_get(&uart.tx, &c)) {
            F4_USART_DR(F4_USART2) = c;
        } else {
            F4_USART_CR1(F4_USART2) &= ~F4_USART_CR1_TXEIE;
        }
    }
}

size_t hal_uart_write(const uint8_t *data, size_t len)
{
    size_t n;
    uint32_t pm;

    if (data == NULL) {
        return 0;
    }
    n = port_ring_write(&uart.tx, data, len);
    pm = cm4_irq_save();
    F4_USART_CR1(F4_USART2) |= F4_USART_CR1_TXEIE;
    cm4_irq_restore(pm);
    return n;
}

/* Top up the transmitter from main context while its data register is
 * empty (at most two bytes on the real USART, whose TXE interrupt sends the
 * rest; everything on a USART model without a TXE interrupt, such as
 * QEMU's). The USART interrupt is masked: the ring's consumer is the ISR. */
static void uart_tx_service(void)
{
    uint32_t pm = cm4_irq_save();
    uint8_t c;

    while ((F4_USART_SR(F4_USART2) & F4_USART_SR_TXE) && port_ring_get(&uart.tx, &c)) {
        F4_USART_DR(F4_USART2) = c;
    }
    cm4_irq_restore(pm);
}

size_t hal_uart_read(uint8_t *data, size_t cap)
{
    uart_tx_service();
    return data == NULL ? 0 : port_ring_read(&uart.rx, data, cap);
}

bool hal_uart_tx_idle(void)
{
    return port_ring_empty(&uart.tx) && (F4_USART_SR(F4_USART2) & F4_USART_SR_TC);
}

/* ---- CAN1 -------------------------------------------------------------------------------- */

void f4_can1_rx0_handler(void);
void f4_can1_rx0_handler(void)
{
    while (F4_CAN_RF0R & 3u) {
        uint32_t rir = F4_CAN_RI0R, h = canrx.head;

        if (!(rir & (1u << 1)) && h - canrx.tail < CAN_RING) { /* data frames (RTR 0) */
            can_frame_t *f = &canrx.q[h % CAN_RING];
            uint32_t lo = F4_CAN_RDL0R, hi = F4_CAN_RDH0R;
            unsigned i;

            /* IDE: EXID in bits 3..31, else STID in 21..31 */
            f->id = (rir & (1u << 2)) ? (HAL_CAN_EFF | (rir >> 3)) : (rir >> 21);
            f->len = (uint8_t)(F4_CAN_RDT0R & 0xFu);
            if (f->len > 8u) {
                f->len = 8u;
            }
            for (i = 0; i < 4u; i++) {
                f->data[i] = (uint8_t)(lo >> (8u * i));
                f->data[4u + i] = (uint8_t)(hi >> (8u * i));
            }
            canrx.head = h + 1u;
        } else if (!(rir & (1u << 1))) {
            canrx.dropped++;
        }
        F4_CAN_RF0R = 1u << 5; /* RFOM0: release the mailbox */
    }
}

bool hal_can_send(uint32_t id, const uint8_t *data, uint8_t len)
{
    uint32_t tsr, lo = 0, hi = 0;
    unsigned m, i;

    if (!clk.can_ok) {
        return false;
    }
    tsr = F4_CAN_TSR;

    if (((id & HAL_CAN_EFF) ? (id & ~HAL_CAN_EFF) > 0x1FFFFFFFu : id > 0x7FFu) || len > 8u ||
        (len > 0u && data == NULL)) {
        return false;
    }
    if (!(tsr & (7u << 26))) {
        return false; /* all three mailboxes busy */
    }
    m = (tsr >> 24) & 3u; /* CODE: next free mailbox */
    for (i = 0; i < len; i++) {
        if (i < 4u) {
            lo |= (uint32_t)data[i] << (8u * i);
        } else {
            hi |= (uint32_t)data[i] << (8u * (i - 4u));
        }
    }
    F4_CAN_TDTR(m) = len;
    F4_CAN_TDLR(m) = lo;
    F4_CAN_TDHR(m) = hi;
    /* extended: EXID in 3..31 and IDE; standard: STID in 21..31; TXRQ */
    F4_CAN_TIR(m) = ((id & HAL_CAN_EFF) ? ((id << 3) | (1u << 2)) : (id << 21)) | 1u;
    return true;
}

bool hal_can_receive(uint32_t *id, uint8_t *data, uint8_t *len)
{
    const can_frame_t *f;
    unsigned i;

    if (id == NULL || data == NULL || len == NULL || canrx.tail == canrx.head) {
        return false;
    }
    f = &canrx.q[canrx.tail % CAN_RING];
    *id = f->id;
    *len = f->len;
    for (i = 0; i < f->len; i++) {
        data[i] = f->data[i];
    }
    canrx.tail++;
    return true;
}

/* ---- flash: sectors 5..11 (app slot 5..9, store 10..11) ---------------------------------- */

static const hal_flash_layout_t flash_layout = {F4_FLASH_REGION_BASE, F4_FLASH_REGION_SIZE,
                                                F4_FLASH_SECTOR_SIZE, 4u};

const hal_flash_layout_t *hal_flash_layout(void)
{
    return &flash_layout;
}

static bool flash_wait(void)
{
    uint32_t sr;

    while (F4_FLASH_SR & F4_FLASH_SR_BSY) {
    }
    sr = F4_FLASH_SR;
    F4_FLASH_SR = sr & F4_FLASH_SR_ERRORS; /* write 1 to clear */
    return (sr & F4_FLASH_SR_ERRORS) == 0u;
}

static void flash_unlock(void)
{
    if (F4_FLASH_CR & F4_FLASH_CR_LOCK) {
        F4_FLASH_KEYR = F4_FLASH_KEY1;
        F4_FLASH_KEYR = F4_FLASH_KEY2;
    }
}

bool hal_flash_erase_page(uint32_t addr)
{
    bool ok;

    if (!cm4_flash_in_region(addr, 1u)) {
        return false;
    }
    flash_unlock();
    (void)flash_wait();
    hal_watchdog_kick(); /* the erase (up to 2 s) stalls the CPU; IWDG ~4 s */
    F4_FLASH_CR = F4_FLASH_CR_PSIZE32 | F4_FLASH_CR_SER |
                  F4_FLASH_CR_SNB(F4_FLASH_FIRST_SECTOR +
                                  (addr - F4_FLASH_REGION_BASE) / F4_FLASH_SECTOR_SIZE);
    F4_FLASH_CR |= F4_FLASH_CR_STRT;
    ok = flash_wait();
    F4_FLASH_CR = F4_FLASH_CR_LOCK;
    hal_watchdog_kick();
    return ok;
}

bool hal_flash_write(uint32_t addr, const uint8_t *data, size_t len)
{
    volatile uint32_t *p = (volatile uint32_t *)(uintptr_t)addr;
    bool ok = true;
    size_t i;

    if (data == NULL || !cm4_flash_in_region(addr, len) || addr % 4u != 0u || len % 4u != 0u) {
        return false;
    }
    for (i = 0; i < len / 4u; i++) {
        if (p[i] != 0xFFFFFFFFu) {
            return false; /* only erased words may be programmed */
        }
    }
    flash_unlock();
    (void)flash_wait();
    F4_FLASH_CR = F4_FLASH_CR_PSIZE32 | F4_FLASH_CR_PG;
    for (i = 0; i < len / 4u && ok; i++) {
        p[i] = (uint32_t)data[4u * i] | ((uint32_t)data[4u * i + 1u] << 8) |
               ((uint32_t)data[4u * i + 2u] << 16) | ((uint32_t)data[4u * i + 3u] << 24);
        ok = flash_wait();
    }
    F4_FLASH_CR = F4_FLASH_CR_LOCK;
    return ok;
}

/* hal_flash_read: memory-mapped, common/cm4_hal.c */

/* ---- system ---------------------------------------------------------------------------------- */

void hal_watchdog_start(void)
{
    F4_IWDG_KR = 0xCCCCu; /* start (LSI ~32 kHz) */
    F4_IWDG_KR = 0x5555u; /* unlock PR / RLR */
    F4_IWDG_PR = 4u;      /* /64: 500 Hz (LSI 17..47 kHz: 266..734 Hz) */
    F4_IWDG_RLR = 2000u;  /* ~4 s, at least 2.7 s: longer than a sector erase */
    F4_IWDG_KR = 0xAAAAu;
}

void hal_watchdog_kick(void)
{
    F4_IWDG_KR = 0xAAAAu;
}

/* hal_system_reset: common/cm4_hal.c */

/* ---- bring-up ------------------------------------------------------------------------------ */

/* Poll until (reg & mask) == want, at most F4_CLOCK_POLLS reads (about
 * 20 ms on HSI; HSE starts in 2 ms, the PLL locks in 0.1 ms). */
static bool wait_bits(volatile uint32_t *reg, uint32_t mask, uint32_t want)
{
    uint32_t n;

    for (n = 0; n < F4_CLOCK_POLLS; n++) {
        if ((*reg & mask) == want) {
            return true;
        }
    }
    return false;
}

/* 168 MHz from the 8 MHz crystal; on any timeout the board stays on HSI
 * 16 MHz (APB1 = APB2 = 16 MHz) with hse_ok false, and every peripheral is
 * set up for the clock that runs. */
static void clocks(void)
{
    clk.hse_ok = false;
    clk.sysclk_hz = F4_HSI_HZ;
    clk.apb1_hz = F4_HSI_HZ;
    clk.tim1_hz = F4_HSI_HZ;
    F4_RCC_CR |= 1u << 16; /* HSEON */
    if (!wait_bits(&F4_RCC_CR, 1u << 17, 1u << 17)) {
        F4_RCC_CR &= ~(1u << 16);
        return;
    }
    /* PLL: M 8, N 336, P 2 (168 MHz), Q 7 (48 MHz), source HSE */
    F4_RCC_PLLCFGR = 8u | (336u << 6) | (0u << 16) | (1u << 22) | (7u << 24);
    F4_RCC_CR |= 1u << 24; /* PLLON */
    if (!wait_bits(&F4_RCC_CR, 1u << 25, 1u << 25)) {
        F4_RCC_CR &= ~((1u << 24) | (1u << 16));
        return;
    }
    F4_FLASH_ACR = 5u | (1u << 8) | (1u << 9) | (1u << 10); /* 5 WS, prefetch, I/D cache */
    F4_RCC_CFGR = (5u << 10) | (4u << 13) | 2u;             /* APB1 /4, APB2 /2, SYSCLK = PLL */
    if (!wait_bits(&F4_RCC_CFGR, 3u << 2, 2u << 2)) {
        F4_RCC_CFGR = 0u; /* back to HSI, no prescalers */
        (void)wait_bits(&F4_RCC_CFGR, 3u << 2, 0u);
        F4_RCC_CR &= ~((1u << 24) | (1u << 16));
        return;
    }
    clk.hse_ok = true;
    clk.sysclk_hz = F4_SYSCLK_HZ;
    clk.apb1_hz = F4_APB1_HZ;
    clk.tim1_hz = 2u * F4_APB2_HZ; /* APB2 prescaler > 1: timers run at 2 x APB2 */
}

/* pin n of port g: mode (0 in, 1 out, 2 AF), alternate function, pull (1 up) */
static void pin(unsigned g, unsigned n, unsigned mode, unsigned af, unsigned pull)
{
    uint32_t b = F4_GPIO(g);

    F4_GPIO_MODER(b) = (F4_GPIO_MODER(b) & ~(3u << (2u * n))) | (mode << (2u * n));
    F4_GPIO_PUPDR(b) = (F4_GPIO_PUPDR(b) & ~(3u << (2u * n))) | (pull << (2u * n));
    F4_GPIO_OSPEEDR(b) |= 2u << (2u * n);
    F4_GPIO_AFR(b, n / 8u) =
        (F4_GPIO_AFR(b, n / 8u) & ~(15u << (4u * (n % 8u)))) | (af << (4u * (n % 8u)));
}

static void encoder_timer(uint32_t t, uint32_t arr)
{
    F4_TIM_CR1(t) = 0u;
    F4_TIM_SMCR(t) = 3u;                                       /* encoder mode 3: x4 */
    F4_TIM_CCMR1(t) = 1u | (1u << 8) | (6u << 4) | (6u << 12); /* TI1, TI2, filter */
    F4_TIM_CCER(t) = 0u;                                       /* both rising (non-inverted) */
    F4_TIM_ARR(t) = arr;
    F4_TIM_CNT(t) = 0u;
    F4_TIM_CR1(t) = 1u; /* CEN */
}

static void peripherals(void)
{
    unsigned i;

    F4_RCC_AHB1ENR |= (1u << F4_PA) | (1u << F4_PB) | (1u << F4_PE);
    F4_RCC_APB1ENR |= 0xFu | (1u << 17) | (1u << 25); /* TIM2..5, USART2, CAN1 */
    F4_RCC_APB2ENR |= 1u;                             /* TIM1 */
    (void)F4_RCC_APB2ENR;

    /* encoders */
    pin(F4_PA, 15u, 2u, 1u, 1u);
    pin(F4_PB, 3u, 2u, 1u, 1u);
    pin(F4_PA, 6u, 2u, 2u, 1u);
    pin(F4_PA, 7u, 2u, 2u, 1u);
    pin(F4_PB, 6u, 2u, 2u, 1u);
    pin(F4_PB, 7u, 2u, 2u, 1u);
    pin(F4_PA, 0u, 2u, 2u, 1u);
    pin(F4_PA, 1u, 2u, 2u, 1u);
    encoder_timer(F4_TIM2, 0xFFFFFFFFu);
    encoder_timer(F4_TIM3, 0xFFFFu);
    encoder_timer(F4_TIM4, 0xFFFFu);
    encoder_timer(F4_TIM5, 0xFFFFFFFFu);
    for (i = 0; i < AXES; i++) {
        port_counter_init(&enc[i], F4_TIM_CNT(enc_tim[i]), enc_bits[i]);
    }

    /* PWM: TIM1 CH1..3, centre-aligned, 50 % */
    for (i = 0; i < AXES; i++) {
        pin(F4_PA, 8u + i, 2u, 1u, 0u);
        pin(F4_PE, i, 1u, 0u, 0u);      /* enable line, low */
        pin(F4_PE, 3u + i, 0u, 0u, 1u); /* fault input, pull-up */
        pin(F4_PE, 6u + i, 0u, 0u, 1u); /* home switch, pull-up */
        F4_GPIO_BSRR(F4_GPIO(F4_PE)) = 1u << (i + 16u);
    }
    F4_TIM_CR1(F4_TIM1) = 1u << 5; /* CMS = 01 */
    F4_TIM_PSC(F4_TIM1) = 0u;
    F4_TIM_ARR(F4_TIM1) = clk.pwm_arr;
    F4_TIM_CCMR1(F4_TIM1) = (6u << 4) | (1u << 3) | (6u << 12) | (1u << 11); /* PWM1, preload */
    F4_TIM_CCMR2(F4_TIM1) = (6u << 4) | (1u << 3);
    for (i = 0; i < AXES; i++) {
        F4_TIM_CCR(F4_TIM1, i + 1u) = clk.pwm_arr / 2u;
    }
    F4_TIM_CCER(F4_TIM1) = 1u | (1u << 4) | (1u << 8);
    F4_TIM_BDTR(F4_TIM1) = 1u << 15; /* MOE */
    F4_TIM_EGR(F4_TIM1) = 1u;
    F4_TIM_CR1(F4_TIM1) |= 1u;

    /* USART2 115200 8N1 */
    pin(F4_PA, 2u, 2u, 7u, 0u);
    pin(F4_PA, 3u, 2u, 7u, 1u);
    F4_USART_BRR(F4_USART2) = (clk.apb1_hz + 115200u / 2u) / 115200u;
    F4_USART_CR1(F4_USART2) =
        F4_USART_CR1_UE | F4_USART_CR1_TE | F4_USART_CR1_RE | F4_USART_CR1_RXNEIE;
    cm4_nvic_enable(F4_IRQ_USART2, 0x40u);

    /* CAN1 500 kbit/s, SJW 1: 42 MHz / 6 = 7 MHz, 1 + 11 + 2 tq (sample
     * point 86 %); on HSI 16 MHz / 2 = 8 MHz, 1 + 13 + 2 tq (88 %). A
     * controller that does not acknowledge init leaves CAN off (can_ok). */
    pin(F4_PB, 8u, 2u, 9u, 1u);
    pin(F4_PB, 9u, 2u, 9u, 0u);
    clk.can_ok = false;
    F4_CAN_MCR = 1u; /* INRQ */
    if (!wait_bits(&F4_CAN_MSR, 1u, 1u)) {
        return;
    }
    F4_CAN_BTR = clk.hse_ok ? (0u << 24) | (1u << 20) | (10u << 16) | 5u
                            : (0u << 24) | (1u << 20) | (12u << 16) | 1u;
    F4_CAN_FMR = 1u;  /* FINIT */
    F4_CAN_FM1R = 0u; /* mask mode */
    F4_CAN_FS1R = 1u; /* bank 0: 32 bit */
    F4_CAN_FFA1R = 0u;
    F4_CAN_F0R1 = 0u; /* accept everything */
    F4_CAN_F0R2 = 0u;
    F4_CAN_FA1R = 1u;
    F4_CAN_FMR = 0u;
    F4_CAN_MCR = (1u << 6) | (1u << 2); /* ABOM, TXFP; leave init */
    if (!wait_bits(&F4_CAN_MSR, 1u, 0u)) {
        return;
    }
    clk.can_ok = true;
    F4_CAN_IER = 1u << 1; /* FMPIE0 */
    cm4_nvic_enable(F4_IRQ_CAN1_RX0, 0x40u);
}

void f4_board_init(uint32_t tick_hz, void (*hook)(void))
{
    clocks();
    clk.pwm_arr = clk.tim1_hz / PWM_HZ / 2u; /* 4200 at 168 MHz */
    peripherals();
    if (!clk.hse_ok && tick_hz > F4_HSI_TICK_HZ_MAX) {
        /* 16 MHz cannot carry a 10 kHz tick (about 1600 cycles each), and
         * the axes are held off (hal_amp_fault): keep the time base, the
         * encoder counts and the links at a tick the CPU can afford */
        tick_hz = F4_HSI_TICK_HZ_MAX;
    }
    tb.period_us = 1000000u / tick_hz;
    tb.load = clk.sysclk_hz / tick_hz - 1u;
    tb.ticks = 0;
    tb.hook = hook;
    CM4_SCB_SHPR3 = (CM4_SCB_SHPR3 & 0x00FFFFFFu) | (0x80u << 24);
    CM4_SYST_RVR = tb.load;
    CM4_SYST_CVR = 0u;
    CM4_SYST_CSR = CM4_SYST_CSR_ENABLE | CM4_SYST_CSR_TICKINT | CM4_SYST_CSR_CLKSOURCE;
    cm4_irq_enable();
}
