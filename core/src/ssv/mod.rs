//! Exact soft shadows from planar area lights: soft shadow volumes (Laine, Aila,
//! Assarsson, Lehtinen and Akenine-Möller, "Soft Shadow Volumes for Ray Tracing",
//! SIGGRAPH 2005) found through the lazily built 3D wedge hierarchy of Lehtinen,
//! Laine and Aila, "An Improved Physically-Based Soft Shadow Volume Algorithm",
//! Eurographics 2006 (thesis §2.4, §3.4).
//!
//! For a receiver `p` and the light samples `s_i` the result is `N` visibility bits:
//! bit `i` (word `i / 64`, bit `i % 64`) is set exactly when no occluder triangle
//! meets the open segment from `p` to `s_i`, as decided by the exact test
//! [`segment_meets_triangle`] (closed triangles; degenerate triangles and
//! triangles containing the whole segment in their plane never occlude; the light
//! itself is not an occluder, and a triangle lying in the light's plane only
//! touches the segment at its open end). [`SoftShadows::query`] returns these bits
//! and the visible count.
//!
//! ## How
//!
//! Depth complexity `D(s)` = number of triangles the segment `p → s` meets. Sweep
//! the sample point along the segment from the light's centroid `c` to `s`: `D`
//! changes only when the ray from `p` crosses an edge `(a, b)`, that is when the
//! edge meets the triangle `(p, c, s)`, and then by `w(p) · σ(s)`, where the
//! silhouette weight `w(p)` sums, over the triangles adjacent to the edge, the
//! orientation sign of the third vertex `v` against the plane `(p, a, b)` (0: not
//! a silhouette, ±1: boundary, ±2: fold, more for non-manifold fans; a triangle
//! whose plane holds `p` adds 0, which is what makes receivers on surfaces
//! exact), and `σ(s)` is the side of `s` against that plane. With
//! `a' = a - p` etc., the edge meets the triangle `(p, c, s)` exactly when
//! `det(a', b', s')` and `det(a', b', c')` differ in sign (the plane `(p, a, b)`
//! separates `c` and `s`), `det(a', c', s')` and `det(b', c', s')` differ (the
//! plane `(p, c, s)` separates `a` and `b`), and `det(a', c', s')` has the sign of
//! `det(a', b', s')` (the crossing point is in front of `p`, not behind it). So
//! the relative depth complexity `R(s) = D(s) - D(c)` is a sum over the
//! silhouette edges whose penumbra wedge holds `p`. The sample with
//! the smallest `R` gets one reference ray through the [`RayCaster`](crate::RayCaster): blocked
//! means every sample is blocked, otherwise exactly the samples sharing the
//! minimum are visible.
//!
//! Certified signs: every determinant above is evaluated in `f64` from `f32`
//! inputs with Shewchuk's forward error bound and, when the bound does not settle
//! the sign, exactly ([`predicates`]). Tie rules: the weight terms use the
//! true sign (0 counts 0). The centroid is only where the sweep starts, so its
//! ties must not change any answer: every determinant with `c` in it is taken
//! at `c + ε e₁ + ε² e₂ + ε³ e₃` for an infinitesimal `ε > 0` (where it is
//! exactly zero, the sign of the first non-zero term of that move), one and
//! the same point for every edge, so a receiver whose segment to the centroid
//! passes exactly through an occluder vertex or edge gets the oracle's bits.
//! (Breaking each such tie as "negative" on its own put the centroid on the
//! negative side of all the planes through a vertex at once, which no point
//! is.) The other exact zeros, a sample exactly on a projected edge, count as
//! negative, with arguments always in the same canonical order (edge endpoints
//! by welded vertex number, which depends only on positions), so every
//! structure counts them the same way. Zero mismatches against the exact
//! oracle are claimed for inputs where no segment passes exactly through an edge
//! or vertex (there the visibility itself is a matter of convention).
//!
//! Triangles near the light's plane. The sweep assumes every triangle is either
//! clear of the light's plane or crosses it outside the polygon. Triangles within
//! a band of half-width `tolerance` around the light's plane whose trace may come
//! near the polygon ("near-light" triangles, for example the emitter itself if it
//! is part of the occluder mesh, or geometry piercing the light) are taken out of
//! the edges and of the reference caster and tested directly against every
//! sample with the exact segment test. Receivers inside the band are answered by
//! the exact test against every triangle that touches the band (the only ones a
//! segment inside the band can meet). For both, the side of every sample of each
//! such triangle's plane (an exact sign) is receiver-independent and kept as
//! bitsets: a query takes the side of `p` once per triangle and sends only the
//! samples strictly on the other side to the rest of the segment test (an open
//! segment with both ends on one side, or an end on the plane, cannot meet the
//! triangle under the rules of [`segment_meets_triangle`]); the bits are those of
//! the per-sample test. A floor crossing the light's plane beside the light, with
//! receivers on the floor, is the case this keeps cheap: the side of such a `p`
//! needs the exact expansion.
//!
//! ## Structures ([`Structure`])
//!
//! The first three give the same bits (they share every exact test and differ
//! only in conservative culling, so they also agree in every tie the culling
//! cannot reach), and so does the fourth away from segments that graze a
//! silhouette edge within `f32` rounding; tests check them bit for bit (the
//! fourth on fixed scenes; on random ones, where such segments turn up, only
//! away from them):
//!
//! - [`Structure::Hierarchy`] (default): the 2006 structure, an octree over the
//!   receivers' space whose nodes keep the edges whose wedge and silhouette region
//!   may touch the node box, subdivided lazily where receivers are (threshold
//!   [`SsvOptions::leaf_edges`], depth limit [`SsvOptions::max_depth`]; a batch
//!   of receivers splits the nodes enough of them fall in before it is queried,
//!   [`SoftShadows::prepare`], a receiver queried alone those that have served
//!   a few queries); shells of boxes around the root cover every other point.
//!   A query walks one root-to-leaf path. Concurrent queries may build nodes
//!   concurrently (every lazily made part is a once-cell).
//! - [`Structure::Hemicube`]: the 2005-style structure, wedges projected from the
//!   light's centroid onto a cube of direction cells (each edge listed in the
//!   cells its wedge, restricted to the part of the light from which the edge
//!   is a silhouette, may reach); a query tests its cell's list.
//! - [`Structure::BruteForce`]: every potential silhouette edge, the obviously
//!   right twin of the two above.
//! - [`Structure::RayTrace`]: `N` shadow rays through the caster, the answer
//!   an `f32` ray tracer gives (it can differ from the exact oracle where a
//!   segment passes within `f32` rounding of a silhouette edge, as Embree's
//!   rays can).
//!
//! The reference ray goes through the caster's `occluded`; an occlusion is then
//! confirmed hit by hit with the exact segment test, so a receiver exactly on a
//! surface is not shadowed by that surface through `f32` rounding (the same holds
//! for [`Structure::RayTrace`]'s rays). An `f32` ray is only as exact as its
//! rounding: near an edge that is a silhouette from the receiver it can miss
//! a surface the segment grazes, or cross a boundary edge the segment passes
//! just inside. Near any other edge the two triangles lie on either side of
//! the segment's plane and the watertight test cannot slip between them. So
//! the reference sample is chosen among the minimum's samples as one whose
//! segment keeps more than 2^-14 (an angle seen from the receiver, fifty
//! times the ray's rounding) from every silhouette edge the sweep met and
//! lies as deep inside the light (so that every edge near its segment is a
//! candidate of the structure); a hit the exact test refutes away from the
//! receiver's own plane, or no such sample among the first few, makes the
//! decision exact instead, over every triangle whose box meets the segment
//! (rare: linear in the triangles).
//!
//! Cost: a receiver whose pyramid to the light misses the occluders' box is
//! answered at once; any other costs a walk, the exact sweep of its candidate
//! edges (most of the time: a fixed part per silhouette edge whose wedge holds
//! it) and one reference ray. Per-frame figures against Embree and the
//! hemicube: `antumbra bench ssv --frame` (README, docs/performance.md).
//!
//! Queries allocate nothing: per-sample counters live on the stack (at most
//! [`MAX_SAMPLES`] samples, 4 KiB of stack per query), beside the record of
//! silhouette edges for the reference sample (16 KiB, left uninitialised); the
//! samples are read from an `f64` structure of arrays made at creation.
//!
//! The files, one idea each: `options.rs` and `error.rs` (what a caller passes
//! and gets back), `build.rs` (creation), `query.rs` (one receiver, and a
//! batch on or off the pool), `sweep.rs` (the sweep of the silhouette edges),
//! `reference.rs` (the reference decision), `near_light.rs` (the band around
//! the light's plane), `caster.rs` (the reference ray's caster),
//! `statistics.rs` (reports), and the structures that find candidate edges
//! (`hierarchy.rs`, `hemicube.rs`, `wedge.rs`, `edge_bounds.rs`).

