/*
 * hal_mps2.c - HAL of the QEMU mps2-an386 board: time base (SysTick), UART0
 * (interrupt-driven byte rings), flash (the code-region RAM with NOR rules),
 * watchdog, reset. Motors and encoders are the simulated axes (plant_mps2.c);
 * the board has no CAN controller.
 *
 * Contexts: the SysTick interrupt runs the tick hook (control tick); the
 * UART interrupts fill / empty the rings; everything else is main context.
 * Rings are single-producer / single-consumer with volatile indices.
 */
#include <stddef.h>

#include "hal.h"
#include "mps2.h"
#include "port.h"
#include "port_ring.h"

#define RX_RING 1024u /* power of two */
#define TX_RING 2048u

static uint8_t rx_buf[RX_RING], tx_buf[TX_RING];

static struct {
    port_ring_t rx;        /* producer: RX ISR, consumer: main */
    port_ring_t tx;        /* producer: main, consumer: TX ISR */
    volatile bool tx_busy; /* a byte is in the transmitter */
    uint32_t rx_dropped;
} uart = {PORT_RING_INIT(rx_buf), PORT_RING_INIT(tx_buf), false, 0u};

static struct {
    uint32_t load;      /* SysTick reload */
    uint32_t period_us; /* tick period */
    volatile uint32_t ticks;
    volatile uint32_t overruns;
    bool manual; /* benchmark: no SysTick, mps2_clock_advance() moves time */
    void (*hook)(void);
} tb;

/* ---- time base --------------------------------------------------------------- */

void mps2_systick_handler(void);
void mps2_systick_handler(void)
{
    tb.ticks++;
    if (tb.hook != NULL) {
        tb.hook();
        if (CM4_SCB_ICSR & CM4_ICSR_PENDSTSET) {
            tb.overruns++;
        }
    }
}

void mps2_set_tick_hook(void (*hook)(void))
{
    tb.hook = hook;
}

uint32_t mps2_tick_overruns(void)
{
    return tb.overruns;
}

void mps2_counter_start(void)
{
    MPS2_TIMER1_CTRL = 0u;
    MPS2_TIMER1_LOAD = 0xFFFFFFFFu;
    MPS2_TIMER1_CTRL = MPS2_TIMER_CTRL_EN | MPS2_TIMER_CTRL_32BIT; /* free-running, no prescale */
}

uint32_t mps2_ticks(void)
{
    return tb.ticks;
}

void mps2_clock_manual(void)
{
    CM4_SYST_CSR = 0u;
    CM4_SCB_ICSR = CM4_ICSR_PENDSTCLR;
    tb.manual = true;
}

void mps2_clock_advance(void)
{
    tb.ticks++;
}

uint32_t hal_time_us(void)
{
    if (tb.manual) {
        return tb.ticks * tb.period_us;
    }
    return cm4_systick_time_us(&tb.ticks, tb.load, tb.period_us, MPS2_SYSCLK_HZ / 1000000u);
}

/* ---- UART0 --------------------------------------------------------------------- */

void mps2_uart0_rx_handler(void);
void mps2_uart0_rx_handler(void)
{
    MPS2_UART_INT(MPS2_UART0) = MPS2_UART_INT_RX;
    while (MPS2_UART_STATE(MPS2_UART0) & MPS2_UART_STATE_RXFULL) {
        uint8_t c = (uint8_t)MPS2_UART_DATA(MPS2_UART0);

        if (!port_ring_put(&uart.rx, c)) {
            uart.rx_dropped++;
        }
    }
}

/* Start the next byte if there is one; called with the TX interrupt masked
 * (from its handler or with interrupts off). */
static void tx_next(void)
{
    uint8_t c;

    if (!(MPS2_UART_STATE(MPS2_UART0) & MPS2_UART_STATE_TXFULL) && port_ring_get(&uart.tx, &c)) {
        uart.tx_busy = true;
        MPS2_UART_DATA(MPS2_UART0) = c;
    } else if (port_ring_empty(&uart.tx)) {
        uart.tx_busy = false;
    }
}

void mps2_uart0_tx_handler(void);
void mps2_uart0_tx_handler(void)
{
    MPS2_UART_INT(MPS2_UART0) = MPS2_UART_INT_TX;
    tx_next();
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
    if (!uart.tx_busy) {
        tx_next();
    }
    cm4_irq_restore(pm);
    return n;
}

size_t hal_uart_read(uint8_t *data, size_t cap)
{
    return data == NULL ? 0 : port_ring_read(&uart.rx, data, cap);
}

bool hal_uart_tx_idle(void)
{
    return port_ring_empty(&uart.tx) && !uart.tx_busy &&
           !(MPS2_UART_STATE(MPS2_UART0) & MPS2_UART_STATE_TXFULL);
}

