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

bool excite_setup(excite_t *ex, const excite_cfg_t *cfg)
{
    if (ex->state == EXCITE_RUNNING || ex->req_start != ex->ack_start) {
        return false;
    }
    if (cfg->bits < 7u || cfg->bits > 16u || cfg->hold == 0u || cfg->n_ticks == 0u ||
        cfg->travel_nm <= 0 || cfg->vel_nm_s <= 0 || cfg->cmd_mv <= 0 || cfg->amp_mv <= 0 ||
        cfg->amp_mv > cfg->cmd_mv || cfg->host_timeout_ticks == 0u) {
        return false;
    }
    ex->cfg = *cfg;
    return true;
}

void excite_start(excite_t *ex)
{
    ex->req_start++;
}

void excite_abort(excite_t *ex)
{
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
    *out = ex->ring[seq & (EXCITE_RING - 1u)];
    return true;
}

static int32_t excite_stop(excite_t *ex, uint32_t state, uint32_t reason)
{
    ex->reason = reason;
    ex->state = state;
    ex->out_mv = 0;
    return 0;
}

static int64_t excite_abs64(int64_t v)
{
    return v < 0 ? -v : v;
}

int32_t excite_tick(excite_t *ex, const excite_in_t *in)
{
    const excite_cfg_t *c = &ex->cfg;

    if (ex->req_start != ex->ack_start) {
        ex->ack_start = ex->req_start;
        ex->ack_abort = ex->req_abort;
        ex->host_last = ex->host_seen;
        ex->host_ticks = 0u;
        ex->k = 0u;
        ex->lfsr = 1u;
        ex->chip_left = c->hold;
        ex->pos0 = in->pos_nm;
        ex->written = 0u;
        ex->released = 0u;
        ex->reason = EXCITE_REASON_NONE;
        ex->state = EXCITE_RUNNING;
    }
    if (ex->state != EXCITE_RUNNING) {
        return 0;
    }
    if (ex->req_abort != ex->ack_abort) {
        ex->ack_abort = ex->req_abort;
        return excite_stop(ex, EXCITE_ABORTED, EXCITE_REASON_ABORTED);
    }
    if (in->estop) {
        return excite_stop(ex, EXCITE_ABORTED, EXCITE_REASON_ESTOP);
    }
    if (in->fault) {
        return excite_stop(ex, EXCITE_ABORTED, EXCITE_REASON_FAULT);
    }
    if (ex->host_seen != ex->host_last) {
        ex->host_last = ex->host_seen;
        ex->host_ticks = 0u;
    } else if (++ex->host_ticks >= c->host_timeout_ticks) {
        return excite_stop(ex, EXCITE_ABORTED, EXCITE_REASON_HOST_SILENT);
    }
    if (excite_abs64(in->pos_nm - ex->pos0) > c->travel_nm) {
        return excite_stop(ex, EXCITE_ABORTED, EXCITE_REASON_TRAVEL);
    }
    if (excite_abs64(in->vel_nm_s) > c->vel_nm_s) {
        return excite_stop(ex, EXCITE_ABORTED, EXCITE_REASON_VELOCITY);
    }
    if (excite_abs64(in->cmd_mv) > c->cmd_mv) {
        return excite_stop(ex, EXCITE_ABORTED, EXCITE_REASON_COMMAND);
    }
    /* sample of the last tick: its command and the position it produced */
    if (ex->k > 0u) {
        if (ex->written - ex->released >= EXCITE_RING) {
            return excite_stop(ex, EXCITE_ABORTED, EXCITE_REASON_OVERRUN);
        }
        excite_sample_t *s = &ex->ring[ex->written & (EXCITE_RING - 1u)];
        s->seq = ex->written;
        s->cmd_mv = in->cmd_mv;
        s->pos_nm = in->pos_nm - ex->pos0;
        ex->written = ex->written + 1u;
    }
    if (ex->k >= c->n_ticks) {
        return excite_stop(ex, EXCITE_DONE, EXCITE_REASON_NONE);
    }
    ex->out_mv = (ex->lfsr & 1u) ? c->amp_mv : -c->amp_mv;
    if (--ex->chip_left == 0u) {
        ex->chip_left = c->hold;
        ex->lfsr = excite_lfsr_step(ex->lfsr, c->bits);
    }
    ex->k++;
    return ex->out_mv;
}
