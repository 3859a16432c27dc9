/*
 * drive_int.h - interfaces between the drive's own modules (drive.c, the
 * state machine; drive_req.c, main's requests to it and main's view of its
 * state; drive_param.c, the parameter table); not for other subsystems.
 */
#ifndef DRIVE_INT_H
#define DRIVE_INT_H

#include <stdbool.h>

#include "arc_ref.h"
#include "drive.h"
#include "drive_ff.h"
#include "drive_home.h"
#include "drive_inputs.h"
#include "interp.h"
#include "motion_ref.h"
#include "preempt.h"

/* The drive's state (defined in drive.c). Ownership (docs/tick-main.md):
 * every field says which context writes it (main: the feed path and the
 * requests; tick: the state, decoders, servo, reference, snapshot; init:
 * drive_init). Only drive.c and drive_req.c touch it. */
typedef struct {
    bool ready;                /* init (drive_init runs before the tick is started) */
    uint8_t enc_edges;         /* init: bit i: ready, i < cfg.axes and not enc_counter[i]
                                * (the channels drive_encoder_edge / _run deliver to;
                                * CORE_AXES <= 8, checked in drive.c) */
    drive_config_t cfg;        /* init; main: see docs/tick-main.md */
    drive_cec_mode_t cec_mode; /* main */
    interp_t ip;               /* producer side main, consumer side tick (interp.h) */
    /* requests: main sets (drive_post()), the tick clears after the effect */
    CORE_SHARED bool req_enable; /* main flushed (DISABLED): switch on    */
    CORE_SHARED bool req_resume; /* main flushed (halted): STOPPING->IDLE */
    CORE_SHARED bool req_disable, req_stop, req_estop, req_reset, req_gains, req_cec;
    CORE_SHARED bool req_ref;  /* main (drive_status): sample the reference scales */
    CORE_SHARED bool req_home; /* main: start homing (payload pend_home) */
    CORE_SHARED uint32_t req_fault;
    /* some req_* above (except req_ref) may be set: main sets it after the
     * flag, the tick clears it before it reads the flags */
    CORE_SHARED bool req_any;
    uint32_t rs_seq;      /* main, payload of req_enable / req_resume */
    servo_params_t pend;  /* main, payload of req_gains */
    cec_mode_t pend_mode; /* main, payload of req_cec   */
    /* tick, read by main (the snapshot, or the state as drive_main_state() reads it) */
    CORE_SHARED drive_state_t state_pub; /* `state` as the tick wrote it */
    CORE_SHARED bool halted;             /* controlled stop reached rest: reference held */
    /* tick only (main reads some inside the snapshot's sequence count) */
    drive_inputs_t in; /* encoders and reference scales (drive_inputs.h) */
    servo_t servo;
    motion_ref_t ref;
    drive_state_t state; /* the tick's copy (plain: read often per tick) */
    uint32_t faults;
    int64_t stop_v;  /* stopping: path speed cap, nm/s               */
    int64_t stop_dv; /* stopping: cap decrease per tick, nm/s        */
    int64_t v_plan;  /* interpolator's (unscaled) path speed, nm/s   */
    int64_t a_plan;  /* ... and tangential acceleration, nm/s^2      */
    /* The interpolator's (chord) reference of the last tick: written by
     * interp_tick only (a fast-path tick writes only its pos[]); drv.ref is
     * built from it (reference_step), then the arc overlay, the stop
     * scaling and the friction feed-forward adjust drv.ref. */
    motion_ref_t ch;
    /* drv.ref holds every field of ch except those the arc overlay rewrites
     * every tick of an arc segment (pos and the plane axes' vel, acc and
     * tangent, the geometry's arc fields): nothing else changed it since the
     * last full copy. A fast-path tick then copies only pos. */
    bool ref_synced;
    bool ref_full;                /* test hook (drive_test_full_ref): no pos-only copy */
    int64_t v_act;                /* path speed of the reference last tick, nm/s  */
    arc_ref_t arc;                /* arc overlay (tick)                           */
    drive_ff_t ff;                /* advance, friction and quadrant feed-forward (drive_ff.h) */
    CORE_SHARED uint32_t tick_lo; /* low word of tick (main reads it) */
    uint32_t seen_done;           /* interpolator segments accounted */
    uint32_t seq_done;            /* internal tag of the next segment to complete */
    uint32_t blocks_done;
    uint32_t cur_tag;
    uint64_t tick;
    /* published snapshot (tick; main reads it under st_seq) */
    CORE_SHARED uint32_t st_seq;
    drive_status_t st;
    /* last: the usual tick's fields keep short offsets */
    uint32_t homed; /* tick: axes homed (main reads it in the snapshot) */
    home_t home;    /* homing sequence (tick, while HOMING) */
} drive_app_t;

extern drive_app_t drv;

/* drive_init succeeded. Any. */
bool drive_ready(void);

/* Take the motion fields of c (plan, stop_decel_nm_s2, arc_chord_nm,
 * start_delay_ms, soft limits, in-position window, the feed-forward
 * corrections ff_advance_ns, friction_ff_mv, friction_ff_band_nm_s,
 * qg_comp (drive_ff.h); the others are ignored) if plan_check_profile accepts the
 * profile (else DRIVE_E_INVALID) and the planner is idle: nothing queued,
 * executing or stopping (else DRIVE_E_BUSY); the empty planner is then
 * re-initialised at its position. All or nothing. Main. */
drive_result_t drive_apply_config(const drive_config_t *c);

/* servo_init on a probe in the scratch area (scratch.h): DRIVE_OK when q
 * is a valid servo configuration, DRIVE_E_INVALID when not, DRIVE_E_BUSY
 * when the area is held. Main. */
drive_result_t drive_servo_probe(const servo_params_t *q);

/* drive_req.c, main context. */
/* Post a request: its payload is written; the flag, then req_any. */
void drive_post(CORE_SHARED bool *flag);
/* The state s as main acts on it, with the requests en(able), dis(able)
 * and stop posted and not yet applied counted as applied. */
drive_state_t drive_main_view(drive_state_t s, bool en, bool dis, bool stop);
/* drive_main_view of the tick's state and every pending request. */
drive_state_t drive_main_state(void);
/* The tick leaves the interpolator alone until main posts a request. */
bool drive_tick_parked(void);
/* RUNNING, STOPPING or HOMING (drive_main_state). */
bool drive_moving(void);

/* drive.c (main, tick parked): drop the queued job and hold pos. */
void drive_flush_all(const pos_nm_t pos[CORE_AXES]);

#endif /* DRIVE_INT_H */
