//! Deforming meshes: per frame, every vertex of a mesh is a receiver shadowed by
//! the mesh itself, with an optional simplified far mesh for distant occluders
//! (Kautz, Lehtinen and Aila 2004, the two-level LOD; Lehtinen's thesis §3.3). No
//! precomputation depends on the animation: the caller hands in the current
//! positions (skinned, simulated) every frame, the normals (or computes them with
//! [`vertex_normals`](super::vertex_normals)), and gets transfer vectors
//! ([`transfer_batch`](super::transfer_batch)) or shaded RGB
//! ([`shade_batch`](super::shade_batch)) per vertex in its own slices (the
//! `batch` module); this module is the loop that makes each receiver's mask
//! ([`scene_mask`]) from the scene's meshes and their clusters.
//!
//! The near/far rule, per receiver at vertex position `p` (the vertex itself, not
//! the lifted center of projection) and radius `near_radius`:
//!
//! - a triangle of the full mesh is rasterized when at least one of its corners is
//!   within the radius, `|c - p|² <= near_radius²`;
//! - a triangle of the far mesh is rasterized when all its corners are beyond it,
//!   `|c - p|² > near_radius²`, so the coarse surface never shadows the fine one
//!   near the receiver.
//!
//! Triangles straddling the radius come from the full mesh only, so choose a radius
//! of several far-mesh edge lengths: a far triangle is excluded as soon as one corner
//! is near, which leaves a thin gap in the far surface around the radius, and a
//! full triangle with one near corner may overlap the far surface it stands in for.
//! Without a far mesh every full-mesh triangle is rasterized and the radius is
//! unused.
//!
//! With coarser levels ([`HemiScene::coarser`], made by
//! [`FarField`](super::FarField)) the rule repeats outwards: each far level's
//! triangle is rasterized when all its corners are beyond that level's radius
//! and at least one is within the next level's (the coarsest has no outer
//! bound), so every distance band has exactly one level.
//!
//! The loop: per receiver, each mesh of the scene in turn (the full mesh,
//! then each far level with its band of radii) is walked cluster by cluster
//! through its hierarchy of boxes (the `walk` module), and the triangles of
//! each cluster taken are culled and rasterized chunk by chunk (the `chunk`
//! module). The masks are identical to the unclustered loop's, bit for bit.
//!
//! The far mesh (the bunny by vertex clustering on a 12³ grid, 902 triangles;
//! near radius a tenth of the diagonal) changes the bunny's transfer vectors by
//! 0.65 % on average (p90 2 %, max 7.5 %; `tests/tests/hemi_lod.rs`). Whole-frame
//! rates (every vertex, diffuse + glossy, with and without the far mesh) are
//! printed by `antumbra bench hemi`.
//!
//! Invariants: everything per receiver is on the stack; the batch functions
//! allocate nothing; they are safe to call from many threads at once (the scene is
//! only read); the `parallel` feature spreads vertices over rayon's pool with
//! identical results.

use glam::Vec3;

use super::chunk::{Projected, rasterize_mesh_batched};
use super::clusters::ClusteredMesh;
use super::cone_mask::{ConeMask, ExactCones, TableCones};
use super::mask::HemiMask;
use super::walk::{Walk, mesh_loop};
use super::{Accumulator, Quality, Receiver, TriangleCounts};

/// One frame of a deforming mesh as the receivers see it: the full mesh (whose
/// vertices are the receivers), optional simplified far meshes with their own
/// current positions, and the radii between them (see the module docs for the
/// rule).
#[derive(Clone, Copy, Debug)]
pub struct HemiScene<'a> {
    /// The full-resolution mesh.
    pub mesh: ClusteredMesh<'a>,
    /// The simplified mesh for distant occluders, if any.
    pub far: Option<ClusteredMesh<'a>>,
    /// Distance from a receiver's vertex within which occluders come from the full
    /// mesh (mesh units, `>= 0`; `+inf` uses the full mesh everywhere). Unused
    /// without a far mesh.
    pub near_radius: f32,
    /// Coarser far meshes beyond `far`, from fine to coarse, each used beyond
    /// its own radius, which must grow from level to level and exceed
    /// `near_radius` (a [`FarField`](super::FarField) makes them). Empty for the
    /// two-level scene; unused without `far`.
    pub coarser: &'a [FarLevel<'a>],
}

