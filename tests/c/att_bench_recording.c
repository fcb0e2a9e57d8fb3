/*
 * att_bench_recording.c - the firmware benchmark's recording (firmware/target/bench.c:
 * TS_BENCH_* of testsim.h, 3,000 samples at 100 Hz) through att_step, "t phi theta psi"
 * (s, rad) per sample into the file named by argv[1]. Built against the estimator and
 * against the same estimator with the reference covariance (ATT_COV_REFERENCE, the same
 * filter unoptimised); compare_scenarios checks that the optimisation changes no result
 * (tests/c/CMakeLists.txt, docs/performance.md "Nothing lost").
 */
#include <stdio.h>

#include "att.h"
#include "testsim.h"

#define SAMPLES 3000

int main(int argc, char **argv)
{
    static const double still[3] = {0.0, 0.0, 0.0};
    static att_ekf_t f;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    FILE *out;
    int k, errors = 0;
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
    ts_sim_init(&sim, &cfg, TS_BENCH_SEED, TS_BENCH_PHI, TS_BENCH_THETA, TS_BENCH_PSI);
    if (att_init(&f, &att_default_settings) != EKF_OK) {
        fprintf(stderr, "att_init failed\n");
        fclose(out);
        return 1;
    }
    for (k = 0; k < SAMPLES; ++k) {
        const int aligned = (att_flags(&f) & ATT_FLAG_ALIGNED) != 0u;
        double w[3];
        att_sample_t smp;
        ekf_scalar_t e[3];
        ekf_status_t st;
        ts_bench_motion(sim.t, w);
        ts_sim_step(&sim, aligned ? w : still, NULL, &smp);
        st = att_step(&f, &smp, NULL);
        errors += ekf_status_is_error(st);
        att_get_euler(&f, e);
        fprintf(out, "%.6f %.17e %.17e %.17e\n", sim.t, ekf_to_double(e[0]), ekf_to_double(e[1]), ekf_to_double(e[2]));
    }
    fclose(out);
    printf("%s: %d samples written to %s, %d refused\n", EKF_SCALAR_NAME, k, argv[1], errors);
    return errors == 0 ? 0 : 1;
}
