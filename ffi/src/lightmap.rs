//! Lightmaps for C callers (core's `lightmap`): the texels of a mesh's UV atlas
//! as receivers, lifted out of geometry, baked like vertices into a transfer set
//! whose entry `i` is receiver `i`, and expanded into a texture with its gutter.
//!
//! `antumbra_lightmap` is an immutable handle around core's `TexelAtlas`:
//! create builds it (and its lift, through a BVH built for the call); describe,
//! receivers, bake and expand only read it, so any number of threads may use
//! one handle at once.

#![cfg(feature = "std")]

use alloc::boxed::Box;
use alloc::vec::Vec;
use core::ffi::c_void;
use core::sync::atomic::AtomicBool;

use crate::boundary::{Poisonable, guard, with_handle};
use crate::error::Error;
use crate::mesh::{antumbra_mesh_view, mesh_from_c};
use crate::raw::{self, Span, Spans, check_disjoint};
use crate::result::*;
use crate::transfer::{
    antumbra_transfer, antumbra_transfer_options, antumbra_transfer_progress_fn, bake_normals,
    bake_with, boxed, check_out, scene_of,
};
use antumbra_core::lightmap::{
    AtlasError, AtlasOptions, LiftOptions, MAX_ATLAS_SIDE, MAX_ATLAS_TEXELS, MAX_GUTTER, TexelAtlas,
};
/// The largest side of a lightmap, in texels.
#[cfg(feature = "std")]
pub const ANTUMBRA_LIGHTMAP_MAX_SIDE: u32 = 16_384;
/// The most texels (`width × height`) of a lightmap.
#[cfg(feature = "std")]
pub const ANTUMBRA_LIGHTMAP_MAX_TEXELS: u64 = 1 << 26;
/// The largest gutter, in texels.
#[cfg(feature = "std")]
pub const ANTUMBRA_LIGHTMAP_MAX_GUTTER: u32 = 64;
/// The most lift probes per receiver.
#[cfg(feature = "std")]
pub const ANTUMBRA_LIGHTMAP_MAX_PROBES: u32 = 64;

// The header needs literals; they must be core's limits.
const _: () = assert!(
    ANTUMBRA_LIGHTMAP_MAX_SIDE == MAX_ATLAS_SIDE
        && ANTUMBRA_LIGHTMAP_MAX_TEXELS == MAX_ATLAS_TEXELS
        && ANTUMBRA_LIGHTMAP_MAX_GUTTER == MAX_GUTTER
);

/// How `antumbra_lightmap_create` lays out receivers. Fill with
/// `antumbra_lightmap_options_init`, then change fields.
///
/// Layout: four `uint32_t`, 16 bytes, no padding.
#[cfg(feature = "std")]
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct antumbra_lightmap_options {
    /// Width in texels, 1 to `ANTUMBRA_LIGHTMAP_MAX_SIDE`. Default 256.
    pub width: u32,
    /// Height in texels, 1 to `ANTUMBRA_LIGHTMAP_MAX_SIDE`; `width × height` at
    /// most `ANTUMBRA_LIGHTMAP_MAX_TEXELS`. Default 256.
    pub height: u32,
    /// Texels of gutter around every chart, 0 to `ANTUMBRA_LIGHTMAP_MAX_GUTTER`:
    /// texels that copy the nearest receiver, so bilinear filtering inside a
    /// chart never reads an unbaked texel (1 suffices; each mip level needs one
    /// more). Default 2.
    pub gutter: u32,
    /// Probe rays per receiver of the lift out of geometry, 0 to
    /// `ANTUMBRA_LIGHTMAP_MAX_PROBES` (0 turns the probes off). Default 8.
    pub lift_probes: u32,
}

const DEFAULT_OPTIONS: antumbra_lightmap_options = antumbra_lightmap_options {
    width: 256,
    height: 256,
    gutter: 2,
    lift_probes: 8,
};