/// A far mesh of a multi-level scene and the distance beyond which it stands in
/// for the finer levels (see [`HemiScene::coarser`]).
#[derive(Clone, Copy, Debug)]
pub struct FarLevel<'a> {
    /// The simplified mesh with its current positions.
    pub mesh: ClusteredMesh<'a>,
    /// Distance from a receiver's vertex within which the finer levels are used:
    /// a triangle of this level is rasterized when all its corners are beyond
    /// it (and, unless this is the coarsest level, at least one corner is within
    /// the next level's radius).
    pub near_radius: f32,
}

impl<'a> HemiScene<'a> {
    /// The full mesh alone, every triangle an occluder.
    #[inline]
    pub fn new(mesh: ClusteredMesh<'a>) -> Self {
        HemiScene {
            mesh,
            far: None,
            near_radius: f32::INFINITY,
            coarser: &[],
        }
    }

    /// The full mesh near the receivers and `far` beyond `near_radius`.
    #[inline]
    pub fn with_far(mesh: ClusteredMesh<'a>, far: ClusteredMesh<'a>, near_radius: f32) -> Self {
        HemiScene {
            mesh,
            far: Some(far),
            near_radius,
            coarser: &[],
        }
    }
}

/// Rasterization options of the batch functions.
#[derive(Clone, Copy, Debug)]
pub struct BatchOptions<'a> {
    /// Exact or table half-space masks.
    pub quality: Quality<'a>,
    /// Skip back-facing triangles (closed, consistently wound meshes only; see
    /// [`Culled::BackFacing`](super::Culled::BackFacing)).
    pub cull_backfaces: bool,
    /// Center of projection `p + normal_offset * n` (see
    /// [`RasterOptions::normal_offset`](super::RasterOptions::normal_offset)).
    pub normal_offset: f32,
    /// Spread the vertices of the batch functions ([`transfer_batch`](super::transfer_batch)
    /// and the `shade_batch*` ones) over rayon's pool. Results are identical
    /// either way. Only the `parallel` feature has a pool; without it the flag
    /// is ignored.
    pub parallel: bool,
}

impl Default for BatchOptions<'_> {
    /// Exact quality, no culling, no offset; on the pool when the `parallel`
    /// feature is on.
    fn default() -> Self {
        BatchOptions {
            quality: Quality::Exact,
            cull_backfaces: false,
            normal_offset: 0.0,
            parallel: cfg!(feature = "parallel"),
        }
    }
}

/// Which triangles of a mesh a receiver takes, by distance (the radii are the
/// pass's).
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Select {
    /// Every triangle.
    All,
    /// Triangles with a corner within the outer radius.
    Near,
    /// Triangles with every corner beyond the inner radius.
    Far,
    /// Triangles with every corner beyond the inner radius and a corner within
    /// the outer one: a far level between two others.
    Band,
}

impl Select {
    /// Whether a triangle is taken, from whether any corner is within the
    /// inner radius, and any within the outer one.
    #[inline(always)]
    pub(super) fn takes(self, any_inner: bool, any_outer: bool) -> bool {
        match self {
            Select::All => true,
            Select::Near => any_outer,
            Select::Far => !any_inner,
            Select::Band => !any_inner & any_outer,
        }
    }
}

/// The mask of the receiver at vertex position `position` with unit `normal`
/// against `scene` (near/far rule of the module docs). Allocation-free.
pub fn scene_mask(
    scene: &HemiScene<'_>,
    position: Vec3,
    normal: Vec3,
    options: &BatchOptions<'_>,
) -> HemiMask {
    scene_mask_with_counts(scene, position, normal, options).0
}

