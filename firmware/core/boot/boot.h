/*
 * boot.h - the bootloader: boot decision and the flashing session, portable
 * over the HAL flash interface (hal_flash_layout/erase_page/write/read).
 *
 * Flash layout of the application slot [slot_base, slot_base + slot_size):
 *
 *   slot_base + 0     image header, 64 bytes (image.h), written LAST but one
 *   slot_base + 64    VALID marker: 8 bytes {BOOT_MARK_VALID, header_crc},
 *                     written last, only after the whole payload in flash
 *                     matched payload_crc (the rest of its 32-byte cell stays
 *                     erased)
 *   slot_base + 96    BAD marker: 8 bytes {BOOT_MARK_BAD, header_crc}, written
 *                     by the application when it judges itself unusable
 *   slot_base + 512   payload (load_addr = slot_base + BOOT_IMAGE_HDR_AREA)
 *
 * Every marker is written once into erased flash and only cleared by erasing
 * the slot's first page, so the design works on flash that forbids
 * re-programming a written cell.
 *
 * Boot decision (boot_start, run on every reset): stay in the bootloader
 * when (first match wins)
 *   1. the host asked for it: *request_word == BOOT_REQUEST_MAGIC (a RAM word
 *      that survives a warm reset; the application sets it with
 *      boot_request_enter() and resets; boot_start clears it),
 *   2. the slot holds no image header (erased, or not our magic),
 *   3. the header is invalid for this drive (version, header CRC, board id,
 *      load address, length),
 *   4. the VALID marker is missing or does not match the header (update
 *      interrupted before the end),
 *   5. the BAD marker is present (the application marked itself bad),
 *   6. the payload CRC in flash differs from payload_crc (checked every boot);
 * otherwise wait `window_us` for a host to connect (any bootloader message),
 * then call the port's `jump` hook with load_addr.
 *
 * Session (boot_handle, one request at a time, main context):
 *   IDLE --ERASE(header ok)--> WRITING --WRITE*--> WRITING --FINISH(crc ok)--> DONE
 *   any --ERASE--> WRITING (a new session; the old image is gone)
 *   any --REBOOT--> reset hook after the reply has been sent
 * ERASE validates the header against the drive (board id, load address,
 * capacity) BEFORE touching flash, then erases the page holding the header
 * first (the old image is invalid from this instant) and the pages of the
 * payload. WRITE programs one block (<= BOOT_BLOCK_MAX bytes, write-unit
 * aligned; the last block may be short) and echoes address and length; a
 * repeated WRITE of data already in flash succeeds (a host retry after a
 * lost reply). FINISH checks the CRC of the whole payload in flash, writes the
 * header, then the VALID marker. A reset anywhere leaves either the old image
 * (before ERASE), or an image without VALID marker (bootloader stays), or the
 * new valid image.
 *
 * Messages (protocol/contour.toml, ids 0x80..0x9F; generated codecs in
 * proto_msgs.h): boot_handle takes one protocol message (msg_id | seq |
 * payload) and produces its reply (same seq):
 *
 *   request         reply                  command
 *   boot_connect    boot_info              boot_identify (cancels the jump window)
 *   boot_erase      boot_erased            boot_erase
 *   boot_write      boot_written (echo)    boot_write
 *   boot_read       boot_data              boot_read
 *   boot_crc        boot_crc_value         boot_crc
 *   boot_finish     boot_finished          boot_finish
 *   boot_reboot     ack                    boot_reboot
 *   identify        identify_reply         axes = 0, capability "bootloader",
 *                                          fw_version = BOOT_VERSION
 * A refused command gets error{code = boot, arg = boot_status_t, lo =
 * detail (the CRC found, for payload_crc)}; a payload of the wrong length
 * error{bad_length}; any other id error{unknown_message}. A request repeating
 * the previous one exactly (same id, seq and payload: a host retry after a
 * lost reply) is answered from a one-entry cache without executing again.
 *
 * Context: everything here runs in the main context of the bootloader (no
 * interrupts touch boot_t). No heap, no floating point.
 */
#ifndef BOOT_BOOT_H
#define BOOT_BOOT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "boot/image.h"

/* Largest reply message boot_handle produces (msg_id | seq | payload). */
#define BOOT_REPLY_MAX 252u

/* Bootloader version reported by CONNECT: (major << 16) | (minor << 8) | patch. */
#define BOOT_VERSION 0x00010000u

/* Largest data block of one WRITE / READ (bytes; fits one protocol message). */
#define BOOT_BLOCK_MAX 224u
/* Largest flash write unit supported (bytes); markers live in 32-byte cells. */
#define BOOT_MAX_WRITE_SIZE 32u

