/*
 * test_att_settings.c - the settings module (firmware/att/att_settings.c): the defaults, the
 * table by name (att_setting_info, _index, _get, _set), the check (att_settings_check) with
 * its scalar-aware square rules and the bounds between settings, the settings that cannot
 * change while the filter runs (att_settings_same_fixed_part, att_set_settings).
 *
 * The test expands the rows of att_settings_table.h with its own macros (offsetof of the
 * field, the literal default and bounds) and compares what att_settings.c built from the same
 * rows: a row expanded into the wrong field, default, bound or flag shows here.
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "att.h"
#include "att_fixture.h"
#include "att_settings.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

/* ---- the rows as the test reads them ---- */

enum { T_S = ATT_SETTING_SCALAR, T_U16 = ATT_SETTING_U16 };

typedef struct {
    const char *name;
    size_t offset;
    int type;
    double def, def_fixed, lo, hi;
    int live;
} row_t;

#define ROW(prefix, field, name, type, def, def_fixed, lo, hi, live) \
    {prefix #name, offsetof(att_settings_t, field), T_##type, def, def_fixed, lo, hi, live},
#define ROW_MAIN(name, type, def, def_fixed, lo, hi, check, live, unit, help) \
    ROW("", name, name, type, def, def_fixed, lo, hi, live)
#define ROW_REST(name, type, def, def_fixed, lo, hi, check, live, unit, help) \
    ROW("rest.", rest.name, name, type, def, def_fixed, lo, hi, live)
#define ROW_BIAS(name, type, def, def_fixed, lo, hi, check, live, unit, help) \
    ROW("bias.", bias.name, name, type, def, def_fixed, lo, hi, live)

static const row_t k_rows[] = {ATT_SETTINGS_MAIN(ROW_MAIN) ATT_SETTINGS_REST(ROW_REST) ATT_SETTINGS_BIAS(ROW_BIAS)};
#define N_ROWS ((int)(sizeof k_rows / sizeof k_rows[0]))

static double row_default(const row_t *r)
{
#if defined(EKF_SCALAR_FIXED)
    return r->def_fixed;
#else
    return r->def;
#endif
}

/* The value of row r in s, read through the test's own offset. */
static double field_value(const att_settings_t *s, const row_t *r)
{
    if (r->type == T_U16) {
        uint16_t v;
        memcpy(&v, (const char *)s + r->offset, sizeof v);
        return (double)v;
    } else {
        ekf_scalar_t v;
        memcpy(&v, (const char *)s + r->offset, sizeof v);
        return ekf_to_double(v);
    }
}

/* The rows as the library describes them: the same names, places, types, bounds and flags,
 * in the same order. */
static void test_table_matches_rows(void)
{
    int i, j;
    TEST_ASSERT_EQUAL_INT(N_ROWS, (int)att_setting_count());
    for (i = 0; i < N_ROWS; ++i) {
        const att_setting_info_t *in = att_setting_info((size_t)i);
        const row_t *r = &k_rows[i];
        TEST_ASSERT_NOT_NULL(in);
        TEST_ASSERT_EQUAL_STRING(r->name, in->name);
        TEST_ASSERT_EQUAL_UINT((unsigned)r->offset, in->offset);
        TEST_ASSERT_EQUAL_INT(r->type, in->type);
        TEST_ASSERT_EQUAL_INT(r->live, in->live);
        TEST_ASSERT_TRUE(in->lo == ekf_from_double(r->lo));
        TEST_ASSERT_TRUE(in->hi == ekf_from_double(r->hi));
        TEST_ASSERT_EQUAL_INT(i, att_setting_index(r->name));
        for (j = 0; j < i; ++j) {
            TEST_ASSERT_TRUE(k_rows[j].offset != r->offset);
        }
    }
    TEST_ASSERT_NULL(att_setting_info((size_t)N_ROWS));
}

/* att_default_settings holds each row's default (default_fixed in the fixed-point build),
 * and att_setting_get reads it. */
static void test_defaults_are_the_rows(void)
{
    int i;
    for (i = 0; i < N_ROWS; ++i) {
        const row_t *r = &k_rows[i];
        const double want = row_default(r);
        ekf_scalar_t got;
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_setting_get(&att_default_settings, (size_t)i, &got));
        AF_NEAR(want, field_value(&att_default_settings, r), af_ulp(want));
        AF_NEAR(want, ekf_to_double(got), af_ulp(want));
        TEST_ASSERT_TRUE(want >= r->lo && want <= r->hi);
    }
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_settings_check(&att_default_settings));
}

/* Names: the prefixes select the group ("accel_noise" and "rest.accel_noise" are two
 * settings); unknown, partial and NULL names are -1. */
