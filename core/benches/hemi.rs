//! Hemispherical rasterization on a bunny-sized closed mesh (a bumpy sphere of
//! 3,712 triangles, concave enough that receivers on it see real occluders), in
//! the same run:
//!
//! - `triangle_exact` / `triangle_table`: nanoseconds per triangle rasterized, over
//!   the triangles that survive culling for a set of receivers on the mesh;
//! - `receiver_exact` / `receiver_table`: microseconds per receiver (cull and
//!   rasterize every triangle), against the baseline `receiver_bvh_rays`: tracing
//!   the same 812 valid cell directions from the same centers with `BvhScene`;
//! - `table_build`: building the default table once.
//! - `triangle_table_pure` / `receiver_table_pure`: the same with the pure table
//!   (the paper's method: every plane from the table, no exact edges);
//!   `receiver_table_sized` / `receiver_table_pure_sized`: per receiver for table
//!   resolutions 32 to 256 (132 KiB to 8 MiB), default exact edges and pure.
//!
//! Integration and shading (masks of the same receivers, built once):
//!
//! - `transfer_*::<N>`: microseconds per mask turned into a local transfer vector
//!   by the per-cell sum, the byte and nibble lookup tables, and the 8×8 block
//!   downsampling, for 9 and 16 coefficients;
//! - `rotation_transfer::<N>` vs `rotation_lighting::<N>`: per vertex, building the
//!   frame's SH rotation and rotating one transfer vector to world space, against
//!   rotating the three lighting channels into the local frame;
//! - `glossy_transfer::<N>`: per mask, the glossy transfer vector of a Phong lobe
//!   (s = 16) about a per-receiver mirror direction;
//! - `shade_vertex_*`: per receiver, mask + transfer + rotation + diffuse (and
//!   glossy) shading, exact masks, 9 coefficients;
//! - `lod_receiver_{exact,table}[_far]::<K>`: microseconds per receiver mask
//!   through `scene_mask`, on the bumpy sphere and on the Stanford bunny of
//!   `tests/data` (every 9th vertex), every triangle read and culled (`K = 0`)
//!   against cluster boxes of `K` triangles, without and with a far mesh (the
//!   sphere: the same surface at 360 triangles, near radius 0.4; the bunny: a
//!   vertex clustering of it on a 12³ grid, 902 triangles, near radius a tenth of
//!   its diagonal);
//! - `frame_{exact,table}[_far]`: shading every vertex (1,984 of the sphere, 1,839
//!   of the bunny) once, diffuse and glossy (s = 16), 9 coefficients, 32-triangle
//!   clusters, boxes recomputed as for a new frame; frames per second is 1 / time.
//!   One thread unless built with `--features parallel`.
//!
//! Single thread (except `frame_*` with `parallel`). Run:
//! `cargo bench -p antumbra-core --features bvh --bench hemi`.

use antumbra_core::MeshView;
use antumbra_core::RayCaster;
use antumbra_core::hemi::{
    BatchOptions, ClusteredMesh, HalfSpaceTable, HemiMask, HemiScene, Material, PhongLobe, Quality,
    RasterOptions, Receiver, TransferLut, TransferMethod, TransferRotation, TransferTable,
    TriangleClusters, TriangleCone, cell_directions, glossy_transfer, rasterize_receiver,
    scene_mask, shade_batch, shade_vertex,
};
use antumbra_core::raycast::BvhScene;
use antumbra_core::sh::{Sh, ShRgb, ShRotation};
use glam::Vec3;

fn main() {
    divan::main();
}

/// A closed UV sphere with its radius modulated by `0.2 sin 5θ sin 4φ`.
fn bumpy_sphere(rings: u32, segments: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    antumbra_core::geom::uv_sphere(rings, segments, |theta, phi| {
        let radius = 1.0 + 0.2 * (5.0 * theta).sin() * (4.0 * phi).sin();
        [
            radius * theta.sin() * phi.cos(),
            radius * theta.sin() * phi.sin(),
            radius * theta.cos(),
        ]
    })
}

