/*
 * axis_model.c - exact (zero-order-hold) integration of the two-inertia axis.
 * See axis_model.h for the specification.
 */
#include "axis_model.h"

#include <math.h>
#include <string.h>

#define PI_D 3.14159265358979323846

void axis_params_lacerda(axis_params_t *p, bool y_axis)
{
    memset(p, 0, sizeof *p);
    p->B = 2.10e-6;
    p->l = 7.96e-4;
    p->K = 1.10e2;
    p->kb = 2.10e-1;
    p->kt = 2.00e-1;
    p->La = 6.70e-3;
    p->I1 = 2.70e-5;
    p->I2 = y_axis ? 3.50e-6 : 8.30e-6;
    p->Ra = 9.00;
    p->kx = 16.0;
    p->vmax = 160.0;
    p->enc_counts_per_rev = 4000.0;
    p->enc_offset_counts = 0.5;
    p->ref_resolution = 1e-9;
    p->seed = 1;
}

void axis_model_matrices(const axis_params_t *p, double a[AXIS_NSTATE][AXIS_NSTATE],
                         double b[AXIS_NSTATE][AXIS_NINPUT])
{
    memset(a, 0, sizeof(double) * AXIS_NSTATE * AXIS_NSTATE);
    memset(b, 0, sizeof(double) * AXIS_NSTATE * AXIS_NINPUT);
    a[0][1] = 1.0;
    a[1][0] = -p->K / p->I1;
    a[1][1] = -p->B / p->I1;
    a[1][2] = p->K / p->I1;
    a[1][3] = p->B / p->I1;
    a[1][4] = p->kt / p->I1;
    a[2][3] = 1.0;
    a[3][0] = p->K / p->I2;
    a[3][1] = p->B / p->I2;
    a[3][2] = -p->K / p->I2;
    a[3][3] = -p->B / p->I2;
    a[4][1] = -p->kb / p->La;
    a[4][4] = -p->Ra / p->La;
    b[4][0] = p->kx / p->La; /* u: amplifier command (clamp applied before) */
    b[1][1] = -1.0 / p->I1;  /* T1 */
    b[3][2] = -1.0 / p->I2;  /* T2 */
}

/* ---- small dense linear algebra (row-major, n <= 16) ------------------- */

#define NMAX 16

static void matmul(unsigned n, const double *x, const double *y, double *out)
{
    double tmp[NMAX * NMAX] = {0};
    unsigned i, j, k;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) {
            double s = 0.0;
            for (k = 0; k < n; k++) {
                s += x[i * n + k] * y[k * n + j];
            }
            tmp[i * n + j] = s;
        }
    }
    memcpy(out, tmp, sizeof(double) * n * n);
}

/* Diagonal similarity scaling by powers of two (exact in binary floating
 * point) so that row and column norms are comparable: d[i] such that
 * bal = D^-1 m D. */
static void balance(unsigned n, double *m, double *d)
{
    unsigned i, j, pass;
    for (i = 0; i < n; i++) {
        d[i] = 1.0;
    }
    for (pass = 0; pass < 100; pass++) {
        bool changed = false;
        for (i = 0; i < n; i++) {
            double c = 0.0, r = 0.0, f = 1.0, s;
            for (j = 0; j < n; j++) {
                if (j != i) {
                    c += fabs(m[j * n + i]);
                    r += fabs(m[i * n + j]);
                }
            }
            if (c == 0.0 || r == 0.0) {
                continue;
            }
            s = c + r;
            while (c < r / 2.0) {
                c *= 2.0;
                r /= 2.0;
                f *= 2.0;
            }
            while (c >= r * 2.0) {
                c /= 2.0;
                r *= 2.0;
                f /= 2.0;
            }
            if ((c + r) < 0.95 * s) {
                changed = true;
                d[i] *= f;
                for (j = 0; j < n; j++) {
                    m[i * n + j] /= f;
                    m[j * n + i] *= f;
                }
            }
        }
        if (!changed) {
            break;
        }
    }
}