/// What a lightmap holds, from `antumbra_lightmap_describe`.
///
/// Layout: four `uint32_t`, then a `size_t`; 24 bytes on 64-bit targets, 20 on
/// 32-bit, no padding.
#[cfg(feature = "std")]
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct antumbra_lightmap_info {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Gutter in texels.
    pub gutter: u32,
    /// Receivers the lift moved (off an edge into their triangle, where
    /// another surface may meet it, or out of geometry).
    pub lifted: u32,
    /// Receivers: the texels the charts cover or touch (the length of the
    /// arrays of `antumbra_lightmap_receivers`, and the vertex count of the set
    /// `antumbra_lightmap_bake` makes).
    pub receiver_count: usize,
}

/// The receivers of a lightmap over a mesh's UV atlas. Immutable and opaque;
/// created by `antumbra_lightmap_create`, freed with `antumbra_lightmap_destroy`.
#[cfg(feature = "std")]
pub struct antumbra_lightmap {
    atlas: TexelAtlas,
    lifted: u32,
    /// The mesh it was built from, to check that bakes get the same one.
    vertex_count: usize,
    triangle_count: usize,
    poisoned: AtomicBool,
}

impl Poisonable for antumbra_lightmap {
    const ARGUMENT: &'static str = "lightmap";

    fn poison_flag(&self) -> &AtomicBool {
        &self.poisoned
    }
}

/// Writes the default options: a 256 × 256 atlas, a 2-texel gutter, 8 lift
/// probes.
///
/// @param options the options to fill; every field is written.
///
/// On a NULL or misaligned pointer nothing is written, and the thread's last error
/// message and the error callback report ANTUMBRA_RESULT_NULL_ARGUMENT or
/// ANTUMBRA_RESULT_INVALID_ARGUMENT.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `options` must be NULL or valid for writing one `antumbra_lightmap_options`.
#[cfg(feature = "std")]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_lightmap_options_init(options: *mut antumbra_lightmap_options) {
    let _ = guard("antumbra_lightmap_options_init", || {
        raw::write_one(options, DEFAULT_OPTIONS, "options")
    });
}

fn atlas_error(error: AtlasError) -> Error {
    let argument = match error {
        AtlasError::Resolution { .. } => "options->width and height",
        AtlasError::Gutter { .. } => "options->gutter",
        AtlasError::Count { argument, .. } => argument,
        AtlasError::UvOutOfRange { .. }
        | AtlasError::DegenerateUv { .. }
        | AtlasError::Overlap { .. } => "uvs",
        AtlasError::Normal { .. } => "normals",
        AtlasError::OutOfMemory => {
            return Error::new(ANTUMBRA_RESULT_OUT_OF_MEMORY, message!("lightmap: {error}"));
        }
    };
    Error::invalid(message!("{argument}: {error}"))
}

