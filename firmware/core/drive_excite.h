/*
 * drive_excite.h - the commissioning excitation on the drive (issue 23).
 *
 * Specification
 * -------------
 * Wires the experiment of excite.h into the drive application: one
 * experiment at a time, of one axis, on an enabled drive at rest (IDLE,
 * nothing queued). Protocol ids 0xD0..0xDF (protocol/contour.toml,
 * excite_*): excite_start (limits: travel, command, velocity, amplitude,
 * duration as n_ticks, host timeout), excite_status, excite_read (pull
 * transfer as calib_read, sample_pull.h: from_seq releases everything before it, at
 * most DRIVE_EXCITE_READ_MAX samples of 8 bytes per reply with a CRC-32 of
 * them, idempotent) and excite_abort. Refusals are error{code = excite,
 * arg = excite_refusal, lo = detail}. excite_start and excite_abort are
 * answered from a one-entry replay cache when the same (id, seq, payload)
 * arrives again (a host retry). Other ids go to the next handler.
 *
 * Sample buffer: taken from the calibration (calib_excite_take: the two
 * buffers are one union); excite_start is refused (calibration) while a
 * calibration run is set up or running, and calibration requests are
 * refused while the experiment holds it. excite_abort gives it back once
 * the experiment stopped (at once when it is not running).
 *
 * Stops: every limit of excite.h within the tick; a drive fault or estop
 * and a drive that leaves IDLE in the same tick; a host silent for
 * host_timeout_ms (every excite_* request counts); a new host session
 * (drive_excite_host_gone, from the composition root). The drive's own
 * command is never changed: the excitation is added at the amplifier
 * (hal_motor_set_mv after the servo wrote its outputs), so when it stops
 * the servo's command is what the motor gets.
 *
 * Contexts
 *   drive_excite_armed   written by main (set by excite_start, cleared by
 *                        drive_excite_poll once the tick stopped the run);
 *                        the tick tests it: while it is false the tick
 *                        costs one flag test (app_tick).
 *   drive_excite_tick()  tick, right after drive_tick(true) with the
 *                        status it published (pos, motor_mv, faults,
 *                        state).
 *   drive_excite_poll(), drive_excite_handle(), drive_excite_host_gone(),
 *   drive_excite_init()  main.
 */
#ifndef DRIVE_EXCITE_H
#define DRIVE_EXCITE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "drive.h"
#include "excite.h"
#include "preempt.h"

#define DRIVE_EXCITE_READ_MAX        29u   /* samples per excite_samples reply */
#define DRIVE_EXCITE_HOST_TIMEOUT_MS 3000u /* largest host_timeout_ms          */

typedef size_t (*drive_excite_handler_fn)(const uint8_t *msg, size_t len, uint32_t now_us,
                                          uint8_t *out, size_t cap);

extern CORE_SHARED bool drive_excite_armed;

void drive_excite_init(void);
void drive_excite_set_next_handler(drive_excite_handler_fn fn);
void drive_excite_tick(const drive_status_t *st);
void drive_excite_poll(void);
/* The host that started the run is gone: it ends with `reason`
 * (EXCITE_REASON_NEW_SESSION). */
void drive_excite_host_gone(uint32_t reason);
size_t drive_excite_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                           size_t cap);
/* Read-out (tests, simulator). */
const excite_t *drive_excite_state(void);

#endif /* DRIVE_EXCITE_H */
