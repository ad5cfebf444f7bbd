//! `antumbra verify hemi` and `antumbra bench hemi`: hemisphere masks against
//! Embree tracing the same cell directions, for agreement and for speed.
//!
//! Receivers are mesh vertices (spread evenly over the vertex order) with their
//! area-weighted normals; the center of projection is pushed off the surface by
//! [`OFFSET_OF_DIAGONAL`] of the bounding-box diagonal so that both the rasterizer
//! and the rays see the surface from the same point.

use std::hint::black_box;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use antumbra_core::hemi::{
    HalfSpaceTable, HemiMask, Quality, RasterOptions, Receiver, cell_direction,
    rasterize_receiver_with_counts,
};
use antumbra_core::raycast::BvhScene;
use antumbra_core::{Ray, RayCaster};
use antumbra_tests::oracle::{OracleOptions, try_cast};
use glam::Vec3;

use crate::builtin;
use crate::cli::{BenchHemiArgs, QualityArg, VerifyHemiArgs};
use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;

/// Center of projection offset along the normal, as a fraction of the diagonal.
const OFFSET_OF_DIAGONAL: f32 = 1e-3;

/// Agreement `verify hemi` requires (the acceptance figures).
fn required_agreement(quality: QualityArg) -> f64 {
    match quality {
        QualityArg::Exact => 0.9999,
        QualityArg::Table => 0.995,
    }
}

fn quality_name(quality: QualityArg) -> &'static str {
    match quality {
        QualityArg::Exact => "exact",
        QualityArg::Table => "table",
    }
}

/// The shared half-space table, built on first use.
fn table() -> &'static HalfSpaceTable {
    static TABLE: OnceLock<HalfSpaceTable> = OnceLock::new();
    TABLE.get_or_init(HalfSpaceTable::default)
}

fn quality(arg: QualityArg) -> Quality<'static> {
    match arg {
        QualityArg::Exact => Quality::Exact,
        QualityArg::Table => Quality::Table(table()),
    }
}

/// Receivers: `count` vertices spread evenly over the vertex order, with their
/// normals; vertices without a normal (only degenerate triangles) are skipped.
fn receivers(mesh: &TriangleMesh, count: usize) -> Vec<(Vec3, Vec3)> {
    let normals = mesh.vertex_normals();
    let vertices = mesh.vertex_count();
    let step = (vertices as f64 / count.max(1) as f64).max(1.0);
    (0..count.min(vertices))
        .map(|k| (k as f64 * step) as usize)
        .filter(|&v| normals[v].is_finite() && normals[v].length_squared() > 0.5)
        .map(|v| (Vec3::from(mesh.positions()[v]), normals[v]))
        .collect()
}

fn load(mesh: &Option<std::path::PathBuf>) -> Result<TriangleMesh> {
    match mesh {
        Some(path) => TriangleMesh::load_obj(path),
        None => builtin::bunny(),
    }
}

/// One ray per valid cell of every receiver, in receiver then row-major cell order.
fn cell_rays(receivers: &[Receiver]) -> Vec<Ray> {
    receivers
        .iter()
        .flat_map(|r| (0..32).flat_map(move |j| (0..32).filter_map(move |i| r.cell_ray(i, j))))
        .collect()
}

/// Runs `antumbra verify hemi`.
pub fn run_verify(args: &VerifyHemiArgs) -> Result<()> {
    let mesh = load(&args.mesh)?;
    let offset = OFFSET_OF_DIAGONAL * mesh.bounds().diagonal();
    let chosen = receivers(&mesh, args.receivers as usize);
    let options = RasterOptions {
        quality: quality(args.quality),
        normal_offset: offset,
        ..RasterOptions::default()
    };
    let view = mesh.view();
    let masks: Vec<HemiMask> = chosen
        .iter()
        .map(|&(p, n)| rasterize_receiver_with_counts(&view, p, n, &options).0)
        .collect();
    let frames: Vec<Receiver> = chosen
        .iter()
        .map(|&(p, n)| Receiver::new(p, n, offset))
        .collect();
    let rays = cell_rays(&frames);
    let embree = try_cast(
        mesh.positions(),
        mesh.indices(),
        &rays,
        OracleOptions::default(),
    )
    .map_err(Error::msg)?;
    let mut next = embree.hits.iter();
    let (mut cells, mut agree) = (0usize, 0usize);
    for mask in &masks {
        for j in 0..32 {
            for i in 0..32 {
                if cell_direction(i, j).is_none() {
                    continue;
                }
                let hit = next.next().expect("one Embree answer per valid cell");
                cells += 1;
                agree += usize::from(mask.get(i, j) == hit.occluded);
            }
        }
    }
    let fraction = agree as f64 / cells.max(1) as f64;
    println!(
        "{}: {} receivers, center of projection {offset:e} off the surface, {} cells differ",
        mesh.name(),
        masks.len(),
        cells - agree
    );
    println!(
        "hemi {} agreement: {:.4}% of {cells} cells, {} receivers",
        quality_name(args.quality),
        100.0 * fraction,
        masks.len()
    );
    let required = required_agreement(args.quality);
    if fraction < required {
        return Err(Error::msg(format!(
            "agreement {:.4} % is below the required {:.2} %",
            100.0 * fraction,
            100.0 * required
        )));
    }
    Ok(())
}

