/*
 * att_bias.c - gyroscope offset in motion (see att_bias.h; docs/derivation.md, "Gyroscope
 * offset in motion").
 */
#include "att_bias.h"

#include "att_defs.h"

/* Smallest variance of an offset component, ATT_BIAS_UNIT^2: keeps Pb positive definite
 * where the updates would round a variance to zero (6e-6 deg/s). */
#define BIAS_VAR_MIN EKF_C(1e-8)

/* Places of Pb's entries (att_bias_t). */
enum { PB_00 = 0, PB_11 = 1, PB_22 = 2, PB_01 = 3, PB_02 = 4, PB_12 = 5 };

/* Largest |V| entry, s: an offset error's effect on an angle over almost three hours (an
 * unobserved heading), and a bound that keeps V finite where the transition amplifies it
 * (rates of tens of rad/s next to the gimbal limit). */
#define BIAS_V_MAX EKF_C(1e4)

/* 1 / ATT_BIAS_UNIT, s/rad: a product, not a division, on every prediction. */
#define PER_UNIT EKF_C(1e3)

/* A value in rad/s as a multiple of ATT_BIAS_UNIT. */
static ekf_scalar_t in_units(ekf_scalar_t v)
{
    return ekf_mul(v, PER_UNIT);
}

void att_bias_reset(att_bias_t *bf, const att_bias_settings_t *s)
{
    const ekf_scalar_t v0 = ekf_max(ekf_sq(in_units(s->sigma_init)), BIAS_VAR_MIN);
    int i;
    for (i = 0; i < 9; ++i) {
        bf->V[i] = EKF_C(0);
    }
    for (i = 0; i < 3; ++i) {
        bf->b[i] = EKF_C(0);
        bf->Pb[i] = v0;         /* variances */
        bf->Pb[3 + i] = EKF_C(0); /* covariances */
    }
    bf->hold = EKF_C(0);
}

void att_bias_hold(att_bias_t *bf, ekf_scalar_t t) { bf->hold = ekf_max(bf->hold, t); }

void att_bias_restart(att_bias_t *bf)
{
    int i;
    for (i = 0; i < 9; ++i) {
        bf->V[i] = EKF_C(0);
    }
}

/* Entry of d1 (att_gen_f1_pattern, checked by test_att_bias): angle row a (0..2), column j of
 * the body rates and angles (0..5). */
#define D1(a, j) ((a) * 6 + (j))

void att_bias_predict(att_bias_t *bf, const att_bias_settings_t *s, const ekf_scalar_t d1[ATT_GEN_F1_NNZ],
                      ekf_scalar_t dt)
{
    /* The angles advance with the body rates w, which contain the residual offset one for
     * one (the gyro update makes them follow the gyro): d angles+ / d b = F_aa V + F_aw, the
     * angle rows of F1 on the angle and body-rate columns (docs/derivation.md, "Gyroscope
     * offset in motion"); F_aa = I + D1's angle block. */
    const ekf_scalar_t q = ekf_mul(ekf_sq(in_units(s->walk)), dt);
    ekf_scalar_t *const V = bf->V;
    const ekf_scalar_t v00 = V[0], v01 = V[1], v02 = V[2], v10 = V[3], v11 = V[4], v12 = V[5];
    int a, j;
    for (a = 0; a < 3; ++a) {
        const ekf_scalar_t *const d = &d1[D1(a, 0)];
        ekf_scalar_t *const row = &V[3 * a];
        /* row a of (I + D_aa) V + D_aw; the heading column of D_aa is zero in these
         * coordinates (att_gen_f1_pattern keeps its place) */
        row[0] = ekf_clamp(ekf_mac(ekf_mac(ekf_add(row[0], d[0]), d[3], v00), d[4], v10), ekf_neg(BIAS_V_MAX), BIAS_V_MAX);
        row[1] = ekf_clamp(ekf_mac(ekf_mac(ekf_add(row[1], d[1]), d[3], v01), d[4], v11), ekf_neg(BIAS_V_MAX), BIAS_V_MAX);
        row[2] = ekf_clamp(ekf_mac(ekf_mac(ekf_add(row[2], d[2]), d[3], v02), d[4], v12), ekf_neg(BIAS_V_MAX), BIAS_V_MAX);
    }
    for (j = 0; j < 3; ++j) {
        bf->Pb[j] = ekf_add(bf->Pb[j], q);
    }
    bf->hold = ekf_max(ekf_sub(bf->hold, dt), EKF_C(0));
}

