//! Demo picture: two boxes on a floor under the sunrise, lit by a lightmap. The
//! lightmap is baked once per texel of the scene's UV atlas (every quad its own
//! chart; receivers lifted out of geometry, a 2-texel gutter), diffuse transfer
//! with one bounce that reads the texel under each hit, then relit under the
//! sky's SH coefficients and drawn with bilinear filtering, as an engine would.

use antumbra_core::transfer::{BakeOptions, Material, Measurement, View};
use glam::{Vec2, Vec3};

use super::hemi::{SUPERSAMPLING, develop, to_rgb8};
use super::{DemoContext, DemoPicture};
use crate::camera::{Camera, ViewAngles};
use crate::error::{Error, Result};
use crate::lightmap::{TexturedMesh, bake_texels, draw_lightmapped};
use crate::mesh::TriangleMesh;
use crate::prt;

/// Rays per texel and pass: the lightmap's noise is a few percent.
const RAYS: u32 = 128;

/// SH bands of the bake and of the sky.
const BANDS: u32 = 4;

/// Diffuse albedo of every surface, for the bounce and the shading.
const ALBEDO: f32 = 0.6;

/// The picture.
pub(super) const PICTURE: DemoPicture = DemoPicture {
    file_name: "lightmap-boxes.png",
    title: "two boxes on a floor under the sunrise, lit by a baked lightmap (diffuse transfer per texel, one bounce between texels), drawn with bilinear filtering",
    render,
};

/// The scene, +Y up: the floor on the left of the atlas, each box face a chart
/// on the right. Every quad has its own vertices and flat normals.
pub(in crate::commands) fn scene() -> Result<TexturedMesh> {
    let (mut positions, mut uvs, mut indices, mut normals) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut quad = |corners: [Vec3; 4], lo: Vec2, size: Vec2| {
        let base = positions.len() as u32;
        let normal = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize();
        let chart = [
            lo,
            lo + Vec2::new(size.x, 0.0),
            lo + size,
            lo + Vec2::new(0.0, size.y),
        ];
        for (p, uv) in corners.iter().zip(chart) {
            positions.push(p.to_array());
            uvs.push(uv.to_array());
            normals.push(normal);
        }
        indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    };
    let v = Vec3::new;
    let f = 1.5;
    quad(
        [v(-f, 0.0, f), v(f, 0.0, f), v(f, 0.0, -f), v(-f, 0.0, -f)],
        Vec2::ZERO,
        Vec2::splat(0.6),
    );
    let boxes = [
        (v(-0.8, 0.0, -0.6), v(-0.1, 0.7, 0.1)),
        (v(0.2, 0.0, -0.1), v(0.9, 0.35, 0.6)),
    ];
    let mut chart = 0;
    for (lo, hi) in boxes {
        let faces = [
            [
                v(lo.x, hi.y, hi.z),
                v(hi.x, hi.y, hi.z),
                v(hi.x, hi.y, lo.z),
                v(lo.x, hi.y, lo.z),
            ],
            [
                v(lo.x, lo.y, hi.z),
                v(hi.x, lo.y, hi.z),
                v(hi.x, hi.y, hi.z),
                v(lo.x, hi.y, hi.z),
            ],
            [
                v(hi.x, lo.y, lo.z),
                v(lo.x, lo.y, lo.z),
                v(lo.x, hi.y, lo.z),
                v(hi.x, hi.y, lo.z),
            ],
            [
                v(hi.x, lo.y, hi.z),
                v(hi.x, lo.y, lo.z),
                v(hi.x, hi.y, lo.z),
                v(hi.x, hi.y, hi.z),
            ],
            [
                v(lo.x, lo.y, lo.z),
                v(lo.x, lo.y, hi.z),
                v(lo.x, hi.y, hi.z),
                v(lo.x, hi.y, lo.z),
            ],
        ];
        for face in faces {
            let at = Vec2::new(
                0.62 + 0.19 * (chart % 2) as f32,
                0.01 + 0.099 * (chart / 2) as f32,
            );
            quad(face, at, Vec2::new(0.18, 0.09));
            chart += 1;
        }
    }
    let mesh = TriangleMesh::new("the lightmap demo's boxes", positions, indices)?;
    Ok(TexturedMesh { mesh, uvs, normals })
}

fn render(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let textured = scene()?;
    let (env, _) = context.sky()?;
    let side = if context.size < 400 { 128 } else { 256 };
    let options = BakeOptions {
        bands: BANDS,
        rays: RAYS,
        bounces: 1,
        albedo: ALBEDO,
        seed: 3,
        ray_offset: prt::default_ray_offset(),
        ..BakeOptions::new(Measurement::Diffuse)
    };
    let started = std::time::Instant::now();
    let bake = bake_texels(&textured, side, side, &options, None)?;
    let baked = started.elapsed();
    let lighting = prt::env_lighting(env, BANDS, 0.0)?;
    let receivers = bake.atlas.receivers().len();
    let mut radiance = vec![[0.0f32; 3]; receivers];
    let material = Material {
        albedo: [ALBEDO; 3],
        ..Material::default()
    };
    bake.set
        .shade(
            &lighting,
            View::Eye([0.0; 3]),
            &material,
            None,
            &mut radiance,
        )
        .map_err(|e| Error::msg(format!("cannot shade the lightmap: {e}")))?;
    let texels = side as usize * side as usize;
    let mut texture = vec![0.0f32; texels * 3];
    bake.atlas
        .expand(radiance.as_flattened(), 3, &mut texture)
        .ok_or_else(|| Error::msg("the lightmap does not match its atlas"))?;

    let (width, height) = context.render_size();
    let view = ViewAngles {
        azimuth: 35f32.to_radians(),
        elevation: 35f32.to_radians(),
        vertical_fov: 40f32.to_radians(),
    };
    let camera = Camera::framing(
        &textured.mesh.bounds(),
        view,
        width as f32 / height as f32,
        0.02,
    );
    let frame = draw_lightmapped(
        &camera,
        &textured,
        &texture,
        (side as usize, side as usize),
        (width * SUPERSAMPLING, height * SUPERSAMPLING),
    );
    let exposure = prt::exposure_of(&frame);
    let picture = develop(&frame, exposure);
    let note = format!(
        "{side}×{side} atlas, {receivers} texels × {RAYS} rays, 1 bounce: baked in {:.0} ms; relit \
         per texel in SH, drawn with bilinear lookups",
        baked.as_secs_f64() * 1e3
    );
    Ok((to_rgb8(&picture), note))
}
