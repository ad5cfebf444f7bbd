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
//! The ground is what makes the contact shadows: it blocks the bunny's lower
//! hemisphere (the grass of the sunrise map) and receives the bunny's shadow at
//! its own vertices. It is a polar grid around the bunny whose rings grow
//! geometrically, fine under the bunny and coarse towards the horizon (where a
//! receiver sees the bunny as a speck), reaching far enough to fill the bottom of
//! the frame like the ray-traced pictures' plane. The far mesh is the bunny's
//! vertex clustering plus the ground as one square of two triangles: every
//! corner is far from every receiver, so it is always taken, and it is coplanar
//! with the fine ground (ground receivers see it on their horizon, culled; bunny
//! receivers see it cover the same directions as the fine ground).

use std::cell::OnceCell;

use antumbra_core::hemi::{Material, VertexShading};
use antumbra_core::sh::ShRgb;
use glam::Vec3;

use crate::bounds::Bounds;
use crate::camera::Camera;
use crate::envmap::EnvironmentMap;
use crate::error::Result;
use crate::hemi_shading::{
    COEFFICIENTS, FAR_CELL_OF_DIAGONAL, LodMesh, Occluders, Posed, Shader, simplify,
};
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

/// Segments around each ring of the ground grid.
const GROUND_SEGMENTS: u32 = 40;

/// Radius of the ground's innermost ring, of its outermost, and the growth from
/// one ring to the next, in units of the bunny's diagonal: rings about as far
/// apart as the segments are wide, from inside the bunny's footprint (a fan
/// covers the rest, hidden under the bunny) to beyond the horizon of the demo's
/// camera.
const GROUND_INNER_RADIUS: f32 = 0.12;
const GROUND_OUTER_RADIUS: f32 = 30.0;
const GROUND_GROWTH: f32 = 1.0 + std::f32::consts::TAU / GROUND_SEGMENTS as f32;

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
        let diagonal = bunny_bounds.diagonal();
        let far_cell = FAR_CELL_OF_DIAGONAL * diagonal;
        let far = with_square_ground(&simplify(&bunny, far_cell)?, &bunny_bounds)?;
        Ok(HemiStage {
            lod: LodMesh::with_far(with_ground(&bunny)?, far, far_cell, diagonal),
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

/// `bunny` standing on a polar ground grid at the bottom of its bounds (see the
/// module docs); the bunny's vertices and triangles come first.
pub(super) fn with_ground(bunny: &TriangleMesh) -> Result<TriangleMesh> {
    let bounds = bunny.bounds();
    let diagonal = bounds.diagonal();
    let (cx, y, cz) = (bounds.center().x, bounds.min.y, bounds.center().z);
    let mut positions = bunny.positions().to_vec();
    let mut indices = bunny.indices().to_vec();
    let center = positions.len() as u32;
    positions.push([cx, y, cz]);
    let segments = GROUND_SEGMENTS;
    let mut radius = GROUND_INNER_RADIUS * diagonal;
    let mut rings = 0u32;
    while radius <= GROUND_OUTER_RADIUS * diagonal {
        for s in 0..segments {
            let angle = std::f32::consts::TAU * s as f32 / segments as f32;
            positions.push([cx + radius * angle.cos(), y, cz + radius * angle.sin()]);
        }
        rings += 1;
        radius *= GROUND_GROWTH;
    }
    let ring = |r: u32, s: u32| center + 1 + r * segments + s % segments;
    // Counter-clockwise seen from above: normals +Y.
    for s in 0..segments {
        indices.extend([center, ring(0, s + 1), ring(0, s)]);
    }
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b) = (ring(r, s), ring(r, s + 1));
            let (c, d) = (ring(r + 1, s), ring(r + 1, s + 1));
            indices.extend([a, b, d, a, d, c]);
        }
    }
    TriangleMesh::new(format!("{} on a ground", bunny.name()), positions, indices)
}

/// `mesh` with a square of two triangles, `2 × GROUND_OUTER_RADIUS` bunny
/// diagonals wide, at the bottom of `bounds`, after its own vertices and triangles.
fn with_square_ground(mesh: &TriangleMesh, bounds: &Bounds) -> Result<TriangleMesh> {
    let half = GROUND_OUTER_RADIUS * bounds.diagonal();
    let (cx, y, cz) = (bounds.center().x, bounds.min.y, bounds.center().z);
    let mut positions = mesh.positions().to_vec();
    let mut indices = mesh.indices().to_vec();
    let base = positions.len() as u32;
    positions.extend([
        [cx - half, y, cz - half],
        [cx - half, y, cz + half],
        [cx + half, y, cz + half],
        [cx + half, y, cz - half],
    ]);
    // Counter-clockwise seen from above.
    indices.extend([0, 1, 2, 0, 2, 3].map(|k| base + k));
    TriangleMesh::new(mesh.name().to_string(), positions, indices)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ground_lies_flat_under_the_bunny_facing_up() {
        let bunny = crate::builtin::bunny().unwrap();
        let stage = with_ground(&bunny).unwrap();
        let n = bunny.vertex_count();
        assert_eq!(&stage.positions()[..n], bunny.positions());
        assert_eq!(&stage.indices()[..bunny.indices().len()], bunny.indices());
        let bottom = bunny.bounds().min.y;
        assert!(stage.positions()[n..].iter().all(|p| p[1] == bottom));
        let normals = stage.vertex_normals();
        assert!(normals[n..].iter().all(|v| (*v - Vec3::Y).length() < 1e-5));
        let reach = stage.bounds().size().x / bunny.bounds().diagonal();
        // The last ring is within one growth step of the outer radius.
        assert!(
            reach * GROUND_GROWTH >= 2.0 * GROUND_OUTER_RADIUS,
            "{reach}"
        );
    }
}
