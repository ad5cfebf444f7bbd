//! Demo picture: the bunny as glazed ceramic relit by matrix radiance transfer
//! (Lehtinen & Kautz 2003) under the sunrise turning about the vertical axis: a
//! contact sheet of frames, each a new lighting vector shaded at every vertex from
//! the same bake, no rays at run time.
//!
//! The bake (once, at the start): diffuse transfer vectors for the matte base and
//! MRT matrices on an 8×8 hemi-octahedral grid for a Phong lobe of exponent 32
//! (the glaze), 4 bands, [`RAYS`] rays per vertex, self-shadowing only (0
//! bounces). Per frame: the sky's SH coefficients rotated, then per vertex a dot
//! product (diffuse) and four rows of the MRT matrix blended for the view
//! direction (glossy).

use std::fmt::Write as _;
use std::time::Instant;

use antumbra_core::transfer::{Material, View};
use glam::Vec3;

use super::hemi::{develop, rasterize, to_rgb8};
use super::{DemoContext, DemoPicture};
use crate::builtin;
use crate::error::{Error, Result};
use crate::picture::HdrImage;
use crate::prt::{self, BakeConfig, BrdfChoice, Kind};

/// Rays per vertex of both bakes: few, the demo must stay quick; the bake's
/// noise is then a few percent (the `embree_transfer` test measures 2.7 %
/// relative RMS for the diffuse transfer at 256 rays; at 64 rays the error is
/// about 8 % and the glaze looks blotchy).
const RAYS: u32 = 256;

/// Rotation of the sky about +Y in each frame, degrees.
const ROTATIONS: [f32; 4] = [0.0, 90.0, 180.0, 270.0];

/// Frames per row of the contact sheet.
const COLUMNS: usize = 2;

/// The glaze's Phong exponent.
const EXPONENT: f32 = 32.0;

/// Diffuse albedo under the glaze, and the glaze's specular reflectance.
const BASE_ALBEDO: [f32; 3] = [0.40, 0.39, 0.37];
const GLAZE: [f32; 3] = [0.5; 3];

/// The picture.
pub(super) const PICTURE: DemoPicture = DemoPicture {
    file_name: "bunny-mrt-rotating-sky.png",
    title: "glossy bunny relit by matrix radiance transfer (8×8 grid, Phong 32) under the sunrise rotating by 90° per frame; frames left to right, top to bottom",
    render,
};

fn render(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let bunny = builtin::bunny()?;
    let (env, _) = context.sky()?;
    let config = |kind| -> Result<BakeConfig> {
        Ok(BakeConfig {
            kind,
            bands: 4,
            grid: 8,
            bounces: 0,
            rays: RAYS,
            albedo: 0.5,
            brdf: BrdfChoice::phong(EXPONENT)?,
            seed: 3,
            ray_offset: prt::default_ray_offset(),
        })
    };
    let diffuse = prt::bake_mesh(&bunny, &config(Kind::Diffuse)?, false, None)?;
    let mrt = prt::bake_mesh(&bunny, &config(Kind::Mrt)?, false, None)?;
    let camera = context.bunny_camera_for(&bunny.bounds());
    let eye = View::Eye(camera.position().to_array());
    let base = Material {
        albedo: BASE_ALBEDO,
        ..Material::default()
    };
    let glaze = Material {
        specular: GLAZE,
        ..Material::default()
    };
    let (width, height) = context.render_size();
    let rows = ROTATIONS.len().div_ceil(COLUMNS);
    let mut sheet = HdrImage::new(width * COLUMNS, height * rows);
    let vertices = bunny.vertex_count();
    let (mut matte, mut glossy) = (vec![[0.0f32; 3]; vertices], vec![[0.0f32; 3]; vertices]);
    let mut exposure = None;
    let mut timings = String::new();
    for (k, degrees) in ROTATIONS.iter().enumerate() {
        let lighting = prt::env_lighting(env, 4, *degrees)?;
        let started = Instant::now();
        diffuse
            .set
            .shade(&lighting, eye, &base, None, &mut matte)
            .and_then(|()| mrt.set.shade(&lighting, eye, &glaze, None, &mut glossy))
            .map_err(|e| Error::msg(format!("cannot shade: {e}")))?;
        let shading = started.elapsed();
        let colors: Vec<Vec3> = matte
            .iter()
            .zip(&glossy)
            .map(|(a, b)| Vec3::from(*a) + Vec3::from(*b))
            .collect();
        let frame = rasterize(
            &camera,
            bunny.positions(),
            bunny.indices(),
            &colors,
            (width, height),
        );
        let exposure = *exposure.get_or_insert_with(|| prt::exposure_of(&frame));
        let tile = develop(&frame, exposure);
        let (x0, y0) = ((k % COLUMNS) * width, (k / COLUMNS) * height);
        for y in 0..height {
            for x in 0..width {
                sheet.set(x0 + x, y0 + y, tile.get(x, y));
            }
        }
        let _ = write!(
            timings,
            "{}{degrees:.0}° {:.2} ms",
            if k == 0 { "" } else { ", " },
            shading.as_secs_f64() * 1e3
        );
    }
    let note = format!(
        "bake {} vertices × {RAYS} rays: diffuse {:.0} ms, MRT {:.0} ms; shading every vertex per frame (diffuse + MRT, one thread): {timings}",
        vertices,
        diffuse.elapsed.as_secs_f64() * 1e3,
        mrt.elapsed.as_secs_f64() * 1e3
    );
    Ok((to_rgb8(&sheet), note))
}
