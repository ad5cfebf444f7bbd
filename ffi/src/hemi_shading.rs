//! Per-vertex transfer vectors and shading for C callers: every vertex of a mesh
//! that deforms every frame is a receiver shadowed by the mesh itself (and, beyond
//! a near radius, by a simplified far mesh), and gets its spherical-harmonic
//! transfer vector or its diffuse and glossy radiance under SH lighting (Kautz,
//! Lehtinen and Aila 2004; core's `hemi::lod`).
//!
//! Two ways in, with identical results bit for bit:
//!
//! - `antumbra_hemi_shader`: a handle created once per mesh topology and
//!   configuration, then called every frame with the current positions. It owns
//!   the per-frame memory (normals, staging), the triangle clusters that let a
//!   receiver skip whole groups of triangles below its horizon, and the cached
//!   glossy lobe, so a frame allocates nothing;
//! - `antumbra_hemi_transfer` / `antumbra_hemi_shade`: one-shot calls that
//!   allocate their scratch memory per call and read every triangle (no
//!   clusters); for tools and occasional use.
//!
//! The tables every configuration reads (the SH cell integrals per band count, the
//! byte lookup table, the half-space table) are built once per process on first
//! use and shared, read-only, by every handle and call.
//!
//! Why this split: the tables depend only on the band count and method, take
//! milliseconds to build and are immutable, so one shared instance per process
//! serves every mesh and thread (as the half-space table of
//! `antumbra_hemi_rasterize` already does). What depends on a mesh is its
//! topology: the grouping of its triangles into clusters (a sort, done once, whose
//! boxes are refreshed every frame so receivers skip clusters below their
//! horizon) and per-vertex scratch memory; plus the glossy lobe of the exponent in
//! use (4 KB, 80 µs to build). Those live in the shader, which therefore needs
//! exclusive access per call: an internal lock makes concurrent calls on one
//! shader wait rather than race, and `raster.parallel` spreads one call over
//! every core.
//!
//! Every result equals core's `transfer_batch` / `shade_batch_split` (and the
//! per-vertex `vertex_transfer` / `shade_vertex` they call) on the same inputs,
//! whichever thread computed it.

use alloc::boxed::Box;
use core::any::Any;
use core::ptr::NonNull;
#[cfg(feature = "std")]
use core::sync::atomic::AtomicBool;
use core::sync::atomic::Ordering;
#[cfg(feature = "std")]
use std::sync::{Mutex, PoisonError};

use antumbra_core::MeshView;
use antumbra_core::hemi::{
    BatchOptions, FarFieldSetup, FarMesh, FarMeshError, HemiShader, MAX_FAR_LEVELS, Material,
    PhongLobe, Quality, ReceiverSampling, ReceiverSamplingError, ShaderError, ShaderFrame,
    ShaderSetup, TransferLut, TransferMethod, TransferSpace, TransferTable, VertexSurface,
};
use antumbra_core::raycast::MAX_COORDINATE;
use antumbra_core::sh::{Sh, ShRgb};
use glam::Vec3;

#[cfg(feature = "std")]
use crate::boundary::check_not_poisoned;
use crate::boundary::guard;
use crate::error::Error;
use crate::fallible;
use crate::frame::UNIT_TOLERANCE;
#[cfg(feature = "std")]
use crate::hemi::shared_table;
use crate::hemi::{
    ANTUMBRA_HEMI_QUALITY_EXACT, DEFAULT_OPTIONS, antumbra_hemi_options, antumbra_hemi_table,
    check_coordinate_range, check_options, non_finite, worth_clustering,
};
use crate::mesh::{antumbra_mesh_view, mesh_from_c};
use crate::raw::{self, Span, Spans, check_disjoint};
use crate::result::*;
use crate::sh::ANTUMBRA_SH_MAX_BANDS;

/// `antumbra_hemi_shading_options.method`: the full per-cell sum of the exact cell
/// integrals (the recommended method, the default).
pub const ANTUMBRA_HEMI_METHOD_CELLS: u32 = 0;

/// `antumbra_hemi_shading_options.method`: the same sum by byte lookups of
/// pre-summed weights (equal to the per-cell sum up to float rounding). Its table
/// (1.2 MB at 3 bands, 8.4 MB at 8) is built on first use and kept until exit.
pub const ANTUMBRA_HEMI_METHOD_LUT: u32 = 1;

/// `antumbra_hemi_shading_options.method`: the paper's 4×4 block downsampling (an
/// 8×8 grid of coverage values); about 1 % from the full sum on average, 4 % at
/// worst (measured on the bunny). Diffuse only: the glossy term always sums cells.
pub const ANTUMBRA_HEMI_METHOD_DOWNSAMPLED: u32 = 2;

/// `antumbra_hemi_shading_options.space`: transfer vectors in world coefficients,
/// ready to dot with world-space lighting (the default).
pub const ANTUMBRA_HEMI_SPACE_WORLD: u32 = 0;

/// `antumbra_hemi_shading_options.space`: transfer vectors in each receiver's
/// local frame (tangent, bitangent, normal) of `antumbra_frame_from_normal`.
pub const ANTUMBRA_HEMI_SPACE_LOCAL: u32 = 1;

/// Options of the per-vertex entry points. Fill with
/// `antumbra_hemi_shading_options_init`, then change fields: fields may be added
/// at the end in later versions, and `options_init` keeps old code correct.
///
/// Layout: the 24-byte `antumbra_hemi_options` (20 on 32-bit targets), then six
/// 4-byte fields; 48 bytes on 64-bit targets, 44 on 32-bit, no padding.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct antumbra_hemi_shading_options {
    /// How the masks are rasterized: quality, back-face culling, normal offset,
    /// parallel (1: vertices are split across the library's worker threads;
    /// results are identical either way) and table, exactly as for
    /// `antumbra_hemi_rasterize`. A caller-owned table given here must outlive
    /// every shader created with these options.
    pub raster: antumbra_hemi_options,
    /// SH bands of the transfer vectors and the lighting: 1 to
    /// `ANTUMBRA_SH_MAX_BANDS` (8); `bands²` coefficients per vector. Default 3.
    pub bands: u32,
    /// How a mask becomes a transfer vector: `ANTUMBRA_HEMI_METHOD_CELLS` (0, the
    /// default), `ANTUMBRA_HEMI_METHOD_LUT` (1) or
    /// `ANTUMBRA_HEMI_METHOD_DOWNSAMPLED` (2). Every method costs well under a
    /// microsecond per vertex against tens for the mask itself.
    pub method: u32,
    /// The space of the vectors `antumbra_hemi_transfer` writes:
    /// `ANTUMBRA_HEMI_SPACE_WORLD` (0, the default) or `ANTUMBRA_HEMI_SPACE_LOCAL`
    /// (1). Shading always works in world space and ignores it.
    pub space: u32,
    /// With a far mesh: the distance from a receiver's vertex (not its lifted
    /// center of projection) within which occluders come from the full mesh. A
    /// full-mesh triangle is rasterized when at least one corner is within the
    /// radius (`|c - p|² <= near_radius²`), a far-mesh triangle when all its corners
    /// are beyond it, so the coarse surface never shadows the fine one near the
    /// receiver. Choose several far-mesh edge lengths. Mesh units, >= 0, or
    /// +INFINITY (the default). With a far mesh the caller passes, +INFINITY
    /// means the full mesh everywhere (the far mesh unused); with the library's
    /// own (`far_triangles` > 0) it means the library's rule: three edges of the
    /// far mesh's clustering cubes (`ANTUMBRA_HEMI_NEAR_CELLS`), so the coarse
    /// surface starts where its error is about a third of the distance; a
    /// finite radius must then be at least `ANTUMBRA_HEMI_MIN_NEAR_CELLS` cube
    /// edges (INVALID_ARGUMENT, with the least radius in the message, else).
    /// With several levels (`far_levels`) this is the first level's radius, and
    /// each further level's is twice the one before.
    /// Ignored without a far mesh.
    pub near_radius: f32,
    /// 0 (the default): no far mesh but the one a caller passes. Otherwise the
    /// library makes one of about this many triangles from the mesh, by vertex
    /// clustering (each far vertex the mean of the full vertices in a cube;
    /// cube edge searched for the count), and moves it with every frame's full
    /// positions, so a deforming mesh needs nothing else: a shader does this once
    /// at creation, a one-shot call in the call. Must be below the mesh's
    /// triangle count; with a caller's `far_mesh` it is INVALID_ARGUMENT. A few
    /// thousand suit meshes of 10k–100k triangles.
    pub far_triangles: u32,
    /// With the library's own far mesh (`far_triangles` > 0): how many far
    /// meshes it makes, 1 to `ANTUMBRA_HEMI_MAX_FAR_LEVELS` (8); 0, the default,
    /// means 1. The first has about `far_triangles` triangles; each further one
    /// clusters with cubes of twice the edge (about a quarter of the triangles)
    /// and is used beyond twice the radius of the one before (`near_radius`
    /// doubling from level to level), so a receiver rasterizes about as many far
    /// triangles per level, and the work per vertex grows with the logarithm of
    /// the mesh's size rather than its area. Levels coarser than 8 triangles are
    /// not made. What it trades: each level keeps its surface within about a
    /// third of the distance, but thin parts vanish sooner in the coarse
    /// levels, so the error grows with the first few levels and then settles
    /// (figures in docs/performance.md, from `antumbra bench hemi`). Must be 0
    /// or 1 without `far_triangles`.
    pub far_levels: u32,
}

/// The most far meshes `antumbra_hemi_shading_options.far_levels` asks for
/// (core's `MAX_FAR_LEVELS`).
pub const ANTUMBRA_HEMI_MAX_FAR_LEVELS: u32 = 8;

const _: () = assert!(ANTUMBRA_HEMI_MAX_FAR_LEVELS as usize == MAX_FAR_LEVELS);

/// The library's near radius with its own far mesh, in edges of the far mesh's
/// clustering cubes (`antumbra_hemi_shading_options.near_radius`; core's
/// `FarMesh::NEAR_CELLS`).
pub const ANTUMBRA_HEMI_NEAR_CELLS: f32 = 3.0;

/// The least near radius with the library's own far mesh, in edges of its
/// clustering cubes (√3, a cube's diagonal; core's `FarMesh::MIN_NEAR_CELLS`):
/// from a smaller radius the coarse triangles made from a receiver's own cube
/// count as distant and can pass over it.
pub const ANTUMBRA_HEMI_MIN_NEAR_CELLS: f32 = 1.732_050_8;

