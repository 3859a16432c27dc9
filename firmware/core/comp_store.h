/*
 * comp_store.h - the compensation tables in the drive's flash.
 *
 * Specification
 * -------------
 * Where: the store takes the top of the HAL flash region (hal_flash_layout();
 * the bootloader never touches it, docs/bootloader.md): two banks of
 * `bank_bytes` = COMP_STORE_REGION_BYTES / 2 rounded up to whole erase pages,
 * bank 0 at end - 2 * bank_bytes, bank 1 at end - bank_bytes (end = base +
 * size). comp_store_bytes() = 2 * bank_bytes is what the port must keep out
 * of its application slot:
 *   simulated drive (2 KiB pages): 2 x 16 KiB, 0x08048000..0x08050000;
 *   QEMU mps2-an386 (4 KiB pages): 2 x 16 KiB, the top 32 KiB;
 *   STM32F4 (128 KiB sectors): 2 x 128 KiB = sectors 10 and 11.
 * No layout (COMP_STORE_E_LAYOUT) when the write unit is 0, > 64 or does not
 * divide 64, or the two banks would take more than half of the region, or
 * a bank cannot hold COMP_STORE_SLOTS full records (the axes, the blob
 * and the 2-D map, below).
 *
 * Bank: a 64-byte header cell at offset 0, then a log of comp records (comp.h:
 * magic, format, axis, version, header CRC, data CRC) from offset 64, each
 * padded with 0xFF to the write unit, appended in address order:
 *   0 u32 magic "CSTB" (0x42545343)  4 u32 seq  8 u32 bank_bytes
 *   12 u32 crc32 of bytes 0..11      16..63 0xFF
 * A bank is valid when its header is; the ACTIVE bank is the valid one with
 * the later seq (serial arithmetic, (int32_t)(a - b) > 0). The log of the
 * active bank ends at the first cell whose 32 header bytes are all 0xFF
 * (clean end) or at a record header that is not valid / does not fit (dirty
 * end: an interrupted append; the next write compacts).
 *
 * Writing a new table (comp_store_write) never endangers the current one;
 * version = current version + 1 (1 when none):
 *   append, when the active bank has a clean end and room: the record is
 *     programmed at the end (after checking those bytes are erased), read
 *     back and decoded (magic, header CRC, data CRC, limits), compared with
 *     what was meant;
 *   compact, otherwise (no valid bank, full or dirty): the other bank is
 *     erased; the new record, then the current record of every other axis
 *     (copied byte for byte from the active bank) are programmed from offset
 *     64; every axis is checked by reading the new bank back; only then the
 *     header with seq = active seq + 1 is programmed and read back. Until the
 *     header is valid the old bank stays active, untouched.
 * The old records stay in flash (and old versions in the log are the
 * fallback) until their bank is erased by the compaction after next.
 * A power cut at any byte of an erase or program leaves the previous or the
 * new table current, for every axis (tests/unit/test_comp_store.c).
 *
 * Loading (comp_store_load): in the active bank, the record of the axis with
 * the highest version (the later one on a tie) that decodes (magic, format,
 * header and data CRC, axis, limits); a damaged record falls back to the
 * previous version while that is still in the log. None: COMP_STORE_EMPTY.
 * A record with n == 0 is a valid "no compensation" (comp_store_clear).
 * "slot" in this interface is the bank (0 or 1) holding the record.
 *
 * Capacity: a bank holds (bank_bytes - 64) / record bytes records: 7 full
 * (126-point, 2 KiB) records in 16 KiB, 63 in 128 KiB, so a sector is
 * erased about every 60 full-table writes on the STM32F4. Compaction needs
 * CORE_AXES full records + 64 bytes per bank (checked by the layout).
 *
 * Context: main only (flash erase and program; on single-bank flash an erase
 * stalls the CPU, see docs/ports.md). No heap: one static record buffer of
 * COMP_RECORD_MAX bytes and one static table the store decodes into (loads,
 * read-back checks and compaction run one after the other); the table
 * comp_store_write takes is encoded with the new version, never copied.
 * comp_store_clear builds its empty table in the scratch area (scratch.h):
 * call it with the area free (COMP_STORE_E_BUSY otherwise).
 */
#ifndef COMP_STORE_H
#define COMP_STORE_H

#include <stdbool.h>
#include <stdint.h>

#include "comp.h"
#include "core_config.h"

