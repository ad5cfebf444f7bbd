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
//! silhouette edge within `f32` rounding; tests check them bit for bit:
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

mod edge_bounds;
mod edges;
mod hemicube;
mod hierarchy;
mod light;
pub mod predicates;
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

/// Pseudo-angle buckets of the sample lookup table (the pseudo-angle runs over
/// `[0, 4)`; `ANGLE_BUCKETS / 4` is a power of two, so bucket bounds and the
/// bucket of a pseudo-angle are computed exactly).
const ANGLE_BUCKETS: usize = 1024;
/// Buckets per pseudo-angle unit.
const ANGLE_SCALE: f64 = (ANGLE_BUCKETS / 4) as f64;

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

/// Points per rayon task of [`SoftShadows::query_batch`]: one query costs tens
/// of microseconds (hundreds of candidate edges times N samples), so small
/// tasks balance well.
pub const PARALLEL_GRAIN: usize = 16;

/// The reference caster: the owned BVH (with `bvh`) or a brute-force loop.
enum Caster {
    #[cfg(feature = "bvh")]
    Bvh(crate::raycast::BvhScene),
    #[cfg(not(feature = "bvh"))]
    Brute(Vec<[Vec3; 3]>),
}

impl Caster {
    fn occluded(&self, ray: &Ray) -> bool {
        match self {
            #[cfg(feature = "bvh")]
            Caster::Bvh(scene) => crate::raycast::RayCaster::occluded(scene, ray),
            #[cfg(not(feature = "bvh"))]
            Caster::Brute(tris) => {
                let Some(prepared) = crate::raycast::PreparedRay::new(ray) else {
                    return false;
                };
                tris.iter()
                    .any(|&[a, b, c]| prepared.intersect(a, b, c).is_some())
            }
        }
    }

    /// The nearest hit in the ray's interval: `(t, triangle index)`.
    fn closest_hit(&self, ray: &Ray) -> Option<(f32, usize)> {
        match self {
            #[cfg(feature = "bvh")]
            Caster::Bvh(scene) => crate::raycast::RayCaster::closest_hit(scene, ray)
                .map(|h| (h.t, h.triangle as usize)),
            #[cfg(not(feature = "bvh"))]
            Caster::Brute(tris) => {
                let mut prepared = crate::raycast::PreparedRay::new(ray)?;
                let mut best = None;
                for (i, &[a, b, c]) in tris.iter().enumerate() {
                    if let Some(hit) = prepared.intersect(a, b, c) {
                        prepared.set_t_max(hit.t);
                        best = Some((hit.t, i));
                    }
                }
                best
            }
        }
    }
}

/// The default root box: a cube about the bounds of the occluders and the
/// light, twice their largest extent on a side.
fn default_root(occluders: &MeshView<'_>, light: &LightPolygon) -> Aabb {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for &v in occluders.indices() {
        let p = occluders.position(v as usize).as_dvec3();
        lo = lo.min(p);
        hi = hi.max(p);
    }
    for v in light.vertices() {
        lo = lo.min(v.as_dvec3());
        hi = hi.max(v.as_dvec3());
    }
    // A cube about the bounds' centre, half again their largest extent on
    // every side: octree cells then stay cubes (a tall root over a
    // ground made tall, thin cells that the lists shrank slowly in).
    let centre = 0.5 * (lo + hi);
    let half = (hi - lo).max_element().max(1e-30);
    Aabb {
        min: centre - DVec3::splat(half),
        max: centre + DVec3::splat(half),
    }
}

/// Sets the first `n` bits of `bits` (bit `i` of word `i / 64`), clears the
/// rest of the words given.
fn set_first(bits: &mut [u64], n: usize) {
    for (k, w) in bits.iter_mut().enumerate() {
        let left = n.saturating_sub(64 * k);
        *w = if left >= 64 { !0 } else { (1u64 << left) - 1 };
    }
}

/// Pieces of a segment whose boxes find the triangles of an exact reference
/// decision ([`SoftShadows::exactly_blocked`]); a power of two, so the
/// pieces' parameters are exact.
#[cfg(feature = "bvh")]
const SEGMENT_PIECES: usize = 32;

/// Most hits the reference ray re-checks exactly before it calls the segment
/// blocked (each is a hit the `f32` caster reports that the exact test refutes,
/// such as a triangle through a receiver on a surface).
const MAX_REFUTED_HITS: usize = 64;