/// The widest spacing of a shader's key receivers, in mesh edges
/// (`antumbra_hemi_shader_set_receivers`; core's
/// `ReceiverSampling::MAX_SPACING`).
pub const ANTUMBRA_HEMI_MAX_RECEIVER_SPACING: u32 = 4;

const _: () = assert!(ANTUMBRA_HEMI_MAX_RECEIVER_SPACING == ReceiverSampling::MAX_SPACING);

const _: () = assert!(ANTUMBRA_HEMI_MIN_NEAR_CELLS == FarMesh::MIN_NEAR_CELLS);

/// The surface and viewer of `antumbra_hemi_shade`: a Lambertian term plus an
/// optional normalised modified Phong lobe about the mirror direction of the view
/// vector. Fill with `antumbra_hemi_material_init`, then change fields (fields may
/// be added at the end in later versions).
///
/// With incident radiance `L` (the lighting), visibility `V` (the mask), normal
/// `n` and `r` the mirror direction of the unit vector `v` from the vertex towards
/// the viewer (`r = 2 (n·v) n - v`), the outgoing radiance of a vertex is
///
/// - diffuse: `albedo/π ∫ L V max(0, n·ω) dω = albedo/π Σ_k T_k l_k`;
/// - glossy: `∫ L V f_r max(0, n·ω) dω` with
///   `f_r(ω) = specular (s + 2)/(2π) max(0, ω·r)^s` and `s = phong_exponent`, so a
///   viewer along the normal of an unoccluded vertex under unit radiance sees
///   exactly `specular`; 0 when the viewer is behind the surface or at the vertex.
///
/// Layout: ten floats (40 bytes), then two pointers; 56 bytes on 64-bit targets, 48
/// on 32-bit, no padding.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct antumbra_hemi_material {
    /// Diffuse albedo (linear RGB, finite, >= 0) of every vertex unless
    /// `vertex_albedo` is set. Default (1, 1, 1).
    pub albedo: [f32; 3],
    /// Specular reflectance `ρ_s` (linear RGB, finite, >= 0; at most 1 per channel
    /// conserves energy). (0, 0, 0), the default, turns the glossy term off.
    pub specular: [f32; 3],
    /// Phong exponent `s` of the glossy lobe (finite, >= 0). Default 16. The lobe is
    /// sampled once per mask cell (cells about 3.6° wide): exponents up to about 64
    /// are resolved well.
    pub phong_exponent: f32,
    /// The viewer's world position, used when `view_directions` is NULL. Finite,
    /// within ±1e12. Default (0, 0, 0).
    pub eye: [f32; 3],
    /// NULL (the default) or 3 floats per vertex of the mesh: the diffuse albedo of
    /// each vertex (finite, >= 0), replacing `albedo`. Borrowed for the call only.
    pub vertex_albedo: *const f32,
    /// NULL (the default: towards `eye` from each vertex) or 3 floats per vertex of
    /// the mesh: the unit direction from each vertex towards the viewer (finite,
    /// length within 1e-3 of 1), for orthographic or per-vertex views. Borrowed for
    /// the call only.
    pub view_directions: *const f32,
}

const DEFAULT_SHADING_OPTIONS: antumbra_hemi_shading_options = antumbra_hemi_shading_options {
    raster: DEFAULT_OPTIONS,
    bands: 3,
    method: ANTUMBRA_HEMI_METHOD_CELLS,
    space: ANTUMBRA_HEMI_SPACE_WORLD,
    near_radius: f32::INFINITY,
    far_triangles: 0,
    far_levels: 0,
};

const DEFAULT_EXPONENT: f32 = 16.0;

const DEFAULT_MATERIAL: antumbra_hemi_material = antumbra_hemi_material {
    albedo: [1.0; 3],
    specular: [0.0; 3],
    phong_exponent: DEFAULT_EXPONENT,
    eye: [0.0; 3],
    vertex_albedo: core::ptr::null(),
    view_directions: core::ptr::null(),
};

/// Writes the default shading options: the defaults of `antumbra_hemi_options_init`
/// in `raster` (exact quality, no back-face culling, normal offset 0, on the
/// calling thread, the shared table), 3 bands, the per-cell method, world space,
/// near radius +INFINITY, no far mesh of the library's (far_triangles 0).
///
/// @param options the options to fill; every field is written.
///
/// On a NULL or misaligned pointer nothing is written, and the thread's last error
/// message and the error callback report ANTUMBRA_RESULT_NULL_ARGUMENT or
/// ANTUMBRA_RESULT_INVALID_ARGUMENT.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `options` must be NULL or valid for writing one `antumbra_hemi_shading_options`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_shading_options_init(
    options: *mut antumbra_hemi_shading_options,
) {
    let _ = guard("antumbra_hemi_shading_options_init", || {
        raw::write_one(options, DEFAULT_SHADING_OPTIONS, "options")
    });
}

/// Writes the default material: albedo (1, 1, 1), no glossy term (specular 0),
/// Phong exponent 16, eye at the origin, no per-vertex albedo or view directions.
///
/// @param material the material to fill; every field is written.
///
/// On a NULL or misaligned pointer nothing is written, and the thread's last error
/// message and the error callback report ANTUMBRA_RESULT_NULL_ARGUMENT or
/// ANTUMBRA_RESULT_INVALID_ARGUMENT.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `material` must be NULL or valid for writing one `antumbra_hemi_material`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_material_init(material: *mut antumbra_hemi_material) {
    let _ = guard("antumbra_hemi_material_init", || {
        raw::write_one(material, DEFAULT_MATERIAL, "material")
    });
}

// ---------------------------------------------------------------------------
// Shared tables
// ---------------------------------------------------------------------------

/// Tables per band count, built on first use and kept until the process exits.
/// A slot holds the table of `bands = index + 1`, so the downcast cannot fail.
/// Racing first calls may each build a table; one is kept, the others dropped.
type Slots = [once_cell::race::OnceBox<Box<dyn Any + Send + Sync>>; ANTUMBRA_SH_MAX_BANDS as usize];

fn shared<T: Any + Send + Sync>(
    slots: &'static Slots,
    bands: usize,
    what: &str,
    build: impl FnOnce() -> Result<T, antumbra_core::fallible::OutOfMemory>,
) -> Result<&'static T, Error> {
    let slot = slots[bands - 1].get_or_try_init(|| {
        let table =
            build().map_err(|_| fallible::out_of_memory(what, core::mem::size_of::<T>()))?;
        let table: Box<dyn Any + Send + Sync> = fallible::boxed(table, what)?;
        fallible::boxed(table, what)
    })?;
    Ok(slot
        .downcast_ref::<T>()
        .expect("a table slot holds the table of its band count"))
}

/// The per-cell SH integrals for `N` coefficients (39 KB at 3 bands, 262 KB at 8;
/// measured 9 ms to build at 3 bands, 26 ms at 8).
fn transfer_table<const N: usize>() -> Result<&'static TransferTable<N>, Error> {
    static SLOTS: Slots =
        [const { once_cell::race::OnceBox::new() }; ANTUMBRA_SH_MAX_BANDS as usize];
    shared(
        &SLOTS,
        Sh::<N>::BANDS,
        "the shared transfer table",
        TransferTable::<N>::try_new,
    )
}

/// The byte lookup table for `N` coefficients.
fn transfer_lut<const N: usize>() -> Result<&'static TransferLut<N>, Error> {
    static SLOTS: Slots =
        [const { once_cell::race::OnceBox::new() }; ANTUMBRA_SH_MAX_BANDS as usize];
    let table = transfer_table::<N>()?;
    shared(
        &SLOTS,
        Sh::<N>::BANDS,
        "the shared transfer lookup table",
        || TransferLut::try_new(table.clone()),
    )
}

fn transfer_method<const N: usize>(method: u32) -> Result<TransferMethod<'static, N>, Error> {
    Ok(match method {
        ANTUMBRA_HEMI_METHOD_LUT => TransferMethod::Lut(transfer_lut::<N>()?),
        ANTUMBRA_HEMI_METHOD_DOWNSAMPLED => TransferMethod::Downsampled(transfer_table::<N>()?),
        _ => TransferMethod::Cells(transfer_table::<N>()?),
    })
}

/// Calls `$f::<N>($args)` with the coefficient count of `$bands` (1 to 8).
macro_rules! with_coefficients {
    ($bands:expr, $f:ident ( $($args:expr),* )) => {
        match $bands {
            1 => $f::<1>($($args),*),
            2 => $f::<4>($($args),*),
            3 => $f::<9>($($args),*),
            4 => $f::<16>($($args),*),
            5 => $f::<25>($($args),*),
            6 => $f::<36>($($args),*),
            7 => $f::<49>($($args),*),
            8 => $f::<64>($($args),*),
            _ => unreachable!("bands checked to be 1 to 8"),
        }
    };
}

/// Builds the tables a configuration reads, so that later calls only read them.
#[cfg(feature = "std")]
fn prepare_tables<const N: usize>(config: &Config) -> Result<(), Error> {
    transfer_method::<N>(config.method).map(|_| ())
}

// ---------------------------------------------------------------------------
// Validated configuration
// ---------------------------------------------------------------------------

/// A caller-owned half-space table kept by a shader between calls.
#[derive(Clone, Copy, Debug)]
struct UserTable(NonNull<antumbra_hemi_table>);

impl UserTable {
    /// Marks the table poisoned (after a panic while it was in use).
    ///
    /// # Safety
    /// The table must still be alive (the caller's contract).
    unsafe fn poison(self) {
        // SAFETY: alive by the caller's contract.
        unsafe { self.0.as_ref() }
            .poisoned
            .store(true, Ordering::Release);
    }
}

// SAFETY: the table is `Send + Sync` (asserted in hemi.rs) and only read; the
// caller promises it outlives every shader that holds it.
unsafe impl Send for UserTable {}
// SAFETY: as above.
unsafe impl Sync for UserTable {}

#[derive(Clone, Copy, Debug)]
enum HalfSpace {
    Exact,
    Shared,
    User(UserTable),
}

