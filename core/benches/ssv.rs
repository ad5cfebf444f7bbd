//! Soft shadow volumes: time per receiver for every structure, in the same run,
//! same samples, one thread.
//!
//! Scenes (N = 256 jittered samples, light tilts as the bench argument):
//!
//! - `bumpy`: a bumpy closed sphere (40 × 80 grid, 6,240 triangles, radius ~1)
//!   one unit above a 20 × 20 floor (800 triangles), a 1 × 1 quad light 5 units
//!   above the floor, tilted about the y axis by 0, 0.7 or 1.4 rad; receivers: a
//!   16 × 16 grid on the floor around the sphere's shadow (penumbra-heavy).
//! - `torus`: the scene of `c_examples/soft_shadows.c` (a torus tilted 35° and
//!   a sphere over a two-triangle floor, 2,562 triangles; a 1.2 × 1.2 square
//!   light at height 3.2 turned 20° about the vertical and tipped about x by
//!   0.17 (the example's 10°), 0.7 or 1.4 rad); receivers: a dense 64 × 64 grid
//!   over the floor `[-2.5, 2.5]²` (every receiver lies on the floor).
//! - `bunny`: `tests/data/bunny.obj` (y up, turned z up, scaled to ~1.9 high,
//!   0.3 above a two-triangle floor), a 1.5 × 1.5 quad light 5 above the floor
//!   tilted about y by 0, 0.7 or 1.4 rad; receivers: a 64 × 64 floor grid over
//!   `[-3, 3]²`.
//!
//! `main` prints, per scene and tilt: the hierarchy's construction (creation,
//! then the first pass over every receiver, which builds the nodes lazily),
//! then per-receiver medians (of 5 interleaved passes, ratios per pass) for the hierarchy, the hemicube, brute
//! force (over every 8th receiver) and plain `BvhScene` rays (256 `occluded`
//! per receiver), their ratios, candidates per query, nodes and bytes, and the
//! bits of every structure checked against the hierarchy's. Then the divan
//! benchmarks on `bumpy` (`receiver::<S>` per structure, hierarchy warmed;
//! `bvh_rays`). `SSV_REPORT_ONLY=1` skips divan; `SSV_LEAF_EDGES` and
//! `SSV_MAX_DEPTH` override the hierarchy's defaults. Run:
//! `cargo bench -p antumbra-core --features bvh --bench ssv`.

use std::time::Instant;

use antumbra_core::glam::Vec3;
use antumbra_core::raycast::BvhScene;
use antumbra_core::ssv::{LightPolygon, SamplePattern, SoftShadows, SsvOptions, Structure};
use antumbra_core::{MeshView, Ray, RayCaster};

const SAMPLES: usize = 256;
const WORDS: usize = SAMPLES / 64;

struct Scene {
    name: &'static str,
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
    light: LightPolygon,
    samples: Vec<Vec3>,
    receivers: Vec<Vec3>,
}

fn floor_quad(positions: &mut Vec<[f32; 3]>, indices: &mut Vec<u32>, half: f32) {
    let base = positions.len() as u32;
    positions.extend([
        [-half, -half, 0.0],
        [half, -half, 0.0],
        [half, half, 0.0],
        [-half, half, 0.0],
    ]);
    indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
}

fn grid(side: usize, lo: f32, hi: f32) -> Vec<Vec3> {
    let step = (hi - lo) / side as f32;
    (0..side * side)
        .map(|k| {
            Vec3::new(
                lo + step * ((k % side) as f32 + 0.5),
                lo + step * ((k / side) as f32 + 0.5),
                0.0,
            )
        })
        .collect()
}

fn quad_grid(
    positions: &[[f32; 3]],
    indices: &mut Vec<u32>,
    rows: u32,
    cols: u32,
    wrap_rows: bool,
) {
    let base = positions.len() as u32 - rows * cols;
    let row_end = if wrap_rows { rows } else { rows - 1 };
    for i in 0..row_end {
        for j in 0..cols {
            let at = |i: u32, j: u32| base + (i % rows) * cols + j % cols;
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            indices.extend([a, b, c, a, c, d]);
        }
    }
}

