//! [`BvhScene`]: a compressed wide BVH (CWBVH, Ylitie et al. 2017) over a mesh,
//! built with obvhs's PLOC builder (and, for [`BuildQuality::Fast`], collapsed
//! to eight-wide nodes by our own greedy pass, `collapse.rs`), answering
//! [`RayCaster`] queries with the same watertight triangle test as the
//! brute-force reference.
//!
//! Triangles are copied into one block per BVH leaf at build time, coordinates
//! in lanes ([`TriangleLanes`]), so a leaf's (up to three) triangles are tested
//! in one pass of four lanes ([`PreparedRay::intersect_lanes`], the scalar
//! watertight test's operations lane by lane, the rare lane that would leave
//! its common path handed to the scalar test), and where the processor has AVX
//! two leaves of a node in one pass of eight (`simd::avx::intersect8`, the same
//! operations); each keeps its original index for hits.
//!
//! obvhs's own box test is tuned for rendering, not exact answers: it ignores boxes
//! that end before t = 1e-4, clamps 1/d to ±8.4e6 (with the wrong sign for -0.0),
//! and compares box entry with the current hit without allowing for rounding, so
//! near hits and exact closest hits can be lost. Traversal here is a loop of our
//! own over obvhs's nodes ([`BvhScene::search`]: octant order, leaves first, a
//! fixed stack of sibling groups, an early exit for occlusion) with a conservative
//! box test of our own ([`TraversalRay`]): child boxes padded against decoding
//! rounding, no epsilon. Ordinary rays (direction components within 2^-40..2^40,
//! origin within 2^64) test child boxes decoded to `f32` once per scene, slab
//! distances as in Ize 2013 with the exit padded for rounding (all eight
//! children in one AVX pass where the processor has AVX, `simd::avx`, else two
//! four-lane halves; the same bits either way); other rays
//! (axis-parallel ones among them) take the general form, exit distances rounded
//! up likewise and parallel axes decided by the origin. The stack holds one
//! group of siblings per level, so it is sized by the tree's depth, measured at
//! build: on the call stack up to 32 levels, on the heap beyond (degenerate
//! trees; obvhs's own `traverse!`, whose 32-entry stack overwrites on overflow,
//! serves only as a test reference, with the same box test in the affine form on
//! the compressed node). Exactness then rests on the watertight triangle test
//! alone, shared with [`super::BruteForceCaster`] (in lanes here, each lane its
//! exact operations), so the two agree bit for bit.

use alloc::collections::TryReserveError;

use alloc::vec::Vec;

#[cfg(test)]
use glam::{BVec3A, UVec2};
use glam::{Vec3, Vec3A, Vec4};
use obvhs::{
    BvhBuildParams,
    bvh2::reinsertion::ReinsertionOptimizer,
    cwbvh::{CwBvh, bvh2_to_cwbvh::bvh2_to_cwbvh, node::CwBvhNode},
    ploc::PlocBuilder,
    triangle::Triangle,
};

mod collapse;
mod packet;
mod refit;

use super::{Hit, PreparedRay, Ray, RayCaster, TriangleHit, TriangleLanes};
use crate::geom::MeshView;
use crate::prefetch::prefetch;
use crate::simd::{self, LaneHits8, Planes8, SlabRay};

/// A bounding volume hierarchy over a copy of a mesh's triangles.
///
/// Built once, queried many times; queries take `&self` and are safe from many
/// threads at once.
#[derive(Clone, Debug)]
pub struct BvhScene {
    bvh: CwBvh,
    /// The triangles of each leaf in lanes, in the order leaves are met walking
    /// the nodes ([`NodePlanes::block_base`] and [`NodePlanes::leaves`] address
    /// them).
    blocks: Vec<TriangleLanes>,
    /// Original triangle index of each lane of `blocks`.
    block_triangles: Vec<[u32; 4]>,
    /// Triangles in the scene.
    triangle_count: usize,
    /// Triangle corners in BVH primitive order, for obvhs's `traverse!` (the
    /// reference the search is tested against).
    #[cfg(test)]
    corners: Vec<[Vec3; 3]>,
    /// Original triangle index of each entry of `corners`.
    #[cfg(test)]
    original: Vec<u32>,
    /// Each node's child boxes decoded once, for the any-hit loop (same index as
    /// the node).
    planes: Vec<NodePlanes>,
    /// Nodes on the longest root-to-leaf path: a bound on the entries
    /// [`BvhScene::search`]'s stack ever holds.
    depth: usize,
    /// Every node's box, then every leaf block's: the scratch of
    /// [`BvhScene::refit`] (empty until the first refit).
    refit_bounds: Vec<[Vec3; 2]>,
    /// Whether queries use the AVX kernels of [`simd::avx`] (a node's eight
    /// child boxes in one pass, two leaves' triangles in one pass) instead of
    /// four lanes at a time: the same bits, decided once per scene by run-time
    /// detection.
    wide: bool,
}

/// Entries of the traversal's stack on the call stack: at most one group of
/// pending siblings per level (see [`BvhScene::search`]), so trees up to this
/// depth (PLOC trees over millions of triangles are well under twenty levels of
/// eight-wide nodes) need no allocation. Small, because the stack is initialised
/// for every ray.
/// Deeper (degenerate) trees get a heap stack of their depth per query.
const STACK_GROUPS: usize = 32;

pub use super::MAX_COORDINATE;

/// Why a [`BvhScene`] could not be built or refitted.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BvhError {
    /// A vertex used by a triangle has a coordinate beyond ±[`MAX_COORDINATE`].
    CoordinateOutOfRange {
        /// The vertex.
        vertex: u32,
    },
    /// The per-triangle arrays (the builder's input, the leaf blocks) or a
    /// refit's scratch could not be reserved.
    OutOfMemory(TryReserveError),
    /// [`BvhScene::refit`] was given a mesh with another number of triangles
    /// than the scene's.
    TriangleCountChanged {
        /// The scene's triangles.
        scene: usize,
        /// The mesh's triangles.
        mesh: usize,
    },
}

impl core::fmt::Display for BvhError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BvhError::CoordinateOutOfRange { vertex } => write!(
                f,
                "vertex {vertex} has a coordinate beyond the supported range of ±{MAX_COORDINATE:e}"
            ),
            BvhError::OutOfMemory(e) => write!(f, "out of memory: {e}"),
            BvhError::TriangleCountChanged { scene, mesh } => write!(
                f,
                "the mesh has {mesh} triangles and the scene {scene}: a refit keeps the triangles"
            ),
        }
    }
}

impl core::error::Error for BvhError {}

/// How much effort [`BvhScene::with_quality`] spends on the hierarchy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildQuality {
    /// obvhs's medium preset (PLOC with a medium search radius, then
    /// reinsertion): the default, for scenes that answer many rays.
    #[default]
    Medium,
    /// obvhs's fastest preset (PLOC with its smallest search radius, no
    /// reinsertion), collapsed to eight-wide nodes greedily rather than by
    /// obvhs's cost model: built in about a third of the time (the
    /// armadillo, 52,000 triangles: 11–12 ms against 32–33 ms), for scenes that
    /// answer few rays per build, such as the one reference ray per receiver
    /// of soft shadows.
    Fast,
}

