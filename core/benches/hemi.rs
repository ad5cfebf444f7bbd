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
//!
//! Single thread. Run: `cargo bench -p antumbra-core --features bvh --bench hemi`.

use antumbra_core::MeshView;
use antumbra_core::RayCaster;
use antumbra_core::hemi::{
    HalfSpaceTable, HemiMask, Quality, RasterOptions, Receiver, TriangleCone, cell_directions,
    rasterize_receiver,
};
use antumbra_core::raycast::BvhScene;
use glam::Vec3;

fn main() {
    divan::main();
}

/// A closed UV sphere with its radius modulated by `0.2 sin 5θ sin 4φ`.
fn bumpy_sphere(rings: u32, segments: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut positions = Vec::new();
    for r in 0..=rings {
        let theta = core::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = core::f32::consts::TAU * s as f32 / segments as f32;
            let radius = 1.0 + 0.2 * (5.0 * theta).sin() * (4.0 * phi).sin();
            positions.push([
                radius * theta.sin() * phi.cos(),
                radius * theta.sin() * phi.sin(),
                radius * theta.cos(),
            ]);
        }
    }
    let mut indices = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = r * segments + s;
            let b = r * segments + (s + 1) % segments;
            let (c, d) = (a + segments, b + segments);
            if r != 0 {
                indices.extend_from_slice(&[a, c, b]);
            }
            if r != rings - 1 {
                indices.extend_from_slice(&[b, c, d]);
            }
        }
    }
    (positions, indices)
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
