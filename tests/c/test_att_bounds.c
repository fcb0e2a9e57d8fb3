/*
 * test_att_bounds.c - every setting's accepted bounds are ones where the filter works: each
 * setting at its lower and at its upper bound (att_setting_info, from
 * att_settings_table.h), one at a time, the others at their defaults, through the random
 * stress input (ts_stress_sample, the distribution of test_att_stress.c).
 *
 * After every step: the state finite; once aligned, P exactly symmetric and positive
 * definite (Cholesky in double), every variance at least var_floor, the angles in their
 * ranges. Per bound: the calls refused as numeric failures (diag.numeric) and the guard's
 * repairs (diag.cov_repairs) at most MAX_EVENTS, about three times the largest count
 * measured at any bound (docs/reliability.md, "Settings at their bounds"). A bound that the
 * settings check refuses with the other settings at their defaults (one that only makes
 * sense together with another setting, such as a gravity above the default accelerometer
 * range, or one the fixed-point build cannot represent) is run at the accepted value
 * closest to it. A bound at which the stress input cannot align the filter (align_samples
 * 65535) is aligned by att_align after a tenth of the steps.
 *
 *     test_att_bounds_x [--steps N] [--seed S] [--report] [--only NAME [--lo V] [--hi V]]
 * --steps: steps per bound (default STEPS); --report prints one line per bound (the figures
 * of docs/reliability.md come from --steps 100000 --report); --only runs one setting's bounds,
 * --lo / --hi replace them (to try a bound before it goes into the table).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "att.h"
#include "testsim.h"
#include "unity.h"

/* Steps per bound in the ctest: about 90 bounds per build in well under a minute (a
 * fixed-point step costs about four float ones). docs/reliability.md records 10^5 per bound
 * (--steps 100000). */
#if defined(EKF_SCALAR_FIXED)
#define STEPS 10000L
#else
#define STEPS 30000L
#endif

/* Numeric refusals and guard repairs allowed per bound, in up to 10^5 steps: about three
 * times the most measured at any bound (1, in fixed point; docs/reliability.md, "Settings at
 * their bounds"). */
#define MAX_EVENTS 3L

static long g_steps = STEPS;
static uint64_t g_seed = 20261123u;
static int g_report;
static const char *g_only;             /* --only NAME: that setting's bounds alone */
static double g_lo = NAN, g_hi = NAN;  /* --lo V, --hi V: other values for them */

void setUp(void) {}
void tearDown(void) {}

typedef struct {
    long numeric, repairs, aligned_steps;
    double min_pivot;
    char failure[160]; /* the first broken invariant, empty if none */
} run_t;

static int angles_in_range(const ekf_scalar_t *x)
{
    return x[ATT_PHI] >= ekf_neg(EKF_PI) && x[ATT_PHI] < EKF_PI && x[ATT_PSI] >= ekf_neg(EKF_PI) && x[ATT_PSI] < EKF_PI &&
           x[ATT_THETA] >= ekf_neg(EKF_HALF_PI) && x[ATT_THETA] <= EKF_HALF_PI;
}

/* The stress input through a filter with settings s; stops at the first broken invariant. */
static void run_stress(const att_settings_t *s, long steps, run_t *out)
{
    static att_ekf_t f;
    ts_rng_t r;
    long k;
    memset(out, 0, sizeof *out);
    out->min_pivot = HUGE_VAL;
    ts_rng_seed(&r, g_seed);
    if (att_init(&f, s) != EKF_OK) {
        snprintf(out->failure, sizeof out->failure, "att_init refused settings the check accepted");
        return;
    }
    for (k = 0; k < steps; ++k) {
        att_sample_t smp;
        ekf_scalar_t P[ATT_N * ATT_N];
        double pivot;
        int i;
        ts_stress_sample(&r, s, &smp);
        if (k == steps / 10 && (att_flags(&f) & ATT_FLAG_ALIGNED) == 0u) {
            /* not aligned yet (align_samples 65535: random directions average to no gravity
             * direction): aligned from one sample at rest, so that the bound is tested too */
            const ekf_scalar_t g[3] = {EKF_C(0), EKF_C(0), s->gravity}, m[3] = {EKF_C(20), EKF_C(0), EKF_C(-40)};
            if (att_align(&f, g, m) != EKF_OK) {
                snprintf(out->failure, sizeof out->failure, "att_align refused");
                break;
            }
        }
        (void)att_step(&f, &smp, NULL);
        if (!ekf_all_finite(att_state(&f), ATT_N)) {
            snprintf(out->failure, sizeof out->failure, "step %ld: state not finite", k);
            break;
        }
        if ((att_flags(&f) & ATT_FLAG_ALIGNED) == 0u) {
            continue;
        }
        ++out->aligned_steps;
        att_get_covariance(&f, P);
        if (!ts_is_symmetric_exact(P, ATT_N) || !ts_is_positive_definite(P, ATT_N, &pivot)) {
            snprintf(out->failure, sizeof out->failure, "step %ld: P not symmetric positive definite", k);
            break;
        }
        out->min_pivot = (pivot < out->min_pivot) ? pivot : out->min_pivot;
        for (i = 0; i < ATT_N; ++i) {
            if (!(P[i * ATT_N + i] >= s->var_floor)) {
                snprintf(out->failure, sizeof out->failure, "step %ld: P[%d][%d] = %g below var_floor", k, i, i,
                         ekf_to_double(P[i * ATT_N + i]));
                break;
            }
        }
        if (out->failure[0] == '\0' && !angles_in_range(att_state(&f))) {
            snprintf(out->failure, sizeof out->failure, "step %ld: angles out of range", k);
        }
        if (out->failure[0] != '\0') {
            break;
        }
    }
    out->numeric = (long)att_diag(&f)->numeric;
    out->repairs = (long)att_diag(&f)->cov_repairs;
}

