/*
 * canopen.h - CiA 301 communication on the drive: NMT slave, boot-up and
 * heartbeat producer, SDO server (expedited and segmented), and the
 * communication objects of the object dictionary (docs/canopen.md).
 *
 * Specification
 * -------------
 * Identifiers (predefined connection set, node id n = 1..127):
 *   0x000          NMT command from the master: DLC 2, cs | node (0 = all)
 *   0x580 + n      SDO server -> client (responses, aborts)
 *   0x600 + n      SDO client -> server (requests)
 *   0x700 + n      boot-up (one byte 0x00) and heartbeat (one byte state)
 *   0x700 + m      heartbeats of the nodes 0x1016 watches (co_hb.h)
 *   0x1005         SYNC (default 0x080; co_sync.h), 0x1014 EMCY (0x080 + n;
 *                  co_emcy.h), 0x1400/0x1800:1 the PDOs (co_pdo.h)
 * co_rx() takes every received classic-CAN frame and returns true for the
 * ones it consumed (the ids above), false for the others (our own protocol
 * on 29-bit ids, other nodes' CANopen traffic). A 29-bit id (HAL_CAN_EFF)
 * is never CANopen's.
 *
 * NMT: after co_init (and after reset node / reset communication) the node
 * sends its boot-up frame and enters PRE-OPERATIONAL. start -> OPERATIONAL,
 * stop -> STOPPED, enter pre-op -> PRE-OPERATIONAL, reset node resets every
 * object to its default, reset communication the 0x1000-0x1FFF ones. An NMT
 * frame whose DLC is not 2, or with an unknown command, is ignored (counted).
 * In STOPPED only NMT and the heartbeat work: SDO requests are ignored.
 *
 * Heartbeat: the state byte (0x04 stopped, 0x05 operational, 0x7F
 * pre-operational) every 0x1017 ms (0 = off), measured from the boot-up.
 *
 * SDO server: one transfer at a time. Request frames must have DLC 8 (CiA
 * 301); shorter ones are ignored and counted (a client's segmented transfer
 * then runs into the SDO timeout). Abort codes (CO_ABORT_*):
 *   unknown / block command specifier      0x05040001
 *   toggle bit not alternated              0x05030000
 *   no segment for CO_SDO_TIMEOUT_US       0x05040000
 *   object does not exist                  0x06020000
 *   sub-index does not exist               0x06090011
 *   write to a read-only object            0x06010002
 *   length does not match / too high / low 0x06070010 / 0x06070012 / 0x06070013
 *   value above max / below min            0x06090031 / 0x06090032
 *   value refused by the object's rules    0x06090030 (PDO / SYNC / EMCY
 *                                          COB-ID, 0x6060 mode; co_pdo.h)
 *   object not mappable / PDO too long     0x06040041 / 0x06040042
 *   PDO parameter while the PDO is valid   0x06010000
 *   0x1016 entry for a node already watched 0x06040043 (co_hb.h)
 *   drive busy / store refused (co_param.h) 0x08000022 / 0x08000020,
 *   flash failed                          0x06060000
 * Expedited downloads without a size indication take the object's size.
 * A segment without an open transfer is answered with 0x05040001. An abort
 * from the client ends the transfer silently. A new initiate during a
 * segmented transfer abandons it (the client restarted).
 *
 * Context: main only. No heap, no floating point. Times are hal_time_us()
 * values (uint32, wrapping). Frames that cannot be sent at once wait in a
 * ring of CO_TX_RING; a full ring drops the frame (counted in tx_dropped).
 */
#ifndef CANOPEN_H
#define CANOPEN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "canopen_od.h"
#include "co_emcy.h"
#include "co_hb.h"
#include "co_pdo.h"
#include "co_sync.h"

#define CO_SDO_TIMEOUT_US 1000000u
#define CO_TX_RING        8u

#define CO_ID_NMT     0x000u
#define CO_ID_TSDO    0x580u
#define CO_ID_RSDO    0x600u
#define CO_ID_HB      0x700u
#define CO_DEVICE_402 0x00020192u /* CiA 402 drive, servo (0x1000) */

#define CO_ABORT_TOGGLE     0x05030000u
#define CO_ABORT_TIMEOUT    0x05040000u
#define CO_ABORT_COMMAND    0x05040001u
#define CO_ABORT_READONLY   0x06010002u
#define CO_ABORT_NO_OBJECT  0x06020000u
#define CO_ABORT_LEN        0x06070010u
#define CO_ABORT_LEN_HIGH   0x06070012u
#define CO_ABORT_LEN_LOW    0x06070013u
#define CO_ABORT_NO_SUB     0x06090011u
#define CO_ABORT_VALUE_HIGH 0x06090031u
#define CO_ABORT_VALUE_LOW  0x06090032u
#define CO_ABORT_VALUE      0x06090030u
#define CO_ABORT_ACCESS     0x06010000u
#define CO_ABORT_NO_MAP     0x06040041u
#define CO_ABORT_MAP_LEN    0x06040042u