/// [`scene_mask`], also counting the triangles rasterized and culled (triangles of
/// skipped clusters are not counted; the far-mesh ones excluded by distance count
/// as `skipped`).
pub fn scene_mask_with_counts(
    scene: &HemiScene<'_>,
    position: Vec3,
    normal: Vec3,
    options: &BatchOptions<'_>,
) -> (HemiMask, TriangleCounts) {
    // SAFETY: the widest build is one the processor runs.
    #[allow(unsafe_code)]
    unsafe {
        traverse_in(
            crate::simd::widest_build(),
            scene,
            position,
            normal,
            options,
        )
    }
}

crate::simd::in_builds! {
    /// [`traverse`], skipping hidden boxes, as compiled for `build`: the
    /// same bits and counts in every build.
    fn traverse_in(
        scene: &HemiScene<'_>,
        position: Vec3,
        normal: Vec3,
        options: &BatchOptions<'_>,
    ) -> (HemiMask, TriangleCounts) {
        traverse(scene, position, normal, options, true)
    }
}

/// [`scene_mask_with_counts`], with the skipping of boxes whose cells are all
/// covered (exact quality only, see [`ConeMask::EXACT`]) as a switch
/// (`skip_hidden`), so tests can compare the counts of everything else with
/// the unclustered loop's.
#[inline(always)]
pub(super) fn traverse(
    scene: &HemiScene<'_>,
    position: Vec3,
    normal: Vec3,
    options: &BatchOptions<'_>,
    skip_hidden: bool,
) -> (HemiMask, TriangleCounts) {
    let receiver = Receiver::new(position, normal, options.normal_offset);
    let cull = options.cull_backfaces;
    if scene.far.is_none() && !scene.mesh.is_clustered() {
        // One mesh without clusters: the plain rasterizer's batched loop (the
        // same expressions, so the same bits and counts).
        return rasterize_mesh_batched(&scene.mesh.mesh, &receiver, &[], cull, options.quality);
    }
    // One loop per quality so the per-triangle work is monomorphic.
    match options.quality {
        Quality::Exact => scene_loop(scene, &receiver, position, cull, skip_hidden, ExactCones),
        Quality::Table(table) => {
            let cones = TableCones(table);
            scene_loop(scene, &receiver, position, cull, skip_hidden, cones)
        }
    }
}

/// What every triangle of one receiver's pass is tested and rasterized with.
#[derive(Clone, Copy)]
pub(super) struct Pass<M> {
    /// The receiver's vertex position, for the near/far rule.
    pub(super) position: Vec3,
    /// The squared radius within which finer levels stand in for this mesh
    /// ([`Select::Far`] and [`Select::Band`]).
    pub(super) inner_r2: f32,
    /// The squared radius within which this mesh stands in for coarser levels
    /// ([`Select::Near`] and [`Select::Band`]).
    pub(super) outer_r2: f32,
    pub(super) cull: bool,
    /// Skip boxes whose reachable cells are all set ([`BoxCells`](super::box_cells::BoxCells)), and test
    /// the triangles of clusters that reach at most `CELL_PATH` (walk.rs) open cells
    /// on those cells alone. Exact quality only.
    pub(super) skip_hidden: bool,
    pub(super) cone_mask: M,
}

impl<M: ConeMask> Pass<M> {
    /// Whether `p` is within the inner and the outer radius.
    #[inline(always)]
    pub(super) fn within(&self, p: Vec3) -> (bool, bool) {
        let d2 = (p - self.position).length_squared();
        (d2 <= self.inner_r2, d2 <= self.outer_r2)
    }
}