/// Validated options.
#[derive(Clone, Copy, Debug)]
struct Config {
    bands: usize,
    method: u32,
    space: TransferSpace,
    near_radius: f32,
    /// Triangles of the library's own far mesh; 0 for none.
    far_triangles: usize,
    /// Levels of the library's own far field (at least 1).
    far_levels: usize,
    cull_backfaces: bool,
    normal_offset: f32,
    parallel: bool,
    half_space: HalfSpace,
}

impl Config {
    /// The half-space quality for one call; rejects a poisoned user table.
    ///
    /// # Safety
    /// A user table must still be alive (the caller's contract).
    unsafe fn quality(&self) -> Result<Quality<'_>, Error> {
        Ok(match self.half_space {
            HalfSpace::Exact => Quality::Exact,
            #[cfg(feature = "std")]
            HalfSpace::Shared => Quality::Table(shared_table()?),
            // `check_options` refuses the table quality in the bare-metal build.
            #[cfg(not(feature = "std"))]
            HalfSpace::Shared => Quality::Exact,
            HalfSpace::User(UserTable(table)) => {
                // SAFETY: alive by the caller's contract.
                let table = unsafe { table.as_ref() };
                if table.poisoned.load(Ordering::Acquire) {
                    return Err(Error::new(
                        ANTUMBRA_RESULT_POISONED,
                        "the caller-owned table of options->raster.table was poisoned by an \
                         earlier internal error; destroy it",
                    ));
                }
                Quality::Table(&table.table)
            }
        })
    }

    /// The caller-owned table, if any, to poison after a panic.
    fn user_table(&self) -> Option<UserTable> {
        match self.half_space {
            HalfSpace::User(table) => Some(table),
            _ => None,
        }
    }

    fn batch_options<'t>(&self, quality: Quality<'t>) -> BatchOptions<'t> {
        BatchOptions {
            quality,
            cull_backfaces: self.cull_backfaces,
            normal_offset: self.normal_offset,
            parallel: self.parallel,
        }
    }
}

/// Checks every field of `options` (the defaults when NULL).
///
/// # Safety
/// `options` must be NULL or point to a valid struct whose `raster.table` is NULL
/// or a live table.
unsafe fn read_shading_options(
    options: *const antumbra_hemi_shading_options,
) -> Result<Config, Error> {
    let options = if options.is_null() {
        DEFAULT_SHADING_OPTIONS
    } else {
        // SAFETY: non-NULL, so by contract a valid options struct.
        *unsafe { raw::reference(options, "options") }?
    };
    // SAFETY: forwarded contract on the table.
    let user_table = unsafe { check_options(&options.raster, "options->raster.") }?;
    if !(1..=ANTUMBRA_SH_MAX_BANDS).contains(&options.bands) {
        return Err(Error::invalid(message!(
            "options->bands is {}; expected 1 to {ANTUMBRA_SH_MAX_BANDS}",
            options.bands
        )));
    }
    if options.method > ANTUMBRA_HEMI_METHOD_DOWNSAMPLED {
        return Err(Error::invalid(message!(
            "options->method is {}; expected ANTUMBRA_HEMI_METHOD_CELLS (0), \
             ANTUMBRA_HEMI_METHOD_LUT (1) or ANTUMBRA_HEMI_METHOD_DOWNSAMPLED (2)",
            options.method
        )));
    }
    let space = match options.space {
        ANTUMBRA_HEMI_SPACE_WORLD => TransferSpace::World,
        ANTUMBRA_HEMI_SPACE_LOCAL => TransferSpace::Local,
        s => {
            return Err(Error::invalid(message!(
                "options->space is {s}; expected ANTUMBRA_HEMI_SPACE_WORLD (0) or \
                 ANTUMBRA_HEMI_SPACE_LOCAL (1)"
            )));
        }
    };
    let radius = options.near_radius;
    if radius.is_nan() {
        return Err(Error::new(
            ANTUMBRA_RESULT_NON_FINITE,
            "options->near_radius is NaN",
        ));
    }
    if radius < 0.0 {
        return Err(Error::invalid(message!(
            "options->near_radius is {radius}; it must be >= 0 (+INFINITY: the full mesh \
             everywhere)"
        )));
    }
    if options.far_levels > ANTUMBRA_HEMI_MAX_FAR_LEVELS {
        return Err(Error::invalid(message!(
            "options->far_levels is {}; expected 0 to ANTUMBRA_HEMI_MAX_FAR_LEVELS \
             ({ANTUMBRA_HEMI_MAX_FAR_LEVELS})",
            options.far_levels
        )));
    }
    if options.far_levels > 1 && options.far_triangles == 0 {
        return Err(Error::invalid(message!(
            "options->far_levels is {} but options->far_triangles is 0: levels are of the \
             library's own far mesh; set far_triangles, or far_levels to 0",
            options.far_levels
        )));
    }
    let half_space = match (options.raster.quality, user_table) {
        (ANTUMBRA_HEMI_QUALITY_EXACT, _) => HalfSpace::Exact,
        (_, Some(table)) => HalfSpace::User(UserTable(NonNull::from(table))),
        (_, None) => HalfSpace::Shared,
    };
    Ok(Config {
        bands: options.bands as usize,
        method: options.method,
        space,
        near_radius: radius,
        far_triangles: options.far_triangles as usize,
        far_levels: options.far_levels.max(1) as usize,
        cull_backfaces: options.raster.cull_backfaces == 1,
        normal_offset: options.raster.normal_offset,
        parallel: options.raster.parallel == 1,
        half_space,
    })
}

// ---------------------------------------------------------------------------
// Validated per-call inputs
// ---------------------------------------------------------------------------

/// The memory a mesh view reads.
fn mesh_spans(
    view: &antumbra_mesh_view,
    positions: &'static str,
    indices: &'static str,
) -> [Option<Span>; 2] {
    let stride = if view.position_stride == 0 {
        12
    } else {
        view.position_stride
    };
    let bytes = match view.vertex_count {
        0 => 0,
        n => (n - 1) * stride + 12,
    };
    [
        Span::of(positions, view.positions.cast::<u8>(), bytes),
        Span::of(indices, view.indices, 3 * view.triangle_count),
    ]
}

/// The meshes and normals of one frame, validated.
struct FrameInput<'a> {
    mesh: MeshView<'a>,
    far: Option<MeshView<'a>>,
    /// 3 floats per vertex, each finite and unit length or exactly zero.
    normals: Option<&'a [f32]>,
    /// The caller memory read, for the overlap checks.
    spans: Spans,
}

/// Validates the mesh (every vertex a receiver), the optional far mesh and the
/// optional normals.
///
/// # Safety
/// The pointers must be NULL or valid for what they describe, for `'a`.
unsafe fn read_frame<'a>(
    mesh: *const antumbra_mesh_view,
    normals: *const f32,
    far_mesh: *const antumbra_mesh_view,
) -> Result<FrameInput<'a>, Error> {
    // SAFETY: caller contract on `mesh`.
    let view = unsafe { raw::reference(mesh, "mesh") }?;
    // SAFETY: caller contract on the arrays inside `mesh`.
    let core_mesh = unsafe { mesh_from_c(view, "mesh") }?;
    // Every vertex is a receiver, so every position must be in range, not only
    // those used by triangles.
    if let Some(vertex) = (0..core_mesh.vertex_count())
        .find(|&v| core_mesh.position(v).abs().max_element() > MAX_COORDINATE)
    {
        return Err(Error::invalid(message!(
            "mesh->positions: vertex {vertex} has a coordinate beyond the supported range of \
             ±{MAX_COORDINATE:e}"
        )));
    }
    let mut spans = Spans::default();
    for span in mesh_spans(view, "mesh->positions", "mesh->indices") {
        spans.push(span);
    }
    let far = if far_mesh.is_null() {
        None
    } else {
        // SAFETY: non-NULL, so by contract a valid view.
        let far_view = unsafe { raw::reference(far_mesh, "far_mesh") }?;
        // SAFETY: caller contract on the arrays inside `far_mesh`.
        let far = unsafe { mesh_from_c(far_view, "far_mesh") }?;
        check_coordinate_range(&far, "far_mesh")?;
        for span in mesh_spans(far_view, "far_mesh->positions", "far_mesh->indices") {
            spans.push(span);
        }
        Some(far)
    };
    let vertex_count = core_mesh.vertex_count();
    let normals = if normals.is_null() {
        None
    } else {
        let xyz = raw::element_count(vertex_count, 3, "mesh->vertex_count")?;
        // SAFETY: caller contract on `normals`.
        let normals = unsafe { raw::slice(normals, xyz, "normals") }?;
        for v in 0..vertex_count {
            let n = Vec3::from_slice(&normals[3 * v..]);
            if !n.is_finite() {
                return Err(non_finite("normals", v, n));
            }
            let length = n.length();
            if n != Vec3::ZERO && (length - 1.0).abs() > UNIT_TOLERANCE {
                return Err(Error::invalid(message!(
                    "normals[{v}] has length {length}, neither 1 (tolerance {UNIT_TOLERANCE}) \
                     nor exactly 0"
                )));
            }
        }
        spans.push(Span::of("normals", normals.as_ptr(), normals.len()));
        Some(normals)
    };
    Ok(FrameInput {
        mesh: core_mesh,
        far,
        normals,
        spans,
    })
}

/// A validated material.
struct MaterialInput<'a> {
    albedo: Vec3,
    specular: Vec3,
    exponent: f32,
    eye: Vec3,
    vertex_albedo: Option<&'a [f32]>,
    view_directions: Option<&'a [f32]>,
}

impl MaterialInput<'_> {
    fn glossy(&self) -> bool {
        self.specular != Vec3::ZERO
    }
}

fn check_reflectance(value: [f32; 3], argument: impl core::fmt::Display) -> Result<Vec3, Error> {
    let v = Vec3::from(value);
    if !v.is_finite() {
        return Err(Error::new(
            ANTUMBRA_RESULT_NON_FINITE,
            message!("{argument} ({}, {}, {}) is not finite", v.x, v.y, v.z),
        ));
    }
    if v.min_element() < 0.0 {
        return Err(Error::invalid(message!(
            "{argument} ({}, {}, {}) has a negative channel",
            v.x,
            v.y,
            v.z
        )));
    }
    Ok(v)
}

