//! Precomputed radiance transfer: one precomputation engine for diffuse PRT, glossy
//! SH transfer and matrix radiance transfer (Lehtinen, "A Framework for Precomputed
//! and Captured Light Transport", TOG 2007 = P1; Lehtinen & Kautz, "Matrix Radiance
//! Transfer", I3D 2003 = P2), PCA compression and a versioned bake file format.
//!
//! P1 writes precomputed transport as `m = M R (I − T_i)^{-1} V E`. Here the
//! emission `E` is distant lighting in `bands²` real SH coefficients (the
//! convention of [`crate::sh`], world frame), transport is ray casting through any
//! [`RayCaster`](crate::RayCaster) with `bounces` diffuse interreflections of
//! albedo `ρ`, and the measurement `M` is one of three configurations of the same
//! code path ([`Measurement`], [`bake`]):
//!
//! | kind                    | per vertex                         | meaning of one column `j` (lighting `Y_j`) |
//! |-------------------------|------------------------------------|--------------------------------------------|
//! | [`TransferKind::Diffuse`]  | `n = bands²` values `t_j`        | irradiance `∫_H L_in cos θ dω`; outgoing radiance is `albedo/π · Σ_j t_j l_j` |
//! | [`TransferKind::GlossySh`] | `n × n` matrix `T_ij`, row-major | world-frame SH coefficient `i` of incident radiance over the vertex's hemisphere (Sloan et al. 2002; zero below the horizon) |
//! | [`TransferKind::Mrt`]      | `G² × n` matrix, row = node      | outgoing radiance toward node `g`'s view direction for the baked [`Brdf`] |
//!
//! Lighting `l` is given as `bands²` RGB triples (`[[f32; 3]]`, coefficient-major);
//! [`lighting_from_sh_rgb`] converts an [`ShRgb`](crate::sh::ShRgb).
//!
//! Run time ([`shade`](TransferSet::shade), or the per-vertex kernels):
//! - diffuse: a dot product per channel ([`shade_diffuse`]);
//! - glossy SH (the 2002 baseline): with `r` the mirror of the view about the
//!   normal, `L_o = ρ_s Σ_i A_l(i) Y_i(r) (T l)_i`, `A_l` the Phong lobe's zonal
//!   factors ([`ZonalKernel::phong`](crate::sh::ZonalKernel::phong)), computed
//!   view-first as `(Tᵀ w) · l` with `w_i = A_l(i) Y_i(r)`: `n² + 3n` multiply-adds
//!   plus one basis evaluation ([`shade_glossy_sh`]); the published order, `T l`
//!   per channel then the lobe (`3n² + 3n`), is [`shade_glossy_sh_2002`], kept as
//!   the baseline benchmarks compare MRT with;
//! - MRT (P2 §3): view → vertex frame → hemi-octahedral cell ([`mrt_tap`]) → four
//!   rows blended bilinearly, dotted with the lighting: `7n` multiply-adds
//!   ([`shade_mrt`]);
//! - MRT from PCA (P2 §4): per frame `r_ck = U_ck · l` for each cluster's mean
//!   and `K` components ([`Pca::frame_terms`]), then per vertex `4 (K + 1)` RGB
//!   multiply-adds of its cluster's terms ([`shade_mrt_pca`]). `K` can be lowered
//!   at run time; clustering ([`cpca`]) costs only the per-frame products.
//!
//! MRT and glossy SH share the incident-radiance projection, so at node view
//! directions MRT with [`PhongBrdf`] equals the glossy SH result to quadrature
//! precision; between nodes the difference is the bilinear interpolation error
//! (measured in the tests, `mrt_matches_glossy_sh_within_interpolation_error`).
//!
//! ```
//! use antumbra_core::{BruteForceCaster, MeshView};
//! use antumbra_core::glam::Vec3;
//! use antumbra_core::transfer::{
//!     BakeOptions, Material, Measurement, PhongBrdf, TransferSet, View, bake,
//! };
//!
//! // A floor quad; any RayCaster over the same triangles works (BvhScene with `bvh`).
//! let positions = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
//! let indices = [0, 1, 2, 0, 2, 3];
//! let normals = [Vec3::Z; 4];
//! let mesh = MeshView::new(&positions, &indices)?;
//! let caster = BruteForceCaster::new(mesh);
//!
//! let brdf = PhongBrdf::new(16.0).unwrap();
//! let options = BakeOptions {
//!     bands: 3,
//!     rays: 64,
//!     ..BakeOptions::new(Measurement::Mrt { grid: 8, brdf: &brdf })
//! };
//! let set = bake(&mesh, &normals, &caster, &options)?;
//! let compressed = set.compress(2)?;
//!
//! // Save and load (validated), then relight: constant white sky, l_0 = 2√π.
//! let loaded = TransferSet::from_bytes(&compressed.to_bytes())?;
//! let mut lighting = [[0.0f32; 3]; 9];
//! lighting[0] = [2.0 * core::f32::consts::PI.sqrt(); 3];
//! let mut rgb = vec![[0.0f32; 3]; loaded.vertex_count()];
//! loaded.shade(&lighting, View::Eye([0.0, 0.5, 3.0]), &Material::glossy(1.0), None, &mut rgb)?;
//! // A normalised Phong lobe under unit radiance reflects 1; with 3 bands the SH
//! // projection of radiance that stops at the horizon overshoots near the normal
//! // (1.25 at the pole for the band-limited step), so expect 1.0 to 1.25.
//! assert!(rgb.iter().all(|c| c[0] > 1.0 && c[0] < 1.25));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Invariants: a bake is deterministic for a seed, and identical serial or parallel
//! (per-vertex random streams, [`rng`]); the vertex frame is
//! [`Frame::from_normal`](crate::Frame::from_normal) of the stored normal; shading
//! kernels allocate nothing; loading a file ([`TransferSet::from_bytes`], format in
//! [`format`]) validates everything and never panics or allocates more than the
//! input's length allows.
//!
//! ## Accuracy and cost
//!
//! Accuracy (`cargo test -p antumbra-core --all-features --lib transfer -- --nocapture`):
//!
//! - diffuse transfer, 0 bounces, 4 bands, 13 ground vertices around a floating box,
//!   against a brute-force midpoint quadrature of 320,000 directions per vertex:
//!   relative RMS error 10.4 % (64 rays), 3.12 % (256), 0.88 % (1,024), 0.30 %
//!   (4,096) — about 3.3× per 4× rays, better than Monte Carlo's 2× thanks to
//!   stratification;
//! - interreflection in a spherical cavity open to a uniform sky through a cap
//!   (area fraction 1/4, albedo 0.8; closed form `π f Σ_i (ρ(1−f))^i`): with the
//!   BVH on a 64-segment sphere at 256 rays the vertex mean is within +0.014 % (0
//!   bounces) and −0.11 % (2 bounces); on a coarse 32-segment sphere −0.34 % and
//!   −1.07 % (the facets' sag);
//! - MRT against glossy SH transfer from the same rays (5 bands, Phong `s = 8`,
//!   300 views per vertex): relative RMS 3.67 % at 8×8, 1.60 % at 12×12, 0.88 % at
//!   16×16 (the bilinear interpolation error, falling as `1/G²`); at the nodes the
//!   two agree to 1.7e-4 (quadrature of the BRDF matrix);
//! - PCA of 33 MRT matrices (6×6 grid, 3 bands, 324 values each): relative RMS
//!   error 51 % with the mean only, 25.7 % at K = 4, 13.2 % at K = 8, 3.5 % at
//!   K = 16, 0 at K = 32 (the data's rank); memory `4 (D (K + 1) + V K)` bytes
//!   ([`TransferSet::pca_levels`]).
//!
//! Cost: glossy SH grows as `n²` multiply-adds per vertex and MRT as `7n`, so
//! MRT gains with every band. MRT's per-vertex cost is dominated by a fixed part
//! rather than its multiply-adds: the view's tap (frame, hemi-octahedral cell)
//! and four rows read at view-dependent places (14 KB per vertex at 12×12 and 25
//! coefficients, so streamed from memory). The batch ([`TransferSet::shade`])
//! computes the taps of 32 vertices before reading rows, to overlap those
//! chains; the single-vertex kernel cannot. Per frame, PCA adds `C (K + 1)`
//! products of a `G² × n` matrix with the lighting (`C` clusters). A bake's time is mostly its rays, cast
//! through the caster it is given. Figures: `cargo bench -p antumbra-core
//! --features bvh --bench transfer` (kernels and batch shading, bake) and
//! `antumbra bench transfer` (the bake against obvhs and Embree casting the same
//! rays, [`bake_rays`]).

