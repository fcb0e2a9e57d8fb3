/*
 * test_att_cov_fx.c - the fixed-point covariance's words (att_cov_fx_words.c, att_cov_fx.c,
 * att_cov_fx_kernels.c) on every word the format allows, saturated ones included:
 *   - the definiteness test (att_cov_is_pd) against a Cholesky in long double of the exact
 *     matrix the words stand for, on random positive definite words near singularity, the same
 *     with a row saturated at +-INT32_MAX (correlations up to 4), and random words: the same
 *     answer wherever the exact pivots are not within 1e-6 of the margin (no negative pivot
 *     that looks positive);
 *   - every operation on random words and exponents (updates, prediction, noise, limits,
 *     remaps, guard): no word INT32_MIN (a negation stays defined), exponents within range;
 *     under the sanitizer build (scripts/test_sanitizers.sh) no undefined behaviour either;
 *   - an update on words far from positive semi-definite: its rank-one term saturated, not
 *     wrapped around;
 *   - a variance whose floor does not fit its state's scale (docs/reliability.md, Finding 12):
 *     floored to the floor by the update, not written as a saturated word below it;
 *   - the largest finite variance added to or scaled: an overflow (infinite), refused by the
 *     guard, no undefined behaviour.
 * Fixed-point build only.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "att_cov_fx_words.h"
#include "att_state.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static ts_rng_t g_rng;

/* The exact value of P - tau I in units of the words' scales (all exponents 0 here):
 * C_ij 2^-29, tau_i = 1 word (8 LSB of Q29.34 rounded up to the words of scale 1). */
static long double word(const att_cov_t *c, int i, int j)
{
    return (long double)c->c[att_fx_ix[i][j]] / (long double)(1u << ATT_FX_CF) -
           ((i == j) ? 1.0L / (long double)(1u << ATT_FX_CF) : 0.0L);
}

/* The smallest (pivot - rel (C_jj - tau_j)) / C_jj of the exact LDL^T, in long double; a
 * non-positive diagonal or pivot gives a negative value. */
static long double exact_slack(const att_cov_t *c, long double rel)
{
    long double L[ATT_N][ATT_N], d[ATT_N], worst = 1.0L;
    int i, j, k;
    for (j = 0; j < ATT_N; ++j) {
        long double v = word(c, j, j);
        if (!(v > 0.0L)) {
            return -1.0L;
        }
        for (k = 0; k < j; ++k) {
            v -= L[j][k] * L[j][k] * d[k];
        }
        {
            const long double s = (v - rel * word(c, j, j)) / word(c, j, j);
            worst = (s < worst) ? s : worst;
        }
        if (!(v > 0.0L)) {
            return (worst < 0.0L) ? worst : -1e-30L;
        }
        d[j] = v;
        for (i = j + 1; i < ATT_N; ++i) {
            long double w = word(c, i, j);
            for (k = 0; k < j; ++k) {
                w -= L[i][k] * L[j][k] * d[k];
            }
            L[i][j] = w / v;
        }
    }
    return worst;
}

static int32_t random_word(void)
{
    const double u = ts_uniform(&g_rng);
    if (u < 0.1) {
        return (ts_uniform(&g_rng) < 0.5) ? INT32_MAX : -INT32_MAX;
    }
    return (int32_t)ts_uniform_in(&g_rng, -2147483647.0, 2147483647.0);
}

/* Words of a random positive definite C = A A^T + tiny I normalised to [1, 2) on the diagonal
 * (correlations up to 1 - 1e-9), exponents 0. */
static void random_pd_words(att_cov_t *c)
{
    double A[ATT_N][ATT_N], C[ATT_N][ATT_N];
    const int rank = 1 + (int)(ts_uniform(&g_rng) * ATT_N);
    int i, j, k;
    for (i = 0; i < ATT_N; ++i) {
        for (k = 0; k < ATT_N; ++k) {
            A[i][k] = (k < rank) ? ts_uniform_in(&g_rng, -1.0, 1.0) : 0.0;
        }
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < ATT_N; ++j) {
            C[i][j] = (i == j) ? pow(10.0, ts_uniform_in(&g_rng, -9.0, -1.0)) : 0.0;
            for (k = 0; k < ATT_N; ++k) {
                C[i][j] += A[i][k] * A[j][k];
            }
        }
    }
    memset(c, 0, sizeof *c);
    for (i = 0; i < ATT_N; ++i) {
        for (j = i; j < ATT_N; ++j) {
            const double r = C[i][j] / sqrt(C[i][i] * C[j][j]);
            c->c[att_fx_ix[i][j]] = (int32_t)lround(r * 1.5 * (double)(1 << ATT_FX_CF));
        }
    }
}

static void check_is_pd(const att_cov_t *c, int *agreed, int *near)
{
    const ekf_scalar_t rel = ATT_PD_MARGIN;
    const long double slack = exact_slack(c, (long double)ekf_to_double(rel));
    const int got = att_cov_is_pd(c, rel);
    if (fabsl(slack) < 1e-6L) {
        ++*near; /* within the words' rounding of the margin: either answer */
        return;
    }
    if (got != (slack > 0.0L)) {
        printf("att_cov_is_pd %d, exact slack %Lg\n", got, slack);
    }
    TEST_ASSERT_EQUAL_INT(slack > 0.0L, got);
    ++*agreed;
}

