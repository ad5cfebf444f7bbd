//! The far field in several levels: a chain of far meshes whose clustering cubes
//! double in edge from level to level, each used beyond a radius that doubles
//! with it, so a receiver rasterizes about the same number of far triangles per
//! level and the count grows with the logarithm of the mesh's extent instead of
//! its area (Kautz, Lehtinen and Aila 2004 use one far level; more levels are
//! the usual continuation of their scheme).
//!
//! Level `k` clusters the full mesh with cubes of edge `c·2^k` on one grid
//! origin, so its cubes are unions of level `k - 1`'s: each level is a
//! clustering of the one below, and every far vertex is the mean of the full
//! vertices in its cube, recomputed from the full mesh's current positions by
//! [`FarField::pose`]. Level `k` stands in for the finer ones beyond
//! `NEAR_CELLS · c·2^k` ([`FarMesh::NEAR_CELLS`], the two-level scene's rule):
//! the surface's error (about a cube edge) stays about a third of the distance
//! at every level, which is what bounds the error of the shading, and each
//! level's band of radii covers about the same number of its triangles.
//!
//! What it trades: with the finest level's cubes of edge `c`, a receiver
//! rasterizes the full mesh within `3c`, then about the same number of
//! triangles per level, so its work no longer grows with the mesh's area;
//! on scanned meshes of 15k–89k triangles about 300–650 rasterized triangles
//! per receiver instead of 900–5,200 with one far mesh of the same first level
//! (`antumbra bench hemi --mesh FILE`, far mesh table). The price is error:
//! vertex clustering closes holes and drops parts thinner than a cube, and the
//! coarse levels' cubes are large, so the irradiance error against traced rays
//! grows with the first two or three levels (on those meshes from 0.2–1.2 %
//! with one level to 0.9–1.9 % with three) and little after. Three levels
//! hold most of the gain.

use alloc::vec::Vec;

use super::clusters::{ClusteredMesh, TriangleClusters};
use super::far_mesh::{FarMesh, FarMeshError};
use super::lod::{FarLevel, HemiScene};
use crate::geom::MeshView;

/// The most levels a far field has: the coarsest's cubes are then 128 times
/// the finest's, as coarse as any mesh needs.
pub const MAX_FAR_LEVELS: usize = 8;

/// Levels with fewer triangles than this are not built: a mesh that coarse
/// stands in for nothing.
const MIN_LEVEL_TRIANGLES: usize = 8;

/// One level: its far mesh and the clusters of its triangles.
#[derive(Clone, Debug)]
struct Level {
    mesh: FarMesh,
    clusters: TriangleClusters,
}

/// Far meshes of a deforming mesh in several levels (see the module docs).
#[derive(Clone, Debug)]
pub struct FarField {
    levels: Vec<Level>,
    /// The finest level's near radius; level `k`'s is `2^k` times it.
    near_radius: f32,
}

/// One frame's far levels, ready for a [`HemiScene`]: on the stack.
#[derive(Clone, Copy, Debug)]
pub struct FarLevels<'a> {
    /// The first `count` are the levels, fine to coarse; the rest repeat the
    /// first and are unused.
    levels: [FarLevel<'a>; MAX_FAR_LEVELS],
    count: usize,
}

impl FarField {
    /// The far field of `mesh` (in its rest pose): the finest level of about
    /// `triangles` triangles (the cube edge searched as
    /// [`FarMesh::with_triangles`] does), then up to `levels - 1` coarser ones,
    /// each with cubes of twice the edge; levels that would have fewer than 8
    /// triangles are left out. `levels` is clamped to `1..=`[`MAX_FAR_LEVELS`].
    pub fn new(mesh: &MeshView<'_>, triangles: usize, levels: usize) -> Result<Self, FarMeshError> {
        let finest = FarMesh::with_triangles(mesh, triangles)?;
        let mut cell = finest.cell_size();
        let mut built = Vec::new();
        built.push(Level::new(finest));
        while built.len() < levels.clamp(1, MAX_FAR_LEVELS) {
            cell *= 2.0;
            match FarMesh::with_cell_size(mesh, cell) {
                Ok(far) if far.triangle_count() >= MIN_LEVEL_TRIANGLES => {
                    built.push(Level::new(far))
                }
                Ok(_) | Err(FarMeshError::Empty) => break,
                Err(e) => return Err(e),
            }
        }
        let near_radius = built[0].mesh.default_near_radius();
        Ok(FarField {
            levels: built,
            near_radius,
        })
    }

