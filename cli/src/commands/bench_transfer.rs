//! `antumbra bench transfer`: the run-time cost per vertex of the ways to relight
//! a baked mesh, the bake's ray throughput against obvhs and Embree on the same
//! rays, and PCA error and memory against the component count — all measured in
//! one run on one mesh, so the ratios compare like with like.
//!
//! Every time is the fastest of several repeats (the machine may be shared: a
//! slower repeat measures the other processes). Shading is timed on one thread (a
//! rayon pool of one), the eye at a fixed point, two ways: through
//! `TransferSet::shade` over every vertex (the batch call: per-call lighting split,
//! per-vertex view vectors), and through the per-vertex kernels (`shade_diffuse`,
//! `shade_glossy_sh`, `shade_glossy_sh_2002`, `shade_mrt`, `shade_mrt_pca`) with
//! the vertex frames and unit view directions computed beforehand, as an engine
//! keeps tangent frames per vertex. Glossy SH, the 2002 baseline, is timed in two
//! orders: view-first `(Tᵀw)·l` (what `TransferSet::shade` runs, `n² + 3n`
//! multiply-adds) and the published one, `T·l` per channel then the lobe
//! (`3n² + 3n`), written in the same four-lane style as MRT; its batch figure
//! comes from a loop doing `shade`'s per-vertex work. MRT is compared with both.
//! The PCA form's per-frame products are part of each timed pass. The bake is the
//! diffuse one (0 bounces: one occlusion ray and one SH evaluation per sample) on
//! one thread (`bake_serial`) and on all cores; the ray batch given to obvhs and
//! Embree is exactly the rays that bake casts, enumerated by
//! `transfer::bake_rays` with the bake's own options (the engine draws its rays
//! through the same function), each caster timed on one thread; obvhs twice,
//! one ray per `occluded` call and each vertex's rays in one `occluded_many`
//! call (the packets the bake traces). The one-thread
//! bake, obvhs and Embree are timed back to back in a few rounds and the fastest
//! of each is compared, with the slowest printed beside it; within a round the
//! bake and Embree each get the same number of passes, the fastest kept.

use std::hint::black_box;
use std::time::Duration;

use antumbra_core::raycast::BvhScene;
use antumbra_core::transfer::{
    GlossyLobe, Material, ShLighting, TransferSet, View, bake_rays, shade_diffuse, shade_glossy_sh,
    shade_glossy_sh_2002, shade_mrt, shade_mrt_pca,
};
use antumbra_core::{Frame, Ray, RayCaster};
use antumbra_tests::oracle::{OracleOptions, try_cast};
use glam::Vec3;

use super::format_rate;
use super::hemi::time_per_call;
use crate::builtin;
use crate::cli::BenchTransferArgs;
use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;
use crate::prt::{self, BakeConfig, BrdfChoice, Kind};

/// Phong exponent of the glossy SH run time and of the MRT bake (the same lobe).
const EXPONENT: f32 = 32.0;

/// Seed of the bakes.
const SEED: u64 = 7;

/// Repeats of every timing; the fastest is reported (the machine may be shared).
const REPEATS: u32 = 7;

/// Runs the benchmark.
pub fn run(args: &BenchTransferArgs) -> Result<()> {
    let mesh = match &args.mesh {
        Some(path) => TriangleMesh::load_obj(path)?,
        None => builtin::bunny()?,
    };
    let min_time = Duration::from_millis(args.min_time);
    let vertices = mesh.vertex_count();
    println!(
        "bench transfer: {} ({} vertices, {} triangles), {} rays per vertex, MRT grid {}×{}, Phong exponent {EXPONENT}, {} threads",
        mesh.name(),
        vertices,
        mesh.triangle_count(),
        args.rays,
        args.grid,
        args.grid,
        rayon::current_num_threads()
    );
    ray_throughput(&mesh, args, min_time)?;
    // Shading is compared on one thread: `TransferSet::shade` spreads vertices over
    // rayon's pool, so it runs inside a pool of one.
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| Error::msg(format!("cannot build a one-thread pool: {e}")))?;
    for &bands in &args.bands {
        println!();
        one.install(|| shading_costs(&mesh, args, bands, min_time))?;
    }
    Ok(())
}

