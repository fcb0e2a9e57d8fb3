/*
 * test_att_cov_limits.c - the refusal thresholds of every covariance implementation, tested
 * directly: the library's (packed float and double, att_cov.c; fixed point, att_cov_fx*.c) and
 * the reference on the generic core (tests/c/support/att_cov_ref.c, linked beside it under
 * other names). No end-of-call guard stands between a kernel and these tests, so a threshold
 * that moved cannot hide behind a repair:
 *   - a new variance negative by 0.75 of the rounding allowance is floored (EKF_OK), by 1.33
 *     of it refused (EKF_ERR_NUMERIC, nothing written): the allowance documented for
 *     each implementation (att_cov.h, ekf.c "variance_tolerance"; fixed point:
 *     32 n EKF_SCALAR_EPS of the state's scale), for a unit row and an angle row, a measured
 *     state and another;
 *   - H P H^T < 0 (S < R) refused where every new variance is positive, H P H^T = 0 (S = R)
 *     accepted;
 *   - the guard: 0, 1 and 2 repair rounds at correlations just inside and beyond what one
 *     round of loading (10 ATT_PD_MARGIN, ekf_cov_ensure_pd) repairs, and the filter's
 *     guard (att_guard_covariance) accepting one round, flagged and counted, and refusing two
 *     (ATT_REPAIR_ROUNDS).
 * Built for float, double and fixed point.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "att.h"
#include "att_cov.h"
#include "att_cov_ref_wrap.h"
#include "att_state.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static const ekf_scalar_t k_floor = EKF_C(1e-9);

/* ---- the implementations on a full P ---- */

typedef struct {
    const char *name;
    int words; /* 1: the fixed-point words, allowance relative to the state's scale */
    ekf_status_t (*unit)(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], int idx, ekf_scalar_t nu, ekf_scalar_t r);
    ekf_status_t (*angles)(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], const ekf_scalar_t h[3], ekf_scalar_t nu,
                           ekf_scalar_t r);
    int (*guard)(ekf_scalar_t P[ATT_NN]);
} impl_t;

/* The library's storage round trip; a refused update must leave it byte for byte. */
static ekf_status_t lib_unit(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], int idx, ekf_scalar_t nu, ekf_scalar_t r)
{
    att_cov_t c, c0;
    ekf_status_t st;
    att_cov_from_full(&c, P);
    c0 = c;
    st = att_cov_update_unit(&c, x, idx, nu, r, EKF_C(0), k_floor, NULL);
    if (st != EKF_OK) {
        TEST_ASSERT_EQUAL_MEMORY(&c0, &c, sizeof c);
    }
    att_cov_to_full(&c, P);
    return st;
}

static ekf_status_t lib_angles(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], const ekf_scalar_t h[3], ekf_scalar_t nu,
                               ekf_scalar_t r)
{
    att_cov_t c, c0;
    ekf_status_t st;
    att_cov_from_full(&c, P);
    c0 = c;
    st = att_cov_update_angles(&c, x, h, nu, r, EKF_C(0), k_floor, NULL);
    if (st != EKF_OK) {
        TEST_ASSERT_EQUAL_MEMORY(&c0, &c, sizeof c);
    }
    att_cov_to_full(&c, P);
    return st;
}

static int lib_guard(ekf_scalar_t P[ATT_NN])
{
    att_cov_t c;
    int r;
    att_cov_from_full(&c, P);
    r = att_cov_guard(&c, ATT_PD_MARGIN, k_floor);
    att_cov_to_full(&c, P);
    return r;
}

static ekf_status_t ref_unit(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], int idx, ekf_scalar_t nu, ekf_scalar_t r)
{
    return refcov_update_unit(P, x, idx, nu, r, EKF_C(0), k_floor, NULL);
}

static ekf_status_t ref_angles(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], const ekf_scalar_t h[3], ekf_scalar_t nu,
                               ekf_scalar_t r)
{
    return refcov_update_angles(P, x, h, nu, r, EKF_C(0), k_floor, NULL);
}

static int ref_guard(ekf_scalar_t P[ATT_NN]) { return refcov_guard(P, ATT_PD_MARGIN, k_floor); }

static const impl_t k_impls[] = {
#if defined(EKF_SCALAR_FIXED)
    {"fixed-point words (att_cov_fx)", 1, lib_unit, lib_angles, lib_guard},
#else
    {"packed (att_cov.c)", 0, lib_unit, lib_angles, lib_guard},
#endif
    {"reference (att_cov_ref.c)", 0, ref_unit, ref_angles, ref_guard},
};
#define N_IMPLS ((int)(sizeof k_impls / sizeof k_impls[0]))

/* ---- the allowance, as documented (not read from the code under test) ---- */

