/*
 * feed.h - the drive's feed path: host-block FIFO -> planner -> the
 * interpolator's FIFO (main context).
 *
 * Specification
 * -------------
 * Host blocks (drive_block_t) are validated against the end point of the
 * last accepted block (all or nothing) and queued in a FIFO of
 * DRIVE_QUEUE_DEPTH entries; each is pushed into the planner as one block
 * (LINE), one dwell (DWELL) or its chords (ARC, arc_seg.h), each planner
 * block getting an internal sequence tag whose segment record (feed_seg_t:
 * host tag, last segment of its host block, the arc chord) the tick reads
 * by the interpolator's tag. When a planner block is popped into the
 * interpolator is drive.h's "Feeding": every waiting host block is pushed
 * before each pop; a block is popped when the planner is full, when the
 * oldest block's plan is final, or when no block is waiting and the
 * interpolator would run short (less than FEED_AHEAD_NS queued beyond its
 * current segment or, idle, no block accepted for cfg->start_delay_ms).
 *
 * Contexts: every function is main context except the inline readers
 * feed_seg() and feed_busy(), which the tick calls. Writers of the shared
 * fields: main writes hq_*, the planner, seq_next and the seg[] records of
 * segments not yet handed to the interpolator (the tick reads only those
 * it was handed: SEG_RING exceeds planner depth + interpolator FIFO + 1);
 * the interpolator's FIFO is single-producer (main, here) single-consumer
 * (the tick, interp_tick).
 */
#ifndef FEED_H
#define FEED_H

#include <stdbool.h>
#include <stdint.h>

#include "arc_ref.h"
#include "arc_seg.h"
#include "drive.h"
#include "interp.h"
#include "planner.h"
#include "preempt.h"

#define FEED_SEG_RING 128u /* > planner depth + interpolator FIFO + 1 */
/* Keep at least this much planned time in the interpolator's FIFO beyond
 * the current segment when no block is waiting and the planner is not
 * full. */
#define FEED_AHEAD_NS ((int64_t)5000000)

/* The record of one planner block (one interpolator segment). */
typedef struct {
    uint32_t host_tag; /* the host block's tag                  */
    bool last;         /* last segment of its host block         */
    bool arc;          /* a chord of an arc: c holds it         */
    arc_chord_t c;
} feed_seg_t;

/* One host block waiting in the FIFO. */
typedef struct {
    drive_block_t b;
    arc_seg_t arc; /* ARC: the chords, and those handed on */
} feed_block_t;

typedef struct {
    const drive_config_t *cfg; /* the drive's configuration (read)  */
    interp_t *ip;              /* producer side only                */
    plan_t plan;
    feed_block_t hq[DRIVE_QUEUE_DEPTH];
    uint16_t hq_head, hq_count; /* main                            */
    pos_nm_t q_end[CORE_AXES];  /* end point of the last accepted block */
    uint32_t seq_next;          /* tag of the next planner block */
    uint32_t queued_at;         /* tick count when the last block was accepted */
    /* main: the last planner move was a chord of an arc that did not end in
     * an exact stop, and that arc's plane, centre and sense (a next arc on
     * the same circle continues it: PLAN_MOVE_ARC_JOIN at their join) */
    bool arc_open;
    drive_plane_t arc_plane;
    pos_nm_t arc_cu, arc_cv;
    int8_t arc_sense;
    feed_seg_t seg[FEED_SEG_RING]; /* main, before the segment's interp slot */
    CORE_SHARED uint32_t skipped;  /* main: host blocks done without a segment
                                    * (zero length or refused by the planner) */
    /* main: hq_count + plan_count, published at the end of feed_queue and
     * feed_poll, after the interpolator's wr: the tick (feed_busy) never
     * sees a block in transit as nothing queued */
    CORE_SHARED uint32_t queued;
} feed_t;

/* Set up empty at `origin` over the planner ring store[depth] with the
 * profile and tick of cfg (kept by pointer), feeding the interpolator ip
 * (initialised here). False when the planner refuses the profile. */
bool feed_init(feed_t *f, const drive_config_t *cfg, interp_t *ip, plan_block_t *store,
               uint16_t depth, const pos_nm_t origin[CORE_AXES]);

/* Drop every queued block, planned or interpolated, and hold pos. Main,
 * with the tick parked (not executing the interpolator: drive state
 * DISABLED, FAULT or halted; the tick resets the interpolator's time step
 * when it leaves that state). */
void feed_flush(feed_t *f, const pos_nm_t pos[CORE_AXES]);

/* Validate b against the end point of the last accepted block and queue
 * it (tick count `now` for the start delay), then push what the planner
 * takes. DRIVE_E_INVALID (malformed), DRIVE_E_FULL (FIFO full) or
 * DRIVE_OK; nothing changes unless DRIVE_OK. */
drive_result_t feed_queue(feed_t *f, const drive_block_t *b, uint32_t now);

/* The feeding loop (see above) at tick count `now`. */
void feed_poll(feed_t *f, uint32_t now);

/* Nothing waiting, planned or in the interpolator (main's own counts and
 * the interpolator's indices). Main. */
bool feed_idle(const feed_t *f);

/* Free host-block slots. */
static inline uint32_t feed_free(const feed_t *f)
{
    return (uint32_t)(DRIVE_QUEUE_DEPTH - f->hq_count);
}

/* Planned time queued: the planner's, plus the interpolator's FIFO from
 * its read index rd (published by the tick) with the current segment's
 * time left rem_rd (interp_queued_ns). */
int64_t feed_queued_ns(const feed_t *f, uint16_t rd, int64_t rem_rd);

/* Replace the planner's profile (the planner must be empty; it is
 * re-initialised at its position). */
void feed_set_profile(feed_t *f, const plan_profile_t *prof);

/* The record of the segment with interpolator tag `tag`. Tick (segments
 * handed to the interpolator) or main. */
static inline const feed_seg_t *feed_seg(const feed_t *f, uint32_t tag)
{
    return &f->seg[tag % FEED_SEG_RING];
}

/* Tag of the next planner block (all before it were pushed). */
static inline uint32_t feed_seq_next(const feed_t *f)
{
    return f->seq_next;
}

/* Host blocks completed without a segment. Any. */
static inline uint32_t feed_skipped(const feed_t *f)
{
    return f->skipped;
}

/* Something waiting, planned or in the interpolator: the tick's test
 * (inline for its state update; its own busy flag first: the usual case;
 * main's part through `queued`). Tick. */
static inline bool feed_busy(const feed_t *f)
{
    return interp_busy(f->ip) || !interp_idle(f->ip) || f->queued != 0u;
}

#endif /* FEED_H */