/* ---- CAN: none on this board ---------------------------------------------------- */

bool hal_can_send(uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)id;
    (void)data;
    (void)len;
    return false;
}

bool hal_can_receive(uint32_t *id, uint8_t *data, uint8_t *len)
{
    (void)id;
    (void)data;
    (void)len;
    return false;
}

/* ---- flash: RAM with NOR rules ----------------------------------------------------- */

static const hal_flash_layout_t flash_layout = {MPS2_FLASH_BASE, MPS2_FLASH_SIZE, MPS2_FLASH_PAGE,
                                                MPS2_FLASH_WRITE};

const hal_flash_layout_t *hal_flash_layout(void)
{
    return &flash_layout;
}

bool hal_flash_erase_page(uint32_t addr)
{
    volatile uint32_t *p;
    uint32_t i;

    if (!cm4_flash_in_region(addr, 1u)) {
        return false;
    }
    addr -= (addr - MPS2_FLASH_BASE) % MPS2_FLASH_PAGE;
    p = (volatile uint32_t *)(uintptr_t)addr;
    for (i = 0; i < MPS2_FLASH_PAGE / 4u; i++) {
        p[i] = 0xFFFFFFFFu;
    }
    return true;
}

bool hal_flash_write(uint32_t addr, const uint8_t *data, size_t len)
{
    volatile uint8_t *p = (volatile uint8_t *)(uintptr_t)addr;
    size_t i;

    if (data == NULL || !cm4_flash_in_region(addr, len) || addr % MPS2_FLASH_WRITE != 0u ||
        len % MPS2_FLASH_WRITE != 0u) {
        return false;
    }
    for (i = 0; i < len; i++) {
        if (p[i] != 0xFFu) {
            return false; /* only erased bytes may be programmed */
        }
    }
    for (i = 0; i < len; i++) {
        p[i] = data[i];
    }
    return true;
}

/* hal_flash_read: memory-mapped, common/cm4_hal.c */

/* ---- system -------------------------------------------------------------------------- */

void hal_watchdog_start(void)
{
    /* started by mps2_board_init: it also guards the start-up */
}

void hal_watchdog_kick(void)
{
    MPS2_WDOG_LOCK = MPS2_WDOG_UNLOCK;
    MPS2_WDOG_INTCLR = 1u; /* clears the interrupt and reloads the counter */
    MPS2_WDOG_LOCK = 0u;
}

/* hal_system_reset: common/cm4_hal.c */

void mps2_board_init(uint32_t tick_hz, void (*hook)(void))
{
    port_ring_init(&uart.rx);
    port_ring_init(&uart.tx);
    uart.tx_busy = false;
    MPS2_UART_CTRL(MPS2_UART0) = 0u;
    MPS2_UART_BAUDDIV(MPS2_UART0) = MPS2_SYSCLK_HZ / 115200u;
    MPS2_UART_INT(MPS2_UART0) = MPS2_UART_INT_TX | MPS2_UART_INT_RX;
    MPS2_UART_CTRL(MPS2_UART0) =
        MPS2_UART_CTRL_TXEN | MPS2_UART_CTRL_RXEN | MPS2_UART_CTRL_TXINT | MPS2_UART_CTRL_RXINT;
    cm4_nvic_enable(MPS2_IRQ_UART0_RX, 0x40u);
    cm4_nvic_enable(MPS2_IRQ_UART0_TX, 0x40u);

    /* watchdog: 5 s at 25 MHz; its first expiry is the NMI (a reset, see
     * vectors_mps2.c). Generous: QEMU's clock is the host's, and a loaded CI
     * host may stall the emulated CPU for a while. */
    MPS2_WDOG_LOCK = MPS2_WDOG_UNLOCK;
    MPS2_WDOG_LOAD = 5u * MPS2_SYSCLK_HZ;
    MPS2_WDOG_CTRL = 3u; /* INTEN | RESEN */
    MPS2_WDOG_LOCK = 0u;

    tb.period_us = 1000000u / tick_hz;
    tb.load = MPS2_SYSCLK_HZ / tick_hz - 1u;
    tb.ticks = 0;
    tb.overruns = 0;
    tb.manual = false;
    tb.hook = hook;
    CM4_SCB_SHPR3 = (CM4_SCB_SHPR3 & 0x00FFFFFFu) | (0x80u << 24); /* SysTick below the UART */
    CM4_SYST_RVR = tb.load;
    CM4_SYST_CVR = 0u;
    CM4_SYST_CSR = CM4_SYST_CSR_ENABLE | CM4_SYST_CSR_TICKINT | CM4_SYST_CSR_CLKSOURCE;
    cm4_irq_enable();
}