impl BvhScene {
    /// Builds the hierarchy over every triangle of `mesh` (which may be empty).
    ///
    /// Fails when a vertex used by a triangle is beyond ±[`MAX_COORDINATE`], or when
    /// the per-triangle arrays (the builder's input; the leaf blocks, 160 bytes
    /// per leaf of up to three triangles: the bulk of the scene's memory) cannot
    /// be reserved;
    /// the builder's own temporary allocations, of the same order, abort on
    /// exhaustion like any Rust allocation.
    pub fn new(mesh: &MeshView<'_>) -> Result<Self, BvhError> {
        Self::with_quality(mesh, BuildQuality::Medium)
    }

    /// [`BvhScene::new`] with the builder's effort chosen: [`BuildQuality::Fast`]
    /// for scenes that answer few rays per build.
    pub fn with_quality(mesh: &MeshView<'_>, quality: BuildQuality) -> Result<Self, BvhError> {
        if let Some(vertex) = out_of_range(mesh) {
            return Err(BvhError::CoordinateOutOfRange { vertex });
        }
        let count = mesh.triangle_count();
        let mut triangles: Vec<Triangle> = Vec::new();
        triangles
            .try_reserve_exact(count)
            .map_err(BvhError::OutOfMemory)?;
        if count == 0 {
            return Ok(BvhScene::empty());
        }
        triangles.extend(mesh.triangles().map(|[a, b, c]| Triangle {
            v0: a.into(),
            v1: b.into(),
            v2: c.into(),
        }));
        // obvhs's `build_cwbvh_from_tris` in its default configuration (no
        // pre-splitting), from its public parts: that helper also validates the
        // result in debug builds, which asserts a depth below 32 (the stack of its
        // own traversal) and so panics on degenerate meshes that this scene
        // traverses correctly.
        let params = match quality {
            BuildQuality::Medium => BvhBuildParams::medium_build(),
            BuildQuality::Fast => BvhBuildParams::fastest_build(),
        };
        let mut bvh2 = PlocBuilder::with_capacity(count).build(
            params.ploc_search_distance,
            &triangles,
            (0..count as u32).collect(),
            params.sort_precision,
            params.search_depth_threshold,
        );
        if params.reinsertion_batch_ratio > 0.0 {
            ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
        }
        // Ordering the children (for rays entering from any side) takes a
        // third of obvhs's conversion; the fast build collapses greedily
        // instead (collapse.rs).
        let collapsed = match quality {
            BuildQuality::Medium => None,
            BuildQuality::Fast => collapse::collapse(&bvh2).map_err(BvhError::OutOfMemory)?,
        };
        let mut bvh = match collapsed {
            Some(bvh) => bvh,
            None => bvh2_to_cwbvh(&bvh2, 3, quality == BuildQuality::Medium, false),
        };
        drop(bvh2);
        let depth = depth(&bvh.nodes);
        let mut planes = Vec::new();
        planes
            .try_reserve_exact(bvh.nodes.len())
            .map_err(BvhError::OutOfMemory)?;
        let leaf_count: usize = bvh
            .nodes
            .iter()
            .map(|node| leaf_slots(node).count_ones() as usize)
            .sum();
        let mut blocks = Vec::new();
        blocks
            .try_reserve_exact(leaf_count)
            .map_err(BvhError::OutOfMemory)?;
        let mut block_triangles = Vec::new();
        block_triangles
            .try_reserve_exact(leaf_count)
            .map_err(BvhError::OutOfMemory)?;
        for node in &bvh.nodes {
            planes.push(NodePlanes::new(node, blocks.len() as u32));
            let mut leaves = leaf_slots(node);
            while leaves != 0 {
                let slot = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let (first, count) =
                    leaf_primitives(node.primitive_base_idx, node.child_meta[slot]);
                let leaf = &bvh.primitive_indices[first..first + count];
                // The leaves come in the order of their primitives, whose
                // triangles lie scattered in the input: ask for those a few
                // leaves on while this one is set up (a triangle spans at
                // most two lines, the second the next triangle's first).
                for &t in bvh
                    .primitive_indices
                    .get(first + TRIANGLES_AHEAD..)
                    .unwrap_or(&[])
                    .iter()
                    .take(count)
                {
                    prefetch(&triangles, t as usize);
                    prefetch(&triangles, t as usize + 1);
                }
                let mut lanes = [[Vec3::ZERO; 3]; 4];
                // From the builder's copy: one read per triangle rather than
                // three through the mesh's indices.
                for (lane, &t) in lanes.iter_mut().zip(leaf) {
                    let Triangle { v0, v1, v2 } = triangles[t as usize];
                    *lane = [v0.into(), v1.into(), v2.into()];
                }
                blocks.push(TriangleLanes::new(&lanes[..count]));
                block_triangles.push(core::array::from_fn(|lane| leaf[lane.min(count - 1)]));
            }
        }
        drop(triangles);
        #[cfg(test)]
        let corners = bvh
            .primitive_indices
            .iter()
            .map(|&t| mesh.triangle(t as usize))
            .collect();
        #[cfg(test)]
        let original = bvh.primitive_indices.clone();
        // The blocks hold the triangles and their indices now.
        bvh.primitive_indices = Vec::new();
        Ok(BvhScene {
            #[cfg(test)]
            corners,
            #[cfg(test)]
            original,
            bvh,
            blocks,
            block_triangles,
            triangle_count: count,
            planes,
            refit_bounds: Vec::new(),
            depth,
            wide: simd::avx_available(),
        })
    }

    /// A scene without triangles (allocates nothing).
    pub(crate) fn empty() -> Self {
        BvhScene {
            bvh: CwBvh::default(),
            blocks: Vec::new(),
            block_triangles: Vec::new(),
            triangle_count: 0,
            #[cfg(test)]
            corners: Vec::new(),
            #[cfg(test)]
            original: Vec::new(),
            planes: Vec::new(),
            refit_bounds: Vec::new(),
            depth: 0,
            wide: simd::avx_available(),
        }
    }

    /// Number of triangles in the scene.
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// [`RayCaster::occluded`] through the general traversal (obvhs's `traverse!`),
    /// for checking the any-hit loop against it.
    #[cfg(test)]
    pub(super) fn occluded_through_traverse_macro(&self, ray: &Ray) -> bool {
        if self.triangle_count == 0 {
            return false;
        }
        PreparedRay::new(ray)
            .is_some_and(|prepared| self.occluded_general(&prepared, &TraversalRay::new(ray)))
    }

    /// [`RayCaster::closest_hit`] through the general traversal (obvhs's
    /// `traverse!`), for checking the closest-hit loop against it.
    #[cfg(test)]
    pub(super) fn closest_hit_through_traverse_macro(&self, ray: &Ray) -> Option<Hit> {
        if self.triangle_count == 0 {
            return None;
        }
        let mut prepared = PreparedRay::new(ray)?;
        self.closest_hit_general(&mut prepared, &mut TraversalRay::new(ray))
    }

    /// Nodes on the hierarchy's longest root-to-leaf path (0 when empty).
    #[cfg(test)]
    pub(super) fn depth(&self) -> usize {
        self.depth
    }

