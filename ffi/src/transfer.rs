//! Precomputed radiance transfer for C callers (P1, P2; core's `transfer`): bake a
//! mesh into a transfer set (diffuse PRT, glossy SH transfer or matrix radiance
//! transfer), save it as a bake file and load it back, PCA-compress an MRT set,
//! and relight every vertex under SH lighting into a caller buffer.
//!
//! `antumbra_transfer` is an immutable handle around core's `TransferSet`: bake,
//! load and compress create one; info, save, compress and shade only read it, so
//! any number of threads may use one handle at once. Shading equals core's
//! `TransferSet::shade` on the same inputs; lighting is given channel-planar
//! (`bands²` red coefficients, then green, then blue), exactly what
//! `antumbra_sh_project_equirect` and `antumbra_sh_rotate` write.
//!
//! Bake files are core's versioned, checksummed format (`transfer::format`); a
//! truncated, corrupted or hostile file is `ANTUMBRA_RESULT_INVALID_DATA` with the
//! reason, never a crash, and loading never allocates more than a small multiple
//! of the input's length.

use alloc::boxed::Box;
use core::sync::atomic::AtomicBool;

use antumbra_core::sh::MAX_COEFFS;
use antumbra_core::transfer::{FormatError, Material, ShadeError, TransferKind, TransferSet, View};

use crate::boundary::{Poisonable, guard, with_handle};
use crate::error::Error;
use crate::raw;
use crate::result::*;

/// What only the hosted build has: baking (it casts rays through the BVH) and
/// PCA compression (which allocates as it goes).
#[cfg(feature = "std")]
use {
    crate::frame::UNIT_TOLERANCE,
    crate::mesh::{antumbra_mesh_view, mesh_from_c},
    crate::sh::ANTUMBRA_SH_MAX_BANDS,
    alloc::vec::Vec,
    antumbra_core::MeshView,
    antumbra_core::hemi::vertex_normals,
    antumbra_core::raycast::BvhScene,
    antumbra_core::transfer::{
        self, BakeError, BakeOptions, Brdf, Measurement, PcaError, PhongBrdf, WardBrdf,
    },
    core::ffi::c_void,
    glam::Vec3,
};

/// `antumbra_transfer_options.kind`: a diffuse transfer vector per vertex
/// (`bands²` values): shadowed (and, with bounces, interreflected) irradiance.
pub const ANTUMBRA_TRANSFER_KIND_DIFFUSE: u32 = 1;
/// `antumbra_transfer_options.kind`: a glossy SH transfer matrix per vertex
/// (`bands² × bands²`, world frame; Sloan, Kautz and Snyder 2002), shaded with a
/// Phong lobe of the material's exponent at run time.
pub const ANTUMBRA_TRANSFER_KIND_GLOSSY_SH: u32 = 2;
/// `antumbra_transfer_options.kind`: a matrix radiance transfer matrix per vertex
/// (`grid² × bands²`: outgoing radiance at the nodes of a bilinear hemispherical
/// basis, for the BRDF baked in; Lehtinen and Kautz 2003).
pub const ANTUMBRA_TRANSFER_KIND_MRT: u32 = 3;

/// `antumbra_transfer_options.brdf`: the reflected Phong lobe,
/// `brdf_params[0]` = exponent (finite, >= 0), `brdf_params[1]` unused (0).
pub const ANTUMBRA_TRANSFER_BRDF_PHONG: u32 = 1;
/// `antumbra_transfer_options.brdf`: Ward's anisotropic BRDF, `brdf_params` =
/// roughness along the tangent and along the bitangent, each in (0, 1].
pub const ANTUMBRA_TRANSFER_BRDF_WARD: u32 = 2;

/// The largest MRT grid side.
pub const ANTUMBRA_TRANSFER_MAX_GRID: u32 = 64;
/// The largest ray count per vertex and pass.
pub const ANTUMBRA_TRANSFER_MAX_RAYS: u32 = 1 << 22;
/// The largest interreflection bounce count.
pub const ANTUMBRA_TRANSFER_MAX_BOUNCES: u32 = 64;

const _: () = {
    assert!(ANTUMBRA_TRANSFER_MAX_GRID == antumbra_core::transfer::MAX_GRID);
    assert!(ANTUMBRA_TRANSFER_MAX_RAYS == antumbra_core::transfer::MAX_RAYS);
    assert!(ANTUMBRA_TRANSFER_MAX_BOUNCES == antumbra_core::transfer::MAX_BOUNCES);
    assert!(ANTUMBRA_TRANSFER_KIND_DIFFUSE == TransferKind::Diffuse as u32);
    assert!(ANTUMBRA_TRANSFER_KIND_GLOSSY_SH == TransferKind::GlossySh as u32);
    assert!(ANTUMBRA_TRANSFER_KIND_MRT == TransferKind::Mrt as u32);
};

#[cfg(feature = "std")]
/// What `antumbra_transfer_bake` measures and how. Fill with
/// `antumbra_transfer_options_init`, then change fields: fields may be added at
/// the end in later versions, and `options_init` keeps old code correct.
///
/// Layout: twelve 4-byte fields, then the 8-byte seed; 56 bytes, no padding.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct antumbra_transfer_options {
    /// `ANTUMBRA_TRANSFER_KIND_DIFFUSE` (the default), `_GLOSSY_SH` or `_MRT`.
    pub kind: u32,
    /// SH bands of the lighting, 1 to `ANTUMBRA_SH_MAX_BANDS` (8). Default 4.
    pub bands: u32,
    /// MRT nodes per side of the hemispherical grid, 2 to
    /// `ANTUMBRA_TRANSFER_MAX_GRID`; ignored by the other kinds. Default 8.
    pub grid: u32,
    /// Rays per vertex and pass, 1 to `ANTUMBRA_TRANSFER_MAX_RAYS`. Default 256.
    /// How they are spread over the vertex's hemisphere, so that the noise can be
    /// predicted: the unit square is stratified (a jittered s × s grid with
    /// s = floor(sqrt(rays)), the remaining rays − s² points uniformly random), then
    /// mapped **cosine-weighted** (concentric disk, lifted) for the diffuse kind and
    /// **uniformly** over the solid angle for glossy SH and MRT, whose projections
    /// weigh every direction alike. Each vertex, pass and seed has its own random
    /// stream. Monte Carlo error falls as 1/sqrt(rays) or faster: about 1/rays^0.8
    /// for diffuse transfer on a closed mesh, where stratification helps most; a
    /// square number of rays stratifies fully.
    pub rays: u32,
    /// Diffuse interreflection bounces, 0 (shadowed direct light only, the
    /// default) to `ANTUMBRA_TRANSFER_MAX_BOUNCES`.
    pub bounces: u32,
    /// 1 (the default): vertices are spread over the library's worker threads;
    /// 0: the calling thread only. Results are identical bit for bit.
    pub parallel: u32,
    /// The BRDF baked into an MRT set: `ANTUMBRA_TRANSFER_BRDF_PHONG` (the default)
    /// or `ANTUMBRA_TRANSFER_BRDF_WARD`; ignored by the other kinds.
    pub brdf: u32,
    /// The BRDF's parameters (see the `ANTUMBRA_TRANSFER_BRDF_*` values). Default
    /// (16, 0): a Phong exponent of 16.
    pub brdf_params: [f32; 2],
    /// Diffuse albedo of the scene for the bounces, in [0, 1). Default 0.5.
    pub albedo: f32,
    /// Ray origins are moved this far along the normal (mesh units, finite, >= 0)
    /// against self-intersection. Default 1e-4, meant for meshes about a unit in
    /// size: scale it with yours (about 1e-4 of the bounding-box diagonal). The
    /// CLI's `antumbra bake --ray-offset` is this same distance with this default.
    pub ray_offset: f32,
    /// Must be 0 (keeps the seed 8-byte aligned without hidden padding).
    pub reserved: u32,
    /// Seed of the random streams: a bake is deterministic for a seed. Default 0.
    pub seed: u64,
}

