/*
 * fuzz_att.c - libFuzzer target: the estimator (firmware/att) with arbitrary settings,
 * sensor values, time steps, validity masks and public calls. Built for float (fuzz_att_f,
 * what ships), double (fuzz_att_d) and Q-format fixed point (fuzz_att_x).
 *
 * Input: a settings block (first byte < 64: the defaults; 240 and above: every setting of
 * the table (att_setting_info) kept at its default, set to its lower or upper bound, scaled
 * by a power of two, or replaced by an arbitrary value; otherwise the 28 fields of the older
 * layout, kept, scaled or arbitrary; att_init must accept or refuse it with
 * EKF_ERR_SETTINGS), then calls: dt, valid, gyro, accel, mag, each value ordinary, extreme
 * or non-finite (fuzz_common.h, fz_real). Bits 0-3 of valid are the sample's ATT_HAS_* /
 * ATT_GYRO_SATURATED bits, bit 7 asks for sensible values, bits 4-6 choose the call:
 * 0, 6, 7 att_step; 1 att_predict(dt); 2, 3, 4 att_update_gyro / _accel / _mag; 5 att_align
 * (with the magnetometer if ATT_HAS_MAG).
 *
 * Invariants after every call: a refused call (any error status) leaves the whole filter
 * byte for byte as it was except its one error counter (diag.rejected, or diag.numeric for
 * EKF_ERR_NUMERIC), and a refused att_init leaves it untouched; the status is one of
 * ekf_status_t; for att_step the report agrees with the status (refused: the first error of
 * the report, every other slot EKF_SKIPPED; applied: the first non-OK stage); state finite;
 * once aligned P exactly symmetric and positive definite (Cholesky in double), angles in
 * their ranges, diagonal >= the variance floor; a guard repair is flagged and counted
 * exactly once per call, and with the default settings repairs stay rare (at most 1 % of
 * the calls, plus 3); only defined flag bits; counters never decrease.
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

static ekf_scalar_t fuzz_setting(fz_t *z, ekf_scalar_t def)
{
    const uint8_t how = fz_u8(z);
    if (how < 160u) {
        return def;
    }
    if (how < 240u) { /* default times 2^-20 .. 2^19 (sign flipped sometimes) */
        const double v = ldexp(ekf_to_double(def), (int)(how % 40u) - 20);
        return ekf_from_double((how & 1u) && how > 235u ? -v : v);
    }
    return ekf_from_double(fz_real(z, 10.0));
}

/* Every setting of the table: default, its lower or upper bound, scaled by 2^-20 .. 2^19, or
 * arbitrary (a count: any 16-bit value); att_setting_set keeps a value outside the setting's
 * own range out, the settings check the rest. */
static void fuzz_table(fz_t *z, att_settings_t *s)
{
    size_t i;
    for (i = 0; i < att_setting_count(); ++i) {
        const att_setting_info_t *info = att_setting_info(i);
        const uint8_t how = fz_u8(z);
        ekf_scalar_t v;
        if (how < 128u) {
            continue;
        }
        (void)att_setting_get(s, i, &v);
        if (how < 160u) {
            v = info->lo;
        } else if (how < 192u) {
            v = info->hi;
        } else if (how < 232u) {
            v = ekf_from_double(ldexp(ekf_to_double(v), (int)(how % 40u) - 20));
        } else {
            v = (info->type == ATT_SETTING_U16) ? ekf_from_int((int32_t)fz_u16(z)) : ekf_from_double(fz_real(z, 10.0));
        }
        (void)att_setting_set(s, i, v);
    }
}

/* Returns 1 if the settings are the defaults. */
static int fuzz_settings(fz_t *z, att_settings_t *s)
{
    ekf_scalar_t *fields[] = {
        &s->rate_walk, &s->angle_walk, &s->euler_rate_rel, &s->gyro_noise, &s->gyro_gate, &s->gyro_range,
        &s->gravity, &s->accel_noise, &s->accel_band, &s->accel_reject, &s->accel_gate, &s->accel_range,
        &s->mag_heading_noise, &s->mag_gate, &s->mag_norm_tol, &s->mag_dip_tol, &s->mag_ref_norm,
        &s->mag_ref_dip, &s->mag_declination, &s->mag_range, &s->gate_timeout, &s->gimbal_limit,
        &s->dt_max, &s->heading_var_max, &s->var_floor, &s->init_tilt_sigma, &s->init_heading_sigma,
        &s->init_rate_sigma,
    };
    size_t i;
    const uint8_t mode = fz_u8(z);
    *s = att_default_settings;
    if (mode < 64u) {
        return 1; /* a quarter of the inputs run the defaults */
    }
    if (mode >= 240u) {
        fuzz_table(z, s);
        return 0;
    }
    for (i = 0; i < sizeof(fields) / sizeof(fields[0]); ++i) {
        *fields[i] = fuzz_setting(z, *fields[i]);
    }
    {
        const uint8_t a = fz_u8(z);
        if (a >= 200u) {
            s->align_samples = (uint16_t)(a == 255u ? fz_u16(z) : a - 200u);
        }
    }
    return 0;
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
        FZ_CHECK(d->steps >= prev.steps && d->gyro_fused >= prev.gyro_fused && d->accel_fused >= prev.accel_fused &&
                     d->mag_fused >= prev.mag_fused && d->gyro_gated >= prev.gyro_gated &&
                     d->accel_gated >= prev.accel_gated && d->mag_gated >= prev.mag_gated &&
                     d->accel_skipped >= prev.accel_skipped && d->mag_skipped >= prev.mag_skipped &&
                     d->rejected >= prev.rejected && d->numeric >= prev.numeric && d->remaps >= prev.remaps &&
                     d->cov_repairs >= prev.cov_repairs && d->heading_resets >= prev.heading_resets &&
                     d->gyro_saturated >= prev.gyro_saturated,
                 "a counter decreased");
        FZ_CHECK(d->gyro_fused + d->gyro_gated - prev.gyro_fused - prev.gyro_gated <= 3u, "gyro updates");
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