fn config(kind: Kind, bands: u32, args: &BenchTransferArgs) -> Result<BakeConfig> {
    Ok(BakeConfig {
        kind,
        bands,
        grid: args.grid,
        bounces: 0,
        rays: args.rays,
        albedo: 0.5,
        brdf: BrdfChoice::phong(EXPONENT)?,
        seed: SEED,
        ray_offset: prt::default_ray_offset(),
    })
}

/// Rounds of the one-thread throughput comparison: each round times the bake, our
/// caster and Embree once, back to back, so a burst of load from other processes
/// hits all three alike; the fastest of each over the rounds is compared (the
/// machine may be shared: a slower pass measures the other processes).
const ROUNDS: usize = 3;

/// Timed passes of Embree's batch per round (the oracle reports the fastest).
const EMBREE_PASSES: u32 = 5;

/// One-thread bakes per round, the fastest kept: as many as Embree's passes, so
/// that neither side of the ratio gets more tries at a quiet moment.
const BAKE_PASSES: u32 = EMBREE_PASSES;

/// The fastest over [`REPEATS`] runs of [`time_per_call`], each for
/// `min_time / REPEATS`.
fn fastest_time(min_time: Duration, mut work: impl FnMut()) -> Duration {
    (0..REPEATS)
        .map(|_| time_per_call(min_time / REPEATS, &mut work))
        .min()
        .unwrap_or(Duration::ZERO)
}

/// `(fastest, slowest)` of `rates`.
fn spread(rates: &[f64]) -> (f64, f64) {
    rates.iter().fold((0.0f64, f64::INFINITY), |(hi, lo), &r| {
        (hi.max(r), lo.min(r))
    })
}

