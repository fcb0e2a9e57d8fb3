/*
 * test_update_thresholds.c - the refusal thresholds of every scalar-update kernel and of the
 * definiteness test, each tested directly (not through the end-of-call guard, whose repair
 * would hide a kernel that accepts what it must refuse):
 *
 *   - a new variance P_ii - K_i b_i negative beyond the kernel's rounding allowance is
 *     refused (EKF_ERR_NUMERIC, x and P unchanged), one negative by less is floored at
 *     var_floor: the generic ekf_update_scalar and the build's att_cov_update_unit /
 *     att_cov_update_angles (float and double: att_cov.c with the generated kernels; fixed
 *     point: att_cov_fx_kernels.c). The allowance is the one docs/derivation.md
 *     ("Covariance update") gives: 32 n eps (|P_ii| + |K_i b_i|), plus in fixed point
 *     32 n LSB (1 + |K_i|)(1 + |K_i| + |b_i|) for the generic core and ATT_FX_TOL LSB of the
 *     state's normalised word for the fixed-point kernel. Probed at 1/4 and 4 times it.
 *     Every other state in turn takes the negative new variance (a check or a floor that
 *     misses one state shows).
 *   - a P negative along H (0 < S < R) with every new variance positive is refused: the
 *     S >= R check; the measured state's own new variance below var_floor is floored.
 *   - att_cov_floor_diag never leaves a variance below the floor (fixed point: rounded up).
 *   - the pivots of ekf_cov_is_pd / att_cov_is_pd: a pivot below rel_margin P_jj fails, one
 *     above passes.
 *
 * Built for float, double and fixed point. Found missing by scripts/mutate.py
 * (docs/reliability.md, "Mutation testing").
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "att_cov.h"
#include "ekf.h"
#include "unity.h"

#if defined(ATT_COV_FX)
#include "att_cov_fx_words.h"
#endif

#define NN (ATT_N * ATT_N)

void setUp(void) {}
void tearDown(void) {}

/* The probe: H = e_A, and a state b correlated with A so that b's new variance is
 * P_bb - P_Ab^2 / (P_AA + r). */
enum { A = ATT_PHI };
/* (the floor a power of two: exact in every scalar) */
static const double P_AA = 1.0, P_BB = 1.5, R_VAR = 1e-3, FLOOR = 9.3132257461547852e-10; /* 2^-30 */

/* P: identity but the (A, b) block [[P_AA, c], [c, P_BB]], c chosen so that b's new variance
 * is `target` in exact arithmetic (c^2 = (P_BB - target)(P_AA + r)). */
static void probe_cov(double target, int b, ekf_scalar_t P[NN])
{
    const double c = sqrt((P_BB - target) * (P_AA + R_VAR));
    int i;
    memset(P, 0, sizeof(ekf_scalar_t) * NN);
    for (i = 0; i < ATT_N; ++i) {
        P[i * ATT_N + i] = EKF_C(1);
    }
    P[A * ATT_N + A] = ekf_from_double(P_AA);
    P[b * ATT_N + b] = ekf_from_double(P_BB);
    P[A * ATT_N + b] = ekf_from_double(c);
    P[b * ATT_N + A] = P[A * ATT_N + b];
}

/* P: identity but P_AA = paa. */
static void diag_cov(double paa, ekf_scalar_t P[NN])
{
    int i;
    memset(P, 0, sizeof(ekf_scalar_t) * NN);
    for (i = 0; i < ATT_N; ++i) {
        P[i * ATT_N + i] = EKF_C(1);
    }
    P[A * ATT_N + A] = ekf_from_double(paa);
}

/* The generic core's allowance for b's new variance of the probe (ekf.c). */
static double generic_tolerance(void)
{
    const double eps = ekf_to_double(EKF_SCALAR_EPS), lsb = ekf_to_double(EKF_SCALAR_ABS_EPS), cn = 32.0 * ATT_N;
    const double b = sqrt(P_BB * (P_AA + R_VAR)), k = b / (P_AA + R_VAR);
    return cn * eps * (P_BB + k * b) + cn * lsb * (1.0 + k) * (1.0 + k + b);
}

