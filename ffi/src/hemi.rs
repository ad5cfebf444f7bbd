//! Hemispherical rasterization for C callers (Kautz, Lehtinen and Aila 2004): the
//! 32×32 visibility mask of a batch of receivers against the current triangles of
//! a mesh, the cell directions external tools need to rebuild what a mask means,
//! and the optional caller-owned half-space table.
//!
//! The conventions are the design's fixed ones (hemi.md, "Conventions"): bit `i` of
//! `rows[j]` is cell `(i, j)`, set = occluded; cell centers
//! `u = (i + 0.5)/16 - 1`, `v = (j + 0.5)/16 - 1`; valid iff `u² + v² < 1`; invalid
//! cells always 0; the direction of a valid cell is `u t + v b + sqrt(1 - u² - v²) n`
//! in the frame of `antumbra_frame_from_normal`. Every mask equals, bit for bit,
//! `antumbra_core::hemi::rasterize_receiver` with the same inputs, whichever thread
//! computed it.

#[cfg(feature = "std")]
use alloc::boxed::Box;
use core::sync::atomic::{AtomicBool, Ordering};
#[cfg(feature = "std")]
use std::sync::{Mutex, OnceLock, PoisonError};

use antumbra_core::MeshView;
use antumbra_core::hemi::{
    self, BatchOptions, ClusteredMesh, HalfSpaceTable, HemiMask, HemiScene, Quality,
    TriangleClusters, VALID_CELL_COUNT, mask_batch,
};
use antumbra_core::raycast::MAX_COORDINATE;
use glam::Vec3;

use crate::boundary::{check_not_poisoned, guard};
use crate::error::Error;
use crate::frame::UNIT_TOLERANCE;
use crate::mesh::{antumbra_mesh_view, mesh_from_c};
use crate::raw;
use crate::result::*;

/// Cells per side of a hemisphere mask (and bits per row).
pub const ANTUMBRA_HEMI_GRID: u32 = 32;

/// Number of valid cells in a mask: those whose center satisfies `u² + v² < 1`.
pub const ANTUMBRA_HEMI_VALID_CELL_COUNT: u32 = 812;

/// `antumbra_hemi_options.quality`: half-space masks solved per row, exact at cell
/// centers (closed half-spaces: a cell exactly on a triangle's edge plane counts
/// as covered). The default.
pub const ANTUMBRA_HEMI_QUALITY_EXACT: u32 = 0;

/// `antumbra_hemi_options.quality`: half-space masks looked up in a precomputed,
/// octant-folded table (the paper's method) for mid-length edges, while edges too
/// short or too long for the table's precision are rasterized exactly: >= 99.8 % of
/// cells agree with Embree on the test meshes (speed against exact quality:
/// `antumbra bench hemi`).
pub const ANTUMBRA_HEMI_QUALITY_TABLE: u32 = 1;

/// Grid points per side of the default half-space table's octant of plane normals
/// (`128 × 129 × 128` bytes, about 2 MiB: each mask is stored with its bit-reversed
/// mirror image).
pub const ANTUMBRA_HEMI_TABLE_DEFAULT_RESOLUTION: u32 = 128;

/// Largest accepted table resolution (`1024 × 1025 × 128` bytes, about 128 MiB).
pub const ANTUMBRA_HEMI_TABLE_MAX_RESOLUTION: u32 = 1024;

const _: () = {
    assert!(ANTUMBRA_HEMI_GRID as usize == hemi::GRID);
    assert!(ANTUMBRA_HEMI_VALID_CELL_COUNT == VALID_CELL_COUNT);
    assert!(ANTUMBRA_HEMI_TABLE_DEFAULT_RESOLUTION == HalfSpaceTable::DEFAULT_RESOLUTION);
    assert!(ANTUMBRA_HEMI_TABLE_MAX_RESOLUTION == HalfSpaceTable::MAX_RESOLUTION);
    assert!(core::mem::size_of::<antumbra_hemi_mask>() == core::mem::size_of::<HemiMask>());
    assert!(core::mem::size_of::<antumbra_hemi_mask>() == 128);
};

