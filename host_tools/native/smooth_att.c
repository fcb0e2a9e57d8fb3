/*
 * smooth_att.c - see smooth_att.h; the mathematics in docs/derivation.md, "Smoother".
 *
 * Epochs. att_step runs gyro update -> predict -> accelerometer -> magnetometer, so the
 * state between two predictions (an epoch) is measured by that sample's accelerometer and
 * magnetometer and by the next sample's gyroscope. The trace of the prediction that ends
 * epoch k gives its filtered state (x_pre: everything up to that gyro update), the Jacobian F
 * and epoch k+1's prediction (x_pred); the last epoch's filtered state is the filter's at the
 * end. The outputs of a sample are its epoch's smoothed state (a refused sample belongs to
 * the epoch before it).
 *
 * Two backward recursions share each step's gain: the full one (the heading cut only where
 * the filter reset or capped it), which gives the heading, and one with the heading cut at
 * every step (no heading information crosses a step), which gives the tilt and the rates
 * (docs/derivation.md, "Smoother": the magnetometer's heading is levelled with the filter's
 * own tilt).
 */
#include "smooth_att.h"

#include <math.h>
#include <string.h>

#include "rts.h"

#define SMOOTH_PI 3.14159265358979323846
#define SMOOTH_BLOCK 4096u /* samples between progress calls (a few ms of work) */
#define DIAG(i) ((i) * (ATT_N + 1))

/* The states cut for a heading reset or cap, and for a saturated gyroscope (the rates and
 * the Euler rates they give). */
#define CUT_HEADING (1u << ATT_PSI)
#define CUT_RATES ((1u << ATT_P) | (1u << ATT_Q) | (1u << ATT_R) | (1u << ATT_PHID) | (1u << ATT_THETAD) | (1u << ATT_PSID))

/* One smoothed epoch of one recursion. */
typedef struct {
    double x[ATT_N];
    double P[ATT_N * ATT_N];
} chain_t;

/* The smoothed epoch, carried backwards: both recursions and what the next step needs. */
typedef struct {
    chain_t full;       /* heading from here */
    chain_t tilt;       /* tilt and rates from here (heading cut at every step) */
    unsigned cut_into;  /* states to cut in the step into this epoch (its events) */
    size_t next;        /* the samples [0, next) are not written yet */
} carry_t;

/* Everything the loops share. */
typedef struct {
    const core_frame_t *fr;
    const core_run_io_t *io;
    const smooth_buffers_t *buf;
    double gimbal_limit, heading_var_max, var_floor;
    smooth_progress_fn progress;
    void *ctx;
    size_t pending;     /* samples done since the last progress call */
    smooth_report_t *rep;
} run_t;

size_t smooth_checkpoints(size_t n, size_t seg_len) { return (seg_len == 0) ? 0 : (n + seg_len - 1) / seg_len; }

static int advance(run_t *r, size_t k)
{
    r->pending += k;
    if (r->progress != NULL && r->pending >= SMOOTH_BLOCK) {
        const size_t done = r->pending;
        r->pending = 0;
        return r->progress(r->ctx, done);
    }
    return 0;
}

/* a in [-pi, pi) */
static double wrap_pi(double a)
{
    if (a >= -SMOOTH_PI && a < SMOOTH_PI) {
        return a;
    }
    a = fmod(a + SMOOTH_PI, 2.0 * SMOOTH_PI);
    return (a < 0.0 ? a + 2.0 * SMOOTH_PI : a) - SMOOTH_PI;
}

/* The other Euler representation of the same rotation: (phi + pi, +-pi - theta, psi + pi),
 * thetad negated, and theta's and thetad's rows and columns of P negated (the map's Jacobian
 * is diag(1, 1, 1, 1, -1, 1, 1, -1, 1)); docs/derivation.md, "Gimbal lock". P may be NULL. */
