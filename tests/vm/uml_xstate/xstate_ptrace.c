/* ptrace() wrapper, loaded with LD_PRELOAD into user-mode Linux (linux.uml), that lets UML
 * kernels before 6.13 run on CPUs whose XSAVE area is larger than the buffer they were built
 * with (docs/hil.md, "user-mode Linux on CPUs with AMX").
 *
 * UML saves and restores the FPU state of its guest processes with
 * ptrace(PTRACE_GETREGSET / PTRACE_SETREGSET, pid, NT_X86_XSTATE, iov) on a buffer whose size
 * was fixed when UML was compiled (2,696 bytes in Debian's 6.1: up to AVX-512 and PKRU). The
 * host kernel accepts reads of any size but refuses with EFAULT every write whose size is not
 * the host's full XSAVE size (11,008 bytes on a CPU with AMX), so the first guest process dies
 * with "ptrace set fp regs failed, errno = 14" and the guest kernel panics.
 *
 * Here every NT_X86_XSTATE read and write whose size is not the host's (CPUID leaf 0xD) goes
 * through a host-sized buffer:
 *   read:  read the full state, give the caller its first iov_len bytes (as the kernel would);
 *   write: read the task's current full state, overlay the caller's part (legacy region, and
 *          every component lying entirely inside its buffer, with their XSTATE_BV bits), keep
 *          the current bytes and XSTATE_BV bits of the components beyond it, write it back.
 * Everything else (other requests, other regsets, XSTATE calls of the host's size) is passed
 * to the C library's ptrace() unchanged.
 *
 * Environment:
 *   ATTEKF_XSTATE_WRAP  auto (default): as above; full: also route XSTATE calls of the host's
 *                       size through the host-sized buffer (tests the path on any CPU);
 *                       pass: pass every call through (the wrapper is inert)
 *   ATTEKF_XSTATE_LOG   file to append one line per process to: the first call that took the
 *                       host-sized path (with both sizes) and, at exit, the call counts
 *
 * Thread and signal safety: one preallocated buffer, taken with an atomic flag; a call that
 * finds it taken (a signal handler, another thread) maps a buffer of its own for the call. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <elf.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/ptrace.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

#include "xstate_layout.h"

/* Call counts, in the order attekf_xstate_stats() returns them. */
enum {
    XS_STAT_OTHER = 0,    /* not NT_X86_XSTATE: passed through */
    XS_STAT_PASS,         /* NT_X86_XSTATE passed through (host-sized, or mode pass) */
    XS_STAT_READ_FULL,    /* reads through the host-sized buffer */
    XS_STAT_WRITE_FULL,   /* writes through read-overlay-write */
    XS_STAT_FAILED,       /* host-sized path calls that failed (errno from the kernel) */
    XS_STAT_COUNT
};

enum { MODE_AUTO, MODE_FULL, MODE_PASS };

typedef long (*ptrace_fn)(enum __ptrace_request request, ...);

/* Public for the self-test (found with dlsym); not part of any header. */
void attekf_xstate_stats(unsigned long out[XS_STAT_COUNT]);
unsigned long attekf_xstate_host_bytes(void);
int attekf_xstate_mode(void);

static ptrace_fn real_ptrace;
static xs_layout layout;
static int have_layout;
static int mode = MODE_AUTO;
static unsigned char *shared_buf;
static size_t map_bytes;
static char shared_busy;
static unsigned long stats[XS_STAT_COUNT];
static int log_fd = -1;
static int logged_read;
static int logged_write;

static void log_line(const char *text)
{
    if (log_fd >= 0) {
        ssize_t w = write(log_fd, text, strlen(text));
        (void)w;
    }
}

static void count(int which)
{
    (void)__atomic_fetch_add(&stats[which], 1ul, __ATOMIC_RELAXED);
}

static void log_first(int *logged, const char *what, size_t caller_bytes, uint64_t kept)
{
    char line[256];
    if (log_fd < 0 || __atomic_exchange_n(logged, 1, __ATOMIC_RELAXED) != 0) {
        return;
    }
    (void)snprintf(line, sizeof line,
                   "xstate_ptrace: pid %ld: first host-sized %s: caller %lu bytes, host %lu bytes, "
                   "components kept from the task 0x%llx\n",
                   (long)getpid(), what, (unsigned long)caller_bytes,
                   (unsigned long)layout.size_bytes, (unsigned long long)kept);
    log_line(line);
}

