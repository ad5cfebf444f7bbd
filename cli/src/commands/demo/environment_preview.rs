//! Demo picture: the sunrise environment map itself, small and tone-mapped.

use super::{DemoContext, DemoPicture};
use crate::error::Result;
use crate::tonemap::to_srgb8_auto;

/// The picture.
pub(super) const PICTURE: DemoPicture = DemoPicture {
    file_name: "sunrise-environment.png",
    title: "the sunrise environment map (equirectangular, +Y up, centre = +X)",
    render,
};

fn render(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let (env, _) = context.sky()?;
    let source = env.image();
    let width = (context.size as usize).min(source.width());
    let height = (width / 2).max(1);
    let preview = source.downsample(width, height);
    let note = format!(
        "box-filtered from {}x{}, auto exposure",
        source.width(),
        source.height()
    );
    Ok((to_srgb8_auto(&preview), note))
}
