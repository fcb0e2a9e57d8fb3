/*
 * instr.c - recorders of the instrumented double build (instr_scalar.h): the magnitude of
 * every arithmetic result, the inputs and states of every att_step, and the covariance
 * after every att_cov.h operation (variances, correlations, smallest eigenvalue, LDL^T
 * pivots, the growth and drop of the variances per operation, the dynamic range of the
 * scaled transition rows). Written at exit to $INSTR_OUT/ranges_<pid>.txt, one line per
 * quantity: name, count, zeros, smallest non-zero |v|, largest |v|, then a histogram of
 * floor(log2 |v|) over bins -120 .. 39. scripts/fixed_ranges.py merges and reports them.
 * Measurement only (docs/fixed_point.md, "Measured ranges").
 */
#define INSTR_NO_API 1
#define INSTR_NO_COV 1
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "att.h"
#include "att_cov.h"
#include "att_gen.h"

#define BIN_LO (-120)
#define BINS 160

typedef struct {
    const char *name;
    long n, zeros;
    double min_nz, max;
    long hist[BINS];
} acc_t;

enum {
    Q_ADD, Q_SUB, Q_MUL, Q_DIV, Q_MAC, Q_SQRT, Q_TRIG_ARG, Q_ATAN2_ARG,
    Q_DT, Q_GYRO, Q_ACCEL, Q_MAG,
    Q_X0, Q_DX0 = Q_X0 + ATT_N, Q_VAR0 = Q_DX0 + ATT_N,
    Q_CORR_GAP = Q_VAR0 + ATT_N, Q_LAMBDA_MIN, Q_LAMBDA_REL, Q_PIVOT_REL, Q_PIVOT_ABS,
    Q_GROW_PROP, Q_GROW_NOISE, Q_GROW_DIAG, Q_DROP_PROP, Q_DROP_UNIT, Q_DROP_UNIT_K, Q_DROP_TILT,
    Q_KAPPA_PROP, Q_D, Q_RVAR, Q_NOISE_VAR, Q_DIAG_VAR, Q_INC_VAR, Q_INNOV,
    Q_COUNT
};

static acc_t g_acc[Q_COUNT];
static int g_ready;

static const char *const k_state[ATT_N] = {"p", "q", "r", "phi", "theta", "psi", "phid", "thetad", "psid"};
static char g_names[3][ATT_N][24];

static void dump(void)
{
    char path[512];
    const char *dir = getenv("INSTR_OUT");
    FILE *fp;
    int i, b;
    snprintf(path, sizeof path, "%s/ranges_%ld.txt", dir != NULL ? dir : ".", (long)getpid());
    fp = fopen(path, "w");
    if (fp == NULL) {
        fprintf(stderr, "instr: cannot write %s\n", path);
        return;
    }
    for (i = 0; i < Q_COUNT; ++i) {
        const acc_t *a = &g_acc[i];
        fprintf(fp, "%s %ld %ld %.17g %.17g", a->name, a->n, a->zeros, a->n > a->zeros ? a->min_nz : 0.0, a->max);
        for (b = 0; b < BINS; ++b) {
            fprintf(fp, " %ld", a->hist[b]);
        }
        fputc('\n', fp);
    }
    fclose(fp);
}