struct Scene {
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
    /// Receivers: vertex position, area-weighted normal.
    receivers: Vec<(Vec3, Vec3)>,
    offset: f32,
}

impl Scene {
    fn new() -> Self {
        let (positions, indices) = bumpy_sphere(30, 64);
        assert_eq!(indices.len() / 3, 3712);
        let mut normals = vec![Vec3::ZERO; positions.len()];
        for t in indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(positions[t[k] as usize]));
            for &v in t {
                normals[v as usize] += (b - a).cross(c - a);
            }
        }
        let receivers = (0..positions.len())
            .step_by(29)
            .map(|v| (Vec3::from(positions[v]), normals[v].normalize()))
            .collect();
        // 1e-3 of the bounding box diagonal, as in the Embree cross-check.
        let offset = 1e-3 * 2.4 * 3f32.sqrt();
        Scene {
            positions,
            indices,
            receivers,
            offset,
        }
    }

    fn mesh(&self) -> MeshView<'_> {
        MeshView::new(&self.positions, &self.indices).unwrap()
    }

    /// The exact masks of the receivers.
    fn masks(&self) -> Vec<HemiMask> {
        let mesh = self.mesh();
        let options = RasterOptions {
            normal_offset: self.offset,
            ..RasterOptions::default()
        };
        self.receivers
            .iter()
            .map(|&(p, n)| rasterize_receiver(&mesh, p, n, &options))
            .collect()
    }

    /// Every cone that survives culling, over all receivers.
    fn cones(&self) -> Vec<TriangleCone> {
        let mesh = self.mesh();
        let mut cones = Vec::new();
        for &(p, n) in &self.receivers {
            let receiver = Receiver::new(p, n, self.offset);
            for [a, b, c] in mesh.triangles() {
                let local = [a, b, c].map(|q| receiver.to_local(q));
                if let Ok(cone) = TriangleCone::new(local[0], local[1], local[2], false) {
                    cones.push(cone);
                }
            }
        }
        cones
    }
}

#[divan::bench]
fn triangle_exact(bencher: divan::Bencher<'_, '_>) {
    let cones = Scene::new().cones();
    bencher
        .counter(divan::counter::ItemsCount::new(cones.len()))
        .bench_local(|| {
            let mut mask = HemiMask::EMPTY;
            for cone in &cones {
                mask |= cone.mask_exact();
            }
            mask
        });
}

#[divan::bench]
fn triangle_table(bencher: divan::Bencher<'_, '_>) {
    let cones = Scene::new().cones();
    let table = HalfSpaceTable::default();
    bencher
        .counter(divan::counter::ItemsCount::new(cones.len()))
        .bench_local(|| {
            let mut mask = HemiMask::EMPTY;
            for cone in &cones {
                mask |= cone.mask_table(&table);
            }
            mask
        });
}

fn receivers_with(bencher: divan::Bencher<'_, '_>, scene: &Scene, quality: Quality<'_>) {
    let mesh = scene.mesh();
    let options = RasterOptions {
        quality,
        normal_offset: scene.offset,
        ..RasterOptions::default()
    };
    bencher
        .counter(divan::counter::ItemsCount::new(scene.receivers.len()))
        .bench_local(|| {
            scene
                .receivers
                .iter()
                .map(|&(p, n)| rasterize_receiver(&mesh, p, n, &options).count_occluded())
                .sum::<u32>()
        });
}

#[divan::bench]
fn receiver_exact(bencher: divan::Bencher<'_, '_>) {
    let scene = Scene::new();
    receivers_with(bencher, &scene, Quality::Exact);
}

#[divan::bench]
fn receiver_table(bencher: divan::Bencher<'_, '_>) {
    let scene = Scene::new();
    let table = HalfSpaceTable::default();
    receivers_with(bencher, &scene, Quality::Table(&table));
}

