//! Refitting a scene to moved vertices: [`BvhScene::refit`].
//!
//! A deforming or rigidly moving mesh keeps its triangles; only their corners
//! move. Rebuilding the hierarchy each frame pays the builder (sorting,
//! clustering, the wide conversion) again; a refit keeps the hierarchy's shape
//! (which triangles share a leaf, which nodes share a parent) and recomputes
//! every box from the new corners, children before parents, in one linear pass.
//!
//! Answers stay exact: a box only has to contain its triangles for the
//! traversal to reach every triangle a ray meets, and the leaf test is the
//! same watertight test, so every query of a refitted scene answers as a scene
//! built on the moved mesh would (up to which of two triangles at exactly the
//! same distance a closest hit reports, which the traversal order decides).
//! Only the speed depends on the shape: boxes of a mesh that moved rigidly
//! keep their overlap, while large deformations grow the boxes that straddle
//! them, and a rebuild then pays for itself.
//!
//! Each node's child boxes are quantised to its grid as the builder does
//! (`p + q · 2^e` with 8-bit `q`), conservatively: the exponent is the
//! smallest power of two whose 255 steps cover the node, lower bounds are
//! rounded down and upper bounds up, in `f64`, whose rounding is far below the
//! relative padding that [`NodePlanes::new`] adds when it decodes them.

#[cfg(test)]
use alloc::vec::Vec;

use glam::{Vec3, Vec4};
use obvhs::cwbvh::node::CwBvhNode;

use super::{BvhError, BvhScene, NodePlanes, leaf_primitives, out_of_range};
use crate::geom::MeshView;
use crate::raycast::TriangleLanes;

/// The smallest normal `f32` exponent: the grid step's exponent is stored as
/// `f32` exponent bits.
const MIN_EXPONENT: i32 = -126;

impl BvhScene {
    /// Moves the scene's triangles to `mesh`'s current corners, keeping the
    /// hierarchy's shape: triangle `t` of the scene becomes triangle `t` of
    /// `mesh` (module docs). Linear in the triangles, without the builder:
    /// for a mesh that deforms or moves every frame.
    ///
    /// Queries answer exactly as a scene built on `mesh` with [`BvhScene::new`]
    /// would; their speed falls as the motion distorts the hierarchy, so
    /// rebuild after large changes of shape.
    ///
    /// Fails, leaving the scene as it was, when `mesh` has a different number
    /// of triangles, when a vertex used by a triangle is beyond
    /// ±[`MAX_COORDINATE`](super::MAX_COORDINATE), or when the pass's scratch
    /// (24 bytes per node and per leaf block) cannot be reserved.
    pub fn refit(&mut self, mesh: &MeshView<'_>) -> Result<(), BvhError> {
        if mesh.triangle_count() != self.triangle_count {
            return Err(BvhError::TriangleCountChanged {
                scene: self.triangle_count,
                mesh: mesh.triangle_count(),
            });
        }
        if let Some(vertex) = out_of_range(mesh) {
            return Err(BvhError::CoordinateOutOfRange { vertex });
        }
        let nodes = self.bvh.nodes.len();
        // The nodes' boxes, then the leaves' (one per block), kept between
        // refits so that a frame's refit does not allocate.
        let mut bounds = core::mem::take(&mut self.refit_bounds);
        let total = nodes + self.blocks.len();
        bounds
            .try_reserve_exact(total.saturating_sub(bounds.len()))
            .map_err(BvhError::OutOfMemory)?;
        // Nothing fails from here on.
        bounds.resize(total, [Vec3::ZERO; 2]);
        let (node_bounds, leaf_bounds) = bounds.split_at_mut(nodes);
        // Each leaf's box is taken while its block is in cache, so that the
        // pass over the nodes below reads 24 bytes per leaf instead of the
        // 160-byte block, in the nodes' order rather than the blocks'.
        for ((lanes, &[t0, t1, t2, t3]), leaf) in self
            .blocks
            .iter_mut()
            .zip(&self.block_triangles)
            .zip(leaf_bounds.iter_mut())
        {
            // The padding lanes' indices repeat the last triangle, as
            // `TriangleLanes::new` fills them.
            let (p, q) = (mesh.triangle(t0 as usize), mesh.triangle(t1 as usize));
            let (r, s) = (mesh.triangle(t2 as usize), mesh.triangle(t3 as usize));
            for (corner, axes) in lanes.corners.iter_mut().enumerate() {
                for (axis, lane) in axes.iter_mut().enumerate() {
                    *lane = Vec4::new(
                        p[corner][axis],
                        q[corner][axis],
                        r[corner][axis],
                        s[corner][axis],
                    );
                }
            }
            *leaf = lanes_bounds(lanes);
        }
        // The builder numbers every node's children after it, so a backward
        // pass meets children first.
        for index in (0..nodes).rev() {
            let plane = &mut self.planes[index];
            let node = &mut self.bvh.nodes[index];
            let mut children = [None; 8];
            for (slot, child) in children.iter_mut().enumerate() {
                if node.imask & (1 << slot) != 0 {
                    let below = node.child_node_index(slot) as usize;
                    debug_assert!(below > index, "children are numbered after parents");
                    *child = Some(node_bounds[below]);
                } else if plane.leaf_mask & (1 << slot) != 0 {
                    let (block, _) = leaf_primitives(plane.block_base, plane.leaves[slot]);
                    *child = Some(leaf_bounds[block]);
                }
            }
            node_bounds[index] = quantise(node, &children);
            *plane = NodePlanes::new(node, plane.block_base);
        }
        self.refit_bounds = bounds;
        #[cfg(test)]
        for (corners, &t) in self.corners.iter_mut().zip(&self.original) {
            *corners = mesh.triangle(t as usize);
        }
        Ok(())
    }
}

