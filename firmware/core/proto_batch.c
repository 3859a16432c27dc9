/*
 * proto_batch.c - block batches: record codec and drive intake (see
 * proto_batch.h).
 */
#include "proto_batch.h"

#include "drive.h"
#include "fixmath.h"
#include "preempt.h"
#include "proto_dispatch.h"
#include "proto_reply.h"

void proto_batch_reset(proto_batch_t *s)
{
    unsigned i;

    s->started = false;
    s->broken = PROTO_ERROR_CODE_NONE;
    s->broken_arg = 0;
    s->start_seq = 0;
    s->next_seq = 0;
    for (i = 0; i < PROTO_MAX_AXES; i++) {
        s->pt[i] = 0;
        s->pump_pt[i] = 0;
    }
    s->feed = 0;
    s->head = 0;
    s->used = 0;
    s->pump_seq = 0;
    s->pump_feed = 0;
}

void proto_batch_rd_init(proto_batch_rd_t *rd, const uint8_t *data, size_t n,
                         const int64_t pt[PROTO_MAX_AXES], uint64_t feed)
{
    unsigned i;

    rd->p = data;
    rd->left = n;
    for (i = 0; i < PROTO_MAX_AXES; i++) {
        rd->pt[i] = pt[i];
    }
    rd->feed = feed;
    rd->record = 0;
}

/* LEB128: false when the data ends inside it, it is longer than 10 bytes
 * or exceeds 64 bits. */
static bool get_uvar(proto_batch_rd_t *rd, uint64_t *v)
{
    uint64_t x = 0;
    unsigned k;

    for (k = 0; k < PROTO_BATCH_VARINT_MAX; k++) {
        uint8_t c;

        if (rd->left == 0u) {
            return false;
        }
        c = *rd->p++;
        rd->left--;
        if (k == PROTO_BATCH_VARINT_MAX - 1u && c > 1u) {
            return false; /* bit 64 and beyond */
        }
        x |= (uint64_t)(c & 0x7Fu) << (7u * k);
        if ((c & 0x80u) == 0u) {
            *v = x;
            return true;
        }
    }
    return false;
}

static bool get_svar(proto_batch_rd_t *rd, int64_t *v)
{
    uint64_t z;

    if (!get_uvar(rd, &z)) {
        return false;
    }
    /* zigzag: 0, -1, 1, -2 ... -> 0, 1, 2, 3 ... */
    *v = (int64_t)(z >> 1) ^ -(int64_t)(z & 1u);
    return true;
}

int proto_batch_rd_next(proto_batch_rd_t *rd, proto_batch_block_t *b)
{
    bool origin = false;

    for (;;) {
        uint8_t head;
        uint8_t kind;
        unsigned i;
        int64_t v;

        if (rd->left == 0u) {
            return 0;
        }
        head = *rd->p++;
        rd->left--;
        rd->record++;
        kind = (uint8_t)(head >> PROTO_BATCH_HEAD_KIND);
        if (kind == PROTO_BATCH_KIND_ORIGIN) {
            if (origin || (head & ((1u << PROTO_BATCH_HEAD_FEED) |
                                   (1u << PROTO_BATCH_HEAD_EXACT_STOP))) != 0u) {
                return -1; /* two in a row, or flags an origin has not */
            }
            origin = true;
            for (i = 0; i < PROTO_MAX_AXES; i++) {
                rd->pt[i] = 0;
                if ((head & (1u << i)) != 0u && !get_svar(rd, &rd->pt[i])) {
                    return -1;
                }
            }
            continue;
        }
        for (i = 0; i < PROTO_MAX_AXES; i++) {
            b->from[i] = rd->pt[i];
            if ((head & (1u << i)) != 0u) {
                if (!get_svar(rd, &v)) {
                    return -1;
                }
                /* wrap-free: a sum beyond int64 is refused, not wrapped */
                if ((v > 0 && rd->pt[i] > INT64_MAX - v) || (v < 0 && rd->pt[i] < INT64_MIN - v)) {
                    return -1;
                }
                rd->pt[i] += v;
            }
            b->target[i] = rd->pt[i];
        }
        b->kind = kind;
        b->exact_stop = (head & (1u << PROTO_BATCH_HEAD_EXACT_STOP)) != 0u;
        b->feed = 0;
        if ((head & (1u << PROTO_BATCH_HEAD_FEED)) != 0u) {
            if (!get_uvar(rd, &b->feed)) {
                return -1;
            }
        }
        switch (kind) {
        case PROTO_BATCH_KIND_LINE:
            if ((head & (1u << PROTO_BATCH_HEAD_FEED)) != 0u) {
                rd->feed = b->feed;
            }
            if (rd->feed == 0u) {
                return -1;
            }
            b->feed = rd->feed;
            break;
        case PROTO_BATCH_KIND_RAPID:
            if ((head & (1u << PROTO_BATCH_HEAD_FEED)) != 0u) {
                return -1;
            }
            break;
        default: /* dwell: a duration, no motion */
            if ((head & ((1u << PROTO_BATCH_HEAD_FEED) | PROTO_BATCH_AXIS_MASK)) !=
                (1u << PROTO_BATCH_HEAD_FEED)) {
                return -1;
            }
            break;
        }
        return 1;
    }
}

