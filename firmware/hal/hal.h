/*
 * hal.h - the one boundary between the portable core and the hardware.
 *
 * A port (firmware/ports/<target>/) implements these functions; the core
 * calls nothing else that touches hardware. The set is deliberately small:
 * a time base, encoder inputs, motor outputs, enable/fault lines, a byte
 * stream (UART), CAN frames, flash pages and a watchdog.
 *
 * Contexts: "tick" is the control-tick interrupt (or the simulator's step),
 * "main" the background loop. Each function says where it may be called.
 * Ports deliver encoder edges by calling the decoder directly from their
 * edge interrupt (see qdec.h); counter-mode ports are polled here.
 */
#ifndef HAL_H
#define HAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define HAL_MAX_AXES 4

/* ---- time base ---------------------------------------------------------- */

/* Free-running microsecond clock (wraps at 2^32 us, ~71 min). Any context. */
uint32_t hal_time_us(void);

/* ---- encoders (counter-mode ports; edge-mode ports return false) -------- */

/* Snapshot of the hardware counter of encoder `ch` (axes 0..n-1, then the
 * reference-scale inputs). Tick context. False when the port has no counter. */
bool hal_encoder_counter(unsigned ch, uint32_t *count);

/* Mean of encoder `axis`'s count over the tick that ends at this tick's
 * sample (since the previous tick's), minus the count at this sample, in
 * 2^-16 counts (negative while the count rises). What timestamped edges
 * (input capture) or a counter sampled by DMA many times per tick give: a
 * boxcar over the tick, so a mode near a multiple of the tick rate is not
 * aliased onto the path (|sinc| 0.006 at 662.6 Hz over 3 ms) and a moving
 * axis resolves below one count. Read by the tick of a drive configured
 * with enc_mean (drive.h) only. lag_q16 NULL: whether the port provides
 * it at all (any context; the drive refuses enc_mean on false). False when
 * the port cannot (then always false). */
bool hal_encoder_mean(unsigned axis, int64_t *lag_q16);

/* ---- motor outputs and lines -------------------------------------------- */

/* Motor command of one axis in millivolts at the amplifier input, already
 * clamped by the core to the configured range. Tick context. */
void hal_motor_set_mv(unsigned axis, int32_t millivolts);

/* Amplifier enable line. Tick or main context. */
void hal_motor_enable(unsigned axis, bool on);

/* Amplifier fault input (true = fault). Tick context. */
bool hal_amp_fault(unsigned axis);

/* One call per tick for all axes (the servo's usual path): the commands of
 * axes 0..n-1, exactly as hal_motor_set_mv(i, mv[i]) in axis order, and the
 * fault inputs of axes 0..n-1 as bits (bit i = hal_amp_fault(i)). n <=
 * HAL_MAX_AXES. Tick context. */
void hal_motor_set_mv_all(const int32_t *mv, unsigned n);
uint32_t hal_amp_fault_mask(unsigned n);

/* The generic forms of the two above, over the per-axis calls, for ports
 * whose hardware has nothing faster (a port's hal_motor_set_mv_all may
 * simply return hal_generic_set_mv_all(mv, n)). */
static inline void hal_generic_set_mv_all(const int32_t *mv, unsigned n)
{
    unsigned i;
    for (i = 0; i < n; i++) {
        hal_motor_set_mv(i, mv[i]);
    }
}

static inline uint32_t hal_generic_amp_fault_mask(unsigned n)
{
    uint32_t m = 0;
    unsigned i;
    for (i = 0; i < n; i++) {
        if (hal_amp_fault(i)) {
            m |= 1u << i;
        }
    }
    return m;
}

/* Home switch of one axis (true = the axis is on its switch). The switch is
 * a region at one end of travel: active from its edge to the end, so an
 * axis that overshoots the edge keeps it active. Read by the homing
 * sequence only (drive_home.h). Tick context. A port without a switch on
 * an axis returns false (homing that axis then fails: switch not found).
 * Ports: sim from the simulated table position (sim.h home_switch_*),
 * mps2_an386 from its plant, stm32f4 a GPIO input (hal_stm32f4.c), linux a
 * GPIO line (hal_linux.c, CONTOUR_GPIO_HOME). */
bool hal_home_switch(unsigned axis);

/* ---- host link ----------------------------------------------------------- */

/* Non-blocking UART: returns bytes accepted / read (0 when none). Main. */
size_t hal_uart_write(const uint8_t *data, size_t len);
size_t hal_uart_read(uint8_t *data, size_t cap);
/* True when every byte given to hal_uart_write has left the transmitter
 * (a reply must leave before a requested reset). Main context. */
bool hal_uart_tx_idle(void);

/* CAN data frames, classic CAN. An id with HAL_CAN_EFF (bit 31, Linux's
 * CAN_EFF_FLAG) set is a 29-bit (extended) id in bits 0..28, otherwise an
 * 11-bit id; remote and error frames are not delivered. Return false when
 * the transmit mailbox is full / no frame is waiting. Main context. */
#define HAL_CAN_EFF 0x80000000u
bool hal_can_send(uint32_t id, const uint8_t *data, uint8_t len);
bool hal_can_receive(uint32_t *id, uint8_t *data, uint8_t *len);

/* ---- flash (bootloader, parameter and compensation store) ---------------- */

typedef struct {
    uint32_t base;       /* first address of the managed region */
    uint32_t size;       /* bytes */
    uint32_t page_size;  /* erase unit, bytes */
    uint32_t write_size; /* write unit, bytes (address and length multiple) */
} hal_flash_layout_t;

const hal_flash_layout_t *hal_flash_layout(void);
/* Erase the page containing addr (to 0xFF). False on error. Main context. */
bool hal_flash_erase_page(uint32_t addr);
/* Program len bytes; only erased bytes may be written. Main context. */
bool hal_flash_write(uint32_t addr, const uint8_t *data, size_t len);
bool hal_flash_read(uint32_t addr, uint8_t *data, size_t len);

/* ---- system --------------------------------------------------------------- */

/* Start the watchdog (app_init, once the application is up; a no-op on a
 * board that starts it earlier or has none), then kick it from main. */
void hal_watchdog_start(void);
void hal_watchdog_kick(void);
/* Reset the processor (never returns on hardware; the simulator restarts). */
void hal_system_reset(void);

#endif /* HAL_H */
