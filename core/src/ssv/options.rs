//! How a [`SoftShadows`] is built: the structure that finds each receiver's
//! candidate edges and the options of [`SoftShadows::new`].

use super::*;

/// Which structure finds the candidate edges of a receiver.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum Structure {
    /// The 2006 lazily built 3D hierarchy (the one to use).
    #[default]
    Hierarchy = 0,
    /// The 2005-style 2D structure around the light (a baseline).
    Hemicube = 1,
    /// Every potential silhouette edge (the reference).
    BruteForce = 2,
    /// `N` shadow rays through the caster (the other reference; `f32` rays,
    /// which can differ from the exact oracle where a segment passes within
    /// rounding of a silhouette edge).
    RayTrace = 3,
}

/// Creation options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SsvOptions {
    /// The candidate-edge structure.
    pub structure: Structure,
    /// Hierarchy: a node with more edges than this may be subdivided, where
    /// enough receivers fall in it and the split pays (the children's mean
    /// list is at most 3/4 of the node's; otherwise it stays a leaf) (default
    /// 16).
    pub leaf_edges: u32,
    /// Hierarchy: deepest level (default 12).
    pub max_depth: u32,
    /// Hierarchy: the root box `[min, max]`, a hint: receivers outside it go
    /// to shells of boxes twice, four times, ... its size around it, each cut
    /// into cells as fine as the root's octants, so they cost about what they
    /// would inside (the first query in a cell tests every edge against it
    /// once). Default: a cube about the bounds of the occluders and the light,
    /// twice their largest extent on a side.
    pub root_bounds: Option<[Vec3; 2]>,
    /// Build the reference caster and the structure side by side on rayon's
    /// threads (with the `parallel` feature; ignored without it). The result
    /// is the same either way (default false).
    pub parallel: bool,
    /// Hemicube: cells per face side (default 64: on the benchmark scene it
    /// lists 22–29% fewer candidates than 32 in under 1 MB; 128 saves another
    /// 15–20% for 3.4× the memory, about the hierarchy's).
    pub hemicube_resolution: u32,
}

impl Default for SsvOptions {
    fn default() -> Self {
        SsvOptions {
            structure: Structure::Hierarchy,
            leaf_edges: 16,
            max_depth: 12,
            root_bounds: None,
            parallel: false,
            hemicube_resolution: 64,
        }
    }
}

impl TryFrom<u32> for Structure {
    type Error = SsvError;

    /// The C ABI's numbering (`ANTUMBRA_SSV_STRUCTURE_*`).
    fn try_from(value: u32) -> Result<Self, SsvError> {
        match value {
            0 => Ok(Structure::Hierarchy),
            1 => Ok(Structure::Hemicube),
            2 => Ok(Structure::BruteForce),
            3 => Ok(Structure::RayTrace),
            _ => Err(SsvError::InvalidOptions),
        }
    }
}
