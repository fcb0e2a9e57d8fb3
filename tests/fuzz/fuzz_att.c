/*
 * fuzz_att.c - libFuzzer target: the estimator (firmware/att) with arbitrary settings,
 * sensor values, time steps, validity masks and public calls. Built for float (fuzz_att_f,
 * what ships), double (fuzz_att_d) and Q-format fixed point (fuzz_att_x).
 *
 * Input: a settings block, then calls. Settings: a first byte below 64, the defaults; else
 * that byte less 64 changes, each to any row of att_settings_table.h (att_setting_info, so
 * a new row is fuzzed without a change here): a value within the row's range or at one of
 * its bounds, set through att_setting_set, or a raw value (the default times 2^k, or
 * anything) written into the field. att_init must accept or refuse them with
 * EKF_ERR_SETTINGS. Calls: dt, valid, gyro, accel, mag, each value ordinary, extreme or
 * non-finite (fuzz_common.h, fz_real). Bits 0-3 of valid are the sample's ATT_HAS_* /
 * ATT_GYRO_SATURATED bits, bit 7 asks for sensible values, bits 4-6 choose the call:
 * 0, 6, 7 att_step; 1 att_predict(dt); 2, 3, 4 att_update_gyro / _accel / _mag; 5 att_align
 * (with the magnetometer if ATT_HAS_MAG).
 *
 * Invariants on the settings: att_setting_set accepts every value within a row's range (unless
 * the scalar cannot use it: a square that underflows or overflows; fixed point: saturates) and
 * refuses, changing nothing, every value outside;
 * att_settings_check refuses a value outside its row's range; att_init agrees with it.
 * After every call: a refused call (any error status) leaves the whole filter byte for byte
 * as it was except its one error counter (diag.rejected, or diag.numeric for
 * EKF_ERR_NUMERIC), and a refused att_init leaves it untouched; the status is one of
 * ekf_status_t; for att_step the report agrees with the status (refused: the first error of
 * the report, every other slot EKF_SKIPPED; applied: the first non-OK stage); state finite;
 * once aligned P exactly symmetric and positive definite (Cholesky in double), angles in
 * their ranges, diagonal >= the variance floor; a guard repair is flagged and counted
 * exactly once per call, and with the default settings repairs stay rare (at most 1 % of
 * the calls, plus 3); only defined flag bits; every counter of att_diag_t (all of them,
 * found from the struct) never decreases, and an applied call on an aligned filter counts
 * what its report says (check_counters).
 */
#include "att.h"
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Every flag att.h defines: a bit outside is an undocumented flag (add new ones here). */
#define FLAG_ALL                                                                                  \
    (ATT_FLAG_ALIGNED | ATT_FLAG_GIMBAL_LOCK | ATT_FLAG_ACCEL_DEWEIGHTED | ATT_FLAG_ACCEL_REJECTED |   \
     ATT_FLAG_MAG_DISTURBED | ATT_FLAG_HEADING_HELD | ATT_FLAG_GYRO_GATED | ATT_FLAG_ACCEL_GATED |     \
     ATT_FLAG_MAG_GATED | ATT_FLAG_GATE_BYPASS | ATT_FLAG_HEADING_LIMITED | ATT_FLAG_REMAPPED |        \
     ATT_FLAG_COV_REPAIRED | ATT_FLAG_AT_REST)

enum { CALL_STEP = 0, CALL_PREDICT, CALL_GYRO, CALL_ACCEL, CALL_MAG, CALL_ALIGN };

#if defined(EKF_SCALAR_FIXED)
#define EKF_SCALAR_IS_FIXED 1
#else
#define EKF_SCALAR_IS_FIXED 0
#endif

/* The counters of att_diag_t: every uint32_t before its first ratio (the binding's diagnostics
 * table, host_tools/native/core_module.c, relies on the same order), so a new counter is
 * checked without a change here. */
#define N_COUNTERS (offsetof(att_diag_t, gyro_ratio) / sizeof(uint32_t))
typedef char counters_are_words[(offsetof(att_diag_t, gyro_ratio) % sizeof(uint32_t) == 0 &&
                                 offsetof(att_diag_t, steps) == 0) ? 1 : -1];
#define COUNTER(d, field) (((const uint32_t *)(const void *)(d))[offsetof(att_diag_t, field) / sizeof(uint32_t)])