static void init(void)
{
    static const char *const names[] = {
        "op_add", "op_sub", "op_mul", "op_div", "op_mac", "op_sqrt", "trig_arg", "atan2_arg",
        "in_dt", "in_gyro", "in_accel", "in_mag"};
    int i;
    for (i = 0; i < Q_X0; ++i) {
        g_acc[i].name = names[i];
    }
    for (i = 0; i < ATT_N; ++i) {
        snprintf(g_names[0][i], sizeof g_names[0][i], "x_%s", k_state[i]);
        snprintf(g_names[1][i], sizeof g_names[1][i], "dx_%s", k_state[i]);
        snprintf(g_names[2][i], sizeof g_names[2][i], "var_%s", k_state[i]);
        g_acc[Q_X0 + i].name = g_names[0][i];
        g_acc[Q_DX0 + i].name = g_names[1][i];
        g_acc[Q_VAR0 + i].name = g_names[2][i];
    }
    g_acc[Q_CORR_GAP].name = "corr_gap";         /* 1 - max |rho_ij| */
    g_acc[Q_LAMBDA_MIN].name = "lambda_min";     /* smallest eigenvalue of P */
    g_acc[Q_LAMBDA_REL].name = "lambda_min_rel"; /* of the correlation matrix D^-1/2 P D^-1/2 */
    g_acc[Q_PIVOT_REL].name = "pivot_rel";       /* min_j d_j / P_jj (LDL^T) */
    g_acc[Q_PIVOT_ABS].name = "pivot_abs";       /* min_j d_j */
    g_acc[Q_GROW_PROP].name = "grow_propagate";  /* max_i P'_ii / P_ii */
    g_acc[Q_GROW_NOISE].name = "grow_rate_noise";
    g_acc[Q_GROW_DIAG].name = "grow_add_diag";
    g_acc[Q_DROP_PROP].name = "drop_propagate";  /* max_i P_ii / P'_ii */
    g_acc[Q_DROP_UNIT].name = "drop_unit_other"; /* unit update, states other than the measured one */
    g_acc[Q_DROP_UNIT_K].name = "drop_unit_measured";
    g_acc[Q_DROP_TILT].name = "drop_tilt";
    g_acc[Q_KAPPA_PROP].name = "kappa_propagate"; /* max_j |F_rj| s_j / s'_r per row of each transition factor */
    g_acc[Q_D].name = "jacobian_d";
    g_acc[Q_RVAR].name = "update_r_var";
    g_acc[Q_NOISE_VAR].name = "rate_noise_var";
    g_acc[Q_DIAG_VAR].name = "add_diag_var";
    g_acc[Q_INC_VAR].name = "increment_var";
    g_acc[Q_INNOV].name = "innovation";
    for (i = 0; i < Q_COUNT; ++i) {
        g_acc[i].min_nz = HUGE_VAL;
    }
    atexit(dump);
    g_ready = 1;
}

static void rec(int q, double v)
{
    acc_t *a;
    if (!g_ready) {
        init();
    }
    a = &g_acc[q];
    v = fabs(v);
    ++a->n;
    if (!(v > 0.0) || !isfinite(v)) {
        ++a->zeros; /* zeros (non-finite values never occur in these runs; counted with them) */
        return;
    }
    if (v < a->min_nz) {
        a->min_nz = v;
    }
    if (v > a->max) {
        a->max = v;
    }
    {
        int b = (int)floor(log2(v)) - BIN_LO;
        b = b < 0 ? 0 : (b >= BINS ? BINS - 1 : b);
        ++a->hist[b];
    }
}

double instr_add(double a, double b) { rec(Q_ADD, a + b); return a + b; }
double instr_sub(double a, double b) { rec(Q_SUB, a - b); return a - b; }
double instr_mul(double a, double b) { rec(Q_MUL, a * b); return a * b; }
double instr_div(double a, double b) { rec(Q_DIV, a / b); return a / b; }
double instr_mac(double c, double a, double b)
{
    rec(Q_MUL, a * b);
    rec(Q_MAC, c + a * b);
    return c + a * b;
}
double instr_sqrt(double a) { rec(Q_SQRT, sqrt(a)); return sqrt(a); }
double instr_sin(double a) { rec(Q_TRIG_ARG, a); return sin(a); }
double instr_cos(double a) { rec(Q_TRIG_ARG, a); return cos(a); }
double instr_atan2(double y, double x)
{
    rec(Q_ATAN2_ARG, y);
    rec(Q_ATAN2_ARG, x);
    return atan2(y, x);
}

/* ---- covariance analysis ---- */

/* Smallest eigenvalue of a symmetric n x n matrix (cyclic Jacobi). */
static double lambda_min(const double *A0, int n)
{
    double A[ATT_N * ATT_N], lo;
    int sweep, p, q, k;
    memcpy(A, A0, sizeof(double) * (size_t)(n * n));
    for (sweep = 0; sweep < 50; ++sweep) {
        double off = 0.0;
        for (p = 0; p < n; ++p) {
            for (q = p + 1; q < n; ++q) {
                off += A[p * n + q] * A[p * n + q];
            }
        }
        if (off < 1e-300) {
            break;
        }
        for (p = 0; p < n; ++p) {
            for (q = p + 1; q < n; ++q) {
                const double apq = A[p * n + q];
                double theta, t, c, s;
                if (fabs(apq) < 1e-300) {
                    continue;
                }
                theta = (A[q * n + q] - A[p * n + p]) / (2.0 * apq);
                t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                c = 1.0 / sqrt(t * t + 1.0);
                s = t * c;
                for (k = 0; k < n; ++k) {
                    const double akp = A[k * n + p], akq = A[k * n + q];
                    A[k * n + p] = c * akp - s * akq;
                    A[k * n + q] = s * akp + c * akq;
                }
                for (k = 0; k < n; ++k) {
                    const double apk = A[p * n + k], aqk = A[q * n + k];
                    A[p * n + k] = c * apk - s * aqk;
                    A[q * n + k] = s * apk + c * aqk;
                }
            }
        }
    }
    lo = A[0];
    for (k = 1; k < n; ++k) {
        lo = fmin(lo, A[k * n + k]);
    }
    return lo;
}

