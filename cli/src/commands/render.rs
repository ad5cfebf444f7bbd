//! `antumbra render`: the demo's renderers on a mesh from a file.

use std::path::PathBuf;
use std::time::Instant;

use super::{absolute, format_duration};
use crate::camera::{Camera, ViewAngles};
use crate::cli::RenderArgs;
use crate::envmap::{EnvironmentMap, EnvironmentSampler};
use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;
use crate::picture::save_png;
use crate::render::{AmbientOcclusion, EnvironmentLighting, RenderSettings};
use crate::scene::Scene;
use crate::tonemap::{to_srgb8_auto, to_unit8};

/// Loads the inputs, renders, writes the PNG and says where.
pub fn run(args: &RenderArgs) -> Result<()> {
    let started = Instant::now();
    let mesh = TriangleMesh::load_obj(&args.mesh)?;
    if mesh.bounds().diagonal() <= 0.0 {
        return Err(Error::msg(format!(
            "{} has zero extent: all its vertices are at one point",
            mesh.name()
        )));
    }
    let env = args.env.as_deref().map(EnvironmentMap::load).transpose()?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| default_output(args, env.is_some()));

    let scene = Scene::new(&mesh, !args.no_ground)?;
    let width = args.size as usize;
    let height = (width * 3 / 4).max(1);
    let view = ViewAngles {
        azimuth: 30f32.to_radians(),
        elevation: 20f32.to_radians(),
        vertical_fov: 35f32.to_radians(),
    };
    let camera = Camera::framing(
        &scene.object_bounds(),
        view,
        width as f32 / height as f32,
        0.08,
    );
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

/// `<mesh stem>-ao.png` or `<mesh stem>-env.png` in the current folder.
fn default_output(args: &RenderArgs, lit: bool) -> PathBuf {
    let stem = args
        .mesh
        .file_stem()
        .map_or_else(|| "render".into(), |s| s.to_string_lossy().into_owned());
    PathBuf::from(format!("{stem}-{}.png", if lit { "env" } else { "ao" }))
}
