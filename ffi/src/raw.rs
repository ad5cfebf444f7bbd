//! The one place raw pointers become slices. Every export goes through these, so
//! the rules are checked the same way everywhere:
//! `(NULL, 0)` is an empty slice, `(NULL, n > 0)` is `ANTUMBRA_RESULT_NULL_ARGUMENT`,
//! a pointer not aligned for its element type or a byte size over `isize::MAX` is
//! `ANTUMBRA_RESULT_INVALID_ARGUMENT`.
//!
//! Argument names are anything `Display` (`"mesh"`, or
//! `format_args!("{argument}->indices")`), formatted only when there is an error to
//! report, so validating a call allocates nothing.

use core::fmt::Display;

use crate::error::Error;

/// Number of elements for `count` items of `per_item` elements each, or an error
/// naming `argument` when it overflows.
pub(crate) fn element_count(
    count: usize,
    per_item: usize,
    argument: impl Display,
) -> Result<usize, Error> {
    count.checked_mul(per_item).ok_or_else(|| {
        Error::invalid(message!(
            "{argument}: {count} items of {per_item} elements overflow size_t"
        ))
    })
}

fn check_raw<T>(pointer: *const T, len: usize, argument: impl Display) -> Result<(), Error> {
    if pointer.is_null() {
        return Err(Error::new(
            crate::result::ANTUMBRA_RESULT_NULL_ARGUMENT,
            message!("{argument} is NULL but {len} elements were expected"),
        ));
    }
    let align = core::mem::align_of::<T>();
    if !(pointer as usize).is_multiple_of(align) {
        return Err(Error::invalid(message!(
            "{argument} ({pointer:p}) is not aligned to {align} bytes"
        )));
    }
    let bytes = len.checked_mul(core::mem::size_of::<T>());
    if bytes.is_none_or(|bytes| bytes > isize::MAX as usize) {
        return Err(Error::invalid(message!(
            "{argument}: {len} elements exceed the address space"
        )));
    }
    Ok(())
}

/// `len` elements at `pointer`, read-only.
///
/// # Safety
/// When `pointer` is not NULL and `len > 0`, it must point to `len` initialised
/// elements that stay valid and unmodified for `'a`.
pub(crate) unsafe fn slice<'a, T>(
    pointer: *const T,
    len: usize,
    argument: impl Display,
) -> Result<&'a [T], Error> {
    if len == 0 {
        return Ok(&[]);
    }
    check_raw(pointer, len, argument)?;
    // SAFETY: non-NULL, aligned, size checked above; validity is the caller's
    // contract.
    Ok(unsafe { core::slice::from_raw_parts(pointer, len) })
}

/// `len` elements at `pointer`, writable.
///
/// # Safety
/// When `pointer` is not NULL and `len > 0`, it must point to `len` elements valid
/// for writes and not aliased by any other live reference for `'a`.
pub(crate) unsafe fn slice_mut<'a, T>(
    pointer: *mut T,
    len: usize,
    argument: impl Display,
) -> Result<&'a mut [T], Error> {
    if len == 0 {
        return Ok(&mut []);
    }
    check_raw(pointer.cast_const(), len, argument)?;
    // SAFETY: as in `slice`, plus exclusivity by the caller's contract.
    Ok(unsafe { core::slice::from_raw_parts_mut(pointer, len) })
}

/// Checks `len` writable elements at `pointer` without creating a reference, for
/// outputs that may legally alias each other or the inputs: write them with
/// `core::ptr` functions only.
pub(crate) fn writable<T>(
    pointer: *mut T,
    len: usize,
    argument: impl Display,
) -> Result<*mut T, Error> {
    if len > 0 {
        check_raw(pointer.cast_const(), len, argument)?;
    }
    Ok(pointer)
}

/// Writes `value` to the one `T` an export's caller passed for output, after
/// checking that `pointer` is not NULL (naming `argument`) and is aligned. The
/// export's contract makes a non-NULL `pointer` valid for that write.
pub(crate) fn write_one<T>(pointer: *mut T, value: T, argument: &str) -> Result<(), Error> {
    if pointer.is_null() {
        return Err(Error::null(argument));
    }
    let out = writable(pointer, 1, argument)?;
    // SAFETY: non-NULL and aligned (checked), valid for a write by the export's
    // contract.
    unsafe { out.write(value) };
    Ok(())
}

/// A required pointer to one value.
///
/// # Safety
/// A non-NULL `pointer` must point to a valid, aligned `T` for `'a`.
pub(crate) unsafe fn reference<'a, T>(
    pointer: *const T,
    argument: impl Display + Copy,
) -> Result<&'a T, Error> {
    // SAFETY: forwarded contract; a one-element slice applies the same checks.
    let one = unsafe { slice(pointer, 1, argument) }.map_err(|e| {
        if pointer.is_null() {
            Error::null(argument)
        } else {
            e
        }
    })?;
    Ok(&one[0])
}

/// A byte range of caller memory, for the overlap checks.
#[derive(Clone, Copy)]
pub(crate) struct Span {
    pub(crate) name: &'static str,
    pub(crate) start: usize,
    pub(crate) end: usize,
}

impl Span {
    pub(crate) fn of<T>(name: &'static str, pointer: *const T, len: usize) -> Option<Span> {
        (!pointer.is_null() && len > 0).then(|| Span {
            name,
            start: pointer as usize,
            // Saturating: a length past the address space is refused by the
            // slice checks; here it only has to not overflow.
            end: (pointer as usize).saturating_add(len.saturating_mul(core::mem::size_of::<T>())),
        })
    }

    pub(crate) fn overlaps(&self, other: &Span) -> bool {
        self.start < other.end && other.start < self.end
    }
}

/// The input arrays of one call (at most eight: two per mesh, the normals, the
/// lighting and the material's two), in a fixed array so validation allocates
/// nothing.
#[derive(Clone, Copy, Default)]
pub(crate) struct Spans {
    items: [Option<Span>; 8],
}

impl Spans {
    pub(crate) fn push(&mut self, span: Option<Span>) {
        if let Some(span) = span {
            let slot = self
                .items
                .iter_mut()
                .find(|slot| slot.is_none())
                .expect("a call has at most eight input arrays");
            *slot = Some(span);
        }
    }
}

/// Outputs must not overlap each other or any input: they are written while the
/// inputs are still read.
pub(crate) fn check_disjoint(outputs: &[Option<Span>], inputs: &Spans) -> Result<(), Error> {
    for (k, output) in outputs.iter().enumerate() {
        let Some(output) = output else { continue };
        for other in outputs[k + 1..].iter().chain(&inputs.items).flatten() {
            if output.overlaps(other) {
                return Err(Error::invalid(message!(
                    "{} overlaps {}; outputs must not share memory with each other or \
                     with the inputs",
                    output.name,
                    other.name
                )));
            }
        }
    }
    Ok(())
}