/// # Safety
/// `material` must be NULL or valid, its arrays NULL or valid for 3 floats per
/// vertex, for `'a`.
unsafe fn read_material<'a>(
    material: *const antumbra_hemi_material,
    vertex_count: usize,
    spans: &mut Spans,
) -> Result<MaterialInput<'a>, Error> {
    // SAFETY: caller contract; copied at once, so it may share memory with outputs.
    let m = *unsafe { raw::reference(material, "material") }?;
    let albedo = check_reflectance(m.albedo, "material->albedo")?;
    let specular = check_reflectance(m.specular, "material->specular")?;
    let exponent = m.phong_exponent;
    if !exponent.is_finite() {
        return Err(Error::new(
            ANTUMBRA_RESULT_NON_FINITE,
            message!("material->phong_exponent is {exponent}; it must be finite"),
        ));
    }
    if exponent < 0.0 {
        return Err(Error::invalid(message!(
            "material->phong_exponent is {exponent}; it must be >= 0"
        )));
    }
    let eye = Vec3::from(m.eye);
    if !eye.is_finite() {
        return Err(Error::new(
            ANTUMBRA_RESULT_NON_FINITE,
            message!(
                "material->eye ({}, {}, {}) is not finite",
                eye.x,
                eye.y,
                eye.z
            ),
        ));
    }
    if eye.abs().max_element() > MAX_COORDINATE {
        return Err(Error::invalid(message!(
            "material->eye ({}, {}, {}) is beyond the supported range of ±{MAX_COORDINATE:e}",
            eye.x,
            eye.y,
            eye.z
        )));
    }
    let xyz = raw::element_count(vertex_count, 3, "mesh->vertex_count")?;
    let vertex_albedo = if m.vertex_albedo.is_null() {
        None
    } else {
        // SAFETY: caller contract on the array.
        let a = unsafe { raw::slice(m.vertex_albedo, xyz, "material->vertex_albedo") }?;
        for v in 0..vertex_count {
            let rgb = [a[3 * v], a[3 * v + 1], a[3 * v + 2]];
            check_reflectance(rgb, format_args!("material->vertex_albedo[{v}]"))?;
        }
        spans.push(Span::of("material->vertex_albedo", a.as_ptr(), a.len()));
        Some(a)
    };
    let view_directions = if m.view_directions.is_null() {
        None
    } else {
        // SAFETY: caller contract on the array.
        let d = unsafe { raw::slice(m.view_directions, xyz, "material->view_directions") }?;
        for v in 0..vertex_count {
            let direction = Vec3::from_slice(&d[3 * v..]);
            if !direction.is_finite() {
                return Err(non_finite("material->view_directions", v, direction));
            }
            let length = direction.length();
            if (length - 1.0).abs() > UNIT_TOLERANCE {
                return Err(Error::invalid(message!(
                    "material->view_directions[{v}] has length {length}, not 1 (tolerance \
                     {UNIT_TOLERANCE})"
                )));
            }
        }
        spans.push(Span::of("material->view_directions", d.as_ptr(), d.len()));
        Some(d)
    };
    Ok(MaterialInput {
        albedo,
        specular,
        exponent,
        eye,
        vertex_albedo,
        view_directions,
    })
}

/// `3 * bands²` finite floats: the red coefficients, then green, then blue.
///
/// # Safety
/// `lighting` must be NULL or valid for `3 * bands²` floats for `'a`.
unsafe fn read_lighting<'a>(
    lighting: *const f32,
    bands: usize,
    spans: &mut Spans,
) -> Result<&'a [f32], Error> {
    let count = bands * bands;
    if lighting.is_null() {
        return Err(Error::null("lighting"));
    }
    // SAFETY: caller contract.
    let l = unsafe { raw::slice(lighting, 3 * count, "lighting") }?;
    if let Some(i) = l.iter().position(|c| !c.is_finite()) {
        return Err(Error::new(
            ANTUMBRA_RESULT_NON_FINITE,
            message!(
                "lighting[{i}] (channel {}, coefficient {}) is {}; it must be finite",
                ["red", "green", "blue"][i / count],
                i % count,
                l[i]
            ),
        ));
    }
    spans.push(Span::of("lighting", l.as_ptr(), l.len()));
    Ok(l)
}

fn lighting_rgb<const N: usize>(l: &[f32]) -> ShRgb<N> {
    let channel = |c: usize| Sh::new(core::array::from_fn(|k| l[c * N + k]));
    ShRgb::from_channels([channel(0), channel(1), channel(2)])
}

// ---------------------------------------------------------------------------
// The per-frame work
// ---------------------------------------------------------------------------

/// Memory reused from frame to frame: core's shader (clusters, far field,
/// normals and shading buffers) and the glossy lobe of the last exponent used
/// (4 KB; a shader allocates it at creation and rebuilds it in place when the
/// exponent changes; one-shot calls build the one they need).
struct Workspace {
    shader: HemiShader,
    lobe: Option<Box<PhongLobe>>,
}

impl Workspace {
    /// Core's shader for `config` and this frame's meshes, after the checks
    /// only the C API makes (a caller's far mesh together with `far_triangles`,
    /// `far_triangles` in the bare-metal build).
    fn new(
        config: &Config,
        input: &FrameInput<'_>,
        clusters: bool,
        shading: bool,
        exponent: Option<f32>,
    ) -> Result<Self, Error> {
        let setup = ShaderSetup {
            clusters,
            far_field: far_field_setup(config, input)?,
            near_radius: config.near_radius,
            shading,
            receivers: None,
        };
        let shader = HemiShader::new(&input.mesh, input.far.as_ref(), &setup)
            .map_err(|e| shader_error(config, input, e))?;
        let lobe = match exponent {
            Some(s) => Some(fallible::boxed(
                PhongLobe::new(s).expect("a checked exponent"),
                "a Phong lobe",
            )?),
            None => None,
        };
        Ok(Workspace { shader, lobe })
    }

    /// This frame: everything posed from `input`'s meshes, the normals filled.
    fn frame<'a>(
        &'a mut self,
        config: &Config,
        input: &FrameInput<'a>,
    ) -> Result<(ShaderFrame<'a>, &'a mut Option<Box<PhongLobe>>), Error> {
        let vertex_count = input.mesh.vertex_count();
        let normals = input
            .normals
            .map(|n| bytemuck::cast_slice::<f32, [f32; 3]>(&n[..3 * vertex_count]));
        let frame = self
            .shader
            .frame(input.mesh, normals, input.far)
            .map_err(|e| shader_error(config, input, e))?;
        Ok((frame, &mut self.lobe))
    }
}

/// The C message of a shader error (the arguments were checked before, so only
/// the far field and memory are expected to fail here).
fn shader_error(config: &Config, input: &FrameInput<'_>, e: ShaderError) -> Error {
    match e {
        ShaderError::FarField(FarMeshError::NearRadius { radius, minimum }) => {
            Error::invalid(message!(
                "options->near_radius is {radius}; with the library's far mesh \
                 (far_triangles {}) it must be at least {minimum}, \
                 ANTUMBRA_HEMI_MIN_NEAR_CELLS edges of its clustering cubes, or +INFINITY \
                 for the library's rule",
                config.far_triangles
            ))
        }
        ShaderError::FarField(e) => Error::invalid(message!(
            "options->far_triangles is {}: {e}",
            config.far_triangles
        )),
        ShaderError::OutOfMemory { what, bytes } => Error::new(
            ANTUMBRA_RESULT_OUT_OF_MEMORY,
            message!(
                "no memory for {what} of {} vertices ({bytes} bytes)",
                input.mesh.vertex_count()
            ),
        ),
        ShaderError::Receivers(ReceiverSamplingError::OutOfMemory { bytes }) => Error::new(
            ANTUMBRA_RESULT_OUT_OF_MEMORY,
            message!(
                "no memory for the receiver sampling of {} vertices ({bytes} bytes)",
                input.mesh.vertex_count()
            ),
        ),
        e => Error::invalid(message!("{e}")),
    }
}

/// The library's far field that `config.far_triangles` asks for, if any
/// (refused together with a caller's far mesh, and in the bare-metal build).
fn far_field_setup(
    config: &Config,
    input: &FrameInput<'_>,
) -> Result<Option<FarFieldSetup>, Error> {
    if config.far_triangles == 0 {
        return Ok(None);
    }
    if input.far.is_some() {
        return Err(Error::invalid(message!(
            "far_mesh is given together with options->far_triangles = {}; pass one or the \
             other (0 far triangles to use the caller's far mesh)",
            config.far_triangles
        )));
    }
    // Simplification allocates in ways the bare-metal build cannot report yet;
    // there a far mesh comes from the caller.
    if cfg!(not(feature = "std")) {
        // The count is checked as the hosted build checks it, so that bad input
        // gets the same code in both builds.
        let available = input.mesh.triangle_count();
        if config.far_triangles >= available {
            return Err(Error::invalid(message!(
                "options->far_triangles is {}: {}",
                config.far_triangles,
                antumbra_core::hemi::FarMeshError::TriangleCount {
                    requested: config.far_triangles,
                    available,
                }
            )));
        }
        return Err(Error::new(
            ANTUMBRA_RESULT_UNSUPPORTED,
            message!(
                "options->far_triangles is {}, but the bare-metal build does not simplify \
                 meshes; pass a far mesh of your own",
                config.far_triangles
            ),
        ));
    }
    Ok(Some(FarFieldSetup {
        triangles: config.far_triangles,
        levels: config.far_levels,
    }))
}

fn transfer_frame<const N: usize>(
    workspace: &mut Workspace,
    config: &Config,
    quality: Quality<'_>,
    input: &FrameInput<'_>,
    out: &mut [f32],
) -> Result<(), Error> {
    let method = transfer_method::<N>(config.method)?;
    let options = config.batch_options(quality);
    let (mut frame, _) = workspace.frame(config, input)?;
    let out = bytemuck::cast_slice_mut::<f32, [f32; N]>(out);
    frame
        .transfer(&options, method, config.space, out)
        .expect("the output holds one vector per vertex");
    Ok(())
}

/// Where the shaded colours go; each NULL when not wanted.
struct Outputs {
    rgb: *mut f32,
    diffuse: *mut f32,
    glossy: *mut f32,
}

