//! The C ABI called from Rust exactly as C would call it: results, messages naming
//! the argument, outputs untouched on failure, and agreement with the core caster.

use std::ffi::CStr;
use std::ptr;

use antumbra::*;

fn last_error() -> String {
    // SAFETY: the library returns a valid NUL-terminated string.
    unsafe { CStr::from_ptr(antumbra_last_error_message()) }
        .to_string_lossy()
        .into_owned()
}

/// A unit quad in the z = 1 plane as two triangles.
const QUAD: [f32; 12] = [-1., -1., 1., 1., -1., 1., 1., 1., 1., -1., 1., 1.];
const QUAD_INDICES: [u32; 6] = [0, 1, 2, 0, 2, 3];

fn quad_view() -> antumbra_mesh_view {
    antumbra_mesh_view {
        positions: QUAD.as_ptr(),
        vertex_count: 4,
        position_stride: 0,
        indices: QUAD_INDICES.as_ptr(),
        triangle_count: 2,
    }
}

fn create(view: &antumbra_mesh_view) -> (antumbra_result, *mut antumbra_scene) {
    let mut scene = ptr::null_mut();
    // SAFETY: `view` points at live arrays; `scene` is a valid out pointer.
    let result = unsafe { antumbra_scene_create(view, &mut scene) };
    (result, scene)
}

