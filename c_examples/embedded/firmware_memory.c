/* The firmware's side of Antumbra's bare-metal contract: the allocator the library
 * calls (newlib's memalign and free, with the bytes counted and, for the
 * out-of-memory sweep, a budget of allocations after which it says no) and the
 * panic hook (a panic is an Antumbra bug: report it and stop). */
#include "antumbra.h"

#include <stdio.h>

#include "firmware.h"

static void report_panic(const char *message, void *user_data)
{
    (void)user_data;
#if !defined(MASKS_ONLY)
    fflush(stdout); /* what the example printed comes first */
#endif
    firmware_write("firmware: PANIC (an Antumbra bug): ");
    firmware_write(message);
    firmware_write("\n");
    firmware_exit(4);
}

#if defined(MASKS_ONLY)

/* The masks need no memory: this image registers no allocator (every allocation
 * would fail), only the panic hook. */
__attribute__((constructor)) void firmware_memory_init(void)
{
    antumbra_set_panic_hook(report_panic, NULL);
}

size_t firmware_heap_peak(void) { return 0; }

#else

#include <malloc.h>
#include <stdlib.h>

static size_t live_bytes, peak_bytes;
static long allocations_left = -1;
static int refused;

static void *counted_alloc(size_t size, size_t align, void *user_data)
{
    (void)user_data;
    if (allocations_left == 0) {
        refused = 1;
        return NULL;
    }
    if (allocations_left > 0) {
        allocations_left--;
    }
    void *block = memalign(align < sizeof(void *) ? sizeof(void *) : align, size);
    if (block) {
        live_bytes += size;
        if (live_bytes > peak_bytes) {
            peak_bytes = live_bytes;
        }
    }
    return block;
}

static void counted_free(void *block, size_t size, size_t align, void *user_data)
{
    (void)align, (void)user_data;
    live_bytes -= size;
    free(block);
}

/* Before main: every program of the firmware (the example, bad_input.c) runs with
 * the allocator and the hook in place. */
__attribute__((constructor)) void firmware_memory_init(void)
{
    antumbra_set_panic_hook(report_panic, NULL);
    if (antumbra_set_allocator(counted_alloc, counted_free, NULL) != ANTUMBRA_RESULT_OK) {
        printf("firmware: antumbra_set_allocator failed: %s\n", antumbra_last_error_message());
        exit(5);
    }
}

size_t firmware_heap_peak(void) { return peak_bytes; }
size_t firmware_heap_live(void) { return live_bytes; }
void firmware_heap_reset_peak(void) { peak_bytes = live_bytes; }

void firmware_heap_fail_after(long allocations)
{
    allocations_left = allocations;
    refused = 0;
}

int firmware_heap_refused(void) { return refused; }

#endif
