//! `antumbra verify ssv` and `antumbra bench ssv`: soft shadow visibility bits
//! (`antumbra_core::ssv`) against Embree occlusion rays, for agreement and for
//! speed, on the shared floor scene of the cross-check tests
//! ([`antumbra_tests::scenes::FloorScene`]: the mesh over a floor, a quad light
//! in three orientations, receivers on the floor and just off the mesh).

use std::hint::black_box;
use std::time::{Duration, Instant};

use antumbra_core::ssv::{
    LightPolygon, SamplePattern, SoftShadows, SsvOptions, SsvStatistics, Structure,
};
use antumbra_tests::oracle::{OracleOptions, try_cast};
use antumbra_tests::scenes::{FloorScene, LightOrientation};
use antumbra_tests::ssv::{
    Comparison, GRAZING_OF_SCENE, MAX_MISMATCH_FRACTION, compare_with_embree, shadow_rays,
};
use glam::Vec3;

use crate::builtin;
use crate::cli::{BenchSsvArgs, VerifySsvArgs};
use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;
use crate::progress;

/// Seed of the jittered light samples (the Embree test uses the same).
pub const SAMPLE_SEED: u64 = 0x55f;

/// Sample counts of the benchmark.
const SAMPLE_COUNTS: [usize; 4] = [16, 64, 256, 1024];

/// Mismatches described one per line.
const SHOWN_MISMATCHES: usize = 10;

fn load(mesh: Option<&std::path::PathBuf>) -> Result<TriangleMesh> {
    match mesh {
        Some(path) => TriangleMesh::load_obj(path),
        None => builtin::bunny(),
    }
}

/// The soft shadows of `scene` with `samples` jittered samples; the time taken.
fn build(
    scene: &FloorScene,
    samples: usize,
    options: SsvOptions,
) -> Result<(SoftShadows, Duration)> {
    let light = LightPolygon::new(&scene.light).map_err(|e| Error::msg(e.to_string()))?;
    let points = light.samples(samples, SamplePattern::Jittered, SAMPLE_SEED);
    let started = Instant::now();
    let ssv = SoftShadows::new(&scene.occluders.view(), light, &points, options)
        .map_err(|e| Error::msg(format!("cannot prepare the soft shadows: {e}")))?;
    Ok((ssv, started.elapsed()))
}

/// Runs `antumbra verify ssv`.
pub fn run_verify(args: &VerifySsvArgs) -> Result<()> {
    let mesh = load(args.mesh.as_ref())?;
    let bar = progress::bar(
        LightOrientation::ALL.len() as u64,
        "verify ssv",
        "light orientations",
    );
    let mut total = Comparison::default();
    let mut lines = Vec::new();
    for orientation in LightOrientation::ALL {
        let scene = FloorScene::new(
            mesh.positions(),
            mesh.indices(),
            orientation,
            args.floor_grid as usize,
            args.mesh_points as usize,
        );
        let (ssv, _) = build(&scene, args.samples as usize, SsvOptions::default())?;
        let comparison =
            compare_with_embree(&scene.occluders, &ssv, &scene.receivers()).map_err(Error::msg)?;
        lines.push(format!(
            "light {:<11} {} receivers ({} on the floor, {} on the mesh), {} bits, {:.2} % visible, {} mismatches",
            orientation.name(),
            comparison.receivers,
            scene.floor_receivers.len(),
            scene.mesh_receivers.len(),
            comparison.bits,
            100.0 * comparison.visible_bits as f64 / comparison.bits.max(1) as f64,
            comparison.mismatches.len()
        ));
        total.merge(comparison);
        bar.inc(1);
    }
    bar.finish_and_clear();
    println!(
        "verify ssv: {} ({} triangles) scaled to a largest extent of 1 over a floor, {} light samples, \
         bits of the hierarchy against Embree occlusion rays over the open segments",
        mesh.name(),
        mesh.triangle_count(),
        args.samples
    );
    for line in &lines {
        println!("{line}");
    }
    for m in total.mismatches.iter().take(SHOWN_MISMATCHES) {
        let class = if m.library != m.exact {
            "LIBRARY DISAGREES WITH THE EXACT TEST"
        } else if m.is_grazing(total.scale) {
            "grazing (Embree rounding)"
        } else {
            "UNEXPLAINED: the library agrees with the exact test, but no edge is near"
        };
        println!(
            "  receiver {:?} sample {:?}: library {}, Embree the opposite; triangle {:?}, {:.2e} from its nearest edge: {class}",
            m.point,
            m.target,
            if m.library { "visible" } else { "blocked" },
            m.triangle,
            m.edge_distance
        );
    }
    let grazing = total
        .mismatches
        .iter()
        .filter(|m| m.is_grazing(total.scale))
        .count();
    println!(
        "mismatches: {} grazing an edge (within {GRAZING_OF_SCENE:e} of the scene size; farthest {:.2e}), \
         {} where the library disagrees with the exact segment test, {} unexplained",
        grazing,
        total.worst_edge_distance(),
        total.library_errors().count(),
        total.unexplained().count()
    );
    println!(
        "ssv agreement: {:.6}% of {} bits, {} mismatches",
        100.0 * total.agreement(),
        total.bits,
        total.mismatches.len()
    );
    if total.passes() {
        Ok(())
    } else {
        Err(Error::msg(format!(
            "more than {MAX_MISMATCH_FRACTION:e} of the bits differ, or a mismatch is not a grazing case"
        )))
    }
}