/* The rounding allowance of a new variance P_ii - K_i b_i: ekf_update_scalar's
 * 32 n eps (|P_ii| + |K_i b_i|), plus in fixed point 32 n LSB (1 + |K_i|) (1 + |K_i| + |b_i|)
 * (every product rounded to one LSB); the fixed-point words': 32 n EKF_SCALAR_EPS of the
 * state's scale, which is 1 for the variances of [1, 4) used here. */
static double allowance(const impl_t *im, double pii, double k, double b)
{
    const double c = 32.0 * ATT_N, eps = ekf_to_double(EKF_SCALAR_EPS);
    double a;
    if (im->words) {
        return c * eps;
    }
    a = c * eps * (fabs(pii) + fabs(k * b));
#if defined(EKF_SCALAR_FIXED)
    a += c * ldexp(1.0, -EKF_FX_FRAC) * (1.0 + fabs(k)) * (1.0 + fabs(k) + fabs(b));
#endif
    return a;
}

static void identity(ekf_scalar_t P[ATT_NN])
{
    int i;
    memset(P, 0, sizeof(ekf_scalar_t) * ATT_NN);
    for (i = 0; i < ATT_N; ++i) {
        P[i * ATT_N + i] = EKF_C(1);
    }
}

static void set_pair(ekf_scalar_t P[ATT_NN], int i, int j, double v)
{
    P[i * ATT_N + j] = P[j * ATT_N + i] = ekf_from_double(v);
}

/* One update that makes P_ii - K_i b_i = -t allowance: a unit row on state k (hk = 0) or the
 * angle row hk e_k (k an angle), with P_kk = 1, P_ik = rho, R = r. Returns the status; *vi is
 * P_ii afterwards. */
static ekf_status_t update_at(const impl_t *im, int k, double hk, int i, double t, double *vi)
{
    const double rho = 1.2, r = (hk == 0.0) ? 0.25 : 0.05;
    const double s = ((hk == 0.0) ? 1.0 : hk * hk) + r, b = (hk == 0.0) ? rho : hk * rho, kg = b / s;
    const double q = kg * b; /* K_i b_i */
    ekf_scalar_t P[ATT_NN], P0[ATT_NN], x[ATT_N] = {0}, x0[ATT_N];
    ekf_status_t st;
    double a = q;
    int it;
    for (it = 0; it < 4; ++it) { /* a = q - t allowance(a): a fixed point, a few steps */
        a = q - t * allowance(im, a, kg, b);
    }
    identity(P);
    set_pair(P, i, k, rho);
    set_pair(P, i, i, a);
    memcpy(P0, P, sizeof P);
    memcpy(x0, x, sizeof x);
    if (hk == 0.0) {
        st = im->unit(P, x, k, EKF_C(0.01), ekf_from_double(r));
    } else {
        const ekf_scalar_t h[3] = {k == ATT_PHI ? ekf_from_double(hk) : EKF_C(0), k == ATT_THETA ? ekf_from_double(hk) : EKF_C(0),
                                   k == ATT_PSI ? ekf_from_double(hk) : EKF_C(0)};
        st = im->angles(P, x, h, EKF_C(0.01), ekf_from_double(r));
    }
    if (st != EKF_OK && !im->words) {
        TEST_ASSERT_EQUAL_MEMORY(P0, P, sizeof P); /* (the words' wrapper compares its storage) */
    }
    if (st != EKF_OK) {
        TEST_ASSERT_EQUAL_MEMORY(x0, x, sizeof x);
    }
    *vi = ekf_to_double(P[i * ATT_N + i]);
    return st;
}

static void expect_threshold(const impl_t *im, int k, double hk, int i)
{
    double vi;
    char what[160];
    snprintf(what, sizeof what, "%s: %s row on state %d, new variance of state %d", im->name, hk == 0.0 ? "unit" : "angle", k, i);
    /* three quarters of the allowance below zero: rounding, floored */
    TEST_ASSERT_EQUAL_INT_MESSAGE(EKF_OK, update_at(im, k, hk, i, 0.75, &vi), what);
    TEST_ASSERT_TRUE_MESSAGE(vi >= ekf_to_double(k_floor) && vi <= 2.0 * ekf_to_double(k_floor), what);
    /* a third beyond the allowance: indefinite beyond rounding, refused */
    TEST_ASSERT_EQUAL_INT_MESSAGE(EKF_ERR_NUMERIC, update_at(im, k, hk, i, 1.33, &vi), what);
}

static void test_new_variance_allowance(void)
{
    int m;
    for (m = 0; m < N_IMPLS; ++m) {
        const impl_t *im = &k_impls[m];
        expect_threshold(im, ATT_P, 0.0, ATT_PHID);   /* a body rate and an Euler rate */
        expect_threshold(im, ATT_PSI, 0.0, ATT_THETA); /* the heading and the pitch */
        expect_threshold(im, ATT_PHI, 0.5, ATT_THETA); /* an angle row: another angle */
        expect_threshold(im, ATT_THETA, 0.5, ATT_Q);   /*   and a body rate */
    }
}