/// Builds the receivers of a lightmap over a mesh's UV atlas: every texel of a
/// `width × height` atlas whose centre a triangle's UVs cover (exactly, with a
/// fill rule on shared edges), or that a triangle's UVs overlap (the nearest
/// point of the nearest triangle), each with a surface point and normal; then
/// moves receivers that start inside geometry (a texel under a box on a floor)
/// past the back faces their probes meet; and marks a gutter around the charts.
/// Texel `(x, y)` covers `u` in `[x/W, (x+1)/W)`, `v` in `[y/H, (y+1)/H)`.
///
/// @param mesh the triangles; every vertex used by a triangle. Same rules as
///        `antumbra_scene_create`.
/// @param uvs 2 floats per vertex: each vertex's lightmap UV, in [0, 1]. The
///        charts (triangles in UV space) must not overlap, and no triangle may
///        have collinear UVs.
/// @param normals NULL (area-weighted vertex normals are computed) or 3 floats
///        per vertex: unit normals, interpolated to each receiver.
/// @param options the atlas (fill with `antumbra_lightmap_options_init`).
/// @param out receives the new lightmap; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (mesh, uvs, options, out);
///         INVALID_ARGUMENT (a size, gutter or probe count out of range, a UV
///         outside [0, 1], collinear UVs, overlapping charts naming both
///         triangles and the texel, a normal not unit length, no triangles,
///         misaligned pointers); INDEX_OUT_OF_RANGE; NON_FINITE (positions,
///         uvs, normals); OUT_OF_MEMORY; PANIC.
///
/// Cost: linear in the texels the triangles' UV boxes span, plus a BVH build and
/// `lift_probes` short rays per receiver. Thread safety: safe from any thread.
///
/// # Safety
/// Pointers must be NULL or valid as described; the arrays in `mesh` valid for the
/// counts and stride it gives.
#[cfg(feature = "std")]
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_lightmap_create(
    mesh: *const antumbra_mesh_view,
    uvs: *const f32,
    normals: *const f32,
    options: *const antumbra_lightmap_options,
    out: *mut *mut antumbra_lightmap,
) -> antumbra_result {
    guard("antumbra_lightmap_create", || {
        if out.is_null() {
            return Err(Error::null("out"));
        }
        let out = raw::writable(out, 1, "out")?;
        // SAFETY: caller contract on `mesh`.
        let view = unsafe { raw::reference(mesh, "mesh") }?;
        // SAFETY: caller contract on `options`; copied at once.
        let options = *unsafe { raw::reference(options, "options") }?;
        // SAFETY: caller contract on the arrays inside `mesh`.
        let mesh = unsafe { mesh_from_c(view, "mesh") }?;
        if mesh.triangle_count() == 0 {
            return Err(Error::invalid(
                "mesh->triangle_count is 0: a lightmap needs at least one triangle",
            ));
        }
        if uvs.is_null() {
            return Err(Error::null("uvs"));
        }
        let count = raw::element_count(mesh.vertex_count(), 2, "mesh->vertex_count")?;
        // SAFETY: caller contract on `uvs`.
        let flat = unsafe { raw::slice(uvs, count, "uvs") }?;
        if let Some(at) = flat.iter().position(|c| !c.is_finite()) {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!("uvs[{}] is not finite", at / 2),
            ));
        }
        // Sized by the caller: OUT_OF_MEMORY rather than an abort when refused.
        let mut uvs: Vec<[f32; 2]> =
            crate::fallible::vec_with_capacity(mesh.vertex_count(), "the uvs")?;
        uvs.extend(flat.chunks_exact(2).map(|uv| [uv[0], uv[1]]));
        // SAFETY: caller contract on `normals`.
        let normals = unsafe { bake_normals(&mesh, normals) }?;
        let atlas_options = AtlasOptions {
            width: options.width,
            height: options.height,
            gutter: options.gutter,
        };
        let mut atlas =
            TexelAtlas::new(&mesh, &uvs, &normals, &atlas_options).map_err(atlas_error)?;
        if options.lift_probes > ANTUMBRA_LIGHTMAP_MAX_PROBES {
            return Err(Error::invalid(message!(
                "options->lift_probes is {}; expected 0 to {ANTUMBRA_LIGHTMAP_MAX_PROBES}",
                options.lift_probes
            )));
        }
        let lifted = if options.lift_probes == 0 {
            0
        } else {
            let scene = scene_of(&mesh)?;
            let lift = LiftOptions {
                probes: options.lift_probes,
                ..LiftOptions::default()
            };
            atlas
                .lift(&mesh, &scene, &lift)
                .expect("the default lift height and reach are valid") as u32
        };
        let handle = crate::fallible::boxed(
            antumbra_lightmap {
                atlas,
                lifted,
                vertex_count: mesh.vertex_count(),
                triangle_count: mesh.triangle_count(),
                poisoned: AtomicBool::new(false),
            },
            "the lightmap handle",
        )?;
        // SAFETY: checked non-NULL and aligned above; valid by contract.
        unsafe { out.write(Box::into_raw(handle)) };
        Ok(())
    })
}

/// Frees a lightmap. NULL is a no-op.
///
/// Ownership: takes back a lightmap from create; it must not be used afterwards.
/// Thread safety: needs exclusive access: no other call on it may be running.
///
/// # Safety
/// `lightmap` must be NULL or a live lightmap, destroyed at most once.
#[cfg(feature = "std")]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_lightmap_destroy(lightmap: *mut antumbra_lightmap) {
    if !lightmap.is_null() {
        // SAFETY: by contract a live handle from `Box::into_raw`, freed once.
        drop(unsafe { Box::from_raw(lightmap) });
    }
}

