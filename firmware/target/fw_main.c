/*
 * fw_main.c - the firmware: the estimator application (firmware/app) on the target HAL
 * backend (hal_target.c), over a recording.
 *
 *   attekf_fw.elf <recording.csv> <output.csv>      (under QEMU: firmware/target/qemu_run.sh)
 *   attekf-fw-host <recording.csv> <output.csv>     the same program built for the host
 *
 * An output row per input sample (output_period_us = 0), so that the firmware's and the
 * host's results can be compared sample by sample. Prints a summary line (and, on the
 * target, the stack high-water mark) and exits 0, or 1 if the input or output failed,
 * 2 on bad usage.
 */
#include <inttypes.h>
#include <stdio.h>

#include "app.h"
#include "hal_target.h"
#if defined(ATTEKF_BARE_METAL)
#include "target.h"
#endif

int main(int argc, char **argv)
{
    static app_t app;
    static hal_target_t backend;
    app_settings_t settings = app_default_settings;
    uint32_t counters[HAL_CNT_COUNT];
    hal_t hal;
    ekf_status_t st;
    hal_status_t hs;
    int rc = 0;

    if (argc != 3) {
        fprintf(stderr, "usage: %s <recording.csv> <output.csv>\n", argc > 0 ? argv[0] : "attekf_fw");
        return 2;
    }
    if (hal_target_open(&backend, argv[1], argv[2]) != HAL_OK) {
        return 1;
    }
    hal_target_bind(&backend, &hal);
    settings.output_period_us = 0u; /* every sample */
    st = app_init(&app, &settings, &att_default_settings, &hal);
    if (st != EKF_OK) {
        fprintf(stderr, "app_init: %s\n", ekf_status_str(st));
        (void)hal_target_close(&backend);
        return 1;
    }
    do {
        hs = app_poll(&app, 10000u);
    } while (hs != HAL_END);

    app_get_counters(&app, counters);
    if (hal_target_close(&backend) != HAL_OK || hal_target_errors(&backend) != 0u) {
        rc = 1;
    }
    printf("samples %" PRIu32 " outputs %" PRIu32 " written %" PRIu32 " heartbeats %" PRIu32
           " ekf_rejected %" PRIu32 " realign %" PRIu32 " gaps %" PRIu32 " errors %" PRIu32 "\n",
           counters[HAL_CNT_SAMPLES], counters[HAL_CNT_OUTPUTS], backend.written, backend.heartbeats,
           counters[HAL_CNT_EKF_REJECTED], counters[HAL_CNT_REALIGN], counters[HAL_CNT_GAPS],
           hal_target_errors(&backend));
#if defined(ATTEKF_BARE_METAL)
    printf("stack high-water %lu of %lu bytes\n", (unsigned long)target_stack_high_water(),
           (unsigned long)target_stack_size());
#endif
    return rc;
}
