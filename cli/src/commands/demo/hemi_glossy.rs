//! Demo picture: the bunny on a ground under the sunrise in SH, glossy (a Phong
//! lobe about the mirror direction of the view at every vertex), shadowed by
//! hemispherical rasterization.

use super::hemi::{develop, rasterize, to_rgb8};
use super::{DemoContext, DemoPicture};
use crate::error::Result;
use crate::hemi_shading::PHONG_EXPONENT;

/// The picture.
pub(super) const PICTURE: DemoPicture = DemoPicture {
    file_name: "bunny-hemi-glossy.png",
    title: "bunny under the sunrise sky in SH, glossy (Phong lobe about the view's mirror direction), hemispherical rasterization",
    render,
};

fn render(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let stage = context.hemi_stage()?;
    let mesh = &stage.lod.full;
    let camera = context.bunny_camera_for(&stage.bunny_bounds);
    let colors = stage.shade_rest(true, camera.position())?;
    let frame = rasterize(
        &camera,
        mesh.positions(),
        mesh.indices(),
        &colors,
        context.render_size(),
    );
    // The diffuse picture's exposure (when it ran first), so the two compare.
    let picture = develop(&frame, stage.exposure(&frame));
    let note = format!(
        "Phong exponent {PHONG_EXPONENT}, specular 0.5 over half the diffuse albedo, matte ground"
    );
    Ok((to_rgb8(&picture), note))
}
