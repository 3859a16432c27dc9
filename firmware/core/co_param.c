/*
 * co_param.c - CiA 402 objects <-> drive parameters (co_param.h is the
 * specification).
 */
#include "co_param.h"

#include <stddef.h>

#include "drive.h"
#include "param_store.h"

#define FERR_OFF    0xFFFFFFFFu
#define SIG_SAVE    0x65766173u /* "save" */
#define SIG_LOAD    0x64616F6Cu /* "load" */
#define ABORT_STORE 0x08000020u /* cannot be stored: wrong signature */
#define ABORT_HW    0x06060000u /* hardware error: the flash failed */

typedef struct {
    uint16_t index;
    uint8_t sub;
    uint8_t param;  /* drive_param_t */
    uint16_t scale; /* drive unit per object unit */
    uint8_t is_i32; /* else u32 */
    size_t offset;  /* in co_od_vars_t */
} co_param_map_t;

static const co_param_map_t maps[] = {
    {0x6065u, 0u, DRIVE_PARAM_FERR_LIMIT, 1u, 0u, offsetof(co_od_vars_t, ferr_window)},
    {0x607Du, 1u, DRIVE_PARAM_SOFT_MIN, 1u, 1u, offsetof(co_od_vars_t, soft_limit_min)},
    {0x607Du, 2u, DRIVE_PARAM_SOFT_MAX, 1u, 1u, offsetof(co_od_vars_t, soft_limit_max)},
    {0x607Fu, 0u, DRIVE_PARAM_V_MAX, 1u, 0u, offsetof(co_od_vars_t, max_profile_velocity)},
    {0x6083u, 0u, DRIVE_PARAM_A_MAX, 1000u, 0u, offsetof(co_od_vars_t, profile_acceleration)},
    {0x6084u, 0u, DRIVE_PARAM_A_MAX, 1000u, 0u, offsetof(co_od_vars_t, profile_deceleration)},
    {0x6085u, 0u, DRIVE_PARAM_STOP_DECEL, 1000u, 0u,
     offsetof(co_od_vars_t, quick_stop_deceleration)},
};

#define MAPS (sizeof maps / sizeof maps[0])

static const co_param_map_t *find(uint16_t index, uint8_t sub)
{
    size_t i;

    for (i = 0; i < MAPS; i++) {
        if (maps[i].index == index && maps[i].sub == sub) {
            return &maps[i];
        }
    }
    return NULL;
}

/* The object's value in the drive's unit. */
static int64_t to_drive(const co_param_map_t *m, uint32_t value)
{
    if (m->is_i32 != 0u) {
        return (int64_t)(int32_t)value;
    }
    if (m->param == DRIVE_PARAM_FERR_LIMIT && value == FERR_OFF) {
        return 0;
    }
    return (int64_t)value * m->scale;
}

/* The drive's value as the object's (saturated to its type). */
static uint32_t to_object(const co_param_map_t *m, int64_t v)
{
    if (m->is_i32 != 0u) {
        v = v > INT32_MAX ? INT32_MAX : (v < INT32_MIN ? INT32_MIN : v);
        return (uint32_t)(int32_t)v;
    }
    if (m->param == DRIVE_PARAM_FERR_LIMIT && v == 0) {
        return FERR_OFF;
    }
    v /= m->scale;
    return v > (int64_t)UINT32_MAX ? UINT32_MAX : (v < 0 ? 0u : (uint32_t)v);
}

static uint32_t *var(co_t *co, const co_param_map_t *m)
{
    return (uint32_t *)(void *)((uint8_t *)&co->od + m->offset);
}

/* 0x1010:1 / 0x1011:1: param_store_save / _save_defaults. */
static uint32_t store(uint16_t index, uint32_t value)
{
    param_store_result_t r;

    if (value != (index == 0x1010u ? SIG_SAVE : SIG_LOAD)) {
        return ABORT_STORE;
    }
    r = index == 0x1010u ? param_store_save(NULL, NULL) : param_store_save_defaults(NULL, NULL);
    if (r == PARAM_STORE_E_STATE) {
        return CO_ABORT_STATE;
    }
    return r == PARAM_STORE_OK ? 0u : ABORT_HW;
}

uint32_t co_param_check(co_t *co, uint16_t index, uint8_t sub, uint32_t value)
{
    const co_param_map_t *m = find(index, sub);
    int64_t v, lo, hi;
    drive_result_t r;

    (void)co;
    if ((index == 0x1010u || index == 0x1011u) && sub == 1u) {
        return store(index, value);
    }
    if (m == NULL) {
        return 0u;
    }
    v = to_drive(m, value);
    if (drive_param_range((drive_param_t)m->param, 0u, &lo, &hi) != DRIVE_OK) {
        return CO_ABORT_VALUE;
    }
    if (v > hi) {
        return CO_ABORT_VALUE_HIGH;
    }
    if (v < lo) {
        return CO_ABORT_VALUE_LOW;
    }
    r = drive_param_set((drive_param_t)m->param, 0u, v);
    if (r == DRIVE_E_BUSY) {
        return CO_ABORT_STATE;
    }
    return r == DRIVE_OK ? 0u : CO_ABORT_VALUE;
}

void co_param_written(co_t *co, uint16_t index, uint8_t sub)
{
    const co_param_map_t *m = find(index, sub);
    int64_t now;

    co->od.store_all = 1u; /* reads: saves on command */
    co->od.restore_all = 1u;
    if (m == NULL || drive_param_get((drive_param_t)m->param, 0u, &now) != DRIVE_OK) {
        return;
    }
    if (to_object(m, now) != *var(co, m)) {
        (void)drive_param_set((drive_param_t)m->param, 0u, to_drive(m, *var(co, m)));
    }
}

void co_param_refresh(co_t *co)
{
    size_t i;
    int64_t v;

    for (i = 0; i < MAPS; i++) {
        if (drive_param_get((drive_param_t)maps[i].param, 0u, &v) == DRIVE_OK) {
            *var(co, &maps[i]) = to_object(&maps[i], v);
        }
    }
}
