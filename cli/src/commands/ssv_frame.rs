//! `antumbra bench ssv --frame`: what a frame of soft shadows costs, on the
//! layout users have ([`antumbra_tests::scenes::GroundScene`]: the mesh over a
//! ground of receivers reaching well beyond it, lights small and large in three
//! orientations), with default options, on one core.
//!
//! Per row, each the fastest of `--passes` frames:
//! - cold: creating the soft shadows and answering every receiver once, as
//!   `antumbra_ssv_query` does on one thread (the hierarchy's
//!   [`SoftShadows::prepare`], then a query per receiver): what a frame costs
//!   when the light or an object moved;
//! - warm: the same queries again on the same handle (a static scene seen
//!   again);
//! - update: the mesh turned 10° about its vertical axis,
//!   [`SoftShadows::update`] and every query (a moving object's frame),
//!   compared with the turned scene's warm frame (the queries again) and its
//!   cold frame (a structure made from the turned mesh, whose bits must be
//!   the updated one's);
//! - Embree: building its scene and casting every shadow ray (one core);
//! - hemicube: the 2005-style structure's cold frame;
//! - and, apart, the hierarchy's cold frame on every core (creation with
//!   `SsvOptions::parallel`, one `query_batch`).
//!
//! Every hierarchy bit is checked against the hemicube's (both exact: they must
//! be equal) and against Embree's (mismatches classified by the exact segment
//! test). Candidates per query on the ground are compared with a hierarchy
//! whose root box is fitted to every receiver (no receiver may fall back to a
//! long list because it lies outside the default root).

use std::time::{Duration, Instant};

use antumbra_core::ssv::{LightPolygon, SamplePattern, SoftShadows, SsvOptions, Structure};
use antumbra_tests::data::Mesh;
use antumbra_tests::oracle::try_frame;
use antumbra_tests::scenes::{GroundScene, LightOrientation, LightSize};
use antumbra_tests::ssv::{Comparison, compare_frame};
use glam::Vec3;

use super::ssv::SAMPLE_SEED;
use crate::builtin;
use crate::cli::BenchSsvArgs;
use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;
use crate::progress;

/// Mesh receivers by default (vertices spread over the vertex order).
const MESH_POINTS: u32 = 4096;

/// One timed frame of one structure.
struct Frame {
    /// Creation and every query.
    cold: Duration,
    /// Every query again.
    warm: Duration,
    /// After the mesh turned ([`moved`]): `SoftShadows::update` and every
    /// query, as a moving object's frame.
    update: Duration,
    /// Every query again on the updated structure (the turned scene's warm
    /// frame, what `update` is compared with).
    moved_warm: Duration,
    /// A cold frame made from the turned mesh (what `update` saves on).
    moved_cold: Duration,
    /// Bits of every receiver, receiver after receiver (from the first frame).
    bits: Vec<u64>,
    /// Candidates per query of the warm frame, on the ground.
    ground_candidates: f64,
    /// Candidates per query of the warm frame, every receiver.
    candidates: f64,
    /// Nodes and bytes after the frames.
    nodes: usize,
    bytes: usize,
}

/// The fastest of `passes` cold frames on every core: creation with
/// `SsvOptions::parallel` and one `query_batch` (rayon).
fn parallel_cold(
    scene: &GroundScene,
    light: &LightPolygon,
    samples: &[Vec3],
    receivers: &[Vec3],
    options: SsvOptions,
    passes: u32,
) -> Result<Duration> {
    let options = SsvOptions {
        parallel: true,
        ..options
    };
    let mut best = Duration::MAX;
    for _ in 0..passes.max(1) {
        let started = Instant::now();
        let ssv = SoftShadows::new(&scene.occluders.view(), light.clone(), samples, options)
            .map_err(|e| Error::msg(format!("cannot prepare the soft shadows: {e}")))?;
        let mut bits = vec![0u64; receivers.len() * ssv.words_per_receiver()];
        ssv.query_batch(receivers, &mut bits, None, true)
            .map_err(|e| Error::msg(format!("query failed: {e}")))?;
        best = best.min(started.elapsed());
    }
    Ok(best)
}