static int is_error(ekf_status_t st) { return ekf_status_is_error(st); }

static int pos_def(const ekf_scalar_t *P)
{
    double L[ATT_N][ATT_N];
    int i, j, k;
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j <= i; ++j) {
            double sum = ekf_to_double(P[i * ATT_N + j]);
            for (k = 0; k < j; ++k) {
                sum -= L[i][k] * L[j][k];
            }
            if (i == j) {
                if (!(sum > 0.0) || !isfinite(sum)) {
                    return 0;
                }
                L[i][i] = sqrt(sum);
            } else {
                L[i][j] = sum / L[j][j];
            }
        }
    }
    return 1;
}

/* The value of row r of att_settings_table.h in s, as a double. */
static double setting_value(const att_settings_t *s, size_t i)
{
    ekf_scalar_t v = EKF_C(0);
    (void)att_setting_get(s, i, &v);
    return ekf_to_double(v);
}

/* 1 if v is within row r's range (a count: and a whole number). */
static int in_row_range(const att_setting_info_t *r, ekf_scalar_t v)
{
    return v >= r->lo && v <= r->hi && (r->type != ATT_SETTING_U16 || ekf_from_int((int32_t)ekf_to_double(v)) == v);
}

/* 1 if att_setting_set may refuse v although it is within its row's range: a value the
 * build's scalar cannot use (docs/reliability.md, "settings not representable"): in float and
 * double one whose square underflows to 0 or overflows; in fixed point also one whose square
 * or a sum with it saturates. */
static int may_refuse_in_range(ekf_scalar_t v)
{
    const ekf_scalar_t q = ekf_sq(v);
    return EKF_SCALAR_IS_FIXED || (v != EKF_C(0) && !(ekf_isfinite(q) && q > EKF_C(0)));
}

/* A value within row r's range: at a bound, or log-spaced between positive bounds that span
 * more than a decade, else evenly spaced (a count rounded to a whole number). */
static ekf_scalar_t value_in_range(fz_t *z, const att_setting_info_t *r, int at_bound)
{
    const double lo = ekf_to_double(r->lo), hi = ekf_to_double(r->hi), t = (double)fz_u8(z) / 255.0;
    double x;
    ekf_scalar_t v;
    if (at_bound) {
        return (t < 0.5) ? r->lo : r->hi;
    }
    x = (lo > 0.0 && hi > 10.0 * lo) ? lo * pow(hi / lo, t) : lo + t * (hi - lo);
    if (r->type == ATT_SETTING_U16) {
        x = floor(x + 0.5);
    }
    v = ekf_from_double(x);
    return (v < r->lo) ? r->lo : (v > r->hi) ? r->hi : v;
}

/* Writes v into row r's field as it is, whatever its range (att_settings_check must judge it). */
static void write_raw(att_settings_t *s, const att_setting_info_t *r, ekf_scalar_t v, uint16_t count)
{
    if (r->type == ATT_SETTING_U16) {
        memcpy((char *)s + r->offset, &count, sizeof count);
    } else {
        memcpy((char *)s + r->offset, &v, sizeof v);
    }
}

/* One change to one row, any row of att_settings_table.h (att_setting_info: a new row is
 * fuzzed without a change here): a value within its range or at one of its bounds through
 * att_setting_set, which must accept it unless the scalar cannot use it (may_refuse_in_range),
 * or a raw value (the default times 2^k, or anything) written into the field, which
 * att_setting_set must refuse when it is out of range and accept when it is within (the same
 * exception). */