#[test]
fn scene_answers_occlusion_and_closest_hit() {
    let (result, scene) = create(&quad_view());
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    assert_eq!(last_error(), "");
    let origins = [0.25f32, 0.5, 0.0, 0.0, 0.0, 0.0, 5.0, 5.0, 0.0];
    let directions = [0.0f32, 0.0, 2.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
    let t_max = [f32::INFINITY, 1.0, f32::INFINITY];
    let mut occluded = [7u8; 3];
    let mut hits = [antumbra_hit {
        distance: 0.0,
        triangle: 0,
        u: 0.0,
        v: 0.0,
    }; 3];
    // SAFETY: every array holds 3 rays.
    unsafe {
        assert_eq!(
            antumbra_scene_occluded(
                scene,
                origins.as_ptr(),
                directions.as_ptr(),
                t_max.as_ptr(),
                3,
                occluded.as_mut_ptr()
            ),
            ANTUMBRA_RESULT_OK
        );
        assert_eq!(
            antumbra_scene_intersect(
                scene,
                origins.as_ptr(),
                directions.as_ptr(),
                t_max.as_ptr(),
                3,
                hits.as_mut_ptr()
            ),
            ANTUMBRA_RESULT_OK
        );
    }
    // Ray 0 hits at z = 1 with a direction of length 2: t = 0.5. Ray 1 stops at
    // t_max = 1 exactly on the plane: open interval, no hit. Ray 2 misses.
    assert_eq!(occluded, [1, 0, 0]);
    assert_eq!(hits[0].distance, 0.5);
    let p = [0.25f32, 0.5, 1.0];
    let tri = QUAD_INDICES[3 * hits[0].triangle as usize..][..3]
        .iter()
        .map(|&i| &QUAD[3 * i as usize..3 * i as usize + 3])
        .collect::<Vec<_>>();
    let (u, v) = (hits[0].u, hits[0].v);
    for k in 0..3 {
        let rebuilt = (1.0 - u - v) * tri[0][k] + u * tri[1][k] + v * tri[2][k];
        assert!(
            (rebuilt - p[k]).abs() < 1e-6,
            "barycentrics rebuild the hit point"
        );
    }
    for miss in &hits[1..] {
        assert_eq!(miss.distance, f32::INFINITY);
        assert_eq!(miss.triangle, ANTUMBRA_INVALID_INDEX);
    }
    // SAFETY: `scene` came from antumbra_scene_create.
    unsafe { antumbra_scene_destroy(scene) };
}

#[test]
fn interleaved_stride_gives_the_same_scene() {
    // position + normal per vertex: stride 24.
    let mut interleaved = Vec::new();
    for v in QUAD.chunks(3) {
        interleaved.extend_from_slice(v);
        interleaved.extend_from_slice(&[0.0, 0.0, 1.0]);
    }
    let view = antumbra_mesh_view {
        positions: interleaved.as_ptr(),
        position_stride: 24,
        ..quad_view()
    };
    let (result, scene) = create(&view);
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    let mut hit = [antumbra_hit {
        distance: 0.0,
        triangle: 9,
        u: 0.0,
        v: 0.0,
    }];
    // SAFETY: one ray.
    let r = unsafe {
        antumbra_scene_intersect(
            scene,
            [0.9f32, -0.9, 0.0].as_ptr(),
            [0.0f32, 0.0, 1.0].as_ptr(),
            [9.0f32].as_ptr(),
            1,
            hit.as_mut_ptr(),
        )
    };
    assert_eq!(r, ANTUMBRA_RESULT_OK);
    assert_eq!((hit[0].distance, hit[0].triangle), (1.0, 0));
    // SAFETY: from create.
    unsafe { antumbra_scene_destroy(scene) };
}

#[test]
fn bad_meshes_are_rejected_with_their_own_code_and_out_untouched() {
    let mut nan = QUAD;
    nan[7] = f32::NAN;
    let mut inf = QUAD;
    inf[0] = f32::NEG_INFINITY;
    let bad_index = [0u32, 1, 2, 0, 2, 4];
    let misaligned = [0u32; 7];
    let cases: Vec<(antumbra_mesh_view, antumbra_result, &str)> = vec![
        (
            antumbra_mesh_view {
                positions: ptr::null(),
                ..quad_view()
            },
            ANTUMBRA_RESULT_NULL_ARGUMENT,
            "mesh->positions",
        ),
        (
            antumbra_mesh_view {
                indices: ptr::null(),
                ..quad_view()
            },
            ANTUMBRA_RESULT_NULL_ARGUMENT,
            "mesh->indices",
        ),
        (
            antumbra_mesh_view {
                triangle_count: 0,
                ..quad_view()
            },
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "mesh->triangle_count",
        ),
        (
            antumbra_mesh_view {
                vertex_count: 0,
                ..quad_view()
            },
            ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE,
            "mesh->indices[0]",
        ),
        (
            antumbra_mesh_view {
                position_stride: 8,
                ..quad_view()
            },
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "mesh->position_stride",
        ),
        (
            antumbra_mesh_view {
                position_stride: usize::MAX,
                ..quad_view()
            },
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "overflows",
        ),
        (
            antumbra_mesh_view {
                indices: bad_index.as_ptr(),
                ..quad_view()
            },
            ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE,
            "mesh->indices[5] (triangle 1) is 4",
        ),
        (
            antumbra_mesh_view {
                positions: nan.as_ptr(),
                ..quad_view()
            },
            ANTUMBRA_RESULT_NON_FINITE,
            "vertex 2",
        ),
        (
            antumbra_mesh_view {
                positions: inf.as_ptr(),
                ..quad_view()
            },
            ANTUMBRA_RESULT_NON_FINITE,
            "vertex 0",
        ),
        (
            // One byte into a live array: a misaligned `const uint32_t *`.
            antumbra_mesh_view {
                indices: misaligned.as_ptr().cast::<u8>().wrapping_add(1).cast(),
                ..quad_view()
            },
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "not aligned",
        ),
    ];
    for (view, code, needle) in cases {
        let sentinel = 0x5a5a as *mut antumbra_scene;
        let mut out = sentinel;
        // SAFETY: the view's non-NULL pointers are live; `out` is valid.
        let result = unsafe { antumbra_scene_create(&view, &mut out) };
        let message = last_error();
        assert_eq!(result, code, "{needle}: {message}");
        assert!(message.starts_with("antumbra_scene_create: "), "{message}");
        assert!(
            message.contains(needle),
            "{message:?} should name {needle:?}"
        );
        assert_eq!(out, sentinel, "out untouched on failure");
    }
    // SAFETY: NULL arguments are what is being tested.
    unsafe {
        assert_eq!(
            antumbra_scene_create(ptr::null(), &mut ptr::null_mut()),
            ANTUMBRA_RESULT_NULL_ARGUMENT
        );
        assert!(last_error().contains("mesh is NULL"));
        assert_eq!(
            antumbra_scene_create(&quad_view(), ptr::null_mut()),
            ANTUMBRA_RESULT_NULL_ARGUMENT
        );
        assert!(last_error().contains("out is NULL"));
    }
}

#[test]
fn coordinates_beyond_the_supported_range_and_misaligned_out_are_rejected() {
    let huge = [-1e20f32, -1., 1., 1., -1., 1., 1., 1., 1., -1., 1., 1.];
    let view = antumbra_mesh_view {
        positions: huge.as_ptr(),
        ..quad_view()
    };
    let (result, scene) = create(&view);
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(scene.is_null());
    assert!(
        last_error().contains("vertex 0 has a coordinate beyond"),
        "{}",
        last_error()
    );
    // An out pointer one byte into a buffer: rejected before anything is built.
    let mut buffer = [0u64; 2];
    let misaligned = buffer
        .as_mut_ptr()
        .cast::<u8>()
        .wrapping_add(1)
        .cast::<*mut antumbra_scene>();
    // SAFETY: the pointer is checked before any write, which is what is tested.
    let result = unsafe { antumbra_scene_create(&quad_view(), misaligned) };
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(last_error().contains("out") && last_error().contains("aligned"));
    assert_eq!(buffer, [0, 0]);
}

#[test]
fn frame_may_be_computed_in_place() {
    let normal = [0.6f32, 0.0, 0.8];
    let (mut t, mut b) = ([0.0f32; 3], [0.0f32; 3]);
    // SAFETY: separate arrays.
    unsafe { antumbra_frame_from_normal(normal.as_ptr(), t.as_mut_ptr(), b.as_mut_ptr()) };
    let mut in_place = normal;
    let mut b2 = [0.0f32; 3];
    // SAFETY: `normal` and `tangent` are the same array, which the docs allow.
    unsafe {
        antumbra_frame_from_normal(in_place.as_ptr(), in_place.as_mut_ptr(), b2.as_mut_ptr())
    };
    assert_eq!((in_place, b2), (t, b));
}

#[test]
fn bad_rays_are_rejected_and_outputs_untouched() {
    let (_, scene) = create(&quad_view());
    let good_o = [0.0f32; 6];
    let good_d = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
    let good_t = [1.0f32, 1.0];
    let nan_o = [0.0f32, 0.0, 0.0, 0.0, f32::NAN, 0.0];
    let inf_d = [0.0f32, 0.0, 1.0, f32::INFINITY, 0.0, 1.0];
    let zero_d = [0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0];
    let nan_t = [1.0f32, f32::NAN];
    let neg_t = [-1.0f32, 1.0];
    type Case<'a> = (
        *const antumbra_scene,
        &'a [f32],
        &'a [f32],
        *const f32,
        antumbra_result,
        &'a str,
    );
    let cases: Vec<Case<'_>> = vec![
        (
            ptr::null(),
            &good_o,
            &good_d,
            good_t.as_ptr(),
            ANTUMBRA_RESULT_NULL_ARGUMENT,
            "scene is NULL",
        ),
        (
            scene,
            &nan_o,
            &good_d,
            good_t.as_ptr(),
            ANTUMBRA_RESULT_NON_FINITE,
            "origins[1]",
        ),
        (
            scene,
            &good_o,
            &inf_d,
            good_t.as_ptr(),
            ANTUMBRA_RESULT_NON_FINITE,
            "directions[1]",
        ),
        (
            scene,
            &good_o,
            &zero_d,
            good_t.as_ptr(),
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "directions[1] is the zero vector",
        ),
        (
            scene,
            &good_o,
            &good_d,
            nan_t.as_ptr(),
            ANTUMBRA_RESULT_NON_FINITE,
            "t_max[1] is NaN",
        ),
        (
            scene,
            &good_o,
            &good_d,
            neg_t.as_ptr(),
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "t_max[0]",
        ),
        (
            scene,
            &good_o,
            &good_d,
            ptr::null(),
            ANTUMBRA_RESULT_NULL_ARGUMENT,
            "t_max is NULL",
        ),
    ];
    for (s, o, d, t, code, needle) in cases {
        let mut occluded = [0xeeu8; 2];
        let mut hits = [antumbra_hit {
            distance: -7.0,
            triangle: 7,
            u: 7.0,
            v: 7.0,
        }; 2];
        // SAFETY: arrays hold 2 rays; NULLs are what is tested.
        let (r1, m1, r2, m2) = unsafe {
            let r1 =
                antumbra_scene_occluded(s, o.as_ptr(), d.as_ptr(), t, 2, occluded.as_mut_ptr());
            let m1 = last_error();
            let r2 = antumbra_scene_intersect(s, o.as_ptr(), d.as_ptr(), t, 2, hits.as_mut_ptr());
            (r1, m1, r2, last_error())
        };
        assert_eq!((r1, r2), (code, code), "{needle}: {m1} / {m2}");
        assert!(
            m1.starts_with("antumbra_scene_occluded: ") && m1.contains(needle),
            "{m1}"
        );
        assert!(
            m2.starts_with("antumbra_scene_intersect: ") && m2.contains(needle),
            "{m2}"
        );
        assert_eq!(occluded, [0xee; 2]);
        assert!(hits.iter().all(|h| h.distance == -7.0 && h.triangle == 7));
    }
    // NULL output with rays to write, and an empty batch with NULL everywhere.
    // SAFETY: NULL handling under test.
    unsafe {
        assert_eq!(
            antumbra_scene_occluded(
                scene,
                good_o.as_ptr(),
                good_d.as_ptr(),
                good_t.as_ptr(),
                2,
                ptr::null_mut()
            ),
            ANTUMBRA_RESULT_NULL_ARGUMENT
        );
        assert!(last_error().contains("occluded is NULL"));
        assert_eq!(
            antumbra_scene_occluded(
                scene,
                ptr::null(),
                ptr::null(),
                ptr::null(),
                0,
                ptr::null_mut()
            ),
            ANTUMBRA_RESULT_OK
        );
        assert_eq!(last_error(), "", "success clears the last error");
        assert_eq!(
            antumbra_scene_occluded(
                scene,
                good_o.as_ptr(),
                good_d.as_ptr(),
                good_t.as_ptr(),
                usize::MAX,
                ptr::null_mut()
            ),
            ANTUMBRA_RESULT_INVALID_ARGUMENT
        );
        antumbra_scene_destroy(scene);
        antumbra_scene_destroy(ptr::null_mut());
    }
}

