//! Precomputed transfer as the commands use it (`bake`, `render --bake`, `bench
//! transfer`, the demo's MRT picture): baking a mesh with `antumbra_core::transfer`,
//! the lighting of an environment map at any band count, and drawing a relit mesh.
//!
//! Choices shared by the commands:
//! - Normals are the area-weighted vertex normals (`antumbra_core::hemi::vertex_normals`,
//!   as everywhere in the CLI); a vertex with none (only degenerate triangles around
//!   it) gets +Y, since the engine needs a unit normal at every vertex.
//! - Ray origins are pushed off the surface by `BakeConfig::ray_offset`, in mesh
//!   units: the one meaning of the C API's `ray_offset` and core's
//!   `BakeOptions::ray_offset`, with the same default ([`default_ray_offset`]).
//! - The lighting is the map's SH projection windowed with the Hann window of
//!   `crate::hemi_shading::hann_window` (against the ringing of a bright sun; see
//!   that module), optionally rotated about +Y.

use std::time::{Duration, Instant};

use antumbra_core::raycast::BvhScene;
use antumbra_core::sh::{EquirectMapping, Sh, ShRgb, ZonalKernel, project_equirect};
use antumbra_core::transfer::{
    BakeOptions, Brdf, Measurement, PhongBrdf, TransferSet, WardBrdf, bake, bake_serial,
    bake_vertices, lighting_from_sh_rgb,
};
use glam::{Mat3, Vec3};
use indicatif::ProgressBar;

use crate::camera::Camera;
use crate::envmap::EnvironmentMap;
use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;
use crate::raster::Framebuffer;

/// The default offset of ray origins along the normal, in mesh units: core's (and
/// so the C API's) default, so that a bake with default options is the same bake
/// through the CLI, the crate and the C library.
pub fn default_ray_offset() -> f32 {
    BakeOptions::new(Measurement::Diffuse).ray_offset
}

/// Which transfer to bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Diffuse transfer vectors.
    Diffuse,
    /// Glossy SH transfer matrices (the 2002 baseline).
    GlossySh,
    /// Matrix radiance transfer.
    Mrt,
}

/// The BRDF of an MRT bake.
#[derive(Clone, Copy, Debug)]
pub enum BrdfChoice {
    /// The reflected Phong lobe of this exponent.
    Phong(PhongBrdf),
    /// Ward's anisotropic BRDF.
    Ward(WardBrdf),
}

impl BrdfChoice {
    /// A Phong lobe; an error for an invalid exponent.
    pub fn phong(exponent: f32) -> Result<Self> {
        PhongBrdf::new(exponent)
            .map(BrdfChoice::Phong)
            .ok_or_else(|| Error::msg(format!("Phong exponent {exponent} must be finite and ≥ 0")))
    }

    /// Ward's BRDF; an error unless both roughnesses are in (0, 1].
    pub fn ward(alpha_x: f32, alpha_y: f32) -> Result<Self> {
        WardBrdf::new(alpha_x, alpha_y)
            .map(BrdfChoice::Ward)
            .ok_or_else(|| {
                Error::msg(format!(
                    "Ward roughnesses {alpha_x}, {alpha_y} must be in (0, 1]"
                ))
            })
    }

    fn as_dyn(&self) -> &dyn Brdf {
        match self {
            BrdfChoice::Phong(b) => b,
            BrdfChoice::Ward(b) => b,
        }
    }

    /// A short description.
    pub fn describe(&self) -> String {
        match self {
            BrdfChoice::Phong(b) => format!("Phong lobe, exponent {}", b.exponent()),
            BrdfChoice::Ward(b) => {
                let info = b.info();
                format!("Ward, roughness {} × {}", info.params[0], info.params[1])
            }
        }
    }
}

/// Everything a bake needs besides the mesh.
#[derive(Clone, Copy, Debug)]
pub struct BakeConfig {
    /// What to measure.
    pub kind: Kind,
    /// SH bands of the lighting.
    pub bands: u32,
    /// MRT grid side.
    pub grid: u32,
    /// Interreflection bounces.
    pub bounces: u32,
    /// Rays per vertex and pass.
    pub rays: u32,
    /// Scene albedo of the bounces.
    pub albedo: f32,
    /// The MRT BRDF.
    pub brdf: BrdfChoice,
    /// Seed of the engine's random streams.
    pub seed: u64,
    /// Ray origins move this far along the normal, in mesh units.
    pub ray_offset: f32,
}