    /// [`Self::search`] with a heap stack of [`Self::depth`] groups, for trees
    /// deeper than [`STACK_GROUPS`] (one allocation per query, only for degenerate
    /// hierarchies). Queries call it with their own copy of the leaf test, so that
    /// the test of the common path has one call site and is inlined there.
    #[cold]
    #[inline(never)]
    fn search_deep<const ANY_HIT: bool>(
        &self,
        traversal: &mut TraversalRay,
        test: impl FnMut(&LeafGroup) -> Option<f32>,
    ) -> bool {
        self.search::<ANY_HIT, false>(0, &mut alloc::vec![0u64; self.depth], traversal, test)
    }

    /// Calls `visit` with the original index of every triangle whose leaf's box
    /// (padded outward, as every box test here) overlaps the closed box `[lo,
    /// hi]`, until it returns true; returns whether it did. A superset of the
    /// triangles whose own boxes overlap `[lo, hi]`, in no particular order,
    /// some more than once.
    pub(crate) fn any_in_box(
        &self,
        lo: Vec3,
        hi: Vec3,
        mut visit: impl FnMut(usize) -> bool,
    ) -> bool {
        if self.triangle_count == 0 {
            return false;
        }
        // Every node on the stack at most once: at most depth × 8 entries.
        let mut stack = alloc::vec::Vec::with_capacity(8 * self.depth);
        stack.push(0usize);
        while let Some(index) = stack.pop() {
            let node = &self.planes[index];
            let [px, py, pz] = node.planes.0;
            let mut overlapping = 0u32;
            for child in 0..8 {
                let inside = px[0][child] <= hi.x
                    && px[1][child] >= lo.x
                    && py[0][child] <= hi.y
                    && py[1][child] >= lo.y
                    && pz[0][child] <= hi.z
                    && pz[1][child] >= lo.z;
                overlapping |= u32::from(inside) << child;
            }
            let mut inner = overlapping & node.imask;
            while inner != 0 {
                let slot = inner.trailing_zeros();
                inner &= inner - 1;
                let rank = (node.imask & ((1 << slot) - 1)).count_ones();
                stack.push((node.child_base + rank) as usize);
            }
            let mut leaves = overlapping & node.leaf_mask;
            while leaves != 0 {
                let leaf = node.take_leaf(&mut leaves);
                let originals = &self.block_triangles[leaf.block];
                if originals[..leaf.count].iter().any(|&t| visit(t as usize)) {
                    return true;
                }
            }
        }
        false
    }

    /// The same scene with the AVX kernels on (where the processor has AVX, the
    /// default: a node's eight child boxes in one pass, two of its leaves'
    /// triangles in one eight-lane pass) or off (four lanes at a time, the
    /// portable path). Every answer is the same either way; this is for
    /// benchmarks and tests that compare the two.
    pub fn with_avx(mut self, avx: bool) -> Self {
        self.wide = avx && simd::avx_available();
        self
    }

    /// Whether queries use the AVX kernels.
    #[cfg(test)]
    pub(super) fn uses_avx(&self) -> bool {
        self.wide
    }
}

/// The child boxes of one node decoded to `f32`, padded outwards exactly as
/// [`TraversalRay::entered_general`] pads them: `planes[axis][0]` the minima,
/// `planes[axis][1]` the maxima, child `i` in lane `i`. Decoding once per scene
/// instead of once per visit saves 48 byte to float conversions and the per-node setup of the affine test per node visited,
/// for 192 bytes per node (the compressed node is 80).
///
/// It also carries the node's links (child base, inner mask, its leaves' blocks
/// and triangle counts), so that the search of ordinary rays reads one record
/// per node instead of this and the compressed node.
#[derive(Clone, Copy, Debug)]
struct NodePlanes {
    planes: Planes8,
    /// [`CwBvhNode::child_base_idx`].
    child_base: u32,
    /// Index in [`BvhScene::blocks`] of the node's first leaf.
    block_base: u32,
    /// [`CwBvhNode::imask`].
    imask: u32,
    /// The child slots that are leaves with triangles ([`leaf_slots`]).
    leaf_mask: u32,
    /// Per child slot that is a leaf, its block's offset from `block_base` in
    /// the low five bits and its triangle count in unary in the top three, the
    /// layout of [`CwBvhNode::child_meta`] (whose low bits are the offset of the
    /// first primitive instead); 0 for every other slot.
    leaves: [u8; 8],
}

/// How far ahead, in primitives, the set-up of the leaf blocks asks for the
/// triangles it will read.
const TRIANGLES_AHEAD: usize = 24;

/// The first vertex used by a triangle of `mesh` with a coordinate beyond
/// ±[`MAX_COORDINATE`].
fn out_of_range(mesh: &MeshView<'_>) -> Option<u32> {
    // The mesh's bounds cover every vertex, used or not: when they are within
    // range no index needs a look.
    let (lo, hi) = mesh.bounds();
    if lo.abs().max(hi.abs()).max_element() <= MAX_COORDINATE {
        return None;
    }
    mesh.indices()
        .iter()
        .copied()
        .find(|&v| mesh.position(v as usize).abs().max_element() > MAX_COORDINATE)
}

/// The child slots of `node` that are leaves with triangles, as a bit mask.
fn leaf_slots(node: &CwBvhNode) -> u32 {
    (0..8)
        .filter(|&slot| node.imask & (1 << slot) == 0 && node.child_meta[slot] >> 5 != 0)
        .fold(0, |mask, slot| mask | 1 << slot)
}

/// The first primitive (in BVH primitive order) and the count of a leaf whose
/// node has primitive base `base` and whose slot has meta `meta`.
fn leaf_primitives(base: u32, meta: u8) -> (usize, usize) {
    (
        (base + u32::from(meta & 0b1_1111)) as usize,
        (meta >> 5).count_ones() as usize,
    )
}

impl NodePlanes {
    /// `node`'s planes and links, its leaves' blocks numbered from `block_base`
    /// in slot order.
    fn new(node: &CwBvhNode, block_base: u32) -> Self {
        let extent = node.compute_extent();
        let base = Vec3A::from(node.p);
        let padding = (base.abs() + extent * 255.0) * BOX_PADDING;
        let (lo_base, hi_base) = (base - padding, base + padding);
        let quantised = [
            [&node.child_min_x, &node.child_max_x],
            [&node.child_min_y, &node.child_max_y],
            [&node.child_min_z, &node.child_max_z],
        ];
        let planes = core::array::from_fn(|axis| {
            let [q_lo, q_hi] = quantised[axis];
            core::array::from_fn(|side| {
                let (q, offset) = if side == 0 {
                    (q_lo, lo_base[axis])
                } else {
                    (q_hi, hi_base[axis])
                };
                core::array::from_fn(|child| f32::from(q[child]) * extent[axis] + offset)
            })
        });
        let mut leaves = [0u8; 8];
        let mut rank = 0;
        let leaf_mask = leaf_slots(node);
        let mut slots = leaf_mask;
        while slots != 0 {
            let slot = slots.trailing_zeros() as usize;
            slots &= slots - 1;
            leaves[slot] = (node.child_meta[slot] & !0b1_1111) | rank;
            rank += 1;
        }
        NodePlanes {
            planes: Planes8(planes),
            child_base: node.child_base_idx,
            block_base,
            imask: u32::from(node.imask),
            leaf_mask,
            leaves,
        }
    }

