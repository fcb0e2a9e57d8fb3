/*
 * att_settings.c - the default settings, the settings check and the settings by name
 * (att.h), all expanded from the rows of att_settings_table.h.
 */
#include "att.h"

#include <stddef.h>
#include <string.h>

#include "att_settings.h"
#include "ekf_util.h"

/* ---- defaults ---- */

#if defined(EKF_SCALAR_FIXED)
#define DEFAULT_S(def, def_fixed) EKF_C(def_fixed)
#define DEFAULT_U16(def, def_fixed) ((uint16_t)(def_fixed))
#else
#define DEFAULT_S(def, def_fixed) EKF_C(def)
#define DEFAULT_U16(def, def_fixed) ((uint16_t)(def))
#endif
#define DEFAULT_FIELD(name, type, def, def_fixed, lo, hi, check, live, unit, help) \
    .name = DEFAULT_##type(def, def_fixed),

const att_settings_t att_default_settings = {
    ATT_SETTINGS_MAIN(DEFAULT_FIELD)
    .rest = {ATT_SETTINGS_REST(DEFAULT_FIELD)},
    .bias = {ATT_SETTINGS_BIAS(DEFAULT_FIELD)},
};

/* ---- the table by name ---- */

/* What the square of a setting must be in the build's scalar (the check column). */
enum { CHECK_ANY, CHECK_FIN2, CHECK_POS2, CHECK_ZPOS2 };

/* prefix and unit are string literals pasted to #name, field a member designator (rest.x):
 * neither can take parentheses. */
