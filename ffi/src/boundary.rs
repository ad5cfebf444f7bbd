//! The panic boundary every export runs inside: no unwinding ever reaches C.
//!
//! A panic is an Antumbra bug; in the hosted build it is reported as
//! `ANTUMBRA_RESULT_PANIC` with the panic message, and the caller is told (by the
//! export) to poison its handle. The bare-metal build cannot unwind: a panic calls
//! the application's hook and stops (see `panic_hook.rs`), so nothing is caught
//! here and no handle is ever poisoned.

use core::sync::atomic::{AtomicBool, Ordering};

use crate::error::{Error, clear_last_error, record};
use crate::raw;
use crate::result::*;

/// Runs a fallible export body: clears the thread's last error, converts `Err` and
/// panics into result codes with messages prefixed by `function`.
pub(crate) fn guard(
    function: &'static str,
    body: impl FnOnce() -> Result<(), Error>,
) -> antumbra_result {
    clear_last_error();
    #[cfg(feature = "std")]
    {
        // Unwind safety: a panicking body leaves no shared state half-updated
        // except handles, which the exports poison.
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(body)) {
            Ok(Ok(())) => ANTUMBRA_RESULT_OK,
            Ok(Err(error)) => record(function, error),
            Err(payload) => record(function, panic_error(payload.as_ref())),
        }
    }
    #[cfg(not(feature = "std"))]
    match body() {
        Ok(()) => ANTUMBRA_RESULT_OK,
        Err(error) => record(function, error),
    }
}

/// The error a caught panic becomes.
#[cfg(feature = "std")]
pub(crate) fn panic_error(payload: &(dyn std::any::Any + Send)) -> Error {
    let what = payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("(no message)");
    Error::new(
        ANTUMBRA_RESULT_PANIC,
        message!("internal error (please report): {what}"),
    )
}

/// A handle that a panicking call poisons: later calls on it return
/// `ANTUMBRA_RESULT_POISONED`.
pub(crate) trait Poisonable {
    /// The handle's parameter name, for messages ("scene", "ssv", ...).
    const ARGUMENT: &'static str;

    /// The handle's poison flag.
    fn poison_flag(&self) -> &AtomicBool;
}

/// `ANTUMBRA_RESULT_POISONED`, naming `argument`, when `flag` is set.
pub(crate) fn check_not_poisoned(flag: &AtomicBool, argument: &str) -> Result<(), Error> {
    if flag.load(Ordering::Acquire) {
        return Err(Error::new(
            ANTUMBRA_RESULT_POISONED,
            message!("{argument} was poisoned by an earlier internal error; destroy it"),
        ));
    }
    Ok(())
}

/// [`with_handle`] for a call that changes the handle: the export's contract
/// lends the handle exclusively (no other call on it may run meanwhile).
pub(crate) fn with_handle_mut<H: Poisonable>(
    function: &'static str,
    handle: *mut H,
    call: impl FnOnce(&mut H) -> Result<(), Error>,
) -> antumbra_result {
    let mut poison: *const AtomicBool = core::ptr::null();
    let result = guard(function, || {
        // SAFETY: by the export's contract `handle` is NULL or a live handle
        // that no other reference uses during the call.
        let handle = &mut unsafe { raw::slice_mut(handle, 1, H::ARGUMENT) }.map_err(|e| {
            if handle.is_null() {
                Error::null(H::ARGUMENT)
            } else {
                e
            }
        })?[0];
        check_not_poisoned(handle.poison_flag(), H::ARGUMENT)?;
        poison = handle.poison_flag();
        call(handle)
    });
    if result == ANTUMBRA_RESULT_PANIC && !poison.is_null() {
        // SAFETY: the handle outlives the call (only destroy frees it, and the
        // caller may not run that meanwhile); the flag is atomic.
        unsafe { (*poison).store(true, Ordering::Release) };
    }
    result
}

/// Runs a call on a handle inside [`guard`]: rejects NULL and poisoned handles,
/// and poisons the handle when the call panics.
pub(crate) fn with_handle<H: Poisonable>(
    function: &'static str,
    handle: *const H,
    call: impl FnOnce(&H) -> Result<(), Error>,
) -> antumbra_result {
    let mut poison: Option<&AtomicBool> = None;
    let result = guard(function, || {
        // SAFETY: by the export's contract `handle` is NULL or a live handle.
        let handle = unsafe { raw::reference(handle, H::ARGUMENT) }?;
        check_not_poisoned(handle.poison_flag(), H::ARGUMENT)?;
        poison = Some(handle.poison_flag());
        call(handle)
    });
    if result == ANTUMBRA_RESULT_PANIC
        && let Some(flag) = poison
    {
        flag.store(true, Ordering::Release);
    }
    result
}