#define BOOT_MARK_VALID_OFF 64u
#define BOOT_MARK_BAD_OFF   96u
#define BOOT_MARK_LEN       8u
#define BOOT_MARK_VALID     0x444C4156u /* "VALD" */
#define BOOT_MARK_BAD       0x21444142u /* "BAD!" */

/* Value of the request word asking the next boot to stay in the bootloader. */
#define BOOT_REQUEST_MAGIC 0xB007100Du

/* Default bytes at the top of the HAL flash region kept out of the slot
 * (parameter and compensation store); see boot_config_default. */
#ifndef BOOT_RESERVED_TOP_DEFAULT
#define BOOT_RESERVED_TOP_DEFAULT 32768u
#endif

/* Default host-connect window before jumping to a valid application (us). */
#ifndef BOOT_WINDOW_US_DEFAULT
#define BOOT_WINDOW_US_DEFAULT 200000u
#endif

/* Board ids (image header `board_id`; CONNECT reports the drive's). */
#define BOOT_BOARD_SIM     0x00000001u /* the simulated drive (firmware/ports/sim) */
#define BOOT_BOARD_STM32F4 0x00000002u /* STM32F405/407 drive */
#define BOOT_BOARD_QEMU    0x00000003u /* QEMU mps2-an386 board */
#define BOOT_BOARD_LINUX   0x00000004u /* Linux single-board computer */

/* Status byte of every response. 1..8 are the boot_image_status_t values
 * (header refused by ERASE, or BOOT_IMAGE_ERR_PAYLOAD_CRC from FINISH). */
typedef enum {
    BOOT_OK = 0,
    BOOT_ERR_STATE = 16,      /* command not allowed now (WRITE/FINISH without ERASE) */
    BOOT_ERR_RANGE = 17,      /* address/length outside the image being written */
    BOOT_ERR_ALIGN = 18,      /* address or length not a multiple of the write unit */
    BOOT_ERR_NOT_ERASED = 19, /* target holds other data: ERASE again */
    BOOT_ERR_FLASH = 20,      /* HAL erase/write/read reported failure */
    BOOT_ERR_VERIFY = 21,     /* read-back after programming differs */
    BOOT_ERR_MALFORMED = 22,  /* request too short/long for its command */
    BOOT_ERR_UNKNOWN = 23     /* unknown command byte */
} boot_status_t;

/* Why the last boot_start stayed in the bootloader (or BOOT_REASON_APP_OK). */
typedef enum {
    BOOT_REASON_APP_OK = 0,
    BOOT_REASON_REQUESTED = 1,
    BOOT_REASON_NO_APP = 2,
    BOOT_REASON_BAD_HEADER = 3,
    BOOT_REASON_NOT_VALIDATED = 4,
    BOOT_REASON_MARKED_BAD = 5,
    BOOT_REASON_CRC = 6,
    BOOT_REASON_FLASH = 7 /* the HAL could not read the slot */
} boot_reason_t;

typedef enum {
    BOOT_SESSION_IDLE = 0,
    BOOT_SESSION_WRITING = 1,
    BOOT_SESSION_DONE = 2
} boot_session_t;

typedef enum {
    BOOT_MODE_STAY = 0,   /* serving the host */
    BOOT_MODE_WINDOW = 1, /* valid app; waiting window_us for a host */
    BOOT_MODE_JUMPED = 2  /* jump hook called (returns only in simulations) */
} boot_mode_t;

typedef enum {
    BOOT_ACT_NONE = 0,
    BOOT_ACT_JUMP = 1, /* jump hook called / port must start the application */
    BOOT_ACT_RESET = 2 /* reset hook called / port must reset */
} boot_action_t;

typedef struct {
    uint32_t board_id;  /* this drive's board id (BOOT_BOARD_*) */
    uint32_t slot_base; /* page-aligned start of the application slot */
    uint32_t slot_size; /* bytes, multiple of the page size, > BOOT_IMAGE_HDR_AREA */
    uint32_t window_us; /* connect window before jumping to a valid app; 0 = none */
    uint8_t node_id;    /* reported by identify (CAN node id; 0 on serial-only ports) */
    /* RAM word surviving a warm reset (port places it in .noinit); NULL = none. */
    volatile uint32_t *request_word;
    /* Start the application at load_addr; on hardware never returns. May be
     * NULL (boot_poll then only returns BOOT_ACT_JUMP). */
    void (*jump)(uint32_t load_addr, void *ctx);
    /* Reset the processor (usually hal_system_reset); may be NULL. */
    void (*reset)(void *ctx);
    void *ctx; /* passed to the hooks */
} boot_config_t;