pub mod cpca;
mod engine;
pub mod format;
mod mrt;
mod pca;
pub mod rng;
mod shade;
mod texels;

#[cfg(test)]
mod tests;

use alloc::vec::Vec;
use core::fmt;

pub use engine::{
    BakePoint, BakeRay, BounceReads, MAX_BOUNCES, MAX_GRID, MAX_RAYS, bake, bake_point_range,
    bake_points, bake_rays, bake_serial, bake_vertices,
};
pub use format::FormatError;
pub use mrt::{
    Brdf, BrdfInfo, MrtTap, PhongBrdf, WardBrdf, hemi_oct_decode, hemi_oct_encode, mrt_tap,
    node_direction,
};
pub use pca::{Pca, PcaError, PcaLevel};
pub use shade::{
    GlossyLobe, Material, ShLighting, ShadeError, View, lighting_from_sh_rgb, shade_diffuse,
    shade_glossy_sh, shade_glossy_sh_2002, shade_glossy_sh_reference, shade_mrt, shade_mrt_pca,
    shade_mrt_reference,
};
pub use texels::{AtlasTexels, TexelsError};

/// Which measurement a transfer set holds (also its code in bake files).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum TransferKind {
    /// Diffuse transfer vectors, `bands²` values per vertex.
    Diffuse = 1,
    /// Glossy SH transfer matrices, `bands² × bands²` per vertex (world frame).
    GlossySh = 2,
    /// MRT matrices, `grid² × bands²` per vertex (vertex frame nodes).
    Mrt = 3,
}