/* The build's kernel's allowance (att_cov.c; att_cov_fx_kernels.c: ATT_FX_TOL LSB of b's
 * word, whose scale is 2^(2 e_B - 29) with P_BB in [1, 4): e_B = 0). */
static double kernel_tolerance(void)
{
#if defined(ATT_COV_FX)
    return (double)ATT_FX_TOL * ldexp(1.0, -29);
#else
    return generic_tolerance();
#endif
}

/* The probe's two outcomes: within the allowance applied with b's variance floored, beyond
 * it refused with the state unchanged (P: by the caller). */
static void check_pair(const char *what, int b, ekf_status_t st_in, ekf_scalar_t pbb_in, ekf_status_t st_out,
                       const ekf_scalar_t x_out[ATT_N], double tol)
{
    int i;
    if (b == ATT_N - 1) {
        printf("%s (%s): allowance %.3g; last state's new variance -tol/4: status %d, P_bb %.3g; -4 tol: status %d\n", what,
               EKF_SCALAR_NAME, tol, (int)st_in, ekf_to_double(pbb_in), (int)st_out);
    }
    TEST_ASSERT_EQUAL_INT_MESSAGE(EKF_OK, st_in, what);
    /* floored: at var_floor (the fixed-point kernel may round the floor up to the next power
     * of two at the word's scale) */
    TEST_ASSERT_TRUE_MESSAGE(ekf_to_double(pbb_in) >= FLOOR && ekf_to_double(pbb_in) <= 2.0 * FLOOR, what);
    TEST_ASSERT_EQUAL_INT_MESSAGE(EKF_ERR_NUMERIC, st_out, what);
    for (i = 0; i < ATT_N; ++i) {
        TEST_ASSERT_TRUE_MESSAGE(x_out[i] == EKF_C(0), what);
    }
}

static ekf_status_t generic_update(ekf_scalar_t x[ATT_N], ekf_scalar_t P[NN])
{
    static const uint8_t idx[1] = {A};
    static const ekf_scalar_t one[1] = {EKF_C(1)};
    const ekf_hrow_t h = {idx, one, 1};
    return ekf_update_scalar(x, P, ATT_N, &h, EKF_C(0), ekf_from_double(R_VAR), EKF_C(0), ekf_from_double(FLOOR),
                             NULL);
}

/* One of the build's kernels: att_cov_update_unit (angles = 0) or att_cov_update_angles
 * with h = e_A (angles = 1). */
static ekf_status_t kernel_update_floor(int angles, ekf_scalar_t x[ATT_N], att_cov_t *c, double var_floor)
{
    static const ekf_scalar_t h3[3] = {EKF_C(1), EKF_C(0), EKF_C(0)};
    const ekf_scalar_t fl = ekf_from_double(var_floor);
    if (angles) {
        return att_cov_update_angles(c, x, h3, EKF_C(0), ekf_from_double(R_VAR), EKF_C(0), fl, NULL);
    }
    return att_cov_update_unit(c, x, A, EKF_C(0), ekf_from_double(R_VAR), EKF_C(0), fl, NULL);
}

static ekf_status_t kernel_update(int angles, ekf_scalar_t x[ATT_N], att_cov_t *c)
{
    return kernel_update_floor(angles, x, c, FLOOR);
}

static void test_generic_update_threshold(void)
{
    const double tol = generic_tolerance();
    int b;
    for (b = 0; b < ATT_N; ++b) {
        ekf_scalar_t P_in[NN], P_out[NN], P_keep[NN], x_in[ATT_N] = {0}, x_out[ATT_N] = {0};
        ekf_status_t st_in, st_out;
        if (b == A) {
            continue;
        }
        probe_cov(-0.25 * tol, b, P_in);
        probe_cov(-4.0 * tol, b, P_out);
        memcpy(P_keep, P_out, sizeof P_keep);
        st_in = generic_update(x_in, P_in);
        st_out = generic_update(x_out, P_out);
        check_pair("ekf_update_scalar", b, st_in, P_in[b * ATT_N + b], st_out, x_out, tol);
        TEST_ASSERT_EQUAL_MEMORY(P_keep, P_out, sizeof P_keep); /* refused: P unchanged */
    }
}