fn shade_frame<const N: usize>(
    workspace: &mut Workspace,
    config: &Config,
    quality: Quality<'_>,
    input: &FrameInput<'_>,
    lighting: &[f32],
    material: &MaterialInput<'_>,
    outputs: Outputs,
) -> Result<(), Error> {
    let method = transfer_method::<N>(config.method)?;
    let options = config.batch_options(quality);
    let lighting = lighting_rgb::<N>(lighting);
    let (mut frame, lobe) = workspace.frame(config, input)?;
    let lobe: Option<&PhongLobe> = if material.glossy() {
        let exponent = material.exponent;
        let new_lobe = || PhongLobe::new(exponent).expect("the exponent was checked to be >= 0");
        match lobe {
            Some(lobe) if lobe.exponent().to_bits() == exponent.to_bits() => {}
            Some(lobe) => **lobe = new_lobe(),
            None => *lobe = Some(fallible::boxed(new_lobe(), "a Phong lobe")?),
        }
        lobe.as_deref()
    } else {
        None
    };
    let surface = |v: usize| VertexSurface {
        material: Material {
            albedo: material
                .vertex_albedo
                .map_or(material.albedo, |a| Vec3::from_slice(&a[3 * v..])),
            specular: material.specular,
            lobe,
            eye: material.eye,
        },
        to_eye: material
            .view_directions
            .map(|d| Vec3::from_slice(&d[3 * v..])),
    };
    let shading = frame
        .shade(&options, method, &lighting, surface)
        .expect("a shader set up for shading holds one entry per vertex");
    let count = shading.len();
    // SAFETY: checked aligned and sized by `check_outputs`, disjoint from every
    // input and the other outputs; valid for writes by the caller's contract.
    let mut rgb = unsafe { optional_out(outputs.rgb, count, "rgb") }?;
    // SAFETY: as above.
    let mut diffuse = unsafe { optional_out(outputs.diffuse, count, "diffuse") }?;
    // SAFETY: as above.
    let mut glossy = unsafe { optional_out(outputs.glossy, count, "glossy") }?;
    for (v, s) in shading.iter().enumerate() {
        if let Some(rgb) = rgb.as_deref_mut() {
            rgb[3 * v..3 * v + 3].copy_from_slice(&(s.diffuse + s.glossy).to_array());
        }
        if let Some(diffuse) = diffuse.as_deref_mut() {
            diffuse[3 * v..3 * v + 3].copy_from_slice(&s.diffuse.to_array());
        }
        if let Some(glossy) = glossy.as_deref_mut() {
            glossy[3 * v..3 * v + 3].copy_from_slice(&s.glossy.to_array());
        }
    }
    Ok(())
}

/// # Safety
/// A non-NULL `pointer` must be valid for `3 * count` floats, aliasing nothing.
unsafe fn optional_out<'a>(
    pointer: *mut f32,
    count: usize,
    argument: &str,
) -> Result<Option<&'a mut [f32]>, Error> {
    if pointer.is_null() {
        return Ok(None);
    }
    // SAFETY: forwarded contract.
    unsafe { raw::slice_mut(pointer, 3 * count, argument) }.map(Some)
}

/// Checks the shading outputs before any work: at least one, each aligned and
/// sized, none overlapping another or an input.
fn check_outputs(outputs: &Outputs, vertex_count: usize, inputs: &Spans) -> Result<(), Error> {
    let xyz = raw::element_count(vertex_count, 3, "mesh->vertex_count")?;
    if vertex_count > 0
        && outputs.rgb.is_null()
        && outputs.diffuse.is_null()
        && outputs.glossy.is_null()
    {
        return Err(Error::new(
            ANTUMBRA_RESULT_NULL_ARGUMENT,
            "rgb, diffuse and glossy are all NULL; pass at least one output",
        ));
    }
    let mut spans = [None; 3];
    for (span, (pointer, name)) in spans.iter_mut().zip([
        (outputs.rgb, "rgb"),
        (outputs.diffuse, "diffuse"),
        (outputs.glossy, "glossy"),
    ]) {
        if !pointer.is_null() {
            raw::writable(pointer, xyz, name)?;
            *span = Span::of(name, pointer.cast_const(), xyz);
        }
    }
    check_disjoint(&spans, inputs)
}

// ---------------------------------------------------------------------------
// The handle
// ---------------------------------------------------------------------------

#[cfg(feature = "std")]
/// Shading state for one mesh topology and one configuration, reused every frame.
/// Opaque; create with `antumbra_hemi_shader_create`, free with
/// `antumbra_hemi_shader_destroy`.
///
/// It holds the validated options, the triangle clusters of the mesh (and far
/// mesh) grouped once from the pose given at creation, the per-frame scratch
/// memory, and the glossy lobe of the last exponent used. Calls on one shader run
/// one at a time (an internal lock); use one shader per thread to shade several
/// meshes at once.
pub struct antumbra_hemi_shader {
    config: Config,
    vertex_count: usize,
    triangle_count: usize,
    /// The far mesh's vertex and triangle counts, when created with one.
    far_counts: Option<(usize, usize)>,
    /// Whether the shader makes its own far mesh (`far_triangles`).
    builds_far: bool,
    workspace: Mutex<Workspace>,
    poisoned: AtomicBool,
}

#[cfg(feature = "std")]
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<antumbra_hemi_shader>();
};

#[cfg(feature = "std")]
/// Creates a shader for a mesh topology (and optionally a far mesh's) and a
/// configuration; the per-frame calls then take the current positions.
///
/// @param mesh the full-resolution mesh whose every vertex is a receiver, in the
///        pose that groups its triangles into clusters (the rest pose; positions
///        are not kept). Its vertex and triangle counts are fixed for the shader's
///        life; the same validation as the per-frame calls applies.
/// @param far_mesh NULL, or the simplified mesh for distant occluders in the same
///        pose (its counts are fixed too). A shader created without one cannot
///        take one later. Must be NULL with `options->far_triangles` > 0: the
///        shader then makes its own far mesh from this pose and moves it with
///        each frame's positions.
/// @param options NULL for the defaults (see `antumbra_hemi_shading_options_init`),
///        or options as documented on `antumbra_hemi_shading_options`. They are
///        copied; a caller-owned table in `options->raster.table` is kept by
///        pointer and must outlive the shader.
/// @param out receives the new shader on success; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (mesh, out, or an array that is NULL
///         with a non-zero count); INVALID_ARGUMENT (an option out of its range,
///         misaligned array or struct, stride below 12, count overflow, a
///         coordinate beyond ±1e12, options->far_triangles not below the mesh's
///         triangle count or given with far_mesh, options->far_levels above 8 or
///         above 1 without far_triangles);
///         INDEX_OUT_OF_RANGE (an index of either
///         mesh); NON_FINITE (a position, options->raster.normal_offset, a NaN
///         options->near_radius); OUT_OF_MEMORY (the per-frame memory or the
///         shared half-space table); POISONED (options->raster.table); PANIC.
///
/// Cost: groups the triangles (recursive median splits of their centroids), reserves
/// 12 + 24 bytes per vertex and about 5 bytes per triangle (both meshes); with
/// `far_triangles`, simplifies the mesh (about 20 clusterings, each a sort of the
/// vertices and triangles: milliseconds per 10k triangles) and keeps the far mesh
/// and its map from full vertices (about 4 bytes per full vertex and 24 per far
/// vertex and triangle); and builds the shared tables of this configuration on
/// first use in the process (the SH cell integrals: about 10 ms at 3 bands, 26 ms
/// at 8; the byte lookup table for ANTUMBRA_HEMI_METHOD_LUT, a few ms more; the
/// half-space table for the table quality), kept until exit. Apart from the reported cases,
/// an allocation failure aborts the process, as Rust allocations do.
/// Ownership: the caller owns `*out` and frees it with
/// `antumbra_hemi_shader_destroy`; the meshes are borrowed for the call only.
/// Thread safety: safe from any thread; shaders are independent of each other.
///
/// # Safety
/// `mesh`, `far_mesh`, `options` and `out` must be NULL or valid; the arrays in the
/// meshes valid for the counts and strides they give.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_shader_create(
    mesh: *const antumbra_mesh_view,
    far_mesh: *const antumbra_mesh_view,
    options: *const antumbra_hemi_shading_options,
    out: *mut *mut antumbra_hemi_shader,
) -> antumbra_result {
    guard("antumbra_hemi_shader_create", || {
        if out.is_null() {
            return Err(Error::null("out"));
        }
        let out = raw::writable(out, 1, "out")?;
        // SAFETY: caller contract on `options` and its table.
        let config = unsafe { read_shading_options(options) }?;
        // SAFETY: caller contract on the meshes.
        let input = unsafe { read_frame(mesh, core::ptr::null(), far_mesh) }?;
        // SAFETY: a user table is alive by the caller's contract.
        unsafe { config.quality() }?;
        with_coefficients!(config.bands, prepare_tables(&config))?;
        let workspace = Workspace::new(&config, &input, true, true, Some(DEFAULT_EXPONENT))?;
        let builds_far = workspace.shader.far_field().is_some();
        let shader = Box::new(antumbra_hemi_shader {
            config,
            vertex_count: input.mesh.vertex_count(),
            triangle_count: input.mesh.triangle_count(),
            far_counts: input.far.map(|f| (f.vertex_count(), f.triangle_count())),
            builds_far,
            workspace: Mutex::new(workspace),
            poisoned: AtomicBool::new(false),
        });
        // SAFETY: non-NULL, aligned (checked), valid for a pointer write by contract.
        unsafe { out.write(Box::into_raw(shader)) };
        Ok(())
    })
}

#[cfg(feature = "std")]
/// Frees a shader. NULL is a no-op.
///
/// Ownership: takes back a shader from `antumbra_hemi_shader_create`; it must not
/// be used afterwards. A caller-owned half-space table it used may be destroyed
/// after this call.
/// Thread safety: needs exclusive access: no call on this shader may be running.
///
/// # Safety
/// `shader` must be NULL or a live shader from `antumbra_hemi_shader_create`,
/// destroyed at most once.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_shader_destroy(shader: *mut antumbra_hemi_shader) {
    let _ = guard("antumbra_hemi_shader_destroy", || {
        if !shader.is_null() {
            // SAFETY: by contract, a live shader created by `Box::into_raw`.
            drop(unsafe { Box::from_raw(shader) });
        }
        Ok(())
    });
}