mod build;
mod caster;
mod edge_bounds;
mod edges;
mod error;
mod hemicube;
mod hierarchy;
mod light;
mod near_light;
mod options;
pub mod predicates;
mod query;
mod reference;
mod silhouette_lanes;
mod statistics;
mod sweep;
mod wedge;

#[cfg(test)]
mod tests;

use alloc::boxed::Box;
use alloc::vec::Vec;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicUsize, Ordering};
use glam::{DVec3, Vec3};

use crate::fallible::{self, OutOfMemory};
use crate::geom::MeshView;
use crate::raycast::Ray;

use edges::EdgeGraph;
use hemicube::Hemicube;
use hierarchy::Hierarchy;
pub use light::{
    LIGHT_TOLERANCE, LightError, LightPolygon, MAX_LIGHT_VERTICES, SamplePattern, SplitMix64,
};
use predicates::{
    ORIENT_BOUND, cross_sign_sequence, crossing_in_triangle, det3_with_permanent, orient3d_exact,
};
pub use predicates::{orient3d, segment_meets_triangle};
use wedge::{Aabb, LightShape};

use caster::Caster;
pub use error::SsvError;
use near_light::{AxisPlane, plane_sides};
pub use options::{SsvOptions, Structure};
pub use query::PARALLEL_GRAIN;
use reference::{NEAR_ANGLE, Silhouettes};
pub use statistics::{QueryInfo, QueryWork, SsvStatistics};
use sweep::{Kernel, direction_near_edge, inset, pseudo_angle};