/// The baseline: the same cell directions traced with the BVH.
#[divan::bench]
fn receiver_bvh_rays(bencher: divan::Bencher<'_, '_>) {
    let scene = Scene::new();
    let bvh = BvhScene::new(&scene.mesh()).unwrap();
    bencher
        .counter(divan::counter::ItemsCount::new(scene.receivers.len()))
        .bench_local(|| {
            let mut occluded = 0u32;
            for &(p, n) in &scene.receivers {
                let receiver = Receiver::new(p, n, scene.offset);
                for (i, j, _) in cell_directions() {
                    let ray = receiver.cell_ray(i, j).unwrap();
                    occluded += u32::from(bvh.occluded(&ray));
                }
            }
            occluded
        });
}

#[divan::bench(sample_count = 10)]
fn table_build() -> HalfSpaceTable {
    HalfSpaceTable::new(HalfSpaceTable::DEFAULT_RESOLUTION)
}

/// Table resolutions timed per receiver: 132 KiB to 8 MiB.
const TABLE_RESOLUTIONS: [u32; 7] = [32, 45, 64, 91, 128, 181, 256];

/// The pure table (the paper's method): no exact edges.
fn pure_table(resolution: u32) -> HalfSpaceTable {
    HalfSpaceTable::new(resolution).with_exact_edges(0.0, f32::INFINITY)
}

#[divan::bench]
fn triangle_table_pure(bencher: divan::Bencher<'_, '_>) {
    let cones = Scene::new().cones();
    let table = pure_table(HalfSpaceTable::DEFAULT_RESOLUTION);
    bencher
        .counter(divan::counter::ItemsCount::new(cones.len()))
        .bench_local(|| {
            let mut mask = HemiMask::EMPTY;
            for cone in &cones {
                mask |= cone.mask_table(&table);
            }
            mask
        });
}

#[divan::bench]
fn receiver_table_pure(bencher: divan::Bencher<'_, '_>) {
    let scene = Scene::new();
    let table = pure_table(HalfSpaceTable::DEFAULT_RESOLUTION);
    receivers_with(bencher, &scene, Quality::Table(&table));
}

#[divan::bench(args = TABLE_RESOLUTIONS)]
fn receiver_table_sized(bencher: divan::Bencher<'_, '_>, resolution: u32) {
    let scene = Scene::new();
    let table = HalfSpaceTable::new(resolution);
    receivers_with(bencher, &scene, Quality::Table(&table));
}

#[divan::bench(args = TABLE_RESOLUTIONS)]
fn receiver_table_pure_sized(bencher: divan::Bencher<'_, '_>, resolution: u32) {
    let scene = Scene::new();
    let table = pure_table(resolution);
    receivers_with(bencher, &scene, Quality::Table(&table));
}

// --- integration and shading ---

/// A deterministic lighting with every coefficient non-zero.
fn lighting<const N: usize>() -> ShRgb<N> {
    let mut l = ShRgb::<N>::ZERO;
    for k in 0..N {
        l.r[k] = 1.0 / (1.0 + k as f32);
        l.g[k] = 0.5 / (1.0 + k as f32);
        l.b[k] = (k as f32 * 0.37).sin();
    }
    l
}

/// Masks for the integration benches: `"receivers"`, the exact masks of the
/// receivers (137 of 812 cells occluded on average), or `"half_planes"`, 256
/// half-space masks of random planes (406 on average, the per-cell sum's worst
/// case).
fn bench_masks(set: &str) -> Vec<HemiMask> {
    if set == "receivers" {
        return Scene::new().masks();
    }
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    };
    (0..256)
        .map(|_| antumbra_core::hemi::half_space_mask(Vec3::new(next(), next(), next())))
        .collect()
}

const MASK_SETS: [&str; 2] = ["receivers", "half_planes"];