#[inline(always)]
fn scene_loop<M: ConeMask>(
    scene: &HemiScene<'_>,
    receiver: &Receiver,
    position: Vec3,
    cull: bool,
    skip_hidden: bool,
    cone_mask: M,
) -> (HemiMask, TriangleCounts) {
    // One scale for every mesh (see Receiver::scaled_frame).
    let levels = match scene.far {
        Some(_) => scene.coarser,
        None => &[],
    };
    let far_bounds = scene.far.as_ref().map(|far| far.mesh.bounds());
    let bounds = core::iter::once(scene.mesh.mesh.bounds())
        .chain(far_bounds)
        .chain(levels.iter().map(|level| level.mesh.mesh.bounds()));
    let mut acc = Accumulator::new(receiver, bounds);
    let pass = |inner: f32, outer: f32| Pass {
        position,
        inner_r2: inner * inner,
        outer_r2: outer * outer,
        cull,
        skip_hidden: skip_hidden && M::EXACT,
        cone_mask,
    };
    let mut projected = Projected::EMPTY;
    let mut walk = Walk::EMPTY;
    let Some(far) = &scene.far else {
        let all = pass(f32::INFINITY, f32::INFINITY);
        mesh_loop(
            &scene.mesh,
            &mut acc,
            &all,
            Select::All,
            &mut projected,
            &mut walk,
        );
        return (acc.mask, acc.counts);
    };
    let near = pass(0.0, scene.near_radius);
    mesh_loop(
        &scene.mesh,
        &mut acc,
        &near,
        Select::Near,
        &mut projected,
        &mut walk,
    );
    // Each far level between its own radius and the next one's.
    let radii = core::iter::once(scene.near_radius).chain(levels.iter().map(|l| l.near_radius));
    let meshes = core::iter::once(far).chain(levels.iter().map(|l| &l.mesh));
    let mut outer = levels.iter().map(|l| l.near_radius);
    for (mesh, inner) in meshes.zip(radii) {
        match outer.next() {
            Some(outer) => {
                let band = pass(inner, outer);
                mesh_loop(
                    mesh,
                    &mut acc,
                    &band,
                    Select::Band,
                    &mut projected,
                    &mut walk,
                );
            }
            None => {
                let far = pass(inner, f32::INFINITY);
                mesh_loop(mesh, &mut acc, &far, Select::Far, &mut projected, &mut walk);
            }
        }
    }
    (acc.mask, acc.counts)
}

#[cfg(test)]
mod tests {
    use super::super::test_meshes::{bumpy_sphere, normals_of};
    use super::*;
    use crate::geom::MeshView;
    use crate::hemi::*;
    use alloc::vec::Vec;

    #[test]
    fn scene_without_far_mesh_is_rasterize_receiver() {
        let (positions, indices) = bumpy_sphere(16, 24, 0.25, 0.7);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        let table = HalfSpaceTable::new(32);
        let mut clusters = TriangleClusters::new(&mesh, 16);
        let clustered = clusters.update(mesh);
        for quality in [Quality::Exact, Quality::Table(&table)] {
            let options = BatchOptions {
                quality,
                normal_offset: 0.01,
                ..BatchOptions::default()
            };
            let raster = RasterOptions {
                quality,
                normal_offset: 0.01,
                ..RasterOptions::default()
            };
            for (v, &n) in normals.iter().enumerate() {
                let p = mesh.position(v);
                let expected = rasterize_receiver(&mesh, p, n, &raster);
                let plain = scene_mask(
                    &HemiScene::new(ClusteredMesh::unclustered(mesh)),
                    p,
                    n,
                    &options,
                );
                let fast = scene_mask(&HemiScene::new(clustered), p, n, &options);
                assert_eq!(plain, expected, "vertex {v}");
                assert_eq!(fast, expected, "vertex {v}");
            }
        }
    }

    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[test]
    fn the_wide_builds_are_the_portable_one() {
        wide_builds_are_the_portable_one((20, 32), (8, 12), 1, true);
    }

    /// [`the_wide_builds_are_the_portable_one`] small enough for Miri (`make
    /// miri` enables every feature of both builds).
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[test]
    fn miri_wide_builds_are_the_portable_one() {
        wide_builds_are_the_portable_one((4, 6), (3, 4), 5, false);
    }

