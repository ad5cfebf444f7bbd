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
            check_exr_size(name, bytes)?;
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
        let brightest = image
            .pixels()
            .iter()
            .map(|p| p.max_element())
            .fold(0.0f32, f32::max);
        if brightest > MAX_RADIANCE {
            return Err(Error::msg(format!(
                "environment map {name} has a texel of {brightest:e}; at most {MAX_RADIANCE:e} \
                 is supported (a render sums up to 65,536 samples of it over the sphere in \
                 f32, which must not overflow)"
            )));
        }
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

/// Brightest texel value an environment map may have: a pixel of a render is
/// a sum of up to 65,536 samples of radiance times `4π` (over two estimators)
/// in `f32`, which stays below `f32::MAX` (3.4e38) from here. A map of 1e37
/// made every picture black (an infinite sum, then a zero exposure).
const MAX_RADIANCE: f32 = 1e32;

/// Most pixels an environment map may have: 16384 × 8192, the largest maps in
/// common use (1.5 GiB as linear RGB).
const MAX_MAP_PIXELS: usize = 16384 * 8192;

/// Refuses an EXR whose header declares a layer of more than
/// [`MAX_MAP_PIXELS`]. The decoder allocates the image from the header before
/// it reads a pixel, so a corrupt or hostile header of a few hundred bytes could
/// otherwise ask for gigabytes (or overflow the size and panic).
fn check_exr_size(name: &str, bytes: &[u8]) -> Result<()> {
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .with_context(|| format!("cannot decode OpenEXR environment map {name}"))?;
    for header in &meta.headers {
        let (width, height) = (header.layer_size.width(), header.layer_size.height());
        if width.checked_mul(height).is_none_or(|n| n > MAX_MAP_PIXELS) {
            return Err(Error::msg(format!(
                "environment map {name} declares {width}x{height} pixels; at most \
                 {MAX_MAP_PIXELS} (16384x8192) are supported"
            )));
        }
    }
    Ok(())
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

    /// A 2×1 EXR whose header is patched to declare `width` × `height`
    /// pixels (no pixel data added): the size a corrupt file claims.
    fn exr_declaring(width: i32, height: i32) -> Vec<u8> {
        use exr::prelude::*;
        let image = Image::from_channels(
            (2, 1),
            SpecificChannels::rgb(|_: Vec2<usize>| (1.0f32, 1.0f32, 1.0f32)),
        );
        let mut out = std::io::Cursor::new(Vec::new());
        image.write().to_buffered(&mut out).unwrap();
        let mut bytes = out.into_inner();
        for attribute in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
            let at = bytes
                .windows(attribute.len())
                .position(|w| w == attribute)
                .unwrap()
                + attribute.len()
                + 4;
            bytes[at + 8..at + 12].copy_from_slice(&(width - 1).to_le_bytes());
            bytes[at + 12..at + 16].copy_from_slice(&(height - 1).to_le_bytes());
        }
        bytes
    }

    /// The CLI review's hostile maps: a few hundred bytes whose header
    /// declared 30000² or 100000² pixels took 10 GB before failing, aborted
    /// on the allocation, or panicked on a capacity overflow.
    #[test]
    fn a_header_declaring_a_huge_map_is_refused_before_decoding() {
        assert!(EnvironmentMap::decode("small", &exr_declaring(2, 1)).is_ok());
        for (width, height) in [(30000, 30000), (100000, 100000), (1 << 20, 1 << 20)] {
            let bytes = exr_declaring(width, height);
            assert!(bytes.len() < 1000);
            let error = EnvironmentMap::decode("huge", &bytes).unwrap_err();
            assert!(
                format!("{error:#}").contains("at most 134217728"),
                "{width}x{height}: {error:#}"
            );
        }
        // A size the header reader itself refuses is an error as well.
        assert!(EnvironmentMap::decode("huge", &exr_declaring(i32::MAX, i32::MAX)).is_err());
    }

    /// The CLI review's map of 1e37 everywhere rendered black on the
    /// ray-traced path; such maps are refused when loaded.
    #[test]
    fn maps_too_bright_to_render_in_f32_are_refused() {
        let map = |value: f32| {
            use exr::prelude::*;
            let image = Image::from_channels(
                (16, 8),
                SpecificChannels::rgb(|_: Vec2<usize>| (value, value, value)),
            );
            let mut out = std::io::Cursor::new(Vec::new());
            image.write().to_buffered(&mut out).unwrap();
            out.into_inner()
        };
        assert!(EnvironmentMap::decode("bright", &map(1e30)).is_ok());
        let error = EnvironmentMap::decode("too bright", &map(1e37)).unwrap_err();
        assert!(format!("{error:#}").contains("at most 1e32"), "{error:#}");
    }

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