/// Describes a lightmap.
///
/// @param lightmap a live lightmap.
/// @param info receives the description; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT; INVALID_ARGUMENT (misaligned);
///         POISONED.
///
/// Thread safety: safe from any thread, concurrently with other reads.
///
/// # Safety
/// `lightmap` must be NULL or live; `info` NULL or valid for one write.
#[cfg(feature = "std")]
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_lightmap_describe(
    lightmap: *const antumbra_lightmap,
    info: *mut antumbra_lightmap_info,
) -> antumbra_result {
    with_handle("antumbra_lightmap_describe", lightmap, |l| {
        let value = antumbra_lightmap_info {
            width: l.atlas.width(),
            height: l.atlas.height(),
            gutter: l.atlas.gutter(),
            lifted: l.lifted,
            receiver_count: l.atlas.receivers().len(),
        };
        raw::write_one(info, value, "info")
    })
}

/// Copies the receivers out, in texel order (row by row from texel (0, 0)).
///
/// @param lightmap a live lightmap.
/// @param positions NULL or 3 floats per receiver: where its rays start (after
///        the lift).
/// @param normals NULL or 3 floats per receiver: its unit normal.
/// @param texels NULL or 2 `uint32_t` per receiver: its texel (x, y).
/// @param receiver_count the lightmap's receiver count (see
///        `antumbra_lightmap_describe`).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (lightmap, or all three arrays);
///         INVALID_ARGUMENT (receiver_count, misaligned or overlapping arrays);
///         POISONED. The arrays are untouched on failure.
///
/// Thread safety: safe from any thread, concurrently with other reads.
///
/// # Safety
/// Each array NULL or valid for writing its length; they must not overlap.
#[cfg(feature = "std")]
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_lightmap_receivers(
    lightmap: *const antumbra_lightmap,
    positions: *mut f32,
    normals: *mut f32,
    texels: *mut u32,
    receiver_count: usize,
) -> antumbra_result {
    with_handle("antumbra_lightmap_receivers", lightmap, |l| {
        let receivers = l.atlas.receivers();
        if receiver_count != receivers.len() {
            return Err(Error::invalid(message!(
                "receiver_count is {receiver_count}; the lightmap has {} receivers",
                receivers.len()
            )));
        }
        if positions.is_null() && normals.is_null() && texels.is_null() {
            return Err(Error::null("positions, normals and texels are all NULL"));
        }
        let n3 = raw::element_count(receiver_count, 3, "receiver_count")?;
        let n2 = raw::element_count(receiver_count, 2, "receiver_count")?;
        let outputs = [
            Span::of("positions", positions, n3),
            Span::of("normals", normals, n3),
            Span::of("texels", texels, n2),
        ];
        check_disjoint(&outputs, &Spans::default())?;
        // SAFETY: caller contract; checked for alignment and overlap.
        let mut positions = unsafe { optional(positions, n3, "positions") }?;
        // SAFETY: as above.
        let mut normals = unsafe { optional(normals, n3, "normals") }?;
        // SAFETY: as above.
        let mut texels = unsafe { optional(texels, n2, "texels") }?;
        for (k, r) in receivers.iter().enumerate() {
            if let Some(p) = positions.as_deref_mut() {
                p[3 * k..3 * k + 3].copy_from_slice(&r.position.to_array());
            }
            if let Some(n) = normals.as_deref_mut() {
                n[3 * k..3 * k + 3].copy_from_slice(&r.normal.to_array());
            }
            if let Some(t) = texels.as_deref_mut() {
                t[2 * k..2 * k + 2].copy_from_slice(&r.texel);
            }
        }
        Ok(())
    })
}

/// `len` writable elements at `pointer`, or `None` for NULL.
///
/// # Safety
/// `pointer` NULL or valid for `len` writes, not aliased, for `'a`.
unsafe fn optional<'a, T>(
    pointer: *mut T,
    len: usize,
    argument: &str,
) -> Result<Option<&'a mut [T]>, Error> {
    if pointer.is_null() {
        return Ok(None);
    }
    // SAFETY: caller contract.
    unsafe { raw::slice_mut(pointer, len, argument) }.map(Some)
}