#define COMP_STORE_REGION_BYTES (32u * 1024u)    /* minimum size of both banks */
#define COMP_STORE_HDR_BYTES    64u              /* bank header cell            */
#define COMP_STORE_BANK_MAGIC   0x42545343u      /* "CSTB" little-endian        */
#define COMP_STORE_SLOT_BLOB    0x50u            /* axis byte of the blob record */
#define COMP_STORE_SLOT_MAP2D   0x51u            /* axis byte of the 2-D map     */
#define COMP_STORE_SLOTS        (CORE_AXES + 2u) /* axes, blob, 2-D map      */
#define COMP_STORE_BLOB_MAX     (COMP_RECORD_MAX - COMP_RECORD_HDR)

typedef enum {
    COMP_STORE_OK = 0,
    COMP_STORE_EMPTY,    /* no valid record for this axis            */
    COMP_STORE_E_ARG,    /* axis out of range, NULL, invalid table    */
    COMP_STORE_E_LAYOUT, /* the flash layout cannot hold the banks    */
    COMP_STORE_E_FLASH,  /* erase / program / read failed             */
    COMP_STORE_E_VERIFY, /* read back differs from what was written   */
    COMP_STORE_E_BUSY    /* comp_store_clear: the scratch area is held */
} comp_store_result_t;

typedef struct {
    uint32_t base;       /* bank 0 address (bank 1 follows)  */
    uint32_t bank_bytes; /* bytes per bank (whole pages)     */
    uint32_t write_size;
} comp_store_layout_t;

/* Bank geometry from hal_flash_layout() (see top); false: no layout. */
bool comp_store_layout(comp_store_layout_t *out);

/* Bytes the store takes at the top of the HAL region (0: no layout). */
uint32_t comp_store_bytes(void);

/* The active bank (0 or 1), 0xFF when none. */
uint8_t comp_store_active_bank(void);

/* Address of bank 0 or 1; 0 when out of range or no layout. */
uint32_t comp_store_bank_addr(unsigned bank);

/* Address of the axis's current record (what comp_store_load returns);
 * 0 when none. For tests and diagnostics. */
uint32_t comp_store_record_addr(unsigned axis);

/* Current table of `axis` into *table (dir_src NULL). *slot gets the bank
 * it came from (may be NULL). */
comp_store_result_t comp_store_load(unsigned axis, comp_table_t *table, unsigned *slot);

/* Store `table` (its axis field must equal `axis`) as the new current
 * table, version = current version + 1 (1 when none); the version written
 * is returned in *version and the bank in *slot (either may be NULL).
 * Steps and guarantees: see top. */
comp_store_result_t comp_store_write(unsigned axis, const comp_table_t *table, uint32_t *version,
                                     unsigned *slot);

/* Store an empty table (n = 0: no compensation) as the new current one. */
comp_store_result_t comp_store_clear(unsigned axis, uint32_t *version);

/* One more record kind in the same log: an opaque blob (the drive's saved
 * parameters, param_store.h) of up to COMP_STORE_BLOB_MAX bytes, in a comp
 * record whose axis byte is COMP_STORE_SLOT_BLOB and whose reserved u16 at
 * offset 14 holds the byte length (data zero-padded to 16-byte units, data
 * CRC over them). Compensation loads never choose it (another axis);
 * compaction carries it over like an axis's table; the same versioning,
 * fallback to the previous version and power-cut guarantees. */
comp_store_result_t comp_store_blob_write(const uint8_t *data, uint16_t len, uint32_t *version);
/* The current blob into data (cap bytes), its length in *len.
 * COMP_STORE_EMPTY: none saved; COMP_STORE_E_VERIFY: blob records are in
 * the log but none decodes (damaged). */
comp_store_result_t comp_store_blob_load(uint8_t *data, uint16_t cap, uint16_t *len,
                                         uint32_t *version);

/* The same for any blob-like slot: COMP_STORE_SLOT_BLOB (the parameters)
 * or COMP_STORE_SLOT_MAP2D (the 2-D compensation map, comp2d.h record;
 * length 0: no map). Other slots: COMP_STORE_E_ARG. */
comp_store_result_t comp_store_slot_write(unsigned slot, const uint8_t *data, uint16_t len,
                                          uint32_t *version);
comp_store_result_t comp_store_slot_load(unsigned slot, uint8_t *data, uint16_t cap, uint16_t *len,
                                         uint32_t *version);

#endif /* COMP_STORE_H */
