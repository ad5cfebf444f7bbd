//! The bare-metal build's heap: every allocation of the library goes through the
//! two functions the application registers with `antumbra_set_allocator`.
//!
//! Until then every allocation fails, and the calls that need memory return
//! `ANTUMBRA_RESULT_OUT_OF_MEMORY`. The library counts the blocks it holds so that
//! an allocator is never swapped under memory the previous one handed out.

use core::alloc::{GlobalAlloc, Layout};
use core::ffi::c_void;
use core::sync::atomic::{AtomicPtr, AtomicUsize, Ordering};

use crate::boundary::guard;
use crate::error::Error;
use crate::result::*;

/// Returns `size` bytes aligned to `align` (a power of two), or NULL when there is
/// no memory. `user_data` is the pointer given to `antumbra_set_allocator`.
pub type antumbra_alloc_fn =
    Option<unsafe extern "C" fn(size: usize, align: usize, user_data: *mut c_void) -> *mut c_void>;

/// Releases a block that the matching `antumbra_alloc_fn` returned, with the same
/// `size` and `align` it was asked for.
pub type antumbra_free_fn = Option<
    unsafe extern "C" fn(pointer: *mut c_void, size: usize, align: usize, user_data: *mut c_void),
>;

type AllocFn = unsafe extern "C" fn(usize, usize, *mut c_void) -> *mut c_void;
type FreeFn = unsafe extern "C" fn(*mut c_void, usize, usize, *mut c_void);

static ALLOC: AtomicPtr<()> = AtomicPtr::new(core::ptr::null_mut());
static FREE: AtomicPtr<()> = AtomicPtr::new(core::ptr::null_mut());
static USER_DATA: AtomicPtr<c_void> = AtomicPtr::new(core::ptr::null_mut());
/// Blocks handed out and not yet released.
static LIVE_BLOCKS: AtomicUsize = AtomicUsize::new(0);

/// The library's global allocator in the bare-metal build.
struct ApplicationAllocator;

#[global_allocator]
static HEAP: ApplicationAllocator = ApplicationAllocator;

// SAFETY: blocks come from the application's allocator, which by the contract of
// `antumbra_set_allocator` returns NULL or `size` bytes aligned to `align`, and
// they go back to the matching free function with the same layout.
unsafe impl GlobalAlloc for ApplicationAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let alloc = ALLOC.load(Ordering::Acquire);
        if alloc.is_null() {
            return core::ptr::null_mut();
        }
        // SAFETY: only `antumbra_set_allocator` stores here, and only an `AllocFn`.
        let alloc: AllocFn = unsafe { core::mem::transmute::<*mut (), AllocFn>(alloc) };
        let user_data = USER_DATA.load(Ordering::Acquire);
        // SAFETY: the application's function, called as its contract says.
        let block = unsafe { alloc(layout.size(), layout.align(), user_data) }.cast::<u8>();
        if block.is_null() {
            return block;
        }
        if !(block as usize).is_multiple_of(layout.align()) {
            // A misaligned block would be undefined behaviour in the library;
            // give it back and report no memory instead.
            // SAFETY: as in `dealloc`, with the layout the block was asked for.
            unsafe { self.release(block, layout) };
            return core::ptr::null_mut();
        }
        LIVE_BLOCKS.fetch_add(1, Ordering::Relaxed);
        block
    }

    unsafe fn dealloc(&self, block: *mut u8, layout: Layout) {
        LIVE_BLOCKS.fetch_sub(1, Ordering::Relaxed);
        // SAFETY: forwarded: `block` came from `alloc` with `layout`.
        unsafe { self.release(block, layout) };
    }
}

impl ApplicationAllocator {
    /// # Safety
    /// `block` came from the registered alloc function with `layout`.
    unsafe fn release(&self, block: *mut u8, layout: Layout) {
        let free = FREE.load(Ordering::Acquire);
        if free.is_null() {
            return;
        }
        // SAFETY: only `antumbra_set_allocator` stores here, and only a `FreeFn`.
        let free: FreeFn = unsafe { core::mem::transmute::<*mut (), FreeFn>(free) };
        let user_data = USER_DATA.load(Ordering::Acquire);
        // SAFETY: the application's function, called as its contract says.
        unsafe { free(block.cast(), layout.size(), layout.align(), user_data) };
    }
}

/// Registers the functions the bare-metal build allocates with (only in the build
/// without ANTUMBRA_HAS_STD; the hosted build uses the system allocator).
///
/// @param alloc returns `size` bytes aligned to `align`, or NULL when there is no
///        memory; every failure becomes ANTUMBRA_RESULT_OUT_OF_MEMORY of the call
///        that needed the memory, never an abort.
/// @param free releases a block `alloc` returned, given the same size and align.
/// @param user_data passed to both untouched.
/// @return ANTUMBRA_RESULT_OK; ANTUMBRA_RESULT_NULL_ARGUMENT when exactly one of
///         `alloc` and `free` is NULL (both NULL removes the allocator, after which
///         every call that needs memory fails with ANTUMBRA_RESULT_OUT_OF_MEMORY);
///         ANTUMBRA_RESULT_INVALID_ARGUMENT while blocks from the previous
///         allocator are still held (destroy every handle first; the shared
///         tables that antumbra_hemi_transfer and antumbra_hemi_shade build on
///         first use are held for the rest of the program).
///
/// Call it before any other Antumbra call that allocates. What each function
/// allocates is in its documentation; the queries (masks, soft-shadow queries,
/// shading) allocate nothing once their structure exists, except the soft-shadow
/// hierarchy, which grows on the queries that first reach each region.
/// Thread safety: call it while no other Antumbra call runs.
#[must_use]
#[unsafe(no_mangle)]
pub extern "C" fn antumbra_set_allocator(
    alloc: antumbra_alloc_fn,
    free: antumbra_free_fn,
    user_data: *mut c_void,
) -> antumbra_result {
    guard("antumbra_set_allocator", || {
        match (alloc, free) {
            (Some(_), None) => return Err(Error::null("free")),
            (None, Some(_)) => return Err(Error::null("alloc")),
            _ => {}
        }
        let live = LIVE_BLOCKS.load(Ordering::Relaxed);
        if live > 0 {
            return Err(Error::invalid(message!(
                "{live} blocks from the previous allocator are still held; destroy every \
                 handle before changing the allocator"
            )));
        }
        let alloc = alloc.map_or(core::ptr::null_mut(), |f| f as *mut ());
        let free = free.map_or(core::ptr::null_mut(), |f| f as *mut ());
        USER_DATA.store(user_data, Ordering::Release);
        FREE.store(free, Ordering::Release);
        ALLOC.store(alloc, Ordering::Release);
        Ok(())
    })
}