/// Repeats `work` until `min_time` has passed (after one warm-up call); returns
/// the mean time per call.
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

/// The structures timed, in table order.
const STRUCTURES: [(Structure, &str); 4] = [
    (Structure::Hierarchy, "hierarchy"),
    (Structure::Hemicube, "hemicube"),
    (Structure::BruteForce, "brute force"),
    (Structure::RayTrace, "obvhs rays"),
];

/// One structure at one sample count.
struct Timing {
    /// Warm time per receiver, µs.
    warm: f64,
    /// First pass per receiver (lazy construction included), µs.
    first: f64,
    /// Creation time.
    build: Duration,
    /// Candidate edges per query.
    candidates: f64,
    /// After the timed passes.
    statistics: SsvStatistics,
}

fn time_structure(
    scene: &FloorScene,
    receivers: &[Vec3],
    samples: usize,
    options: SsvOptions,
    min_time: Duration,
) -> Result<Timing> {
    let (ssv, build_time) = build(scene, samples, options)?;
    let mut bits = vec![0u64; ssv.words_per_receiver()];
    let count = receivers.len().max(1) as f64;
    let started = Instant::now();
    let mut candidates = 0u64;
    for &p in receivers {
        let info = ssv
            .query_detailed(p, &mut bits)
            .map_err(|e| Error::msg(format!("query failed: {e}")))?;
        candidates += u64::from(info.candidates);
    }
    let first = started.elapsed().as_secs_f64() * 1e6 / count;
    let warm = time_per_call(min_time, || {
        for &p in receivers {
            let _ = black_box(ssv.query(black_box(p), &mut bits));
        }
    });
    Ok(Timing {
        warm: warm.as_secs_f64() * 1e6 / count,
        first,
        build: build_time,
        candidates: candidates as f64 / count,
        statistics: ssv.statistics(),
    })
}

fn kib(bytes: usize) -> String {
    if bytes >= 10 << 20 {
        format!("{:.0} MiB", bytes as f64 / (1 << 20) as f64)
    } else {
        format!("{:.0} KiB", bytes as f64 / 1024.0)
    }
}

