/*
 * interp.h - interpolator: turns frozen planner segments into the per-tick
 * reference (motion_ref_t) of every axis.
 *
 * Specification
 * -------------
 * The main context pops blocks from the planner into the FIFO with
 * interp_refill() (one block per call while there is room); the tick context calls interp_tick()
 * once per control tick. The two share a single-producer single-consumer FIFO of INTERP_FIFO
 * segments: main writes a slot then advances `wr`; tick reads a slot then advances `rd`. Each index
 * is written by one context only.
 *
 * Time. Each tick advances the time of the current block by tick_ns (an
 * integer number of ns). When it reaches the block's duration the excess is
 * carried into the next block, so the block boundaries fall exactly where
 * the planner put them on a continuous time line: a block is current for
 * ceil or floor of (its duration / tick) ticks, and n consecutive blocks
 * take their summed duration to within one tick. If the FIFO is empty when
 * a block ends, the reference stays at its end point (the planner plans the
 * last queued block to stop there); a block that arrives while idle starts
 * at the next tick. Ending a block with a non-zero exit speed on an empty
 * FIFO is an underrun (counted in `underruns`).
 *
 * Reference. Path distance s(t) is the planner's profile evaluated in closed
 * form (scurve.h, sc_eval_phase) at the block time, times the factor
 * len / s_end that absorbs the sub-nanometre rounding of the phase times.
 * Axis i: pos_i = start_i + round(s * delta_i / len) with the exact ratio
 * in q2_62, so the last tick of a block lands exactly on its integer end
 * point and nothing drifts over any number of blocks. Cost (Cortex-M4):
 * in cruise phases the distance floor(v * tau / 1e9) advances by an exact
 * quotient/remainder increment per tick (no 128-bit multiply-divide) and
 * the velocities are those of the phase start; the products are inline
 * 32 x 32 -> 64 multiplies. A cruise tick that stays inside its phase and
 * segment (the usual tick) takes a short path that updates only the
 * quotient, the corrected distance and the positions (cr_fast). Every
 * output equals the closed form bit for bit (test_interp checks it on
 * every tick). Velocity and
 * acceleration feed-forward: v * u_i and a * u_i (nm/s, nm/s^2). Geometry:
 * MOTION_GEOM_LINE through the block start with the block's unit tangent
 * (q1_30); MOTION_GEOM_NONE while idle or dwelling. The planner has no arc
 * blocks, so MOTION_GEOM_ARC is never produced.
 *
 * Limits: inside a block the reference follows the profile, whose speed,
 * acceleration and jerk never exceed the block's (projected) limits; the
 * generated positions are those of the continuous profile rounded to 1 nm
 * (model error < 0.01 nm), so finite differences of the references exceed
 * the limits only by the rounding (|d^k p| <= lim * h^k + 2^(k-1) nm). At
 * junctions the axis velocity steps by v * (u2 - u1) as the cornering rule
 * allowed (a sharp corner at non-zero speed).
 *
 * Units: positions nm, velocities nm/s, accelerations nm/s^2, times ns and
 * ticks.
 */
#ifndef INTERP_H
#define INTERP_H

#include <stdbool.h>
#include <stdint.h>

#include "core_config.h"
#include "motion_ref.h"
#include "planner.h"
#include "preempt.h"

#ifndef INTERP_FIFO
#define INTERP_FIFO 8 /* a power of two */
#endif

