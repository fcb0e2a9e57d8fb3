/*
 * test_att_cov.c - the library's covariance implementation (att_cov.h; the generated
 * att_cov_gen.c in the float and double builds) against the reference implementation
 * (att_cov_ref.c, linked beside it under other names: support/att_cov_ref_wrap.h), operation
 * by operation, on random covariances of every scale the filter produces and on the filter's
 * own covariance along the benchmark recording:
 *   - the scalar updates (unit H, the tilt H): status, state, covariance and ekf_innov_t bit
 *     for bit, refusals included (P indefinite along H, a new variance negative beyond
 *     rounding, a non-finite or non-positive input, the gate);
 *   - the prediction (factored F P F^T + rate noise, increment variances): within a few
 *     units of rounding (16 eps) of each entry's scale (predict_scale); a
 *     non-finite Jacobian refused with P unchanged;
 *   - the bounds and remaps (floor, cap, reset, negate, diagonal noise, rate noise): bit for
 *     bit;
 *   - the guard: the same outcome (passed, repaired, refused), a repaired P passing.
 * Built for float and double (the fixed-point build has only the reference); on the target
 * too, where the float updates take the VLDM/VSTM path.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "att.h"
#include "att_cov.h"
#include "att_cov_ref_wrap.h"
#include "att_state.h"
#include "att_model.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define TRIALS 400

static ts_rng_t g_rng;

/* Random symmetric positive definite P = S C S: C = A A^T / 9 + 0.05 I (correlations of any
 * strength), S diagonal with standard deviations spread over 10^-4 .. 10^1. */
static void random_spd(ekf_scalar_t P[ATT_NN])
{
    double A[ATT_NN], sd[ATT_N];
    int i, j, k;
    for (i = 0; i < ATT_NN; ++i) {
        A[i] = ts_uniform_in(&g_rng, -1.0, 1.0);
    }
    for (i = 0; i < ATT_N; ++i) {
        sd[i] = pow(10.0, ts_uniform_in(&g_rng, -4.0, 1.0));
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j <= i; ++j) {
            double acc = (i == j) ? 0.05 : 0.0;
            for (k = 0; k < ATT_N; ++k) {
                acc += A[i * ATT_N + k] * A[j * ATT_N + k] / 9.0;
            }
            P[i * ATT_N + j] = P[j * ATT_N + i] = ekf_from_double(acc * sd[i] * sd[j]);
        }
    }
}

/* A random state with rates up to 3 rad/s and any attitude (pitch within 80 deg). */
static void random_state(ekf_scalar_t x[ATT_N])
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        x[i] = ekf_from_double(ts_uniform_in(&g_rng, -3.0, 3.0));
    }
    x[ATT_THETA] = ekf_from_double(ts_uniform_in(&g_rng, -1.4, 1.4));
}

static void load_gen(att_cov_t *c, const ekf_scalar_t P[ATT_NN]) { att_cov_from_full(c, P); }

static void expect_same_matrix(const att_cov_t *c, const ekf_scalar_t Pref[ATT_NN], const char *what)
{
    ekf_scalar_t P[ATT_NN];
    att_cov_to_full(c, P);
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(Pref, P, sizeof P, what);
}

static void expect_same_info(const ekf_innov_t *a, const ekf_innov_t *b)
{
    TEST_ASSERT_EQUAL_MEMORY(a, b, sizeof *a);
}