    /// The leaf in the lowest slot of `leaves` (not empty), which loses it.
    #[inline(always)]
    fn take_leaf(&self, leaves: &mut u32) -> Leaf {
        let slot = leaves.trailing_zeros() as usize;
        *leaves &= *leaves - 1;
        let (block, count) = leaf_primitives(self.block_base, self.leaves[slot]);
        Leaf { block, count }
    }
}

/// Relative slack of the far distance in [`TraversalRay::entered_planes`]: each
/// slab distance `(plane - o) * (1 / d)` is within `gamma(3)` of exact relatively,
/// so near and far are each off by at most that; `2 * SLAB_ROUNDING` (Ize 2013
/// pads by one) also covers the rounding of the padding itself.
const PLANE_SLACK: f32 = 2.0 * SLAB_ROUNDING;

/// Number of nodes on the longest root-to-node path of a non-empty hierarchy.
fn depth(nodes: &[CwBvhNode]) -> usize {
    let mut deepest = 0;
    let mut pending = alloc::vec![(0usize, 1usize)];
    while let Some((index, level)) = pending.pop() {
        deepest = deepest.max(level);
        let node = &nodes[index];
        let inner = (0..8).filter(|&slot| node.imask & (1 << slot) != 0);
        pending.extend(inner.map(|slot| (node.child_node_index(slot) as usize, level + 1)));
    }
    deepest
}

/// Relative rounding bound of one slab distance `(plane - origin) * (1 / d)`:
/// three roundings, `2 * gamma(3)` as in Ize, "Robust BVH Ray Traversal" (JCGT 2013).
const SLAB_ROUNDING: f32 = 2.0 * (3.0 * f32::EPSILON / 2.0) / (1.0 - 3.0 * f32::EPSILON / 2.0);
/// Relative padding of decoded child boxes, which absorbs the rounding of
/// `p + q * extent` (the quantised planes are exact, the sum is not).
const BOX_PADDING: f32 = 4.0 * f32::EPSILON;
/// Relative slack of the fast box test, applied to `|c| + 255 |s|` (a bound on the
/// magnitude of every slab distance of a node, see [`TraversalRay::entered_fast`]).
/// It must cover the rounding of `q * s + c` with `c = (p - o) / d` and `s = e / d`
/// (at most 5 roundings: `1/d`, `p - o`, the two products and the sum, under
/// 6 units in the last place of the magnitude bound) and the rounding of the bound
/// itself. The fast test uses the query's own direction, so there is no direction
/// error to cover. 64 units in the last place (`32 * f32::EPSILON`) leave a
/// factor of ten.
#[cfg(test)]
const FAST_SLACK: f32 = 32.0 * f32::EPSILON;
/// The fast box test applies when every direction component is at least this in
/// magnitude (so `1/d <= 2^40`) ...
const FAST_MIN_DIRECTION: f32 = 1.0 / (1u64 << 40) as f32;
/// ... and at most this, so `1/d` is a normal number ...
const FAST_MAX_DIRECTION: f32 = (1u64 << 40) as f32;
/// ... and every origin coordinate at most this: with node coordinates below
/// 2^41 (scenes stop at [`MAX_COORDINATE`]), `|c| < 2^106` and `255 |s| < 2^90`,
/// so no slab distance overflows and `0 * s` is never `0 * inf`.
const FAST_MAX_ORIGIN: f32 = (1u128 << 64) as f32;

/// Per-ray constants of the conservative box test, in units of the query's
/// direction for the fast test and of the unit direction for the general one.
#[derive(Clone, Copy)]
struct TraversalRay {
    origin: Vec3A,
    /// 1/d per axis; unused on parallel axes.
    inverse: Vec3A,
    /// Axes along which the direction is zero (or below the smallest normal f32):
    /// the ray is treated as parallel to those slabs, which is exact for zero and
    /// off by less than 1.2e-38 of the distance travelled otherwise.
    parallel: [bool; 3],
    /// Axes along which the direction is negative: the near slab plane is the
    /// box's maximum.
    negative: [bool; 3],
    /// The same as a lane mask.
    #[cfg(test)]
    negative_lanes: BVec3A,
    /// Whether the fast box test applies (see [`FAST_MIN_DIRECTION`]).
    fast: bool,
    /// Query `t` to box-test distance (1 for the fast test).
    length: f32,
    /// Never cull a box that could hold a hit after this distance (<= 0).
    t_min: f32,
    /// Never cull a box that could hold a hit before this distance.
    t_max: f32,
}

impl TraversalRay {
    /// `ray` must be valid (finite, non-zero direction).
    #[inline]
    fn new(ray: &Ray) -> Self {
        let magnitude = ray.direction.abs();
        let fast = magnitude.min_element() >= FAST_MIN_DIRECTION
            && magnitude.max_element() <= FAST_MAX_DIRECTION
            && ray.origin.abs().max_element() <= FAST_MAX_ORIGIN;
        let (inverse, parallel, length) = if fast {
            // Distances in the query's own units: no normalisation, no error.
            (Vec3A::ONE / Vec3A::from(ray.direction), [false; 3], 1.0)
        } else {
            Self::unit_inverse(ray.direction)
        };
        let negative = ray.direction.to_array().map(|c| c < 0.0);
        // Boxes behind the origin can hold hits only for a negative t_min; round
        // that bound outwards like t_max.
        let t_min = if ray.t_min < 0.0 {
            let distance = ray.t_min * length;
            distance + distance * (4.0 * f32::EPSILON)
        } else {
            0.0
        };
        let mut traversal = TraversalRay {
            origin: ray.origin.into(),
            inverse,
            parallel,
            negative,
            #[cfg(test)]
            negative_lanes: BVec3A::from(negative),
            fast,
            length,
            t_min,
            t_max: 0.0,
        };
        traversal.shorten(ray.t_max);
        traversal
    }

    /// For [`Self::entered_general`]: `1 / d` of the unit direction (0 on parallel
    /// axes), the parallel axes, and the direction's length. Normalising keeps
    /// `1 / d` finite for any finite direction.
    #[cold]
    fn unit_inverse(direction: Vec3) -> (Vec3A, [bool; 3], f32) {
        // Scale first so squaring cannot overflow for huge directions.
        let largest = direction.abs().max_element();
        let scaled = direction / largest;
        let length = largest * scaled.length();
        let unit = scaled.normalize();
        let parallel = unit.to_array().map(|c| c.abs() < f32::MIN_POSITIVE);
        let inverse = unit.to_array().map(|c| {
            if c.abs() < f32::MIN_POSITIVE {
                0.0
            } else {
                1.0 / c
            }
        });
        (Vec3A::from_array(inverse), parallel, length)
    }

    /// Culls boxes beyond query parameter `t`, rounded up (the product `t * length`
    /// rounds once more), towards +infinity for negative `t` too.
    #[inline]
    fn shorten(&mut self, t: f32) {
        let distance = t * self.length;
        self.t_max = distance + distance.abs() * (4.0 * f32::EPSILON);
    }

    /// Bit `i` set when the ray may enter child slot `i` of `node` at a distance in
    /// `[t_min, t_max]`. Conservative: no child holding a hit is ever culled.
    #[cfg(test)]
    #[inline(always)]
    fn entered(&self, node: &CwBvhNode) -> u32 {
        if self.fast {
            self.entered_fast(node)
        } else {
            self.entered_general(node)
        }
    }