/// The bake's rays per second on one thread and all cores, against obvhs and
/// Embree casting exactly the bake's rays on one thread.
fn ray_throughput(mesh: &TriangleMesh, args: &BenchTransferArgs, min_time: Duration) -> Result<()> {
    let bands = args.bands.first().copied().unwrap_or(4);
    let diffuse = config(Kind::Diffuse, bands, args)?;
    let warm_up = prt::bake_mesh(mesh, &diffuse, true, None)?;
    let rays = the_bakes_rays(mesh, &diffuse)?;
    if rays.len() as u64 != warm_up.rays_cast {
        return Err(Error::msg(format!(
            "bake_rays gave {} rays, the bake cast {}",
            rays.len(),
            warm_up.rays_cast
        )));
    }
    let bvh = BvhScene::new(&mesh.view()).map_err(|e| Error::msg(e.to_string()))?;
    let (mut bakes, mut ours, mut embrees) = (Vec::new(), Vec::new(), Vec::new());
    let mut packets = Vec::new();
    let mut answers = vec![false; rays.len()];
    let per_vertex = diffuse.rays as usize;
    let mut agree = None;
    for _ in 0..ROUNDS {
        let mut fastest = 0.0f64;
        for _ in 0..BAKE_PASSES {
            let serial = prt::bake_mesh(mesh, &diffuse, true, None)?;
            fastest = fastest.max(serial.rays_cast as f64 / serial.elapsed.as_secs_f64());
        }
        bakes.push(fastest);
        let elapsed = fastest_time(min_time, || {
            for ray in &rays {
                black_box(bvh.occluded(black_box(ray)));
            }
        });
        ours.push(rays.len() as f64 / elapsed.as_secs_f64());
        // As the bake traces them: each vertex's rays in one call.
        let elapsed = fastest_time(min_time, || {
            for (rays, answers) in rays.chunks(per_vertex).zip(answers.chunks_mut(per_vertex)) {
                bvh.occluded_many(black_box(rays), answers);
            }
            black_box(&answers);
        });
        packets.push(rays.len() as f64 / elapsed.as_secs_f64());
        if args.no_embree {
            continue;
        }
        let run = try_cast(
            mesh.positions(),
            mesh.indices(),
            &rays,
            OracleOptions {
                timing: true,
                timing_passes: EMBREE_PASSES,
                ..OracleOptions::default()
            },
        )
        .map_err(|e| Error::msg(format!("{e}\n(use --no-embree to skip this figure)")))?;
        let seconds = run.occluded_seconds.expect("timing was requested");
        embrees.push(rays.len() as f64 / seconds);
        agree.get_or_insert_with(|| {
            run.hits
                .iter()
                .zip(&rays)
                .filter(|(hit, ray)| hit.occluded == bvh.occluded(ray))
                .count()
        });
    }
    let parallel = prt::bake_mesh(mesh, &diffuse, false, None)?;
    let bake_parallel = parallel.rays_cast as f64 / parallel.elapsed.as_secs_f64();
    let ((bake, bake_low), (obvhs, obvhs_low)) = (spread(&bakes), spread(&ours));
    let (packet, packet_low) = spread(&packets);
    println!(
        "bake throughput ({bands} bands, diffuse, 0 bounces; occlusion rays; one thread: fastest of {ROUNDS} rounds, slowest in brackets):"
    );
    println!(
        "  bake, one thread        {:>16}  ({})  rays + SH evaluation + accumulation; fastest of {BAKE_PASSES} bakes per round",
        format_rate(bake, "rays"),
        format_rate(bake_low, "rays")
    );
    println!(
        "  bake, {} threads         {:>16}",
        rayon::current_num_threads(),
        format_rate(bake_parallel, "rays")
    );
    println!(
        "  obvhs occluded alone    {:>16}  ({})  {} rays: exactly the bake's, from transfer::bake_rays; fastest of {REPEATS} passes per round",
        format_rate(obvhs, "rays"),
        format_rate(obvhs_low, "rays"),
        rays.len()
    );
    println!(
        "  obvhs occluded_many     {:>16}  ({})  the same rays, each vertex's {per_vertex} in one call (packets from one origin, as the bake traces them)",
        format_rate(packet, "rays"),
        format_rate(packet_low, "rays"),
    );
    let Some(agree) = agree else {
        return Ok(());
    };
    let (embree, embree_low) = spread(&embrees);
    println!(
        "  Embree occluded         {:>16}  ({})  embreex, a batch rtcOccluded1 loop, fastest of {EMBREE_PASSES} passes per round; agrees with obvhs on {:.4} % of the rays",
        format_rate(embree, "rays"),
        format_rate(embree_low, "rays"),
        100.0 * agree as f64 / rays.len().max(1) as f64
    );
    let per_round: Vec<f64> = bakes.iter().zip(&embrees).map(|(b, e)| b / e).collect();
    let (round_high, round_low) = spread(&per_round);
    println!(
        "  ratios (one thread, fastest of each): bake / Embree {:.2} (per round {round_low:.2}–{round_high:.2}), occluded_many / Embree {:.2}, occluded / Embree {:.2} (goal: bake at least Embree's throughput, ratio ≥ 1)",
        bake / embree,
        packet / embree,
        obvhs / embree,
    );
    Ok(())
}

