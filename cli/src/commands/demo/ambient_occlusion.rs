//! Demo picture: ray-cast ambient occlusion of the bunny on a ground plane.

use super::{DemoContext, DemoPicture};
use crate::error::Result;
use crate::render::{AmbientOcclusion, RenderSettings};
use crate::tonemap::to_unit8;

/// Occlusion rays per pixel.
const SAMPLES: u32 = 64;

/// The picture.
pub(super) const PICTURE: DemoPicture = DemoPicture {
    file_name: "bunny-ambient-occlusion.png",
    title: "bunny, ray-cast ambient occlusion (BVH closest hit + occlusion rays)",
    render,
};

fn render(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let scene = context.bunny_scene()?;
    let camera = context.bunny_camera(scene);
    let (width, height) = context.render_size();
    let settings = RenderSettings {
        width,
        height,
        samples: SAMPLES,
    };
    let occlusion = AmbientOcclusion::for_object(&scene.object_bounds());
    let image = occlusion.render(scene, &camera, &settings);
    let note = format!(
        "{SAMPLES} rays/pixel, occluders up to {:.2} away",
        occlusion.max_distance
    );
    Ok((to_unit8(&image), note))
}