static void full(const att_cov_t *c, double P[ATT_N * ATT_N])
{
    ekf_scalar_t Ps[ATT_N * ATT_N];
    int i;
    att_cov_to_full(c, Ps);
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        P[i] = ekf_to_double(Ps[i]);
    }
}

static void analyse(const att_cov_t *c)
{
    double P[ATT_N * ATT_N], R[ATT_N * ATT_N], L[ATT_N][ATT_N], d[ATT_N];
    double gap = 1.0, prel = HUGE_VAL, pabs = HUGE_VAL;
    int i, j, k;
    full(c, P);
    for (i = 0; i < ATT_N; ++i) {
        rec(Q_VAR0 + i, P[i * ATT_N + i]);
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < ATT_N; ++j) {
            R[i * ATT_N + j] = P[i * ATT_N + j] / sqrt(P[i * ATT_N + i] * P[j * ATT_N + j]);
            if (j > i) {
                gap = fmin(gap, 1.0 - fabs(R[i * ATT_N + j]));
            }
        }
    }
    rec(Q_CORR_GAP, gap);
    rec(Q_LAMBDA_MIN, lambda_min(P, ATT_N));
    rec(Q_LAMBDA_REL, lambda_min(R, ATT_N));
    for (j = 0; j < ATT_N; ++j) {
        double v = P[j * ATT_N + j];
        for (k = 0; k < j; ++k) {
            double w = P[j * ATT_N + k];
            int m;
            for (m = 0; m < k; ++m) {
                w -= L[j][m] * d[m] * L[k][m];
            }
            L[j][k] = w / d[k];
            v -= L[j][k] * L[j][k] * d[k];
        }
        d[j] = v;
        prel = fmin(prel, v / P[j * ATT_N + j]);
        pabs = fmin(pabs, v);
    }
    rec(Q_PIVOT_REL, prel);
    rec(Q_PIVOT_ABS, pabs);
}

static void diag_of(const att_cov_t *c, double v[ATT_N])
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        v[i] = ekf_to_double(att_cov_var(c, i));
    }
}

/* max over states of after / before (grow) or before / after (drop), states in mask */
static void ratio(int q, const double *before, const double *after, int grow, unsigned mask)
{
    double worst = 0.0;
    int i;
    for (i = 0; i < ATT_N; ++i) {
        if ((mask & (1u << i)) != 0u && before[i] > 0.0 && after[i] > 0.0) {
            worst = fmax(worst, grow ? after[i] / before[i] : before[i] / after[i]);
        }
    }
    if (worst > 0.0) {
        rec(q, worst);
    }
}

void instr_cov_set_diag(att_cov_t *c, const ekf_scalar_t var[ATT_N]) { att_cov_set_diag(c, var); }

/* Dynamic range of each scaled row of the factor F = I + D (D's values d on pat, its rows
 * changed; S'^-1 F S, s = sqrt(diag)): the row's largest entry against the row's result
 * (log2 of it is what a block-scaled row loses), recorded for the changed rows. */
static void kappa_factor(const ekf_nz_t *pat, int nnz, const ekf_scalar_t *d, const double *b, const double *a,
                         int first)
{
    double kappa[ATT_N] = {0};
    int k, i;
    for (k = 0; k < nnz; ++k) {
        const int r = pat[k].row, j = pat[k].col;
        const double f = ekf_to_double(d[k]) + (r == j ? 1.0 : 0.0);
        if (a[r] > 0.0) {
            kappa[r] = fmax(kappa[r], fabs(f) * sqrt(b[j]) / sqrt(a[r]));
        }
    }
    for (i = first; i < first + 3; ++i) {
        if (a[i] > 0.0) {
            kappa[i] = fmax(kappa[i], sqrt(b[i]) / sqrt(a[i])); /* the identity term */
            rec(Q_KAPPA_PROP, kappa[i]);
        }
    }
}

/* The diagonal of F P F^T for F = I + D (pattern pat), in double. */
static void factor_diag(const double *P, const ekf_nz_t *pat, int nnz, const ekf_scalar_t *d, double out[ATT_N])
{
    double F[ATT_N * ATT_N] = {0};
    int k, i, j, m;
    for (i = 0; i < ATT_N; ++i) {
        F[i * ATT_N + i] = 1.0;
    }
    for (k = 0; k < nnz; ++k) {
        F[pat[k].row * ATT_N + pat[k].col] += ekf_to_double(d[k]);
    }
    for (i = 0; i < ATT_N; ++i) {
        double s = 0.0;
        for (j = 0; j < ATT_N; ++j) {
            for (m = 0; m < ATT_N; ++m) {
                s += F[i * ATT_N + j] * P[j * ATT_N + m] * F[i * ATT_N + m];
            }
        }
        out[i] = s;
    }
}

