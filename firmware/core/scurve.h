/*
 * scurve.h - single-block velocity profiles: jerk-limited (S-curve, 7 phases)
 * and trapezoidal, in closed form.
 *
 * Specification
 * -------------
 * A block of length `len` (nm) is entered at v0 and left at v1 (nm/s) with the
 * path acceleration zero at both ends (S-curve) and never faster than
 * `lim.v_max`. The profile is three segments:
 *
 *   accel  v0 -> vp : phases 0 (jerk +J), 1 (constant acc), 2 (jerk -J)
 *   cruise at vp    : phase 3
 *   decel  vp -> v1 : phases 4 (jerk -J), 5 (constant dec), 6 (jerk +J)
 *
 * Closed forms for a speed change dv >= 0 at jerk J, acceleration A:
 *   dv >= A^2/J (acceleration limit reached):
 *       t_j = A/J, t_a = dv/A - A/J,       distance = (2 v + dv)/2 (dv/A + A/J)
 *   dv <  A^2/J (reduced: A not reached):
 *       t_j = sqrt(dv/J), t_a = 0,         distance = (2 v + dv) sqrt(dv/J)
 * (v the lower of the two speeds; the segment is symmetric in time so its mean
 * speed is the mid speed). Trapezoidal mode: t_j = 0, t_a = dv/A.
 *
 * Peak speed vp: vp = v_max when the two segments at v_max fit in len (full
 * 7-phase or 5/3-phase profile with cruise). Otherwise ("target speed not
 * reached") vp is the closed-form lower bound
 *     vp = sc_reach(max(v0, v1), (len - dist(min, max)) / 2)
 * which is feasible because dist(a, c) <= dist(a, b) + dist(b, c) for the
 * time-optimal segment; the distance it leaves is cruised at vp (phase 3).
 * Trapezoidal mode solves vp exactly: vp^2 = (2 A len + v0^2 + v1^2) / 2.
 *
 * sc_reach(v, d): the largest speed reachable from v within distance d (a
 * guaranteed lower bound). Trapezoid: sqrt(v^2 + 2 A d). S-curve with the
 * acceleration limit reached: the quadratic in dv, solved in the stable form
 *     dv = 4 A (d - v A/J) / (sqrt((2v - A^2/J)^2 + 8 A d) + 2v + A^2/J).
 * S-curve without it: the depressed cubic J w^3 + 2 v w = d in w = sqrt(dv/J)
 * (a half segment time). First, where sc_dist decides by one exact
 * comparison (d >= 8192 nm and below 2^31 nm, v + v_max <= 3.04e9 nm/s, the
 * gain below A^2/J), the closed form: with K = floor(d)^2 J, hi is
 * reachable from v iff (v + hi)^2 (hi - v) <= K (exact 128-bit
 * comparison). From rest the gain is cbrt(K) (a 56-entry seed and one
 * Halley step, within 6e-6); from v > 0 and c = K / (8 v^3) <= 3/8 it is
 * 2v t with t (1 + t)^2 = c, t = c R, R the Pade [2/2] approximant
 * (11 + 54c + 26c^2) / (11 + 76c + 101c^2) refined by one Newton step
 * (within 4e-6); v_max first when it passes the comparison. The gain is
 * lowered by 2^-16 (rest) or 2^-14 + 2 nm/s (v > 0), capped at v_max and
 * returned only if the comparison confirms it: gain >= 1 - 2^-14 - 2e-5 of
 * the exact one, minus 3 nm/s (test_scurve test_reach_closed_form).
 * Otherwise (v > 0) v_max itself is returned when
 * sc_dist(v, v_max) <= d. Then an estimate: from rest w = cbrt(d / J)
 * (20 significant bits), from v > 0 four Newton steps from w_u (below) in a
 * normalised 32-bit-mantissa format; the gain J w^2, lowered by 1/4096 +
 * 2 nm/s and capped at v_max, is returned when sc_dist confirms it
 * (sc_dist(v, result) <= d). Otherwise the bracketing path: the closed-form
 * upper bound w_u = min(d / 2v, cbrt(d / J)) improved by three fixed Newton
 * steps (each stays an upper bound: the cubic is convex), and the returned
 * lower bound is the chord value w = d / (J w_u^2 + 2 v). No loop runs to
 * convergence: the cost is bounded and the result never overshoots.
 * Speed gain >= 0.995 of the exact reach (test_scurve: worst 0.9971).
 *
 * Units and formats
 *   time       int64 ns (phase durations, floored to whole ns)
 *   speed      int64 nm/s, 0 .. SC_V_LIMIT
 *   acc, jerk  int64 nm/s^2, nm/s^3 (SC_A_MIN..SC_A_LIMIT, SC_J_MIN..SC_J_LIMIT)
 *   state      sc_state_t: s in nm * 2^16 (q48_16), v in nm/s * 2^16,
 *              a in nm/s^2 * 2^16; evaluation uses time in s * 2^40 (phases
 *              with acceleration, < 2^52 ns) or exact ns products (cruise)
 *
 * The realised profile is the one sc_eval() computes from the integer phase
 * durations: phase start states are obtained by evaluating the previous
 * phase at its full duration, so they are continuous by construction. The
 * realised distance `s_end_q16` differs from len * 2^16 by less than
 * vp * 1 ns (rounding of the cruise time); the interpolator scales it out.
 *
 * At-rest S-curve (SC_SHAPE_SCURVE_AT_REST): the shape is chosen by the
 * speeds, so every function below stays consistent with the others:
 *   sc_dist(va, vb)     S-curve if min(va, vb) == 0, else trapezoid;
 *   sc_reach(v, d)      S-curve if v <= 0, else trapezoid;
 *   sc_plan(v0, v1)     S-curve if v0 == 0 or v1 == 0 (a block that starts
 *                       or ends at rest), else trapezoid.
 * The resulting reach is still monotone in v (from rest the S-curve reaches
 * less than the trapezoid: sc_reach(0, d) <= trapezoid reach from any v),
 * and the distance from or to rest is monotone in the other speed.
 *
 * Range checks (plan_check_profile enforces them per axis): a_max/j_max <= 3 s
 * (SC_TJ_MAX_NS), so every square root argument fits 63 bits.
 *
 * Contexts: pure functions, reentrant, no floating point, bounded time.
 */
