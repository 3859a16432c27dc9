/*
 * image.h - the firmware image header: what a flashable image says about itself.
 *
 * An image file is this 64-byte header followed by the payload (the raw
 * application binary that goes to `load_addr`). In flash the header sits at
 * the start of the application slot, BOOT_IMAGE_HDR_AREA bytes before the
 * payload, so `load_addr` = slot base + BOOT_IMAGE_HDR_AREA (see boot.h and
 * docs/bootloader.md). All fields are little-endian:
 *
 *   off size field            meaning
 *     0   4  magic            BOOT_IMAGE_MAGIC ("CTFW" in ASCII order)
 *     4   2  format_version   BOOT_IMAGE_FORMAT_VERSION (1)
 *     6   2  header_size      BOOT_IMAGE_HDR_SIZE (64)
 *     8   4  board_id         target board; must equal the drive's board id
 *    12   4  fw_version       (major << 16) | (minor << 8) | patch
 *    16   4  load_addr        flash address of the first payload byte
 *    20   4  length           payload bytes, 1 .. slot capacity
 *    24   4  payload_crc      crc32 (crc.h) of the `length` payload bytes
 *    28  16  build_id         opaque build identity (e.g. leading bytes of a git hash)
 *    44  16  reserved         zero
 *    60   4  header_crc       crc32 of bytes 0..59
 *
 * Parsing never trusts the input: boot_image_parse checks magic, version, size
 * and header CRC; boot_image_check adds the target checks (board id, load
 * address, capacity). Pure functions, any context, no flash access.
 */
#ifndef BOOT_IMAGE_H
#define BOOT_IMAGE_H

#include <stdbool.h>
#include <stdint.h>

#define BOOT_IMAGE_MAGIC          0x57465443u /* bytes 'C' 'T' 'F' 'W' */
#define BOOT_IMAGE_FORMAT_VERSION 1u
#define BOOT_IMAGE_HDR_SIZE       64u
#define BOOT_IMAGE_BUILD_ID_LEN   16u
/* Bytes reserved at the start of the slot for header and markers; the
 * payload starts this far in (512 keeps a Cortex-M vector table aligned). */
#define BOOT_IMAGE_HDR_AREA 512u

typedef struct {
    uint32_t magic;
    uint16_t format_version;
    uint16_t header_size;
    uint32_t board_id;
    uint32_t fw_version;
    uint32_t load_addr;
    uint32_t length;
    uint32_t payload_crc;
    uint8_t build_id[BOOT_IMAGE_BUILD_ID_LEN];
    uint32_t header_crc;
} boot_image_header_t;

/* Result codes of parsing and checking; stable numbers (they go on the wire
 * inside boot status codes, see boot.h). */
typedef enum {
    BOOT_IMAGE_OK = 0,
    BOOT_IMAGE_ERR_MAGIC = 1,      /* not an image header (or erased flash) */
    BOOT_IMAGE_ERR_VERSION = 2,    /* unknown format version or header size */
    BOOT_IMAGE_ERR_HDR_CRC = 3,    /* header bytes corrupted */
    BOOT_IMAGE_ERR_BOARD = 4,      /* built for another board */
    BOOT_IMAGE_ERR_LOAD_ADDR = 5,  /* payload not at this drive's application address */
    BOOT_IMAGE_ERR_LENGTH = 6,     /* zero length or larger than the slot */
    BOOT_IMAGE_ERR_RESERVED = 7,   /* reserved bytes not zero */
    BOOT_IMAGE_ERR_PAYLOAD_CRC = 8 /* payload does not match payload_crc */
} boot_image_status_t;

/* Decode 64 header bytes into *h and check magic, format version, header
 * size, reserved bytes and header CRC (in that order; the first failure is
 * returned). *h is filled even on failure. */
boot_image_status_t boot_image_parse(const uint8_t raw[BOOT_IMAGE_HDR_SIZE],
                                     boot_image_header_t *h);

/* Encode *h into 64 bytes, computing header_crc (h->header_crc is updated). */
void boot_image_encode(boot_image_header_t *h, uint8_t raw[BOOT_IMAGE_HDR_SIZE]);

/* Target checks on a parsed header: board id, load address and that
 * `length` is 1..max_length. */
boot_image_status_t boot_image_check(const boot_image_header_t *h, uint32_t board_id,
                                     uint32_t load_addr, uint32_t max_length);

/* Little-endian helpers shared with the bootloader. */
uint32_t boot_image_get_u32(const uint8_t *p);
uint16_t boot_image_get_u16(const uint8_t *p);
void boot_image_put_u32(uint8_t *p, uint32_t v);
void boot_image_put_u16(uint8_t *p, uint16_t v);

#endif /* BOOT_IMAGE_H */
