//! What the hemispherical-rasterization pictures share: the bunny standing on a
//! ground, its far mesh, the sunrise projected to SH, the shading tables, the
//! materials, one exposure for all of them, and drawing a mesh shaded per vertex.
//!
//! These pictures trace no rays. Every vertex of the stage (the bunny and the
//! ground) is a receiver whose 32×32 visibility mask is rasterized from the
//! stage's own triangles (`antumbra_core::hemi`), turned into an SH transfer
//! vector and shaded under the SH sky; the shaded mesh is then drawn with a
//! z-buffered triangle rasterizer interpolating the vertex colours
//! ([`crate::raster`]), 3×3 supersampled.
//!
//! The ground ([`crate::ground`]) is what makes the contact shadows: it blocks
//! the bunny's lower hemisphere (the grass of the sunrise map) and receives the
//! bunny's shadow at its own vertices.

use std::cell::OnceCell;

use antumbra_core::hemi::{Material, VertexShading};
use antumbra_core::sh::ShRgb;
use glam::Vec3;

use crate::bounds::Bounds;
use crate::camera::Camera;
use crate::envmap::EnvironmentMap;
use crate::error::Result;
use crate::ground::on_ground;
use crate::hemi_shading::{COEFFICIENTS, LodMesh, Occluders, Posed, Shader};
use crate::mesh::TriangleMesh;
use crate::picture::HdrImage;
use crate::raster::Framebuffer;
use crate::tonemap::{auto_exposure, filmic, linear_to_srgb};

/// Samples per pixel side when drawing (anti-aliasing by supersampling).
pub(super) const SUPERSAMPLING: usize = 3;

/// Diffuse albedo of the diffuse bunny (the ray-traced pictures' object albedo).
const DIFFUSE_ALBEDO: Vec3 = Vec3::new(0.80, 0.78, 0.74);

/// Diffuse albedo of the glossy bunny: the same hue, darker, so that the white
/// highlights stand out (glazed ceramic rather than chalk).
const GLOSSY_ALBEDO: Vec3 = Vec3::new(0.40, 0.39, 0.37);

/// Specular reflectance of the glossy bunny (white highlights).
const GLOSSY_SPECULAR: Vec3 = Vec3::splat(0.50);

/// Diffuse albedo of the ground (the ray-traced pictures' ground).
const GROUND_ALBEDO: Vec3 = Vec3::splat(0.5);

/// Display-space backdrop colours at the top and bottom of the pictures (seen
/// only above the ground's far edge).
const BACKDROP_TOP: Vec3 = Vec3::new(0.36, 0.38, 0.41);
const BACKDROP_BOTTOM: Vec3 = Vec3::new(0.17, 0.18, 0.19);

/// The bunny on its ground with the far mesh, the SH sky and the tables, built
/// once.
pub(super) struct HemiStage {
    /// The bunny followed by the ground, and the far mesh of both.
    pub lod: LodMesh,
    /// Vertices of the bunny: the first ones of `lod.full`.
    pub bunny_vertices: usize,
    /// Bounds of the bunny alone (the camera frames it; the twist is sized by it).
    pub bunny_bounds: Bounds,
    /// The sunrise's radiance in SH.
    pub lighting: ShRgb<COEFFICIENTS>,
    /// Transfer table, Phong lobe, half-space table.
    pub shader: Shader,
    /// The exposure every hemi picture uses, set by the diffuse picture.
    exposure: OnceCell<f32>,
}

impl HemiStage {
    /// Puts `bunny` on a ground and builds the far mesh, the SH projection of
    /// `sky` and the tables.
    pub fn new(bunny: TriangleMesh, sky: &EnvironmentMap) -> Result<Self> {
        let bunny_bounds = bunny.bounds();
        Ok(HemiStage {
            lod: on_ground(&bunny)?,
            bunny_vertices: bunny.vertex_count(),
            bunny_bounds,
            lighting: crate::hemi_shading::sky_lighting(sky)?,
            shader: Shader::new(),
            exposure: OnceCell::new(),
        })
    }

