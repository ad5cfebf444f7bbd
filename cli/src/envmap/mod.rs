//! HDR environment maps in the equirectangular layout ([`equirect`]): loading
//! (OpenEXR with `exr`, PNG with `image`), radiance lookup, downsampling for
//! previews, and importance sampling ([`EnvironmentSampler`]).

pub mod equirect;
mod sampler;

use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{Context, Error, Result};
use crate::picture::HdrImage;

pub use sampler::EnvironmentSampler;

/// Linear-light RGB radiance over the sphere of directions, stored as an
/// equirectangular image (see [`equirect`] for the axes).
#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    image: HdrImage,
}

impl EnvironmentMap {
    /// Wraps an equirectangular image (any size, ideally 2:1).
    pub fn from_image(image: HdrImage) -> Self {
        EnvironmentMap { image }
    }

    /// Loads an OpenEXR (`.exr`) or PNG (`.png`) file, chosen by its content.
    /// PNG values are decoded from sRGB to linear; EXR values are used as stored
    /// (negative and non-finite values become 0).
    pub fn load(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let bytes =
            std::fs::read(path).with_context(|| format!("cannot read environment map {name}"))?;
        Self::decode(&name, &bytes)
    }

    /// Decodes an in-memory EXR or PNG file; `name` is used in messages.
    pub fn decode(name: &str, bytes: &[u8]) -> Result<Self> {
        const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
        const PNG_MAGIC: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
        let image = if bytes.starts_with(&EXR_MAGIC) {
            decode_exr(bytes)
                .with_context(|| format!("cannot decode OpenEXR environment map {name}"))?
        } else if bytes.starts_with(&PNG_MAGIC) {
            decode_png(bytes)
                .with_context(|| format!("cannot decode PNG environment map {name}"))?
        } else {
            return Err(Error::msg(format!(
                "{name} is neither an OpenEXR nor a PNG file (environment maps must be one of those)"
            )));
        };
        if image.width() < 2 || image.height() < 1 {
            return Err(Error::msg(format!(
                "environment map {name} is only {}x{} pixels",
                image.width(),
                image.height()
            )));
        }
        Ok(Self::from_image(image))
    }

    /// The equirectangular image.
    pub fn image(&self) -> &HdrImage {
        &self.image
    }

    /// Radiance arriving from `direction` (any non-zero length): the texel the
    /// direction falls in, without filtering, so it is exactly the value the
    /// importance sampler's density was built from.
    pub fn radiance(&self, direction: Vec3) -> Vec3 {
        self.radiance_at_uv(equirect::direction_to_uv(direction))
    }

    /// Radiance at equirectangular coordinates `uv`.
    pub fn radiance_at_uv(&self, uv: Vec2) -> Vec3 {
        let (column, row) = equirect::uv_to_texel(uv, self.image.width(), self.image.height());
        self.image.get(column, row)
    }
}

/// The first RGB(A) layer of an EXR file, at full resolution.
fn decode_exr(bytes: &[u8]) -> std::result::Result<HdrImage, exr::error::Error> {
    use exr::prelude::*;
    let decoded = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution, _channels| HdrImage::new(resolution.width(), resolution.height()),
            |image: &mut HdrImage, position, (r, g, b, _a): (f32, f32, f32, f32)| {
                image.set(position.x(), position.y(), sanitize(Vec3::new(r, g, b)));
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))?;
    Ok(decoded.layer_data.channel_data.pixels)
}

/// A PNG, converted from sRGB-encoded 8 or 16 bits to linear floats.
fn decode_png(bytes: &[u8]) -> std::result::Result<HdrImage, image::ImageError> {
    let decoded =
        image::load_from_memory_with_format(bytes, image::ImageFormat::Png)?.into_rgb32f();
    let mut out = HdrImage::new(decoded.width() as usize, decoded.height() as usize);
    for (x, y, pixel) in decoded.enumerate_pixels() {
        let [r, g, b] = pixel.0.map(crate::tonemap::srgb_to_linear);
        out.set(x as usize, y as usize, Vec3::new(r, g, b));
    }
    Ok(out)
}

/// Negative or non-finite radiance has no physical meaning; treat it as black.
fn sanitize(rgb: Vec3) -> Vec3 {
    Vec3::from_array(
        rgb.to_array()
            .map(|c| if c.is_finite() { c.max(0.0) } else { 0.0 }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_uses_the_documented_axes() {
        // Top half red, bottom half blue; the right half of each brighter.
        let mut image = HdrImage::new(4, 2);
        for x in 0..4 {
            let bright = if x >= 2 { 2.0 } else { 1.0 };
            image.set(x, 0, Vec3::new(bright, 0.0, 0.0));
            image.set(x, 1, Vec3::new(0.0, 0.0, bright));
        }
        let env = EnvironmentMap::from_image(image);
        // Up reads the top row (red), down the bottom row (blue).
        assert!(env.radiance(Vec3::new(0.0, 1.0, 0.0)).x > 0.0);
        assert!(env.radiance(Vec3::new(0.0, -1.0, 0.0)).z > 0.0);
        // +X is the centre of the image (u = 0.5, column 2), −Z is u = 0.25 (column 1).
        assert_eq!(env.radiance(Vec3::new(1.0, 0.1, 0.0)).x, 2.0);
        assert_eq!(env.radiance(Vec3::new(0.0, 0.1, -1.0)).x, 1.0);
        assert_eq!(env.radiance(Vec3::new(0.0, 0.1, 1.0)).x, 2.0);
    }

    #[test]
    fn rejects_unknown_formats() {
        let error = EnvironmentMap::decode("sky.hdr", b"#?RADIANCE\n").unwrap_err();
        assert!(error.to_string().contains("sky.hdr"));
    }

    #[test]
    fn built_in_sunrise_decodes() {
        let env = EnvironmentMap::decode("sunrise", crate::builtin::SUNRISE_EXR).unwrap();
        assert_eq!((env.image().width(), env.image().height()), (1024, 512));
        // The sun is near column 614, row 233 (SOURCES.md): far brighter than the mean.
        let sun = env.image().get(614, 233);
        assert!(sun.max_element() > 1000.0, "{sun}");
    }
}
