//! Exact soft shadows from a planar area light for C callers: soft shadow volumes
//! (Laine et al. 2005) found through the lazily built 3D wedge hierarchy of
//! Lehtinen, Laine and Aila 2006 (thesis §2.4, §3.4), over `antumbra_core::ssv`.
//!
//! A handle (`antumbra_ssv`) owns the occluders' edges, the light, its samples and
//! the candidate-edge structure; `antumbra_ssv_query` answers, for each receiver
//! point, the N visibility bits: bit `i` (word `i / 64`, bit `i % 64`) is set when
//! no occluder triangle meets the open segment from the point to sample `i`. Every
//! bit equals `SoftShadows::query` with the same inputs, whichever structure and
//! thread computed it. The handle also counts the work its queries did (candidate
//! edges per query), read back with `antumbra_ssv_get_statistics`.

use alloc::boxed::Box;
use alloc::vec::Vec;
#[cfg(feature = "std")]
use core::sync::atomic::AtomicU64 as Counter;
use core::sync::atomic::{AtomicBool, Ordering};

use antumbra_core::raycast::MAX_COORDINATE;
use antumbra_core::ssv::{
    LightError, LightPolygon, MAX_LIGHT_VERTICES, MAX_SAMPLES, SamplePattern, SoftShadows,
    SsvError, SsvOptions, Structure,
};
use glam::Vec3;

use crate::boundary::{Poisonable, guard, with_handle, with_handle_mut};
use crate::error::Error;
use crate::fallible;
use crate::hemi::{check_coordinate_range, flag, non_finite};
use crate::mesh::{antumbra_mesh_view, mesh_from_c};
use crate::raw;
use crate::result::*;

/// `antumbra_ssv_options.structure`: the 2006 lazily built 3D hierarchy over
/// receiver space (one root-to-leaf walk per query). The default and the one to use.
pub const ANTUMBRA_SSV_STRUCTURE_HIERARCHY: u32 = 0;
/// `antumbra_ssv_options.structure`: the 2005-style 2D structure, wedges projected
/// onto a cube of direction cells around the light's centroid (a baseline).
pub const ANTUMBRA_SSV_STRUCTURE_HEMICUBE: u32 = 1;
/// `antumbra_ssv_options.structure`: every potential silhouette edge for every
/// query (the obviously right reference; slow).
pub const ANTUMBRA_SSV_STRUCTURE_BRUTE_FORCE: u32 = 2;
/// `antumbra_ssv_options.structure`: N shadow rays per receiver through the
/// library's BVH, each hit confirmed exactly (the other reference).
pub const ANTUMBRA_SSV_STRUCTURE_RAY_TRACE: u32 = 3;

/// `antumbra_ssv_generate_samples` pattern: one uniformly random point per stratum.
pub const ANTUMBRA_SSV_SAMPLES_JITTERED: u32 = 0;
/// `antumbra_ssv_generate_samples` pattern: the centre of each stratum.
pub const ANTUMBRA_SSV_SAMPLES_STRATIFIED: u32 = 1;

/// Most light samples a soft shadow handle may have.
pub const ANTUMBRA_SSV_MAX_SAMPLES: u32 = 1024;
/// Most vertices of the light polygon.
pub const ANTUMBRA_SSV_MAX_LIGHT_VERTICES: u32 = 16;
/// Largest accepted `antumbra_ssv_options.max_depth`.
pub const ANTUMBRA_SSV_MAX_DEPTH_LIMIT: u32 = 24;
/// Largest accepted `antumbra_ssv_options.hemicube_resolution`.
pub const ANTUMBRA_SSV_MAX_HEMICUBE_RESOLUTION: u32 = 1024;

const _: () = {
    assert!(ANTUMBRA_SSV_MAX_SAMPLES as usize == MAX_SAMPLES);
    assert!(ANTUMBRA_SSV_MAX_LIGHT_VERTICES as usize == MAX_LIGHT_VERTICES);
    assert!(Structure::Hierarchy as u32 == ANTUMBRA_SSV_STRUCTURE_HIERARCHY);
    assert!(Structure::Hemicube as u32 == ANTUMBRA_SSV_STRUCTURE_HEMICUBE);
    assert!(Structure::BruteForce as u32 == ANTUMBRA_SSV_STRUCTURE_BRUTE_FORCE);
    assert!(Structure::RayTrace as u32 == ANTUMBRA_SSV_STRUCTURE_RAY_TRACE);
    assert!(core::mem::size_of::<antumbra_ssv_options>() == 48);
    assert!(core::mem::size_of::<antumbra_ssv_statistics>() == 96);
};

/// Options of `antumbra_ssv_create`. Fill with `antumbra_ssv_options_init`, then
/// change fields: fields may be added at the end in later versions, and
/// `options_init` keeps old code correct.
///
/// Layout: 48 bytes, twelve 4-byte fields, no padding, 4-byte aligned.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct antumbra_ssv_options {
    /// `ANTUMBRA_SSV_STRUCTURE_HIERARCHY` (0, the default), `_HEMICUBE` (1),
    /// `_BRUTE_FORCE` (2) or `_RAY_TRACE` (3). All give the same bits; they differ
    /// in speed and memory.
    pub structure: u32,
    /// Hierarchy: a node holding more candidate edges than this may be
    /// subdivided, where enough receivers fall in it (eight of one
    /// `antumbra_ssv_query` call, or eight queries over time) and only when
    /// splitting shortens the lists. At least 1; default 16.
    pub leaf_edges: u32,
    /// Hierarchy: deepest level of the octree, 0 to `ANTUMBRA_SSV_MAX_DEPTH_LIMIT`
    /// (24); default 12.
    pub max_depth: u32,
    /// Hemicube: cells per cube face side, 1 to 1024; default 64.
    pub hemicube_resolution: u32,
    /// 0 (the default): `antumbra_ssv_create` and `antumbra_ssv_query` run on
    /// the calling thread. 1: creation builds the reference ray's BVH and the
    /// structure side by side, and the points of one query call, and the
    /// building of the hierarchy's nodes they need, are split across the
    /// library's worker threads (a rayon pool of one thread per core, started
    /// on first use and kept for the life of the process). The bits are
    /// identical either way.
    pub parallel: u32,
    /// 0 (the default): the hierarchy's root box is a cube about the bounds of
    /// the occluders and the light, twice their largest extent on a side. 1: it is
    /// `[root_min, root_max]`. Either way a hint: receivers outside the root
    /// box go to shells of boxes around it as fine as the root's own nodes,
    /// at about the same cost as inside.
    pub use_root_bounds: u32,
    /// Lower corner of the root box when `use_root_bounds` is 1 (finite).
    pub root_min: [f32; 3],
    /// Upper corner of the root box when `use_root_bounds` is 1 (finite, each
    /// coordinate above `root_min`'s).
    pub root_max: [f32; 3],
}