impl TransferKind {
    /// The kind of a file code.
    pub fn from_code(code: u32) -> Option<Self> {
        match code {
            1 => Some(TransferKind::Diffuse),
            2 => Some(TransferKind::GlossySh),
            3 => Some(TransferKind::Mrt),
            _ => None,
        }
    }

    /// Values per vertex for `bands` and `grid` (`grid` ignored unless MRT);
    /// saturates at `usize::MAX` instead of overflowing.
    pub fn block_len(self, bands: u32, grid: u32) -> usize {
        let n = (bands as usize).saturating_mul(bands as usize);
        match self {
            TransferKind::Diffuse => n,
            TransferKind::GlossySh => n.saturating_mul(n),
            TransferKind::Mrt => (grid as usize)
                .saturating_mul(grid as usize)
                .saturating_mul(n),
        }
    }
}

/// The measurement a bake makes: the three PRT methods as configurations.
#[derive(Clone, Copy)]
pub enum Measurement<'a> {
    /// Diffuse transfer vector per vertex.
    Diffuse,
    /// Glossy SH transfer matrix per vertex (world frame).
    GlossySh,
    /// MRT matrix per vertex on a `grid × grid` hemi-octahedral bilinear basis
    /// (`2 ≤ grid ≤ MAX_GRID`) for the BRDF `brdf`.
    Mrt {
        /// Nodes per side.
        grid: u32,
        /// The BRDF's reflection kernel.
        brdf: &'a dyn Brdf,
    },
}

impl fmt::Debug for Measurement<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Measurement::Diffuse => f.write_str("Diffuse"),
            Measurement::GlossySh => f.write_str("GlossySh"),
            Measurement::Mrt { grid, brdf } => f
                .debug_struct("Mrt")
                .field("grid", grid)
                .field("brdf", &brdf.info())
                .finish(),
        }
    }
}

/// Progress callback: `(vertex passes done, total)`. With `parallel` it is called
/// from worker threads, and calls may arrive slightly out of order.
pub type Progress<'a> = &'a (dyn Fn(usize, usize) + Sync);

/// Everything a bake needs besides the mesh and the ray caster.
#[derive(Clone, Copy)]
pub struct BakeOptions<'a> {
    /// What to measure.
    pub measurement: Measurement<'a>,
    /// SH bands of the lighting (1 ..= [`MAX_BANDS`](crate::sh::MAX_BANDS)).
    pub bands: u32,
    /// Rays per vertex and pass (stratified; 1 ..= [`MAX_RAYS`]).
    pub rays: u32,
    /// Diffuse interreflection bounces (0 = shadowed direct light only).
    pub bounces: u32,
    /// Diffuse albedo of the scene for the bounces, in `[0, 1)`.
    pub albedo: f32,
    /// Ray origins are moved this far along the normal (world units), against
    /// self-intersection.
    pub ray_offset: f32,
    /// Seed of the random streams.
    pub seed: u64,
    /// Optional progress report.
    pub progress: Option<Progress<'a>>,
}