    /// Sets the finest level's near radius (mesh units, finite and at least
    /// [`FarField::min_near_radius`]; the default is [`FarMesh::NEAR_CELLS`]
    /// of its cube edges); level `k`'s is `2^k` times it, so every level keeps
    /// the same ratio of cube edge to distance. A smaller or non-finite radius
    /// is refused ([`FarMeshError::NearRadius`]) and the radius kept.
    pub fn set_near_radius(&mut self, radius: f32) -> Result<(), FarMeshError> {
        let minimum = self.min_near_radius();
        // Written so that NaN is refused too.
        if !(radius.is_finite() && radius >= minimum) {
            return Err(FarMeshError::NearRadius { radius, minimum });
        }
        self.near_radius = radius;
        Ok(())
    }

    /// The least near radius [`FarField::set_near_radius`] accepts:
    /// [`FarMesh::MIN_NEAR_CELLS`] edges of the finest level's cubes.
    pub fn min_near_radius(&self) -> f32 {
        FarMesh::MIN_NEAR_CELLS * self.levels[0].mesh.cell_size()
    }

    /// The number of levels.
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// The far mesh of level `k` (0 the finest), in the last pose.
    pub fn level(&self, k: usize) -> &FarMesh {
        &self.levels[k].mesh
    }

    /// The radius beyond which level `k` stands in for the finer ones.
    pub fn near_radius(&self, k: usize) -> f32 {
        self.near_radius * libm::exp2f(k as f32)
    }

    /// Triangles over all levels.
    pub fn triangle_count(&self) -> usize {
        self.levels.iter().map(|l| l.mesh.triangle_count()).sum()
    }

    /// Bytes held by the levels' meshes and clusters.
    pub fn heap_bytes(&self) -> usize {
        self.levels.iter().map(|l| l.mesh.heap_bytes()).sum()
    }