const DEFAULT_OPTIONS: antumbra_ssv_options = antumbra_ssv_options {
    structure: ANTUMBRA_SSV_STRUCTURE_HIERARCHY,
    leaf_edges: 16,
    max_depth: 12,
    hemicube_resolution: 64,
    parallel: 0,
    use_root_bounds: 0,
    root_min: [0.0; 3],
    root_max: [0.0; 3],
};

/// What a soft shadow handle holds and the work its queries did, from
/// `antumbra_ssv_get_statistics`. The query counters cover every successful
/// `antumbra_ssv_query` on the handle since it was created or last updated
/// (all threads).
///
/// Layout: 96 bytes, four 4-byte fields then ten 8-byte fields, no padding,
/// 8-byte aligned.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct antumbra_ssv_statistics {
    /// The structure chosen at creation (`ANTUMBRA_SSV_STRUCTURE_*`).
    pub structure: u32,
    /// Number of light samples N.
    pub sample_count: u32,
    /// `ceil(N / 64)`: the `uint64_t` words of one receiver's bits.
    pub words_per_receiver: u32,
    /// Vertices of the light polygon.
    pub light_vertex_count: u32,
    /// Welded edges of the occluders (triangles near the light excluded).
    pub edges: u64,
    /// Edges that may be silhouettes for some receiver (flat interior edges
    /// excluded): what brute force tests per query.
    pub potential_edges: u64,
    /// Triangles near the light's plane, tested directly against every sample.
    pub near_light_triangles: u64,
    /// Hierarchy nodes built so far (grows as queries arrive) or hemicube cells;
    /// 0 for brute force and ray tracing.
    pub nodes: u64,
    /// Bytes held by the structure's node or cell lists (not the BVH).
    pub bytes: u64,
    /// Receivers queried.
    pub queries: u64,
    /// Candidate edges the structure handed to the exact tests, summed over queries.
    pub candidates: u64,
    /// Candidates that were silhouettes of their receiver, summed over queries.
    pub silhouettes: u64,
    /// Rays cast, summed over queries (1 per receiver for the wedge structures,
    /// N for ray tracing, 0 for receivers in the light's plane).
    pub rays: u64,
    /// `candidates / queries` (0 before the first query).
    pub candidates_per_query: f64,
}

/// Soft shadows from one planar area light with a fixed set of samples over a
/// fixed set of occluders. Opaque; create with `antumbra_ssv_create`, free with
/// `antumbra_ssv_destroy`.
pub struct antumbra_ssv {
    shadows: SoftShadows,
    parallel: bool,
    queries: Counter,
    candidates: Counter,
    silhouettes: Counter,
    rays: Counter,
    poisoned: AtomicBool,
}

// Queries take `&antumbra_ssv` from many threads; keep that true by construction.
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<antumbra_ssv>();
};

/// Writes the default options: the hierarchy, 16 edges per leaf, depth 12,
/// hemicube resolution 64, on the calling thread, the automatic root box.
///
/// @param options the options to fill; every field is written.
///
/// On a NULL or misaligned pointer nothing is written, and the thread's last error
/// message and the error callback report ANTUMBRA_RESULT_NULL_ARGUMENT or
/// ANTUMBRA_RESULT_INVALID_ARGUMENT.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `options` must be NULL or valid for writing one `antumbra_ssv_options`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_ssv_options_init(options: *mut antumbra_ssv_options) {
    let _ = guard("antumbra_ssv_options_init", || {
        if options.is_null() {
            return Err(Error::null("options"));
        }
        let out = raw::writable(options, 1, "options")?;
        // SAFETY: non-NULL and aligned (checked), valid for a write by contract.
        unsafe { out.write(DEFAULT_OPTIONS) };
        Ok(())
    });
}

/// Checks every field of `options` and converts them; `parallel` separately.
fn check_options(options: &antumbra_ssv_options) -> Result<(SsvOptions, bool), Error> {
    let structure = match options.structure {
        ANTUMBRA_SSV_STRUCTURE_HIERARCHY => Structure::Hierarchy,
        ANTUMBRA_SSV_STRUCTURE_HEMICUBE => Structure::Hemicube,
        ANTUMBRA_SSV_STRUCTURE_BRUTE_FORCE => Structure::BruteForce,
        ANTUMBRA_SSV_STRUCTURE_RAY_TRACE => Structure::RayTrace,
        s => {
            return Err(Error::invalid(message!(
                "options->structure is {s}; expected ANTUMBRA_SSV_STRUCTURE_HIERARCHY (0), \
                 _HEMICUBE (1), _BRUTE_FORCE (2) or _RAY_TRACE (3)"
            )));
        }
    };
    if options.leaf_edges == 0 {
        return Err(Error::invalid(
            "options->leaf_edges is 0; expected at least 1",
        ));
    }
    if options.max_depth > ANTUMBRA_SSV_MAX_DEPTH_LIMIT {
        return Err(Error::invalid(message!(
            "options->max_depth is {}; expected 0 to {ANTUMBRA_SSV_MAX_DEPTH_LIMIT}",
            options.max_depth
        )));
    }
    if !(1..=ANTUMBRA_SSV_MAX_HEMICUBE_RESOLUTION).contains(&options.hemicube_resolution) {
        return Err(Error::invalid(message!(
            "options->hemicube_resolution is {}; expected 1 to \
             {ANTUMBRA_SSV_MAX_HEMICUBE_RESOLUTION}",
            options.hemicube_resolution
        )));
    }
    let parallel = flag(options.parallel, "options->parallel")?;
    let root_bounds = if flag(options.use_root_bounds, "options->use_root_bounds")? {
        let (lo, hi) = (
            Vec3::from_array(options.root_min),
            Vec3::from_array(options.root_max),
        );
        if !lo.is_finite() {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!(
                    "options->root_min ({}, {}, {}) is not finite",
                    lo.x,
                    lo.y,
                    lo.z
                ),
            ));
        }
        if !hi.is_finite() {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!(
                    "options->root_max ({}, {}, {}) is not finite",
                    hi.x,
                    hi.y,
                    hi.z
                ),
            ));
        }
        if !lo.cmplt(hi).all() {
            return Err(Error::invalid(message!(
                "options->root_min ({}, {}, {}) is not below options->root_max ({}, {}, {}) \
                 in every coordinate",
                lo.x,
                lo.y,
                lo.z,
                hi.x,
                hi.y,
                hi.z
            )));
        }
        Some([lo, hi])
    } else {
        None
    };
    #[cfg(not(feature = "std"))]
    if parallel {
        return Err(crate::hemi::unsupported_parallel("options->parallel"));
    }
    #[cfg(not(feature = "std"))]
    if structure == Structure::Hemicube {
        return Err(Error::new(
            ANTUMBRA_RESULT_UNSUPPORTED,
            "options->structure is ANTUMBRA_SSV_STRUCTURE_HEMICUBE, which the bare-metal build \
             does not include (its construction cannot report running out of memory); use \
             ANTUMBRA_SSV_STRUCTURE_HIERARCHY",
        ));
    }
    Ok((
        SsvOptions {
            structure,
            leaf_edges: options.leaf_edges,
            max_depth: options.max_depth,
            root_bounds,
            parallel,
            hemicube_resolution: options.hemicube_resolution,
        },
        parallel,
    ))
}

