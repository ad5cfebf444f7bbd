//! Occlusion and closest hits of many rays in one search:
//! `RayCaster::occluded_many` and `RayCaster::closest_hit_many` of
//! [`BvhScene`].
//!
//! Rays that start together (a bake's rays from one vertex) enter mostly the
//! same nodes near the root. Searching them one by one pays a node's fixed
//! costs (the stack, the loads of its planes and links, the branches of the
//! loop) once per ray; a packet search pays them once per node and tests only
//! the rays that entered the node's box, each with exactly the box test of
//! [`BvhScene`]'s [`occluded`](crate::RayCaster::occluded). So every ray
//! enters the same nodes as alone. Deep in the tree, where a node is reached
//! by only a few of the packet's rays, each of them finishes that subtree
//! with the single-ray search.
//!
//! The leaves: where every ray of the packet starts at the same point and
//! covers `(0, ∞)`, a leaf's triangles are first tested against all its rays
//! at once ([`SharedOrigin`]): from a common origin, a ray misses a triangle
//! when its direction is outside one of the three planes through the origin
//! and an edge, which is one dot product per plane and ray, the planes shared.
//! Only a miss certain beyond the rounding of both this test and the
//! watertight one is taken; every other ray (a hit, or a direction within
//! rounding of an edge plane) gets the watertight test of [`BvhScene`]'s
//! [`occluded`](crate::RayCaster::occluded) on that leaf. Other packets test
//! each ray's leaves with the watertight test directly. Either way each ray's
//! answer (whether some triangle is hit) is the bit [`BvhScene`]'s
//! [`occluded`](crate::RayCaster::occluded) gives; only the order of the work
//! differs. A closest-hit search shortens each ray at its hits as alone (a
//! certain miss is a miss for any interval), so its hit has the `t` of
//! [`BvhScene`]'s [`closest_hit`](crate::RayCaster::closest_hit); where two
//! triangles are hit at exactly that `t`, the order of the work decides which
//! is reported.

use glam::{BVec4A, Vec3, Vec4};

use super::{BvhScene, Leaf, LeafGroup, NodePlanes, STACK_GROUPS, TraversalRay, octant_order};
use crate::raycast::{Hit, PreparedRay, Ray, TriangleLanes};
use crate::simd::SlabRay;

/// A node reached by at most this many of a packet's rays is searched by each
/// alone ([`BvhScene::search`] from that node): a packet's costs per node
/// (gathering the rays per child, the loops over leaves and children) are
/// shared by too few rays to pay (measured on the bunny, the armadillo and the
/// camel: 2 to 4 alike, about 5 % faster than none).
const SEARCHED_ALONE: u32 = 3;

/// Rays a packet search holds at most: one bit each in a `u64` mask.
pub(super) const PACKET_RAYS: usize = 64;

/// Pending nodes of a packet search: a node pushes at most its eight children,
/// and at most one node per level is being expanded, so a tree of
/// [`STACK_GROUPS`] levels never holds more.
const PACKET_STACK: usize = 8 * STACK_GROUPS;

/// Relative bound, against `‖d‖₁ ‖e_i‖₁ ‖e_j‖₁`, on the rounding of an edge
/// plane's side `d · (e_i × e_j)` as computed here (`e = v - o` rounded, the
/// cross product and the dot product: about `8 ε`) plus that of the watertight
/// test's edge function for the same edge scaled to these units (the sheared
/// corners and their 2D cross product: about `48 ε`), with a factor of four
/// to spare. A side beyond it has the same sign in both.
const SIDE_BOUND: f32 = 256.0 * f32::EPSILON;

/// Relative bound, against `‖e_0‖₁ ‖e_1‖₁ ‖e_2‖₁`, on the rounding of the
/// triple product `e_0 · (e_1 × e_2)` here (about `8 ε`) and of the watertight
/// test's scaled hit distance, whose sign is that product's (about `150 ε`),
/// with a factor of three to spare: a product beyond it puts the origin on the
/// same side of the triangle's plane in both.
const VOLUME_BOUND: f32 = 512.0 * f32::EPSILON;

