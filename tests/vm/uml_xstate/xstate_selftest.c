/* Self-test of the ptrace XSTATE wrapper (xstate_ptrace.c), on whatever CPU it runs:
 *
 *   LD_PRELOAD=libxstate_ptrace.so [ATTEKF_XSTATE_WRAP=auto|full|pass] xstate_selftest
 *   xstate_selftest --info          print this CPU's XSAVE layout (CPUID leaf 0xD) and exit
 *   xstate_selftest --probe BYTES   ask the kernel itself (no wrapper) whether it accepts an
 *                                   NT_X86_XSTATE write of BYTES to a stopped child, as UML
 *                                   does with its buffer; prints probe_bytes= host_bytes= errno=
 *                                   (0: accepted) and exits 0 when the probe could run
 *
 * It stops a child of its own and moves the child's FPU state with ptrace(), through the
 * wrapper, the way user-mode Linux does, with buffers of the host's size and smaller ones
 * (576 bytes, and the end of each component short of the host's size). A smaller buffer is
 * what UML uses on a CPU with AMX, and every x86-64 CPU with more than SSE has a state larger
 * than 576 bytes, so the host-sized path is exercised on any machine. Checked against direct
 * system calls (which bypass the wrapper):
 *   - other requests (PEEKDATA, GETREGS) and XSTATE calls of the host's size pass through
 *     unchanged (mode full: the host-sized ones take the host-sized path instead);
 *   - a smaller read returns the kernel's first bytes;
 *   - a smaller write, which the kernel itself refuses (EFAULT), succeeds and sets exactly the
 *     caller's part: the legacy region and the components inside the buffer take the caller's
 *     values, the components beyond it keep their values and XSTATE_BV bits;
 *   - mode pass: the wrapper is inert (the smaller write fails as without it).
 * Prints one line per check; exit 0 all passed, 1 a check failed, 2 could not run. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <elf.h>
#include <errno.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ptrace.h>
#include <sys/syscall.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <sys/user.h>
#include <sys/wait.h>
#include <unistd.h>

#include "xstate_layout.h"

#define N_STATS 5   /* other, xstate passed, reads host-sized, writes host-sized, failed */
#define MAX_SIZES 24
enum { ST_OTHER = 0, ST_PASS, ST_READ, ST_WRITE, ST_FAILED };
enum { MODE_AUTO, MODE_FULL, MODE_PASS };

typedef void (*stats_fn)(unsigned long out[N_STATS]);
typedef int (*mode_fn)(void);

static volatile uint64_t marker = 0x1122334455667788ull;
static xs_layout lay;
static stats_fn get_stats;
static int n_checks;
static int n_failed;

static void check(int ok, const char *what, size_t n)
{
    ++n_checks;
    if (!ok) {
        ++n_failed;
    }
    printf("%s: %s (%lu bytes)\n", ok ? "ok" : "FAIL", what, (unsigned long)n);
}

/* The kernel's ptrace, bypassing the wrapper. */
static long sys_regset(long req, pid_t pid, unsigned char *buf, size_t *len)
{
    struct iovec iov;
    long r;
    iov.iov_base = buf;
    iov.iov_len = *len;
    r = syscall(SYS_ptrace, req, (long)pid, (long)NT_X86_XSTATE, &iov);
    *len = iov.iov_len;
    return r;
}

/* ptrace() as the program sees it: the wrapper when preloaded. */
static long lib_regset(enum __ptrace_request req, pid_t pid, unsigned char *buf, size_t *len)
{
    struct iovec iov;
    long r;
    iov.iov_base = buf;
    iov.iov_len = *len;
    r = ptrace(req, pid, (void *)(uintptr_t)NT_X86_XSTATE, &iov);
    *len = iov.iov_len;
    return r;
}

static void stats_now(unsigned long s[N_STATS])
{
    get_stats(s);
}

static void fill(unsigned char *p, size_t n, unsigned int seed)
{
    size_t k;
    for (k = 0u; k < n; ++k) {
        p[k] = (unsigned char)((k * 131u + seed * 17u + 1u) & 0xFFu);
    }
}

/* XMM0-15 in the legacy region: the SSE part every caller owns. */
#define XMM_OFFSET 160u
#define XMM_BYTES 256u

static int same_outside_caller(const unsigned char *after, const unsigned char *ref, uint64_t covered)
{
    unsigned int i;
    uint64_t keep = lay.user_mask & ~covered;
    if ((xs_get_bv(after) & keep) != (xs_get_bv(ref) & keep)) {
        return 0;
    }
    for (i = 2u; i < XS_MAX_COMPONENTS; ++i) {
        if (((keep >> i) & 1u) && memcmp(after + lay.offset[i], ref + lay.offset[i], lay.length[i]) != 0) {
            return 0;
        }
    }
    return 1;
}