/// The visibility of the hemisphere above one receiver: 32 rows of 32 bits. Bit `i`
/// of `rows[j]` is cell `(i, j)`; 1 = occluded (the ray from the center of
/// projection along the cell's direction hits a triangle at some t > 0), 0 = free.
/// Cells outside the unit disk (`u² + v² >= 1`, see `antumbra_hemi_cell_direction`)
/// are always 0. 128 bytes, 4-byte aligned, no padding.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct antumbra_hemi_mask {
    /// Row `j` of cells (`v = (j + 0.5)/16 - 1`); bit `i` is column `i`
    /// (`u = (i + 0.5)/16 - 1`).
    pub rows: [u32; 32],
}

impl From<HemiMask> for antumbra_hemi_mask {
    #[inline]
    fn from(mask: HemiMask) -> Self {
        antumbra_hemi_mask { rows: mask.rows }
    }
}

/// A half-space table owned by the caller, for `antumbra_hemi_options.table`:
/// `resolution × (resolution + 1) × 128` bytes of precomputed masks, immutable once
/// built. Opaque;
/// create with `antumbra_hemi_table_create`, free with `antumbra_hemi_table_destroy`.
pub struct antumbra_hemi_table {
    pub(crate) table: HalfSpaceTable,
    pub(crate) poisoned: AtomicBool,
}

// Rasterizations read a table from many threads; keep that true by construction.
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<antumbra_hemi_table>();
};

/// Options of `antumbra_hemi_rasterize`. Fill with `antumbra_hemi_options_init`,
/// then change fields: fields may be added at the end in later versions, and
/// `options_init` keeps old code correct.
///
/// Layout: 24 bytes on 64-bit targets, 20 on 32-bit, no padding.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct antumbra_hemi_options {
    /// `ANTUMBRA_HEMI_QUALITY_EXACT` (0, the default) or `ANTUMBRA_HEMI_QUALITY_TABLE` (1).
    pub quality: u32,
    /// 0 (the default): every triangle occludes, from either side. 1: skip
    /// triangles whose back (clockwise side) faces the center of projection; right
    /// for closed, consistently counter-clockwise meshes seen from outside, wrong
    /// for open meshes and receivers inside a closed one.
    pub cull_backfaces: u32,
    /// The center of projection is `position + normal_offset * normal` (mesh units;
    /// finite, 0 to 1e12). 0 (the default) is exact for receivers on the surface:
    /// the triangles around a receiver vertex are seen edge-on and block nothing;
    /// a small positive value lifts the center off the surface as ray tracers do
    /// (then the neighbours block grazing directions in concave regions).
    pub normal_offset: f32,
    /// 0 (the default): the whole batch runs on the calling thread. 1: receivers
    /// are split across the library's worker threads (a rayon pool of one thread
    /// per core, started on first use and kept for the life of the process). The
    /// masks are identical either way.
    pub parallel: u32,
    /// The table for `ANTUMBRA_HEMI_QUALITY_TABLE`; NULL (the default) uses the
    /// library's shared table of the default resolution, built on the first call
    /// that needs it (2 MiB, kept until the process exits). Ignored by the exact
    /// quality. Borrowed for the call only.
    pub table: *const antumbra_hemi_table,
}

pub(crate) const DEFAULT_OPTIONS: antumbra_hemi_options = antumbra_hemi_options {
    quality: ANTUMBRA_HEMI_QUALITY_EXACT,
    cull_backfaces: 0,
    normal_offset: 0.0,
    parallel: 0,
    table: core::ptr::null(),
};

/// Writes the default options: exact quality, no back-face culling, normal offset
/// 0, on the calling thread, the shared table.
///
/// @param options the options to fill; every field is written.
///
/// On a NULL or misaligned pointer nothing is written, and the thread's last error
/// message and the error callback report ANTUMBRA_RESULT_NULL_ARGUMENT or
/// ANTUMBRA_RESULT_INVALID_ARGUMENT.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `options` must be NULL or valid for writing one `antumbra_hemi_options`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_options_init(options: *mut antumbra_hemi_options) {
    let _ = guard("antumbra_hemi_options_init", || {
        if options.is_null() {
            return Err(Error::null("options"));
        }
        let out = raw::writable(options, 1, "options")?;
        // SAFETY: non-NULL and aligned (checked), valid for a write by contract.
        unsafe { out.write(DEFAULT_OPTIONS) };
        Ok(())
    });
}