/// Runs `antumbra bench ssv`.
pub fn run_bench(args: &BenchSsvArgs) -> Result<()> {
    if args.frame {
        return super::ssv_frame::run(args);
    }
    let mesh = load(args.mesh.first())?;
    let mesh_points = args.mesh_points.unwrap_or(100);
    let min_time = Duration::from_millis(args.min_time);
    let orientations = LightOrientation::ALL;
    let counts: Vec<usize> = if args.samples.is_empty() {
        SAMPLE_COUNTS.to_vec()
    } else {
        args.samples.iter().map(|&n| n as usize).collect()
    };
    let leaf_edges = args.leaf_edges.unwrap_or(SsvOptions::default().leaf_edges);
    let max_depth = args.max_depth.unwrap_or(SsvOptions::default().max_depth);
    println!(
        "bench ssv: {} ({} triangles) scaled to a largest extent of 1 over a floor (2 triangles), 0.5 x 0.5 quad light \
         1.8 away; one thread; time per receiver (warm: the hierarchy's lazy nodes built by a first pass, \
         printed apart), each warm figure repeated for at least {} ms; hierarchy: leaf edges {}, max depth {}",
        mesh.name(),
        mesh.triangle_count(),
        args.min_time,
        leaf_edges,
        max_depth
    );
    let bar = progress::bar(
        (orientations.len() * counts.len()) as u64,
        "bench ssv",
        "configurations",
    );
    // hierarchy time per receiver at [orientation][N], for the orientation summary.
    let mut hierarchy = vec![vec![0.0f64; counts.len()]; orientations.len()];
    let mut goals = Vec::new();
    let mut tables = Vec::new();
    for (o, &orientation) in orientations.iter().enumerate() {
        let scene = FloorScene::new(
            mesh.positions(),
            mesh.indices(),
            orientation,
            args.floor_grid as usize,
            mesh_points as usize,
        );
        let receivers = scene.receivers();
        let count = receivers.len().max(1) as f64;
        let mut table = vec![format!(
            "light {} ({} receivers: {} on the floor, {} on the mesh)",
            orientation.name(),
            receivers.len(),
            scene.floor_receivers.len(),
            scene.mesh_receivers.len()
        )];
        table.push(format!(
            "{:>5} | {:>10} {:>10} {:>10} {:>10} {:>10} µs/receiver | hierarchy faster than: {:>7} {:>8} {:>7} {:>7} | candidates: {:>6} {:>6} {:>6} | hierarchy first pass, nodes, memory | hemicube memory",
            "N", "hierarchy", "hemicube", "brute", "obvhs rays", "Embree", "Embree", "hemicube", "brute", "rays", "hier", "hemi", "brute"
        ));
        for (k, &n) in counts.iter().enumerate() {
            let timings = STRUCTURES
                .iter()
                .map(|&(structure, _)| {
                    let options = SsvOptions {
                        structure,
                        leaf_edges,
                        max_depth,
                        ..SsvOptions::default()
                    };
                    time_structure(&scene, &receivers, n, options, min_time)
                })
                .collect::<Result<Vec<_>>>()?;
            let embree = if args.no_embree {
                None
            } else {
                let light =
                    LightPolygon::new(&scene.light).map_err(|e| Error::msg(e.to_string()))?;
                let samples = light.samples(n, SamplePattern::Jittered, SAMPLE_SEED);
                let rays = shadow_rays(&receivers, &samples);
                let run = try_cast(
                    &scene.occluders.positions,
                    &scene.occluders.indices,
                    &rays,
                    OracleOptions {
                        timing: true,
                        ..OracleOptions::default()
                    },
                )
                .map_err(|e| Error::msg(format!("{e}\n(use --no-embree to skip this figure)")))?;
                let seconds = run.occluded_seconds.expect("timing was requested");
                Some(seconds * 1e6 / count)
            };
            let [h, hc, bf, rt] = [0, 1, 2, 3].map(|i| &timings[i]);
            hierarchy[o][k] = h.warm;
            let ratio = |other: f64| format!("{:.2}x", other / h.warm);
            table.push(format!(
                "{n:>5} | {:>10.2} {:>10.2} {:>10.2} {:>10.2} {:>10} µs/receiver | hierarchy faster than: {:>7} {:>8} {:>7} {:>7} | candidates: {:>6.1} {:>6.1} {:>6.1} | {:.2} µs, {} nodes, {} | {} ({} cells, built in {:.1} ms)",
                h.warm,
                hc.warm,
                bf.warm,
                rt.warm,
                embree.map_or("-".to_string(), |e| format!("{e:.2}")),
                embree.map_or("-".to_string(), ratio),
                ratio(hc.warm),
                ratio(bf.warm),
                ratio(rt.warm),
                h.candidates,
                hc.candidates,
                bf.candidates,
                h.first,
                h.statistics.nodes,
                kib(h.statistics.bytes),
                kib(hc.statistics.bytes),
                hc.statistics.nodes,
                hc.build.as_secs_f64() * 1e3,
            ));
            if n == 256 {
                goals.push(format!(
                    "N = 256, light {:<11}: hierarchy {:.2}x faster than Embree rays (goal >= 10x), {:.2}x faster than the hemicube (goal >= 1.6x), {:.2}x faster than obvhs rays",
                    orientation.name(),
                    embree.map_or(f64::NAN, |e| e / h.warm),
                    hc.warm / h.warm,
                    rt.warm / h.warm
                ));
            }
            bar.inc(1);
        }
        tables.push(table);
    }
    bar.finish_and_clear();
    for table in tables {
        println!();
        for line in table {
            println!("{line}");
        }
    }
    println!();
    for line in goals {
        println!("{line}");
    }
    let spreads: Vec<String> = counts
        .iter()
        .enumerate()
        .map(|(k, n)| {
            let times = hierarchy.iter().map(|row| row[k]);
            let max = times.clone().fold(0.0, f64::max);
            let min = times.fold(f64::INFINITY, f64::min);
            format!("N = {n}: {:.2}x", max / min)
        })
        .collect();
    println!(
        "light orientation changes the hierarchy's time per receiver by (slowest / fastest, goal < 2x): {}",
        spreads.join(", ")
    );
    Ok(())
}