#[cfg(feature = "std")]
pub(crate) const DEFAULT_OPTIONS: antumbra_transfer_options = antumbra_transfer_options {
    kind: ANTUMBRA_TRANSFER_KIND_DIFFUSE,
    bands: 4,
    grid: 8,
    rays: 256,
    bounces: 0,
    parallel: 1,
    brdf: ANTUMBRA_TRANSFER_BRDF_PHONG,
    brdf_params: [16.0, 0.0],
    albedo: 0.5,
    ray_offset: 1e-4,
    reserved: 0,
    seed: 0,
};

/// What a transfer set holds, from `antumbra_transfer_describe`.
///
/// Layout: fourteen 4-byte fields, then two `size_t`; 72 bytes on 64-bit
/// targets, 64 on 32-bit, no padding.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct antumbra_transfer_info {
    /// `ANTUMBRA_TRANSFER_KIND_*`.
    pub kind: u32,
    /// SH bands of the lighting.
    pub bands: u32,
    /// Lighting coefficients per channel, `bands²`; shading takes `3 *
    /// coeff_count` floats.
    pub coeff_count: u32,
    /// MRT grid side (0 for the other kinds).
    pub grid: u32,
    /// PCA components (per cluster) of a compressed MRT set; 0 when
    /// uncompressed.
    pub components: u32,
    /// Number of vertices (the length of every per-vertex array of shading).
    pub vertex_count: u32,
    /// Rays per vertex and pass of the bake.
    pub rays: u32,
    /// Interreflection bounces of the bake.
    pub bounces: u32,
    /// Scene albedo of the bounces.
    pub albedo: f32,
    /// The BRDF of an MRT set: `ANTUMBRA_TRANSFER_BRDF_*`, or 0 (none, or not
    /// described).
    pub brdf: u32,
    /// Its parameters.
    pub brdf_params: [f32; 2],
    /// Clusters of a compressed MRT set (1 for `antumbra_transfer_compress`,
    /// the requested count for `antumbra_transfer_compress_clustered`); 0 when
    /// uncompressed.
    pub clusters: u32,
    /// Lightmap atlas width in texels of a texel set (a lightmap from
    /// `antumbra_lightmap_bake` or a version-3 bake file; its entries' texels
    /// from `antumbra_transfer_texels`); 0 for a per-vertex set.
    pub atlas_width: u32,
    /// Lightmap atlas height in texels; 0 for a per-vertex set.
    pub atlas_height: u32,
    /// Always 0.
    pub reserved: u32,
    /// Bytes of the per-vertex data in memory (dense blocks, or the PCA's
    /// means, components, weights and, with several clusters, each vertex's
    /// cluster).
    pub data_bytes: usize,
    /// Bytes `antumbra_transfer_save` writes.
    pub file_bytes: usize,
}

/// The surface and viewer of `antumbra_transfer_shade`. Fill with
/// `antumbra_transfer_material_init`, then change fields (fields may be added at
/// the end in later versions). Its fields mean and default what those of
/// `antumbra_hemi_material` of the same names do: a white Lambertian surface
/// unless `specular` is set.
///
/// Outgoing radiance toward the viewer, per kind: diffuse: `albedo/π · Σ_j t_j
/// l_j` (t the transfer vector, l the lighting); glossy SH: `specular ·` the
/// transferred radiance convolved with a Phong lobe of `phong_exponent` about the
/// mirror direction (the 2002 baseline); MRT: `specular ·` the bilinear blend of
/// the baked node radiances (the BRDF is in the bake).
///
/// Layout: ten floats (40 bytes), then a pointer; 48 bytes on 64-bit targets, 44
/// on 32-bit, no padding.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct antumbra_transfer_material {
    /// Diffuse albedo (linear RGB, finite, >= 0), diffuse kind. Default (1, 1, 1).
    pub albedo: [f32; 3],
    /// Specular reflectance `ρ_s` (linear RGB, finite, >= 0) multiplying the
    /// glossy SH and MRT results. (0, 0, 0), the default, turns the glossy term
    /// off, so glossy SH and MRT sets (which hold only a glossy term) shade to
    /// black until it is set; (1, 1, 1) shows the baked lobe as it is.
    pub specular: [f32; 3],
    /// Phong exponent of the glossy SH run time (finite, >= 0); MRT bakes its
    /// BRDF and ignores it. Default 16.
    pub phong_exponent: f32,
    /// The viewer's world position, used when `view_directions` is NULL; finite.
    /// Default (0, 0, 0).
    pub eye: [f32; 3],
    /// NULL (the default: each vertex looks towards `eye`) or 3 floats per vertex:
    /// the direction from each vertex towards the viewer (finite, non-zero, any
    /// length), for orthographic or per-vertex views. Borrowed for the call only.
    pub view_directions: *const f32,
}