/* What boot_connect reports (boot_info). */
typedef struct {
    uint32_t boot_version;
    uint32_t board_id;
    uint32_t slot_base;
    uint32_t slot_size;
    uint32_t page_size;
    uint32_t write_size;
    uint32_t load_addr; /* where an image's payload must go */
    uint32_t max_length;
    uint16_t block_max;
    uint8_t reason;  /* boot_reason_t of the last decision, re-evaluated */
    uint8_t session; /* boot_session_t */
    /* Header of the image in the slot, zero when none parses. */
    uint32_t app_version;
    uint32_t app_length;
    uint32_t app_crc;
    uint8_t app_build_id[8]; /* first 8 bytes of its build id */
} boot_ident_t;

typedef struct {
    boot_config_t cfg;
    uint32_t page_size;
    uint32_t write_size;
    boot_mode_t mode;
    boot_reason_t reason; /* of the last boot_start */
    boot_session_t session;
    bool reboot_pending;
    uint32_t window_start_us;
    boot_image_header_t hdr;              /* session image header (valid in WRITING/DONE) */
    uint8_t hdr_raw[BOOT_IMAGE_HDR_SIZE]; /* its encoded form */
    /* one-entry reply cache: last request (id, seq, length, crc) and reply */
    bool cache_valid;
    uint8_t cache_id;
    uint8_t cache_seq;
    uint16_t cache_req_len;
    uint32_t cache_req_crc;
    uint16_t cache_len;
    uint8_t cache[BOOT_REPLY_MAX];
} boot_t;

/* Fill *cfg for this port's HAL flash region: the slot is the region minus
 * BOOT_RESERVED_TOP_DEFAULT rounded up to whole pages; window
 * BOOT_WINDOW_US_DEFAULT; no hooks, no request word. */
void boot_config_default(boot_config_t *cfg, uint32_t board_id);

/* Check the config against the HAL layout; false if unusable (slot outside
 * the region, unaligned, too small, write unit > BOOT_MAX_WRITE_SIZE). */
bool boot_init(boot_t *b, const boot_config_t *cfg);

/* The boot decision (see top). Consumes the request word. Returns the reason;
 * mode becomes WINDOW (app ok, window_us > 0), JUMPED (app ok, no window: jump
 * hook already called) or STAY. */
boot_reason_t boot_start(boot_t *b, uint32_t now_us);

/* Background step: jumps when the window has expired, resets when a REBOOT
 * reply has gone out. Call after sending each response. */
boot_action_t boot_poll(boot_t *b, uint32_t now_us);

/* Execute one protocol message msg = msg_id | seq | payload (len >= 2) and
 * write its reply message into out (cap >= BOOT_REPLY_MAX). Returns the
 * reply length, 0 when there is nothing to send (len < 2, cap too small, or
 * a message id the host should not get an answer for: drive-to-host ids).
 * Any bootloader request cancels the jump window. */
size_t boot_handle(boot_t *b, const uint8_t *msg, size_t len, uint8_t *out, size_t cap);

/* The same commands, typed (used by boot_handle and by tests). */
void boot_identify(boot_t *b, boot_ident_t *id);
boot_status_t boot_erase(boot_t *b, const uint8_t hdr[BOOT_IMAGE_HDR_SIZE], uint16_t *pages);
boot_status_t boot_write(boot_t *b, uint32_t addr, const uint8_t *data, size_t len);
boot_status_t boot_read(boot_t *b, uint32_t addr, uint8_t *out, size_t len);
boot_status_t boot_crc(boot_t *b, uint32_t addr, uint32_t len, uint32_t *crc);
boot_status_t boot_finish(boot_t *b, uint32_t *crc);
boot_status_t boot_reboot(boot_t *b);

/* Evaluate the slot without side effects: reason as in boot_start steps 2..6;
 * *h receives the header when one parses (may be NULL). Usable by the
 * application (e.g. to report its own version from its header). */
boot_reason_t boot_check_app(const boot_config_t *cfg, boot_image_header_t *h);

/* Application side: ask the next boot to stay in the bootloader (then reset). */
void boot_request_enter(const boot_config_t *cfg);

/* Application side: mark the image in the slot bad, so the bootloader stays
 * from the next boot on. False if no image header or the flash write failed. */
bool boot_app_mark_bad(const boot_config_t *cfg);

#endif /* BOOT_BOOT_H */
