/*
 * test_candump.c - candump log lines (firmware/app/candump.c), the format attekf-node
 * replays and writes: accepted forms, every rejected form, and format -> parse round trips.
 */
#include <string.h>

#include "candump.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static hal_frame_t parse_ok(const char *line)
{
    hal_frame_t f;
    memset(&f, 0xAA, sizeof(f));
    TEST_ASSERT_EQUAL_INT_MESSAGE(CANDUMP_FRAME, candump_parse_line(line, &f), line);
    return f;
}

static void test_standard_and_extended_frames(void)
{
    hal_frame_t f = parse_ok("(1700000000.123456) vcan0 123#0011AAff\n");
    static const uint8_t d[4] = {0x00, 0x11, 0xAA, 0xFF};
    TEST_ASSERT_EQUAL_UINT64(1700000000123456ull, f.t_us);
    TEST_ASSERT_EQUAL_HEX32(0x123u, f.id);
    TEST_ASSERT_EQUAL_UINT8(4u, f.dlc);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(d, f.data, 4);
    TEST_ASSERT_EQUAL_HEX8(0u, f.data[4]); /* the rest zeroed */
    f = parse_ok("  (0.000001) can0 1FFFFFFF#\r\n");
    TEST_ASSERT_EQUAL_UINT64(1u, f.t_us);
    TEST_ASSERT_EQUAL_HEX32(0x9FFFFFFFu, f.id);
    TEST_ASSERT_EQUAL_UINT8(0u, f.dlc);
    f = parse_ok("(5.1234567) x 7FF#0102030405060708"); /* no newline, sub-us digits dropped */
    TEST_ASSERT_EQUAL_UINT64(5123456u, f.t_us);
    TEST_ASSERT_EQUAL_UINT8(8u, f.dlc);
    f = parse_ok("(5.000000) x 00000010#01 trailing words are ignored");
    TEST_ASSERT_EQUAL_HEX32(0x80000010u, f.id);
}

static void test_skipped_lines(void)
{
    hal_frame_t f;
    static const char *const skip[] = {"", "\n", "   \t\n", "# a comment\n", "(1.000000) vcan0 123#R\n",
                                       "(1.000000) vcan0 123##1AABB\n"};
    size_t i;
    for (i = 0; i < sizeof(skip) / sizeof(skip[0]); ++i) {
        TEST_ASSERT_EQUAL_INT_MESSAGE(CANDUMP_SKIP, candump_parse_line(skip[i], &f), skip[i]);
    }
}

static void test_rejected_lines(void)
{
    hal_frame_t f;
    static const char *const bad[] = {
        "1.000000 vcan0 123#00\n",            /* no parentheses */
        "(-5.000000) vcan0 123#00\n",         /* negative time (strtoull wrapped it) */
        "(+5.000000) vcan0 123#00\n",         /* sign */
        "(5.00000) vcan0 123#00\n",           /* five fraction digits */
        "(5) vcan0 123#00\n",                 /* no fraction */
        "(.000000) vcan0 123#00\n",           /* no seconds */
        "(18446744073709.551616) v 123#00\n", /* 2^64 us */
        "(18446744073710.000000) v 123#00\n",
        "(99999999999999999999999.000000) v 123#00\n",
        "(5.000000 vcan0 123#00\n",           /* no ')' */
        "(5.000000)vcan0 123#00\n",           /* no blank before the channel */
        "(5.000000) \n",                      /* no channel */
        "(5.000000) vcan0\n",                 /* no id */
        "(5.000000) vcan0 #00\n",             /* empty id */
        "(5.000000) vcan0 0x12#00\n",         /* C prefix */
        "(5.000000) vcan0 800#00\n",          /* beyond 11 bits in 3 digits */
        "(5.000000) vcan0 20000000#00\n",     /* beyond 29 bits */
        "(5.000000) vcan0 100000000#00\n",    /* nine digits */
        "(5.000000) vcan0 123 00\n",          /* no '#' */
        "(5.000000) vcan0 123#001\n",         /* odd digit */
        "(5.000000) vcan0 123#0g\n",          /* not hex */
        "(5.000000) vcan0 123#000102030405060708\n", /* nine bytes */
        "(5.000000) vcan0 123#00;\n",         /* stray character */
    };
    size_t i;
    for (i = 0; i < sizeof(bad) / sizeof(bad[0]); ++i) {
        TEST_ASSERT_EQUAL_INT_MESSAGE(CANDUMP_BAD, candump_parse_line(bad[i], &f), bad[i]);
    }
    TEST_ASSERT_EQUAL_INT(CANDUMP_BAD, candump_parse_line(NULL, &f));
    TEST_ASSERT_EQUAL_INT(CANDUMP_BAD, candump_parse_line("(1.000000) v 1#", NULL));
}

static void test_round_trip_and_format_errors(void)
{
    hal_frame_t f, g;
    char buf[96];
    int n, k;
    memset(&f, 0, sizeof(f));
    for (k = 0; k <= 8; ++k) {
        f.t_us = UINT64_MAX - (uint64_t)(unsigned)k; /* the largest times */
        f.id = (k % 2) ? (0x80000000u | (0x1ABCDEFu + (uint32_t)k)) : (0x700u + (uint32_t)k);
        f.dlc = (uint8_t)k;
        f.data[k % 8] = (uint8_t)(0x5A + k);
        n = candump_format_line(&f, "vcan0", buf, sizeof(buf));
        TEST_ASSERT_TRUE(n > 0 && (size_t)n == strlen(buf) && buf[n - 1] == '\n');
        memset(&g, 0, sizeof(g));
        TEST_ASSERT_EQUAL_INT(CANDUMP_FRAME, candump_parse_line(buf, &g));
        TEST_ASSERT_EQUAL_UINT64(f.t_us, g.t_us);
        TEST_ASSERT_EQUAL_HEX32(f.id, g.id);
        TEST_ASSERT_EQUAL_UINT8(f.dlc, g.dlc);
        if (f.dlc > 0u) {
            TEST_ASSERT_EQUAL_HEX8_ARRAY(f.data, g.data, f.dlc);
        }
    }
    TEST_ASSERT_EQUAL_INT(-1, candump_format_line(&f, "vcan0", buf, 10)); /* does not fit */
    TEST_ASSERT_EQUAL_INT(-1, candump_format_line(&f, "two words", buf, sizeof(buf)));
    TEST_ASSERT_EQUAL_INT(-1, candump_format_line(&f, "", buf, sizeof(buf)));
    f.dlc = 9u;
    TEST_ASSERT_EQUAL_INT(-1, candump_format_line(&f, "vcan0", buf, sizeof(buf)));
    f.dlc = 1u;
    f.id = 0x800u; /* 12 bits without the extended flag */
    TEST_ASSERT_EQUAL_INT(-1, candump_format_line(&f, "vcan0", buf, sizeof(buf)));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_standard_and_extended_frames);
    RUN_TEST(test_skipped_lines);
    RUN_TEST(test_rejected_lines);
    RUN_TEST(test_round_trip_and_format_errors);
    return UNITY_END();
}