static void test_index_by_name(void)
{
    const int main_noise = att_setting_index("accel_noise"), rest_noise = att_setting_index("rest.accel_noise");
    TEST_ASSERT_TRUE(main_noise >= 0 && rest_noise >= 0 && main_noise != rest_noise);
    TEST_ASSERT_EQUAL_UINT((unsigned)offsetof(att_settings_t, accel_noise),
                           att_setting_info((size_t)main_noise)->offset);
    TEST_ASSERT_EQUAL_UINT((unsigned)offsetof(att_settings_t, rest.accel_noise),
                           att_setting_info((size_t)rest_noise)->offset);
    TEST_ASSERT_EQUAL_INT(-1, att_setting_index("rest_gyro"));
    TEST_ASSERT_EQUAL_INT(-1, att_setting_index("rest."));
    TEST_ASSERT_EQUAL_INT(-1, att_setting_index("bias.walk "));
    TEST_ASSERT_EQUAL_INT(-1, att_setting_index(""));
    TEST_ASSERT_EQUAL_INT(-1, att_setting_index(NULL));
}

/* get and set: errors for NULL and an index beyond the table, with nothing written. */
static void test_get_set_errors(void)
{
    att_settings_t s = att_default_settings;
    ekf_scalar_t v = EKF_C(1);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_setting_get(NULL, 0, &v));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_setting_get(&s, 0, NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, att_setting_get(&s, (size_t)N_ROWS, &v));
    TEST_ASSERT_TRUE(v == EKF_C(1));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_setting_set(NULL, 0, EKF_C(1)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, att_setting_set(&s, (size_t)N_ROWS, EKF_C(1)));
    TEST_ASSERT_EQUAL_MEMORY(&att_default_settings, &s, sizeof s);
}

/* Each row: a value just outside its range is refused with the settings unchanged; its
 * bounds themselves are accepted where the build's scalar holds their squares as the row
 * requires (always in float and double), and then written to that row's field only. */
static void test_set_within_own_range_only(void)
{
    int i, j;
    for (i = 0; i < N_ROWS; ++i) {
        const row_t *r = &k_rows[i];
        const double below = (r->type == T_U16) ? r->lo - 1.0 : r->lo - (fabs(r->lo) * 1e-3 + 1e-3);
        const double above = (r->type == T_U16) ? r->hi + 1.0 : r->hi + (fabs(r->hi) * 1e-3 + 1e-3);
        const double ends[2] = {r->lo, r->hi};
        int e;
        att_settings_t s = att_default_settings;
        TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_setting_set(&s, (size_t)i, ekf_from_double(below)));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_setting_set(&s, (size_t)i, ekf_from_double(above)));
        TEST_ASSERT_EQUAL_MEMORY(&att_default_settings, &s, sizeof s);
        for (e = 0; e < 2; ++e) {
            const ekf_status_t st = att_setting_set(&s, (size_t)i, ekf_from_double(ends[e]));
#if defined(EKF_SCALAR_FIXED)
            if (st != EKF_OK) {
                TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, st);
                continue; /* the square rules are checked in test_square_rules */
            }
#endif
            TEST_ASSERT_EQUAL_INT(EKF_OK, st);
            AF_NEAR(ekf_to_double(ekf_from_double(ends[e])), field_value(&s, r), 0.0);
            for (j = 0; j < N_ROWS; ++j) {
                if (j != i) {
                    AF_NEAR(field_value(&att_default_settings, &k_rows[j]), field_value(&s, &k_rows[j]), 0.0);
                }
            }
            s = att_default_settings;
        }
    }
}

/* A count is a whole number; a scalar NaN or infinity is refused. */
static void test_counts_are_whole_numbers(void)
{
    att_settings_t s = att_default_settings;
    const size_t order = (size_t)att_setting_index("accel_lpf_order");
    const size_t n = (size_t)att_setting_index("align_samples");
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_setting_set(&s, order, EKF_C(1.5)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_setting_set(&s, n, EKF_C(20.25)));
    TEST_ASSERT_EQUAL_MEMORY(&att_default_settings, &s, sizeof s);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_setting_set(&s, order, EKF_C(1)));
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_setting_set(&s, n, EKF_C(65535)));
    TEST_ASSERT_EQUAL_UINT16(1u, s.accel_lpf_order);
    TEST_ASSERT_EQUAL_UINT16(65535u, s.align_samples);
#if !defined(EKF_SCALAR_FIXED)
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS,
                          att_setting_set(&s, (size_t)att_setting_index("rate_walk"), ekf_from_double((double)NAN)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS,
                          att_setting_set(&s, (size_t)att_setting_index("dt_max"), ekf_from_double((double)INFINITY)));
#endif
}

/* The check column: a noise whose variance rounds to zero in the build's scalar (POS2), a
 * gate whose square is not finite (FIN2), a ZPOS2 value that is neither 0 nor of positive
 * square. Float holds 1e-18 and 1e12; Q29.34 holds neither (LSB 5.8e-11, range 5.4e8). */
