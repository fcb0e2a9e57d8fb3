/*
 * fx_count.h - the saturations of the fixed-point arithmetic, counted in a test: the test is
 * linked with the library built with EKF_FX_SATURATION_HOOK=fx_count_saturation
 * (attekf_x_counted, COUNT_SATURATIONS in tests/CMakeLists.txt; firmware/ekf/ekf_fixed.h).
 * The count lives here, in the test, not in the library. In the float and double builds
 * nothing calls the hook and the count stays 0.
 */
#ifndef FX_COUNT_H
#define FX_COUNT_H

#include <stdint.h>

/* Saturations since the start or the last reset (stops at UINT32_MAX). */
uint32_t fx_count_saturations(void);
void fx_count_reset(void);
/* The hook ekf_fx_saturate calls. */
void fx_count_saturation(void);

#endif /* FX_COUNT_H */