fn transfer_with<const N: usize>(
    bencher: divan::Bencher<'_, '_>,
    set: &str,
    transfer: impl Fn(&HemiMask) -> Sh<N>,
) {
    let masks = bench_masks(set);
    bencher
        .counter(divan::counter::ItemsCount::new(masks.len()))
        .bench_local(|| {
            masks
                .iter()
                .map(|m| transfer(divan::black_box(m)).coeffs[0])
                .sum::<f32>()
        });
}

#[divan::bench(consts = [9, 16], args = MASK_SETS)]
fn transfer_cells<const N: usize>(bencher: divan::Bencher<'_, '_>, set: &str) {
    let table = TransferTable::<N>::new();
    transfer_with(bencher, set, |m| table.transfer(m));
}

#[divan::bench(consts = [9, 16], args = MASK_SETS)]
fn transfer_lut_bytes<const N: usize>(bencher: divan::Bencher<'_, '_>, set: &str) {
    let lut = TransferLut::new(TransferTable::<N>::new());
    transfer_with(bencher, set, |m| lut.transfer(m));
}

#[divan::bench(consts = [9, 16], args = MASK_SETS)]
fn transfer_lut_nibbles<const N: usize>(bencher: divan::Bencher<'_, '_>, set: &str) {
    let lut = TransferLut::with_chunk_bits(TransferTable::<N>::new(), 4);
    transfer_with(bencher, set, |m| lut.transfer(m));
}

#[divan::bench(consts = [9, 16], args = MASK_SETS)]
fn transfer_downsampled<const N: usize>(bencher: divan::Bencher<'_, '_>, set: &str) {
    let table = TransferTable::<N>::new();
    transfer_with(bencher, set, |m| table.transfer_downsampled(m));
}

#[divan::bench(consts = [9, 16], sample_count = 10)]
fn transfer_table_build<const N: usize>() -> TransferTable<N> {
    TransferTable::<N>::new()
}

#[divan::bench(consts = [9, 16])]
fn rotation_transfer<const N: usize>(bencher: divan::Bencher<'_, '_>) {
    let scene = Scene::new();
    let t = TransferTable::<N>::new().unoccluded();
    bencher
        .counter(divan::counter::ItemsCount::new(scene.receivers.len()))
        .bench_local(|| {
            scene
                .receivers
                .iter()
                .map(|&(_, n)| {
                    let frame = antumbra_core::Frame::from_normal(divan::black_box(n));
                    TransferRotation::<N>::new(&frame).to_world(&t).coeffs[1]
                })
                .sum::<f32>()
        });
}

#[divan::bench(consts = [9, 16])]
fn rotation_lighting<const N: usize>(bencher: divan::Bencher<'_, '_>) {
    let scene = Scene::new();
    let light = lighting::<N>();
    bencher
        .counter(divan::counter::ItemsCount::new(scene.receivers.len()))
        .bench_local(|| {
            scene
                .receivers
                .iter()
                .map(|&(_, n)| {
                    let frame = antumbra_core::Frame::from_normal(divan::black_box(n));
                    let to_local = antumbra_core::hemi::frame_matrix(&frame).transpose();
                    ShRotation::<N>::new(to_local).apply_rgb(&light).b.coeffs[1]
                })
                .sum::<f32>()
        });
}

#[divan::bench(consts = [9, 16])]
fn glossy_transfer_s16<const N: usize>(bencher: divan::Bencher<'_, '_>) {
    let scene = Scene::new();
    let masks = scene.masks();
    let table = TransferTable::<N>::new();
    let lobe = PhongLobe::new(16.0).unwrap();
    // A mirror direction per receiver: the view from far along +y.
    let mirrors: Vec<Vec3> = scene
        .receivers
        .iter()
        .map(|&(_, n)| {
            let frame = antumbra_core::Frame::from_normal(n);
            let r = antumbra_core::hemi::mirror_direction(n, Vec3::Y);
            let r = frame.to_local(r);
            if r.z < 0.0 {
                Vec3::new(r.x, r.y, -r.z)
            } else {
                r
            }
        })
        .collect();
    bencher
        .counter(divan::counter::ItemsCount::new(masks.len()))
        .bench_local(|| {
            masks
                .iter()
                .zip(&mirrors)
                .map(|(m, &r)| glossy_transfer(&table, divan::black_box(m), &lobe, r).coeffs[0])
                .sum::<f32>()
        });
}