/// `count` points of 3 floats at `pointer`, each finite and within ±1e12, named
/// `argument[i]` in messages, their count `count_argument`.
///
/// # Safety
/// A non-NULL `pointer` must be valid for `3 * count` floats for `'a`.
unsafe fn points<'a>(
    pointer: *const f32,
    (count, count_argument): (usize, &str),
    argument: &str,
) -> Result<&'a [f32], Error> {
    let xyz = raw::element_count(count, 3, count_argument)?;
    // SAFETY: forwarded contract.
    let floats = unsafe { raw::slice(pointer, xyz, argument) }?;
    for (i, p) in floats.chunks_exact(3).enumerate() {
        let p = Vec3::from_slice(p);
        if !p.is_finite() {
            return Err(non_finite(argument, i, p));
        }
        if p.abs().max_element() > MAX_COORDINATE {
            return Err(Error::invalid(message!(
                "{argument}[{i}] ({}, {}, {}) is beyond the supported range of \
                 ±{MAX_COORDINATE:e}",
                p.x,
                p.y,
                p.z
            )));
        }
    }
    Ok(floats)
}

fn to_vec3s(floats: &[f32], what: &str) -> Result<Vec<Vec3>, Error> {
    let mut points = fallible::vec_with_capacity(floats.len() / 3, what)?;
    points.extend(floats.chunks_exact(3).map(Vec3::from_slice));
    Ok(points)
}

/// The validated light polygon from C arguments.
///
/// # Safety
/// A non-NULL `light_vertices` must be valid for `3 * light_vertex_count` floats.
unsafe fn read_light(
    light_vertices: *const f32,
    light_vertex_count: usize,
) -> Result<LightPolygon, Error> {
    if !(3..=MAX_LIGHT_VERTICES).contains(&light_vertex_count) {
        return Err(Error::invalid(message!(
            "light_vertex_count is {light_vertex_count}; a light polygon needs 3 to \
             {MAX_LIGHT_VERTICES} vertices"
        )));
    }
    // SAFETY: forwarded contract.
    let floats = unsafe {
        points(
            light_vertices,
            (light_vertex_count, "light_vertex_count"),
            "light_vertices",
        )
    }?;
    LightPolygon::new(&to_vec3s(floats, "the light's vertices")?).map_err(light_error)
}

fn light_error(error: LightError) -> Error {
    match error {
        LightError::VertexCount { count } => Error::invalid(message!(
            "light_vertex_count is {count}; a light polygon needs 3 to {MAX_LIGHT_VERTICES} \
             vertices"
        )),
        LightError::NonFinite => Error::new(
            ANTUMBRA_RESULT_NON_FINITE,
            "light_vertices has a NaN or infinite coordinate",
        ),
        LightError::Degenerate => Error::invalid(
            "light_vertices: the polygon is degenerate (zero area, or two consecutive \
             vertices equal)",
        ),
        LightError::NotPlanar { vertex } => Error::invalid(message!(
            "light_vertices[{vertex}] is off the polygon's plane (tolerance {:e} of its \
             diameter, or 8 units of f32 rounding at its largest coordinate if more)",
            antumbra_core::ssv::LIGHT_TOLERANCE
        )),
        LightError::NotConvex { vertex } => Error::invalid(message!(
            "light_vertices: the polygon is not convex at light_vertices[{vertex}] (or winds \
             more than once)"
        )),
        LightError::SampleOffLight { index } => Error::invalid(message!(
            "samples[{index}] is off the light polygon (beyond {:e} of its diameter, or 8 \
             units of f32 rounding at its largest coordinate if more, from its plane or \
             outside its edges)",
            antumbra_core::ssv::LIGHT_TOLERANCE
        )),
        LightError::OutOfMemory => Error::new(
            ANTUMBRA_RESULT_OUT_OF_MEMORY,
            "no memory for the light polygon",
        ),
    }
}

