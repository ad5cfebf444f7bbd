//! A cache hint for loops whose next reads are known ahead but scattered in
//! memory (the hardware prefetcher only follows strides).

/// Asks the cache for the line holding `data[index]`: a hint, which neither
/// faults nor changes any value, whatever the index (no-op off x86).
#[inline(always)]
pub(crate) fn prefetch<T>(data: &[T], index: usize) {
    #[cfg(all(
        any(target_arch = "x86", target_arch = "x86_64"),
        target_feature = "sse"
    ))]
    {
        #[cfg(target_arch = "x86")]
        use core::arch::x86::{_MM_HINT_T0, _mm_prefetch};
        #[cfg(target_arch = "x86_64")]
        use core::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // Pointer arithmetic without a dereference: no bounds to keep.
        let address = data.as_ptr().wrapping_add(index).cast::<i8>();
        #[allow(unsafe_code)]
        // SAFETY: `prefetch` has no architectural effect besides filling a cache
        // line: it never faults and never reads memory visibly, for any address.
        // The only reason it is `unsafe` is its `#[target_feature(enable = "sse")]`,
        // which every x86-64 target has and which this build guards by `cfg`.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(address)
        };
    }
    #[cfg(not(all(
        any(target_arch = "x86", target_arch = "x86_64"),
        target_feature = "sse"
    )))]
    let _ = (data, index);
}
