//! What a structure holds and what its queries did, for reports.

use super::*;

/// What a structure holds, for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SsvStatistics {
    /// The structure.
    pub structure: Structure,
    /// Welded edges of the occluders (near-light triangles excluded).
    pub edges: usize,
    /// Edges that may be silhouettes with a non-zero weight for some receiver
    /// (flat interior edges excluded).
    pub potential_edges: usize,
    /// Triangles tested directly against every sample (near the light).
    pub near_light_triangles: usize,
    /// Hierarchy nodes built so far (lazy: grows with queries); hemicube cells.
    pub nodes: usize,
    /// Bytes held by the structure's node or cell lists (not the caster).
    pub bytes: usize,
    /// Queries answered so far (all threads; wraps at `usize::MAX`).
    pub queries: usize,
    /// Candidate edges handed to the exact tests over those queries (wraps);
    /// `candidates / queries` is the mean per query.
    pub candidates: usize,
}

/// What one query did, beside its bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueryInfo {
    /// Samples visible.
    pub visible: u32,
    /// Candidate edges the structure handed to the exact tests.
    pub candidates: u32,
    /// Candidates with a non-zero silhouette weight at the receiver.
    pub silhouettes: u32,
    /// Reference rays cast: 1 for the wedge structures, `N` for ray tracing, 0
    /// for a receiver in the band around the light's plane (answered by exact
    /// segment tests, module docs).
    pub rays: u32,
}

/// What a batch of queries did ([`SoftShadows::query_batch`]): the
/// [`QueryInfo`] of each query, summed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueryWork {
    /// Queries answered.
    pub queries: u64,
    /// Samples visible, over all queries.
    pub visible: u64,
    /// Candidate edges handed to the exact tests.
    pub candidates: u64,
    /// Candidates with a non-zero silhouette weight at their receiver.
    pub silhouettes: u64,
    /// Reference rays cast.
    pub rays: u64,
}

impl QueryWork {
    /// This work and one more query's.
    #[must_use]
    pub fn with(self, info: &QueryInfo) -> QueryWork {
        QueryWork {
            queries: self.queries + 1,
            visible: self.visible + u64::from(info.visible),
            candidates: self.candidates + u64::from(info.candidates),
            silhouettes: self.silhouettes + u64::from(info.silhouettes),
            rays: self.rays + u64::from(info.rays),
        }
    }

    /// The work of two batches together.
    #[must_use]
    pub fn merge(self, other: QueryWork) -> QueryWork {
        QueryWork {
            queries: self.queries + other.queries,
            visible: self.visible + other.visible,
            candidates: self.candidates + other.candidates,
            silhouettes: self.silhouettes + other.silhouettes,
            rays: self.rays + other.rays,
        }
    }
}
