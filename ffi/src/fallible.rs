//! Allocation that reports failure instead of aborting: the bare-metal build's
//! allocator is the application's, and running out of it is a result code
//! (`ANTUMBRA_RESULT_OUT_OF_MEMORY`), never a stop. Core's `fallible` module
//! allocates; this one names what was refused in the error.

use alloc::boxed::Box;
use alloc::vec::Vec;

use antumbra_core::fallible;

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
    fallible::boxed(value).map_err(|_| out_of_memory(what, core::mem::size_of::<T>()))
}

/// An empty vector with room for `len` elements, or OUT_OF_MEMORY naming `what`.
pub(crate) fn vec_with_capacity<T>(len: usize, what: &str) -> Result<Vec<T>, Error> {
    fallible::with_capacity(len)
        .map_err(|_| out_of_memory(what, len.saturating_mul(core::mem::size_of::<T>())))
}
