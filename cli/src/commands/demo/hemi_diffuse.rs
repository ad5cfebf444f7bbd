//! Demo picture: the bunny on a ground under the sunrise in SH, diffuse, shadowed
//! by hemispherical rasterization at every vertex (no rays).

use super::hemi::{develop, rasterize, to_rgb8};
use super::{DemoContext, DemoPicture};
use crate::error::Result;
use crate::hemi_shading::COEFFICIENTS;

/// The picture.
pub(super) const PICTURE: DemoPicture = DemoPicture {
    file_name: "bunny-hemi-diffuse.png",
    title: "bunny under the sunrise sky in SH, diffuse, per-vertex shadows by hemispherical rasterization (no rays)",
    render,
};

fn render(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let stage = context.hemi_stage()?;
    let mesh = &stage.lod.full;
    let camera = context.bunny_camera_for(&stage.bunny_bounds);
    let colors = stage.shade_rest(false, camera.position())?;
    let frame = rasterize(
        &camera,
        mesh.positions(),
        mesh.indices(),
        &colors,
        context.render_size(),
    );
    let picture = develop(&frame, stage.exposure(&frame));
    let note = format!(
        "{} vertices shaded (bunny {}, ground {}), exact 32x32 masks, {COEFFICIENTS} SH coefficients",
        mesh.vertex_count(),
        stage.bunny_vertices,
        mesh.vertex_count() - stage.bunny_vertices
    );
    Ok((to_rgb8(&picture), note))
}
