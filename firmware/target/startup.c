/*
 * startup.c - reset, vector table, fault reporting and newlib glue for the QEMU mps2
 * boards (mps2-an386: Cortex-M4F, mps2-an385: Cortex-M3). Memory map in mps2-an38x.ld.
 *
 * Reset sequence: FPU on (M4F) -> .data copied from flash -> .bss zeroed -> stack painted
 * -> semihosting handles opened -> static constructors -> main(argc, argv) -> exit().
 * Linked with -nostartfiles: newlib's crt0 has no M-profile vector table, so this file
 * replaces it, and provides the _init/_fini that __libc_init_array calls.
 */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "target.h"

/* Linker script symbols (addresses only; the objects have no meaningful type). */
extern uint32_t __data_load__[], __data_start__[], __data_end__[];
extern uint32_t __bss_start__[], __bss_end__[];
extern uint32_t __heap_start__[], __heap_end__[];
extern uint32_t __stack_limit__[], __stack_top__[];

/* newlib */
extern void __libc_init_array(void);
extern void initialise_monitor_handles(void);
/* the application */
extern int main(int argc, char **argv);

/* Prototypes of the functions the vector table and newlib reach by name. */
void reset_handler(void);
void fault_report(const uint32_t *frame, uint32_t exc_return);
void _init(void);
void _fini(void);
void *_sbrk(ptrdiff_t incr);

#define STACK_PAINT 0xC5AC5AC5u
/* Bytes left unpainted under the painting function's own frame. */
#define PAINT_MARGIN 64u

/* System Control Block and SysTick registers (Armv7-M ARM, B3.2 and B3.3). */
#define SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)
#define SCB_CFSR (*(volatile uint32_t *)0xE000ED28u)
#define SCB_HFSR (*(volatile uint32_t *)0xE000ED2Cu)
#define SCB_MMFAR (*(volatile uint32_t *)0xE000ED34u)
#define SCB_BFAR (*(volatile uint32_t *)0xE000ED38u)
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)

void target_stack_paint(uintptr_t lo, uintptr_t hi)
{
    /* volatile: these words are below the stack pointer, which the compiler would
     * otherwise be entitled to consider dead memory */
    volatile uint32_t *p = (volatile uint32_t *)((lo + 3u) & ~(uintptr_t)3u);
    const volatile uint32_t *const end = (const volatile uint32_t *)(hi & ~(uintptr_t)3u);
    while (p < end) {
        *p++ = STACK_PAINT;
    }
}

uintptr_t target_stack_lowest_touched(uintptr_t lo, uintptr_t hi)
{
    const volatile uint32_t *p = (const volatile uint32_t *)((lo + 3u) & ~(uintptr_t)3u);
    const volatile uint32_t *const end = (const volatile uint32_t *)(hi & ~(uintptr_t)3u);
    while (p < end && *p == STACK_PAINT) {
        ++p;
    }
    return (p < end) ? (uintptr_t)p : hi;
}

size_t target_stack_size(void)
{
    return (size_t)((uintptr_t)__stack_top__ - (uintptr_t)__stack_limit__);
}

size_t target_stack_high_water(void)
{
    const uintptr_t top = (uintptr_t)__stack_top__;
    return (size_t)(top - target_stack_lowest_touched((uintptr_t)__stack_limit__, top));
}

void target_systick_start(void)
{
    SYST_CSR = 0u;
    SYST_RVR = 0x00FFFFFFu; /* full 24-bit range, wraps every 2^24 ticks */
    SYST_CVR = 0u;          /* any write clears the counter (reloads on the next tick) */
    SYST_CSR = (1u << 2) | (1u << 0); /* CLKSOURCE = processor clock, ENABLE; no interrupt */
}

/* Hexadecimal of v into out[0..9] (8 digits + NUL). No printf: the fault handler must
 * not depend on newlib's state, nor touch the FPU. */
static void hex32(uint32_t v, char out[9])
{
    static const char digits[] = "0123456789abcdef";
    int i;
    for (i = 7; i >= 0; --i) {
        out[i] = digits[v & 0xFu];
        v >>= 4;
    }
    out[8] = '\0';
}

static void report_word(const char *name, uint32_t v)
{
    char buf[9];
    hex32(v, buf);
    semihost_write0(name);
    semihost_write0(buf);
}

/* Called by fault_entry with the exception frame the core pushed (r0-r3, r12, lr, pc,
 * xpsr). Reports where the fault happened and ends the run with exit status 3, so that
 * a crash fails a test instead of hanging it. */
void fault_report(const uint32_t *frame, uint32_t exc_return)
{
    semihost_write0("\n*** FAULT");
    report_word(" pc=0x", frame[6]);
    report_word(" lr=0x", frame[5]);
    report_word(" cfsr=0x", SCB_CFSR);
    report_word(" hfsr=0x", SCB_HFSR);
    report_word(" mmfar=0x", SCB_MMFAR);
    report_word(" bfar=0x", SCB_BFAR);
    report_word(" exc_return=0x", exc_return);
    semihost_write0("\n");
    _exit(3);
}

