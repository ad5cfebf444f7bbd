//! `antumbra verify hemi` and `antumbra bench hemi`: hemisphere masks against
//! Embree tracing the same cell directions, for agreement and for speed.
//!
//! Receivers are mesh vertices (spread evenly over the vertex order) with their
//! area-weighted normals; the center of projection is pushed off the surface by
//! [`OFFSET_OF_DIAGONAL`] of the bounding-box diagonal so that both the rasterizer
//! and the rays see the surface from the same point.
//!
//! `bench hemi` ends with frames per second of a deforming mesh, every vertex
//! shaded per frame, with and without the far mesh, on a one-thread rayon pool
//! and on the default pool ([`crate::hemi_shading`] has the choices: SH order,
//! window, far mesh size, near radius).

use std::hint::black_box;
use std::time::{Duration, Instant};

use antumbra_core::Frame;
use antumbra_core::hemi::{
    BatchOptions, FarField, FarMesh, HemiMask, HemiScene, Material, Quality, RasterOptions,
    Receiver, ReceiverLod, TransferMethod, TransferRotation, TransferSpace, TransferTable,
    TriangleClusters, VertexShading, cell_direction, cell_directions,
    rasterize_receiver_with_counts, receiver_build, scene_mask_with_counts, vertex_transfer,
};
use antumbra_core::raycast::BvhScene;
use antumbra_core::sh::Sh;
use antumbra_core::{Ray, RayCaster};
use antumbra_tests::oracle::{OracleOptions, try_cast, try_frame};
use glam::Vec3;

use super::format_duration;
use crate::bounds::Bounds;
use crate::builtin;
use crate::cli::{BenchHemiArgs, QualityArg, VerifyHemiArgs};
use crate::error::{Error, Result};
use crate::ground::on_ground;
use crate::hemi_shading::{
    COEFFICIENTS, FAR_CELL_OF_DIAGONAL, LodMesh, NEAR_RADIUS_OF_DIAGONAL, OFFSET_OF_DIAGONAL,
    Occluders, PHONG_EXPONENT, Posed, Shader, Twist, half_space_table, sky_lighting,
};
use crate::mesh::TriangleMesh;

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

fn quality(arg: QualityArg) -> Quality<'static> {
    match arg {
        QualityArg::Exact => Quality::Exact,
        QualityArg::Table => Quality::Table(half_space_table()),
    }
}

/// Receivers: `count` vertices spread evenly over the vertex order, with their
/// normals; vertices without a normal (only degenerate triangles) are skipped.
pub(super) fn receivers(mesh: &TriangleMesh, count: usize) -> Vec<(Vec3, Vec3)> {
    let normals = mesh.vertex_normals();
    receiver_vertices(&normals, count)
        .into_iter()
        .map(|v| (Vec3::from(mesh.positions()[v]), normals[v]))
        .collect()
}

/// The vertices of [`receivers`], from the mesh's vertex `normals`.
pub(super) fn receiver_vertices(normals: &[Vec3], count: usize) -> Vec<usize> {
    let vertices = normals.len();
    let step = (vertices as f64 / count.max(1) as f64).max(1.0);
    (0..count.min(vertices))
        .map(|k| (k as f64 * step) as usize)
        .filter(|&v| normals[v].is_finite() && normals[v].length_squared() > 0.5)
        .collect()
}

/// Seconds Embree takes to create and commit a scene of `mesh` (one core,
/// the fastest of three), the build part of its deforming frame.
pub(super) fn embree_build_seconds(mesh: &TriangleMesh) -> Result<f64> {
    let center = mesh.bounds().center();
    let run = try_frame(
        mesh.positions(),
        mesh.indices(),
        &[center],
        &[center + Vec3::X],
        3,
    )
    .map_err(|e| Error::msg(format!("{e}\n(use --no-embree to skip Embree's figures)")))?;
    Ok(run.build_seconds)
}

fn load(mesh: &Option<std::path::PathBuf>) -> Result<TriangleMesh> {
    match mesh {
        Some(path) => TriangleMesh::load_obj(path),
        None => builtin::bunny(),
    }
}

