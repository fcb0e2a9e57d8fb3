/*
 * semihost.c - the two Arm semihosting calls the runtime makes itself (everything else,
 * printf and file I/O included, goes through newlib's librdimon).
 *
 * Semihosting on M-profile: BKPT 0xAB with the operation in r0 and a parameter pointer in
 * r1; the debugger (here QEMU) performs it and returns the result in r0. Operation numbers
 * from Arm's "Semihosting for AArch32 and AArch64" specification.
 */
#include "target.h"

#define SYS_WRITE0 0x04
#define SYS_GET_CMDLINE 0x15

static int semihost_call(int op, void *arg)
{
    register int r0 __asm__("r0") = op;
    register void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void semihost_write0(const char *s)
{
    /* the call only reads the string; the cast drops const for the generic signature */
    union {
        const char *c;
        void *v;
    } u;
    u.c = s;
    (void)semihost_call(SYS_WRITE0, u.v);
}

int semihost_cmdline(char *buf, size_t len)
{
    struct {
        char *buf;
        int len;
    } block;
    if (buf == NULL || len < 2u || len > 0x7fffffffu) {
        return -1;
    }
    block.buf = buf;
    block.len = (int)len - 1;
    if (semihost_call(SYS_GET_CMDLINE, &block) != 0) {
        buf[0] = '\0';
        return -1;
    }
    buf[block.len] = '\0';
    return 0;
}
