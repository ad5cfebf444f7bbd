//! `antumbra bake`: precomputed transfer written as a bake file, or per-vertex
//! ambient occlusion written as text or CSV.

use std::fmt::Write as _;
use std::time::Instant;

use antumbra_core::raycast::BvhScene;
use glam::Vec3;
use rayon::prelude::*;

use super::{absolute, format_duration};
use antumbra_core::transfer::{TransferKind, TransferSet};

use crate::cli::{BakeArgs, BakeKind, MergeArgs};
use crate::error::{Context, Error, Result};
use crate::lightmap;
use crate::mesh::TriangleMesh;
use crate::progress;
use crate::prt;
use crate::render::ambient_ray_escapes;
use crate::sampling::{R2Sequence, SampleRng, hash_seed};
use crate::shard::{self, PartHeader, mesh_checksum, part_bytes};

/// Seed of the bake's random numbers.
const SEED: u64 = 0xBA;

/// Bakes and writes the file.
pub fn run(args: &BakeArgs) -> Result<()> {
    if args.kind != BakeKind::Ao {
        return run_transfer(args);
    }
    if args.shard.is_some() {
        return Err(Error::msg(
            "--shard splits transfer bakes (--kind diffuse, glossy-sh or mrt), not ao",
        ));
    }
    if let Some(d) = args.max_distance.filter(|d| d.is_nan() || *d <= 0.0) {
        return Err(Error::msg(format!(
            "--max-distance must be positive, not {d}"
        )));
    }
    let started = Instant::now();
    let mesh = TriangleMesh::load_obj(&args.mesh)?;
    let max_distance = args.max_distance.unwrap_or(f32::INFINITY);
    let visibility = bake_visibility(&mesh, args.rays, max_distance, args.ray_offset);
    let normals = mesh.vertex_normals();
    let csv = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    let text = if csv {
        format_csv(&mesh, &normals, &visibility)
    } else {
        format_text(&mesh, args.rays, max_distance, &visibility)
    };
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create folder {}", parent.display()))?;
    }
    std::fs::write(&args.out, text)
        .with_context(|| format!("cannot write {}", args.out.display()))?;

    let mean =
        visibility.iter().map(|&v| f64::from(v)).sum::<f64>() / visibility.len().max(1) as f64;
    println!(
        "baked ambient occlusion of {} ({} vertices, {} rays each) in {}",
        mesh.name(),
        mesh.vertex_count(),
        args.rays,
        format_duration(started.elapsed())
    );
    println!("  mean visibility {mean:.3} (1 = unoccluded)");
    println!(
        "  wrote {} ({})",
        absolute(&args.out).display(),
        if csv { "CSV" } else { "text" }
    );
    Ok(())
}

/// `bake --texels`: the lightmap of the mesh's UV atlas, written as a bake file
/// (a part file with `--shard`, compressed with `--pca`) or, for an output
/// ending in `.exr`, as OpenEXR channels.
fn run_texels(
    args: &BakeArgs,
    config: &prt::BakeConfig,
    brdf: &prt::BrdfChoice,
    width: u32,
    height: u32,
) -> Result<()> {
    let exr = is_exr(&args.out);
    if exr && (args.shard.is_some() || args.pca.is_some()) {
        return Err(Error::msg(
            "an OpenEXR lightmap holds the whole atlas, dense: write a bake file (not .exr) \
             with --shard or --pca; `antumbra merge -o FILE.exr` writes the joined parts as \
             OpenEXR",
        ));
    }
    let started = Instant::now();
    let textured = lightmap::TexturedMesh::load(&args.mesh)?;
    let options = prt::bake_options(config);
    let bake = lightmap::bake_texels(&textured, width, height, &options, args.shard)?;
    let receivers = bake.atlas.receivers().len();
    let what = match config.kind {
        prt::Kind::Diffuse => "diffuse transfer".to_string(),
        prt::Kind::GlossySh => "glossy SH transfer".to_string(),
        prt::Kind::Mrt => format!("matrix radiance transfer ({})", brdf.describe()),
    };
    println!(
        "baked the {width}x{height} lightmap ({what}) of {}: {} of {receivers} texels ({} moved \
         off creases or out of geometry), {} rays each, {} bounce{}, in {}",
        textured.mesh.name(),
        bake.range.len(),
        bake.lifted,
        args.rays,
        args.bounces,
        if args.bounces == 1 { "" } else { "s" },
        format_duration(started.elapsed())
    );
    if exr {
        lightmap::write_exr(&bake.set, &args.out)?;
        println!(
            "  wrote {} ({} channels per texel)",
            absolute(&args.out).display(),
            bake.set.block_len()
        );
        return Ok(());
    }
    if let Some(shard) = args.shard {
        let header = PartHeader {
            shard,
            first: bake.range.start as u64,
            end: bake.range.end as u64,
            total: receivers as u64,
            seed: args.seed,
            ray_offset: args.ray_offset,
            mesh_crc: shard::texel_checksum(&textured, width, height),
        };
        let bytes = part_bytes(&header, &bake.set);
        write_file(&args.out, &bytes)?;
        println!(
            "  part {}/{}: texels {}..{} of {receivers}; wrote {} ({} bytes); join the parts \
             with `antumbra merge`",
            shard.index,
            shard.count,
            bake.range.start,
            bake.range.end,
            absolute(&args.out).display(),
            bytes.len()
        );
        return Ok(());
    }
    let set = compress_if_asked(bake.set, args.pca, args.clusters)?;
    let bytes = set.to_bytes();
    write_file(&args.out, &bytes)?;
    println!(
        "  wrote {} (bake file version {}, {} bytes, {:.1} bytes of transfer per texel)",
        absolute(&args.out).display(),
        set.file_version(),
        bytes.len(),
        set.data_bytes() as f64 / set.vertex_count().max(1) as f64
    );
    Ok(())
}

