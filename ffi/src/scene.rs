//! `antumbra_scene`: a BVH over a mesh, the ray caster C users and later Antumbra
//! entry points share.

use std::sync::atomic::AtomicBool;

use antumbra_core::raycast::{BvhError, BvhScene};
use antumbra_core::{MeshView, Ray, RayCaster};
use glam::Vec3;

use crate::boundary::{Poisonable, guard, with_handle, with_handle_mut};
use crate::error::Error;
use crate::mesh::{antumbra_mesh_view, mesh_from_c};
use crate::raw;
use crate::result::*;

/// Triangle index reported by a ray that hits nothing.
pub const ANTUMBRA_INVALID_INDEX: u32 = u32::MAX;

/// A ray-casting scene: a compressed wide BVH over a copy of a mesh's
/// triangles. Opaque; create with `antumbra_scene_create`, move its triangles
/// with `antumbra_scene_refit`, free with `antumbra_scene_destroy`.
pub struct antumbra_scene {
    bvh: BvhScene,
    poisoned: AtomicBool,
}

// Queries take `&antumbra_scene` from many threads; keep that true by construction.
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<antumbra_scene>();
};

/// The closest hit of one ray.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct antumbra_hit {
    /// Ray parameter of the hit in units of the direction's length; +INFINITY on a miss.
    pub distance: f32,
    /// Index of the triangle hit; ANTUMBRA_INVALID_INDEX on a miss.
    pub triangle: u32,
    /// Barycentric weight of the triangle's second corner (0 on a miss).
    pub u: f32,
    /// Barycentric weight of the third corner; hit = (1-u-v)*v0 + u*v1 + v*v2.
    pub v: f32,
}

const MISS: antumbra_hit = antumbra_hit {
    distance: f32::INFINITY,
    triangle: ANTUMBRA_INVALID_INDEX,
    u: 0.0,
    v: 0.0,
};

/// Builds a scene over `mesh`, copying its triangles (the mesh may be freed
/// afterwards).
///
/// @param mesh the triangles; at least one. Every index < vertex_count, every
///        coordinate finite and within ±1e12 (vertices used by triangles),
///        position_stride 0 (packed) or >= 12.
/// @param out receives the new scene on success; untouched on failure.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (mesh, out, or a NULL array with a
///         non-zero count); INVALID_ARGUMENT (no triangles, stride below 12,
///         misaligned indices or out, size overflow, coordinate beyond ±1e12);
///         INDEX_OUT_OF_RANGE; NON_FINITE; OUT_OF_MEMORY (when the triangle
///         arrays cannot be reserved; the BVH builder's own temporary allocations
///         abort the process on exhaustion, as Rust allocations do); PANIC.
///
/// Ownership: the caller owns `*out` and frees it with `antumbra_scene_destroy`.
/// Thread safety: safe from any thread; the new scene is independent of others.
///
/// # Safety
/// `mesh` and `out` must be NULL or valid; the arrays in `mesh` must be valid for
/// the counts and stride it gives.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_scene_create(
    mesh: *const antumbra_mesh_view,
    out: *mut *mut antumbra_scene,
) -> antumbra_result {
    guard("antumbra_scene_create", || {
        if out.is_null() {
            return Err(Error::null("out"));
        }
        let out = raw::writable(out, 1, "out")?;
        // SAFETY: caller contract on `mesh`.
        let view = unsafe { raw::reference(mesh, "mesh") }?;
        // SAFETY: caller contract on the arrays inside `mesh`.
        let mesh = unsafe { mesh_from_c(view, "mesh") }?;
        if mesh.triangle_count() == 0 {
            return Err(Error::invalid(
                "mesh->triangle_count is 0: a scene needs at least one triangle",
            ));
        }
        let bvh = BvhScene::new(&mesh).map_err(|e| scene_error(e, &mesh))?;
        let scene = Box::new(antumbra_scene {
            bvh,
            poisoned: AtomicBool::new(false),
        });
        // SAFETY: `out` is non-NULL and, by contract, valid for a pointer write.
        unsafe { *out = Box::into_raw(scene) };
        Ok(())
    })
}

