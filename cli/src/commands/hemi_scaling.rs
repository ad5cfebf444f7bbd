//! `antumbra bench hemi --scaling`: how a deforming-mesh frame's cost per
//! vertex grows with the mesh, for the exact path and the library's far field,
//! against Embree's frame on the same receivers, with the error each far-field
//! setting costs.
//!
//! Per mesh (the built-in bunny, teapot and armadillo, then each `--mesh`), one row per
//! setting of `antumbra_hemi_shading_options` (`far_triangles`, `far_levels`),
//! the last one following the mesh's size (a first level of a quarter of its
//! triangles, every level), whose growth from the smallest mesh of about
//! 10,000 triangles or more to the largest is printed at the end:
//!
//! - **ours**: one frame of core's `HemiShader` (what `antumbra_hemi_shader_transfer`
//!   runs), one thread: the frame's posing (normals, cluster boxes, far levels)
//!   over every vertex, divided by the vertex count, plus the transfer vector
//!   (3 bands, exact masks) of each timed receiver;
//! - **Embree**: the scene's build divided by the vertex count, plus the 812
//!   occlusion rays of each timed receiver (one batch, one thread);
//! - **error**: relative RMS over the receivers of the transfer vector's
//!   constant coefficient (ambient occlusion) against the full mesh's exact
//!   one, divided by its mean;
//! - **tested**: triangles and hierarchy nodes tested per receiver.
//!
//! Then the whole frame (posing, then every vertex, one thread), timed alike:
//! the exact path (`every`), and sparse receivers (`spacing/tolerance` and
//! the share rasterized) with the full mesh and the `(n/4)` far field, their
//! error over every vertex against the exact full mesh.

use std::hint::black_box;
use std::time::Duration;

use antumbra_core::MeshView;
use antumbra_core::hemi::{
    BatchOptions, FarFieldSetup, HemiShader, MAX_FAR_LEVELS, Receiver, ReceiverLod, ShaderSetup,
    TransferMethod, TransferSpace, TransferTable, receiver_build, scene_mask_with_counts,
    vertex_transfer,
};
use antumbra_core::sh::Sh;
use antumbra_tests::oracle::{OracleOptions, try_cast};
use glam::Vec3;

use super::hemi::{cell_rays, embree_build_seconds, receiver_vertices, receivers, time_per_call};
use crate::builtin;
use crate::cli::BenchHemiArgs;
use crate::error::{Error, Result};
use crate::hemi_shading::OFFSET_OF_DIAGONAL;
use crate::mesh::TriangleMesh;

/// SH coefficients of the transfer vectors: 3 bands, as the frames users shade
/// diffuse surfaces with.
const COEFFICIENTS: usize = 9;

/// First far levels (`far_triangles`) of the table, those below a quarter of
/// the mesh's triangles.
const FAR_TRIANGLES: [usize; 2] = [2_000, 8_000];

/// Far levels (`far_levels`) of the table.
const FAR_LEVELS: [usize; 2] = [1, 3];

/// The setting that follows the mesh's size: a first level of a quarter of
/// its triangles and every level the library builds, so the full mesh is
/// rasterized only within a few triangles of the receiver and each coarser
/// level covers a band twice as wide; its rows are marked `(n/4)`.
const RELATIVE_DIVISOR: usize = 4;

/// Meshes with fewer triangles are left out of the growth line, which runs
/// from a mesh of about ten thousand triangles (homer, 9,856) up.
const GROWTH_FROM: usize = 9_000;

/// Sparse-receiver settings of the table (`ReceiverLod` spacing and
/// tolerance), each timed with the full mesh and with the `(n/4)` far field.
/// Keys one edge apart: on the meshes measured, at the same tolerance wider
/// spacings rasterize as many vertices (more of them disagree) for more error.
const RECEIVER_LODS: [ReceiverLod; 3] = [
    ReceiverLod {
        spacing: 1,
        tolerance: 0.05,
    },
    ReceiverLod {
        spacing: 1,
        tolerance: 0.1,
    },
    ReceiverLod {
        spacing: 1,
        tolerance: 0.2,
    },
];

/// How a row's frame is timed.
#[derive(Clone, Copy)]
enum Timing {
    /// Posing over every vertex, then the timed receivers only.
    Sampled,
    /// The whole frame (posing, then every vertex), with sparse receivers
    /// or (`None`) every vertex rasterized.
    Frame(Option<ReceiverLod>),
}