static void test_definiteness_exact_on_any_words(void)
{
    int trial, agreed = 0, near = 0, pd = 0;
    ts_rng_seed(&g_rng, 41);
    for (trial = 0; trial < 30000; ++trial) {
        att_cov_t c;
        int i, j;
        random_pd_words(&c);
        if (trial % 3 == 1) { /* one row (its diagonal too) saturated: correlations up to 4 */
            const int r = (int)(ts_uniform(&g_rng) * ATT_N);
            for (j = 0; j < ATT_N; ++j) {
                c.c[att_fx_ix[r][j]] = (ts_uniform(&g_rng) < 0.5) ? INT32_MAX : -INT32_MAX;
            }
            c.c[att_fx_dg[r]] = INT32_MAX;
        } else if (trial % 3 == 2) { /* any words */
            for (i = 0; i < ATT_FX_NP; ++i) {
                c.c[i] = random_word();
            }
            for (i = 0; i < ATT_N; ++i) { /* a positive diagonal, so the factorisation runs on */
                c.c[att_fx_dg[i]] = (c.c[att_fx_dg[i]] == -INT32_MAX) ? INT32_MAX : (c.c[att_fx_dg[i]] < 0 ? -c.c[att_fx_dg[i]] : c.c[att_fx_dg[i]]);
            }
        }
        check_is_pd(&c, &agreed, &near);
        pd += att_cov_is_pd(&c, ATT_PD_MARGIN);
    }
    printf("definiteness: %d agreed with the exact pivots (%d positive definite), %d within 1e-6 of the margin\n", agreed,
           pd, near);
    TEST_ASSERT_TRUE(pd > 1000 && agreed > 25000);
}

/* Random words and exponents through every operation: no INT32_MIN word, exponents within
 * their range; the sanitizer build checks that nothing overflows on the way. */
static void random_cov(att_cov_t *c)
{
    int i;
    for (i = 0; i < ATT_FX_NP; ++i) {
        c->c[i] = random_word();
    }
    for (i = 0; i < ATT_N; ++i) {
        c->e[i] = (int8_t)(ATT_FX_E_MIN + (int)(ts_uniform(&g_rng) * (ATT_FX_E_MAX - ATT_FX_E_MIN + 1)));
    }
    c->spare = 0u;
    c->inf = 0u;
}

static ekf_scalar_t random_value(double lo_exp, double hi_exp)
{
    const double v = pow(10.0, ts_uniform_in(&g_rng, lo_exp, hi_exp));
    return ekf_from_double((ts_uniform(&g_rng) < 0.5) ? -v : v);
}

static void expect_words_defined(const att_cov_t *c)
{
    int i;
    for (i = 0; i < ATT_FX_NP; ++i) {
        TEST_ASSERT_TRUE(c->c[i] != INT32_MIN);
    }
    for (i = 0; i < ATT_N; ++i) {
        TEST_ASSERT_TRUE(c->e[i] >= ATT_FX_E_MIN && c->e[i] <= ATT_FX_E_MAX);
    }
}

static void test_every_operation_on_any_words(void)
{
    int trial;
    ts_rng_seed(&g_rng, 42);
    for (trial = 0; trial < 20000; ++trial) {
        att_cov_t c;
        ekf_scalar_t x[ATT_N], d1[ATT_GEN_F1_NNZ], d2[ATT_GEN_F2_NNZ], var[3], inc[3], g[9], h[3];
        const ekf_scalar_t floor = ekf_from_double(pow(10.0, ts_uniform_in(&g_rng, -9.0, -2.0)));
        const int i = (int)(ts_uniform(&g_rng) * ATT_N);
        int k;
        random_cov(&c);
        for (k = 0; k < ATT_N; ++k) {
            x[k] = random_value(-3.0, 3.0);
        }
        for (k = 0; k < ATT_GEN_F1_NNZ; ++k) {
            d1[k] = random_value(-6.0, 5.0);
        }
        for (k = 0; k < ATT_GEN_F2_NNZ; ++k) {
            d2[k] = random_value(-6.0, 5.0);
        }
        for (k = 0; k < 3; ++k) {
            var[k] = ekf_abs(random_value(-9.0, 8.0));
            h[k] = (ts_uniform(&g_rng) < 0.3) ? EKF_C(0) : random_value(-3.0, 3.0);
        }
        for (k = 0; k < 9; ++k) {
            g[k] = random_value(-3.0, 3.0);
        }
        switch (trial % 8) {
        case 0: (void)att_cov_update_unit(&c, x, i, random_value(-3.0, 2.0), ekf_abs(random_value(-9.0, 6.0)), EKF_C(0), floor, NULL); break;
        case 1: (void)att_cov_update_angles(&c, x, h, random_value(-3.0, 2.0), ekf_abs(random_value(-9.0, 6.0)), EKF_C(0), floor, NULL); break;
        case 2: (void)att_cov_predict(&c, d1, d2, var, inc); break;
        case 3: att_cov_add_rate_noise(&c, g, var); break;
        case 4:
            att_cov_add_var(&c, i, ekf_abs(random_value(-12.0, 8.5)));
            att_cov_scale_diag(&c, 0, ATT_N, ekf_abs(random_value(-6.0, 1.0)));
            break;
        case 5: (void)att_cov_limit_variance(&c, i, ekf_abs(random_value(-6.0, 6.0))); break;
        case 6: (void)att_cov_floor_diag(&c, floor); break;
        default: (void)att_cov_guard(&c, ATT_PD_MARGIN, floor); break;
        }
        expect_words_defined(&c);
        att_cov_negate_state(&c, i);
        expect_words_defined(&c);
    }
}