/// Smallest L1 distance from the origin of a corner the shared-origin test
/// decides for: with fast rays' directions (components in `2^-40..2^40`), every
/// product then stays far above the subnormal range relative to its bound.
const MIN_CORNER: f32 = 1.0 / (1u64 << 40) as f32;
/// Largest such distance: three of them times a direction stay below `f32::MAX`.
const MAX_CORNER: f32 = (1u64 << 40) as f32;

/// One ray of a packet: its box-test and triangle-test constants.
#[derive(Clone, Copy)]
struct PacketRay {
    traversal: TraversalRay,
    slab: SlabRay,
    prepared: PreparedRay,
}

impl PacketRay {
    /// `ray`'s constants; `None` when the ray is not valid.
    #[inline(always)]
    fn of(ray: &Ray) -> Option<Self> {
        let prepared = PreparedRay::new(ray)?;
        let traversal = TraversalRay::new(ray);
        Some(PacketRay {
            slab: traversal.slab_ray(),
            traversal,
            prepared,
        })
    }
}

/// The directions of a packet whose rays all start at `origin` and cover `(0,
/// ∞)`, by lane, for the shared-origin leaf test.
struct SharedOrigin {
    origin: Vec3,
    x: [f32; PACKET_RAYS],
    y: [f32; PACKET_RAYS],
    z: [f32; PACKET_RAYS],
    /// `‖d‖₁` of each direction.
    norm: [f32; PACKET_RAYS],
}

impl SharedOrigin {
    /// The lanes of `candidates` that may hit a triangle of `block`: every
    /// other lane misses all of them, for certain, by the watertight test too.
    /// The block's (up to four) triangles are in lanes, so a ray costs three
    /// four-lane dot products and their comparisons.
    #[inline(always)]
    fn may_hit(&self, candidates: u64, block: &TriangleLanes) -> u64 {
        let origin = self.origin.to_array().map(Vec4::splat);
        // Corners relative to the origin, `e[corner][axis]`, a triangle per lane.
        let e: [[Vec4; 3]; 3] = block
            .corners
            .map(|corner| core::array::from_fn(|axis| corner[axis] - origin[axis]));
        let norm = e.map(|[x, y, z]| x.abs() + y.abs() + z.abs());
        let cross = |[ax, ay, az]: [Vec4; 3], [bx, by, bz]: [Vec4; 3]| {
            [ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx]
        };
        let planes = [(1, 2), (2, 0), (0, 1)].map(|(i, j)| cross(e[i], e[j]));
        let [px, py, pz] = planes[0];
        let volume = e[0][0] * px + e[0][1] * py + e[0][2] * pz;
        let volume_bound = Vec4::splat(VOLUME_BOUND) * norm[0] * norm[1] * norm[2];
        // Oriented so that a hit in front has every side positive.
        let sign = Vec4::select(volume.cmplt(Vec4::ZERO), Vec4::NEG_ONE, Vec4::ONE);
        let planes = planes.map(|p| p.map(|c| c * sign));
        let bounds =
            [(1, 2), (2, 0), (0, 1)].map(|(i, j)| Vec4::splat(SIDE_BOUND) * norm[i] * norm[j]);
        // The relative bounds hold where nothing overflows and underflow's
        // absolute errors (2^-149 each) are far below them: every corner
        // within [2^-40, 2^40] of the origin (in L1) besides the fast rays'
        // direction range. Other triangles are left to the watertight test.
        let in_range = norm.iter().fold(BVec4A::splat(true), |ok, n| {
            ok & n.cmpge(Vec4::splat(MIN_CORNER)) & n.cmple(Vec4::splat(MAX_CORNER))
        });
        if !in_range.any() {
            return candidates;
        }
        // Behind the origin only counts as a miss where the origin is surely off
        // the triangle's plane.
        let off_plane = volume.abs().cmpgt(volume_bound);
        let mut may_hit = 0u64;
        let mut pending = candidates;
        while pending != 0 {
            let lane = pending.trailing_zeros() as usize;
            pending &= pending - 1;
            let (x, y, z) = (
                Vec4::splat(self.x[lane]),
                Vec4::splat(self.y[lane]),
                Vec4::splat(self.z[lane]),
            );
            let n = Vec4::splat(self.norm[lane]);
            let mut outside = BVec4A::splat(false);
            let mut inside = BVec4A::splat(false);
            for ([px, py, pz], bound) in planes.iter().zip(&bounds) {
                let side = x * *px + y * *py + z * *pz;
                let margin = *bound * n;
                outside |= side.cmplt(-margin);
                inside |= side.cmpgt(margin);
            }
            let miss = outside & (inside | off_plane) & in_range;
            if !miss.all() {
                may_hit |= 1 << lane;
            }
        }
        may_hit
    }
}