/// A bake's result and cost.
pub struct Baked {
    /// The transfer set.
    pub set: TransferSet,
    /// Wall time of the engine.
    pub elapsed: Duration,
    /// Rays cast (vertices × rays × passes).
    pub rays_cast: u64,
}

/// Unit normals for the engine (see the module docs).
pub fn unit_normals(mesh: &TriangleMesh) -> Vec<Vec3> {
    mesh.vertex_normals()
        .into_iter()
        .map(|n| if n == Vec3::ZERO { Vec3::Y } else { n })
        .collect()
}

/// The core options of a bake with `config`, without a progress report
/// (the bake, and `bench transfer` enumerating the bake's rays, share them).
pub fn bake_options(config: &BakeConfig) -> BakeOptions<'_> {
    let measurement = match config.kind {
        Kind::Diffuse => Measurement::Diffuse,
        Kind::GlossySh => Measurement::GlossySh,
        Kind::Mrt => Measurement::Mrt {
            grid: config.grid,
            brdf: config.brdf.as_dyn(),
        },
    };
    BakeOptions {
        bands: config.bands,
        rays: config.rays,
        bounces: config.bounces,
        albedo: config.albedo,
        ray_offset: config.ray_offset,
        seed: config.seed,
        ..BakeOptions::new(measurement)
    }
}

/// Bakes `mesh` (on all cores, or one with `serial`), advancing `bar` by one per
/// vertex pass when given.
pub fn bake_mesh(
    mesh: &TriangleMesh,
    config: &BakeConfig,
    serial: bool,
    bar: Option<&ProgressBar>,
) -> Result<Baked> {
    bake_mesh_vertices(mesh, config, serial, None, bar)
}

/// [`bake_mesh`] of the vertices in `vertices` only (all when `None`): the part of
/// a bake split across machines (core's `bake_vertices`).
pub fn bake_mesh_vertices(
    mesh: &TriangleMesh,
    config: &BakeConfig,
    serial: bool,
    vertices: Option<std::ops::Range<usize>>,
    bar: Option<&ProgressBar>,
) -> Result<Baked> {
    let view = mesh.view();
    let normals = unit_normals(mesh);
    let bvh = BvhScene::new(&view).map_err(|e| Error::msg(e.to_string()))?;
    let progress = |_: usize, _: usize| {
        if let Some(bar) = bar {
            bar.inc(1);
        }
    };
    let options = BakeOptions {
        progress: Some(&progress),
        ..bake_options(config)
    };
    let started = Instant::now();
    let set = match (&vertices, serial) {
        (Some(range), _) => bake_vertices(&view, &normals, &bvh, &options, range.clone()),
        (None, true) => bake_serial(&view, &normals, &bvh, &options),
        (None, false) => bake(&view, &normals, &bvh, &options),
    }
    .map_err(|e| Error::msg(format!("cannot bake: {e}")))?;
    let elapsed = started.elapsed();
    // Every pass but the last runs over every vertex; the last over the range.
    let last_pass = vertices.map_or(mesh.vertex_count(), |r| r.len()) as u64;
    Ok(Baked {
        set,
        elapsed,
        rays_cast: (mesh.vertex_count() as u64 * u64::from(config.bounces) + last_pass)
            * u64::from(config.rays),
    })
}

/// The map's radiance in `bands²` windowed SH coefficients, rotated by `rotate_deg`
/// degrees about +Y, as the engine's lighting (RGB triples).
pub fn env_lighting(env: &EnvironmentMap, bands: u32, rotate_deg: f32) -> Result<Vec<[f32; 3]>> {
    let rotation = Mat3::from_rotation_y(rotate_deg.to_radians());
    match bands {
        1 => project::<1>(env, rotation),
        2 => project::<4>(env, rotation),
        3 => project::<9>(env, rotation),
        4 => project::<16>(env, rotation),
        5 => project::<25>(env, rotation),
        6 => project::<36>(env, rotation),
        7 => project::<49>(env, rotation),
        8 => project::<64>(env, rotation),
        _ => Err(Error::msg(format!("{bands} bands is outside 1..=8"))),
    }
}