/// Pseudo-angle buckets of the sample lookup table (the pseudo-angle runs over
/// `[0, 4)`; `ANGLE_BUCKETS / 4` is a power of two, so bucket bounds and the
/// bucket of a pseudo-angle are computed exactly).
pub(crate) const ANGLE_BUCKETS: usize = 1024;
/// Buckets per pseudo-angle unit.
pub(crate) const ANGLE_SCALE: f64 = (ANGLE_BUCKETS / 4) as f64;

/// Most light samples a [`SoftShadows`] may have.
pub const MAX_SAMPLES: usize = 1024;

/// Sample counts up to this take the smaller of a query's two counter arrays.
const COMMON_SAMPLES: usize = 256;

/// Runs `f` on `n` zeroed counters on the stack (`n <= MAX_SAMPLES`). Only
/// what is used is zeroed: clearing all of [`MAX_SAMPLES`] (4 KiB) would be a
/// noticeable share of a query at 256 samples.
#[inline(always)]
fn with_counters<R>(n: usize, f: impl FnOnce(&mut [i32]) -> R) -> R {
    if n <= COMMON_SAMPLES {
        f(&mut [0i32; COMMON_SAMPLES][..n])
    } else {
        f(&mut [0i32; MAX_SAMPLES][..n])
    }
}