const DEFAULT_MATERIAL: antumbra_transfer_material = antumbra_transfer_material {
    albedo: [1.0; 3],
    specular: [0.0; 3],
    phong_exponent: 16.0,
    eye: [0.0; 3],
    view_directions: core::ptr::null(),
};

#[cfg(feature = "std")]
/// Progress of `antumbra_transfer_bake`: `done` of `total` vertex passes
/// (vertices × (1 + bounces)). With `options->parallel` = 1 it is called from the
/// library's worker threads, possibly at once and slightly out of order; it must
/// be thread-safe, return normally and not call back into Antumbra.
pub type antumbra_transfer_progress_fn =
    Option<unsafe extern "C" fn(done: usize, total: usize, user_data: *mut c_void)>;

/// A baked transfer set: kind, bands, grid, per-vertex positions and normals and
/// the per-vertex transfer data (dense, or PCA-compressed for MRT). Immutable and
/// opaque; created by `antumbra_transfer_bake`, `antumbra_transfer_load`,
/// `antumbra_transfer_compress` or `antumbra_transfer_compress_clustered`, freed
/// with `antumbra_transfer_destroy`.
pub struct antumbra_transfer {
    pub(crate) set: TransferSet,
    poisoned: AtomicBool,
}

// Info, save, compress and shade take `&antumbra_transfer` from many threads.
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<antumbra_transfer>();
};

#[cfg(feature = "std")]
/// Writes the default bake options: diffuse kind, 4 bands, grid 8, 256 rays, no
/// bounces, parallel, a Phong BRDF of exponent 16 (MRT), albedo 0.5, ray offset
/// 1e-4, seed 0.
///
/// @param options the options to fill; every field is written.
///
/// On a NULL or misaligned pointer nothing is written, and the thread's last error
/// message and the error callback report ANTUMBRA_RESULT_NULL_ARGUMENT or
/// ANTUMBRA_RESULT_INVALID_ARGUMENT.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `options` must be NULL or valid for writing one `antumbra_transfer_options`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_options_init(options: *mut antumbra_transfer_options) {
    let _ = guard("antumbra_transfer_options_init", || {
        raw::write_one(options, DEFAULT_OPTIONS, "options")
    });
}

/// Writes the default material, that of `antumbra_hemi_material_init`: albedo
/// (1, 1, 1), no glossy term (specular 0), Phong exponent 16, eye at the origin,
/// no per-vertex view directions. Set `specular` to shade glossy SH and MRT sets.
///
/// @param material the material to fill; every field is written.
///
/// On a NULL or misaligned pointer nothing is written, and the thread's last error
/// message and the error callback report ANTUMBRA_RESULT_NULL_ARGUMENT or
/// ANTUMBRA_RESULT_INVALID_ARGUMENT.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `material` must be NULL or valid for writing one `antumbra_transfer_material`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_material_init(
    material: *mut antumbra_transfer_material,
) {
    let _ = guard("antumbra_transfer_material_init", || {
        raw::write_one(material, DEFAULT_MATERIAL, "material")
    });
}

#[cfg(feature = "std")]
/// The BRDF an MRT bake uses, chosen from the options.
enum BakeBrdf {
    Phong(PhongBrdf),
    Ward(WardBrdf),
}

#[cfg(feature = "std")]
impl BakeBrdf {
    fn as_dyn(&self) -> &dyn Brdf {
        match self {
            BakeBrdf::Phong(b) => b,
            BakeBrdf::Ward(b) => b,
        }
    }
}

fn finite_in(value: f32, argument: &str, ok: bool, range: &str) -> Result<(), Error> {
    if !value.is_finite() {
        return Err(Error::new(
            ANTUMBRA_RESULT_NON_FINITE,
            message!("{argument} is {value}; it must be finite"),
        ));
    }
    if !ok {
        return Err(Error::invalid(message!(
            "{argument} is {value}; expected {range}"
        )));
    }
    Ok(())
}

#[cfg(feature = "std")]
/// Validates the options, naming the field; returns the BRDF for an MRT bake.
fn check_options(o: &antumbra_transfer_options) -> Result<Option<BakeBrdf>, Error> {
    if !(ANTUMBRA_TRANSFER_KIND_DIFFUSE..=ANTUMBRA_TRANSFER_KIND_MRT).contains(&o.kind) {
        return Err(Error::invalid(message!(
            "options->kind is {}; expected ANTUMBRA_TRANSFER_KIND_DIFFUSE (1), _GLOSSY_SH (2) \
             or _MRT (3)",
            o.kind
        )));
    }
    if !(1..=ANTUMBRA_SH_MAX_BANDS).contains(&o.bands) {
        return Err(Error::invalid(message!(
            "options->bands is {}; expected 1 to {ANTUMBRA_SH_MAX_BANDS}",
            o.bands
        )));
    }
    if !(1..=ANTUMBRA_TRANSFER_MAX_RAYS).contains(&o.rays) {
        return Err(Error::invalid(message!(
            "options->rays is {}; expected 1 to {ANTUMBRA_TRANSFER_MAX_RAYS}",
            o.rays
        )));
    }
    if o.bounces > ANTUMBRA_TRANSFER_MAX_BOUNCES {
        return Err(Error::invalid(message!(
            "options->bounces is {}; expected 0 to {ANTUMBRA_TRANSFER_MAX_BOUNCES}",
            o.bounces
        )));
    }
    if o.parallel > 1 {
        return Err(Error::invalid(message!(
            "options->parallel is {}; expected 0 or 1",
            o.parallel
        )));
    }
    if o.reserved != 0 {
        return Err(Error::invalid(message!(
            "options->reserved is {}; it must be 0",
            o.reserved
        )));
    }
    finite_in(
        o.albedo,
        "options->albedo",
        (0.0..1.0).contains(&o.albedo),
        "a value in [0, 1)",
    )?;
    finite_in(
        o.ray_offset,
        "options->ray_offset",
        o.ray_offset >= 0.0,
        "a value >= 0",
    )?;
    if o.kind != ANTUMBRA_TRANSFER_KIND_MRT {
        return Ok(None);
    }
    if !(2..=ANTUMBRA_TRANSFER_MAX_GRID).contains(&o.grid) {
        return Err(Error::invalid(message!(
            "options->grid is {}; expected 2 to {ANTUMBRA_TRANSFER_MAX_GRID} for an MRT bake",
            o.grid
        )));
    }
    let [p0, p1] = o.brdf_params;
    match o.brdf {
        ANTUMBRA_TRANSFER_BRDF_PHONG => {
            finite_in(
                p0,
                "options->brdf_params[0] (Phong exponent)",
                p0 >= 0.0,
                "a value >= 0",
            )?;
            let brdf = PhongBrdf::new(p0).ok_or_else(|| {
                Error::invalid(message!(
                    "options->brdf_params[0] {p0} is not a Phong exponent"
                ))
            })?;
            Ok(Some(BakeBrdf::Phong(brdf)))
        }
        ANTUMBRA_TRANSFER_BRDF_WARD => {
            for (i, a) in [p0, p1].into_iter().enumerate() {
                finite_in(
                    a,
                    &message!("options->brdf_params[{i}] (Ward roughness)"),
                    a > 0.0 && a <= 1.0,
                    "a value in (0, 1]",
                )?;
            }
            let brdf = WardBrdf::new(p0, p1).ok_or_else(|| {
                Error::invalid(message!(
                    "options->brdf_params ({p0}, {p1}) are not Ward roughnesses"
                ))
            })?;
            Ok(Some(BakeBrdf::Ward(brdf)))
        }
        other => Err(Error::invalid(message!(
            "options->brdf is {other}; expected ANTUMBRA_TRANSFER_BRDF_PHONG (1) or \
             ANTUMBRA_TRANSFER_BRDF_WARD (2) for an MRT bake"
        ))),
    }
}

