//! Soft shadow volumes: time per receiver for every structure on one scene, in
//! the same run, same samples, one thread.
//!
//! Scene: a bumpy closed sphere (40 × 80 grid, 6,240 triangles, radius ~1) one
//! unit above a 20 × 20 floor (800 triangles), a 1 × 1 quad light 5 units above
//! the floor, tilted about the y axis by 0, 0.7 or 1.4 rad (the bench argument:
//! light orientation); 256 jittered samples. Receivers: a 16 × 16 grid on
//! the floor around the sphere's shadow (a penumbra-heavy set).
//!
//! - `receiver::<S>`: microseconds per receiver for `Hierarchy`, `Hemicube`,
//!   `BruteForce` and `RayTrace` (the structure's own N verified rays);
//!   the hierarchy is warmed (every receiver queried once) before timing, so
//!   the lazy node construction is not in the figure;
//! - `bvh_rays`: the plain baseline, 256 `occluded` rays per receiver through
//!   the same kind of `BvhScene`.
//!
//! `main` prints candidates per query, silhouettes per query, nodes and bytes
//! of each structure before the timings, then the hemicube at 16² to 128² cells
//! per face (candidates, memory, a rough best-of-five time per receiver). Run:
//! `cargo bench -p antumbra-core --features bvh --bench ssv`.

use antumbra_core::glam::Vec3;
use antumbra_core::raycast::BvhScene;
use antumbra_core::ssv::{LightPolygon, SamplePattern, SoftShadows, SsvOptions, Structure};
use antumbra_core::{MeshView, Ray, RayCaster};

const SAMPLES: usize = 256;

struct Scene {
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
    light: LightPolygon,
    samples: Vec<Vec3>,
    receivers: Vec<Vec3>,
}

