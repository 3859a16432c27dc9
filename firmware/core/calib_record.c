/*
 * calib_record.c - the compensation-record messages of the calibration
 * service (calib.h, part 2): comp_write stages a record, comp_commit checks
 * it, stores it in flash and installs it from flash, comp_clear stores an
 * empty table, comp_get reports the active one. Split from calib.c (size);
 * the run, the sample ring and the dispatch stay there (calib_int.h).
 * Main context only.
 */
#include "calib_int.h"

#include "comp_store.h"
#include "proto_msgs.h"
#include "proto_reply.h"
#include "sample_pull.h"
#include "scratch.h"

/* The staged record (main). stage_axis: the axis it is for, -1: none. */
static struct {
    uint8_t buf[COMP_RECORD_MAX];
    sample_pull_stage_t stage; /* of buf */
    int16_t stage_axis;
} rec;

void calib_record_reset(void)
{
    sample_pull_stage_init(&rec.stage, rec.buf, (uint16_t)sizeof rec.buf);
    rec.stage_axis = -1;
}

static unsigned axes(void)
{
    const drive_config_t *c = drive_config();
    return c != NULL ? c->axes : 0u;
}

static size_t reply_error(uint8_t *out, uint8_t req, uint8_t seq, uint8_t code, uint16_t arg,
                          int64_t lo)
{
    return proto_reply_error(out, seq, req, code, arg, lo, 0);
}

static size_t refuse(uint8_t *out, const uint8_t *msg, uint8_t status, int64_t detail)
{
    return reply_error(out, msg[0], msg[1], (uint8_t)PROTO_ERROR_CODE_CALIB, status, detail);
}