/* One update of each kind on (P, x) with both implementations: identical bits. */
static void compare_updates(const ekf_scalar_t P0[ATT_NN], const ekf_scalar_t x0[ATT_N], ekf_scalar_t nu,
                            ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t h_phi, ekf_scalar_t h_theta,
                            int *statuses)
{
    static const int unit[4] = {ATT_P, ATT_Q, ATT_R, ATT_PSI};
    const ekf_scalar_t floor = EKF_C(1e-12);
    int u;
    for (u = 0; u < 6; ++u) {
        ekf_scalar_t Pr[ATT_NN], xr[ATT_N], xg[ATT_N];
        ekf_innov_t ir, ig;
        att_cov_t c;
        ekf_status_t sr, sg;
        memcpy(Pr, P0, sizeof Pr);
        memcpy(xr, x0, sizeof xr);
        memcpy(xg, x0, sizeof xg);
        memset(&ir, 0x5a, sizeof ir);
        memset(&ig, 0xa5, sizeof ig);
        load_gen(&c, P0);
        if (u < 4) {
            sr = refcov_update_unit(Pr, xr, unit[u], nu, r_var, gate, floor, &ir);
            sg = att_cov_update_unit(&c, xg, unit[u], nu, r_var, gate, floor, &ig);
        } else {
            /* the accelerometer's rows (no heading entry), then a row on all three angles */
            const ekf_scalar_t h[3] = {h_phi, h_theta,
                                       (u == 4) ? EKF_C(0) : ekf_mul(EKF_C(0.5), ekf_sub(h_phi, h_theta))};
            sr = refcov_update_angles(Pr, xr, h, nu, r_var, gate, floor, &ir);
            sg = att_cov_update_angles(&c, xg, h, nu, r_var, gate, floor, &ig);
        }
        TEST_ASSERT_EQUAL_INT(sr, sg);
        TEST_ASSERT_EQUAL_MEMORY(xr, xg, sizeof xr);
        expect_same_matrix(&c, Pr, "update");
        expect_same_info(&ir, &ig);
        if (sr != EKF_OK) {
            TEST_ASSERT_EQUAL_MEMORY(x0, xg, sizeof xr); /* refused or gated: nothing written */
            expect_same_matrix(&c, P0, "refused update");
        }
        if (statuses != NULL && (unsigned)sr <= (unsigned)EKF_SKIPPED) {
            ++statuses[sr];
        }
    }
}

static void test_updates_bit_identical(void)
{
    int trial, statuses[EKF_SKIPPED + 1] = {0};
    ts_rng_seed(&g_rng, 11);
    for (trial = 0; trial < TRIALS; ++trial) {
        ekf_scalar_t P[ATT_NN], x[ATT_N];
        const ekf_scalar_t nu = ekf_from_double(ts_uniform_in(&g_rng, -1.0, 1.0) * pow(10.0, ts_uniform_in(&g_rng, -4.0, 0.0)));
        const ekf_scalar_t r = ekf_from_double(pow(10.0, ts_uniform_in(&g_rng, -8.0, 0.0)));
        const ekf_scalar_t gate = (trial % 3 == 0) ? EKF_C(0) : EKF_C(3);
        random_spd(P);
        random_state(x);
        compare_updates(P, x, nu, r, gate, ekf_from_double(ts_uniform_in(&g_rng, -1.0, 1.0)),
                        ekf_from_double(ts_uniform_in(&g_rng, -1.0, 1.0)), statuses);
    }
    printf("updates: %d fused, %d gated, %d refused\n", statuses[EKF_OK], statuses[EKF_GATED],
           statuses[EKF_ERR_NUMERIC]);
    TEST_ASSERT_TRUE(statuses[EKF_OK] > 0 && statuses[EKF_GATED] > 0);
}

