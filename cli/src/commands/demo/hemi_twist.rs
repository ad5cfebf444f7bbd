//! Demo picture: a contact sheet of frames of the bunny twisting about its
//! vertical axis, re-shaded every frame from the deformed positions alone (normals,
//! cluster boxes, masks, transfer: nothing is precomputed per pose), with the far
//! mesh for distant occluders.

use std::fmt::Write as _;

use super::hemi::{develop, rasterize, to_rgb8};
use super::{DemoContext, DemoPicture};
use antumbra_core::hemi::VertexShading;

use crate::bounds::Bounds;
use crate::error::Result;
use crate::hemi_shading::{Occluders, Posed, Twist};
use crate::picture::HdrImage;

/// The twist of the top of the bunny in each frame, in degrees (the bottom stays).
const TWIST_DEGREES: [f32; 4] = [0.0, 40.0, 80.0, 120.0];

/// Frames per row of the contact sheet.
const COLUMNS: usize = 2;

/// Display colour of the lines between frames.
const SEPARATOR: glam::Vec3 = glam::Vec3::new(0.08, 0.08, 0.09);

/// The picture.
pub(super) const PICTURE: DemoPicture = DemoPicture {
    file_name: "bunny-hemi-twist.png",
    title: "twisting bunny, re-shaded every frame by hemispherical rasterization (glossy, far mesh); frames left to right, top to bottom",
    render,
};

fn render(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let stage = context.hemi_stage()?;
    let lod = &stage.lod;
    // The bunny turns about its own vertical axis; the ground, at the bottom of
    // the bunny's bounds, does not move.
    let twist = Twist::of_bounds(&stage.bunny_bounds);
    // One camera for every frame, framing the bunny in all of them.
    let bounds = TWIST_DEGREES.iter().fold(Bounds::EMPTY, |bounds, degrees| {
        let angle = degrees.to_radians();
        let frame = Bounds::of_points(
            lod.full.positions()[..stage.bunny_vertices]
                .iter()
                .map(|&p| twist.apply(p.into(), angle)),
        );
        Bounds {
            min: bounds.min.min(frame.min),
            max: bounds.max.max(frame.max),
        }
    });
    let camera = context.bunny_camera_for(&bounds);
    let material = stage.material(true, camera.position());
    let quality = stage.shader.quality(false);
    let (width, height) = context.render_size();
    let rows = TWIST_DEGREES.len().div_ceil(COLUMNS);
    let mut sheet = HdrImage::new(width * COLUMNS, height * rows);
    let mut posed = Posed::new(lod, Occluders::FarMesh)?;
    let mut shading = vec![VertexShading::default(); lod.full.vertex_count()];
    let mut timings = String::new();
    for (k, degrees) in TWIST_DEGREES.iter().enumerate() {
        let angle = degrees.to_radians();
        let time = posed.frame(
            |p| twist.apply(p, angle),
            &stage.shader,
            quality,
            &stage.lighting,
            &material,
            &mut shading,
        )?;
        let frame = rasterize(
            &camera,
            posed.positions(),
            lod.full.indices(),
            &stage.colors(&shading, true),
            (width, height),
        );
        let tile = develop(&frame, stage.exposure(&frame));
        let (x0, y0) = ((k % COLUMNS) * width, (k / COLUMNS) * height);
        for y in 0..height {
            for x in 0..width {
                sheet.set(x0 + x, y0 + y, tile.get(x, y));
            }
        }
        let _ = write!(
            timings,
            "{}{degrees:.0}° {:.1} ms",
            if k == 0 { "" } else { ", " },
            time.total().as_secs_f64() * 1e3
        );
    }
    // Thin dark lines between the frames.
    let line = (width / 240).max(1);
    for y in 0..sheet.height() {
        for x in 0..sheet.width() {
            let (tx, ty) = (x % width, y % height);
            if (x >= width && tx < line) || (y >= height && ty < line) {
                sheet.set(x, y, SEPARATOR);
            }
        }
    }
    let note = format!(
        "far mesh {} triangles (bunny by vertex clustering with cells of {:.3}, ground 2), near radius {:.3}; \
         per frame, twist then pose + shading: {timings}",
        lod.far.triangle_count(),
        lod.far_cell,
        lod.near_radius
    );
    Ok((to_rgb8(&sheet), note))
}
