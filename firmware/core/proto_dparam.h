/*
 * proto_dparam.h - the protocol's parameters owned by the drive's parameter
 * API (drive.h drive_param_*): the map from a parameter's base id
 * (protocol/contour.toml; per-axis ones without the axis) to drive_param_t.
 *
 * proto_drive_param(base_id, out): true and *out set when base_id is one
 * of them; false (out untouched) otherwise. Pure; any context.
 */
#ifndef PROTO_DPARAM_H
#define PROTO_DPARAM_H

#include <stdbool.h>
#include <stdint.h>

#include "drive.h"

bool proto_drive_param(uint16_t base_id, drive_param_t *out);

#endif /* PROTO_DPARAM_H */