#[test]
fn last_error_copy_reports_required_size() {
    // SAFETY: NULL mesh under test; buffers are valid for their capacities.
    unsafe {
        let _ = antumbra_scene_create(ptr::null(), &mut ptr::null_mut());
        let expected = last_error();
        let mut required = 0usize;
        let mut small = [b'x' as std::ffi::c_char; 4];
        assert_eq!(
            antumbra_last_error_message_copy(small.as_mut_ptr(), small.len(), &mut required),
            ANTUMBRA_RESULT_BUFFER_TOO_SMALL
        );
        assert_eq!(required, expected.len() + 1);
        assert!(
            small.iter().all(|&c| c == b'x' as std::ffi::c_char),
            "untouched"
        );
        let mut untouched = 7usize;
        assert_eq!(
            antumbra_last_error_message_copy(ptr::null_mut(), 3, &mut untouched),
            ANTUMBRA_RESULT_NULL_ARGUMENT
        );
        assert_eq!(
            untouched, 7,
            "required_size is written only on OK or BUFFER_TOO_SMALL"
        );
        let mut big = vec![0 as std::ffi::c_char; required];
        assert_eq!(
            antumbra_last_error_message_copy(big.as_mut_ptr(), big.len(), ptr::null_mut()),
            ANTUMBRA_RESULT_OK
        );
        assert_eq!(CStr::from_ptr(big.as_ptr()).to_str().unwrap(), expected);
        assert_eq!(last_error(), expected, "copying does not clear the message");
    }
}

