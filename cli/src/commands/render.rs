//! `antumbra render`: the demo's renderers on a mesh from a file, or a bake file
//! relit under an environment map (`--bake`).

use std::path::PathBuf;
use std::time::Instant;

use super::{absolute, format_duration};
use antumbra_core::transfer::{Material, TransferKind, TransferSet, View};

use crate::builtin;
use crate::camera::{Camera, ViewAngles};
use crate::cli::RenderArgs;
use crate::envmap::{EnvironmentMap, EnvironmentSampler};
use crate::error::{Error, Result};
use crate::lightmap;
use crate::mesh::TriangleMesh;
use crate::picture::save_png;
use crate::prt;
use crate::render::{AmbientOcclusion, EnvironmentLighting, RenderSettings};
use crate::scene::Scene;
use crate::tonemap::{to_srgb8_auto, to_unit8};

/// Loads the inputs, renders, writes the PNG and says where.
pub fn run(args: &RenderArgs) -> Result<()> {
    if !args.rotate.is_finite() {
        // NaN would rotate the lighting to NaN: a silently black picture.
        return Err(Error::msg(format!(
            "--rotate is {}; expected a finite number of degrees",
            args.rotate
        )));
    }
    if let Some(bake) = &args.bake {
        return run_relight(args, bake);
    }
    let started = Instant::now();
    let mesh = TriangleMesh::load_obj(&args.mesh)?;
    mesh.require_extent()?;
    let env = args.env.as_deref().map(EnvironmentMap::load).transpose()?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| default_output(args, env.is_some()));

    let scene = Scene::new(&mesh, !args.no_ground)?;
    let width = args.size as usize;
    let height = (width * 3 / 4).max(1);
    let camera = camera_for(&scene.object_bounds(), width, height);
    let settings = RenderSettings {
        width,
        height,
        samples: args.samples,
    };
    let loaded = started.elapsed();

    let rendering = Instant::now();
    let (picture, what) = match &env {
        None => {
            let occlusion = AmbientOcclusion::for_object(&scene.object_bounds());
            let image = occlusion.render(&scene, &camera, &settings);
            (to_unit8(&image), "ambient occlusion")
        }
        Some(env) => {
            let sampler = EnvironmentSampler::new(env);
            let lighting = EnvironmentLighting {
                env,
                sampler: &sampler,
            };
            let image = lighting.render(&scene, &camera, &settings);
            (to_srgb8_auto(&image), "environment lighting")
        }
    };
    let rendered = rendering.elapsed();
    save_png(&picture, &out)?;
    println!(
        "{what} of {} ({} triangles), {}x{} px, {} samples/pixel",
        mesh.name(),
        mesh.triangle_count(),
        width,
        height,
        args.samples
    );
    println!(
        "  loading {}, rendering {}",
        format_duration(loaded),
        format_duration(rendered)
    );
    println!("  wrote {}", absolute(&out).display());
    Ok(())
}

/// The camera of `render`: three-quarter view from slightly above.
fn camera_for(bounds: &crate::bounds::Bounds, width: usize, height: usize) -> Camera {
    let view = ViewAngles {
        azimuth: 30f32.to_radians(),
        elevation: 20f32.to_radians(),
        vertical_fov: 35f32.to_radians(),
    };
    Camera::framing(bounds, view, width as f32 / height as f32, 0.08)
}

/// Supersampling of relit pictures (samples per pixel side), as long as the
/// framebuffer stays within [`RELIGHT_SAMPLE_BUDGET`].
const RELIGHT_SUPERSAMPLING: usize = 3;

/// Most framebuffer samples a relit picture may take (16 bytes each, so 1 GiB):
/// `--size 8192` at 3×3 samples per pixel would take 13 GB.
const RELIGHT_SAMPLE_BUDGET: usize = 1 << 26;

/// The supersampling of a relit picture of `width` × `height` pixels: the most,
/// up to [`RELIGHT_SUPERSAMPLING`], whose framebuffer fits the budget, and at
/// least one.
fn relight_supersampling(width: usize, height: usize) -> usize {
    (1..=RELIGHT_SUPERSAMPLING)
        .rev()
        .find(|&f| (width * f).saturating_mul(height * f) <= RELIGHT_SAMPLE_BUDGET)
        .unwrap_or(1)
}

/// Diffuse albedo of relit diffuse bakes (the ray-traced pictures' object albedo).
const RELIGHT_ALBEDO: [f32; 3] = [0.80, 0.78, 0.74];