/* Words that pass the update's checks (every new variance about 0) but are far from positive
 * semi-definite: row k and the diagonal at +INT32_MAX (4), every other entry -INT32_MAX. The
 * rank-one term T_i v_j is then about +4 and C_ij - T_i v_j about -8: saturated to
 * -INT32_MAX, not wrapped around to a positive word. */
static void test_update_saturates_the_rank_one_term(void)
{
    const int k = ATT_R;
    ekf_scalar_t x[ATT_N] = {0};
    att_cov_t c;
    int i, j;
    memset(&c, 0, sizeof c);
    for (i = 0; i < ATT_N; ++i) {
        for (j = i; j < ATT_N; ++j) {
            c.c[att_fx_ix[i][j]] = (i == j || i == k || j == k) ? INT32_MAX : -INT32_MAX;
        }
    }
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_cov_update_unit(&c, x, k, EKF_C(0.01), EKF_C(1e-6), EKF_C(0), EKF_C(1e-9), NULL));
    for (i = 0; i < ATT_N; ++i) {
        for (j = i + 1; j < ATT_N; ++j) {
            if (i != k && j != k) {
                TEST_ASSERT_EQUAL_INT32(-INT32_MAX, c.c[att_fx_ix[i][j]]);
            }
        }
    }
}

/* A tiny variance (scale 2^-40 .. 2^-30) whose floor does not fit a word of its scale: the
 * update's floor sets it to the floor, in the floor's own scale. */
static void test_update_floors_a_variance_below_a_floor_it_cannot_hold(void)
{
    const ekf_scalar_t floor = EKF_C(6.5e-5);
    int e;
    for (e = ATT_FX_E_MIN; e <= -12; ++e) {
        ekf_scalar_t var[ATT_N], x[ATT_N] = {0};
        att_cov_t c;
        int i;
        for (i = 0; i < ATT_N; ++i) {
            var[i] = EKF_C(1);
        }
        att_cov_set_diag(&c, var);
        /* the heading's variance a saturated word at exponent e, far below the floor */
        att_fx_set_exp(&c, ATT_PSI, e);
        c.c[att_fx_dg[ATT_PSI]] = INT32_MAX;
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_cov_update_unit(&c, x, ATT_P, EKF_C(0.01), EKF_C(0.1), EKF_C(0), floor, NULL));
        TEST_ASSERT_TRUE(att_cov_var(&c, ATT_PSI) >= floor);
        TEST_ASSERT_TRUE(att_cov_var(&c, ATT_PSI) <= ekf_mul(floor, EKF_C(1.000001)));
        TEST_ASSERT_TRUE(c.c[att_fx_dg[ATT_PSI]] < INT32_MAX);
    }
}

/* The largest finite variance (Q29.34) added to a variance, and a variance beyond the scalar's
 * range scaled: an overflow of the covariance (infinite), which the guard refuses. */
static void test_largest_variance_overflows_cleanly(void)
{
    ekf_scalar_t var[ATT_N];
    att_cov_t c;
    int i;
    for (i = 0; i < ATT_N; ++i) {
        var[i] = EKF_C(1);
    }
    att_cov_set_diag(&c, var);
    att_cov_add_var(&c, ATT_PHID, EKF_FX_INF - 1);
    TEST_ASSERT_EQUAL_INT(-1, att_cov_guard(&c, ATT_PD_MARGIN, EKF_C(1e-9)));
    att_cov_set_diag(&c, var);
    att_fx_set_exp(&c, ATT_PHID, ATT_FX_E_MAX); /* 2^48 = 2.8e14, beyond Q29.34 */
    c.c[att_fx_dg[ATT_PHID]] = INT32_MAX;
    att_cov_scale_diag(&c, ATT_PHID, 1, EKF_C(1));
    TEST_ASSERT_EQUAL_INT(-1, att_cov_guard(&c, ATT_PD_MARGIN, EKF_C(1e-9)));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_definiteness_exact_on_any_words);
    RUN_TEST(test_every_operation_on_any_words);
    RUN_TEST(test_update_saturates_the_rank_one_term);
    RUN_TEST(test_update_floors_a_variance_below_a_floor_it_cannot_hold);
    RUN_TEST(test_largest_variance_overflows_cleanly);
    return UNITY_END();
}