#[test]
fn result_strings_and_version() {
    let name = |c| {
        // SAFETY: static strings.
        unsafe { CStr::from_ptr(antumbra_result_str(c)) }
            .to_str()
            .unwrap()
    };
    assert_eq!(name(ANTUMBRA_RESULT_OK), "ANTUMBRA_RESULT_OK");
    assert_eq!(name(ANTUMBRA_RESULT_POISONED), "ANTUMBRA_RESULT_POISONED");
    assert_eq!(name(-3), "ANTUMBRA_RESULT_UNKNOWN");
    assert_eq!(
        name(ANTUMBRA_RESULT_INVALID_DATA + 1),
        "ANTUMBRA_RESULT_UNKNOWN"
    );
    let codes = [
        ANTUMBRA_RESULT_OK,
        ANTUMBRA_RESULT_NULL_ARGUMENT,
        ANTUMBRA_RESULT_INVALID_ARGUMENT,
        ANTUMBRA_RESULT_NON_FINITE,
        ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE,
        ANTUMBRA_RESULT_BUFFER_TOO_SMALL,
        ANTUMBRA_RESULT_OUT_OF_MEMORY,
        ANTUMBRA_RESULT_UNSUPPORTED,
        ANTUMBRA_RESULT_PANIC,
        ANTUMBRA_RESULT_POISONED,
        ANTUMBRA_RESULT_INVALID_DATA,
    ];
    let names: std::collections::HashSet<_> = codes.iter().map(|&c| name(c)).collect();
    assert_eq!(names.len(), codes.len(), "every code has its own name");
    assert!(!names.contains("ANTUMBRA_RESULT_UNKNOWN"));
    let v = antumbra_version();
    let expected = env!("CARGO_PKG_VERSION")
        .split('.')
        .map(|p| p.parse::<u32>().unwrap())
        .fold(0, |acc, p| (acc << 8) | p);
    assert_eq!(v, expected);
    // SAFETY: static string.
    let s = unsafe { CStr::from_ptr(antumbra_version_string()) };
    assert_eq!(s.to_str().unwrap(), env!("CARGO_PKG_VERSION"));
}

