/*
 * att_scenario.c - runs one fixed, deterministic scenario through att_step and writes
 * "t phi theta psi" (s, rad) per sample to the file named by argv[1]. Built for float
 * and double; compare_scenarios checks the two outputs agree.
 *
 * Scenario (100 Hz, 150 s, sensor noise as in testsim's defaults): static, rotations about
 * changing axes up to 2 rad/s, pitch excursions to 70 deg, linear-acceleration bursts and
 * a magnetic disturbance.
 */
#include <stdio.h>

#include "att.h"
#include "testsim.h"

static void profile(double t, double w[3], double lin[3], int *mag_disturbed)
{
    const int seg = (int)(t / 10.0);
    w[0] = w[1] = w[2] = 0.0;
    lin[0] = lin[1] = lin[2] = 0.0;
    *mag_disturbed = 0;
    switch (seg) {
    case 1: w[2] = 1.0; break;
    case 2: w[0] = 0.6; w[1] = -0.3; break;
    case 3: w[1] = 0.12; break;               /* pitch up ~70 deg */
    case 4: w[1] = -0.12; w[2] = 0.8; break;  /* and back while yawing */
    case 5: w[0] = 2.0; break;
    case 6: lin[0] = 2.0 * ((int)(t * 2.0) % 2 ? 1.0 : -1.0); break;
    case 7: w[0] = 0.3; w[1] = 0.4; w[2] = -0.5; *mag_disturbed = 1; break;
    case 8: w[2] = -1.5; lin[1] = 1.0; break;
    case 10: w[0] = -0.5; w[2] = 0.5; break;
    case 12: w[1] = 0.2; w[2] = 0.3; break;
    default: break;
    }
}

int main(int argc, char **argv)
{
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_ekf_t f;
    FILE *out;
    int k;
    if (argc != 2) {
        fprintf(stderr, "usage: %s OUTPUT\n", argv[0]);
        return 2;
    }
    out = fopen(argv[1], "w");
    if (out == NULL) {
        perror(argv[1]);
        return 1;
    }
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 4242, 0.1, -0.05, 0.7);
    if (att_init(&f, &att_default_settings) != EKF_OK) {
        fprintf(stderr, "att_init failed\n");
        return 1;
    }
    for (k = 0; k < 15000; ++k) {
        double w[3], lin[3];
        int dist;
        att_sample_t smp;
        ekf_scalar_t e[3];
        profile(sim.t, w, lin, &dist);
        ts_sim_step(&sim, w, lin, &smp);
        if (dist) {
            smp.mag[0] = ekf_add(smp.mag[0], EKF_C(15)); /* hard-iron-like offset, uT */
        }
        (void)att_step(&f, &smp, NULL);
        att_get_euler(&f, e);
        fprintf(out, "%.6f %.9e %.9e %.9e\n", sim.t, ekf_to_double(e[0]), ekf_to_double(e[1]), ekf_to_double(e[2]));
    }
    fclose(out);
    printf("%s: %d samples written to %s\n", EKF_SCALAR_NAME, k, argv[1]);
    return 0;
}