static void test_square_rules(void)
{
    struct {
        const char *name;
        double value;
        int ok_ieee, ok_fixed;
    } k_cases[] = {
        {"gyro_noise", 1e-9, 1, 0},    /* POS2 */
        {"gyro_noise", 1e-3, 1, 1},
        {"gyro_gate", 1e6, 1, 0},      /* FIN2 */
        {"gyro_gate", 1e3, 1, 1},
        {"angle_walk", 0.0, 1, 1},     /* ZPOS2: zero */
        {"angle_walk", 1e-6, 1, 0},    /* ZPOS2: square 1e-12 */
        {"gyro_range", 50.0, 1, 1},    /* ANY: no rule on the square */
    };
    size_t c;
    for (c = 0; c < sizeof k_cases / sizeof k_cases[0]; ++c) {
        att_settings_t s = att_default_settings;
        const int i = att_setting_index(k_cases[c].name);
#if defined(EKF_SCALAR_FIXED)
        const int ok = k_cases[c].ok_fixed;
#else
        const int ok = k_cases[c].ok_ieee;
#endif
        TEST_ASSERT_TRUE(i >= 0);
        TEST_ASSERT_EQUAL_INT(ok ? EKF_OK : EKF_ERR_SETTINGS,
                              att_setting_set(&s, (size_t)i, ekf_from_double(k_cases[c].value)));
        /* att_settings_check applies the same rule to a value written directly */
        memcpy((char *)&s + k_rows[i].offset, &(ekf_scalar_t){ekf_from_double(k_cases[c].value)},
               sizeof(ekf_scalar_t));
        if (strcmp(k_cases[c].name, "gyro_range") != 0) {
            TEST_ASSERT_EQUAL_INT(ok ? EKF_OK : EKF_ERR_SETTINGS, att_settings_check(&s));
        }
    }
}

/* The bounds between settings: each on its own refuses, equality passes. */
static void test_bounds_between_settings(void)
{
    att_settings_t s;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_settings_check(NULL));
    s = att_default_settings;
    s.accel_range = ekf_mul(s.gravity, EKF_C(0.99));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_settings_check(&s));
    s.accel_range = s.gravity;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_settings_check(&s));
    s = att_default_settings;
    s.heading_var_max = EKF_C(1e-4);
    s.var_floor = EKF_C(2e-4);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_settings_check(&s));
    s.var_floor = s.heading_var_max;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_settings_check(&s));
    s = att_default_settings;
    s.gyro_range = EKF_C(0.02);
    s.bias.sigma_init = EKF_C(0.01);
    s.rest.bias_max = EKF_C(0.03);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_settings_check(&s));
    s.rest.bias_max = s.gyro_range;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_settings_check(&s));
    s.bias.sigma_init = EKF_C(0.025);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_settings_check(&s));
#if defined(EKF_SCALAR_FIXED)
    /* the fixed-point guard's absolute margin is 8 LSB (4.7e-10): a floor must be twice it */
    s = att_default_settings;
    s.var_floor = EKF_C(5e-10);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_settings_check(&s));
    s.var_floor = EKF_C(1e-9);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_settings_check(&s));
#endif
}

/* A different accepted value for row i (not its default), written into *s. */
static void change_row(att_settings_t *s, int i)
{
    const row_t *r = &k_rows[i];
    const double def = field_value(&att_default_settings, r);
    const double tries[5] = {r->lo, r->hi, def * 0.5, (r->lo + r->hi) * 0.5, def + 1.0};
    int t;
    for (t = 0; t < 5; ++t) {
        if (tries[t] != def && att_setting_set(s, (size_t)i, ekf_from_double(tries[t])) == EKF_OK &&
            field_value(s, r) != def) {
            return;
        }
    }
    TEST_FAIL_MESSAGE(r->name);
}

/* att_settings_same_fixed_part tells the rows that need att_init (live 0) from the others;
 * att_set_settings takes a change of the latter into force and refuses the former. */
static void test_live_and_fixed_settings(void)
{
    int i, fixed_rows = 0;
    for (i = 0; i < N_ROWS; ++i) {
        att_settings_t s = att_default_settings;
        change_row(&s, i);
        TEST_ASSERT_EQUAL_INT(k_rows[i].live, att_settings_same_fixed_part(&att_default_settings, &s));
        fixed_rows += !k_rows[i].live;
    }
    TEST_ASSERT_TRUE(fixed_rows > 0);
    {
        static att_ekf_t f;
        static att_ekf_t before;
        att_settings_t s = att_default_settings;
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &att_default_settings));
        s.rate_walk = EKF_C(3.0);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_set_settings(&f, &s));
        TEST_ASSERT_EQUAL_MEMORY(&s, att_settings(&f), sizeof s);
        before = f;
        s.accel_lpf_order = 1u;
        TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_set_settings(&f, &s));
        s = *att_settings(&f);
        s.rate_walk = EKF_C(-1.0);
        TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_set_settings(&f, &s));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_set_settings(NULL, &s));
        TEST_ASSERT_EQUAL_MEMORY(&before, &f, sizeof f);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_table_matches_rows);
    RUN_TEST(test_defaults_are_the_rows);
    RUN_TEST(test_index_by_name);
    RUN_TEST(test_get_set_errors);
    RUN_TEST(test_set_within_own_range_only);
    RUN_TEST(test_counts_are_whole_numbers);
    RUN_TEST(test_square_rules);
    RUN_TEST(test_bounds_between_settings);
    RUN_TEST(test_live_and_fixed_settings);
    af_print_worst();
    return UNITY_END();
}