static void other_branch(double x[ATT_N], double *P)
{
    int i;
    x[ATT_THETA] = ((x[ATT_THETA] >= 0.0) ? SMOOTH_PI : -SMOOTH_PI) - x[ATT_THETA];
    x[ATT_PHI] = wrap_pi(x[ATT_PHI] + SMOOTH_PI);
    x[ATT_PSI] = wrap_pi(x[ATT_PSI] + SMOOTH_PI);
    x[ATT_THETAD] = -x[ATT_THETAD];
    if (P == NULL) {
        return;
    }
    for (i = 0; i < ATT_N; ++i) {
        P[ATT_THETA * ATT_N + i] = -P[ATT_THETA * ATT_N + i];
        P[ATT_THETAD * ATT_N + i] = -P[ATT_THETAD * ATT_N + i];
    }
    for (i = 0; i < ATT_N; ++i) {
        P[i * ATT_N + ATT_THETA] = -P[i * ATT_N + ATT_THETA];
        P[i * ATT_N + ATT_THETAD] = -P[i * ATT_N + ATT_THETAD];
    }
}

/* The filter's ranges (att_model_normalise): theta in [-pi/2, pi/2], phi and psi in [-pi, pi). */
static void normalise(chain_t *c)
{
    c->x[ATT_THETA] = wrap_pi(c->x[ATT_THETA]);
    if (fabs(c->x[ATT_THETA]) > 0.5 * SMOOTH_PI) {
        other_branch(c->x, c->P);
    }
    c->x[ATT_PHI] = wrap_pi(c->x[ATT_PHI]);
    c->x[ATT_PSI] = wrap_pi(c->x[ATT_PSI]);
}

/* Distance of two Euler triples as angles (wrapped), for choosing a representation. */
static double euler_distance(const double a[ATT_N], const double b[ATT_N])
{
    return fabs(wrap_pi(a[ATT_PHI] - b[ATT_PHI])) + fabs(a[ATT_THETA] - b[ATT_THETA]) +
           fabs(wrap_pi(a[ATT_PSI] - b[ATT_PSI]));
}

/* c in the Euler representation nearest to ref (over the top of +-90 deg pitch the two can
 * differ); 1 if it changed. */
static int align_branch(chain_t *c, const double ref[ATT_N])
{
    double alt[ATT_N];
    memcpy(alt, c->x, sizeof alt);
    other_branch(alt, NULL);
    if (euler_distance(alt, ref) < euler_distance(c->x, ref)) {
        other_branch(c->x, c->P);
        return 1;
    }
    return 0;
}

/* Quaternion [w x y z] of ZYX Euler angles e (body to ENU). */
static void euler_quat(const double *e, double q[4])
{
    const double cr = cos(0.5 * e[0]), sr = sin(0.5 * e[0]), cp = cos(0.5 * e[1]), sp = sin(0.5 * e[1]);
    const double cy = cos(0.5 * e[2]), sy = sin(0.5 * e[2]);
    q[0] = cy * cp * cr + sy * sp * sr;
    q[1] = cy * cp * sr - sy * sp * cr;
    q[2] = cy * sp * cr + sy * cp * sr;
    q[3] = sy * cp * cr - cy * sp * sr;
}

/* The angles b relative to the angles a (qa their quaternion) as Euler-angle increments at a:
 * d = W(a) u, u the body-frame rotation vector of R(a)^T R(b) (to first order
 * R(a + d) = R(a) Exp(E(a) d), E = W^-1), with W's sec(theta) clamped at the gimbal limit like
 * the filter's (docs/derivation.md, "Smoother"). Independent of either's representation. */