/// `render --bake`: loads the bake and the mesh, shades every vertex under the map
/// in SH, draws the mesh with the vertex colours.
fn run_relight(args: &RenderArgs, bake: &std::path::Path) -> Result<()> {
    let started = Instant::now();
    let bytes = std::fs::read(bake)
        .map_err(|e| Error::msg(format!("cannot read bake file {}: {e}", bake.display())))?;
    let set = TransferSet::from_bytes(&bytes)
        .map_err(|e| Error::msg(format!("{} is not a valid bake file: {e}", bake.display())))?;
    if set.texels().is_some() {
        return run_relight_texels(args, bake, &set, started);
    }
    let mesh = TriangleMesh::load_obj(&args.mesh)?;
    prt::check_matches(&set, &mesh)?;
    let env = load_env(args)?;
    let lighting = prt::env_lighting(&env, set.bands(), args.rotate)?;
    let out = relit_output(args, bake);
    let width = args.size as usize;
    let height = (width * 3 / 4).max(1);
    let camera = camera_for(&mesh.bounds(), width, height);
    let loaded = started.elapsed();

    let shading = Instant::now();
    let material = relight_material(args);
    let mut radiance = vec![[0.0f32; 3]; set.vertex_count()];
    set.shade(
        &lighting,
        View::Eye(camera.position().to_array()),
        &material,
        args.components,
        &mut radiance,
    )
    .map_err(|e| Error::msg(format!("cannot shade: {e}")))?;
    let shaded = shading.elapsed();
    let colors: Vec<glam::Vec3> = radiance.iter().map(|c| glam::Vec3::from(*c)).collect();
    let frame = prt::draw(
        &camera,
        &mesh,
        &colors,
        (width, height),
        relight_supersampling(width, height),
    );
    let picture = super::demo::hemi::develop(&frame, prt::exposure_of(&frame));
    save_png(&super::demo::hemi::to_rgb8(&picture), &out)?;
    let kind = describe_set(&set, args);
    println!(
        "relit {} ({kind}, {} bands, {} vertices) under {} rotated {}°, {}x{} px",
        bake.display(),
        set.bands(),
        set.vertex_count(),
        env_name(args),
        args.rotate,
        width,
        height
    );
    println!(
        "  loading {}, shading {} ({:.0} ns per vertex)",
        format_duration(loaded),
        format_duration(shaded),
        shaded.as_secs_f64() * 1e9 / set.vertex_count().max(1) as f64
    );
    println!("  wrote {}", absolute(&out).display());
    Ok(())
}

/// The environment map of `--env`, or the built-in sunrise.
fn load_env(args: &RenderArgs) -> Result<EnvironmentMap> {
    match &args.env {
        Some(path) => EnvironmentMap::load(path),
        None => builtin::sunrise(),
    }
}

/// The map's name for the summary line.
fn env_name(args: &RenderArgs) -> String {
    args.env.as_deref().map_or_else(
        || "the built-in sunrise".to_string(),
        |p| p.display().to_string(),
    )
}