#[cfg(feature = "std")]
/// The caller's normals (validated) or the area-weighted ones of `mesh`.
///
/// # Safety
/// `normals` must be NULL or valid for `3 * mesh.vertex_count()` floats.
pub(crate) unsafe fn bake_normals(
    mesh: &MeshView<'_>,
    normals: *const f32,
) -> Result<Vec<Vec3>, Error> {
    let vertices = mesh.vertex_count();
    let mut out = Vec::new();
    out.try_reserve_exact(vertices).map_err(|e| {
        Error::new(
            ANTUMBRA_RESULT_OUT_OF_MEMORY,
            message!("no memory for {vertices} normals: {e}"),
        )
    })?;
    if normals.is_null() {
        out.resize(vertices, Vec3::ZERO);
        vertex_normals(mesh, &mut out).map_err(|e| Error::invalid(message!("{e}")))?;
        if let Some(v) = out.iter().position(|n| *n == Vec3::ZERO) {
            return Err(Error::invalid(message!(
                "normals is NULL and vertex {v} has no area-weighted normal (it is used by \
                 no triangle, or only by degenerate ones); pass normals"
            )));
        }
        return Ok(out);
    }
    let xyz = raw::element_count(vertices, 3, "mesh->vertex_count")?;
    // SAFETY: caller contract on `normals`.
    let given = unsafe { raw::slice(normals, xyz, "normals") }?;
    for (v, n) in given.chunks_exact(3).enumerate() {
        let n = Vec3::from_slice(n);
        if !n.is_finite() {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!("normals[{v}] ({}, {}, {}) is not finite", n.x, n.y, n.z),
            ));
        }
        let length = n.length();
        if (length - 1.0).abs() > UNIT_TOLERANCE {
            return Err(Error::invalid(message!(
                "normals[{v}] has length {length}, not 1 (tolerance {UNIT_TOLERANCE})"
            )));
        }
        out.push(n);
    }
    Ok(out)
}

#[cfg(feature = "std")]
/// Forwards core's progress to the C callback.
struct ProgressSink {
    callback: unsafe extern "C" fn(usize, usize, *mut c_void),
    user_data: *mut c_void,
}

// SAFETY: the caller promises the callback may be called from any thread with its
// `user_data` (documented on `antumbra_transfer_progress_fn`).
#[cfg(feature = "std")]
unsafe impl Sync for ProgressSink {}

#[cfg(feature = "std")]
impl ProgressSink {
    fn report(&self, done: usize, total: usize) {
        // SAFETY: the caller registered this function for this bake.
        unsafe { (self.callback)(done, total, self.user_data) };
    }
}

#[cfg(feature = "std")]
fn bake_error(error: BakeError) -> Error {
    let field = match error {
        BakeError::Bands(_) => "options->bands",
        BakeError::Rays(_) => "options->rays",
        BakeError::Bounces(_) => "options->bounces",
        BakeError::Albedo(_) => "options->albedo",
        BakeError::RayOffset(_) => "options->ray_offset",
        BakeError::Grid(_) => "options->grid",
        BakeError::NormalCount { .. } | BakeError::Normal { .. } => "normals",
        BakeError::TooManyVertices(_) | BakeError::NoVertices | BakeError::VertexRange { .. } => {
            "mesh->vertex_count"
        }
        BakeError::BrdfNotFinite => "options->brdf_params",
        // The C API bakes vertices only.
        BakeError::Point { .. } => "points",
        BakeError::TooLarge { .. } => {
            return Error::new(
                ANTUMBRA_RESULT_OUT_OF_MEMORY,
                message!("mesh and options: {error}"),
            );
        }
    };
    Error::invalid(message!("{field}: {error}"))
}

pub(crate) fn boxed(set: TransferSet, out: *mut *mut antumbra_transfer) -> Result<(), Error> {
    let handle = crate::fallible::boxed(
        antumbra_transfer {
            set,
            poisoned: AtomicBool::new(false),
        },
        "the transfer handle",
    )?;
    // SAFETY: the exports check `out` non-NULL and aligned before any work, and
    // the caller promises it is valid for a pointer write.
    unsafe { *out = Box::into_raw(handle) };
    Ok(())
}

pub(crate) fn check_out(
    out: *mut *mut antumbra_transfer,
) -> Result<*mut *mut antumbra_transfer, Error> {
    if out.is_null() {
        return Err(Error::null("out"));
    }
    raw::writable(out, 1, "out")
}

