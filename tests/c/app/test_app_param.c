/*
 * test_app_param.c - the node's parameters (firmware/app/app_param.c): one list of the filter's
 * settings and the node's, found by name, their ranges and the checks between them, the
 * configuration lines (exact round trip, every refusal named), and a running node's live and
 * pending changes, applied by a restart.
 */
#include <math.h>
#include <string.h>

#include "app.h"
#include "app_param.h"
#include "hal_virtual.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static void test_the_list(void)
{
    const size_t n = app_param_count();
    size_t i, j;
    TEST_ASSERT_TRUE(n > att_setting_count());
    for (i = 0; i < n; ++i) {
        app_param_info_t a, b;
        app_config_t d;
        float v;
        TEST_ASSERT_EQUAL_INT(1, app_param_info(i, &a));
        TEST_ASSERT_NOT_NULL(a.name);
        TEST_ASSERT_EQUAL_INT((int)i, app_param_index(a.name));
        TEST_ASSERT_TRUE(a.lo <= a.def && a.def <= a.hi);
        /* the default is what app_default_config holds */
        app_default_config(&d);
        TEST_ASSERT_EQUAL_INT(1, app_config_get(&d, i, &v));
        TEST_ASSERT_EQUAL_FLOAT(a.def, v);
        for (j = i + 1u; j < n; ++j) {
            TEST_ASSERT_EQUAL_INT(1, app_param_info(j, &b));
            TEST_ASSERT_TRUE(strcmp(a.name, b.name) != 0);
        }
        if (i < att_setting_count()) {
            TEST_ASSERT_EQUAL_STRING(att_setting_info(i)->name, a.name);
            TEST_ASSERT_EQUAL_UINT8(att_setting_info(i)->live, a.live);
        }
    }
    TEST_ASSERT_EQUAL_INT(0, app_param_info(n, NULL));
    TEST_ASSERT_EQUAL_INT(-1, app_param_index("no.such"));
    TEST_ASSERT_EQUAL_INT(-1, app_param_index(NULL));
    TEST_ASSERT_TRUE(app_param_index("node.id") >= (int)att_setting_count());
}

static void test_config_set_checks_ranges_and_consistency(void)
{
    app_config_t c;
    const size_t gyro = (size_t)app_param_index("gyro_noise");
    const size_t order = (size_t)app_param_index("accel_lpf_order");
    const size_t id = (size_t)app_param_index("node.id");
    const size_t base = (size_t)app_param_index("node.dbc_base");
    const size_t gap = (size_t)app_param_index("app.max_gap_ms");
    const size_t dt = (size_t)app_param_index("dt_max");
    float v;
    app_default_config(&c);
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_config_set(&c, gyro, 0.001f));
    TEST_ASSERT_EQUAL_FLOAT(0.001f, c.att.gyro_noise);
    TEST_ASSERT_EQUAL_INT(APP_PARAM_RANGE, app_config_set(&c, gyro, -1.0f));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_RANGE, app_config_set(&c, gyro, NAN));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_RANGE, app_config_set(&c, order, 1.5f)); /* a count */
    TEST_ASSERT_EQUAL_INT(APP_PARAM_RANGE, app_config_set(&c, order, 3.0f));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_config_set(&c, order, 1.0f));
    TEST_ASSERT_EQUAL_UINT16(1u, c.att.accel_lpf_order);
    TEST_ASSERT_EQUAL_INT(APP_PARAM_RANGE, app_config_set(&c, id, 0.0f));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_config_set(&c, id, 42.0f));
    TEST_ASSERT_EQUAL_UINT8(42u, c.node.node_id);
    /* inconsistent with another parameter: the node's frames on the IMU's */
    TEST_ASSERT_EQUAL_INT(APP_PARAM_RANGE, app_config_set(&c, base, 257.0f));
    TEST_ASSERT_EQUAL_UINT16(0x180u, c.node.dbc_base);
    /* a gap too long for dt_max: refused either way round */
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_config_set(&c, dt, 0.01f));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_RANGE, app_config_set(&c, gap, 20000.0f));
    TEST_ASSERT_EQUAL_INT(1, app_config_get(&c, gap, &v));
    TEST_ASSERT_EQUAL_FLOAT(2000.0f, v);
    TEST_ASSERT_EQUAL_UINT32(2000000u, c.app.max_gap_us); /* ms in the parameter, us inside */
    TEST_ASSERT_EQUAL_INT(APP_PARAM_NO_SUCH, app_config_set(&c, app_param_count(), 1.0f));
}