/// Bakes the lightmap's receivers against the mesh it was built from: the same
/// engine and options as `antumbra_transfer_bake`, each receiver drawing its own
/// rays, so the set's entry `i` (its "vertex" `i`) is receiver `i`. With
/// bounces, a receiver's pass k reads pass k - 1 of the texel under each hit's
/// UV (the gutter included), so light bounces between texels. Shade, save and
/// compress the set as any other.
///
/// @param lightmap a live lightmap.
/// @param mesh the mesh the lightmap was built from (same vertex and triangle
///        counts; same rules as `antumbra_transfer_bake`).
/// @param normals NULL (area-weighted) or 3 floats per vertex: the vertex normals
///        that tell a hit's front from its back.
/// @param options what to measure (fill with `antumbra_transfer_options_init`).
/// @param progress NULL or a function told of progress: `done` of `total`
///        passes (receivers × (1 + bounces)).
/// @param user_data passed to `progress` untouched.
/// @param out receives the new transfer set; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT; INVALID_ARGUMENT (a mesh other than
///         the lightmap's, options as `antumbra_transfer_bake`); NON_FINITE;
///         OUT_OF_MEMORY; POISONED; PANIC.
///
/// Cost: as a vertex bake of `receiver_count` vertices. Thread safety: safe from
/// any thread, concurrently with other reads of the lightmap.
///
/// # Safety
/// As `antumbra_transfer_bake`; `lightmap` NULL or live.
#[cfg(feature = "std")]
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_lightmap_bake(
    lightmap: *const antumbra_lightmap,
    mesh: *const antumbra_mesh_view,
    normals: *const f32,
    options: *const antumbra_transfer_options,
    progress: antumbra_transfer_progress_fn,
    user_data: *mut c_void,
    out: *mut *mut antumbra_transfer,
) -> antumbra_result {
    with_handle("antumbra_lightmap_bake", lightmap, |l| {
        let out = check_out(out)?;
        // SAFETY: caller contract on `mesh`.
        let view = unsafe { raw::reference(mesh, "mesh") }?;
        // SAFETY: caller contract on `options`.
        let options = unsafe { raw::reference(options, "options") }?;
        // SAFETY: caller contract on the arrays inside `mesh`.
        let mesh = unsafe { mesh_from_c(view, "mesh") }?;
        if (mesh.vertex_count(), mesh.triangle_count()) != (l.vertex_count, l.triangle_count) {
            return Err(Error::invalid(message!(
                "mesh has {} vertices and {} triangles; the lightmap was built from {} and {}",
                mesh.vertex_count(),
                mesh.triangle_count(),
                l.vertex_count,
                l.triangle_count
            )));
        }
        // SAFETY: caller contract on `normals`.
        let normals = unsafe { bake_normals(&mesh, normals) }?;
        let scene = scene_of(&mesh)?;
        let parallel = options.parallel == 1;
        let set = bake_with(options, progress, user_data, |bake_options| {
            l.atlas
                .bake(&mesh, &normals, &scene, bake_options, parallel)
        })?;
        boxed(set, out)
    })
}

