//! [`BvhScene`]: a compressed wide BVH (CWBVH, Ylitie et al. 2017) over a mesh,
//! built with obvhs's PLOC builder, answering [`RayCaster`] queries with the same
//! watertight triangle test as the brute-force reference.
//!
//! Triangles are copied into BVH leaf order at build time so a leaf's triangles are
//! contiguous in memory; each keeps its original index for hits.

use alloc::collections::TryReserveError;
use alloc::vec::Vec;
use core::time::Duration;

use glam::{Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris},
    ray::{Ray as ObvhsRay, RayHit},
    triangle::Triangle,
};

use super::{Hit, PreparedRay, Ray, RayCaster};
use crate::geom::MeshView;

/// A bounding volume hierarchy over a copy of a mesh's triangles.
///
/// Built once, queried many times; queries take `&self` and are safe from many
/// threads at once.
#[derive(Clone, Debug)]
pub struct BvhScene {
    bvh: CwBvh,
    /// Triangle corners in BVH primitive order.
    corners: Vec<[Vec3; 3]>,
    /// Original triangle index of each entry of `corners`.
    original: Vec<u32>,
}

impl BvhScene {
    /// Builds the hierarchy over every triangle of `mesh` (which may be empty).
    ///
    /// Aborts like any Rust allocation if memory runs out; [`BvhScene::try_new`]
    /// reports that instead.
    pub fn new(mesh: &MeshView<'_>) -> Self {
        match Self::try_new(mesh) {
            Ok(scene) => scene,
            Err(_) => alloc::alloc::handle_alloc_error(core::alloc::Layout::new::<[Vec3; 3]>()),
        }
    }

    /// Builds the hierarchy, reporting failure to reserve the per-triangle arrays
    /// (the bulk of the scene's memory) instead of aborting. The builder's own
    /// temporary allocations, of the same order, are not covered.
    pub fn try_new(mesh: &MeshView<'_>) -> Result<Self, TryReserveError> {
        let count = mesh.triangle_count();
        let mut triangles: Vec<Triangle> = Vec::new();
        let mut corners: Vec<[Vec3; 3]> = Vec::new();
        triangles.try_reserve_exact(count)?;
        corners.try_reserve_exact(count)?;
        if count == 0 {
            return Ok(BvhScene {
                bvh: CwBvh::default(),
                corners,
                original: Vec::new(),
            });
        }
        triangles.extend(mesh.triangles().map(|[a, b, c]| Triangle {
            v0: a.into(),
            v1: b.into(),
            v2: c.into(),
        }));
        let mut build_time = Duration::ZERO;
        let bvh =
            build_cwbvh_from_tris(&triangles, BvhBuildParams::medium_build(), &mut build_time);
        drop(triangles);
        let original = bvh.primitive_indices.clone();
        corners.extend(original.iter().map(|&t| mesh.triangle(t as usize)));
        Ok(BvhScene {
            bvh,
            corners,
            original,
        })
    }

    /// Number of triangles in the scene.
    pub fn triangle_count(&self) -> usize {
        self.corners.len()
    }

    fn obvhs_ray(ray: &Ray) -> ObvhsRay {
        // The node test only culls; clamping t_min to 0 keeps its interval valid for
        // negative t_min while the triangle test still applies the exact interval.
        ObvhsRay::new(
            Vec3A::from(ray.origin),
            Vec3A::from(ray.direction),
            ray.t_min.max(0.0),
            ray.t_max,
        )
    }
}

impl RayCaster for BvhScene {
    fn occluded(&self, ray: &Ray) -> bool {
        if self.corners.is_empty() {
            return false;
        }
        let Some(prepared) = PreparedRay::new(ray) else {
            return false;
        };
        !self
            .bvh
            .ray_traverse_miss(Self::obvhs_ray(ray), |_, primitive| {
                let [a, b, c] = self.corners[primitive];
                match prepared.intersect(a, b, c) {
                    Some(hit) => hit.t,
                    None => f32::INFINITY,
                }
            })
    }

    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        if self.corners.is_empty() {
            return None;
        }
        let mut prepared = PreparedRay::new(ray)?;
        let mut best: Option<Hit> = None;
        let mut record = RayHit::none();
        self.bvh
            .ray_traverse(Self::obvhs_ray(ray), &mut record, |_, primitive| {
                let [a, b, c] = self.corners[primitive];
                match prepared.intersect(a, b, c) {
                    Some(hit) => {
                        prepared.set_t_max(hit.t);
                        best = Some(Hit {
                            t: hit.t,
                            triangle: self.original[primitive],
                            u: hit.u,
                            v: hit.v,
                        });
                        hit.t
                    }
                    None => f32::INFINITY,
                }
            });
        best
    }
}
