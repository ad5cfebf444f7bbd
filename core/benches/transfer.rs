//! Precomputed transfer at run time and at bake time, each next to its baseline in
//! the same run:
//!
//! - per-vertex shading (`shade/*`, 32 (in cache) or 2,048 vertices per iteration, one view and one
//!   random normal per vertex, RGB lighting) at 4, 5 and 6 bands: diffuse PRT (a
//!   dot product), glossy SH transfer (the 2002 baseline: view-first `(Tᵀw)·l`, and
//!   the published form `T·l` per channel, both as the serial reference
//!   (`glossy_sh_textbook`) and in MRT's four-lane style (`glossy_sh_2002`)), MRT 12×12 (four rows blended) and MRT
//!   from its PCA at K = 4, 8 and 16 (per vertex only; the per-frame products are
//!   `pca_frame_terms`). MRT's cost does not depend on the grid size (always four
//!   rows), only its memory does.
//! - the batch entry `TransferSet::shade` (`shade_batch/*`) at 4, 5 and 6 bands on
//!   a 2,112-vertex mesh: what an engine pays per vertex, per-call work included.
//! - bake throughput (`bake/*`): rays per second through the obvhs BVH on a
//!   4,000-triangle bumpy sphere, occlusion rays only (0 bounces) and with one
//!   closest-hit bounce, one thread.
//!
//! Run: `cargo bench -p antumbra-core --features bvh --bench transfer`.

use antumbra_core::Frame;
use antumbra_core::MeshView;
use antumbra_core::raycast::BvhScene;
use antumbra_core::transfer::{
    BakeOptions, GlossyLobe, Measurement, Pca, PhongBrdf, ShLighting, bake_serial, mrt_tap,
    shade_diffuse, shade_glossy_sh, shade_glossy_sh_2002, shade_glossy_sh_reference, shade_mrt,
    shade_mrt_pca,
};
use glam::Vec3;
use rand::{Rng, SeedableRng, rngs::SmallRng};

fn main() {
    divan::main();
}

const GRID: u32 = 12;
/// 32 vertices keep every kernel's data in L1/L2 (compute cost); 2,048 stream
/// from memory (uncompressed MRT at 12×12 and 25 coefficients is 14 KB per vertex,
/// 29 MB in all, and each vertex reads four rows at view-dependent places).
const VERTEX_COUNTS: [usize; 2] = [32, 2048];

struct Inputs {
    normals: Vec<Vec3>,
    frames: Vec<Frame>,
    views: Vec<Vec3>,
    lighting: Vec<[f32; 3]>,
    /// The same lighting split per channel (built once per frame by a renderer).
    planar: ShLighting,
    data: Vec<f32>,
}

fn unit(rng: &mut SmallRng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.length() > 0.1 && v.length() <= 1.0 {
            break v.normalize();
        }
    }
}

/// Random blocks of `block` values per vertex, normals, and views in front of
/// each vertex (so no kernel takes its early exit).
fn inputs(n: usize, block: usize, vertices: usize) -> Inputs {
    let mut rng = SmallRng::seed_from_u64(9);
    let normals: Vec<Vec3> = (0..vertices).map(|_| unit(&mut rng)).collect();
    let views = normals
        .iter()
        .map(|&nrm| {
            let v = unit(&mut rng);
            (if v.dot(nrm) < 0.0 { -v } else { v } + 0.2 * nrm).normalize()
        })
        .collect();
    let lighting: Vec<[f32; 3]> = (0..n)
        .map(|_| [rng.random(), rng.random(), rng.random()])
        .collect();
    Inputs {
        frames: normals.iter().map(|&n| Frame::from_normal(n)).collect(),
        normals,
        views,
        planar: ShLighting::new(&lighting).unwrap(),
        lighting,
        data: (0..vertices * block)
            .map(|_| rng.random_range(-1.0..1.0))
            .collect(),
    }
}

