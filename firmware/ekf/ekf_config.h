/*
 * ekf_config.h - the one compile-time configuration header of the estimator.
 *
 * Every build option of the filter library is chosen here (or by the matching -D flag
 * from the build system). Nothing else in the library reads the preprocessor for
 * configuration.
 *
 * Scalar type (exactly one; default EKF_SCALAR_FLOAT):
 *   EKF_SCALAR_FLOAT   32-bit IEEE float. The default: what a Cortex-M4F runs natively.
 *   EKF_SCALAR_DOUBLE  64-bit IEEE double. The reference build used by the Jacobian tests.
 *   EKF_SCALAR_FIXED   signed Q-format fixed point in 64 bits (ekf_fixed.h; Q29.34 unless
 *                      EKF_FX_FRAC says otherwise), for cores without an FPU
 *                      (docs/fixed_point.md). Needs ekf_fixed.c in the library.
 *
 * Model code never names float or double: it uses ekf_scalar_t and the operations of
 * ekf_scalar.h, so that another number representation (a Q-format fixed-point type)
 * can be plugged in there without touching any model.
 */
#ifndef EKF_CONFIG_H
#define EKF_CONFIG_H

#ifdef __cplusplus
extern "C" {
#endif

#if defined(EKF_SCALAR_FLOAT) + defined(EKF_SCALAR_DOUBLE) + defined(EKF_SCALAR_FIXED) > 1
#error "ekf_config.h: define at most one of EKF_SCALAR_FLOAT, EKF_SCALAR_DOUBLE, EKF_SCALAR_FIXED"
#endif

#if !defined(EKF_SCALAR_DOUBLE) && !defined(EKF_SCALAR_FLOAT) && !defined(EKF_SCALAR_FIXED)
#define EKF_SCALAR_FLOAT 1
#endif

/* The scalar type in the link. Code compiled for one scalar type and linked against a
 * library built for another would hand every number over in the wrong representation, so
 * att.h declares att_init under the name EKF_SCALAR_LINK_NAME(att_init), which carries the
 * scalar type and which only the library of that type defines. A mismatch fails to link:
 *     undefined reference to `att_init_for_EKF_SCALAR_FLOAT'
 * names the type the calling code was compiled for (docs/porting.md, "Scalar type"). */
#if defined(EKF_SCALAR_DOUBLE)
#define EKF_SCALAR_LINK_NAME(name) name##_for_EKF_SCALAR_DOUBLE
#elif defined(EKF_SCALAR_FIXED)
#define EKF_SCALAR_LINK_NAME(name) name##_for_EKF_SCALAR_FIXED
#else
#define EKF_SCALAR_LINK_NAME(name) name##_for_EKF_SCALAR_FLOAT
#endif

/* Largest state dimension any generic routine must handle. Sizes two scratch vectors on
 * the stack of ekf_update_scalar() and one index table of ekf_cov_propagate(); the models'
 * own arrays are sized by their own constants. At most 255 (dimensions are uint8_t). */
#ifndef EKF_MAX_STATES
#define EKF_MAX_STATES 32
#endif
#if EKF_MAX_STATES > 255 || EKF_MAX_STATES < 1
#error "EKF_MAX_STATES must be in 1..255"
#endif

#ifdef __cplusplus
}
#endif

#endif /* EKF_CONFIG_H */