/// One ray per valid cell of every receiver, in receiver then row-major cell order.
pub(super) fn cell_rays(receivers: &[Receiver]) -> Vec<Ray> {
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
pub(super) fn time_per_call(min_time: Duration, mut work: impl FnMut()) -> Duration {
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
    if args.scaling {
        return super::hemi_scaling::run(args);
    }
    if args.mesh.len() > 1 {
        return Err(Error::msg(
            "--mesh is given more than once: only --scaling takes several meshes",
        ));
    }
    let mesh = load(&args.mesh.first().cloned())?;
    // The frames per second need a far mesh, sized from the diagonal: refuse
    // before any timing rather than after.
    mesh.require_extent()?;
    let min_time = Duration::from_millis(args.min_time);
    if args.on_ground {
        let object = mesh.bounds();
        return frame_rates(on_ground(&mesh)?, &object, args.quality, min_time, None);
    }
    let offset = OFFSET_OF_DIAGONAL * mesh.bounds().diagonal();
    let chosen = receivers(&mesh, args.receivers as usize);
    let count = chosen.len().max(1) as f64;
    let view = mesh.view();
    let _ = half_space_table();
    println!(
        "bench hemi: {} ({} triangles), {} receivers, one thread, each figure repeated for at least {} ms; \
         the rasterizer's {} build",
        mesh.name(),
        mesh.triangle_count(),
        chosen.len(),
        args.min_time,
        receiver_build()
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
    // The same receivers through the batch path engines use: the mesh in
    // 32-triangle clusters whose boxes skip whole clusters below a receiver's
    // horizon. The clusters are built once, outside the timing, as Embree's and
    // the BVH's trees are; a deforming mesh recomputes only their boxes per frame
    // (in the frames-per-second figures below).
    let mut clusters = TriangleClusters::new(&view, TriangleClusters::DEFAULT_SIZE);
    let scene = HemiScene::new(clusters.update(view));
    for arg in [QualityArg::Exact, QualityArg::Table] {
        let options = BatchOptions {
            quality: quality(arg),
            normal_offset: offset,
            ..BatchOptions::default()
        };
        let (mut rasterized, mut nodes) = (0u64, 0u64);
        for &(p, n) in &chosen {
            // Same masks as the unclustered rasterizer (the clusters only skip).
            let plain = RasterOptions {
                quality: quality(arg),
                normal_offset: offset,
                ..RasterOptions::default()
            };
            let expected = rasterize_receiver_with_counts(&view, p, n, &plain).0;
            let (mask, counts) = scene_mask_with_counts(&scene, p, n, &options);
            if mask != expected {
                return Err(Error::msg("clustered and plain masks differ"));
            }
            rasterized += u64::from(counts.rasterized);
            nodes += u64::from(counts.nodes);
        }
        let elapsed = time_per_call(min_time, || {
            for &(p, n) in &chosen {
                black_box(scene_mask_with_counts(&scene, black_box(p), n, &options));
            }
        });
        let micros = elapsed.as_secs_f64() * 1e6 / count;
        println!(
            "rasterizer {:<5}  {micros:>9.2} µs per receiver  with {}-triangle clusters \
             ({:.0} triangles and {:.0} hierarchy nodes tested per receiver)",
            quality_name(arg),
            TriangleClusters::DEFAULT_SIZE,
            rasterized as f64 / count,
            nodes as f64 / count,
        );
        per_receiver.push((
            if matches!(arg, QualityArg::Exact) {
                "exact, clustered"
            } else {
                "table, clustered"
            },
            micros,
        ));
    }
    // What grouping costs against what it saves per receiver: the batch entry
    // points of the C API group when a call has at least this many receivers.
    let build = time_per_call(min_time, || {
        black_box(TriangleClusters::new(
            black_box(&view),
            TriangleClusters::DEFAULT_SIZE,
        ));
    });
    let saved = per_receiver[0].1 - per_receiver[2].1;
    println!(
        "grouping the clusters: {:.1} µs ({:.0} ns per triangle); saves {saved:.2} µs per exact \
         receiver, so it pays for itself from {:.1} receivers",
        build.as_secs_f64() * 1e6,
        build.as_secs_f64() * 1e9 / mesh.triangle_count().max(1) as f64,
        build.as_secs_f64() * 1e6 / saved.max(f64::MIN_POSITIVE)
    );
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
    // The same rays as a ray tracer with packets casts them: each receiver's
    // in one call (rays from one point, traced together, the same answers).
    let per_receiver_rays = rays.len() / chosen.len().max(1);
    let mut answers = vec![false; rays.len()];
    let elapsed = time_per_call(min_time, || {
        for (rays, answers) in rays
            .chunks(per_receiver_rays.max(1))
            .zip(answers.chunks_mut(per_receiver_rays.max(1)))
        {
            bvh.occluded_many(black_box(rays), answers);
        }
        black_box(&answers);
    });
    let packet_micros = elapsed.as_secs_f64() * 1e6 / count;
    let same = rays
        .iter()
        .zip(&answers)
        .all(|(ray, &answer)| bvh.occluded(ray) == answer);
    println!(
        "BVH, packets       {packet_micros:>9.2} µs per receiver  (a receiver's rays per occluded_many call; {} answers as one ray at a time)",
        if same { "the same" } else { "NOT the same" }
    );
    let mut embree_hits: Option<Vec<bool>> = None;
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
        embree_hits = Some(run.hits.iter().map(|h| h.occluded).collect());
        let micros = seconds * 1e6 / count;
        println!("Embree (embreex)   {micros:>9.2} µs per receiver  (one batch rtcOccluded1 loop)");
        Some(micros)
    };
    for (name, micros) in per_receiver {
        print!(
            "rasterizer {name}: {:.2}x less time per receiver than the BVH ({:.2}x than its packets)",
            bvh_micros / micros,
            packet_micros / micros
        );
        if let Some(embree) = embree_micros {
            print!(", {:.2}x less than Embree", embree / micros);
        }
        println!();
    }
    println!();
    // The reference of the far-mesh table: the full mesh traced along every cell
    // direction, by Embree when it ran, else by our BVH (the same answers).
    let (reference_hits, reference_name, reference_micros) = match (embree_hits, embree_micros) {
        (Some(hits), Some(micros)) => (hits, "Embree", micros),
        _ => (
            rays.iter().map(|ray| bvh.occluded(ray)).collect(),
            "the BVH",
            bvh_micros,
        ),
    };
    far_mesh_table(
        &mesh,
        &chosen,
        offset,
        &reference_hits,
        (reference_name, reference_micros),
        min_time,
    )?;
    println!();
    let object = mesh.bounds();
    frame_rates(
        LodMesh::new(mesh)?,
        &object,
        args.quality,
        min_time,
        embree_micros,
    )
}

/// Far mesh sizes (triangles) the far-mesh table tries, those below half the
/// mesh's count.
const FAR_TABLE_TRIANGLES: [usize; 6] = [500, 1_000, 2_000, 4_000, 8_000, 16_000];

/// Far-field levels the far-mesh table tries (the first level of each size
/// above, then coarser ones).
const FAR_TABLE_LEVELS: [usize; 2] = [3, 6];

/// Near radii the far-mesh table tries besides the library's rule, as fractions of
/// the bounding-box diagonal.
const FAR_TABLE_RADII_OF_DIAGONAL: [f32; 2] = [0.05, 0.1];

/// The table of far mesh sizes and near radii: time per vertex of its transfer
/// vectors (exact masks, clusters, as a shader computes them) against tracing the
/// 812 cell directions of the full mesh, and the irradiance error against those
/// rays under the built-in sky (4 bands, windowed), relative RMS over the
/// receivers' luminance.
fn far_mesh_table(
    mesh: &TriangleMesh,
    chosen: &[(Vec3, Vec3)],
    offset: f32,
    reference_hits: &[bool],
    (reference_name, reference_micros): (&str, f64),
    min_time: Duration,
) -> Result<()> {
    let table = TransferTable::<COEFFICIENTS>::new();
    let method = TransferMethod::Cells(&table);
    let lighting = sky_lighting(&builtin::sunrise()?)?;
    let luminance = |t: &Sh<COEFFICIENTS>| {
        f64::from(
            0.2126 * lighting.r.dot(t) + 0.7152 * lighting.g.dot(t) + 0.0722 * lighting.b.dot(t),
        )
    };
    // Reference irradiance of each receiver from the traced cells.
    let mut next = reference_hits.iter();
    let reference: Vec<f64> = chosen
        .iter()
        .map(|&(_, n)| {
            let mut mask = HemiMask::default();
            for (i, j, _) in cell_directions() {
                mask.set(i, j, *next.next().expect("one answer per valid cell"));
            }
            let local = method.transfer(&mask);
            luminance(&TransferRotation::new(&Frame::from_normal(n)).to_world(&local))
        })
        .collect();
    let reference_power: f64 = reference.iter().map(|e| e * e).sum();
    let view = mesh.view();
    let diagonal = mesh.bounds().diagonal();
    let options = BatchOptions {
        quality: Quality::Exact,
        normal_offset: offset,
        ..BatchOptions::default()
    };
    let mut full_clusters = TriangleClusters::new(&view, TriangleClusters::DEFAULT_SIZE);
    let count = chosen.len().max(1) as f64;
    println!(
        "far mesh table: transfer vectors ({COEFFICIENTS} coefficients, exact masks, clusters) per \
         vertex against {reference_name} tracing the 812 cell directions of the full mesh \
         ({reference_micros:.1} µs per vertex); irradiance under the built-in sky, relative RMS \
         error of the luminance against those rays"
    );
    println!(
        "{:>14} {:>22} {:>16} {:>14} {:>12} {:>12} {:>8}",
        "far triangles",
        "near radius",
        "µs per vertex",
        "rays / this",
        "error",
        "rasterized",
        "nodes"
    );
    let full = full_clusters.update(view);
    let row = |scene: &HemiScene<'_>, far_name: &str, radius_name: &str| {
        let transfer =
            |p: Vec3, n: Vec3| vertex_transfer(scene, p, n, &options, method, TransferSpace::World);
        let mut error = 0.0f64;
        let (mut rasterized, mut nodes) = (0u64, 0u64);
        for (&(p, n), &want) in chosen.iter().zip(&reference) {
            let got = luminance(&transfer(p, n));
            error += (got - want) * (got - want);
            let counts = scene_mask_with_counts(scene, p, n, &options).1;
            rasterized += u64::from(counts.rasterized);
            nodes += u64::from(counts.nodes);
        }
        let elapsed = time_per_call(min_time, || {
            for &(p, n) in chosen {
                black_box(transfer(black_box(p), n));
            }
        });
        let micros = elapsed.as_secs_f64() * 1e6 / count;
        println!(
            "{far_name:>14} {radius_name:>22} {micros:>16.2} {:>13.2}x {:>11.3}% {:>12.0} {:>8.0}",
            reference_micros / micros,
            100.0 * (error / reference_power.max(f64::MIN_POSITIVE)).sqrt(),
            rasterized as f64 / count,
            nodes as f64 / count,
        );
    };
    row(&HemiScene::new(full), "none", "(full mesh)");
    for target in FAR_TABLE_TRIANGLES {
        if 2 * target > mesh.triangle_count() {
            continue;
        }
        let far = FarMesh::with_triangles(&view, target)
            .map_err(|e| Error::msg(format!("cannot simplify {}: {e}", mesh.name())))?;
        let mut far_clusters = TriangleClusters::new(&far.view(), TriangleClusters::DEFAULT_SIZE);
        let far_mesh = far_clusters.update(far.view());
        let rule = far.default_near_radius();
        let name = far.triangle_count().to_string();
        row(
            &HemiScene::with_far(full, far_mesh, rule),
            &name,
            &format!("{rule:.4} (3 cells)"),
        );
        for fraction in FAR_TABLE_RADII_OF_DIAGONAL {
            let radius = fraction * diagonal;
            row(
                &HemiScene::with_far(full, far_mesh, radius),
                &name,
                &format!("{radius:.4} (diag/{:.0})", 1.0 / fraction),
            );
        }
        let mut previous = 0;
        for levels in FAR_TABLE_LEVELS {
            let mut field = FarField::new(&view, target, levels)
                .map_err(|e| Error::msg(format!("cannot simplify {}: {e}", mesh.name())))?;
            let built = field.level_count();
            // A small mesh runs out of coarser levels: no second row of the
            // same field.
            if built == previous {
                continue;
            }
            previous = built;
            let posed = field.pose(&view).map_err(|e| Error::msg(e.to_string()))?;
            row(
                &posed.scene(full),
                &format!("{name} +{}", built - 1),
                &format!("{rule:.4} x 2^k ({built} levels)"),
            );
        }
    }
    Ok(())
}

