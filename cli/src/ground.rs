//! An object standing on a wide ground, the layout most scenes have: the
//! demo's stage for hemispherical rasterization, and `antumbra bench hemi
//! --on-ground`.
//!
//! The ground is a polar grid around the object whose rings grow
//! geometrically, fine under the object and coarse towards the horizon (where
//! a receiver sees the object as a speck), reaching 30 of the object's
//! diagonals so that it fills the bottom of the demo's frame like the
//! ray-traced pictures' plane. The far mesh is the object's vertex clustering
//! plus the ground as one square of two triangles: every corner is far from
//! every receiver, so it is always taken, and it is coplanar with the fine
//! ground (ground receivers see it on their horizon, culled; the object's
//! receivers see it cover the same directions as the fine ground). A flat
//! ground is where vertex clustering, the library's own far field, does
//! worst: it keeps a ground's triangles wherever they are larger than its
//! cubes, and its cubes small enough for the object leave the ground's many
//! triangles for the object's receivers to rasterize, so a caller who knows
//! the ground is flat passes this far mesh instead.

use crate::bounds::Bounds;
use crate::error::Result;
use crate::hemi_shading::{FAR_CELL_OF_DIAGONAL, LodMesh, simplify};
use crate::mesh::TriangleMesh;

/// Segments around each ring of the ground grid.
const GROUND_SEGMENTS: u32 = 40;

/// Radius of the ground's innermost ring, of its outermost, and the growth from
/// one ring to the next, in units of the bunny's diagonal: rings about as far
/// apart as the segments are wide, from inside the bunny's footprint (a fan
/// covers the rest, hidden under the bunny) to beyond the horizon of the demo's
/// camera.
const GROUND_INNER_RADIUS: f32 = 0.12;
const GROUND_OUTER_RADIUS: f32 = 30.0;
const GROUND_GROWTH: f32 = 1.0 + std::f32::consts::TAU / GROUND_SEGMENTS as f32;

/// `object` on the ground (its vertices and triangles first) with its far
/// mesh: the object by vertex clustering with cells of
/// [`FAR_CELL_OF_DIAGONAL`] of its diagonal, plus the ground as one square;
/// the near radius is [`LodMesh`]'s rule for the object's diagonal.
pub fn on_ground(object: &TriangleMesh) -> Result<LodMesh> {
    let bounds = object.bounds();
    let diagonal = bounds.diagonal();
    let far_cell = FAR_CELL_OF_DIAGONAL * diagonal;
    let far = with_square_ground(&simplify(object, far_cell)?, &bounds)?;
    Ok(LodMesh::with_far(
        with_ground(object)?,
        far,
        far_cell,
        diagonal,
    ))
}

/// `bunny` standing on the polar ground grid at the bottom of its bounds (see
/// the module docs); the bunny's vertices and triangles come first.
fn with_ground(bunny: &TriangleMesh) -> Result<TriangleMesh> {
    let bounds = bunny.bounds();
    let diagonal = bounds.diagonal();
    let (cx, y, cz) = (bounds.center().x, bounds.min.y, bounds.center().z);
    let mut positions = bunny.positions().to_vec();
    let mut indices = bunny.indices().to_vec();
    let center = positions.len() as u32;
    positions.push([cx, y, cz]);
    let segments = GROUND_SEGMENTS;
    let mut radius = GROUND_INNER_RADIUS * diagonal;
    let mut rings = 0u32;
    while radius <= GROUND_OUTER_RADIUS * diagonal {
        for s in 0..segments {
            let angle = std::f32::consts::TAU * s as f32 / segments as f32;
            positions.push([cx + radius * angle.cos(), y, cz + radius * angle.sin()]);
        }
        rings += 1;
        radius *= GROUND_GROWTH;
    }
    let ring = |r: u32, s: u32| center + 1 + r * segments + s % segments;
    // Counter-clockwise seen from above: normals +Y.
    for s in 0..segments {
        indices.extend([center, ring(0, s + 1), ring(0, s)]);
    }
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b) = (ring(r, s), ring(r, s + 1));
            let (c, d) = (ring(r + 1, s), ring(r + 1, s + 1));
            indices.extend([a, b, d, a, d, c]);
        }
    }
    TriangleMesh::new(format!("{} on a ground", bunny.name()), positions, indices)
}

/// `mesh` with a square of two triangles, `2 × GROUND_OUTER_RADIUS` bunny
/// diagonals wide, at the bottom of `bounds`, after its own vertices and triangles.
fn with_square_ground(mesh: &TriangleMesh, bounds: &Bounds) -> Result<TriangleMesh> {
    let half = GROUND_OUTER_RADIUS * bounds.diagonal();
    let (cx, y, cz) = (bounds.center().x, bounds.min.y, bounds.center().z);
    let mut positions = mesh.positions().to_vec();
    let mut indices = mesh.indices().to_vec();
    let base = positions.len() as u32;
    positions.extend([
        [cx - half, y, cz - half],
        [cx - half, y, cz + half],
        [cx + half, y, cz + half],
        [cx + half, y, cz - half],
    ]);
    // Counter-clockwise seen from above.
    indices.extend([0, 1, 2, 0, 2, 3].map(|k| base + k));
    TriangleMesh::new(mesh.name().to_string(), positions, indices)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin;
    use glam::Vec3;

    #[test]
    fn the_ground_lies_flat_under_the_bunny_facing_up() {
        let bunny = builtin::bunny().unwrap();
        let stage = with_ground(&bunny).unwrap();
        let n = bunny.vertex_count();
        assert_eq!(&stage.positions()[..n], bunny.positions());
        assert_eq!(&stage.indices()[..bunny.indices().len()], bunny.indices());
        let bottom = bunny.bounds().min.y;
        assert!(stage.positions()[n..].iter().all(|p| p[1] == bottom));
        let normals = stage.vertex_normals();
        assert!(normals[n..].iter().all(|v| (*v - Vec3::Y).length() < 1e-5));
        let reach = stage.bounds().size().x / bunny.bounds().diagonal();
        // The last ring is within one growth step of the outer radius.
        assert!(
            reach * GROUND_GROWTH >= 2.0 * GROUND_OUTER_RADIUS,
            "{reach}"
        );
    }
}