    /// The children of `node` the ray may enter at a distance in `[t_min, t_max]`, as
    /// the hit mask obvhs's `traverse!` expects. Conservative: no child holding a hit
    /// is ever culled.
    #[cfg(test)]
    #[inline(always)]
    fn child_hits(&self, node: &CwBvhNode, oct_inv4: u32) -> u32 {
        let mut entered = self.entered(node);
        // Empty children have no child bits, so they add nothing below.
        let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
        let mut hits = 0;
        while entered != 0 {
            let child = entered.trailing_zeros();
            entered &= entered - 1;
            let shift = (bit_index8 >> (8 * child)) & 0xff;
            hits |= (((child_bits8 >> (8 * child)) & 0xff) as u32) << shift;
        }
        hits
    }

    /// Quantised planes `q` of children `4 * half .. 4 * half + 4` as lanes.
    #[inline(always)]
    fn lanes(planes: &[u8; 8], half: usize) -> Vec4 {
        let q = &planes[4 * half..4 * half + 4];
        Vec4::new(q[0].into(), q[1].into(), q[2].into(), q[3].into())
    }

    /// Bit `i` set when the ray may enter child `i`: the common case of
    /// [`Self::child_hits`], for rays whose direction and origin are in range
    /// ([`Self::fast`]), in units of the query's direction.
    ///
    /// A child plane is `p + q e` (`p` the node's base, padded like
    /// [`Self::entered_general`] does, `e` a power of two, `q` a byte), so its slab
    /// distance is the affine `q s + c` with `s = e / d` and `c = (p - o) / d`,
    /// computed once per node: two operations per plane instead of four, and the
    /// near and far planes are picked by the direction's sign instead of a min and
    /// max. Every distance of the node is at most `|c| + 255 |s|` in magnitude, so
    /// widening each axis's interval by [`FAST_SLACK`] times that covers all its
    /// rounding; the interval is then a superset of the exact one and no child
    /// holding a hit is culled.
    #[cfg(test)]
    #[inline(always)]
    fn entered_fast(&self, node: &CwBvhNode) -> u32 {
        let extent = node.compute_extent();
        let base = Vec3A::from(node.p);
        let padding = (base.abs() + extent * 255.0) * BOX_PADDING;
        let c_lo = (base - padding - self.origin) * self.inverse;
        let c_hi = (base + padding - self.origin) * self.inverse;
        let scale = extent * self.inverse;
        let slack = (c_lo.abs().max(c_hi.abs()) + scale.abs() * 255.0) * FAST_SLACK;
        let c_near = Vec3A::select(self.negative_lanes, c_hi, c_lo) - slack;
        let c_far = Vec3A::select(self.negative_lanes, c_lo, c_hi) + slack;
        let planes = [
            (&node.child_min_x, &node.child_max_x),
            (&node.child_min_y, &node.child_max_y),
            (&node.child_min_z, &node.child_max_z),
        ];
        let mut entered = 0;
        for half in 0..2 {
            let slab = |axis: usize| {
                let (lo, hi) = planes[axis];
                let (near, far) = if self.negative[axis] {
                    (hi, lo)
                } else {
                    (lo, hi)
                };
                let s = Vec4::splat(scale[axis]);
                (
                    Self::lanes(near, half) * s + Vec4::splat(c_near[axis]),
                    Self::lanes(far, half) * s + Vec4::splat(c_far[axis]),
                )
            };
            let (near_x, far_x) = slab(0);
            let (near_y, far_y) = slab(1);
            let (near_z, far_z) = slab(2);
            let near = near_x.max(near_y).max(near_z).max(Vec4::splat(self.t_min));
            let far = far_x.min(far_y).min(far_z).min(Vec4::splat(self.t_max));
            entered |= near.cmple(far).bitmask() << (4 * half);
        }
        entered
    }

    /// Bit `i` set when the ray may enter child `i` of the node whose decoded boxes
    /// are `planes`, for [`Self::fast`] rays: slab distances `(plane - o) * (1 / d)`
    /// as in Ize 2013, the far distance padded by [`PLANE_SLACK`] relatively and by
    /// the smallest normal f32 absolutely (a product that underflows is off by
    /// less than that). The fast limits keep every distance finite. It is the
    /// portable twin of [`simd::avx::entered8`], which must give the
    /// same bits.
    #[inline(always)]
    fn entered_planes(&self, planes: &Planes8) -> u32 {
        let mut entered = 0;
        for half in 0..2 {
            let slab = |axis: usize| {
                let side = usize::from(self.negative[axis]);
                let o = Vec4::splat(self.origin[axis]);
                let inv = Vec4::splat(self.inverse[axis]);
                let axis_planes = &planes.0[axis];
                let quad = |side: usize| Vec4::from_slice(&axis_planes[side][4 * half..]);
                ((quad(side) - o) * inv, (quad(1 - side) - o) * inv)
            };
            let (near_x, far_x) = slab(0);
            let (near_y, far_y) = slab(1);
            let (near_z, far_z) = slab(2);
            let near = near_x.max(near_y).max(near_z).max(Vec4::splat(self.t_min));
            let far = far_x.min(far_y).min(far_z);
            let far =
                (far + (far.abs() * PLANE_SLACK + f32::MIN_POSITIVE)).min(Vec4::splat(self.t_max));
            entered |= near.cmple(far).bitmask() << (4 * half);
        }
        entered
    }

    /// The constants of the eight-lane test of [`simd::avx::entered8`], which
    /// evaluates [`Self::entered_planes`]'s operations (fast rays only).
    #[inline(always)]
    fn slab_ray(&self) -> SlabRay {
        SlabRay {
            origin: self.origin.to_array(),
            inverse: self.inverse.to_array(),
            negative: self.negative.map(usize::from),
            t_min: self.t_min,
            slack: PLANE_SLACK,
        }
    }