static void kernel_probe(int angles)
{
    const double tol = kernel_tolerance();
    const char *what = angles ? "att_cov_update_angles" : "att_cov_update_unit";
    int b;
    for (b = 0; b < ATT_N; ++b) {
        ekf_scalar_t P_in[NN], P_out[NN], x_in[ATT_N] = {0}, x_out[ATT_N] = {0};
        att_cov_t c_in, c_out, c_keep;
        ekf_status_t st_in, st_out;
        if (b == A) {
            continue;
        }
        probe_cov(-0.25 * tol, b, P_in);
        probe_cov(-4.0 * tol, b, P_out);
        att_cov_from_full(&c_in, P_in);
        att_cov_from_full(&c_out, P_out);
        c_keep = c_out;
        st_in = kernel_update(angles, x_in, &c_in);
        st_out = kernel_update(angles, x_out, &c_out);
        att_cov_to_full(&c_in, P_in);
        check_pair(what, b, st_in, P_in[b * ATT_N + b], st_out, x_out, tol);
        TEST_ASSERT_EQUAL_MEMORY(&c_keep, &c_out, sizeof c_keep); /* refused: P unchanged */
    }
}

static void test_kernel_update_unit_threshold(void) { kernel_probe(0); }
static void test_kernel_update_angles_threshold(void) { kernel_probe(1); }

/* H = (1, 1) on (phi, theta) and P's (phi, theta) block [[1, -(1 + d)], [-(1 + d), 1]] with
 * d = R/4: H P H^T = -2 d = -R/2, so 0 < S = R/2 < R, while every new variance,
 * 1 - d^2 / S, stays near 1: only the S >= R check sees that P is not positive
 * semi-definite along H. Every kernel refuses, changing nothing. */
static void test_negative_along_h_is_refused(void)
{
    static const uint8_t idx[2] = {ATT_PHI, ATT_THETA};
    static const ekf_scalar_t one[2] = {EKF_C(1), EKF_C(1)};
    static const ekf_scalar_t h3[3] = {EKF_C(1), EKF_C(1), EKF_C(0)};
    const ekf_hrow_t h = {idx, one, 2};
    ekf_scalar_t P[NN], P_keep[NN], x[ATT_N] = {0};
    att_cov_t c, c_keep;
    diag_cov(1.0, P);
    P[ATT_PHI * ATT_N + ATT_THETA] = ekf_from_double(-(1.0 + 0.25 * R_VAR));
    P[ATT_THETA * ATT_N + ATT_PHI] = P[ATT_PHI * ATT_N + ATT_THETA];
    memcpy(P_keep, P, sizeof P_keep);
    att_cov_from_full(&c, P);
    c_keep = c;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, ekf_update_scalar(x, P, ATT_N, &h, EKF_C(0), ekf_from_double(R_VAR),
                                                             EKF_C(0), ekf_from_double(FLOOR), NULL));
    TEST_ASSERT_EQUAL_MEMORY(P_keep, P, sizeof P_keep);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, att_cov_update_angles(&c, x, h3, EKF_C(0), ekf_from_double(R_VAR),
                                                                 EKF_C(0), ekf_from_double(FLOOR), NULL));
    TEST_ASSERT_EQUAL_MEMORY(&c_keep, &c, sizeof c_keep);
}

/* The measured state's own new variance P_AA R / S below the floor is floored too. */
static void test_measured_variance_is_floored(void)
{
    ekf_scalar_t P[NN], x[ATT_N] = {0};
    att_cov_t c;
    int angles;
    diag_cov(0.25 * FLOOR, P);
    TEST_ASSERT_EQUAL_INT(EKF_OK, generic_update(x, P));
    TEST_ASSERT_TRUE(ekf_to_double(P[A * ATT_N + A]) >= FLOOR && ekf_to_double(P[A * ATT_N + A]) <= 2.0 * FLOOR);
    diag_cov(0.25 * FLOOR, P);
    for (angles = 0; angles < 2; ++angles) {
        att_cov_from_full(&c, P);
        TEST_ASSERT_EQUAL_INT(EKF_OK, kernel_update(angles, x, &c));
        TEST_ASSERT_TRUE(ekf_to_double(att_cov_get(&c, A, A)) >= FLOOR &&
                         ekf_to_double(att_cov_get(&c, A, A)) <= 2.0 * FLOOR);
    }
}

