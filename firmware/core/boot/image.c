/* image.c - see image.h. */
#include "boot/image.h"

#include "crc.h"

#define OFF_MAGIC    0u
#define OFF_FORMAT   4u
#define OFF_HDR_SIZE 6u
#define OFF_BOARD    8u
#define OFF_VERSION  12u
#define OFF_LOAD     16u
#define OFF_LENGTH   20u
#define OFF_PCRC     24u
#define OFF_BUILD_ID 28u
#define OFF_RESERVED 44u
#define RESERVED_LEN 16u
#define OFF_HCRC     60u

uint32_t boot_image_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

uint16_t boot_image_get_u16(const uint8_t *p)
{
    return (uint16_t)((uint16_t)p[0] | ((uint16_t)p[1] << 8));
}

void boot_image_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

void boot_image_put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

boot_image_status_t boot_image_parse(const uint8_t raw[BOOT_IMAGE_HDR_SIZE], boot_image_header_t *h)
{
    unsigned i;

    h->magic = boot_image_get_u32(raw + OFF_MAGIC);
    h->format_version = boot_image_get_u16(raw + OFF_FORMAT);
    h->header_size = boot_image_get_u16(raw + OFF_HDR_SIZE);
    h->board_id = boot_image_get_u32(raw + OFF_BOARD);
    h->fw_version = boot_image_get_u32(raw + OFF_VERSION);
    h->load_addr = boot_image_get_u32(raw + OFF_LOAD);
    h->length = boot_image_get_u32(raw + OFF_LENGTH);
    h->payload_crc = boot_image_get_u32(raw + OFF_PCRC);
    for (i = 0; i < BOOT_IMAGE_BUILD_ID_LEN; i++) {
        h->build_id[i] = raw[OFF_BUILD_ID + i];
    }
    h->header_crc = boot_image_get_u32(raw + OFF_HCRC);

    if (h->magic != BOOT_IMAGE_MAGIC) {
        return BOOT_IMAGE_ERR_MAGIC;
    }
    if (h->format_version != BOOT_IMAGE_FORMAT_VERSION || h->header_size != BOOT_IMAGE_HDR_SIZE) {
        return BOOT_IMAGE_ERR_VERSION;
    }
    if (crc32_update(CRC32_INIT, raw, OFF_HCRC) != h->header_crc) {
        return BOOT_IMAGE_ERR_HDR_CRC;
    }
    for (i = 0; i < RESERVED_LEN; i++) {
        if (raw[OFF_RESERVED + i] != 0u) {
            return BOOT_IMAGE_ERR_RESERVED;
        }
    }
    return BOOT_IMAGE_OK;
}

void boot_image_encode(boot_image_header_t *h, uint8_t raw[BOOT_IMAGE_HDR_SIZE])
{
    unsigned i;

    for (i = 0; i < BOOT_IMAGE_HDR_SIZE; i++) {
        raw[i] = 0u;
    }
    boot_image_put_u32(raw + OFF_MAGIC, h->magic);
    boot_image_put_u16(raw + OFF_FORMAT, h->format_version);
    boot_image_put_u16(raw + OFF_HDR_SIZE, h->header_size);
    boot_image_put_u32(raw + OFF_BOARD, h->board_id);
    boot_image_put_u32(raw + OFF_VERSION, h->fw_version);
    boot_image_put_u32(raw + OFF_LOAD, h->load_addr);
    boot_image_put_u32(raw + OFF_LENGTH, h->length);
    boot_image_put_u32(raw + OFF_PCRC, h->payload_crc);
    for (i = 0; i < BOOT_IMAGE_BUILD_ID_LEN; i++) {
        raw[OFF_BUILD_ID + i] = h->build_id[i];
    }
    h->header_crc = crc32_update(CRC32_INIT, raw, OFF_HCRC);
    boot_image_put_u32(raw + OFF_HCRC, h->header_crc);
}

boot_image_status_t boot_image_check(const boot_image_header_t *h, uint32_t board_id,
                                     uint32_t load_addr, uint32_t max_length)
{
    if (h->board_id != board_id) {
        return BOOT_IMAGE_ERR_BOARD;
    }
    if (h->load_addr != load_addr) {
        return BOOT_IMAGE_ERR_LOAD_ADDR;
    }
    if (h->length == 0u || h->length > max_length) {
        return BOOT_IMAGE_ERR_LENGTH;
    }
    return BOOT_IMAGE_OK;
}
