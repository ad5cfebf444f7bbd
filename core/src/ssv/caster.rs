//! The reference ray's caster: the owned BVH (with `bvh`) or a brute-force
//! loop over the occluders.

use super::*;

/// The reference caster: the owned BVH (with `bvh`) or a brute-force loop.
pub(super) enum Caster {
    #[cfg(feature = "bvh")]
    Bvh(crate::raycast::BvhScene),
    #[cfg(not(feature = "bvh"))]
    Brute(Vec<[Vec3; 3]>),
}

impl Caster {
    /// A caster over no triangles (a placeholder while the one it replaces
    /// moves to its new owner).
    #[cfg(feature = "bvh")]
    fn empty() -> Caster {
        Caster::Bvh(crate::raycast::BvhScene::empty())
    }

    /// The caster for `graph`, made from this one: with `bvh`, when it holds
    /// as many triangles, refitted to the graph's positions (the hierarchy
    /// kept, about ten times cheaper than a build, the same answers) and moved
    /// out, leaving an empty caster; otherwise built anew, this one untouched.
    /// On failure this one is untouched.
    pub(super) fn refitted(&mut self, graph: &EdgeGraph) -> Result<Caster, SsvError> {
        #[cfg(feature = "bvh")]
        if let Caster::Bvh(scene) = self
            && scene.triangle_count() == graph.triangles.len()
        {
            let mesh = graph_view(graph)?;
            scene.refit(&mesh).map_err(|_| SsvError::Caster)?;
            return Ok(core::mem::replace(self, Caster::empty()));
        }
        SoftShadows::build_caster(graph)
    }

    /// A triangle the ray hits in its interval (the first found, not
    /// necessarily the nearest), by index, or `None`.
    pub(super) fn occluding_triangle(&self, ray: &Ray) -> Option<usize> {
        match self {
            #[cfg(feature = "bvh")]
            Caster::Bvh(scene) => scene.occluding_triangle(ray).map(|t| t as usize),
            #[cfg(not(feature = "bvh"))]
            Caster::Brute(tris) => {
                let prepared = crate::raycast::PreparedRay::new(ray)?;
                tris.iter()
                    .position(|&[a, b, c]| prepared.intersect(a, b, c).is_some())
            }
        }
    }

    /// The nearest hit in the ray's interval: `(t, triangle index)`.
    pub(super) fn closest_hit(&self, ray: &Ray) -> Option<(f32, usize)> {
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

impl SoftShadows {
    pub(super) fn build_caster(graph: &EdgeGraph) -> Result<Caster, SsvError> {
        #[cfg(feature = "bvh")]
        {
            let mesh = graph_view(graph)?;
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
}

/// The welded graph's positions and triangles as a mesh, for the BVH: a view
/// of the graph's own arrays, nothing copied.
#[cfg(feature = "bvh")]
fn graph_view(graph: &EdgeGraph) -> Result<MeshView<'_>, SsvError> {
    let positions: &[[f32; 3]] = bytemuck::cast_slice(&graph.positions);
    let indices: &[u32] = bytemuck::cast_slice(&graph.triangles);
    MeshView::new(positions, indices).map_err(|_| SsvError::Caster)
}