    /// Compares the masks and counts of the wider builds of the receiver's
    /// loops that this processor runs (AVX2, AVX-512; see
    /// [`crate::simd::Build`]) and the dispatched one with the portable
    /// build's, on a twisted bumpy sphere of
    /// `(rings, segments)` (every `step`th vertex a receiver), alone,
    /// clustered, and with a far sphere; the exact quality, and the table's
    /// when `with_table`.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[allow(unsafe_code)]
    fn wide_builds_are_the_portable_one(
        (rings, segments): (u32, u32),
        (far_rings, far_segments): (u32, u32),
        step: usize,
        with_table: bool,
    ) {
        use super::super::chunk::{batched, batched_in, rasterize_mesh_batched};
        use crate::simd::Build;
        let widest = crate::simd::widest_build();
        if widest == Build::Portable {
            return;
        }
        let (positions, indices) = bumpy_sphere(rings, segments, 0.25, 0.8);
        let (far_positions, far_indices) = bumpy_sphere(far_rings, far_segments, 0.25, 0.8);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let far = MeshView::new(&far_positions, &far_indices).unwrap();
        let normals = normals_of(&mesh);
        let table = with_table.then(|| HalfSpaceTable::new(32));
        let mut clusters = TriangleClusters::new(&mesh, 8);
        let mut far_clusters = TriangleClusters::new(&far, 8);
        let (fast, fast_far) = (clusters.update(mesh), far_clusters.update(far));
        let scenes = [
            HemiScene::new(ClusteredMesh::unclustered(mesh)),
            HemiScene::new(fast),
            HemiScene::with_far(fast, fast_far, 0.4),
        ];
        let qualities = core::iter::once(Quality::Exact).chain(table.as_ref().map(Quality::Table));
        let (mut compared, mut occluded) = (0, 0);
        for quality in qualities {
            let options = BatchOptions {
                quality,
                normal_offset: 0.005,
                ..BatchOptions::default()
            };
            for scene in &scenes {
                for (v, &n) in normals.iter().enumerate().step_by(step) {
                    let p = mesh.position(v);
                    let receiver = Receiver::new(p, n, options.normal_offset);
                    let portable = traverse(scene, p, n, &options, true);
                    let unclustered = batched(&mesh, &receiver, &[], true, quality);
                    let wide = [Build::Avx2, Build::Avx512]
                        .into_iter()
                        .filter(|&b| b <= widest);
                    for build in wide {
                        // SAFETY: the processor runs every build up to the widest.
                        let (clustered, plain) = unsafe {
                            (
                                traverse_in(build, scene, p, n, &options),
                                batched_in(build, &mesh, &receiver, &[], true, quality),
                            )
                        };
                        assert_eq!(clustered, portable, "{build:?}, vertex {v}");
                        assert_eq!(plain, unclustered, "{build:?} unclustered, vertex {v}");
                    }
                    let dispatched = scene_mask_with_counts(scene, p, n, &options);
                    assert_eq!(dispatched, portable, "dispatched, vertex {v}");
                    let dispatched = rasterize_mesh_batched(&mesh, &receiver, &[], true, quality);
                    assert_eq!(
                        dispatched, unclustered,
                        "dispatched unclustered, vertex {v}"
                    );
                    compared += 1;
                    occluded += portable.0.count_occluded();
                }
            }
        }
        assert!(compared >= 3 * normals.len().div_ceil(step));
        assert!(occluded > 0, "the spheres shadow themselves");
    }

