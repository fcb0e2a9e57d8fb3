/*
 * att_jacobian_vectors.c - the generated model functions (att_gen.c) and the trigonometry
 * (att_trig) at 2,000 deterministic random states, one value per line, to the file named by
 * argv[1]. Built for double and fixed point, with the inputs on the Q29.34 grid in both;
 * compare_vectors checks the fixed-point outputs against double within a bound in units of
 * the Q format's resolution (docs/fixed_point.md, "Accuracy").
 *
 * States: angles uniform (pitch up to the 85 deg gimbal limit, a tenth of them within 1 deg
 * of it), body and Euler rates within +-40 rad/s (a tenth exactly at rest), dt 1 .. 10 ms.
 */
#include <math.h>
#include <stdio.h>

#include "att_gen.h"
#include "att_model.h"
#include "testsim.h"

#define STATES 2000
#define LIMIT 1.4835298641951802 /* 85 deg */

/* Inputs on the Q29.34 grid, so that both builds evaluate exactly the same state. */
static ekf_scalar_t in(double v) { return ekf_from_double(floor(v * 17179869184.0 + 0.5) / 17179869184.0); }

static void put(FILE *fp, const ekf_scalar_t *v, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        fprintf(fp, "%.17g\n", ekf_to_double(v[i]));
    }
}

/* C = Exp([u]x) and Jr(u) dt in double, on the grid (att_model_rotation's formulas, written
 * out in double: the inputs, not what is checked here). */
static void grid_rotation(const double u[3], double dt, ekf_scalar_t C[9], ekf_scalar_t J[9])
{
    const double th2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2], th = sqrt(th2);
    const double a = (th > 1e-6) ? sin(th) / th : 1.0 - th2 / 6.0;
    const double b = (th > 1e-4) ? (1.0 - cos(th)) / th2 : 0.5 - th2 / 24.0;
    const double c = (th > 1e-3) ? (th - sin(th)) / (th2 * th) : 1.0 / 6.0 - th2 / 120.0;
    const double U[9] = {0.0, -u[2], u[1], u[2], 0.0, -u[0], -u[1], u[0], 0.0};
    int i, j;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            const double u2 = u[i] * u[j] - ((i == j) ? th2 : 0.0), one = (i == j) ? 1.0 : 0.0;
            C[3 * i + j] = in(one + a * U[3 * i + j] + b * u2);
            J[3 * i + j] = in((one - b * U[3 * i + j] + c * u2) * dt);
        }
    }
}

/* Trigonometry of (phi, theta) computed in double (pitch clamped to the limit, as att_trig
 * does) and put on the grid. */
static void grid_trig(double phi, double theta, att_trig_t *out)
{
    theta = theta > LIMIT ? LIMIT : theta < -LIMIT ? -LIMIT : theta;
    out->sphi = in(sin(phi));
    out->cphi = in(cos(phi));
    out->sth = in(sin(theta));
    out->cth = in(cos(theta));
    out->secth = in(1.0 / cos(theta));
}