typedef struct {
    char lines[80][128];
    int n;
} lines_t;

static int keep_line(void *user, const char *line)
{
    lines_t *l = (lines_t *)user;
    TEST_ASSERT_TRUE(l->n < 80);
    strcpy(l->lines[l->n++], line);
    return 1;
}

static int refuse_line(void *user, const char *line)
{
    (void)user;
    (void)line;
    return 0;
}

/* Lines of the non-default parameters read back to exactly the same configuration. */
static void test_lines_round_trip(void)
{
    static lines_t l;
    app_config_t a, b;
    char err[160];
    size_t i;
    int k;
    app_default_config(&a);
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_config_set(&a, (size_t)app_param_index("gyro_noise"), 3.3333333e-4f));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_config_set(&a, (size_t)app_param_index("mag_declination"), -0.1234567f));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_config_set(&a, (size_t)app_param_index("rest.bias_tau"), 12.5f));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_config_set(&a, (size_t)app_param_index("node.protocol"), 1.0f));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_config_set(&a, (size_t)app_param_index("app.output_period_us"), 2500.0f));
    l.n = 0;
    TEST_ASSERT_EQUAL_INT(1, app_config_write(&a, keep_line, &l));
    TEST_ASSERT_EQUAL_INT(5, l.n);
    app_default_config(&b);
    for (k = 0; k < l.n; ++k) {
        TEST_ASSERT_EQUAL_INT_MESSAGE(1, app_config_read_line(&b, l.lines[k], err, sizeof(err)), l.lines[k]);
    }
    for (i = 0; i < app_param_count(); ++i) {
        float x, y;
        TEST_ASSERT_EQUAL_INT(1, app_config_get(&a, i, &x));
        TEST_ASSERT_EQUAL_INT(1, app_config_get(&b, i, &y));
        TEST_ASSERT_EQUAL_MEMORY(&x, &y, sizeof(x));
    }
    TEST_ASSERT_EQUAL_INT(0, app_config_write(&a, refuse_line, NULL));
}

static void test_bad_lines_say_why(void)
{
    app_config_t c, d;
    char err[160];
    app_default_config(&c);
    d = c;
    TEST_ASSERT_EQUAL_INT(0, app_config_read_line(&c, "   # a comment", err, sizeof(err)));
    TEST_ASSERT_EQUAL_INT(0, app_config_read_line(&c, "\n", err, sizeof(err)));
    TEST_ASSERT_EQUAL_INT(1, app_config_read_line(&c, "  gyro_noise   0.0005  \r\n", err, sizeof(err)));
    TEST_ASSERT_EQUAL_INT(-1, app_config_read_line(&c, "gyro_nois 0.1", err, sizeof(err)));
    TEST_ASSERT_NOT_NULL(strstr(err, "no parameter 'gyro_nois'"));
    TEST_ASSERT_EQUAL_INT(-1, app_config_read_line(&c, "gyro_noise", err, sizeof(err)));
    TEST_ASSERT_NOT_NULL(strstr(err, "not a number"));
    TEST_ASSERT_EQUAL_INT(-1, app_config_read_line(&c, "gyro_noise 0.1 0.2", err, sizeof(err)));
    TEST_ASSERT_EQUAL_INT(-1, app_config_read_line(&c, "gyro_noise 1e9", err, sizeof(err)));
    TEST_ASSERT_NOT_NULL(strstr(err, "outside"));
    TEST_ASSERT_EQUAL_INT(-1, app_config_read_line(&c, "node.id 1.5", err, sizeof(err)));
    TEST_ASSERT_NOT_NULL(strstr(err, "whole number"));
    TEST_ASSERT_EQUAL_FLOAT(0.0005f, c.att.gyro_noise); /* only the good line changed it */
    c.att.gyro_noise = d.att.gyro_noise;
    TEST_ASSERT_EQUAL_MEMORY(&d, &c, sizeof(c));
}

