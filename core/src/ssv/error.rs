//! Why soft shadows could not be built or a query could not run.

use super::*;

/// Why a soft shadow set could not be created or queried.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SsvError {
    /// The light polygon or a sample was rejected.
    Light(LightError),
    /// No samples, or more than [`MAX_SAMPLES`].
    SampleCount {
        /// The count given.
        count: usize,
    },
    /// An option is out of range (`leaf_edges == 0`, a hemicube resolution of 0
    /// or above 1024, a root box that is empty or not finite).
    InvalidOptions,
    /// The reference ray caster could not be built (coordinates beyond the BVH's
    /// range, or out of memory).
    Caster,
    /// A receiver point is not finite.
    NonFiniteReceiver,
    /// An output slice is too short: bits need
    /// [`SoftShadows::words_per_receiver`] words per receiver, visible counts
    /// one entry per receiver, depth complexities one per sample.
    BitsTooShort {
        /// Entries needed.
        needed: usize,
        /// Entries given.
        got: usize,
    },
    /// The allocator refused memory while building the structure (only
    /// allocators that can run out, such as a bare-metal application's, get
    /// here). Without `std`, queries never fail for memory: a hierarchy node
    /// that cannot be allocated is replaced by the coarser node above it.
    OutOfMemory,
}

impl From<OutOfMemory> for SsvError {
    fn from(_: OutOfMemory) -> Self {
        SsvError::OutOfMemory
    }
}

impl From<LightError> for SsvError {
    fn from(e: LightError) -> Self {
        SsvError::Light(e)
    }
}

impl core::fmt::Display for SsvError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SsvError::Light(e) => write!(f, "{e}"),
            SsvError::SampleCount { count } => {
                write!(
                    f,
                    "soft shadows need 1 to {MAX_SAMPLES} light samples, got {count}"
                )
            }
            SsvError::InvalidOptions => write!(f, "invalid soft shadow options"),
            SsvError::Caster => write!(f, "the reference ray caster could not be built"),
            SsvError::NonFiniteReceiver => write!(f, "receiver point is not finite"),
            SsvError::BitsTooShort { needed, got } => {
                write!(f, "output needs {needed} entries, got {got}")
            }
            SsvError::OutOfMemory => f.write_str("no memory for the soft-shadow structure"),
        }
    }
}

impl core::error::Error for SsvError {}