#[divan::bench_group(name = "shade")]
mod shade {
    use super::*;

    #[divan::bench(consts = [16, 25, 36], args = VERTEX_COUNTS)]
    fn diffuse<const N: usize>(bencher: divan::Bencher<'_, '_>, vertices: usize) {
        let inp = inputs(N, N, vertices);
        bencher
            .counter(divan::counter::ItemsCount::new(vertices))
            .bench_local(|| {
                let mut acc = Vec3::ZERO;
                for v in 0..vertices {
                    acc += shade_diffuse(&inp.data[v * N..(v + 1) * N], &inp.lighting);
                }
                divan::black_box(acc)
            });
    }

    #[divan::bench(consts = [16, 25, 36], args = VERTEX_COUNTS)]
    fn glossy_sh<const N: usize>(bencher: divan::Bencher<'_, '_>, vertices: usize) {
        let inp = inputs(N, N * N, vertices);
        let bands = (N as f32).sqrt() as u32;
        let lobe = GlossyLobe::phong(bands, 16.0).unwrap();
        bencher
            .counter(divan::counter::ItemsCount::new(vertices))
            .bench_local(|| {
                let mut acc = Vec3::ZERO;
                for v in 0..vertices {
                    acc += shade_glossy_sh(
                        &inp.data[v * N * N..(v + 1) * N * N],
                        &lobe,
                        &inp.planar,
                        inp.normals[v],
                        inp.views[v],
                    );
                }
                divan::black_box(acc)
            });
    }

    #[divan::bench(consts = [16, 25, 36], args = VERTEX_COUNTS)]
    fn glossy_sh_textbook<const N: usize>(bencher: divan::Bencher<'_, '_>, vertices: usize) {
        let inp = inputs(N, N * N, vertices);
        let bands = (N as f32).sqrt() as u32;
        let lobe = GlossyLobe::phong(bands, 16.0).unwrap();
        bencher
            .counter(divan::counter::ItemsCount::new(vertices))
            .bench_local(|| {
                let mut acc = Vec3::ZERO;
                for v in 0..vertices {
                    acc += shade_glossy_sh_reference(
                        &inp.data[v * N * N..(v + 1) * N * N],
                        &lobe,
                        &inp.lighting,
                        inp.normals[v],
                        inp.views[v],
                    );
                }
                divan::black_box(acc)
            });
    }

    /// The published order written like the MRT kernel (four lanes, fixed size).
    #[divan::bench(consts = [16, 25, 36], args = VERTEX_COUNTS)]
    fn glossy_sh_2002<const N: usize>(bencher: divan::Bencher<'_, '_>, vertices: usize) {
        let inp = inputs(N, N * N, vertices);
        let bands = (N as f32).sqrt() as u32;
        let lobe = GlossyLobe::phong(bands, 16.0).unwrap();
        bencher
            .counter(divan::counter::ItemsCount::new(vertices))
            .bench_local(|| {
                let mut acc = Vec3::ZERO;
                for v in 0..vertices {
                    acc += shade_glossy_sh_2002(
                        &inp.data[v * N * N..(v + 1) * N * N],
                        &lobe,
                        &inp.planar,
                        inp.normals[v],
                        inp.views[v],
                    );
                }
                divan::black_box(acc)
            });
    }

    #[divan::bench(consts = [16, 25, 36], args = VERTEX_COUNTS)]
    fn mrt<const N: usize>(bencher: divan::Bencher<'_, '_>, vertices: usize) {
        let block = (GRID * GRID) as usize * N;
        let inp = inputs(N, block, vertices);
        bencher
            .counter(divan::counter::ItemsCount::new(vertices))
            .bench_local(|| {
                let mut acc = Vec3::ZERO;
                for v in 0..vertices {
                    acc += shade_mrt(
                        &inp.data[v * block..(v + 1) * block],
                        GRID,
                        &inp.planar,
                        &inp.frames[v],
                        inp.views[v],
                    );
                }
                divan::black_box(acc)
            });
    }