fn shade_vertices(bencher: divan::Bencher<'_, '_>, glossy: bool) {
    let scene = Scene::new();
    let mesh = scene.mesh();
    let table = TransferTable::<9>::new();
    let light = lighting::<9>();
    let lobe = PhongLobe::new(16.0).unwrap();
    let material = Material {
        albedo: Vec3::splat(0.8),
        specular: if glossy { Vec3::splat(0.2) } else { Vec3::ZERO },
        lobe: Some(&lobe),
        eye: Vec3::new(0.0, 10.0, 3.0),
    };
    let mut clusters = TriangleClusters::new(&mesh, TriangleClusters::DEFAULT_SIZE);
    let hemi = HemiScene::new(clusters.update(mesh));
    let options = BatchOptions {
        normal_offset: scene.offset,
        ..BatchOptions::default()
    };
    bencher
        .counter(divan::counter::ItemsCount::new(scene.receivers.len()))
        .bench_local(|| {
            scene
                .receivers
                .iter()
                .map(|&(p, n)| {
                    let s = shade_vertex(
                        &hemi,
                        p,
                        n,
                        &options,
                        TransferMethod::Cells(&table),
                        &light,
                        &material,
                    );
                    s.diffuse.x + s.glossy.x
                })
                .sum::<f32>()
        });
}

#[divan::bench]
fn shade_vertex_diffuse(bencher: divan::Bencher<'_, '_>) {
    shade_vertices(bencher, false);
}

#[divan::bench]
fn shade_vertex_diffuse_glossy(bencher: divan::Bencher<'_, '_>) {
    shade_vertices(bencher, true);
}

/// A mesh for the LOD and frame benches, with its far mesh and receivers.
struct LodMesh {
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
    far_positions: Vec<[f32; 3]>,
    far_indices: Vec<u32>,
    near_radius: f32,
    offset: f32,
}

const LOD_MESHES: [&str; 2] = ["sphere", "bunny"];

impl LodMesh {
    /// `"sphere"`: the 3,712-triangle bumpy sphere, its far mesh the same surface
    /// at 360 triangles (10 × 20), near radius 0.4 (a sixth of the diagonal).
    /// `"bunny"`: the Stanford bunny of `tests/data` (3,674 triangles), its far mesh
    /// a vertex clustering of it on a 12³ grid, near radius a tenth of the diagonal.
    fn new(name: &str) -> Self {
        let (positions, indices, far_positions, far_indices) = if name == "sphere" {
            let (p, i) = bumpy_sphere(30, 64);
            let (fp, fi) = bumpy_sphere(10, 20);
            (p, i, fp, fi)
        } else {
            let (p, i) = bunny();
            let (fp, fi) = vertex_clustering(&p, &i, 12);
            (p, i, fp, fi)
        };
        let (lo, hi) = positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p.into()), hi.max(p.into()))
            });
        let diagonal = (hi - lo).length();
        LodMesh {
            positions,
            indices,
            far_positions,
            far_indices,
            near_radius: if name == "sphere" {
                0.4
            } else {
                0.1 * diagonal
            },
            offset: 1e-3 * diagonal,
        }
    }

    fn mesh(&self) -> MeshView<'_> {
        MeshView::new(&self.positions, &self.indices).unwrap()
    }

    fn far(&self) -> MeshView<'_> {
        MeshView::new(&self.far_positions, &self.far_indices).unwrap()
    }

    fn normals(&self) -> Vec<Vec3> {
        let mut normals = vec![Vec3::ZERO; self.positions.len()];
        antumbra_core::hemi::vertex_normals(&self.mesh(), &mut normals).unwrap();
        normals
    }
}