static int equal_caller_part(const unsigned char *after, const unsigned char *client, uint64_t covered)
{
    unsigned int i;
    if (memcmp(after + XMM_OFFSET, client + XMM_OFFSET, XMM_BYTES) != 0) {
        return 0;
    }
    if ((xs_get_bv(after) & covered) != (xs_get_bv(client) & covered)) {
        return 0;
    }
    for (i = 2u; i < XS_MAX_COMPONENTS; ++i) {
        if ((((covered & xs_get_bv(client)) >> i) & 1u)
            && memcmp(after + lay.offset[i], client + lay.offset[i], lay.length[i]) != 0) {
            return 0;
        }
    }
    return 1;
}

static int info(void)
{
    unsigned int i;
    printf("host_bytes=%lu user_mask=0x%llx components=", (unsigned long)lay.size_bytes,
           (unsigned long long)lay.user_mask);
    for (i = 2u; i < XS_MAX_COMPONENTS; ++i) {
        if ((lay.user_mask >> i) & 1u) {
            printf("%u:%lu+%lu,", i, (unsigned long)lay.offset[i], (unsigned long)lay.length[i]);
        }
    }
    printf("\n");
    return 0;
}

static int smaller_sizes(size_t out[MAX_SIZES])
{
    static const size_t uml_debian_6_1 = 2696u;   /* Debian bookworm's linux.uml */
    size_t cand[MAX_SIZES];
    int n = 0;
    int m = 0;
    int a;
    int b;
    unsigned int i;
    cand[n++] = XS_MIN_BYTES;
    cand[n++] = uml_debian_6_1;
    for (i = 2u; i < XS_MAX_COMPONENTS && n < MAX_SIZES; ++i) {
        if ((lay.user_mask >> i) & 1u) {
            cand[n++] = (size_t)lay.offset[i] + (size_t)lay.length[i];
        }
    }
    for (a = 0; a < n; ++a) {
        int dup = 0;
        if (cand[a] >= lay.size_bytes) {
            continue;
        }
        for (b = 0; b < m; ++b) {
            dup |= (out[b] == cand[a]);
        }
        if (!dup) {
            out[m++] = cand[a];
        }
    }
    return m;
}

static void test_sizes(pid_t pid, int mode, unsigned char *ref, unsigned char *work, unsigned char *after)
{
    size_t sizes[MAX_SIZES];
    unsigned long s0[N_STATS];
    unsigned long s1[N_STATS];
    size_t host = lay.size_bytes;
    int ns = smaller_sizes(sizes);
    int k;
    for (k = 0; k < ns; ++k) {
        size_t n = sizes[k];
        size_t len = n;
        uint64_t covered = xs_covered_mask(&lay, n);
        unsigned int i;
        long r;
        int e;
        /* read */
        memset(work, 0xA5, host);
        stats_now(s0);
        r = lib_regset(PTRACE_GETREGSET, pid, work, &len);
        stats_now(s1);
        check(r == 0 && len == n && memcmp(work, ref, n) == 0, "smaller read returns the kernel's first bytes", n);
        check(mode == MODE_PASS ? s1[ST_PASS] == s0[ST_PASS] + 1u : s1[ST_READ] == s0[ST_READ] + 1u,
              mode == MODE_PASS ? "smaller read passed through (mode pass)" : "smaller read took the host-sized path", n);
        /* the kernel alone refuses a smaller write */
        memcpy(work, ref, host);
        len = n;
        r = sys_regset(PTRACE_SETREGSET, pid, work, &len);
        e = errno;
        check(r == -1 && e == EFAULT, "the host kernel refuses this write without the wrapper (EFAULT)", n);
        /* a caller that knows only its first n bytes: new XMM and components, its own header */
        memcpy(work, ref, n);
        fill(work + XMM_OFFSET, XMM_BYTES, (unsigned int)n);
        for (i = 2u; i < XS_MAX_COMPONENTS; ++i) {
            /* components in use in the reference (AVX, AVX-512); PKRU (9) keeps a valid value,
             * AMX tile configuration (17) stays in its initial state */
            if ((((covered & xs_get_bv(ref)) >> i) & 1u) && i != 9u) {
                fill(work + lay.offset[i], lay.length[i], (unsigned int)(n + i));
            }
        }
        xs_set_bv(work, xs_get_bv(ref) & covered);
        len = n;
        stats_now(s0);
        r = lib_regset(PTRACE_SETREGSET, pid, work, &len);
        e = errno;
        stats_now(s1);
        if (mode == MODE_PASS) {
            check(r == -1 && e == EFAULT, "smaller write passed through and refused (mode pass)", n);
            continue;
        }
        check(r == 0 && s1[ST_WRITE] == s0[ST_WRITE] + 1u, "smaller write accepted via the host-sized path", n);
        len = host;
        r = sys_regset(PTRACE_GETREGSET, pid, after, &len);
        check(r == 0 && equal_caller_part(after, work, covered), "the caller's part took the written values", n);
        check(r == 0 && same_outside_caller(after, ref, covered),
              "components beyond the caller's buffer kept their values and XSTATE_BV bits", n);
        len = host;
        (void)sys_regset(PTRACE_SETREGSET, pid, ref, &len);   /* back to the reference state */
    }
}