#ifndef SCURVE_H
#define SCURVE_H

#include <stdbool.h>
#include <stdint.h>

#define SC_PHASES 7

#define SC_V_LIMIT   ((int64_t)4294967295)      /* 4.29 m/s                 */
#define SC_A_MIN     ((int64_t)1000)            /* 1 um/s^2                 */
#define SC_A_LIMIT   ((int64_t)1000000000000)   /* 1000 m/s^2               */
#define SC_J_MIN     ((int64_t)1000)            /* 1 um/s^3                 */
#define SC_J_LIMIT   ((int64_t)100000000000000) /* 1e5 m/s^3                */
#define SC_LEN_MAX   ((int64_t)1 << 40)         /* 1.1 km per block         */
#define SC_NS_PER_S  ((int64_t)1000000000)
#define SC_TJ_MAX_NS ((int64_t)3000000000) /* a_max / j_max at most 3 s */

typedef enum {
    SC_SHAPE_SCURVE = 0,           /* jerk-limited, acceleration zero at block ends */
    SC_SHAPE_TRAPEZOID = 1,        /* acceleration-limited, jerk unbounded          */
    SC_SHAPE_SCURVE_AT_REST = 2,   /* S-curve where a speed involved is 0, else
                                    * trapezoid (see "At-rest S-curve" above) */
    SC_SHAPE_SCURVE_CONTINUOUS = 3 /* jerk-limited with the acceleration
                                    * continuous across blocks: a planner
                                    * shape (planner.h); the functions below
                                    * never see it (blocks get the S-curve) */
} sc_shape_t;

typedef struct {
    int64_t v_max; /* nm/s, cruise limit of the block                  */
    int64_t a_max; /* nm/s^2                                           */
    int64_t j_max; /* nm/s^3 (ignored for SC_SHAPE_TRAPEZOID)          */
    uint8_t shape; /* sc_shape_t                                       */
} sc_limits_t;

/* State on a profile: distance, speed and acceleration, all * 2^16. */
typedef struct {
    int64_t s_q16; /* nm * 2^16    */
    int64_t v_q16; /* nm/s * 2^16  */
    int64_t a_q16; /* nm/s^2 * 2^16 */
} sc_state_t;

typedef struct {
    int64_t t_ns[SC_PHASES];     /* phase durations, ns                       */
    int64_t jerk[SC_PHASES];     /* jerk of each phase, nm/s^3 (signed)       */
    int64_t j6_q16[SC_PHASES];   /* jerk / 6 * 2^16 (evaluation constant)     */
    sc_state_t start[SC_PHASES]; /* realised state at each phase start (the
                                  * acceleration used by the phase: set, not
                                  * continuous, in trapezoidal mode)        */
    int64_t len;                 /* nm                                       */
    int64_t v0, vp, v1;          /* entry, peak (cruise) and exit speed, nm/s */
    int64_t total_ns;            /* sum of t_ns                              */
    int64_t s_end_q16;           /* realised distance at total_ns            */
} sc_profile_t;

/* floor(a * b / c) with a 128-bit product, saturated to INT64_MAX; a, b >= 0,
 * c > 0 (c == 0 saturates). */
int64_t sc_muldiv(int64_t a, int64_t b, int64_t c);
/* ceil(a * b / c), same rules. */
int64_t sc_muldiv_ceil(int64_t a, int64_t b, int64_t c);