void axis_expm(unsigned n, const double *m, double t, double *out)
{
    double a[NMAX * NMAX], term[NMAX * NMAX], sum[NMAX * NMAX], d[NMAX];
    double norm = 0.0;
    unsigned i, j, k, s = 0;

    for (i = 0; i < n * n; i++) {
        a[i] = m[i] * t;
    }
    balance(n, a, d);
    for (i = 0; i < n; i++) {
        double r = 0.0;
        for (j = 0; j < n; j++) {
            r += fabs(a[i * n + j]);
        }
        if (r > norm) {
            norm = r;
        }
    }
    while (norm > 0.25 && s < 60) {
        norm /= 2.0;
        s++;
    }
    for (i = 0; i < n * n; i++) {
        a[i] = ldexp(a[i], -(int)s);
    }
    /* Taylor series: with ||a|| <= 1/4, 20 terms leave < 1e-30. */
    memset(sum, 0, sizeof(double) * n * n);
    memset(term, 0, sizeof(double) * n * n);
    for (i = 0; i < n; i++) {
        sum[i * n + i] = 1.0;
        term[i * n + i] = 1.0;
    }
    for (k = 1; k <= 20; k++) {
        matmul(n, term, a, term);
        for (i = 0; i < n * n; i++) {
            term[i] /= (double)k;
            sum[i] += term[i];
        }
    }
    for (k = 0; k < s; k++) {
        matmul(n, sum, sum, sum);
    }
    /* undo the balancing: e^{M t} = D e^{bal} D^-1 */
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) {
            out[i * n + j] = sum[i * n + j] * d[i] / d[j];
        }
    }
}

/* ---- eigenvalues: characteristic polynomial + Aberth iteration ----------- */

void axis_model_eigenvalues(const axis_params_t *p, double complex ev[AXIS_NSTATE])
{
    enum { N = AXIS_NSTATE };
    double a[N][N], b[N][AXIS_NINPUT];
    double m[N * N], d[N], mk[N * N], tmp[N * N], c[N + 1];
    const double scale = 1000.0; /* roots in units of 1000 rad/s */
    unsigned i, j, k, it;

    axis_model_matrices(p, a, b);
    for (i = 0; i < N; i++) {
        for (j = 0; j < N; j++) {
            m[i * N + j] = a[i][j] / scale;
        }
    }
    balance(N, m, d);
    /* Faddeev-LeVerrier: det(sI - m) = sum c[k] s^(N-k), c[0] = 1. */
    c[0] = 1.0;
    memset(mk, 0, sizeof mk);
    for (k = 1; k <= N; k++) {
        double tr = 0.0;
        /* mk <- m (mk_prev + c[k-1] I) */
        memcpy(tmp, mk, sizeof tmp);
        for (i = 0; i < N; i++) {
            tmp[i * N + i] += c[k - 1];
        }
        matmul(N, m, tmp, mk);
        for (i = 0; i < N; i++) {
            tr += mk[i * N + i];
        }
        c[k] = -tr / (double)k;
    }
    /* Aberth-Ehrlich iteration from points on a circle. */
    for (i = 0; i < N; i++) {
        double ang = 2.0 * PI_D * (double)i / (double)N + 0.4;
        ev[i] = 3.0 * (cos(ang) + I * sin(ang));
    }
    for (it = 0; it < 500; it++) {
        double maxstep = 0.0;
        for (i = 0; i < N; i++) {
            double complex pv = c[0], dp = 0.0, sum = 0.0, w;
            for (k = 1; k <= N; k++) {
                dp = dp * ev[i] + pv;
                pv = pv * ev[i] + c[k];
            }
            if (cabs(pv) == 0.0) {
                continue;
            }
            for (j = 0; j < N; j++) {
                if (j != i) {
                    sum += 1.0 / (ev[i] - ev[j]);
                }
            }
            w = pv / dp;
            w = w / (1.0 - w * sum);
            ev[i] -= w;
            if (cabs(w) > maxstep) {
                maxstep = cabs(w);
            }
        }
        if (maxstep < 1e-15) {
            break;
        }
    }
    for (i = 0; i < N; i++) {
        ev[i] *= scale;
        if (fabs(cimag(ev[i])) < 1e-9 * (1.0 + cabs(ev[i]))) {
            ev[i] = creal(ev[i]);
        }
    }
    /* insertion sort by real part, then imaginary part */
    for (i = 1; i < N; i++) {
        double complex x = ev[i];
        j = i;
        while (j > 0 && (creal(ev[j - 1]) > creal(x) + 1e-6 * cabs(x) ||
                         (fabs(creal(ev[j - 1]) - creal(x)) <= 1e-6 * cabs(x) &&
                          cimag(ev[j - 1]) > cimag(x)))) {
            ev[j] = ev[j - 1];
            j--;
        }
        ev[j] = x;
    }
}

/* ---- discretisation ----------------------------------------------------- */