static void test_update_refusals_identical(void)
{
    ekf_scalar_t P[ATT_NN], x[ATT_N];
    int k;
    ts_rng_seed(&g_rng, 12);
    random_state(x);
    /* indefinite along e_idx (a negative variance), and a new variance negative beyond
     * rounding: [[1, 2], [2, 1]] in the (psi, p) and (phi, theta) planes */
    random_spd(P);
    P[ATT_PSI * ATT_N + ATT_PSI] = EKF_C(-1);
    compare_updates(P, x, EKF_C(0.1), EKF_C(0.01), EKF_C(0), EKF_C(0.5), EKF_C(-0.5), NULL);
    memset(P, 0, sizeof P);
    for (k = 0; k < ATT_N; ++k) {
        P[k * ATT_N + k] = EKF_C(1);
    }
    P[ATT_PSI * ATT_N + ATT_P] = P[ATT_P * ATT_N + ATT_PSI] = EKF_C(2);
    P[ATT_PHI * ATT_N + ATT_THETA] = P[ATT_THETA * ATT_N + ATT_PHI] = EKF_C(2);
    compare_updates(P, x, EKF_C(0.1), EKF_C(0.01), EKF_C(0), EKF_C(1), EKF_C(0), NULL);
    /* bad inputs: non-finite innovation, noise, H; noise <= 0; an infinite variance */
    random_spd(P);
    compare_updates(P, x, ekf_from_double((double)NAN), EKF_C(0.01), EKF_C(3), EKF_C(1), EKF_C(1), NULL);
    compare_updates(P, x, EKF_C(0.1), ekf_from_double((double)INFINITY), EKF_C(3), EKF_C(1), EKF_C(1), NULL);
    compare_updates(P, x, EKF_C(0.1), EKF_C(0), EKF_C(3), EKF_C(1), EKF_C(1), NULL);
    compare_updates(P, x, EKF_C(0.1), EKF_C(-1), EKF_C(3), EKF_C(1), EKF_C(1), NULL);
    compare_updates(P, x, EKF_C(0.1), EKF_C(0.01), EKF_C(3), ekf_from_double((double)NAN), EKF_C(1), NULL);
    P[ATT_PHID * ATT_N + ATT_PHID] = ekf_from_double((double)INFINITY);
    compare_updates(P, x, EKF_C(0.1), EKF_C(0.01), EKF_C(0), EKF_C(1), EKF_C(1), NULL);
    /* a gate so small that gate^2 S underflows */
    random_spd(P);
    compare_updates(P, x, EKF_C(0.1), EKF_C(0.01), ekf_from_double(1e-30), EKF_C(1), EKF_C(1), NULL);
}

/* The factors of the transition at a random state and step. */
static void random_factors(ekf_scalar_t d1[ATT_GEN_F1_NNZ], ekf_scalar_t d2[ATT_GEN_F2_NNZ])
{
    ekf_scalar_t x[ATT_N], xn[ATT_N];
    att_motion_t mo;
    const ekf_scalar_t dt = ekf_from_double(pow(10.0, ts_uniform_in(&g_rng, -4.0, -1.3)));
    random_state(x);
    att_model_transition(x, NULL, dt, att_default_settings.gimbal_limit, xn, &mo);
    att_gen_transition_factors(&mo.t0, &mo.t, x, mo.rot, mo.jd, d1, d2);
}

/* The scale of the rounding of entry (i, j) of F2 F1 P F1^T F2^T + G diag(var) G^T as both
 * implementations evaluate it, factor by factor, in double: (|F| |P| |F|^T)_ij +
 * (|G| var |G|^T)_ij with |F| = (I + |D2|) (I + |D1|). (The reference forms F2 = I + D2
 * row by row as P_r + D2_r P with D2_rr = -1: its rounding scales with the old Euler-rate
 * entries that cancel, which the generated kernel never reads.) */
static void predict_scale(const ekf_scalar_t P0[ATT_NN], const ekf_scalar_t d1[ATT_GEN_F1_NNZ],
                          const ekf_scalar_t d2[ATT_GEN_F2_NNZ], const ekf_scalar_t var[3], double M[ATT_NN])
{
    double F1[ATT_NN] = {0}, F2[ATT_NN] = {0}, F[ATT_NN], T[ATT_NN];
    int i, j, k;
    for (i = 0; i < ATT_N; ++i) {
        F1[i * ATT_N + i] = F2[i * ATT_N + i] = 1.0;
    }
    for (k = 0; k < ATT_GEN_F1_NNZ; ++k) {
        F1[att_gen_f1_pattern[k].row * ATT_N + att_gen_f1_pattern[k].col] += fabs(ekf_to_double(d1[k]));
    }
    for (k = 0; k < ATT_GEN_F2_NNZ; ++k) {
        F2[att_gen_f2_pattern[k].row * ATT_N + att_gen_f2_pattern[k].col] += fabs(ekf_to_double(d2[k]));
    }
    for (i = 0; i < ATT_NN; ++i) {
        double a = 0.0;
        for (k = 0; k < ATT_N; ++k) {
            a += fabs(F2[(i / ATT_N) * ATT_N + k] * F1[k * ATT_N + i % ATT_N]);
        }
        F[i] = a;
    }
    for (i = 0; i < ATT_NN; ++i) { /* T = |F| |P| */
        double a = 0.0;
        for (k = 0; k < ATT_N; ++k) {
            a += F[(i / ATT_N) * ATT_N + k] * fabs(ekf_to_double(P0[k * ATT_N + i % ATT_N]));
        }
        T[i] = a;
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < ATT_N; ++j) {
            double a = 0.0;
            for (k = 0; k < ATT_N; ++k) {
                a += T[i * ATT_N + k] * F[j * ATT_N + k];
            }
            for (k = 0; k < 3; ++k) { /* G = F2's body-rate columns */
                a += fabs(F2[i * ATT_N + k] * F2[j * ATT_N + k]) * ekf_to_double(var[k]);
            }
            M[i * ATT_N + j] = a;
        }
    }
}

