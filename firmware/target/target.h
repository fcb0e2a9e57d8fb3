/*
 * target.h - services of the bare-metal runtime for the QEMU mps2 boards (startup.c,
 * semihost.c): what the firmware, the benchmark and the on-target tests may call.
 *
 * The runtime is board support, not estimator code: on a real board it is replaced by the
 * vendor's startup file and linker script (docs/porting.md).
 */
#ifndef TARGET_H
#define TARGET_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Bytes of the main stack ever used since reset (stack painting, startup.c). The stack
 * below the current stack pointer is painted at reset; this scans for the deepest word
 * that no longer holds the paint. */
size_t target_stack_high_water(void);

/* Size of the main stack region reserved by the linker script, bytes. */
size_t target_stack_size(void);

/* Stack of one call, measured by painting (the benchmark):
 *     const uintptr_t sp = target_sp();
 *     target_stack_paint(sp - depth, sp - margin);   paint [lo, hi) below the caller
 *     f();
 *     used = sp - target_stack_lowest_touched(sp - depth, sp - margin);
 * The margin keeps the painting function's own frame out of the painted range; a result
 * equal to the margin means "at most margin", one equal to depth means "depth or more". */
static inline uintptr_t target_sp(void)
{
    uintptr_t sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    return sp;
}
void target_stack_paint(uintptr_t lo, uintptr_t hi);
/* Lowest address in [lo, hi) whose word lost the paint; hi if none did. */
uintptr_t target_stack_lowest_touched(uintptr_t lo, uintptr_t hi);

/* SysTick (Armv7-M ARM B3.3) as an instruction counter. Only meaningful under QEMU with
 * -icount, where virtual time advances a fixed amount per executed instruction: with
 * shift=8 each instruction takes 256 ns, and the 25 MHz mps2 processor clock counts 6.4
 * SysTick ticks in that time. target_systick_start() runs the 24-bit counter freely (no
 * interrupt); TARGET_SYSTICK_NOW is its current value, counting down. */
#define TARGET_SYSTICK_NOW (*(volatile uint32_t *)0xE000E018u)
#define TARGET_SYSTICK_MASK 0x00FFFFFFu
void target_systick_start(void);

/* Semihosting primitives that work without newlib (fault handler, early start-up). */
void semihost_write0(const char *s);
/* Fills buf with the command line given to QEMU (NUL-terminated); 0 on success. */
int semihost_cmdline(char *buf, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* TARGET_H */