/* H = (1, -1, 0) on the angles with P_phi,theta = c: H P H^T = 2 - 2 c. c = 1 + 1e-3: H P H^T
 * = -2e-3, S < R, while every new variance P_ii - b_i^2 / S is positive (b = +-1e-3): only the
 * S >= R check refuses. c = 1: H P H^T = 0, S = R, accepted. */
static void test_s_below_r_refused(void)
{
    int m;
    for (m = 0; m < N_IMPLS; ++m) {
        const impl_t *im = &k_impls[m];
        const ekf_scalar_t h[3] = {EKF_C(1), EKF_C(-1), EKF_C(0)};
        ekf_scalar_t P[ATT_NN], x[ATT_N] = {0};
        identity(P);
        set_pair(P, ATT_PHI, ATT_THETA, 1.001);
        TEST_ASSERT_EQUAL_INT_MESSAGE(EKF_ERR_NUMERIC, im->angles(P, x, h, EKF_C(0.01), EKF_C(1)), im->name);
        identity(P);
        set_pair(P, ATT_PHI, ATT_THETA, 1.0);
        TEST_ASSERT_EQUAL_INT_MESSAGE(EKF_OK, im->angles(P, x, h, EKF_C(0.01), EKF_C(1)), im->name);
        /* a unit row on a negative variance: S = P_kk + R < R */
        identity(P);
        set_pair(P, ATT_R, ATT_R, -1e-3);
        TEST_ASSERT_EQUAL_INT_MESSAGE(EKF_ERR_NUMERIC, im->unit(P, x, ATT_R, EKF_C(0.01), EKF_C(1)), im->name);
    }
}

/* P = I with the (phi, theta) correlation 1 + d ATT_PD_MARGIN: one round of loading by
 * lambda = 10 margin passes while (1 + d m) <= (1 + 10 m) sqrt(1 - m), about d <= 9.5; two
 * rounds (lambda 10 m, then 100 m) while d <= about 109; none while 1 - (1 + d m)^2 >= m,
 * about d <= -0.5. */
static void correlated(ekf_scalar_t P[ATT_NN], double d)
{
    identity(P);
    set_pair(P, ATT_PHI, ATT_THETA, 1.0 + d * ekf_to_double(ATT_PD_MARGIN));
}

static void test_guard_rounds(void)
{
    static const struct {
        double d;
        int rounds;
    } cases[] = {{-2.0, 0}, {-1.0, 0}, {0.5, 1}, {4.0, 1}, {8.0, 1}, {12.0, 2}, {30.0, 2}, {100.0, 2}};
    int m, k;
    for (m = 0; m < N_IMPLS; ++m) {
        for (k = 0; k < (int)(sizeof cases / sizeof cases[0]); ++k) {
            ekf_scalar_t P[ATT_NN];
            char what[120];
            correlated(P, cases[k].d);
            snprintf(what, sizeof what, "%s: correlation 1 %+g margin", k_impls[m].name, cases[k].d);
            TEST_ASSERT_EQUAL_INT_MESSAGE(cases[k].rounds, k_impls[m].guard(P), what);
        }
    }
}

/* The filter's guard: one round accepted (flagged, counted), two refused. */
static void test_filter_guard_accepts_one_round(void)
{
    static att_ekf_t f;
    static const double d[3] = {-2.0, 4.0, 30.0};
    const ekf_scalar_t acc[3] = {EKF_C(0), EKF_C(0), EKF_C(9.81)}, mag[3] = {EKF_C(20), EKF_C(0), EKF_C(-40)};
    int k;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &att_default_settings));
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_align(&f, acc, mag));
    for (k = 0; k < 3; ++k) {
        ekf_scalar_t P[ATT_NN];
        const uint32_t before = att_diag(&f)->cov_repairs;
        ekf_status_t st;
        correlated(P, d[k]);
        att_cov_from_full(&f.vars.cov, P);
        st = att_guard_covariance(&f.vars, &f.settings);
        TEST_ASSERT_EQUAL_INT(k < 2 ? EKF_OK : EKF_ERR_NUMERIC, st);
        if (k < 2) {
            TEST_ASSERT_EQUAL_UINT32(before + (uint32_t)k, att_diag(&f)->cov_repairs);
            TEST_ASSERT_EQUAL_INT(k, (att_flags(&f) & ATT_FLAG_COV_REPAIRED) != 0u);
            TEST_ASSERT_TRUE(att_cov_is_pd(&f.vars.cov, ATT_PD_MARGIN));
        }
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_new_variance_allowance);
    RUN_TEST(test_s_below_r_refused);
    RUN_TEST(test_guard_rounds);
    RUN_TEST(test_filter_guard_accepts_one_round);
    return UNITY_END();
}
