/*
 * param_store.h - the drive's parameters in flash: `config save` and the
 * load at start-up.
 *
 * Specification
 * -------------
 * What: every drive parameter (drive.h drive_param_t: planner limits and
 * rules, stop deceleration, arc chord, start delay, servo gains and
 * feed-forward, following-error limit, soft limits, in-position window,
 * friction feed-forward, feed-forward advance, quadrant-glitch
 * compensation, feed-forward learning rate, mean measurement),
 * per axis for the axes in use. Not stored: the link's parameters (periods,
 * watchdog) and the CEC mode (chosen per job).
 *
 * Where: one blob record of the compensation store's two-bank log
 * (comp_store.h, comp_store_blob_*): the same versioning, fallback to the
 * previous version when the current one is damaged, and power-cut safety.
 * Blob (little-endian):
 *   0 u32 magic "DPAR" (0x52415044)   4 u16 format (PARAM_STORE_FORMAT)
 *   6 u8 axes                          7 u8 DRIVE_PARAM_COUNT of the writer
 *   8 u16 entries                      10 u16 reserved (0)
 *   12 + 10 i: u8 drive_param_t, u8 axis, i64 value
 *
 * param_store_save: only while the drive is DISABLED (like compensation
 * tables: an erase can stall the CPU); writes the values in use.
 * param_store_load (app_init, after drive_init): reads the blob; when it is
 * readable, of this format and parameter count, for the same axes, and every
 * value is accepted (drive_param_set_all: ranges, whole profile, servo
 * gains), applies all of it; otherwise nothing (the defaults stay) and the
 * status says why. Context: main.
 */
#ifndef PARAM_STORE_H
#define PARAM_STORE_H

#include <stdint.h>

#include "drive.h"

#define PARAM_STORE_MAGIC  0x52415044u /* "DPAR" little-endian */
#define PARAM_STORE_FORMAT 1u

/* Values of the protocol enum param_store_status (protocol/contour.toml). */
typedef enum {
    PARAM_STORE_NONE = 0, /* nothing saved: defaults                      */
    PARAM_STORE_LOADED,   /* the saved parameters are in use              */
    PARAM_STORE_CORRUPT,  /* unreadable (flash, CRC, length): defaults    */
    PARAM_STORE_VERSION,  /* other format or parameter set: defaults      */
    PARAM_STORE_AXES,     /* saved for another axis count: defaults       */
    PARAM_STORE_REFUSED   /* a value the drive refuses: defaults          */
} param_store_status_t;

typedef enum {
    PARAM_STORE_OK = 0,
    PARAM_STORE_E_STATE, /* the drive is not disabled */
    PARAM_STORE_E_FLASH  /* the store refused or failed (comp_store_result_t in *detail) */
} param_store_result_t;

param_store_result_t param_store_save(uint32_t *version, uint32_t *detail);
/* The same rule and store, with no parameter in the record: the next
 * param_store_load keeps every default (status LOADED). CANopen 0x1011. */
param_store_result_t param_store_save_defaults(uint32_t *version, uint32_t *detail);
param_store_status_t param_store_load(void);
/* Status of the last load (PARAM_STORE_NONE before one). */
param_store_status_t param_store_status(void);

/* Blob of the current parameters into buf (cap bytes); its length, 0 when
 * it does not fit. For tests. */
uint16_t param_store_encode(uint8_t *buf, uint16_t cap);

#endif /* PARAM_STORE_H */
