//! Per-texel receivers from a UV atlas: the texels of a lightmap that a mesh's
//! charts cover, each with a surface point and normal to bake from, and a
//! gutter so that bilinear filtering never reads an unbaked texel.
//!
//! Texel `(x, y)` of a `W × H` atlas is the square `u ∈ [x/W, (x+1)/W)`,
//! `v ∈ [y/H, (y+1)/H)`, its centre `((x + ½)/W, (y + ½)/H)`; row 0 is at
//! `v = 0`. Every vertex has a UV in `[0, 1]²`, and the charts (the triangles in
//! UV space) must not overlap.
//!
//! - A texel whose centre lies in a triangle's UV footprint is **covered**: its
//!   receiver is that triangle's point at the centre. The test is exact (integer
//!   edge functions on UVs snapped to 1/256 of a texel) with a fill rule on
//!   edges, so a centre on an edge between two triangles belongs to exactly one
//!   of them, and a centre two triangles claim is an overlap of charts: an error.
//! - A texel that a footprint overlaps but whose centre no triangle covers is
//!   **touched**: its receiver is the point, of the nearest such triangle, that is
//!   nearest the centre (measured in texels).
//! - **Gutter** texels, within [`AtlasOptions::gutter`] texels (8-neighbour
//!   steps) of a receiver's texel, read the nearest receiver's value; so a
//!   bilinear lookup at any UV inside a chart, which reads the four texels
//!   around it, reads only receivers and gutter with a gutter of at least 1.
//!
//! Receivers start on the surface; [`TexelAtlas::lift`] then moves each off it
//! and out of any geometry it starts inside (a texel under a box on a floor, or
//! across a thin wall), the classic lightmap leak.
//!
//! Cost: linear in the texels the triangles' UV boxes span, plus, for the lift,
//! eight short rays per receiver.

mod bake;
pub(crate) mod gutter;
mod lift;
mod raster;
#[cfg(test)]
mod tests;

use alloc::vec::Vec;

use glam::Vec3;

use crate::fallible::OutOfMemory;
use crate::geom::MeshView;

pub use lift::LiftOptions;

/// The largest atlas side [`TexelAtlas::new`] accepts (a 16k texture).
pub const MAX_ATLAS_SIDE: u32 = 16_384;

/// The largest number of texels (`W × H`) [`TexelAtlas::new`] accepts: an 8k
/// square, 256 MiB of per-texel indices.
pub const MAX_ATLAS_TEXELS: u64 = 1 << 26;

/// The largest gutter [`TexelAtlas::new`] accepts, in texels.
pub const MAX_GUTTER: u32 = 64;

/// How [`TexelAtlas::new`] lays receivers out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AtlasOptions {
    /// Atlas width in texels, `1..=MAX_ATLAS_SIDE`.
    pub width: u32,
    /// Atlas height in texels, `1..=MAX_ATLAS_SIDE`; `width × height` at most
    /// [`MAX_ATLAS_TEXELS`].
    pub height: u32,
    /// Texels of gutter around every chart, `0..=MAX_GUTTER`. Default 2: one
    /// keeps bilinear lookups inside charts on baked values, the second one
    /// level of mipmaps.
    pub gutter: u32,
}

impl AtlasOptions {
    /// A `width × height` atlas with the default gutter of 2 texels.
    pub fn new(width: u32, height: u32) -> Self {
        AtlasOptions {
            width,
            height,
            gutter: 2,
        }
    }
}

/// Why [`TexelAtlas::new`] refused its input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AtlasError {
    /// The width or height is 0 or above [`MAX_ATLAS_SIDE`], or their product is
    /// above [`MAX_ATLAS_TEXELS`].
    Resolution {
        /// The width asked for.
        width: u32,
        /// The height asked for.
        height: u32,
    },
    /// The gutter is above [`MAX_GUTTER`].
    Gutter {
        /// The gutter asked for.
        gutter: u32,
    },
    /// There is not one UV (or one normal) per vertex.
    Count {
        /// `"uvs"` or `"normals"`.
        argument: &'static str,
        /// The mesh's vertex count.
        expected: usize,
        /// The length given.
        found: usize,
    },
    /// A vertex's UV is not finite or lies outside `[0, 1]²`.
    UvOutOfRange {
        /// The vertex.
        vertex: usize,
    },
    /// A vertex's normal is not finite or is zero.
    Normal {
        /// The vertex.
        vertex: usize,
    },
    /// A triangle's UVs are collinear: it has no area in the atlas.
    DegenerateUv {
        /// The triangle.
        triangle: usize,
    },
    /// Two triangles cover the same texel centre: the charts overlap.
    Overlap {
        /// The triangle that covered the centre first.
        first: usize,
        /// The triangle that covered it again.
        second: usize,
        /// The texel `(x, y)`.
        texel: [u32; 2],
    },
    /// The per-texel arrays could not be allocated.
    OutOfMemory,
}