    /// The view-dependent part of MRT alone: view to local frame, hemi-octahedral
    /// cell, four node indices and weights.
    #[divan::bench(args = VERTEX_COUNTS)]
    fn mrt_tap_only(bencher: divan::Bencher<'_, '_>, vertices: usize) {
        let inp = inputs(1, 1, vertices);
        bencher
            .counter(divan::counter::ItemsCount::new(vertices))
            .bench_local(|| {
                let mut acc = 0.0f32;
                for v in 0..vertices {
                    if let Some(t) = mrt_tap(GRID, inp.frames[v].to_local(inp.views[v])) {
                        acc += t.weights[0] + t.nodes[3] as f32;
                    }
                }
                divan::black_box(acc)
            });
    }

    #[divan::bench(args = [4, 8, 16])]
    fn mrt_pca_25(bencher: divan::Bencher<'_, '_>, k: usize) {
        let vertices = 2048;
        // Per vertex only: K weights, and the per-frame terms (random here; their
        // cost is `pca_frame_terms`).
        let rows = (GRID * GRID) as usize;
        let inp = inputs(25, k, vertices);
        let mut rng = SmallRng::seed_from_u64(4);
        let terms: Vec<[f32; 3]> = (0..rows * (k + 1))
            .map(|_| [rng.random(), rng.random(), rng.random()])
            .collect();
        bencher
            .counter(divan::counter::ItemsCount::new(vertices))
            .bench_local(|| {
                let mut acc = Vec3::ZERO;
                for v in 0..vertices {
                    acc += shade_mrt_pca(
                        &inp.data[v * k..(v + 1) * k],
                        &terms,
                        k,
                        GRID,
                        &inp.frames[v],
                        inp.views[v],
                    );
                }
                divan::black_box(acc)
            });
    }
}

/// A bumpy sphere: `rings × segments` quads, radius modulated so that bumps shadow
/// their neighbours.
fn bumpy_sphere(rings: u32, segments: u32) -> (Vec<[f32; 3]>, Vec<u32>, Vec<Vec3>) {
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let dir = Vec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            let radius = 1.0 + 0.15 * (5.0 * theta).sin() * (7.0 * phi).sin();
            positions.push((dir * radius).to_array());
            normals.push(dir);
        }
    }
    let mut indices = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = r * segments + s;
            let b = r * segments + (s + 1) % segments;
            indices.extend_from_slice(&[a, b, b + segments, a, b + segments, a + segments]);
        }
    }
    (positions, indices, normals)
}

#[divan::bench_group(name = "bake", sample_count = 5, sample_size = 1)]
mod bake_group {
    use super::*;

    fn run(bencher: divan::Bencher<'_, '_>, bounces: u32) {
        let (positions, indices, normals) = bumpy_sphere(32, 64);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let bvh = BvhScene::new(&mesh).unwrap();
        let rays = 64u32;
        let options = BakeOptions {
            bands: 3,
            rays,
            bounces,
            ray_offset: 1e-3,
            ..BakeOptions::new(Measurement::Diffuse)
        };
        let total = mesh.vertex_count() * rays as usize * (bounces as usize + 1);
        bencher
            .counter(divan::counter::ItemsCount::new(total))
            .bench_local(|| bake_serial(&mesh, &normals, &bvh, &options).unwrap());
    }

    /// Occlusion rays only.
    #[divan::bench]
    fn direct_rays(bencher: divan::Bencher<'_, '_>) {
        run(bencher, 0);
    }

    /// Half occlusion, half closest-hit rays with interpolation at the hit.
    #[divan::bench]
    fn one_bounce_rays(bencher: divan::Bencher<'_, '_>) {
        run(bencher, 1);
    }
}