/// Exact soft shadows from one planar area light with a fixed set of samples over
/// a fixed set of occluders. Owns everything it needs; `Send + Sync`; queries
/// take `&self` and may run from many threads at once.
pub struct SoftShadows {
    light: LightPolygon,
    samples: Vec<Vec3>,
    structure: Structure,
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
    /// Prepares the occluders for `light` and `samples` (validated: on the light
    /// within [`LightPolygon::tolerance`], 1 to [`MAX_SAMPLES`] of them; make them
    /// with [`LightPolygon::samples`]).
    ///
    /// With the `bvh` feature the reference caster is an owned `BvhScene`
    /// (obvhs); without it a brute-force loop over
    /// the triangles (correct, but linear per query).
    pub fn new(
        occluders: &MeshView<'_>,
        light: LightPolygon,
        samples: &[Vec3],
        options: SsvOptions,
    ) -> Result<Self, SsvError> {
        if samples.is_empty() || samples.len() > MAX_SAMPLES {
            return Err(SsvError::SampleCount {
                count: samples.len(),
            });
        }
        light.validate_samples(samples)?;
        if options.leaf_edges == 0
            || options.hemicube_resolution == 0
            || options.hemicube_resolution > 1024
            || options
                .root_bounds
                .is_some_and(|[lo, hi]| !(lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all()))
        {
            return Err(SsvError::InvalidOptions);
        }
        let tolerance = f64::from(light.tolerance());
        let plane_normal = light.normal().as_dvec3();
        let plane_point = light.centroid().as_dvec3();
        // The band holds the light's vertices (planar within the tolerance) and
        // the samples (on the plane within the tolerance), with room to spare.
        let band_half_width = 4.0 * tolerance;
        let (u_axis, v_axis) = plane_normal.any_orthonormal_pair();
        let light_uv: Vec<(f64, f64)> = fallible::collect(light.vertices().iter().map(|v| {
            let d = v.as_dvec3() - plane_point;
            (d.dot(u_axis), d.dot(v_axis))
        }))?;
        let (mut umin, mut umax, mut vmin, mut vmax) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for &(u, v) in &light_uv {
            umin = umin.min(u);
            umax = umax.max(u);
            vmin = vmin.min(v);
            vmax = vmax.max(v);
        }
        let margin = 4.0 * tolerance;
        // Regular triangles as indices into the occluders' positions.
        // (Within its capacity: pushing allocates nothing.)
        let mut regular: Vec<[u32; 3]> = fallible::with_capacity(occluders.triangle_count())?;
        let mut near_light = Vec::new();
        let mut band = Vec::new();
        let mut occluder_lo = DVec3::splat(f64::INFINITY);
        let mut occluder_hi = DVec3::splat(f64::NEG_INFINITY);
        for (t, tri) in occluders.triangles().enumerate() {
            if edges::degenerate(tri[0], tri[1], tri[2]) {
                continue;
            }
            for v in tri {
                occluder_lo = occluder_lo.min(v.as_dvec3());
                occluder_hi = occluder_hi.max(v.as_dvec3());
            }
            let heights = tri.map(|v| (v.as_dvec3() - plane_point).dot(plane_normal));
            let (hmin, hmax) = (
                heights[0].min(heights[1]).min(heights[2]),
                heights[0].max(heights[1]).max(heights[2]),
            );
            if hmin > band_half_width || hmax < -band_half_width {
                regular.push(occluders.triangle_indices(t));
                continue;
            }
            fallible::push(&mut band, tri)?;
            // Conservative: the triangle's footprint box in the plane against the
            // light's, both grown by the margin.
            let (mut tu0, mut tu1, mut tv0, mut tv1) = (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            );
            for v in tri {
                let d = v.as_dvec3() - plane_point;
                let (u, w) = (d.dot(u_axis), d.dot(v_axis));
                tu0 = tu0.min(u);
                tu1 = tu1.max(u);
                tv0 = tv0.min(w);
                tv1 = tv1.max(w);
            }
            if tu0 > umax + margin
                || tu1 < umin - margin
                || tv0 > vmax + margin
                || tv1 < vmin - margin
            {
                regular.push(occluders.triangle_indices(t));
            } else {
                fallible::push(&mut near_light, tri)?;
            }
        }
        let positions: Vec<Vec3> =
            fallible::collect((0..occluders.vertex_count()).map(|v| occluders.position(v)))?;
        let graph = EdgeGraph::from_indexed(&positions, &regular)?;
        let potential: Vec<u32> = fallible::collect(
            (0..graph.edges.len() as u32).filter(|&e| !graph.is_flat(&graph.edges[e as usize])),
        )?;
        let shape = LightShape {
            vertices: fallible::collect(light.vertices().iter().map(|v| v.as_dvec3()))?,
            normal: plane_normal,
            tolerance,
        };
        // The reference caster and the structure, side by side on rayon's
        // threads with `options.parallel`.
        type Structures = (Option<Hierarchy>, Option<Box<Hemicube>>);
        let structure = || -> Result<Structures, OutOfMemory> {
            Ok(match options.structure {
                Structure::Hierarchy => {
                    let root = match options.root_bounds {
                        Some([lo, hi]) => Aabb {
                            min: lo.as_dvec3(),
                            max: hi.as_dvec3(),
                        },
                        None => default_root(occluders, &light),
                    };
                    let hierarchy = Hierarchy::new(&graph, &shape, &potential, root, options)?;
                    (Some(hierarchy), None)
                }
                Structure::Hemicube => {
                    let hemicube = Hemicube::new(
                        &graph,
                        &shape,
                        &potential,
                        light.centroid().as_dvec3(),
                        options.hemicube_resolution as usize,
                    );
                    (None, Some(Box::new(hemicube)))
                }
                Structure::BruteForce | Structure::RayTrace => (None, None),
            })
        };
        #[cfg(feature = "parallel")]
        let (caster, structures) = if options.parallel {
            rayon::join(|| Self::build_caster(&graph), structure)
        } else {
            (Self::build_caster(&graph), structure())
        };
        #[cfg(not(feature = "parallel"))]
        let (caster, structures) = (Self::build_caster(&graph), structure());
        let caster = caster?;
        let (hierarchy, hemicube) = structures?;
        // Angular order of the samples about the centroid (receiver-independent).
        let angle_radius = 1e-3 * f64::from(light.diameter());
        let mut keyed: Vec<(f64, u32)> = fallible::with_capacity(samples.len())?;
        let mut central: Vec<u32> = Vec::new();
        let mut sample_offset: f64 = 0.0;
        for (i, s) in samples.iter().enumerate() {
            let d = s.as_dvec3() - plane_point;
            sample_offset = sample_offset.max(d.dot(plane_normal).abs());
            let (x, y) = (d.dot(u_axis), d.dot(v_axis));
            if libm::hypot(x, y) < angle_radius {
                fallible::push(&mut central, i as u32)?;
            } else {
                keyed.push((pseudo_angle(x, y), i as u32));
            }
        }
        // Unstable sort (no scratch memory): the index breaks every tie.
        keyed.sort_unstable_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
        let angles: Vec<f64> = fallible::collect(keyed.iter().map(|k| k.0))?;
        let angle_starts = fallible::collect(
            (0..=ANGLE_BUCKETS)
                .map(|k| angles.partition_point(|&t| t < k as f64 / ANGLE_SCALE) as u32),
        )?;
        let mut order: Vec<u32> = fallible::with_capacity(samples.len())?;
        order.extend(keyed.iter().map(|k| k.1).chain(central));
        let twice_area: f64 = (0..light_uv.len())
            .map(|i| {
                let ((x0, y0), (x1, y1)) = (light_uv[i], light_uv[(i + 1) % light_uv.len()]);
                x0 * y1 - x1 * y0
            })
            .sum();
        let orientation = if twice_area < 0.0 { -1.0 } else { 1.0 };
        let insets = fallible::collect(order.iter().map(|&o| {
            inset(
                &light_uv,
                orientation,
                samples[o as usize].as_dvec3() - plane_point,
                u_axis,
                v_axis,
            )
        }))?;
        let axis = |axis: usize| {
            fallible::collect(order.iter().map(|&o| f64::from(samples[o as usize][axis])))
        };
        let soa = [axis(0)?, axis(1)?, axis(2)?];
        let (sample_lo, sample_hi) = samples.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), s| (lo.min(s.as_dvec3()), hi.max(s.as_dvec3())),
        );
        let words = samples.len().div_ceil(64);
        let near_sides = plane_sides(&near_light, samples, words)?;
        let band_sides = plane_sides(&band, samples, words)?;
        let near_planes = fallible::collect(near_light.iter().map(AxisPlane::of))?;
        let band_planes = fallible::collect(band.iter().map(AxisPlane::of))?;
        let mut rank = fallible::filled(0u32, order.len())?;
        for (k, &i) in order.iter().enumerate() {
            rank[i as usize] = k as u32;
        }
        let this = SoftShadows {
            occluder_box: occluder_lo
                .cmple(occluder_hi)
                .all()
                .then_some((occluder_lo, occluder_hi)),
            insets,
            soa,
            near_sides,
            band_sides,
            near_planes,
            band_planes,
            sample_lo,
            sample_hi,
            rank,
            order,
            angles,
            angle_starts,
            u_axis,
            v_axis,
            angle_radius,
            sample_offset,
            shape_diameter: f64::from(light.diameter()),
            centroid: light.centroid(),
            light,
            samples: fallible::copied(samples)?,
            structure: options.structure,
            graph,
            potential,
            near_light,
            band,
            caster,
            shape,
            plane_normal,
            plane_point,
            band_half_width,
            hierarchy,
            hemicube,
            queries: AtomicUsize::new(0),
            candidates: AtomicUsize::new(0),
        };
        Ok(this)
    }

    fn build_caster(graph: &EdgeGraph) -> Result<Caster, SsvError> {
        #[cfg(feature = "bvh")]
        {
            let positions: Vec<[f32; 3]> = graph.positions.iter().map(|p| p.to_array()).collect();
            let indices: Vec<u32> = graph.triangles.iter().flatten().copied().collect();
            let mesh = MeshView::new(&positions, &indices).map_err(|_| SsvError::Caster)?;
            // One reference ray per receiver: a quick build pays.
            let scene =
                crate::raycast::BvhScene::with_quality(&mesh, crate::raycast::BuildQuality::Fast)
                    .map_err(|_| SsvError::Caster)?;
            Ok(Caster::Bvh(scene))
        }
        #[cfg(not(feature = "bvh"))]
        {
            let p = |i: u32| graph.positions[i as usize];
            Ok(Caster::Brute(fallible::collect(
                graph.triangles.iter().map(|&[a, b, c]| [p(a), p(b), p(c)]),
            )?))
        }
    }

    /// The light.
    pub fn light(&self) -> &LightPolygon {
        &self.light
    }

    /// The samples, in bit order.
    pub fn samples(&self) -> &[Vec3] {
        &self.samples
    }

    /// Number of samples `N`.
    pub fn sample_count(&self) -> usize {
        self.samples.len()
    }

    /// `ceil(N / 64)`: the `u64` words of one receiver's bits.
    pub fn words_per_receiver(&self) -> usize {
        self.samples.len().div_ceil(64)
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

    /// The visibility bits of receiver `p` into `bits[..words_per_receiver()]`
    /// (bit `i` of word `i / 64` set = sample `i` visible; unused high bits of the
    /// last word cleared; words beyond untouched). Returns the visible count.
    pub fn query(&self, p: Vec3, bits: &mut [u64]) -> Result<u32, SsvError> {
        self.query_detailed(p, bits).map(|info| info.visible)
    }

    /// [`SoftShadows::query`] with the work it did.
    pub fn query_detailed(&self, p: Vec3, bits: &mut [u64]) -> Result<QueryInfo, SsvError> {
        let info = self.query_uncounted(p, bits)?;
        self.queries.fetch_add(1, Ordering::Relaxed);
        self.candidates
            .fetch_add(info.candidates as usize, Ordering::Relaxed);
        Ok(info)
    }

    fn query_uncounted(&self, p: Vec3, bits: &mut [u64]) -> Result<QueryInfo, SsvError> {
        let words = self.words_per_receiver();
        if bits.len() < words {
            return Err(SsvError::BitsTooShort {
                needed: words,
                got: bits.len(),
            });
        }
        if !p.is_finite() {
            return Err(SsvError::NonFiniteReceiver);
        }
        let bits = &mut bits[..words];
        bits.fill(0);
        let n = self.samples.len();
        let mut info = QueryInfo::default();
        let height = (p.as_dvec3() - self.plane_point).dot(self.plane_normal);
        if height.abs() <= self.band_half_width {
            // Inside the band around the light's plane only band triangles can
            // meet a segment (module docs).
            for (k, w) in bits.iter_mut().enumerate() {
                let left = n - 64 * k;
                *w = if left >= 64 { !0 } else { (1 << left) - 1 };
            }
            self.clear_blocked(&self.band, &self.band_sides, &self.band_planes, p, bits);
            info.visible = bits.iter().map(|w| w.count_ones()).sum();
            return Ok(info);
        }
        if self.structure != Structure::RayTrace && self.pyramid_misses_occluders(p.as_dvec3()) {
            // No segment to a sample can meet a triangle.
            set_first(bits, n);
            info.visible = n as u32;
            return Ok(info);
        }
        if self.structure == Structure::RayTrace {
            for (i, &s) in self.samples.iter().enumerate() {
                info.rays += 1;
                let blocked = self.reference_blocked(p, s, false).unwrap_or(true);
                if !blocked && !self.near_blocked(p, s) {
                    bits[i / 64] |= 1 << (i % 64);
                    info.visible += 1;
                }
            }
            return Ok(info);
        }
        let mut silhouettes = Silhouettes::new();
        let lit = with_counters(n, |counters| {
            self.sweep(p, counters, &mut info, &mut silhouettes);
            let min = counters.iter().copied().min().expect("at least one sample");
            if self.minimum_blocked(p, counters, min, &silhouettes) {
                return false;
            }
            if info.silhouettes == 0 {
                // No edge changed a counter: every sample shares the minimum.
                set_first(bits, n);
                return true;
            }
            // Counters are in angular order, bits in the caller's: gathered
            // branch-free through the inverse order (a scattered, branchy
            // store per sample costs far more on a lit receiver).
            for (w, word) in bits.iter_mut().enumerate() {
                let rank = &self.rank[64 * w..(64 * w + 64).min(n)];
                *word = rank.iter().enumerate().fold(0u64, |acc, (j, &k)| {
                    acc | u64::from(counters[k as usize] == min) << j
                });
            }
            true
        });
        info.rays = 1;
        if !lit {
            return Ok(info);
        }
        // The near-light triangles take away the samples they block.
        self.clear_blocked(
            &self.near_light,
            &self.near_sides,
            &self.near_planes,
            p,
            bits,
        );
        info.visible = bits.iter().map(|w| w.count_ones()).sum();
        Ok(info)
    }

    /// The relative depth complexity `R(s)` of every sample, in angular order
    /// (`counters[k]` belongs to sample `order[k]`), from the structure's
    /// candidates (every potential edge for [`Structure::RayTrace`]).
    /// Also records the silhouette edges the sweep meets in `silhouettes`.
    fn sweep(
        &self,
        p: Vec3,
        counters: &mut [i32],
        info: &mut QueryInfo,
        silhouettes: &mut Silhouettes,
    ) {
        self.sweep_with(Kernel::new(self, p, silhouettes), counters, info);
    }

    fn sweep_with(&self, mut kernel: Kernel<'_>, counters: &mut [i32], info: &mut QueryInfo) {
        self.for_each_candidate(kernel.p, |e: u32| {
            info.candidates += 1;
            if kernel.add_edge(self, e, counters) {
                info.silhouettes += 1;
            }
        });
    }

    /// The structure's candidate edges for receiver `p`.
    fn for_each_candidate(&self, p: Vec3, mut visit: impl FnMut(u32)) {
        match (&self.hierarchy, &self.hemicube) {
            (Some(h), _) => {
                h.for_each_candidate(&self.graph, &self.shape, p.as_dvec3(), &mut visit)
            }
            (_, Some(c)) => c.for_each_candidate(p.as_dvec3(), &mut visit),
            _ => self.potential.iter().for_each(|&e| visit(e)),
        }
    }

    /// Whether the pyramid from `p` to the light (grown by its tolerance)
    /// provably misses the box of every occluder: a plane of the pyramid (one
    /// through `p` and a light edge, the light's plane, the plane through `p`
    /// parallel to it) with the box beyond it by more than the tolerance and
    /// the rounding of these few `f64` operations. Then every sample is
    /// visible, with no structure walked and no ray cast: most of a ground
    /// outside the shadows.
    fn pyramid_misses_occluders(&self, p: DVec3) -> bool {
        let Some((lo, hi)) = self.occluder_box else {
            return true;
        };
        let (centre, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
        let light = &self.shape.vertices;
        let scale = light
            .iter()
            .fold(p.abs().max(centre.abs() + half).max_element(), |m, v| {
                m.max(v.abs().max_element())
            });
        let slack = self.shape.tolerance + 1e-9 * scale;
        // The box beyond the plane through `point` with unit normal `n`
        // (pointing away from the pyramid) by more than the slack.
        let beyond = |n: DVec3, point: DVec3| n.dot(centre - point) - n.abs().dot(half) > slack;
        let toward = self.plane_normal * (self.plane_point - p).dot(self.plane_normal).signum();
        if beyond(toward, self.plane_point) || beyond(-toward, p) {
            return true;
        }
        let inside = self.centroid.as_dvec3();
        let k = light.len();
        (0..k).any(|j| {
            let (a, b) = (light[j], light[(j + 1) % k]);
            let n = (a - p).cross(b - p);
            let side = n.dot(inside - p);
            let n = -n * side.signum();
            let length = n.length();
            // A plane nearly through the light's centroid (p near the light's
            // plane) decides nothing.
            side.abs() > 1e-6 * length * (inside - p).length()
                && length.is_finite()
                && length > 0.0
                && beyond(n / length, p)
        })
    }

    /// The silhouette weight of edge `e` at `p` (exact signs, as the sweep
    /// takes them).
    fn silhouette_weight(&self, p: Vec3, e: u32) -> i32 {
        let edge = &self.graph.edges[e as usize];
        let [a, b] = [edge.a, edge.b].map(|v| self.graph.positions[v as usize]);
        let thirds = self.graph.third_of(edge).iter();
        thirds
            .map(|&v| orient3d(a, b, self.graph.positions[v as usize], p))
            .sum()
    }

    /// The depth complexity of every sample relative to the least:
    /// `out[i] = D(p, s_i) - min_j D(p, s_j)`, where `D` counts the triangles
    /// meeting the open segment (as [`segment_meets_triangle`] decides), from
    /// the silhouette sweep (no ray). This is what an any-hit tracer counting
    /// every hit along each segment gives, up to one constant per receiver.
    /// `out` needs [`SoftShadows::sample_count`] entries (more are untouched).
    pub fn relative_depth_complexity(&self, p: Vec3, out: &mut [i32]) -> Result<(), SsvError> {
        let n = self.samples.len();
        if out.len() < n {
            return Err(SsvError::BitsTooShort {
                needed: n,
                got: out.len(),
            });
        }
        if !p.is_finite() {
            return Err(SsvError::NonFiniteReceiver);
        }
        let out = &mut out[..n];
        let count = |tris: &[[Vec3; 3]], s: Vec3| {
            tris.iter()
                .filter(|&&[a, b, c]| segment_meets_triangle(p, s, a, b, c))
                .count() as i32
        };
        let height = (p.as_dvec3() - self.plane_point).dot(self.plane_normal);
        if height.abs() <= self.band_half_width {
            for (o, &s) in out.iter_mut().zip(&self.samples) {
                *o = count(&self.band, s);
            }
        } else {
            let mut silhouettes = Silhouettes::new();
            with_counters(n, |counters| {
                self.sweep(p, counters, &mut QueryInfo::default(), &mut silhouettes);
                for (k, &r) in counters.iter().enumerate() {
                    let i = self.order[k] as usize;
                    out[i] = r + count(&self.near_light, self.samples[i]);
                }
            });
        }
        let min = out.iter().copied().min().unwrap_or(0);
        out.iter_mut().for_each(|o| *o -= min);
        Ok(())
    }

    /// Builds ahead what queries of `points` will need of the structure (the
    /// hierarchy's nodes, split where enough of the receivers fall to pay for
    /// it; nothing for the other structures), so that a batch of receivers
    /// queried next pays neither coarse nodes nor nodes it does not need.
    /// [`SoftShadows::query_batch`] does this itself; call it before
    /// querying a batch one point at a time. With `parallel` (and the
    /// `parallel` feature) the work is spread over rayon's pool. Non-finite
    /// points are skipped. Never changes a query's bits.
    pub fn prepare<P: Copy + Into<Vec3>>(&self, points: &[P], parallel: bool) {
        if let Some(h) = &self.hierarchy {
            // Preparing only saves the queries work: without memory, skip it.
            let Ok(points) = fallible::collect(
                points
                    .iter()
                    .map(|&p| p.into())
                    .filter(|p: &Vec3| p.is_finite())
                    .map(|p| p.as_dvec3()),
            ) else {
                return;
            };
            h.prepare(&self.graph, &self.shape, &points, parallel);
        }
    }

    /// Queries every point: receiver `r`'s bits go to
    /// `bits[r * words_per_receiver()..][..words_per_receiver()]`, its visible
    /// count to `visible[r]` when given; returns the work of all the queries,
    /// summed. Every point is checked before any is computed, and the
    /// hierarchy is prepared for the batch first ([`SoftShadows::prepare`]).
    /// With `parallel` (and the `parallel` feature) the points are spread
    /// over rayon's pool, [`PARALLEL_GRAIN`] at least per task; the results
    /// are the same either way. Points are anything that converts to a
    /// `Vec3` (`[f32; 3]` too, so a caller's flat array need not be copied).
    pub fn query_batch<P: Copy + Into<Vec3> + Sync>(
        &self,
        points: &[P],
        bits: &mut [u64],
        visible: Option<&mut [u32]>,
        parallel: bool,
    ) -> Result<QueryWork, SsvError> {
        let words = self.words_per_receiver();
        let needed = points.len() * words;
        if bits.len() < needed {
            return Err(SsvError::BitsTooShort {
                needed,
                got: bits.len(),
            });
        }
        if let Some(v) = &visible
            && v.len() < points.len()
        {
            return Err(SsvError::BitsTooShort {
                needed: points.len(),
                got: v.len(),
            });
        }
        if points.iter().any(|&p| !p.into().is_finite()) {
            return Err(SsvError::NonFiniteReceiver);
        }
        if points.is_empty() {
            return Ok(QueryWork::default());
        }
        let bits = &mut bits[..needed];
        self.prepare(points, parallel);
        let one = |p: P, out: &mut [u64]| {
            self.query_detailed(p.into(), out)
                .expect("the point is finite and its words are there")
        };
        #[cfg(feature = "parallel")]
        if parallel && points.len() > 1 {
            use rayon::prelude::*;
            let chunks = bits.par_chunks_mut(words.max(1)).zip(points.par_iter());
            let work = match visible {
                Some(v) => chunks
                    .zip(v[..points.len()].par_iter_mut())
                    .with_min_len(PARALLEL_GRAIN)
                    .fold(QueryWork::default, |work, ((out, &p), v)| {
                        let info = one(p, out);
                        *v = info.visible;
                        work.with(&info)
                    })
                    .reduce(QueryWork::default, QueryWork::merge),
                None => chunks
                    .with_min_len(PARALLEL_GRAIN)
                    .fold(QueryWork::default, |work, (out, &p)| {
                        work.with(&one(p, out))
                    })
                    .reduce(QueryWork::default, QueryWork::merge),
            };
            return Ok(work);
        }
        let mut visible = visible;
        let mut work = QueryWork::default();
        for (r, (out, &p)) in bits.chunks_mut(words.max(1)).zip(points).enumerate() {
            let info = one(p, out);
            if let Some(v) = visible.as_deref_mut() {
                v[r] = info.visible;
            }
            work = work.with(&info);
        }
        Ok(work)
    }

    /// The Monte Carlo estimate, from a receiver's bits, of
    /// `∫_L V(p, s) cos θ_p cos θ_s / |s - p|² dA(s)` (thesis Eq. 1.16 per unit
    /// emitted radiance: multiply by the light's radiance for irradiance):
    /// `area / N · Σ_visible max(0, n·d) |n_L·d| / |d|⁴` with `d = s - p`, the
    /// receiver's unit normal `n` and the light's normal `n_L` (two-sided light).
    pub fn irradiance(&self, p: Vec3, normal: Vec3, bits: &[u64]) -> f32 {
        let light_normal = self.light.normal();
        let mut any_visible = false;
        let mut sum = 0.0f64;
        for (i, &s) in self.samples.iter().enumerate() {
            if bits.get(i / 64).is_some_and(|w| w >> (i % 64) & 1 == 1) {
                let d = (s - p).as_dvec3();
                let r2 = d.length_squared();
                if r2 > 0.0 {
                    let cos_p = normal.as_dvec3().dot(d).max(0.0);
                    let cos_l = light_normal.as_dvec3().dot(d).abs();
                    sum += cos_p * cos_l / (r2 * r2);
                    any_visible = true;
                }
            }
        }
        if !any_visible || sum == 0.0 {
            // No light arrives (and a light whose area overflows f32 would
            // make it 0 · ∞).
            return 0.0;
        }
        (sum * f64::from(self.light.area()) / self.samples.len() as f64) as f32
    }

    /// Whether the samples of least relative depth complexity `min` (in
    /// `counters`, angular order) are blocked: exactly when the segment to any
    /// one of them meets a triangle (they share the depth complexity).
    ///
    /// An `f32` ray decides it when the segment keeps clear of every
    /// silhouette edge the sweep met ([`Self::reference_sample`]): then the
    /// ray, within a few units of `f32` rounding of the segment, meets the
    /// surfaces the segment meets. Near an edge that is not a silhouette from
    /// `p` the two triangles are on either side of the segment's plane and
    /// the watertight test cannot slip between them; near a silhouette edge
    /// it can (the segment grazing a surface that the ray misses, or a
    /// boundary edge). Without such a sample among the first tries, or when a
    /// hit away from the receiver's own plane is refuted, the decision is
    /// exact ([`Self::exactly_blocked`]).
    fn minimum_blocked(
        &self,
        p: Vec3,
        counters: &[i32],
        min: i32,
        silhouettes: &Silhouettes,
    ) -> bool {
        let candidates = counters
            .iter()
            .enumerate()
            .filter(|&(_, &r)| r == min)
            .map(|(k, _)| k);
        match self.reference_sample(p, candidates, silhouettes) {
            Some(s) => self
                .reference_blocked(p, s, true)
                .unwrap_or_else(|| self.exactly_blocked(p, s)),
            None => {
                let first = counters.iter().position(|&r| r == min).unwrap_or(0);
                self.exactly_blocked(p, self.samples[self.order[first] as usize])
            }
        }
    }

    /// The first of the first [`REFERENCE_TRIES`] `candidates` (angular
    /// indices) whose segment from `p` stays more than [`NEAR_ANGLE`] (seen
    /// from `p`) from every silhouette edge at `p`: the recorded ones, or
    /// when the record overflowed the structure's candidates again. The sample
    /// must also lie that far inside the light (projected from `p`), so that
    /// an edge near its segment overlaps the light and is a candidate of every
    /// structure (their culling keeps every edge whose projection overlaps
    /// the light). `None` if no candidate qualifies.
    fn reference_sample(
        &self,
        p: Vec3,
        candidates: impl Iterator<Item = usize>,
        silhouettes: &Silhouettes,
    ) -> Option<Vec3> {
        let pw = p.as_dvec3();
        // Height of p over the light's plane: a direction off by an angle α
        // meets the plane α |s'|² / h from s.
        let height = (self.plane_point - pw).dot(self.plane_normal).abs();
        let near = |sw: DVec3, e: u32| {
            let edge = &self.graph.edges[e as usize];
            let [a, b] = [edge.a, edge.b].map(|v| self.graph.positions[v as usize].as_dvec3() - pw);
            direction_near_edge(sw, a, b)
        };
        let chosen = candidates.take(REFERENCE_TRIES).find(|&k| {
            let s = self.samples[self.order[k] as usize];
            let sw = s.as_dvec3() - pw;
            let deep_inside = self.insets[k] > 4.0 * NEAR_ANGLE * sw.length_squared() / height;
            if !deep_inside {
                return false;
            }
            if silhouettes.overflow {
                // Every silhouette again, from the structure's candidates:
                // the cheap test of the direction first.
                let mut clear = true;
                self.for_each_candidate(p, |e| {
                    clear &= !(near(sw, e) && self.silhouette_weight(p, e) != 0);
                });
                return clear;
            }
            // The f32 unit normals are within 1e-7 of the exact ones: the
            // prefilter's bound allows for it.
            let bound = (NEAR_ANGLE + 1e-6) * sw.length();
            silhouettes
                .recorded()
                .all(|(e, n)| n.as_dvec3().dot(sw).abs() > bound || !near(sw, e))
        });
        chosen.map(|k| self.samples[self.order[k] as usize])
    }

    /// The reference ray over the open segment `p → s`, through the caster.
    ///
    /// The `f32` watertight test may report a triangle the segment only touches
    /// at `p` (a receiver on a surface: the triangle's plane holds `p` and
    /// rounding puts the hit at `t ≈ 1e-17`). So an occlusion is confirmed: the
    /// nearest hit is re-checked with the exact segment test, and if refuted
    /// the search goes on beyond it. With `certified`, a refuted hit whose
    /// plane does not hold `p` returns `None` instead: the ray then passes
    /// within rounding of that triangle's edge, where it may also have skipped
    /// the neighbour the segment does cross.
    fn reference_blocked(&self, p: Vec3, s: Vec3, certified: bool) -> Option<bool> {
        let mut ray = Ray::new(p, s - p, 1.0);
        if !self.caster.occluded(&ray) {
            return Some(false);
        }
        for _ in 0..MAX_REFUTED_HITS {
            let Some((t, triangle)) = self.caster.closest_hit(&ray) else {
                return Some(false);
            };
            let [a, b, c] =
                self.graph.triangles[triangle].map(|v| self.graph.positions[v as usize]);
            if segment_meets_triangle(p, s, a, b, c) || t <= ray.t_min || t.is_nan() {
                return Some(true);
            }
            if certified && orient3d(a, b, c, p) != 0 {
                return None;
            }
            ray.t_min = t;
        }
        Some(true)
    }

    /// Whether the open segment `p → s` meets an occluder triangle, exactly
    /// ([`segment_meets_triangle`] on every triangle whose box meets the box of
    /// one of [`SEGMENT_PIECES`] consecutive pieces of the segment, found
    /// through the reference caster's hierarchy; without `bvh`, every triangle
    /// whose box meets the segment's), for the rare references
    /// [`Self::minimum_blocked`] cannot leave to a ray.
    #[cold]
    #[inline(never)]
    fn exactly_blocked(&self, p: Vec3, s: Vec3) -> bool {
        let meets = |t: usize| {
            let [a, b, c] = self.graph.triangles[t].map(|v| self.graph.positions[v as usize]);
            segment_meets_triangle(p, s, a, b, c)
        };
        #[cfg(feature = "bvh")]
        {
            let Caster::Bvh(scene) = &self.caster;
            let (pw, sw) = (p.as_dvec3(), s.as_dvec3());
            let d = sw - pw;
            // Every point of a piece is in the box of its ends; the ends are
            // off by the rounding of `p + t d` (t is exact: a power of two
            // divides it), far below this pad.
            let pad = 4.0 * f64::EPSILON * (pw.abs() + sw.abs());
            (0..SEGMENT_PIECES).any(|k| {
                let t = |k: usize| k as f64 / SEGMENT_PIECES as f64;
                let (x0, x1) = (pw + d * t(k), pw + d * t(k + 1));
                let lo = (x0.min(x1) - pad).to_array().map(crate::geom::f32_down);
                let hi = (x0.max(x1) + pad).to_array().map(crate::geom::f32_up);
                scene.any_in_box(Vec3::from(lo), Vec3::from(hi), meets)
            })
        }
        #[cfg(not(feature = "bvh"))]
        {
            let (lo, hi) = (p.min(s), p.max(s));
            (0..self.graph.triangles.len()).any(|t| {
                let [a, b, c] = self.graph.triangles[t].map(|v| self.graph.positions[v as usize]);
                let (tlo, thi) = (a.min(b).min(c), a.max(b).max(c));
                tlo.cmple(hi).all() && thi.cmpge(lo).all() && meets(t)
            })
        }
    }

    /// Clears in `bits` every sample `s` for which one of `triangles` meets the
    /// open segment `p → s`, exactly as [`segment_meets_triangle`] decides, with
    /// the samples' sides of each plane taken from `sides` (see
    /// [`plane_sides`]).
    ///
    /// [`segment_meets_triangle`] needs `p` and `s` strictly on opposite sides
    /// of the triangle's plane (an open segment with an endpoint on the plane,
    /// or both on one side, touches the plane at most at that endpoint, which it
    /// excludes; a segment in the plane is declared not to meet the triangle).
    /// Both signs are the same exact `orient3d(a, b, c, ·)`, so with the side of
    /// `p` computed once per triangle only the samples strictly on the other
    /// side go on to the edge tests, and the result is the same bit for bit.
    /// This matters most for receivers on a near-light triangle's plane (a
    /// floor crossing the light's plane): there the sign of `p` needs the exact
    /// expansion, once per triangle instead of once per sample.
    fn clear_blocked(
        &self,
        triangles: &[[Vec3; 3]],
        sides: &[u64],
        planes: &[Option<AxisPlane>],
        p: Vec3,
        bits: &mut [u64],
    ) {
        let words = bits.len();
        for ((&[a, b, c], side), plane) in triangles
            .iter()
            .zip(sides.chunks_exact(2 * words))
            .zip(planes)
        {
            let p_side = match plane {
                Some(plane) => plane.side(p),
                None => orient3d(a, b, c, p),
            };
            let opposite = match p_side {
                1 => &side[words..],
                -1 => &side[..words],
                _ => continue,
            };
            for (k, (w, &o)) in bits.iter_mut().zip(opposite).enumerate() {
                let mut todo = *w & o;
                while todo != 0 {
                    let j = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    if crossing_in_triangle(p, self.samples[64 * k + j], a, b, c) {
                        *w &= !(1 << j);
                    }
                }
            }
        }
    }

    fn near_blocked(&self, p: Vec3, s: Vec3) -> bool {
        self.near_light
            .iter()
            .any(|&[a, b, c]| segment_meets_triangle(p, s, a, b, c))
    }
}

/// The plane of a triangle whose corners share one coordinate exactly
/// (`corner[axis] == value`, a floor or a wall), where `orient3d(a, b, c, p)`
/// needs no determinant: with column `axis` constant (`value - p[axis]`) in
/// `det[a - p, b - p, c - p]`, the determinant is that difference times the
/// triangle's projected 2D orientation, which does not depend on `p`. So the
/// sign is `sign(p[axis] - value)` times `up`, the sign at one point above the
/// plane (exact, taken once). This spares the exact expansion that a receiver
/// lying on such a plane (a floor receiver) would otherwise need.
#[derive(Clone, Copy, Debug)]
struct AxisPlane {
    axis: usize,
    value: f32,
    up: i32,
}

impl AxisPlane {
    fn of(&[a, b, c]: &[Vec3; 3]) -> Option<AxisPlane> {
        let axis = (0..3).find(|&k| a[k] == b[k] && b[k] == c[k])?;
        let value = a[axis];
        // A representable point strictly above the plane (finite, so that
        // orient3d is exact on it).
        let above = [value + 1.0, value * 2.0, value * 0.5]
            .into_iter()
            .find(|&v| v > value && v.is_finite())?;
        let mut q = a;
        q[axis] = above;
        let up = orient3d(a, b, c, q);
        (up != 0).then_some(AxisPlane { axis, value, up })
    }

    /// `orient3d(a, b, c, p)` for the triangle this was made from.
    #[inline]
    fn side(&self, p: Vec3) -> i32 {
        let x = p[self.axis];
        if x > self.value {
            self.up
        } else if x < self.value {
            -self.up
        } else {
            0
        }
    }
}

/// The side of every sample of each triangle's plane, as
/// [`segment_meets_triangle`] computes it (`orient3d(a, b, c, s)`, exact): per
/// triangle `words` words with bit `i` set where sample `i` is strictly above
/// (`> 0`), then `words` words where it is strictly below (`< 0`).
fn plane_sides(
    triangles: &[[Vec3; 3]],
    samples: &[Vec3],
    words: usize,
) -> Result<Vec<u64>, OutOfMemory> {
    let mut sides = fallible::filled(0u64, 2 * words * triangles.len())?;
    for (&[a, b, c], side) in triangles.iter().zip(sides.chunks_exact_mut(2 * words)) {
        for (i, &s) in samples.iter().enumerate() {
            match orient3d(a, b, c, s) {
                1 => side[i / 64] |= 1 << (i % 64),
                -1 => side[words + i / 64] |= 1 << (i % 64),
                _ => {}
            }
        }
    }
    Ok(sides)
}

/// Per-receiver state of the depth-complexity integration. A sample relative
/// to the receiver is `s - p` rounded once in `f64` (computed where it is
/// used, from the shared structure of arrays: nothing per sample is written
/// per receiver).
struct Kernel<'a> {
    p: Vec3,
    pw: DVec3,
    sx: &'a [f64],
    sy: &'a [f64],
    sz: &'a [f64],
    /// Componentwise largest |s - p| (for the error bounds).
    smax: DVec3,
    /// Centroid relative to the receiver.
    cp: DVec3,
    /// Light vertices relative to the receiver (quick rejection).
    lights: [DVec3; MAX_LIGHT_VERTICES],
    /// Their lengths, scaled by `2 NEAR_ANGLE`: how far (seen from p) the
    /// plane of a recorded silhouette may pass beside the light.
    light_near: [f64; MAX_LIGHT_VERTICES],
    light_count: usize,
    /// The receiver's side of the light plane as a direction: the sweep happens
    /// in front of p along it.
    toward: DVec3,
    /// Height of the centroid over the receiver along `toward`.
    hc: f64,
    /// `|cp|`, for the projection's rounding bound.
    cp_length: f64,
    /// The part of the arc margin due to samples off the light's plane
    /// (receiver-dependent only); `None` when it is too large for arcs.
    shift_margin: Option<f64>,
    /// Tests only: every sample (no arc, no bucket range) through the
    /// per-sample [`Kernel::crosses`] (the slow twin of the arc-restricted,
    /// branch-free pass).
    slow: bool,
    /// Tests only: samples the fast pass left unsure so far.
    unsure: u32,
    /// Where the silhouette edges met are recorded (for the choice of the
    /// reference sample).
    silhouettes: &'a mut Silhouettes,
}