impl Scene {
    fn bumpy(tilt: f32) -> Self {
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
            name: "bumpy",
            positions,
            indices,
            light,
            samples,
            receivers,
        }
    }

    /// The scene of `c_examples/soft_shadows.c`, the light tipped by `tip`.
    fn torus(tip: f32) -> Self {
        use core::f32::consts::{PI, TAU};
        let (mut positions, mut indices) = (Vec::new(), Vec::new());
        let (rings, sides) = (48u32, 16u32);
        let (ct, st) = (35f32.to_radians().cos(), 35f32.to_radians().sin());
        for i in 0..rings {
            let u = TAU * i as f32 / rings as f32;
            for j in 0..sides {
                let w = TAU * j as f32 / sides as f32;
                let r = 0.7 + 0.2 * w.cos();
                let (x, y, z) = (r * u.cos(), r * u.sin(), 0.2 * w.sin());
                positions.push([-0.2 + x, 0.3 + ct * y - st * z, 1.1 + st * y + ct * z]);
            }
        }
        quad_grid(&positions, &mut indices, rings, sides, true);
        let (slices, stacks) = (32u32, 16u32);
        for i in 0..=stacks {
            let polar = PI * i as f32 / stacks as f32;
            for j in 0..=slices {
                let azimuth = TAU * (j % slices) as f32 / slices as f32;
                positions.push([
                    0.95 + 0.35 * polar.sin() * azimuth.cos(),
                    -0.7 + 0.35 * polar.sin() * azimuth.sin(),
                    0.5 + 0.35 * polar.cos(),
                ]);
            }
        }
        let base = positions.len() as u32 - (stacks + 1) * (slices + 1);
        for i in 0..stacks {
            for j in 0..slices {
                let at = |i: u32, j: u32| base + i * (slices + 1) + j;
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                indices.extend([a, b, c, a, c, d]);
            }
        }
        floor_quad(&mut positions, &mut indices, 3.5);
        let turn = 20f32.to_radians();
        let corners: Vec<Vec3> = [(-0.6, -0.6), (0.6, -0.6), (0.6, 0.6), (-0.6, 0.6)]
            .iter()
            .map(|&(cx, cy): &(f32, f32)| {
                let x = turn.cos() * cx - turn.sin() * cy;
                let y = turn.sin() * cx + turn.cos() * cy;
                Vec3::new(0.3 + x, 0.1 + tip.cos() * y, 3.2 + tip.sin() * y)
            })
            .collect();
        let light = LightPolygon::new(&corners).unwrap();
        let samples = light.samples(SAMPLES, SamplePattern::Jittered, 20_060_905);
        Scene {
            name: "torus",
            positions,
            indices,
            light,
            samples,
            receivers: grid(64, -2.5, 2.5),
        }
    }

    fn bunny(tilt: f32) -> Self {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/bunny.obj");
        let (models, _) = tobj::load_obj(
            path,
            &tobj::LoadOptions {
                triangulate: true,
                single_index: true,
                ..Default::default()
            },
        )
        .expect("tests/data/bunny.obj");
        let (mut positions, mut indices) = (Vec::new(), Vec::new());
        for m in &models {
            let base = positions.len() as u32;
            // y up to z up (x, y, z) -> (x, -z, y), scaled by 0.2, lifted 0.3.
            positions.extend(
                m.mesh
                    .positions
                    .chunks(3)
                    .map(|v| [0.2 * v[0], -0.2 * v[2], 0.3 + 0.2 * v[1]]),
            );
            indices.extend(m.mesh.indices.iter().map(|&i| base + i));
        }
        floor_quad(&mut positions, &mut indices, 4.0);
        let (c, s) = (tilt.cos(), tilt.sin());
        let corner = |x: f32, y: f32| Vec3::new(0.5 + x * c, 0.3 + y, 5.0 + x * s);
        let light = LightPolygon::new(&[
            corner(-0.75, -0.75),
            corner(0.75, -0.75),
            corner(0.75, 0.75),
            corner(-0.75, 0.75),
        ])
        .unwrap();
        let samples = light.samples(SAMPLES, SamplePattern::Jittered, 7);
        Scene {
            name: "bunny",
            positions,
            indices,
            light,
            samples,
            receivers: grid(64, -3.0, 3.0),
        }
    }

    fn view(&self) -> MeshView<'_> {
        MeshView::new(&self.positions, &self.indices).unwrap()
    }

    fn build(&self, structure: Structure) -> SoftShadows {
        // SSV_LEAF_EDGES / SSV_MAX_DEPTH override the defaults (for tuning).
        let env = |name: &str| std::env::var(name).ok().and_then(|v| v.parse().ok());
        let defaults = SsvOptions::default();
        let options = SsvOptions {
            structure,
            leaf_edges: env("SSV_LEAF_EDGES").unwrap_or(defaults.leaf_edges),
            max_depth: env("SSV_MAX_DEPTH").unwrap_or(defaults.max_depth),
            ..defaults
        };
        SoftShadows::new(&self.view(), self.light.clone(), &self.samples, options).unwrap()
    }
}

const TILTS: [f32; 3] = [0.0, 0.7, 1.4];
const TIPS: [f32; 3] = [0.174_532_93, 0.7, 1.4];