/* max over the entries of |gen - ref| / M_ij (predict_scale). */
static double predict_error(const att_cov_t *c, const ekf_scalar_t Pr[ATT_NN], const double M[ATT_NN])
{
    ekf_scalar_t P[ATT_NN];
    double worst = 0.0;
    int i;
    att_cov_to_full(c, P);
    for (i = 0; i < ATT_NN; ++i) {
        const double e = fabs(ekf_to_double(P[i]) - ekf_to_double(Pr[i])) / M[i];
        worst = (e > worst) ? e : worst;
    }
    return worst;
}

static void test_predict_matches_reference(void)
{
    /* 16 units of rounding of the entry's scale (measured: under 3, the printout says) */
    const double tol = 16.0 * ekf_to_double(EKF_SCALAR_EPS);
    double worst = 0.0, worst_inc = 0.0;
    int trial, i;
    ts_rng_seed(&g_rng, 13);
    for (trial = 0; trial < TRIALS; ++trial) {
        ekf_scalar_t P[ATT_NN], d1[ATT_GEN_F1_NNZ], d2[ATT_GEN_F2_NNZ], ir[3], ig[3];
        const ekf_scalar_t q = ekf_from_double(pow(10.0, ts_uniform_in(&g_rng, -8.0, -2.0)));
        const ekf_scalar_t var[3] = {q, ekf_mul(q, EKF_C(2)), ekf_mul(q, EKF_C(0.5))};
        att_cov_t c;
        double e;
        double M[ATT_NN];
        random_spd(P);
        random_factors(d1, d2);
        predict_scale(P, d1, d2, var, M);
        load_gen(&c, P);
        TEST_ASSERT_EQUAL_INT(EKF_OK, refcov_predict(P, d1, d2, var, ir));
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_cov_predict(&c, d1, d2, var, ig));
        e = predict_error(&c, P, M);
        worst = (e > worst) ? e : worst;
        for (i = 0; i < 3; ++i) {
            /* relative to the angle's own variance after the step (what it is added to) */
            const double d = fabs(ekf_to_double(ig[i]) - ekf_to_double(ir[i])) /
                             ekf_to_double(P[(ATT_PHI + i) * ATT_N + ATT_PHI + i]);
            worst_inc = (d > worst_inc) ? d : worst_inc;
            TEST_ASSERT_TRUE(ig[i] >= EKF_C(0));
        }
    }
    printf("prediction: max |gen - ref| / (|F| |P| |F|^T + |G| var |G|^T) = %.2f eps, increment variances %.2f eps of P_ii\n",
           worst / ekf_to_double(EKF_SCALAR_EPS), worst_inc / ekf_to_double(EKF_SCALAR_EPS));
    TEST_ASSERT_TRUE(worst <= tol);
    TEST_ASSERT_TRUE(worst_inc <= tol);
}