/// The Stanford bunny of `tests/data/bunny.obj` (plain `v` and `f` lines).
fn bunny() -> (Vec<[f32; 3]>, Vec<u32>) {
    let text = include_str!("../../tests/data/bunny.obj");
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let v: Vec<f32> = words.map(|w| w.parse().unwrap()).collect();
                positions.push([v[0], v[1], v[2]]);
            }
            Some("f") => indices.extend(words.map(|w| w.parse::<u32>().unwrap() - 1)),
            _ => {}
        }
    }
    (positions, indices)
}

/// Rossignac–Borrel vertex clustering: vertices snapped to the mean of their cell
/// of a `cells³` grid over the bounds, triangles that collapse dropped.
fn vertex_clustering(
    positions: &[[f32; 3]],
    indices: &[u32],
    cells: u32,
) -> (Vec<[f32; 3]>, Vec<u32>) {
    let (lo, hi) = positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p.into()), hi.max(p.into()))
        });
    let size = (hi - lo) / cells as f32;
    let cell_of = |p: [f32; 3]| {
        let c = ((Vec3::from(p) - lo) / size)
            .floor()
            .min(Vec3::splat(cells as f32 - 1.0));
        (c.x as u32 * cells + c.y as u32) * cells + c.z as u32
    };
    let mut remap = std::collections::HashMap::new();
    let mut sums: Vec<(Vec3, f32)> = Vec::new();
    let vertex_cell: Vec<u32> = positions
        .iter()
        .map(|&p| {
            let next = sums.len() as u32;
            let id = *remap.entry(cell_of(p)).or_insert(next);
            if id == next {
                sums.push((Vec3::ZERO, 0.0));
            }
            sums[id as usize].0 += Vec3::from(p);
            sums[id as usize].1 += 1.0;
            id
        })
        .collect();
    let far_positions = sums.iter().map(|(s, n)| (*s / *n).to_array()).collect();
    let far_indices = indices
        .chunks_exact(3)
        .map(|t| [0, 1, 2].map(|k| vertex_cell[t[k] as usize]))
        .filter(|[a, b, c]| a != b && b != c && c != a)
        .flatten()
        .collect();
    (far_positions, far_indices)
}

fn lod_receivers(
    bencher: divan::Bencher<'_, '_>,
    name: &str,
    cluster_size: usize,
    far: bool,
    quality: Quality<'_>,
) {
    let lod = LodMesh::new(name);
    let (mesh, far_mesh) = (lod.mesh(), lod.far());
    let normals = lod.normals();
    let receivers: Vec<usize> = (0..mesh.vertex_count()).step_by(9).collect();
    let mut clusters = (cluster_size > 0).then(|| TriangleClusters::new(&mesh, cluster_size));
    let mut far_clusters =
        (cluster_size > 0).then(|| TriangleClusters::new(&far_mesh, cluster_size));
    let near = match &mut clusters {
        Some(c) => c.update(mesh),
        None => ClusteredMesh::unclustered(mesh),
    };
    let coarse = match &mut far_clusters {
        Some(c) => c.update(far_mesh),
        None => ClusteredMesh::unclustered(far_mesh),
    };
    let hemi = if far {
        HemiScene::with_far(near, coarse, lod.near_radius)
    } else {
        HemiScene::new(near)
    };
    let options = BatchOptions {
        quality,
        normal_offset: lod.offset,
        ..BatchOptions::default()
    };
    bencher
        .counter(divan::counter::ItemsCount::new(receivers.len()))
        .bench_local(|| {
            receivers
                .iter()
                .map(|&v| {
                    scene_mask(&hemi, mesh.position(v), normals[v], &options).count_occluded()
                })
                .sum::<u32>()
        });
}

/// Cluster sizes of the LOD benches; 0 = no clusters (every triangle read).
const CLUSTER_SIZES: [usize; 4] = [0, 16, 32, 64];

