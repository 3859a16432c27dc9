/* The drive's 2-D compensation map: comp2d_link.h. */
#include "comp2d_link.h"

#include "calib.h"
#include "comp2d_live.h"
#include "comp_store.h"
#include "crc.h"
#include "drive.h"
#include "hal.h"
#include "proto_msgs.h"
#include "proto_replay.h"
#include "proto_reply.h"
#include "sample_pull.h"
#include "scratch.h"

#define FIELD_NM ((pos_nm_t)1 << 50)

static struct {
    uint8_t buf[COMP2D_RECORD_MAX];
    /* the staging of buf (comp2d_write); after load() buf holds the
     * stored record and nothing is staged */
    sample_pull_stage_t stage;
    /* the record in use: store version, bank, length, crc32 */
    uint32_t version;
    uint8_t slot;
    uint16_t length;
    uint32_t crc;
    comp2d_handler_fn next;
    proto_replay_t replay;
} lk2; /* main */

static size_t refuse(uint8_t *out, const uint8_t *msg, uint8_t status, int64_t lo)
{
    return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_CALIB, status, lo, 0);
}

/* The drive's field: X and Y's soft limits when set. */
static void field(pos_nm_t lo[2], pos_nm_t hi[2])
{
    const drive_config_t *c = drive_config();
    unsigned a;
    for (a = 0; a < 2u; a++) {
        bool on = c != NULL && c->soft_min[a] < c->soft_max[a];
        lo[a] = on ? c->soft_min[a] : -FIELD_NM;
        hi[a] = on ? c->soft_max[a] : FIELD_NM;
    }
}

/* Decode and check a record into m: COMP2D_OK or the refusal; which axis
 * is outside the field in *axis. */
static int parse(const uint8_t *buf, uint32_t len, comp2d_map_t *m, unsigned *axis)
{
    pos_nm_t lo[2], hi[2];
    int r = comp2d_decode(buf, len, m);
    field(lo, hi);
    if (r == COMP2D_OK) {
        r = comp2d_check(m, lo, hi);
    }
    *axis = m->x0 < lo[0] || m->x0 + (pos_nm_t)(m->nx - 1u) * m->dx > hi[0] ? 0u : 1u;
    return r;
}

/* Use the record buf[0..len) (len 0: no map); false when it fails its
 * checks (then no map). The map is decoded in the scratch area. */
static bool use(const uint8_t *buf, uint16_t len, uint32_t version, unsigned slot)
{
    comp2d_map_t *m;
    unsigned axis;
    bool ok = false;
    lk2.version = version;
    lk2.slot = (uint8_t)slot;
    lk2.length = len;
    lk2.crc = crc32_update(CRC32_INIT, buf, len);
    if (len == 0u || (m = scratch_claim(SCRATCH_COMP2D, sizeof *m)) == NULL) {
        comp2d_live_set(NULL);
        return len == 0u;
    }
    if (parse(buf, len, m, &axis) == COMP2D_OK) {
        comp2d_prepare(m);
        comp2d_live_set(m);
        ok = true;
    } else {
        comp2d_live_set(NULL);
    }
    scratch_release(SCRATCH_COMP2D);
    return ok;
}

/* The current record from flash into the staging buffer, then in use. */
static comp_store_result_t load(void)
{
    uint16_t len = 0u;
    uint32_t version = 0u;
    comp_store_result_t r = comp_store_slot_load(COMP_STORE_SLOT_MAP2D, lk2.buf,
                                                 (uint16_t)sizeof lk2.buf, &len, &version);
    lk2.stage.staged = 0u; /* the staging buffer now holds the stored record */
    if (r != COMP_STORE_OK) {
        (void)use(lk2.buf, 0u, 0u, 0xFFu);
        return r;
    }
    (void)use(lk2.buf, len, version, (unsigned)comp_store_active_bank());
    return COMP_STORE_OK;
}

void comp2d_link_init(void)
{
    comp2d_handler_fn next = lk2.next;
    sample_pull_stage_init(&lk2.stage, lk2.buf, (uint16_t)sizeof lk2.buf);
    lk2.next = next;
    proto_replay_reset(&lk2.replay);
    comp2d_live_init();
    if (drive_config() != NULL && drive_config()->axes >= 2u) {
        (void)load();
    }
}