/// Exactly the rays a bake of `mesh` with `config` casts, vertex after vertex and
/// pass after pass, in the bake's order: `transfer::bake_rays` with the options
/// the bake itself uses (`prt::bake_options`).
fn the_bakes_rays(mesh: &TriangleMesh, config: &BakeConfig) -> Result<Vec<Ray>> {
    let normals = prt::unit_normals(mesh);
    let options = prt::bake_options(config);
    // Reserved fallibly: `--rays` up to 65,536 on a large mesh is more rays than
    // memory holds, which must be an error, not an abort.
    let count = mesh
        .vertex_count()
        .checked_mul(config.rays as usize * (config.bounces as usize + 1));
    let mut rays: Vec<Ray> = Vec::new();
    count
        .and_then(|n| rays.try_reserve_exact(n).ok())
        .ok_or_else(|| {
            Error::msg(format!(
                "cannot hold the bake's {} rays ({} vertices x {} rays x {} passes) for Embree; \
                 use fewer --rays",
                count.map_or_else(|| "too many".to_string(), |n| n.to_string()),
                mesh.vertex_count(),
                config.rays,
                config.bounces + 1
            ))
        })?;
    for pass in 0..=config.bounces {
        for (v, (p, n)) in mesh.positions().iter().zip(&normals).enumerate() {
            bake_rays(Vec3::from(*p), *n, v, pass, &options, |r| rays.push(r.ray))
                .map_err(|e| Error::msg(format!("cannot enumerate the bake's rays: {e}")))?;
        }
    }
    Ok(rays)
}

/// One timed shading configuration.
struct Timed {
    name: String,
    nanos_per_vertex: f64,
    multiply_adds: usize,
}

/// Nanoseconds per vertex of relighting every vertex of `set`.
fn time_shade(
    set: &TransferSet,
    lighting: &[[f32; 3]],
    eye: [f32; 3],
    components: Option<usize>,
    min_time: Duration,
) -> Result<f64> {
    let material = Material {
        phong_exponent: EXPONENT,
        ..Material::glossy(1.0)
    };
    let mut out = vec![[0.0f32; 3]; set.vertex_count()];
    set.shade(lighting, View::Eye(eye), &material, components, &mut out)
        .map_err(|e| Error::msg(format!("cannot shade: {e}")))?;
    let elapsed = fastest_time(min_time, || {
        let _ = set.shade(
            black_box(lighting),
            View::Eye(eye),
            &material,
            components,
            black_box(&mut out),
        );
    });
    Ok(elapsed.as_secs_f64() * 1e9 / set.vertex_count().max(1) as f64)
}

/// Nanoseconds per vertex of relighting every vertex of the glossy SH `set` with
/// `kernel` in a loop that does what `TransferSet::shade` does for glossy SH (the
/// lighting split per call, per vertex the unit view vector from the eye and the
/// kernel at the vertex normal), so that the view-first and the published (2002)
/// order are timed with the same per-vertex work around them.
fn time_glossy_loop(
    set: &TransferSet,
    lighting: &[[f32; 3]],
    eye: [f32; 3],
    kernel: fn(&[f32], &GlossyLobe, &ShLighting, Vec3, Vec3) -> Vec3,
    min_time: Duration,
) -> Result<f64> {
    let data = set
        .dense_data()
        .ok_or_else(|| Error::msg("a dense set was expected"))?;
    let lobe =
        GlossyLobe::phong(set.bands(), EXPONENT).ok_or_else(|| Error::msg("invalid Phong lobe"))?;
    let len = set.block_len();
    let eye = Vec3::from(eye);
    let normals: Vec<Vec3> = set.normals().iter().map(|n| Vec3::from(*n)).collect();
    let positions = set.positions();
    let mut out = vec![[0.0f32; 3]; set.vertex_count()];
    let elapsed = fastest_time(min_time, || {
        let Some(planar) = ShLighting::new(black_box(lighting)) else {
            return;
        };
        for (v, (o, block)) in out.iter_mut().zip(data.chunks_exact(len)).enumerate() {
            let to_eye = (eye - Vec3::from(positions[v])).normalize_or_zero();
            *o = kernel(block, &lobe, &planar, normals[v], to_eye).to_array();
        }
        black_box(&mut out);
    });
    Ok(elapsed.as_secs_f64() * 1e9 / set.vertex_count().max(1) as f64)
}