#[cfg(feature = "std")]
/// Builds a half-space table that the caller owns, for `antumbra_hemi_options.table`.
///
/// @param resolution grid points per side of the octant of plane normals: 0 for
///        the default (`ANTUMBRA_HEMI_TABLE_DEFAULT_RESOLUTION`, 128), or 1 to
///        `ANTUMBRA_HEMI_TABLE_MAX_RESOLUTION` (1024; 1 is raised to 2). The table
///        takes `resolution × (resolution + 1) × 128` bytes; the pure table's wrong
///        cells per half-space mask halve with each doubling (1.64 on average at
///        128), and edges whose error would be too large are rasterized exactly.
/// @param out receives the new table on success; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (out); INVALID_ARGUMENT (resolution
///         above 1024, misaligned out); OUT_OF_MEMORY (the table's one allocation
///         failed); PANIC.
///
/// Building takes a few milliseconds at the default resolution (quadratic in it).
/// Ownership: the caller owns `*out` and frees it with `antumbra_hemi_table_destroy`.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `out` must be NULL or valid for writing one pointer.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_table_create(
    resolution: u32,
    out: *mut *mut antumbra_hemi_table,
) -> antumbra_result {
    guard("antumbra_hemi_table_create", || {
        if out.is_null() {
            return Err(Error::null("out"));
        }
        let out = raw::writable(out, 1, "out")?;
        let resolution = match resolution {
            0 => HalfSpaceTable::DEFAULT_RESOLUTION,
            r if r <= HalfSpaceTable::MAX_RESOLUTION => r,
            r => {
                return Err(Error::invalid(message!(
                    "resolution is {r}; expected 0 (the default) or 1 to {}",
                    HalfSpaceTable::MAX_RESOLUTION
                )));
            }
        };
        let table = build_table(resolution)?;
        let handle = Box::new(antumbra_hemi_table {
            table,
            poisoned: AtomicBool::new(false),
        });
        // SAFETY: non-NULL, aligned (checked), valid for a pointer write by contract.
        unsafe { out.write(Box::into_raw(handle)) };
        Ok(())
    })
}

#[cfg(feature = "std")]
/// Frees a table. NULL is a no-op.
///
/// Ownership: takes back a table from `antumbra_hemi_table_create`; it must not be
/// used afterwards. Thread safety: needs exclusive access: no rasterization using
/// this table may be running.
///
/// # Safety
/// `table` must be NULL or a live table from `antumbra_hemi_table_create`,
/// destroyed at most once.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_table_destroy(table: *mut antumbra_hemi_table) {
    let _ = guard("antumbra_hemi_table_destroy", || {
        if !table.is_null() {
            // SAFETY: by contract, a live table created by `Box::into_raw`.
            drop(unsafe { Box::from_raw(table) });
        }
        Ok(())
    });
}

#[cfg(feature = "std")]
fn build_table(resolution: u32) -> Result<HalfSpaceTable, Error> {
    HalfSpaceTable::try_new(resolution).map_err(|e| {
        Error::new(
            ANTUMBRA_RESULT_OUT_OF_MEMORY,
            message!(
                "no memory for a half-space table of {resolution}² masks ({} bytes): {e}",
                resolution as usize * resolution as usize * core::mem::size_of::<HemiMask>()
            ),
        )
    })
}