int main(int argc, char **argv)
{
    ts_rng_t r;
    FILE *fp;
    int k, i;
    if (argc != 2) {
        fprintf(stderr, "usage: %s OUTPUT\n", argv[0]);
        return 2;
    }
    fp = fopen(argv[1], "w");
    if (fp == NULL) {
        perror(argv[1]);
        return 1;
    }
    ts_rng_seed(&r, 31337);
    for (k = 0; k < STATES; ++k) {
        ekf_scalar_t x[ATT_N], d1[ATT_GEN_F1_NNZ], d2[ATT_GEN_F2_NNZ], g[9], h[3], hj[6], lev[3], er[3], br[3], m[3];
        ekf_scalar_t dt, rot[9], jd[9];
        att_trig_t tb, tn, tn_own;
        const int rest = (k % 10) == 0, edge = (k % 10) == 1;
        for (i = 0; i < 3; ++i) {
            x[ATT_P + i] = rest ? EKF_C(0) : in(ts_uniform_in(&r, -40.0, 40.0));
            x[ATT_PHID + i] = rest ? EKF_C(0) : in(ts_uniform_in(&r, -40.0, 40.0));
            m[i] = in(ts_uniform_in(&r, -60.0, 60.0));
        }
        x[ATT_PHI] = in(ts_uniform_in(&r, -3.14159, 3.14159));
        x[ATT_THETA] = in(edge ? ts_uniform_in(&r, LIMIT - 0.0175, LIMIT) * (k % 20 == 1 ? -1.0 : 1.0)
                                            : ts_uniform_in(&r, -LIMIT, LIMIT));
        x[ATT_PSI] = in(ts_uniform_in(&r, -3.14159, 3.14159));
        dt = in(ts_uniform_in(&r, 0.001, 0.01));
        {
            /* angles before and after the step computed in double and put on the grid: the
             * Jacobian's sensitivity to the angle (~sec^3 |w|) would otherwise amplify the
             * rounding of this input step, not of the functions under test */
            const double u[3] = {ekf_to_double(x[ATT_P]) * ekf_to_double(dt), ekf_to_double(x[ATT_Q]) * ekf_to_double(dt),
                                 ekf_to_double(x[ATT_R]) * ekf_to_double(dt)};
            const double phin = ekf_to_double(in(ekf_to_double(x[ATT_PHI]) + ekf_to_double(dt) * ekf_to_double(x[ATT_PHID])));
            const double thn = ekf_to_double(in(ekf_to_double(x[ATT_THETA]) + ekf_to_double(dt) * ekf_to_double(x[ATT_THETAD])));
            /* this build's own trigonometry: written out and checked on its own */
            (void)att_trig(ekf_from_double(phin), ekf_from_double(thn), EKF_C(LIMIT), &tn_own);
            /* The generated functions get trigonometry computed in double and put on the
             * grid, the same inputs in both builds, so that what is compared is their own
             * arithmetic: the fixed-point sine and cosine (a few LSB off) would otherwise be
             * amplified by the functions' sensitivity to the angle, which no arrangement of
             * the arithmetic can remove. */
            grid_trig(ekf_to_double(x[ATT_PHI]), ekf_to_double(x[ATT_THETA]), &tb);
            grid_trig(phin, thn, &tn);
            grid_rotation(u, ekf_to_double(dt), rot, jd);
        }
        att_gen_transition_factors(&tb, &tn, x, rot, jd, d1, d2);
        att_gen_noise_jacobian(&tn, g);
        att_gen_accel_h(&tn, h);
        att_gen_accel_jacobian(&tn, hj);
        att_gen_mag_level(&tn, m, lev);
        att_gen_euler_rates(&tn, &x[ATT_P], er);
        att_gen_body_rates(&tn, &x[ATT_PHID], br);
        tn = tn_own;
        put(fp, &tn.sphi, 1);
        put(fp, &tn.cphi, 1);
        put(fp, &tn.sth, 1);
        put(fp, &tn.cth, 1);
        put(fp, &tn.secth, 1);
        put(fp, d1, ATT_GEN_F1_NNZ);
        put(fp, d2, ATT_GEN_F2_NNZ);
        put(fp, g, 9);
        put(fp, h, 3);
        put(fp, hj, 6);
        put(fp, lev, 3);
        put(fp, er, 3);
        put(fp, br, 3);
    }
    fclose(fp);
    /* 65 values per state: compare_vectors's GROUP (tests/c/CMakeLists.txt) */
    if (5 + ATT_GEN_F1_NNZ + ATT_GEN_F2_NNZ + 9 + 3 + 6 + 3 + 3 + 3 != 65) {
        fprintf(stderr, "values per state changed: update GROUP in tests/c/CMakeLists.txt\n");
        return 1;
    }
    printf("%s: %d states written to %s\n", EKF_SCALAR_NAME, STATES, argv[1]);
    return 0;
}
