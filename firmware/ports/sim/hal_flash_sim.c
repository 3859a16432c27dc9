/* hal_flash_sim.c - see hal_flash_sim.h. Defines only the hal_flash_* functions
 * of hal.h; the rest of the simulator's HAL lives in other files. */
#include "hal_flash_sim.h"

#include <stdio.h>
#include <string.h>

#include "hal.h"

static uint8_t mem[FLASH_SIM_MAX_SIZE];
static hal_flash_layout_t layout = {FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE,
                                    FLASH_SIM_DEFAULT_PAGE, FLASH_SIM_DEFAULT_WRITE};
static bool initialised;
static FILE *file;
static long budget = -1;
static bool powered = true;
static flash_sim_stats_t stats;

static void ensure_init(void)
{
    if (!initialised) {
        memset(mem, 0xFF, sizeof mem);
        initialised = true;
    }
}

/* Offset of [addr, addr + len) in mem, or false when outside the region. */
static bool offset_of(uint32_t addr, size_t len, uint32_t *off)
{
    if (addr < layout.base || addr - layout.base > layout.size ||
        len > (size_t)(layout.size - (addr - layout.base))) {
        return false;
    }
    *off = addr - layout.base;
    return true;
}

static void mirror(uint32_t off, size_t len)
{
    if (file == NULL || len == 0u) {
        return;
    }
    if (fseek(file, (long)off, SEEK_SET) != 0 || fwrite(mem + off, 1, len, file) != len ||
        fflush(file) != 0) {
        fprintf(stderr, "flash_sim: cannot write the flash file\n");
    }
}

/* Consume one byte of the power budget; false when the power just failed. */
static bool spend(void)
{
    if (budget == 0) {
        powered = false;
        return false;
    }
    if (budget > 0) {
        budget--;
    }
    return true;
}

bool flash_sim_configure(uint32_t base, uint32_t size, uint32_t page_size, uint32_t write_size)
{
    if (size == 0u || page_size == 0u || write_size == 0u || size > FLASH_SIM_MAX_SIZE ||
        page_size % write_size != 0u || size % page_size != 0u ||
        (uint64_t)base + size > 0x100000000ull) {
        return false;
    }
    flash_sim_detach();
    layout.base = base;
    layout.size = size;
    layout.page_size = page_size;
    layout.write_size = write_size;
    memset(mem, 0xFF, sizeof mem);
    initialised = true;
    budget = -1;
    powered = true;
    flash_sim_stats_reset();
    return true;
}

bool flash_sim_attach(const char *path)
{
    FILE *f;
    long n;

    ensure_init();
    flash_sim_detach();
    f = fopen(path, "r+b");
    if (f == NULL) {
        f = fopen(path, "w+b");
        if (f == NULL) {
            return false;
        }
        memset(mem, 0xFF, layout.size);
        if (fwrite(mem, 1, layout.size, f) != layout.size || fflush(f) != 0) {
            fclose(f);
            return false;
        }
        file = f;
        return true;
    }
    if (fseek(f, 0, SEEK_END) != 0 || (n = ftell(f)) != (long)layout.size ||
        fseek(f, 0, SEEK_SET) != 0 || fread(mem, 1, layout.size, f) != layout.size) {
        fclose(f);
        return false;
    }
    file = f;
    return true;
}

void flash_sim_detach(void)
{
    if (file != NULL) {
        fclose(file);
        file = NULL;
    }
}

void flash_sim_power_cut_after(long n)
{
    budget = n < 0 ? -1 : n;
}

void flash_sim_power_on(void)
{
    powered = true;
    budget = -1;
}

bool flash_sim_powered(void)
{
    return powered;
}

bool flash_sim_poke(uint32_t addr, uint8_t value)
{
    uint32_t off;

    ensure_init();
    if (!offset_of(addr, 1, &off)) {
        return false;
    }
    mem[off] = value;
    mirror(off, 1);
    return true;
}

const flash_sim_stats_t *flash_sim_stats(void)
{
    return &stats;
}

void flash_sim_stats_reset(void)
{
    memset(&stats, 0, sizeof stats);
}

const hal_flash_layout_t *hal_flash_layout(void)
{
    ensure_init();
    return &layout;
}

bool hal_flash_erase_page(uint32_t addr)
{
    uint32_t off;
    uint32_t i;

    ensure_init();
    if (!powered || !offset_of(addr, 1, &off)) {
        return false;
    }
    off -= off % layout.page_size;
    for (i = 0; i < layout.page_size; i++) {
        if (!spend()) {
            mirror(off, i);
            return false;
        }
        mem[off + i] = 0xFFu;
    }
    mirror(off, layout.page_size);
    stats.erases++;
    return true;
}

bool hal_flash_write(uint32_t addr, const uint8_t *data, size_t len)
{
    uint32_t off;
    size_t i;

    ensure_init();
    if (!powered) {
        return false;
    }
    if (data == NULL || len == 0u || !offset_of(addr, len, &off) || off % layout.write_size != 0u ||
        len % layout.write_size != 0u) {
        stats.violations++;
        return false;
    }
    for (i = 0; i < len; i++) {
        if (mem[off + i] != 0xFFu) {
            stats.violations++;
            return false;
        }
    }
    for (i = 0; i < len; i++) {
        if (!spend()) {
            mirror(off, i);
            return false;
        }
        mem[off + i] = data[i];
    }
    mirror(off, len);
    stats.writes++;
    stats.bytes += (uint32_t)len;
    return true;
}

bool hal_flash_read(uint32_t addr, uint8_t *data, size_t len)
{
    uint32_t off;

    ensure_init();
    if (!powered || data == NULL || !offset_of(addr, len, &off)) {
        return false;
    }
    memcpy(data, mem + off, len);
    return true;
}