impl Scene {
    fn new(tilt: f32) -> Self {
        let (rings, segments) = (40u32, 80u32);
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        for r in 0..=rings {
            let theta = core::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..segments {
                let phi = core::f32::consts::TAU * s as f32 / segments as f32;
                let radius = 1.0 + 0.2 * (5.0 * theta).sin() * (4.0 * phi).sin();
                positions.push([
                    radius * theta.sin() * phi.cos(),
                    radius * theta.sin() * phi.sin(),
                    2.2 + radius * theta.cos(),
                ]);
            }
        }
        for r in 0..rings {
            for s in 0..segments {
                let at = |r: u32, s: u32| r * segments + s % segments;
                let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s), at(r + 1, s + 1));
                if r != 0 {
                    indices.extend([a, c, b]);
                }
                if r != rings - 1 {
                    indices.extend([b, c, d]);
                }
            }
        }
        let base = positions.len() as u32;
        let n = 20u32;
        for j in 0..=n {
            for i in 0..=n {
                positions.push([
                    -6.0 + 12.0 * i as f32 / n as f32,
                    -6.0 + 12.0 * j as f32 / n as f32,
                    0.0,
                ]);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let at = |i: u32, j: u32| base + j * (n + 1) + i;
                indices.extend([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                indices.extend([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        let (c, s) = (tilt.cos(), tilt.sin());
        let corner = |x: f32, y: f32| Vec3::new(0.8 + x * c, 0.3 + y, 5.0 + x * s);
        let light = LightPolygon::new(&[
            corner(-0.5, -0.5),
            corner(0.5, -0.5),
            corner(0.5, 0.5),
            corner(-0.5, 0.5),
        ])
        .unwrap();
        let samples = light.samples(SAMPLES, SamplePattern::Jittered, 1);
        let receivers = (0..16 * 16)
            .map(|k| {
                Vec3::new(
                    -2.5 + 0.25 * (k % 16) as f32,
                    -2.0 + 0.25 * (k / 16) as f32,
                    0.0,
                )
            })
            .collect();
        Scene {
            positions,
            indices,
            light,
            samples,
            receivers,
        }
    }

    fn view(&self) -> MeshView<'_> {
        MeshView::new(&self.positions, &self.indices).unwrap()
    }

    fn build(&self, structure: Structure) -> SoftShadows {
        let options = SsvOptions {
            structure,
            ..SsvOptions::default()
        };
        SoftShadows::new(&self.view(), self.light.clone(), &self.samples, options).unwrap()
    }
}

const STRUCTURES: [Structure; 4] = [
    Structure::Hierarchy,
    Structure::Hemicube,
    Structure::BruteForce,
    Structure::RayTrace,
];

const TILTS: [f32; 3] = [0.0, 0.7, 1.4];

fn main() {
    for tilt in TILTS {
        report(tilt);
    }
    divan::main();
}

fn report(tilt: f32) {
    let scene = Scene::new(tilt);
    println!(
        "ssv scene (light tilt {tilt} rad): {} triangles, {} samples, {} receivers",
        scene.indices.len() / 3,
        SAMPLES,
        scene.receivers.len()
    );
    let mut reference: Option<Vec<u64>> = None;
    for structure in STRUCTURES {
        let ss = scene.build(structure);
        let (mut candidates, mut silhouettes, mut visible) = (0u64, 0u64, 0u64);
        let mut all_bits = Vec::new();
        for &p in &scene.receivers {
            let mut bits = [0u64; SAMPLES / 64];
            let info = ss.query_detailed(p, &mut bits).unwrap();
            candidates += u64::from(info.candidates);
            silhouettes += u64::from(info.silhouettes);
            visible += u64::from(info.visible);
            all_bits.extend_from_slice(&bits);
        }
        let r = scene.receivers.len() as f64;
        let stats = ss.statistics();
        println!(
            "{structure:?}: {:.1} candidates/query, {:.1} silhouettes/query, {} potential edges, {} nodes, {} KiB, {:.1}% visible",
            candidates as f64 / r,
            silhouettes as f64 / r,
            stats.potential_edges,
            stats.nodes,
            stats.bytes / 1024,
            100.0 * visible as f64 / (r * SAMPLES as f64)
        );
        match &reference {
            None => reference = Some(all_bits),
            Some(bits) => {
                let mismatches: u32 = bits
                    .iter()
                    .zip(&all_bits)
                    .map(|(a, b)| (a ^ b).count_ones())
                    .sum();
                println!("  bits differing from the hierarchy: {mismatches}");
            }
        }
    }
    // The hemicube's resolution: candidates, memory and a rough mean time per
    // receiver (the fastest of five passes over the receivers after a warm-up
    // pass).
    for resolution in [16, 32, 64, 128] {
        let options = SsvOptions {
            structure: Structure::Hemicube,
            hemicube_resolution: resolution,
            ..SsvOptions::default()
        };
        let ss =
            SoftShadows::new(&scene.view(), scene.light.clone(), &scene.samples, options).unwrap();
        let mut bits = [0u64; SAMPLES / 64];
        for &p in &scene.receivers {
            ss.query(p, &mut bits).unwrap();
        }
        let stats = ss.statistics();
        let micros = (0..5)
            .map(|_| {
                let start = std::time::Instant::now();
                for &p in &scene.receivers {
                    ss.query(p, &mut bits).unwrap();
                }
                start.elapsed().as_secs_f64() * 1e6 / scene.receivers.len() as f64
            })
            .fold(f64::INFINITY, f64::min);
        println!(
            "  hemicube {resolution}²/face: {:.1} candidates/query, {} KiB, {micros:.1} µs/receiver (best pass)",
            stats.candidates as f64 / stats.queries as f64,
            stats.bytes / 1024
        );
    }
}

#[divan::bench(types = [HierarchyS, HemicubeS, BruteForceS, RayTraceS], args = TILTS)]
fn receiver<S: Pick>(bencher: divan::Bencher<'_, '_>, tilt: f32) {
    let scene = Scene::new(tilt);
    let ss = scene.build(S::STRUCTURE);
    let mut bits = [0u64; SAMPLES / 64];
    for &p in &scene.receivers {
        ss.query(p, &mut bits).unwrap();
    }
    let mut k = 0;
    bencher.bench_local(|| {
        k = (k + 1) % scene.receivers.len();
        ss.query(scene.receivers[k], &mut bits).unwrap()
    });
}

#[divan::bench(args = TILTS)]
fn bvh_rays(bencher: divan::Bencher<'_, '_>, tilt: f32) {
    let scene = Scene::new(tilt);
    let bvh = BvhScene::new(&scene.view()).unwrap();
    let mut k = 0;
    bencher.bench_local(|| {
        k = (k + 1) % scene.receivers.len();
        let p = scene.receivers[k];
        scene
            .samples
            .iter()
            .filter(|&&s| !bvh.occluded(&Ray::new(p, s - p, 1.0)))
            .count()
    });
}

trait Pick {
    const STRUCTURE: Structure;
}

struct HierarchyS;
struct HemicubeS;
struct BruteForceS;
struct RayTraceS;

impl Pick for HierarchyS {
    const STRUCTURE: Structure = Structure::Hierarchy;
}
impl Pick for HemicubeS {
    const STRUCTURE: Structure = Structure::Hemicube;
}
impl Pick for BruteForceS {
    const STRUCTURE: Structure = Structure::BruteForce;
}
impl Pick for RayTraceS {
    const STRUCTURE: Structure = Structure::RayTrace;
}