/// One row of the table.
struct Row {
    mesh: String,
    size: LightSize,
    orientation: LightOrientation,
    hierarchy: Frame,
    /// The hierarchy's cold frame on every core.
    parallel_cold: Duration,
    hemicube: Option<Frame>,
    /// Build and rays.
    embree: Option<(Duration, Duration)>,
    comparison: Option<Comparison>,
    /// Candidates per ground query with a root box fitted to the receivers.
    fitted_ground_candidates: f64,
    hemicube_bits_equal: Option<bool>,
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Times `passes` frames of `options` on `scene`: the fastest cold and warm.
fn frames(
    scene: &GroundScene,
    light: &LightPolygon,
    samples: &[Vec3],
    receivers: &[Vec3],
    options: SsvOptions,
    passes: u32,
) -> Result<Frame> {
    let ground = scene.ground_receivers.len();
    let mut best: Option<Frame> = None;
    for _ in 0..passes.max(1) {
        let started = Instant::now();
        let mut ssv = SoftShadows::new(&scene.occluders.view(), light.clone(), samples, options)
            .map_err(|e| Error::msg(format!("cannot prepare the soft shadows: {e}")))?;
        let words = ssv.words_per_receiver();
        let mut bits = vec![0u64; receivers.len() * words];
        // What antumbra_ssv_query does on one thread.
        ssv.prepare(receivers, false);
        for (out, &p) in bits.chunks_exact_mut(words).zip(receivers) {
            ssv.query(p, out)
                .map_err(|e| Error::msg(format!("query failed: {e}")))?;
        }
        let cold = started.elapsed();
        let started = Instant::now();
        let mut scratch = vec![0u64; words];
        let (mut all, mut on_ground) = (0u64, 0u64);
        for (r, &p) in receivers.iter().enumerate() {
            let info = ssv
                .query_detailed(p, &mut scratch)
                .map_err(|e| Error::msg(format!("query failed: {e}")))?;
            all += u64::from(info.candidates);
            if r < ground {
                on_ground += u64::from(info.candidates);
            }
        }
        let warm = started.elapsed();
        let statistics = ssv.statistics();
        // The mesh moved: update and query, then the queries again.
        let turned = moved(&scene.occluders);
        let started = Instant::now();
        ssv.update(&turned.view())
            .map_err(|e| Error::msg(format!("cannot update the soft shadows: {e}")))?;
        ssv.prepare(receivers, false);
        let mut moved_bits = vec![0u64; receivers.len() * words];
        for (out, &p) in moved_bits.chunks_exact_mut(words).zip(receivers) {
            ssv.query(p, out)
                .map_err(|e| Error::msg(format!("query failed: {e}")))?;
        }
        let update = started.elapsed();
        let started = Instant::now();
        for &p in receivers {
            ssv.query(p, &mut scratch)
                .map_err(|e| Error::msg(format!("query failed: {e}")))?;
        }
        let moved_warm = started.elapsed();
        // A cold frame on the turned mesh, its bits the updated structure's.
        let started = Instant::now();
        let fresh = SoftShadows::new(&turned.view(), light.clone(), samples, options)
            .map_err(|e| Error::msg(format!("cannot prepare the soft shadows: {e}")))?;
        fresh.prepare(receivers, false);
        let mut fresh_bits = vec![0u64; receivers.len() * words];
        for (out, &p) in fresh_bits.chunks_exact_mut(words).zip(receivers) {
            fresh
                .query(p, out)
                .map_err(|e| Error::msg(format!("query failed: {e}")))?;
        }
        let moved_cold = started.elapsed();
        if fresh_bits != moved_bits {
            return Err(Error::msg(
                "the updated structure's bits differ from a new one's on the turned mesh",
            ));
        }
        let frame = Frame {
            cold,
            warm,
            update,
            moved_warm,
            moved_cold,
            bits,
            ground_candidates: on_ground as f64 / ground.max(1) as f64,
            candidates: all as f64 / receivers.len().max(1) as f64,
            nodes: statistics.nodes,
            bytes: statistics.bytes,
        };
        best = Some(match best {
            None => frame,
            Some(b) => Frame {
                cold: b.cold.min(frame.cold),
                warm: b.warm.min(frame.warm),
                update: b.update.min(frame.update),
                moved_warm: b.moved_warm.min(frame.moved_warm),
                moved_cold: b.moved_cold.min(frame.moved_cold),
                ..b
            },
        });
    }
    Ok(best.expect("at least one pass"))
}

/// The occluders turned by 10° about the vertical axis through their centre:
/// a moving object's next frame (the same triangles, so the reference ray's
/// BVH is refitted).
fn moved(occluders: &Mesh) -> Mesh {
    let (lo, hi) = occluders.bounds();
    let centre = (lo + hi) / 2.0;
    let turn = glam::Quat::from_rotation_y(10f32.to_radians());
    Mesh {
        positions: occluders
            .positions
            .iter()
            .map(|&p| (centre + turn * (Vec3::from(p) - centre)).to_array())
            .collect(),
        indices: occluders.indices.clone(),
    }
}

/// Candidates per ground query of a hierarchy whose root box holds every
/// receiver, the light and the occluders (untimed).
fn fitted_ground_candidates(
    scene: &GroundScene,
    light: &LightPolygon,
    samples: &[Vec3],
    receivers: &[Vec3],
    options: SsvOptions,
) -> Result<f64> {
    let points = receivers
        .iter()
        .chain(&scene.light)
        .copied()
        .chain(scene.occluders.positions.iter().map(|&p| Vec3::from(p)));
    let (lo, hi) = points.fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    );
    let pad = 1e-3 * (hi - lo).max_element();
    let fitted = SsvOptions {
        root_bounds: Some([lo - pad, hi + pad]),
        ..options
    };
    let ssv = SoftShadows::new(&scene.occluders.view(), light.clone(), samples, fitted)
        .map_err(|e| Error::msg(format!("cannot prepare the soft shadows: {e}")))?;
    ssv.prepare(receivers, false);
    let mut bits = vec![0u64; ssv.words_per_receiver()];
    let mut total = 0u64;
    for &p in &scene.ground_receivers {
        total += u64::from(
            ssv.query_detailed(p, &mut bits)
                .map_err(|e| Error::msg(format!("query failed: {e}")))?
                .candidates,
        );
    }
    Ok(total as f64 / scene.ground_receivers.len().max(1) as f64)
}