typedef struct {
    /* shared FIFO: main writes a slot, then wr; the tick reads the slot
     * after wr, then advances rd */
    plan_seg_t fifo[INTERP_FIFO]; /* main                                    */
    CORE_SHARED uint16_t wr;      /* main                                    */
    CORE_SHARED uint16_t rd;      /* tick                                    */
    /* tick state (every field below: tick; interp_init / interp_reset write
     * them from main only while the tick does not run the interpolator) */
    int64_t tick_ns;
    bool busy;               /* a segment is current                   */
    int64_t t_ns;            /* time into the current segment, ns      */
    int phase;               /* current phase of the segment           */
    int64_t phase_t0;        /* start time of that phase, ns           */
    int64_t corr_q32;        /* (len * 2^16 - s_end) / s_end, q32      */
    pos_nm_t pos[CORE_AXES]; /* hold position: the last reference position
                              * of a general tick (fast-path ticks write
                              * only the reference's)                    */
    uint64_t ticks;          /* ticks since init                       */
    uint64_t busy_ticks;     /* ticks with a segment current           */
    uint32_t blocks_done;    /* segments completed                     */
    uint32_t underruns;      /* segments that ended moving, FIFO empty */
    uint32_t tag;            /* tag of the current (or last) segment   */
    /* Written by interp_tick for the drive's arc overlay and stop ramp
     * (tick context; zero while idle or dwelling): */
    int64_t s_q16; /* path distance into the current segment,
                    * q16 nm, in [0, len * 2^16]              */
    int64_t v_q16; /* profile path speed, q16 nm/s (>= 0)     */
    int64_t a_q16; /* profile path acceleration, q16 nm/s^2   */
    /* per-segment constants (set when a segment begins) */
    q1_30_t tan[CORE_AXES]; /* unit tangent, ratio_q62 / 2^32          */
    /* Cruise phases (jerk 0, acceleration 0, speed v >= 0): the distance
     * floor(v * tau / 1e9) is advanced by whole ticks of cr_h ns as an
     * exact quotient (cr_q) and remainder (cr_r < 1e9) instead of a
     * 128-bit multiply-divide per tick; identical to sc_eval_phase. */
    bool cr_ok;                /* the cache below holds this phase         */
    int cr_phase;              /* phase of the cache                       */
    int64_t cr_tau;            /* time into the phase of the last tick, ns
                                * (not kept up to date while cr_fast)     */
    int64_t cr_h;              /* step the increments below are for, ns    */
    uint64_t cr_q, cr_dq;      /* v * cr_tau = cr_q * 1e9 + cr_r           */
    uint32_t cr_r, cr_dr;      /* v * cr_h = cr_dq * 1e9 + cr_dr (< 1e9)  */
    int64_t cr_vel[CORE_AXES]; /* axis velocities of the cruise, nm/s   */
    uint64_t cr_ur[CORE_AXES]; /* |ratio_q62| of the segment            */
    bool cr_neg[CORE_AXES];    /* ratio_q62 < 0                          */
    /* Cruise fast path: while cr_fast, a tick of cr_h ns whose new time
     * stays below cr_tend (the end of the phase or of the segment, ns) is
     * a cache hit of the same phase with no phase or segment change, so
     * interp_tick evaluates only the quotient step, the length correction
     * (corr_q32 fits int32) and the positions: the same values. */
    bool cr_fast;
    int64_t cr_tend; /* min(phase end, segment end), ns into the segment */
    int64_t cr_s0;   /* path distance at the phase start, q16 nm         */
    int64_t cr_lq;   /* segment length, q16 nm                           */
    /* True when the last interp_tick was a fast-path tick, which writes
     * only ref->pos[]: every other field of the motion_ref_t is what the
     * tick before wrote (the same values). Tick context. */
    bool ref_pos_only;
    /* Bit i: fast-path ticks leave pos[i] (of ip and of the reference)
     * unwritten, stale (the drive sets it for the plane axes whose arc
     * overlay rewrites them without reading them). Written by the caller
     * after an interp_tick, in effect for the following fast-path ticks;
     * every other tick clears it and writes every axis. Tick context. */
    uint8_t fast_skip;
} interp_t;

/* Initialise idle at `start` with a tick period of tick_ns (> 0). Main,
 * with the tick not running the interpolator. */
void interp_init(interp_t *ip, int64_t tick_ns, const pos_nm_t start[CORE_AXES]);

/* Free FIFO slots. Main. */
uint16_t interp_room(const interp_t *ip);

/* Pop ONE planner block into the FIFO if there is room; returns 1 if it did.
 * The main loop pushes every block it has (until the planner is full)
 * before each call, so that each block is frozen with the same look-ahead
 * as plan_estimate() gives it:
 *     while (interp_room(ip)) { push_all_available(); if (!interp_refill(ip, p)) break; }
 * Main. */
unsigned interp_refill(interp_t *ip, plan_t *p);

/* Advance one tick and write the reference for the new time into *ref.
 * A cruise fast-path tick (ip->ref_pos_only set) writes only ref->pos[]:
 * the caller passes the same motion_ref_t every tick and changes none of
 * its fields (a caller that adjusts the reference works on a copy; the
 * drive does). Every other tick writes every field. Tick. */