int att_bias_update(att_bias_t *bf, int learn, const ekf_scalar_t h[3], const ekf_scalar_t pht[3], ekf_scalar_t nu,
                    ekf_scalar_t s_var, ekf_scalar_t derate, ekf_scalar_t x_ang[3])
{
    ekf_scalar_t *const V = bf->V, *const P = bf->Pb;
    /* the measurement's sensitivity to the offset, g = -h V (V from before the update) */
    const ekf_scalar_t g0 = ekf_neg(ekf_mac(ekf_mac(ekf_mul(h[0], V[0]), h[1], V[3]), h[2], V[6]));
    const ekf_scalar_t g1 = ekf_neg(ekf_mac(ekf_mac(ekf_mul(h[0], V[1]), h[1], V[4]), h[2], V[7]));
    const ekf_scalar_t g2 = ekf_neg(ekf_mac(ekf_mac(ekf_mul(h[0], V[2]), h[1], V[5]), h[2], V[8]));
    const ekf_scalar_t inv_s = ekf_div(EKF_C(1), s_var);
    ekf_scalar_t u0, u1, u2, p0, p1, p2, sb, e, d0, d1, d2;
    int i;

    /* the EKF's update moves its error's sensitivity too: V <- (I - k h) V = V + k g^T with
     * the EKF's gain of the angles k = pht / S */
    for (i = 0; i < 3; ++i) {
        const ekf_scalar_t ki = ekf_mul(pht[i], inv_s);
        ekf_scalar_t *const row = &V[3 * i];
        row[0] = ekf_mac(row[0], ki, g0);
        row[1] = ekf_mac(row[1], ki, g1);
        row[2] = ekf_mac(row[2], ki, g2);
    }
    if (!learn || bf->hold > EKF_C(0)) {
        return 0;
    }
    s_var = ekf_mul(s_var, derate);
    /* innovation nu = g b + (the EKF's own error and the sensor noise, variance s_var); with
     * the offset in ATT_BIAS_UNIT its sensitivity is u = g ATT_BIAS_UNIT, and Pb u = p */
    u0 = ekf_mul(g0, ATT_BIAS_UNIT);
    u1 = ekf_mul(g1, ATT_BIAS_UNIT);
    u2 = ekf_mul(g2, ATT_BIAS_UNIT);
    p0 = ekf_mac(ekf_mac(ekf_mul(P[PB_00], u0), P[PB_01], u1), P[PB_02], u2);
    p1 = ekf_mac(ekf_mac(ekf_mul(P[PB_01], u0), P[PB_11], u1), P[PB_12], u2);
    p2 = ekf_mac(ekf_mac(ekf_mul(P[PB_02], u0), P[PB_12], u1), P[PB_22], u2);
    sb = ekf_mac(ekf_mac(ekf_mac(s_var, u0, p0), u1, p1), u2, p2);
    if (!(sb > EKF_C(0)) || !(s_var > EKF_C(0)) || ekf_sq(nu) > ekf_mul(EKF_C(9), sb)) {
        return 0;
    }
    sb = ekf_div(EKF_C(1), sb);
    e = ekf_mul(nu, sb); /* the offset moves by p e (in ATT_BIAS_UNIT) */
    /* Pb <- Pb - p p^T / sb (the variances kept above BIAS_VAR_MIN) */
    P[PB_00] = ekf_max(ekf_sub(P[PB_00], ekf_mul(ekf_mul(p0, sb), p0)), BIAS_VAR_MIN);
    P[PB_11] = ekf_max(ekf_sub(P[PB_11], ekf_mul(ekf_mul(p1, sb), p1)), BIAS_VAR_MIN);
    P[PB_22] = ekf_max(ekf_sub(P[PB_22], ekf_mul(ekf_mul(p2, sb), p2)), BIAS_VAR_MIN);
    P[PB_01] = ekf_sub(P[PB_01], ekf_mul(ekf_mul(p0, sb), p1));
    P[PB_02] = ekf_sub(P[PB_02], ekf_mul(ekf_mul(p0, sb), p2));
    P[PB_12] = ekf_sub(P[PB_12], ekf_mul(ekf_mul(p1, sb), p2));
    /* db, rad/s */
    d0 = ekf_mul(ekf_mul(p0, e), ATT_BIAS_UNIT);
    d1 = ekf_mul(ekf_mul(p1, e), ATT_BIAS_UNIT);
    d2 = ekf_mul(ekf_mul(p2, e), ATT_BIAS_UNIT);
    /* the angles' error was V b: take the part now known out of them, the heading only where
     * the measurement is of the heading (the magnetometer): from the accelerometer the
     * heading's share would rest on V's heading row alone, and a wrong offset would turn the
     * heading faster than the offset itself does (docs/derivation.md, "Gyroscope offset in
     * motion") */
    for (i = 0; i < ((h[2] != EKF_C(0)) ? 3 : 2); ++i) {
        const ekf_scalar_t *const row = &V[3 * i];
        x_ang[i] = ekf_sub(x_ang[i], ekf_mac(ekf_mac(ekf_mul(row[0], d0), row[1], d1), row[2], d2));
    }
    bf->b[0] = ekf_add(bf->b[0], d0);
    bf->b[1] = ekf_add(bf->b[1], d1);
    bf->b[2] = ekf_add(bf->b[2], d2);
    return (d0 != EKF_C(0)) || (d1 != EKF_C(0)) || (d2 != EKF_C(0));
}