/// Component counts of the PCA error table, up to the baked one.
fn pca_table_counts(k: usize) -> Vec<usize> {
    let mut counts: Vec<usize> = std::iter::successors(Some(1usize), |c| Some(c * 2))
        .take_while(|&c| c < k)
        .collect();
    counts.push(k);
    counts
}

/// `bake --kind diffuse|glossy-sh|mrt`.
fn run_transfer(args: &BakeArgs) -> Result<()> {
    if args.max_distance.is_some() {
        return Err(Error::msg("--max-distance applies to --kind ao only"));
    }
    let kind = match args.kind {
        BakeKind::Diffuse => prt::Kind::Diffuse,
        BakeKind::GlossySh => prt::Kind::GlossySh,
        BakeKind::Mrt => prt::Kind::Mrt,
        BakeKind::Ao => unreachable!("handled by run"),
    };
    if args.pca.is_some() && kind != prt::Kind::Mrt {
        return Err(Error::msg("--pca compresses MRT bakes only (--kind mrt)"));
    }
    if args.pca.is_some() && args.shard.is_some() {
        return Err(Error::msg(
            "--pca needs every vertex: bake the parts without it, then `antumbra merge --pca K`",
        ));
    }
    let brdf = match args.ward.as_deref() {
        Some(&[ax, ay]) => prt::BrdfChoice::ward(ax, ay)?,
        Some(other) => {
            return Err(Error::msg(format!(
                "--ward takes two roughnesses, got {other:?}"
            )));
        }
        None => prt::BrdfChoice::phong(args.phong_exponent)?,
    };
    let config = prt::BakeConfig {
        kind,
        bands: args.bands,
        grid: args.grid,
        bounces: args.bounces,
        rays: args.rays,
        albedo: args.albedo,
        brdf,
        seed: args.seed,
        ray_offset: args.ray_offset,
    };
    if let Some((width, height)) = args.texels {
        return run_texels(args, &config, &brdf, width, height);
    }
    let mesh = TriangleMesh::load_obj(&args.mesh)?;
    let vertices = match args.shard {
        Some(shard) => {
            let range = shard.range(mesh.vertex_count());
            if range.is_empty() {
                return Err(Error::msg(format!(
                    "--shard {}/{}: {} has only {} vertices, fewer than the parts",
                    shard.index,
                    shard.count,
                    mesh.name(),
                    mesh.vertex_count()
                )));
            }
            Some(range)
        }
        None => None,
    };
    let last_pass = vertices.as_ref().map_or(mesh.vertex_count(), |r| r.len()) as u64;
    let passes = mesh.vertex_count() as u64 * u64::from(args.bounces) + last_pass;
    let bar = progress::bar(passes, "baking transfer", "vertex passes");
    let baked = prt::bake_mesh_vertices(&mesh, &config, false, vertices.clone(), Some(&bar))?;
    bar.finish_and_clear();
    let what = match kind {
        prt::Kind::Diffuse => "diffuse transfer".to_string(),
        prt::Kind::GlossySh => "glossy SH transfer".to_string(),
        prt::Kind::Mrt => format!(
            "matrix radiance transfer ({}×{} grid, {})",
            args.grid,
            args.grid,
            brdf.describe()
        ),
    };
    println!(
        "baked {what} of {} ({} vertices, {} bands, {} rays, {} bounce{}) in {}, {}",
        mesh.name(),
        mesh.vertex_count(),
        args.bands,
        args.rays,
        args.bounces,
        if args.bounces == 1 { "" } else { "s" },
        format_duration(baked.elapsed),
        super::format_rate(
            baked.rays_cast as f64 / baked.elapsed.as_secs_f64().max(1e-9),
            "rays"
        )
    );
    let dense = baked.set;
    if let (Some(shard), Some(range)) = (args.shard, vertices) {
        let header = PartHeader {
            shard,
            first: range.start as u64,
            end: range.end as u64,
            total: mesh.vertex_count() as u64,
            seed: args.seed,
            ray_offset: args.ray_offset,
            mesh_crc: mesh_checksum(&mesh),
        };
        let bytes = part_bytes(&header, &dense);
        write_file(&args.out, &bytes)?;
        println!(
            "  part {}/{}: vertices {}..{} of {}; wrote {} ({} bytes); join the parts with \
             `antumbra merge`",
            shard.index,
            shard.count,
            range.start,
            range.end,
            mesh.vertex_count(),
            absolute(&args.out).display(),
            bytes.len()
        );
        return Ok(());
    }
    let set = compress_if_asked(dense, args.pca, args.clusters)?;
    let bytes = set.to_bytes();
    write_file(&args.out, &bytes)?;
    println!(
        "  wrote {} ({} bytes, {:.1} bytes of transfer per vertex)",
        absolute(&args.out).display(),
        bytes.len(),
        set.data_bytes() as f64 / set.vertex_count().max(1) as f64
    );
    Ok(())
}