static void test_every_bound_works(void)
{
    const long max_numeric = MAX_EVENTS, max_repairs = MAX_EVENTS;
    long worst_numeric = 0, worst_repairs = 0;
    int failures = 0, narrowed = 0;
    size_t i;
    for (i = 0; i < att_setting_count(); ++i) {
        const att_setting_info_t *info = att_setting_info(i);
        int hi;
        if (g_only != NULL && strcmp(g_only, info->name) != 0) {
            continue;
        }
        for (hi = 0; hi < 2; ++hi) {
            att_settings_t s = att_default_settings;
            const double other = hi ? g_hi : g_lo;
            ekf_scalar_t v;
            run_t run;
            if (!isnan(other)) {
                v = ekf_from_double(other);
                if (att_setting_set(&s, i, v) != EKF_OK || att_settings_check(&s) != EKF_OK) {
                    printf("%s = %g: refused by the settings check\n", info->name, other);
                    ++failures;
                    continue;
                }
            } else if (ts_setting_at_bound(&s, i, hi) != 0) {
                printf("%s: no value near its %s bound accepted\n", info->name, hi ? "upper" : "lower");
                ++failures;
                continue;
            }
            TEST_ASSERT_EQUAL_INT(EKF_OK, att_setting_get(&s, i, &v));
            if (v != (hi ? info->hi : info->lo)) {
                ++narrowed;
            }
            run_stress(&s, g_steps, &run);
            if (g_report) {
                printf("%-22s %s %-12g numeric %6ld  repairs %4ld  aligned %6ld  min pivot %.2e%s%s\n", info->name,
                       hi ? "hi" : "lo", ekf_to_double(v), run.numeric, run.repairs, run.aligned_steps, run.min_pivot,
                       run.failure[0] ? "  FAILED: " : "", run.failure);
            }
            worst_numeric = (run.numeric > worst_numeric) ? run.numeric : worst_numeric;
            worst_repairs = (run.repairs > worst_repairs) ? run.repairs : worst_repairs;
            if (run.failure[0] != '\0' || run.numeric > max_numeric || run.repairs > max_repairs || run.aligned_steps == 0) {
                printf("%s = %g (%s bound): %s; numeric %ld (at most %ld), repairs %ld (at most %ld), aligned steps %ld\n",
                       info->name, ekf_to_double(v), hi ? "upper" : "lower", run.failure[0] ? run.failure : "counts",
                       run.numeric, max_numeric, run.repairs, max_repairs, run.aligned_steps);
                ++failures;
            }
        }
    }
    printf("%s: %zu settings, %d bounds refused with the defaults (run at the accepted value closest to them), %ld steps per bound; largest numeric %ld, repairs %ld\n",
           EKF_SCALAR_NAME, att_setting_count(), narrowed, g_steps, worst_numeric, worst_repairs);
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, failures, "a setting's bound where the filter does not work (above)");
}

int main(int argc, char **argv)
{
    int i;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--steps") == 0 && i + 1 < argc) {
            g_steps = atol(argv[++i]);
        } else if (strcmp(argv[i], "--seed") == 0 && i + 1 < argc) {
            g_seed = strtoull(argv[++i], NULL, 10);
        } else if (strcmp(argv[i], "--only") == 0 && i + 1 < argc) {
            g_only = argv[++i];
        } else if (strcmp(argv[i], "--lo") == 0 && i + 1 < argc) {
            g_lo = atof(argv[++i]);
        } else if (strcmp(argv[i], "--hi") == 0 && i + 1 < argc) {
            g_hi = atof(argv[++i]);
        } else if (strcmp(argv[i], "--report") == 0) {
            g_report = 1;
        } else {
            fprintf(stderr, "usage: %s [--steps N] [--seed S] [--report] [--only NAME [--lo V] [--hi V]]\n", argv[0]);
            return 2;
        }
    }
    UNITY_BEGIN();
    RUN_TEST(test_every_bound_works);
    return UNITY_END();
}
