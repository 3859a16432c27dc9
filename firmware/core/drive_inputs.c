/*
 * drive_inputs.c - the drive's position inputs (specification in
 * drive_inputs.h).
 */
#include "drive_inputs.h"

bool drive_inputs_init(drive_inputs_t *in, const drive_config_t *cfg, uint32_t now_ns)
{
    unsigned i;
    in->any_counter = false;
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
    return true;
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
