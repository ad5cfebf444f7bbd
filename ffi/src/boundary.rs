//! The panic boundary every export runs inside: no unwinding ever reaches C.
//!
//! A panic is an Antumbra bug; it is reported as `ANTUMBRA_RESULT_PANIC` with the
//! panic message, and the caller is told (by the export) to poison its handle.

use std::panic::{AssertUnwindSafe, catch_unwind};

use crate::error::{Error, clear_last_error, record};
use crate::result::*;

/// Runs a fallible export body: clears the thread's last error, converts `Err` and
/// panics into result codes with messages prefixed by `function`.
pub(crate) fn guard(
    function: &'static str,
    body: impl FnOnce() -> Result<(), Error>,
) -> antumbra_result {
    clear_last_error();
    // Unwind safety: a panicking body leaves no shared state half-updated except
    // handles, which the exports poison.
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => ANTUMBRA_RESULT_OK,
        Ok(Err(error)) => record(function, error),
        Err(payload) => record(function, panic_error(payload.as_ref())),
    }
}

/// The error a caught panic becomes.
pub(crate) fn panic_error(payload: &(dyn std::any::Any + Send)) -> Error {
    let what = payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("(no message)");
    Error::new(
        ANTUMBRA_RESULT_PANIC,
        format!("internal error (please report): {what}"),
    )
}
