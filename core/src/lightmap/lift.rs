//! Moving texel receivers out of geometry they start in: a texel under a box
//! standing on a floor, or whose centre lies across a thin wall, would bake the
//! light inside the box or behind the wall (the classic lightmap leak).

use glam::Vec3;

use super::TexelAtlas;
use crate::geom::{Frame, MeshView};
use crate::raycast::{Ray, RayCaster};

/// Below this barycentric weight a receiver counts as on its triangle's edge.
const EDGE_WEIGHT: f32 = 1e-3;

/// How [`TexelAtlas::lift`] probes around each receiver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiftOptions {
    /// Height above the receiver's triangle, along its normal, at which the
    /// probes start, as a fraction of the texel's world size (finite, > 0).
    /// Default 1e-3.
    pub height: f32,
    /// Probe rays per receiver, spread evenly over the tangent plane (0 turns the
    /// lift off). Default 8.
    pub probes: u32,
    /// Probe length in texels (finite, > 0): geometry this far from the
    /// receiver counts. Default 1, the texel's footprint and a little beyond.
    pub reach: f32,
}

impl Default for LiftOptions {
    fn default() -> Self {
        LiftOptions {
            height: 1e-3,
            probes: 8,
            reach: 1.0,
        }
    }
}

impl TexelAtlas {
    /// Moves each receiver that starts inside geometry out of it: probes from
    /// just above the receiver's triangle in the tangent plane, and where one
    /// meets the back of a triangle (the receiver is behind that surface), the
    /// receiver moves past the nearest such hit, `height` above its own plane.
    /// A receiver on an edge of its triangle (where another surface may meet it,
    /// a crease) first moves `height` into the triangle. Other receivers stay
    /// where they are.
    ///
    /// `caster` must hold `mesh`'s triangles in the same order (hit indices
    /// address `mesh`), and `mesh` must be the one the atlas was built from.
    /// Returns how many receivers moved; `None` (and nothing moved) for options
    /// out of range.
    pub fn lift<C: RayCaster + ?Sized>(
        &mut self,
        mesh: &MeshView<'_>,
        caster: &C,
        options: &LiftOptions,
    ) -> Option<usize> {
        let valid = |x: f32| x.is_finite() && x > 0.0;
        if !valid(options.height) || !valid(options.reach) {
            return None;
        }
        let mut moved = 0;
        for receiver in &mut self.receivers {
            let mut pulled = false;
            let triangle = receiver.triangle as usize;
            let [a, b, c] = mesh.triangle(triangle);
            let mut up = (b - a).cross(c - a).normalize_or_zero();
            if up == Vec3::ZERO {
                continue;
            }
            if up.dot(receiver.normal) < 0.0 {
                up = -up;
            }
            let frame = Frame::from_normal(up);
            let size = receiver.texel_size;
            // A receiver on its triangle's edge (a touched texel's nearest
            // point, a centre on an edge) may lie on another surface too (the
            // floor under a wall's bottom row): its rays would start exactly in
            // that surface's plane, where the two sides' hits are decided by
            // rounding. Moving it `height` into its own triangle puts it on the
            // right side of every surface through the edge.
            let [u, v] = receiver.barycentric;
            if u.min(v).min(1.0 - u - v) < EDGE_WEIGHT {
                let inward = ((a + b + c) / 3.0 - receiver.position).normalize_or_zero();
                receiver.position += inward * (options.height * size);
                pulled = true;
            }
            let start = receiver.position + up * (options.height * size);
            let reach = options.reach * size;
            let mut nearest: Option<(f32, Vec3)> = None;
            for k in 0..options.probes {
                let angle = core::f32::consts::TAU * k as f32 / options.probes as f32;
                let (sin, cos) = libm::sincosf(angle);
                let direction = frame.tangent * cos + frame.bitangent * sin;
                // Surfaces through the start itself (the floor under a wall's
                // bottom row, in a crease) are not behind the receiver: hits
                // closer than the start's height are ignored.
                let probe = Ray {
                    t_min: options.height * size,
                    ..Ray::new(start, direction, reach)
                };
                let Some(hit) = caster.closest_hit(&probe) else {
                    continue;
                };
                let [ha, hb, hc] = mesh.triangle(hit.triangle as usize);
                let facing = (hb - ha).cross(hc - ha);
                if facing.dot(direction) > 0.0 && nearest.is_none_or(|(t, _)| hit.t < t) {
                    nearest = Some((hit.t, direction));
                }
            }
            if let Some((t, direction)) = nearest {
                // Past the back face by a sliver of the texel, off the plane.
                receiver.position = start + direction * (t + options.height * size);
            }
            moved += usize::from(pulled || nearest.is_some());
        }
        Some(moved)
    }
}