/// Runs `antumbra bench ssv --frame`.
pub fn run(args: &BenchSsvArgs) -> Result<()> {
    let meshes: Vec<TriangleMesh> = if args.mesh.is_empty() {
        vec![builtin::bunny()?, builtin::armadillo()?]
    } else {
        args.mesh
            .iter()
            .map(|path| TriangleMesh::load_obj(path))
            .collect::<Result<_>>()?
    };
    let samples_per_light = args.samples.first().copied().unwrap_or(256) as usize;
    let mesh_points = args.mesh_points.unwrap_or(MESH_POINTS) as usize;
    let defaults = SsvOptions::default();
    let options = SsvOptions {
        leaf_edges: args.leaf_edges.unwrap_or(defaults.leaf_edges),
        max_depth: args.max_depth.unwrap_or(defaults.max_depth),
        ..defaults
    };
    println!(
        "bench ssv --frame: each mesh scaled to a largest extent of 1 over a {w} x {w} ground of \
         receivers (±1.5, not an occluder) plus up to {mesh_points} receivers on the mesh; a quad \
         light 2.5 from the mesh, side 1/4 or 4/5 of the extent; {samples_per_light} jittered \
         samples; one core; each time the fastest of {} frames; hierarchy: leaf edges {}, max \
         depth {}",
        args.passes,
        options.leaf_edges,
        options.max_depth,
        w = args.ground,
    );
    let rows_per_mesh = LightSize::ALL.len() * LightOrientation::ALL.len();
    let bar = progress::bar(
        (meshes.len() * rows_per_mesh) as u64,
        "bench ssv --frame",
        "frames",
    );
    let mut rows = Vec::new();
    for mesh in &meshes {
        for size in LightSize::ALL {
            for orientation in LightOrientation::ALL {
                rows.push(row(
                    mesh,
                    size,
                    orientation,
                    args,
                    options,
                    samples_per_light,
                    mesh_points,
                )?);
                bar.inc(1);
            }
        }
    }
    bar.finish_and_clear();
    print_tables(&meshes, &rows);
    print_summary(&rows)
}