/// Writes a texture from per-receiver values: each texel the values of the
/// receiver it reads (its own, or for a gutter texel the nearest receiver's);
/// texels outside the charts and gutter are left as they are. Row `y` of the
/// image is texel row `y` (`v` from `y/H`), `channels` floats per texel.
///
/// @param lightmap a live lightmap.
/// @param values `channels` floats per receiver, in receiver order (finite or
///        not: copied as given).
/// @param value_count `receiver_count × channels`.
/// @param channels floats per texel, at least 1.
/// @param image `width × height × channels` floats.
/// @param image_count its length, `width × height × channels`.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT; INVALID_ARGUMENT (a count that does
///         not match, channels 0, misaligned or overlapping arrays); POISONED.
///         The image is untouched on failure.
///
/// Thread safety: safe from any thread, concurrently with other reads.
///
/// # Safety
/// `values` valid for `value_count` reads, `image` for `image_count` writes,
/// not overlapping.
#[cfg(feature = "std")]
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_lightmap_expand(
    lightmap: *const antumbra_lightmap,
    values: *const f32,
    value_count: usize,
    channels: u32,
    image: *mut f32,
    image_count: usize,
) -> antumbra_result {
    with_handle("antumbra_lightmap_expand", lightmap, |l| {
        let size = (l.atlas.width(), l.atlas.height());
        let receivers = l.atlas.receivers().len();
        // SAFETY: caller contract on the arrays.
        let (values, image, channels) = unsafe {
            crate::transfer_texels::expand_arguments(
                (values, value_count),
                channels,
                (image, image_count),
                (receivers, "receivers"),
                size,
            )
        }?;
        l.atlas
            .expand(values, channels, image)
            .ok_or_else(|| Error::invalid("the counts do not match the lightmap"))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transfer::{antumbra_transfer_describe, antumbra_transfer_destroy};
    use crate::transfer_texels::antumbra_transfer_texels;
    use antumbra_core::MeshView;
    use antumbra_core::raycast::BvhScene;
    use antumbra_core::transfer::{BakeOptions, Measurement};
    use glam::Vec3;

    /// Create, describe, receivers and bake through the ABI give what core's
    /// atlas, lift and `bake_points` give on the same input.
    #[test]
    fn the_abi_is_cores_atlas_and_point_bake() {
        let positions = [
            0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0,
        ];
        let uvs = [0.1f32, 0.1, 0.9, 0.1, 0.1, 0.9, 0.95, 0.95];
        // A triangle on the floor and one standing over its corner.
        let indices = [0u32, 1, 2, 1, 3, 2];
        let view = antumbra_mesh_view {
            positions: positions.as_ptr(),
            vertex_count: 4,
            position_stride: 0,
            indices: indices.as_ptr(),
            triangle_count: 2,
        };
        let options = antumbra_lightmap_options {
            width: 16,
            height: 8,
            ..DEFAULT_OPTIONS
        };
        let mut handle = core::ptr::null_mut();
        // SAFETY: valid arrays and pointers.
        let created = unsafe {
            antumbra_lightmap_create(
                &view,
                uvs.as_ptr(),
                core::ptr::null(),
                &options,
                &mut handle,
            )
        };
        assert_eq!(created, ANTUMBRA_RESULT_OK);
        let mut info = antumbra_lightmap_info {
            width: 0,
            height: 0,
            gutter: 0,
            lifted: 0,
            receiver_count: 0,
        };
        // SAFETY: a live handle.
        let described = unsafe { antumbra_lightmap_describe(handle, &mut info) };
        assert_eq!(described, ANTUMBRA_RESULT_OK);
        assert_eq!((info.width, info.height, info.gutter), (16, 8, 2));

        // Core on the same input.
        let flat: Vec<[f32; 3]> = positions.chunks(3).map(|p| [p[0], p[1], p[2]]).collect();
        let mesh = MeshView::new(&flat, &indices).unwrap();
        let mut normals = vec![Vec3::ZERO; 4];
        antumbra_core::hemi::vertex_normals(&mesh, &mut normals).unwrap();
        let uv_pairs: Vec<[f32; 2]> = uvs.chunks(2).map(|t| [t[0], t[1]]).collect();
        let mut atlas =
            TexelAtlas::new(&mesh, &uv_pairs, &normals, &AtlasOptions::new(16, 8)).unwrap();
        let scene = BvhScene::new(&mesh).unwrap();
        let lifted = atlas.lift(&mesh, &scene, &LiftOptions::default()).unwrap();
        assert_eq!(info.receiver_count, atlas.receivers().len());
        assert_eq!(info.lifted as usize, lifted);

        let n = info.receiver_count;
        let (mut texels, mut points) = (vec![0u32; 2 * n], vec![0.0f32; 3 * n]);
        // SAFETY: arrays of the receiver count.
        let copied = unsafe {
            antumbra_lightmap_receivers(
                handle,
                points.as_mut_ptr(),
                core::ptr::null_mut(),
                texels.as_mut_ptr(),
                n,
            )
        };
        assert_eq!(copied, ANTUMBRA_RESULT_OK);
        for (k, r) in atlas.receivers().iter().enumerate() {
            assert_eq!(texels[2 * k..2 * k + 2], r.texel);
            assert_eq!(points[3 * k..3 * k + 3], r.position.to_array());
        }

        let mut transfer_options = crate::transfer::DEFAULT_OPTIONS;
        transfer_options.bands = 3;
        transfer_options.rays = 32;
        let mut set = core::ptr::null_mut();
        // SAFETY: valid pointers; a live handle.
        let baked = unsafe {
            antumbra_lightmap_bake(
                handle,
                &view,
                core::ptr::null(),
                &transfer_options,
                None,
                core::ptr::null_mut(),
                &mut set,
            )
        };
        assert_eq!(baked, ANTUMBRA_RESULT_OK);
        let bake_options = BakeOptions {
            bands: 3,
            rays: 32,
            ..BakeOptions::new(Measurement::Diffuse)
        };
        let want = atlas
            .bake(&mesh, &normals, &scene, &bake_options, false)
            .unwrap();
        // SAFETY: a live set from the bake.
        let got = unsafe { &(*set).set };
        assert_eq!(*got, want);
        let mut set_info = core::mem::MaybeUninit::uninit();
        // SAFETY: a live set; valid for one write.
        let described = unsafe { antumbra_transfer_describe(set, set_info.as_mut_ptr()) };
        assert_eq!(described, ANTUMBRA_RESULT_OK);
        // SAFETY: written by describe.
        let set_info = unsafe { set_info.assume_init() };
        assert_eq!((set_info.atlas_width, set_info.atlas_height), (16, 8));

        // The set's texels are the receivers', and its texture with the same
        // gutter is the lightmap's.
        let mut indices_out = vec![0u32; n];
        // SAFETY: a live set; room for its entries.
        let copied = unsafe { antumbra_transfer_texels(set, indices_out.as_mut_ptr(), n) };
        assert_eq!(copied, ANTUMBRA_RESULT_OK);
        for (k, r) in atlas.receivers().iter().enumerate() {
            assert_eq!(indices_out[k], r.texel[1] * 16 + r.texel[0]);
        }
        // SAFETY: a live set; a wrong count is refused with the output untouched.
        let refused = unsafe { antumbra_transfer_texels(set, indices_out.as_mut_ptr(), n + 1) };
        assert_eq!(refused, crate::result::ANTUMBRA_RESULT_INVALID_ARGUMENT);
        let values: Vec<f32> = (0..2 * n).map(|i| i as f32 + 0.5).collect();
        let (mut from_lightmap, mut from_set) =
            (vec![-1.0f32; 16 * 8 * 2], vec![-1.0f32; 16 * 8 * 2]);
        // SAFETY: live handles; arrays of the stated lengths, disjoint.
        unsafe {
            let a = antumbra_lightmap_expand(
                handle,
                values.as_ptr(),
                values.len(),
                2,
                from_lightmap.as_mut_ptr(),
                from_lightmap.len(),
            );
            let b = crate::transfer_texels::antumbra_transfer_expand(
                set,
                2,
                values.as_ptr(),
                values.len(),
                2,
                from_set.as_mut_ptr(),
                from_set.len(),
            );
            assert_eq!((a, b), (ANTUMBRA_RESULT_OK, ANTUMBRA_RESULT_OK));
            let wide = crate::transfer_texels::antumbra_transfer_expand(
                set,
                65,
                values.as_ptr(),
                values.len(),
                2,
                from_set.as_mut_ptr(),
                from_set.len(),
            );
            assert_eq!(wide, crate::result::ANTUMBRA_RESULT_INVALID_ARGUMENT);
        }
        assert_eq!(from_set, from_lightmap);
        // SAFETY: from bake and create, destroyed once.
        unsafe {
            antumbra_transfer_destroy(set);
            antumbra_lightmap_destroy(handle);
        }
    }
}
