/*
 * hal_sim.h - the simulator's side of the HAL port (firmware/ports/sim).
 *
 * The simulator (hil_sim/) and the simulated-drive server drive the virtual
 * peripherals through these functions; the firmware core sees only hal.h.
 * Everything is single-threaded: the simulator calls these between or around
 * drive ticks from the same thread that runs the firmware.
 *
 *   time        hal_time_us() returns the simulated clock set here (ns).
 *   motors      hal_motor_set_mv() stores the command (clamped to
 *               +-HAL_SIM_MV_LIMIT); the model reads it back; a disabled
 *               amplifier outputs 0.
 *   encoders    axes deliver edges (edge mode): hal_encoder_counter() returns
 *               false for them; a channel given a counter value with
 *               hal_sim_set_counter() (e.g. the reference scale) reports it;
 *               hal_encoder_mean() returns what hal_sim_set_encoder_mean()
 *               set.
 *   UART / CAN  byte ring and frame queue in each direction.
 *   watchdog    counts kicks; hal_system_reset() raises a flag the server
 *               acts on (the simulator restarts the firmware).
 *   flash       in hal_flash_sim.c (bootloader's file), not here.
 */
#ifndef HAL_SIM_H
#define HAL_SIM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#define HAL_SIM_CHANNELS   (2 * HAL_MAX_AXES)
#define HAL_SIM_MV_LIMIT   160000
#define HAL_SIM_UART_BYTES 8192
#define HAL_SIM_CAN_FRAMES 256

/* Back to power-on state: time 0, motors off, queues empty, flags clear. */
void hal_sim_reset(void);

void hal_sim_set_time_ns(uint64_t t_ns);
uint64_t hal_sim_time_ns(void);

/* Motor command as the amplifier sees it: 0 when disabled, mV. */
int32_t hal_sim_motor_mv(unsigned axis);
bool hal_sim_motor_enabled(unsigned axis);
void hal_sim_set_amp_fault(unsigned axis, bool fault);
/* Home switch input of an axis (hal_home_switch): the value set here, or,
 * with a source set (fn != NULL), what fn(ctx, axis) returns when the
 * firmware reads it. hal_sim_set_home_switch clears the source (there is
 * one for all axes: the other axes then read their last value set here),
 * as hal_sim_set_counter clears its channel's. */
void hal_sim_set_home_switch(unsigned axis, bool on);
typedef bool (*hal_sim_home_fn)(void *ctx, unsigned axis);
void hal_sim_set_home_source(hal_sim_home_fn fn, void *ctx);

/* Hardware counter value of channel ch (valid = false: edge mode); clears a
 * source of that channel. */
void hal_sim_set_counter(unsigned ch, uint32_t count, bool valid);
/* A source of channel ch's counter (fn != NULL): hal_encoder_counter()
 * reports fn(ctx, ch), computed when the firmware reads it (sim.c: the
 * reference scales, which the drive samples on a few ticks only). fn NULL:
 * the channel reports the last hal_sim_set_counter() value again. */
typedef uint32_t (*hal_sim_counter_fn)(void *ctx, unsigned ch);
void hal_sim_set_counter_source(unsigned ch, hal_sim_counter_fn fn, void *ctx);

/* Mean reading of axis `axis` over the last tick (hal_encoder_mean): the
 * simulator sets it every tick from the generator's reading over the
 * substeps (sim.c) while the drive has enc_mean. hal_sim_set_mean_port(false)
 * makes the port one that cannot provide it (tests of the drive's refusal);
 * hal_sim_reset: it can, lag 0. */
void hal_sim_set_encoder_mean(unsigned axis, int64_t lag_q16);
void hal_sim_set_mean_port(bool provides);

/* Host side of the UART: bytes toward the drive / bytes the drive sent. */
size_t hal_sim_uart_inject(const uint8_t *data, size_t len);
size_t hal_sim_uart_drain(uint8_t *data, size_t cap);

/* Host side of the CAN bus. False when the queue is full / empty. */
bool hal_sim_can_inject(uint32_t id, const uint8_t *data, uint8_t len);
bool hal_sim_can_drain(uint32_t *id, uint8_t *data, uint8_t *len);

uint32_t hal_sim_watchdog_kicks(void);
/* True once after hal_system_reset() was called (clears the flag). */
bool hal_sim_take_reset_request(void);

#endif /* HAL_SIM_H */