/// One row: a setting's frame and error.
struct Row {
    setting: String,
    /// `all` (the timed receivers), `every` (the whole frame, every vertex
    /// rasterized), or the sparse-receiver setting and the share of vertices
    /// it rasterized (the whole frame).
    receivers: String,
    /// The setting that follows the mesh's size ([`RELATIVE_DIVISOR`]).
    relative: bool,
    micros: f64,
    error: Option<f64>,
    triangles: f64,
    nodes: f64,
    /// For a sparse-receiver row, the time `HemiShader::set_receivers` takes
    /// to make its sampling, per vertex.
    sampling_micros: Option<f64>,
}

/// Runs the scaling table.
pub fn run(args: &BenchHemiArgs) -> Result<()> {
    let mut meshes = vec![builtin::bunny()?, builtin::teapot()?, builtin::armadillo()?];
    for path in &args.mesh {
        meshes.push(TriangleMesh::load_obj(path)?);
    }
    let min_time = Duration::from_millis(args.min_time);
    println!(
        "bench hemi --scaling: a deforming-mesh frame per vertex (posing over every vertex, \
         then {COEFFICIENTS}-coefficient transfer vectors of {} receivers, exact masks, one \
         thread) against Embree's frame (scene build per vertex, then 812 rays per receiver); \
         error: relative RMS of the constant coefficient against the full mesh's; the \
         rasterizer's {} build",
        args.receivers,
        receiver_build()
    );
    // Meshes by file name, not path.
    let names: Vec<String> = meshes
        .iter()
        .map(|m| {
            let name = std::path::Path::new(m.name());
            name.file_name()
                .map_or(m.name().to_string(), |f| f.to_string_lossy().into_owned())
        })
        .collect();
    let width = names
        .iter()
        .map(|n| n.chars().count())
        .max()
        .unwrap_or(4)
        .max(4);
    println!(
        "{:<width$} {:>9} {:<16} {:<14} {:>12} {:>12} {:>12} {:>8} {:>10} {:>8}",
        "mesh",
        "triangles",
        "far field",
        "receivers",
        "µs / vertex",
        "Embree µs",
        "Embree/ours",
        "error",
        "triangles",
        "nodes"
    );
    let mut worst: Option<(String, f64)> = None;
    // Per mesh, the sparse-receiver settings' sampling times.
    let mut samplings: Vec<String> = Vec::new();
    // The relative setting's time per vertex on meshes of at least
    // GROWTH_FROM triangles: (triangles, µs, name).
    let mut relative: Vec<(usize, f64, String)> = Vec::new();
    for (mesh, name) in meshes.iter().zip(&names) {
        let embree = if args.no_embree {
            None
        } else {
            Some(embree_frame(mesh, args.receivers as usize)?)
        };
        for row in rows(mesh, args.receivers as usize, min_time)? {
            let ratio = embree.map(|e| e / row.micros);
            println!(
                "{name:<width$} {:>9} {:<16} {:<14} {:>12.2} {:>12} {:>12} {:>8} {:>10} {:>8}",
                mesh.triangle_count(),
                row.setting,
                row.receivers,
                row.micros,
                embree.map_or("-".to_string(), |e| format!("{e:.2}")),
                ratio.map_or("-".to_string(), |r| format!("{r:.2}x")),
                row.error
                    .map_or("exact".to_string(), |e| format!("{:.2}%", 100.0 * e)),
                count(row.triangles),
                count(row.nodes),
            );
            if let Some(micros) = row.sampling_micros
                && row.setting == "none"
            {
                samplings.push(format!("{name} {} {micros:.2} µs", row.receivers));
            }
            if row.relative && mesh.triangle_count() >= GROWTH_FROM {
                relative.push((mesh.triangle_count(), row.micros, name.clone()));
            }
            if let Some(ratio) = ratio
                && worst.as_ref().is_none_or(|(_, w)| ratio < *w)
            {
                worst = Some((
                    format!(
                        "{name}, far field {}, receivers {}",
                        row.setting, row.receivers
                    ),
                    ratio,
                ));
            }
        }
    }
    if !samplings.is_empty() {
        println!(
            "making the sparse receivers' sampling (set_receivers), per vertex: {}",
            samplings.join("; ")
        );
    }
    if let Some((name, ratio)) = worst {
        println!("worst row: {name}, {ratio:.2}x Embree's frame");
    }
    let smallest = relative.iter().min_by_key(|r| r.0);
    let largest = relative.iter().max_by_key(|r| r.0);
    if let (Some(small), Some(large)) = (smallest, largest)
        && large.0 > small.0
    {
        println!(
            "growth of the (n/4) far field's time per vertex from {} ({} triangles) to {} ({}): \
             {:.2} -> {:.2} µs, {:.2}x",
            small.2,
            small.0,
            large.2,
            large.0,
            small.1,
            large.1,
            large.1 / small.1
        );
    }
    Ok(())
}

