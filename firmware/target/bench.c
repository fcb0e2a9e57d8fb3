/*
 * bench.c - instructions and stack of the estimator's stages, measured on the target.
 *
 * Run under QEMU with -icount shift=8 (scripts/bench_firmware.py does): every executed
 * instruction then advances virtual time by 256 ns, and SysTick, clocked at 25 MHz, by
 * exactly 6.4 ticks. The SysTick difference around a call, divided by 6.4, is the number
 * of instructions it executed, deterministically. (Instructions, not cycles: on a real
 * Cortex-M4 loads, branches, VDIV and VSQRT take more than one cycle.)
 *
 * Inputs: 30 s at 100 Hz of simulated motion with gyroscope, accelerometer and
 * magnetometer in every sample (the benchmark recording, TS_BENCH_* of
 * tests/c/support/testsim.h, double precision, outside the measured regions). For each
 * sample after the alignment the full att_step is timed on the filter; the public stages
 * (att_update_gyro, att_predict, att_update_accel, att_update_mag, each a whole call with
 * its own guard and commit) one by one on a copy of it; and the parts of att_step one by
 * one on a third copy, in att_step's order (att.c): the saved copy of the
 * variables (the commit's cost on the normal path), the rest detector, the gyroscope,
 * prediction, accelerometer and magnetometer stages, the guard with the last finiteness
 * check. All three must end in the same state, bit for bit, or the benchmark fails; what
 * att_step spends beyond its parts (validation, the report) is printed as step_other.
 *
 * Stack: the stack below the caller is painted before each att_step and scanned after it.
 *
 * Usage: attekf_bench.elf [samples]   (default 3000; fewer for an instruction trace)
 * Output: "key value..." lines, parsed by scripts/bench_firmware.py. Exit status 0, or
 * 1 (estimator misbehaved), 2 (SysTick does not count instructions: not under -icount)
 * or 3 (bad argument).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "att.h"
#include "att_accel.h"
#include "att_gyro.h"
#include "att_mag.h"
#include "att_predict.h"
#include "att_state.h"
#include "ekf_util.h"
#include "target.h"
#include "testsim.h"

#define SAMPLES_DEFAULT 3000ul
/* Instructions are counted in ticks * 5 / 32 (6.4 ticks each). */
#define TICKS_PER_INSN_X10 64u
#define STACK_DEPTH 4096u
#define STACK_MARGIN 128u

typedef struct {
    const char *name;
    uint32_t min, max;
    uint64_t sum;
    uint32_t n;
} stat_t;

static void stat_add(stat_t *s, uint32_t insns)
{
    if (s->n == 0u || insns < s->min) {
        s->min = insns;
    }
    if (insns > s->max) {
        s->max = insns;
    }
    s->sum += insns;
    ++s->n;
}

static void stat_print(const stat_t *s)
{
    const uint32_t mean = (s->n > 0u) ? (uint32_t)((s->sum + s->n / 2u) / s->n) : 0u;
    printf("insns %s min %lu mean %lu max %lu n %lu\n", s->name, (unsigned long)s->min,
           (unsigned long)mean, (unsigned long)s->max, (unsigned long)s->n);
}

/* SysTick ticks between two counter values read in that order (it counts down). */
static uint32_t elapsed(uint32_t t0, uint32_t t1)
{
    return (t0 - t1) & TARGET_SYSTICK_MASK;
}

/* Ticks to instructions, rounded to nearest. */
static uint32_t to_insns(uint32_t ticks)
{
    return (ticks * 10u + TICKS_PER_INSN_X10 / 2u) / TICKS_PER_INSN_X10;
}

/* Cost of the measurement itself: two counter reads around nothing. */
static uint32_t baseline_ticks(void)
{
    const uint32_t t0 = TARGET_SYSTICK_NOW;
    const uint32_t t1 = TARGET_SYSTICK_NOW;
    return elapsed(t0, t1);
}