static size_t put_uvar(uint8_t *buf, size_t cap, size_t at, uint64_t v)
{
    do {
        if (at >= cap) {
            return 0;
        }
        buf[at++] = (uint8_t)((v & 0x7Fu) | (v > 0x7Fu ? 0x80u : 0u));
        v >>= 7;
    } while (v != 0u);
    return at;
}

static uint64_t zigzag(int64_t v)
{
    return v < 0 ? ~((uint64_t)v << 1) : (uint64_t)v << 1;
}

size_t proto_batch_put(uint8_t *buf, size_t cap, const proto_batch_block_t *b,
                       int64_t pt[PROTO_MAX_AXES], uint64_t *feed, int origin)
{
    size_t at = 0;
    size_t head_at;
    uint8_t head;
    unsigned i;

    if (origin) {
        if (cap == 0u) {
            return 0;
        }
        buf[at++] =
            (uint8_t)((PROTO_BATCH_KIND_ORIGIN << PROTO_BATCH_HEAD_KIND) | PROTO_BATCH_AXIS_MASK);
        for (i = 0; i < PROTO_MAX_AXES && at != 0u; i++) {
            at = put_uvar(buf, cap, at, zigzag(pt[i]));
        }
        if (at == 0u) {
            return 0;
        }
    }
    if (at >= cap) {
        return 0;
    }
    head_at = at++;
    head = (uint8_t)(b->kind << PROTO_BATCH_HEAD_KIND);
    if (b->exact_stop && b->kind != PROTO_BATCH_KIND_DWELL) {
        head |= 1u << PROTO_BATCH_HEAD_EXACT_STOP;
    }
    for (i = 0; i < PROTO_MAX_AXES && b->kind != PROTO_BATCH_KIND_DWELL; i++) {
        if (b->target[i] != pt[i]) {
            head |= (uint8_t)(1u << i);
            at =
                put_uvar(buf, cap, at, zigzag((int64_t)((uint64_t)b->target[i] - (uint64_t)pt[i])));
            if (at == 0u) {
                return 0;
            }
        }
    }
    if (b->kind == PROTO_BATCH_KIND_DWELL ||
        (b->kind == PROTO_BATCH_KIND_LINE && b->feed != *feed)) {
        head |= 1u << PROTO_BATCH_HEAD_FEED;
        at = put_uvar(buf, cap, at, b->feed);
        if (at == 0u) {
            return 0;
        }
    }
    buf[head_at] = head;
    if (b->kind == PROTO_BATCH_KIND_LINE) {
        *feed = b->feed;
    }
    if (b->kind != PROTO_BATCH_KIND_DWELL) {
        for (i = 0; i < PROTO_MAX_AXES; i++) {
            pt[i] = b->target[i];
        }
    }
    return at;
}

/* ---- intake ------------------------------------------------------------------ */

static bool pos_ok(int64_t v)
{
    return v >= -PROTO_POS_LIMIT_NM && v <= PROTO_POS_LIMIT_NM;
}

/* What the planner refuses whatever its state, for a block from `from`:
 * PROTO_ERROR_CODE_NONE or the refusal (*arg: field or axis). */
