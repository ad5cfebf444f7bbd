//! Meshes the hemi tests share.

use alloc::vec;
use alloc::vec::Vec;
use glam::Vec3;

use super::vertex_normals;
use crate::geom::MeshView;

/// A closed UV sphere with its radius modulated by `bump` (0 = round) so that
/// it has concave regions, twisted about +z by `twist` radians per unit of
/// height; counter-clockwise seen from outside.
pub(super) fn bumpy_sphere(
    rings: u32,
    segments: u32,
    bump: f32,
    twist: f32,
) -> (Vec<[f32; 3]>, Vec<u32>) {
    crate::geom::uv_sphere(rings, segments, |theta, phi| {
        let radius = 1.0 + bump * libm::sinf(5.0 * theta) * libm::sinf(4.0 * phi);
        let z = radius * libm::cosf(theta);
        let angle = phi + twist * z;
        [
            radius * libm::sinf(theta) * libm::cosf(angle),
            radius * libm::sinf(theta) * libm::sinf(angle),
            z,
        ]
    })
}

/// The area-weighted vertex normals of `mesh`.
pub(super) fn normals_of(mesh: &MeshView<'_>) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; mesh.vertex_count()];
    vertex_normals(mesh, &mut normals).unwrap();
    normals
}

/// A small deterministic generator (xorshift), in `[0, 1)`.
pub(super) struct Rng(pub(super) u64);

impl Rng {
    pub(super) fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}