/* Fault entry: passes the stack frame (main or process stack, per EXC_RETURN bit 2). */
__attribute__((naked)) static void fault_entry(void)
{
    __asm__ volatile("tst lr, #4\n"
                     "ite eq\n"
                     "mrseq r0, msp\n"
                     "mrsne r0, psp\n"
                     "mov r1, lr\n"
                     "b fault_report\n");
}

/* An interrupt nothing expects: reported like a fault. */
static void unexpected_irq(void)
{
    semihost_write0("\n*** unexpected interrupt\n");
    _exit(4);
}

#define ARGV_MAX 16
static char cmdline[1024];
static char *argv_buf[ARGV_MAX + 1];

/* argv from the semihosting command line: words separated by spaces (QEMU joins its
 * "arg=" values with single spaces; arguments with spaces are not supported). */
static int build_argv(void)
{
    int argc = 0;
    char *p = cmdline;
    if (semihost_cmdline(cmdline, sizeof cmdline) != 0) {
        cmdline[0] = '\0';
    }
    while (*p != '\0' && argc < ARGV_MAX) {
        while (*p == ' ') {
            *p++ = '\0';
        }
        if (*p == '\0') {
            break;
        }
        argv_buf[argc++] = p;
        while (*p != '\0' && *p != ' ') {
            ++p;
        }
    }
    argv_buf[argc] = NULL;
    return argc;
}

void reset_handler(void)
{
#if defined(__ARM_FP)
    /* CP10 and CP11 full access: without it the first VFP instruction faults (UFSR.NOCP).
     * Nothing before this line may use a floating-point register. */
    SCB_CPACR |= (0xFu << 20);
    __asm__ volatile("dsb\n isb" ::: "memory");
#endif
    {
        const size_t data_bytes = (size_t)((uintptr_t)__data_end__ - (uintptr_t)__data_start__);
        const size_t bss_bytes = (size_t)((uintptr_t)__bss_end__ - (uintptr_t)__bss_start__);
        memcpy(__data_start__, __data_load__, data_bytes);
        memset(__bss_start__, 0, bss_bytes);
    }
    target_stack_paint((uintptr_t)__stack_limit__, target_sp() - PAINT_MARGIN);
    initialise_monitor_handles();
    __libc_init_array();
    exit(main(build_argv(), argv_buf));
}

/* newlib's __libc_init_array/__libc_fini_array call these around the init arrays; with
 * -nostartfiles there is no crti.o to provide them, and there is nothing to do. */
void _init(void) {}
void _fini(void) {}

/* Heap for newlib (stdio buffers): from the end of .bss up to the stack region. A request
 * that does not fit fails with ENOMEM instead of growing into the stack. */
void *_sbrk(ptrdiff_t incr)
{
    static uintptr_t brk;
    uintptr_t old;
    if (brk == 0u) {
        brk = (uintptr_t)__heap_start__;
    }
    old = brk;
    if ((incr > 0 && (uintptr_t)incr > (uintptr_t)__heap_end__ - brk) ||
        (incr < 0 && (uintptr_t)(-incr) > brk - (uintptr_t)__heap_start__)) {
        errno = ENOMEM;
        return (void *)-1;
    }
    brk = (incr >= 0) ? brk + (uintptr_t)incr : brk - (uintptr_t)(-incr);
    return (void *)old;
}

/* The vector table (Armv7-M ARM, B1.5.2): the initial main stack pointer, then the
 * exception handlers. The linker script places .isr_vector at address 0 (VTOR reset
 * value), where the core reads it at reset. */
typedef void (*handler_t)(void);
typedef struct {
    uint32_t *initial_sp;
    handler_t reset;
    handler_t nmi;
    handler_t hard_fault;
    handler_t mem_manage;
    handler_t bus_fault;
    handler_t usage_fault;
    handler_t reserved[4];
    handler_t svcall;
    handler_t debug_monitor;
    handler_t reserved2;
    handler_t pendsv;
    handler_t systick;
    handler_t irq[32]; /* mps2 external interrupts (UARTs, timers, ...); none is enabled */
} vector_table_t;

__attribute__((section(".isr_vector"), used)) const vector_table_t vector_table = {
    .initial_sp = __stack_top__,
    .reset = reset_handler,
    .nmi = fault_entry,
    .hard_fault = fault_entry,
    .mem_manage = fault_entry,
    .bus_fault = fault_entry,
    .usage_fault = fault_entry,
    .reserved = {NULL, NULL, NULL, NULL},
    .svcall = unexpected_irq,
    .debug_monitor = unexpected_irq,
    .reserved2 = NULL,
    .pendsv = unexpected_irq,
    .systick = unexpected_irq,
    .irq = {unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq,
            unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq,
            unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq,
            unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq,
            unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq, unexpected_irq,
            unexpected_irq, unexpected_irq},
};