ekf_status_t instr_cov_predict(att_cov_t *c, const ekf_scalar_t d1[ATT_GEN_F1_NNZ], const ekf_scalar_t d2[ATT_GEN_F2_NNZ],
                               const ekf_scalar_t var[3], ekf_scalar_t inc_var[3])
{
    ekf_scalar_t Pq[ATT_N * ATT_N];
    double P[ATT_N * ATT_N], b[ATT_N], m1[ATT_N], a[ATT_N];
    ekf_status_t st;
    int k, i;
    diag_of(c, b);
    att_cov_to_full(c, Pq);
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        P[i] = ekf_to_double(Pq[i]);
    }
    for (k = 0; k < ATT_GEN_F1_NNZ; ++k) {
        rec(Q_D, ekf_to_double(d1[k]));
    }
    for (k = 0; k < ATT_GEN_F2_NNZ; ++k) {
        rec(Q_D, ekf_to_double(d2[k]));
    }
    for (i = 0; i < 3; ++i) {
        rec(Q_NOISE_VAR, ekf_to_double(var[i]));
    }
    st = att_cov_predict(c, d1, d2, var, inc_var);
    if (st != EKF_OK) {
        return st;
    }
    diag_of(c, a);
    ratio(Q_GROW_PROP, b, a, 1, 0x1ffu);
    ratio(Q_DROP_PROP, b, a, 0, 0x1ffu);
    /* the first factor's result (the rate noise on the rates between the factors) */
    factor_diag(P, att_gen_f1_pattern, ATT_GEN_F1_NNZ, d1, m1);
    kappa_factor(att_gen_f1_pattern, ATT_GEN_F1_NNZ, d1, b, m1, ATT_PHI);
    for (i = 0; i < 3; ++i) {
        m1[ATT_P + i] += ekf_to_double(var[i]);
    }
    kappa_factor(att_gen_f2_pattern, ATT_GEN_F2_NNZ, d2, m1, a, ATT_PHID);
    for (i = 0; i < 3; ++i) {
        rec(Q_INC_VAR, ekf_to_double(inc_var[i]));
    }
    return st;
}

void instr_cov_add_rate_noise(att_cov_t *c, const ekf_scalar_t g[9], const ekf_scalar_t var[3])
{
    double b[ATT_N], a[ATT_N];
    int i;
    for (i = 0; i < 3; ++i) {
        rec(Q_NOISE_VAR, ekf_to_double(var[i]));
    }
    diag_of(c, b);
    att_cov_add_rate_noise(c, g, var);
    diag_of(c, a);
    ratio(Q_GROW_NOISE, b, a, 1, 0x1ffu);
}

void instr_cov_add_diag(att_cov_t *c, int first, int len, ekf_scalar_t var)
{
    double b[ATT_N], a[ATT_N];
    rec(Q_DIAG_VAR, ekf_to_double(var));
    diag_of(c, b);
    att_cov_add_diag(c, first, len, var);
    diag_of(c, a);
    ratio(Q_GROW_DIAG, b, a, 1, 0x1ffu);
}

void instr_cov_add_var(att_cov_t *c, int i, ekf_scalar_t var)
{
    rec(Q_DIAG_VAR, ekf_to_double(var));
    att_cov_add_var(c, i, var);
}

void instr_cov_scale_diag(att_cov_t *c, int first, int len, ekf_scalar_t rel) { att_cov_scale_diag(c, first, len, rel); }
int instr_cov_floor_diag(att_cov_t *c, ekf_scalar_t floor) { return att_cov_floor_diag(c, floor); }
void instr_cov_reset_state(att_cov_t *c, int i, ekf_scalar_t var) { att_cov_reset_state(c, i, var); }
int instr_cov_limit_variance(att_cov_t *c, int i, ekf_scalar_t max_var) { return att_cov_limit_variance(c, i, max_var); }

