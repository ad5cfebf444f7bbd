/* Start-up code for the Cortex-M4 firmware: the vector table, the reset handler
 * (copy .data, clear .bss, turn on the FPU, paint the stack, run the
 * constructors and main, exit through semihosting), a fault handler that
 * reports and stops, and direct semihosting output for the masks-only image,
 * which does without newlib's stdio (-DMASKS_ONLY). */
#include <stdint.h>
#include <stdlib.h>

#include "firmware.h"

extern uint32_t __data_load[], __data_start[], __data_end[];
extern uint32_t __bss_start[], __bss_end[];
extern uint32_t __stack_top[], __stack_limit[];
extern void (*__init_array_start[])(void), (*__init_array_end[])(void);

extern void initialise_monitor_handles(void);
int main(void);

void reset_handler(void);
void fault_handler(void);

#define STACK_PAINT 0xA5A5A5A5u

__attribute__((section(".vectors"), used)) static void (*const vectors[16])(void) = {
    (void (*)(void))(uintptr_t)__stack_top, /* initial stack pointer */
    reset_handler,
    fault_handler, /* NMI */
    fault_handler, /* HardFault */
    fault_handler, /* MemManage */
    fault_handler, /* BusFault */
    fault_handler, /* UsageFault */
};

/* ARM semihosting: operation in r0, argument in r1, `bkpt 0xAB` traps to the
 * debugger (QEMU with -semihosting-config enable=on). */
static uint32_t semihost(uint32_t operation, const void *argument)
{
    register uint32_t r0 __asm__("r0") = operation;
    register const void *r1 __asm__("r1") = argument;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void firmware_write(const char *text)
{
    semihost(0x04 /* SYS_WRITE0 */, text);
}

__attribute__((noreturn)) void firmware_exit(int status)
{
    /* SYS_EXIT with ADP_Stopped_ApplicationExit (QEMU exits with 0) or
     * ADP_Stopped_RunTimeErrorUnknown (QEMU exits with 1). */
    semihost(0x18, (const void *)(uintptr_t)(status == 0 ? 0x20026u : 0x20023u));
    for (;;) {
    }
}

size_t firmware_stack_used(void)
{
    /* The lowest word no longer holding the paint is the deepest the stack went. */
    uint32_t *word = __stack_limit;
    while (word < __stack_top && *word == STACK_PAINT) {
        word++;
    }
    return (size_t)((uintptr_t)__stack_top - (uintptr_t)word);
}

__attribute__((noreturn)) void reset_handler(void)
{
    uint32_t *from = __data_load;
    for (uint32_t *to = __data_start; to < __data_end;) {
        *to++ = *from++;
    }
    for (uint32_t *to = __bss_start; to < __bss_end;) {
        *to++ = 0;
    }
    /* CPACR: full access to the coprocessors CP10 and CP11 (the FPU) before any
     * floating-point instruction runs. */
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    /* Paint the stack below the current frame (which is a few words deep). */
    uint32_t *sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    for (uint32_t *word = __stack_limit; word < sp - 16; word++) {
        *word = STACK_PAINT;
    }
#if !defined(MASKS_ONLY)
    initialise_monitor_handles();
#endif
    /* Constructors (firmware_memory.c registers the allocator in one). */
    for (void (**constructor)(void) = __init_array_start; constructor < __init_array_end; constructor++) {
        (*constructor)();
    }
#if defined(MASKS_ONLY)
    firmware_exit(main());
#else
    exit(main()); /* flushes stdout */
#endif
}

void fault_handler(void)
{
    firmware_write("firmware: processor fault\n");
    firmware_exit(3);
}
