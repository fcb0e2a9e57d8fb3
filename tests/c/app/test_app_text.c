/*
 * test_app_text.c - the node's text protocol (firmware/app/app_text.c) over the virtual backend:
 * samples in, a CSV line per output with the header first; commands in, each answered.
 */
#include <stdio.h>
#include <string.h>

#include "app.h"
#include "app_param.h"
#include "hal_virtual.h"
#include "unity.h"

#define QLEN 256
#define MAX_LINES 400

static hal_virtual_t v;
static hal_t hal;
static app_t app;
static hal_sample_t squeue[QLEN];
static hal_line_t lqueue[16];
static char lines[MAX_LINES][160];
static int n_lines;
static int saved;

static void on_line(void *user, const char *text)
{
    (void)user;
    TEST_ASSERT_TRUE(n_lines < MAX_LINES);
    TEST_ASSERT_TRUE(strlen(text) < sizeof(lines[0]));
    strcpy(lines[n_lines++], text);
}

static int save(void *user, const app_config_t *cfg)
{
    (void)user;
    (void)cfg;
    ++saved;
    return 1;
}

void setUp(void)
{
    app_config_t cfg;
    n_lines = 0;
    saved = 0;
    hal_virtual_init(&v, NULL, 0u, squeue, QLEN, lqueue, 16u);
    hal_virtual_set_sinks(&v, NULL, on_line, NULL, NULL);
    hal_virtual_bind(&v, &hal);
    app_default_config(&cfg);
    cfg.node.protocol = APP_PROTO_TEXT;
    cfg.app.output_period_us = 0u;
    TEST_ASSERT_EQUAL_INT(EKF_OK, app_init(&app, &cfg, &hal));
}
void tearDown(void) {}

static void push_samples(int n)
{
    int k;
    for (k = 0; k < n; ++k) {
        hal_sample_t s;
        memset(&s, 0, sizeof(s));
        s.seq = (uint16_t)k;
        s.t_us = 10000u * (uint64_t)k;
        s.rx_us = s.t_us;
        s.accel[2] = 9.81f;
        s.mag[1] = 20.0f;
        s.mag[2] = -40.0f;
        s.valid = HAL_HAS_ALL;
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_sample(&v, &s));
    }
}

static void run(void)
{
    int polls = 0;
    hal_virtual_end(&v);
    while (app_poll(&app, 10000u) != HAL_END) {
        TEST_ASSERT_TRUE(++polls < 100000);
    }
}

static int find(const char *text)
{
    int i;
    for (i = 0; i < n_lines; ++i) {
        if (strcmp(lines[i], text) == 0) {
            return i;
        }
    }
    return -1;
}

static void test_csv_lines(void)
{
    unsigned seq = 99, flags = 0;
    float roll = 1.0f;
    push_samples(20);
    run();
    TEST_ASSERT_EQUAL_INT(21, n_lines);
    TEST_ASSERT_EQUAL_STRING("t_s,roll_rad,pitch_rad,yaw_rad,sigma_roll_rad,sigma_pitch_rad,sigma_yaw_rad,"
                             "rate_p_rad_s,rate_q_rad_s,rate_r_rad_s,flags,node_flags,seq",
                             lines[0]);
    TEST_ASSERT_EQUAL_STRING("0.000000,,,,,,,,,,0,0,0", lines[1]); /* not aligned: empty cells */
    TEST_ASSERT_EQUAL_INT(3, sscanf(lines[20], "0.190000,%f,%*f,%*f,%*f,%*f,%*f,%*f,%*f,%*f,%*u,%u,%u", &roll, &flags,
                                    &seq));
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 0.0f, roll);
    TEST_ASSERT_EQUAL_UINT(19u, seq);
    TEST_ASSERT_EQUAL_UINT(APP_FLAG_ALIGNED, flags);
}

static void test_commands_are_answered(void)
{
    const app_hooks_t hooks = {save, NULL, NULL, NULL};
    app_set_hooks(&app, &hooks);
    push_samples(3);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "set mag_declination 0.1"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "get mag_declination"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "set accel_lpf_order 1"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "set accel_lpf_order x"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "set nothing 1"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "set gyro_noise"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "save"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "erase"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "fly"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 5000u, "# a comment: ignored"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 15000u, "restart"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 15000u, "get accel_lpf_order"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 15000u, "list"));
    run();
    TEST_ASSERT_TRUE(find("# mag_declination 0.100000001") > 0);
    TEST_ASSERT_TRUE(find("# accel_lpf_order 1 (pending restart)") > 0);
    TEST_ASSERT_TRUE(find("# error: not a number") > 0);
    TEST_ASSERT_TRUE(find("# error: no such parameter (list)") > 0);
    TEST_ASSERT_TRUE(find("# error: set NAME VALUE") > 0);
    TEST_ASSERT_TRUE(find("# done") > 0);
    TEST_ASSERT_TRUE(find("# error: no storage here") > 0); /* erase: no hook */
    TEST_ASSERT_TRUE(find("# error: unknown command (get, set, list, save, erase, restart)") > 0);
    TEST_ASSERT_TRUE(find("# restarting") > 0);
    TEST_ASSERT_TRUE(find("# accel_lpf_order 1") > find("# restarting"));
    TEST_ASSERT_TRUE(find("# node.dbc_imu_base 256") > find("# restarting")); /* the list's last line */
    TEST_ASSERT_EQUAL_INT(1, saved);
    TEST_ASSERT_EQUAL_UINT16(1u, app_filter(&app)->settings.accel_lpf_order);
    {
        uint32_t c[APP_CNT_COUNT];
        app_get_counters(&app, c);
        TEST_ASSERT_EQUAL_UINT32(12u, c[APP_CNT_REQUESTS]);
        TEST_ASSERT_EQUAL_UINT32(5u, c[APP_CNT_REFUSED]);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_csv_lines);
    RUN_TEST(test_commands_are_answered);
    return UNITY_END();
}
