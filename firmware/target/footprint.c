/*
 * footprint.c - the smallest program that uses the whole estimator the way firmware does
 * (init, step with every sensor, the outputs), for measuring its flash and RAM with
 * arm-none-eabi-size and the link map (scripts/bench_firmware.py). Not meant to be run for
 * results; it does run (and exits 0) so that ctest can check the image is sound.
 *
 * Inputs come from volatile memory so that nothing is folded at compile time; no stdio,
 * so the image holds the estimator, the runtime and little else.
 */
#include "att.h"

volatile float fp_in[10] = {0.01f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 9.81f, 20.0f, 0.0f, -40.0f};
volatile float fp_out[16];
volatile uint32_t fp_flags;

int main(void)
{
    static att_ekf_t f;
    att_sample_t s;
    ekf_scalar_t e[3], q[4], v[ATT_N];
    int i, k;

    if (att_init(&f, &att_default_settings) != EKF_OK) {
        return 1;
    }
    for (k = 0; k < 100; ++k) {
        s.dt = ekf_from_float(fp_in[0]);
        for (i = 0; i < 3; ++i) {
            s.gyro[i] = ekf_from_float(fp_in[1 + i]);
            s.accel[i] = ekf_from_float(fp_in[4 + i]);
            s.mag[i] = ekf_from_float(fp_in[7 + i]);
        }
        s.valid = ATT_HAS_GYRO | ATT_HAS_ACCEL | ATT_HAS_MAG;
        (void)att_step(&f, &s, NULL);
    }
    att_get_euler(&f, e);
    att_get_quaternion(&f, q);
    att_get_variances(&f, v);
    for (i = 0; i < 3; ++i) {
        fp_out[i] = ekf_to_float(e[i]);
        fp_out[3 + i] = ekf_to_float(v[ATT_PHI + i]);
    }
    for (i = 0; i < 4; ++i) {
        fp_out[6 + i] = ekf_to_float(q[i]);
    }
    fp_flags = att_flags(&f);
    return (att_flags(&f) & ATT_FLAG_ALIGNED) ? 0 : 1;
}