impl<'a> BakeOptions<'a> {
    /// Defaults: 4 bands, 256 rays, no bounces, albedo 0.5, offset 1e-4, seed 0.
    pub fn new(measurement: Measurement<'a>) -> Self {
        BakeOptions {
            measurement,
            bands: 4,
            rays: 256,
            bounces: 0,
            albedo: 0.5,
            ray_offset: 1e-4,
            seed: 0,
            progress: None,
        }
    }
}

impl fmt::Debug for BakeOptions<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("BakeOptions")
            .field("measurement", &self.measurement)
            .field("bands", &self.bands)
            .field("rays", &self.rays)
            .field("bounces", &self.bounces)
            .field("albedo", &self.albedo)
            .field("ray_offset", &self.ray_offset)
            .field("seed", &self.seed)
            .field("progress", &self.progress.is_some())
            .finish()
    }
}

/// Why a bake was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BakeError {
    /// `bands` outside `1..=MAX_BANDS`.
    Bands(u32),
    /// `rays` outside `1..=MAX_RAYS`.
    Rays(u32),
    /// `bounces` above [`MAX_BOUNCES`].
    Bounces(u32),
    /// `albedo` not in `[0, 1)`.
    Albedo(f32),
    /// `ray_offset` negative or not finite.
    RayOffset(f32),
    /// MRT `grid` outside `2..=MAX_GRID`.
    Grid(u32),
    /// The normal slice does not have one normal per vertex.
    NormalCount {
        /// Normals given.
        normals: usize,
        /// Vertices of the mesh.
        vertices: usize,
    },
    /// A normal is not finite and unit length (within 1e-3).
    Normal {
        /// Its vertex.
        index: usize,
    },
    /// More vertices than a file can address.
    TooManyVertices(usize),
    /// The mesh has no vertex, or [`bake_points`] was given no point (nothing to
    /// bake; a bake file holds at least one).
    NoVertices,
    /// The MRT BRDF's kernel gave a non-finite value, so its node matrix is not
    /// finite.
    BrdfNotFinite,
    /// The transfer data would not fit in memory (checked before any ray).
    TooLarge {
        /// Bytes of one of its buffers (`u64::MAX`: the size overflowed).
        bytes: u64,
    },
    /// A point of [`bake_points`] has a position that is not finite or a normal
    /// that is not unit length (within 1e-3).
    Point {
        /// The point.
        index: usize,
    },
    /// The vertex range of [`bake_vertices`] (or the point range of
    /// [`bake_point_range`]) is empty or reaches past the mesh (the points).
    VertexRange {
        /// First vertex asked for.
        start: usize,
        /// One past the last vertex asked for.
        end: usize,
        /// Vertices of the mesh.
        vertices: usize,
    },
}

impl fmt::Display for BakeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            BakeError::Bands(b) => write!(f, "bands = {b} is outside 1..=8"),
            BakeError::Rays(r) => write!(f, "rays = {r} is outside 1..={MAX_RAYS}"),
            BakeError::Bounces(b) => write!(f, "bounces = {b} is above {MAX_BOUNCES}"),
            BakeError::Albedo(a) => write!(f, "albedo = {a} is not in [0, 1)"),
            BakeError::RayOffset(o) => write!(f, "ray_offset = {o} is negative or not finite"),
            BakeError::Grid(g) => write!(f, "grid = {g} is outside 2..={MAX_GRID}"),
            BakeError::NormalCount { normals, vertices } => {
                write!(f, "{normals} normals given for {vertices} vertices")
            }
            BakeError::Normal { index } => {
                write!(f, "normals[{index}] is not a finite unit vector")
            }
            BakeError::TooManyVertices(n) => write!(f, "{n} vertices is more than 2^32 - 1"),
            BakeError::NoVertices => {
                f.write_str("the mesh has no vertices (or no points were given)")
            }
            BakeError::Point { index } => write!(
                f,
                "points[{index}] has a position that is not finite or a normal that is not a unit vector"
            ),
            BakeError::BrdfNotFinite => f.write_str("brdf.kernel returned a non-finite value"),
            BakeError::TooLarge { bytes } => write!(
                f,
                "the transfer data needs a buffer of {bytes} bytes, more than can be allocated \
                 (fewer vertices, bands or a smaller grid)"
            ),
            BakeError::VertexRange {
                start,
                end,
                vertices,
            } => write!(
                f,
                "entries {start}..{end} are not a non-empty range of the {vertices} vertices (or \
                 points) of the bake"
            ),
        }
    }
}

