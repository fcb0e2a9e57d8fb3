/*
 * att_cov_fx_words.h - the words of the fixed-point build's covariance (att_cov.h, ATT_COV_FX;
 * docs/fixed_point.md, "Covariance"): the packed index, rounding and scaling of words, the
 * exponents, the variance floor (att_cov_fx_words.c). Shared by att_cov_fx.c (storage, small
 * operations, guard) and att_cov_fx_kernels.c (propagation, updates), which both depend on
 * this module and not on each other's internals. Not part of the public API, not installed.
 *
 * P_ij = C_ij 2^(e_i + e_j - ATT_FX_CF). A variance "in the band" has C_ii in
 * [ATT_FX_C_ONE, 2^31). Words are saturated to +-INT32_MAX, never INT32_MIN (so that a
 * negation is defined). Helpers take a value v and a shift sh and return round(v 2^-sh)
 * (sh < 0: a left shift), rounding half up, saturated; none of them can overflow for any
 * int64 v and any sh.
 */
#ifndef ATT_COV_FX_WORDS_H
#define ATT_COV_FX_WORDS_H

#include "att_cov.h"

#if !defined(ATT_COV_FX)
#error "att_cov_fx_words.h belongs to the fixed-point build"
#endif

#define ATT_FX_NP (ATT_N * (ATT_N + 1) / 2)
#define ATT_FX_CF 29                             /* fraction bits of C (Q2.29) */
#define ATT_FX_C_ONE ((int32_t)1 << ATT_FX_CF)   /* c = 1, the lower edge of the band */
#define ATT_FX_E_MIN (-40)                       /* exponent of a zero variance, the smallest */
#define ATT_FX_E_MAX 24                          /* variances below 4^25 (1.1e15) */
/* Rounding allowance of a new variance, LSB of C: 32 n times the covariance's relative
 * rounding unit (2^-27 of the scale, EKF_SCALAR_EPS), as in the reference's updates. */
#define ATT_FX_TOL (32 * ATT_N * 4)

/* Packed index of (i, j) in att_cov_t.c (symmetric). */
extern const uint8_t att_fx_ix[ATT_N][ATT_N];
/* Packed index of (i, i): att_fx_ix[i][i] in one table load. */
extern const uint8_t att_fx_dg[ATT_N];

/* The few-instruction helpers of the kernels' inner loops are inlined even at -Os (a call
 * would cost more than their body on the Cortex-M3). */
#if defined(__GNUC__)
#define ATT_FX_INLINE static inline __attribute__((always_inline))
#else
#define ATT_FX_INLINE static inline
#endif

/* Bit length of v (0 for 0), of |v|. */
#define att_fx_bitlen64 ekf_fx_bitlen64
ATT_FX_INLINE int att_fx_abslen(int64_t v) { return ekf_fx_bitlen64((v < 0) ? (uint64_t)0 - (uint64_t)v : (uint64_t)v); }
/* v saturated to a word, +-INT32_MAX. */
ATT_FX_INLINE int32_t att_fx_sat(int64_t v) { return (v > INT32_MAX) ? INT32_MAX : (v < -INT32_MAX) ? -INT32_MAX : (int32_t)v; }
/* round(v 2^-sh) for sh > 0, as floor(v 2^-sh) plus the last bit shifted out: the value of
 * (v + 2^(sh-1)) >> sh without the sum, which could overflow (sh >= 63: 0). */