ekf_status_t instr_cov_update_unit(att_cov_t *c, ekf_scalar_t x[ATT_N], int idx, ekf_scalar_t nu, ekf_scalar_t r_var,
                                   ekf_scalar_t gate, ekf_scalar_t var_floor, ekf_innov_t *info)
{
    double b[ATT_N], a[ATT_N];
    ekf_status_t st;
    diag_of(c, b);
    rec(Q_RVAR, ekf_to_double(r_var));
    rec(Q_INNOV, ekf_to_double(nu));
    st = att_cov_update_unit(c, x, idx, nu, r_var, gate, var_floor, info);
    if (st == EKF_OK) {
        diag_of(c, a);
        ratio(Q_DROP_UNIT, b, a, 0, 0x1ffu & ~(1u << idx));
        ratio(Q_DROP_UNIT_K, b, a, 0, 1u << idx);
    }
    return st;
}

ekf_status_t instr_cov_update_tilt(att_cov_t *c, ekf_scalar_t x[ATT_N], ekf_scalar_t h_phi, ekf_scalar_t h_theta,
                                   ekf_scalar_t nu, ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor,
                                   ekf_innov_t *info)
{
    double b[ATT_N], a[ATT_N];
    ekf_status_t st;
    diag_of(c, b);
    rec(Q_RVAR, ekf_to_double(r_var));
    rec(Q_INNOV, ekf_to_double(nu));
    st = att_cov_update_tilt(c, x, h_phi, h_theta, nu, r_var, gate, var_floor, info);
    if (st == EKF_OK) {
        diag_of(c, a);
        ratio(Q_DROP_TILT, b, a, 0, 0x1ffu);
    }
    return st;
}

int instr_cov_ensure_pd(att_cov_t *c, ekf_scalar_t rel_margin, ekf_scalar_t var_floor)
{
    const int r = att_cov_ensure_pd(c, rel_margin, var_floor);
    if (r >= 0) {
        analyse(c);
    }
    return r;
}

/* The guard at the end of every public call: the covariance the filter keeps. */
int instr_cov_guard(att_cov_t *c, ekf_scalar_t rel_margin, ekf_scalar_t var_floor)
{
    const int r = att_cov_guard(c, rel_margin, var_floor);
    if (r >= 0) {
        analyse(c);
    }
    return r;
}

/* ---- the public step ---- */

const att_ekf_t *g_last_filter;
static double g_last_x[ATT_N];

ekf_status_t instr_att_step(att_ekf_t *f, const att_sample_t *sm, att_step_report_t *rep)
{
    ekf_status_t st;
    int i;
    if (f != NULL && sm != NULL) {
        if (isfinite(ekf_to_double(sm->dt)) && ekf_to_double(sm->dt) > 0.0) {
            rec(Q_DT, ekf_to_double(sm->dt));
        }
        for (i = 0; i < 3; ++i) {
            if ((sm->valid & ATT_HAS_GYRO) && isfinite(ekf_to_double(sm->gyro[i]))) {
                rec(Q_GYRO, ekf_to_double(sm->gyro[i]));
            }
            if ((sm->valid & ATT_HAS_ACCEL) && isfinite(ekf_to_double(sm->accel[i]))) {
                rec(Q_ACCEL, ekf_to_double(sm->accel[i]));
            }
            if ((sm->valid & ATT_HAS_MAG) && isfinite(ekf_to_double(sm->mag[i]))) {
                rec(Q_MAG, ekf_to_double(sm->mag[i]));
            }
        }
    }
    st = att_step(f, sm, rep);
    if (f != NULL && (att_flags(f) & ATT_FLAG_ALIGNED) != 0u) {
        const ekf_scalar_t *x = att_state(f);
        for (i = 0; i < ATT_N; ++i) {
            const double v = ekf_to_double(x[i]);
            rec(Q_X0 + i, v);
            if (g_last_filter == f) {
                double dv = v - g_last_x[i];
                if (i >= ATT_PHI && i <= ATT_PSI) {
                    dv = remainder(dv, 6.283185307179586); /* a wrap is not a step */
                }
                rec(Q_DX0 + i, dv);
            }
            g_last_x[i] = v;
        }
        g_last_filter = f;
    } else {
        g_last_filter = NULL;
    }
    return st;
}

/* The settings the instrumented runs use: the defaults with the fixed-point build's
 * values where they differ (scripts/fixed_ranges.py passes them; the stress and envelope
 * drivers are compiled with att_default_settings renamed to this). */
att_settings_t instr_default_settings;

static void instr_settings_init(void) __attribute__((constructor));
static void instr_settings_init(void)
{
    const char *g = getenv("INSTR_GIMBAL_LIMIT");
    const char *vf = getenv("INSTR_VAR_FLOOR");
    instr_default_settings = att_default_settings;
    if (g != NULL) {
        instr_default_settings.gimbal_limit = ekf_from_double(strtod(g, NULL));
    }
    if (vf != NULL) {
        instr_default_settings.var_floor = ekf_from_double(strtod(vf, NULL));
    }
}
