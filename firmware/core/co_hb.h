/*
 * co_hb.h - CiA 301 heartbeat consumer of the drive's CANopen node: the
 * master's heartbeat as the communication watchdog (docs/canopen.md).
 *
 * Specification
 * -------------
 * 0x1016:1..CO_HB_CONSUMERS: node id (bits 16..23) and time in ms (bits
 * 0..15); an entry whose node id or time is 0 is unused. Bits 24..31 set or
 * node id > 127 -> abort 0x06090030; two used entries with the same node
 * id -> 0x06040043. Writing an entry restarts it (waiting).
 * co_hb_rx takes a frame 0x700 + node of DLC >= 1 (a heartbeat or boot-up)
 * of a node some used entry watches and returns true; the entry is then
 * active from that time (monitoring starts with the first heartbeat, CiA
 * 301). co_hb_poll: an active entry with no heartbeat for its time times
 * out once (back to waiting until the next heartbeat), counted in `lost`,
 * and the node reacts as 0x1029:1 says: 0 OPERATIONAL -> PRE-OPERATIONAL,
 * 1 nothing, 2 -> STOPPED. The drive's reaction (controlled stop, fault,
 * EMCY 0x8130) is co_drive.h's, on a change of `lost`.
 * co_hb_alive: whether a frame co_rx consumed is a sign of life for the
 * drive's link watchdog: any CANopen frame while no entry is used, else
 * only the watched heartbeats.
 * NMT reset node / communication clears the entries (0x1016 is a
 * communication object) and their state. Main context only.
 */
#ifndef CO_HB_H
#define CO_HB_H

#include <stdbool.h>
#include <stdint.h>

#define CO_HB_CONSUMERS       4u
#define CO_ABORT_PARAM_INCOMP 0x06040043u /* general parameter incompatibility */

typedef struct {
    uint32_t last_us[CO_HB_CONSUMERS]; /* time of the last heartbeat */
    uint8_t active[CO_HB_CONSUMERS];   /* 1: heartbeat seen, watching */
    uint32_t lost;                     /* timeouts so far */
} co_hb_t;

struct co_s;

bool co_hb_rx(struct co_s *co, uint32_t id, uint8_t len, uint32_t now_us);
void co_hb_poll(struct co_s *co, uint32_t now_us);
bool co_hb_alive(const struct co_s *co, uint32_t id);
uint32_t co_hb_check(const struct co_s *co, uint8_t sub, uint32_t value);
void co_hb_written(struct co_s *co, uint8_t sub);

#endif
