//! Demo picture: the bunny lit by the sunrise sky, with ray-traced visibility.

use super::{DemoContext, DemoPicture};
use crate::error::Result;
use crate::render::{EnvironmentLighting, RenderSettings};
use crate::tonemap::to_srgb8_auto;

/// Samples per pixel (each: one primary ray and two shadow rays).
const SAMPLES: u32 = 48;

/// The picture.
pub(super) const PICTURE: DemoPicture = DemoPicture {
    file_name: "bunny-sunrise.png",
    title: "bunny under the sunrise HDR sky, diffuse, ray-traced shadows (MIS)",
    render,
};

fn render(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let scene = context.bunny_scene()?;
    let (env, sampler) = context.sky()?;
    let camera = context.bunny_camera(scene);
    let (width, height) = context.render_size();
    let settings = RenderSettings {
        width,
        height,
        samples: SAMPLES,
    };
    let image = EnvironmentLighting { env, sampler }.render(scene, &camera, &settings);
    let note = format!("{SAMPLES} samples/pixel, sky and cosine sampling, auto exposure");
    Ok((to_srgb8_auto(&image), note))
}