/// Exact soft shadows from one planar area light with a fixed set of samples over
/// a fixed set of occluders. Owns everything it needs; `Send + Sync`; queries
/// take `&self` and may run from many threads at once.
pub struct SoftShadows {
    light: LightPolygon,
    samples: Vec<Vec3>,
    structure: Structure,
    /// The options it was made with, for [`SoftShadows::update`].
    options: SsvOptions,
    graph: EdgeGraph,
    /// Potential silhouette edges (indices into `graph.edges`).
    potential: Vec<u32>,
    near_light: Vec<[Vec3; 3]>,
    /// For each near-light triangle, the side of every sample of its plane:
    /// [`SoftShadows::words_per_receiver`] words of "strictly above"
    /// (`orient3d > 0`), then as many of "strictly below" (receiver-independent,
    /// exact; bit `i` is sample `i`).
    near_sides: Vec<u64>,
    /// For each near-light triangle, its plane when axis-aligned (see
    /// [`AxisPlane`]).
    near_planes: Vec<Option<AxisPlane>>,
    band: Vec<[Vec3; 3]>,
    /// The same sides for the band triangles.
    band_sides: Vec<u64>,
    /// The same planes for the band triangles.
    band_planes: Vec<Option<AxisPlane>>,
    caster: Caster,
    shape: LightShape,
    centroid: Vec3,
    plane_normal: DVec3,
    plane_point: DVec3,
    band_half_width: f64,
    hierarchy: Option<Hierarchy>,
    hemicube: Option<Box<Hemicube>>,
    queries: AtomicUsize,
    candidates: AtomicUsize,
    /// Sample indices by pseudo-angle about the centroid in the light's plane;
    /// samples closer to the centroid than `angle_radius` come last.
    order: Vec<u32>,
    /// The inverse of `order`: sample `i`'s place in the angular order.
    rank: Vec<u32>,
    /// Pseudo-angles of the first `angles.len()` samples of `order`.
    angles: Vec<f64>,
    /// `angle_starts[k]`: the first index of `angles` at or above the
    /// pseudo-angle `k / ANGLE_SCALE` (`ANGLE_BUCKETS + 1` entries): a sample
    /// range for a pseudo-angle range in two lookups instead of two binary
    /// searches (a superset by at most a bucket at each end).
    angle_starts: Vec<u32>,
    u_axis: DVec3,
    v_axis: DVec3,
    angle_radius: f64,
    /// Largest distance of a sample from the light's plane.
    sample_offset: f64,
    shape_diameter: f64,
    /// Sample coordinates in angular order (`order`), widened to `f64` once
    /// (exact), structure of arrays for the per-sample loop.
    soa: [Vec<f64>; 3],
    /// The same in `f32`, followed by eight zeros (so the eight-lane pass
    /// reads a whole block from any sample on).
    #[cfg_attr(not(all(target_arch = "x86_64", feature = "std")), allow(dead_code))]
    soa32: [Vec<f32>; 3],
    /// How far inside the light's polygon each sample lies, in its plane
    /// (negative outside; angular order).
    insets: Vec<f64>,
    /// Bounds of every occluder triangle (none: no triangle).
    occluder_box: Option<(DVec3, DVec3)>,
    /// Componentwise bounds of the samples (exact `f64` of `f32`).
    sample_lo: DVec3,
    sample_hi: DVec3,
}

const _: () = {
    const fn send_sync<T: Send + Sync>() {}
    send_sync::<SoftShadows>();
};

impl SoftShadows {
    /// The light.
    pub fn light(&self) -> &LightPolygon {
        &self.light
    }

    /// The samples, in bit order.
    pub fn samples(&self) -> &[Vec3] {
        &self.samples
    }

    /// The samples' `f32` coordinates by axis, in angular order, with the
    /// eight zeros after the last (the eight-lane sample passes' input).
    #[cfg(all(target_arch = "x86_64", feature = "std"))]
    pub(super) fn samples32(&self) -> [&[f32]; 3] {
        [&self.soa32[0], &self.soa32[1], &self.soa32[2]]
    }

    /// Number of samples `N`.
    pub fn sample_count(&self) -> usize {
        self.samples.len()
    }

    /// `ceil(N / 64)`: the `u64` words of one receiver's bits.
    pub fn words_per_receiver(&self) -> usize {
        self.samples.len().div_ceil(64)
    }

    /// The options it was made with.
    pub fn options(&self) -> SsvOptions {
        self.options
    }

    /// The structure chosen at creation.
    pub fn structure(&self) -> Structure {
        self.structure
    }

    /// Sizes, for reports (the hierarchy's grow as queries build nodes).
    pub fn statistics(&self) -> SsvStatistics {
        let (nodes, bytes) = match (&self.hierarchy, &self.hemicube) {
            (Some(h), _) => (h.nodes(), h.bytes()),
            (_, Some(c)) => (c.cells(), c.bytes()),
            _ => (0, 0),
        };
        SsvStatistics {
            structure: self.structure,
            edges: self.graph.edges.len(),
            potential_edges: self.potential.len(),
            near_light_triangles: self.near_light.len(),
            nodes,
            bytes,
            queries: self.queries.load(Ordering::Relaxed),
            candidates: self.candidates.load(Ordering::Relaxed),
        }
    }
}