    #[test]
    fn clusters_change_nothing_with_a_far_mesh_while_deforming() {
        let (rest, indices) = bumpy_sphere(20, 32, 0.25, 0.0);
        let (far_rest, far_indices) = bumpy_sphere(8, 12, 0.25, 0.0);
        let rest_mesh = MeshView::new(&rest, &indices).unwrap();
        let far_rest_mesh = MeshView::new(&far_rest, &far_indices).unwrap();
        let mut clusters = TriangleClusters::new(&rest_mesh, 8);
        let mut far_clusters = TriangleClusters::new(&far_rest_mesh, 8);
        for twist in [0.0f32, 0.5, 1.5] {
            let (positions, _) = bumpy_sphere(20, 32, 0.25, twist);
            let (far_positions, _) = bumpy_sphere(8, 12, 0.25, twist);
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let far = MeshView::new(&far_positions, &far_indices).unwrap();
            let normals = normals_of(&mesh);
            let options = BatchOptions {
                normal_offset: 0.005,
                ..BatchOptions::default()
            };
            let fast_mesh = clusters.update(mesh);
            let fast_far = far_clusters.update(far);
            for radius in [0.0f32, 0.3, 0.8, f32::INFINITY] {
                let plain = HemiScene::with_far(
                    ClusteredMesh::unclustered(mesh),
                    ClusteredMesh::unclustered(far),
                    radius,
                );
                let fast = HemiScene::with_far(fast_mesh, fast_far, radius);
                let r2 = radius * radius;
                for v in (0..mesh.vertex_count()).step_by(3) {
                    let (p, n) = (mesh.position(v), normals[v]);
                    let a = scene_mask(&plain, p, n, &options);
                    let b = scene_mask(&fast, p, n, &options);
                    assert_eq!(a, b, "twist {twist} radius {radius} vertex {v}");
                    // The rule, spelled out.
                    let near = |q: Vec3| (q - p).length_squared() <= r2;
                    let receiver = Receiver::new(p, n, options.normal_offset);
                    let mut expected = HemiMask::EMPTY;
                    let full = mesh.triangles().filter(|t| t.iter().any(|&q| near(q)));
                    let coarse = far.triangles().filter(|t| t.iter().all(|&q| !near(q)));
                    rasterize_triangles_into(
                        &mut expected,
                        &receiver,
                        full.chain(coarse),
                        Quality::Exact,
                        false,
                    );
                    assert_eq!(a, expected, "twist {twist} radius {radius} vertex {v}");
                }
            }
        }
    }