#[cfg(feature = "std")]
/// Bakes the transfer of every vertex of a mesh: rays cast from each vertex over
/// its hemisphere against the mesh itself (a BVH built for the call), for every
/// lighting coefficient at once, with `options->bounces` diffuse interreflections.
///
/// @param mesh the triangles (at least one); every vertex must be used by a
///        triangle unless `normals` are given. Same rules as `antumbra_scene_create`.
/// @param normals NULL (area-weighted vertex normals are computed) or 3 floats per
///        vertex: unit normals (finite, length within 1e-3 of 1) defining each
///        vertex's hemisphere and frame.
/// @param options what to measure; NULL is not allowed (fill one with
///        `antumbra_transfer_options_init`).
/// @param progress NULL or a function told of progress (see
///        `antumbra_transfer_progress_fn`).
/// @param user_data passed to `progress` untouched.
/// @param out receives the new transfer set on success; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (mesh, options, out, or an array of
///         `mesh` with a non-zero count); INVALID_ARGUMENT (an option out of range,
///         naming it; no triangles; an unused vertex without given normals; a
///         normal not unit length; misaligned pointer; coordinate beyond ±1e12);
///         INDEX_OUT_OF_RANGE (mesh->indices); NON_FINITE (positions, normals,
///         albedo, ray_offset, BRDF parameters); OUT_OF_MEMORY (the normals or
///         the BVH's triangle arrays could not be reserved; the bake's result
///         arrays, sized below, abort the process on exhaustion, as Rust
///         allocations do); PANIC.
///
/// Cost: vertices × (1 + bounces) × rays rays; memory per vertex `4 bands²` bytes
/// (diffuse), `4 bands⁴` (glossy SH), `4 grid² bands²` (MRT).
/// Ownership: the caller owns `*out` and frees it with `antumbra_transfer_destroy`;
/// the mesh and normals are borrowed for the call only.
/// Thread safety: safe from any thread; the new set is independent of others.
///
/// # Safety
/// Pointers must be NULL or valid as described; the arrays in `mesh` valid for the
/// counts and stride it gives.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_bake(
    mesh: *const antumbra_mesh_view,
    normals: *const f32,
    options: *const antumbra_transfer_options,
    progress: antumbra_transfer_progress_fn,
    user_data: *mut c_void,
    out: *mut *mut antumbra_transfer,
) -> antumbra_result {
    guard("antumbra_transfer_bake", || {
        let out = check_out(out)?;
        // SAFETY: caller contract on `mesh`.
        let view = unsafe { raw::reference(mesh, "mesh") }?;
        // SAFETY: caller contract on `options`.
        let options = unsafe { raw::reference(options, "options") }?;
        // SAFETY: caller contract on the arrays inside `mesh`.
        let mesh = unsafe { mesh_from_c(view, "mesh") }?;
        if mesh.triangle_count() == 0 {
            return Err(Error::invalid(
                "mesh->triangle_count is 0: a bake needs at least one triangle",
            ));
        }
        check_options(options)?;
        // SAFETY: caller contract on `normals`.
        let normals = unsafe { bake_normals(&mesh, normals) }?;
        let scene = scene_of(&mesh)?;
        let parallel = options.parallel == 1;
        let set = bake_with(options, progress, user_data, |bake_options| {
            if parallel {
                transfer::bake(&mesh, &normals, &scene, bake_options)
            } else {
                transfer::bake_serial(&mesh, &normals, &scene, bake_options)
            }
        })?;
        boxed(set, out)?;
        Ok(())
    })
}

/// The BVH of a bake's mesh, its errors named as the C API names them.
#[cfg(feature = "std")]
pub(crate) fn scene_of(mesh: &MeshView<'_>) -> Result<BvhScene, Error> {
    BvhScene::new(mesh).map_err(|e| crate::scene::scene_error(e, mesh))
}

/// Runs `bake` with the core options of `options` (checked) and the caller's
/// progress callback: the part of every C bake entry point after its inputs are
/// read.
#[cfg(feature = "std")]
pub(crate) fn bake_with(
    options: &antumbra_transfer_options,
    progress: antumbra_transfer_progress_fn,
    user_data: *mut c_void,
    bake: impl FnOnce(&BakeOptions<'_>) -> Result<TransferSet, BakeError>,
) -> Result<TransferSet, Error> {
    let brdf = check_options(options)?;
    let measurement = match (options.kind, &brdf) {
        (ANTUMBRA_TRANSFER_KIND_GLOSSY_SH, _) => Measurement::GlossySh,
        (ANTUMBRA_TRANSFER_KIND_MRT, Some(brdf)) => Measurement::Mrt {
            grid: options.grid,
            brdf: brdf.as_dyn(),
        },
        _ => Measurement::Diffuse,
    };
    let sink = progress.map(|callback| ProgressSink {
        callback,
        user_data,
    });
    let report = |done: usize, total: usize| {
        if let Some(sink) = &sink {
            sink.report(done, total);
        }
    };
    let bake_options = BakeOptions {
        measurement,
        bands: options.bands,
        rays: options.rays,
        bounces: options.bounces,
        albedo: options.albedo,
        ray_offset: options.ray_offset,
        seed: options.seed,
        progress: sink.as_ref().map(|_| &report as transfer::Progress<'_>),
    };
    bake(&bake_options).map_err(bake_error)
}

/// Frees a transfer set. NULL is a no-op.
///
/// Ownership: takes back a set from bake, load or compress; it must not be used
/// afterwards. Thread safety: needs exclusive access: no other call on this set
/// may be running.
///
/// # Safety
/// `transfer` must be NULL or a live set, destroyed at most once.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_destroy(transfer: *mut antumbra_transfer) {
    let _ = guard("antumbra_transfer_destroy", || {
        if !transfer.is_null() {
            // SAFETY: by contract, a live set created by `Box::into_raw`.
            drop(unsafe { Box::from_raw(transfer) });
        }
        Ok(())
    });
}

impl Poisonable for antumbra_transfer {
    const ARGUMENT: &'static str = "transfer";

    fn poison_flag(&self) -> &AtomicBool {
        &self.poisoned
    }
}

/// Describes a transfer set: kind, sizes, how it was baked, memory and file size.
///
/// @param transfer the set.
/// @param info receives the description; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (transfer, info); INVALID_ARGUMENT
///         (misaligned info); POISONED; PANIC.
///
/// Thread safety: any number of threads may use the same set at once.
///
/// # Safety
/// `transfer` must be NULL or a live set; `info` NULL or valid for one write.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_describe(
    transfer: *const antumbra_transfer,
    info: *mut antumbra_transfer_info,
) -> antumbra_result {
    with_handle("antumbra_transfer_describe", transfer, |t| {
        if info.is_null() {
            return Err(Error::null("info"));
        }
        let out = raw::writable(info, 1, "info")?;
        let set = &t.set;
        let baked = set.info();
        let value = antumbra_transfer_info {
            kind: set.kind() as u32,
            bands: set.bands(),
            coeff_count: set.coeff_count() as u32,
            grid: set.grid(),
            components: set.pca().map_or(0, |p| p.components() as u32),
            vertex_count: set.vertex_count() as u32,
            rays: baked.rays,
            bounces: baked.bounces,
            albedo: baked.albedo,
            brdf: baked.brdf.kind,
            brdf_params: baked.brdf.params,
            clusters: set.pca().map_or(0, |p| p.clusters() as u32),
            atlas_width: set.texels().map_or(0, |t| t.width()),
            atlas_height: set.texels().map_or(0, |t| t.height()),
            reserved: 0,
            data_bytes: set.data_bytes(),
            file_bytes: set.byte_len(),
        };
        // SAFETY: non-NULL, aligned (checked), valid by contract.
        unsafe { out.write(value) };
        Ok(())
    })
}