/// A scene error, named as the C API names the mesh's fields.
pub(crate) fn scene_error(error: BvhError, mesh: &MeshView<'_>) -> Error {
    match error {
        BvhError::CoordinateOutOfRange { vertex } => Error::invalid(message!(
            "mesh->positions: vertex {vertex} has a coordinate beyond the supported \
             range of ±{:e}",
            antumbra_core::raycast::MAX_COORDINATE
        )),
        BvhError::OutOfMemory(e) => Error::new(
            ANTUMBRA_RESULT_OUT_OF_MEMORY,
            message!("no memory for {} triangles: {e}", mesh.triangle_count()),
        ),
        BvhError::TriangleCountChanged { scene, mesh } => Error::invalid(message!(
            "mesh->triangle_count is {mesh} but the scene has {scene} triangles: a refit \
             moves the same triangles (create a new scene for another mesh)"
        )),
    }
}

/// Moves a scene's triangles to `mesh`'s current positions, keeping its
/// hierarchy: triangle t of the scene becomes triangle t of `mesh`. For a
/// mesh that deforms or moves every frame: linear in the triangles and about
/// ten times cheaper than `antumbra_scene_create` (the armadillo's 52,000
/// triangles: about 3 ms against 33 ms on one core). Every query afterwards
/// answers as a scene created from `mesh` would (a closest hit at exactly the
/// distance of another triangle may report either); only their speed drops
/// as deformation distorts the hierarchy, so create a new scene after large
/// changes of shape.
///
/// @param scene the scene to move.
/// @param mesh the moved triangles: as many as the scene's, checked as
///        `antumbra_scene_create` checks a mesh (usually the same indices with
///        new positions).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (scene, mesh, or a NULL array with
///         a non-zero count); INVALID_ARGUMENT (another triangle count, stride
///         below 12, misaligned arrays, size overflow, coordinate beyond
///         ±1e12); INDEX_OUT_OF_RANGE; NON_FINITE; OUT_OF_MEMORY (the refit's
///         scratch, 24 bytes per node, on the first refit); POISONED; PANIC.
///         On failure the scene is unchanged.
///
/// Ownership: borrows both for the call. Thread safety: needs exclusive access
/// to `scene`: no query or other call on it may be running.
///
/// # Safety
/// `scene` must be NULL or a live scene from `antumbra_scene_create`; `mesh`
/// NULL or valid, its arrays valid for the counts and stride it gives.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_scene_refit(
    scene: *mut antumbra_scene,
    mesh: *const antumbra_mesh_view,
) -> antumbra_result {
    with_handle_mut("antumbra_scene_refit", scene, |scene| {
        // SAFETY: caller contract on `mesh`.
        let view = unsafe { raw::reference(mesh, "mesh") }?;
        // SAFETY: caller contract on the arrays inside `mesh`.
        let mesh = unsafe { mesh_from_c(view, "mesh") }?;
        scene.bvh.refit(&mesh).map_err(|e| scene_error(e, &mesh))
    })
}

/// Frees a scene. NULL is a no-op.
///
/// Ownership: takes back a scene from `antumbra_scene_create`; it must not be used
/// afterwards. Thread safety: needs exclusive access: no query on this scene may
/// be running.
///
/// # Safety
/// `scene` must be NULL or a live scene from `antumbra_scene_create`, destroyed at
/// most once.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_scene_destroy(scene: *mut antumbra_scene) {
    let _ = guard("antumbra_scene_destroy", || {
        if !scene.is_null() {
            // SAFETY: by contract, a live scene created by `Box::into_raw`.
            drop(unsafe { Box::from_raw(scene) });
        }
        Ok(())
    });
}

