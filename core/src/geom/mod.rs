//! Geometry shared by every algorithm: validated mesh views and receiver frames.
//!
//! Everything here borrows caller data; nothing allocates.

mod frame;
mod mesh;

pub use frame::Frame;
pub use mesh::{MeshError, MeshView, POSITION_BYTES};
