//! `antumbra bench raycast`: BVH against brute-force throughput, measured on the
//! same rays in the same run.

use std::hint::black_box;
use std::time::{Duration, Instant};

use antumbra_core::raycast::BvhScene;
use antumbra_core::{BruteForceCaster, Ray, RayCaster};
use rayon::prelude::*;

use super::hemi::time_per_call;
use super::{format_duration, format_rate};
use crate::builtin;
use crate::cli::BenchRaycastArgs;
use crate::error::Result;
use crate::mesh::TriangleMesh;
use crate::ray_batch::{RayClass, random_rays};

/// Seed of the benchmark's rays.
const SEED: u64 = 0xBE;

/// The two queries of the [`RayCaster`] trait.
#[derive(Clone, Copy)]
enum Query {
    ClosestHit,
    Occluded,
}

impl Query {
    fn name(self) -> &'static str {
        match self {
            Query::ClosestHit => "closest hit",
            Query::Occluded => "occluded",
        }
    }

    /// Runs the query; true when something was hit.
    fn cast(self, caster: &impl RayCaster, ray: &Ray) -> bool {
        match self {
            Query::ClosestHit => black_box(caster.closest_hit(black_box(ray))).is_some(),
            Query::Occluded => black_box(caster.occluded(black_box(ray))),
        }
    }
}

/// One timed configuration.
struct Measurement {
    rays_per_second: f64,
    hits: usize,
}

/// Runs the benchmark and prints the table.
pub fn run_raycast(args: &BenchRaycastArgs) -> Result<()> {
    let mesh = match &args.mesh {
        Some(path) => TriangleMesh::load_obj(path)?,
        None => builtin::bunny()?,
    };
    let rays: Vec<Ray> = random_rays(&mesh, &RayClass::WORKLOAD, args.rays as usize, SEED)
        .into_iter()
        .map(|(_, ray)| ray)
        .collect();
    let build_started = Instant::now();
    let bvh = BvhScene::new(&mesh.view()).expect("TriangleMesh keeps coordinates in range");
    let build_time = build_started.elapsed();
    let brute_force = BruteForceCaster::new(mesh.view());
    let threads = rayon::current_num_threads();
    // Fast configurations are timed over many passes of the batch, not one short one.
    let min_time = Duration::from_millis(args.min_time);

    println!(
        "bench raycast: {} ({} triangles), {} rays (half inbound, half from the surface)",
        mesh.name(),
        mesh.triangle_count(),
        rays.len()
    );
    println!(
        "BVH build {}; each figure repeats the batch for at least {}",
        format_duration(build_time),
        format_duration(min_time)
    );
    println!();
    println!(
        "{:<12} {:>8} {:>16} {:>16} {:>10}",
        "query", "threads", "brute force", "BVH", "speed-up"
    );
    let mut bvh_rates = Vec::new();
    let mut disagreements = Vec::new();
    for query in [Query::ClosestHit, Query::Occluded] {
        for parallel in [false, true] {
            let baseline = measure(&rays, parallel, min_time, |ray| {
                query.cast(&brute_force, ray)
            });
            let accelerated = measure(&rays, parallel, min_time, |ray| query.cast(&bvh, ray));
            if baseline.hits != accelerated.hits && parallel {
                // Timings stay meaningful; the answers are `verify`'s business.
                disagreements.push(format!(
                    "{}: brute force hit {} rays, the BVH {}",
                    query.name(),
                    baseline.hits,
                    accelerated.hits
                ));
            }
            println!(
                "{:<12} {:>8} {:>16} {:>16} {:>9.1}x",
                query.name(),
                if parallel { threads } else { 1 },
                format_rate(baseline.rays_per_second, "rays"),
                format_rate(accelerated.rays_per_second, "rays"),
                accelerated.rays_per_second / baseline.rays_per_second
            );
            bvh_rates.push(accelerated.rays_per_second);
        }
    }
    println!();
    println!(
        "all-core scaling of the BVH on {threads} threads: closest hit {:.2}x, occluded {:.2}x",
        bvh_rates[1] / bvh_rates[0],
        bvh_rates[3] / bvh_rates[2]
    );
    for disagreement in &disagreements {
        eprintln!(
            "warning: the casters disagree on some rays ({disagreement}); run `antumbra verify`"
        );
    }
    moving_mesh(&mesh, args.rays as usize, min_time)
}

/// Twists of the moving-mesh table: radians of turn about the vertical axis
/// from the bottom to the top of the mesh.
const TWISTS: [f32; 4] = [0.0, 0.5, 1.5, 4.0];

