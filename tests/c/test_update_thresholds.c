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
#include "att_cov_fx.h"
#endif

#define NN (ATT_N * ATT_N)

void setUp(void) {}
void tearDown(void) {}

/* The states of the probe: H = e_A, and B correlated with A so that B's new variance is
 * P_BB - P_AB^2 / (P_AA + r). */
enum { A = ATT_PHI, B = ATT_THETA };
/* (the floor a power of two: exact in every scalar) */
static const double P_AA = 1.0, P_BB = 1.5, R_VAR = 1e-3, FLOOR = 9.3132257461547852e-10; /* 2^-30 */

/* P: identity but the (A, B) block [[P_AA, c], [c, P_BB]], c chosen so that B's new variance
 * is `target` in exact arithmetic (c^2 = (P_BB - target)(P_AA + r)). */
static void probe_cov(double target, ekf_scalar_t P[NN])
{
    const double c = sqrt((P_BB - target) * (P_AA + R_VAR));
    int i;
    memset(P, 0, sizeof(ekf_scalar_t) * NN);
    for (i = 0; i < ATT_N; ++i) {
        P[i * ATT_N + i] = EKF_C(1);
    }
    P[A * ATT_N + A] = ekf_from_double(P_AA);
    P[B * ATT_N + B] = ekf_from_double(P_BB);
    P[A * ATT_N + B] = ekf_from_double(c);
    P[B * ATT_N + A] = P[A * ATT_N + B];
}

/* The generic core's allowance for B's new variance of the probe (ekf.c). */
static double generic_tolerance(void)
{
    const double eps = ekf_to_double(EKF_SCALAR_EPS), lsb = ekf_to_double(EKF_SCALAR_ABS_EPS), cn = 32.0 * ATT_N;
    const double b = sqrt(P_BB * (P_AA + R_VAR)), k = b / (P_AA + R_VAR);
    return cn * eps * (P_BB + k * b) + cn * lsb * (1.0 + k) * (1.0 + k + b);
}

/* The build's kernel's allowance (att_cov.c; att_cov_fx_kernels.c: ATT_FX_TOL LSB of B's
 * word, whose scale is 2^(2 e_B - 29) with P_BB in [1, 4): e_B = 0). */
static double kernel_tolerance(void)
{
#if defined(ATT_COV_FX)
    return (double)ATT_FX_TOL * ldexp(1.0, -29);
#else
    return generic_tolerance();
#endif
}

/* The probe's two outcomes: within the allowance applied with B's variance floored, beyond
 * it refused with the state unchanged (P: by the caller). */
static void check_pair(const char *what, ekf_status_t st_in, ekf_scalar_t pbb_in, ekf_status_t st_out,
                       const ekf_scalar_t x_out[ATT_N], double tol)
{
    int i;
    printf("%s (%s): allowance %.3g; new variance -tol/4: status %d, P_BB %.3g; -4 tol: status %d\n", what,
           EKF_SCALAR_NAME, tol, (int)st_in, ekf_to_double(pbb_in), (int)st_out);
    TEST_ASSERT_EQUAL_INT_MESSAGE(EKF_OK, st_in, what);
    /* floored: at var_floor (the fixed-point kernel may round the floor up to the next power
     * of two at the word's scale) */
    TEST_ASSERT_TRUE_MESSAGE(ekf_to_double(pbb_in) >= FLOOR && ekf_to_double(pbb_in) <= 2.0 * FLOOR, what);
    TEST_ASSERT_EQUAL_INT_MESSAGE(EKF_ERR_NUMERIC, st_out, what);
    for (i = 0; i < ATT_N; ++i) {
        TEST_ASSERT_TRUE_MESSAGE(x_out[i] == EKF_C(0), what);
    }
}