static void fuzz_setting(fz_t *z, att_settings_t *s)
{
    const size_t i = fz_u8(z) % att_setting_count();
    const att_setting_info_t *r = att_setting_info(i);
    const uint8_t how = fz_u8(z);
    att_settings_t copy = *s;
    ekf_scalar_t v;
    uint16_t count = 0u;
    ekf_status_t st;
    if (how < 160u) {
        v = value_in_range(z, r, how >= 96u);
        st = att_setting_set(s, i, v);
        FZ_CHECK(st == EKF_OK || (st == EKF_ERR_SETTINGS && may_refuse_in_range(v) && memcmp(&copy, s, sizeof copy) == 0),
                 "att_setting_set(%s, %g) within [%g, %g]: status %d", r->name, ekf_to_double(v),
                 ekf_to_double(r->lo), ekf_to_double(r->hi), (int)st);
        return;
    }
    if (how < 240u) { /* the default times 2^-20 .. 2^19, the sign flipped sometimes */
        const double d = ldexp(setting_value(&att_default_settings, i), (int)(how % 40u) - 20);
        v = ekf_from_double((how & 1u) && how > 235u ? -d : d);
        count = (uint16_t)((d < 0.0) ? 0.0 : (d > 65535.0) ? 65535.0 : d);
    } else {
        v = ekf_from_double(fz_real(z, 10.0));
        count = fz_u16(z);
    }
    if (r->type == ATT_SETTING_U16) {
        v = ekf_from_int((int32_t)count);
    }
    st = att_setting_set(&copy, i, v);
    FZ_CHECK((st == EKF_OK) == in_row_range(r, v) || (st == EKF_ERR_SETTINGS && in_row_range(r, v) && may_refuse_in_range(v)),
             "att_setting_set(%s, %g): status %d, range [%g, %g]", r->name, ekf_to_double(v), (int)st,
             ekf_to_double(r->lo), ekf_to_double(r->hi));
    write_raw(s, r, v, count);
}

/* Returns 1 if the settings are the defaults. A first byte below 64 (a quarter of the inputs):
 * the defaults; else that byte less 64 changes (fuzz_setting). */
static int fuzz_settings(fz_t *z, att_settings_t *s)
{
    const uint8_t c = fz_u8(z);
    int k;
    *s = att_default_settings;
    if (c < 64u) {
        return 1;
    }
    for (k = 0; k < c - 64; ++k) {
        fuzz_setting(z, s);
    }
    return 0;
}

/* att_settings_check refuses a value outside its row's range. */
static void check_rows(const att_settings_t *s, ekf_status_t st)
{
    size_t i;
    for (i = 0; i < att_setting_count(); ++i) {
        const att_setting_info_t *r = att_setting_info(i);
        ekf_scalar_t v = EKF_C(0);
        (void)att_setting_get(s, i, &v);
        FZ_CHECK(st != EKF_OK || in_row_range(r, v), "att_settings_check accepted %s = %g outside [%g, %g]", r->name,
                 ekf_to_double(v), ekf_to_double(r->lo), ekf_to_double(r->hi));
    }
}

static void fuzz_vec(fz_t *z, ekf_scalar_t v[3], double scale)
{
    int i;
    for (i = 0; i < 3; ++i) {
        v[i] = ekf_from_double(fz_real(z, scale));
    }
}

static int call_of(uint8_t valid)
{
    const int c = (valid >> 4) & 7;
    return (c >= 6) ? CALL_STEP : c;
}

/* The filter after a refused call: as before but for one error counter. */
static void check_refused(const att_ekf_t *f, const att_ekf_t *before, ekf_status_t st, int steps)
{
    static att_ekf_t expect;
    memcpy(&expect, before, sizeof expect);
    if (st == EKF_ERR_NUMERIC) {
        expect.vars.diag.numeric += (expect.vars.diag.numeric != UINT32_MAX) ? 1u : 0u;
    } else {
        expect.vars.diag.rejected += (expect.vars.diag.rejected != UINT32_MAX) ? 1u : 0u;
    }
    FZ_CHECK(memcmp(&expect, f, sizeof expect) == 0, "refused call (status %d) changed the filter at step %d", (int)st, steps);
}

/* The counters after one call (prev: before it): none decreases or grows by more than 4 (the
 * remaps of one step: predict and three stages); an applied call on an aligned filter counts
 * what its report says each sensor stage did (att.h, att_diag_t): a gyroscope sample three
 * scalar updates fused or gated, an accelerometer sample two, a heading one, a sample not
 * fused by policy one skip; a saturated gyroscope sample one gyro_saturated; att_step alone
 * counts steps. */