/* P identity but [[1, c], [c, 1]] on (A, B_PIVOT): the second pivot 1 - c^2. */
enum { B_PIVOT = ATT_THETA };
static void pivot_cov(double pivot, ekf_scalar_t P[NN])
{
    probe_cov(0.0, B_PIVOT, P);
    P[A * ATT_N + A] = EKF_C(1);
    P[B_PIVOT * ATT_N + B_PIVOT] = EKF_C(1);
    P[A * ATT_N + B_PIVOT] = ekf_from_double(sqrt(1.0 - pivot));
    P[B_PIVOT * ATT_N + A] = P[A * ATT_N + B_PIVOT];
}

static void test_definiteness_margin(void)
{
    const double margin = 1e-3;
    ekf_scalar_t P[NN], work[NN];
    att_cov_t c;
    pivot_cov(4.0 * margin, P);
    TEST_ASSERT_EQUAL_INT(1, ekf_cov_is_pd(P, ATT_N, ekf_from_double(margin), work));
    att_cov_from_full(&c, P);
    TEST_ASSERT_EQUAL_INT(1, att_cov_is_pd(&c, ekf_from_double(margin)));
    pivot_cov(0.25 * margin, P); /* positive definite, but a pivot below the margin */
    TEST_ASSERT_EQUAL_INT(0, ekf_cov_is_pd(P, ATT_N, ekf_from_double(margin), work));
    att_cov_from_full(&c, P);
    TEST_ASSERT_EQUAL_INT(0, att_cov_is_pd(&c, ekf_from_double(margin)));
}

/* att_cov_floor_diag leaves every variance at or above the floor, exactly in the scalar, for
 * floors that are not powers of two and variances of every scale (fixed point: the floor is
 * rounded up, never to nearest, into each state's word). */
static void test_floor_is_never_undercut(void)
{
    /* (the second 1.25 2^-29: 1.25 words of a state of unit scale, where rounding to nearest
     * would give one) */
    static const double floors[5] = {1e-9, 2.3283064365386963e-09, 3.3e-9, 7.7e-7, 1.3e-5};
    ekf_scalar_t P[NN];
    att_cov_t c;
    int k, i, low = 0;
    for (k = 0; k < 5; ++k) {
        const ekf_scalar_t fl = ekf_from_double(floors[k]);
        diag_cov(1.0, P);
        for (i = 0; i < ATT_N; ++i) { /* variances from far above to far below the floor */
            P[i * ATT_N + i] = ekf_from_double(floors[k] * ldexp(1.0, 12 - 3 * i));
        }
        att_cov_from_full(&c, P);
        TEST_ASSERT_EQUAL_INT(0, att_cov_floor_diag(&c, fl));
        for (i = 0; i < ATT_N; ++i) {
            low += (att_cov_get(&c, i, i) < fl);
        }
        /* and the update kernels' floor of a new variance (written in the word of a state
         * whose scale is far above the floor) */
        for (i = 0; i < 2; ++i) {
            ekf_scalar_t x[ATT_N] = {0};
            probe_cov(-0.25 * kernel_tolerance(), ATT_PSI, P);
            att_cov_from_full(&c, P);
            TEST_ASSERT_EQUAL_INT(EKF_OK, kernel_update_floor(i, x, &c, floors[k]));
            low += (att_cov_get(&c, ATT_PSI, ATT_PSI) < fl);
        }
    }
    TEST_ASSERT_EQUAL_INT(0, low);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_generic_update_threshold);
    RUN_TEST(test_kernel_update_unit_threshold);
    RUN_TEST(test_kernel_update_angles_threshold);
    RUN_TEST(test_negative_along_h_is_refused);
    RUN_TEST(test_measured_variance_is_floored);
    RUN_TEST(test_definiteness_margin);
    RUN_TEST(test_floor_is_never_undercut);
    return UNITY_END();
}