static void discretise(const axis_params_t *p, double h, bool free_gap,
                       double phi[AXIS_NSTATE][AXIS_NSTATE], double gam[AXIS_NSTATE][AXIS_NINPUT])
{
    enum { N = AXIS_NSTATE, M = AXIS_NINPUT, NA = AXIS_NSTATE + AXIS_NINPUT };
    double a[N][N], b[N][M], aug[NA * NA], e[NA * NA];
    unsigned i, j;
    axis_params_t q = *p;
    if (free_gap) {
        q.K = 0.0;
        q.B = 0.0;
    }
    axis_model_matrices(&q, a, b);
    memset(aug, 0, sizeof aug);
    for (i = 0; i < N; i++) {
        for (j = 0; j < N; j++) {
            aug[i * NA + j] = a[i][j];
        }
        for (j = 0; j < M; j++) {
            aug[i * NA + N + j] = b[i][j];
        }
    }
    axis_expm(NA, aug, h, e);
    for (i = 0; i < N; i++) {
        for (j = 0; j < N; j++) {
            phi[i][j] = e[i * NA + j];
        }
        for (j = 0; j < M; j++) {
            gam[i][j] = e[i * NA + N + j];
        }
    }
}

static uint64_t splitmix64(uint64_t *s)
{
    uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static double uniform01(uint64_t *s)
{
    return ((double)(splitmix64(s) >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

bool axis_init(axis_t *ax, const axis_params_t *p, double h)
{
    unsigned i;
    memset(ax, 0, sizeof *ax);
    if (!(h > 0.0) || !(p->I1 > 0.0) || !(p->I2 > 0.0) || !(p->La > 0.0) || !(p->l > 0.0) ||
        !(p->K >= 0.0) || !(p->B >= 0.0) || !(p->kx > 0.0) || !(p->vmax > 0.0) ||
        !(p->enc_counts_per_rev >= 1.0) || !(p->enc_counts_per_rev <= AXIS_ENC_COUNTS_MAX) ||
        !(p->l * 2.0 * PI_D <= AXIS_LEAD_MAX_M) || !(p->ref_resolution > 0.0) ||
        p->pitch_n > AXIS_PITCH_MAX || p->coulomb_motor < 0.0 || p->coulomb_table < 0.0 ||
        p->backlash < 0.0 || p->enc_noise_counts < 0.0 || p->pitch_dir_band < 0.0 ||
        !(p->ref_noise >= 0.0)) {
        return false;
    }
    for (i = 1; i < p->pitch_n; i++) {
        if (!(p->pitch_pos[i] > p->pitch_pos[i - 1])) {
            return false;
        }
    }
    ax->p = *p;
    axis_set_load_torque(ax, p->load_torque);
    ax->h = h;
    discretise(p, h, false, ax->phi, ax->gam);
    if (p->backlash > 0.0) {
        discretise(p, h, true, ax->phi_free, ax->gam_free);
    }
    for (i = 0; i < AXIS_NSTATE; i++) {
        unsigned j;
        for (j = 0; j < AXIS_NSTATE; j++) {
            ax->lin[j][i] = ax->phi[i][j];
        }
        ax->lin[AXIS_NSTATE][i] = ax->gam[i][0];
    }
    ax->enc_scale = p->enc_counts_per_rev / (2.0 * PI_D);
    ax->pitch_dir = 1;
    ax->rng = p->seed;
    ax->ref_rng = p->seed ^ 0x52454653u; /* "REFS": a stream of its own */
    return true;
}

static double clampd(double v, double lim)
{
    if (v > lim) {
        return lim;
    }
    if (v < -lim) {
        return -lim;
    }
    return v;
}

static void track_direction(axis_t *ax)
{
    double x = ax->p.l * ax->z[2];
    if (ax->pitch_dir > 0) {
        if (x > ax->pitch_turn) {
            ax->pitch_turn = x;
        } else if (x < ax->pitch_turn - ax->p.pitch_dir_band) {
            ax->pitch_dir = -1;
            ax->pitch_turn = x;
        }
    } else {
        if (x < ax->pitch_turn) {
            ax->pitch_turn = x;
        } else if (x > ax->pitch_turn + ax->p.pitch_dir_band) {
            ax->pitch_dir = 1;
            ax->pitch_turn = x;
        }
    }
}

/* z <- Phi z + Gamma[:, 0] u by columns, two rows per vector operation
 * (GCC/Clang vector extension; lanes do exactly the scalar operations). */
#if defined(__GNUC__)
#define AXIS_NOINLINE __attribute__((noinline))
#else
#define AXIS_NOINLINE
#endif

__extension__ typedef double axis_v2 __attribute__((vector_size(16)));

static axis_v2 v2_load(const double *p)
{
    axis_v2 v;
    memcpy(&v, p, sizeof v);
    return v;
}

/* acc[0..2] += column c (6 rows) times x */
static void lin_column(axis_v2 *acc, const double *c, double x)
{
    axis_v2 s = {x, x};
    acc[0] += v2_load(c) * s;
    acc[1] += v2_load(c + 2) * s;
    acc[2] += v2_load(c + 4) * s;
}

/* z unchanged bit for bit (so -0.0 and +0.0 differ, and a NaN never rests) */
static bool same_state(const double *a, const double *b)
{
    uint64_t x[AXIS_NSTATE], y[AXIS_NSTATE];
    unsigned i;
    memcpy(x, a, sizeof x);
    memcpy(y, b, sizeof y);
    for (i = 0; i < AXIS_NSTATE; i++) {
        if (x[i] != y[i]) {
            return false;
        }
    }
    return true;
}

/* Returns true when z came out bit for bit as it was: th1 first (it changes
 * on almost every substep of a moving axis), the rest only when th1 did
 * not; z is stored either way (the same bits when unchanged). */
static bool lin_update(axis_t *ax, double u)
{
    enum { R = AXIS_NSTATE + 1 };
    const double *l = &ax->lin[0][0];
    double *z = ax->z, out[AXIS_NSTATE];
    axis_v2 acc[3], s = {z[0], z[0]};
    uint64_t b0, z0;
    bool same;

    acc[0] = v2_load(l) * s;
    acc[1] = v2_load(l + 2) * s;
    acc[2] = v2_load(l + 4) * s;
    lin_column(acc, l + 1 * R, z[1]);
    lin_column(acc, l + 2 * R, z[2]);
    lin_column(acc, l + 3 * R, z[3]);
    lin_column(acc, l + 4 * R, z[4]);
    lin_column(acc, l + 5 * R, u);
    out[0] = acc[0][0];
    memcpy(&b0, &out[0], sizeof b0);
    memcpy(&z0, &z[0], sizeof z0);
    same = b0 == z0;
    if (same) {
        out[1] = acc[0][1];
        out[2] = acc[1][0];
        out[3] = acc[1][1];
        out[4] = acc[2][0];
        same = same_state(out, z);
    }
    memcpy(z, &acc[0], sizeof acc[0]);
    memcpy(z + 2, &acc[1], sizeof acc[1]);
    z[4] = acc[2][0];
    return same;
}

/* The substep with a load torque, friction or backlash (out of line: the
 * linear substep below does not load what it needs). */
static AXIS_NOINLINE void substep_general(axis_t *ax, double u)
{
    const axis_params_t *p = &ax->p;
    double *z = ax->z;
    double in[AXIS_NINPUT], nz[AXIS_NSTATE];
    double(*phi)[AXIS_NSTATE] = ax->phi;
    double(*gam)[AXIS_NINPUT] = ax->gam;
    double k = p->K, bd = p->B, delta = 0.0;
    unsigned i;

    in[0] = clampd(u * p->kx, p->vmax) / p->kx;
    ax->v_applied = in[0] * p->kx;
    in[1] = p->load_torque;
    in[2] = 0.0;
    if (p->backlash > 0.0) {
        double gap = z[0] - z[2], half = p->backlash / (2.0 * p->l);
        if (fabs(gap) <= half) {
            phi = ax->phi_free;
            gam = ax->gam_free;
            k = 0.0;
            bd = 0.0;
        } else {
            delta = gap > 0.0 ? half : -half;
            in[1] -= p->K * delta;
            in[2] += p->K * delta;
        }
    }
    if (p->coulomb_motor > 0.0) {
        double net = p->kt * z[4] - k * (z[0] - z[2]) - bd * (z[1] - z[3]) - in[1];
        in[1] += clampd(p->I1 * z[1] / ax->h + net, p->coulomb_motor);
    }
    if (p->coulomb_table > 0.0) {
        double net = k * (z[0] - z[2]) + bd * (z[1] - z[3]) - in[2];
        in[2] += clampd(p->I2 * z[3] / ax->h + net, p->coulomb_table * p->l);
    }
    if (in[1] == 0.0 && in[2] == 0.0 && phi == ax->phi) {
        lin_update(ax, in[0]);
    } else {
        for (i = 0; i < AXIS_NSTATE; i++) {
            nz[i] = phi[i][0] * z[0] + phi[i][1] * z[1] + phi[i][2] * z[2] + phi[i][3] * z[3] +
                    phi[i][4] * z[4] + gam[i][0] * in[0] + gam[i][1] * in[1] + gam[i][2] * in[2];
        }
        memcpy(z, nz, sizeof nz);
    }
    if (p->pitch_n > 0) {
        track_direction(ax);
    }
}

void axis_set_load_torque(axis_t *ax, double t)
{
    const axis_params_t *p = &ax->p;
    ax->p.load_torque = t;
    ax->lin_only = p->load_torque == 0.0 && p->backlash <= 0.0 && p->coulomb_motor <= 0.0 &&
                   p->coulomb_table <= 0.0;
}

bool axis_substep_lin(axis_t *ax, double u)
{
    const axis_params_t *p = &ax->p;
    /* only u acts (T1 = T2 = 0: the same bits as the full update); at
     * rest with the same command, z and v_applied stay as they are */
    uint64_t ub;
    memcpy(&ub, &u, sizeof ub);
    if (!ax->rest || ub != ax->rest_u) {
        double v = clampd(u * p->kx, p->vmax) / p->kx;
        ax->v_applied = v * p->kx;
        ax->rest = lin_update(ax, v);
        ax->rest_u = ub;
    }
    return ax->rest;
}

bool axis_substep(axis_t *ax, double u)
{
    const axis_params_t *p = &ax->p;
    if (ax->lin_only) {
        axis_substep_lin(ax, u);
        if (p->pitch_n > 0) {
            track_direction(ax);
        }
        return ax->rest;
    }
    ax->rest = false;
    substep_general(ax, u);
    return false;
}

double axis_encoder_noisy(axis_t *ax)
{
    double c = axis_encoder_counts(ax);
    double u1 = uniform01(&ax->rng), u2 = uniform01(&ax->rng);
    return c + ax->p.enc_noise_counts * sqrt(-2.0 * log(u1)) * cos(2.0 * PI_D * u2);
}

double axis_pitch_error(const axis_params_t *p, double x, int dir)
{
    const double *e = dir > 0 ? p->pitch_err_fwd : p->pitch_err_rev;
    unsigned i;
    if (p->pitch_n == 0) {
        return 0.0;
    }
    if (x <= p->pitch_pos[0]) {
        return e[0];
    }
    for (i = 1; i < p->pitch_n; i++) {
        if (x <= p->pitch_pos[i]) {
            double f = (x - p->pitch_pos[i - 1]) / (p->pitch_pos[i] - p->pitch_pos[i - 1]);
            return e[i - 1] + f * (e[i] - e[i - 1]);
        }
    }
    return e[p->pitch_n - 1];
}

int64_t axis_ref_count(const axis_t *ax)
{
    return (int64_t)floor(axis_table_pos(ax) / ax->p.ref_resolution + 0.5);
}

void axis_set_position(axis_t *ax, double x)
{
    memset(ax->z, 0, sizeof ax->z);
    ax->z[0] = x / ax->p.l;
    ax->z[2] = x / ax->p.l;
    ax->pitch_turn = x;
    ax->rest = false;
}

int64_t axis_ref_reading(axis_t *ax)
{
    return axis_ref_reading_at(ax, axis_table_pos(ax));
}

int64_t axis_ref_reading_at(axis_t *ax, double x)
{
    uint64_t xb, rb;
    if (ax->p.ref_noise > 0.0) {
        double u1 = uniform01(&ax->ref_rng), u2 = uniform01(&ax->ref_rng);
        x += ax->p.ref_noise * sqrt(-2.0 * log(u1)) * cos(2.0 * PI_D * u2);
        return axis_floor_i64(x / ax->p.ref_resolution + 0.5);
    }
    memcpy(&xb, &x, sizeof xb);
    memcpy(&rb, &ax->p.ref_resolution, sizeof rb);
    if (!ax->ref_memo || xb != ax->ref_x || rb != ax->ref_res) {
        ax->ref_count = axis_floor_i64(x / ax->p.ref_resolution + 0.5);
        ax->ref_x = xb;
        ax->ref_res = rb;
        ax->ref_memo = true;
    }
    return ax->ref_count;
}