/* A child of ours, stopped under ptrace (the way UML's guest processes are); 0 on failure. */
static pid_t stopped_child(void)
{
    int status;
    pid_t pid = fork();
    if (pid < 0) {
        perror("xstate_selftest: fork");
        return 0;
    }
    if (pid == 0) {
        if (syscall(SYS_ptrace, (long)PTRACE_TRACEME, 0L, 0L, 0L) != 0) {
            _exit(3);
        }
        (void)raise(SIGSTOP);
        for (;;) {
            pause();
        }
    }
    if (waitpid(pid, &status, 0) != pid || !WIFSTOPPED(status)) {
        fprintf(stderr, "xstate_selftest: the child did not stop under ptrace\n");
        return 0;
    }
    return pid;
}

static void end_child(pid_t pid)
{
    int status;
    (void)kill(pid, SIGKILL);
    (void)waitpid(pid, &status, 0);
}

/* The kernel's own answer to a write of `bytes`, read first with the same size (UML reads its
 * state, then writes it back): direct system calls, so a preloaded wrapper plays no part. */
static int probe(const char *arg)
{
    static unsigned char buf[65536];
    char *end = NULL;
    unsigned long bytes = strtoul(arg, &end, 10);
    size_t len;
    long r;
    int e = 0;
    pid_t pid;
    if (end == arg || *end != '\0' || bytes < XS_MIN_BYTES || bytes > sizeof buf || bytes % 8u != 0u) {
        fprintf(stderr, "xstate_selftest: --probe: BYTES must be a multiple of 8 from %u to %lu, not '%s'\n",
                XS_MIN_BYTES, (unsigned long)sizeof buf, arg);
        return 2;
    }
    pid = stopped_child();
    if (pid == 0) {
        return 2;
    }
    len = (size_t)bytes;
    r = sys_regset(PTRACE_GETREGSET, pid, buf, &len);
    if (r != 0) {
        e = errno;
        end_child(pid);
        fprintf(stderr, "xstate_selftest: --probe: PTRACE_GETREGSET NT_X86_XSTATE failed: %s\n", strerror(e));
        return 2;
    }
    len = (size_t)bytes;
    r = sys_regset(PTRACE_SETREGSET, pid, buf, &len);
    e = (r == 0) ? 0 : errno;
    end_child(pid);
    printf("probe_bytes=%lu host_bytes=%lu errno=%d\n", bytes, (unsigned long)lay.size_bytes, e);
    return 0;
}