/// The library's shared table, built by the first call that needs it. A failed
/// build (out of memory) is not remembered: a later call tries again.
#[cfg(feature = "std")]
pub(crate) fn shared_table() -> Result<&'static HalfSpaceTable, Error> {
    static TABLE: OnceLock<HalfSpaceTable> = OnceLock::new();
    // Serialises the builds so concurrent first calls build one table, not one
    // each (the OnceLock alone cannot report an allocation failure).
    static BUILDING: Mutex<()> = Mutex::new(());
    if let Some(table) = TABLE.get() {
        return Ok(table);
    }
    let _building = BUILDING.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some(table) = TABLE.get() {
        return Ok(table);
    }
    let table = build_table(HalfSpaceTable::DEFAULT_RESOLUTION)?;
    Ok(TABLE.get_or_init(|| table))
}

/// Validated options, with the table resolved.
struct Settings<'t> {
    quality: Quality<'t>,
    cull_backfaces: bool,
    normal_offset: f32,
    /// Always false in the bare-metal build (refused by `check_options`).
    #[cfg_attr(not(feature = "std"), allow(dead_code))]
    parallel: bool,
}

pub(crate) fn flag(value: u32, argument: &str) -> Result<bool, Error> {
    match value {
        0 => Ok(false),
        1 => Ok(true),
        v => Err(Error::invalid(message!(
            "{argument} is {v}; expected 0 or 1"
        ))),
    }
}

/// Checks every field of `options` (the defaults when NULL); returns the user
/// table to use, if any, without resolving the shared one yet.
///
/// # Safety
/// `options` must be NULL or point to a valid `antumbra_hemi_options` whose `table`
/// is NULL or a live table.
unsafe fn read_options<'a>(
    options: *const antumbra_hemi_options,
) -> Result<(antumbra_hemi_options, Option<&'a antumbra_hemi_table>), Error> {
    let options = if options.is_null() {
        DEFAULT_OPTIONS
    } else {
        // SAFETY: non-NULL, so by contract a valid options struct.
        *unsafe { raw::reference(options, "options") }?
    };
    // SAFETY: forwarded contract on `options.table`.
    let table = unsafe { check_options(&options, "options->") }?;
    Ok((options, table))
}

/// Checks every field of `options`, naming them `{prefix}quality`, ... in
/// messages; returns the user table to use, if any (not the shared one).
///
/// # Safety
/// `options.table` must be NULL or a live table for `'a`.
pub(crate) unsafe fn check_options<'a>(
    options: &antumbra_hemi_options,
    prefix: &str,
) -> Result<Option<&'a antumbra_hemi_table>, Error> {
    if options.quality > ANTUMBRA_HEMI_QUALITY_TABLE {
        return Err(Error::invalid(message!(
            "{prefix}quality is {}; expected ANTUMBRA_HEMI_QUALITY_EXACT (0) or \
             ANTUMBRA_HEMI_QUALITY_TABLE (1)",
            options.quality
        )));
    }
    flag(options.cull_backfaces, &message!("{prefix}cull_backfaces"))?;
    flag(options.parallel, &message!("{prefix}parallel"))?;
    let offset = options.normal_offset;
    if !offset.is_finite() {
        return Err(Error::new(
            ANTUMBRA_RESULT_NON_FINITE,
            message!("{prefix}normal_offset is {offset}; it must be finite"),
        ));
    }
    if !(0.0..=MAX_COORDINATE).contains(&offset) {
        return Err(Error::invalid(message!(
            "{prefix}normal_offset is {offset}; expected 0 to {MAX_COORDINATE:e}"
        )));
    }
    #[cfg(not(feature = "std"))]
    {
        if options.quality == ANTUMBRA_HEMI_QUALITY_TABLE {
            return Err(Error::new(
                ANTUMBRA_RESULT_UNSUPPORTED,
                message!(
                    "{prefix}quality is ANTUMBRA_HEMI_QUALITY_TABLE, which the bare-metal \
                     build does not include (its table is 2 MiB); use \
                     ANTUMBRA_HEMI_QUALITY_EXACT"
                ),
            ));
        }
        if options.parallel == 1 {
            return Err(unsupported_parallel(&message!("{prefix}parallel")));
        }
    }
    if options.quality == ANTUMBRA_HEMI_QUALITY_TABLE && !options.table.is_null() {
        let argument = message!("{prefix}table");
        // SAFETY: non-NULL, so by contract a live table.
        let table = unsafe { raw::reference(options.table, &argument) }?;
        check_not_poisoned(&table.poisoned, &argument)?;
        Ok(Some(table))
    } else {
        Ok(None)
    }
}