#[allow(clippy::too_many_arguments)]
fn row(
    mesh: &TriangleMesh,
    size: LightSize,
    orientation: LightOrientation,
    args: &BenchSsvArgs,
    options: SsvOptions,
    samples_per_light: usize,
    mesh_points: usize,
) -> Result<Row> {
    let scene = GroundScene::new(
        mesh.positions(),
        mesh.indices(),
        orientation,
        size,
        args.ground as usize,
        mesh_points,
    );
    let receivers = scene.receivers();
    let light = LightPolygon::new(&scene.light).map_err(|e| Error::msg(e.to_string()))?;
    let samples = light.samples(samples_per_light, SamplePattern::Jittered, SAMPLE_SEED);
    let hierarchy = frames(&scene, &light, &samples, &receivers, options, args.passes)?;
    let parallel_cold = parallel_cold(&scene, &light, &samples, &receivers, options, args.passes)?;
    let fitted = fitted_ground_candidates(&scene, &light, &samples, &receivers, options)?;
    let hemicube = if args.no_hemicube {
        None
    } else {
        let hemicube_options = SsvOptions {
            structure: Structure::Hemicube,
            ..options
        };
        Some(frames(
            &scene,
            &light,
            &samples,
            &receivers,
            hemicube_options,
            args.passes,
        )?)
    };
    let hemicube_bits_equal = hemicube.as_ref().map(|h| h.bits == hierarchy.bits);
    let (embree, comparison) = if args.no_embree {
        (None, None)
    } else {
        let run = try_frame(
            &scene.occluders.positions,
            &scene.occluders.indices,
            &receivers,
            &samples,
            args.passes,
        )
        .map_err(|e| Error::msg(format!("{e}\n(use --no-embree to skip this figure)")))?;
        let comparison = compare_frame(
            &scene.occluders,
            &receivers,
            &samples,
            &hierarchy.bits,
            &run.visible,
        )
        .map_err(Error::msg)?;
        (
            Some((
                Duration::from_secs_f64(run.build_seconds),
                Duration::from_secs_f64(run.rays_seconds),
            )),
            Some(comparison),
        )
    };
    Ok(Row {
        mesh: format!("{} ({} triangles)", mesh.name(), mesh.triangle_count()),
        size,
        orientation,
        hierarchy,
        parallel_cold,
        hemicube,
        embree,
        comparison,
        fitted_ground_candidates: fitted,
        hemicube_bits_equal,
    })
}

fn kib(bytes: usize) -> String {
    if bytes >= 10 << 20 {
        format!("{:.0} MiB", bytes as f64 / (1 << 20) as f64)
    } else {
        format!("{:.0} KiB", bytes as f64 / 1024.0)
    }
}

fn print_tables(meshes: &[TriangleMesh], rows: &[Row]) {
    let per_mesh = rows.len() / meshes.len().max(1);
    for chunk in rows.chunks(per_mesh.max(1)) {
        println!();
        println!("{}", chunk[0].mesh);
        println!(
            "{:>5} {:<11} | {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} | {:>9} {:>11} {:>10} {:>11} {:>13} | {:>10} {:>16} | {:>7} {:>8} | bits vs Embree",
            "light",
            "",
            "cold ms",
            "warm ms",
            "update ms",
            &format!("{}-thread", rayon::current_num_threads()),
            "Embree ms",
            "(build)",
            "hemicube",
            "cold/warm",
            "update/warm",
            "new/update",
            "Embree/cold",
            "hemicube/cold",
            "candidates",
            "ground (fitted)",
            "nodes",
            "memory",
        );
        for r in chunk {
            let h = &r.hierarchy;
            let embree = r.embree.map(|(b, t)| b + t);
            let hemicube = r.hemicube.as_ref().map(|f| f.cold);
            let opt_ms = |d: Option<Duration>| d.map_or("-".into(), |d| format!("{:.1}", ms(d)));
            let ratio = |d: Option<Duration>| {
                d.map_or("-".into(), |d| format!("{:.2}x", ms(d) / ms(h.cold)))
            };
            let bits = match (&r.comparison, r.hemicube_bits_equal) {
                (Some(c), equal) => format!(
                    "{} mismatches of {} ({} grazing, {} library errors){}",
                    c.mismatches.len(),
                    c.bits,
                    c.mismatches
                        .iter()
                        .filter(|m| m.is_grazing(c.scale))
                        .count(),
                    c.library_errors().count(),
                    if equal == Some(false) {
                        "; HEMICUBE BITS DIFFER"
                    } else {
                        ""
                    }
                ),
                (None, Some(false)) => "HEMICUBE BITS DIFFER".into(),
                (None, _) => "-".into(),
            };
            println!(
                "{:>5} {:<11} | {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9} {:>9} {:>9} | {:>8.2}x {:>10.2}x {:>9.2}x {:>11} {:>13} | {:>10.1} {:>7.1} ({:>6.1}) | {:>7} {:>8} | {bits}",
                r.size.name(),
                r.orientation.name(),
                ms(h.cold),
                ms(h.warm),
                ms(h.update),
                ms(r.parallel_cold),
                opt_ms(embree),
                opt_ms(r.embree.map(|(b, _)| b)),
                opt_ms(hemicube),
                ms(h.cold) / ms(h.warm),
                ms(h.update) / ms(h.moved_warm),
                ms(h.moved_cold) / ms(h.update),
                ratio(embree),
                ratio(hemicube),
                h.candidates,
                h.ground_candidates,
                r.fitted_ground_candidates,
                h.nodes,
                kib(h.bytes),
            );
        }
    }
}

