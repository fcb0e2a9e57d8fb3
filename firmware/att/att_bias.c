/*
 * att_bias.c - gyroscope offset in motion (see att_bias.h; docs/derivation.md, "Gyroscope
 * offset in motion").
 */
#include "att_bias.h"

#include "att_defs.h"

/* Smallest variance of an offset component, ATT_BIAS_UNIT^2: keeps Pb positive definite
 * where the updates would round a variance to zero (6e-6 deg/s). */
#define BIAS_VAR_MIN EKF_C(1e-8)

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
    int i;
    for (i = 0; i < 9; ++i) {
        bf->Pb[i] = EKF_C(0);
        bf->V[i] = EKF_C(0);
    }
    for (i = 0; i < 3; ++i) {
        bf->b[i] = EKF_C(0);
        bf->Pb[4 * i] = ekf_max(ekf_sq(in_units(s->sigma_init)), BIAS_VAR_MIN);
    }
}

void att_bias_restart(att_bias_t *bf)
{
    int i;
    for (i = 0; i < 9; ++i) {
        bf->V[i] = EKF_C(0);
    }
}

/* Entries of d1 (att_gen_f1_pattern, checked by test_att_bias): the angle rows' columns
 * p, q, r (dt W at the midpoint angles) and phi, theta (dt M, the angles' own coupling). */
enum {
    D1_PHI_P = 0, D1_PHI_Q = 1, D1_PHI_R = 2, D1_PHI_PHI = 3, D1_PHI_THETA = 4,
    D1_THETA_Q = 7, D1_THETA_R = 8, D1_THETA_PHI = 9,
    D1_PSI_Q = 11, D1_PSI_R = 12, D1_PSI_PHI = 13, D1_PSI_THETA = 14
};

void att_bias_predict(att_bias_t *bf, const att_bias_settings_t *s, const ekf_scalar_t d1[ATT_GEN_F1_NNZ],
                      ekf_scalar_t dt)
{
    /* The angles advance by dt W(m) w with the body rates w, which contain the residual
     * offset one for one (the gyro update makes them follow the gyro): d angles+ / d b =
     * (I + dt M(m)) V + dt W(m), the angle rows of F1 on the angle and body-rate columns
     * (docs/derivation.md, "Gyroscope offset in motion"; M's yaw column is zero). The
     * Euler-rate columns are left out: the Euler rates follow the body rates within a step,
     * so their part is the same dependence once more at second order in dt. */
    const ekf_scalar_t q = ekf_mul(ekf_sq(in_units(s->walk)), dt);
    ekf_scalar_t *V = bf->V;
    int j;
    for (j = 0; j < 3; ++j) {
        const ekf_scalar_t v0 = V[j], v1 = V[3 + j];
        V[j] = ekf_mac(ekf_mac(v0, d1[D1_PHI_PHI], v0), d1[D1_PHI_THETA], v1);
        V[3 + j] = ekf_mac(v1, d1[D1_THETA_PHI], v0);
        V[6 + j] = ekf_mac(ekf_mac(V[6 + j], d1[D1_PSI_PHI], v0), d1[D1_PSI_THETA], v1);
    }
    V[0] = ekf_add(V[0], d1[D1_PHI_P]);
    V[1] = ekf_add(V[1], d1[D1_PHI_Q]);
    V[2] = ekf_add(V[2], d1[D1_PHI_R]);
    V[4] = ekf_add(V[4], d1[D1_THETA_Q]);
    V[5] = ekf_add(V[5], d1[D1_THETA_R]);
    V[7] = ekf_add(V[7], d1[D1_PSI_Q]);
    V[8] = ekf_add(V[8], d1[D1_PSI_R]);
    for (j = 0; j < 9; ++j) {
        V[j] = ekf_clamp(V[j], ekf_neg(BIAS_V_MAX), BIAS_V_MAX);
    }
    for (j = 0; j < 3; ++j) {
        bf->Pb[4 * j] = ekf_add(bf->Pb[4 * j], q);
    }
}

void att_bias_sensitivity(const att_bias_t *bf, const ekf_scalar_t h[3], ekf_scalar_t g[3])
{
    int j;
    for (j = 0; j < 3; ++j) {
        g[j] = ekf_neg(ekf_mac(ekf_mac(ekf_mul(h[0], bf->V[j]), h[1], bf->V[3 + j]), h[2], bf->V[6 + j]));
    }
}