#[cfg(feature = "std")]
impl antumbra_hemi_shader {
    /// Checks that this frame's meshes have the topology the shader was made for.
    fn check_topology(&self, input: &FrameInput<'_>) -> Result<(), Error> {
        let (v, t) = (input.mesh.vertex_count(), input.mesh.triangle_count());
        if (v, t) != (self.vertex_count, self.triangle_count) {
            return Err(Error::invalid(message!(
                "mesh has {v} vertices and {t} triangles, but the shader was created for \
                 {} vertices and {} triangles",
                self.vertex_count,
                self.triangle_count
            )));
        }
        match (input.far, self.far_counts) {
            (None, _) => Ok(()),
            (Some(_), _) if self.builds_far => Err(Error::invalid(
                "far_mesh is given, but the shader makes its own far mesh \
                 (options->far_triangles at creation); pass NULL",
            )),
            (Some(_), None) => Err(Error::invalid(
                "far_mesh is given, but the shader was created without a far mesh",
            )),
            (Some(far), Some((fv, ft))) => {
                let (v, t) = (far.vertex_count(), far.triangle_count());
                if (v, t) != (fv, ft) {
                    Err(Error::invalid(message!(
                        "far_mesh has {v} vertices and {t} triangles, but the shader was \
                         created with a far mesh of {fv} vertices and {ft} triangles"
                    )))
                } else {
                    Ok(())
                }
            }
        }
    }
}

#[cfg(feature = "std")]
/// Runs a per-frame call on a shader: rejects NULL and poisoned shaders, takes its
/// lock, and poisons the shader (and its caller-owned table) when the call panics.
fn with_shader(
    function: &'static str,
    shader: *mut antumbra_hemi_shader,
    body: impl FnOnce(&antumbra_hemi_shader, &mut Workspace) -> Result<(), Error>,
) -> antumbra_result {
    let mut poison_shader: Option<&AtomicBool> = None;
    let mut poison_table: Option<UserTable> = None;
    let result = guard(function, || {
        // SAFETY: by contract `shader` is NULL or a live shader; only shared
        // references are made (the workspace is behind the lock).
        let shader = unsafe { raw::reference(shader.cast_const(), "shader") }?;
        check_not_poisoned(&shader.poisoned, "shader")?;
        poison_shader = Some(&shader.poisoned);
        poison_table = shader.config.user_table();
        // The lock is only poisoned by a panic, which also set `shader.poisoned`.
        let mut workspace = shader
            .workspace
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        body(shader, &mut workspace)
    });
    if result == ANTUMBRA_RESULT_PANIC {
        if let Some(flag) = poison_shader {
            flag.store(true, Ordering::Release);
        }
        if let Some(table) = poison_table {
            // SAFETY: a user table outlives the shader by contract.
            unsafe { table.poison() };
        }
    }
    result
}

#[cfg(feature = "std")]
/// Regroups a shader's triangle clusters from the current pose, for meshes whose
/// shape changed so much since creation that the rest-pose clusters are no
/// longer compact (shading gets slower, never different: results do not depend
/// on the grouping).
///
/// @param shader the shader.
/// @param mesh the mesh in its current pose, with the shader's counts.
/// @param far_mesh NULL (the far clusters are kept) or the far mesh in its current
///        pose, with the counts given at creation.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT; INVALID_ARGUMENT (counts differing
///         from the shader's, a far mesh for a shader created without one, and
///         the mesh checks of `antumbra_hemi_shader_create`); INDEX_OUT_OF_RANGE;
///         NON_FINITE; POISONED; PANIC (the shader is poisoned).
///
/// Cost: recursive median splits of the triangles' centroids (allocates
/// temporary memory).
/// Thread safety: calls on one shader run one at a time (an internal lock).
///
/// # Safety
/// `shader` must be NULL or a live shader; the meshes NULL or valid.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_shader_regroup(
    shader: *mut antumbra_hemi_shader,
    mesh: *const antumbra_mesh_view,
    far_mesh: *const antumbra_mesh_view,
) -> antumbra_result {
    with_shader(
        "antumbra_hemi_shader_regroup",
        shader,
        |shader, workspace| {
            // SAFETY: caller contract on the meshes.
            let input = unsafe { read_frame(mesh, core::ptr::null(), far_mesh) }?;
            shader.check_topology(&input)?;
            workspace
                .shader
                .regroup(&input.mesh, input.far.as_ref())
                .map_err(|e| shader_error(&shader.config, &input, e))
        },
    )
}

#[cfg(feature = "std")]
/// Makes a shader's frames (`antumbra_hemi_shader_transfer` and
/// `antumbra_hemi_shader_shade`) rasterize only some vertices (sparse
/// receivers) and interpolate the rest, or every vertex again (`spacing` 0,
/// the default at creation).
///
/// The *keys* are vertices `spacing` mesh edges apart (every other vertex has
/// one within `spacing` edges): about a quarter of a triangle mesh's vertices
/// at 1, a tenth at 2. Each frame the keys are rasterized; every other vertex
/// takes its open hemisphere's transfer less the weighted mean occlusion of
/// the 3 to 8 nearest keys (weights by inverse squared distance in the pose
/// given here), unless one of those keys' occlusion is more than `tolerance`
/// times the open hemisphere's transfer (SH norms) from that mean, or its
/// normal turns more than about 37° (cosine 0.8) from the vertex's: then that
/// vertex is rasterized too. Keys and rasterized vertices get exactly the
/// vectors and colours of a shader without sparse receivers.
///
/// Shading borrows the glossy term's occlusion the same way: an interpolated
/// vertex's glossy transfer is its own open lobe (about its own mirror
/// direction) less its keys' weighted blocked lobe, and a vertex is
/// rasterized unless every key has the same glossy lobe and their blocked
/// lobes pass the same test against its open one.
///
/// The trade with spacing 1, one thread, 3 bands, on meshes of about 15,000
/// to 89,000 triangles (`antumbra bench hemi --scaling`, docs/performance.md):
/// tolerance 0.05 rasterizes 57–89 % of the vertices and makes a frame
/// 1.0–1.4× as fast for 0.2–0.5 % ambient-occlusion error; 0.1 rasterizes
/// 41–72 %, 1.2–2.1× for 0.4–1.2 %; 0.2 rasterizes 28–55 %, 1.7–3.4× for
/// 0.6–2.0 %. Wider spacings rasterize as many vertices for more error on
/// those meshes. Coarse meshes (a few thousand triangles, sharp creases) gain
/// little, and a loose tolerance costs them more. The vertices interpolated
/// are mostly the open, cheap ones, so a frame gains less than the share
/// skipped: shading the deforming bunny (diffuse + glossy, `antumbra bench
/// hemi`) at tolerance 0.1 rasterizes 67 % for 1.1× the frame rate, CGAL's
/// bear (27,648 triangles) 52 % for 1.5–1.6×, at 0.2–0.3 % colour error.
///
/// @param shader the shader.
/// @param mesh the mesh in a pose (the rest pose, or any with the shader's
///        counts) to measure the weights in.
/// @param spacing 0 (every vertex rasterized) to
///        `ANTUMBRA_HEMI_MAX_RECEIVER_SPACING`.
/// @param tolerance finite, >= 0 (read only with `spacing` > 0).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT; INVALID_ARGUMENT (`spacing`
///         above the maximum, a negative `tolerance`, counts differing from the
///         shader's, and the mesh checks of `antumbra_hemi_shader_create`);
///         INDEX_OUT_OF_RANGE; NON_FINITE (`tolerance` or a position);
///         OUT_OF_MEMORY; POISONED; PANIC (the shader is poisoned). On failure
///         the shader keeps its previous setting.
///
/// Cost: a breadth-first search of a few rings around every vertex (0.1 to
/// 0.9 µs per vertex at spacing 1, `antumbra bench hemi --scaling`); it
/// allocates the sampling (about 50 bytes per vertex) and the keys' per-frame
/// occlusion and colours (536 bytes per key). A frame then allocates nothing.
/// Thread safety: calls on one shader run one at a time (an internal lock).
///
/// # Safety
/// `shader` must be NULL or a live shader; `mesh` NULL or valid.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_shader_set_receivers(
    shader: *mut antumbra_hemi_shader,
    mesh: *const antumbra_mesh_view,
    spacing: u32,
    tolerance: f32,
) -> antumbra_result {
    with_shader(
        "antumbra_hemi_shader_set_receivers",
        shader,
        |shader, workspace| {
            if spacing > ANTUMBRA_HEMI_MAX_RECEIVER_SPACING {
                return Err(Error::invalid(message!(
                    "spacing is {spacing}; it must be 0 (every vertex) to \
                     ANTUMBRA_HEMI_MAX_RECEIVER_SPACING ({ANTUMBRA_HEMI_MAX_RECEIVER_SPACING})"
                )));
            }
            if spacing > 0 {
                if !tolerance.is_finite() {
                    return Err(Error::new(
                        ANTUMBRA_RESULT_NON_FINITE,
                        message!("tolerance is {tolerance}; it must be finite"),
                    ));
                }
                if tolerance < 0.0 {
                    return Err(Error::invalid(message!(
                        "tolerance is {tolerance}; it must be >= 0"
                    )));
                }
            }
            // SAFETY: caller contract on the mesh.
            let input = unsafe { read_frame(mesh, core::ptr::null(), core::ptr::null()) }?;
            shader.check_topology(&input)?;
            let lod =
                (spacing > 0).then_some(antumbra_core::hemi::ReceiverLod { spacing, tolerance });
            workspace
                .shader
                .set_receivers(&input.mesh, lod)
                .map_err(|e| shader_error(&shader.config, &input, e))
        },
    )
}