/// The box of a leaf's triangles, from their lanes (the padding lanes repeat
/// a triangle of the leaf, so they add nothing).
fn lanes_bounds(lanes: &TriangleLanes) -> [Vec3; 2] {
    let [a, b, c] = &lanes.corners;
    let axis = |k: usize| {
        let lo = a[k].min(b[k]).min(c[k]).min_element();
        let hi = a[k].max(b[k]).max(c[k]).max_element();
        (lo, hi)
    };
    let ((x0, x1), (y0, y1), (z0, z1)) = (axis(0), axis(1), axis(2));
    [Vec3::new(x0, y0, z0), Vec3::new(x1, y1, z1)]
}

/// Sets `node`'s grid (`p`, `e`) to the union of `children`'s boxes and its
/// child slots to their conservatively quantised boxes; returns the union.
/// Empty slots keep their bytes (the traversal never enters them).
pub(super) fn quantise(node: &mut CwBvhNode, children: &[Option<[Vec3; 2]>; 8]) -> [Vec3; 2] {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for [child_lo, child_hi] in children.iter().flatten() {
        lo = lo.min(*child_lo);
        hi = hi.max(*child_hi);
    }
    if lo.cmpgt(hi).any() {
        // No child: nothing to bound (the builder makes no such node).
        return [lo, hi];
    }
    node.p = lo;
    let mut steps = [0.0f64; 3];
    for axis in 0..3 {
        let exponent = grid_exponent(f64::from(hi[axis]) - f64::from(lo[axis]));
        // The biased exponent bits of 2^exponent as an f32 (1..=254).
        node.e[axis] = (exponent + 127) as u8;
        steps[axis] = pow2(exponent);
    }
    let origin = [f64::from(lo.x), f64::from(lo.y), f64::from(lo.z)];
    // Dividing by a power of two is multiplying by its exact inverse.
    let scale = steps.map(|step| 1.0 / step);
    // `v >= origin`, so the offset is at least 0 and truncation is the floor.
    let down = |v: f32, axis: usize| {
        let q = (f64::from(v) - origin[axis]) * scale[axis];
        q.clamp(0.0, 255.0) as u8
    };
    let up = |v: f32, axis: usize| {
        let q = ((f64::from(v) - origin[axis]) * scale[axis]).clamp(0.0, 255.0);
        let floor = q as u8;
        floor + u8::from(f64::from(floor) < q)
    };
    for (slot, child) in children.iter().enumerate() {
        let Some([child_lo, child_hi]) = child else {
            continue;
        };
        node.child_min_x[slot] = down(child_lo.x, 0);
        node.child_min_y[slot] = down(child_lo.y, 1);
        node.child_min_z[slot] = down(child_lo.z, 2);
        node.child_max_x[slot] = up(child_hi.x, 0);
        node.child_max_y[slot] = up(child_hi.y, 1);
        node.child_max_z[slot] = up(child_hi.z, 2);
    }
    [lo, hi]
}