void att_bias_rest(att_bias_t *bf, ekf_scalar_t w, ekf_scalar_t gyro_var)
{
    /* the rest offset is the average of the raw gyro, which contains the whole offset: what
     * was learned in motion moves into it at its averaging weight, and the uncertainty is
     * that of the running average, (1 - w)^2 Pb + w^2 gyro_var */
    const ekf_scalar_t keep = ekf_sub(EKF_C(1), w);
    const ekf_scalar_t keep2 = ekf_sq(keep);
    const ekf_scalar_t fresh = ekf_mul(ekf_sq(w), ekf_mul(gyro_var, ekf_sq(PER_UNIT)));
    int i;
    for (i = 0; i < 3; ++i) {
        bf->b[i] = ekf_mul(keep, bf->b[i]);
        bf->Pb[i] = ekf_max(ekf_mac(fresh, keep2, bf->Pb[i]), BIAS_VAR_MIN);
        bf->Pb[3 + i] = ekf_mul(keep2, bf->Pb[3 + i]);
    }
}

void att_bias_remap(att_bias_t *bf)
{
    int j;
    for (j = 0; j < 3; ++j) {
        bf->V[3 + j] = ekf_neg(bf->V[3 + j]);
    }
}

void att_bias_heading_reset(att_bias_t *bf)
{
    int j;
    for (j = 0; j < 3; ++j) {
        bf->V[6 + j] = EKF_C(0);
    }
}

void att_bias_cov(const att_bias_t *bf, ekf_scalar_t c[6])
{
    static const uint8_t row[6] = {0, 1, 2, 0, 0, 1};
    static const uint8_t col[6] = {0, 1, 2, 1, 2, 2};
    static const uint8_t at[9] = {PB_00, PB_01, PB_02, PB_01, PB_11, PB_12, PB_02, PB_12, PB_22};
    ekf_scalar_t vu[9], vp[9]; /* V ATT_BIAS_UNIT (rad per unit), vu Pb */
    int i, j;
    for (i = 0; i < 9; ++i) {
        vu[i] = ekf_mul(bf->V[i], ATT_BIAS_UNIT);
    }
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            vp[3 * i + j] = ekf_mac(ekf_mac(ekf_mul(vu[3 * i], bf->Pb[at[j]]), vu[3 * i + 1], bf->Pb[at[3 + j]]),
                                    vu[3 * i + 2], bf->Pb[at[6 + j]]);
        }
    }
    for (i = 0; i < 6; ++i) {
        const int r = row[i], k = col[i];
        c[i] = ekf_add(c[i], ekf_mac(ekf_mac(ekf_mul(vp[3 * r], vu[3 * k]), vp[3 * r + 1], vu[3 * k + 1]),
                                     vp[3 * r + 2], vu[3 * k + 2]));
    }
}