ATT_FX_INLINE int64_t att_fx_round_shr(int64_t v, int sh)
{
    return (sh >= 64) ? 0 : (v >> (sh - 1) >> 1) + ((v >> (sh - 1)) & 1);
}
/* round(v 2^-sh) as a C word (saturated to +-INT32_MAX): the common case inline. */
int32_t att_fx_to_c_any(int64_t v, int sh);
ATT_FX_INLINE int32_t att_fx_to_c(int64_t v, int sh)
{
    /* in 32-bit operations on v's two words: round half up as floor(v 2^-sh) plus the last
     * bit shifted out; a result at a word's edge (or beyond) takes the general path */
    const int32_t hi = (int32_t)(v >> 32);
    const uint32_t lo = (uint32_t)v;
    if (sh >= 32 && sh < 63) {
        const int k = sh - 32;
        const int32_t q = hi >> k;
        if (q > INT32_MIN && q < INT32_MAX) {
            return q + (int32_t)((k > 0) ? ((uint32_t)hi >> (k - 1)) & 1u : lo >> 31);
        }
    } else if (sh > 0 && sh < 32) {
        const int32_t q = (int32_t)((lo >> sh) | ((uint32_t)hi << (32 - sh)));
        if ((hi >> sh) == (q >> 31) && q > INT32_MIN && q < INT32_MAX) {
            return q + (int32_t)((lo >> (sh - 1)) & 1u);
        }
    } else if (sh <= 0 && sh > -31) {
        /* an exact left shift of a value that stays within the word (a word brought into a
         * smaller scale, the common case of the kernels' rescaling) */
        const int64_t lim = (int64_t)(INT32_MAX >> -sh);
        if (v <= lim && v >= -lim) {
            return (int32_t)((uint32_t)(int32_t)v << -sh);
        }
    }
    return att_fx_to_c_any(v, sh);
}
/* round(v 2^-sh) for 0 < sh < 63 and |v| < 2^62, as (v + 2^(sh-1)) >> sh, in 32-bit
 * operations on v's two words (floor plus the last bit shifted out). */
ATT_FX_INLINE int64_t att_fx_shr(int64_t v, int sh)
{
    const int32_t hi = (int32_t)(v >> 32);
    const uint32_t lo = (uint32_t)v;
    if (sh >= 32) {
        const int k = sh - 32;
        return (int64_t)(hi >> k) + (int64_t)((k > 0) ? ((uint32_t)hi >> (k - 1)) & 1u : lo >> 31);
    }
    return (int64_t)(((uint64_t)(uint32_t)(hi >> sh) << 32) | ((lo >> sh) | ((uint32_t)hi << (32 - sh)))) +
           (int64_t)((lo >> (sh - 1)) & 1u);
}
/* att_fx_to_c of a word: a right shift in 32-bit operations (round half up as
 * floor(v 2^-sh) plus the last bit shifted out, which cannot overflow). */
ATT_FX_INLINE int32_t att_fx_w(int32_t v, int sh)
{
    if (sh > 0 && sh < 32) {
        return (v >> sh) + ((v >> (sh - 1)) & 1);
    }
    return att_fx_to_c(v, sh);
}
/* round(v 2^-sh) as a Q29.34 value (saturated: infinite). */
ekf_scalar_t att_fx_to_q(int64_t v, int sh);
/* The exponent that puts the variance m 2^x (m > 0) into the band. */
int att_fx_norm_exp(uint64_t m, int x);
/* The word and exponent of the variance v (Q29.34, v != 0, finite): v = word 2^(2 e - 29). */
int32_t att_fx_norm_q(ekf_scalar_t v, int *e);
/* The band's exponent of cii 2^(2 ei - 29) + m 2^x (m >= 0, m < 2^63). */
int att_fx_sum_exp(int32_t cii, int ei, uint64_t m, int x);
/* State i's exponent set to en: row and column i rescaled (P the same, but for rounding). */
void att_fx_set_exp(att_cov_t *c, int i, int en);
/* State i back into the band if its variance is positive and below it. */
void att_fx_renorm(att_cov_t *c, int i);
/* floor (Q29.34) in the units of state i's C, rounded up; INT32_MAX if it does not fit a
 * word of that scale (every word is then at most the floor). */
int32_t att_fx_floor_c(const att_cov_t *c, int i, ekf_scalar_t floor);
/* P_ii <- max(P_ii, floor), then state i back into the band (att_fx_renorm). A floor that
 * does not fit a word of state i's scale is set in its own scale, the row and column
 * rescaled with it, so that no saturated word stands for it. */
void att_fx_floor_var(att_cov_t *c, int i, ekf_scalar_t floor);
/* State i's variance overflowed: infinite (a saturation of the format, ekf_fixed.h). */
void att_fx_overflow(att_cov_t *c, int i);
/* The words of a row of nine int64 values, with a common scale: w[j] = round(v[j] 2^-sh), sh
 * putting the largest magnitude below 2^30 (the OR of the magnitudes has its bit length).
 * Returns sh. */
int att_fx_block_row(const int64_t *v, int32_t *w);

#endif /* ATT_COV_FX_WORDS_H */
