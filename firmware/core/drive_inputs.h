/*
 * drive_inputs.h - the drive's position inputs: one encoder decoder per axis
 * (edges or a hardware counter, qdec.h) and the reference scales.
 *
 * Specification
 * -------------
 * drive_inputs_init sets the decoders up from the drive's configuration
 * (drive.h, drive_config_t): encoder axis i scaled by nm_per_count, from
 * enc_initial_lines or, for an enc_counter axis, from the counter's value
 * at init (position 0 there), illegal transitions latched at once; a
 * reference scale on counter channel axes + i when ref_nm_per_count_num is
 * not 0 and the port has the counter, absolute (position = counter times
 * the scale). Each tick drive_inputs_sample samples every encoder and fills
 * the servo's feedback; drive_inputs_ref_sample adds each reference
 * scale's counter change since its last sample, taken as int32 (so samples
 * must come while a scale moves less than 2^31 counts between them:
 * DRIVE_REF_SAMPLE_TICKS), and scales it. X and Y (axes 0 and 1) then get
 * the 2-D map's correction (comp2d_live.h) in both the feedback and the
 * decoders' pos_nm.
 * Mean measurement (cfg->enc_mean, drive.h): the feedback of every axis is
 * then its decoder's position plus hal_encoder_mean's lag (2^-16 counts)
 * scaled by nm_per_count (rounded; after the 2-D map, which is taken at
 * the sample: the map's slope over half a tick's travel is below a nm);
 * the decoders' own output (pos_nm, the status) stays the sample's.
 * Interpolated measurement (cfg->enc_interp, drive.h): the feedback of
 * every axis is its decoder's position plus enc_interp_pos's estimate
 * below the count (2^-16 counts, scaled as the mean's lag), at the sample,
 * or with enc_mean hal_encoder_mean's lag plus enc_interp_mean_residual
 * over the tick (1e9 / tick_hz rounded, ns); the decoders' own output
 * stays the sample's.
 * drive_inputs_mean_ok: the port provides it for axes 0..axes-1.
 * drive_inputs_set_mean switches it (main, planner idle: the reference at
 * rest).
 *
 * Contexts: init main (drive_init, tick not running); the samples tick;
 * encoder edges (qdec_edge on enc[]) the edge interrupt per qdec.h. The
 * fields are the tick's; main reads them inside the drive's snapshot.
 */
#ifndef DRIVE_INPUTS_H
#define DRIVE_INPUTS_H

#include <stdbool.h>
#include <stdint.h>

#include "comp2d_live.h"
#include "drive.h"
#include "enc_interp.h"
#include "hal.h"
#include "qdec.h"
#include "servo.h"

typedef struct {
    qdec_t enc[CORE_AXES];
    qdec_t refs[CORE_AXES]; /* configuration and scaling only (see ref_*) */
    bool ref_on[CORE_AXES]; /* axis i has a reference scale */
    /* Reference scales: only their position is ever read (published as
     * refscale), so just the counter's unwrapped count (what
     * qdec_sample_counter accumulates) is kept and scaled. */
    uint32_t ref_raw[CORE_AXES]; /* counter value at the last sample   */
    int64_t ref_cnt[CORE_AXES];  /* counts since init                   */
    pos_nm_t ref_nm[CORE_AXES];  /* position, nm (published)            */
    bool any_counter;            /* some axis in use has enc_counter    */
    bool mean;                   /* enc_mean (main writes, planner idle) */
    bool slow;                   /* any_counter, mean or interp: the
                                  * out-of-line sample (main writes with
                                  * mean)                              */
    bool interp;                 /* enc_interp (drive_inputs_init)      */
    uint32_t tick_ns;            /* 1e9 / tick_hz: enc_mean's window    */
    enc_interp_t ip[CORE_AXES];  /* enc_interp per axis (tick)          */
} drive_inputs_t;

/* Set up the decoders of cfg's axes at now_ns (see above). False when a
 * decoder refuses its configuration or an enc_counter axis has no counter
 * on this port. Main. */
bool drive_inputs_init(drive_inputs_t *in, const drive_config_t *cfg, uint32_t now_ns);

/* True when hal_encoder_mean answers for axes 0..axes-1. Any. */
bool drive_inputs_mean_ok(unsigned axes);
void drive_inputs_set_mean(drive_inputs_t *in, bool on);

/* A lag in 2^-16 counts in nm: fx_muldiv64(lag, num, den 2^16) (rounded,
 * ties away from zero, saturated), the same result for every argument, in
 * one product and a shift for den 1 and |lag| < 2^31 (the usual scale, a
 * lag within 2^15 counts). Pure. */
static inline int64_t drive_inputs_lag_nm(int64_t lag, int32_t num, int32_t den)
{
    if (den == 1 && lag == (int64_t)(int32_t)lag) {
        /* |lag num| < 2^62; ties away from zero on the magnitude */
        int64_t p = (int64_t)(int32_t)lag * num;
        int64_t q = (int64_t)((fx_uabs64(p) + 32768u) >> 16);

        return p < 0 ? -q : q;
    }
    return fx_muldiv64(lag, num, (int64_t)den * 65536);
}

/* drive_inputs_sample with counters or the mean (out of line). Tick. */
void drive_inputs_sample_slow(drive_inputs_t *in, const drive_config_t *cfg, uint32_t now_ns,
                              servo_fb_t *fb);

/* Sample every encoder at now_ns and fill fb as servo_fb_from_qdec would
 * (pos_nm, the fault bit; 0 beyond cfg->axes). Inline: the tick. */
static inline void drive_inputs_sample(drive_inputs_t *in, const drive_config_t *cfg,
                                       uint32_t now_ns, servo_fb_t *fb)
{
    uint32_t enc_fault = 0;
    unsigned i;
    if (in->slow) {
        drive_inputs_sample_slow(in, cfg, now_ns, fb);
        return;
    }
    for (i = 0; i < CORE_AXES; i++) { /* the usual configuration: edges */
        qdec_t *q = &in->enc[i];
        if (i >= cfg->axes) {
            fb->pos[i] = 0;
            continue;
        }
        qdec_sample(q, now_ns);
        fb->pos[i] = q->out.pos_nm;
        if (q->out.faults != 0) {
            enc_fault |= 1u << i;
        }
    }
    fb->enc_fault = enc_fault;
    /* the 2-D map (no map: one load and a branch); the feedback and the
     * decoders' output alike, as for the 1-D tables */
    comp2d_live_apply(&in->enc[0].out.pos_nm, &in->enc[1].out.pos_nm, &fb->pos[0], &fb->pos[1]);
}

/* Sample the reference scales of the first `axes` axes (see above). Tick. */
void drive_inputs_ref_sample(drive_inputs_t *in, unsigned axes);

#endif /* DRIVE_INPUTS_H */