#define INFO(prefix, field, name, type, lo, hi, check, live, unit)                                       \
    /* NOLINTNEXTLINE(bugprone-macro-parentheses) */                                                     \
    {prefix #name, unit, (uint16_t)offsetof(att_settings_t, field), (uint8_t)ATT_SETTING_##type##_TYPE, \
     (uint8_t)CHECK_##check, (uint8_t)(live), EKF_C(lo), EKF_C(hi)},
#define ATT_SETTING_S_TYPE ATT_SETTING_SCALAR
#define ATT_SETTING_U16_TYPE ATT_SETTING_U16
#define INFO_MAIN(name, type, def, def_fixed, lo, hi, check, live, unit, help) \
    INFO("", name, name, type, lo, hi, check, live, unit)
#define INFO_REST(name, type, def, def_fixed, lo, hi, check, live, unit, help) \
    INFO("rest.", rest.name, name, type, lo, hi, check, live, unit)
#define INFO_BIAS(name, type, def, def_fixed, lo, hi, check, live, unit, help) \
    INFO("bias.", bias.name, name, type, lo, hi, check, live, unit)

static const att_setting_info_t k_info[] = {
    ATT_SETTINGS_MAIN(INFO_MAIN) ATT_SETTINGS_REST(INFO_REST) ATT_SETTINGS_BIAS(INFO_BIAS)};

enum { N_SETTINGS = (int)(sizeof k_info / sizeof k_info[0]) };

size_t att_setting_count(void) { return (size_t)N_SETTINGS; }

const att_setting_info_t *att_setting_info(size_t i) { return (i < (size_t)N_SETTINGS) ? &k_info[i] : NULL; }

int att_setting_index(const char *name)
{
    int i;
    if (name == NULL) {
        return -1;
    }
    for (i = 0; i < N_SETTINGS; ++i) {
        if (strcmp(k_info[i].name, name) == 0) {
            return i;
        }
    }
    return -1;
}

static ekf_scalar_t *scalar_field(att_settings_t *s, const att_setting_info_t *r)
{
    return (ekf_scalar_t *)(void *)((char *)s + r->offset);
}

static const ekf_scalar_t *scalar_field_c(const att_settings_t *s, const att_setting_info_t *r)
{
    return (const ekf_scalar_t *)(const void *)((const char *)s + r->offset);
}

static uint16_t count_field(const att_settings_t *s, const att_setting_info_t *r)
{
    uint16_t v;
    memcpy(&v, (const char *)s + r->offset, sizeof v);
    return v;
}

/* The value of a row as a scalar (a count converted). */
static ekf_scalar_t value_of(const att_settings_t *s, const att_setting_info_t *r)
{
    return (r->type == ATT_SETTING_U16) ? ekf_from_int((int32_t)count_field(s, r)) : *scalar_field_c(s, r);
}

/* 1 if v is in the row's range and its square is what the row says. The variances derived
 * from the settings must be representable in the build's scalar: no noise variance that
 * rounds to zero (nothing would be fused, or a variance would be exact where it must not
 * be), no square that saturates. Every setting in range passes in float and double; the
 * fixed-point build refuses, for example, a gyro_noise of 1e-6 in Q29.34 (its square is
 * below one LSB). */
static int value_ok(const att_setting_info_t *r, ekf_scalar_t v)
{
    const ekf_scalar_t q = ekf_sq(v);
    if (!ekf_in_range(v, r->lo, r->hi)) {
        return 0;
    }
    switch (r->check) {
    case CHECK_FIN2: return ekf_isfinite(q);
    case CHECK_POS2: return ekf_isfinite(q) && q > EKF_C(0);
    case CHECK_ZPOS2: return v == EKF_C(0) || (ekf_isfinite(q) && q > EKF_C(0));
    default: return 1;
    }
}

ekf_status_t att_setting_get(const att_settings_t *s, size_t i, ekf_scalar_t *value)
{
    if (s == NULL || value == NULL) {
        return EKF_ERR_NULL;
    }
    if (i >= (size_t)N_SETTINGS) {
        return EKF_ERR_DIMENSION;
    }
    *value = value_of(s, &k_info[i]);
    return EKF_OK;
}

ekf_status_t att_setting_set(att_settings_t *s, size_t i, ekf_scalar_t value)
{
    const att_setting_info_t *r;
    if (s == NULL) {
        return EKF_ERR_NULL;
    }
    if (i >= (size_t)N_SETTINGS) {
        return EKF_ERR_DIMENSION;
    }
    r = &k_info[i];
    if (!value_ok(r, value)) {
        return EKF_ERR_SETTINGS;
    }
    if (r->type == ATT_SETTING_U16) {
        /* a count: a whole number within the row's range (which lies in 0..65535) */
        const uint16_t v = (uint16_t)ekf_to_float(value); /* exact in float up to 2^24 */
        if (ekf_from_int((int32_t)v) != value) {
            return EKF_ERR_SETTINGS;
        }
        memcpy((char *)s + r->offset, &v, sizeof v);
    } else {
        *scalar_field(s, r) = value;
    }
    return EKF_OK;
}

/* ---- the check ---- */

/* The bounds and sums derived from several settings are representable in the build's
 * scalar (see value_ok); the fixed-point build also refuses a var_floor that is not above
 * twice the covariance guard's absolute margin, which the guard could then not hold
 * (docs/fixed_point.md). */
static int representable(const att_settings_t *s)
{
#if defined(ATT_COV_FX)
    if (!(s->var_floor >= 2 * ATT_COV_FX_TAU)) {
        return 0;
    }
#endif
    const ekf_scalar_t sec_lim = ekf_div(EKF_C(1), ekf_cos(s->gimbal_limit));
    const ekf_scalar_t n = ekf_from_int((int32_t)s->align_samples);
    /* the accelerometer's per-sample variance at the longest step is the smallest */
    const ekf_scalar_t r_accel = ekf_div(ekf_div(ekf_sq(s->accel_noise), s->dt_max), ekf_sq(s->gravity));
    return s->var_floor > EKF_C(0) && ekf_isfinite(r_accel) && r_accel > EKF_C(0) &&
           /* the Euler-rate variance bound (att_predict.c) and the norms of the sensor vectors */
           ekf_isfinite(ekf_sq(ekf_mul(s->gyro_range, ekf_add(EKF_C(1), ekf_mul(EKF_C(2), sec_lim))))) &&
           ekf_isfinite(ekf_mul(EKF_C(3), ekf_sq(s->accel_range))) &&
           ekf_isfinite(ekf_mul(EKF_C(3), ekf_sq(s->mag_range))) &&
           /* the sums of the alignment average */
           ekf_isfinite(ekf_mul(n, s->accel_range)) && ekf_isfinite(ekf_mul(n, s->mag_range));
}

ekf_status_t att_settings_check(const att_settings_t *s)
{
    int i;
    if (s == NULL) {
        return EKF_ERR_NULL;
    }
    for (i = 0; i < N_SETTINGS; ++i) {
        if (!value_ok(&k_info[i], value_of(s, &k_info[i]))) {
            return EKF_ERR_SETTINGS;
        }
    }
    /* the settings that bound each other (their help in att_settings_table.h says so) */
    if (s->accel_range < s->gravity || s->heading_var_max < s->var_floor || s->rest.bias_max > s->gyro_range ||
        s->bias.sigma_init > s->gyro_range || !representable(s)) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}

/* 1 if every setting that cannot change while the filter runs is the same in a and b. */
int att_settings_same_fixed_part(const att_settings_t *a, const att_settings_t *b)
{
    int i;
    for (i = 0; i < N_SETTINGS; ++i) {
        const att_setting_info_t *r = &k_info[i];
        if (!r->live && value_of(a, r) != value_of(b, r)) {
            return 0;
        }
    }
    return 1;
}
