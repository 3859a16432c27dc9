/*
 * drive_inputs.c - the drive's position inputs (specification in
 * drive_inputs.h).
 */
#include "drive_inputs.h"

bool drive_inputs_init(drive_inputs_t *in, const drive_config_t *cfg, uint32_t now_ns)
{
    unsigned i;
    in->any_counter = false;
    in->mean = false;
    for (i = 0; i < CORE_AXES; i++) {
        in->ref_on[i] = false;
        if (i >= cfg->axes) {
            continue;
        }
        in->any_counter = in->any_counter || cfg->enc_counter[i];
        {
            qdec_config_t qc;
            uint32_t init;
            qdec_config_default(&qc);
            qc.nm_per_count_num = cfg->nm_per_count_num[i];
            qc.nm_per_count_den = cfg->nm_per_count_den[i];
            qc.illegal_limit = 1;
            qc.illegal_window_ns = 1000000000ull;
            init = cfg->enc_initial_lines[i];
            if (cfg->enc_counter[i]) {
                /* counter input: the port must have the counter */
                qc.input = QDEC_INPUT_COUNTER;
                qc.counter_bits = 32;
                if (!hal_encoder_counter(i, &init)) {
                    return false;
                }
            }
            if (!qdec_init(&in->enc[i], &qc, init, now_ns)) {
                return false;
            }
        }
        if (cfg->ref_nm_per_count_num[i] != 0) {
            qdec_config_t qc;
            uint32_t raw;
            if (hal_encoder_counter(cfg->axes + i, &raw)) {
                qdec_config_default(&qc);
                qc.input = QDEC_INPUT_COUNTER;
                qc.counter_bits = 32;
                qc.nm_per_count_num = cfg->ref_nm_per_count_num[i];
                qc.nm_per_count_den = cfg->ref_nm_per_count_den[i];
                if (!qdec_init(&in->refs[i], &qc, raw, now_ns)) {
                    return false;
                }
                /* absolute: the counter's value is the scale's position */
                qdec_set_offset_nm(&in->refs[i],
                                   qdec_counts_to_nm(&in->refs[i], (int64_t)(int32_t)raw));
                in->ref_raw[i] = raw;
                in->ref_cnt[i] = 0;
                in->ref_nm[i] = in->refs[i].out.pos_nm; /* until the first sample */
                in->ref_on[i] = true;
            }
        }
    }
    in->interp = cfg->enc_interp;
    in->tick_ns = (uint32_t)((1000000000u + cfg->tick_hz / 2u) / cfg->tick_hz);
    for (i = 0; i < CORE_AXES; i++) {
        enc_interp_reset(&in->ip[i], in->enc[i].out.pos, in->enc[i].last_nedge);
    }
    drive_inputs_set_mean(in, cfg->enc_mean);
    return true;
}

bool drive_inputs_mean_ok(unsigned axes)
{
    unsigned i;
    for (i = 0; i < axes; i++) {
        if (!hal_encoder_mean(i, NULL)) {
            return false;
        }
    }
    return true;
}

void drive_inputs_set_mean(drive_inputs_t *in, bool on)
{
    in->mean = on;
    in->slow = in->any_counter || on || in->interp;
}

void drive_inputs_sample_slow(drive_inputs_t *in, const drive_config_t *cfg, uint32_t now_ns,
                              servo_fb_t *fb)
{
    uint32_t enc_fault = 0;
    unsigned i;
    for (i = 0; i < CORE_AXES; i++) {
        qdec_t *q = &in->enc[i];
        if (i >= cfg->axes) {
            fb->pos[i] = 0;
            continue;
        }
        if (cfg->enc_counter[i]) {
            uint32_t raw = q->last_raw; /* no snapshot: no change */
            (void)hal_encoder_counter(i, &raw);
            qdec_sample_counter(q, raw, now_ns);
        } else {
            qdec_sample(q, now_ns);
        }
        fb->pos[i] = q->out.pos_nm;
        if (q->out.faults != 0) {
            enc_fault |= 1u << i;
        }
    }
    fb->enc_fault = enc_fault;
    comp2d_live_apply(&in->enc[0].out.pos_nm, &in->enc[1].out.pos_nm, &fb->pos[0], &fb->pos[1]);
    for (i = 0; (in->mean || in->interp) && i < cfg->axes; i++) {
        const qdec_t *q = &in->enc[i];
        int64_t lag = 0;
        bool ok = true;
        if (in->interp) {
            enc_interp_update(&in->ip[i], q->out.pos, q->last_nedge, q->out.dir, q->t_edge);
        }
        if (in->mean) {
            ok = hal_encoder_mean(i, &lag);
            if (ok && in->interp) {
                lag += enc_interp_mean_residual(&in->ip[i], q->now, in->tick_ns);
            }
        } else {
            lag = enc_interp_pos(&in->ip[i], q->now);
        }
        if (ok) {
            fb->pos[i] +=
                drive_inputs_lag_nm(lag, cfg->nm_per_count_num[i], cfg->nm_per_count_den[i]);
        }
    }
}

void drive_inputs_ref_sample(drive_inputs_t *in, unsigned axes)
{
    unsigned i;
    for (i = 0; i < axes; i++) {
        uint32_t raw;
        if (in->ref_on[i] && hal_encoder_counter(axes + i, &raw)) {
            in->ref_cnt[i] += (int32_t)(raw - in->ref_raw[i]);
            in->ref_raw[i] = raw;
            in->ref_nm[i] = qdec_counts_to_nm(&in->refs[i], in->ref_cnt[i]);
        }
    }
}