/// Far levels of the frames-per-second table's third row.
const FRAME_FAR_LEVELS: usize = 3;

/// The sparse receivers' tolerance in the frames-per-second table's last two
/// rows (keys one edge apart).
const FRAME_SPARSE_TOLERANCE: f32 = 0.1;

/// Twist angles the benchmark's frames cycle through, in degrees.
const FRAME_TWIST_DEGREES: [f32; 4] = [0.0, 40.0, 80.0, 120.0];

/// Calls `frame(k)` for `k = 0, 1, ...` (each returns its own time) until
/// `min_time` has passed, the first call a warm-up unless it alone took
/// `min_time` (then it is the measurement); returns the mean time per frame.
fn time_frames(
    min_time: Duration,
    mut frame: impl FnMut(usize) -> Result<Duration>,
) -> Result<Duration> {
    let first = frame(0)?;
    if first >= min_time {
        return Ok(first);
    }
    let (mut total, mut count) = (Duration::ZERO, 0u32);
    while count == 0 || total < min_time {
        total += frame(count as usize + 1)?;
        count += 1;
    }
    Ok(total / count)
}

/// The frames-per-second table of `bench hemi`: every vertex of `lod` shaded
/// per frame with the object of bounds `object` twisted (the ground, at its
/// bottom, stays), with the full mesh, the far mesh and the library's far
/// levels, on one thread and on rayon's default pool.
fn frame_rates(
    lod: LodMesh,
    object: &Bounds,
    quality_arg: QualityArg,
    min_time: Duration,
    embree_micros: Option<f64>,
) -> Result<()> {
    let triangles = lod.full.triangle_count();
    let diagonal = object.diagonal();
    let twist = Twist::of_bounds(object);
    let shader = Shader::new();
    let lighting = sky_lighting(&builtin::sunrise()?)?;
    let center = object.center();
    let material = Material {
        albedo: Vec3::splat(0.4),
        specular: Vec3::splat(0.5),
        lobe: Some(shader.lobe()),
        eye: center + diagonal * Vec3::new(-0.4, 0.5, 1.1),
    };
    let quality = match quality_arg {
        QualityArg::Exact => shader.quality(false),
        QualityArg::Table => shader.quality(true),
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| Error::msg(format!("cannot start a one-thread pool: {e}")))?;
    let threads = rayon::current_num_threads();
    println!(
        "frames per second shading every vertex of {} ({} vertices; diffuse + glossy, {COEFFICIENTS} SH coefficients, \
         Phong exponent {PHONG_EXPONENT}, {} masks, {}-triangle clusters); each frame twists the mesh, \
         recomputes normals and cluster boxes, and shades; the rasterizer's {} build",
        lod.full.name(),
        lod.full.vertex_count(),
        quality_name(quality_arg),
        TriangleClusters::DEFAULT_SIZE,
        receiver_build()
    );
    println!(
        "far mesh: {} triangles of {triangles} (vertex clustering, cells of {:.4} = diagonal/{:.0}), near radius {:.4} (diagonal/{:.0})",
        lod.far.triangle_count(),
        lod.far_cell,
        1.0 / FAR_CELL_OF_DIAGONAL,
        lod.near_radius,
        1.0 / NEAR_RADIUS_OF_DIAGONAL
    );
    let mut out = vec![VertexShading::default(); lod.full.vertex_count()];
    let mut rates = Vec::new();
    let mut levels_built = 0;
    // Each row's colours in the first twist's pose, for their error against
    // the full mesh's (the first row).
    let mut colours: Vec<Vec<VertexShading>> = Vec::new();
    // Each row's receivers rasterized in that pose.
    let mut rasterized: Vec<usize> = Vec::new();
    let sparse = ReceiverLod {
        spacing: 1,
        tolerance: FRAME_SPARSE_TOLERANCE,
    };
    let settings = [
        (Occluders::Full, None),
        (Occluders::FarMesh, None),
        (Occluders::FarLevels(FRAME_FAR_LEVELS), None),
        (Occluders::Full, Some(sparse)),
        (Occluders::FarMesh, Some(sparse)),
    ];
    for (occluders, receivers) in settings {
        let mut posed = Posed::new(&lod, occluders)?;
        posed.set_receivers(receivers)?;
        if let Some(field) = posed.far_field() {
            levels_built = field.level_count();
            println!(
                "far levels: {levels_built}, the first of {} triangles with cells of {:.4} \
                 ({:.1} times the far mesh's), near radius {:.4}, doubling per level",
                field.level(0).triangle_count(),
                field.level(0).cell_size(),
                field.level(0).cell_size() / lod.far_cell,
                field.near_radius(0)
            );
        }
        let first = FRAME_TWIST_DEGREES[0].to_radians();
        let time = posed.frame(
            |p| twist.apply(p, first),
            &shader,
            quality,
            &lighting,
            &material,
            &mut out,
        )?;
        colours.push(out.clone());
        rasterized.push(time.rasterized);
        let mut row = Vec::new();
        for pool in [Some(&one), None] {
            let mut frame = |k: usize| -> Result<Duration> {
                let angle = FRAME_TWIST_DEGREES[k % FRAME_TWIST_DEGREES.len()].to_radians();
                let mut run = || {
                    posed.frame(
                        |p| twist.apply(p, angle),
                        &shader,
                        quality,
                        &lighting,
                        &material,
                        &mut out,
                    )
                };
                let time = match pool {
                    Some(pool) => pool.install(run)?,
                    None => run()?,
                };
                Ok(time.total())
            };
            row.push(time_frames(min_time, &mut frame)?);
        }
        rates.push(row);
    }
    let cell = |d: Duration| {
        let fps = 1.0 / d.as_secs_f64().max(1e-9);
        // Three significant digits, also for the large meshes' fractions of a frame.
        let digits = (2 - fps.log10().floor() as i32).clamp(1, 6) as usize;
        format!("{fps:.digits$} fps ({})", format_duration(d))
    };
    // Relative RMS of the colours against the full mesh's.
    let error = |row: &[VertexShading]| {
        let (mut squared, mut total) = (0.0f64, 0.0f64);
        for (got, want) in row.iter().zip(&colours[0]) {
            let (got, want) = (got.diffuse + got.glossy, want.diffuse + want.glossy);
            squared += f64::from((got - want).length_squared());
            total += f64::from(want.length_squared());
        }
        (squared / total.max(f64::MIN_POSITIVE)).sqrt()
    };
    println!();
    println!(
        "{:<34} {:>24} {:>24} {:>14} {:>11}",
        "occluders",
        "1 thread",
        format!("{threads} threads"),
        "colour error",
        "rasterized"
    );
    let sparse_name = format!("sparse receivers (1, {FRAME_SPARSE_TOLERANCE})");
    let names = [
        "full mesh".to_string(),
        "full near + far mesh".to_string(),
        format!("full near + {levels_built} far levels"),
        format!("full mesh, {sparse_name}"),
        format!("far mesh, {sparse_name}"),
    ];
    let vertices = lod.full.vertex_count().max(1) as f64;
    for (((name, row), shaded), count) in names.iter().zip(&rates).zip(&colours).zip(&rasterized) {
        println!(
            "{name:<34} {:>24} {:>24} {:>13.2}% {:>10.0}%",
            cell(row[0]),
            cell(row[1]),
            100.0 * error(shaded),
            100.0 * *count as f64 / vertices
        );
    }
    let speed_up = |r: usize, k: usize| rates[0][k].as_secs_f64() / rates[r][k].as_secs_f64();
    for (r, name) in [
        (1, "far mesh speed-up"),
        (2, "far levels speed-up"),
        (3, "sparse receivers speed-up"),
        (4, "far mesh + sparse speed-up"),
    ] {
        println!(
            "{name:<34} {:>24} {:>24}",
            format!("{:.2}x", speed_up(r, 0)),
            format!("{:.2}x", speed_up(r, 1))
        );
    }
    // Embree's deforming frame on one core: a new scene of the posed mesh,
    // then the 812 cell rays of every vertex at the per-receiver cost measured
    // above.
    if let Some(micros) = embree_micros {
        let build = embree_build_seconds(&lod.full)?;
        let embree = build + micros * 1e-6 * lod.full.vertex_count() as f64;
        print!(
            "Embree's frame on 1 thread: {} (scene build {}, 812 rays per vertex); ",
            format_duration(Duration::from_secs_f64(embree)),
            format_duration(Duration::from_secs_f64(build))
        );
        let ratios: Vec<String> = names
            .iter()
            .zip(&rates)
            .map(|(name, row)| format!("{name} {:.2}x", embree / row[0].as_secs_f64()))
            .collect();
        println!("Embree's frame / ours: {}", ratios.join(", "));
    }
    println!(
        "all-core scaling on {threads} threads: full mesh {:.2}x, with the far mesh {:.2}x",
        rates[0][0].as_secs_f64() / rates[0][1].as_secs_f64(),
        rates[1][0].as_secs_f64() / rates[1][1].as_secs_f64()
    );
    Ok(())
}