impl BvhScene {
    /// Writes [`RayCaster::occluded`](crate::raycast::RayCaster::occluded) of
    /// each ray of `rays` to the same index of `occluded`, tracing up to
    /// [`PACKET_RAYS`] rays in one search.
    pub(super) fn occluded_many_with<const WIDE: bool>(&self, rays: &[Ray], occluded: &mut [bool]) {
        for (rays, occluded) in rays
            .chunks(PACKET_RAYS)
            .zip(occluded.chunks_mut(PACKET_RAYS))
        {
            let mut best = [None; PACKET_RAYS];
            let hits = self.chunk::<true, WIDE>(rays, &mut best);
            for (lane, out) in occluded.iter_mut().enumerate() {
                *out = hits & (1 << lane) != 0;
            }
        }
    }

    /// Writes [`RayCaster::closest_hit`](crate::raycast::RayCaster::closest_hit)
    /// of each ray of `rays` to the same index of `hits`, tracing up to
    /// [`PACKET_RAYS`] rays in one search. Ties between triangles at the same
    /// `t` may resolve differently from one ray alone.
    pub(super) fn closest_hit_many_with<const WIDE: bool>(
        &self,
        rays: &[Ray],
        hits: &mut [Option<Hit>],
    ) {
        for (rays, hits) in rays.chunks(PACKET_RAYS).zip(hits.chunks_mut(PACKET_RAYS)) {
            let mut best = [None; PACKET_RAYS];
            self.chunk::<false, WIDE>(rays, &mut best);
            hits.copy_from_slice(&best[..hits.len()]);
        }
    }

    /// The search of at most [`PACKET_RAYS`] rays: with `ANY_HIT`, the mask
    /// of the occluded ones; otherwise each ray's closest hit in `best` (and
    /// an empty mask).
    #[inline(always)]
    fn chunk<const ANY_HIT: bool, const WIDE: bool>(
        &self,
        rays: &[Ray],
        best: &mut [Option<Hit>; PACKET_RAYS],
    ) -> u64 {
        debug_assert!(rays.len() <= PACKET_RAYS);
        let alone = |ray: &Ray, best: &mut Option<Hit>| -> bool {
            if ANY_HIT {
                self.occluding_triangle_with::<WIDE>(ray).is_some()
            } else {
                *best = self.closest_hit_with::<WIDE>(ray);
                false
            }
        };
        // Lanes outside `members` hold this ray and are never read.
        let unused = PacketRay::of(&Ray::new(Vec3::ZERO, Vec3::Z, f32::INFINITY));
        let (Some(unused), false) = (
            unused,
            self.triangle_count == 0 || self.depth > STACK_GROUPS,
        ) else {
            let mut hits = 0u64;
            for (lane, ray) in rays.iter().enumerate() {
                hits |= u64::from(alone(ray, &mut best[lane])) << lane;
            }
            return hits;
        };
        let mut packet = [unused; PACKET_RAYS];
        let mut members = 0u64;
        let mut hits = 0u64;
        let mut shared = SharedOrigin {
            origin: rays.first().map_or(Vec3::ZERO, |ray| ray.origin),
            x: [0.0; PACKET_RAYS],
            y: [0.0; PACKET_RAYS],
            z: [0.0; PACKET_RAYS],
            norm: [0.0; PACKET_RAYS],
        };
        let mut is_shared = true;
        let mut heading = Vec3::ZERO;
        for (lane, ray) in rays.iter().enumerate() {
            let Some(packet_ray) = PacketRay::of(ray) else {
                continue;
            };
            if !packet_ray.traversal.fast {
                // Rare rays (axis-parallel, huge or tiny directions) take the
                // general box test of the single-ray search.
                hits |= u64::from(alone(ray, &mut best[lane])) << lane;
                continue;
            }
            let d = ray.direction;
            is_shared &= ray.origin.to_array().map(f32::to_bits)
                == shared.origin.to_array().map(f32::to_bits)
                && ray.t_min == 0.0
                && ray.t_max == f32::INFINITY;
            (shared.x[lane], shared.y[lane], shared.z[lane]) = (d.x, d.y, d.z);
            shared.norm[lane] = d.abs().element_sum();
            heading += d / shared.norm[lane];
            members |= 1 << lane;
            packet[lane] = packet_ray;
        }
        // Children are taken in the order of the packet's mean direction: most
        // rays of a packet escape, and those visit every box they enter in any
        // order, so one packet in one order beats one per octant.
        let octant = (u32::from(heading.x < 0.0) << 2)
            | (u32::from(heading.y < 0.0) << 1)
            | u32::from(heading.z < 0.0);
        if members != 0 {
            let shared = is_shared.then_some(&shared);
            hits |= self.search_packet::<ANY_HIT, WIDE>(&mut packet, best, members, octant, shared);
        }
        hits
    }