/// Repeats `work` until `min_time` has passed; returns the mean time per call.
fn time_per_call(min_time: Duration, mut work: impl FnMut()) -> Duration {
    work();
    let started = Instant::now();
    let mut calls = 0u32;
    while calls == 0 || started.elapsed() < min_time {
        work();
        calls += 1;
    }
    started.elapsed() / calls
}

/// Runs `antumbra bench hemi`.
pub fn run_bench(args: &BenchHemiArgs) -> Result<()> {
    let mesh = load(&args.mesh)?;
    let offset = OFFSET_OF_DIAGONAL * mesh.bounds().diagonal();
    let chosen = receivers(&mesh, args.receivers as usize);
    let count = chosen.len().max(1) as f64;
    let view = mesh.view();
    let min_time = Duration::from_millis(args.min_time);
    let _ = table();
    println!(
        "bench hemi: {} ({} triangles), {} receivers, one thread, each figure repeated for at least {} ms",
        mesh.name(),
        mesh.triangle_count(),
        chosen.len(),
        args.min_time
    );
    let mut per_receiver = Vec::new();
    for arg in [QualityArg::Exact, QualityArg::Table] {
        let options = RasterOptions {
            quality: quality(arg),
            normal_offset: offset,
            ..RasterOptions::default()
        };
        let rasterized: u64 = chosen
            .iter()
            .map(|&(p, n)| {
                u64::from(
                    rasterize_receiver_with_counts(&view, p, n, &options)
                        .1
                        .rasterized,
                )
            })
            .sum();
        let elapsed = time_per_call(min_time, || {
            for &(p, n) in &chosen {
                black_box(rasterize_receiver_with_counts(
                    &view,
                    black_box(p),
                    n,
                    &options,
                ));
            }
        });
        let micros = elapsed.as_secs_f64() * 1e6 / count;
        println!(
            "rasterizer {:<5}  {micros:>9.2} µs per receiver  {:>7.1} ns per rasterized triangle ({:.0} of {} triangles rasterized per receiver)",
            quality_name(arg),
            elapsed.as_secs_f64() * 1e9 / rasterized.max(1) as f64,
            rasterized as f64 / count,
            mesh.triangle_count()
        );
        per_receiver.push((quality_name(arg), micros));
    }
    let frames: Vec<Receiver> = chosen
        .iter()
        .map(|&(p, n)| Receiver::new(p, n, offset))
        .collect();
    let rays = cell_rays(&frames);
    let bvh = BvhScene::new(&view).map_err(|e| Error::msg(e.to_string()))?;
    let elapsed = time_per_call(min_time, || {
        for ray in &rays {
            black_box(bvh.occluded(black_box(ray)));
        }
    });
    let bvh_micros = elapsed.as_secs_f64() * 1e6 / count;
    println!(
        "BVH (obvhs CWBVH)  {bvh_micros:>9.2} µs per receiver  ({} occlusion rays per receiver)",
        rays.len() as f64 / count
    );
    let embree_micros = if args.no_embree {
        None
    } else {
        let run = try_cast(
            mesh.positions(),
            mesh.indices(),
            &rays,
            OracleOptions {
                timing: true,
                ..OracleOptions::default()
            },
        )
        .map_err(|e| Error::msg(format!("{e}\n(use --no-embree to skip this figure)")))?;
        let seconds = run.occluded_seconds.expect("timing was requested");
        let micros = seconds * 1e6 / count;
        println!("Embree (embreex)   {micros:>9.2} µs per receiver  (one batch rtcOccluded1 loop)");
        Some(micros)
    };
    for (name, micros) in per_receiver {
        print!(
            "rasterizer {name}: {:.2}x less time per receiver than the BVH",
            bvh_micros / micros
        );
        if let Some(embree) = embree_micros {
            print!(", {:.2}x less than Embree", embree / micros);
        }
        println!();
    }
    Ok(())
}