/// Builds the soft shadows of the light polygon `light_vertices` with the light
/// samples `samples` over the triangles of `occluders`.
///
/// Visibility is exact: the bits `antumbra_ssv_query` returns are those of N
/// shadow segments from the receiver to the samples tested exactly against every
/// occluder triangle (closed triangles, two-sided; degenerate triangles never
/// occlude; the light itself is never an occluder and emits to both sides).
///
/// @param occluders the triangles; 0 triangles is allowed (everything is lit).
///        Every index < vertex_count, every coordinate of a vertex used by a
///        triangle finite and within ±1e12, position_stride 0 (packed) or >= 12.
///        Copied: the mesh may be freed afterwards.
/// @param light_vertices 3 floats per vertex, in order around the polygon (either
///        winding): convex, planar within 1e-4 of its diameter (or 8 units of
///        f32 rounding at its largest coordinate, if more), non-zero area, no
///        two consecutive vertices equal, coordinates finite within ±1e12.
/// @param light_vertex_count 3 to `ANTUMBRA_SSV_MAX_LIGHT_VERTICES` (16).
/// @param samples 3 floats per light sample (bit i of a result is sample i), each
///        on the light polygon within the same tolerance; make them with
///        `antumbra_ssv_generate_samples`. Copied.
/// @param sample_count 1 to `ANTUMBRA_SSV_MAX_SAMPLES` (1024).
/// @param options NULL for the defaults (see `antumbra_ssv_options_init`).
/// @param out receives the new handle on success; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (occluders, out, light_vertices,
///         samples, or a mesh array with a non-zero count); INVALID_ARGUMENT (a
///         light vertex count outside 3..16, a sample count outside 1..1024, a
///         non-convex, non-planar or degenerate light, a sample off the light, an
///         option out of range, misaligned pointer, stride below 12, size
///         overflow, a coordinate beyond ±1e12); INDEX_OUT_OF_RANGE (a mesh
///         index); NON_FINITE (a NaN or infinite mesh position, light vertex,
///         sample or root bound); OUT_OF_MEMORY (the structure or the BVH could
///         not be allocated; nothing is kept); UNSUPPORTED (without
///         ANTUMBRA_HAS_STD: the hemicube structure, `parallel` = 1); PANIC.
///         Messages name the argument and index, e.g. `samples[7] is off the
///         light polygon ...`.
///
/// Cost: O(triangles log triangles) (edge welding, the BVH); allocates the edge
/// graph, the structure and a copy of the samples (tens of bytes per triangle).
/// The hierarchy's nodes are built lazily by the queries that reach them, the
/// hemicube's cells here. Without ANTUMBRA_HAS_STD the reference ray goes
/// through every triangle (no BVH): O(triangles) per query.
/// Ownership: the caller owns `*out` and frees it with `antumbra_ssv_destroy`.
/// Thread safety: safe from any thread; the new handle is independent of others.
///
/// # Safety
/// `occluders`, `options` and `out` must be NULL or valid; the arrays in
/// `occluders` valid for the counts and stride it gives; non-NULL
/// `light_vertices` and `samples` valid for 3 floats per vertex or sample.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_ssv_create(
    occluders: *const antumbra_mesh_view,
    light_vertices: *const f32,
    light_vertex_count: usize,
    samples: *const f32,
    sample_count: usize,
    options: *const antumbra_ssv_options,
    out: *mut *mut antumbra_ssv,
) -> antumbra_result {
    guard("antumbra_ssv_create", || {
        if out.is_null() {
            return Err(Error::null("out"));
        }
        let out = raw::writable(out, 1, "out")?;
        let options = if options.is_null() {
            DEFAULT_OPTIONS
        } else {
            // SAFETY: non-NULL, so by contract a valid options struct.
            *unsafe { raw::reference(options, "options") }?
        };
        let (core_options, parallel) = check_options(&options)?;
        // SAFETY: caller contract on `occluders`.
        let view = unsafe { raw::reference(occluders, "occluders") }?;
        // SAFETY: caller contract on the arrays inside `occluders`.
        let mesh = unsafe { mesh_from_c(view, "occluders") }?;
        check_coordinate_range(&mesh, "occluders")?;
        // SAFETY: caller contract on `light_vertices`.
        let light = unsafe { read_light(light_vertices, light_vertex_count) }?;
        if sample_count == 0 || sample_count > MAX_SAMPLES {
            return Err(Error::invalid(message!(
                "sample_count is {sample_count}; expected 1 to {MAX_SAMPLES}"
            )));
        }
        // SAFETY: caller contract on `samples`.
        let samples = to_vec3s(
            unsafe { points(samples, (sample_count, "sample_count"), "samples") }?,
            "the samples",
        )?;
        light.validate_samples(&samples).map_err(light_error)?;
        let triangles = mesh.triangle_count();
        let shadows = SoftShadows::new(&mesh, light, &samples, core_options)
            .map_err(|e| creation_error(e, triangles))?;
        let handle = fallible::boxed(
            antumbra_ssv {
                shadows,
                parallel,
                queries: Counter::new(0),
                candidates: Counter::new(0),
                silhouettes: Counter::new(0),
                rays: Counter::new(0),
                poisoned: AtomicBool::new(false),
            },
            "the soft shadow handle",
        )?;
        // SAFETY: non-NULL, aligned (checked), valid for a pointer write by contract.
        unsafe { out.write(Box::into_raw(handle)) };
        Ok(())
    })
}

/// A creation or update error of the core, once the inputs are checked.
fn creation_error(error: SsvError, triangles: usize) -> Error {
    match error {
        SsvError::Light(e) => light_error(e),
        SsvError::OutOfMemory => Error::new(
            ANTUMBRA_RESULT_OUT_OF_MEMORY,
            message!("no memory for the soft shadows over {triangles} triangles"),
        ),
        // Every other input was checked before; what is left is allocation.
        SsvError::Caster => Error::new(
            ANTUMBRA_RESULT_OUT_OF_MEMORY,
            message!("no memory for the ray caster over {triangles} triangles"),
        ),
        other => Error::invalid(message!("{other}")),
    }
}

/// Moves the occluders of a soft shadow handle to `occluders` (an object
/// moved or deformed, or another mesh), keeping its light, samples and
/// options: every query afterwards returns exactly the bits of a handle
/// created from `occluders`. Cheaper than `antumbra_ssv_destroy` and
/// `antumbra_ssv_create`: the reference ray's BVH is refitted to the new
/// positions instead of built again when the occluders keep their number of
/// triangles (welded, without degenerate ones); the rest depends on where
/// the edges are and is made anew. A moving object's frame (update and every
/// query) costs 0.9–1.05 times a new handle's (`antumbra bench ssv --frame`:
/// the saving, the BVH's build, is at most a tenth of a small light's frame
/// over a 52,000-triangle mesh). The statistics restart.
///
/// @param ssv the handle.
/// @param occluders the new occluders, checked as `antumbra_ssv_create`
///        checks them. Copied: the mesh may be freed afterwards.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (ssv, occluders, or a mesh array
///         with a non-zero count); INVALID_ARGUMENT (misaligned pointer, stride
///         below 12, size overflow, a coordinate beyond ±1e12);
///         INDEX_OUT_OF_RANGE; NON_FINITE; OUT_OF_MEMORY; POISONED; PANIC. On
///         failure the handle is unchanged.
///
/// Ownership: borrows `occluders` for the call. Thread safety: needs exclusive
/// access to `ssv`: no query or other call on it may be running.
///
/// # Safety
/// `ssv` must be NULL or a live handle from `antumbra_ssv_create`;
/// `occluders` NULL or valid, its arrays valid for the counts and stride it
/// gives.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_ssv_update(
    ssv: *mut antumbra_ssv,
    occluders: *const antumbra_mesh_view,
) -> antumbra_result {
    with_handle_mut("antumbra_ssv_update", ssv, |ssv| {
        // SAFETY: caller contract on `occluders`.
        let view = unsafe { raw::reference(occluders, "occluders") }?;
        // SAFETY: caller contract on the arrays inside `occluders`.
        let mesh = unsafe { mesh_from_c(view, "occluders") }?;
        check_coordinate_range(&mesh, "occluders")?;
        let triangles = mesh.triangle_count();
        ssv.shadows
            .update(&mesh)
            .map_err(|e| creation_error(e, triangles))?;
        ssv.queries = Counter::new(0);
        ssv.candidates = Counter::new(0);
        ssv.silhouettes = Counter::new(0);
        ssv.rays = Counter::new(0);
        Ok(())
    })
}