static int run(int mode)
{
    static unsigned char base[65536];
    static unsigned char ref[65536];
    static unsigned char work[65536];
    static unsigned char after[65536];
    size_t host = lay.size_bytes;
    size_t len;
    unsigned long s0[N_STATS];
    unsigned long s1[N_STATS];
    struct user_regs_struct r_lib;
    struct user_regs_struct r_sys;
    unsigned int i;
    long word;
    long r;
    pid_t pid = stopped_child();
    if (pid == 0) {
        return 2;
    }
    /* other requests pass through */
    stats_now(s0);
    errno = 0;
    word = ptrace(PTRACE_PEEKDATA, pid, (void *)&marker, NULL);
    check(errno == 0 && (uint64_t)word == marker, "PTRACE_PEEKDATA passes through", sizeof word);
    r = ptrace(PTRACE_GETREGS, pid, NULL, &r_lib);
    check(r == 0 && syscall(SYS_ptrace, (long)PTRACE_GETREGS, (long)pid, 0L, &r_sys) == 0
          && memcmp(&r_lib, &r_sys, sizeof r_lib) == 0, "PTRACE_GETREGS passes through", sizeof r_lib);
    stats_now(s1);
    check(s1[ST_OTHER] == s0[ST_OTHER] + 2u && s1[ST_READ] == s0[ST_READ], "counted as passed through", 0u);
    /* the kernel's regset is the size CPUID gives */
    len = sizeof base;
    r = sys_regset(PTRACE_GETREGSET, pid, base, &len);
    check(r == 0 && len == host, "the kernel's NT_X86_XSTATE size equals CPUID leaf 0xD", len);
    /* a reference state with every vector component in use */
    memcpy(ref, base, host);
    fill(ref + XMM_OFFSET, XMM_BYTES, 1u);
    for (i = 2u; i < XS_MAX_COMPONENTS; ++i) {
        if (((lay.user_mask >> i) & 1u) && (i == 2u || (i >= 5u && i <= 7u))) {   /* AVX, AVX-512 */
            fill(ref + lay.offset[i], lay.length[i], i);
            xs_set_bv(ref, xs_get_bv(ref) | ((uint64_t)1u << i));
        }
    }
    len = host;
    r = sys_regset(PTRACE_SETREGSET, pid, ref, &len);
    len = host;
    r |= sys_regset(PTRACE_GETREGSET, pid, ref, &len);
    check(r == 0, "reference state set and read back directly", host);
    printf("info: host %lu bytes, XSTATE_BV of the reference 0x%llx, mode %s\n", (unsigned long)host,
           (unsigned long long)xs_get_bv(ref), mode == MODE_FULL ? "full" : (mode == MODE_PASS ? "pass" : "auto"));
    /* host-sized calls */
    len = host;
    stats_now(s0);
    r = lib_regset(PTRACE_GETREGSET, pid, work, &len);
    stats_now(s1);
    check(r == 0 && len == host && memcmp(work, ref, host) == 0, "host-sized read returns the state", host);
    check(mode == MODE_FULL ? s1[ST_READ] == s0[ST_READ] + 1u : s1[ST_PASS] == s0[ST_PASS] + 1u,
          mode == MODE_FULL ? "host-sized read took the host-sized path (mode full)" : "host-sized read passed through", host);
    fill(work + XMM_OFFSET, XMM_BYTES, 2u);
    len = host;
    stats_now(s0);
    r = lib_regset(PTRACE_SETREGSET, pid, work, &len);
    stats_now(s1);
    len = host;
    r |= sys_regset(PTRACE_GETREGSET, pid, after, &len);
    check(r == 0 && memcmp(after, work, host) == 0, "host-sized write sets the whole state", host);
    check(mode == MODE_FULL ? s1[ST_WRITE] == s0[ST_WRITE] + 1u : s1[ST_PASS] == s0[ST_PASS] + 1u,
          mode == MODE_FULL ? "host-sized write took the host-sized path (mode full)" : "host-sized write passed through", host);
    len = host;
    (void)sys_regset(PTRACE_SETREGSET, pid, ref, &len);
    test_sizes(pid, mode, ref, work, after);
    end_child(pid);
    printf("xstate_selftest: %d checks, %d failed\n", n_checks, n_failed);
    return n_failed == 0 ? 0 : 1;
}

int main(int argc, char **argv)
{
    void *sym;
    mode_fn get_mode;
    if (xs_layout_read(&lay) != 0) {
        fprintf(stderr, "xstate_selftest: this CPU has no XSAVE (CPUID leaf 0xD)\n");
        return 2;
    }
    if (lay.size_bytes > 65536u) {
        fprintf(stderr, "xstate_selftest: XSAVE area of %lu bytes is beyond this test's buffers\n",
                (unsigned long)lay.size_bytes);
        return 2;
    }
    if (argc > 1 && strcmp(argv[1], "--info") == 0) {
        return info();
    }
    if (argc > 2 && strcmp(argv[1], "--probe") == 0) {
        return probe(argv[2]);
    }
    sym = dlsym(RTLD_DEFAULT, "attekf_xstate_stats");
    if (sym == NULL) {
        fprintf(stderr, "xstate_selftest: the wrapper is not loaded (LD_PRELOAD=.../libxstate_ptrace.so)\n");
        return 2;
    }
    memcpy(&get_stats, &sym, sizeof get_stats);
    sym = dlsym(RTLD_DEFAULT, "attekf_xstate_mode");
    if (sym == NULL) {
        fprintf(stderr, "xstate_selftest: the wrapper has no attekf_xstate_mode\n");
        return 2;
    }
    memcpy(&get_mode, &sym, sizeof get_mode);
    return run(get_mode());
}