/// Most silhouette edges a query records for [`SoftShadows::reference_sample`];
/// past this every reference decision is exact ([`SoftShadows::exactly_blocked`]).
const RECORDED_SILHOUETTES: usize = 1024;

/// Angle (as a sine) within which a reference segment counts as near a
/// silhouette edge, as seen from the receiver. The `f32` ray departs from the
/// exact segment by a few units of `f32` rounding in angle (the rounded
/// direction, the corners moved to the origin and sheared, the edge functions'
/// own rounding: about `20 ε₃₂ ≈ 1.2e-6` in all), so beyond this the ray crosses
/// each silhouette edge on the same side as the segment, with a factor of fifty
/// to spare.
const NEAR_ANGLE: f64 = 1.0 / 16384.0;

/// Reference candidates tried before a query decides its reference exactly.
const REFERENCE_TRIES: usize = 8;

/// The silhouette edges of one receiver whose plane through it comes within
/// [`NEAR_ANGLE`] of the light (the edges near which an `f32` ray can cross
/// differently from the exact segment), each with that plane's unit normal.
///
/// The slots are left uninitialised until recorded: a query makes one of
/// these 16 KiB records on its stack, and writing it whole would cost more than
/// the bunny's reference ray.
struct Silhouettes {
    /// Edge and unit `a' × b'` (rounded to `f32`: the test that reads it
    /// allows for that); the first `len` are written.
    slots: [MaybeUninit<(u32, [f32; 3])>; RECORDED_SILHOUETTES],
    len: usize,
    /// More edges were met than fit.
    overflow: bool,
}