static size_t reply_comp_info(uint8_t *out, uint8_t seq, unsigned axis)
{
    proto_comp_info_t m;
    const comp_table_t *t = calib_comp_active(axis);
    comp_table_t *cur;
    unsigned slot = 0xFFu;
    m.axis = (uint8_t)axis;
    m.active = t != NULL ? 1u : 0u;
    m.slot = calib_comp_slot(axis);
    m.n = 0u;
    m.version = m.data_crc = m.ramp_us = 0u;
    if (t != NULL) {
        m.n = t->n;
        m.version = t->version;
        m.data_crc = t->data_crc;
        m.ramp_us = t->ramp_us;
    } else if ((cur = scratch_claim(SCRATCH_CALIB, sizeof *cur)) != NULL) {
        if (comp_store_load(axis, cur, &slot) == COMP_STORE_OK) {
            m.version = cur->version; /* an empty table is current */
            m.data_crc = cur->data_crc;
            m.slot = (uint8_t)slot;
        }
        scratch_release(SCRATCH_CALIB);
    }
    out[0] = (uint8_t)PROTO_MSG_COMP_INFO;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_comp_info_encode(&m, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

size_t calib_h_comp_write(const uint8_t *msg, size_t plen, uint8_t *out)
{
    static proto_comp_write_t m;
    proto_comp_written_t w;
    bool fresh;
    if (!proto_comp_write_decode(msg + PROTO_MSG_HDR, plen, &m)) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen,
                           PROTO_COMP_WRITE_LEN);
    }
    if (m.axis >= axes()) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_AXIS, m.axis);
    }
    fresh = m.offset == 0u || rec.stage_axis != (int16_t)m.axis; /* a new record */
    if (!sample_pull_stage_write(&rec.stage, m.offset, m.data, m.data_len, fresh)) {
        return refuse(out, msg, PROTO_CALIB_STATUS_RECORD_RANGE, m.offset);
    }
    rec.stage_axis = (int16_t)m.axis;
    w.axis = m.axis;
    w.offset = m.offset;
    w.len = m.data_len;
    out[0] = (uint8_t)PROTO_MSG_COMP_WRITTEN;
    out[1] = msg[1];
    return PROTO_MSG_HDR + proto_comp_written_encode(&w, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

/* Compensation tables reach flash only with the drive disabled: a flash
 * program or erase stalls a single-bank MCU (STM32F4: up to 2 s for a
 * sector) and no control tick may be lost while the axes are powered.
 * Checked on every board so the host sees one behaviour. True when the
 * drive refuses (nothing is changed; a staged record is kept). */
static bool flash_refused(const uint8_t *msg, uint8_t *out, size_t *len)
{
    drive_status_t st;
    drive_snapshot(&st);
    if (st.state == DRIVE_DISABLED) {
        return false;
    }
    *len = refuse(out, msg, PROTO_CALIB_STATUS_DRIVE_ENABLED, st.state);
    return true;
}

/* Decode, store, load back and install the staged record (t: scratch). */
/* Decode the staged record (in scratch.h) and store it: 0 or a refusal. */
static size_t comp_commit_in(const proto_comp_commit_t *m, const uint8_t *msg, uint8_t *out)
{
    comp_table_t *t = scratch_claim(SCRATCH_CALIB, sizeof *t);
    comp_result_t cr = t != NULL ? comp_record_decode(rec.buf, m->length, t) : COMP_E_ARG;
    comp_store_result_t sr;
    size_t n = 0u;
    if (cr == COMP_OK && t->axis != m->axis) {
        cr = COMP_E_AXIS;
    }
    if (cr != COMP_OK) {
        n = refuse(out, msg, PROTO_CALIB_STATUS_RECORD, cr);
    } else if (!flash_refused(msg, out, &n)) {
        sr = comp_store_write(m->axis, t, NULL, NULL);
        n = sr == COMP_STORE_OK ? 0u : refuse(out, msg, PROTO_CALIB_STATUS_FLASH, sr);
    }
    if (t != NULL) {
        scratch_release(SCRATCH_CALIB);
    }
    return n;
}

size_t calib_h_comp_commit(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_comp_commit_t m;
    comp_store_result_t sr;
    uint32_t crc;
    size_t n;
    if (!proto_comp_commit_decode(msg + PROTO_MSG_HDR, plen, &m) || plen != PROTO_COMP_COMMIT_LEN) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen,
                           PROTO_COMP_COMMIT_LEN);
    }
    if (m.axis >= axes()) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_AXIS, m.axis);
    }
    if (rec.stage_axis != (int16_t)m.axis || m.length < COMP_RECORD_HDR ||
        m.length > COMP_RECORD_MAX) {
        return refuse(out, msg, PROTO_CALIB_STATUS_RECORD_RANGE, m.length);
    }
    crc = sample_pull_stage_crc(&rec.stage, m.length);
    if (crc != m.crc) {
        return refuse(out, msg, PROTO_CALIB_STATUS_RECORD_CRC, crc);
    }
    n = comp_commit_in(&m, msg, out);
    if (n != 0u) {
        return n;
    }
    sr = calib_load_install(m.axis); /* what the flash holds, not what the link delivered */
    if (sr != COMP_STORE_OK) {
        return refuse(out, msg, PROTO_CALIB_STATUS_FLASH, sr);
    }
    rec.stage_axis = -1;
    return reply_comp_info(out, msg[1], m.axis);
}

size_t calib_h_comp_clear(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_comp_clear_t m;
    comp_store_result_t sr;
    size_t rlen;
    if (!proto_comp_clear_decode(msg + PROTO_MSG_HDR, plen, &m) || plen != PROTO_COMP_CLEAR_LEN) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen,
                           PROTO_COMP_CLEAR_LEN);
    }
    if (m.axis >= axes()) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_AXIS, m.axis);
    }
    if (flash_refused(msg, out, &rlen)) {
        return rlen;
    }
    sr = comp_store_clear(m.axis, NULL); /* claims the scratch area itself */
    if (sr == COMP_STORE_OK) {
        sr = calib_load_install(m.axis);
    }
    if (sr != COMP_STORE_OK) {
        return refuse(out, msg, PROTO_CALIB_STATUS_FLASH, sr);
    }
    return reply_comp_info(out, msg[1], m.axis);
}

size_t calib_h_comp_get(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_comp_get_t m;
    if (!proto_comp_get_decode(msg + PROTO_MSG_HDR, plen, &m) || plen != PROTO_COMP_GET_LEN) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen,
                           PROTO_COMP_GET_LEN);
    }
    if (m.axis >= axes()) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_AXIS, m.axis);
    }
    return reply_comp_info(out, msg[1], m.axis);
}
