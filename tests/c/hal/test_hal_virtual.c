/*
 * test_hal_virtual.c - the virtual backend (hal/virtual/hal_virtual.c): inputs of the three kinds
 * in time order on a simulated clock, the end of input, full queues, a link that goes down and a
 * transmitter that fails, every count.
 */
#include <string.h>

#include "hal_virtual.h"
#include "unity.h"

static hal_virtual_t v;
static hal_t hal;
static hal_frame_t frames[4];
static hal_sample_t samples[4];
static hal_line_t lines[2];
static int sent_frames, sent_lines;

static void on_frame(void *user, const hal_frame_t *f)
{
    (void)user;
    TEST_ASSERT_EQUAL_UINT64(hal_virtual_now_us(&v), f->t_us); /* stamped when sent */
    ++sent_frames;
}

static void on_line(void *user, const char *text)
{
    (void)user;
    TEST_ASSERT_EQUAL_STRING("hello", text);
    ++sent_lines;
}

void setUp(void)
{
    sent_frames = sent_lines = 0;
    hal_virtual_init(&v, frames, 4u, samples, 4u, lines, 2u);
    hal_virtual_set_sinks(&v, on_frame, on_line, NULL, NULL);
    hal_virtual_bind(&v, &hal);
}
void tearDown(void) {}

static void test_inputs_in_time_order_on_the_simulated_clock(void)
{
    hal_frame_t f;
    hal_sample_t s;
    hal_input_t in;
    memset(&f, 0, sizeof(f));
    memset(&s, 0, sizeof(s));
    f.t_us = 3000u;
    s.rx_us = 2000u;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_frame(&v, &f));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_sample(&v, &s));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 1000u, "get x"));
    TEST_ASSERT_EQUAL_INT(HAL_EMPTY, hal_receive(&hal, &in, 500u)); /* nothing yet: time passes */
    TEST_ASSERT_EQUAL_UINT64(500u, hal_now_us(&hal));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_receive(&hal, &in, 10000u));
    TEST_ASSERT_EQUAL_UINT8(HAL_IN_LINE, in.kind);
    TEST_ASSERT_EQUAL_STRING("get x", in.u.line.text);
    TEST_ASSERT_EQUAL_UINT64(1000u, hal_now_us(&hal));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_receive(&hal, &in, 10000u));
    TEST_ASSERT_EQUAL_UINT8(HAL_IN_SAMPLE, in.kind);
    TEST_ASSERT_EQUAL_UINT64(2000u, hal_now_us(&hal));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_receive(&hal, &in, 10000u));
    TEST_ASSERT_EQUAL_UINT8(HAL_IN_FRAME, in.kind);
    TEST_ASSERT_EQUAL_UINT64(3000u, hal_now_us(&hal));
    TEST_ASSERT_EQUAL_INT(HAL_EMPTY, hal_receive(&hal, &in, 10000u));
    TEST_ASSERT_EQUAL_UINT64(13000u, hal_now_us(&hal));
    hal_virtual_end(&v);
    TEST_ASSERT_EQUAL_INT(HAL_END, hal_receive(&hal, &in, 10000u));
    {
        hal_link_stats_t st;
        hal_get_stats(&hal, &st);
        TEST_ASSERT_EQUAL_UINT32(3u, st.rx_frames);
    }
}

static void test_full_queues_and_long_lines(void)
{
    hal_frame_t f;
    hal_link_stats_t st;
    char longline[HAL_LINE_MAX + 1];
    int k;
    memset(&f, 0, sizeof(f));
    for (k = 0; k < 4; ++k) {
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_frame(&v, &f));
    }
    TEST_ASSERT_EQUAL_UINT(0u, hal_virtual_frame_space(&v));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_FULL, hal_virtual_push_frame(&v, &f));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 0u, "a"));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_line(&v, 0u, "b"));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_FULL, hal_virtual_push_line(&v, 0u, "c"));
    memset(longline, 'x', sizeof(longline) - 1u);
    longline[HAL_LINE_MAX] = '\0';
    TEST_ASSERT_EQUAL_INT(HAL_ERR_ARG, hal_virtual_push_line(&v, 0u, longline));
    hal_get_stats(&hal, &st);
    TEST_ASSERT_EQUAL_UINT32(2u, st.rx_overflow);
}

static void test_link_down_and_transmit_failures(void)
{
    hal_frame_t f[3];
    hal_input_t in;
    hal_link_stats_t st;
    memset(f, 0, sizeof(f));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_send_frames(&hal, f, 3u));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_write_line(&hal, "hello"));
    TEST_ASSERT_EQUAL_INT(3, sent_frames);
    TEST_ASSERT_EQUAL_INT(1, sent_lines);
    hal_virtual_set_tx_fail(&v, 1);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, hal_send_frames(&hal, f, 3u));
    hal_virtual_set_tx_fail(&v, 0);
    hal_virtual_set_link(&v, 0);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_LINK_DOWN, hal_receive(&hal, &in, 1000u)); /* once */
    TEST_ASSERT_EQUAL_INT(HAL_EMPTY, hal_receive(&hal, &in, 1000u));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_LINK_DOWN, hal_write_line(&hal, "hello"));
    hal_virtual_set_link(&v, 1);
    TEST_ASSERT_EQUAL_INT(3, sent_frames);
    hal_get_stats(&hal, &st);
    TEST_ASSERT_EQUAL_UINT32(4u, st.tx_frames);
    TEST_ASSERT_EQUAL_UINT32(4u, st.tx_errors);
    TEST_ASSERT_EQUAL_UINT32(1u, st.link_down);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_ARG, hal_receive(&hal, NULL, 0u));
}

static void test_counting_saturates(void)
{
    uint32_t c = UINT32_MAX - 1u;
    hal_count(&c);
    hal_count(&c);
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, c);
    c = 5u;
    hal_count_n(&c, UINT32_MAX);
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, c);
    TEST_ASSERT_EQUAL_STRING("HAL_ERR_FULL", hal_status_name(HAL_ERR_FULL));
    TEST_ASSERT_EQUAL_INT(1, hal_valid(&hal));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_inputs_in_time_order_on_the_simulated_clock);
    RUN_TEST(test_full_queues_and_long_lines);
    RUN_TEST(test_link_down_and_transmit_failures);
    RUN_TEST(test_counting_saturates);
    return UNITY_END();
}
