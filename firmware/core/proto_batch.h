/*
 * proto_batch.h - block batches of queue_batch: the record codec and the
 * drive's intake (protocol/README.md, "Block batches").
 *
 * Specification
 * -------------
 * A batch carries `count` blocks numbered first_seq, first_seq + 1, ... as
 * records, each a head byte
 *     bits 0..3  axis mask: a delta follows for each of these axes
 *     bit  4     PROTO_BATCH_HEAD_FEED: a feed follows the deltas
 *     bit  5     PROTO_BATCH_HEAD_EXACT_STOP
 *     bits 6..7  PROTO_BATCH_KIND_* (line, rapid, dwell, origin)
 * then the deltas (zigzag LEB128, nm, axis order) and the feed (LEB128:
 * line nm/s, dwell ms). A delta is relative to the stream's point: the
 * target of the previous block of the stream (a dwell keeps it); an axis
 * without a delta keeps its coordinate. A line without a feed runs at the
 * stream's feed (the last line feed given). An origin record is no block:
 * its masked axes take the absolute values that follow (zigzag LEB128), the
 * other axes 0; two origin records in a row are malformed, and origin
 * records after a batch's last block are ignored. Integers are at most 10
 * bytes, the last byte's high bit clear; a value above 2^64 - 1 is malformed.
 *
 * Intake (proto_batch_request, main context): the whole batch is parsed
 * first (well-formed, `count` blocks); a malformed one is refused whole
 * (error bad_value with the record index, bad_length when the count
 * differs) and changes nothing. A batch without PROTO_BATCH_FLAG_START
 * must begin at the block the drive expects (next_seq), else nothing is
 * taken (status sequence). A start batch begins a new stream at its
 * first_seq - unless it starts where the current stream started (the same
 * start batch again, a retry its replay cache no longer holds: status
 * sequence; hosts start each job at a new, random block number) or the
 * ring still holds blocks of the current stream (status busy). Then its blocks are checked in order
 * against what the planner would refuse whatever its state (positions within
 * +-PROTO_POS_LIMIT_NM and 0 on axes the drive does not have, line feed
 * 1..SC_V_LIMIT, dwell 1..PROTO_DWELL_MAX_MS, a move shorter than
 * SC_LEN_MAX, the soft travel limits) and their records copied, as they
 * are, into the intake ring (PROTO_BATCH_RING bytes) until one is refused
 * or the ring is full: the reply (batch_reply) says how many were taken
 * (a prefix), the block expected next, the refusal of the first one not
 * taken (status, arg), and the window after them: the ring's free bytes,
 * the planned time queued, blocks done and the state, read once. A drive
 * that would refuse any block now (drive_accepting: disabled, faulted,
 * stopping, homing) takes nothing (status disabled / faulted / busy).
 *
 * The ring holds about 1000 short blocks (4 bytes each for a 10 um move
 * of one axis at the stream's feed) in the RAM of 28 host-FIFO entries.
 * proto_batch_pump (main: after each batch and from proto_dispatch_poll)
 * decodes it into drive_queue_block while the drive's host FIFO has room.
 * A block the drive refuses there (it faulted, stopped or was disabled
 * meanwhile) ends the stream: the ring is emptied, next_seq goes back to
 * that block and every later batch gets its refusal (status, arg) until a
 * start batch. proto_batch_flush (stop, estop, watchdog) empties the ring
 * the same way (status busy). Nothing of the ring reaches the planner
 * after a stop.
 *
 * No heap; the stream state (proto_batch_t) is main's.
 */
#ifndef PROTO_BATCH_H
#define PROTO_BATCH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "proto_msgs.h"

#define PROTO_BATCH_VARINT_MAX 10u /* bytes of one LEB128 integer */
#define PROTO_BATCH_AXIS_MASK  0x0Fu

/* One decoded block. */
typedef struct {
    uint8_t kind; /* PROTO_BATCH_KIND_LINE, _RAPID or _DWELL */
    bool exact_stop;
    int64_t from[PROTO_MAX_AXES];   /* the stream's point before it, nm */
    int64_t target[PROTO_MAX_AXES]; /* absolute, nm (a dwell: the stream's point) */
    uint64_t feed;                  /* line: nm/s; dwell: ms; rapid: 0 */
} proto_batch_block_t;

/* Reading position in a batch. */
typedef struct {
    const uint8_t *p;
    size_t left;
    int64_t pt[PROTO_MAX_AXES]; /* the stream's point */
    uint64_t feed;              /* the stream's feed (0: none yet) */
    uint16_t record;            /* records read (origin records included) */
} proto_batch_rd_t;

#ifndef PROTO_BATCH_RING
#define PROTO_BATCH_RING 4096u /* intake ring, bytes */
#endif
/* Longest record: head, 4 deltas and a feed of 10 bytes each. */
#define PROTO_BATCH_RECORD_MAX (1u + 5u * PROTO_BATCH_VARINT_MAX)

/* The stream of one host and its intake ring (all main context). */
typedef struct {
    bool started;               /* a start batch was taken this session */
    uint8_t broken;             /* error code that ended the stream, 0 none */
    uint16_t broken_arg;        /* its arg */
    uint32_t start_seq;         /* first_seq of the start batch */
    uint32_t next_seq;          /* block number expected next */
    int64_t pt[PROTO_MAX_AXES]; /* the stream's point after block next_seq - 1 */
    uint64_t feed;              /* the stream's feed after it, nm/s */
    /* ring of records taken and not yet queued */
    uint8_t ring[PROTO_BATCH_RING];
    uint16_t head, used;             /* oldest byte, bytes held */
    uint32_t pump_seq;               /* block number of the oldest record's block */
    int64_t pump_pt[PROTO_MAX_AXES]; /* decoder state at the ring's head */
    uint64_t pump_feed;
} proto_batch_t;

void proto_batch_reset(proto_batch_t *s);

void proto_batch_rd_init(proto_batch_rd_t *rd, const uint8_t *data, size_t n,
                         const int64_t pt[PROTO_MAX_AXES], uint64_t feed);

/* Next block into *b: 1; 0 at the end of the data; -1 malformed (the
 * record index is rd->record - 1). A line without any feed so far is
 * malformed. */
int proto_batch_rd_next(proto_batch_rd_t *rd, proto_batch_block_t *b);

/* Append the record of b (deltas from pt, feed only when it differs from
 * *feed for a line, always for a dwell) and update pt and *feed; returns
 * the bytes written, 0 when cap is too small. origin != 0: write an origin
 * record of pt first (all PROTO_MAX_AXES axes). For tests, fuzzing and
 * hosts in C. */
size_t proto_batch_put(uint8_t *buf, size_t cap, const proto_batch_block_t *b,
                       int64_t pt[PROTO_MAX_AXES], uint64_t *feed, int origin);

/* Queue what the drive's host FIFO takes from the ring (see above). Main. */
void proto_batch_pump(proto_batch_t *s);

/* Empty the ring and end the stream with `code` (a stop). Main. */
void proto_batch_flush(proto_batch_t *s, uint8_t code);

/* Bytes free in the ring. */
static inline uint16_t proto_batch_free(const proto_batch_t *s)
{
    return (uint16_t)(PROTO_BATCH_RING - s->used);
}

/* Handle a queue_batch payload p[n] of a drive with `axes` axes: the reply
 * message (batch_reply or error) into out (PROTO_MSG_MAX bytes); returns its
 * length. Main. */
size_t proto_batch_request(proto_batch_t *s, unsigned axes, uint8_t seq, const uint8_t *p, size_t n,
                           uint8_t *out);

#endif /* PROTO_BATCH_H */