    /// [`Self::entered_planes`] in one pass of eight AVX lanes. Only for searches
    /// entered through a `#[target_feature(enable = "avx")]` query, which run only
    /// where [`simd::avx_available`] said so.
    #[inline(always)]
    fn entered_wide(&self, planes: &Planes8, slab: &SlabRay) -> u32 {
        #[cfg(target_arch = "x86_64")]
        {
            // SAFETY: wide searches are entered only from `occluding_triangle_avx` and
            // `closest_hit_avx`, which are called only when `BvhScene::wide`, set
            // from run-time detection of AVX.
            #[allow(unsafe_code)]
            unsafe {
                simd::avx::entered8(planes, slab, self.t_max)
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = slab;
            self.entered_planes(planes)
        }
    }

    /// Bit `i` set when the ray may enter child `i`, for any valid ray: child boxes
    /// padded against decoding rounding, parallel axes decided by the origin, exit
    /// distances rounded up as in Ize 2013. Four children at a time in `Vec4`
    /// lanes (SSE2 on x86-64).
    #[inline(never)]
    fn entered_general(&self, node: &CwBvhNode) -> u32 {
        let extent = node.compute_extent();
        let base = Vec3A::from(node.p);
        let padding = (base.abs() + extent * 255.0) * BOX_PADDING;
        let lo_base = base - padding;
        let hi_base = base + padding;
        let mut entered = 0;
        for half in 0..2 {
            // (plane - origin) / d per axis; planes are exact in the node's grid.
            let slab = |q_lo: Vec4, q_hi: Vec4, axis: usize| {
                let o = self.origin[axis];
                let lo = q_lo * extent[axis] + lo_base[axis];
                let hi = q_hi * extent[axis] + hi_base[axis];
                if self.parallel[axis] {
                    // Inside the slab: no constraint; outside: never enters.
                    let inside = lo.cmple(Vec4::splat(o)) & Vec4::splat(o).cmple(hi);
                    // f32::MAX, not infinity: padding the exit below must not
                    // produce inf - inf.
                    let everything = Vec4::splat(f32::MAX);
                    (
                        Vec4::select(inside, -everything, everything),
                        Vec4::select(inside, everything, -everything),
                    )
                } else {
                    let inv = self.inverse[axis];
                    let t_lo = (lo - o) * inv;
                    let t_hi = (hi - o) * inv;
                    (t_lo.min(t_hi), t_lo.max(t_hi))
                }
            };
            let lanes = |planes: &[u8; 8]| Self::lanes(planes, half);
            let (near_x, far_x) = slab(lanes(&node.child_min_x), lanes(&node.child_max_x), 0);
            let (near_y, far_y) = slab(lanes(&node.child_min_y), lanes(&node.child_max_y), 1);
            let (near_z, far_z) = slab(lanes(&node.child_min_z), lanes(&node.child_max_z), 2);
            let near = near_x.max(near_y).max(near_z).max(Vec4::splat(self.t_min));
            let far = far_x.min(far_y).min(far_z);
            let far = (far + far.abs() * SLAB_ROUNDING).min(Vec4::splat(self.t_max));
            entered |= near.cmple(far).bitmask() << (4 * half);
        }
        entered
    }
}

impl BvhScene {
    /// Any-hit search from node `root` (0: the whole tree) with a traversal loop
    /// of our own: no child ordering beyond
    /// the ray's octant, leaves tested as soon as their node is, an early exit on
    /// the first hit, and a stack of sibling groups.
    ///
    /// Stack bound: a group is pushed when a node with entered inner children is
    /// visited, and popped as soon as its last pending child is taken, before that
    /// child is visited. So while a node at level `L` (the root is level 1) is
    /// visited, every group on the stack holds siblings of a distinct strict
    /// ancestor's children, at most `L - 1` groups, and pushing its own makes at most
    /// `L`: `stack` needs [`Self::depth`] entries (a shorter one panics, never
    /// overwrites).
    ///
    /// A group packs `first child node << 16 | the parent's inner-child mask << 8 |
    /// pending children`; pending children are kept in octant order, bit `slot ^ octant`,
    /// so the lowest bit is the child nearest the ray's origin side, as in the
    /// CWBVH paper's ordering.
    ///
    /// `test` is called with every entered leaf (with `WIDE`, two at a time
    /// where a node has two left) and returns the `t` of the nearest hit it accepted, if
    /// any. With `ANY_HIT` the search stops at the first hit and returns true;
    /// otherwise each hit shortens the box test and the search runs to the end
    /// (the closest-hit search), returning false.
    ///
    /// With `WIDE` the child boxes of ordinary rays are tested in one pass of
    /// eight AVX lanes and a node's leaves two at a time in eight triangle lanes
    /// (callers enter such searches only where AVX runs), else four lanes at a
    /// time; the two give the same bits.
    #[inline(always)]
    fn search<const ANY_HIT: bool, const WIDE: bool>(
        &self,
        root: usize,
        stack: &mut [u64],
        traversal: &mut TraversalRay,
        mut test: impl FnMut(&LeafGroup) -> Option<f32>,
    ) -> bool {
        let slab = traversal.slab_ray();
        let octant = (u32::from(traversal.negative[0]) << 2)
            | (u32::from(traversal.negative[1]) << 1)
            | u32::from(traversal.negative[2]);
        let mut depth = 0;
        let mut index = root;
        loop {
            let node = &self.planes[index];
            let entered = if !traversal.fast {
                traversal.entered_general(&self.bvh.nodes[index])
            } else if WIDE {
                traversal.entered_wide(&node.planes, &slab)
            } else {
                traversal.entered_planes(&node.planes)
            };
            let imask = node.imask;
            let inner = entered & imask;
            if inner != 0 {
                stack[depth] = (u64::from(node.child_base) << 16)
                    | u64::from(imask << 8 | octant_order(inner, octant));
                depth += 1;
            }
            // The next node, chosen before the leaves are tested so that its
            // load can start while they are: the first pending child of the
            // innermost group.
            let next = depth.checked_sub(1).map(|top| {
                let group = &mut stack[top];
                let slot = group.trailing_zeros() ^ octant;
                let parent_imask = (*group >> 8) as u32 & 0xff;
                // Pending is not empty, so its lowest bit is the group's lowest.
                *group &= *group - 1;
                if *group & 0xff == 0 {
                    depth = top;
                }
                ((*group >> 16) as u32 + (parent_imask & ((1 << slot) - 1)).count_ones()) as usize
            });
            // Empty slots are not leaves, so every slot left has triangles.
            let mut leaves = entered & node.leaf_mask;
            while leaves != 0 {
                // Wide searches test two leaves per pass where there are two.
                let first = node.take_leaf(&mut leaves);
                let second = (WIDE && leaves != 0).then(|| node.take_leaf(&mut leaves));
                if let Some(t) = test(&LeafGroup { first, second }) {
                    if ANY_HIT {
                        return true;
                    }
                    traversal.shorten(t);
                }
            }
            let Some(next) = next else {
                return false;
            };
            index = next;
        }
    }

    /// [`RayCaster::occluded`] through obvhs's `traverse!`, the reference
    /// [`Self::search`] is tested against. Only for hierarchies at most 32 nodes
    /// deep: `traverse!`'s fixed stack of 32 entries overwrites on overflow.
    #[cfg(test)]
    fn occluded_general(&self, prepared: &PreparedRay, traversal: &TraversalRay) -> bool {
        let mut state = self.bvh.new_traversal(traversal.inverse);
        let mut node;
        let mut occluded = false;
        // A bare `break` would only leave the macro's inner primitive loop.
        'search: {
            obvhs::traverse!(
                self.bvh,
                node,
                state,
                traversal.child_hits(node, state.oct_inv4),
                {
                    let [a, b, c] = self.corners[state.primitive_id as usize];
                    if prepared.intersect(a, b, c).is_some() {
                        occluded = true;
                        break 'search;
                    }
                }
            );
        }
        occluded
    }
}

impl BvhScene {
    /// [`RayCaster::closest_hit`] through obvhs's `traverse!`, the reference
    /// [`Self::search`] is tested against (hierarchies at most 32 nodes deep, as
    /// for [`Self::occluded_general`]).
    #[cfg(test)]
    fn closest_hit_general(
        &self,
        prepared: &mut PreparedRay,
        traversal: &mut TraversalRay,
    ) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut state = self.bvh.new_traversal(traversal.inverse);
        let mut node;
        obvhs::traverse!(
            self.bvh,
            node,
            state,
            traversal.child_hits(node, state.oct_inv4),
            {
                let primitive = state.primitive_id as usize;
                let [a, b, c] = self.corners[primitive];
                if let Some(hit) = prepared.intersect(a, b, c) {
                    prepared.set_t_max(hit.t);
                    traversal.shorten(hit.t);
                    best = Some(Hit {
                        t: hit.t,
                        triangle: self.original[primitive],
                        u: hit.u,
                        v: hit.v,
                    });
                }
            }
        );
        best
    }
}