/// The error for `parallel` = 1 in the bare-metal build, which has no threads.
#[cfg(not(feature = "std"))]
pub(crate) fn unsupported_parallel(argument: &str) -> Error {
    Error::new(
        ANTUMBRA_RESULT_UNSUPPORTED,
        message!("{argument} is 1, but the bare-metal build has no worker threads; use 0"),
    )
}

/// Hemisphere masks of a batch of receivers against every triangle of `mesh`.
///
/// For receiver k at `receiver_positions[3k..3k+3]` with unit normal
/// `receiver_normals[3k..3k+3]`, `masks[k]` gets bit `i` of `rows[j]` set when the
/// ray from the center of projection `o = position + options->normal_offset * normal`
/// along cell (i, j)'s direction (see `antumbra_hemi_cell_direction`, in the frame
/// of `antumbra_frame_from_normal`) hits a triangle at some t > 0; triangles are
/// two-sided unless `options->cull_backfaces` is set. Triangles entirely at or below
/// the receiver's horizon plane and triangles seen edge-on (including those with a
/// corner exactly at the center of projection) block nothing. Exact quality decides
/// each cell at its center (closed cones: a cell exactly on an edge plane counts
/// as covered, so shared edges leave no pinholes); table quality has a few wrong
/// cells along silhouette edges (about 99.7 % of cells agree with ray casting on a
/// typical closed mesh).
///
/// @param mesh the occluders; 0 triangles gives empty masks. Every index <
///        vertex_count; every position finite, and those used by triangles within
///        ±1e12; position_stride 0 (packed) or >= 12.
/// @param receiver_positions 3 floats per receiver, finite, within ±1e12.
/// @param receiver_normals 3 floats per receiver, finite, unit length within 1e-3
///        (used as given: normalise in float for the frame to be orthonormal).
/// @param receiver_count number of receivers; 0 is a valid empty batch (the three
///        arrays may then be NULL).
/// @param options NULL for the defaults (see `antumbra_hemi_options_init`), or
///        options with quality 0 or 1, cull_backfaces 0 or 1, parallel 0 or 1,
///        normal_offset finite in [0, 1e12], table NULL or a live table.
/// @param masks receives one mask per receiver; untouched on failure (except
///        after ANTUMBRA_RESULT_PANIC, an internal bug, when it may be partly
///        written). Must not overlap the inputs.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (mesh, or an array that is NULL with
///         a non-zero count); INVALID_ARGUMENT (an option out of its range,
///         misaligned array or options, stride below 12, count overflow, a
///         coordinate beyond ±1e12, a normal whose length is not 1 within 1e-3);
///         INDEX_OUT_OF_RANGE (a mesh index); NON_FINITE (NaN or infinite mesh
///         position, receiver position or normal, or normal_offset);
///         OUT_OF_MEMORY (the shared table could not be allocated on first use);
///         POISONED (options->table); PANIC (an internal bug; a user table in use
///         is poisoned).
///         Messages name the argument and the receiver index, e.g.
///         `receiver_normals[12] has length 0.5, not 1 (tolerance 0.001)`.
///
/// Cost: O(receivers × triangles above each receiver's horizon), no allocation per
/// receiver. A call with 32 or more receivers first groups the triangles into
/// clusters (about 110 ns and a few tens of bytes per triangle, freed on return), whose boxes
/// skip whole clusters below a receiver's horizon: the same masks, 1.5–2.5× less
/// time per receiver on closed meshes. The first call with
/// the table quality and no `options->table` builds the library's shared table
/// (2 MiB, a few milliseconds; once per process, kept until exit). Without
/// ANTUMBRA_HAS_STD (bare metal) the call never groups and allocates nothing;
/// the table quality and `parallel` = 1 are ANTUMBRA_RESULT_UNSUPPORTED there.
/// On x86-64 every rasterizing call (these, the transfer and shading calls and
/// the shader) runs an AVX2 or AVX-512 build of its loops where the processor
/// has one, with the same bits; the environment variable ANTUMBRA_HEMI_BUILD,
/// read once, caps it (`portable` or `avx2`: valgrind 3.19 stops at a
/// register move of the AVX2 build).
/// Ownership: borrows every argument for the call only.
/// Thread safety: any number of threads may rasterize at once, with the same or
/// different meshes, options and tables (all are only read).
///
/// # Safety
/// The arrays in `mesh` must be valid for the counts and stride it gives; each
/// non-NULL receiver array for `3 * receiver_count` floats; `masks` for
/// `receiver_count` masks; `options` NULL or valid.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_rasterize(
    mesh: *const antumbra_mesh_view,
    receiver_positions: *const f32,
    receiver_normals: *const f32,
    receiver_count: usize,
    options: *const antumbra_hemi_options,
    masks: *mut antumbra_hemi_mask,
) -> antumbra_result {
    let mut poison: Option<&AtomicBool> = None;
    let result = guard("antumbra_hemi_rasterize", || {
        // SAFETY: caller contract on `options` and its table.
        let (options, user_table) = unsafe { read_options(options) }?;
        poison = user_table.map(|t| &t.poisoned);
        // SAFETY: caller contract on `mesh` and its arrays.
        let view = unsafe { raw::reference(mesh, "mesh") }?;
        // SAFETY: as above.
        let mesh = unsafe { mesh_from_c(view, "mesh") }?;
        check_coordinate_range(&mesh, "mesh")?;
        // SAFETY: caller contract on the receiver arrays.
        let receivers =
            unsafe { Receivers::new(receiver_positions, receiver_normals, receiver_count) }?;
        // SAFETY: caller contract: valid for `receiver_count` masks, no overlap.
        let out = unsafe { raw::slice_mut(masks, receiver_count, "masks") }?;
        #[cfg(feature = "std")]
        let quality = match (options.quality, user_table) {
            (ANTUMBRA_HEMI_QUALITY_EXACT, _) => Quality::Exact,
            (_, Some(table)) => Quality::Table(&table.table),
            (_, None) if receiver_count == 0 => Quality::Exact,
            (_, None) => Quality::Table(shared_table()?),
        };
        // `check_options` refused the table quality.
        #[cfg(not(feature = "std"))]
        let quality = Quality::Exact;
        let settings = Settings {
            quality,
            cull_backfaces: options.cull_backfaces == 1,
            normal_offset: options.normal_offset,
            parallel: options.parallel == 1,
        };
        rasterize_batch(&mesh, &receivers, &settings, out);
        Ok(())
    });
    if result == ANTUMBRA_RESULT_PANIC
        && let Some(flag) = poison
    {
        flag.store(true, Ordering::Release);
    }
    result
}