static void angle_difference(const double *a, const double qa[4], const double *b, double theta_limit, double d[3])
{
    double qb[4], w, v[3], vn, k, sp, cp, th, st, sec;
    euler_quat(b, qb);
    /* conj(qa) * qb */
    w = qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3];
    v[0] = qa[0] * qb[1] - qa[1] * qb[0] - qa[2] * qb[3] + qa[3] * qb[2];
    v[1] = qa[0] * qb[2] + qa[1] * qb[3] - qa[2] * qb[0] - qa[3] * qb[1];
    v[2] = qa[0] * qb[3] - qa[1] * qb[2] + qa[2] * qb[1] - qa[3] * qb[0];
    if (w < 0.0) { /* the shorter way round */
        w = -w;
        v[0] = -v[0];
        v[1] = -v[1];
        v[2] = -v[2];
    }
    vn = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    k = (vn > 1e-300) ? 2.0 * atan2(vn, w) / vn : 2.0;
    v[0] *= k;
    v[1] *= k;
    v[2] *= k;
    sp = sin(a[0]);
    cp = cos(a[0]);
    th = fmax(-theta_limit, fmin(theta_limit, a[1]));
    st = sin(th);
    sec = 1.0 / cos(th);
    d[0] = v[0] + (sp * v[1] + cp * v[2]) * st * sec;
    d[1] = cp * v[1] - sp * v[2];
    d[2] = (sp * v[1] + cp * v[2]) * sec;
}

static void to_double(const ekf_scalar_t *in, double *out, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        out[i] = ekf_to_double(in[i]);
    }
}

/* 1 if the heading's row of P (off the diagonal) is exactly zero: a reset that is not counted
 * in diag.heading_resets (the first field of a filter aligned without one) leaves it so. */
static int heading_decorrelated(const double *P)
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        if (i != ATT_PSI && P[ATT_PSI * ATT_N + i] != 0.0) {
            return 0;
        }
    }
    return 1;
}

/* dx = c - x_pred, c first brought into x_pred's Euler representation. rotation: the angles
 * as a rotation at x_pred (qp its quaternion; angle_difference: bounded where roll and heading
 * are not separately defined), else in the state's coordinates, phi and psi wrapped (a
 * heading difference then has no roll or pitch component at all). */
static void difference(run_t *r, chain_t *c, const double xp[ATT_N], const double qp[4], int rotation,
                       double dx[ATT_N])
{
    int i;
    if (align_branch(c, xp)) {
        r->rep->branch_flips++;
    }
    for (i = 0; i < ATT_N; ++i) {
        dx[i] = c->x[i] - xp[i];
    }
    if (rotation) {
        angle_difference(&xp[ATT_PHI], qp, &c->x[ATT_PHI], r->gimbal_limit, &dx[ATT_PHI]);
    } else {
        dx[ATT_PHI] = wrap_pi(dx[ATT_PHI]);
        dx[ATT_PSI] = wrap_pi(dx[ATT_PSI]);
    }
}

/* One backward step over trace T (the prediction from epoch k to k+1; c the smoothed epoch
 * k+1; event the SMOOTH_EVENT_* of T's step; cut_prev the cut of the step into epoch k): c
 * becomes the smoothed epoch k. */