impl core::fmt::Display for AtlasError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            AtlasError::Resolution { width, height } => write!(
                f,
                "atlas resolution {width} x {height}: each side must be 1..={MAX_ATLAS_SIDE} \
                 and the texels at most {MAX_ATLAS_TEXELS}"
            ),
            AtlasError::Gutter { gutter } => {
                write!(f, "gutter {gutter}: it must be at most {MAX_GUTTER} texels")
            }
            AtlasError::Count {
                argument,
                expected,
                found,
            } => write!(
                f,
                "{argument}: {found} given, the mesh has {expected} vertices (one each)"
            ),
            AtlasError::UvOutOfRange { vertex } => write!(
                f,
                "uvs[{vertex}] is not finite or lies outside [0, 1] x [0, 1]"
            ),
            AtlasError::Normal { vertex } => {
                write!(f, "normals[{vertex}] is not finite or is zero")
            }
            AtlasError::DegenerateUv { triangle } => write!(
                f,
                "triangle {triangle} has collinear UVs: it has no area in the atlas"
            ),
            AtlasError::Overlap {
                first,
                second,
                texel: [x, y],
            } => write!(
                f,
                "triangles {first} and {second} both cover texel ({x}, {y}): the UV charts overlap"
            ),
            AtlasError::OutOfMemory => write!(f, "out of memory for the atlas's per-texel arrays"),
        }
    }
}

impl core::error::Error for AtlasError {}

impl From<OutOfMemory> for AtlasError {
    fn from(_: OutOfMemory) -> Self {
        AtlasError::OutOfMemory
    }
}

/// How a receiver's texel meets the charts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coverage {
    /// The texel's centre lies in the receiver's triangle.
    Centre,
    /// The triangle overlaps the texel, but no triangle holds its centre: the
    /// receiver is the triangle's point nearest the centre.
    Touched,
}

/// One texel's receiver: where its bake rays start and around which normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelReceiver {
    /// The texel `(x, y)`.
    pub texel: [u32; 2],
    /// The surface point (after [`TexelAtlas::lift`], moved off the surface and
    /// out of geometry).
    pub position: Vec3,
    /// The unit normal interpolated from the vertex normals (the triangle's own
    /// where they cancel), on the same side as the triangle's.
    pub normal: Vec3,
    /// The triangle the receiver lies on.
    pub triangle: u32,
    /// Barycentric weights of the triangle's second and third corners at the
    /// receiver (before the lift), as [`crate::Hit`]'s `u` and `v`.
    pub barycentric: [f32; 2],
    /// Centre or touched.
    pub coverage: Coverage,
    /// The world length of one texel on the receiver's triangle (the square
    /// root of its world area over its area in texels).
    pub texel_size: f32,
}

impl TexelReceiver {
    /// The texel's row-major index `y · width + x` in an atlas `width` texels
    /// wide (how a texel set and a bake file name it).
    pub fn texel_index(&self, width: u32) -> u32 {
        self.texel[1] * width + self.texel[0]
    }
}

/// The receivers of a lightmap over a mesh's UV atlas, and which receiver each
/// texel (receiver, gutter or empty) reads.
#[derive(Clone, Debug)]
pub struct TexelAtlas {
    width: u32,
    height: u32,
    gutter: u32,
    /// In texel order: row by row, from `(0, 0)`.
    receivers: Vec<TexelReceiver>,
    /// Per texel, row by row: the receiver it reads, or [`EMPTY`].
    reads: Vec<u32>,
    /// The mesh's UVs, for mapping hits to texels.
    uvs: Vec<[f32; 2]>,
}

/// A texel that reads no receiver.
const EMPTY: u32 = u32::MAX;