/// Copies the vertex positions and unit normals a set was baked with (world
/// frame; each vertex's shading frame is `antumbra_frame_from_normal` of its
/// normal), for drawing a loaded set or computing view directions.
///
/// @param transfer the set.
/// @param positions NULL (not wanted) or room for 3 floats per vertex.
/// @param normals NULL (not wanted) or room for 3 floats per vertex.
/// @param vertex_count the number of vertices the arrays hold; must equal the
///        set's (`antumbra_transfer_describe`'s `vertex_count`).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (transfer); INVALID_ARGUMENT
///         (vertex_count not the set's, misaligned array); POISONED; PANIC.
///         Outputs are untouched on failure.
///
/// Thread safety: any number of threads may use the same set at once.
///
/// # Safety
/// `transfer` must be NULL or a live set; each non-NULL array valid for `3 *
/// vertex_count` floats and not overlapping the other.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_geometry(
    transfer: *const antumbra_transfer,
    positions: *mut f32,
    normals: *mut f32,
    vertex_count: usize,
) -> antumbra_result {
    with_handle("antumbra_transfer_geometry", transfer, |t| {
        let set = &t.set;
        if vertex_count != set.vertex_count() {
            return Err(Error::invalid(message!(
                "vertex_count is {vertex_count}; the set has {} vertices",
                set.vertex_count()
            )));
        }
        let xyz = raw::element_count(vertex_count, 3, "vertex_count")?;
        let targets = [
            (positions, set.positions(), "positions"),
            (normals, set.normals(), "normals"),
        ];
        for (pointer, _, name) in targets {
            if !pointer.is_null() {
                raw::writable(pointer, xyz, name)?;
            }
        }
        for (pointer, values, _) in targets {
            if !pointer.is_null() {
                let flat: &[f32] = bytemuck::cast_slice(values);
                // SAFETY: non-NULL, aligned and sized (checked above); the caller
                // promises validity and no overlap with the set's own memory.
                unsafe { core::ptr::copy_nonoverlapping(flat.as_ptr(), pointer, flat.len()) };
            }
        }
        Ok(())
    })
}

/// Writes a transfer set as a bake file (docs/bake-format.md: a 72-byte header
/// with magic, version, kind, bands, grid, K, counts and CRC-32 checksums, then
/// little-endian floats; version 2, with a 76-byte header, for a clustered PCA
/// only; version 3, with an 84-byte header and each entry's texel, for a
/// lightmap) into a caller buffer.
///
/// @param transfer the set.
/// @param buffer destination of `capacity` bytes; may be NULL when `capacity` is 0
///        (to ask for the size).
/// @param capacity size of `buffer` in bytes.
/// @param size if not NULL, receives the bytes written on success, or the bytes
///        needed on ANTUMBRA_RESULT_BUFFER_TOO_SMALL (also
///        `antumbra_transfer_describe`'s `file_bytes`).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (transfer; buffer with capacity > 0);
///         INVALID_ARGUMENT (misaligned size); BUFFER_TOO_SMALL (nothing written
///         to `buffer`); OUT_OF_MEMORY; POISONED; PANIC.
///
/// Cost: writes the file straight into `buffer`; allocates nothing.
/// Thread safety: any number of threads may use the same set at once.
///
/// # Safety
/// `buffer` must be NULL or valid for `capacity` bytes; `size` NULL or valid.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_save(
    transfer: *const antumbra_transfer,
    buffer: *mut u8,
    capacity: usize,
    size: *mut usize,
) -> antumbra_result {
    with_handle("antumbra_transfer_save", transfer, |t| {
        let buffer = raw::writable(buffer, capacity, "buffer")?;
        let size = if size.is_null() {
            None
        } else {
            Some(raw::writable(size, 1, "size")?)
        };
        let needed = t.set.byte_len();
        let report = |value: usize| {
            if let Some(size) = size {
                // SAFETY: non-NULL, aligned (checked), valid by contract.
                unsafe { size.write(value) };
            }
        };
        if capacity < needed {
            report(needed);
            return Err(Error::new(
                ANTUMBRA_RESULT_BUFFER_TOO_SMALL,
                message!("capacity is {capacity} bytes; the file needs {needed}"),
            ));
        }
        // SAFETY: `buffer` is valid for `capacity >= needed` bytes of writes by
        // the caller's contract and cannot overlap the library-owned set.
        let out = unsafe { core::slice::from_raw_parts_mut(buffer, needed) };
        // Written in place: saving allocates nothing.
        t.set.write_to(out);
        report(needed);
        Ok(())
    })
}

fn format_error(error: FormatError) -> Error {
    let code = match error {
        FormatError::OutOfMemory { .. } => ANTUMBRA_RESULT_OUT_OF_MEMORY,
        _ => ANTUMBRA_RESULT_INVALID_DATA,
    };
    Error::new(code, message!("bytes: {error}"))
}

/// Reads a bake file (as written by `antumbra_transfer_save` or the `antumbra
/// bake` command) and validates everything: length, magic, version, header
/// checksum, every header field, the payload length (before allocating), the
/// payload checksum and every value.
///
/// @param bytes the file's contents, `len` bytes; no alignment needed.
/// @param len its length.
/// @param out receives the new transfer set on success; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (bytes with len > 0, out);
///         INVALID_ARGUMENT (misaligned out); INVALID_DATA (truncated, bad magic,
///         unsupported version, a field out of range, checksum mismatch, trailing
///         bytes, a non-finite value, a vertex's cluster out of range; the
///         message names the field); OUT_OF_MEMORY
///         (nothing is kept); PANIC.
///
/// Cost: allocates the set: about the file's size plus 36 bytes per vertex (the
/// vertex frames).
/// Ownership: the caller owns `*out` (free with `antumbra_transfer_destroy`);
/// `bytes` is borrowed for the call only.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `bytes` must be NULL or valid for `len` bytes; `out` NULL or valid.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_load(
    bytes: *const u8,
    len: usize,
    out: *mut *mut antumbra_transfer,
) -> antumbra_result {
    guard("antumbra_transfer_load", || {
        let out = check_out(out)?;
        // SAFETY: caller contract on `bytes`.
        let bytes = unsafe { raw::slice(bytes, len, "bytes") }?;
        let set = TransferSet::from_bytes(bytes).map_err(format_error)?;
        boxed(set, out)?;
        Ok(())
    })
}

