//! Random numbers and the sampling routines built on them: a small seeded
//! generator, a low-discrepancy 2D sequence, the cosine-weighted hemisphere, and
//! piecewise-constant distributions for importance sampling.
//!
//! Everything is deterministic given a seed, so pictures do not change with the
//! number of threads.

mod distribution;
mod hemisphere;
mod random;
mod sequence;

pub use distribution::Distribution2D;
pub use hemisphere::{cosine_hemisphere, cosine_hemisphere_pdf, uniform_sphere};
pub use random::{SampleRng, hash_seed};
pub use sequence::R2Sequence;
