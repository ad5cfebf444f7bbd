/* What the firmware's support code (startup.c, firmware_memory.c) offers the
 * embedded example on the device. */
#ifndef EMBEDDED_FIRMWARE_H
#define EMBEDDED_FIRMWARE_H

#include <stddef.h>

/* Writes a NUL-terminated text to the host through semihosting (no stdio). */
void firmware_write(const char *text);

/* Ends the emulation with `status` (0: success) through semihosting. */
void firmware_exit(int status) __attribute__((noreturn));

/* Bytes of stack used so far (the painted stack's high-water mark). */
size_t firmware_stack_used(void);

/* Registers the heap below with Antumbra and a panic hook that reports and exits
 * (a constructor: it runs before main). */
void firmware_memory_init(void);

/* Largest number of bytes Antumbra held at once, and the bytes it holds now. */
size_t firmware_heap_peak(void);
size_t firmware_heap_live(void);
void firmware_heap_reset_peak(void);

/* From now on, allow `allocations` more successful allocations, then fail every
 * one (a negative count: never fail). For the out-of-memory sweep. */
void firmware_heap_fail_after(long allocations);

/* Whether an allocation was refused since the last fail_after call. */
int firmware_heap_refused(void);

#endif
