//! Baking a lightmap: the atlas's receivers as the bake's points, each bounce
//! reading the previous pass of the texel under its hit's UV. The set carries
//! the receivers' texels ([`crate::transfer::AtlasTexels`]), so a bake file
//! of it is a lightmap on its own.

use alloc::vec::Vec;
use core::ops::Range;

use glam::Vec3;

use super::{TexelAtlas, TexelReceiver};
use crate::geom::MeshView;
use crate::raycast::RayCaster;
use crate::transfer::{
    BakeError, BakeOptions, BakePoint, BounceReads, TransferSet, bake_point_range,
};

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
    /// [`crate::transfer::bake_points`]: the set's entry `i` is receiver `i`,
    /// it carries the receivers' texels ([`TransferSet::texels`]), and a bounce
    /// reads the texel under the hit's UV ([`TexelAtlas::receiver_at_hit`]).
    /// `parallel` runs on rayon's pool with the `parallel` feature; the result
    /// is the same either way.
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
        self.bake_receivers(mesh, 0..self.receivers.len(), |points, reads| {
            crate::transfer::bake_points(mesh, normals, caster, points, reads, options, parallel)
        })
    }

    /// The part of [`Self::bake`] that holds `receivers` (a range of them, as
    /// `antumbra bake --texels --shard` splits a lightmap across machines):
    /// each value bit for bit the whole bake's, with bounces still reading
    /// every receiver's previous pass, so the parts of consecutive ranges
    /// joined by [`TransferSet::concat`] are the whole bake, texels included.
    ///
    /// Errors: those of [`crate::transfer::bake_point_range`].
    pub fn bake_part<C: RayCaster + Sync + ?Sized>(
        &self,
        mesh: &MeshView<'_>,
        normals: &[Vec3],
        caster: &C,
        options: &BakeOptions<'_>,
        receivers: Range<usize>,
    ) -> Result<TransferSet, BakeError> {
        self.bake_receivers(mesh, receivers.clone(), |points, reads| {
            bake_point_range(mesh, normals, caster, points, reads, options, receivers)
        })
    }

    /// Runs `bake` on every receiver as a point, its bounces reading the
    /// texel under each hit's UV, and gives the set (entries for `receivers`)
    /// their texels.
    fn bake_receivers(
        &self,
        mesh: &MeshView<'_>,
        receivers: Range<usize>,
        bake: impl FnOnce(&[BakePoint], BounceReads<'_>) -> Result<TransferSet, BakeError>,
    ) -> Result<TransferSet, BakeError> {
        let points: Vec<BakePoint> = self.receivers.iter().map(BakePoint::from).collect();
        let lookup = |triangle: usize, u: f32, v: f32| self.receiver_at_hit(mesh, triangle, u, v);
        let set = bake(&points, BounceReads::Points(&lookup))?;
        Ok(self.with_texels(set, receivers))
    }

    /// `set` (entries for `receivers`) with those receivers' texels.
    fn with_texels(&self, set: TransferSet, receivers: Range<usize>) -> TransferSet {
        let width = self.width;
        let texels = self.receivers[receivers]
            .iter()
            .map(|r| r.texel_index(width))
            .collect();
        set.with_texels(width, self.height, texels)
            .expect("an atlas's receivers are one per texel, in texel order")
    }
}