/// A per-receiver count, or `-` where the row has none.
fn count(value: f64) -> String {
    if value.is_nan() {
        "-".to_string()
    } else {
        format!("{value:.0}")
    }
}

/// Embree's frame per vertex on `mesh`: the scene's build over the vertex
/// count plus the 812 cell rays of each of `count` receivers.
fn embree_frame(mesh: &TriangleMesh, count: usize) -> Result<f64> {
    let offset = OFFSET_OF_DIAGONAL * mesh.bounds().diagonal();
    let receivers: Vec<Receiver> = receivers(mesh, count)
        .into_iter()
        .map(|(p, n)| Receiver::new(p, n, offset))
        .collect();
    let rays = try_cast(
        mesh.positions(),
        mesh.indices(),
        &cell_rays(&receivers),
        OracleOptions {
            timing: true,
            timing_passes: 3,
            ..OracleOptions::default()
        },
    )
    .map_err(|e| Error::msg(format!("{e}\n(use --no-embree to skip Embree's figures)")))?
    .occluded_seconds
    .expect("timing was requested");
    let per_vertex = embree_build_seconds(mesh)? / mesh.vertex_count().max(1) as f64;
    Ok(1e6 * (per_vertex + rays / receivers.len().max(1) as f64))
}

/// The rows of `mesh`: the exact path, then each far-field setting below a
/// quarter of its triangles, then the one that follows its size; then each
/// sparse-receiver setting with the full mesh and with that last far field.
fn rows(mesh: &TriangleMesh, count: usize, min_time: Duration) -> Result<Vec<Row>> {
    let view = mesh.view();
    let vertices = receiver_vertices(&mesh.vertex_normals(), count);
    let table = TransferTable::<COEFFICIENTS>::new();
    let method = TransferMethod::Cells(&table);
    let options = BatchOptions {
        normal_offset: OFFSET_OF_DIAGONAL * mesh.bounds().diagonal(),
        parallel: false,
        ..BatchOptions::default()
    };
    // Each setting, and whether it is the one that follows the mesh's size.
    let mut settings = vec![(None, false, Timing::Sampled)];
    for triangles in FAR_TRIANGLES {
        if 4 * triangles <= mesh.triangle_count() {
            settings.extend(FAR_LEVELS.map(|levels| {
                (
                    Some(FarFieldSetup { triangles, levels }),
                    false,
                    Timing::Sampled,
                )
            }));
        }
    }
    let quarter = mesh.triangle_count() / RELATIVE_DIVISOR;
    let relative = (quarter > 0).then_some(FarFieldSetup {
        triangles: quarter,
        levels: MAX_FAR_LEVELS,
    });
    if relative.is_some() {
        settings.push((relative, true, Timing::Sampled));
    }
    // The exact path timed as the sparse rows are, their baseline.
    settings.push((None, false, Timing::Frame(None)));
    for lod in RECEIVER_LODS {
        settings.push((None, false, Timing::Frame(Some(lod))));
        if relative.is_some() {
            settings.push((relative, true, Timing::Frame(Some(lod))));
        }
    }
    let frame_view = || {
        MeshView::new(mesh.positions(), mesh.indices())
            .map_err(|e| Error::msg(format!("{}: {e}", mesh.name())))
    };
    let mut exact: Vec<f64> = Vec::new();
    // Every vertex's exact ambient occlusion, for the sparse-receiver rows
    // (made when the first one needs it, on every thread: untimed).
    let mut every_exact: Vec<f64> = Vec::new();
    let mut rows = Vec::new();
    for (far_field, relative, timing) in settings {
        let setup = ShaderSetup {
            far_field,
            ..ShaderSetup::default()
        };
        let mut shader = HemiShader::new(&view, None, &setup)
            .map_err(|e| Error::msg(format!("cannot make the shader of {}: {e}", mesh.name())))?;
        let far_label = match far_field {
            None => "none".to_string(),
            Some(FarFieldSetup { triangles, .. }) => {
                let built = shader.far_field().map_or(0, |f| f.level_count());
                let mark = if relative { " (n/4)" } else { "" };
                format!("{triangles} x {built}{mark}")
            }
        };
        if let Timing::Frame(lod) = timing {
            let sampling = time_per_call(min_time, || {
                shader.set_receivers(&view, lod).expect("a valid sampling");
            });
            if every_exact.is_empty() {
                every_exact = every_vertex_ambient(mesh, method, &options)?;
            }
            let mut out = vec![[0.0f32; COEFFICIENTS]; mesh.vertex_count()];
            let mut rasterized = 0;
            // The whole frame: posing, then every vertex's vector.
            let frame_time = time_per_call(min_time, || {
                let view = frame_view().expect("the mesh was validated when loaded");
                let mut frame = shader
                    .frame(view, None, None)
                    .expect("the shader fits the mesh");
                rasterized = frame
                    .transfer(&options, method, TransferSpace::Local, &mut out)
                    .expect("one vector per vertex");
                black_box(&out);
            });
            let n = mesh.vertex_count().max(1) as f64;
            let ambient: Vec<f64> = out.iter().map(|t| f64::from(t[0])).collect();
            let share = 100.0 * rasterized as f64 / n;
            rows.push(Row {
                setting: far_label,
                receivers: match lod {
                    Some(lod) => format!("{}/{} {share:.0}%", lod.spacing, lod.tolerance),
                    None => "every".to_string(),
                },
                relative: false,
                micros: 1e6 * frame_time.as_secs_f64() / n,
                error: lod.map(|_| relative_rms(&every_exact, &ambient)),
                triangles: f64::NAN,
                nodes: f64::NAN,
                sampling_micros: lod.map(|_| 1e6 * sampling.as_secs_f64() / n),
            });
            continue;
        }
        // Posing the whole mesh, per vertex.
        let pose = time_per_call(min_time, || {
            let view = frame_view().expect("the mesh was validated when loaded");
            black_box(
                shader
                    .frame(view, None, None)
                    .expect("the shader fits the mesh"),
            );
        });
        let frame = shader
            .frame(frame_view()?, None, None)
            .map_err(|e| Error::msg(e.to_string()))?;
        let scene = frame.scene();
        let normals = frame.normals();
        let transfer = |v: usize| -> Sh<COEFFICIENTS> {
            let p = Vec3::from(mesh.positions()[v]);
            vertex_transfer(
                &scene,
                p,
                normals[v],
                &options,
                method,
                TransferSpace::Local,
            )
        };
        // Untimed: each receiver's ambient occlusion (the local transfer's
        // constant coefficient, what `transfer` gives) and its counts.
        let (mut triangles, mut nodes) = (0u64, 0u64);
        let ambient: Vec<f64> = vertices
            .iter()
            .map(|&v| {
                let p = Vec3::from(mesh.positions()[v]);
                let (mask, counts) = scene_mask_with_counts(&scene, p, normals[v], &options);
                triangles += u64::from(counts.rasterized);
                nodes += u64::from(counts.nodes);
                f64::from(method.transfer(&mask)[0])
            })
            .collect();
        let receivers = time_per_call(min_time, || {
            for &v in &vertices {
                black_box(transfer(black_box(v)));
            }
        });
        let n = vertices.len().max(1) as f64;
        let micros = 1e6
            * (pose.as_secs_f64() / mesh.vertex_count().max(1) as f64
                + receivers.as_secs_f64() / n);
        let error = match far_field {
            None => {
                exact = ambient;
                None
            }
            Some(_) => Some(relative_rms(&exact, &ambient)),
        };
        rows.push(Row {
            setting: far_label,
            receivers: "all".to_string(),
            relative,
            micros,
            error,
            triangles: triangles as f64 / n,
            nodes: nodes as f64 / n,
            sampling_micros: None,
        });
    }
    Ok(rows)
}