int att_bias_update(att_bias_t *bf, int learn, const ekf_scalar_t g[3], const ekf_scalar_t k[3], ekf_scalar_t nu,
                    ekf_scalar_t s_var, ekf_scalar_t x_ang[3])
{
    ekf_scalar_t gu[3], pg[3], db[3], sb;
    int i, j, learned = 0;

    /* the EKF's update moves its error's sensitivity too: V <- (I - k h) V = V + k g^T */
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            bf->V[3 * i + j] = ekf_mac(bf->V[3 * i + j], k[i], g[j]);
        }
    }
    if (!learn) {
        return 0;
    }
    /* innovation nu = g b + (the EKF's own error and the sensor noise, variance s_var); with
     * the offset in ATT_BIAS_UNIT its sensitivity is gu = g ATT_BIAS_UNIT */
    for (i = 0; i < 3; ++i) {
        gu[i] = ekf_mul(g[i], ATT_BIAS_UNIT);
    }
    for (i = 0; i < 3; ++i) {
        pg[i] = ekf_mac(ekf_mac(ekf_mul(bf->Pb[3 * i], gu[0]), bf->Pb[3 * i + 1], gu[1]), bf->Pb[3 * i + 2], gu[2]);
    }
    sb = ekf_mac(ekf_mac(ekf_mac(s_var, gu[0], pg[0]), gu[1], pg[1]), gu[2], pg[2]);
    if (!(sb > EKF_C(0)) || !(s_var > EKF_C(0)) || ekf_sq(nu) > ekf_mul(EKF_C(9), sb)) {
        return 0;
    }
    sb = ekf_div(EKF_C(1), sb);
    for (i = 0; i < 3; ++i) {
        const ekf_scalar_t ki = ekf_mul(pg[i], sb);
        db[i] = ekf_mul(ekf_mul(ki, nu), ATT_BIAS_UNIT); /* rad/s */
        for (j = i; j < 3; ++j) {
            const ekf_scalar_t p = ekf_sub(bf->Pb[3 * i + j], ekf_mul(ki, pg[j]));
            bf->Pb[3 * i + j] = p;
            bf->Pb[3 * j + i] = p;
        }
        bf->Pb[4 * i] = ekf_max(bf->Pb[4 * i], BIAS_VAR_MIN);
    }
    /* the angles' error was V b: take the part now known out of them */
    for (i = 0; i < 3; ++i) {
        x_ang[i] = ekf_sub(x_ang[i], ekf_mac(ekf_mac(ekf_mul(bf->V[3 * i], db[0]), bf->V[3 * i + 1], db[1]),
                                             bf->V[3 * i + 2], db[2]));
        bf->b[i] = ekf_add(bf->b[i], db[i]);
        learned |= (db[i] != EKF_C(0));
    }
    return learned;
}

void att_bias_rest(att_bias_t *bf, ekf_scalar_t w, ekf_scalar_t gyro_var)
{
    /* the rest offset is the average of the raw gyro, which contains the whole offset: what
     * was learned in motion moves into it at its averaging weight, and the uncertainty is
     * that of the running average, (1 - w)^2 Pb + w^2 gyro_var */
    const ekf_scalar_t keep = ekf_sub(EKF_C(1), w);
    const ekf_scalar_t keep2 = ekf_sq(keep);
    int i;
    for (i = 0; i < 3; ++i) {
        bf->b[i] = ekf_mul(keep, bf->b[i]);
    }
    for (i = 0; i < 9; ++i) {
        bf->Pb[i] = ekf_mul(keep2, bf->Pb[i]);
    }
    for (i = 0; i < 3; ++i) {
        bf->Pb[4 * i] = ekf_max(ekf_mac(bf->Pb[4 * i], ekf_sq(w), ekf_mul(gyro_var, ekf_sq(PER_UNIT))),
                                BIAS_VAR_MIN);
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
    ekf_scalar_t vu[9], vp[9]; /* V ATT_BIAS_UNIT (rad per unit), vu Pb */
    int i, j;
    for (i = 0; i < 9; ++i) {
        vu[i] = ekf_mul(bf->V[i], ATT_BIAS_UNIT);
    }
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            vp[3 * i + j] = ekf_mac(ekf_mac(ekf_mul(vu[3 * i], bf->Pb[j]), vu[3 * i + 1], bf->Pb[3 + j]),
                                    vu[3 * i + 2], bf->Pb[6 + j]);
        }
    }
    for (i = 0; i < 6; ++i) {
        const int r = row[i], k = col[i];
        c[i] = ekf_add(c[i], ekf_mac(ekf_mac(ekf_mul(vp[3 * r], vu[3 * k]), vp[3 * r + 1], vu[3 * k + 1]),
                                     vp[3 * r + 2], vu[3 * k + 2]));
    }
}