    /// The search of the rays `members` of `packet`: with `ANY_HIT`, the mask
    /// of those that hit a triangle; otherwise each one's closest hit in
    /// `best` (its interval shortened at each hit, as alone). `shared` holds
    /// their directions where they all start at one point and cover `(0, ∞)`.
    ///
    /// A stack entry is a node and the rays that entered its box. Visiting it,
    /// each of those rays not yet occluded tests the node's child boxes; then
    /// the leaves are tested (per leaf with the shared-origin test first, or
    /// per ray as [`BvhScene::search`] does); the inner children are pushed
    /// with the rays that entered each, farthest first in `octant`'s order, so
    /// the nearest is visited next. A node reached by at most
    /// [`SEARCHED_ALONE`] rays is left to the single-ray search of each.
    #[inline(always)]
    fn search_packet<const ANY_HIT: bool, const WIDE: bool>(
        &self,
        packet: &mut [PacketRay; PACKET_RAYS],
        best: &mut [Option<Hit>; PACKET_RAYS],
        members: u64,
        octant: u32,
        shared: Option<&SharedOrigin>,
    ) -> u64 {
        let mut nodes = [0u32; PACKET_STACK];
        let mut masks = [0u64; PACKET_STACK];
        let mut depth = 1;
        masks[0] = members;
        // The rays found occluded (any-hit searches only).
        let mut hit = 0u64;
        while depth > 0 {
            depth -= 1;
            let active = masks[depth] & !hit;
            if active == 0 {
                continue;
            }
            let index = nodes[depth] as usize;
            if active.count_ones() <= SEARCHED_ALONE {
                // Too few rays left to share a node's costs: each finishes the
                // subtree with the single-ray search.
                let mut each = active;
                while each != 0 {
                    let lane = each.trailing_zeros() as usize;
                    each &= each - 1;
                    let PacketRay {
                        traversal,
                        prepared,
                        ..
                    } = &mut packet[lane];
                    let best = &mut best[lane];
                    let stack = &mut [0u64; STACK_GROUPS];
                    let found = if ANY_HIT {
                        self.search::<true, WIDE>(index, stack, traversal, |group| {
                            self.any_hit_leaf::<WIDE>(prepared, group).map(|(t, _)| t)
                        })
                    } else {
                        self.search::<false, WIDE>(index, stack, traversal, |group| {
                            self.closest_hit_leaf::<WIDE>(prepared, best, group)
                        })
                    };
                    hit |= u64::from(found) << lane;
                }
                continue;
            }
            let node = &self.planes[index];
            let mut entered_by = [0u64; 8];
            let mut entered_bytes = [0u8; PACKET_RAYS];
            // The children some ray entered.
            let mut entered_any = 0;
            let mut pending = active;
            while pending != 0 {
                let lane = pending.trailing_zeros() as usize;
                pending &= pending - 1;
                let ray = &mut packet[lane];
                let entered = if WIDE {
                    ray.traversal.entered_wide(&node.planes, &ray.slab)
                } else {
                    ray.traversal.entered_planes(&node.planes)
                };
                if shared.is_none()
                    && self.ray_leaves::<ANY_HIT, WIDE>(node, entered, ray, &mut best[lane])
                {
                    hit |= 1 << lane;
                    continue;
                }
                entered_bytes[lane] = entered as u8;
                entered_any |= entered;
            }
            // The rays that entered each child, from the rays' bytes: bit `slot`
            // of eight bytes gathered into eight bits by one multiplication.
            let mut groups = active;
            while groups != 0 {
                let group = groups.trailing_zeros() as usize / 8;
                groups &= !(0xff << (8 * group));
                // Lanes that did not test this node hold 0.
                let word = u64::from_le_bytes(
                    entered_bytes[8 * group..8 * group + 8]
                        .try_into()
                        .unwrap_or([0; 8]),
                );
                for (slot, rays) in entered_by.iter_mut().enumerate() {
                    let bits = ((word >> slot) & 0x0101_0101_0101_0101)
                        .wrapping_mul(0x0102_0408_1020_4080)
                        >> 56;
                    *rays |= bits << (8 * group);
                }
            }
            if let Some(shared) = shared {
                let mut leaves = node.leaf_mask & entered_any;
                while leaves != 0 {
                    let slot = leaves.trailing_zeros() as usize;
                    let leaf = node.take_leaf(&mut leaves);
                    let rays = entered_by[slot] & !hit;
                    if rays != 0 {
                        hit |= self.shared_leaf::<ANY_HIT, WIDE>(packet, best, shared, leaf, rays);
                    }
                }
            }
            let mut order = octant_order(node.imask & entered_any, octant);
            while order != 0 {
                let top = 31 - order.leading_zeros();
                order &= !(1 << top);
                let slot = top ^ octant;
                let rays = entered_by[slot as usize] & !hit;
                if rays != 0 {
                    let rank = (node.imask & ((1 << slot) - 1)).count_ones();
                    nodes[depth] = node.child_base + rank;
                    masks[depth] = rays;
                    depth += 1;
                }
            }
        }
        hit & members
    }

