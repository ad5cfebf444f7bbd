//! Occlusion of many rays in one search: `RayCaster::occluded_many` of
//! [`BvhScene`].
//!
//! Rays that start together (a bake's rays from one vertex) enter mostly the
//! same nodes near the root. Searching them one by one pays a node's fixed
//! costs (the stack, the loads of its planes and links, the branches of the
//! loop) once per ray; a packet search pays them once per node and tests only
//! the rays that entered the node's box, each with exactly the box test of
//! [`BvhScene::occluded`]. So every ray enters the same nodes as alone.
//!
//! The leaves: where every ray of the packet starts at the same point and
//! covers `(0, ∞)`, a leaf's triangles are first tested against all its rays
//! at once ([`SharedOrigin`]): from a common origin, a ray misses a triangle
//! when its direction is outside one of the three planes through the origin
//! and an edge, which is one dot product per plane and ray, the planes shared.
//! Only a miss certain beyond the rounding of both this test and the
//! watertight one is taken; every other ray (a hit, or a direction within
//! rounding of an edge plane) gets the watertight test of
//! [`BvhScene::occluded`] on that leaf. Other packets test each ray's leaves
//! with the watertight test directly. Either way each ray's answer (whether
//! some triangle is hit) is the bit [`BvhScene::occluded`] gives; only the
//! order of the work differs.

use glam::Vec3;

use super::{BvhScene, Leaf, LeafGroup, NodePlanes, STACK_GROUPS, TraversalRay, octant_order};
use crate::raycast::{PreparedRay, Ray};
use crate::simd::SlabRay;

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