/// The vertices used by triangles must lie within ±MAX_COORDINATE, so that corner
/// differences and their cross and triple products stay finite (a non-finite
/// product would silently cull the triangle).
pub(crate) fn check_coordinate_range(mesh: &MeshView<'_>, argument: &str) -> Result<(), Error> {
    match mesh
        .indices()
        .iter()
        .find(|&&v| mesh.position(v as usize).abs().max_element() > MAX_COORDINATE)
    {
        Some(&vertex) => Err(Error::invalid(message!(
            "{argument}->positions: vertex {vertex} has a coordinate beyond the supported range \
             of ±{MAX_COORDINATE:e}"
        ))),
        None => Ok(()),
    }
}

/// A batch of at least this many receivers groups the mesh's triangles into
/// clusters first, whose boxes skip whole clusters below a receiver's horizon (the
/// same masks). `antumbra bench hemi` prints the break-even point ("pays for
/// itself from N receivers"): about 5 on the armadillo, 9 on homer, 10 on the
/// bunny and 22 on the Chinese dragon of CGAL's data (grouping costs about 110 ns
/// per triangle; the saving per receiver depends on how much of the mesh lies
/// below its horizon). The threshold sits above the largest measured.
pub(crate) const CLUSTER_MIN_RECEIVERS: usize = 32;