typedef enum {
    CO_NMT_INIT = 0x00,
    CO_NMT_STOPPED = 0x04,
    CO_NMT_OPERATIONAL = 0x05,
    CO_NMT_PREOP = 0x7F,
} co_nmt_state_t;

/* Transmit one classic CAN frame (11-bit id); false when the mailbox is full. */
typedef bool (*co_tx_fn)(void *ctx, uint32_t id, const uint8_t *data, uint8_t len);

/* Called after an SDO download stored a new value (main context). */
typedef void (*co_write_hook_fn)(void *ctx, uint16_t index, uint8_t sub);

/* Called at each SYNC the node acts on (main context, co_sync.h): phase
 * CO_SYNC_SAMPLE before the synchronous TPDOs sample their objects (refresh
 * the inputs, e.g. 0x6064), CO_SYNC_APPLY after the synchronous RPDOs
 * wrote theirs (act on the outputs, e.g. 0x607A in CSP). */
enum { CO_SYNC_SAMPLE = 0, CO_SYNC_APPLY = 1 };
typedef void (*co_sync_hook_fn)(void *ctx, int phase, uint32_t now_us);

/* Called before an SDO download stores a value of an object that has no
 * rules in the CiA 301 modules; 0 lets it through, else the abort code
 * (e.g. 0x6060's supported modes). An RPDO's data are not checked. */
typedef uint32_t (*co_check_hook_fn)(void *ctx, uint16_t index, uint8_t sub, uint32_t value);

typedef struct co_config_s {
    uint8_t node_id; /* 1..127 */
    uint32_t vendor_id;
    uint32_t product_code;
    uint32_t revision;
    uint32_t serial;
} co_config_t;

typedef struct {
    uint32_t nmt_ignored; /* NMT frames with a bad DLC or command */
    uint32_t sdo_short;   /* SDO requests with DLC < 8 (ignored) */
    uint32_t sdo_aborts;  /* aborts sent */
    uint32_t tx_dropped;  /* frames lost to a full transmit ring */
} co_stats_t;

typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t data[8];
} co_frame_t;

typedef struct co_s {
    co_config_t cfg;
    co_od_vars_t od;
    co_nmt_state_t nmt;
    co_stats_t stats;
    co_tx_fn tx;
    void *tx_ctx;
    co_write_hook_fn on_write; /* NULL: none */
    void *hook_ctx;
    co_sync_hook_fn on_sync;   /* NULL: none */
    co_check_hook_fn on_check; /* NULL: none */
    co_pdo_t pdo;
    co_sync_t sync;
    co_emcy_t emcy;
    co_hb_t hb;
    uint32_t hb_last_us;
    /* SDO transfer (segmented) */
    uint8_t sdo_mode; /* 0 idle, 1 download, 2 upload */
    uint8_t sdo_toggle;
    uint16_t sdo_index;
    uint8_t sdo_sub;
    uint32_t sdo_size; /* download: indicated (0 = none); upload: total */
    uint32_t sdo_pos;
    uint32_t sdo_last_us;
    uint8_t sdo_buf[CO_STR_MAX];
    /* transmit ring */
    co_frame_t txq[CO_TX_RING];
    uint8_t txq_head, txq_tail;
} co_t;

/* Reset everything to defaults, send boot-up, enter PRE-OPERATIONAL. */
void co_init(co_t *co, const co_config_t *cfg, co_tx_fn tx, void *ctx, uint32_t now_us);
/* One received frame; true when it was a CANopen frame for this node. */
bool co_rx(co_t *co, uint32_t id, const uint8_t *data, uint8_t len, uint32_t now_us);
/* Heartbeat, SDO timeout, transmit retries. Call every main loop pass. */
void co_poll(co_t *co, uint32_t now_us);
co_nmt_state_t co_nmt_state(const co_t *co);
void co_set_error_register(co_t *co, uint8_t reg);
/* Hook called after every successful SDO download (co_init clears it). */
void co_set_write_hook(co_t *co, co_write_hook_fn fn, void *ctx);
/* Hooks called at SYNC and before an SDO write (co_init clears them; the
 * write hook's ctx). */
void co_set_sync_hook(co_t *co, co_sync_hook_fn fn);
void co_set_check_hook(co_t *co, co_check_hook_fn fn);

/* For the PDO, SYNC and EMCY modules: the object dictionary entry (NULL and
 * *abort set when there is none), its variable, and a frame to send. */
const co_od_entry_t *co_od_find(uint16_t index, uint8_t sub, uint32_t *abort);
uint8_t *co_od_var(co_t *co, const co_od_entry_t *e);
/* co_od.c: the value's size now (a string's length), its bytes
 * (little-endian), and a checked write of n bytes (0 or the abort code). */
uint32_t co_od_size(co_t *co, const co_od_entry_t *e);
void co_od_read(co_t *co, const co_od_entry_t *e, uint8_t *out);
uint32_t co_od_write(co_t *co, const co_od_entry_t *e, const uint8_t *in, uint32_t n);
void co_send(co_t *co, uint32_t id, const uint8_t *data, uint8_t len);

#endif
