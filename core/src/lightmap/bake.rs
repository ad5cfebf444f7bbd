//! Baking a lightmap: the atlas's receivers as the bake's points, each bounce
//! reading the previous pass of the texel under its hit's UV.

use alloc::vec::Vec;

use glam::Vec3;

use super::{TexelAtlas, TexelReceiver};
use crate::geom::MeshView;
use crate::raycast::RayCaster;
use crate::transfer::{BakeError, BakeOptions, BakePoint, BounceReads, TransferSet, bake_points};

impl From<&TexelReceiver> for BakePoint {
    fn from(receiver: &TexelReceiver) -> Self {
        BakePoint {
            position: receiver.position,
            normal: receiver.normal,
        }
    }
}

impl TexelAtlas {
    /// Bakes every receiver against `mesh` (the mesh the atlas was built from,
    /// with `normals` one per vertex, which tell a hit's front from its back),
    /// through `caster` (holding the mesh's triangles in order), with
    /// [`crate::transfer::bake_points`]: the set's entry `i` is receiver `i`, and
    /// a bounce reads the texel under the hit's UV
    /// ([`TexelAtlas::receiver_at_hit`]). `parallel` runs on rayon's pool with
    /// the `parallel` feature; the result is the same either way.
    ///
    /// Errors: those of [`crate::transfer::bake_points`].
    pub fn bake<C: RayCaster + Sync + ?Sized>(
        &self,
        mesh: &MeshView<'_>,
        normals: &[Vec3],
        caster: &C,
        options: &BakeOptions<'_>,
        parallel: bool,
    ) -> Result<TransferSet, BakeError> {
        let points: Vec<BakePoint> = self.receivers().iter().map(BakePoint::from).collect();
        let lookup = |triangle: usize, u: f32, v: f32| self.receiver_at_hit(mesh, triangle, u, v);
        bake_points(
            mesh,
            normals,
            caster,
            &points,
            BounceReads::Points(&lookup),
            options,
            parallel,
        )
    }
}