static void backward_step(run_t *r, const att_trace_t *T, unsigned event, unsigned cut_prev, carry_t *c)
{
    double xf[ATT_N], Pf[ATT_N * ATT_N], F[ATT_N * ATT_N], xp[ATT_N], Pp[ATT_N * ATT_N], qp[4];
    double dx_full[ATT_N], dx_tilt[ATT_N];
    chain_t out;
    rts_gain_t g_full, g_tilt;
    unsigned cut = c->cut_into;
    to_double(T->x_pre, xf, ATT_N);
    to_double(T->P_pre, Pf, ATT_N * ATT_N);
    to_double(T->F, F, ATT_N * ATT_N);
    to_double(T->x_pred, xp, ATT_N);
    to_double(T->P_pred, Pp, ATT_N * ATT_N);
    /* a reset in this step's magnetometer update, a heading capped by this prediction, or
     * none measured yet: the heading of epoch k+1 tells nothing about epoch k's */
    if ((event & (SMOOTH_EVENT_HEADING_RESET | SMOOTH_EVENT_NO_MAGNETOMETER)) != 0u ||
        !(Pp[DIAG(ATT_PSI)] < r->heading_var_max)) {
        cut |= CUT_HEADING;
    }
    if ((cut & CUT_HEADING) != 0u) {
        r->rep->heading_cuts++;
    }
    if ((cut & CUT_RATES) != 0u) {
        r->rep->rate_cuts++;
    }
    euler_quat(&xp[ATT_PHI], qp);
    /* the full recursion compares rotations; the tilt recursion, whose heading is cut,
     * compares in Euler coordinates, where the heading difference has no tilt component
     * (docs/derivation.md, "Smoother") */
    difference(r, &c->full, xp, qp, 1, dx_full);
    difference(r, &c->tilt, xp, qp, 0, dx_tilt);
    if (rts_gain(ATT_N, Pf, F, Pp, cut, &g_full) != RTS_OK) {
        r->rep->not_pd++;
    }
    (void)rts_gain_cut(&g_full, ATT_PSI, &g_tilt);
    rts_apply(&g_full, xf, Pf, Pp, dx_full, c->full.P, out.x, out.P);
    normalise(&out);
    c->full = out;
    rts_apply(&g_tilt, xf, Pf, Pp, dx_tilt, c->tilt.P, out.x, out.P);
    normalise(&out);
    c->tilt = out;
    c->cut_into = cut_prev | (heading_decorrelated(Pf) ? CUT_HEADING : 0u);
}

/* The smoothed epoch's attitude (tilt from the tilt recursion, heading from the full one, in
 * the tilt's Euler representation) and its covariance of roll, pitch, yaw, packed like
 * att_get_angle_covariance: the variances of the recursion each angle comes from and the
 * full recursion's correlations. */
static void smoothed_attitude(const carry_t *c, double x[ATT_N], double cov[6])
{
    static const int row[6] = {0, 1, 2, 0, 0, 1}, col[6] = {0, 1, 2, 1, 2, 2};
    const double *P = c->full.P;
    double full[ATT_N], alt[ATT_N], sd[3];
    int k, flip;
    memcpy(full, c->full.x, sizeof full);
    memcpy(alt, full, sizeof alt);
    other_branch(alt, NULL);
    flip = euler_distance(alt, c->tilt.x) < euler_distance(full, c->tilt.x);
    memcpy(x, c->tilt.x, sizeof(double) * ATT_N);
    x[ATT_PSI] = flip ? alt[ATT_PSI] : full[ATT_PSI];
    sd[0] = sqrt(fmax(c->tilt.P[DIAG(ATT_PHI)], 0.0));
    sd[1] = sqrt(fmax(c->tilt.P[DIAG(ATT_THETA)], 0.0));
    sd[2] = sqrt(fmax(P[DIAG(ATT_PSI)], 0.0));
    for (k = 0; k < 6; ++k) {
        const int i = ATT_PHI + row[k], j = ATT_PHI + col[k];
        const double vi = P[DIAG(i)], vj = P[DIAG(j)];
        /* the other representation negates theta: its correlations change sign */
        const double sign = (flip && (row[k] == 1) != (col[k] == 1)) ? -1.0 : 1.0;
        cov[k] = (k < 3) ? sd[k] * sd[k]
                         : ((vi > 0.0 && vj > 0.0) ? sign * P[i * ATT_N + j] / sqrt(vi * vj) * sd[row[k]] * sd[col[k]]
                                                   : 0.0);
    }
}

/* Writes the smoothed epoch c to the samples [lo, c->next) that are aligned, then
 * c->next = lo. Their cov rows hold the filter's considered terms (the forward pass left them
 * there), which the reported covariance keeps. Returns the number of samples [lo, next). */