/// Rays described by three parallel arrays, validated once.
struct RayBatch<'a> {
    origins: &'a [f32],
    directions: &'a [f32],
    t_max: &'a [f32],
}

impl<'a> RayBatch<'a> {
    /// # Safety
    /// The pointers must be valid for `ray_count` rays as documented on the exports.
    unsafe fn new(
        origins: *const f32,
        directions: *const f32,
        t_max: *const f32,
        ray_count: usize,
    ) -> Result<Self, Error> {
        let xyz = raw::element_count(ray_count, 3, "ray_count")?;
        // SAFETY: caller contract forwarded.
        let origins = unsafe { raw::slice(origins, xyz, "origins") }?;
        // SAFETY: caller contract forwarded.
        let directions = unsafe { raw::slice(directions, xyz, "directions") }?;
        // SAFETY: caller contract forwarded.
        let t_max = unsafe { raw::slice(t_max, ray_count, "t_max") }?;
        for i in 0..ray_count {
            let o = &origins[3 * i..3 * i + 3];
            if !o.iter().all(|c| c.is_finite()) {
                return Err(non_finite("origins", i, o));
            }
            let d = &directions[3 * i..3 * i + 3];
            if !d.iter().all(|c| c.is_finite()) {
                return Err(non_finite("directions", i, d));
            }
            if d.iter().all(|&c| c == 0.0) {
                return Err(Error::invalid(message!(
                    "directions[{i}] is the zero vector"
                )));
            }
            let t = t_max[i];
            if t.is_nan() {
                return Err(Error::new(
                    ANTUMBRA_RESULT_NON_FINITE,
                    message!("t_max[{i}] is NaN"),
                ));
            }
            if t < 0.0 {
                return Err(Error::invalid(message!(
                    "t_max[{i}] is {t}; it must be >= 0 (+INFINITY for an unbounded ray)"
                )));
            }
        }
        Ok(RayBatch {
            origins,
            directions,
            t_max,
        })
    }

    /// Calls `f` with the rays [`PACKET`] at a time and the matching part of
    /// `out` (one entry per ray): the core traces rays from one point
    /// together (`RayCaster::occluded_many`, `closest_hit_many`).
    fn in_packets<T>(&self, out: &mut [T], mut f: impl FnMut(&[Ray], &mut [T])) {
        let mut chunk = [Ray::new(Vec3::ZERO, Vec3::Z, 0.0); PACKET];
        for (c, part) in out.chunks_mut(PACKET).enumerate() {
            let chunk = &mut chunk[..part.len()];
            for (k, ray) in chunk.iter_mut().enumerate() {
                *ray = self.ray(c * PACKET + k);
            }
            f(chunk, part);
        }
    }

    fn ray(&self, i: usize) -> Ray {
        let o = &self.origins[3 * i..3 * i + 3];
        let d = &self.directions[3 * i..3 * i + 3];
        Ray::new(
            Vec3::new(o[0], o[1], o[2]),
            Vec3::new(d[0], d[1], d[2]),
            self.t_max[i],
        )
    }
}

/// Rays handed to the core per call: a packet of the BVH.
const PACKET: usize = 64;

fn non_finite(argument: &str, ray: usize, xyz: &[f32]) -> Error {
    Error::new(
        ANTUMBRA_RESULT_NON_FINITE,
        message!(
            "{argument}[{ray}] ({}, {}, {}) is not finite",
            xyz[0],
            xyz[1],
            xyz[2]
        ),
    )
}

impl Poisonable for antumbra_scene {
    const ARGUMENT: &'static str = "scene";

    fn poison_flag(&self) -> &AtomicBool {
        &self.poisoned
    }
}