__attribute__((constructor)) static void xstate_init(void)
{
    void *sym = dlsym(RTLD_NEXT, "ptrace");
    const char *m = getenv("ATTEKF_XSTATE_WRAP");
    const char *path = getenv("ATTEKF_XSTATE_LOG");
    size_t page = (size_t)sysconf(_SC_PAGESIZE);
    if (sym == NULL) {
        static const char msg[] = "xstate_ptrace: the C library has no ptrace()\n";
        ssize_t w = write(2, msg, sizeof msg - 1u);
        (void)w;
        abort();
    }
    memcpy(&real_ptrace, &sym, sizeof real_ptrace);
    if (path != NULL && path[0] != '\0') {
        log_fd = open(path, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
    }
    if (m != NULL && strcmp(m, "full") == 0) {
        mode = MODE_FULL;
    } else if (m != NULL && strcmp(m, "pass") == 0) {
        mode = MODE_PASS;
    }
    have_layout = (xs_layout_read(&layout) == 0);
    if (!have_layout) {
        mode = MODE_PASS;          /* no XSAVE: nothing to adapt */
        return;
    }
    map_bytes = ((size_t)layout.size_bytes + page - 1u) / page * page;
    shared_buf = mmap(NULL, map_bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (shared_buf == MAP_FAILED) {
        shared_buf = NULL;
    }
}

__attribute__((destructor)) static void xstate_fini(void)
{
    char line[256];
    if (log_fd < 0 || (stats[XS_STAT_PASS] | stats[XS_STAT_READ_FULL] | stats[XS_STAT_WRITE_FULL]) == 0u) {
        return;
    }
    (void)snprintf(line, sizeof line,
                   "xstate_ptrace: pid %ld: exit: xstate passed %lu, reads host-sized %lu, "
                   "writes host-sized %lu, failed %lu; other requests %lu\n",
                   (long)getpid(), stats[XS_STAT_PASS], stats[XS_STAT_READ_FULL],
                   stats[XS_STAT_WRITE_FULL], stats[XS_STAT_FAILED], stats[XS_STAT_OTHER]);
    log_line(line);
}

/* A host-sized buffer: the shared one if free, else one mapped for this call. */
static unsigned char *buf_take(void)
{
    void *p;
    if (shared_buf != NULL && !__atomic_test_and_set(&shared_busy, __ATOMIC_ACQUIRE)) {
        return shared_buf;
    }
    p = mmap(NULL, map_bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    return (p == MAP_FAILED) ? NULL : (unsigned char *)p;
}

static void buf_give(unsigned char *b)
{
    if (b == shared_buf) {
        __atomic_clear(&shared_busy, __ATOMIC_RELEASE);
    } else {
        (void)munmap(b, map_bytes);
    }
}

/* Reads the task's whole state into b; 0, or -1 with errno. */
static long read_full(pid_t pid, unsigned char *b, size_t *got)
{
    struct iovec full;
    long r;
    full.iov_base = b;
    full.iov_len = layout.size_bytes;
    r = real_ptrace(PTRACE_GETREGSET, pid, (void *)(uintptr_t)NT_X86_XSTATE, &full);
    *got = full.iov_len;
    return r;
}

static long xstate_read(pid_t pid, struct iovec *iov)
{
    unsigned char *b = buf_take();
    size_t got = 0u;
    size_t n;
    long r;
    int e;
    if (b == NULL) {
        errno = ENOMEM;
        count(XS_STAT_FAILED);
        return -1;
    }
    r = read_full(pid, b, &got);
    e = errno;
    if (r == 0) {
        n = (iov->iov_len < got) ? iov->iov_len : got;
        memcpy(iov->iov_base, b, n);
        iov->iov_len = n;
        count(XS_STAT_READ_FULL);
        log_first(&logged_read, "read", iov->iov_len, 0u);
    } else {
        count(XS_STAT_FAILED);
    }
    buf_give(b);
    errno = e;
    return r;
}

static long xstate_write(pid_t pid, const struct iovec *iov)
{
    const unsigned char *c = (const unsigned char *)iov->iov_base;
    unsigned char *b = buf_take();
    struct iovec full;
    size_t got = 0u;
    size_t m;
    uint64_t covered;
    unsigned int i;
    long r;
    int e;
    if (b == NULL) {
        errno = ENOMEM;
        count(XS_STAT_FAILED);
        return -1;
    }
    r = read_full(pid, b, &got);
    if (r == 0 && got != layout.size_bytes) {
        errno = EIO;               /* the kernel's regset size is not CPUID's: do not guess */
        r = -1;
    }
    if (r == 0) {
        m = (iov->iov_len < got) ? iov->iov_len : got;
        covered = xs_covered_mask(&layout, m);
        memcpy(b, c, XS_LEGACY_BYTES);
        for (i = 2u; i < XS_MAX_COMPONENTS; ++i) {
            if ((covered >> i) & 1u) {
                memcpy(b + layout.offset[i], c + layout.offset[i], layout.length[i]);
            }
        }
        xs_set_bv(b, (xs_get_bv(c) & covered) | (xs_get_bv(b) & ~covered));
        full.iov_base = b;
        full.iov_len = got;
        r = real_ptrace(PTRACE_SETREGSET, pid, (void *)(uintptr_t)NT_X86_XSTATE, &full);
        if (r == 0) {
            count(XS_STAT_WRITE_FULL);
            log_first(&logged_write, "write", iov->iov_len, layout.user_mask & ~covered);
        }
    }
    e = errno;
    if (r != 0) {
        count(XS_STAT_FAILED);
    }
    buf_give(b);
    errno = e;
    return r;
}

long ptrace(enum __ptrace_request request, ...)
{
    va_list ap;
    pid_t pid;
    void *addr;
    void *data;
    va_start(ap, request);
    pid = va_arg(ap, pid_t);
    addr = va_arg(ap, void *);
    data = va_arg(ap, void *);
    va_end(ap);
    if ((request == PTRACE_GETREGSET || request == PTRACE_SETREGSET)
        && (uintptr_t)addr == (uintptr_t)NT_X86_XSTATE) {
        const struct iovec *iov = (const struct iovec *)data;
        if (mode != MODE_PASS && iov != NULL && iov->iov_len >= XS_MIN_BYTES
            && (iov->iov_len != layout.size_bytes || mode == MODE_FULL)) {
            return (request == PTRACE_GETREGSET) ? xstate_read(pid, (struct iovec *)data)
                                                 : xstate_write(pid, iov);
        }
        count(XS_STAT_PASS);
    } else {
        count(XS_STAT_OTHER);
    }
    return real_ptrace(request, pid, addr, data);
}

void attekf_xstate_stats(unsigned long out[XS_STAT_COUNT])
{
    int k;
    for (k = 0; k < XS_STAT_COUNT; ++k) {
        out[k] = __atomic_load_n(&stats[k], __ATOMIC_RELAXED);
    }
}

unsigned long attekf_xstate_host_bytes(void)
{
    return have_layout ? (unsigned long)layout.size_bytes : 0ul;
}

int attekf_xstate_mode(void)
{
    return mode;
}