/* a * b saturated to INT64_MAX; 0 when a <= 0 or b <= 0 (= sc_muldiv(a, b, 1)). */
int64_t sc_mul_sat(int64_t a, int64_t b);

/* Sign of a * b - c * d (-1, 0, 1) with exact 128-bit products: compares
 * the ratios a / c and d / b without dividing (the planner picks the axis
 * that limits a block with it, then divides once). */
int sc_cmp_products(uint64_t a, uint64_t b, uint64_t c, uint64_t d);

/* Distance (nm, rounded up) to change speed between va and vb (either
 * order) with acceleration zero at both ends. Reduced S-curve case with
 * (va + vb)^2 and (va + vb)^2 dv / J below 2^63: the exact ceiling of
 * (va + vb) sqrt(dv / J) (one division); otherwise through the half-segment
 * time rounded up to whole ns (never below the exact ceiling). */
int64_t sc_dist(int64_t va, int64_t vb, const sc_limits_t *lim);

/* Largest speed (nm/s) reachable from v within distance d (nm), never above
 * lim->v_max (and never below v). A lower bound: sc_dist(v, result) <= d. */
int64_t sc_reach(int64_t v, int64_t d, const sc_limits_t *lim);

/* floor (*q) and ceil (*qc) of a_max^2 / j_max, the speed change that
 * reaches a_max (one 128/64 division); a_max, j_max > 0. */
void sc_limits_aaj(const sc_limits_t *lim, int64_t *q, int64_t *qc);

/* sc_reach with floor and ceil of a_max^2 / j_max supplied (from
 * sc_limits_aaj on the same limits; both < 0: computed; q >= 0 with
 * qc < 0: q is a lower bound of the floor, used by the closed form, and the
 * exact values are computed only if another path runs). Always a lower
 * bound of the reach (sc_dist(v, result) <= d); with the exact values the
 * same result as sc_reach. */
int64_t sc_reach_pre(int64_t v, int64_t d, const sc_limits_t *lim, int64_t q, int64_t qc);

/* The closed-form reach's constants for one distance d (nm) and limits
 * (the planner keeps them per block: its passes always reach over the
 * whole block): K = d^2 J (128 bits, exact) and its top 32 bits; bk = 0
 * when the closed form does not apply to d and lim (then sc_reach_k is
 * sc_reach_pre). */
typedef struct {
    uint64_t k_hi, k_lo;
    int64_t d; /* the distance, nm                          */
    int64_t q; /* q and qc as for sc_reach_pre               */
    int64_t qc;
    uint32_t mk; /* top 32 bits of K                          */
    int32_t bk;  /* bit length of K, or 0                     */
} sc_reach_k_t;

/* q, qc: as for sc_reach_pre (floor and ceil of A^2/J; or a lower bound
 * of the floor and qc < 0). */
void sc_reach_k_init(sc_reach_k_t *rk, int64_t d, const sc_limits_t *lim, int64_t q, int64_t qc);

/* sc_reach_pre(v, d, lim, q, qc) with rk from sc_reach_k_init(rk, d, lim, q,
 * qc) on the same limits (v_max may have been lowered since): the same
 * result. */
int64_t sc_reach_k(int64_t v, const sc_limits_t *lim, const sc_reach_k_t *rk);

/* Plan one block: fills *p (phases, realised states, total time). v0 and v1
 * must satisfy sc_dist(v0, v1) <= len (the planner guarantees it); if they
 * do not, the block still gets a valid profile whose realised distance falls
 * short and the interpolator scales it. */
void sc_plan(sc_profile_t *p, int64_t len, int64_t v0, int64_t v1, const sc_limits_t *lim);

/* floor((2^64 - 1) / v) for 1 <= v < 2^32 (0 otherwise): the reciprocal
 * sc_plan_cruise_rec takes (the planner keeps it while consecutive blocks
 * cruise at the same speed). */
uint64_t sc_cruise_recip(int64_t v);

/* sc_plan(p, len, v, v, lim), the cruise time's division replaced by a
 * multiply with rec = sc_cruise_recip(v) and an exact remainder correction
 * (rec == 0: divided): the same profile. */
void sc_plan_cruise_rec(sc_profile_t *p, int64_t len, int64_t v, const sc_limits_t *lim,
                        uint64_t rec);

/* State at time t_ns from the start of phase `ph` (0 <= t_ns <= t_ns[ph]). */
void sc_eval_phase(const sc_profile_t *p, int ph, int64_t t_ns, sc_state_t *out);

/* State at time t_ns (clamped to [0, total_ns]) from the block start. */
void sc_eval(const sc_profile_t *p, int64_t t_ns, sc_state_t *out);

/* Time split of a planned profile, ns. */
int64_t sc_time_accel(const sc_profile_t *p);
int64_t sc_time_cruise(const sc_profile_t *p);
int64_t sc_time_decel(const sc_profile_t *p);

#endif /* SCURVE_H */
