//! Allocation that reports failure instead of aborting: the bare-metal build's
//! allocator is the application's, and running out of it is a result code
//! (`ANTUMBRA_RESULT_OUT_OF_MEMORY`), never a stop.

use alloc::boxed::Box;
use alloc::vec::Vec;
use core::alloc::Layout;

use crate::error::Error;
use crate::result::ANTUMBRA_RESULT_OUT_OF_MEMORY;

/// The error for `bytes` bytes of `what` that could not be had.
pub(crate) fn out_of_memory(what: &str, bytes: usize) -> Error {
    Error::new(
        ANTUMBRA_RESULT_OUT_OF_MEMORY,
        message!("no memory for {what} ({bytes} bytes)"),
    )
}

/// `Box::new(value)`, or OUT_OF_MEMORY naming `what`.
pub(crate) fn boxed<T>(value: T, what: &str) -> Result<Box<T>, Error> {
    let layout = Layout::new::<T>();
    if layout.size() == 0 {
        return Ok(Box::new(value));
    }
    // SAFETY: the layout has a non-zero size.
    let block = unsafe { alloc::alloc::alloc(layout) }.cast::<T>();
    if block.is_null() {
        return Err(out_of_memory(what, layout.size()));
    }
    // SAFETY: a fresh, aligned block for one `T`, owned by the Box from here on.
    unsafe {
        block.write(value);
        Ok(Box::from_raw(block))
    }
}

/// An empty vector with room for `len` elements, or OUT_OF_MEMORY naming `what`.
pub(crate) fn vec_with_capacity<T>(len: usize, what: &str) -> Result<Vec<T>, Error> {
    let mut items = Vec::new();
    items
        .try_reserve_exact(len)
        .map_err(|_| out_of_memory(what, len.saturating_mul(core::mem::size_of::<T>())))?;
    Ok(items)
}
