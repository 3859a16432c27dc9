/*
 * excite.c - bounded PRBS excitation of one axis (excite.h).
 */
#include "excite.h"

#include <string.h>

/* Feedback taps (bit numbers from 1) of maximal-length LFSRs, 7..16 bits. */
static const uint8_t excite_taps[10][2] = {
    {7, 6}, {8, 6}, {9, 5}, {10, 7}, {11, 9}, {12, 6}, {13, 4}, {14, 5}, {15, 14}, {16, 15},
};
/* 8, 12, 13, 14 and 16 bits need four taps; the other two of them: */
static const uint8_t excite_taps_hi[10][2] = {
    {0, 0}, {5, 4}, {0, 0}, {0, 0}, {0, 0}, {4, 1}, {3, 1}, {3, 1}, {0, 0}, {13, 4},
};

static uint32_t excite_lfsr_step(uint32_t s, unsigned bits)
{
    const unsigned i = bits - 7u;
    uint32_t fb = (s >> (excite_taps[i][0] - 1u)) ^ (s >> (excite_taps[i][1] - 1u));

    if (excite_taps_hi[i][0] != 0u) {
        fb ^= (s >> (excite_taps_hi[i][0] - 1u)) ^ (s >> (excite_taps_hi[i][1] - 1u));
    }
    return ((s << 1) | (fb & 1u)) & ((1u << bits) - 1u);
}

void excite_init(excite_t *ex)
{
    memset(ex, 0, sizeof(*ex));
}

bool excite_setup(excite_t *ex, const excite_cfg_t *cfg, excite_sample_t *buf, uint32_t n)
{
    uint32_t period;

    if (ex->state == EXCITE_RUNNING || ex->req_start != ex->ack_start) {
        return false;
    }
    if (cfg->bits < 7u || cfg->bits > 16u || cfg->hold == 0u || cfg->n_ticks == 0u ||
        cfg->windows == 0u || cfg->travel_nm <= 0 || cfg->vel_dpos_nm <= 0 || cfg->cmd_mv <= 0 ||
        cfg->amp_mv <= 0 || cfg->amp_mv > cfg->cmd_mv || cfg->host_timeout_ticks == 0u) {
        return false;
    }
    period = ((1u << cfg->bits) - 1u) * cfg->hold;
    if (buf == NULL || n == 0u || (n & (n - 1u)) != 0u || period > n) {
        return false;
    }
    ex->cfg = *cfg;
    ex->buf = buf;
    ex->buf_mask = n - 1u;
    ex->period = period;
    return true;
}

void excite_start(excite_t *ex)
{
    ex->req_start++;
}

void excite_abort(excite_t *ex, uint32_t reason)
{
    ex->abort_reason = reason;
    ex->req_abort++;
}

void excite_host_alive(excite_t *ex)
{
    ex->host_seen++;
}

void excite_release(excite_t *ex, uint32_t seq)
{
    if ((int32_t)(seq - ex->written) <= 0 && (int32_t)(seq - ex->released) > 0) {
        ex->released = seq;
    }
}

bool excite_sample(const excite_t *ex, uint32_t seq, excite_sample_t *out)
{
    if ((int32_t)(seq - ex->released) < 0 || (int32_t)(seq - ex->written) >= 0) {
        return false;
    }
    *out = ex->buf[seq & ex->buf_mask];
    return true;
}

static int32_t excite_stop(excite_t *ex, uint32_t state, uint32_t reason)
{
    ex->reason = reason;
    ex->state = state;
    return 0;
}

static int64_t excite_abs64(int64_t v)
{
    return v < 0 ? -v : v;
}

static int32_t excite_sat32(int64_t v)
{
    return v > INT32_MAX ? INT32_MAX : (v < INT32_MIN ? INT32_MIN : (int32_t)v);
}