static size_t write_epoch(run_t *r, carry_t *c, size_t lo)
{
    const core_run_io_t *io = r->io;
    const size_t count = c->next - lo;
    double x[ATT_N], pc[6], q[4], e[3];
    size_t i;
    int k;
    smoothed_attitude(c, x, pc);
    core_attitude_from_euler(r->fr, &x[ATT_PHI], q, e);
    for (i = lo; i < c->next; ++i) {
        double *cov = &io->cov[6 * i], *var = &io->var[(size_t)ATT_N * i];
        if ((io->flags[i] & ATT_FLAG_ALIGNED) == 0u) {
            continue; /* no estimate before alignment: the forward pass wrote that */
        }
        for (k = 0; k < 6; ++k) {
            cov[k] += pc[k];
        }
        for (k = 0; k < 3; ++k) {
            cov[k] = fmax(cov[k], r->var_floor);
        }
        cov[2] = fmin(cov[2], r->heading_var_max);
        memcpy(&io->state[(size_t)ATT_N * i], x, sizeof x);
        for (k = 0; k < ATT_N; ++k) {
            var[k] = c->tilt.P[DIAG(k)];
        }
        var[ATT_PHI] = cov[0];
        var[ATT_THETA] = cov[1];
        var[ATT_PSI] = cov[2];
        memcpy(&io->quat[4 * i], q, sizeof q);
        memcpy(&io->euler[3 * i], e, sizeof e);
        core_cov_to_frame(r->fr, cov);
    }
    c->next = lo;
    return count;
}

/* The forward filter's considered terms after a step (att_get_angle_covariance minus P's
 * angle block), packed like it, ENU. */
static void considered_terms(const att_ekf_t *f, double out[6])
{
    static const int row[6] = {0, 1, 2, 0, 0, 1}, col[6] = {0, 1, 2, 1, 2, 2};
    ekf_scalar_t c[6], P[ATT_N * ATT_N];
    int k;
    att_get_angle_covariance(f, c);
    att_get_covariance(f, P);
    for (k = 0; k < 6; ++k) {
        out[k] = ekf_to_double(c[k]) - ekf_to_double(P[(ATT_PHI + row[k]) * ATT_N + ATT_PHI + col[k]]);
    }
}

/* The filter's outputs of sample i that the smoother keeps (flags, status, gyroscope offset),
 * and the considered terms in cov; before alignment all of them (no estimate). */
static void forward_outputs(run_t *r, const att_ekf_t *f, size_t i, ekf_status_t st, const att_step_report_t *rep)
{
    if ((att_flags(f) & ATT_FLAG_ALIGNED) == 0u) {
        core_write_row(r->fr, f, i, st, rep, r->io);
    } else {
        core_run_io_t kept = *r->io;
        kept.state = kept.var = kept.quat = kept.euler = kept.cov = NULL;
        core_write_row(r->fr, f, i, st, rep, &kept);
        considered_terms(f, &r->io->cov[6 * i]);
    }
}

/* The samples [i0, i1) through f, with their traces into the buffer (from its start) when
 * traced; count: the traces. first: the forward pass (also writes the filter's outputs). */
static int run_segment(run_t *r, att_ekf_t *f, size_t i0, size_t i1, int first, int traced, size_t *count)
{
    const smooth_buffers_t *b = r->buf;
    size_t i, cnt = 0;
    for (i = i0; i < i1; ++i) {
        att_sample_t s;
        att_step_report_t rep;
        ekf_status_t st;
        const att_diag_t *d = att_diag(f);
        const uint32_t resets = d->heading_resets, saturated = d->gyro_saturated;
        att_trace_t *tr = traced ? &b->trace[cnt] : NULL;
        core_run_sample(r->fr, r->io, i, &s);
        st = att_step_traced(f, &s, &rep, tr);
        if (tr != NULL && tr->predicted) {
            /* every magnetometer sample of an aligned filter is counted as fused, gated or skipped */
            const int no_mag = d->mag_fused == 0u && d->mag_gated == 0u && d->mag_skipped == 0u;
            b->trace_sample[cnt] = i;
            b->trace_event[cnt] = (uint8_t)(((d->heading_resets != resets) ? SMOOTH_EVENT_HEADING_RESET : 0u) |
                                            ((d->gyro_saturated != saturated) ? SMOOTH_EVENT_GYRO_SATURATED : 0u) |
                                            (no_mag ? SMOOTH_EVENT_NO_MAGNETOMETER : 0u));
            ++cnt;
        }
        if (first) {
            forward_outputs(r, f, i, st, &rep);
            if (advance(r, 1)) {
                return 1;
            }
        }
    }
    *count = cnt;
    return 0;
}