#[test]
fn frame_matches_core_and_rejects_bad_normals() {
    let n = [0.6f32, 0.0, 0.8];
    let (mut t, mut b) = ([9.0f32; 3], [9.0f32; 3]);
    // SAFETY: 3 floats each.
    unsafe { antumbra_frame_from_normal(n.as_ptr(), t.as_mut_ptr(), b.as_mut_ptr()) };
    let core = antumbra_core::Frame::from_normal(glam::Vec3::from(n));
    assert_eq!((t, b), (core.tangent.to_array(), core.bitangent.to_array()));
    for (normal, needle) in [
        ([f32::NAN, 0.0, 1.0], "not finite"),
        ([0.0, 0.0, 2.0], "length 2"),
    ] {
        let (mut t, mut b) = ([9.0f32; 3], [9.0f32; 3]);
        // SAFETY: 3 floats each.
        unsafe { antumbra_frame_from_normal(normal.as_ptr(), t.as_mut_ptr(), b.as_mut_ptr()) };
        assert_eq!((t, b), ([9.0; 3], [9.0; 3]));
        assert!(last_error().contains(needle), "{}", last_error());
    }
    let mut t = [9.0f32; 3];
    // SAFETY: NULL under test.
    unsafe { antumbra_frame_from_normal(n.as_ptr(), t.as_mut_ptr(), ptr::null_mut()) };
    assert!(last_error().contains("bitangent is NULL"));
    assert_eq!(t, [9.0; 3]);
}
