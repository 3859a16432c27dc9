/*
 * param_store.c - the drive's parameters in flash (see param_store.h).
 */
#include "param_store.h"

#include <stdbool.h>

#include "comp_store.h"
#include "scratch.h"

#define HDR   12u
#define ENTRY 10u

static param_store_status_t status; /* main */

uint16_t param_store_encode(uint8_t *buf, uint16_t cap)
{
    const drive_config_t *c = drive_config();
    uint32_t at = HDR, n = 0u, i;
    unsigned id, a, axes;
    int64_t v;

    if (buf == NULL || cap < HDR) {
        return 0u;
    }
    for (id = 0; id < (unsigned)DRIVE_PARAM_COUNT; id++) {
        axes = drive_param_get((drive_param_t)id, 1u, &v) == DRIVE_OK ? c->axes : 1u;
        for (a = 0; a < axes; a++) {
            if (drive_param_get((drive_param_t)id, a, &v) != DRIVE_OK) {
                continue;
            }
            if (at + ENTRY > cap) {
                return 0u;
            }
            buf[at] = (uint8_t)id;
            buf[at + 1u] = (uint8_t)a;
            for (i = 0; i < 8u; i++) {
                buf[at + 2u + i] = (uint8_t)((uint64_t)v >> (8u * i));
            }
            at += ENTRY;
            n++;
        }
    }
    buf[0] = (uint8_t)PARAM_STORE_MAGIC;
    buf[1] = (uint8_t)(PARAM_STORE_MAGIC >> 8);
    buf[2] = (uint8_t)(PARAM_STORE_MAGIC >> 16);
    buf[3] = (uint8_t)(PARAM_STORE_MAGIC >> 24);
    buf[4] = (uint8_t)PARAM_STORE_FORMAT;
    buf[5] = 0u;
    buf[6] = (uint8_t)c->axes;
    buf[7] = (uint8_t)DRIVE_PARAM_COUNT;
    buf[8] = (uint8_t)n;
    buf[9] = (uint8_t)(n >> 8);
    buf[10] = 0u;
    buf[11] = 0u;
    return (uint16_t)at;
}

static param_store_result_t save(bool defaults, uint32_t *version, uint32_t *detail)
{
    drive_status_t st;
    uint16_t len;
    comp_store_result_t r;
    uint8_t *blob;

    drive_status(&st);
    if (st.state != DRIVE_DISABLED) {
        return PARAM_STORE_E_STATE;
    }
    blob = scratch_claim(SCRATCH_PARAM_STORE, COMP_STORE_BLOB_MAX);
    if (blob == NULL) {
        len = 0u;
        r = COMP_STORE_E_BUSY;
    } else {
        len = param_store_encode(blob, (uint16_t)COMP_STORE_BLOB_MAX);
        if (defaults && len != 0u) {
            blob[8] = 0u; /* no entries: the next load keeps the defaults */
            blob[9] = 0u;
            len = HDR;
        }
        r = len == 0u ? COMP_STORE_E_ARG : comp_store_blob_write(blob, len, version);
        scratch_release(SCRATCH_PARAM_STORE);
    }
    if (detail != NULL) {
        *detail = (uint32_t)r;
    }
    return r == COMP_STORE_OK ? PARAM_STORE_OK : PARAM_STORE_E_FLASH;
}

param_store_result_t param_store_save(uint32_t *version, uint32_t *detail)
{
    return save(false, version, detail);
}

param_store_result_t param_store_save_defaults(uint32_t *version, uint32_t *detail)
{
    return save(true, version, detail);
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

/* The blob (in the scratch area) checked and staged into the drive's
 * candidate configuration (drive_param_begin / _stage); LOADED: commit
 * next. */
static param_store_status_t stage(uint8_t *blob)
{
    uint16_t len = 0u, n, k;
    uint32_t i;
    uint64_t v;
    comp_store_result_t r = comp_store_blob_load(blob, (uint16_t)COMP_STORE_BLOB_MAX, &len, NULL);

    if (r == COMP_STORE_EMPTY || r == COMP_STORE_E_LAYOUT) {
        return PARAM_STORE_NONE;
    }
    if (r != COMP_STORE_OK || len < HDR) {
        return PARAM_STORE_CORRUPT;
    }
    if (get32(blob) != PARAM_STORE_MAGIC || blob[4] != PARAM_STORE_FORMAT || blob[5] != 0u ||
        blob[7] != (uint8_t)DRIVE_PARAM_COUNT) {
        return PARAM_STORE_VERSION;
    }
    if (blob[6] != drive_config()->axes) {
        return PARAM_STORE_AXES;
    }
    n = (uint16_t)(blob[8] | (blob[9] << 8));
    if ((uint32_t)HDR + (uint32_t)n * ENTRY != len) {
        return PARAM_STORE_CORRUPT;
    }
    if (drive_param_begin() != DRIVE_OK) {
        return PARAM_STORE_REFUSED;
    }
    for (k = 0; k < n; k++) {
        const uint8_t *e = blob + HDR + (uint32_t)k * ENTRY;
        v = 0u;
        for (i = 0; i < 8u; i++) {
            v |= (uint64_t)e[2u + i] << (8u * i);
        }
        if (e[0] >= (uint8_t)DRIVE_PARAM_COUNT ||
            drive_param_stage((drive_param_t)e[0], e[1], (int64_t)v) != DRIVE_OK) {
            return PARAM_STORE_REFUSED;
        }
    }
    return PARAM_STORE_LOADED;
}

static param_store_status_t load(void)
{
    uint8_t *blob = scratch_claim(SCRATCH_PARAM_STORE, COMP_STORE_BLOB_MAX);
    param_store_status_t s;
    if (blob == NULL) {
        return PARAM_STORE_CORRUPT;
    }
    s = stage(blob);
    scratch_release(SCRATCH_PARAM_STORE); /* before the commit's servo probe */
    if (s != PARAM_STORE_LOADED) {
        return s;
    }
    return drive_param_commit() == DRIVE_OK ? PARAM_STORE_LOADED : PARAM_STORE_REFUSED;
}

param_store_status_t param_store_load(void)
{
    status = load();
    return status;
}

param_store_status_t param_store_status(void)
{
    return status;
}
