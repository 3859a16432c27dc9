/*
 * comp2d_link.h - the drive's 2-D compensation map (issue 22): stored in
 * flash, uploaded, read and cleared over the link, applied to X and Y in
 * the tick (comp2d_live.h).
 *
 * Specification
 * -------------
 * Store: the map's record (comp2d.h) is a blob-like record of the
 * compensation store's two-bank log (comp_store.h, slot
 * COMP_STORE_SLOT_MAP2D): versioned (store version + 1 on every write),
 * read back after writing, carried over compactions, a damaged newest
 * record falls back to the previous one, an empty record (length 0) is
 * "no map". comp2d_link_init loads it at start-up and uses it when it
 * still passes comp2d_check against the drive's field.
 *
 * Messages (protocol/contour.toml, ids 0xC8..0xCF): comp2d_write (bytes
 * into a staging buffer of COMP2D_RECORD_MAX bytes; offset 0 starts a new
 * record), comp2d_commit(length, crc32), comp2d_get, comp2d_clear,
 * comp2d_read(offset, max) -> comp2d_data, replies comp2d_info. Refusals
 * are error{calib, status, lo}:
 *   record_range  length / offset outside the staging buffer
 *   record_crc    CRC-32 of the staged bytes differs (lo = what the drive has)
 *   comp2d_axes   the drive has fewer than two axes
 *   comp2d_memory more nodes than the drive holds (lo = nx * ny)
 *   comp2d_field  the grid reaches outside the drive's field (lo = 1 + axis):
 *                 X and Y's soft limits when set, else +-2^50 nm
 *   comp2d_record not a map record, or its version or node spacing
 *                 (lo = COMP2D_E_*)
 *   drive_enabled commit / clear with the drive not disabled (lo = state):
 *                 a flash write stalls a single-bank MCU
 *   flash         the store failed (lo = comp_store result); the previous
 *                 map stays in use
 * Commit and clear and write are answered from a one-entry replay cache
 * when the same request comes again (a lost reply never runs them twice).
 *
 * Contexts: main (handler, poll, init before the tick); the tick reads
 * only the published anchor (comp2d_live.h).
 */
#ifndef COMP2D_LINK_H
#define COMP2D_LINK_H

#include <stddef.h>
#include <stdint.h>

/* The map from flash (if any). After calib_init (the 1-D tables). Main. */
void comp2d_link_init(void);

/* Re-anchor the tick's correction at the axes' position (comp2d_live_poll
 * with X, Y from the drive's snapshot, after the 1-D tables). Main, every
 * main-loop pass. */
void comp2d_link_poll(void);

/* The link handler of ids 0xC8..0xCF; other ids go to the next handler
 * (comp2d_link_set_next) or are answered unknown_message. Main. */
typedef size_t (*comp2d_handler_fn)(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                                    size_t cap);
size_t comp2d_link_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                          size_t cap);
void comp2d_link_set_next(comp2d_handler_fn fn);

#endif /* COMP2D_LINK_H */