#[divan::bench(consts = CLUSTER_SIZES, args = LOD_MESHES)]
fn lod_receiver_exact<const K: usize>(bencher: divan::Bencher<'_, '_>, mesh: &str) {
    lod_receivers(bencher, mesh, K, false, Quality::Exact);
}

#[divan::bench(consts = CLUSTER_SIZES, args = LOD_MESHES)]
fn lod_receiver_table<const K: usize>(bencher: divan::Bencher<'_, '_>, mesh: &str) {
    let table = HalfSpaceTable::default();
    lod_receivers(bencher, mesh, K, false, Quality::Table(&table));
}

#[divan::bench(consts = CLUSTER_SIZES, args = LOD_MESHES)]
fn lod_receiver_exact_far<const K: usize>(bencher: divan::Bencher<'_, '_>, mesh: &str) {
    lod_receivers(bencher, mesh, K, true, Quality::Exact);
}

#[divan::bench(consts = CLUSTER_SIZES, args = LOD_MESHES)]
fn lod_receiver_table_far<const K: usize>(bencher: divan::Bencher<'_, '_>, mesh: &str) {
    let table = HalfSpaceTable::default();
    lod_receivers(bencher, mesh, K, true, Quality::Table(&table));
}

fn frame(bencher: divan::Bencher<'_, '_>, name: &str, far: bool, quality: Quality<'_>) {
    let lod = LodMesh::new(name);
    let (mesh, far_mesh) = (lod.mesh(), lod.far());
    let normals = lod.normals();
    let mut clusters = TriangleClusters::new(&mesh, TriangleClusters::DEFAULT_SIZE);
    let mut far_clusters = TriangleClusters::new(&far_mesh, TriangleClusters::DEFAULT_SIZE);
    let table = TransferTable::<9>::new();
    let light = lighting::<9>();
    let lobe = PhongLobe::new(16.0).unwrap();
    let material = Material {
        albedo: Vec3::splat(0.8),
        specular: Vec3::splat(0.2),
        lobe: Some(&lobe),
        eye: Vec3::new(0.0, 10.0, 3.0),
    };
    let options = BatchOptions {
        quality,
        normal_offset: lod.offset,
        ..BatchOptions::default()
    };
    let mut out = vec![Vec3::ZERO; mesh.vertex_count()];
    bencher
        .counter(divan::counter::ItemsCount::new(1usize))
        .bench_local(|| {
            // A frame: new boxes for the current positions, then every vertex.
            let near = clusters.update(mesh);
            let hemi = if far {
                HemiScene::with_far(near, far_clusters.update(far_mesh), lod.near_radius)
            } else {
                HemiScene::new(near)
            };
            shade_batch(
                &hemi,
                &normals,
                &options,
                TransferMethod::Cells(&table),
                &light,
                &material,
                &mut out,
            )
            .unwrap();
            out[0]
        });
}

#[divan::bench(sample_count = 10, args = LOD_MESHES)]
fn frame_exact(bencher: divan::Bencher<'_, '_>, mesh: &str) {
    frame(bencher, mesh, false, Quality::Exact);
}

#[divan::bench(sample_count = 10, args = LOD_MESHES)]
fn frame_exact_far(bencher: divan::Bencher<'_, '_>, mesh: &str) {
    frame(bencher, mesh, true, Quality::Exact);
}

#[divan::bench(sample_count = 10, args = LOD_MESHES)]
fn frame_table(bencher: divan::Bencher<'_, '_>, mesh: &str) {
    let table = HalfSpaceTable::default();
    frame(bencher, mesh, false, Quality::Table(&table));
}

#[divan::bench(sample_count = 10, args = LOD_MESHES)]
fn frame_table_far(bencher: divan::Bencher<'_, '_>, mesh: &str) {
    let table = HalfSpaceTable::default();
    frame(bencher, mesh, true, Quality::Table(&table));
}