/// Frees a soft shadow handle. NULL is a no-op.
///
/// Ownership: takes back a handle from `antumbra_ssv_create`; it must not be used
/// afterwards. Thread safety: needs exclusive access: no query or statistics call
/// on this handle may be running.
///
/// # Safety
/// `ssv` must be NULL or a live handle from `antumbra_ssv_create`, destroyed at
/// most once.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_ssv_destroy(ssv: *mut antumbra_ssv) {
    let _ = guard("antumbra_ssv_destroy", || {
        if !ssv.is_null() {
            // SAFETY: by contract, a live handle created by `Box::into_raw`.
            drop(unsafe { Box::from_raw(ssv) });
        }
        Ok(())
    });
}

impl Poisonable for antumbra_ssv {
    const ARGUMENT: &'static str = "ssv";

    fn poison_flag(&self) -> &AtomicBool {
        &self.poisoned
    }
}

/// A work counter of the handle. The bare-metal target has no 64-bit atomics, and
/// its calls are single-threaded by contract.
#[cfg(not(feature = "std"))]
struct Counter(core::cell::Cell<u64>);

#[cfg(not(feature = "std"))]
impl Counter {
    const fn new(value: u64) -> Self {
        Counter(core::cell::Cell::new(value))
    }

    fn fetch_add(&self, value: u64, _: Ordering) -> u64 {
        let old = self.0.get();
        self.0.set(old.wrapping_add(value));
        old
    }

    fn load(&self, _: Ordering) -> u64 {
        self.0.get()
    }
}

// SAFETY: the bare-metal build runs the library on one thread of execution (its
// documented contract), so the cell is never accessed concurrently.
#[cfg(not(feature = "std"))]
unsafe impl Sync for Counter {}

/// The visibility bits of a batch of receiver points.
///
/// For point k at `points[3k..3k+3]`, bit i of receiver k (bit `i % 64` of
/// `visibility_bits[k * W + i / 64]`, `W = ceil(sample_count / 64)`) is set when
/// light sample i is visible from the point: no occluder triangle meets the open
/// segment from the point to the sample. Unused high bits of a receiver's last
/// word are 0. `visible_counts[k]`, when given, is the number of bits set.
///
/// @param ssv the handle.
/// @param points 3 floats per receiver, finite, within ±1e12. Points may be
///        anywhere (on the floor, on an occluder's surface, in free space).
/// @param point_count number of receivers; 0 is a valid empty batch (the arrays
///        may then be NULL).
/// @param visibility_bits receives `point_count * W` words, 8-byte aligned;
///        untouched on failure (except after ANTUMBRA_RESULT_PANIC, an internal
///        bug, when it may be partly written).
/// @param visible_counts NULL, or receives one count per receiver (4-byte
///        aligned); untouched on failure (same exception).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (ssv, points or visibility_bits with
///         point_count > 0); INVALID_ARGUMENT (misaligned array, point_count
///         overflow, a coordinate beyond ±1e12); NON_FINITE (a NaN or infinite
///         point, named with its index, e.g. `points[3] (nan, 0, 1) is not
///         finite`); POISONED; PANIC (the handle is poisoned).
///
/// Cost: per receiver, one walk of the structure, the exact tests of its
/// candidate edges against the N samples, and one reference ray; no allocation
/// per receiver. Before the queries, the hierarchy builds the nodes the
/// call's points need (it splits a node where eight or more of them fall and
/// the split shortens the lists; a few arrays of `point_count` entries for
/// that), so pass a frame's receivers in one call rather than one by one.
/// Without ANTUMBRA_HAS_STD memory never makes a query fail: where a node cannot
/// be allocated the walk stops at the coarser node it reached, whose candidates
/// include the finer one's (the same bits, more work).
/// Ownership: borrows every array for the call only; the outputs must not overlap
/// each other or `points`.
/// Thread safety: any number of threads may query the same handle at once
/// (including the hierarchy's lazy construction); with `options.parallel` = 1 a
/// call also uses the library's worker threads.
///
/// # Safety
/// A non-NULL `points` must be valid for `3 * point_count` floats,
/// `visibility_bits` for `point_count * W` words, `visible_counts` for
/// `point_count` counts.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_ssv_query(
    ssv: *const antumbra_ssv,
    points: *const f32,
    point_count: usize,
    visibility_bits: *mut u64,
    visible_counts: *mut u32,
) -> antumbra_result {
    with_handle("antumbra_ssv_query", ssv, |ssv| {
        let words = ssv.shadows.words_per_receiver();
        // SAFETY: caller contract on `points`.
        let floats = unsafe { self::points(points, (point_count, "point_count"), "points") }?;
        let word_count = raw::element_count(
            point_count,
            words,
            format_args!("point_count * words_per_receiver ({words})"),
        )?;
        // SAFETY: caller contract: valid for `word_count` words, no overlap.
        let bits = unsafe { raw::slice_mut(visibility_bits, word_count, "visibility_bits") }?;
        let counts = if visible_counts.is_null() {
            None
        } else {
            // SAFETY: caller contract: valid for `point_count` counts, no overlap.
            Some(unsafe { raw::slice_mut(visible_counts, point_count, "visible_counts") }?)
        };
        // Every input is valid: the core query fails only on non-finite points
        // and short outputs, both excluded above. The batch prepares the
        // hierarchy for its points and runs on the pool when the handle was
        // made with `parallel`.
        let receivers: &[[f32; 3]] = bytemuck::cast_slice(floats);
        let work = ssv
            .shadows
            .query_batch(receivers, bits, counts, ssv.parallel)
            .expect("validated receivers and outputs");
        ssv.queries.fetch_add(work.queries, Ordering::Relaxed);
        ssv.candidates.fetch_add(work.candidates, Ordering::Relaxed);
        ssv.silhouettes
            .fetch_add(work.silhouettes, Ordering::Relaxed);
        ssv.rays.fetch_add(work.rays, Ordering::Relaxed);
        Ok(())
    })
}