/// `dense`, PCA-compressed to `pca` components in `clusters` clusters (1 when
/// not given) when asked, with the error and memory table printed. The
/// clustering's seed is fixed, so `merge` compresses exactly as `bake` does.
fn compress_if_asked(
    dense: TransferSet,
    pca: Option<u32>,
    clusters: Option<u32>,
) -> Result<TransferSet> {
    Ok(match pca {
        None => dense,
        Some(k) => {
            let started = Instant::now();
            let c = clusters.unwrap_or(1);
            let compressed = dense
                .compress_clustered(c as usize, k as usize, 0)
                .map_err(|e| Error::msg(format!("cannot compress: {e}")))?;
            let what = if c > 1 {
                format!("clustered PCA to {c} clusters of {k} components")
            } else {
                format!("PCA to {k} components")
            };
            println!(
                "  {what} in {}; error and memory against K:",
                format_duration(started.elapsed())
            );
            let dense_per_vertex = dense.data_bytes() as f64 / dense.vertex_count() as f64;
            let levels = dense
                .pca_levels(&compressed, &pca_table_counts(k as usize))
                .expect("compressed from this set");
            for level in levels {
                println!(
                    "    K = {:>3}: relative RMS error {:>7.3} %, {:>7.1} bytes per vertex ({:.1}x less than dense {:.0})",
                    level.components,
                    100.0 * level.relative_rms_error,
                    level.bytes_per_vertex,
                    dense_per_vertex / level.bytes_per_vertex,
                    dense_per_vertex
                );
            }
            compressed
        }
    })
}

/// Writes `bytes` to `path`, creating its folder.
fn write_file(path: &std::path::Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create folder {}", parent.display()))?;
    }
    std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))
}

/// `antumbra merge`: joins the parts of a sharded bake into its bake file.
pub fn run_merge(args: &MergeArgs) -> Result<()> {
    let started = Instant::now();
    let parts = shard::read_parts(&args.parts)?;
    let count = parts.len();
    let joined = shard::merge(parts)?;
    if args.pca.is_some() && joined.kind() != TransferKind::Mrt {
        return Err(Error::msg("--pca compresses MRT bakes only"));
    }
    let entries = joined.vertex_count();
    let what = if joined.texels().is_some() {
        "texels"
    } else {
        "vertices"
    };
    if is_exr(&args.out) {
        if joined.texels().is_none() || args.pca.is_some() {
            return Err(Error::msg(
                "an OpenEXR output holds a lightmap's dense coefficients: merge the parts of \
                 `bake --texels`, without --pca, or write a bake file (not .exr)",
            ));
        }
        lightmap::write_exr(&joined, &args.out)?;
        println!(
            "merged {count} parts ({entries} texels) in {}; wrote {} ({} channels per texel)",
            format_duration(started.elapsed()),
            absolute(&args.out).display(),
            joined.block_len()
        );
        return Ok(());
    }
    let set = compress_if_asked(joined, args.pca, args.clusters)?;
    let bytes = set.to_bytes();
    write_file(&args.out, &bytes)?;
    println!(
        "merged {count} parts ({entries} {what}) in {}; wrote {} ({} bytes)",
        format_duration(started.elapsed()),
        absolute(&args.out).display(),
        bytes.len()
    );
    Ok(())
}