/// Whether a batch of `receivers` over `triangles` groups them into clusters.
pub(crate) fn worth_clustering(receivers: usize, triangles: usize) -> bool {
    receivers >= CLUSTER_MIN_RECEIVERS && triangles > TriangleClusters::DEFAULT_SIZE
}

fn rasterize_batch(
    mesh: &MeshView<'_>,
    receivers: &Receivers<'_>,
    settings: &Settings<'_>,
    out: &mut [antumbra_hemi_mask],
) {
    // The bare-metal build never groups: its masks allocate nothing, and the
    // meshes it meets are small.
    let mut clusters = (cfg!(feature = "std")
        && worth_clustering(out.len(), mesh.triangle_count()))
    .then(|| TriangleClusters::new(mesh, TriangleClusters::DEFAULT_SIZE));
    let scene = HemiScene::new(match clusters.as_mut() {
        Some(c) => c.update(*mesh),
        None => ClusteredMesh::unclustered(*mesh),
    });
    let options = BatchOptions {
        quality: settings.quality,
        cull_backfaces: settings.cull_backfaces,
        normal_offset: settings.normal_offset,
        parallel: settings.parallel,
    };
    mask_batch(&scene, |k| receivers.get(k), &options, out);
}

/// Receiver positions and normals, validated once.
struct Receivers<'a> {
    positions: &'a [f32],
    normals: &'a [f32],
}

impl<'a> Receivers<'a> {
    /// # Safety
    /// Non-NULL pointers must be valid for `3 * count` floats for `'a`.
    unsafe fn new(positions: *const f32, normals: *const f32, count: usize) -> Result<Self, Error> {
        let xyz = raw::element_count(count, 3, "receiver_count")?;
        // SAFETY: caller contract forwarded.
        let positions = unsafe { raw::slice(positions, xyz, "receiver_positions") }?;
        // SAFETY: caller contract forwarded.
        let normals = unsafe { raw::slice(normals, xyz, "receiver_normals") }?;
        for k in 0..count {
            let p = Vec3::from_slice(&positions[3 * k..]);
            if !p.is_finite() {
                return Err(non_finite("receiver_positions", k, p));
            }
            if p.abs().max_element() > MAX_COORDINATE {
                return Err(Error::invalid(message!(
                    "receiver_positions[{k}] ({}, {}, {}) is beyond the supported range of \
                     ±{MAX_COORDINATE:e}",
                    p.x,
                    p.y,
                    p.z
                )));
            }
            let n = Vec3::from_slice(&normals[3 * k..]);
            if !n.is_finite() {
                return Err(non_finite("receiver_normals", k, n));
            }
            let length = n.length();
            if (length - 1.0).abs() > UNIT_TOLERANCE {
                return Err(Error::invalid(message!(
                    "receiver_normals[{k}] has length {length}, not 1 (tolerance {UNIT_TOLERANCE})"
                )));
            }
        }
        Ok(Receivers { positions, normals })
    }

    #[inline]
    fn get(&self, k: usize) -> (Vec3, Vec3) {
        (
            Vec3::from_slice(&self.positions[3 * k..]),
            Vec3::from_slice(&self.normals[3 * k..]),
        )
    }
}

pub(crate) fn non_finite(argument: &str, k: usize, v: Vec3) -> Error {
    Error::new(
        ANTUMBRA_RESULT_NON_FINITE,
        message!("{argument}[{k}] ({}, {}, {}) is not finite", v.x, v.y, v.z),
    )
}

