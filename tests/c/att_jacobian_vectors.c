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
        ekf_scalar_t x[ATT_N], d[ATT_GEN_F_NNZ], g[9], h[3], hj[6], lev[3], er[3], br[3], m[3], dt;
        att_trig_t tm, tn, tn_own;
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
            const double half = 0.5 * ekf_to_double(dt); /* exact in double, in both builds */
            /* midpoint and advanced angles computed in double and put on the grid: the
             * Jacobian's sensitivity to the angle (~sec^3 |w|) would otherwise amplify the
             * rounding of this input step, not of the functions under test */
            const double phim = ekf_to_double(in(ekf_to_double(x[ATT_PHI]) + half * ekf_to_double(x[ATT_PHID])));
            const double thm = ekf_to_double(in(ekf_to_double(x[ATT_THETA]) + half * ekf_to_double(x[ATT_THETAD])));
            const double phin = ekf_to_double(in(ekf_to_double(x[ATT_PHI]) + ekf_to_double(dt) * ekf_to_double(x[ATT_PHID])));
            const double thn = ekf_to_double(in(ekf_to_double(x[ATT_THETA]) + ekf_to_double(dt) * ekf_to_double(x[ATT_THETAD])));
            /* this build's own trigonometry: written out and checked on its own */
            (void)att_trig(ekf_from_double(phin), ekf_from_double(thn), EKF_C(LIMIT), &tn_own);
            /* The generated functions get trigonometry computed in double and put on the
             * grid, the same inputs in both builds, so that what is compared is their own
             * arithmetic: the fixed-point sine and cosine (a few LSB off) would otherwise be
             * amplified by the functions' sensitivity to the angle, which no arrangement of
             * the arithmetic can remove. */
            grid_trig(phim, thm, &tm);
            grid_trig(phin, thn, &tn);
        }
        att_gen_transition_jacobian(&tm, &tn, x, dt, d);
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
        put(fp, d, ATT_GEN_F_NNZ);
        put(fp, g, 9);
        put(fp, h, 3);
        put(fp, hj, 6);
        put(fp, lev, 3);
        put(fp, er, 3);
        put(fp, br, 3);
    }
    fclose(fp);
    /* 71 values per state: compare_vectors's GROUP (tests/c/CMakeLists.txt) */
    if (5 + ATT_GEN_F_NNZ + 9 + 3 + 6 + 3 + 3 + 3 != 71) {
        fprintf(stderr, "values per state changed: update GROUP in tests/c/CMakeLists.txt\n");
        return 1;
    }
    printf("%s: %d states written to %s\n", EKF_SCALAR_NAME, STATES, argv[1]);
    return 0;
}