/// The worst row of each acceptance figure (issue 14), and whether it holds.
fn print_summary(rows: &[Row]) -> Result<()> {
    println!();
    // The worst row of `values`, against the goal when there is one (rows
    // without a goal are reported only).
    let worst =
        |label: &str, values: Vec<(f64, &Row)>, higher_is_better: bool, goal: Option<f64>| {
            let pick = values.into_iter().reduce(|a, b| {
                let better_a = if higher_is_better {
                    a.0 < b.0
                } else {
                    a.0 > b.0
                };
                if better_a { a } else { b }
            });
            if let Some((value, r)) = pick {
                let verdict = match goal {
                    None => String::from("reported"),
                    Some(goal) => {
                        let holds = if higher_is_better {
                            value >= goal
                        } else {
                            value <= goal
                        };
                        format!(
                            "goal {} {goal}x: {}",
                            if higher_is_better { ">=" } else { "<=" },
                            if holds { "holds" } else { "NOT MET" }
                        )
                    }
                };
                println!(
                    "{label}: worst {value:.2}x ({} {} {}), {verdict}",
                    r.mesh,
                    r.size.name(),
                    r.orientation.name(),
                );
            }
        };
    let h = |r: &Row| ms(r.hierarchy.cold);
    worst(
        "cold frame / warm frame",
        rows.iter()
            .map(|r| (ms(r.hierarchy.cold) / ms(r.hierarchy.warm), r))
            .collect(),
        false,
        Some(1.3),
    );
    worst(
        "update frame (the mesh turned 10°, update, every query) / warm frame",
        rows.iter()
            .map(|r| (ms(r.hierarchy.update) / ms(r.hierarchy.moved_warm), r))
            .collect(),
        false,
        Some(1.15),
    );
    // The goals of the soft-shadow work: against Embree per light size, and
    // against the hemicube under the large light (reported under the small).
    for (size, goal) in [(LightSize::Small, 8.0), (LightSize::Large, 1.5)] {
        worst(
            &format!(
                "Embree's frame / hierarchy's cold frame, light {}",
                size.name()
            ),
            rows.iter()
                .filter(|r| r.size == size)
                .filter_map(|r| r.embree.map(|(b, t)| (ms(b + t) / h(r), r)))
                .collect(),
            true,
            Some(goal),
        );
    }
    for (size, goal) in [(LightSize::Small, None), (LightSize::Large, Some(1.6))] {
        worst(
            &format!(
                "hemicube's cold frame / hierarchy's cold frame, light {}",
                size.name()
            ),
            rows.iter()
                .filter(|r| r.size == size)
                .filter_map(|r| r.hemicube.as_ref().map(|f| (ms(f.cold) / h(r), r)))
                .collect(),
            true,
            goal,
        );
    }
    worst(
        "ground candidates / with a root fitted to the receivers",
        rows.iter()
            .map(|r| {
                (
                    r.hierarchy.ground_candidates / r.fitted_ground_candidates.max(1e-9),
                    r,
                )
            })
            .collect(),
        false,
        Some(2.0),
    );
    let differing = rows
        .iter()
        .filter(|r| r.hemicube_bits_equal == Some(false))
        .count();
    let (mut mismatches, mut errors, mut unexplained, mut bits) = (0, 0, 0, 0u64);
    for c in rows.iter().filter_map(|r| r.comparison.as_ref()) {
        mismatches += c.mismatches.len();
        errors += c.library_errors().count();
        unexplained += c.unexplained().count();
        bits += c.bits;
    }
    println!(
        "bits: hierarchy against Embree {mismatches} mismatches of {bits} ({errors} where the \
         library disagrees with the exact segment test, {unexplained} not grazing an edge); \
         against the hemicube {differing} rows differ"
    );
    if errors > 0 || differing > 0 {
        return Err(Error::msg(
            "the hierarchy's bits differ from the exact test or from the hemicube",
        ));
    }
    Ok(())
}