/// Every vertex's exact ambient occlusion (the full mesh, on every thread).
fn every_vertex_ambient(
    mesh: &TriangleMesh,
    method: TransferMethod<'_, COEFFICIENTS>,
    options: &BatchOptions<'_>,
) -> Result<Vec<f64>> {
    let view = mesh.view();
    let mut shader = HemiShader::new(&view, None, &ShaderSetup::default())
        .map_err(|e| Error::msg(e.to_string()))?;
    let mut frame = shader
        .frame(view, None, None)
        .map_err(|e| Error::msg(e.to_string()))?;
    let mut out = vec![[0.0f32; COEFFICIENTS]; mesh.vertex_count()];
    let pooled = BatchOptions {
        parallel: true,
        ..*options
    };
    frame
        .transfer(&pooled, method, TransferSpace::Local, &mut out)
        .map_err(|e| Error::msg(e.to_string()))?;
    Ok(out.iter().map(|t| f64::from(t[0])).collect())
}

/// Relative RMS of `got` against `want`, divided by `want`'s mean.
fn relative_rms(want: &[f64], got: &[f64]) -> f64 {
    let n = want.len().max(1) as f64;
    let mean = want.iter().sum::<f64>() / n;
    let squared: f64 = want.iter().zip(got).map(|(a, b)| (a - b) * (a - b)).sum();
    (squared / n).sqrt() / mean.abs().max(f64::MIN_POSITIVE)
}