/// Any-hit occlusion for a batch of rays: `occluded[i] = 1` when ray i hits a
/// triangle at some `0 < t < t_max[i]` (t in units of `|directions[i]|`), else 0.
/// Triangles are two-sided; the triangle test is watertight. Consecutive rays
/// are traced in packets of up to 64; rays that start at one point with
/// unbounded t_max (a bake's, an ambient-occlusion probe's) go about twice as
/// fast as one by one, with the same answers.
///
/// @param scene the scene.
/// @param origins 3 floats per ray, finite.
/// @param directions 3 floats per ray, finite, not all zero; need not be unit.
/// @param t_max one per ray, >= 0; +INFINITY for unbounded rays.
/// @param ray_count number of rays; 0 is a valid empty batch (arrays may be NULL).
/// @param occluded receives one byte per ray; untouched on failure (except after
///        ANTUMBRA_RESULT_PANIC, an internal bug, when it may be partly written).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (scene, or an array with ray_count
///         > 0); INVALID_ARGUMENT (zero direction, negative t_max, misaligned
///         array, ray_count overflow); NON_FINITE (NaN or infinite origin or
///         direction, NaN t_max); POISONED; PANIC.
///
/// Ownership: borrows every array for the call only.
/// Thread safety: any number of threads may query the same scene at once.
///
/// # Safety
/// Each non-NULL array must be valid for `ray_count` rays; `occluded` must not
/// overlap the inputs.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_scene_occluded(
    scene: *const antumbra_scene,
    origins: *const f32,
    directions: *const f32,
    t_max: *const f32,
    ray_count: usize,
    occluded: *mut u8,
) -> antumbra_result {
    with_handle("antumbra_scene_occluded", scene, |scene| {
        // SAFETY: caller contract forwarded.
        let rays = unsafe { RayBatch::new(origins, directions, t_max, ray_count) }?;
        // SAFETY: caller contract forwarded.
        let out = unsafe { raw::slice_mut(occluded, ray_count, "occluded") }?;
        let mut answers = [false; PACKET];
        rays.in_packets(out, |chunk, flags| {
            let answers = &mut answers[..chunk.len()];
            scene.bvh.occluded_many(chunk, answers);
            for (flag, &answer) in flags.iter_mut().zip(answers.iter()) {
                *flag = u8::from(answer);
            }
        });
        Ok(())
    })
}