#[cfg(feature = "std")]
/// PCA-compresses an uncompressed MRT set: a mean and `components` principal
/// components of the per-vertex matrices, `components` weights per vertex.
/// Shading the result costs `4 (K + 1)` RGB multiply-adds per vertex after `K + 1`
/// per-frame products; with all components it reproduces the uncompressed set
/// to float precision.
///
/// @param transfer an uncompressed MRT set.
/// @param components K, 1 to min(grid² bands², vertex count).
/// @param out receives the new compressed set; untouched on failure. The source
///        set is unchanged.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (transfer, out); INVALID_ARGUMENT
///         (not an uncompressed MRT set, components out of range, misaligned out);
///         POISONED; PANIC.
///
/// Cost: about 64 · vertices · grid² bands² · K multiply-adds; deterministic.
/// Ownership: the caller owns `*out`.
/// Thread safety: any number of threads may use the same source set at once.
///
/// # Safety
/// `transfer` must be NULL or a live set; `out` NULL or valid.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_compress(
    transfer: *const antumbra_transfer,
    components: u32,
    out: *mut *mut antumbra_transfer,
) -> antumbra_result {
    compress_into("antumbra_transfer_compress", transfer, 1, components, out)
}

#[cfg(feature = "std")]
/// Clustered-PCA-compresses an uncompressed MRT set (Sloan et al. 2003): the
/// vertices are split into `clusters` groups whose matrices are alike, and each
/// group gets its own mean and `components` principal components, so the same
/// K reconstructs far better than one global PCA when the vertex frames point
/// every way. Shading costs the same per vertex as `antumbra_transfer_compress`
/// (`4 (K + 1)` RGB multiply-adds) plus `clusters (K + 1)` per-frame products per
/// grid node. With `clusters` = 1 the result equals `antumbra_transfer_compress`.
/// Saved as bake-file version 2 when `clusters` > 1.
///
/// @param transfer an uncompressed MRT set.
/// @param clusters C, 1 to the vertex count.
/// @param components K per cluster, 1 to min(grid² bands², vertex count).
/// @param out receives the new compressed set; untouched on failure. The source
///        set is unchanged.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (transfer, out); INVALID_ARGUMENT
///         (not an uncompressed MRT set, clusters or components out of range,
///         misaligned out); POISONED; PANIC.
///
/// Cost: about three global PCAs (`antumbra_transfer_compress`), plus at most
/// 4 k-means rounds of vertices · C · grid² bands² and 8 reclassifications of
/// vertices · C · (K + 1) · grid² bands² multiply-adds; deterministic (the
/// clustering's seed is fixed).
/// Ownership: the caller owns `*out`.
/// Thread safety: any number of threads may use the same source set at once.
///
/// # Safety
/// `transfer` must be NULL or a live set; `out` NULL or valid.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_compress_clustered(
    transfer: *const antumbra_transfer,
    clusters: u32,
    components: u32,
    out: *mut *mut antumbra_transfer,
) -> antumbra_result {
    compress_into(
        "antumbra_transfer_compress_clustered",
        transfer,
        clusters,
        components,
        out,
    )
}

#[cfg(feature = "std")]
/// Both compressions (one cluster is the global PCA, as in core), reported
/// under `function`'s name.
fn compress_into(
    function: &'static str,
    transfer: *const antumbra_transfer,
    clusters: u32,
    components: u32,
    out: *mut *mut antumbra_transfer,
) -> antumbra_result {
    with_handle(function, transfer, |t| {
        let out = check_out(out)?;
        let set = t
            .set
            .compress_clustered(clusters as usize, components as usize, 0)
            .map_err(|e| pca_error(&t.set, e))?;
        boxed(set, out)?;
        Ok(())
    })
}

#[cfg(feature = "std")]
/// The message of a failed compression, naming the argument.
fn pca_error(set: &TransferSet, e: PcaError) -> Error {
    match e {
        PcaError::NotDenseMrt => Error::invalid(message!(
            "transfer: {e} (this set is kind {}{})",
            set.kind() as u32,
            if set.pca().is_some() {
                ", already compressed"
            } else {
                ""
            }
        )),
        PcaError::Components { .. } => Error::invalid(message!("components: {e}")),
        PcaError::Clusters { .. } => Error::invalid(message!("clusters: {e}")),
    }
}

/// Validates the material's values and borrows its view directions.
///
/// # Safety
/// `m.view_directions` must be NULL or valid for `3 * vertices` floats.
unsafe fn read_material<'a>(
    m: &antumbra_transfer_material,
    vertices: usize,
) -> Result<(Material, View<'a>), Error> {
    for (name, rgb) in [
        ("material->albedo", m.albedo),
        ("material->specular", m.specular),
    ] {
        for (i, c) in rgb.into_iter().enumerate() {
            finite_in(c, &message!("{name}[{i}]"), c >= 0.0, "a value >= 0")?;
        }
    }
    finite_in(
        m.phong_exponent,
        "material->phong_exponent",
        m.phong_exponent >= 0.0,
        "a value >= 0",
    )?;
    let view = if m.view_directions.is_null() {
        if let Some(i) = m.eye.iter().position(|c| !c.is_finite()) {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!("material->eye[{i}] is {}; it must be finite", m.eye[i]),
            ));
        }
        View::Eye(m.eye)
    } else {
        let xyz = raw::element_count(vertices, 3, "vertex_count")?;
        // SAFETY: caller contract on `view_directions`.
        let d = unsafe { raw::slice(m.view_directions, xyz, "material->view_directions") }?;
        let d: &[[f32; 3]] = bytemuck::cast_slice(d);
        for (v, d) in d.iter().enumerate() {
            if !d.iter().all(|c| c.is_finite()) {
                return Err(Error::new(
                    ANTUMBRA_RESULT_NON_FINITE,
                    message!(
                        "material->view_directions[{v}] ({}, {}, {}) is not finite",
                        d[0],
                        d[1],
                        d[2]
                    ),
                ));
            }
            if d.iter().all(|&c| c == 0.0) {
                return Err(Error::invalid(message!(
                    "material->view_directions[{v}] is the zero vector"
                )));
            }
        }
        View::Directions(d)
    };
    let material = Material {
        albedo: m.albedo,
        specular: m.specular,
        phong_exponent: m.phong_exponent,
    };
    Ok((material, view))
}