/// `mask` with bit `i` moved to bit `i ^ octant` (`octant` < 8): three swaps of
/// bit groups, one per set bit of `octant`.
#[inline(always)]
fn octant_order(mut mask: u32, octant: u32) -> u32 {
    if octant & 1 != 0 {
        mask = ((mask & 0x55) << 1) | ((mask >> 1) & 0x55);
    }
    if octant & 2 != 0 {
        mask = ((mask & 0x33) << 2) | ((mask >> 2) & 0x33);
    }
    if octant & 4 != 0 {
        mask = ((mask & 0x0f) << 4) | ((mask >> 4) & 0x0f);
    }
    mask
}

#[cfg(test)]
std::thread_local! {
    /// Lanes this thread's queries handed to the scalar test: tests check that
    /// the cases they aim at exactly-zero edge functions reach that path.
    pub(super) static SCALAR_LANES: core::cell::Cell<usize> = const { core::cell::Cell::new(0) };
}

/// Counts one lane decided by the scalar test (tests only).
#[inline(always)]
fn count_scalar_lane() {
    #[cfg(test)]
    SCALAR_LANES.with(|lanes| lanes.set(lanes.get() + 1));
}

/// A leaf of an entered node: its block in [`BvhScene::blocks`] and triangle
/// count.
#[derive(Clone, Copy, Debug)]
struct Leaf {
    block: usize,
    count: usize,
}

/// The leaves one leaf test takes: one block in four lanes, or (with AVX) two
/// in eight, lanes 4–7 the second block's.
#[derive(Clone, Copy, Debug)]
struct LeafGroup {
    first: Leaf,
    second: Option<Leaf>,
}

impl LeafGroup {
    /// Lanes that hold triangles.
    #[inline(always)]
    fn present(&self) -> u32 {
        let lanes = |leaf: Leaf| (1u32 << leaf.count) - 1;
        lanes(self.first) | self.second.map_or(0, |second| lanes(second) << 4)
    }

    /// The block and lane within it of lane `lane`.
    #[inline(always)]
    fn locate(&self, lane: usize) -> (usize, usize) {
        match self.second {
            Some(second) if lane >= 4 => (second.block, lane - 4),
            _ => (self.first.block, lane),
        }
    }
}

impl BvhScene {
    /// The lane test of `group`, in the eight-lane layout either way: its one
    /// block in four `Vec4` lanes or, in a wide search, its two in one AVX pass.
    /// The two give the same answer per lane.
    #[inline(always)]
    fn decide<const WIDE: bool>(&self, prepared: &PreparedRay, group: &LeafGroup) -> LaneHits8 {
        let first = &self.blocks[group.first.block];
        #[cfg(target_arch = "x86_64")]
        if let (true, Some(second)) = (WIDE, group.second) {
            let second = &self.blocks[second.block];
            // SAFETY: wide searches are entered only from `occluding_triangle_avx` and
            // `closest_hit_avx`, which run only where `BvhScene::wide` says
            // run-time detection found AVX.
            #[allow(unsafe_code)]
            return unsafe {
                simd::avx::intersect8(
                    &prepared.sheared(),
                    prepared.t_max(),
                    &first.corners,
                    &second.corners,
                    super::WIDE_EXTENT,
                    super::WIDE_DETERMINANT,
                )
            };
        }
        let d = prepared.intersect_lanes(first);
        let eight = |v: glam::Vec4| {
            let [a, b, c, e] = v.to_array();
            [a, b, c, e, 0.0, 0.0, 0.0, 0.0]
        };
        LaneHits8 {
            hits: d.hits,
            undecided: d.undecided,
            t: eight(d.t),
            u: eight(d.u),
            v: eight(d.v),
        }
    }

    /// The any-hit leaf test: `t` of a hit on a triangle of `group`, and the
    /// triangle's original index. The lanes decide all but the rare triangles
    /// that leave the common `f32` path, which the scalar test decides.
    #[inline(always)]
    fn any_hit_leaf<const WIDE: bool>(
        &self,
        prepared: &PreparedRay,
        group: &LeafGroup,
    ) -> Option<(f32, u32)> {
        let decided = self.decide::<WIDE>(prepared, group);
        let present = group.present();
        let hits = decided.hits & present;
        if hits != 0 {
            let lane = hits.trailing_zeros() as usize;
            let (block, block_lane) = group.locate(lane);
            return Some((decided.t[lane], self.block_triangles[block][block_lane]));
        }
        let mut undecided = decided.undecided & present;
        while undecided != 0 {
            let (block, lane) = group.locate(undecided.trailing_zeros() as usize);
            undecided &= undecided - 1;
            count_scalar_lane();
            let [a, b, c] = self.blocks[block].triangle(lane);
            if let Some(hit) = prepared.intersect(a, b, c) {
                return Some((hit.t, self.block_triangles[block][lane]));
            }
        }
        None
    }

    /// The closest-hit leaf test over the triangles of `group`, in lane order
    /// as the scalar loop would take them: each hit nearer than the current end
    /// shortens `prepared` and becomes `best`; returns the `t` of the last
    /// (nearest) one.
    #[inline(always)]
    fn closest_hit_leaf<const WIDE: bool>(
        &self,
        prepared: &mut PreparedRay,
        best: &mut Option<Hit>,
        group: &LeafGroup,
    ) -> Option<f32> {
        let decided = self.decide::<WIDE>(prepared, group);
        let mut pending = (decided.hits | decided.undecided) & group.present();
        let mut nearest = None;
        while pending != 0 {
            let lane = pending.trailing_zeros() as usize;
            pending &= pending - 1;
            let (block, block_lane) = group.locate(lane);
            let hit = if decided.undecided & (1 << lane) != 0 {
                count_scalar_lane();
                let [a, b, c] = self.blocks[block].triangle(block_lane);
                prepared.intersect(a, b, c)
            } else {
                // Decided against the interval's end when the leaf began: an
                // earlier lane may have shortened it since.
                let t = decided.t[lane];
                (t < prepared.t_max()).then(|| TriangleHit {
                    t,
                    u: decided.u[lane],
                    v: decided.v[lane],
                })
            };
            if let Some(hit) = hit {
                prepared.set_t_max(hit.t);
                *best = Some(Hit {
                    t: hit.t,
                    triangle: self.block_triangles[block][block_lane],
                    u: hit.u,
                    v: hit.v,
                });
                nearest = Some(hit.t);
            }
        }
        nearest
    }
}