void interp_tick(interp_t *ip, motion_ref_t *ref);

/* True when no segment is current or queued (reads wr and rd only: busy
 * implies rd != wr, the current segment stays in the FIFO until it ends).
 * Any. */
static inline bool interp_idle(const interp_t *ip)
{
    return ip->wr == ip->rd;
}

/* ---- accessors: the only way other modules read or write an interp_t ----
 * (static inline: the drive's tick uses them). */

/* A segment is current (not idle between segments or at rest). Tick. */
static inline bool interp_busy(const interp_t *ip)
{
    return ip->busy;
}

/* Tag of the current (or last) segment. Tick. */
static inline uint32_t interp_tag(const interp_t *ip)
{
    return ip->tag;
}

/* Segments completed since interp_init. Tick. */
static inline uint32_t interp_blocks_done(const interp_t *ip)
{
    return ip->blocks_done;
}

/* Segments that ended moving on an empty FIFO since interp_init. Any. */
static inline uint32_t interp_underruns(const interp_t *ip)
{
    return ip->underruns;
}

/* The time step of the following ticks, ns (>= 0; 0 holds the time): the
 * drive's controlled stop slows the interpolator's time down. Tick (or main
 * with the tick stopped). */
static inline void interp_set_tick_ns(interp_t *ip, int64_t tick_ns)
{
    ip->tick_ns = tick_ns;
}

/* The last interp_tick was a fast-path tick (see interp_t.ref_pos_only). */
static inline bool interp_pos_only(const interp_t *ip)
{
    return ip->ref_pos_only;
}

/* The axes fast-path ticks leave unwritten (see interp_t.fast_skip). Tick. */
static inline unsigned interp_fast_skip(const interp_t *ip)
{
    return ip->fast_skip;
}

static inline void interp_set_fast_skip(interp_t *ip, uint8_t mask)
{
    ip->fast_skip = mask;
}

/* The next tick may be a cruise fast-path tick (interp_t.cr_fast). Tick. */
static inline bool interp_cruise_next(const interp_t *ip)
{
    return ip->cr_fast;
}

/* Length of the current segment, nm (0 when idle). Tick. */
static inline int64_t interp_seg_len(const interp_t *ip)
{
    return ip->busy ? ip->fifo[ip->rd & (INTERP_FIFO - 1)].len : 0;
}

/* Path advance of one cruise fast-path tick of the current phase, q32 nm:
 * ds = (cr_dq + cr_dr / 1e9) * 2^16 * (1 + corr_q32 / 2^32), the fast
 * path's step in q16 nm (to within 2 q16 units, not accumulated) in q32,
 * the remainder's division by a reciprocal (within 1 of the exact floor).
 * -1 when the step is 2^46 q16 nm or more (no such phase is needed). Tick,
 * after an interp_tick that left interp_cruise_next() true. */
int64_t interp_cruise_ds_q32(const interp_t *ip);

/* Planned time queued after the current segment, ns: the FIFO slots
 * main wrote beyond the one the tick reads (0 when idle). Main. */
int64_t interp_ahead_ns(const interp_t *ip);

/* Read index of the FIFO and the time left in the current segment (-1 when
 * none), for a snapshot inside the tick's publication window (it reads the
 * tick's fields: validated by the snapshot's count, CORE_NO_TSAN). Main. */
static inline uint16_t interp_rd(const interp_t *ip)
{
    return ip->rd;
}

static inline CORE_NO_TSAN int64_t interp_left_ns(const interp_t *ip)
{
    int64_t rem;

    if (!ip->busy) {
        return -1;
    }
    rem = ip->fifo[ip->rd & (INTERP_FIFO - 1)].total_ns - ip->t_ns;
    return rem < 0 ? 0 : rem;
}

/* Planned time in the FIFO from slot rd (a read index the tick published)
 * to the write index, ns, the slot rd counted by rem_rd when rem_rd >= 0
 * (the time left in it) and in full otherwise. Main (the only writer of
 * the slots). */
int64_t interp_queued_ns(const interp_t *ip, uint16_t rd, int64_t rem_rd);

/* Drop everything (after a stop or a fault) and hold `pos`. Main, with the
 * tick not running the interpolator (the drive: tick parked, drive.c). */
void interp_reset(interp_t *ip, const pos_nm_t pos[CORE_AXES]);

#endif /* INTERP_H */