impl Silhouettes {
    fn new() -> Self {
        Silhouettes {
            slots: [const { MaybeUninit::uninit() }; RECORDED_SILHOUETTES],
            len: 0,
            overflow: false,
        }
    }

    fn record(&mut self, edge: u32, unit_normal: DVec3) {
        match self.slots.get_mut(self.len) {
            Some(slot) => {
                slot.write((edge, unit_normal.as_vec3().to_array()));
                self.len += 1;
            }
            None => self.overflow = true,
        }
    }

    /// The recorded edges and normals.
    fn recorded(&self) -> impl Iterator<Item = (u32, Vec3)> + '_ {
        self.slots[..self.len].iter().map(|slot| {
            #[allow(unsafe_code)]
            // SAFETY: `record` writes slot `len` before it increments `len`,
            // and nothing else changes either, so every slot below `len` holds
            // a written value (a plain `Copy` tuple).
            let (edge, normal) = unsafe { slot.assume_init() };
            (edge, Vec3::from_array(normal))
        })
    }
}

#[inline]
fn wide(v: Vec3) -> [f64; 3] {
    [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
}

impl<'a> Kernel<'a> {
    fn new(ss: &'a SoftShadows, p: Vec3, silhouettes: &'a mut Silhouettes) -> Self {
        let pw = p.as_dvec3();
        // Rounding is monotone, so the largest |fl(s - p)| over the samples is
        // reached at the samples' componentwise bounds: the same value as the
        // maximum over every sample.
        let smax = (ss.sample_lo - pw).abs().max((ss.sample_hi - pw).abs());
        let mut k = Kernel {
            p,
            pw,
            sx: &ss.soa[0],
            sy: &ss.soa[1],
            sz: &ss.soa[2],
            smax,
            cp: ss.centroid.as_dvec3() - pw,
            lights: [DVec3::ZERO; MAX_LIGHT_VERTICES],
            light_near: [0.0; MAX_LIGHT_VERTICES],
            light_count: ss.shape.vertices.len(),
            toward: ss.plane_normal * (ss.plane_point - pw).dot(ss.plane_normal).signum(),
            hc: 0.0,
            cp_length: 0.0,
            shift_margin: None,
            slow: false,
            unsure: 0,
            silhouettes,
        };
        k.hc = k.cp.dot(k.toward);
        k.cp_length = k.cp.length();
        // Samples are on the plane only up to rounding (or the tolerance of
        // user samples): seen from p, a sample at height e off the plane shifts
        // by up to |s - p| e / hc, an angle of that over its distance from the
        // centroid (at least `angle_radius`).
        let sample_shift =
            (k.cp_length + ss.shape_diameter) * ss.sample_offset / k.hc / ss.angle_radius;
        if sample_shift <= 0.25 {
            k.shift_margin = Some(2.0 * sample_shift + 1e-9);
        }
        for (i, v) in ss.shape.vertices.iter().enumerate() {
            k.lights[i] = *v - pw;
            k.light_near[i] = 2.0 * NEAR_ANGLE * k.lights[i].length();
        }
        k
    }

    /// Adds the edge's contribution to the relative depth complexity of every
    /// sample; returns whether its weight at the receiver is non-zero.
    fn add_edge(&mut self, ss: &SoftShadows, e: u32, counters: &mut [i32]) -> bool {
        let g = &ss.graph;
        let edge = &g.edges[e as usize];
        let (a, b) = (g.positions[edge.a as usize], g.positions[edge.b as usize]);
        let (aw, bw) = (a.as_dvec3() - self.pw, b.as_dvec3() - self.pw);
        // Quick rejections first (conservative, with slack): the edge wholly
        // behind the receiver or beyond the light's plane cannot meet (p, c, s).
        let slack = 1e-9 * (aw.abs().max(bw.abs()).max(self.cp.abs()).max_element());
        let (ha, hb) = (aw.dot(self.toward), bw.dot(self.toward));
        let hc = self.hc;
        if (ha < -slack && hb < -slack) || (ha > hc + slack && hb > hc + slack) {
            return false;
        }
        // Silhouette weight: exact signs, zero counts zero.
        let (a3, b3) = (aw.to_array(), bw.to_array());
        let mut weight = 0;
        for &v in g.third_of(edge) {
            let vp = g.positions[v as usize];
            let vw = (vp.as_dvec3() - self.pw).to_array();
            let (det, perm) = det3_with_permanent(a3, b3, vw);
            // Branch-free in the certain case (the sign is data-dependent, a
            // branch on it mispredicts about half the time).
            let bound = ORIENT_BOUND * perm;
            weight += i32::from(det > bound) - i32::from(det < -bound);
            if det.abs() <= bound {
                weight += orient3d_exact(wide(a), wide(b), wide(vp), wide(self.p));
            }
        }
        if weight == 0 {
            return false;
        }
        let nrm = aw.cross(bw);
        let nperm = DVec3::new(
            (aw.y * bw.z).abs() + (aw.z * bw.y).abs(),
            (aw.z * bw.x).abs() + (aw.x * bw.z).abs(),
            (aw.x * bw.y).abs() + (aw.y * bw.x).abs(),
        );
        let nrm_length = nrm.length();
        // The plane (p, a, b) must cut the light (grown by its tolerance) for
        // the edge to change a counter, and come within [`NEAR_ANGLE`] of it
        // (seen from p) for a reference segment to pass near the edge.
        let reach = nrm_length * ss.shape.tolerance * 2.0;
        let (mut above, mut below) = (false, false);
        let (mut near_above, mut near_below) = (false, false);
        let lights = self.lights[..self.light_count].iter();
        for (l, near) in lights.zip(&self.light_near) {
            let d = nrm.dot(*l);
            let err = ORIENT_BOUND * nperm.dot(l.abs()) + reach;
            above |= d > -err;
            below |= d < err;
            let near = err + near * nrm_length;
            near_above |= d > -near;
            near_below |= d < near;
        }
        if near_above && near_below {
            self.silhouettes.record(e, nrm / nrm_length);
        }
        if !(above && below) {
            return true;
        }
        // Side of the centroid, its ties broken by the centroid's
        // infinitesimal move (module docs).
        let cw = self.cp.to_array();
        let (det, perm) = det3_with_permanent(a3, b3, cw);
        let c_pos = if det.abs() > ORIENT_BOUND * perm {
            det > 0.0
        } else {
            let (a, b, p) = (wide(a), wide(b), wide(self.p));
            match orient3d_exact(a, b, wide(ss.centroid), p) {
                0 => cross_sign_sequence(a, p, b, p) > 0,
                sign => sign > 0,
            }
        };
        let amat = aw.cross(self.cp);
        let bmat = bw.cross(self.cp);
        let perm_of = |x: DVec3, y: DVec3| {
            DVec3::new(
                (x.y * y.z).abs() + (x.z * y.y).abs(),
                (x.z * y.x).abs() + (x.x * y.z).abs(),
                (x.x * y.y).abs() + (x.y * y.x).abs(),
            )
        };
        let err_n = ORIENT_BOUND * nperm.dot(self.smax);
        let err_a = ORIENT_BOUND * perm_of(aw, self.cp).dot(self.smax);
        let err_b = ORIENT_BOUND * perm_of(bw, self.cp).dot(self.smax);
        let err_c = ORIENT_BOUND * perm;
        // The crossing test is spelled out at `EdgePlanes`.
        let want = !c_pos;
        let planes = EdgePlanes {
            a,
            b,
            nrm,
            amat,
            bmat,
            det,
            errs: [err_n, err_a, err_b, err_c + err_n + err_a + err_b],
            // The wanted side folded into a factor of ±1 (exact).
            g: if want { 1.0 } else { -1.0 },
            want,
            contribution: if want { weight } else { -weight },
        };
        let n = counters.len();
        let mut unsure = 0;
        // The slow twin tests every sample: it checks the arc and its bucket
        // range as well as the fast pass.
        let arc = if self.slow {
            None
        } else {
            self.arc(ss, aw, bw)
        };
        match arc {
            None => unsure += self.run(ss, &planes, 0, n, counters),
            Some((lo, hi)) => {
                // Samples by pseudo-angle about the centroid: those in the arc
                // (a cyclic range), then those too close to the centroid for an
                // angle (always tested). The buckets holding `lo` and `hi`
                // (exact: the scale is a power of two) widen the range to
                // whole buckets: extra samples only get tested, none is left
                // out.
                let angled = ss.angles.len();
                let bucket = |t: f64| ((t * ANGLE_SCALE) as usize).min(ANGLE_BUCKETS - 1);
                let first = ss.angle_starts[bucket(lo)] as usize;
                let last = ss.angle_starts[bucket(hi) + 1] as usize;
                if lo <= hi {
                    unsure += self.run(ss, &planes, first, last, counters);
                } else if first < last {
                    // A wrapped range whose widened ends overlap: every
                    // sample (once).
                    unsure += self.run(ss, &planes, 0, angled, counters);
                } else {
                    unsure += self.run(ss, &planes, first, angled, counters);
                    unsure += self.run(ss, &planes, 0, last, counters);
                }
                if angled < n {
                    unsure += self.run(ss, &planes, angled, n, counters);
                }
            }
        }
        self.unsure += unsure;
        true
    }

    /// Adds the edge's contribution to the samples `lo..hi` (angular order)
    /// that it crosses; returns how many were unsure after the float pass.
    ///
    /// The fast pass: every sample classified branch-free from the certified
    /// float signs ([`Kernel::crosses`]'s float half): certainly crossing
    /// (counted here), certainly not, or unsure (some sign within its bound and
    /// no certain rejection). Unsure samples, rare, then go through
    /// [`Kernel::crosses`] (exact signs where the bounds do not settle them),
    /// so the counts are exactly its counts for every sample.
    #[inline(always)]
    fn run(
        &self,
        ss: &SoftShadows,
        planes: &EdgePlanes,
        lo: usize,
        hi: usize,
        counters: &mut [i32],
    ) -> u32 {
        if self.slow {
            for (i, c) in counters.iter_mut().enumerate().take(hi).skip(lo) {
                if self.crosses(ss, planes, i) {
                    *c += planes.contribution;
                }
            }
            return 0;
        }
        let (px, py, pz) = (self.pw.x, self.pw.y, self.pw.z);
        let mut any_unsure = false;
        let range = lo..hi;
        let (xs, ys, zs) = (
            &self.sx[range.clone()],
            &self.sy[range.clone()],
            &self.sz[range.clone()],
        );
        let cs = &mut counters[range];
        for (((c, &x), &y), &z) in cs.iter_mut().zip(xs).zip(ys).zip(zs) {
            let (hit, reject) = planes.classify([x - px, y - py, z - pz]);
            *c += if hit { planes.contribution } else { 0 };
            any_unsure |= !(hit | reject);
        }
        if any_unsure {
            self.settle(ss, planes, lo, hi, counters)
        } else {
            0
        }
    }

    /// The unsure samples of `lo..hi` through the exact test (rare: kept out
    /// of line so that the fast loop stays small).
    #[cold]
    #[inline(never)]
    fn settle(
        &self,
        ss: &SoftShadows,
        planes: &EdgePlanes,
        lo: usize,
        hi: usize,
        counters: &mut [i32],
    ) -> u32 {
        let mut unsure = 0;
        for (i, c) in counters.iter_mut().enumerate().take(hi).skip(lo) {
            let v = [
                self.sx[i] - self.pw.x,
                self.sy[i] - self.pw.y,
                self.sz[i] - self.pw.z,
            ];
            let (hit, reject) = planes.classify(v);
            if !(hit | reject) {
                unsure += 1;
                if self.crosses(ss, planes, i) {
                    *c += planes.contribution;
                }
            }
        }
        unsure
    }

    /// Whether the edge meets the triangle `(p, c, s)` for sample `i` (angular
    /// order), exactly: the certified float signs, then exact `orient3d`
    /// where they do not settle (the per-sample reference of the fast pass).
    fn crosses(&self, ss: &SoftShadows, planes: &EdgePlanes, i: usize) -> bool {
        let sign = |v: f64, err: f64| -> Option<bool> {
            if v > err {
                Some(true)
            } else if v < -err {
                Some(false)
            } else {
                None
            }
        };
        let EdgePlanes {
            a,
            b,
            nrm,
            amat,
            bmat,
            det,
            want,
            ..
        } = *planes;
        let [err_n, err_a, err_b, err_base] = planes.errs;
        let (x, y, z) = (
            self.sx[i] - self.pw.x,
            self.sy[i] - self.pw.y,
            self.sz[i] - self.pw.z,
        );
        let vs = nrm.x * x + nrm.y * y + nrm.z * z;
        let fs = sign(vs, err_n);
        if fs == Some(!want) {
            return false;
        }
        let va = amat.x * x + amat.y * y + amat.z * z;
        let vb = bmat.x * x + bmat.y * y + bmat.z * z;
        let fa = sign(va, err_a);
        let fb = sign(vb, err_b);
        if fa.is_some() && fa == fb {
            return false;
        }
        let vo = det - vs + va - vb;
        let err_o = err_base + SUM_BOUND * (det.abs() + vs.abs() + va.abs() + vb.abs());
        let fo = sign(vo, err_o);
        if fo == Some(!want) {
            return false;
        }
        if fs.is_none() || fa.is_none() || fb.is_none() || fo.is_none() {
            let s = wide(ss.samples[ss.order[i] as usize]);
            let pp = wide(self.p);
            let cc = wide(ss.centroid);
            let (a, b) = (wide(a), wide(b));
            // The sign, exact; where it is zero and the determinant has the
            // centroid in it, the sign of the term the centroid's move adds
            // (`moved`), else negative.
            let exact_pos = |f: Option<bool>, [x, y, z, w]: [[f64; 3]; 4], moved: fn(_) -> i32| {
                f.unwrap_or_else(|| match orient3d_exact(x, y, z, w) {
                    0 => moved([x, y, z, w]) > 0,
                    sign => sign > 0,
                })
            };
            let ps = exact_pos(fs, [a, b, s, pp], |_| 0);
            // det[a - p, c - p, s - p]: the move adds det[a - p, e, s - p].
            let pa = exact_pos(fa, [a, cc, s, pp], |[x, _, z, w]| {
                -cross_sign_sequence(x, w, z, w)
            });
            let pb = exact_pos(fb, [b, cc, s, pp], |[x, _, z, w]| {
                -cross_sign_sequence(x, w, z, w)
            });
            // det[a - s, b - s, c - s]: the move adds det[a - s, b - s, e].
            let po = exact_pos(fo, [a, b, cc, s], |[x, y, _, w]| {
                cross_sign_sequence(x, w, y, w)
            });
            if ps != want || pa == pb || po != want {
                return false;
            }
        }
        true
    }

    /// The pseudo-angle range `[lo, hi]` (cyclic: `lo > hi` wraps past 4) about
    /// the centroid in the light's plane that holds every sample `s` for which
    /// the segment from the centroid to `s` can cross the edge's projection from
    /// the receiver, grown by a margin far above the rounding of the projection;
    /// `None` (test every sample) when the projection is ill-conditioned (an
    /// endpoint nearly level with or behind the receiver, an endpoint projecting
    /// near the centroid, or the edge's projection nearly through it).
    fn arc(&self, ss: &SoftShadows, aw: DVec3, bw: DVec3) -> Option<(f64, f64)> {
        let shift_margin = self.shift_margin?;
        let hc = self.hc;
        let (ha, hb) = (aw.dot(self.toward), bw.dot(self.toward));
        if !(ha > 1e-3 * hc && hb > 1e-3 * hc) {
            return None;
        }
        // The 1-norm bounds the length from above (a larger rounding bound).
        let norm1 = |w: DVec3| w.x.abs() + w.y.abs() + w.z.abs();
        let project = |w: DVec3, h: f64| {
            let scale = hc / h;
            let q = w * scale - self.cp;
            let err = 1e-12 * (norm1(w) * scale + self.cp_length);
            (q.dot(ss.u_axis), q.dot(ss.v_axis), err)
        };
        let (xa, ya, ea) = project(aw, ha);
        let (xb, yb, eb) = project(bw, hb);
        // Bounds of the projections' distances from the centroid without a
        // square root: max(|x|, |y|) <= r <= |x| + |y|. The lower bound goes
        // where r divides an error (a wider margin), the upper one where it
        // scales a threshold below which the arc is not used.
        let (ra, rb) = (xa.abs().max(ya.abs()), xb.abs().max(yb.abs()));
        if ra < 1e4 * ea || rb < 1e4 * eb {
            return None;
        }
        let cross = xa * yb - ya * xb;
        if cross.abs() < 1e-6 * (xa.abs() + ya.abs()) * (xb.abs() + yb.abs()) {
            return None;
        }
        let margin = 4.0 * (ea * rb + eb * ra) / (ra * rb) + shift_margin;
        let (pa, pb) = (pseudo_angle(xa, ya), pseudo_angle(xb, yb));
        // Counter-clockwise from the first to the second is the short way.
        let (from, to) = if cross > 0.0 { (pa, pb) } else { (pb, pa) };
        let wrap = |t: f64| {
            if t < 0.0 {
                t + 4.0
            } else if t >= 4.0 {
                t - 4.0
            } else {
                t
            }
        };
        Some((wrap(from - margin), wrap(to + margin)))
    }
}

/// Rounding of the four-term sum `det(a',b',c') - det(a',b',s') + det(a',c',s')
/// - det(b',c',s')`, on top of each term's own bound.
const SUM_BOUND: f64 = 4.0 * f64::EPSILON;

/// One edge's planes at one receiver, for the per-sample crossing test: the
/// edge meets the triangle `(p, c, s)` when `(a, b)` crosses the plane
/// `(p, c, s)` (`det(a', c', s')` and `det(b', c', s')` differ in sign) and the
/// three orientations `orient(a, b, p, c) = -det(a', b', c')`,
/// `orient(a, b, s, p) = det(a', b', s')` and `orient(a, b, c, s) =
/// det(a',b',c') - det(a',b',s') + det(a',c',s') - det(b',c',s')` share one
/// sign (the line `ab` passes through the closed triangle).
struct EdgePlanes {
    a: Vec3,
    b: Vec3,
    /// `a' × b'`: `det(a', b', s') = nrm · s'`.
    nrm: DVec3,
    /// `a' × c'`.
    amat: DVec3,
    /// `b' × c'`.
    bmat: DVec3,
    /// `det(a', b', c')`.
    det: f64,
    /// Error bounds of `nrm · s'`, `amat · s'`, `bmat · s'`, and the sum of
    /// those three and `det`'s.
    errs: [f64; 4],
    /// `1` when the wanted side (`want`) is positive, else `-1`.
    g: f64,
    /// The side of `p`'s plane through the edge opposite the centroid's.
    want: bool,
    /// `±weight`: what a crossed sample's counter gets.
    contribution: i32,
}

impl EdgePlanes {
    /// Certainly crossing, certainly not (both false: unsure), from the
    /// certified float signs, branch-free.
    #[inline(always)]
    fn classify(&self, v: [f64; 3]) -> (bool, bool) {
        let (nrm, amat, bmat) = (self.nrm, self.amat, self.bmat);
        let [err_n, err_a, err_b, err_base] = self.errs;
        let [x, y, z] = v;
        let vs = nrm.x * x + nrm.y * y + nrm.z * z;
        let va = amat.x * x + amat.y * y + amat.z * z;
        let vb = bmat.x * x + bmat.y * y + bmat.z * z;
        let vo = self.det - vs + va - vb;
        let err_o = err_base + SUM_BOUND * (self.det.abs() + vs.abs() + va.abs() + vb.abs());
        let (sg, og) = (vs * self.g, vo * self.g);
        let (a_pos, a_neg) = (va > err_a, va < -err_a);
        let (b_pos, b_neg) = (vb > err_b, vb < -err_b);
        let hit = (sg > err_n) & (og > err_o) & ((a_pos & b_neg) | (a_neg & b_pos));
        let reject = (sg < -err_n) | (og < -err_o) | (a_pos & b_pos) | (a_neg & b_neg);
        (hit, reject)
    }
}

/// How far the point `d` (relative to the light's centroid) lies inside the
/// convex polygon `uv` (the light's vertices in the plane's `(u, v)`
/// coordinates), measured in the plane: the least distance to an edge's line,
/// negative outside. `orientation` is 1 for a counter-clockwise `uv`, -1 for a
/// clockwise one.
fn inset(uv: &[(f64, f64)], orientation: f64, d: DVec3, u_axis: DVec3, v_axis: DVec3) -> f64 {
    let (x, y) = (d.dot(u_axis), d.dot(v_axis));
    (0..uv.len())
        .map(|i| {
            let ((x0, y0), (x1, y1)) = (uv[i], uv[(i + 1) % uv.len()]);
            let (ex, ey) = (x1 - x0, y1 - y0);
            orientation * (ex * (y - y0) - ey * (x - x0)) / libm::hypot(ex, ey)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Whether the direction `s` (from the receiver) is within [`NEAR_ANGLE`] of
/// the edge from `a` to `b` (relative to the receiver) as seen from the
/// receiver: within that angle of the plane through the receiver and the edge,
/// and, in that plane, within that angle of the arc of directions from `a` to
/// `b` (a superset of the directions within that angle of the edge's points).
/// An edge seen end-on (its plane undefined) is near a direction near either
/// endpoint. `f64` from `f32` coordinates: far more precise than the angle.
fn direction_near_edge(s: DVec3, a: DVec3, b: DVec3) -> bool {
    let n = a.cross(b);
    let (ls, la, lb, ln) = (s.length(), a.length(), b.length(), n.length());
    let near_endpoint =
        |e: DVec3, le: f64| e.cross(s).length() <= NEAR_ANGLE * le * ls && e.dot(s) > 0.0;
    if ln <= 1e-9 * la * lb {
        return near_endpoint(a, la) || near_endpoint(b, lb);
    }
    if n.dot(s).abs() > NEAR_ANGLE * ln * ls {
        return false;
    }
    // In the plane, `a → b` turns counter-clockwise about `n` through less
    // than a half turn: `s` is inside the arc when it is on the inner side of
    // both ends, allowing the angle.
    let inside_a = a.cross(s).dot(n) >= -NEAR_ANGLE * la * ls * ln;
    let inside_b = s.cross(b).dot(n) >= -NEAR_ANGLE * ls * lb * ln;
    (inside_a && inside_b) || near_endpoint(a, la) || near_endpoint(b, lb)
}

/// A cheap angle substitute, monotone in the angle of `(x, y)` about the origin,
/// in `[0, 4)`, changing by at most one unit per radian (so an angle margin is
/// also a pseudo-angle margin).
#[inline]
fn pseudo_angle(x: f64, y: f64) -> f64 {
    let t = y / (x.abs() + y.abs());
    if x >= 0.0 {
        if t >= 0.0 { t } else { 4.0 + t }
    } else {
        2.0 - t
    }
}
