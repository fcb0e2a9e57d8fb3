/*
 * fuzz_candump.c - libFuzzer target: the candump log lines attekf-node replays and writes
 * (firmware/app/candump.c).
 *
 * Input: text, cut into lines at '\n'; each line is parsed from its own exactly-sized heap
 * copy (so ASan sees any read past its end). Invariants: the answer is one of
 * candump_result_t; a frame has dlc <= 8 and an id within 11 bits, or within 29 bits with
 * bit 31 set; written back with candump_format_line it fits a 96-byte line and parses to
 * the same frame (time, id, length, data). Then the first 17 bytes of the input as a frame
 * struct: whatever candump_format_line accepts parses back to that frame.
 */
#include "candump.h"
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void same_frame(const hal_frame_t *a, const hal_frame_t *b)
{
    FZ_CHECK(a->t_us == b->t_us && a->id == b->id && a->dlc == b->dlc &&
                 memcmp(a->data, b->data, a->dlc) == 0,
             "round trip changed the frame (id 0x%x dlc %u)", (unsigned)a->id, (unsigned)a->dlc);
}

static void check_line(const char *line)
{
    hal_frame_t f, g;
    char out[96];
    const candump_result_t r = candump_parse_line(line, &f);
    FZ_CHECK(r == CANDUMP_BAD || r == CANDUMP_SKIP || r == CANDUMP_FRAME, "result %d", (int)r);
    if (r != CANDUMP_FRAME) {
        return;
    }
    FZ_CHECK(f.dlc <= 8u, "dlc %u", (unsigned)f.dlc);
    FZ_CHECK((f.id & 0x80000000u) ? (f.id & 0x7FFFFFFFu) <= 0x1FFFFFFFu : f.id <= 0x7FFu, "id 0x%x", (unsigned)f.id);
    FZ_CHECK(candump_format_line(&f, "vcan0", out, sizeof(out)) > 0, "a parsed frame does not format");
    FZ_CHECK(candump_parse_line(out, &g) == CANDUMP_FRAME, "formatted line does not parse: %s", out);
    same_frame(&f, &g);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    size_t start = 0, i;
    for (i = 0; i <= size; ++i) {
        if (i == size || data[i] == '\n') {
            const size_t end = (i < size) ? i + 1 : i; /* keep the '\n' */
            char *line = (char *)malloc(end - start + 1u);
            if (line == NULL) {
                return 0;
            }
            memcpy(line, data + start, end - start);
            line[end - start] = '\0';
            check_line(line);
            free(line);
            start = end;
        }
    }
    {
        fz_t z = {data, size};
        hal_frame_t f, g;
        char out[96];
        memset(&f, 0, sizeof(f));
        fz_bytes(&z, &f.t_us, sizeof(f.t_us));
        fz_bytes(&z, &f.id, sizeof(f.id));
        f.dlc = fz_u8(&z);
        fz_bytes(&z, f.data, sizeof(f.data));
        if (candump_format_line(&f, "can0", out, sizeof(out)) > 0) {
            FZ_CHECK(candump_parse_line(out, &g) == CANDUMP_FRAME, "formatted line does not parse: %s", out);
            same_frame(&f, &g);
        }
    }
    return 0;
}