static void check_counters(const att_diag_t *prev, const att_diag_t *d, int call, const att_sample_t *smp,
                           const att_step_report_t *rep, ekf_status_t st, int was_aligned)
{
    size_t k;
    ekf_status_t gyro = EKF_SKIPPED, accel = EKF_SKIPPED, mag = EKF_SKIPPED;
    int saturated = 0, stepped = 0;
    for (k = 0; k < N_COUNTERS; ++k) {
        const uint32_t a = ((const uint32_t *)(const void *)prev)[k], b = ((const uint32_t *)(const void *)d)[k];
        FZ_CHECK(b >= a && b - a <= 4u, "counter %u of att_diag_t (byte %u) went from %u to %u", (unsigned)k,
                 (unsigned)(k * sizeof(uint32_t)), (unsigned)a, (unsigned)b);
    }
    if (is_error(st) || !was_aligned) {
        return; /* refusals: check_refused; alignment: its own counting */
    }
    switch (call) {
    case CALL_STEP:
        stepped = 1;
        saturated = (smp->valid & ATT_GYRO_SATURATED) != 0u;
        gyro = (!saturated && (smp->valid & ATT_HAS_GYRO) != 0u) ? rep->gyro : EKF_SKIPPED;
        accel = ((smp->valid & ATT_HAS_ACCEL) != 0u) ? rep->accel : EKF_SKIPPED;
        mag = ((smp->valid & ATT_HAS_MAG) != 0u) ? rep->mag : EKF_SKIPPED;
        if ((smp->valid & ATT_HAS_ACCEL) == 0u) {
            accel = (ekf_status_t)-1; /* not present: nothing counted */
        }
        if ((smp->valid & ATT_HAS_MAG) == 0u) {
            mag = (ekf_status_t)-1;
        }
        break;
    case CALL_GYRO: gyro = st; break;
    case CALL_ACCEL: accel = st; break;
    case CALL_MAG: mag = st; break;
    default: break;
    }
    if (call != CALL_ACCEL && call != CALL_STEP) {
        accel = (ekf_status_t)-1;
    }
    if (call != CALL_MAG && call != CALL_STEP) {
        mag = (ekf_status_t)-1;
    }
#define DELTA(field) (COUNTER(d, field) - COUNTER(prev, field))
    FZ_CHECK(DELTA(steps) == (uint32_t)stepped, "steps +%u (call %d)", (unsigned)DELTA(steps), call);
    FZ_CHECK(DELTA(gyro_saturated) == (uint32_t)saturated, "gyro_saturated +%u, saturated sample %d",
             (unsigned)DELTA(gyro_saturated), saturated);
    if (gyro == EKF_OK || gyro == EKF_GATED) {
        FZ_CHECK(DELTA(gyro_fused) + DELTA(gyro_gated) == 3u && (DELTA(gyro_gated) > 0u) == (gyro == EKF_GATED),
                 "gyro %d: fused +%u gated +%u", (int)gyro, (unsigned)DELTA(gyro_fused), (unsigned)DELTA(gyro_gated));
    } else {
        FZ_CHECK(DELTA(gyro_fused) + DELTA(gyro_gated) == 0u, "gyro not run: fused +%u gated +%u",
                 (unsigned)DELTA(gyro_fused), (unsigned)DELTA(gyro_gated));
    }
    if (accel == EKF_OK || accel == EKF_GATED) {
        FZ_CHECK(DELTA(accel_fused) + DELTA(accel_gated) == 2u && (DELTA(accel_gated) > 0u) == (accel == EKF_GATED) &&
                     DELTA(accel_skipped) == 0u,
                 "accel %d: fused +%u gated +%u skipped +%u", (int)accel, (unsigned)DELTA(accel_fused),
                 (unsigned)DELTA(accel_gated), (unsigned)DELTA(accel_skipped));
    } else {
        FZ_CHECK(DELTA(accel_fused) + DELTA(accel_gated) == 0u && DELTA(accel_skipped) == (accel == EKF_SKIPPED ? 1u : 0u),
                 "accel %d: fused +%u gated +%u skipped +%u", (int)accel, (unsigned)DELTA(accel_fused),
                 (unsigned)DELTA(accel_gated), (unsigned)DELTA(accel_skipped));
    }
    FZ_CHECK(DELTA(mag_fused) == (mag == EKF_OK ? 1u : 0u) && DELTA(mag_gated) == (mag == EKF_GATED ? 1u : 0u) &&
                 DELTA(mag_skipped) == (mag == EKF_SKIPPED ? 1u : 0u),
             "mag %d: fused +%u gated +%u skipped +%u", (int)mag, (unsigned)DELTA(mag_fused), (unsigned)DELTA(mag_gated),
             (unsigned)DELTA(mag_skipped));
    FZ_CHECK(DELTA(heading_resets) <= DELTA(mag_fused), "heading_resets +%u, mag_fused +%u",
             (unsigned)DELTA(heading_resets), (unsigned)DELTA(mag_fused));
#undef DELTA
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static att_ekf_t f, before;
    att_settings_t s;
    fz_t z = {data, size};
    ekf_status_t st;
    att_diag_t prev;
    int steps = 0, defaults;

    defaults = fuzz_settings(&z, &s);
    st = att_settings_check(&s);
    FZ_CHECK(st == EKF_OK || st == EKF_ERR_SETTINGS, "settings_check %d", (int)st);
    check_rows(&s, st);
    memcpy(&before, &f, sizeof before);
    FZ_CHECK(att_init(&f, &s) == st, "att_init disagrees with att_settings_check");
    if (st != EKF_OK) {
        FZ_CHECK(memcmp(&before, &f, sizeof f) == 0, "a refused att_init wrote the filter");
        return 0;
    }
    memset(&prev, 0, sizeof(prev));
    while (fz_more(&z) && steps++ < 4000) {
        att_sample_t smp;
        att_step_report_t rep;
        const int was_aligned = (att_flags(&f) & ATT_FLAG_ALIGNED) != 0u;
        const uint8_t dtk = fz_u8(&z);
        const att_diag_t *d;
        int i, call;

        memset(&smp, 0, sizeof(smp));
        if (dtk < 200u) { /* 0.1 ms .. ~2 s, log spaced */
            smp.dt = ekf_from_double(1e-4 * pow(1.05, (double)dtk));
        } else {
            smp.dt = ekf_from_double(fz_real(&z, 0.01));
        }
        smp.valid = fz_u8(&z);
        call = call_of(smp.valid);
        if (smp.valid & 0x80u) { /* repeat the pattern with sensible values: move the filter */
            const double tilt = (double)(int8_t)fz_u8(&z) / 40.0;
            smp.gyro[0] = ekf_from_double((double)(int8_t)fz_u8(&z) / 20.0);
            smp.gyro[1] = ekf_from_double((double)(int8_t)fz_u8(&z) / 20.0);
            smp.gyro[2] = ekf_from_double((double)(int8_t)fz_u8(&z) / 20.0);
            smp.accel[0] = ekf_from_double(-9.81 * sin(tilt));
            smp.accel[1] = EKF_C(0.3);
            smp.accel[2] = ekf_from_double(9.81 * cos(tilt));
            smp.mag[0] = EKF_C(20);
            smp.mag[1] = EKF_C(5);
            smp.mag[2] = EKF_C(-40);
        } else {
            fuzz_vec(&z, smp.gyro, 5.0);
            fuzz_vec(&z, smp.accel, 20.0);
            fuzz_vec(&z, smp.mag, 60.0);
        }
        memcpy(&before, &f, sizeof before);

        switch (call) {
        case CALL_PREDICT: st = att_predict(&f, smp.dt); break;
        case CALL_GYRO: st = att_update_gyro(&f, smp.gyro, smp.dt); break;
        case CALL_ACCEL: st = att_update_accel(&f, smp.accel, smp.dt); break;
        case CALL_MAG: st = att_update_mag(&f, smp.mag, smp.dt); break;
        case CALL_ALIGN: st = att_align(&f, smp.accel, (smp.valid & ATT_HAS_MAG) ? smp.mag : NULL); break;
        default: st = att_step(&f, &smp, &rep); break;
        }
        FZ_CHECK((unsigned)st <= (unsigned)EKF_SKIPPED, "status %d", (int)st);
        if (is_error(st)) {
            check_refused(&f, &before, st, steps);
        }
        if (call == CALL_STEP) {
            FZ_CHECK((unsigned)rep.predict <= EKF_SKIPPED && (unsigned)rep.gyro <= EKF_SKIPPED &&
                         (unsigned)rep.accel <= EKF_SKIPPED && (unsigned)rep.mag <= EKF_SKIPPED,
                     "report");
            if (is_error(st)) {
                /* refused: the first error of the report, every other slot skipped */
                const ekf_status_t first = is_error(rep.predict) ? rep.predict
                                           : is_error(rep.gyro)  ? rep.gyro
                                           : is_error(rep.accel) ? rep.accel
                                                                 : rep.mag;
                FZ_CHECK(st == first, "status %d, first error %d", (int)st, (int)first);
                FZ_CHECK((is_error(rep.predict) || rep.predict == EKF_SKIPPED) &&
                             (is_error(rep.gyro) || rep.gyro == EKF_SKIPPED) &&
                             (is_error(rep.accel) || rep.accel == EKF_SKIPPED) && (is_error(rep.mag) || rep.mag == EKF_SKIPPED),
                         "refused sample with a stage reported as run");
            } else if (was_aligned) {
                const ekf_status_t first = rep.predict != EKF_OK ? rep.predict
                                           : rep.gyro != EKF_OK  ? rep.gyro
                                           : rep.accel != EKF_OK ? rep.accel
                                                                 : rep.mag;
                FZ_CHECK(st == first, "status %d, first stage %d", (int)st, (int)first);
                FZ_CHECK(!is_error(rep.predict) && !is_error(rep.gyro) && !is_error(rep.accel) && !is_error(rep.mag),
                         "applied sample with an error in its report");
            }
        }
        FZ_CHECK(ekf_all_finite(att_state(&f), ATT_N), "non-finite state at step %d", steps);
        FZ_CHECK((att_flags(&f) & ~FLAG_ALL) == 0u, "flags 0x%x: a bit att.h does not define (new flag? add it to FLAG_ALL)",
                 (unsigned)att_flags(&f));
        d = att_diag(&f);
        if (!is_error(st) && (att_flags(&f) & ATT_FLAG_ALIGNED)) {
            /* the guard ran: a repair is flagged and counted once */
            const uint32_t repaired = (att_flags(&f) & ATT_FLAG_COV_REPAIRED) ? 1u : 0u;
            FZ_CHECK(d->cov_repairs - prev.cov_repairs == repaired || d->cov_repairs == UINT32_MAX,
                     "repairs counted %u, flagged %u", (unsigned)(d->cov_repairs - prev.cov_repairs), (unsigned)repaired);
        }
        if (att_flags(&f) & ATT_FLAG_ALIGNED) {
            const ekf_scalar_t *x = att_state(&f);
            ekf_scalar_t P[ATT_N * ATT_N];
            int j;
            att_get_covariance(&f, P);
            for (i = 0; i < ATT_N; ++i) {
                for (j = 0; j < i; ++j) {
                    FZ_CHECK(memcmp(&P[i * ATT_N + j], &P[j * ATT_N + i], sizeof(P[0])) == 0,
                             "P not symmetric at (%d,%d) step %d", i, j, steps);
                }
                FZ_CHECK(P[i * ATT_N + i] >= s.var_floor, "P[%d][%d] = %g below the floor %g at step %d (status %d, flags 0x%x)",
                         i, i, ekf_to_double(P[i * ATT_N + i]), ekf_to_double(s.var_floor), steps, (int)st,
                         (unsigned)att_flags(&f));
            }
            FZ_CHECK(pos_def(P), "P not positive definite at step %d", steps);
            FZ_CHECK(x[ATT_PHI] >= ekf_neg(EKF_PI) && x[ATT_PHI] < EKF_PI && x[ATT_PSI] >= ekf_neg(EKF_PI) &&
                         x[ATT_PSI] < EKF_PI && x[ATT_THETA] >= ekf_neg(EKF_HALF_PI) && x[ATT_THETA] <= EKF_HALF_PI,
                     "angles out of range: %g %g %g", ekf_to_double(x[ATT_PHI]), ekf_to_double(x[ATT_THETA]),
                     ekf_to_double(x[ATT_PSI]));
        }
        check_counters(&prev, d, call, &smp, &rep, st, was_aligned);
        prev = *d;
    }
    if (defaults) {
        /* with the default settings the guard's repairs stay rare whatever the input (the
         * 10^6-step random stress needs 331 in float: docs/reliability.md) */
        FZ_CHECK(att_diag(&f)->cov_repairs <= (uint32_t)steps / 100u + 3u, "%u guard repairs in %d calls",
                 (unsigned)att_diag(&f)->cov_repairs, steps);
    }
    return 0;
}