static void test_predict_refuses_non_finite_jacobian(void)
{
    ekf_scalar_t P[ATT_NN], d1[ATT_GEN_F1_NNZ], d2[ATT_GEN_F2_NNZ], inc[3] = {EKF_C(7), EKF_C(7), EKF_C(7)};
    const ekf_scalar_t var[3] = {EKF_C(1e-4), EKF_C(1e-4), EKF_C(1e-4)};
    int k;
    ts_rng_seed(&g_rng, 14);
    random_spd(P);
    for (k = 0; k < ATT_GEN_F1_NNZ + ATT_GEN_F2_NNZ; ++k) {
        att_cov_t c;
        ekf_scalar_t *slot;
        random_factors(d1, d2);
        slot = (k < ATT_GEN_F1_NNZ) ? &d1[k] : &d2[k - ATT_GEN_F1_NNZ];
        if (k >= ATT_GEN_F1_NNZ && (*slot == EKF_C(1) || *slot == EKF_C(-1))) {
            continue; /* a structural constant of F2: an implementation may not read it */
        }
        *slot = ekf_from_double((k % 2) ? (double)INFINITY : (double)NAN);
        load_gen(&c, P);
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, att_cov_predict(&c, d1, d2, var, inc));
        expect_same_matrix(&c, P, "refused prediction");
        TEST_ASSERT_TRUE(inc[0] == EKF_C(7) && inc[1] == EKF_C(7) && inc[2] == EKF_C(7));
        {
            ekf_scalar_t Pr[ATT_NN];
            memcpy(Pr, P, sizeof Pr);
            TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, refcov_predict(Pr, d1, d2, var, inc));
            TEST_ASSERT_EQUAL_MEMORY(P, Pr, sizeof P);
        }
    }
}

static void test_bounds_and_remaps_bit_identical(void)
{
    int trial;
    ts_rng_seed(&g_rng, 15);
    for (trial = 0; trial < TRIALS; ++trial) {
        ekf_scalar_t P[ATT_NN], g[9], var[3], vd[ATT_N];
        att_cov_t c;
        const int i = (int)(ts_uniform(&g_rng) * ATT_N);
        const ekf_scalar_t v = ekf_from_double(pow(10.0, ts_uniform_in(&g_rng, -6.0, 1.0)));
        int k;
        random_spd(P);
        for (k = 0; k < 9; ++k) {
            g[k] = ekf_from_double(ts_uniform_in(&g_rng, -3.0, 3.0));
        }
        for (k = 0; k < 3; ++k) {
            var[k] = ekf_from_double(pow(10.0, ts_uniform_in(&g_rng, -6.0, 0.0)));
        }
        load_gen(&c, P);
        refcov_add_rate_noise(P, g, var);
        att_cov_add_rate_noise(&c, g, var);
        expect_same_matrix(&c, P, "add_rate_noise");
        refcov_add_diag(P, ATT_PHI, 3, v);
        att_cov_add_diag(&c, ATT_PHI, 3, v);
        refcov_add_var(P, i, v);
        att_cov_add_var(&c, i, v);
        refcov_scale_diag(P, ATT_PHID, 3, EKF_C(1e-3));
        att_cov_scale_diag(&c, ATT_PHID, 3, EKF_C(1e-3));
        expect_same_matrix(&c, P, "diagonal noise");
        TEST_ASSERT_EQUAL_INT(refcov_limit_variance(P, i, v), att_cov_limit_variance(&c, i, v));
        expect_same_matrix(&c, P, "limit_variance");
        refcov_negate_state(P, i);
        att_cov_negate_state(&c, i);
        expect_same_matrix(&c, P, "negate_state");
        /* a variance pushed below the floor by rounding size and one far below zero */
        P[i * ATT_N + i] = ekf_from_double((trial % 2) ? -1e-9 * ekf_to_double(P[i * ATT_N + i]) : -1.0);
        load_gen(&c, P);
        TEST_ASSERT_EQUAL_INT(refcov_floor_diag(P, EKF_C(1e-6)), att_cov_floor_diag(&c, EKF_C(1e-6)));
        expect_same_matrix(&c, P, "floor_diag");
        refcov_reset_state(P, i, v);
        att_cov_reset_state(&c, i, v);
        expect_same_matrix(&c, P, "reset_state");
        TEST_ASSERT_TRUE(att_cov_var(&c, i) == v && att_cov_get(&c, i, (i + 1) % ATT_N) == EKF_C(0));
        for (k = 0; k < ATT_N; ++k) {
            vd[k] = v;
        }
        refcov_set_diag(P, vd);
        att_cov_set_diag(&c, vd);
        expect_same_matrix(&c, P, "set_diag");
    }
}

