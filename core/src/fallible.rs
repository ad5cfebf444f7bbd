//! Allocation that reports failure instead of aborting, for the structures a
//! bare-metal application builds with an allocator that can run out (the C
//! library's bare-metal build returns `ANTUMBRA_RESULT_OUT_OF_MEMORY` then).
// `boxed` allocates a block by hand: `Box::try_new` is not stable.
#![allow(unsafe_code)]

use alloc::boxed::Box;
use alloc::collections::TryReserveError;
use alloc::vec::Vec;
use core::alloc::Layout;

/// The allocator refused memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutOfMemory;

impl From<TryReserveError> for OutOfMemory {
    fn from(_: TryReserveError) -> Self {
        OutOfMemory
    }
}

impl core::fmt::Display for OutOfMemory {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("out of memory")
    }
}

impl core::error::Error for OutOfMemory {}

/// An empty vector with room for exactly `len` elements.
pub fn with_capacity<T>(len: usize) -> Result<Vec<T>, OutOfMemory> {
    let mut items = Vec::new();
    items.try_reserve_exact(len)?;
    Ok(items)
}

/// `vec![value; len]`.
pub(crate) fn filled<T: Clone>(value: T, len: usize) -> Result<Vec<T>, OutOfMemory> {
    let mut items = with_capacity(len)?;
    items.resize(len, value);
    Ok(items)
}

/// `items.to_vec()`.
pub(crate) fn copied<T: Copy>(items: &[T]) -> Result<Vec<T>, OutOfMemory> {
    let mut out = with_capacity(items.len())?;
    out.extend_from_slice(items);
    Ok(out)
}

/// `items.collect()`, growing as `Vec` does.
pub(crate) fn collect<T>(items: impl Iterator<Item = T>) -> Result<Vec<T>, OutOfMemory> {
    let mut out = with_capacity(items.size_hint().0)?;
    for item in items {
        push(&mut out, item)?;
    }
    Ok(out)
}

/// `items.push(item)`.
pub(crate) fn push<T>(items: &mut Vec<T>, item: T) -> Result<(), OutOfMemory> {
    items.try_reserve(1)?;
    items.push(item);
    Ok(())
}

/// `Box::new(value)`.
pub fn boxed<T>(value: T) -> Result<Box<T>, OutOfMemory> {
    let layout = Layout::new::<T>();
    if layout.size() == 0 {
        return Ok(Box::new(value));
    }
    // SAFETY: the layout has a non-zero size.
    let block = unsafe { alloc::alloc::alloc(layout) }.cast::<T>();
    if block.is_null() {
        return Err(OutOfMemory);
    }
    // SAFETY: a fresh block with `T`'s layout, owned by the Box from here on.
    unsafe {
        block.write(value);
        Ok(Box::from_raw(block))
    }
}
