/*
 * crc.h - the checksums of the product, one implementation each.
 *
 *   crc32      IEEE 802.3 (reflected, poly 0xEDB88320, init and final xor
 *              0xFFFFFFFF): firmware images, flash records, calibration tables.
 *              crc32("123456789") = 0xCBF43926.
 *   crc16      CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection,
 *              no final xor): serial frames. crc16("123456789") = 0x29B1.
 *
 * Incremental use: pass the previous return value as `crc` (start with
 * CRC32_INIT / CRC16_INIT); crc32 returns the finalised value each call.
 * Pure functions, any context.
 */
#ifndef CRC_H
#define CRC_H

#include <stddef.h>
#include <stdint.h>

#define CRC32_INIT 0u
#define CRC16_INIT 0xFFFFu

uint32_t crc32_update(uint32_t crc, const uint8_t *data, size_t len);
uint16_t crc16_update(uint16_t crc, const uint8_t *data, size_t len);

#endif /* CRC_H */