#[cfg(feature = "std")]
/// Transfer vectors of every vertex of a mesh in its current pose, through a
/// shader: as `antumbra_hemi_transfer` with the shader's options, allocating
/// nothing and skipping whole clusters of triangles below each receiver's
/// horizon (the results are identical), unless sparse receivers are set
/// (`antumbra_hemi_shader_set_receivers`: then only the keys and the vertices
/// whose keys disagree get those results, the rest interpolated).
///
/// @param shader the shader, created for this mesh's topology.
/// @param mesh the current pose: the vertex and triangle counts given at creation
///        (the indices may differ; they are validated every call; with sparse
///        receivers the keys and weights stay those of the mesh given to
///        `antumbra_hemi_shader_set_receivers`).
/// @param normals NULL (area-weighted normals are computed) or 3 floats per vertex,
///        as for `antumbra_hemi_transfer`.
/// @param far_mesh NULL (no far mesh this frame, or the shader's own when created
///        with `far_triangles`, posed from `mesh`) or the far mesh's current
///        pose, with the counts given at creation.
/// @param transfer receives `vertex_count * bands²` floats, as for
///        `antumbra_hemi_transfer`; untouched on failure.
/// @return as `antumbra_hemi_transfer`, plus INVALID_ARGUMENT for counts that
///         differ from the shader's and for a far mesh given to a shader created
///         without one; POISONED (the shader, or its caller-owned table); PANIC
///         (the shader and its caller-owned table are poisoned).
///
/// Cost: O(vertices × triangles above each receiver's horizon); no allocation
/// (rayon's scheduler aside, with options->raster.parallel).
/// Thread safety: calls on one shader run one at a time (an internal lock:
/// concurrent calls wait; each already uses every core with parallel = 1). Use
/// one shader per thread to work on several meshes at once.
///
/// # Safety
/// `shader` must be NULL or a live shader; the other pointers NULL or valid for
/// what they describe.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_shader_transfer(
    shader: *mut antumbra_hemi_shader,
    mesh: *const antumbra_mesh_view,
    normals: *const f32,
    far_mesh: *const antumbra_mesh_view,
    transfer: *mut f32,
) -> antumbra_result {
    with_shader(
        "antumbra_hemi_shader_transfer",
        shader,
        |shader, workspace| {
            // SAFETY: caller contract on every pointer.
            unsafe {
                transfer_call(
                    &shader.config,
                    Some(workspace),
                    Some(shader),
                    mesh,
                    normals,
                    far_mesh,
                    transfer,
                )
            }
        },
    )
}

#[cfg(feature = "std")]
/// Shaded colours of every vertex of a mesh in its current pose, through a
/// shader: as `antumbra_hemi_shade` with the shader's options, allocating nothing
/// per frame and skipping whole clusters of triangles below each receiver's
/// horizon (the results are identical), unless sparse receivers are set
/// (`antumbra_hemi_shader_set_receivers`: then only the keys and the vertices
/// whose keys disagree get those results, the rest interpolated).
///
/// @param shader the shader, created for this mesh's topology.
/// @param mesh the current pose: the vertex and triangle counts given at creation.
/// @param normals NULL (computed) or 3 floats per vertex, as for
///        `antumbra_hemi_shade`.
/// @param far_mesh NULL (no far mesh this frame, or the shader's own when created
///        with `far_triangles`, posed from `mesh`) or the far mesh's current
///        pose, with the counts given at creation.
/// @param lighting `3 * bands²` floats of world SH incident radiance (bands of the
///        shader's options), as for `antumbra_hemi_shade`.
/// @param material the material, as for `antumbra_hemi_shade`. The glossy lobe is
///        rebuilt (about 80 µs, no allocation) only when the exponent changes.
/// @param rgb, diffuse, glossy as for `antumbra_hemi_shade`.
/// @return as `antumbra_hemi_shade`, plus INVALID_ARGUMENT for counts that differ
///         from the shader's and for a far mesh given to a shader created without
///         one; POISONED (the shader, or its caller-owned table); PANIC (the
///         shader and its caller-owned table are poisoned).
///
/// Cost: O(vertices × triangles above each receiver's horizon); no allocation
/// (rayon's scheduler aside, with options->raster.parallel).
/// Thread safety: calls on one shader run one at a time (an internal lock).
///
/// # Safety
/// `shader` must be NULL or a live shader; the other pointers NULL or valid for
/// what they describe.
#[must_use]
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn antumbra_hemi_shader_shade(
    shader: *mut antumbra_hemi_shader,
    mesh: *const antumbra_mesh_view,
    normals: *const f32,
    far_mesh: *const antumbra_mesh_view,
    lighting: *const f32,
    material: *const antumbra_hemi_material,
    rgb: *mut f32,
    diffuse: *mut f32,
    glossy: *mut f32,
) -> antumbra_result {
    with_shader("antumbra_hemi_shader_shade", shader, |shader, workspace| {
        let outputs = Outputs {
            rgb,
            diffuse,
            glossy,
        };
        // SAFETY: caller contract on every pointer.
        unsafe {
            shade_call(
                &shader.config,
                Some(workspace),
                Some(shader),
                mesh,
                normals,
                far_mesh,
                lighting,
                material,
                outputs,
            )
        }
    })
}

// ---------------------------------------------------------------------------
// One-shot calls
// ---------------------------------------------------------------------------

/// The shader a call runs for, if any (the per-call functions serve both).
#[cfg(feature = "std")]
type ShaderHandle = antumbra_hemi_shader;

/// The bare-metal build has no shaders (they need a lock); nothing is of this type.
#[cfg(not(feature = "std"))]
enum ShaderHandle {}

#[cfg(not(feature = "std"))]
impl ShaderHandle {
    fn check_topology(&self, _: &FrameInput<'_>) -> Result<(), Error> {
        match *self {}
    }
}

/// # Safety
/// Every pointer NULL or valid for what it describes; a user table in `config`
/// alive.
unsafe fn transfer_call(
    config: &Config,
    workspace: Option<&mut Workspace>,
    shader: Option<&ShaderHandle>,
    mesh: *const antumbra_mesh_view,
    normals: *const f32,
    far_mesh: *const antumbra_mesh_view,
    transfer: *mut f32,
) -> Result<(), Error> {
    // SAFETY: caller contract.
    let input = unsafe { read_frame(mesh, normals, far_mesh) }?;
    if let Some(shader) = shader {
        shader.check_topology(&input)?;
    }
    let count = config.bands * config.bands;
    let len = raw::element_count(input.mesh.vertex_count(), count, "mesh->vertex_count")?;
    raw::writable(transfer, len, "transfer")?;
    check_disjoint(
        &[Span::of("transfer", transfer.cast_const(), len)],
        &input.spans,
    )?;
    if len == 0 {
        return Ok(());
    }
    // SAFETY: a user table is alive by the caller's contract.
    let quality = unsafe { config.quality() }?;
    let mut fresh;
    let workspace = match workspace {
        Some(workspace) => workspace,
        None => {
            let clusters = worth_it(&input);
            fresh = Workspace::new(config, &input, clusters, false, None)?;
            &mut fresh
        }
    };
    // SAFETY: checked aligned and sized; disjoint from every input by the check
    // above; valid for writes by the caller's contract.
    let out = unsafe { raw::slice_mut(transfer, len, "transfer") }?;
    with_coefficients!(
        config.bands,
        transfer_frame(workspace, config, quality, &input, out)
    )
}

/// # Safety
/// Every pointer NULL or valid for what it describes; a user table in `config`
/// alive.
#[allow(clippy::too_many_arguments)]
unsafe fn shade_call(
    config: &Config,
    workspace: Option<&mut Workspace>,
    shader: Option<&ShaderHandle>,
    mesh: *const antumbra_mesh_view,
    normals: *const f32,
    far_mesh: *const antumbra_mesh_view,
    lighting: *const f32,
    material: *const antumbra_hemi_material,
    outputs: Outputs,
) -> Result<(), Error> {
    // SAFETY: caller contract.
    let mut input = unsafe { read_frame(mesh, normals, far_mesh) }?;
    if let Some(shader) = shader {
        shader.check_topology(&input)?;
    }
    let vertex_count = input.mesh.vertex_count();
    // SAFETY: caller contract.
    let lighting = unsafe { read_lighting(lighting, config.bands, &mut input.spans) }?;
    // SAFETY: caller contract.
    let material = unsafe { read_material(material, vertex_count, &mut input.spans) }?;
    check_outputs(&outputs, vertex_count, &input.spans)?;
    if vertex_count == 0 {
        return Ok(());
    }
    // SAFETY: a user table is alive by the caller's contract.
    let quality = unsafe { config.quality() }?;
    let mut fresh;
    let workspace = match workspace {
        Some(workspace) => workspace,
        None => {
            let exponent = material.glossy().then_some(material.exponent);
            let clusters = worth_it(&input);
            fresh = Workspace::new(config, &input, clusters, true, exponent)?;
            &mut fresh
        }
    };
    with_coefficients!(
        config.bands,
        shade_frame(
            workspace, config, quality, &input, lighting, &material, outputs
        )
    )
}

/// Whether a one-shot call groups the triangles of its meshes into clusters:
/// when it has enough receivers to pay for it (the same results). The
/// bare-metal build never groups (grouping allocates; see hemi.rs).
fn worth_it(input: &FrameInput<'_>) -> bool {
    cfg!(feature = "std")
        && worth_clustering(input.mesh.vertex_count(), input.mesh.triangle_count())
}

/// Runs a one-shot call: validates the options and poisons a caller-owned table
/// in use when the call panics.
fn one_shot(
    function: &'static str,
    options: *const antumbra_hemi_shading_options,
    body: impl FnOnce(&Config) -> Result<(), Error>,
) -> antumbra_result {
    let mut poison: Option<UserTable> = None;
    let result = guard(function, || {
        // SAFETY: caller contract on `options` and its table.
        let config = unsafe { read_shading_options(options) }?;
        poison = config.user_table();
        body(&config)
    });
    if result == ANTUMBRA_RESULT_PANIC
        && let Some(table) = poison
    {
        // SAFETY: the table is alive for the call by the caller's contract.
        unsafe { table.poison() };
    }
    result
}