static uint8_t block_check(const proto_batch_block_t *b, const int64_t from[PROTO_MAX_AXES],
                           unsigned axes, uint16_t *arg)
{
    pos_nm_t t[CORE_AXES];
    pos_nm_t f[CORE_AXES];
    unsigned i;

    *arg = 0;
    if (b->kind == PROTO_BATCH_KIND_DWELL) {
        return (b->feed >= 1u && b->feed <= PROTO_DWELL_MAX_MS) ? PROTO_ERROR_CODE_NONE
                                                                : PROTO_ERROR_CODE_OUT_OF_RANGE;
    }
    if (b->kind == PROTO_BATCH_KIND_LINE && (b->feed < 1u || b->feed > (uint64_t)SC_V_LIMIT)) {
        return PROTO_ERROR_CODE_OUT_OF_RANGE;
    }
    for (i = 0; i < PROTO_MAX_AXES; i++) {
        *arg = (uint16_t)i;
        if (!pos_ok(b->target[i]) || (i >= axes && b->target[i] != 0)) {
            return PROTO_ERROR_CODE_OUT_OF_RANGE;
        }
        /* both within +-PROTO_POS_LIMIT_NM: no overflow */
        if (fx_sat_abs64(b->target[i] - from[i]) >= SC_LEN_MAX) {
            return PROTO_ERROR_CODE_BAD_VALUE;
        }
    }
    for (i = 0; i < CORE_AXES; i++) {
        t[i] = i < PROTO_MAX_AXES ? b->target[i] : 0;
        f[i] = i < PROTO_MAX_AXES ? from[i] : 0;
    }
    if (drive_soft_limit_check(t, f) != DRIVE_OK) {
        unsigned axis = 0;
        int64_t lo, hi;

        drive_soft_limit_refused(&axis, &lo, &hi);
        *arg = (uint16_t)axis;
        return PROTO_ERROR_CODE_OUT_OF_RANGE;
    }
    *arg = 0;
    return PROTO_ERROR_CODE_NONE;
}

/* drive_queue_block's refusal as error code and arg. */
static uint8_t refusal(drive_result_t r, uint16_t *arg)
{
    unsigned axis = 0;
    int64_t lo, hi;

    *arg = 0;
    switch (r) {
    case DRIVE_E_FULL:
        return PROTO_ERROR_CODE_QUEUE_FULL;
    case DRIVE_E_INVALID:
        return PROTO_ERROR_CODE_BAD_VALUE;
    case DRIVE_E_DISABLED:
        return PROTO_ERROR_CODE_DISABLED;
    case DRIVE_E_FAULTED:
        return PROTO_ERROR_CODE_FAULTED;
    case DRIVE_E_BUSY:
        return PROTO_ERROR_CODE_BUSY;
    case DRIVE_E_LIMIT:
        drive_soft_limit_refused(&axis, &lo, &hi);
        *arg = (uint16_t)axis;
        return PROTO_ERROR_CODE_OUT_OF_RANGE;
    default:
        *arg = (uint16_t)r;
        return PROTO_ERROR_CODE_INTERNAL;
    }
}

static void to_drive(const proto_batch_block_t *pb, uint32_t tag, drive_block_t *b)
{
    drive_block_t zero = {0};
    unsigned i;

    *b = zero;
    b->tag = tag;
    b->exact_stop = pb->exact_stop;
    switch (pb->kind) {
    case PROTO_BATCH_KIND_DWELL:
        b->kind = DRIVE_BLOCK_DWELL;
        b->dwell_ms = (uint32_t)pb->feed;
        return;
    case PROTO_BATCH_KIND_RAPID:
        b->kind = DRIVE_BLOCK_LINE;
        b->feed_nm_s = PROTO_RAPID_FEED_NM_S;
        break;
    default:
        b->kind = DRIVE_BLOCK_LINE;
        b->feed_nm_s = (int64_t)pb->feed;
        break;
    }
    for (i = 0; i < CORE_AXES; i++) {
        b->target[i] = i < PROTO_MAX_AXES ? pb->target[i] : 0;
    }
}

static void ring_put(proto_batch_t *s, const uint8_t *p, size_t n)
{
    size_t i;

    for (i = 0; i < n; i++) {
        s->ring[(s->head + s->used + i) % PROTO_BATCH_RING] = p[i];
    }
    s->used = (uint16_t)(s->used + n);
}