impl core::error::Error for BakeError {}

/// How a set was baked (recorded in files; shading does not depend on it except
/// through the data).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeInfo {
    /// Rays per vertex and pass.
    pub rays: u32,
    /// Interreflection bounces.
    pub bounces: u32,
    /// Scene albedo of the bounces.
    pub albedo: f32,
    /// The BRDF of an MRT set ([`BrdfInfo::CUSTOM`] otherwise).
    pub brdf: BrdfInfo,
}

/// The per-vertex data: dense blocks or their PCA.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Payload {
    Dense(Vec<f32>),
    Pca(Pca),
}

/// A baked transfer set: kind, band count, grid, per-vertex positions and normals
/// (the vertex frames are [`Frame::from_normal`](crate::Frame::from_normal) of the
/// normals) and the per-vertex blocks, dense or PCA-compressed.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferSet {
    pub(crate) kind: TransferKind,
    pub(crate) bands: u32,
    pub(crate) grid: u32,
    pub(crate) info: BakeInfo,
    pub(crate) positions: Vec<[f32; 3]>,
    pub(crate) normals: Vec<[f32; 3]>,
    /// [`Frame::from_normal`](crate::Frame::from_normal) of every normal, built
    /// once with the set so that shading does not rebuild a frame per vertex.
    pub(crate) frames: Vec<crate::Frame>,
    pub(crate) payload: Payload,
    /// For a texel bake, the lightmap texel of every entry.
    pub(crate) texels: Option<AtlasTexels>,
}

/// The texels of joined parts: none when no part has any, else the parts'
/// lists one after another, which must all be of one atlas and stay strictly
/// increasing.
fn join_texels(parts: &[TransferSet]) -> Result<Option<AtlasTexels>, ConcatError> {
    let Some(first) = parts.first().and_then(|p| p.texels.as_ref()) else {
        return match parts.iter().position(|p| p.texels.is_some()) {
            Some(index) => Err(ConcatError::Texels { index }),
            None => Ok(None),
        };
    };
    let mut texels: Vec<u32> = Vec::new();
    for (index, part) in parts.iter().enumerate() {
        let fits = part.texels.as_ref().filter(|t| {
            (t.width, t.height) == (first.width, first.height)
                && match (texels.last(), t.texels.first()) {
                    (Some(last), Some(next)) => next > last,
                    _ => true,
                }
        });
        let Some(part_texels) = fits else {
            return Err(ConcatError::Texels { index });
        };
        texels.extend_from_slice(&part_texels.texels);
    }
    Ok(Some(AtlasTexels {
        width: first.width,
        height: first.height,
        texels,
    }))
}

/// The vertex frames of unit normals (the bake's and the run time's).
pub(crate) fn frames_of(normals: &[[f32; 3]]) -> Vec<crate::Frame> {
    try_frames_of(normals).expect("memory for the vertex frames")
}

/// [`frames_of`], or the allocation's error (for loading with an allocator that
/// can run out).
pub(crate) fn try_frames_of(
    normals: &[[f32; 3]],
) -> Result<Vec<crate::Frame>, crate::fallible::OutOfMemory> {
    let mut frames = crate::fallible::with_capacity(normals.len())?;
    frames.extend(
        normals
            .iter()
            .map(|n| crate::Frame::from_normal(glam::Vec3::from_array(*n))),
    );
    Ok(frames)
}

/// Why [`TransferSet::concat`] refused its parts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConcatError {
    /// No part was given.
    Empty,
    /// Part `index` was baked differently from part 0 (kind, bands, grid, rays,
    /// bounces, albedo or BRDF).
    Settings {
        /// The part that differs.
        index: usize,
    },
    /// Part `index` is PCA-compressed; only dense parts are joined (compress the
    /// joined set).
    Compressed {
        /// The compressed part.
        index: usize,
    },
    /// Part `index` is a texel bake and part 0 is not (or the other way
    /// round), its atlas has another size, or its texels do not follow the
    /// previous part's (the parts of one lightmap, in order, do).
    Texels {
        /// The part that does not fit.
        index: usize,
    },
}