/// Spherical-harmonic transfer vectors of every vertex of a mesh, each vertex a
/// receiver shadowed by the mesh itself (and, beyond `options->near_radius`, by
/// `far_mesh`).
///
/// For vertex v at position p with unit normal n, the mask of
/// `antumbra_hemi_rasterize` (center of projection `p + normal_offset * n`, the
/// options' quality and culling; with a far mesh, the near/far rule of
/// `antumbra_hemi_shading_options.near_radius`) gives the visibility V, and
///
/// `T_k = ∫ V(ω) y_k(ω) max(0, n·ω) dω`
///
/// summed over the unoccluded cells with their exact integrals (`method`). In
/// world space (the default) `y_k` are the world SH basis functions, so for world
/// SH coefficients `l_k` of incident radiance the irradiance is `Σ_k T_k l_k` and a
/// Lambertian vertex's radiance `albedo/π Σ_k T_k l_k`; in local space they are
/// taken in the frame (tangent, bitangent, normal) of `antumbra_frame_from_normal`.
/// An unoccluded vertex gets the clamped cosine about its normal: in local space
/// its zonal coefficients at the m = 0 indices `l(l+1)` (`T_0 = √π/2 = 0.886227`,
/// `T_2 = √(π/3) = 1.023327`, `T_6 = 0.495416`, 0 for odd l > 1) and 0 elsewhere;
/// in world space `T_k = A_l Y_k(n)` (`A_0 = π`, `A_1 = 2π/3`, `A_2 = π/4`, ...).
/// SH convention as `antumbra_sh_eval`: real, orthonormal, Condon–Shortley phase,
/// coefficient (l, m) at index `l(l+1) + m`.
///
/// @param mesh the mesh; every vertex is a receiver. Every index < vertex_count;
///        every position finite and within ±1e12; position_stride 0 or >= 12. A
///        mesh without vertices gives an empty result.
/// @param normals NULL: area-weighted vertex normals are computed (the normalised
///        sum of the unnormalised face normals `(b - a) × (c - a)` around each
///        vertex, so counter-clockwise triangles give outward normals; a vertex in
///        no triangle, or whose sum is zero, gets (0, 0, 0)). Otherwise 3 floats
///        per vertex, finite, each unit length within 1e-3 (used as given) or
///        exactly (0, 0, 0). A vertex with a zero normal gets a zero vector.
/// @param far_mesh NULL, or the simplified mesh for distant occluders, in the same
///        space and pose (same checks as `mesh`, only triangle corners range-checked).
///        Must be NULL with `options->far_triangles` > 0, which makes a far mesh
///        from `mesh` as given, in the call (a shader makes it once).
/// @param options NULL for the defaults, or see `antumbra_hemi_shading_options`.
/// @param transfer receives `vertex_count * bands²` floats: vertex v's coefficients
///        at `transfer[v * bands² + l(l+1) + m]`; untouched on failure (except
///        after ANTUMBRA_RESULT_PANIC). Must not overlap any input (checked).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (mesh, transfer, or an array that is
///         NULL with a non-zero count); INVALID_ARGUMENT (an option out of its
///         range, misaligned array or struct, stride below 12, count overflow, a
///         coordinate beyond ±1e12, a normal that is neither unit nor zero,
///         overlapping output, options->far_triangles not below the mesh's
///         triangle count or given with far_mesh, options->far_levels above 8 or
///         above 1 without far_triangles);
///         INDEX_OUT_OF_RANGE (an index of either mesh);
///         NON_FINITE (a position, a normal, options->raster.normal_offset, a NaN
///         near_radius); OUT_OF_MEMORY (scratch memory, or the shared half-space
///         table on first use); POISONED (options->raster.table); PANIC (a
///         caller-owned table in use is poisoned).
///         Messages name the argument and index, e.g.
///         `normals[7] has length 0.5, neither 1 (tolerance 0.001) nor exactly 0`.
///
/// Cost: O(vertices × triangles above each receiver's horizon); allocates 12 bytes
/// per vertex for the normals, and with 32 or more vertices groups the triangles
/// into clusters (as `antumbra_hemi_rasterize`; a shader groups them once). The first call with a configuration builds the shared tables it reads
/// (see `antumbra_hemi_shader_create`). With options->raster.parallel = 1 the
/// vertices are split across the library's worker threads; results are identical.
/// Without ANTUMBRA_HAS_STD (bare metal) the call never groups, and
/// `far_triangles` > 0 and `parallel` = 1 are ANTUMBRA_RESULT_UNSUPPORTED (pass
/// a far mesh of your own); every allocation failure is OUT_OF_MEMORY.
/// Ownership: borrows every argument for the call only.
/// Thread safety: any number of threads may call at once (the inputs and shared
/// tables are only read).
///
/// # Safety
/// The arrays in the meshes must be valid for their counts and strides; a non-NULL
/// `normals` for `3 * vertex_count` floats; `transfer` for
/// `vertex_count * bands²` floats; `options` NULL or valid.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_transfer(
    mesh: *const antumbra_mesh_view,
    normals: *const f32,
    far_mesh: *const antumbra_mesh_view,
    options: *const antumbra_hemi_shading_options,
    transfer: *mut f32,
) -> antumbra_result {
    one_shot("antumbra_hemi_transfer", options, |config| {
        // SAFETY: caller contract on every pointer.
        unsafe { transfer_call(config, None, None, mesh, normals, far_mesh, transfer) }
    })
}

/// Diffuse and glossy radiance of every vertex of a mesh under world SH lighting,
/// each vertex a receiver shadowed by the mesh itself (and, beyond
/// `options->near_radius`, by `far_mesh`).
///
/// Per vertex with visibility V (the mask, as for `antumbra_hemi_transfer`):
/// diffuse `albedo/π Σ_k T_k l_k` with `T` the world transfer vector of
/// `antumbra_hemi_transfer` (the options' method), and glossy
/// `specular Σ_k G_k l_k` with `G_k = ∫ V(ω) (s + 2)/(2π) max(0, ω·r)^s y_k(ω)
/// max(0, n·ω) dω` summed per unoccluded cell (the lobe at the cell's center,
/// whatever the method), for the mirror direction r of the view (see
/// `antumbra_hemi_material`). Lighting, transfer and colours are linear; no
/// clamping: SH ringing of a sharp light can make a channel slightly negative.
///
/// @param mesh, normals, far_mesh, options as for `antumbra_hemi_transfer`
///        (options->space is ignored). A vertex with a zero normal gets black.
/// @param lighting `3 * bands²` floats (bands = options->bands): world SH
///        coefficients of incident radiance `L(ω)` (radiance arriving from
///        direction ω), red then green then blue, the layout
///        `antumbra_sh_project_equirect` writes. Finite.
/// @param material the material and viewer (see `antumbra_hemi_material`).
/// @param rgb NULL or receives 3 floats per vertex: diffuse + glossy.
/// @param diffuse NULL or receives 3 floats per vertex: the diffuse term.
/// @param glossy NULL or receives 3 floats per vertex: the glossy term (0 with
///        specular 0).
///        At least one of the three must be non-NULL (when there are vertices).
///        Untouched on failure (except after ANTUMBRA_RESULT_PANIC). They must
///        not overlap each other or any input array (checked).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (mesh, lighting, material, all three
///         outputs, or an array that is NULL with a non-zero count);
///         INVALID_ARGUMENT (as `antumbra_hemi_transfer`, plus a negative albedo or
///         specular channel or exponent, an eye beyond ±1e12, a view direction
///         that is not unit length, overlapping outputs); INDEX_OUT_OF_RANGE;
///         NON_FINITE (as `antumbra_hemi_transfer`, plus a lighting coefficient,
///         albedo, specular, exponent, eye or view direction); OUT_OF_MEMORY;
///         POISONED; PANIC. Messages name the argument and index, e.g.
///         `lighting[10] (channel green, coefficient 1) is nan; it must be finite`.
///
/// Cost: as `antumbra_hemi_transfer`, plus about a microsecond per vertex for the
/// glossy sum; allocates 36 bytes per vertex and builds the glossy lobe (80 µs) per call
/// (a shader keeps both).
/// Ownership: borrows every argument for the call only.
/// Thread safety: any number of threads may call at once.
///
/// # Safety
/// As `antumbra_hemi_transfer`; `lighting` NULL or valid for `3 * bands²` floats;
/// `material` NULL or valid, with its arrays NULL or valid for 3 floats per
/// vertex; each non-NULL output valid for `3 * vertex_count` floats.
#[must_use]
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn antumbra_hemi_shade(
    mesh: *const antumbra_mesh_view,
    normals: *const f32,
    far_mesh: *const antumbra_mesh_view,
    options: *const antumbra_hemi_shading_options,
    lighting: *const f32,
    material: *const antumbra_hemi_material,
    rgb: *mut f32,
    diffuse: *mut f32,
    glossy: *mut f32,
) -> antumbra_result {
    one_shot("antumbra_hemi_shade", options, |config| {
        let outputs = Outputs {
            rgb,
            diffuse,
            glossy,
        };
        // SAFETY: caller contract on every pointer.
        unsafe {
            shade_call(
                config, None, None, mesh, normals, far_mesh, lighting, material, outputs,
            )
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_overlap_only_when_they_share_bytes() {
        let a = Span {
            name: "a",
            start: 0,
            end: 12,
        };
        let b = Span {
            name: "b",
            start: 12,
            end: 24,
        };
        assert!(!a.overlaps(&b) && !b.overlaps(&a));
        let c = Span {
            name: "c",
            start: 8,
            end: 16,
        };
        assert!(a.overlaps(&c) && c.overlaps(&b));
        assert!(check_disjoint(&[Some(a), None, Some(b)], &Spans::default()).is_ok());
        let mut inputs = Spans::default();
        inputs.push(Some(c));
        assert!(check_disjoint(&[Some(a)], &inputs).is_err());
        assert!(check_disjoint(&[Some(a), Some(c)], &Spans::default()).is_err());
    }

    #[test]
    fn a_poisoned_shader_is_refused() {
        let positions = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let indices = [0u32, 1, 2];
        let view = antumbra_mesh_view {
            positions: positions.as_ptr(),
            vertex_count: 3,
            position_stride: 0,
            indices: indices.as_ptr(),
            triangle_count: 1,
        };
        let mut shader = core::ptr::null_mut();
        // SAFETY: a valid mesh and out pointer.
        let created = unsafe {
            antumbra_hemi_shader_create(&view, core::ptr::null(), core::ptr::null(), &mut shader)
        };
        assert_eq!(created, ANTUMBRA_RESULT_OK);
        // What `with_shader` does after a panic.
        // SAFETY: a live shader.
        unsafe { &*shader }.poisoned.store(true, Ordering::Release);
        let mut out = [0.0f32; 27];
        // SAFETY: a live shader, a valid mesh and output.
        let result = unsafe {
            antumbra_hemi_shader_transfer(
                shader,
                &view,
                core::ptr::null(),
                core::ptr::null(),
                out.as_mut_ptr(),
            )
        };
        assert_eq!(result, ANTUMBRA_RESULT_POISONED);
        assert_eq!(out, [0.0; 27]);
        // SAFETY: from create, destroyed once.
        unsafe { antumbra_hemi_shader_destroy(shader) };
    }

    #[test]
    fn shared_tables_are_built_once_per_band_count() {
        let a: *const TransferTable<9> = transfer_table::<9>().unwrap();
        let b: *const TransferTable<9> = transfer_table::<9>().unwrap();
        assert_eq!(a, b);
        assert_eq!(transfer_table::<4>().unwrap().unoccluded().coeffs.len(), 4);
    }
}
