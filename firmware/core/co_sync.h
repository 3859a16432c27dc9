/*
 * co_sync.h - CiA 301 SYNC consumer of the drive's CANopen node.
 *
 * Specification
 * -------------
 * The SYNC COB-ID is 0x1005 (default 0x080). Only consuming is supported:
 * a write that sets bit 30 (generate SYNC) or bit 29 (29-bit id), or names
 * an id above 0x7FF, is refused with 0x06090030. A SYNC frame has DLC 0, or
 * 1 (the counter of CiA 301 v4.2, read and ignored); another DLC is counted
 * in bad_len and ignored. Only in NMT OPERATIONAL does a SYNC act: it runs
 * the synchronous PDOs (co_pdo_sync: TPDO sampling, then the RPDOs written
 * before it) and the node's SYNC hook (canopen.h), and is counted.
 * 0x1006 (communication cycle period, us; 0 = not checked): a gap between
 * two SYNCs above 1.5 periods counts in `late` (a missed SYNC). The gap
 * since the first SYNC is checked from the second one on.
 *
 * Context: main only (the frame comes through co_rx). No heap.
 */
#ifndef CO_SYNC_H
#define CO_SYNC_H

#include <stdbool.h>
#include <stdint.h>

typedef struct {
    uint32_t count;      /* SYNCs acted on                                  */
    uint32_t last_us;    /* time of the last one (co_rx's now_us)           */
    uint32_t late;       /* gaps above 1.5 x 0x1006                         */
    uint32_t bad_len;    /* SYNC frames with DLC > 1 (ignored)              */
    uint32_t gap_max_us; /* longest gap between two SYNCs acted on       */
} co_sync_t;

struct co_s;

/* The SYNC frame of this node's 0x1005? Then it is handled: true. */
bool co_sync_rx(struct co_s *co, uint32_t id, uint8_t len, uint32_t now_us);
/* 0 or the abort code for a value written to 0x1005 / 0x1006. */
uint32_t co_sync_check(const struct co_s *co, uint16_t index, uint32_t value);

#endif