/// The exponent `k` of the smallest grid step `2^k` (at least the smallest
/// normal `f32`) whose 255 steps reach `extent`.
fn grid_exponent(extent: f64) -> i32 {
    if extent <= 255.0 * pow2(MIN_EXPONENT) {
        return MIN_EXPONENT;
    }
    // The binary exponent of extent / 255 (rounded, so corrected below), then
    // the exact condition `255 · 2^k >= extent` (products by powers of two are
    // exact) decides. Coordinates within ±MAX_COORDINATE keep k below 40.
    let step = extent / 255.0;
    let mut exponent = (((step.to_bits() >> 52) & 0x7ff) as i32 - 1023).clamp(MIN_EXPONENT, 127);
    while exponent < 127 && 255.0 * pow2(exponent) < extent {
        exponent += 1;
    }
    while exponent > MIN_EXPONENT && 255.0 * pow2(exponent - 1) >= extent {
        exponent -= 1;
    }
    exponent
}

/// `2^k` for `-126 <= k <= 127`, exactly.
fn pow2(k: i32) -> f64 {
    f64::from_bits(((k + 1023) as u64) << 52)
}

#[cfg(test)]
impl BvhScene {
    /// Checks that every child box of every node, as quantised (decoded
    /// exactly, in `f64`) and as decoded for the searches, holds the corners of
    /// every triangle below it; returns the triangles below `index`.
    pub(in crate::raycast) fn assert_boxes_hold(
        &self,
        mesh: &MeshView<'_>,
        index: usize,
    ) -> Vec<u32> {
        let node = &self.bvh.nodes[index];
        let plane = &self.planes[index];
        let mut all = Vec::new();
        for slot in 0..8 {
            let below = if node.imask & (1 << slot) != 0 {
                self.assert_boxes_hold(mesh, node.child_node_index(slot) as usize)
            } else if plane.leaf_mask & (1 << slot) != 0 {
                let (block, count) = leaf_primitives(plane.block_base, plane.leaves[slot]);
                self.block_triangles[block][..count].to_vec()
            } else {
                continue;
            };
            let quantised = [
                [node.child_min_x[slot], node.child_max_x[slot]],
                [node.child_min_y[slot], node.child_max_y[slot]],
                [node.child_min_z[slot], node.child_max_z[slot]],
            ];
            for &t in &below {
                for corner in mesh.triangle(t as usize) {
                    for axis in 0..3 {
                        let step = f64::from(f32::from_bits(u32::from(node.e[axis]) << 23));
                        let p = f64::from(node.p[axis]);
                        let [lo, hi] = quantised[axis];
                        let c = f64::from(corner[axis]);
                        assert!(
                            p + f64::from(lo) * step <= c && c <= p + f64::from(hi) * step,
                            "node {index} slot {slot} axis {axis}: {c} outside the grid box"
                        );
                        let [planes_lo, planes_hi] = plane.planes.0[axis];
                        assert!(
                            planes_lo[slot] <= corner[axis] && corner[axis] <= planes_hi[slot],
                            "node {index} slot {slot} axis {axis}: {c} outside the searched box"
                        );
                    }
                }
            }
            all.extend(below);
        }
        all
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_step_is_the_least_power_of_two_that_covers() {
        assert_eq!(grid_exponent(0.0), MIN_EXPONENT);
        assert_eq!(grid_exponent(255.0), 0);
        assert_eq!(grid_exponent(255.5), 1);
        assert_eq!(grid_exponent(127.5), -1);
        assert_eq!(grid_exponent(2.0e12), 33);
        for k in [-126, -20, 0, 33, 127] {
            assert_eq!(pow2(k), 2f64.powi(k));
        }
    }
}