/* The backward pass over the traces of one segment (count of them), from its last. */
static int smooth_segment(run_t *r, size_t count, carry_t *c)
{
    const smooth_buffers_t *b = r->buf;
    size_t t;
    for (t = count; t-- > 0;) {
        const unsigned event = b->trace_event[t];
        /* the trace's step starts with the gyro update that ends the previous epoch: a
         * saturated one raised the rates within that epoch (cut in the step into it) */
        const unsigned cut_prev = ((event & SMOOTH_EVENT_GYRO_SATURATED) != 0u) ? CUT_RATES : 0u;
        const size_t written = write_epoch(r, c, b->trace_sample[t]);
        backward_step(r, &b->trace[t], event, cut_prev, c);
        r->rep->epochs++;
        if (advance(r, written)) {
            return 1;
        }
    }
    return 0;
}

int smooth_run(att_ekf_t *f, const core_frame_t *fr, size_t n, const core_run_io_t *io, const smooth_buffers_t *buf,
               smooth_progress_fn progress, void *ctx, smooth_report_t *report)
{
    const size_t L = buf->seg_len, segments = smooth_checkpoints(n, buf->seg_len);
    run_t r;
    carry_t c;
    size_t seg, count = 0;
    memset(report, 0, sizeof *report);
    r.fr = fr;
    r.io = io;
    r.buf = buf;
    r.gimbal_limit = ekf_to_double(att_settings(f)->gimbal_limit);
    r.heading_var_max = ekf_to_double(att_settings(f)->heading_var_max);
    r.var_floor = ekf_to_double(att_settings(f)->var_floor);
    r.progress = progress;
    r.ctx = ctx;
    r.pending = 0;
    r.rep = report;
    /* forward: checkpoints, the filter's outputs, the last segment's traces (the earlier
     * segments' are recomputed in the backward pass: not traced here) */
    for (seg = 0; seg < segments; ++seg) {
        buf->ckpt[seg] = *f;
        if (run_segment(&r, f, seg * L, (seg + 1 < segments) ? (seg + 1) * L : n, 1, seg + 1 == segments, &count)) {
            return 1;
        }
    }
    /* backward from the filter's last state */
    {
        ekf_scalar_t P[ATT_N * ATT_N];
        to_double(att_state(f), c.full.x, ATT_N);
        att_get_covariance(f, P);
        to_double(P, c.full.P, ATT_N * ATT_N);
        c.tilt = c.full;
        c.cut_into = heading_decorrelated(c.full.P) ? CUT_HEADING : 0u;
        c.next = n;
    }
    for (seg = segments; seg-- > 0;) {
        if (seg + 1 < segments) {
            att_ekf_t g = buf->ckpt[seg];
            (void)run_segment(&r, &g, seg * L, (seg + 1) * L, 0, 1, &count);
            report->recomputed += (uint32_t)L;
        }
        if (smooth_segment(&r, count, &c)) {
            return 1;
        }
    }
    r.pending += write_epoch(&r, &c, 0); /* the first epoch, from the alignment on */
    if (progress != NULL && r.pending > 0) {
        return progress(ctx, r.pending);
    }
    return 0;
}