/* A loop of known length (1 + 2 * 1000 instructions). If SysTick does not count it as
 * 2001 instructions, the run is not under -icount shift=8 and every other figure would be
 * meaningless. */
static int check_calibration(uint32_t base)
{
    uint32_t t0, t1, insns;
    t0 = TARGET_SYSTICK_NOW;
    __asm__ volatile("movs r0, #250\n"
                     "lsls r0, r0, #2\n" /* 1000 */
                     "1: subs r0, r0, #1\n"
                     "bne 1b\n" ::: "r0", "cc");
    t1 = TARGET_SYSTICK_NOW;
    insns = to_insns(elapsed(t0, t1) - base);
    printf("calibration loop %lu insns (expected 2002) ticks %lu baseline ticks %lu\n",
           (unsigned long)insns, (unsigned long)elapsed(t0, t1), (unsigned long)base);
    return insns == 2002u;
}

int main(int argc, char **argv)
{
    static att_ekf_t filter, staged, parts;
    static att_vars_t saved;
    static stat_t st_predict = {"predict", 0, 0, 0, 0}, st_gyro = {"update_gyro", 0, 0, 0, 0},
                  st_accel = {"update_accel", 0, 0, 0, 0}, st_mag = {"update_mag", 0, 0, 0, 0},
                  st_step = {"step", 0, 0, 0, 0}, st_stages = {"stages_sum", 0, 0, 0, 0};
    static stat_t st_p_commit = {"part_commit", 0, 0, 0, 0}, st_p_rest = {"part_rest", 0, 0, 0, 0},
                  st_p_gyro = {"part_gyro", 0, 0, 0, 0}, st_p_predict = {"part_predict", 0, 0, 0, 0},
                  st_p_accel = {"part_accel", 0, 0, 0, 0}, st_p_mag = {"part_mag", 0, 0, 0, 0},
                  st_p_guard = {"part_guard", 0, 0, 0, 0}, st_p_other = {"step_other", 0, 0, 0, 0};
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    uint32_t base, k, max_stack = 0u, mismatches = 0u, errors = 0u;
    unsigned long samples = SAMPLES_DEFAULT;
    const uintptr_t sp = target_sp();

    if (argc > 1) {
        char *end = NULL;
        samples = strtoul(argv[1], &end, 10);
        if (end == argv[1] || *end != '\0' || samples < 20ul || samples > 1000000ul) {
            printf("error: samples must be an integer in 20..1000000, got '%s'\n", argv[1]);
            return 3;
        }
    }

    target_systick_start();
    base = baseline_ticks();
    if (!check_calibration(base)) {
        printf("error: SysTick does not count instructions; run under qemu -icount shift=8\n");
        return 2;
    }
    printf("target %s scalar %s samples %lu\n",
#if defined(__ARM_FP)
           "fpu",
#else
           "soft-float",
#endif
           EKF_SCALAR_NAME, samples);

    if (att_init(&filter, &att_default_settings) != EKF_OK) {
        printf("error: att_init failed\n");
        return 1;
    }
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, TS_BENCH_SEED, TS_BENCH_PHI, TS_BENCH_THETA, TS_BENCH_PSI);

    for (k = 0; k < samples; ++k) {
        static const double still[3] = {0.0, 0.0, 0.0};
        double w[3];
        att_sample_t s;
        att_step_report_t rep;
        ekf_status_t status;
        uint32_t t0, t1, used;
        uint32_t c_gyro, c_predict, c_accel, c_mag, c_step;

        ts_bench_motion(sim.t, w);
        ts_sim_step(&sim, (att_flags(&filter) & ATT_FLAG_ALIGNED) ? w : still, NULL, &s);
        if ((att_flags(&filter) & ATT_FLAG_ALIGNED) == 0u) {
            if (att_step(&filter, &s, NULL) != EKF_OK) {
                printf("error: alignment failed at sample %lu\n", (unsigned long)k);
                return 1;
            }
            continue;
        }
        staged = filter;
        parts = filter;

        /* the full step, with its stack */
        target_stack_paint(sp - STACK_DEPTH, sp - STACK_MARGIN);
        t0 = TARGET_SYSTICK_NOW;
        status = att_step(&filter, &s, &rep);
        t1 = TARGET_SYSTICK_NOW;
        used = (uint32_t)(sp - target_stack_lowest_touched(sp - STACK_DEPTH, sp - STACK_MARGIN));
        if (used > max_stack) {
            max_stack = used;
        }
        c_step = to_insns(elapsed(t0, t1) - base);
        stat_add(&st_step, c_step);
        if (ekf_status_is_error(status)) {
            ++errors;
        }

        /* the same stages one by one, in att_step's order */
        t0 = TARGET_SYSTICK_NOW;
        (void)att_update_gyro(&staged, s.gyro, s.dt);
        t1 = TARGET_SYSTICK_NOW;
        c_gyro = to_insns(elapsed(t0, t1) - base);
        t0 = TARGET_SYSTICK_NOW;
        (void)att_predict(&staged, s.dt);
        t1 = TARGET_SYSTICK_NOW;
        c_predict = to_insns(elapsed(t0, t1) - base);
        t0 = TARGET_SYSTICK_NOW;
        (void)att_update_accel(&staged, s.accel, s.dt);
        t1 = TARGET_SYSTICK_NOW;
        c_accel = to_insns(elapsed(t0, t1) - base);
        t0 = TARGET_SYSTICK_NOW;
        (void)att_update_mag(&staged, s.mag, s.dt);
        t1 = TARGET_SYSTICK_NOW;
        c_mag = to_insns(elapsed(t0, t1) - base);
        stat_add(&st_gyro, c_gyro);
        stat_add(&st_predict, c_predict);
        stat_add(&st_accel, c_accel);
        stat_add(&st_mag, c_mag);
        stat_add(&st_stages, c_gyro + c_predict + c_accel + c_mag);

        /* att_step's parts, in its order, on the third copy */
        {
            att_vars_t *const pv = &parts.vars;
            const att_settings_t *const set = &parts.settings;
            uint32_t c_commit, c_rest, c_guard, sum;
            int ok;
            t0 = TARGET_SYSTICK_NOW;
            att_vars_copy(&saved, pv);
            t1 = TARGET_SYSTICK_NOW;
            c_commit = to_insns(elapsed(t0, t1) - base);
            t0 = TARGET_SYSTICK_NOW;
            pv->flags &= ~ATT_FLAG_AT_REST;
            if (att_rest_update(&pv->rest, &set->rest, s.gyro, s.accel, s.dt)) {
                pv->flags |= ATT_FLAG_AT_REST;
            }
            t1 = TARGET_SYSTICK_NOW;
            c_rest = to_insns(elapsed(t0, t1) - base);
            t0 = TARGET_SYSTICK_NOW;
            (void)att_stage_gyro(pv, set, s.gyro, s.dt);
            t1 = TARGET_SYSTICK_NOW;
            c_gyro = to_insns(elapsed(t0, t1) - base);
            t0 = TARGET_SYSTICK_NOW;
            (void)att_stage_predict(pv, set, s.dt, NULL);
            ekf_count(&pv->diag.steps);
            t1 = TARGET_SYSTICK_NOW;
            c_predict = to_insns(elapsed(t0, t1) - base);
            t0 = TARGET_SYSTICK_NOW;
            (void)att_stage_accel(pv, set, s.accel, s.dt);
            t1 = TARGET_SYSTICK_NOW;
            c_accel = to_insns(elapsed(t0, t1) - base);
            t0 = TARGET_SYSTICK_NOW;
            (void)att_stage_mag(pv, set, s.mag, s.dt);
            t1 = TARGET_SYSTICK_NOW;
            c_mag = to_insns(elapsed(t0, t1) - base);
            t0 = TARGET_SYSTICK_NOW;
            ok = att_guard_covariance(pv, set) == EKF_OK && ekf_all_finite(pv->x, ATT_N);
            t1 = TARGET_SYSTICK_NOW;
            c_guard = to_insns(elapsed(t0, t1) - base);
            if (!ok) {
                ++errors;
            }
            stat_add(&st_p_commit, c_commit);
            stat_add(&st_p_rest, c_rest);
            stat_add(&st_p_gyro, c_gyro);
            stat_add(&st_p_predict, c_predict);
            stat_add(&st_p_accel, c_accel);
            stat_add(&st_p_mag, c_mag);
            stat_add(&st_p_guard, c_guard);
            sum = c_commit + c_rest + c_gyro + c_predict + c_accel + c_mag + c_guard;
            stat_add(&st_p_other, (c_step > sum) ? c_step - sum : 0u);
        }
        {
            static ekf_scalar_t P_staged[ATT_N * ATT_N], P_filter[ATT_N * ATT_N];
            att_get_covariance(&staged, P_staged);
            att_get_covariance(&filter, P_filter);
            if (memcmp(att_state(&staged), att_state(&filter), sizeof(ekf_scalar_t) * ATT_N) != 0 ||
                memcmp(P_staged, P_filter, sizeof P_filter) != 0 || memcmp(&parts, &filter, sizeof parts) != 0) {
                ++mismatches;
            }
        }
    }

    stat_print(&st_predict);
    stat_print(&st_gyro);
    stat_print(&st_accel);
    stat_print(&st_mag);
    stat_print(&st_step);
    stat_print(&st_stages);
    stat_print(&st_p_commit);
    stat_print(&st_p_rest);
    stat_print(&st_p_gyro);
    stat_print(&st_p_predict);
    stat_print(&st_p_accel);
    stat_print(&st_p_mag);
    stat_print(&st_p_guard);
    stat_print(&st_p_other);
    {
        const att_diag_t *d = att_diag(&filter);
        double e[3];
        ekf_scalar_t est[3];
        double ed[3];
        att_get_euler(&filter, est);
        ed[0] = ekf_to_double(est[0]);
        ed[1] = ekf_to_double(est[1]);
        ed[2] = ekf_to_double(est[2]);
        ts_sim_euler(&sim, e);
        printf("fused gyro %lu accel %lu mag %lu skipped accel %lu mag %lu gated gyro %lu accel %lu mag %lu\n",
               (unsigned long)d->gyro_fused, (unsigned long)d->accel_fused, (unsigned long)d->mag_fused,
               (unsigned long)d->accel_skipped, (unsigned long)d->mag_skipped, (unsigned long)d->gyro_gated,
               (unsigned long)d->accel_gated, (unsigned long)d->mag_gated);
        printf("final attitude error %.4f deg\n", ts_euler_angle_between(ed, e) * 57.29577951308232);
    }
    printf("stack step_max %lu\n", (unsigned long)max_stack);
    if (max_stack >= STACK_DEPTH) {
        printf("error: att_step used the whole %u-byte stack probe: its stack is at least that\n",
               STACK_DEPTH);
        return 1;
    }
    printf("stack image_high_water %lu of %lu\n", (unsigned long)target_stack_high_water(),
           (unsigned long)target_stack_size());
    printf("memory state_x_P %lu filter_struct %lu settings %lu\n",
           (unsigned long)(sizeof filter.vars.x + sizeof filter.vars.cov), (unsigned long)sizeof filter,
           (unsigned long)sizeof filter.settings);
    if (errors > 0u || mismatches > 0u) {
        printf("error: %lu steps failed, %lu staged or part-by-part runs differ from att_step\n", (unsigned long)errors,
               (unsigned long)mismatches);
        return 1;
    }
    return 0;
}