impl TexelAtlas {
    /// The receivers of `mesh` (one UV and one normal per vertex) in an atlas of
    /// `options`: see the module docs for which texels get one and where.
    /// Receivers lie on the surface; [`Self::lift`] moves them off it.
    ///
    /// Errors: [`AtlasError`], naming the resolution, gutter, count, vertex or
    /// triangles at fault; nothing is returned on error.
    pub fn new(
        mesh: &MeshView<'_>,
        uvs: &[[f32; 2]],
        normals: &[Vec3],
        options: &AtlasOptions,
    ) -> Result<Self, AtlasError> {
        let (width, height) = (options.width, options.height);
        if !(1..=MAX_ATLAS_SIDE).contains(&width)
            || !(1..=MAX_ATLAS_SIDE).contains(&height)
            || u64::from(width) * u64::from(height) > MAX_ATLAS_TEXELS
        {
            return Err(AtlasError::Resolution { width, height });
        }
        if options.gutter > MAX_GUTTER {
            return Err(AtlasError::Gutter {
                gutter: options.gutter,
            });
        }
        let vertices = mesh.vertex_count();
        for (argument, found) in [("uvs", uvs.len()), ("normals", normals.len())] {
            if found != vertices {
                return Err(AtlasError::Count {
                    argument,
                    expected: vertices,
                    found,
                });
            }
        }
        if let Some(vertex) = uvs
            .iter()
            .position(|uv| !uv.iter().all(|c| (0.0..=1.0).contains(c)))
        {
            return Err(AtlasError::UvOutOfRange { vertex });
        }
        if let Some(vertex) = normals
            .iter()
            .position(|n| !n.is_finite() || *n == Vec3::ZERO)
        {
            return Err(AtlasError::Normal { vertex });
        }
        let mut receivers = raster::receivers(mesh, uvs, normals, width, height)?;
        receivers.sort_unstable_by_key(|r| (r.texel[1], r.texel[0]));
        let texels = receivers.iter().map(|r| r.texel_index(width) as usize);
        let reads = gutter::reads(texels, width, height, options.gutter)?;
        Ok(TexelAtlas {
            width,
            height,
            gutter: options.gutter,
            receivers,
            reads,
            uvs: crate::fallible::copied(uvs)?,
        })
    }

    /// Atlas width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Atlas height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The gutter it was built with, in texels.
    pub fn gutter(&self) -> u32 {
        self.gutter
    }

    /// The receivers, in texel order (row by row).
    pub fn receivers(&self) -> &[TexelReceiver] {
        &self.receivers
    }

    /// The receiver texel `(x, y)` reads: its own, a gutter texel's nearest, or
    /// `None` for a texel outside the charts and the gutter (or outside the
    /// atlas).
    pub fn receiver_at(&self, x: u32, y: u32) -> Option<usize> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let read = self.reads[y as usize * self.width as usize + x as usize];
        (read != EMPTY).then_some(read as usize)
    }

    /// The receiver that the point of `triangle` (of the mesh the atlas was
    /// built from) with barycentric weights `u`, `v` of its second and third
    /// corners reads: that of the texel under the point's UV. This is how a
    /// texel bake's bounce reads the previous pass at a hit
    /// ([`crate::transfer::BounceReads::Points`]). `None` outside the mesh or
    /// the charts.
    pub fn receiver_at_hit(
        &self,
        mesh: &MeshView<'_>,
        triangle: usize,
        u: f32,
        v: f32,
    ) -> Option<usize> {
        if triangle >= mesh.triangle_count() {
            return None;
        }
        let [a, b, c] = mesh
            .triangle_indices(triangle)
            .map(|i| glam::Vec2::from(*self.uvs.get(i as usize).unwrap_or(&[f32::NAN; 2])));
        let uv = a * (1.0 - u - v) + b * u + c * v;
        let texel = |t: f32, side: u32| {
            let x = libm::floorf(t * side as f32);
            // NaN and points off the atlas read nothing; `v = 1` is the last row.
            (x >= 0.0 && x <= side as f32).then(|| (x as u32).min(side - 1))
        };
        self.receiver_at(texel(uv.x, self.width)?, texel(uv.y, self.height)?)
    }

    /// Fills `image` (`width × height` texels of `channels` values, row by row)
    /// from `values` (`channels` per receiver, in receiver order): each texel the
    /// value of the receiver it reads, gutter included; texels that read none are
    /// left as they are. `None` when a length does not match.
    pub fn expand(&self, values: &[f32], channels: usize, image: &mut [f32]) -> Option<()> {
        gutter::fill(&self.reads, self.receivers.len(), values, channels, image)
    }
}