/// A moving mesh: per twist, moving the scene's triangles with
/// `BvhScene::refit` against building a scene over the moved mesh (each the
/// mean over `min_time` after a warm-up), and the occlusion throughput (one thread) of the
/// refitted scene against the rebuilt one on rays over the moved mesh, with
/// every answer compared.
fn moving_mesh(mesh: &TriangleMesh, ray_count: usize, min_time: Duration) -> Result<()> {
    let (lo, hi) = mesh.view().bounds();
    let centre = (lo + hi) / 2.0;
    let height = (hi.y - lo.y).max(f32::MIN_POSITIVE);
    println!();
    println!(
        "moving mesh: the mesh twisted about its vertical axis, then its scene refitted (the hierarchy kept) or rebuilt; occluded rays on one thread"
    );
    println!(
        "{:>8} {:>12} {:>12} {:>14} {:>16} {:>16} {:>14}",
        "twist",
        "rebuild",
        "refit",
        "refit faster",
        "rays, rebuilt",
        "rays, refitted",
        "refitted / new"
    );
    let mut scene = BvhScene::new(&mesh.view()).expect("TriangleMesh keeps coordinates in range");
    for twist in TWISTS {
        let moved: Vec<[f32; 3]> = mesh
            .positions()
            .iter()
            .map(|&p| {
                let q = glam::Vec3::from(p) - centre;
                let turn = glam::Quat::from_rotation_y(twist * (q.y / height));
                (centre + turn * q).to_array()
            })
            .collect();
        let moved = TriangleMesh::new(mesh.name(), moved, mesh.indices().to_vec())?;
        let view = moved.view();
        let rebuild = time_per_call(min_time, || {
            black_box(BvhScene::new(&view).expect("in range"));
        });
        let refit = time_per_call(min_time, || {
            scene.refit(&view).expect("the same triangles, in range");
        });
        let rebuilt = BvhScene::new(&view).expect("in range");
        let rays: Vec<Ray> = random_rays(&moved, &RayClass::WORKLOAD, ray_count, SEED)
            .into_iter()
            .map(|(_, ray)| ray)
            .collect();
        let differ = rays
            .iter()
            .filter(|ray| scene.occluded(ray) != rebuilt.occluded(ray))
            .count();
        if differ > 0 {
            return Err(crate::error::Error::msg(format!(
                "twist {twist}: the refitted scene answers {differ} of {} rays unlike a new one",
                rays.len()
            )));
        }
        let fresh = measure(&rays, false, min_time, |ray| rebuilt.occluded(ray));
        let refitted = measure(&rays, false, min_time, |ray| scene.occluded(ray));
        println!(
            "{:>8} {:>12} {:>12} {:>13.1}x {:>16} {:>16} {:>13.2}x",
            format!("{twist} rad"),
            format_duration(rebuild),
            format_duration(refit),
            rebuild.as_secs_f64() / refit.as_secs_f64(),
            format_rate(fresh.rays_per_second, "rays"),
            format_rate(refitted.rays_per_second, "rays"),
            refitted.rays_per_second / fresh.rays_per_second
        );
    }
    println!(
        "(every refitted answer equal to the rebuilt scene's; each twist is refitted from the previous one)"
    );
    Ok(())
}

/// Casts the whole batch repeatedly (one thread, or rayon on all cores) until
/// `min_time` has passed; the first pass is a warm-up and not timed.
fn measure(
    rays: &[Ray],
    parallel: bool,
    min_time: Duration,
    cast: impl Fn(&Ray) -> bool + Sync,
) -> Measurement {
    let pass = || {
        if parallel {
            rays.par_iter().filter(|ray| cast(ray)).count()
        } else {
            rays.iter().filter(|ray| cast(ray)).count()
        }
    };
    let warm_up = Instant::now();
    let hits = pass();
    // A pass slower than the minimum is already a good measurement.
    let warm_up_time = warm_up.elapsed();
    if warm_up_time >= min_time {
        return Measurement {
            rays_per_second: rays.len() as f64 / warm_up_time.as_secs_f64(),
            hits,
        };
    }
    let mut passes = 0u64;
    let started = Instant::now();
    while started.elapsed() < min_time {
        black_box(pass());
        passes += 1;
    }
    Measurement {
        rays_per_second: (passes as f64 * rays.len() as f64) / started.elapsed().as_secs_f64(),
        hits,
    }
}