/// Reports the handle's sizes and the work its queries did so far.
///
/// @param ssv the handle.
/// @param statistics receives the statistics; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (ssv, statistics); INVALID_ARGUMENT
///         (misaligned statistics); POISONED; PANIC.
///
/// The counters of queries running at the same time on other threads may be
/// partly included (each query call adds its counts when it finishes).
/// Thread safety: may run while other threads query the same handle.
///
/// # Safety
/// `ssv` must be NULL or a live handle; `statistics` NULL or valid for writing one
/// `antumbra_ssv_statistics`.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_ssv_get_statistics(
    ssv: *const antumbra_ssv,
    statistics: *mut antumbra_ssv_statistics,
) -> antumbra_result {
    with_handle("antumbra_ssv_get_statistics", ssv, |ssv| {
        if statistics.is_null() {
            return Err(Error::null("statistics"));
        }
        let out = raw::writable(statistics, 1, "statistics")?;
        let s = ssv.shadows.statistics();
        let queries = ssv.queries.load(Ordering::Relaxed);
        let candidates = ssv.candidates.load(Ordering::Relaxed);
        let value = antumbra_ssv_statistics {
            structure: s.structure as u32,
            sample_count: ssv.shadows.sample_count() as u32,
            words_per_receiver: ssv.shadows.words_per_receiver() as u32,
            light_vertex_count: ssv.shadows.light().vertices().len() as u32,
            edges: s.edges as u64,
            potential_edges: s.potential_edges as u64,
            near_light_triangles: s.near_light_triangles as u64,
            nodes: s.nodes as u64,
            bytes: s.bytes as u64,
            queries,
            candidates,
            silhouettes: ssv.silhouettes.load(Ordering::Relaxed),
            rays: ssv.rays.load(Ordering::Relaxed),
            candidates_per_query: if queries == 0 {
                0.0
            } else {
                candidates as f64 / queries as f64
            },
        };
        // SAFETY: non-NULL, aligned (checked), valid for a write by contract.
        unsafe { out.write(value) };
        Ok(())
    })
}

