//! The bare-metal build's panic handler. A panic is an Antumbra bug: with no
//! unwinding on bare metal, the library reports it through the application's hook
//! and stops.

use core::cell::UnsafeCell;
use core::ffi::{c_char, c_void};
use core::sync::atomic::{AtomicPtr, Ordering};

use crate::error::FixedMessage;

/// Called once when the library panics (an Antumbra bug; please report it), with a
/// NUL-terminated description (file, line, message) and the `user_data` given to
/// `antumbra_set_panic_hook`. It may log, reset the device or halt; if it returns,
/// the library stops in an endless loop.
pub type antumbra_panic_hook =
    Option<unsafe extern "C" fn(message: *const c_char, user_data: *mut c_void)>;

type HookFn = unsafe extern "C" fn(*const c_char, *mut c_void);

static HOOK: AtomicPtr<()> = AtomicPtr::new(core::ptr::null_mut());
static USER_DATA: AtomicPtr<c_void> = AtomicPtr::new(core::ptr::null_mut());

/// Installs (or, with NULL, removes) the function called when the library panics
/// (only in the build without ANTUMBRA_HAS_STD; the hosted build returns
/// ANTUMBRA_RESULT_PANIC from the call instead).
///
/// @param hook called with the panic's description; NULL removes it.
/// @param user_data passed back to `hook` untouched.
///
/// A panic is a bug of Antumbra, never a consequence of bad input (bad input is a
/// result code). Without a hook the library stops silently in an endless loop.
/// Thread safety: call it while no other Antumbra call runs.
#[unsafe(no_mangle)]
pub extern "C" fn antumbra_set_panic_hook(hook: antumbra_panic_hook, user_data: *mut c_void) {
    USER_DATA.store(user_data, Ordering::Release);
    HOOK.store(
        hook.map_or(core::ptr::null_mut(), |f| f as *mut ()),
        Ordering::Release,
    );
}

/// The description handed to the hook; static because the stack may be what broke.
struct PanicText(UnsafeCell<[u8; 256]>);

// SAFETY: written once, by the panicking call, which never returns.
unsafe impl Sync for PanicText {}

static TEXT: PanicText = PanicText(UnsafeCell::new([0; 256]));

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    let mut text = FixedMessage::new();
    let _ = core::fmt::Write::write_fmt(&mut text, format_args!("antumbra bug: {info}"));
    // SAFETY: the only writer, and it never returns (see `PanicText`).
    let buffer = unsafe { &mut *TEXT.0.get() };
    let bytes = text.as_str().as_bytes();
    let len = bytes.len().min(buffer.len() - 1);
    buffer[..len].copy_from_slice(&bytes[..len]);
    buffer[len] = 0;
    let hook = HOOK.load(Ordering::Acquire);
    if !hook.is_null() {
        // SAFETY: only `antumbra_set_panic_hook` stores here, and only a `HookFn`.
        let hook: HookFn = unsafe { core::mem::transmute::<*mut (), HookFn>(hook) };
        // SAFETY: the application's function, called as its contract says.
        unsafe { hook(buffer.as_ptr().cast(), USER_DATA.load(Ordering::Acquire)) };
    }
    loop {
        core::hint::spin_loop();
    }
}