/* A running node: live parameters at once, the others at the restart; the pending value is what
 * a read gives, and setting back the value in force withdraws it. */
static void test_live_and_pending_on_a_running_node(void)
{
    static hal_virtual_t v;
    static app_t app;
    hal_t hal;
    app_config_t cfg;
    const size_t decl = (size_t)app_param_index("mag_declination");
    const size_t order = (size_t)app_param_index("accel_lpf_order");
    const size_t period = (size_t)app_param_index("app.output_period_us");
    const size_t id = (size_t)app_param_index("node.id");
    float x;
    hal_virtual_init(&v, NULL, 0u, NULL, 0u, NULL, 0u);
    hal_virtual_bind(&v, &hal);
    app_default_config(&cfg);
    TEST_ASSERT_EQUAL_INT(EKF_OK, app_init(&app, &cfg, &hal));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_param_set(&app, decl, 0.2f));
    TEST_ASSERT_EQUAL_FLOAT(0.2f, app_filter(&app)->settings.mag_declination);
    TEST_ASSERT_EQUAL_INT(APP_PARAM_OK, app_param_set(&app, period, 2500.0f));
    TEST_ASSERT_EQUAL_UINT32(2500u, app.settings.output_period_us);
    TEST_ASSERT_EQUAL_INT(APP_PARAM_PENDING, app_param_set(&app, order, 1.0f));
    TEST_ASSERT_EQUAL_UINT16(2u, app_filter(&app)->settings.accel_lpf_order);
    TEST_ASSERT_EQUAL_INT(1, app_param_get(&app, order, &x));
    TEST_ASSERT_EQUAL_FLOAT(1.0f, x);
    TEST_ASSERT_EQUAL_INT(APP_PARAM_PENDING, app_param_set(&app, id, 7.0f));
    TEST_ASSERT_EQUAL_UINT8(2u, app.n_pending);
    TEST_ASSERT_EQUAL_INT(APP_PARAM_PENDING, app_param_set(&app, id, 100.0f)); /* back: withdrawn */
    TEST_ASSERT_EQUAL_UINT8(1u, app.n_pending);
    TEST_ASSERT_EQUAL_INT(APP_PARAM_RANGE, app_param_set(&app, order, 5.0f));
    TEST_ASSERT_EQUAL_INT(APP_PARAM_NO_SUCH, app_param_set(&app, app_param_count(), 1.0f));
    app_restart(&app);
    TEST_ASSERT_EQUAL_UINT16(1u, app_filter(&app)->settings.accel_lpf_order);
    TEST_ASSERT_EQUAL_FLOAT(0.2f, app_filter(&app)->settings.mag_declination); /* live ones kept */
    TEST_ASSERT_EQUAL_UINT32(2500u, app.settings.output_period_us);
    TEST_ASSERT_EQUAL_UINT8(0u, app.n_pending);
    TEST_ASSERT_EQUAL_UINT8(100u, app.node.node_id);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_the_list);
    RUN_TEST(test_config_set_checks_ranges_and_consistency);
    RUN_TEST(test_lines_round_trip);
    RUN_TEST(test_bad_lines_say_why);
    RUN_TEST(test_live_and_pending_on_a_running_node);
    return UNITY_END();
}
