//! From linear radiance to displayable 8-bit sRGB: exposure, a filmic curve, and
//! the sRGB transfer function.

use glam::Vec3;

use crate::picture::HdrImage;

/// Where the auto exposure puts the image's log-average luminance: below the
/// photographic middle grey (0.18) because under a low sun the surfaces facing it
/// are several times brighter than the ground that dominates the average, and
/// 0.18 burns them out.
const KEY: f32 = 0.12;

/// Exposure scale that maps the log-average (geometric mean) luminance of
/// `image` to [`KEY`] (Reinhard et al. 2002). The geometric mean ignores a
/// few extreme pixels, such as a visible sun, that an arithmetic mean would not.
pub fn auto_exposure(image: &HdrImage) -> f32 {
    let pixels = image.pixels();
    if pixels.is_empty() {
        return 1.0;
    }
    let log_sum: f64 = pixels
        .iter()
        .map(|&p| f64::from(luminance(p).max(0.0) + 1e-4).ln())
        .sum();
    let log_average = (log_sum / pixels.len() as f64).exp() as f32;
    KEY / log_average
}

/// Tone-maps with [`auto_exposure`] and [`filmic`], then encodes as sRGB.
pub fn to_srgb8_auto(image: &HdrImage) -> image::RgbImage {
    to_srgb8(image, auto_exposure(image))
}

/// Scales by `exposure`, applies [`filmic`] per channel, and encodes with the
/// sRGB transfer function.
pub fn to_srgb8(image: &HdrImage, exposure: f32) -> image::RgbImage {
    map_to_rgb8(image, |c| linear_to_srgb(filmic(c * exposure)))
}

/// Writes values in `[0, 1]` straight to 8 bits, without the sRGB curve: the
/// customary display of ambient occlusion, whose contrast the sRGB curve would
/// wash out (it maps 0.5 to 0.74).
pub fn to_unit8(image: &HdrImage) -> image::RgbImage {
    map_to_rgb8(image, |c| c.clamp(0.0, 1.0))
}

/// Maps every channel through `display` (whose output must be in `[0, 1]`) and
/// quantises to 8 bits.
fn map_to_rgb8(image: &HdrImage, display: impl Fn(f32) -> f32) -> image::RgbImage {
    let mut out = image::RgbImage::new(image.width() as u32, image.height() as u32);
    for (pixel, &value) in out.pixels_mut().zip(image.pixels()) {
        pixel.0 = value.to_array().map(|c| (display(c) * 255.0 + 0.5) as u8);
    }
    out
}

/// Krzysztof Narkowicz's fit of the ACES filmic curve: a gentle toe and a
/// shoulder that rolls highlights off instead of clipping them.
pub fn filmic(x: f32) -> f32 {
    let x = x.max(0.0);
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// The sRGB encoding of a linear value in `[0, 1]`.
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The linear value of an sRGB-encoded value in `[0, 1]`.
pub fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// Rec. 709 luminance of linear RGB.
pub fn luminance(rgb: Vec3) -> f32 {
    rgb.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_and_hits_known_values() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        assert!((linear_to_srgb(0.214_041) - 0.5).abs() < 1e-4);
        for i in 0..=100 {
            let x = i as f32 / 100.0;
            assert!((srgb_to_linear(linear_to_srgb(x)) - x).abs() < 1e-5);
        }
    }

    #[test]
    fn filmic_is_monotonic_and_bounded() {
        let mut previous = 0.0;
        for i in 0..1000 {
            let y = filmic(i as f32 * 0.05);
            assert!((0.0..=1.0).contains(&y) && y >= previous);
            previous = y;
        }
    }

    #[test]
    fn unit_values_are_written_as_they_are() {
        let mut image = HdrImage::new(2, 1);
        image.set(0, 0, Vec3::splat(0.5));
        image.set(1, 0, Vec3::splat(2.0));
        let out = to_unit8(&image);
        assert_eq!(out.get_pixel(0, 0).0, [128; 3]);
        assert_eq!(out.get_pixel(1, 0).0, [255; 3]);
    }

    #[test]
    fn auto_exposure_maps_a_flat_image_to_middle_grey() {
        let mut image = HdrImage::new(4, 4);
        image.fill(Vec3::splat(3.0));
        let exposure = auto_exposure(&image);
        assert!((3.0 * exposure - KEY).abs() < 1e-3);
    }
}