static void test_generic_update_threshold(void)
{
    static const uint8_t idx[1] = {A};
    static const ekf_scalar_t one[1] = {EKF_C(1)};
    const ekf_hrow_t h = {idx, one, 1};
    const double tol = generic_tolerance();
    ekf_scalar_t P_in[NN], P_out[NN], P_keep[NN], x_in[ATT_N] = {0}, x_out[ATT_N] = {0};
    ekf_status_t st_in, st_out;
    probe_cov(-0.25 * tol, P_in);
    probe_cov(-4.0 * tol, P_out);
    memcpy(P_keep, P_out, sizeof P_keep);
    st_in = ekf_update_scalar(x_in, P_in, ATT_N, &h, EKF_C(0), ekf_from_double(R_VAR), EKF_C(0),
                              ekf_from_double(FLOOR), NULL);
    st_out = ekf_update_scalar(x_out, P_out, ATT_N, &h, EKF_C(0), ekf_from_double(R_VAR), EKF_C(0),
                               ekf_from_double(FLOOR), NULL);
    check_pair("ekf_update_scalar", st_in, P_in[B * ATT_N + B], st_out, x_out, tol);
    TEST_ASSERT_EQUAL_MEMORY(P_keep, P_out, sizeof P_keep); /* refused: P unchanged */
}

/* One of the build's kernels: att_cov_update_unit (angles = 0) or att_cov_update_angles
 * with h = e_phi (angles = 1). */
static void kernel_probe(int angles)
{
    static const ekf_scalar_t h3[3] = {EKF_C(1), EKF_C(0), EKF_C(0)};
    const double tol = kernel_tolerance();
    ekf_scalar_t P_in[NN], P_out[NN], x_in[ATT_N] = {0}, x_out[ATT_N] = {0};
    att_cov_t c_in, c_out, c_keep;
    ekf_status_t st_in, st_out;
    probe_cov(-0.25 * tol, P_in);
    probe_cov(-4.0 * tol, P_out);
    att_cov_from_full(&c_in, P_in);
    att_cov_from_full(&c_out, P_out);
    c_keep = c_out;
    if (angles) {
        st_in = att_cov_update_angles(&c_in, x_in, h3, EKF_C(0), ekf_from_double(R_VAR), EKF_C(0),
                                      ekf_from_double(FLOOR), NULL);
        st_out = att_cov_update_angles(&c_out, x_out, h3, EKF_C(0), ekf_from_double(R_VAR), EKF_C(0),
                                       ekf_from_double(FLOOR), NULL);
    } else {
        st_in = att_cov_update_unit(&c_in, x_in, A, EKF_C(0), ekf_from_double(R_VAR), EKF_C(0),
                                    ekf_from_double(FLOOR), NULL);
        st_out = att_cov_update_unit(&c_out, x_out, A, EKF_C(0), ekf_from_double(R_VAR), EKF_C(0),
                                     ekf_from_double(FLOOR), NULL);
    }
    att_cov_to_full(&c_in, P_in);
    check_pair(angles ? "att_cov_update_angles" : "att_cov_update_unit", st_in, P_in[B * ATT_N + B], st_out, x_out,
               tol);
    TEST_ASSERT_EQUAL_MEMORY(&c_keep, &c_out, sizeof c_keep); /* refused: P unchanged */
}

static void test_kernel_update_unit_threshold(void) { kernel_probe(0); }
static void test_kernel_update_angles_threshold(void) { kernel_probe(1); }

/* P identity but [[1, c], [c, 1]] on (A, B): the second pivot 1 - c^2. */
static void pivot_cov(double pivot, ekf_scalar_t P[NN])
{
    probe_cov(0.0, P);
    P[A * ATT_N + A] = EKF_C(1);
    P[B * ATT_N + B] = EKF_C(1);
    P[A * ATT_N + B] = ekf_from_double(sqrt(1.0 - pivot));
    P[B * ATT_N + A] = P[A * ATT_N + B];
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

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_generic_update_threshold);
    RUN_TEST(test_kernel_update_unit_threshold);
    RUN_TEST(test_kernel_update_angles_threshold);
    RUN_TEST(test_definiteness_margin);
    return UNITY_END();
}