/// Relights every vertex of a transfer set: RGB radiance toward the viewer under
/// SH lighting (see `antumbra_transfer_material` for the formula of each kind).
///
/// @param transfer the set.
/// @param lighting `3 * bands²` floats, finite: the bands² red SH coefficients of
///        the distant lighting (world frame), then green, then blue, as written by
///        `antumbra_sh_project_equirect` and `antumbra_sh_rotate`.
/// @param lighting_count the number of floats in `lighting`; must be `3 *
///        info.coeff_count`.
/// @param material the surface and viewer; NULL means the defaults of
///        `antumbra_transfer_material_init`.
/// @param components for a PCA-compressed MRT set, how many components to use (the
///        run-time quality knob; values above the baked count use all of them); 0
///        = all. Ignored by uncompressed sets.
/// @param rgb receives 3 floats per vertex; untouched on failure. Must not overlap
///        the inputs.
/// @param vertex_count the number of vertices `rgb` (and
///        `material->view_directions`) holds; must equal `info.vertex_count`.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (transfer, lighting, rgb,
///         view_directions with vertices); INVALID_ARGUMENT (lighting_count or
///         vertex_count not the set's, a negative material value, a zero view
///         direction, misaligned array); NON_FINITE (lighting, material values,
///         eye, view directions, naming the index); POISONED; PANIC.
///
/// Cost per vertex: 3 bands² multiply-adds (diffuse), about bands⁴ + 3 bands²
/// (glossy SH), 7 bands² (MRT), 4 (K + 1) RGB multiply-adds after C (K + 1)
/// per-frame products per grid node (MRT from PCA, C clusters). A compressed set
/// allocates one per-frame buffer of C grid² (K + 1) RGB values; the others
/// allocate nothing.
/// Thread safety: any number of threads may shade the same set at once.
///
/// # Safety
/// Pointers must be NULL or valid for the counts described.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_shade(
    transfer: *const antumbra_transfer,
    lighting: *const f32,
    lighting_count: usize,
    material: *const antumbra_transfer_material,
    components: u32,
    rgb: *mut f32,
    vertex_count: usize,
) -> antumbra_result {
    with_handle("antumbra_transfer_shade", transfer, |t| {
        let set = &t.set;
        let n = set.coeff_count();
        if lighting.is_null() {
            return Err(Error::null("lighting"));
        }
        if lighting_count != 3 * n {
            return Err(Error::invalid(message!(
                "lighting_count is {lighting_count}; the set has {} bands and needs \
                 3 * {n} = {} floats",
                set.bands(),
                3 * n
            )));
        }
        // SAFETY: caller contract on `lighting`.
        let l = unsafe { raw::slice(lighting, lighting_count, "lighting") }?;
        if let Some(i) = l.iter().position(|c| !c.is_finite()) {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!(
                    "lighting[{i}] (channel {}, coefficient {}) is {}; it must be finite",
                    ["red", "green", "blue"][i / n],
                    i % n,
                    l[i]
                ),
            ));
        }
        let vertices = set.vertex_count();
        if vertex_count != vertices {
            return Err(Error::invalid(message!(
                "vertex_count is {vertex_count}; the set has {vertices} vertices"
            )));
        }
        let m = if material.is_null() {
            &DEFAULT_MATERIAL
        } else {
            // SAFETY: caller contract on `material`.
            unsafe { raw::reference(material, "material") }?
        };
        // SAFETY: caller contract on `material->view_directions`.
        let (material, view) = unsafe { read_material(m, vertices) }?;
        if rgb.is_null() {
            return Err(Error::null("rgb"));
        }
        let xyz = raw::element_count(vertices, 3, "vertex_count")?;
        // SAFETY: caller contract: valid for 3 floats per vertex, no overlap.
        let out = unsafe { raw::slice_mut(rgb, xyz, "rgb") }?;
        let mut interleaved = [[0.0f32; 3]; MAX_COEFFS];
        for (j, c) in interleaved[..n].iter_mut().enumerate() {
            *c = [l[j], l[n + j], l[2 * n + j]];
        }
        let k = match components {
            0 => None,
            k => Some(k as usize),
        };
        set.shade(
            &interleaved[..n],
            view,
            &material,
            k,
            bytemuck::cast_slice_mut(out),
        )
        .map_err(|e| match e {
            ShadeError::NonFinite { argument } => Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!("material->{argument}: {e}"),
            ),
            ShadeError::OutOfMemory { .. } => {
                Error::new(ANTUMBRA_RESULT_OUT_OF_MEMORY, message!("{e}"))
            }
            other => Error::invalid(message!("{other}")),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panicking_call_poisons_the_set() {
        let positions = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let indices = [0u32, 1, 2];
        let view = antumbra_mesh_view {
            positions: positions.as_ptr(),
            vertex_count: 3,
            position_stride: 0,
            indices: indices.as_ptr(),
            triangle_count: 1,
        };
        let mut options = DEFAULT_OPTIONS;
        options.rays = 16;
        options.bands = 2;
        let mut set = std::ptr::null_mut();
        // SAFETY: live arrays and options, valid out pointer.
        let baked = unsafe {
            antumbra_transfer_bake(
                &view,
                std::ptr::null(),
                &options,
                None,
                std::ptr::null_mut(),
                &mut set,
            )
        };
        assert_eq!(baked, ANTUMBRA_RESULT_OK);
        let result = with_handle("test_query", set, |_| panic!("deliberate"));
        assert_eq!(result, ANTUMBRA_RESULT_PANIC);
        let mut info = antumbra_transfer_info::zeroed();
        // SAFETY: live set, valid out pointer.
        let later = unsafe { antumbra_transfer_describe(set, &mut info) };
        assert_eq!(later, ANTUMBRA_RESULT_POISONED);
        assert_eq!(info, antumbra_transfer_info::zeroed());
        // SAFETY: from bake, destroyed once.
        unsafe { antumbra_transfer_destroy(set) };
    }

    use bytemuck::Zeroable;
}
