/*
 * libFuzzer harness: the CiA 301 node (canopen.c): NMT slave, SDO server,
 * SYNC consumer, PDOs, EMCY and heartbeat consumer (co_sync.c, co_pdo.c,
 * co_emcy.c, co_hb.c).
 *
 * The input is cut into CAN frames: per frame one byte selects the kind
 * (bits 7..5: 0 the node's SDO request, 1 NMT 0x000, 2 SYNC 0x080, 3 one of
 * the default RPDO ids 0x200..0x500 + node (bits 4..3 pick it), 4 an EMCY
 * update with the next byte as the drive's fault bits, 5 any 11-bit id from
 * the next two bytes, 6 a 29-bit id, 7 a heartbeat of node 5 (0x705)) and the DLC (low nibble,
 * 0..15, above 8 taken as 8), then the data bytes; a time step of the next byte (ms) runs co_poll.
 * Every frame the node sends must be a classic CAN frame (11-bit id, DLC <= 8), every SDO response
 * DLC 8, every heartbeat DLC 1, every EMCY DLC 8; the transfer state must stay within its buffer
 * and every PDO's resolved mapping within 8 bytes; nothing may crash or loop. SDO downloads reach
 * the PDO configuration (0x1400-0x1BFF), so mappings, COB-IDs and transmission types are fuzzed
 * through their own checks, and the heartbeat consumer 0x1016 (co_hb.c) with its timeouts.
 */
#include <stdint.h>
#include <string.h>

#include "canopen.h"

#define NODE 7u

static uint32_t calls;

static bool tx_check(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    (void)data;
    if (len > 8u || id > 0x7FFu) {
        __builtin_trap();
    }
    if (id == CO_ID_TSDO + NODE && len != 8u) {
        __builtin_trap();
    }
    if (id == CO_ID_HB + NODE && len != 1u) {
        __builtin_trap();
    }
    if (id == 0x080u + NODE && len != 8u && len != 6u && len != 2u) {
        __builtin_trap(); /* EMCY, or a TPDO someone moved there */
    }
    return ++calls % 5u != 0u; /* now and then a full mailbox */
}

int LLVMFuzzerTestOneInput(const uint8_t *in, size_t n);

int LLVMFuzzerTestOneInput(const uint8_t *in, size_t n)
{
    static const co_config_t cfg = {NODE, 1u, 2u, 3u, 4u};
    static co_t co;
    uint32_t now = 0;
    size_t i = 0;

    co_init(&co, &cfg, tx_check, NULL, now);
    while (i < n) {
        uint8_t sel = in[i++];
        uint8_t len = (uint8_t)(sel & 0x0Fu);
        uint8_t f[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        unsigned kind = sel >> 5;
        uint32_t id = CO_ID_RSDO + NODE;

        if (len > 8u) {
            len = 8u;
        }
        if (kind == 1u) {
            id = CO_ID_NMT;
        } else if (kind == 2u) {
            id = 0x080u;
        } else if (kind == 3u) {
            id = 0x200u + 0x100u * ((sel >> 3) & 3u) + NODE;
        } else if (kind == 4u && i < n) {
            co_emcy_update(&co, in[i++], now);
        } else if (kind == 5u && n - i >= 2u) {
            id = ((uint32_t)in[i] << 8 | in[i + 1]) & 0x7FFu;
            i += 2u;
        } else if (kind == 7u) {
            id = CO_ID_HB + 5u;
        } else if (kind == 6u && n - i >= 2u) {
            id = 0x80000000u | 0x1FC00000u | ((uint32_t)in[i] << 8 | in[i + 1]);
            i += 2u;
        }
        if (n - i < len) {
            len = (uint8_t)(n - i);
        }
        memcpy(f, &in[i], len);
        i += len;
        (void)co_rx(&co, id, f, len, now);
        if (i < n) {
            now += (uint32_t)in[i++] * 1000u;
        }
        co_poll(&co, now);
        if (co.sdo_pos > sizeof co.sdo_buf || co.sdo_mode > 2u || co.hb.active[0] > 1u) {
            __builtin_trap();
        }
        for (unsigned k = 0; k < CO_PDO_N; k++) {
            if (co.pdo.rx[k].len > 8u || co.pdo.tx[k].len > 8u ||
                co.pdo.rx[k].nslots > CO_PDO_MAP_MAX || co.pdo.tx[k].nslots > CO_PDO_MAP_MAX) {
                __builtin_trap();
            }
        }
    }
    return 0;
}