/// Nanoseconds per vertex of the kernels, in the order diffuse, glossy SH
/// (view-first), glossy SH (2002 order), MRT, then MRT from PCA for each of `ks`.
#[allow(clippy::too_many_arguments)]
fn kernel_costs(
    diffuse: &TransferSet,
    glossy: &TransferSet,
    mrt: &TransferSet,
    pca_set: &TransferSet,
    ks: &[usize],
    lighting: &[[f32; 3]],
    eye: [f32; 3],
    min_time: Duration,
) -> Result<Vec<f64>> {
    let vertices = mrt.vertex_count();
    let eye = Vec3::from(eye);
    let normals: Vec<Vec3> = mrt.normals().iter().map(|n| Vec3::from(*n)).collect();
    let frames: Vec<Frame> = normals.iter().map(|n| Frame::from_normal(*n)).collect();
    let to_eye: Vec<Vec3> = mrt
        .positions()
        .iter()
        .map(|p| (eye - Vec3::from(*p)).normalize_or_zero())
        .collect();
    let missing = || Error::msg("a dense set was expected");
    let (d, g, m) = (
        diffuse.dense_data().ok_or_else(missing)?,
        glossy.dense_data().ok_or_else(missing)?,
        mrt.dense_data().ok_or_else(missing)?,
    );
    let n = lighting.len();
    let lobe =
        GlossyLobe::phong(mrt.bands(), EXPONENT).ok_or_else(|| Error::msg("invalid Phong lobe"))?;
    // Split per channel once per frame, as `TransferSet::shade` does.
    let planar = ShLighting::new(lighting).ok_or_else(|| Error::msg("too many coefficients"))?;
    let per_vertex = |elapsed: Duration| elapsed.as_secs_f64() * 1e9 / vertices.max(1) as f64;
    let mut out = Vec::new();
    out.push(per_vertex(fastest_time(min_time, || {
        for block in d.chunks_exact(n) {
            black_box(shade_diffuse(black_box(block), lighting));
        }
    })));
    out.push(per_vertex(fastest_time(min_time, || {
        for (v, block) in g.chunks_exact(n * n).enumerate() {
            black_box(shade_glossy_sh(
                black_box(block),
                &lobe,
                &planar,
                normals[v],
                to_eye[v],
            ));
        }
    })));
    out.push(per_vertex(fastest_time(min_time, || {
        for (v, block) in g.chunks_exact(n * n).enumerate() {
            black_box(shade_glossy_sh_2002(
                black_box(block),
                &lobe,
                &planar,
                normals[v],
                to_eye[v],
            ));
        }
    })));
    let len = mrt.block_len();
    let grid = mrt.grid();
    out.push(per_vertex(fastest_time(min_time, || {
        for (v, block) in m.chunks_exact(len).enumerate() {
            black_box(shade_mrt(
                black_box(block),
                grid,
                &planar,
                &frames[v],
                to_eye[v],
            ));
        }
    })));
    let pca = pca_set
        .pca()
        .ok_or_else(|| Error::msg("a PCA set was expected"))?;
    let baked = pca.components();
    for &k in ks {
        let mut terms = vec![[0.0f32; 3]; pca.frame_terms_len(k)];
        let part = pca.cluster_terms_len(k);
        out.push(per_vertex(fastest_time(min_time, || {
            pca.frame_terms(lighting, k, &mut terms);
            for v in 0..vertices {
                let w = &pca.weights()[v * baked..v * baked + k];
                let start = pca.cluster_of(v) * part;
                black_box(shade_mrt_pca(
                    black_box(w),
                    &terms[start..start + part],
                    k,
                    grid,
                    &frames[v],
                    to_eye[v],
                ));
            }
        })));
    }
    Ok(out)
}

