//! Ray casting throughput on a procedural scene, on the same rays in the same run:
//! `BvhScene` against the brute-force reference (the baseline), and against obvhs's
//! own traversal with its Möller–Trumbore test (`obvhs_native_*`), which is what
//! the exact, conservative box test and the watertight triangle test cost.
//!
//! Run: `cargo bench -p antumbra-core --features bvh --bench raycast`.

use antumbra_core::{BruteForceCaster, MeshView, Ray, RayCaster, raycast::BvhScene};
use glam::Vec3;
use rand::{Rng, SeedableRng, rngs::SmallRng};

fn main() {
    divan::main();
}

/// A closed UV sphere of `rings * segments * 2` triangles, radius 1 at the origin.
fn sphere(rings: u32, segments: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut positions = Vec::new();
    for r in 0..=rings {
        let theta = core::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = core::f32::consts::TAU * s as f32 / segments as f32;
            positions.push([
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ]);
        }
    }
    let mut indices = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = r * segments + s;
            let b = r * segments + (s + 1) % segments;
            let c = a + segments;
            let d = b + segments;
            indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    (positions, indices)
}

fn rays(count: usize) -> Vec<Ray> {
    let mut rng = SmallRng::seed_from_u64(7);
    (0..count)
        .map(|_| {
            let origin = Vec3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            );
            let target = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            Ray::new(origin, target - origin, f32::INFINITY)
        })
        .collect()
}

const RAYS: usize = 1024;

#[divan::bench(args = [8, 32])]
fn bvh_closest_hit(bencher: divan::Bencher<'_, '_>, rings: u32) {
    let (positions, indices) = sphere(rings, 2 * rings);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let scene = BvhScene::new(&mesh).unwrap();
    let rays = rays(RAYS);
    bencher
        .counter(divan::counter::ItemsCount::new(RAYS))
        .bench_local(|| rays.iter().filter_map(|r| scene.closest_hit(r)).count());
}

#[divan::bench(args = [8, 32])]
fn brute_force_closest_hit(bencher: divan::Bencher<'_, '_>, rings: u32) {
    let (positions, indices) = sphere(rings, 2 * rings);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let caster = BruteForceCaster::new(mesh);
    let rays = rays(RAYS);
    bencher
        .counter(divan::counter::ItemsCount::new(RAYS))
        .bench_local(|| rays.iter().filter_map(|r| caster.closest_hit(r)).count());
}

#[divan::bench(args = [8, 32])]
fn bvh_occluded(bencher: divan::Bencher<'_, '_>, rings: u32) {
    let (positions, indices) = sphere(rings, 2 * rings);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let scene = BvhScene::new(&mesh).unwrap();
    let rays = rays(RAYS);
    bencher
        .counter(divan::counter::ItemsCount::new(RAYS))
        .bench_local(|| rays.iter().filter(|r| scene.occluded(r)).count());
}

#[divan::bench(args = [8, 32])]
fn obvhs_native_closest_hit(bencher: divan::Bencher<'_, '_>, rings: u32) {
    use obvhs::{BvhBuildParams, cwbvh::builder::build_cwbvh_from_tris, ray::RayHit};
    let (positions, indices) = sphere(rings, 2 * rings);
    let triangles: Vec<obvhs::triangle::Triangle> = indices
        .chunks_exact(3)
        .map(|t| obvhs::triangle::Triangle {
            v0: positions[t[0] as usize].into(),
            v1: positions[t[1] as usize].into(),
            v2: positions[t[2] as usize].into(),
        })
        .collect();
    let mut build_time = core::time::Duration::ZERO;
    let bvh = build_cwbvh_from_tris(&triangles, BvhBuildParams::medium_build(), &mut build_time);
    let rays: Vec<obvhs::ray::Ray> = rays(RAYS)
        .iter()
        .map(|r| obvhs::ray::Ray::new_inf(r.origin.into(), r.direction.into()))
        .collect();
    bencher
        .counter(divan::counter::ItemsCount::new(RAYS))
        .bench_local(|| {
            rays.iter()
                .filter(|&&ray| {
                    let mut hit = RayHit::none();
                    bvh.ray_traverse(ray, &mut hit, |r, id| {
                        triangles[bvh.primitive_indices[id] as usize].intersect(r)
                    })
                })
                .count()
        });
}