impl fmt::Display for ConcatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ConcatError::Empty => f.write_str("no part to join"),
            ConcatError::Settings { index } => write!(
                f,
                "part {index} was baked with other settings than part 0 (kind, bands, grid, \
                 rays, bounces, albedo or BRDF)"
            ),
            ConcatError::Compressed { index } => write!(
                f,
                "part {index} is PCA-compressed; join dense parts, then compress"
            ),
            ConcatError::Texels { index } => write!(
                f,
                "part {index} does not continue part 0's lightmap (a vertex bake beside a \
                 texel bake, another atlas size, or texels not after the previous part's)"
            ),
        }
    }
}

impl core::error::Error for ConcatError {}

impl TransferSet {
    /// The vertices of `parts`, in order, as one set: the whole bake when the parts
    /// are [`bake_vertices`] of consecutive ranges with the same options (or,
    /// for a lightmap, [`TexelAtlas::bake_part`](crate::lightmap::TexelAtlas::bake_part)
    /// of consecutive ranges of its receivers). The parts must be dense and
    /// baked alike, and either all per-vertex or all texels of one atlas.
    pub fn concat(parts: &[TransferSet]) -> Result<TransferSet, ConcatError> {
        let first = parts.first().ok_or(ConcatError::Empty)?;
        let mut data = Vec::new();
        for (index, part) in parts.iter().enumerate() {
            let alike = part.kind == first.kind
                && part.bands == first.bands
                && part.grid == first.grid
                && part.info == first.info;
            if !alike {
                return Err(ConcatError::Settings { index });
            }
            match &part.payload {
                Payload::Dense(d) => data.extend_from_slice(d),
                Payload::Pca(_) => return Err(ConcatError::Compressed { index }),
            }
        }
        let positions: Vec<[f32; 3]> = parts
            .iter()
            .flat_map(|p| p.positions.iter().copied())
            .collect();
        let normals: Vec<[f32; 3]> = parts
            .iter()
            .flat_map(|p| p.normals.iter().copied())
            .collect();
        let texels = join_texels(parts)?;
        Ok(TransferSet {
            kind: first.kind,
            bands: first.bands,
            grid: first.grid,
            info: first.info,
            frames: frames_of(&normals),
            positions,
            normals,
            payload: Payload::Dense(data),
            texels,
        })
    }

    /// The measurement held.
    pub fn kind(&self) -> TransferKind {
        self.kind
    }

    /// SH bands of the lighting.
    pub fn bands(&self) -> u32 {
        self.bands
    }

    /// Lighting coefficients, `bands²`.
    pub fn coeff_count(&self) -> usize {
        (self.bands * self.bands) as usize
    }

    /// MRT nodes per side (0 for the other kinds).
    pub fn grid(&self) -> u32 {
        self.grid
    }

    /// How the set was baked.
    pub fn info(&self) -> &BakeInfo {
        &self.info
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Values per vertex block ([`TransferKind::block_len`]).
    pub fn block_len(&self) -> usize {
        self.kind.block_len(self.bands, self.grid)
    }

    /// Vertex positions (world).
    pub fn positions(&self) -> &[[f32; 3]] {
        &self.positions
    }

    /// Unit vertex normals (world).
    pub fn normals(&self) -> &[[f32; 3]] {
        &self.normals
    }

    /// The dense block of `vertex` (layout in the [module docs](self)); `None` when
    /// compressed or out of range.
    pub fn vertex_block(&self, vertex: usize) -> Option<&[f32]> {
        match &self.payload {
            Payload::Dense(d) => {
                let len = self.block_len();
                d.get(vertex * len..(vertex + 1) * len)
            }
            Payload::Pca(_) => None,
        }
    }

    /// Every dense block, vertex after vertex; `None` when compressed.
    pub fn dense_data(&self) -> Option<&[f32]> {
        match &self.payload {
            Payload::Dense(d) => Some(d),
            Payload::Pca(_) => None,
        }
    }

    /// The PCA, when compressed.
    pub fn pca(&self) -> Option<&Pca> {
        match &self.payload {
            Payload::Pca(p) => Some(p),
            Payload::Dense(_) => None,
        }
    }

    /// Bytes of the per-vertex data (dense blocks, or mean + basis + weights).
    pub fn data_bytes(&self) -> usize {
        4 * match &self.payload {
            Payload::Dense(d) => d.len(),
            Payload::Pca(p) => p.value_count(),
        }
    }
}
