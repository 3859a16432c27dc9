/*
 * comp_store.h - the compensation tables in the drive's flash.
 *
 * Specification
 * -------------
 * Where: the store region is the top COMP_STORE_REGION_BYTES (32 KiB) of the
 * HAL flash region (hal_flash_layout(); docs/bootloader.md leaves it to the
 * parameter and compensation store, the bootloader never touches it). The
 * compensation tables take the TOP of that region: for each axis a = 0..
 * CORE_AXES-1 two slots s = 0, 1 of `slot_bytes` = COMP_RECORD_MAX rounded up
 * to whole pages, slot (a, s) at
 *     end - (2 * CORE_AXES - (2 a + s)) * slot_bytes,   end = base + size.
 * The rest of the store region (below) is left to a parameter store.
 * Simulated drive (2 KiB pages): 6 slots of 2 KiB, 0x0803D000..0x08040000.
 *
 * What: one comp record (comp.h: header with magic, format, axis, version,
 * header CRC, data CRC) per slot, padded with 0xFF to the write unit.
 *
 * Writing a new table (comp_store_write) never endangers the current one:
 *   1. the slot NOT holding the axis's current record is erased (the
 *      current record stays in the other slot);
 *   2. the new record is programmed there with version = current + 1;
 *   3. it is read back and decoded (magic, header CRC, data CRC, limits) and
 *      compared with what was meant to be written.
 * Only a record that passed 3 is ever returned by comp_store_load; until
 * then (and after any failure, power cut included) the previous version is
 * the current one. The previous table stays in flash until the next write.
 *
 * Loading (comp_store_load): of the two slots of the axis, the valid record
 * (magic, format, header and data CRC, axis, limits) with the higher version;
 * none: COMP_STORE_EMPTY. A record with n == 0 is a valid "no compensation"
 * (comp_store_clear writes one).
 *
 * Context: main only (flash erase and program). No heap: one static record
 * buffer of COMP_RECORD_MAX bytes.
 */
#ifndef COMP_STORE_H
#define COMP_STORE_H

#include <stdbool.h>
#include <stdint.h>

#include "comp.h"
#include "core_config.h"

#define COMP_STORE_REGION_BYTES (32u * 1024u)

typedef enum {
    COMP_STORE_OK = 0,
    COMP_STORE_EMPTY,    /* no valid record for this axis            */
    COMP_STORE_E_ARG,    /* axis out of range, NULL, invalid table    */
    COMP_STORE_E_LAYOUT, /* the flash layout cannot hold the slots    */
    COMP_STORE_E_FLASH,  /* erase / program / read failed             */
    COMP_STORE_E_VERIFY  /* read back differs from what was written   */
} comp_store_result_t;

typedef struct {
    uint32_t base;       /* first slot (axis 0, slot 0) address */
    uint32_t slot_bytes; /* bytes per slot (whole pages)       */
    uint32_t write_size;
} comp_store_layout_t;

/* Slot geometry from hal_flash_layout(). False when the region cannot hold
 * 2 * CORE_AXES slots inside the top COMP_STORE_REGION_BYTES. */
bool comp_store_layout(comp_store_layout_t *out);

/* Address of slot (axis, slot); 0 when out of range or no layout. */
uint32_t comp_store_slot_addr(unsigned axis, unsigned slot);

/* Current table of `axis` into *table (dir_src NULL). *slot gets the slot
 * it came from (may be NULL). */
comp_store_result_t comp_store_load(unsigned axis, comp_table_t *table, unsigned *slot);

/* Store `table` (its axis field must equal `axis`) as the new current
 * table, version = current version + 1 (1 when none); the version written
 * is returned in *version and the slot in *slot (either may be NULL).
 * Steps and guarantees: see top. */
comp_store_result_t comp_store_write(unsigned axis, const comp_table_t *table, uint32_t *version,
                                     unsigned *slot);

/* Store an empty table (n = 0: no compensation) as the new current one. */
comp_store_result_t comp_store_clear(unsigned axis, uint32_t *version);

#endif /* COMP_STORE_H */