/// One ray of a packet: its box-test and triangle-test constants.
#[derive(Clone, Copy)]
struct PacketRay {
    traversal: TraversalRay,
    slab: SlabRay,
    prepared: PreparedRay,
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
    /// The lanes of `candidates` that may hit one of the first `count`
    /// triangles `triangle(k)`: every other lane misses all of them, for
    /// certain, by the watertight test too.
    #[inline(always)]
    fn may_hit(&self, candidates: u64, count: usize, triangle: impl Fn(usize) -> [Vec3; 3]) -> u64 {
        let mut may_hit = 0u64;
        for k in 0..count {
            let [a, b, c] = triangle(k);
            let e = [a - self.origin, b - self.origin, c - self.origin];
            let norm = e.map(|e| e.abs().element_sum());
            let volume = e[0].dot(e[1].cross(e[2]));
            let volume_bound = VOLUME_BOUND * norm[0] * norm[1] * norm[2];
            // Oriented so that a hit in front has every side positive.
            let sign = if volume < 0.0 { -1.0 } else { 1.0 };
            let planes = [(1, 2), (2, 0), (0, 1)].map(|(i, j)| e[i].cross(e[j]) * sign);
            let bounds = [(1, 2), (2, 0), (0, 1)].map(|(i, j)| SIDE_BOUND * norm[i] * norm[j]);
            if !(volume_bound.is_finite() && bounds.iter().all(|b| b.is_finite())) {
                // Too large to bound in f32: leave every lane to the exact test.
                return candidates;
            }
            // Behind the origin only counts as a miss where the origin is
            // surely off the triangle's plane.
            let off_plane = volume.abs() > volume_bound;
            for group in 0..PACKET_RAYS / 8 {
                let lanes = (candidates >> (8 * group)) as u8;
                if lanes == 0 {
                    continue;
                }
                let base = 8 * group;
                let lanes_of = |values: &[f32; PACKET_RAYS]| -> [f32; 8] {
                    core::array::from_fn(|lane| values[base + lane])
                };
                let (x, y, z, n) = (
                    lanes_of(&self.x),
                    lanes_of(&self.y),
                    lanes_of(&self.z),
                    lanes_of(&self.norm),
                );
                let mut outside = [false; 8];
                let mut inside = [false; 8];
                for (plane, bound) in planes.iter().zip(&bounds) {
                    for lane in 0..8 {
                        let side = x[lane] * plane.x + y[lane] * plane.y + z[lane] * plane.z;
                        let margin = bound * n[lane];
                        outside[lane] |= side < -margin;
                        inside[lane] |= side > margin;
                    }
                }
                let mut possible = 0u8;
                for lane in 0..8 {
                    let miss = outside[lane] & (inside[lane] | off_plane);
                    possible |= u8::from(!miss) << lane;
                }
                may_hit |= u64::from(possible & lanes) << base;
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
            self.occluded_chunk::<WIDE>(rays, occluded);
        }
    }

    /// [`Self::occluded_many_with`] on at most [`PACKET_RAYS`] rays.
    #[inline(always)]
    fn occluded_chunk<const WIDE: bool>(&self, rays: &[Ray], occluded: &mut [bool]) {
        debug_assert!(rays.len() <= PACKET_RAYS && rays.len() == occluded.len());
        if self.triangle_count == 0 || self.depth > STACK_GROUPS {
            for (ray, out) in rays.iter().zip(occluded.iter_mut()) {
                *out = self.occluded_with::<WIDE>(ray);
            }
            return;
        }
        let mut packet = [None::<PacketRay>; PACKET_RAYS];
        let mut members = 0u64;
        let mut shared = SharedOrigin {
            origin: rays.first().map_or(Vec3::ZERO, |ray| ray.origin),
            x: [0.0; PACKET_RAYS],
            y: [0.0; PACKET_RAYS],
            z: [0.0; PACKET_RAYS],
            norm: [0.0; PACKET_RAYS],
        };
        let mut is_shared = true;
        let mut heading = Vec3::ZERO;
        for (lane, (ray, out)) in rays.iter().zip(occluded.iter_mut()).enumerate() {
            let Some(prepared) = PreparedRay::new(ray) else {
                *out = false;
                continue;
            };
            let traversal = TraversalRay::new(ray);
            if !traversal.fast {
                // Rare rays (axis-parallel, huge or tiny directions) take the
                // general box test of the single-ray search.
                *out = self.occluded_with::<WIDE>(ray);
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
            packet[lane] = Some(PacketRay {
                slab: traversal.slab_ray(),
                traversal,
                prepared,
            });
        }
        // Children are taken in the order of the packet's mean direction: most
        // rays of a packet escape, and those visit every box they enter in any
        // order, so one packet in one order beats one per octant.
        let octant = (u32::from(heading.x < 0.0) << 2)
            | (u32::from(heading.y < 0.0) << 1)
            | u32::from(heading.z < 0.0);
        let hits = if members == 0 {
            0
        } else if is_shared {
            self.search_packet::<WIDE>(&packet, members, octant, Some(&shared))
        } else {
            self.search_packet::<WIDE>(&packet, members, octant, None)
        };
        for (lane, out) in occluded.iter_mut().enumerate() {
            if members & (1 << lane) != 0 {
                *out = hits & (1 << lane) != 0;
            }
        }
    }

    /// The any-hit search of the rays `members` of `packet` (all `Some`): the
    /// mask of those that hit a triangle. `shared` holds their directions
    /// where they all start at one point and cover `(0, ∞)`.
    ///
    /// A stack entry is a node and the rays that entered its box. Visiting it,
    /// each of those rays not yet occluded tests the node's child boxes; then
    /// the leaves are tested (per leaf with the shared-origin test first, or
    /// per ray as [`BvhScene::search`] does); the inner children are pushed
    /// with the rays that entered each, farthest first in `octant`'s order, so
    /// the nearest is visited next.
    #[inline(always)]
    fn search_packet<const WIDE: bool>(
        &self,
        packet: &[Option<PacketRay>; PACKET_RAYS],
        members: u64,
        octant: u32,
        shared: Option<&SharedOrigin>,
    ) -> u64 {
        let mut nodes = [0u32; PACKET_STACK];
        let mut masks = [0u64; PACKET_STACK];
        let mut depth = 1;
        masks[0] = members;
        let mut hit = 0u64;
        while depth > 0 {
            depth -= 1;
            let active = masks[depth] & !hit;
            if active == 0 {
                continue;
            }
            let node = &self.planes[nodes[depth] as usize];
            let mut entered_by = [0u64; 8];
            let mut pending = active;
            while pending != 0 {
                let lane = pending.trailing_zeros() as usize;
                pending &= pending - 1;
                let Some(ray) = &packet[lane] else {
                    continue;
                };
                let entered = if WIDE {
                    ray.traversal.entered_wide(&node.planes, &ray.slab)
                } else {
                    ray.traversal.entered_planes(&node.planes)
                };
                if shared.is_none() && self.ray_hits_leaves::<WIDE>(node, entered, ray) {
                    hit |= 1 << lane;
                    continue;
                }
                let mut slots = entered & (node.imask | node.leaf_mask);
                while slots != 0 {
                    let slot = slots.trailing_zeros() as usize;
                    slots &= slots - 1;
                    entered_by[slot] |= 1 << lane;
                }
            }
            if let Some(shared) = shared {
                let mut leaves = node.leaf_mask;
                while leaves != 0 {
                    let slot = leaves.trailing_zeros() as usize;
                    let leaf = node.take_leaf(&mut leaves);
                    let rays = entered_by[slot] & !hit;
                    if rays.count_ones() >= SHARED_MIN {
                        hit |= self.leaf_hits::<WIDE>(packet, shared, leaf, rays);
                    } else if rays != 0 {
                        hit |= self.leaf_hits_each::<WIDE>(packet, leaf, rays);
                    }
                }
            }
            let mut order = octant_order(node.imask, octant);
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

    /// Whether `ray` hits a triangle of the leaves of `node` in `entered`,
    /// tested as [`BvhScene::search`] tests them (two at a time in wide
    /// searches).
    #[inline(always)]
    fn ray_hits_leaves<const WIDE: bool>(
        &self,
        node: &NodePlanes,
        entered: u32,
        ray: &PacketRay,
    ) -> bool {
        let mut leaves = entered & node.leaf_mask;
        while leaves != 0 {
            let first = node.take_leaf(&mut leaves);
            let second = (WIDE && leaves != 0).then(|| node.take_leaf(&mut leaves));
            let group = LeafGroup { first, second };
            if self.any_hit_leaf::<WIDE>(&ray.prepared, &group).is_some() {
                return true;
            }
        }
        false
    }

    /// The rays of `rays` that hit a triangle of `leaf`, by the watertight test
    /// alone.
    #[inline(always)]
    fn leaf_hits_each<const WIDE: bool>(
        &self,
        packet: &[Option<PacketRay>; PACKET_RAYS],
        leaf: Leaf,
        mut rays: u64,
    ) -> u64 {
        let group = LeafGroup {
            first: leaf,
            second: None,
        };
        let mut hits = 0u64;
        while rays != 0 {
            let lane = rays.trailing_zeros() as usize;
            rays &= rays - 1;
            if let Some(ray) = &packet[lane]
                && self.any_hit_leaf::<WIDE>(&ray.prepared, &group).is_some()
            {
                hits |= 1 << lane;
            }
        }
        hits
    }

    /// The rays of `rays` that hit a triangle of `leaf`: the shared-origin
    /// test rules out the certain misses, the watertight test decides the rest.
    #[inline(always)]
    fn leaf_hits<const WIDE: bool>(
        &self,
        packet: &[Option<PacketRay>; PACKET_RAYS],
        shared: &SharedOrigin,
        leaf: Leaf,
        rays: u64,
    ) -> u64 {
        let block = &self.blocks[leaf.block];
        let mut undecided = shared.may_hit(rays, leaf.count, |k| block.triangle(k));
        let mut hits = 0u64;
        let group = LeafGroup {
            first: leaf,
            second: None,
        };
        while undecided != 0 {
            let lane = undecided.trailing_zeros() as usize;
            undecided &= undecided - 1;
            if let Some(ray) = &packet[lane]
                && self.any_hit_leaf::<WIDE>(&ray.prepared, &group).is_some()
            {
                hits |= 1 << lane;
            }
        }
        hits
    }
}

const SHARED_MIN: u32 = 8;