/// `--out`, or `<bake stem>-relit.png`.
fn relit_output(args: &RenderArgs, bake: &std::path::Path) -> PathBuf {
    args.out.clone().unwrap_or_else(|| {
        let stem = bake
            .file_stem()
            .map_or_else(|| "relit".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from(format!("{stem}-relit.png"))
    })
}

/// The shading material of `render --bake`: glossy SH and MRT sets hold only
/// the glossy term, the baked lobe as it is.
fn relight_material(args: &RenderArgs) -> Material {
    Material {
        albedo: RELIGHT_ALBEDO,
        phong_exponent: args.exponent,
        ..Material::glossy(1.0)
    }
}

/// `render --bake` of a texel bake (a lightmap, bake file version 3): shades
/// every texel under the map in SH (glossy kinds towards the camera, as an
/// engine's per-pixel view would approximate), spreads the colours over the
/// atlas with the gutter, writes that texture as an RGB OpenEXR beside the
/// picture, and draws the mesh (with the UVs the lightmap was baked for) with
/// bilinear lookups into it.
fn run_relight_texels(
    args: &RenderArgs,
    bake: &std::path::Path,
    set: &TransferSet,
    started: Instant,
) -> Result<()> {
    let texels = set.texels().expect("a texel bake");
    let textured = lightmap::TexturedMesh::load(&args.mesh)?;
    lightmap::check_texels_match(&textured, texels)?;
    let env = load_env(args)?;
    let lighting = prt::env_lighting(&env, set.bands(), args.rotate)?;
    let out = relit_output(args, bake);
    let width = args.size as usize;
    let height = (width * 3 / 4).max(1);
    let camera = camera_for(&textured.mesh.bounds(), width, height);
    let loaded = started.elapsed();

    let shading = Instant::now();
    let mut radiance = vec![[0.0f32; 3]; set.vertex_count()];
    set.shade(
        &lighting,
        View::Eye(camera.position().to_array()),
        &relight_material(args),
        args.components,
        &mut radiance,
    )
    .map_err(|e| Error::msg(format!("cannot shade: {e}")))?;
    let (side_x, side_y) = (texels.width() as usize, texels.height() as usize);
    let mut texture = vec![0.0f32; side_x * side_y * 3];
    texels
        .expand(lightmap::GUTTER, radiance.as_flattened(), 3, &mut texture)
        .ok_or_else(|| Error::msg("the lightmap does not match its texels"))?;
    let shaded = shading.elapsed();
    // Beside the picture, never over it (`--out` may itself end in .exr).
    let stem = out
        .file_stem()
        .map_or_else(|| "relit".into(), |s| s.to_string_lossy().into_owned());
    let texture_path = out.with_file_name(format!("{stem}-lightmap.exr"));
    let names = ["R", "G", "B"].map(String::from);
    lightmap::write_channels(&texture, (side_x, side_y), &names, &texture_path)?;
    let supersampling = relight_supersampling(width, height);
    let frame = lightmap::draw_lightmapped(
        &camera,
        &textured,
        &texture,
        (side_x, side_y),
        (width * supersampling, height * supersampling),
    );
    let picture = super::demo::hemi::develop(&frame, prt::exposure_of(&frame));
    save_png(&super::demo::hemi::to_rgb8(&picture), &out)?;
    println!(
        "relit the lightmap {} ({}, {} bands, {} texels of {side_x}x{side_y}) under {} rotated \
         {}°, {width}x{height} px",
        bake.display(),
        describe_set(set, args),
        set.bands(),
        set.vertex_count(),
        env_name(args),
        args.rotate,
    );
    println!(
        "  loading {}, shading and the texture {} ({:.0} ns per texel)",
        format_duration(loaded),
        format_duration(shaded),
        shaded.as_secs_f64() * 1e9 / set.vertex_count().max(1) as f64
    );
    println!(
        "  wrote {} and its lightmap {} (linear RGB, 2-texel gutter, row 0 at v = 1)",
        absolute(&out).display(),
        absolute(&texture_path).display()
    );
    Ok(())
}

/// The set's kind for the summary line.
fn describe_set(set: &TransferSet, args: &RenderArgs) -> String {
    match set.kind() {
        TransferKind::Diffuse => "diffuse transfer".to_string(),
        TransferKind::GlossySh => format!("glossy SH transfer, Phong exponent {}", args.exponent),
        TransferKind::Mrt => match set.pca() {
            Some(pca) => format!(
                "MRT {0}×{0} from PCA, {1} of {2} components{3}",
                set.grid(),
                args.components.unwrap_or(usize::MAX).min(pca.components()),
                pca.components(),
                if pca.clusters() > 1 {
                    format!(" in each of {} clusters", pca.clusters())
                } else {
                    String::new()
                }
            ),
            None => format!("MRT {0}×{0}", set.grid()),
        },
    }
}

/// `<mesh stem>-ao.png` or `<mesh stem>-env.png` in the current folder.
fn default_output(args: &RenderArgs, lit: bool) -> PathBuf {
    let stem = args
        .mesh
        .file_stem()
        .map_or_else(|| "render".into(), |s| s.to_string_lossy().into_owned());
    PathBuf::from(format!("{stem}-{}.png", if lit { "env" } else { "ao" }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The CLI review's `render --bake --size 8192` took 13 GB at 3×3 samples
    /// per pixel; large pictures take fewer samples, small ones keep 3×3.
    #[test]
    fn relit_framebuffers_stay_within_the_budget() {
        assert_eq!(relight_supersampling(640, 480), 3);
        assert_eq!(relight_supersampling(2048, 1536), 3);
        assert_eq!(relight_supersampling(4096, 3072), 2);
        assert_eq!(relight_supersampling(8192, 6144), 1);
        for (w, h) in [(640, 480), (4096, 3072), (8192, 6144), (16384, 12288)] {
            let f = relight_supersampling(w, h);
            assert!(f == 1 || w * f * h * f <= RELIGHT_SAMPLE_BUDGET);
        }
    }
}