    /// The material every vertex is shaded with: unit albedo (each vertex's own
    /// albedo multiplies the diffuse part afterwards, see [`HemiStage::colors`])
    /// and, when `glossy`, the bunny's lobe seen from `eye`.
    pub fn material(&self, glossy: bool, eye: Vec3) -> Material<'_> {
        Material {
            albedo: Vec3::ONE,
            specular: if glossy { GLOSSY_SPECULAR } else { Vec3::ZERO },
            lobe: glossy.then(|| self.shader.lobe()),
            eye,
        }
    }

    /// Outgoing radiance of every vertex: its albedo times the diffuse part (the
    /// bunny's diffuse or glossy albedo, the ground's), plus the glossy part on
    /// the bunny only (the ground is matte).
    pub fn colors(&self, shading: &[VertexShading], glossy: bool) -> Vec<Vec3> {
        let albedo = if glossy {
            GLOSSY_ALBEDO
        } else {
            DIFFUSE_ALBEDO
        };
        shading
            .iter()
            .enumerate()
            .map(|(v, s)| {
                if v < self.bunny_vertices {
                    albedo * s.diffuse + s.glossy
                } else {
                    GROUND_ALBEDO * s.diffuse
                }
            })
            .collect()
    }

    /// Shades the rest pose (full mesh, exact masks) and returns the vertex
    /// radiance.
    pub fn shade_rest(&self, glossy: bool, eye: Vec3) -> Result<Vec<Vec3>> {
        let mut posed = Posed::new(&self.lod, Occluders::Full)?;
        let mut shading = vec![VertexShading::default(); self.lod.full.vertex_count()];
        posed.shade(
            &self.shader,
            self.shader.quality(false),
            &self.lighting,
            &self.material(glossy, eye),
            &mut shading,
        )?;
        Ok(self.colors(&shading, glossy))
    }

    /// The shared exposure: set from `frame` on the first call (auto exposure of
    /// its covered pixels, as the ray-traced pictures' whole-image exposure),
    /// returned unchanged afterwards.
    pub fn exposure(&self, frame: &Framebuffer) -> f32 {
        *self.exposure.get_or_init(|| {
            let covered: Vec<Vec3> = (0..frame.height())
                .flat_map(|y| (0..frame.width()).filter_map(move |x| frame.get(x, y)))
                .collect();
            auto_exposure(&HdrImage::from_pixels(covered.len(), 1, covered))
        })
    }
}

/// Draws a mesh with one linear radiance per vertex as seen by `camera`, at
/// `SUPERSAMPLING`² samples per pixel of a `width × height` picture.
pub(super) fn rasterize(
    camera: &Camera,
    positions: &[[f32; 3]],
    indices: &[u32],
    colors: &[Vec3],
    (width, height): (usize, usize),
) -> Framebuffer {
    let mut frame = Framebuffer::new(width * SUPERSAMPLING, height * SUPERSAMPLING);
    frame.draw_mesh(camera, positions, indices, colors);
    frame
}

/// The finished picture of a supersampled frame: tone-mapped with `exposure` (the
/// filmic curve, sRGB) over the backdrop, then box-filtered down in display space.
pub(crate) fn develop(frame: &Framebuffer, exposure: f32) -> HdrImage {
    let (wide, high) = (frame.width(), frame.height());
    let mut display = HdrImage::new(wide, high);
    for y in 0..high {
        let backdrop = BACKDROP_TOP.lerp(BACKDROP_BOTTOM, (y as f32 + 0.5) / high as f32);
        for x in 0..wide {
            let value = match frame.get(x, y) {
                Some(radiance) => Vec3::from_array(
                    (radiance * exposure)
                        .to_array()
                        .map(|c| linear_to_srgb(filmic(c))),
                ),
                None => backdrop,
            };
            display.set(x, y, value);
        }
    }
    display.downsample(wide / SUPERSAMPLING, high / SUPERSAMPLING)
}

/// Quantises a display-space image (values in `[0, 1]`) to 8 bits.
pub(crate) fn to_rgb8(display: &HdrImage) -> image::RgbImage {
    let mut out = image::RgbImage::new(display.width() as u32, display.height() as u32);
    for (pixel, value) in out.pixels_mut().zip(display.pixels()) {
        pixel.0 = value
            .to_array()
            .map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
    }
    out
}