static void excite_begin(excite_t *ex, const excite_in_t *in)
{
    unsigned i;

    ex->ack_start = ex->req_start;
    ex->ack_abort = ex->req_abort;
    ex->host_last = ex->host_seen;
    ex->host_ticks = 0u;
    ex->k = 0u;
    ex->phase = 0u;
    ex->rec_left = 0u;
    ex->windows_done = 0u;
    ex->lfsr = 1u;
    ex->chip_left = ex->cfg.hold;
    ex->pos0 = in->pos_nm;
    for (i = 0; i < EXCITE_VEL_TICKS; i++) {
        ex->hist[i] = in->pos_nm;
    }
    ex->written = 0u;
    ex->released = 0u;
    ex->reason = EXCITE_REASON_NONE;
    ex->state = EXCITE_RUNNING;
}

/* The reason to stop this tick, before any output (NONE: go on). */
static uint32_t excite_check(excite_t *ex, const excite_in_t *in)
{
    const excite_cfg_t *c = &ex->cfg;
    int64_t *old = &ex->hist[ex->k % EXCITE_VEL_TICKS];
    int64_t dpos = in->pos_nm - *old;

    *old = in->pos_nm;
    if (ex->req_abort != ex->ack_abort) {
        ex->ack_abort = ex->req_abort;
        return ex->abort_reason;
    }
    if (in->estop) {
        return EXCITE_REASON_ESTOP;
    }
    if (in->fault) {
        return EXCITE_REASON_FAULT;
    }
    if (!in->idle) {
        return EXCITE_REASON_DRIVE_STATE;
    }
    if (ex->host_seen != ex->host_last) {
        ex->host_last = ex->host_seen;
        ex->host_ticks = 0u;
    } else if (++ex->host_ticks >= c->host_timeout_ticks) {
        return EXCITE_REASON_HOST_SILENT;
    }
    if (ex->k >= c->n_ticks) {
        return EXCITE_REASON_DURATION;
    }
    if (excite_abs64(in->pos_nm - ex->pos0) > c->travel_nm) {
        return EXCITE_REASON_TRAVEL;
    }
    if (excite_abs64(dpos) > c->vel_dpos_nm) {
        return EXCITE_REASON_VELOCITY;
    }
    return EXCITE_REASON_NONE;
}

int32_t excite_tick(excite_t *ex, const excite_in_t *in)
{
    const excite_cfg_t *c = &ex->cfg;
    uint32_t why;
    int32_t out;
    int64_t total;

    if (ex->req_start != ex->ack_start) {
        excite_begin(ex, in);
    }
    if (ex->state != EXCITE_RUNNING) {
        return 0;
    }
    why = excite_check(ex, in);
    if (why != EXCITE_REASON_NONE) {
        return excite_stop(ex, EXCITE_ABORTED, why);
    }
    out = (ex->lfsr & 1u) ? c->amp_mv : -c->amp_mv;
    total = (int64_t)in->cmd_mv + out;
    if (excite_abs64(total) > c->cmd_mv) {
        return excite_stop(ex, EXCITE_ABORTED, EXCITE_REASON_COMMAND);
    }
    /* a window starts at a period boundary with room for all of it */
    if (ex->phase == 0u && ex->k >= c->skip_ticks && ex->windows_done < c->windows &&
        ex->written - ex->released + ex->period <= ex->buf_mask + 1u) {
        ex->rec_left = ex->period;
    }
    if (ex->rec_left != 0u) {
        excite_sample_t *s = &ex->buf[ex->written & ex->buf_mask];
        s->cmd_mv = (int32_t)total;
        s->pos_nm = excite_sat32(in->pos_nm - ex->pos0);
        ex->written = ex->written + 1u;
        if (--ex->rec_left == 0u && ++ex->windows_done >= c->windows) {
            excite_stop(ex, EXCITE_DONE, EXCITE_REASON_NONE); /* this tick's output still goes */
        }
    }
    if (--ex->chip_left == 0u) {
        ex->chip_left = c->hold;
        ex->lfsr = excite_lfsr_step(ex->lfsr, c->bits);
    }
    if (++ex->phase == ex->period) {
        ex->phase = 0u;
    }
    ex->k = ex->k + 1u;
    return out;
}