    #[test]
    fn far_levels_take_their_bands_with_and_without_clusters() {
        // The full mesh and three coarser spheres, posed together.
        let grids = [(20, 32), (12, 18), (8, 12), (5, 8)];
        let rest: Vec<_> = grids.map(|(r, s)| bumpy_sphere(r, s, 0.25, 0.0)).into();
        let mut clusters: Vec<TriangleClusters> = rest
            .iter()
            .map(|(p, i)| TriangleClusters::new(&MeshView::new(p, i).unwrap(), 8))
            .collect();
        for twist in [0.0f32, 0.9] {
            let posed: Vec<_> = grids.map(|(r, s)| bumpy_sphere(r, s, 0.25, twist).0).into();
            let views: Vec<MeshView<'_>> = posed
                .iter()
                .zip(&rest)
                .map(|(p, (_, i))| MeshView::new(p, i).unwrap())
                .collect();
            let fast: Vec<ClusteredMesh<'_>> = clusters
                .iter_mut()
                .zip(&views)
                .map(|(c, &v)| c.update(v))
                .collect();
            let mesh = views[0];
            let normals = normals_of(&mesh);
            let options = BatchOptions {
                normal_offset: 0.005,
                ..BatchOptions::default()
            };
            // Radii of the far mesh and its two coarser levels: growing, a
            // band left empty by equal radii, and everything far.
            for radii in [
                [0.3f32, 0.6, 1.2],
                [0.2, 0.2, 0.9],
                [0.0, 0.5, 0.5],
                [0.4, 0.8, f32::INFINITY],
            ] {
                fn level<'m>(
                    meshes: &[ClusteredMesh<'m>],
                    radii: [f32; 3],
                    k: usize,
                ) -> FarLevel<'m> {
                    FarLevel {
                        mesh: meshes[k + 1],
                        near_radius: radii[k],
                    }
                }
                let plain_meshes: Vec<_> = views
                    .iter()
                    .map(|&v| ClusteredMesh::unclustered(v))
                    .collect();
                let plain_levels = [
                    level(&plain_meshes, radii, 1),
                    level(&plain_meshes, radii, 2),
                ];
                let fast_levels = [level(&fast, radii, 1), level(&fast, radii, 2)];
                let plain = HemiScene {
                    coarser: &plain_levels,
                    ..HemiScene::with_far(plain_meshes[0], plain_meshes[1], radii[0])
                };
                let clustered = HemiScene {
                    coarser: &fast_levels,
                    ..HemiScene::with_far(fast[0], fast[1], radii[0])
                };
                for v in (0..mesh.vertex_count()).step_by(5) {
                    let (p, n) = (mesh.position(v), normals[v]);
                    let (a, counts) = scene_mask_with_counts(&plain, p, n, &options);
                    let (b, _) = scene_mask_with_counts(&clustered, p, n, &options);
                    assert_eq!(a, b, "twist {twist} radii {radii:?} vertex {v}");
                    let (_, fast_counts) = traverse(&clustered, p, n, &options, false);
                    assert_eq!(counts.rasterized, fast_counts.rasterized);
                    // The rule, spelled out: level k's triangles with every
                    // corner beyond its radius and one within the next's.
                    let within = |q: Vec3, r: f32| (q - p).length_squared() <= r * r;
                    let bounds = [0.0, radii[0], radii[1], radii[2], f32::INFINITY];
                    let mut expected = HemiMask::EMPTY;
                    let receiver = Receiver::new(p, n, options.normal_offset);
                    for (k, view) in views.iter().enumerate() {
                        let (inner, outer) = (bounds[k], bounds[k + 1]);
                        let taken = view.triangles().filter(|t| {
                            (k == 0 || t.iter().all(|&q| !within(q, inner)))
                                && (k == 3 || t.iter().any(|&q| within(q, outer)))
                        });
                        rasterize_triangles_into(
                            &mut expected,
                            &receiver,
                            taken,
                            Quality::Exact,
                            false,
                        );
                    }
                    assert_eq!(a, expected, "twist {twist} radii {radii:?} vertex {v}");
                }
            }
        }
    }

    #[test]
    fn clusters_regroup_when_the_indices_change() {
        let (positions, indices) = bumpy_sphere(10, 16, 0.25, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut clusters = TriangleClusters::new(&mesh, 40);
        let _ = clusters.update(mesh);
        // Same triangle count, other corners: every triangle's winding flipped
        // and the triangles reversed.
        let mut flipped: Vec<u32> = indices
            .chunks(3)
            .rev()
            .flat_map(|t| [t[0], t[2], t[1]])
            .collect();
        flipped.truncate(indices.len());
        let other = MeshView::new(&positions, &flipped).unwrap();
        let normals = normals_of(&mesh);
        let clustered = clusters.update(other);
        let options = BatchOptions {
            cull_backfaces: true,
            normal_offset: 0.01,
            ..BatchOptions::default()
        };
        for v in (0..mesh.vertex_count()).step_by(3) {
            let (p, n) = (mesh.position(v), normals[v]);
            let plain = scene_mask(
                &HemiScene::new(ClusteredMesh::unclustered(other)),
                p,
                n,
                &options,
            );
            assert_eq!(
                scene_mask(&HemiScene::new(clustered), p, n, &options),
                plain,
                "vertex {v}"
            );
        }
    }

    #[test]
    fn clusters_cull_most_triangles_below_the_horizon() {
        let (positions, indices) = bumpy_sphere(30, 64, 0.25, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        let mut clusters = TriangleClusters::new(&mesh, TriangleClusters::DEFAULT_SIZE);
        assert_eq!(clusters.cluster_count(), mesh.triangle_count().div_ceil(32));
        let scene = HemiScene::new(clusters.update(mesh));
        let options = BatchOptions::default();
        let (mut seen, mut total) = (0u64, 0u64);
        for v in (0..mesh.vertex_count()).step_by(7) {
            let (_, counts) =
                scene_mask_with_counts(&scene, mesh.position(v), normals[v], &options);
            seen += u64::from(counts.rasterized + counts.below_horizon + counts.degenerate);
            total += mesh.triangle_count() as u64;
        }
        // Triangles of skipped clusters are not even read (measured: 36 %).
        assert!(seen * 2 < total, "{seen} of {total} triangles read");
    }
}
