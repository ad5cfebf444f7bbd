//! Renderers: pictures computed by casting rays into a [`Scene`].
//!
//! Every renderer shades pixels independently, in parallel over rows with rayon,
//! with one seeded random generator per pixel, so a picture is the same whatever
//! the thread count.

mod ambient_occlusion;
mod environment_lighting;

use antumbra_core::Ray;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::picture::HdrImage;
use crate::progress;
use crate::sampling::{SampleRng, hash_seed};

pub use ambient_occlusion::{AmbientOcclusion, ambient_ray_escapes};
pub use environment_lighting::EnvironmentLighting;

/// Size of a picture and the samples spent on each pixel.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Samples per pixel (each with its own sub-pixel position, so edges are
    /// anti-aliased).
    pub samples: u32,
}

/// Shades every pixel of a `settings.width × settings.height` picture in
/// parallel, showing a progress bar labelled `label`. `shade` gets the pixel and a
/// generator seeded from `seed` and the pixel's index.
pub fn render_pixels<F>(settings: &RenderSettings, label: &str, seed: u64, shade: F) -> HdrImage
where
    F: Fn(usize, usize, &mut SampleRng) -> Vec3 + Sync,
{
    let (width, height) = (settings.width, settings.height);
    let bar = progress::bar(height as u64, label, "rows");
    let mut pixels = vec![Vec3::ZERO; width * height];
    pixels
        .par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, pixel) in row.iter_mut().enumerate() {
                let mut rng = SampleRng::new(hash_seed(&[seed, (y * width + x) as u64]));
                *pixel = shade(x, y, &mut rng);
            }
            bar.inc(1);
        });
    bar.finish_and_clear();
    HdrImage::from_pixels(width, height, pixels)
}

/// Image coordinates (`[0, 1]²`, top left origin) of a random point in pixel `(x, y)`.
fn jittered_pixel(settings: &RenderSettings, x: usize, y: usize, rng: &mut SampleRng) -> Vec2 {
    let jitter = rng.next_vec2();
    Vec2::new(
        (x as f32 + jitter.x) / settings.width as f32,
        (y as f32 + jitter.y) / settings.height as f32,
    )
}

/// The primary ray through a random point of pixel `(x, y)`.
fn camera_ray(
    camera: &Camera,
    settings: &RenderSettings,
    x: usize,
    y: usize,
    rng: &mut SampleRng,
) -> Ray {
    let direction = camera.direction(jittered_pixel(settings, x, y, rng));
    Ray::new(camera.position(), direction, f32::INFINITY)
}