impl BvhScene {
    /// [`Self::occluding_triangle`] compiled with AVX, testing eight child
    /// boxes and two leaves at a time.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn occluding_triangle_avx(&self, ray: &Ray) -> Option<u32> {
        self.occluding_triangle_with::<true>(ray)
    }

    /// [`RayCaster::closest_hit`] compiled with AVX, testing eight child boxes
    /// and two leaves at a time.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn closest_hit_avx(&self, ray: &Ray) -> Option<Hit> {
        self.closest_hit_with::<true>(ray)
    }

    /// The original index of a triangle the ray hits (the first the search
    /// finds, not necessarily the nearest), or `None`.
    #[inline(always)]
    fn occluding_triangle_with<const WIDE: bool>(&self, ray: &Ray) -> Option<u32> {
        if self.triangle_count == 0 {
            return None;
        }
        let prepared = PreparedRay::new(ray)?;
        let mut traversal = TraversalRay::new(ray);
        let mut found = None;
        // Two closures over one inlined body: each has a single call site, so
        // the common path's leaf test is inlined into its traversal loop.
        let mut test = |hit: Option<(f32, u32)>| {
            let (t, triangle) = hit?;
            found = Some(triangle);
            Some(t)
        };
        if self.depth <= STACK_GROUPS {
            self.search::<true, WIDE>(0, &mut [0u64; STACK_GROUPS], &mut traversal, |group| {
                test(self.any_hit_leaf::<WIDE>(&prepared, group))
            });
        } else {
            self.search_deep::<true>(&mut traversal, |group| {
                test(self.any_hit_leaf::<false>(&prepared, group))
            });
        }
        found
    }

    /// [`RayCaster::occluded`] that also names a triangle the ray hits: the
    /// first the search finds, not necessarily the nearest.
    pub(crate) fn occluding_triangle(&self, ray: &Ray) -> Option<u32> {
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` is set only where run-time detection found AVX.
            #[allow(unsafe_code)]
            return unsafe { self.occluding_triangle_avx(ray) };
        }
        self.occluding_triangle_with::<false>(ray)
    }

    /// [`RayCaster::occluded_many`] compiled with AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn occluded_many_avx(&self, rays: &[Ray], occluded: &mut [bool]) {
        self.occluded_many_with::<true>(rays, occluded);
    }

    /// [`RayCaster::closest_hit_many`] compiled with AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn closest_hit_many_avx(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_hit_many_with::<true>(rays, hits);
    }

    #[inline(always)]
    fn closest_hit_with<const WIDE: bool>(&self, ray: &Ray) -> Option<Hit> {
        if self.triangle_count == 0 {
            return None;
        }
        let mut prepared = PreparedRay::new(ray)?;
        let mut traversal = TraversalRay::new(ray);
        let mut best: Option<Hit> = None;
        if self.depth <= STACK_GROUPS {
            self.search::<false, WIDE>(0, &mut [0u64; STACK_GROUPS], &mut traversal, |group| {
                self.closest_hit_leaf::<WIDE>(&mut prepared, &mut best, group)
            });
        } else {
            self.search_deep::<false>(&mut traversal, |group| {
                self.closest_hit_leaf::<false>(&mut prepared, &mut best, group)
            });
        }
        best
    }
}

impl RayCaster for BvhScene {
    fn occluded(&self, ray: &Ray) -> bool {
        self.occluding_triangle(ray).is_some()
    }

    /// Traces the rays in packets of up to 64 (see the `packet` module): the
    /// answers of [`Self::occluded`], bit for bit.
    fn occluded_many(&self, rays: &[Ray], occluded: &mut [bool]) {
        assert_eq!(
            rays.len(),
            occluded.len(),
            "occluded_many: one answer per ray"
        );
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` is set only where run-time detection found AVX.
            #[allow(unsafe_code)]
            return unsafe { self.occluded_many_avx(rays, occluded) };
        }
        self.occluded_many_with::<false>(rays, occluded);
    }

    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` is set only where run-time detection found AVX.
            #[allow(unsafe_code)]
            return unsafe { self.closest_hit_avx(ray) };
        }
        self.closest_hit_with::<false>(ray)
    }

    /// Traces the rays in packets as [`Self::occluded_many`] does; each hit's
    /// `t` is [`Self::closest_hit`]'s (ties may resolve to another triangle).
    fn closest_hit_many(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(
            rays.len(),
            hits.len(),
            "closest_hit_many: one answer per ray"
        );
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` is set only where run-time detection found AVX.
            #[allow(unsafe_code)]
            return unsafe { self.closest_hit_many_avx(rays, hits) };
        }
        self.closest_hit_many_with::<false>(rays, hits);
    }
}

// The AVX kernel it tests exists on x86_64 only.
#[cfg(all(test, target_arch = "x86_64"))]
mod wide_box_test {
    use super::*;
    use rand::{Rng, SeedableRng, rngs::SmallRng};

    fn point(rng: &mut SmallRng, spread: f32) -> Vec3 {
        Vec3::new(
            rng.random_range(-spread..spread),
            rng.random_range(-spread..spread),
            rng.random_range(-spread..spread),
        )
    }

    /// The eight-lane AVX box test gives the bits of the two four-lane halves on
    /// every node of a random soup, for rays from inside and outside it, with
    /// finite and infinite ends and negative starts: the slow twin of the fast
    /// path `BvhScene::occluded` and `closest_hit` take wherever AVX runs.
    #[test]
    fn eight_lanes_equal_two_halves_on_every_node() {
        if !simd::avx_available() {
            std::println!("this processor has no AVX: the eight-lane test is never used here");
            return;
        }
        let mut rng = SmallRng::seed_from_u64(31);
        let mut positions = Vec::new();
        for _ in 0..600 {
            let center = point(&mut rng, 1.0);
            for _ in 0..3 {
                positions.push((center + point(&mut rng, 0.15)).to_array());
            }
        }
        let indices: Vec<u32> = (0..positions.len() as u32).collect();
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let scene = BvhScene::new(&mesh).unwrap();
        let (mut checked, mut entered) = (0usize, 0usize);
        for _ in 0..3000 {
            let origin = point(&mut rng, 2.0);
            // Half the rays aim at a corner of some child box, where entry and
            // exit distances meet and the padding and the comparison decide.
            let target = if rng.random_bool(0.5) {
                let node = &scene.planes[rng.random_range(0..scene.planes.len())]
                    .planes
                    .0;
                let child = rng.random_range(0..8);
                Vec3::from_array(core::array::from_fn(|axis| {
                    node[axis][rng.random_range(0..2)][child]
                }))
            } else {
                point(&mut rng, 1.0)
            };
            let direction = (target - origin) * rng.random_range(0.01..100.0);
            let mut ray = Ray::new(origin, direction, f32::INFINITY);
            if rng.random_bool(0.3) {
                ray.t_max = rng.random_range(0.0..1.5);
            } else if rng.random_bool(0.1) {
                // Entry and exit both clamped to zero for boxes around the origin.
                ray.t_max = 0.0;
            }
            if rng.random_bool(0.2) {
                ray.t_min = -rng.random_range(0.0..1.0);
            }
            let traversal = TraversalRay::new(&ray);
            if !traversal.fast {
                continue;
            }
            let slab = traversal.slab_ray();
            for node in &scene.planes {
                let quads = traversal.entered_planes(&node.planes);
                // SAFETY: AVX was detected above.
                #[allow(unsafe_code)]
                let eight = unsafe { simd::avx::entered8(&node.planes, &slab, traversal.t_max) };
                assert_eq!(eight, quads, "{ray:?}");
                checked += 1;
                entered += quads.count_ones() as usize;
            }
        }
        assert!(
            checked > 100_000 && entered > 10_000,
            "{checked} nodes, {entered} children"
        );
    }
}