void comp2d_link_poll(void)
{
    drive_status_t st;
    pos_nm_t p[2];
    unsigned a;
    if (comp2d_live_map() == NULL || drive_config() == NULL || drive_config()->axes < 2u) {
        return;
    }
    drive_snapshot(&st);
    for (a = 0; a < 2u; a++) {
        const comp_table_t *t = calib_comp_active(a);
        /* after the 1-D table, if any (its direction: its own ramp) */
        p[a] = t != NULL ? comp_correct(t, st.pos_raw[a], COMP_DIR_NONE) : st.pos_raw[a];
    }
    comp2d_live_poll(p, st.vel_ref, hal_time_us());
}

void comp2d_link_set_next(comp2d_handler_fn fn)
{
    lk2.next = fn;
}

static size_t reply_info(uint8_t *out, uint8_t seq)
{
    proto_comp2d_info_t m;
    const comp2d_map_t *map = comp2d_live_map();
    m.active = map != NULL ? 1u : 0u;
    m.nx = map != NULL ? map->nx : 0u;
    m.ny = map != NULL ? map->ny : 0u;
    m.slot = lk2.slot;
    m.version = lk2.version;
    m.length = lk2.length;
    m.crc = lk2.length != 0u ? lk2.crc : 0u;
    out[0] = (uint8_t)PROTO_MSG_COMP2D_INFO;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_comp2d_info_encode(&m, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

static size_t bad_length(uint8_t *out, const uint8_t *msg, size_t plen, size_t want)
{
    return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_BAD_LENGTH,
                             (uint16_t)plen, (int64_t)want, 0);
}

static size_t h_write(const uint8_t *msg, size_t plen, uint8_t *out)
{
    static proto_comp2d_write_t m;
    proto_comp2d_written_t w;
    if (!proto_comp2d_write_decode(msg + PROTO_MSG_HDR, plen, &m)) {
        return bad_length(out, msg, plen, PROTO_COMP2D_WRITE_LEN);
    }
    if (!sample_pull_stage_write(&lk2.stage, m.offset, m.data, m.data_len, m.offset == 0u)) {
        return refuse(out, msg, PROTO_CALIB_STATUS_RECORD_RANGE, m.offset);
    }
    w.offset = m.offset;
    w.len = m.data_len;
    out[0] = (uint8_t)PROTO_MSG_COMP2D_WRITTEN;
    out[1] = msg[1];
    return PROTO_MSG_HDR + proto_comp2d_written_encode(&w, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

/* Store buf[0..len) (len 0: no map) as the current record and use what
 * the flash then holds, not what the link delivered: comp2d_info, or a
 * refusal. The drive must be disabled for a flash write
 * (docs/calibration.md). */
static size_t store(const uint8_t *msg, uint8_t *out, const uint8_t *buf, uint16_t len)
{
    drive_status_t st;
    comp_store_result_t sr;
    drive_snapshot(&st);
    if (st.state != DRIVE_DISABLED) {
        return refuse(out, msg, PROTO_CALIB_STATUS_DRIVE_ENABLED, st.state);
    }
    sr = comp_store_slot_write(COMP_STORE_SLOT_MAP2D, buf, len, NULL);
    if (sr == COMP_STORE_OK) {
        sr = load();
    }
    if (sr != COMP_STORE_OK) {
        return refuse(out, msg, PROTO_CALIB_STATUS_FLASH, sr);
    }
    return reply_info(out, msg[1]);
}

static size_t h_commit(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_comp2d_commit_t m;
    comp2d_map_t *map;
    unsigned axis = 0u;
    uint32_t crc;
    size_t n;
    int r;
    if (!proto_comp2d_commit_decode(msg + PROTO_MSG_HDR, plen, &m) ||
        plen != PROTO_COMP2D_COMMIT_LEN) {
        return bad_length(out, msg, plen, PROTO_COMP2D_COMMIT_LEN);
    }
    if (drive_config()->axes < 2u) {
        return refuse(out, msg, PROTO_CALIB_STATUS_COMP2D_AXES, drive_config()->axes);
    }
    if (m.length > lk2.stage.staged || m.length == 0u) { /* staged <= the buffer */
        return refuse(out, msg, PROTO_CALIB_STATUS_RECORD_RANGE, m.length);
    }
    crc = sample_pull_stage_crc(&lk2.stage, m.length);
    if (crc != m.crc) {
        return refuse(out, msg, PROTO_CALIB_STATUS_RECORD_CRC, crc);
    }
    map = scratch_claim(SCRATCH_COMP2D, sizeof *map);
    if (map == NULL) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BUSY, 0);
    }
    r = parse(lk2.buf, m.length, map, &axis);
    n = (size_t)map->nx * map->ny;
    scratch_release(SCRATCH_COMP2D);
    if (r == COMP2D_E_MEMORY) {
        return refuse(out, msg, PROTO_CALIB_STATUS_COMP2D_MEMORY, (int64_t)n);
    }
    if (r == COMP2D_E_FIELD) {
        return refuse(out, msg, PROTO_CALIB_STATUS_COMP2D_FIELD, 1 + (int64_t)axis);
    }
    if (r != COMP2D_OK) {
        return refuse(out, msg, PROTO_CALIB_STATUS_COMP2D_RECORD, r);
    }
    return store(msg, out, lk2.buf, m.length);
}

static size_t h_clear(const uint8_t *msg, size_t plen, uint8_t *out)
{
    if (plen != 0u) {
        return bad_length(out, msg, plen, 0u);
    }
    return store(msg, out, NULL, 0u);
}

static size_t h_read(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_comp2d_read_t m;
    proto_comp2d_data_t d;
    uint8_t *buf;
    uint16_t len = 0u;
    if (!proto_comp2d_read_decode(msg + PROTO_MSG_HDR, plen, &m) || plen != PROTO_COMP2D_READ_LEN) {
        return bad_length(out, msg, plen, PROTO_COMP2D_READ_LEN);
    }
    buf = scratch_claim(SCRATCH_COMP2D, COMP2D_RECORD_MAX);
    if (buf == NULL) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BUSY, 0);
    }
    if (comp_store_slot_load(COMP_STORE_SLOT_MAP2D, buf, COMP2D_RECORD_MAX, &len, NULL) !=
        COMP_STORE_OK) {
        len = 0u;
    }
    d.offset = m.offset;
    d.total = len;
    d.data_len = (uint16_t)sample_pull_copy(d.data, m.max < sizeof d.data ? m.max : sizeof d.data,
                                            buf, len, m.offset);
    scratch_release(SCRATCH_COMP2D);
    out[0] = (uint8_t)PROTO_MSG_COMP2D_DATA;
    out[1] = msg[1];
    return PROTO_MSG_HDR + proto_comp2d_data_encode(&d, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

/* One request of the 2-D compensation's range (proto_replay_exec_t). */
static size_t execute(void *ctx, const uint8_t *msg, size_t len, uint8_t *out)
{
    const size_t plen = len - PROTO_MSG_HDR;

    (void)ctx;
    switch (msg[0]) {
    case PROTO_MSG_COMP2D_WRITE:
        return h_write(msg, plen, out);
    case PROTO_MSG_COMP2D_COMMIT:
        return h_commit(msg, plen, out);
    case PROTO_MSG_COMP2D_CLEAR:
        return h_clear(msg, plen, out);
    case PROTO_MSG_COMP2D_READ:
        return h_read(msg, plen, out);
    default: /* comp2d_get */
        return plen == 0u ? reply_info(out, msg[1]) : bad_length(out, msg, plen, 0u);
    }
}

size_t comp2d_link_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out, size_t cap)
{
    uint8_t id;
    if (msg == NULL || out == NULL || len < PROTO_MSG_HDR || cap < PROTO_MSG_MAX) {
        return 0;
    }
    id = msg[0];
    if (id < PROTO_MSG_COMP2D_WRITE || id > PROTO_MSG_COMP2D_READ) {
        if (lk2.next != NULL) {
            return lk2.next(msg, len, now_us, out, cap);
        }
        return proto_reply_error(out, msg[1], id, (uint8_t)PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0u, 0,
                                 0);
    }
    if (id == PROTO_MSG_COMP2D_WRITE || id == PROTO_MSG_COMP2D_COMMIT ||
        id == PROTO_MSG_COMP2D_CLEAR) {
        return proto_replay_answer(&lk2.replay, msg, len, out, cap, execute, NULL);
    }
    return execute(NULL, msg, len, out);
}
