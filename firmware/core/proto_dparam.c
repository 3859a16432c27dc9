/*
 * proto_dparam.c - which protocol parameter is which drive parameter
 * (specification in proto_dparam.h).
 */
#include "proto_dparam.h"

#include <stddef.h>

#include "proto_msgs.h"

/* Parameters owned by the drive's parameter API (drive.h drive_param_*). */
static const struct {
    uint16_t proto;
    drive_param_t drv;
} drive_params[] = {
    {PROTO_PARAM_MAX_VELOCITY, DRIVE_PARAM_V_MAX},
    {PROTO_PARAM_MAX_ACCELERATION, DRIVE_PARAM_A_MAX},
    {PROTO_PARAM_MAX_JERK, DRIVE_PARAM_J_MAX},
    {PROTO_PARAM_CORNER_VELOCITY_STEP, DRIVE_PARAM_CORNER_DV},
    {PROTO_PARAM_CORNER_ACCELERATION, DRIVE_PARAM_CORNER_ACC},
    {PROTO_PARAM_JUNCTION_DEVIATION, DRIVE_PARAM_JUNCTION_DEV},
    {PROTO_PARAM_CORNER_RULE, DRIVE_PARAM_CORNER},
    {PROTO_PARAM_VELOCITY_PROFILE, DRIVE_PARAM_SHAPE},
    {PROTO_PARAM_MIN_BLOCK_TIME, DRIVE_PARAM_MIN_BLOCK_NS},
    {PROTO_PARAM_MIN_BLOCK_WINDOW, DRIVE_PARAM_MBT_WINDOW},
    {PROTO_PARAM_STOP_DECELERATION, DRIVE_PARAM_STOP_DECEL},
    {PROTO_PARAM_ARC_CHORD_TOLERANCE, DRIVE_PARAM_ARC_CHORD},
    {PROTO_PARAM_START_DELAY_MS, DRIVE_PARAM_START_DELAY_MS},
    {PROTO_PARAM_PID_KP, DRIVE_PARAM_KP},
    {PROTO_PARAM_PID_KI, DRIVE_PARAM_KI},
    {PROTO_PARAM_PID_KD, DRIVE_PARAM_KD},
    {PROTO_PARAM_VELOCITY_FEEDFORWARD, DRIVE_PARAM_KVFF},
    {PROTO_PARAM_ACCELERATION_FEEDFORWARD, DRIVE_PARAM_KAFF},
    {PROTO_PARAM_FOLLOWING_ERROR_LIMIT, DRIVE_PARAM_FERR_LIMIT},
    {PROTO_PARAM_SOFT_LIMIT_MIN, DRIVE_PARAM_SOFT_MIN},
    {PROTO_PARAM_SOFT_LIMIT_MAX, DRIVE_PARAM_SOFT_MAX},
    {PROTO_PARAM_IN_POSITION_WINDOW, DRIVE_PARAM_IN_POS},
    {PROTO_PARAM_FRICTION_FF_MV, DRIVE_PARAM_FRICTION_FF},
    {PROTO_PARAM_FRICTION_FF_BAND, DRIVE_PARAM_FRICTION_BAND},
    {PROTO_PARAM_FF_ADVANCE_NS, DRIVE_PARAM_FF_ADVANCE},
    {PROTO_PARAM_QG_COMP, DRIVE_PARAM_QG_COMP},
    {PROTO_PARAM_FFL_RATE, DRIVE_PARAM_FFL_RATE},
};

bool proto_drive_param(uint16_t base_id, drive_param_t *out)
{
    size_t i;

    for (i = 0; i < sizeof drive_params / sizeof drive_params[0]; i++) {
        if (drive_params[i].proto == base_id) {
            *out = drive_params[i].drv;
            return true;
        }
    }
    return false;
}