static void test_guard_same_outcome(void)
{
    const ekf_scalar_t floor = att_default_settings.var_floor;
    int trial, outcomes[3] = {0, 0, 0};
    ts_rng_seed(&g_rng, 16);
    for (trial = 0; trial < TRIALS; ++trial) {
        ekf_scalar_t P[ATT_NN], Pr[ATT_NN];
        att_cov_t c;
        int rr, rg, k;
        random_spd(P);
        if (trial % 3 == 1) {
            /* indefinite: minus 1.5 times a rank-one part along a random direction */
            double u[ATT_N], n2 = 0.0;
            for (k = 0; k < ATT_N; ++k) {
                u[k] = ts_uniform_in(&g_rng, -1.0, 1.0) * sqrt(ekf_to_double(P[k * ATT_N + k]));
                n2 += u[k] * u[k];
            }
            for (k = 0; k < ATT_NN; ++k) {
                P[k] = ekf_sub(P[k], ekf_from_double(0.5 * u[k / ATT_N] * u[k % ATT_N] / n2 *
                                                     ekf_to_double(P[(k / ATT_N) * ATT_N + k / ATT_N])));
            }
            for (k = 0; k < ATT_N; ++k) {
                P[k * ATT_N + k] = ekf_mul(P[k * ATT_N + k], EKF_C(0.2));
            }
        } else if (trial % 3 == 2) {
            P[(trial % ATT_N) * ATT_N + (trial + 1) % ATT_N] = ekf_from_double((double)INFINITY);
            P[((trial + 1) % ATT_N) * ATT_N + trial % ATT_N] = ekf_from_double((double)INFINITY);
        }
        memcpy(Pr, P, sizeof Pr);
        load_gen(&c, P);
        rr = refcov_guard(Pr, ATT_PD_MARGIN, floor);
        rg = att_cov_guard(&c, ATT_PD_MARGIN, floor);
        TEST_ASSERT_EQUAL_INT(rr < 0 ? -1 : (rr > 0), rg < 0 ? -1 : (rg > 0));
        ++outcomes[rg < 0 ? 2 : (rg > 0)];
        if (rg >= 0) {
            ekf_scalar_t Pg[ATT_NN];
            att_cov_to_full(&c, Pg);
            TEST_ASSERT_TRUE(att_cov_is_pd(&c, ATT_PD_MARGIN));
            TEST_ASSERT_TRUE(refcov_is_pd(Pg, ATT_PD_MARGIN));
            for (k = 0; k < ATT_N; ++k) {
                TEST_ASSERT_TRUE(Pg[k * ATT_N + k] >= floor);
            }
        }
    }
    printf("guard: %d passed, %d repaired, %d refused\n", outcomes[0], outcomes[1], outcomes[2]);
    TEST_ASSERT_TRUE(outcomes[0] > 0 && outcomes[1] > 0 && outcomes[2] > 0);
}

/* The filter's own covariance along the benchmark recording: each step's P through every
 * update (bit for bit) and the prediction (within rounding). */