/// Shading cost per vertex of the four methods at `bands`, and the PCA table.
fn shading_costs(
    mesh: &TriangleMesh,
    args: &BenchTransferArgs,
    bands: u32,
    min_time: Duration,
) -> Result<()> {
    let n = (bands * bands) as usize;
    let bake = |kind| -> Result<TransferSet> {
        Ok(prt::bake_mesh(mesh, &config(kind, bands, args)?, false, None)?.set)
    };
    let diffuse = bake(Kind::Diffuse)?;
    let glossy = bake(Kind::GlossySh)?;
    let mrt = bake(Kind::Mrt)?;
    let max_k = args
        .max_components
        .clamp(1, mrt.block_len().min(mrt.vertex_count()));
    let started = std::time::Instant::now();
    let pca = mrt
        .compress(max_k)
        .map_err(|e| Error::msg(format!("cannot compress: {e}")))?;
    let compress_time = started.elapsed();
    let lighting = prt::env_lighting(&builtin::sunrise()?, bands, 0.0)?;
    let bounds = mesh.bounds();
    let eye = (bounds.center() + bounds.diagonal() * Vec3::new(-0.4, 0.5, 1.1)).to_array();

    let mut timed = vec![
        Timed {
            name: "diffuse PRT".into(),
            nanos_per_vertex: time_shade(&diffuse, &lighting, eye, None, min_time)?,
            multiply_adds: 3 * n,
        },
        Timed {
            name: "glossy SH, view-first".into(),
            nanos_per_vertex: time_shade(&glossy, &lighting, eye, None, min_time)?,
            multiply_adds: n * n + 3 * n,
        },
        Timed {
            name: "glossy SH, 2002 order".into(),
            nanos_per_vertex: time_glossy_loop(
                &glossy,
                &lighting,
                eye,
                shade_glossy_sh_2002,
                min_time,
            )?,
            multiply_adds: 3 * n * n + 3 * n,
        },
        Timed {
            name: "MRT".into(),
            nanos_per_vertex: time_shade(&mrt, &lighting, eye, None, min_time)?,
            multiply_adds: 7 * n,
        },
    ];
    let mut ks: Vec<usize> = [4usize, 8, 16].into_iter().filter(|&k| k < max_k).collect();
    ks.push(max_k);
    for &k in &ks {
        timed.push(Timed {
            name: format!("MRT from PCA, K = {k}"),
            nanos_per_vertex: time_shade(&pca, &lighting, eye, Some(k), min_time)?,
            multiply_adds: 3 * 4 * (k + 1),
        });
    }
    // The same loop as the 2002 row around the view-first kernel: how much of the
    // gap between the two glossy rows is the loop rather than the kernel.
    let view_first_loop = time_glossy_loop(&glossy, &lighting, eye, shade_glossy_sh, min_time)?;
    let (view_first, published) = (timed[1].nanos_per_vertex, timed[2].nanos_per_vertex);
    println!(
        "shading cost per vertex, {bands} bands ({n} coefficients), one thread, {} vertices per call:",
        mesh.vertex_count()
    );
    println!(
        "  batch TransferSet::shade (lighting split per call, frames cached in the set, view vectors per vertex;"
    );
    println!(
        "  the 2002 order through a loop doing the same per-vertex work, where the view-first kernel takes {view_first_loop:.1} ns):"
    );
    println!(
        "  {:<26} {:>8}      {:>5}                       cheaper than glossy SH: view-first   2002 order",
        "", "", "multiply-adds (nominal)"
    );
    for t in &timed {
        println!(
            "  {:<26} {:>8.1} ns   {:>5}                         {:>6.2}x   {:>6.2}x",
            t.name,
            t.nanos_per_vertex,
            t.multiply_adds,
            view_first / t.nanos_per_vertex,
            published / t.nanos_per_vertex
        );
    }
    let kernels = kernel_costs(&diffuse, &glossy, &mrt, &pca, &ks, &lighting, eye, min_time)?;
    println!("  per-vertex kernels (frames and unit view directions precomputed):");
    let (view_first_kernel, published_kernel) = (kernels[1], kernels[2]);
    for (t, ns) in timed.iter().zip(&kernels) {
        println!(
            "  {:<26} {:>8.1} ns                                 {:>6.2}x   {:>6.2}x",
            t.name,
            ns,
            view_first_kernel / ns,
            published_kernel / ns
        );
    }
    println!(
        "  goal: MRT at least 5x cheaper than glossy SH at equal bands: batch {:.2}x view-first, {:.2}x 2002 order (PCA K = {k0}: {:.2}x, {:.2}x); kernels {:.2}x, {:.2}x",
        view_first / timed[3].nanos_per_vertex,
        published / timed[3].nanos_per_vertex,
        view_first / timed[4].nanos_per_vertex,
        published / timed[4].nanos_per_vertex,
        view_first_kernel / kernels[3],
        published_kernel / kernels[3],
        k0 = ks[0]
    );

    let mut counts: Vec<usize> = std::iter::successors(Some(1usize), |c| Some(c * 2))
        .take_while(|&c| c < max_k)
        .collect();
    counts.push(max_k);
    let levels = mrt
        .pca_levels(&pca, &counts)
        .expect("compressed from this set");
    let dense = mrt.data_bytes() as f64 / mrt.vertex_count() as f64;
    println!(
        "PCA of the MRT matrices ({} values each; compressed to {max_k} in {:.2} s): error and memory against K",
        mrt.block_len(),
        compress_time.as_secs_f64()
    );
    println!(
        "  dense            {dense:>9.1} bytes per vertex (diffuse {:.0}, glossy SH {:.0})",
        diffuse.data_bytes() as f64 / diffuse.vertex_count() as f64,
        glossy.data_bytes() as f64 / glossy.vertex_count() as f64
    );
    for level in levels {
        println!(
            "  K = {:>3}          {:>9.1} bytes per vertex ({:>5.1}x less), relative RMS error {:>7.3} %",
            level.components,
            level.bytes_per_vertex,
            dense / level.bytes_per_vertex,
            100.0 * level.relative_rms_error
        );
    }
    clustered_table(&mrt, args, &lighting, eye, min_time)
}