/// Closest hit for a batch of rays: the hit with the smallest t in
/// `0 < t < t_max[i]` (t in units of `|directions[i]|`). A miss reports distance
/// +INFINITY, triangle ANTUMBRA_INVALID_INDEX and u = v = 0. Equal-distance ties
/// may report either triangle. Triangles are two-sided; the test is watertight.
/// Consecutive rays are traced in packets of up to 64, as by
/// antumbra_scene_occluded.
///
/// @param scene the scene.
/// @param origins 3 floats per ray, finite.
/// @param directions 3 floats per ray, finite, not all zero; need not be unit.
/// @param t_max one per ray, >= 0; +INFINITY for unbounded rays.
/// @param ray_count number of rays; 0 is a valid empty batch (arrays may be NULL).
/// @param hits receives one antumbra_hit per ray; untouched on failure (except
///        after ANTUMBRA_RESULT_PANIC, an internal bug, when it may be partly
///        written).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (scene, or an array with ray_count
///         > 0); INVALID_ARGUMENT (zero direction, negative t_max, misaligned
///         array, ray_count overflow); NON_FINITE (NaN or infinite origin or
///         direction, NaN t_max); POISONED; PANIC.
///
/// Ownership: borrows every array for the call only.
/// Thread safety: any number of threads may query the same scene at once.
///
/// # Safety
/// As `antumbra_scene_occluded`, with `hits` valid for `ray_count` hits.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_scene_intersect(
    scene: *const antumbra_scene,
    origins: *const f32,
    directions: *const f32,
    t_max: *const f32,
    ray_count: usize,
    hits: *mut antumbra_hit,
) -> antumbra_result {
    with_handle("antumbra_scene_intersect", scene, |scene| {
        // SAFETY: caller contract forwarded.
        let rays = unsafe { RayBatch::new(origins, directions, t_max, ray_count) }?;
        // SAFETY: caller contract forwarded.
        let out = unsafe { raw::slice_mut(hits, ray_count, "hits") }?;
        let mut found = [None; PACKET];
        rays.in_packets(out, |chunk, slots| {
            let found = &mut found[..chunk.len()];
            scene.bvh.closest_hit_many(chunk, found);
            for (slot, hit) in slots.iter_mut().zip(found.iter()) {
                *slot = hit.map_or(MISS, |hit| antumbra_hit {
                    distance: hit.t,
                    triangle: hit.triangle,
                    u: hit.u,
                    v: hit.v,
                });
            }
        });
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wavy 8 × 8 grid of quads over z = `height`.
    fn grid(height: f32, wave: f32) -> (Vec<f32>, Vec<u32>) {
        let mut positions = Vec::new();
        for j in 0..9 {
            for i in 0..9 {
                let (x, y) = (i as f32 / 8.0 - 0.5, j as f32 / 8.0 - 0.5);
                positions.extend([x, y, height + wave * (7.0 * x).sin() * (5.0 * y).cos()]);
            }
        }
        let mut indices = Vec::new();
        for j in 0..8u32 {
            for i in 0..8u32 {
                let v = j * 9 + i;
                indices.extend([v, v + 1, v + 10, v, v + 10, v + 9]);
            }
        }
        (positions, indices)
    }

    fn view(positions: &[f32], indices: &[u32]) -> antumbra_mesh_view {
        antumbra_mesh_view {
            positions: positions.as_ptr(),
            vertex_count: positions.len() / 3,
            position_stride: 0,
            indices: indices.as_ptr(),
            triangle_count: indices.len() / 3,
        }
    }

    /// Every ray's closest hit (through `antumbra_scene_intersect`).
    fn hits(
        scene: *const antumbra_scene,
        origins: &[f32],
        directions: &[f32],
    ) -> Vec<antumbra_hit> {
        let count = origins.len() / 3;
        let t_max = vec![f32::INFINITY; count];
        let mut out = vec![MISS; count];
        // SAFETY: arrays of `count` rays and hits.
        let result = unsafe {
            antumbra_scene_intersect(
                scene,
                origins.as_ptr(),
                directions.as_ptr(),
                t_max.as_ptr(),
                count,
                out.as_mut_ptr(),
            )
        };
        assert_eq!(result, ANTUMBRA_RESULT_OK);
        out
    }

    #[test]
    fn a_refitted_scene_answers_as_a_new_one_and_bad_refits_change_nothing() {
        let (flat, indices) = grid(1.0, 0.0);
        let (wavy, _) = grid(0.6, 0.2);
        let mut scene = std::ptr::null_mut();
        // SAFETY: live arrays, valid out pointer.
        let created = unsafe { antumbra_scene_create(&view(&flat, &indices), &mut scene) };
        assert_eq!(created, ANTUMBRA_RESULT_OK);
        let mut fresh = std::ptr::null_mut();
        // SAFETY: as above.
        let created = unsafe { antumbra_scene_create(&view(&wavy, &indices), &mut fresh) };
        assert_eq!(created, ANTUMBRA_RESULT_OK);
        // A fan of rays up from below the grid.
        let (mut origins, mut directions) = (Vec::new(), Vec::new());
        for k in 0..400 {
            let (a, b) = (k as f32 * 0.754_877_7 % 1.0, k as f32 * 0.569_840_3 % 1.0);
            origins.extend([0.1, -0.05, 0.0]);
            directions.extend([a - 0.5, b - 0.5, 0.7]);
        }
        let before = hits(scene, &origins, &directions);
        // SAFETY: live scene (exclusive here) and arrays.
        let refitted = unsafe { antumbra_scene_refit(scene, &view(&wavy, &indices)) };
        assert_eq!(refitted, ANTUMBRA_RESULT_OK);
        let after = hits(scene, &origins, &directions);
        assert_eq!(after, hits(fresh, &origins, &directions));
        assert_ne!(after, before, "the refit moved nothing");
        assert!(
            after
                .iter()
                .filter(|h| h.triangle != ANTUMBRA_INVALID_INDEX)
                .count()
                > 300
        );
        // Refused refits, the scene as it was.
        let message = || {
            // SAFETY: the library's message pointer is valid until the next call.
            let text = unsafe { std::ffi::CStr::from_ptr(crate::antumbra_last_error_message()) };
            text.to_str().unwrap().to_owned()
        };
        // SAFETY: as above; one triangle fewer.
        let fewer =
            unsafe { antumbra_scene_refit(scene, &view(&flat, &indices[..indices.len() - 3])) };
        assert_eq!(fewer, ANTUMBRA_RESULT_INVALID_ARGUMENT);
        assert!(
            message().contains("mesh->triangle_count is 127"),
            "{}",
            message()
        );
        let mut far = flat.clone();
        far[4] = 2e12;
        // SAFETY: as above.
        let out_of_range = unsafe { antumbra_scene_refit(scene, &view(&far, &indices)) };
        assert_eq!(out_of_range, ANTUMBRA_RESULT_INVALID_ARGUMENT);
        assert!(
            message().contains("mesh->positions: vertex 1"),
            "{}",
            message()
        );
        // SAFETY: NULL handle and NULL mesh are refused before any use.
        let (no_scene, no_mesh) = unsafe {
            (
                antumbra_scene_refit(std::ptr::null_mut(), &view(&flat, &indices)),
                antumbra_scene_refit(scene, std::ptr::null()),
            )
        };
        assert_eq!(
            (no_scene, no_mesh),
            (ANTUMBRA_RESULT_NULL_ARGUMENT, ANTUMBRA_RESULT_NULL_ARGUMENT)
        );
        assert_eq!(hits(scene, &origins, &directions), after);
        // A panic inside a changing call poisons the scene too.
        let result = with_handle_mut("test_refit", scene, |_| panic!("deliberate"));
        assert_eq!(result, ANTUMBRA_RESULT_PANIC);
        // SAFETY: live scene, refused as poisoned.
        let later = unsafe { antumbra_scene_refit(scene, &view(&wavy, &indices)) };
        assert_eq!(later, ANTUMBRA_RESULT_POISONED);
        // SAFETY: from create, destroyed once.
        unsafe {
            antumbra_scene_destroy(scene);
            antumbra_scene_destroy(fresh);
        }
    }

    #[test]
    fn a_panicking_query_poisons_the_scene() {
        let positions = [0.0f32, 0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 1.0, 1.0];
        let indices = [0u32, 1, 2];
        let view = antumbra_mesh_view {
            positions: positions.as_ptr(),
            vertex_count: 3,
            position_stride: 0,
            indices: indices.as_ptr(),
            triangle_count: 1,
        };
        let mut scene = std::ptr::null_mut();
        // SAFETY: live arrays, valid out pointer.
        let created = unsafe { antumbra_scene_create(&view, &mut scene) };
        assert_eq!(created, ANTUMBRA_RESULT_OK);
        let result = with_handle("test_query", scene, |_| panic!("deliberate"));
        assert_eq!(result, ANTUMBRA_RESULT_PANIC);
        // SAFETY: the library's message pointer is valid until the next call.
        let message = unsafe { std::ffi::CStr::from_ptr(crate::antumbra_last_error_message()) };
        assert!(message.to_str().unwrap().contains("deliberate"));
        // SAFETY: an empty batch; only the poison check runs.
        let later = unsafe {
            antumbra_scene_occluded(
                scene,
                std::ptr::null(),
                std::ptr::null(),
                std::ptr::null(),
                0,
                std::ptr::null_mut(),
            )
        };
        assert_eq!(later, ANTUMBRA_RESULT_POISONED);
        // SAFETY: from create, destroyed once.
        unsafe { antumbra_scene_destroy(scene) };
    }
}