static void test_filter_covariances(void)
{
    static const double still[3] = {0.0, 0.0, 0.0};
    static att_ekf_t f;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    double worst = 0.0;
    int k;
    ts_rng_seed(&g_rng, 17);
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, TS_BENCH_SEED, TS_BENCH_PHI, TS_BENCH_THETA, TS_BENCH_PSI);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &att_default_settings));
    for (k = 0; k < 600; ++k) {
        const int aligned = (att_flags(&f) & ATT_FLAG_ALIGNED) != 0u;
        double w[3];
        att_sample_t smp;
        ts_bench_motion(sim.t, w);
        ts_sim_step(&sim, aligned ? w : still, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
        if (aligned && k % 5 == 0) {
            ekf_scalar_t P[ATT_NN], x[ATT_N], d1[ATT_GEN_F1_NNZ], d2[ATT_GEN_F2_NNZ], xn[ATT_N], ir[3], ig[3];
            const ekf_scalar_t var[3] = {EKF_C(1e-3), EKF_C(1e-3), EKF_C(1e-3)};
            att_motion_t mo;
            att_cov_t c;
            double e;
            att_get_covariance(&f, P);
            memcpy(x, att_state(&f), sizeof x);
            compare_updates(P, x, EKF_C(0.01), EKF_C(1e-4), EKF_C(3), EKF_C(-0.3), EKF_C(0.8), NULL);
            att_model_transition(x, NULL, smp.dt, att_default_settings.gimbal_limit, xn, &mo);
            att_gen_transition_factors(&mo.t0, &mo.t, x, mo.rot, mo.jd, d1, d2);
            double M[ATT_NN];
            predict_scale(P, d1, d2, var, M);
            load_gen(&c, P);
            TEST_ASSERT_EQUAL_INT(EKF_OK, att_cov_predict(&c, d1, d2, var, ig));
            TEST_ASSERT_EQUAL_INT(EKF_OK, refcov_predict(P, d1, d2, var, ir));
            e = predict_error(&c, P, M);
            worst = (e > worst) ? e : worst;
        }
    }
    printf("filter covariances: prediction max |gen - ref| / (|F| |P| |F|^T + |G| var |G|^T) = %.2f eps\n",
           worst / ekf_to_double(EKF_SCALAR_EPS));
    TEST_ASSERT_TRUE(worst <= 16.0 * ekf_to_double(EKF_SCALAR_EPS));
}

/* A value the filter keeps is a normal number or zero, never subnormal. */
static int is_subnormal(ekf_scalar_t v)
{
    const double d = fabs(ekf_to_double(v));
#if defined(EKF_SCALAR_FLOAT)
    return d > 0.0 && d < 1.17549435e-38;
#else
    return d > 0.0 && d < 2.2250738585072014e-308;
#endif
}

/* A rotation, then a long rest with a gyroscope that reads exactly zero (a noise-free or
 * quantised sensor): the low-pass filters of the rest detector and the offset decay to
 * exactly zero, not to a subnormal number on which every later operation would take an x86
 * FPU's slow path (docs/performance.md, "Subnormal numbers"). */
static void test_rest_with_exact_zero_gyro_keeps_no_subnormal(void)
{
    static const double spin[3] = {0.5, -0.3, 0.4}, zero[3] = {0.0, 0.0, 0.0};
    static att_ekf_t f;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    int k, i, found = 0;
    ts_sim_default(&cfg);
    cfg.gyro_noise = 0.0;
    cfg.gyro_bias[0] = cfg.gyro_bias[1] = cfg.gyro_bias[2] = 0.0;
    ts_sim_init(&sim, &cfg, 5, 0.0, 0.0, 0.0);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &att_default_settings));
    for (k = 0; k < 12000; ++k) { /* (the old detector's low-pass was subnormal from step 5,150 on) */
        att_sample_t smp;
        ts_sim_step(&sim, (k > 300 && k < 800) ? spin : zero, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
        if (k > 8000) {
            const att_vars_t *v = &f.vars;
            ekf_scalar_t P[ATT_NN];
            att_get_covariance(&f, P);
            for (i = 0; i < ATT_NN; ++i) {
                found |= is_subnormal(P[i]);
            }
            for (i = 0; i < ATT_N; ++i) {
                found |= is_subnormal(v->x[i]);
            }
            for (i = 0; i < 3; ++i) {
                found |= is_subnormal(v->rest.gyro_lp[i]) | is_subnormal(v->rest.acc_lp[i]) |
                         is_subnormal(v->rest.bias[i]) | is_subnormal(v->accel_lp[i]);
            }
            found |= is_subnormal(v->accel_dev_var);
        }
    }
    TEST_ASSERT_FALSE_MESSAGE(found, "a subnormal value in the filter at rest");
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_updates_bit_identical);
    RUN_TEST(test_update_refusals_identical);
    RUN_TEST(test_predict_matches_reference);
    RUN_TEST(test_predict_refuses_non_finite_jacobian);
    RUN_TEST(test_bounds_and_remaps_bit_identical);
    RUN_TEST(test_guard_same_outcome);
    RUN_TEST(test_filter_covariances);
    RUN_TEST(test_rest_with_exact_zero_gyro_keeps_no_subnormal);
    return UNITY_END();
}
