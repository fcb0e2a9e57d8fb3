/*
 * fw_main.c - the firmware: the estimator application (firmware/app) on the target HAL
 * backend (hal_target.c), over a recording, with the application's text protocol: a CSV
 * line per output, commands from an optional command file answered in the same output.
 *
 *   attekf_fw.elf <recording.csv> <output.csv> [commands.txt]   (under QEMU: qemu_run.sh)
 *   attekf-fw-host <recording.csv> <output.csv> [commands.txt]  the same program for the host
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

/* Heartbeat outputs (not written: they repeat the last estimate). */
static void count_heartbeats(void *user, const app_output_t *out)
{
    if (out->kind == APP_OUT_HEARTBEAT) {
        hal_count((uint32_t *)user);
    }
}

int main(int argc, char **argv)
{
    static app_t app;
    static hal_target_t backend;
    app_config_t cfg;
    app_hooks_t hooks = {NULL, NULL, count_heartbeats, NULL};
    uint32_t counters[APP_CNT_COUNT];
    uint32_t heartbeats = 0u;
    hal_t hal;
    ekf_status_t st;
    hal_status_t hs;
    int rc = 0;

    if (argc != 3 && argc != 4) {
        fprintf(stderr, "usage: %s <recording.csv> <output.csv> [commands.txt]\n", argc > 0 ? argv[0] : "attekf_fw");
        return 2;
    }
    if (hal_target_open(&backend, argv[1], argv[2], argc == 4 ? argv[3] : NULL) != HAL_OK) {
        return 1;
    }
    hal_target_bind(&backend, &hal);
    app_default_config(&cfg);
    cfg.app.output_period_us = 0u; /* every sample */
    cfg.node.protocol = APP_PROTO_TEXT; /* samples come from the backend */
    st = app_init(&app, &cfg, &hal);
    if (st != EKF_OK) {
        fprintf(stderr, "app_init: %s\n", ekf_status_str(st));
        (void)hal_target_close(&backend);
        return 1;
    }
    hooks.user = &heartbeats;
    app_set_hooks(&app, &hooks);
    do {
        hs = app_poll(&app, 10000u);
    } while (hs != HAL_END);

    app_get_counters(&app, counters);
    if (hal_target_close(&backend) != HAL_OK || hal_target_errors(&backend) != 0u) {
        rc = 1;
    }
    printf("samples %" PRIu32 " outputs %" PRIu32 " lines %" PRIu32 " heartbeats %" PRIu32 " requests %" PRIu32
           " ekf_rejected %" PRIu32 " realign %" PRIu32 " gaps %" PRIu32 " errors %" PRIu32 "\n",
           counters[APP_CNT_SAMPLES], counters[APP_CNT_OUTPUTS], counters[APP_CNT_TX_FRAMES], heartbeats,
           counters[APP_CNT_REQUESTS], counters[APP_CNT_EKF_REJECTED], counters[APP_CNT_REALIGN],
           counters[APP_CNT_GAPS], hal_target_errors(&backend));
#if defined(ATTEKF_BARE_METAL)
    printf("stack high-water %lu of %lu bytes\n", (unsigned long)target_stack_high_water(),
           (unsigned long)target_stack_size());
#endif
    return rc;
}