/// The batch entry `TransferSet::shade` (what the C ABI and the CLI call) over a
/// 2,112-vertex bumpy sphere, one thread, eye outside: per-vertex cost including
/// the per-call work (lighting split, PCA frame terms) and the view vectors.
#[divan::bench_group(name = "shade_batch", sample_count = 30)]
mod shade_batch {
    use super::*;
    use antumbra_core::transfer::{Material, TransferSet, View};

    fn set(measurement: Measurement<'_>, bands: u32) -> TransferSet {
        let (positions, indices, normals) = bumpy_sphere(32, 64);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let bvh = BvhScene::new(&mesh).unwrap();
        let options = BakeOptions {
            bands,
            rays: 4,
            ray_offset: 1e-3,
            ..BakeOptions::new(measurement)
        };
        bake_serial(&mesh, &normals, &bvh, &options).unwrap()
    }

    fn run(bencher: divan::Bencher<'_, '_>, set: &TransferSet, k: Option<usize>) {
        let n = set.coeff_count();
        let lighting: Vec<[f32; 3]> = (0..n).map(|i| [0.5, 0.4, 0.3 / (i + 1) as f32]).collect();
        let mut out = vec![[0.0f32; 3]; set.vertex_count()];
        let material = Material::glossy(1.0);
        bencher
            .counter(divan::counter::ItemsCount::new(set.vertex_count()))
            .bench_local(|| {
                set.shade(
                    &lighting,
                    View::Eye([0.3, 2.5, 3.0]),
                    &material,
                    k,
                    &mut out,
                )
                .unwrap();
                divan::black_box(out[0])
            });
    }

    #[divan::bench(args = [4, 5, 6])]
    fn diffuse(bencher: divan::Bencher<'_, '_>, bands: u32) {
        run(bencher, &set(Measurement::Diffuse, bands), None);
    }

    #[divan::bench(args = [4, 5, 6])]
    fn glossy_sh(bencher: divan::Bencher<'_, '_>, bands: u32) {
        run(bencher, &set(Measurement::GlossySh, bands), None);
    }

    #[divan::bench(args = [4, 5, 6])]
    fn mrt(bencher: divan::Bencher<'_, '_>, bands: u32) {
        let brdf = PhongBrdf::new(16.0).unwrap();
        let m = Measurement::Mrt {
            grid: GRID,
            brdf: &brdf,
        };
        run(bencher, &set(m, bands), None);
    }

    /// MRT from its PCA with K = 4 (per-frame products included).
    #[divan::bench(args = [4, 5, 6])]
    fn mrt_pca_k4(bencher: divan::Bencher<'_, '_>, bands: u32) {
        let brdf = PhongBrdf::new(16.0).unwrap();
        let m = Measurement::Mrt {
            grid: GRID,
            brdf: &brdf,
        };
        run(bencher, &set(m, bands).compress(4).unwrap(), Some(4));
    }
}

/// Per-frame cost of rendering from PCA: `K + 1` products of a `G² × 25` matrix
/// with RGB lighting.
#[divan::bench(args = [4, 8, 16])]
fn pca_frame_terms(bencher: divan::Bencher<'_, '_>, k: usize) {
    let (positions, indices, normals) = bumpy_sphere(6, 12);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let bvh = BvhScene::new(&mesh).unwrap();
    let brdf = PhongBrdf::new(8.0).unwrap();
    let options = BakeOptions {
        bands: 5,
        rays: 16,
        ray_offset: 1e-3,
        ..BakeOptions::new(Measurement::Mrt {
            grid: GRID,
            brdf: &brdf,
        })
    };
    let set = bake_serial(&mesh, &normals, &bvh, &options).unwrap();
    let compressed = set.compress(k).unwrap();
    let pca: &Pca = compressed.pca().unwrap();
    let lighting = vec![[0.5f32, 0.4, 0.3]; 25];
    let mut out = vec![[0.0f32; 3]; pca.frame_terms_len(k)];
    bencher.bench_local(|| {
        pca.frame_terms(&lighting, k, &mut out);
        divan::black_box(out[0])
    });
}