void proto_batch_flush(proto_batch_t *s, uint8_t code)
{
    unsigned i;

    if (!s->started) {
        return;
    }
    s->head = 0;
    s->used = 0;
    s->next_seq = s->pump_seq;
    for (i = 0; i < PROTO_MAX_AXES; i++) {
        s->pt[i] = s->pump_pt[i];
    }
    s->feed = s->pump_feed;
    s->broken = code;
    s->broken_arg = 0;
}

void proto_batch_pump(proto_batch_t *s)
{
    uint8_t rec[2u * PROTO_BATCH_RECORD_MAX]; /* an origin record and a block */

    while (s->used > 0u) {
        proto_batch_rd_t rd;
        proto_batch_block_t b;
        drive_block_t db;
        drive_result_t dr;
        size_t n = s->used < sizeof(rec) ? s->used : sizeof(rec);
        const uint8_t *src = &s->ring[s->head];
        size_t i;
        size_t took;
        int k;

        if ((size_t)s->head + n > PROTO_BATCH_RING) { /* wraps: a straight copy */
            for (i = 0; i < n; i++) {
                rec[i] = s->ring[(s->head + i) % PROTO_BATCH_RING];
            }
            src = rec;
        }
        proto_batch_rd_init(&rd, src, n, s->pump_pt, s->pump_feed);
        k = proto_batch_rd_next(&rd, &b); /* origin records are applied on the way */
        took = n - rd.left;
        if (k < 0) { /* never: the records were checked (one origin at most) */
            proto_batch_flush(s, PROTO_ERROR_CODE_INTERNAL);
            return;
        }
        if (k != 1) {
            /* only origin records left (k == 0); never malformed: checked */
            s->head = (uint16_t)((s->head + took) % PROTO_BATCH_RING);
            s->used = (uint16_t)(s->used - took);
            for (i = 0; i < PROTO_MAX_AXES; i++) {
                s->pump_pt[i] = rd.pt[i];
            }
            continue;
        }
        to_drive(&b, s->pump_seq, &db);
        dr = drive_queue_block(&db);
        PREEMPT_POINT();
        if (dr == DRIVE_E_FULL) {
            return;
        }
        if (dr != DRIVE_OK) {
            uint16_t arg;
            uint8_t code = refusal(dr, &arg);

            proto_batch_flush(s, code);
            s->broken_arg = arg;
            return;
        }
        s->head = (uint16_t)((s->head + took) % PROTO_BATCH_RING);
        s->used = (uint16_t)(s->used - took);
        for (i = 0; i < PROTO_MAX_AXES; i++) {
            s->pump_pt[i] = rd.pt[i];
        }
        s->pump_feed = rd.feed;
        s->pump_seq++;
    }
}

/* Take the blocks of a parsed batch into the ring (see proto_batch.h). */
static void take(proto_batch_t *s, const proto_queue_batch_t *q, unsigned axes,
                 proto_batch_reply_t *r)
{
    proto_batch_rd_t rd;
    proto_batch_block_t b;
    const uint8_t *from = q->data; /* first byte not yet in the ring */
    unsigned i;

    proto_batch_rd_init(&rd, q->data, q->data_len, s->pt, s->feed);
    for (;;) {
        uint8_t code;
        uint16_t arg;

        if (proto_batch_rd_next(&rd, &b) != 1) {
            break;
        }
        code = block_check(&b, b.from, axes, &arg);
        if (code == PROTO_ERROR_CODE_NONE && (size_t)(rd.p - from) > proto_batch_free(s)) {
            code = PROTO_ERROR_CODE_QUEUE_FULL;
        }
        if (code != PROTO_ERROR_CODE_NONE) {
            r->status = code;
            r->arg = arg;
            break;
        }
        ring_put(s, from, (size_t)(rd.p - from));
        from = rd.p;
        r->accepted++;
        s->next_seq++;
        for (i = 0; i < PROTO_MAX_AXES; i++) {
            s->pt[i] = rd.pt[i];
        }
        s->feed = rd.feed;
    }
}