fn main() {
    if std::env::var_os("SSV_PROFILE").is_some() {
        // Hierarchy queries only (for a profiler), construction done first.
        for scene in [
            Scene::torus(TIPS[0]),
            Scene::bunny(TILTS[0]),
            Scene::bumpy(TILTS[1]),
        ] {
            let ss = scene.build(Structure::Hierarchy);
            let mut out = [0u64; WORDS];
            for _ in 0..20 {
                for &p in &scene.receivers {
                    std::hint::black_box(ss.query(p, &mut out).unwrap());
                }
            }
        }
        return;
    }
    for tilt in TILTS {
        report(&Scene::bumpy(tilt), tilt);
    }
    for tip in TIPS {
        report(&Scene::torus(tip), tip);
    }
    for tilt in TILTS {
        report(&Scene::bunny(tilt), tilt);
    }
    if std::env::var_os("SSV_REPORT_ONLY").is_none() {
        divan::main();
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Seconds per receiver of one pass of `f` over `receivers`.
fn pass(receivers: &[Vec3], f: &mut dyn FnMut(Vec3) -> u32) -> f64 {
    let start = Instant::now();
    let mut total = 0u64;
    for &p in receivers {
        total += u64::from(f(p));
    }
    std::hint::black_box(total);
    start.elapsed().as_secs_f64() / receivers.len() as f64
}

const PASSES: usize = 5;

fn report(scene: &Scene, tilt: f32) {
    let n = scene.receivers.len();
    println!(
        "ssv {} (light tilt {tilt} rad): {} triangles, {} samples, {} receivers",
        scene.name,
        scene.indices.len() / 3,
        SAMPLES,
        n
    );
    // Brute force runs on every 8th receiver (its bits are checked against the
    // hierarchy's on those).
    let sparse: Vec<Vec3> = scene.receivers.iter().step_by(8).copied().collect();
    let mut reference: Vec<u64> = Vec::new();
    let mut sets = Vec::new();
    for (slot, structure) in [
        Structure::Hierarchy,
        Structure::Hemicube,
        Structure::BruteForce,
    ]
    .into_iter()
    .enumerate()
    {
        let start = Instant::now();
        let ss = scene.build(structure);
        let created = start.elapsed().as_secs_f64();
        let receivers = if structure == Structure::BruteForce {
            &sparse
        } else {
            &scene.receivers
        };
        let start = Instant::now();
        let (mut candidates, mut bits) = (0u64, vec![0u64; receivers.len() * WORDS]);
        for (k, &p) in receivers.iter().enumerate() {
            let info = ss
                .query_detailed(p, &mut bits[k * WORDS..][..WORDS])
                .unwrap();
            candidates += u64::from(info.candidates);
        }
        let first = start.elapsed().as_secs_f64();
        let stats = ss.statistics();
        println!(
            "  {structure:?}: {:.1} candidates/query, {} nodes, {:.2} MiB; created in {:.1} ms, first pass (lazy construction included) {:.1} ms",
            candidates as f64 / receivers.len() as f64,
            stats.nodes,
            stats.bytes as f64 / (1024.0 * 1024.0),
            created * 1e3,
            first * 1e3,
        );
        if slot == 0 {
            reference = bits;
        } else {
            let step = if structure == Structure::BruteForce {
                8
            } else {
                1
            };
            let mismatches: u32 = bits
                .chunks(WORDS)
                .enumerate()
                .map(|(k, b)| {
                    b.iter()
                        .zip(&reference[k * step * WORDS..][..WORDS])
                        .map(|(x, y)| (x ^ y).count_ones())
                        .sum::<u32>()
                })
                .sum();
            println!("    bits differing from the hierarchy: {mismatches}");
        }
        sets.push((ss, receivers));
    }
    let bvh = BvhScene::new(&scene.view()).unwrap();
    // Interleaved passes (hierarchy, hemicube, brute force, rays) so that the
    // ratios of one pass see the same machine load; medians over the passes.
    let mut times: [Vec<f64>; 4] = Default::default();
    let mut ratios: [Vec<f64>; 3] = Default::default();
    let mut out = [0u64; WORDS];
    for _ in 0..PASSES {
        let mut t = [0.0; 4];
        for (k, (ss, receivers)) in sets.iter().enumerate() {
            t[k] = pass(receivers, &mut |p| ss.query(p, &mut out).unwrap());
        }
        t[3] = pass(&scene.receivers, &mut |p| {
            scene
                .samples
                .iter()
                .filter(|&&s| !bvh.occluded(&Ray::new(p, s - p, 1.0)))
                .count() as u32
        });
        for k in 0..4 {
            times[k].push(t[k]);
        }
        ratios[0].push(t[3] / t[0]);
        ratios[1].push(t[1] / t[0]);
        ratios[2].push(t[2] / t[0]);
    }
    let [h, c, b, r] = times.map(|v| median(v) * 1e6);
    let [rr, rc, rb] = ratios.map(median);
    println!(
        "  us/receiver (median of {PASSES} interleaved passes): hierarchy {h:.2}, hemicube {c:.2}, brute force {b:.1}, BvhScene rays {r:.1}; hierarchy faster than rays {rr:.1}x, than hemicube {rc:.2}x, than brute force {rb:.1}x"
    );
}

#[divan::bench(types = [HierarchyS, HemicubeS, BruteForceS, RayTraceS], args = TILTS)]
fn receiver<S: Pick>(bencher: divan::Bencher<'_, '_>, tilt: f32) {
    let scene = Scene::bumpy(tilt);
    let ss = scene.build(S::STRUCTURE);
    let mut bits = [0u64; WORDS];
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
    let scene = Scene::bumpy(tilt);
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
