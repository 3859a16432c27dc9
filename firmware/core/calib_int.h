/*
 * calib_int.h - internal interface between the parts of the calibration
 * service (calib.c: run, sample ring, dispatch; calib_record.c: the
 * compensation-record messages). Not for other modules. Main context.
 */
#ifndef CALIB_INT_H
#define CALIB_INT_H

#include <stddef.h>
#include <stdint.h>

#include "calib.h"
#include "comp_store.h"

/* calib.c: load the axis's current table from flash and install it;
 * the flash slot of the active table (0xFF: none). */
comp_store_result_t calib_load_install(unsigned axis);
uint8_t calib_comp_slot(unsigned axis);

/* calib_record.c: forget the staged record (calib_init); the handlers of
 * comp_write, comp_commit, comp_clear and comp_get (same contract as
 * calib_handle's; plen: payload length). */
void calib_record_reset(void);
size_t calib_h_comp_write(const uint8_t *msg, size_t plen, uint8_t *out);
size_t calib_h_comp_commit(const uint8_t *msg, size_t plen, uint8_t *out);
size_t calib_h_comp_clear(const uint8_t *msg, size_t plen, uint8_t *out);
size_t calib_h_comp_get(const uint8_t *msg, size_t plen, uint8_t *out);

#endif /* CALIB_INT_H */