/// One row of the clustered-PCA table.
struct ClusteredRow {
    clusters: usize,
    components: usize,
    bytes_per_vertex: f64,
    error: f64,
    /// Components of the global PCA with the most bytes per vertex not above
    /// this row's, and its error.
    global_components: usize,
    global_error: f64,
    shade_ns: f64,
    global_shade_ns: f64,
    fit_seconds: f64,
}

/// Clustered PCA at every (C, K) of the arguments against one global PCA: the
/// error at the same K, and at equal bytes per vertex (cluster bases amortised
/// over the vertices), and the batch shading time at the same K.
fn clustered_table(
    mrt: &TransferSet,
    args: &BenchTransferArgs,
    lighting: &[[f32; 3]],
    eye: [f32; 3],
    min_time: Duration,
) -> Result<()> {
    let vertices = mrt.vertex_count();
    let max = mrt.block_len().min(vertices);
    let mut fits = Vec::new();
    for &c in args
        .clusters
        .iter()
        .filter(|&&c| (2..=vertices).contains(&c))
    {
        for &k in args
            .cluster_components
            .iter()
            .filter(|&&k| (1..=max).contains(&k))
        {
            let started = std::time::Instant::now();
            let set = mrt
                .compress_clustered(c, k, 0)
                .map_err(|e| Error::msg(format!("cannot compress: {e}")))?;
            fits.push((c, k, set, started.elapsed().as_secs_f64()));
        }
    }
    if fits.is_empty() {
        return Ok(());
    }
    // Each row's error and bytes, then one global PCA with enough components
    // to match the largest row's bytes.
    let levels = fits
        .iter()
        .map(|(_, k, set, _)| {
            let level = mrt
                .pca_levels(set, &[*k])
                .expect("compressed from this set")[0];
            (level, *k)
        })
        .collect::<Vec<_>>();
    let largest = levels.iter().map(|(l, _)| l.bytes).max().unwrap_or(0);
    let d = mrt.block_len();
    // Global bytes at K: 4 (D (K + 1) + V K).
    let global_k_for = |bytes: usize| -> usize {
        let per_k = 4 * (d + vertices);
        (bytes.saturating_sub(4 * d) / per_k).clamp(1, max)
    };
    let global_max = global_k_for(largest)
        .max(args.cluster_components.iter().copied().max().unwrap_or(1))
        .min(max);
    let started = std::time::Instant::now();
    let global = mrt
        .compress(global_max)
        .map_err(|e| Error::msg(format!("cannot compress: {e}")))?;
    let global_seconds = started.elapsed().as_secs_f64();
    // The global errors the rows compare with: at each row's K and at the K of
    // its bytes (only those, since each level rebuilds every block).
    let mut needed: Vec<usize> = levels
        .iter()
        .flat_map(|(level, k)| [*k, global_k_for(level.bytes)])
        .map(|k| k.min(global_max))
        .collect();
    needed.sort_unstable();
    needed.dedup();
    let global_levels = mrt
        .pca_levels(&global, &needed)
        .expect("compressed from this set");
    let global_error = |k: usize| {
        let k = k.min(global_max);
        global_levels
            .iter()
            .find(|l| l.components == k)
            .map_or(f64::NAN, |l| l.relative_rms_error)
    };
    let mut rows = Vec::new();
    for ((c, k, set, fit_seconds), (level, _)) in fits.iter().zip(&levels) {
        let equal = global_k_for(level.bytes).min(global_max);
        rows.push(ClusteredRow {
            clusters: *c,
            components: *k,
            bytes_per_vertex: level.bytes_per_vertex,
            error: level.relative_rms_error,
            global_components: equal,
            global_error: global_error(equal),
            shade_ns: time_shade(set, lighting, eye, Some(*k), min_time)?,
            global_shade_ns: time_shade(&global, lighting, eye, Some(*k), min_time)?,
            fit_seconds: *fit_seconds,
        });
    }
    println!(
        "clustered PCA (Sloan et al. 2003) against one global PCA (fitted to K = {global_max} in {global_seconds:.2} s); bytes include every cluster's basis and each vertex's cluster:"
    );
    println!(
        "  {:>4} {:>4} {:>10} {:>9} | global at equal bytes: {:>4} {:>9} {:>7} | global at this K {:>9} | shading ns/vertex {:>7} {:>7} {:>6} | fit",
        "C", "K", "bytes/vtx", "error", "K", "error", "ratio", "error", "CPCA", "global", "ratio"
    );
    for r in &rows {
        println!(
            "  {:>4} {:>4} {:>10.1} {:>8.3}% | {:>27} {:>8.3}% {:>6.2}x | {:>25.3}% | {:>25.1} {:>7.1} {:>5.2}x | {:.2} s",
            r.clusters,
            r.components,
            r.bytes_per_vertex,
            100.0 * r.error,
            r.global_components,
            100.0 * r.global_error,
            r.global_error / r.error.max(f64::MIN_POSITIVE),
            100.0 * global_error(r.components),
            r.shade_ns,
            r.global_shade_ns,
            r.shade_ns / r.global_shade_ns,
            r.fit_seconds
        );
    }
    if let Some(worst) = rows
        .iter()
        .min_by(|a, b| (a.global_error / a.error).total_cmp(&(b.global_error / b.error)))
    {
        println!(
            "  worst row: C = {}, K = {}: {:.2}x less error than global PCA at equal bytes (goal 3x); shading {:.2}x global's at the same K (goal at most 1.5x)",
            worst.clusters,
            worst.components,
            worst.global_error / worst.error.max(f64::MIN_POSITIVE),
            worst.shade_ns / worst.global_shade_ns
        );
    }
    Ok(())
}