fn project<const N: usize>(env: &EnvironmentMap, rotation: Mat3) -> Result<Vec<[f32; 3]>> {
    let image = env.image();
    let projected: ShRgb<N> = project_equirect(
        image.pixels(),
        image.width(),
        image.height(),
        &EquirectMapping::Y_UP,
    )
    .map_err(|e| Error::msg(format!("cannot project the environment map to SH: {e}")))?;
    let window = crate::hemi_shading::hann_window(Sh::<N>::BANDS);
    let sh = projected
        .convolved(&ZonalKernel::from_factors(&window))
        .rotated(rotation);
    Ok(lighting_from_sh_rgb(&sh).to_vec())
}

/// Checks that `set` was baked from `mesh`: same vertex count and positions.
pub fn check_matches(set: &TransferSet, mesh: &TriangleMesh) -> Result<()> {
    if set.vertex_count() != mesh.vertex_count() {
        return Err(Error::msg(format!(
            "the bake file has {} vertices, {} has {}: bake it from this mesh",
            set.vertex_count(),
            mesh.name(),
            mesh.vertex_count()
        )));
    }
    let tolerance = 1e-5 * mesh.bounds().diagonal();
    let moved = set
        .positions()
        .iter()
        .zip(mesh.positions())
        .position(|(a, b)| (Vec3::from(*a) - Vec3::from(*b)).length() > tolerance);
    if let Some(v) = moved {
        return Err(Error::msg(format!(
            "vertex {v} of the bake file is not where {} has it: bake it from this mesh",
            mesh.name()
        )));
    }
    Ok(())
}

/// Draws a mesh with one linear radiance per vertex, supersampled
/// (`supersampling`² samples per pixel).
pub fn draw(
    camera: &Camera,
    mesh: &TriangleMesh,
    colors: &[Vec3],
    (width, height): (usize, usize),
    supersampling: usize,
) -> Framebuffer {
    let mut frame = Framebuffer::new(width * supersampling, height * supersampling);
    frame.draw_mesh(camera, mesh.positions(), mesh.indices(), colors);
    frame
}

/// The auto exposure of a frame's covered pixels.
pub fn exposure_of(frame: &Framebuffer) -> f32 {
    let covered: Vec<Vec3> = (0..frame.height())
        .flat_map(|y| (0..frame.width()).filter_map(move |x| frame.get(x, y)))
        .collect();
    crate::tonemap::auto_exposure(&crate::picture::HdrImage::from_pixels(
        covered.len(),
        1,
        covered,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_sky_lighting_has_only_the_dc_term_and_rotation_keeps_it() {
        let image =
            crate::picture::HdrImage::from_pixels(256, 128, vec![Vec3::splat(2.0); 256 * 128]);
        let env = EnvironmentMap::from_image(image);
        for rotate in [0.0, 77.0] {
            let l = env_lighting(&env, 3, rotate).unwrap();
            assert_eq!(l.len(), 9);
            // ∫ 2 · Y_0 dω = 2 · 2√π.
            let dc = 4.0 * std::f32::consts::PI.sqrt();
            assert!((l[0][0] - dc).abs() < 1e-3 * dc, "{l:?}");
            // A coarse map's pixel quadrature leaks into band 2 (0.2 at 4 rows); 128
            // rows keep it below 1e-3.
            assert!(l[1..].iter().flatten().all(|c| c.abs() < 1e-3), "{l:?}");
        }
        assert!(env_lighting(&env, 9, 0.0).is_err());
    }

    #[test]
    fn baked_sets_have_the_requested_shape() {
        let tetra = TriangleMesh::parse_obj_str(
            "tetra",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
        )
        .unwrap();
        let mut config = BakeConfig {
            kind: Kind::Mrt,
            bands: 3,
            grid: 4,
            bounces: 1,
            rays: 16,
            albedo: 0.5,
            brdf: BrdfChoice::phong(8.0).unwrap(),
            seed: 1,
            ray_offset: default_ray_offset(),
        };
        let baked = bake_mesh(&tetra, &config, true, None).unwrap();
        assert_eq!(baked.set.block_len(), 16 * 9);
        assert_eq!(baked.rays_cast, 4 * 16 * 2);
        check_matches(&baked.set, &tetra).unwrap();
        config.kind = Kind::Diffuse;
        let parallel = bake_mesh(&tetra, &config, false, None).unwrap();
        let serial = bake_mesh(&tetra, &config, true, None).unwrap();
        assert_eq!(parallel.set, serial.set);
        assert_eq!(serial.set.block_len(), 9);
    }
}