/// Whether `path` names an OpenEXR file (ends in `.exr`, any case).
fn is_exr(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

/// Fraction of `rays` cosine-weighted rays per vertex that escape within
/// `max_distance`, from origins `ray_offset` (mesh units) along the normal, which
/// keeps rays from hitting the vertex's own triangles at t ≈ 0. Vertices with no
/// defined normal (only degenerate triangles around them) get 1.
pub fn bake_visibility(
    mesh: &TriangleMesh,
    rays: u32,
    max_distance: f32,
    ray_offset: f32,
) -> Vec<f32> {
    let bvh = BvhScene::new(&mesh.view()).expect("TriangleMesh keeps coordinates in range");
    let normals = mesh.vertex_normals();
    let offset = ray_offset;
    let bar = progress::bar(mesh.vertex_count() as u64, "baking", "vertices");
    let visibility = mesh
        .positions()
        .par_iter()
        .zip(normals.par_iter())
        .enumerate()
        .map(|(vertex, (&position, &normal))| {
            bar.inc(1);
            if normal == Vec3::ZERO {
                return 1.0;
            }
            let mut rng = SampleRng::new(hash_seed(&[SEED, vertex as u64]));
            let directions = R2Sequence::new(rng.next_vec2());
            let origin = Vec3::from(position) + offset * normal;
            let open = (0..rays)
                .filter(|&i| {
                    ambient_ray_escapes(&bvh, origin, normal, directions.point(i), max_distance)
                })
                .count();
            open as f32 / rays as f32
        })
        .collect();
    bar.finish_and_clear();
    visibility
}

/// The text format: a `#` header line, then one value per vertex.
fn format_text(mesh: &TriangleMesh, rays: u32, max_distance: f32, visibility: &[f32]) -> String {
    let mut out = format!(
        "# antumbra ambient occlusion v1: {} lines follow, line i+2 = visibility of vertex i \
         in [0,1] (1 = unoccluded, cosine-weighted); mesh {}, {} rays per vertex, max distance {}\n",
        visibility.len(),
        // One header line whatever the file name holds.
        mesh.name().escape_debug(),
        rays,
        if max_distance.is_finite() {
            max_distance.to_string()
        } else {
            "unlimited".to_string()
        }
    );
    for v in visibility {
        let _ = writeln!(out, "{v:.6}");
    }
    out
}

/// The CSV format: a header row, then `vertex,x,y,z,nx,ny,nz,visibility` per vertex.
fn format_csv(mesh: &TriangleMesh, normals: &[Vec3], visibility: &[f32]) -> String {
    let mut out = String::from("vertex,x,y,z,nx,ny,nz,visibility\n");
    for (i, ((p, n), v)) in mesh
        .positions()
        .iter()
        .zip(normals)
        .zip(visibility)
        .enumerate()
    {
        let _ = writeln!(
            out,
            "{i},{},{},{},{:.6},{:.6},{:.6},{v:.6}",
            p[0], p[1], p[2], n.x, n.y, n.z
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn convex_mesh_is_fully_visible_and_formats_have_one_header_line() {
        let tetra = TriangleMesh::parse_obj_str(
            "tetra",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
        )
        .unwrap();
        let visibility = bake_visibility(&tetra, 64, f32::INFINITY, prt::default_ray_offset());
        assert!(visibility.iter().all(|&v| v == 1.0), "{visibility:?}");
        let text = format_text(&tetra, 64, f32::INFINITY, &visibility);
        assert_eq!(text.lines().count(), 5);
        assert!(text.starts_with('#'));
        let csv = format_csv(&tetra, &tetra.vertex_normals(), &visibility);
        assert_eq!(csv.lines().count(), 5);
    }

    #[test]
    fn pca_table_doubles_up_to_the_baked_count() {
        assert_eq!(pca_table_counts(1), vec![1]);
        assert_eq!(pca_table_counts(8), vec![1, 2, 4, 8]);
        assert_eq!(pca_table_counts(12), vec![1, 2, 4, 8, 12]);
    }

    #[test]
    fn concave_vertices_are_darker() {
        // The bunny's mean visibility is well below 1 and every value is in range.
        let bunny = crate::builtin::bunny().unwrap();
        let visibility = bake_visibility(&bunny, 32, f32::INFINITY, prt::default_ray_offset());
        assert!(visibility.iter().all(|v| (0.0..=1.0).contains(v)));
        let mean = visibility.iter().sum::<f32>() / visibility.len() as f32;
        assert!(mean > 0.5 && mean < 0.98, "{mean}");
    }
}
