//! Ray casting throughput on a procedural scene, on the same rays in the same run:
//! `BvhScene` against the brute-force reference (the baseline), and against obvhs's
//! own traversal with its Möller–Trumbore test (`obvhs_native_*`), which is what
//! the exact, conservative box test and the watertight triangle test cost.
//!
//! The `bunny_surface_*` benches cast the rays a PRT bake or ambient occlusion
//! casts: origins on the Stanford bunny (3,674 triangles), cosine-distributed
//! directions about the face normal, unbounded.
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

/// The Stanford bunny of the test data (`tests/data/SOURCES.md`), parsed from its
/// `v` and `f` lines (1-based, triangles only).
fn bunny() -> (Vec<[f32; 3]>, Vec<u32>) {
    let text = include_str!("../../tests/data/bunny.obj");
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut c = words.map(|w| w.parse::<f32>().unwrap());
                positions.push([c.next().unwrap(), c.next().unwrap(), c.next().unwrap()]);
            }
            Some("f") => indices.extend(words.map(|w| w.parse::<u32>().unwrap() - 1)),
            _ => {}
        }
    }
    (positions, indices)
}

/// Rays from uniform points of the bunny's surface, cosine-distributed about the
/// face normal: the rays of a transfer bake.
fn surface_rays(mesh: &MeshView<'_>, count: usize) -> Vec<Ray> {
    let mut rng = SmallRng::seed_from_u64(11);
    (0..count)
        .map(|_| {
            let [a, b, c] = mesh.triangle(rng.random_range(0..mesh.triangle_count()));
            let (mut s, mut t) = (rng.random::<f32>(), rng.random::<f32>());
            if s + t > 1.0 {
                (s, t) = (1.0 - s, 1.0 - t);
            }
            let origin = a + s * (b - a) + t * (c - a);
            let normal = (b - a).cross(c - a).normalize();
            // Malley: a uniform point of the disc lifted to the hemisphere.
            let (u1, u2) = (rng.random::<f32>(), rng.random::<f32>());
            let (r, phi) = (u1.sqrt(), core::f32::consts::TAU * u2);
            let (x, y) = normal.any_orthonormal_pair();
            let direction =
                r * phi.cos() * x + r * phi.sin() * y + (1.0 - u1).max(0.0).sqrt() * normal;
            Ray::new(origin, direction, f32::INFINITY)
        })
        .collect()
}

const SURFACE_RAYS: usize = 4096;

#[divan::bench]
fn bunny_surface_occluded(bencher: divan::Bencher<'_, '_>) {
    bunny_surface_occluded_with(bencher, true);
}

/// The same rays on the portable path, four lanes at a time, instead of AVX's
/// eight (the same answers).
#[divan::bench]
fn bunny_surface_occluded_four_lanes(bencher: divan::Bencher<'_, '_>) {
    bunny_surface_occluded_with(bencher, false);
}

/// Occlusion of the bunny's surface rays, with or without the AVX kernels
/// (`BvhScene::with_avx`: eight child boxes, two leaves per pass).
fn bunny_surface_occluded_with(bencher: divan::Bencher<'_, '_>, wide: bool) {
    let (positions, indices) = bunny();
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let scene = BvhScene::new(&mesh).unwrap().with_avx(wide);
    let rays = surface_rays(&mesh, SURFACE_RAYS);
    bencher
        .counter(divan::counter::ItemsCount::new(SURFACE_RAYS))
        .bench_local(|| rays.iter().filter(|r| scene.occluded(r)).count());
}

#[divan::bench]
fn bunny_surface_closest_hit(bencher: divan::Bencher<'_, '_>) {
    let (positions, indices) = bunny();
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let scene = BvhScene::new(&mesh).unwrap();
    let rays = surface_rays(&mesh, SURFACE_RAYS);
    bencher
        .counter(divan::counter::ItemsCount::new(SURFACE_RAYS))
        .bench_local(|| rays.iter().filter_map(|r| scene.closest_hit(r)).count());
}

/// obvhs's own traversal and Möller–Trumbore on the same surface rays (closest
/// hit: obvhs has no any-hit entry point), for scale.
#[divan::bench]
fn bunny_surface_obvhs_native_closest_hit(bencher: divan::Bencher<'_, '_>) {
    use obvhs::{BvhBuildParams, cwbvh::builder::build_cwbvh_from_tris, ray::RayHit};
    let (positions, indices) = bunny();
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let triangles: Vec<obvhs::triangle::Triangle> = mesh
        .triangles()
        .map(|[a, b, c]| obvhs::triangle::Triangle {
            v0: a.into(),
            v1: b.into(),
            v2: c.into(),
        })
        .collect();
    let mut build_time = core::time::Duration::ZERO;
    let bvh = build_cwbvh_from_tris(&triangles, BvhBuildParams::medium_build(), &mut build_time);
    let rays: Vec<obvhs::ray::Ray> = surface_rays(&mesh, SURFACE_RAYS)
        .iter()
        .map(|r| obvhs::ray::Ray::new_inf(r.origin.into(), r.direction.into()))
        .collect();
    bencher
        .counter(divan::counter::ItemsCount::new(SURFACE_RAYS))
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