/// Light samples on a convex planar polygon, deterministic in `seed`, for
/// `antumbra_ssv_create`.
///
/// The polygon is cut into a fan of triangles from vertex 0; each gets a share of
/// the samples proportional to its area; a triangle with m samples has a k × k
/// grid of strata (k² >= m) over the unit square, m of them chosen by a seeded
/// shuffle and mapped onto the triangle by an area-preserving warp. Stratified
/// takes the strata centres, jittered one uniform point in each. The same
/// arguments give the same floats on every platform and thread.
///
/// @param light_vertices 3 floats per vertex, as for `antumbra_ssv_create`.
/// @param light_vertex_count 3 to 16.
/// @param sample_count 1 to `ANTUMBRA_SSV_MAX_SAMPLES` (1024).
/// @param pattern `ANTUMBRA_SSV_SAMPLES_JITTERED` (0) or
///        `ANTUMBRA_SSV_SAMPLES_STRATIFIED` (1).
/// @param seed any value.
/// @param samples receives `3 * sample_count` floats; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (light_vertices, samples);
///         INVALID_ARGUMENT (a count out of range, an unknown pattern, a
///         non-convex, non-planar or degenerate light, a coordinate beyond
///         ±1e12, misaligned arrays); NON_FINITE (a light vertex); OUT_OF_MEMORY;
///         PANIC.
///
/// Cost: allocates a temporary of `12 * sample_count` bytes.
/// Thread safety: safe from any thread.
///
/// # Safety
/// A non-NULL `light_vertices` must be valid for `3 * light_vertex_count` floats,
/// `samples` for writing `3 * sample_count` floats, not overlapping them.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_ssv_generate_samples(
    light_vertices: *const f32,
    light_vertex_count: usize,
    sample_count: usize,
    pattern: u32,
    seed: u64,
    samples: *mut f32,
) -> antumbra_result {
    guard("antumbra_ssv_generate_samples", || {
        // SAFETY: caller contract on `light_vertices`.
        let light = unsafe { read_light(light_vertices, light_vertex_count) }?;
        if sample_count == 0 || sample_count > MAX_SAMPLES {
            return Err(Error::invalid(message!(
                "sample_count is {sample_count}; expected 1 to {MAX_SAMPLES}"
            )));
        }
        let pattern = match pattern {
            ANTUMBRA_SSV_SAMPLES_JITTERED => SamplePattern::Jittered,
            ANTUMBRA_SSV_SAMPLES_STRATIFIED => SamplePattern::Stratified,
            p => {
                return Err(Error::invalid(message!(
                    "pattern is {p}; expected ANTUMBRA_SSV_SAMPLES_JITTERED (0) or \
                     ANTUMBRA_SSV_SAMPLES_STRATIFIED (1)"
                )));
            }
        };
        // SAFETY: caller contract: valid for `3 * sample_count` floats, no overlap.
        let out = unsafe { raw::slice_mut(samples, 3 * sample_count, "samples") }?;
        let generated = light
            .try_samples(sample_count, pattern, seed)
            .map_err(|_| fallible::out_of_memory("the samples", 12 * sample_count))?;
        if generated.len() != sample_count {
            // Not expected (core apportions every sample); never a partly written buffer.
            return Err(Error::invalid(message!(
                "light_vertices: the light gave {} samples for sample_count {sample_count}",
                generated.len()
            )));
        }
        for (slot, s) in out.chunks_exact_mut(3).zip(&generated) {
            slot.copy_from_slice(&s.to_array());
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUAD: [f32; 12] = [
        -0.5, -0.5, 2.0, 0.5, -0.5, 2.0, 0.5, 0.5, 2.0, -0.5, 0.5, 2.0,
    ];

    /// A thin light (accepted, within the coordinate range) once made core
    /// return 2 of 16 samples: a debug build panicked, a release build would
    /// have returned OK with most of the buffer unwritten.
    #[test]
    fn generate_samples_of_a_thin_light_writes_every_sample() {
        let thin: [f32; 12] = [
            0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1e-24, 0.0, 0.0, 1e-24, 0.0,
        ];
        let mut samples = vec![f32::NAN; 3 * 16];
        // SAFETY: 4 vertices and 16 samples' worth of floats.
        let r = unsafe {
            antumbra_ssv_generate_samples(
                thin.as_ptr(),
                4,
                16,
                ANTUMBRA_SSV_SAMPLES_STRATIFIED,
                1,
                samples.as_mut_ptr(),
            )
        };
        assert_eq!(r, ANTUMBRA_RESULT_OK);
        assert!(samples.iter().all(|x| x.is_finite()), "{samples:?}");
    }

    /// An overflowing `point_count` was reported as "points count"; the
    /// message names the parameter.
    #[test]
    fn an_overflowing_point_count_is_named() {
        let samples = [0.0f32, 0.0, 2.0];
        let ssv = create(ANTUMBRA_SSV_STRUCTURE_HIERARCHY, &samples, 0);
        let points = [0.0f32; 3];
        let mut bits = [7u64];
        // SAFETY: a valid handle; the count is refused before anything is read.
        let r = unsafe {
            antumbra_ssv_query(
                ssv,
                points.as_ptr(),
                usize::MAX / 2,
                bits.as_mut_ptr(),
                core::ptr::null_mut(),
            )
        };
        // SAFETY: the library's own NUL-terminated message.
        let message = unsafe { core::ffi::CStr::from_ptr(crate::antumbra_last_error_message()) }
            .to_string_lossy()
            .into_owned();
        // SAFETY: created above, destroyed once.
        unsafe { antumbra_ssv_destroy(ssv) };
        assert_eq!(r, ANTUMBRA_RESULT_INVALID_ARGUMENT);
        assert!(
            message.starts_with("antumbra_ssv_query: point_count:"),
            "{message}"
        );
        assert_eq!(bits, [7]);
    }

    /// The C defaults are written out for the header's docs; they must be core's.
    #[test]
    fn default_options_are_cores_defaults() {
        let core = SsvOptions::default();
        assert_eq!(DEFAULT_OPTIONS.structure, core.structure as u32);
        assert_eq!(DEFAULT_OPTIONS.leaf_edges, core.leaf_edges);
        assert_eq!(DEFAULT_OPTIONS.max_depth, core.max_depth);
        assert_eq!(
            DEFAULT_OPTIONS.hemicube_resolution,
            core.hemicube_resolution
        );
        assert_eq!(
            DEFAULT_OPTIONS.use_root_bounds,
            u32::from(core.root_bounds.is_some())
        );
    }

    /// A small square occluder at z = 1 under the light at z = 2.
    fn blocker() -> ([f32; 12], [u32; 6]) {
        (
            [
                -0.2, -0.2, 1.0, 0.2, -0.2, 1.0, 0.2, 0.2, 1.0, -0.2, 0.2, 1.0,
            ],
            [0, 1, 2, 0, 2, 3],
        )
    }

    fn create(structure: u32, samples: &[f32], parallel: u32) -> *mut antumbra_ssv {
        let (positions, indices) = blocker();
        let view = antumbra_mesh_view {
            positions: positions.as_ptr(),
            vertex_count: 4,
            position_stride: 0,
            indices: indices.as_ptr(),
            triangle_count: 2,
        };
        let options = antumbra_ssv_options {
            structure,
            parallel,
            ..DEFAULT_OPTIONS
        };
        let mut ssv = core::ptr::null_mut();
        // SAFETY: live arrays, valid pointers.
        let result = unsafe {
            antumbra_ssv_create(
                &view,
                QUAD.as_ptr(),
                4,
                samples.as_ptr(),
                samples.len() / 3,
                &options,
                &mut ssv,
            )
        };
        assert_eq!(result, ANTUMBRA_RESULT_OK);
        ssv
    }

    fn generated(count: usize) -> Vec<f32> {
        let mut samples = vec![0.0f32; 3 * count];
        // SAFETY: live arrays of the right sizes.
        let result = unsafe {
            antumbra_ssv_generate_samples(
                QUAD.as_ptr(),
                4,
                count,
                ANTUMBRA_SSV_SAMPLES_JITTERED,
                7,
                samples.as_mut_ptr(),
            )
        };
        assert_eq!(result, ANTUMBRA_RESULT_OK);
        samples
    }

    /// Every structure, on one thread or many, gives the core's bits, and the
    /// counters add up.
    #[test]
    fn the_ffi_query_equals_the_core_query() {
        let samples = generated(100);
        let points: Vec<f32> = (0..64)
            .flat_map(|k| {
                let (i, j) = (k % 8, k / 8);
                [(i as f32 - 3.5) * 0.15, (j as f32 - 3.5) * 0.15, 0.0]
            })
            .collect();
        let n = points.len() / 3;
        let mut reference: Option<Vec<u64>> = None;
        for structure in 0..4 {
            for parallel in 0..2 {
                let ssv = create(structure, &samples, parallel);
                let mut bits = vec![0u64; 2 * n];
                let mut counts = vec![0u32; n];
                // SAFETY: live handle and arrays of the documented sizes.
                let result = unsafe {
                    antumbra_ssv_query(
                        ssv,
                        points.as_ptr(),
                        n,
                        bits.as_mut_ptr(),
                        counts.as_mut_ptr(),
                    )
                };
                assert_eq!(result, ANTUMBRA_RESULT_OK);
                // SAFETY: a live handle.
                let shadows = unsafe { &(*ssv).shadows };
                for k in 0..n {
                    let mut want = [0u64; 2];
                    let visible = shadows
                        .query(Vec3::from_slice(&points[3 * k..]), &mut want)
                        .unwrap();
                    assert_eq!(&bits[2 * k..2 * k + 2], &want, "receiver {k}");
                    assert_eq!(counts[k], visible);
                    assert_eq!(
                        visible,
                        want[0].count_ones() + want[1].count_ones(),
                        "count is the bits set"
                    );
                }
                match &reference {
                    None => reference = Some(bits.clone()),
                    Some(r) => assert_eq!(r, &bits, "structure {structure} parallel {parallel}"),
                }
                let mut stats = antumbra_ssv_statistics::default();
                // SAFETY: live handle, valid out pointer.
                let got = unsafe { antumbra_ssv_get_statistics(ssv, &mut stats) };
                assert_eq!(got, ANTUMBRA_RESULT_OK);
                assert_eq!(stats.structure, structure);
                assert_eq!(stats.queries, n as u64);
                assert_eq!(stats.sample_count, 100);
                assert_eq!(stats.words_per_receiver, 2);
                if structure == ANTUMBRA_SSV_STRUCTURE_RAY_TRACE {
                    assert_eq!(stats.rays, 100 * n as u64);
                } else {
                    assert_eq!(stats.rays, n as u64);
                    assert!(stats.candidates >= stats.silhouettes);
                }
                // SAFETY: from create, destroyed once.
                unsafe { antumbra_ssv_destroy(ssv) };
            }
        }
        // The scene is not trivial: the centre point sees part of the light only.
        let r = reference.unwrap();
        let centre = 4 * 8 + 4;
        let visible = r[2 * centre].count_ones() + r[2 * centre + 1].count_ones();
        assert!(visible > 0 && visible < 100, "centre sees {visible} of 100");
    }

    /// `antumbra_ssv_update` moves the blocker: the bits equal the core's on
    /// the moved blocker, the statistics restart, and a refused update leaves
    /// the handle as it was.
    #[test]
    fn an_updated_handle_answers_for_the_moved_occluders() {
        let samples = generated(64);
        let points: Vec<f32> = (0..49)
            .flat_map(|k| {
                [
                    ((k % 7) as f32 - 3.0) * 0.1,
                    ((k / 7) as f32 - 3.0) * 0.1,
                    0.0,
                ]
            })
            .collect();
        let n = points.len() / 3;
        let query = |ssv: *mut antumbra_ssv| {
            let mut bits = vec![0u64; n];
            // SAFETY: live handle and arrays of the documented sizes.
            let result = unsafe {
                antumbra_ssv_query(
                    ssv,
                    points.as_ptr(),
                    n,
                    bits.as_mut_ptr(),
                    core::ptr::null_mut(),
                )
            };
            assert_eq!(result, ANTUMBRA_RESULT_OK);
            bits
        };
        let (positions, indices) = blocker();
        let shifted: Vec<f32> = positions
            .chunks_exact(3)
            .flat_map(|p| [p[0] + 0.15, p[1] - 0.1, p[2] + 0.2])
            .collect();
        let shifted_core: Vec<[f32; 3]> = shifted
            .chunks_exact(3)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        let core_mesh = antumbra_core::MeshView::new(&shifted_core, &indices).unwrap();
        for structure in 0..4 {
            let ssv = create(structure, &samples, 0);
            let before = query(ssv);
            let view = antumbra_mesh_view {
                positions: shifted.as_ptr(),
                vertex_count: 4,
                position_stride: 0,
                indices: indices.as_ptr(),
                triangle_count: 2,
            };
            // SAFETY: live handle (exclusive here) and arrays.
            let result = unsafe { antumbra_ssv_update(ssv, &view) };
            assert_eq!(result, ANTUMBRA_RESULT_OK);
            let mut stats = antumbra_ssv_statistics::default();
            // SAFETY: live handle, valid out pointer.
            let got = unsafe { antumbra_ssv_get_statistics(ssv, &mut stats) };
            assert_eq!((got, stats.queries), (ANTUMBRA_RESULT_OK, 0));
            let after = query(ssv);
            assert_ne!(
                after, before,
                "structure {structure}: the blocker did not move"
            );
            // SAFETY: a live handle.
            let options = unsafe { (*ssv).shadows.options() };
            let light = LightPolygon::new(
                &QUAD
                    .chunks_exact(3)
                    .map(Vec3::from_slice)
                    .collect::<Vec<_>>(),
            )
            .unwrap();
            let fresh = SoftShadows::new(
                &core_mesh,
                light,
                &to_vec3s(&samples, "samples").unwrap(),
                options,
            )
            .unwrap();
            for k in 0..n {
                let mut want = [0u64; 1];
                fresh
                    .query(Vec3::from_slice(&points[3 * k..]), &mut want)
                    .unwrap();
                assert_eq!(after[k], want[0], "structure {structure}, receiver {k}");
            }
            // Refused: an index out of range and a NULL mesh; nothing changes.
            let bad_indices = [0u32, 1, 2, 0, 2, 4];
            let bad = antumbra_mesh_view {
                indices: bad_indices.as_ptr(),
                ..view
            };
            // SAFETY: as above.
            let (out_of_range, null) = unsafe {
                (
                    antumbra_ssv_update(ssv, &bad),
                    antumbra_ssv_update(ssv, core::ptr::null()),
                )
            };
            assert_eq!(out_of_range, ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE);
            assert_eq!(null, ANTUMBRA_RESULT_NULL_ARGUMENT);
            assert_eq!(query(ssv), after);
            // SAFETY: from create, destroyed once.
            unsafe { antumbra_ssv_destroy(ssv) };
        }
    }

    #[test]
    fn a_panicking_query_poisons_the_handle() {
        let samples = generated(16);
        let ssv = create(ANTUMBRA_SSV_STRUCTURE_HIERARCHY, &samples, 0);
        let result = with_handle("test_query", ssv, |_| panic!("deliberate"));
        assert_eq!(result, ANTUMBRA_RESULT_PANIC);
        // SAFETY: an empty batch; only the poison check runs.
        let later = unsafe {
            antumbra_ssv_query(
                ssv,
                core::ptr::null(),
                0,
                core::ptr::null_mut(),
                core::ptr::null_mut(),
            )
        };
        assert_eq!(later, ANTUMBRA_RESULT_POISONED);
        // SAFETY: from create, destroyed once.
        unsafe { antumbra_ssv_destroy(ssv) };
    }

    #[test]
    fn generated_samples_equal_the_core_samples() {
        let samples = generated(37);
        let light = LightPolygon::new(&to_vec3s(&QUAD, "quad").unwrap()).unwrap();
        let want = light.samples(37, SamplePattern::Jittered, 7);
        assert_eq!(to_vec3s(&samples, "samples").unwrap(), want);
    }
}
