/*
 * att_outputs.c - the outputs of the attitude estimator (att.h): read-only accessors of the
 * state, its covariance and the reported attitude covariance, flags and diagnostics.
 */
#include "att.h"

#include "att_model.h"

void att_get_euler(const att_ekf_t *f, ekf_scalar_t euler[3])
{
    euler[0] = f->vars.x[ATT_PHI];
    euler[1] = f->vars.x[ATT_THETA];
    euler[2] = f->vars.x[ATT_PSI];
}

void att_get_body_rates(const att_ekf_t *f, ekf_scalar_t w[3])
{
    w[0] = f->vars.x[ATT_P];
    w[1] = f->vars.x[ATT_Q];
    w[2] = f->vars.x[ATT_R];
}

void att_get_gyro_bias(const att_ekf_t *f, ekf_scalar_t b[3])
{
    const ekf_scalar_t m = f->settings.rest.bias_max;
    int i;
    for (i = 0; i < 3; ++i) {
        b[i] = ekf_clamp(ekf_add(f->vars.rest.bias[i], f->vars.bias.b[i]), ekf_neg(m), m);
    }
}

void att_get_gyro_bias_sigma(const att_ekf_t *f, ekf_scalar_t sigma[3])
{
    int i;
    /* Pb is packed (00, 11, 22, ...) in units of ATT_BIAS_UNIT^2 (att_bias.h) */
    for (i = 0; i < 3; ++i) {
        sigma[i] = ekf_mul(ekf_sqrt(f->vars.bias.Pb[i]), ATT_BIAS_UNIT);
    }
}

void att_get_euler_rates(const att_ekf_t *f, ekf_scalar_t e[3])
{
    e[0] = f->vars.x[ATT_PHID];
    e[1] = f->vars.x[ATT_THETAD];
    e[2] = f->vars.x[ATT_PSID];
}

void att_get_quaternion(const att_ekf_t *f, ekf_scalar_t q[4])
{
    att_model_euler_to_quat(f->vars.x[ATT_PHI], f->vars.x[ATT_THETA], f->vars.x[ATT_PSI], q);
}

/* Beyond the gimbal limit the covariance was propagated with W at the clamped pitch, but a
 * body-frame error maps into roll and heading by the true sec(theta): their rows and columns
 * are scaled by up to cos(gimbal_limit) / |cos(theta)|, each at most so far that its variance
 * stays within heading_var_max (a congruence with a positive diagonal, so c stays positive
 * semi-definite; docs/derivation.md, "Gimbal lock"). */
static ekf_scalar_t gimbal_factor(const att_settings_t *s, ekf_scalar_t c_th, ekf_scalar_t var)
{
    const ekf_scalar_t c_lim = ekf_cos(s->gimbal_limit);
    ekf_scalar_t k_max;
    if (!(ekf_max(var, s->var_floor) < s->heading_var_max)) {
        return EKF_C(1);
    }
    k_max = ekf_sqrt(ekf_div(s->heading_var_max, ekf_max(var, s->var_floor)));
    return (ekf_mul(c_th, k_max) > c_lim) ? ekf_max(ekf_div(c_lim, c_th), EKF_C(1)) : k_max;
}

static void gimbal_scale(const att_vars_t *v, const att_settings_t *s, ekf_scalar_t c[6])
{
    ekf_scalar_t c_th, k_phi, k_psi;
    if ((v->flags & ATT_FLAG_GIMBAL_LOCK) == 0u) {
        return;
    }
    c_th = ekf_abs(ekf_cos(v->x[ATT_THETA]));
    k_phi = gimbal_factor(s, c_th, c[0]);
    k_psi = gimbal_factor(s, c_th, c[2]);
    c[0] = ekf_mul(ekf_mul(c[0], k_phi), k_phi);
    c[2] = ekf_mul(ekf_mul(c[2], k_psi), k_psi);
    c[4] = ekf_mul(ekf_mul(c[4], k_phi), k_psi);
    c[3] = ekf_mul(c[3], k_phi);
    c[5] = ekf_mul(c[5], k_psi);
}

void att_get_angle_covariance(const att_ekf_t *f, ekf_scalar_t c[6])
{
    const att_settings_t *s = &f->settings;
    const att_vars_t *v = &f->vars;
    c[0] = att_cov_var(&v->cov, ATT_PHI);
    c[1] = att_cov_var(&v->cov, ATT_THETA);
    c[2] = att_cov_var(&v->cov, ATT_PSI);
    c[3] = att_cov_get(&v->cov, ATT_PHI, ATT_THETA);
    c[4] = att_cov_get(&v->cov, ATT_PHI, ATT_PSI);
    c[5] = att_cov_get(&v->cov, ATT_THETA, ATT_PSI);
    if ((v->flags & ATT_FLAG_ALIGNED) == 0u) {
        return;
    }
    att_bias_cov(&v->bias, c);
    att_consider_add(&v->consider, c);
    c[0] = ekf_add(c[0], ekf_sq(s->accel_ref_sigma));
    c[1] = ekf_add(c[1], ekf_sq(s->accel_ref_sigma));
    if ((v->flags & ATT_FLAG_HEADING_LIMITED) == 0u && v->mag_ref_norm > EKF_C(0)) {
        c[2] = ekf_add(c[2], ekf_sq(s->mag_ref_sigma));
    }
    gimbal_scale(v, s, c);
    /* an unobserved heading is at most uniform: never report more than the cap */
    c[2] = ekf_min(c[2], s->heading_var_max);
}

void att_get_variances(const att_ekf_t *f, ekf_scalar_t var[ATT_N])
{
    ekf_scalar_t c[6];
    int i;
    for (i = 0; i < ATT_N; ++i) {
        var[i] = att_cov_var(&f->vars.cov, i);
    }
    att_get_angle_covariance(f, c);
    var[ATT_PHI] = c[0];
    var[ATT_THETA] = c[1];
    var[ATT_PSI] = c[2];
}

void att_get_covariance(const att_ekf_t *f, ekf_scalar_t P[ATT_N * ATT_N]) { att_cov_to_full(&f->vars.cov, P); }
const ekf_scalar_t *att_state(const att_ekf_t *f) { return f->vars.x; }
const att_settings_t *att_settings(const att_ekf_t *f) { return &f->settings; }
uint32_t att_flags(const att_ekf_t *f) { return f->vars.flags; }
const att_diag_t *att_diag(const att_ekf_t *f) { return &f->vars.diag; }