size_t proto_batch_request(proto_batch_t *s, unsigned axes, uint8_t seq, const uint8_t *p, size_t n,
                           uint8_t *out)
{
    proto_queue_batch_t q;
    proto_batch_reply_t r;
    proto_batch_rd_t rd;
    proto_batch_block_t b;
    drive_status_t st;
    bool start;
    unsigned blocks = 0;
    int k;

    if (!proto_queue_batch_decode(p, n, &q)) {
        return proto_reply_error(out, seq, PROTO_MSG_QUEUE_BATCH, PROTO_ERROR_CODE_BAD_LENGTH,
                                 (uint16_t)n, PROTO_QUEUE_BATCH_LEN, PROTO_QUEUE_BATCH_MAX_LEN);
    }
    if ((q.flags & ~(1u << PROTO_BATCH_FLAG_START)) != 0u) {
        return proto_reply_error(out, seq, PROTO_MSG_QUEUE_BATCH, PROTO_ERROR_CODE_BAD_VALUE, 2, 0,
                                 0);
    }
    start = (q.flags & (1u << PROTO_BATCH_FLAG_START)) != 0u;
    /* 1: the whole batch is parsed before anything is taken */
    proto_batch_rd_init(&rd, q.data, q.data_len, s->pt, start ? 0u : s->feed);
    while ((k = proto_batch_rd_next(&rd, &b)) == 1) {
        blocks++;
    }
    if (k < 0) {
        return proto_reply_error(out, seq, PROTO_MSG_QUEUE_BATCH, PROTO_ERROR_CODE_BAD_VALUE,
                                 (uint16_t)(rd.record - 1u), 0, 0);
    }
    if (blocks != q.count) {
        return proto_reply_error(out, seq, PROTO_MSG_QUEUE_BATCH, PROTO_ERROR_CODE_BAD_LENGTH,
                                 (uint16_t)blocks, q.count, q.count);
    }
    r.first_seq = q.first_seq;
    r.accepted = 0;
    r.status = PROTO_ERROR_CODE_NONE;
    r.arg = 0;
    drive_status(&st);
    if (q.count > 0u) {
        drive_result_t dr = drive_accepting(); /* first: a refused start starts nothing */

        PREEMPT_POINT();
        if (dr != DRIVE_OK) {
            r.status = refusal(dr, &r.arg);
        }
    }
    if (r.status != PROTO_ERROR_CODE_NONE) {
        /* the drive takes nothing now */
    } else if (start && s->started && q.first_seq == s->start_seq) {
        /* the start batch again (a retry the replay cache no longer
         * holds): not a new stream, never its blocks twice */
        r.status = PROTO_ERROR_CODE_SEQUENCE;
    } else if (start) {
        /* a new stream, unless the ring still holds blocks of the last */
        if (s->used == 0u) {
            proto_batch_reset(s);
            s->started = true;
            s->start_seq = q.first_seq;
            s->next_seq = q.first_seq;
            s->pump_seq = q.first_seq;
        } else {
            r.status = PROTO_ERROR_CODE_BUSY;
        }
    } else if (s->broken != PROTO_ERROR_CODE_NONE) {
        r.status = s->broken; /* the stream ended: whatever block this is */
        r.arg = s->broken_arg;
    } else if (!s->started || q.first_seq != s->next_seq) {
        r.status = PROTO_ERROR_CODE_SEQUENCE;
    }
    if (r.status == PROTO_ERROR_CODE_NONE && q.count > 0u) {
        take(s, &q, axes, &r);
        proto_batch_pump(s);
        drive_status(&st);
        if (s->broken != PROTO_ERROR_CODE_NONE) {
            /* the drive refused a block the ring held (its own checks, from
             * where it really is): the stream ends at that block */
            uint32_t kept = s->next_seq - q.first_seq;

            r.status = s->broken;
            r.arg = s->broken_arg;
            if (kept < r.accepted) {
                r.accepted = (uint8_t)kept;
            }
        }
    }
    r.next_seq = s->next_seq;
    r.free_bytes = proto_batch_free(s);
    r.queued_us = fx_sat_u32(st.queued_time_ns / 1000);
    r.blocks_done = st.blocks_done;
    r.state = proto_dispatch_state(&st);
    out[0] = PROTO_MSG_BATCH_REPLY;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_batch_reply_encode(&r, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}
