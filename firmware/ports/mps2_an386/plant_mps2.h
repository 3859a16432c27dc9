/*
 * plant_mps2.h - the simulated axes of the QEMU board: the simulator's axis
 * model (hil_sim/axis_model.h, the thesis's X/Y axes, 5 mm lead, 4000
 * counts per motor revolution, 1 nm reference scale) with x4 quadrature
 * edges as hil_sim/qgen.h makes them, compiled into the image as the
 * board's "hardware". They implement the motor and encoder part of hal.h:
 *   hal_motor_set_mv / hal_motor_enable   the amplifier input (0 when disabled)
 *   hal_amp_fault                         never
 *   hal_encoder_counter(ch)               reference scales on channels
 *                                         axes..2*axes-1 (32-bit counts);
 *                                         axis encoders are edge mode (false)
 *
 * Pitch error (what `contour calibrate` measures on this board): axis X's
 * table position is l th2 + e(x), e piecewise linear between
 *     x mm        -20  -10    0   10   20   30   40   50
 *     e um         -4   -2    0  +12   +8  +15  +18  +14   (held beyond)
 * in both directions (no hysteresis: the servo overshoots a stop and comes
 * back, so a direction-dependent map would be read on the flank opposite
 * to the approach). The reference scale reads the table, the motor
 * encoder l th1, so the calibration error (encoder - reference) is -e:
 * 0, -12, -8 um at 0, 10, 20 mm (tests/python/test_ports_qemu.py). Y and
 * Z have none. The map lives in the plant (doubles, like the rest of the
 * model); the drive's code sees only counts.
 *
 * Homing: each axis's home switch (hal_home_switch) is active at table
 * positions <= -21.3 mm, and its encoder has an index (Z) one count wide
 * every motor turn (4000 counts), one at position 0: the simulator's
 * defaults (hil_sim/sim.h).
 *
 * plant_init  prepares the models for `axes` axes at tick_hz (substeps of at
 *             most 100 us) and fills the encoder part of the drive's
 *             configuration (scales, initial line levels). Main context,
 *             before drive_init.
 * plant_step  advances the models over one tick period with the motor
 *             commands just computed, delivering every encoder count change
 *             as a quadrature edge (drive_encoder_edge) time-stamped on the
 *             drive's ns clock (tick k at k * period). Tick context, right
 *             after drive_tick.
 */
#ifndef PLANT_MPS2_H
#define PLANT_MPS2_H

#include <stdbool.h>
#include <stdint.h>

#include "drive.h"

/* The QEMU machine's drive configuration: drive_config_default for `axes`
 * at tick_hz with the amplifier input limited to +-10 V (as the
 * simulator's machine). Encoder fields are filled by plant_init. */
void plant_drive_config(drive_config_t *cfg, uint32_t tick_hz, unsigned axes);

bool plant_init(uint32_t tick_hz, unsigned axes, drive_config_t *cfg);
void plant_step(uint32_t tick);
/* True table position of an axis in nm (for diagnostics). */
int64_t plant_table_nm(unsigned axis);

#endif /* PLANT_MPS2_H */
