//! Images: linear-light float RGB ([`HdrImage`]) as renderers produce them, and
//! writing finished 8-bit pictures as PNG.

use std::io::Write;
use std::path::Path;

use glam::Vec3;

use crate::error::{Context, Result};

/// A `width × height` image of linear RGB floats, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct HdrImage {
    width: usize,
    height: usize,
    pixels: Vec<Vec3>,
}

impl HdrImage {
    /// A black image.
    pub fn new(width: usize, height: usize) -> Self {
        HdrImage {
            width,
            height,
            pixels: vec![Vec3::ZERO; width * height],
        }
    }

    /// An image from row-major pixels; `pixels.len()` must be `width * height`.
    pub fn from_pixels(width: usize, height: usize, pixels: Vec<Vec3>) -> Self {
        assert_eq!(
            pixels.len(),
            width * height,
            "pixel count must match the size"
        );
        HdrImage {
            width,
            height,
            pixels,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row-major pixels.
    pub fn pixels(&self) -> &[Vec3] {
        &self.pixels
    }

    /// Pixel `(x, y)`; panics when outside the image.
    pub fn get(&self, x: usize, y: usize) -> Vec3 {
        self.pixels[y * self.width + x]
    }

    /// Sets pixel `(x, y)`; panics when outside the image.
    pub fn set(&mut self, x: usize, y: usize, value: Vec3) {
        self.pixels[y * self.width + x] = value;
    }

    /// Sets every pixel to `value`.
    #[cfg(test)]
    pub fn fill(&mut self, value: Vec3) {
        self.pixels.fill(value);
    }

    /// A smaller copy where each pixel averages the block of source pixels it
    /// covers (a box filter; enough for previews).
    pub fn downsample(&self, width: usize, height: usize) -> HdrImage {
        let span = |i: usize, target: usize, source: usize| {
            let start = i * source / target;
            let end = ((i + 1) * source / target).max(start + 1).min(source);
            start..end
        };
        let mut out = HdrImage::new(width, height);
        for y in 0..height {
            let rows = span(y, height, self.height);
            for x in 0..width {
                let columns = span(x, width, self.width);
                let mut sum = Vec3::ZERO;
                let mut count = 0.0;
                for sy in rows.clone() {
                    for sx in columns.clone() {
                        sum += self.get(sx, sy);
                        count += 1.0;
                    }
                }
                out.set(x, y, sum / count);
            }
        }
        out
    }
}

/// Writes an 8-bit sRGB picture as PNG, creating missing parent folders.
pub fn save_png(picture: &image::RgbImage, path: &Path) -> Result<()> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create folder {}", parent.display()))?;
    }
    // Encoded into our own buffered writer and flushed here: `save_with_format`
    // drops its writer unflushed, so a failure to write a small picture (one
    // that fits the buffer) was swallowed and reported as success.
    let write = || -> std::io::Result<()> {
        let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
        picture
            .write_to(&mut file, image::ImageFormat::Png)
            .map_err(std::io::Error::other)?;
        file.flush()
    };
    write().with_context(|| format!("cannot write PNG {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_averages_blocks() {
        let mut image = HdrImage::new(4, 2);
        for x in 0..4 {
            image.set(x, 0, Vec3::splat(x as f32));
            image.set(x, 1, Vec3::splat(10.0));
        }
        let small = image.downsample(2, 1);
        assert_eq!(small.get(0, 0), Vec3::splat((0.0 + 1.0 + 20.0) / 4.0));
        assert_eq!(small.get(1, 0), Vec3::splat((2.0 + 3.0 + 20.0) / 4.0));
    }
}
