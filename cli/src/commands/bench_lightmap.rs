//! `antumbra bench lightmap`: what a lightmap texel costs against a mesh
//! vertex, at the same rays, on one thread, measured in one run on one mesh.
//!
//! Rows, each the fastest of `--repeats` runs:
//! - the texel bake per receiver: building the atlas, the lift out of geometry,
//!   and the bake (`TexelAtlas::bake`), against the vertex bake
//!   (`transfer::bake_serial`) per vertex of the same mesh. Texels and vertices
//!   sit in different places (texels mostly on open surfaces, a quad mesh's
//!   vertices in its corners), so this ratio holds the scene's share too;
//! - the point bake (`transfer::bake_points`) at the mesh's own vertices
//!   against the vertex bake: the same sites and rays, so the ratio is the
//!   engine's overhead for arbitrary points alone.

use std::time::{Duration, Instant};

use antumbra_core::lightmap::{LiftOptions, TexelAtlas};
use antumbra_core::raycast::BvhScene;
use antumbra_core::transfer::{
    BakeOptions, BakePoint, BounceReads, Measurement, bake_points, bake_serial,
};

use crate::cli::BenchLightmapArgs;
use crate::error::{Error, Result};
use crate::lightmap::{TexturedMesh, atlas_of};
use crate::prt;

/// Seed of every bake.
const SEED: u64 = 11;

/// The fastest of `repeats` runs of `work`.
fn fastest<T>(repeats: u32, mut work: impl FnMut() -> Result<T>) -> Result<Duration> {
    let mut best = Duration::MAX;
    for _ in 0..repeats {
        let started = Instant::now();
        std::hint::black_box(work()?);
        best = best.min(started.elapsed());
    }
    Ok(best)
}

/// Runs the benchmark on a one-thread pool.
pub fn run(args: &BenchLightmapArgs) -> Result<()> {
    let textured = match &args.mesh {
        Some(path) => TexturedMesh::load(path)?,
        None => super::demo::lightmap::scene()?,
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| Error::msg(format!("cannot build a one-thread pool: {e}")))?;
    one.install(|| measure(&textured, args))
}

fn measure(textured: &TexturedMesh, args: &BenchLightmapArgs) -> Result<()> {
    let (width, height) = args.texels;
    let view = textured.mesh.view();
    let normals = &textured.normals;
    let bvh = BvhScene::new(&view).map_err(|e| Error::msg(e.to_string()))?;
    let make_atlas = || -> Result<TexelAtlas> {
        let mut atlas = atlas_of(textured, width, height)?;
        atlas
            .lift(&view, &bvh, &LiftOptions::default())
            .expect("the default lift options are valid");
        Ok(atlas)
    };
    let atlas = make_atlas()?;
    let receivers = atlas.receivers().len();
    let vertices = textured.mesh.vertex_count();
    println!(
        "bench lightmap: {} ({vertices} vertices, {} triangles), {width}x{height} atlas with \
         {receivers} texel receivers, {} rays per receiver and per vertex, one thread, fastest \
         of {}",
        textured.mesh.name(),
        textured.mesh.triangle_count(),
        args.rays,
        args.repeats
    );
    let per = |time: Duration, count: usize| time.as_secs_f64() * 1e6 / count as f64;
    let atlas_time = fastest(args.repeats, make_atlas)?;
    println!(
        "  atlas and lift: {:.2} µs per receiver",
        per(atlas_time, receivers)
    );
    println!(
        "  {:<10} {:>13} {:>13} {:>13} {:>15} {:>13}",
        "transfer", "texel µs", "vertex µs", "texel/vertex", "points at verts", "/vertex bake"
    );
    for (name, measurement) in [
        ("diffuse", Measurement::Diffuse),
        ("glossy SH", Measurement::GlossySh),
    ] {
        let options = BakeOptions {
            bands: 4,
            rays: args.rays,
            seed: SEED,
            ray_offset: prt::default_ray_offset(),
            ..BakeOptions::new(measurement)
        };
        let bake_error = |e: antumbra_core::transfer::BakeError| Error::msg(e.to_string());
        let texel = fastest(args.repeats, || {
            atlas
                .bake(&view, normals, &bvh, &options, false)
                .map_err(bake_error)
        })?;
        let vertex = fastest(args.repeats, || {
            bake_serial(&view, normals, &bvh, &options).map_err(bake_error)
        })?;
        let sites: Vec<BakePoint> = (0..vertices)
            .map(|v| BakePoint {
                position: glam::Vec3::from(textured.mesh.positions()[v]),
                normal: normals[v],
            })
            .collect();
        let points = fastest(args.repeats, || {
            bake_points(
                &view,
                normals,
                &bvh,
                &sites,
                BounceReads::Vertices,
                &options,
                false,
            )
            .map_err(bake_error)
        })?;
        let texel_total = per(texel + atlas_time, receivers);
        let vertex_each = per(vertex, vertices);
        println!(
            "  {name:<10} {texel_total:>13.2} {vertex_each:>13.2} {:>12.2}× {:>15.2} {:>12.2}×",
            texel_total / vertex_each,
            per(points, vertices),
            points.as_secs_f64() / vertex.as_secs_f64()
        );
    }
    println!(
        "  (texel µs: atlas, lift and bake per receiver; vertex µs: the vertex bake per vertex; \
         points at verts: the point bake at the vertices, per vertex)"
    );
    Ok(())
}
