/*
 * hal_flash_sim.h - the simulated drive's flash (implements hal_flash_* of hal.h).
 *
 * Page semantics like on-chip NOR flash, strictly:
 *   - erased bytes read 0xFF; hal_flash_erase_page sets a whole page to 0xFF;
 *   - hal_flash_write programs whole write units (address and length multiples
 *     of write_size) and only into erased bytes: writing over a byte that is
 *     not 0xFF fails without changing anything (even if the new value would
 *     only clear bits) and is counted as a violation;
 *   - accesses outside [base, base + size) fail.
 *
 * Storage is a RAM array, optionally mirrored to a file (flash_sim_attach):
 * every program and erase is written through to the file at once, so a
 * killed or restarted simulator process finds the flash as it was, and a
 * simulated reset (re-running the boot decision) sees the same bytes.
 * The file is the raw flash content, `size` bytes, offset 0 = `base`.
 *
 * Fault injection: flash_sim_power_cut_after(n) lets n more bytes be
 * programmed or erased (byte by byte, in address order), then the flash
 * loses power in the middle of that operation: the operation stops half done
 * and every call fails until flash_sim_power_on() (the simulated reset).
 *
 * Default geometry (before any flash_sim_configure): base 0x08010000,
 * 256 KiB, 2 KiB pages, 8-byte write unit, all erased, not file backed.
 * Simulator main context only (not thread-safe).
 */
#ifndef HAL_FLASH_SIM_H
#define HAL_FLASH_SIM_H

#include <stdbool.h>
#include <stdint.h>

#define FLASH_SIM_MAX_SIZE      (1024u * 1024u)
#define FLASH_SIM_DEFAULT_BASE  0x08010000u
#define FLASH_SIM_DEFAULT_SIZE  (256u * 1024u)
#define FLASH_SIM_DEFAULT_PAGE  2048u
#define FLASH_SIM_DEFAULT_WRITE 8u

typedef struct {
    uint32_t erases;     /* pages erased */
    uint32_t writes;     /* hal_flash_write calls that succeeded */
    uint32_t bytes;      /* bytes programmed */
    uint32_t violations; /* writes refused: not erased, unaligned, out of range */
} flash_sim_stats_t;

/* Set the geometry and erase everything (detaches any file). False when the
 * geometry is inconsistent (page not a multiple of write unit, size not a
 * multiple of page, size > FLASH_SIM_MAX_SIZE, zero values). */
bool flash_sim_configure(uint32_t base, uint32_t size, uint32_t page_size, uint32_t write_size);

/* Mirror the flash to `path`: an existing file of exactly `size` bytes is
 * loaded; a missing file is created erased. False (and not attached) when
 * the file cannot be opened or has another size. */
bool flash_sim_attach(const char *path);
void flash_sim_detach(void);

/* Power-cut injection (see top); n < 0 disables it. */
void flash_sim_power_cut_after(long n);
void flash_sim_power_on(void);
bool flash_sim_powered(void);

/* Direct access for tests: corrupt one byte in place, bypassing the rules
 * (a bit flip in the array, written through to the file). */
bool flash_sim_poke(uint32_t addr, uint8_t value);

const flash_sim_stats_t *flash_sim_stats(void);
void flash_sim_stats_reset(void);

#endif /* HAL_FLASH_SIM_H */