/// The local direction of cell (i, j): `(u, v, sqrt(1 - u² - v²))` with
/// `u = (i + 0.5)/16 - 1`, `v = (j + 0.5)/16 - 1`, in the receiver frame
/// (tangent, bitangent, normal) of `antumbra_frame_from_normal`; the world
/// direction is `u * tangent + v * bitangent + z * normal`. Every coordinate is
/// exact except one correctly rounded square root, so `sqrtf(1 - u*u - v*v)`
/// in C gives the same bits.
///
/// @param i column, 0 to 31 (bit i of a mask row).
/// @param j row, 0 to 31 (`rows[j]` of a mask).
/// @param local_direction receives 3 floats (unit length up to rounding);
///        untouched on failure.
/// @return ANTUMBRA_RESULT_OK; INVALID_ARGUMENT when i or j is 32 or more, when
///         the cell's center lies outside the unit disk (`u² + v² >= 1`: an
///         invalid cell, always 0 in masks), or when local_direction is
///         misaligned; NULL_ARGUMENT (local_direction).
///
/// Thread safety: safe from any thread.
///
/// # Safety
/// `local_direction` must be NULL or valid for writing 3 floats.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_cell_direction(
    i: u32,
    j: u32,
    local_direction: *mut f32,
) -> antumbra_result {
    guard("antumbra_hemi_cell_direction", || {
        // SAFETY: caller contract: valid for 3 floats, aliasing nothing we read.
        let out = unsafe { raw::slice_mut(local_direction, 3, "local_direction") }?;
        if i >= ANTUMBRA_HEMI_GRID || j >= ANTUMBRA_HEMI_GRID {
            return Err(Error::invalid(message!(
                "cell ({i}, {j}) is outside the {ANTUMBRA_HEMI_GRID}x{ANTUMBRA_HEMI_GRID} grid"
            )));
        }
        let direction = hemi::cell_direction(i as usize, j as usize).ok_or_else(|| {
            let (u, v) = (
                hemi::cell_coordinate(i as usize),
                hemi::cell_coordinate(j as usize),
            );
            Error::invalid(message!(
                "cell ({i}, {j}) is outside the unit disk (u = {u}, v = {v}, u² + v² = {} >= 1)",
                u * u + v * v
            ))
        })?;
        out.copy_from_slice(&direction.to_array());
        Ok(())
    })
}

/// Writes the mask of every valid cell (the 812 cells whose center lies inside
/// the unit disk): the cells a mask can set. `ANTUMBRA_HEMI_VALID_CELL_COUNT`
/// bits are set.
///
/// @param mask receives the mask; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (mask); INVALID_ARGUMENT (misaligned).
///
/// Thread safety: safe from any thread.
///
/// # Safety
/// `mask` must be NULL or valid for writing one `antumbra_hemi_mask`.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_hemi_valid_mask(
    mask: *mut antumbra_hemi_mask,
) -> antumbra_result {
    guard("antumbra_hemi_valid_mask", || {
        if mask.is_null() {
            return Err(Error::null("mask"));
        }
        let out = raw::writable(mask, 1, "mask")?;
        // SAFETY: non-NULL, aligned (checked), valid for a write by contract.
        unsafe { out.write(HemiMask::VALID.into()) };
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_poisoned_user_table_is_refused() {
        let mut table = core::ptr::null_mut();
        // SAFETY: valid out pointer.
        let created = unsafe { antumbra_hemi_table_create(4, &mut table) };
        assert_eq!(created, ANTUMBRA_RESULT_OK);
        // What the export does after a panic with this table in use.
        // SAFETY: a live table.
        unsafe { &*table }.poisoned.store(true, Ordering::Release);
        let options = antumbra_hemi_options {
            quality: ANTUMBRA_HEMI_QUALITY_TABLE,
            table,
            ..DEFAULT_OPTIONS
        };
        let view = antumbra_mesh_view {
            positions: core::ptr::null(),
            vertex_count: 0,
            position_stride: 0,
            indices: core::ptr::null(),
            triangle_count: 0,
        };
        // SAFETY: an empty mesh and batch.
        let result = unsafe {
            antumbra_hemi_rasterize(
                &view,
                core::ptr::null(),
                core::ptr::null(),
                0,
                &options,
                core::ptr::null_mut(),
            )
        };
        assert_eq!(result, ANTUMBRA_RESULT_POISONED);
        // SAFETY: from create, destroyed once.
        unsafe { antumbra_hemi_table_destroy(table) };
    }
}