    /// Moves every level to the full mesh's current positions (`mesh`, the vertex
    /// count it was made from) and recomputes the levels' cluster boxes; returns
    /// the levels for this frame's scene ([`FarLevels::scene`]). Allocates
    /// nothing.
    pub fn pose<'a>(&'a mut self, mesh: &MeshView<'_>) -> Result<FarLevels<'a>, FarMeshError> {
        let mut levels: [Option<FarLevel<'a>>; MAX_FAR_LEVELS] = [None; MAX_FAR_LEVELS];
        let count = self.levels.len();
        let mut radius = self.near_radius;
        for (slot, level) in levels.iter_mut().zip(self.levels.iter_mut()) {
            level.mesh.pose(mesh)?;
            let view = level.mesh.view();
            *slot = Some(FarLevel {
                mesh: level.clusters.update(view),
                near_radius: radius,
            });
            radius *= 2.0;
        }
        let first = levels[0].expect("a far field has at least one level");
        Ok(FarLevels {
            levels: levels.map(|level| level.unwrap_or(first)),
            count,
        })
    }
}

impl FarField {
    /// [`FarField::pose`], then each level's triangles grouped again for the
    /// new positions ([`TriangleClusters::reorder`]): for a mesh that has
    /// moved far from the pose the clusters were grouped in, where their
    /// boxes have grown loose.
    pub fn regroup(&mut self, mesh: &MeshView<'_>) -> Result<(), FarMeshError> {
        for level in &mut self.levels {
            level.mesh.pose(mesh)?;
            level.clusters.reorder(&level.mesh.view());
        }
        Ok(())
    }
}

impl Level {
    fn new(mesh: FarMesh) -> Self {
        let clusters = TriangleClusters::new(&mesh.view(), TriangleClusters::DEFAULT_SIZE);
        Level { mesh, clusters }
    }
}

impl<'a> FarLevels<'a> {
    /// The scene of the full mesh `mesh` near the receivers and these levels
    /// beyond it.
    pub fn scene<'s>(&'s self, mesh: ClusteredMesh<'s>) -> HemiScene<'s> {
        let first = self.levels[0];
        HemiScene {
            mesh,
            far: Some(first.mesh),
            near_radius: first.near_radius,
            coarser: &self.levels[1..self.count],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_meshes::{bumpy_sphere, normals_of};
    use super::*;
    use crate::hemi::{BatchOptions, scene_mask, vertex_normals};
    use alloc::vec;
    use glam::Vec3;

    #[test]
    fn levels_double_their_cubes_and_radii() {
        let (positions, indices) = bumpy_sphere(48, 64, 0.2, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut field = FarField::new(&mesh, 1200, 4).unwrap();
        assert_eq!(field.level_count(), 4);
        let finest = FarMesh::with_triangles(&mesh, 1200).unwrap();
        assert_eq!(field.level(0).indices(), finest.indices());
        let mut triangles = usize::MAX;
        for k in 0..field.level_count() {
            let cell = finest.cell_size() * libm::exp2f(k as f32);
            assert_eq!(field.level(k).cell_size(), cell);
            assert_eq!(field.near_radius(k), FarMesh::NEAR_CELLS * cell);
            // Coarser levels have fewer triangles.
            assert!(field.level(k).triangle_count() < triangles);
            triangles = field.level(k).triangle_count();
        }
        field.set_near_radius(0.5).unwrap();
        let levels = field.pose(&mesh).unwrap();
        let scene = levels.scene(crate::hemi::ClusteredMesh::unclustered(mesh));
        assert_eq!(scene.near_radius, 0.5);
        let radii: Vec<f32> = scene.coarser.iter().map(|l| l.near_radius).collect();
        assert_eq!(radii, [1.0, 2.0, 4.0]);
    }

    /// A bumpy sphere of radius about 1 standing on a flat ground (`z = 0`,
    /// facing up) of polar rings growing outwards to 40 radii, as a scene's
    /// ground is tessellated; returns the mesh and the first ground vertex.
    fn sphere_on_ground() -> (Vec<[f32; 3]>, Vec<u32>, usize) {
        let (mut positions, mut indices) = bumpy_sphere(24, 32, 0.15, 0.0);
        for p in &mut positions {
            p[2] += 1.25;
        }
        let first = positions.len();
        const SEGMENTS: u32 = 24;
        positions.push([0.0, 0.0, 0.0]);
        let mut radius = 0.3f32;
        let mut rings = 0u32;
        while radius < 40.0 {
            for s in 0..SEGMENTS {
                let angle = core::f32::consts::TAU * s as f32 / SEGMENTS as f32;
                positions.push([radius * libm::cosf(angle), radius * libm::sinf(angle), 0.0]);
            }
            radius *= 1.3;
            rings += 1;
        }
        let ring = |r: u32, s: u32| first as u32 + 1 + r * SEGMENTS + s % SEGMENTS;
        for s in 0..SEGMENTS {
            indices.extend([first as u32, ring(0, s), ring(0, s + 1)]);
            for r in 0..rings - 1 {
                let (a, b) = (ring(r, s), ring(r, s + 1));
                let (c, d) = (ring(r + 1, s), ring(r + 1, s + 1));
                indices.extend([a, c, d, a, d, b]);
            }
        }
        (positions, indices, first)
    }

    #[test]
    fn a_near_radius_below_a_cube_diagonal_is_refused() {
        let (positions, indices, _) = sphere_on_ground();
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut field = FarField::new(&mesh, 600, MAX_FAR_LEVELS).unwrap();
        let minimum = field.min_near_radius();
        assert_eq!(
            minimum,
            FarMesh::MIN_NEAR_CELLS * field.level(0).cell_size()
        );
        let default = field.near_radius(0);
        for radius in [0.99 * minimum, 0.0, -1.0, f32::NAN, f32::INFINITY] {
            let refused = field.set_near_radius(radius);
            assert!(
                matches!(refused, Err(FarMeshError::NearRadius { minimum: m, .. }) if m == minimum),
                "{radius}: {refused:?}"
            );
            assert_eq!(
                field.near_radius(0),
                default,
                "a refused radius is not kept"
            );
        }
        field.set_near_radius(minimum).unwrap();
        assert_eq!(field.near_radius(0), minimum);
    }

    /// The hazard the minimum radius keeps out: from a radius under a cube
    /// edge, coarse triangles joining the sphere's cubes to the ground's pass
    /// over ground receivers, which then see far more of their sky covered
    /// than the full mesh covers; from the minimum on, none does.
    #[test]
    fn coarse_levels_do_not_pass_over_ground_receivers() {
        let (positions, indices, first_ground) = sphere_on_ground();
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        let mut field = FarField::new(&mesh, 600, MAX_FAR_LEVELS).unwrap();
        let minimum = field.min_near_radius();
        field.set_near_radius(minimum).unwrap();
        let options = BatchOptions {
            normal_offset: 1e-3,
            ..BatchOptions::default()
        };
        let levels = field.pose(&mesh).unwrap();
        let exact = HemiScene::new(ClusteredMesh::unclustered(mesh));
        let at_minimum = levels.scene(ClusteredMesh::unclustered(mesh));
        // The same levels, every radius a third of a cube edge.
        let mut small: Vec<FarLevel<'_>> = at_minimum.coarser.to_vec();
        for level in &mut small {
            level.near_radius /= 3.0 * FarMesh::MIN_NEAR_CELLS;
        }
        let below = HemiScene {
            near_radius: at_minimum.near_radius / (3.0 * FarMesh::MIN_NEAR_CELLS),
            coarser: &small,
            ..at_minimum
        };
        // Receivers whose far-field mask covers more than twice the full
        // mesh's cells and 40 more (a tenth of the lowest ring of cells).
        let over_covered = |scene: &HemiScene<'_>| {
            (first_ground..mesh.vertex_count())
                .filter(|&v| {
                    let p = mesh.position(v);
                    let far = scene_mask(scene, p, normals[v], &options).count_occluded();
                    let full = scene_mask(&exact, p, normals[v], &options).count_occluded();
                    far > 2 * full + 40
                })
                .count()
        };
        let (fine, coarse) = (over_covered(&at_minimum), over_covered(&below));
        assert_eq!(fine, 0);
        assert!(coarse > 0, "the hazard is not reproduced");
    }

    #[test]
    fn too_coarse_levels_are_left_out() {
        let (positions, indices) = bumpy_sphere(48, 64, 0.2, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        // Cubes 128 times those of a 200-triangle mesh hold the whole sphere.
        let field = FarField::new(&mesh, 200, MAX_FAR_LEVELS + 3).unwrap();
        assert!(field.level_count() < MAX_FAR_LEVELS);
        for k in 0..field.level_count() {
            assert!(field.level(k).triangle_count() >= MIN_LEVEL_TRIANGLES);
        }
        assert!(FarField::new(&mesh, 0, 3).is_err());
    }

    #[test]
    fn one_level_is_the_two_level_scene_and_every_level_follows_the_pose() {
        let (rest, indices) = bumpy_sphere(48, 64, 0.2, 0.0);
        let rest_mesh = MeshView::new(&rest, &indices).unwrap();
        let mut field = FarField::new(&rest_mesh, 1500, 1).unwrap();
        let mut deep = FarField::new(&rest_mesh, 1500, 3).unwrap();
        let mut far = FarMesh::with_triangles(&rest_mesh, 1500).unwrap();
        let mut far_clusters = TriangleClusters::new(&far.view(), TriangleClusters::DEFAULT_SIZE);
        let options = BatchOptions {
            normal_offset: 1e-3,
            ..BatchOptions::default()
        };
        for twist in [0.0f32, 1.2] {
            let (positions, _) = bumpy_sphere(48, 64, 0.2, twist);
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let mut normals = vec![Vec3::ZERO; mesh.vertex_count()];
            vertex_normals(&mesh, &mut normals).unwrap();
            far.pose(&mesh).unwrap();
            let two_level = HemiScene::with_far(
                ClusteredMesh::unclustered(mesh),
                far_clusters.update(far.view()),
                far.default_near_radius(),
            );
            let levels = field.pose(&mesh).unwrap();
            let one = levels.scene(ClusteredMesh::unclustered(mesh));
            for v in (0..mesh.vertex_count()).step_by(37) {
                let (p, n) = (mesh.position(v), normals[v]);
                assert_eq!(
                    scene_mask(&one, p, n, &options),
                    scene_mask(&two_level, p, n, &options)
                );
            }
            let _ = deep.pose(&mesh).unwrap();
            for k in 0..deep.level_count() {
                let level = deep.level(k);
                for (f, position) in level.positions().iter().enumerate() {
                    let members = level.members(f);
                    let mean = members
                        .iter()
                        .fold(Vec3::ZERO, |sum, &m| sum + mesh.position(m as usize))
                        / members.len() as f32;
                    assert!((Vec3::from(*position) - mean).length() < 1e-5);
                }
            }
        }
    }
}
