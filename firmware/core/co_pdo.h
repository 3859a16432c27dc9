/*
 * co_pdo.h - CiA 301 process data objects of the drive's CANopen node:
 * CO_PDO_N receive (RPDO) and CO_PDO_N transmit (TPDO) PDOs of up to
 * CO_PDO_MAP_MAX mapped objects each.
 *
 * Specification
 * -------------
 * Configuration is the object dictionary (protocol/canopen.toml):
 * 0x1400+k / 0x1800+k communication (sub 1 COB-ID, bit 31 = not valid,
 * bit 30 RTR not allowed (accepted, RTR is never served), bit 29 = 29-bit
 * id (refused); sub 2 transmission type; TPDO sub 3 inhibit time (100 us),
 * sub 5 event timer (ms)), 0x1600+k / 0x1A00+k mapping (sub 0 count, subs
 * 1..8 index << 16 | sub << 8 | bits). The CiA 301 sequence is enforced:
 *   - COB-ID: a valid PDO's id cannot change (write bit 31 first); a valid
 *     id must be 11-bit, 0x001..0x7FF, outside CiA 301's restricted ids
 *     (0x000, 0x001-0x07F, 0x101-0x180, 0x581-0x5FF, 0x601-0x67F,
 *     0x6E0-0x6FF, 0x701-0x7FF): else 0x06090030;
 *   - mapping: written only while the PDO is not valid (else 0x06010000),
 *     an entry only while sub 0 is 0 (else 0x06010000); an entry must name
 *     an existing PDO-mappable object with its exact size in bits (RPDO: a
 *     writable one) or be 0 (else 0x06040041); sub 0 = n needs entries
 *     1..n valid and at most 64 bits in all (else 0x06040041 / 0x06040042);
 *   - transmission type: RPDO 0..240 (synchronous: applied at the next
 *     SYNC) or 254/255 (applied on reception); TPDO 0 (at a SYNC when the
 *     data changed), 1..240 (every n-th SYNC), 254/255 (on change, at most
 *     every inhibit time, and every event timer if not 0); RTR types
 *     252/253 and 241..251 are refused (0x06090030); inhibit time only
 *     while the PDO is not valid (else 0x06010000).
 * PDOs run in NMT OPERATIONAL only. A received RPDO shorter than its
 * mapping is ignored (counted in rpdo_short); a synchronous RPDO received
 * twice before a SYNC keeps the newer data (counted in rpdo_overrun).
 * Every object an RPDO writes goes through the node's write hook, as an SDO
 * download does (the controlword of an RPDO runs the 402 state machine).
 * Mapped data are little-endian, objects byte-aligned.
 *
 * Context: main only. No heap. RAM: co_pdo_t (about 420 bytes) plus the
 * configuration objects in co_od_vars_t.
 */
#ifndef CO_PDO_H
#define CO_PDO_H

#include <stdbool.h>
#include <stdint.h>

#define CO_PDO_N       4u
#define CO_PDO_MAP_MAX 8u

typedef struct {
    uint16_t off; /* variable in co_od_vars_t */
    uint8_t len;  /* bytes */
} co_pdo_slot_t;

typedef struct {
    co_pdo_slot_t slot[CO_PDO_MAP_MAX];
    uint8_t nslots;
    uint8_t len;      /* frame bytes */
    bool valid;       /* COB-ID valid and mapping resolved */
    bool pending;     /* RPDO: data waiting for the SYNC; TPDO: sent once */
    uint8_t syncs;    /* TPDO: SYNCs since it was last sent */
    uint8_t data[8];  /* RPDO: data received; TPDO: data last sent */
    uint32_t last_us; /* TPDO: last transmission */
} co_pdo_ch_t;

typedef struct {
    co_pdo_ch_t rx[CO_PDO_N];
    co_pdo_ch_t tx[CO_PDO_N];
    uint32_t rpdo_short;   /* RPDOs shorter than their mapping */
    uint32_t rpdo_overrun; /* synchronous RPDO data replaced before a SYNC */
    uint32_t tpdo_sent;
} co_pdo_t;

struct co_s;

/* Resolve every PDO from the object dictionary (after co_od_defaults). */
void co_pdo_init(struct co_s *co);
/* 0 or the abort code for `value` written to index:sub (0x1400-0x1BFF). */
uint32_t co_pdo_check(const struct co_s *co, uint16_t index, uint8_t sub, uint32_t value);
/* After a write to 0x1400-0x1BFF: resolve that PDO again. */
void co_pdo_written(struct co_s *co, uint16_t index);
/* A received frame on a valid RPDO's COB-ID? Then it is handled: true. */
bool co_pdo_rx(struct co_s *co, uint32_t id, const uint8_t *data, uint8_t len);
/* At a SYNC (co_sync.c): synchronous TPDOs, then synchronous RPDOs. */
void co_pdo_sync(struct co_s *co, uint32_t now_us);
/* Event-driven TPDOs (types 254/255). */
void co_pdo_poll(struct co_s *co, uint32_t now_us);

#endif