    /// One ray's test of one leaf group, as [`BvhScene::search`] runs it: with
    /// `ANY_HIT`, whether a triangle is hit; otherwise the closest hit so far
    /// kept in `best` and the ray shortened to it (and false).
    #[inline(always)]
    fn ray_leaf<const ANY_HIT: bool, const WIDE: bool>(
        &self,
        ray: &mut PacketRay,
        best: &mut Option<Hit>,
        group: &LeafGroup,
    ) -> bool {
        if ANY_HIT {
            return self.any_hit_leaf::<WIDE>(&ray.prepared, group).is_some();
        }
        if let Some(t) = self.closest_hit_leaf::<WIDE>(&mut ray.prepared, best, group) {
            ray.traversal.shorten(t);
        }
        false
    }

    /// [`Self::ray_leaf`] over the leaves of `node` in `entered` (two at a
    /// time in wide searches), stopping at the first hit of an any-hit search.
    #[inline(always)]
    fn ray_leaves<const ANY_HIT: bool, const WIDE: bool>(
        &self,
        node: &NodePlanes,
        entered: u32,
        ray: &mut PacketRay,
        best: &mut Option<Hit>,
    ) -> bool {
        let mut leaves = entered & node.leaf_mask;
        while leaves != 0 {
            let first = node.take_leaf(&mut leaves);
            let second = (WIDE && leaves != 0).then(|| node.take_leaf(&mut leaves));
            if self.ray_leaf::<ANY_HIT, WIDE>(ray, best, &LeafGroup { first, second }) {
                return true;
            }
        }
        false
    }

    /// [`Self::ray_leaf`] of `leaf` for the rays `rays`, after the
    /// shared-origin test has ruled out their certain misses: with `ANY_HIT`,
    /// the mask of those that hit.
    #[inline(always)]
    fn shared_leaf<const ANY_HIT: bool, const WIDE: bool>(
        &self,
        packet: &mut [PacketRay; PACKET_RAYS],
        best: &mut [Option<Hit>; PACKET_RAYS],
        shared: &SharedOrigin,
        leaf: Leaf,
        rays: u64,
    ) -> u64 {
        let mut undecided = shared.may_hit(rays, &self.blocks[leaf.block]);
        let mut hits = 0u64;
        let group = LeafGroup {
            first: leaf,
            second: None,
        };
        while undecided != 0 {
            let lane = undecided.trailing_zeros() as usize;
            undecided &= undecided - 1;
            if self.ray_leaf::<ANY_HIT, WIDE>(&mut packet[lane], &mut best[lane], &group) {
                hits |= 1 << lane;
            }
        }
        hits
    }
}
