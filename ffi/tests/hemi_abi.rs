//! The hemisphere and SH exports called from Rust exactly as C would call them:
//! bit-for-bit agreement with core, the documented defaults, one code and a message
//! naming the argument for every class of bad input, outputs untouched on failure.

use std::ffi::CStr;
use std::ptr;

use antumbra::*;
use antumbra_core::MeshView;
use antumbra_core::glam::Vec3;
use antumbra_core::hemi::{self, HalfSpaceTable, HemiMask, Quality, RasterOptions};
use antumbra_core::sh::{self, EquirectMapping};

fn last_error() -> String {
    // SAFETY: the library returns a valid NUL-terminated string.
    unsafe { CStr::from_ptr(antumbra_last_error_message()) }
        .to_string_lossy()
        .into_owned()
}

/// A closed UV sphere with its radius modulated by `0.25 sin 5θ sin 4φ`, wound
/// counter-clockwise seen from outside, and concave enough that receivers on it
/// see real occluders; with the analytic normal of the unmodulated sphere at each
/// vertex (unit, not the surface normal: any unit normal is a valid receiver).
struct Blob {
    positions: Vec<f32>,
    normals: Vec<f32>,
    indices: Vec<u32>,
}

fn blob(rings: u32, segments: u32) -> Blob {
    let mut normals = Vec::new();
    let (positions, indices) = antumbra_core::geom::uv_sphere(rings, segments, |theta, phi| {
        let radius = 1.0 + 0.25 * (5.0 * theta).sin() * (4.0 * phi).sin();
        let n = Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
        .normalize();
        normals.extend_from_slice(&n.to_array());
        (n * radius).to_array()
    });
    Blob {
        positions: positions.into_iter().flatten().collect(),
        normals,
        indices,
    }
}

impl Blob {
    fn view(&self) -> antumbra_mesh_view {
        antumbra_mesh_view {
            positions: self.positions.as_ptr(),
            vertex_count: self.positions.len() / 3,
            position_stride: 0,
            indices: self.indices.as_ptr(),
            triangle_count: self.indices.len() / 3,
        }
    }

    fn core(&self) -> MeshView<'_> {
        MeshView::new(bytemuck::cast_slice(&self.positions), &self.indices).unwrap()
    }

    fn receiver_count(&self) -> usize {
        self.positions.len() / 3
    }
}

fn default_options() -> antumbra_hemi_options {
    let mut options = std::mem::MaybeUninit::<antumbra_hemi_options>::uninit();
    // SAFETY: a valid pointer to one options struct; init writes every field.
    unsafe {
        antumbra_hemi_options_init(options.as_mut_ptr());
        options.assume_init()
    }
}

/// Calls antumbra_hemi_rasterize on the blob's vertices.
fn rasterize(
    view: &antumbra_mesh_view,
    positions: &[f32],
    normals: &[f32],
    options: Option<&antumbra_hemi_options>,
) -> (antumbra_result, Vec<antumbra_hemi_mask>) {
    let count = positions.len() / 3;
    let mut masks = vec![antumbra_hemi_mask { rows: [0xdead; 32] }; count];
    // SAFETY: arrays of `count` receivers and masks.
    let result = unsafe {
        antumbra_hemi_rasterize(
            view,
            positions.as_ptr(),
            normals.as_ptr(),
            count,
            options.map_or(ptr::null(), |o| o as *const _),
            masks.as_mut_ptr(),
        )
    };
    (result, masks)
}

fn core_masks(
    blob: &Blob,
    quality: Quality<'_>,
    cull_backfaces: bool,
    normal_offset: f32,
) -> Vec<HemiMask> {
    let mesh = blob.core();
    let options = RasterOptions {
        quality,
        cull_backfaces,
        normal_offset,
        skip_triangles: &[],
    };
    (0..blob.receiver_count())
        .map(|k| {
            let p = Vec3::from_slice(&blob.positions[3 * k..]);
            let n = Vec3::from_slice(&blob.normals[3 * k..]);
            hemi::rasterize_receiver(&mesh, p, n, &options)
        })
        .collect()
}

#[test]
fn masks_equal_core_bit_for_bit_in_every_mode() {
    let blob = blob(14, 20);
    let view = blob.view();
    let shared = HalfSpaceTable::default();
    let small = HalfSpaceTable::new(32);
    let mut user_table = ptr::null_mut();
    // SAFETY: a valid out pointer.
    let created = unsafe { antumbra_hemi_table_create(32, &mut user_table) };
    assert_eq!(created, ANTUMBRA_RESULT_OK, "{}", last_error());
    let mut occluded_somewhere = 0;
    for quality in [ANTUMBRA_HEMI_QUALITY_EXACT, ANTUMBRA_HEMI_QUALITY_TABLE] {
        for table in [ptr::null(), user_table.cast_const()] {
            for cull in [0, 1] {
                for offset in [0.0f32, 0.01] {
                    let core_quality = match (quality, table.is_null()) {
                        (ANTUMBRA_HEMI_QUALITY_EXACT, _) => Quality::Exact,
                        (_, true) => Quality::Table(&shared),
                        (_, false) => Quality::Table(&small),
                    };
                    let want = core_masks(&blob, core_quality, cull == 1, offset);
                    for parallel in [0, 1] {
                        let options = antumbra_hemi_options {
                            quality,
                            cull_backfaces: cull,
                            normal_offset: offset,
                            parallel,
                            table,
                        };
                        let (result, got) =
                            rasterize(&view, &blob.positions, &blob.normals, Some(&options));
                        assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
                        assert_eq!(last_error(), "");
                        for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                            assert_eq!(g.rows, w.rows, "receiver {k}, {options:?}");
                        }
                        // A batch this large groups the triangles into clusters; a
                        // small one does not. Both give the plain rasterizer's bits.
                        assert!(got.len() >= 32 * 4);
                        let few = 3 * 10;
                        let (result, got) = rasterize(
                            &view,
                            &blob.positions[..few],
                            &blob.normals[..few],
                            Some(&options),
                        );
                        assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
                        for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                            assert_eq!(g.rows, w.rows, "receiver {k} of a small batch");
                        }
                    }
                    occluded_somewhere += want.iter().filter(|m| !m.is_empty()).count();
                }
            }
        }
    }
    assert!(occluded_somewhere > 100, "the blob must shadow itself");
    // NULL options are the defaults.
    let (result, with_null) = rasterize(&view, &blob.positions, &blob.normals, None);
    assert_eq!(result, ANTUMBRA_RESULT_OK);
    let (_, with_defaults) = rasterize(
        &view,
        &blob.positions,
        &blob.normals,
        Some(&default_options()),
    );
    assert_eq!(with_null, with_defaults);
    // SAFETY: from create, destroyed once.
    unsafe { antumbra_hemi_table_destroy(user_table) };
}

#[test]
fn strided_positions_and_invalid_cells_stay_clear() {
    let blob = blob(10, 14);
    let mut interleaved = Vec::new();
    for (p, n) in blob.positions.chunks(3).zip(blob.normals.chunks(3)) {
        interleaved.extend_from_slice(p);
        interleaved.extend_from_slice(n);
    }
    let strided = antumbra_mesh_view {
        positions: interleaved.as_ptr(),
        position_stride: 24,
        ..blob.view()
    };
    let options = antumbra_hemi_options {
        normal_offset: 0.02,
        ..default_options()
    };
    let (r1, packed) = rasterize(&blob.view(), &blob.positions, &blob.normals, Some(&options));
    let (r2, from_strided) = rasterize(&strided, &blob.positions, &blob.normals, Some(&options));
    assert_eq!((r1, r2), (ANTUMBRA_RESULT_OK, ANTUMBRA_RESULT_OK));
    assert_eq!(packed, from_strided);
    let mut valid = antumbra_hemi_mask { rows: [7; 32] };
    // SAFETY: one mask.
    let result = unsafe { antumbra_hemi_valid_mask(&mut valid) };
    assert_eq!(result, ANTUMBRA_RESULT_OK);
    assert_eq!(valid.rows, HemiMask::VALID.rows);
    let count: u32 = valid.rows.iter().map(|r| r.count_ones()).sum();
    assert_eq!(count, ANTUMBRA_HEMI_VALID_CELL_COUNT);
    for mask in &packed {
        for (row, valid_row) in mask.rows.iter().zip(valid.rows) {
            assert_eq!(row & !valid_row, 0, "invalid cells are always 0");
        }
    }
    // SAFETY: NULL and a misaligned pointer under test.
    unsafe {
        assert_eq!(
            antumbra_hemi_valid_mask(ptr::null_mut()),
            ANTUMBRA_RESULT_NULL_ARGUMENT
        );
        assert!(last_error().contains("mask is NULL"));
        let mut buffer = [0u32; 40];
        let misaligned = buffer
            .as_mut_ptr()
            .cast::<u8>()
            .wrapping_add(1)
            .cast::<antumbra_hemi_mask>();
        assert_eq!(
            antumbra_hemi_valid_mask(misaligned),
            ANTUMBRA_RESULT_INVALID_ARGUMENT
        );
        assert_eq!(buffer, [0; 40]);
    }
}

#[test]
fn many_threads_rasterize_the_same_mesh_and_table_at_once() {
    let blob = blob(10, 14);
    let view = blob.view();
    let mut table = ptr::null_mut();
    // SAFETY: a valid out pointer.
    let created = unsafe { antumbra_hemi_table_create(0, &mut table) };
    assert_eq!(created, ANTUMBRA_RESULT_OK);
    // Raw pointers are not Send; the table and mesh are only read.
    let table_address = table as usize;
    let want = core_masks(
        &blob,
        Quality::Table(&HalfSpaceTable::default()),
        false,
        0.0,
    );
    std::thread::scope(|scope| {
        for t in 0..4 {
            let (blob, want) = (&blob, &want);
            scope.spawn(move || {
                let options = antumbra_hemi_options {
                    quality: ANTUMBRA_HEMI_QUALITY_TABLE,
                    table: if t % 2 == 0 {
                        table_address as *const antumbra_hemi_table
                    } else {
                        ptr::null()
                    },
                    parallel: t / 2,
                    ..default_options()
                };
                let view = blob.view();
                for _ in 0..3 {
                    let (result, got) =
                        rasterize(&view, &blob.positions, &blob.normals, Some(&options));
                    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
                    assert!(got.iter().zip(want).all(|(g, w)| g.rows == w.rows));
                }
            });
        }
    });
    let _ = view;
    // SAFETY: from create, no rasterization running.
    unsafe { antumbra_hemi_table_destroy(table) };
}

#[test]
fn options_init_writes_the_documented_defaults() {
    let mut options = antumbra_hemi_options {
        quality: 0xabab_abab,
        cull_backfaces: 0xabab_abab,
        normal_offset: f32::NAN,
        parallel: 0xabab_abab,
        table: 0x5a5a as *const antumbra_hemi_table,
    };
    // SAFETY: a valid options struct.
    unsafe { antumbra_hemi_options_init(&mut options) };
    assert_eq!(options.quality, ANTUMBRA_HEMI_QUALITY_EXACT);
    assert_eq!(options.quality, 0);
    assert_eq!(options.cull_backfaces, 0);
    assert_eq!(options.normal_offset.to_bits(), 0.0f32.to_bits());
    assert_eq!(options.parallel, 0);
    assert!(options.table.is_null());
    assert_eq!(last_error(), "");
    assert_eq!(ANTUMBRA_HEMI_QUALITY_TABLE, 1);
    // Layout: the fixed leading fields first, no padding.
    assert_eq!(std::mem::offset_of!(antumbra_hemi_options, quality), 0);
    assert_eq!(
        std::mem::offset_of!(antumbra_hemi_options, cull_backfaces),
        4
    );
    assert_eq!(
        std::mem::offset_of!(antumbra_hemi_options, normal_offset),
        8
    );
    assert_eq!(std::mem::offset_of!(antumbra_hemi_options, parallel), 12);
    assert_eq!(std::mem::offset_of!(antumbra_hemi_options, table), 16);
    assert_eq!(
        std::mem::size_of::<antumbra_hemi_options>(),
        16 + std::mem::size_of::<usize>()
    );
    assert_eq!(std::mem::size_of::<antumbra_hemi_mask>(), 128);
    // SAFETY: NULL and misaligned pointers under test.
    unsafe {
        antumbra_hemi_options_init(ptr::null_mut());
        assert!(last_error().contains("options is NULL"), "{}", last_error());
        let mut buffer = [0u64; 4];
        let misaligned = buffer
            .as_mut_ptr()
            .cast::<u8>()
            .wrapping_add(2)
            .cast::<antumbra_hemi_options>();
        antumbra_hemi_options_init(misaligned);
        assert!(last_error().contains("aligned"), "{}", last_error());
        assert_eq!(buffer, [0; 4]);
    }
}

/// One bad call: what to change, the code, and a needle the message must contain.
struct BadCall<'a> {
    mesh: *const antumbra_mesh_view,
    positions: *const f32,
    normals: *const f32,
    count: usize,
    options: *const antumbra_hemi_options,
    masks: Option<*mut antumbra_hemi_mask>,
    code: antumbra_result,
    needle: &'a str,
}

#[test]
fn every_bad_input_has_its_code_a_message_naming_it_and_leaves_masks_untouched() {
    let blob = blob(6, 8);
    let good_view = blob.view();
    let n = 3;
    let positions = &blob.positions[..3 * n];
    let normals = &blob.normals[..3 * n];
    let with = |k: usize, c: usize, value: f32, of: &[f32]| {
        let mut v = of.to_vec();
        v[3 * k + c] = value;
        v
    };
    let nan_position = with(1, 2, f32::NAN, positions);
    let far_position = with(1, 0, 1e13, positions);
    let inf_normal = with(2, 0, f32::INFINITY, normals);
    let half_normal: Vec<f32> = normals
        .iter()
        .enumerate()
        .map(|(i, &c)| if i / 3 == 1 { 0.5 * c } else { c })
        .collect();
    let zero_normal = [normals[..3].to_vec(), vec![0.0; 6]].concat();
    let mut nan_mesh = blob.positions.clone();
    nan_mesh[3 * 4 + 1] = f32::NAN;
    let mut huge_mesh = blob.positions.clone();
    huge_mesh[0] = -1e20;
    let mut bad_indices = blob.indices.clone();
    bad_indices[5] = 10_000;
    let views = [
        antumbra_mesh_view {
            positions: ptr::null(),
            ..good_view
        },
        antumbra_mesh_view {
            positions: nan_mesh.as_ptr(),
            ..good_view
        },
        antumbra_mesh_view {
            positions: huge_mesh.as_ptr(),
            ..good_view
        },
        antumbra_mesh_view {
            indices: bad_indices.as_ptr(),
            ..good_view
        },
        antumbra_mesh_view {
            position_stride: 4,
            ..good_view
        },
    ];
    let option = |f: &dyn Fn(&mut antumbra_hemi_options)| {
        let mut o = default_options();
        f(&mut o);
        o
    };
    let bad_options = [
        option(&|o| o.quality = 2),
        option(&|o| o.cull_backfaces = 2),
        option(&|o| o.parallel = 7),
        option(&|o| o.normal_offset = f32::NAN),
        option(&|o| o.normal_offset = -0.1),
        option(&|o| o.normal_offset = 1e13),
    ];
    let mut misaligned_floats = vec![0.0f32; 3 * n + 1];
    misaligned_floats[..3 * n].copy_from_slice(positions);
    let misaligned_positions = misaligned_floats
        .as_ptr()
        .cast::<u8>()
        .wrapping_add(1)
        .cast::<f32>();
    let options_buffer = [0u64; 5];
    let misaligned_options = options_buffer
        .as_ptr()
        .cast::<u8>()
        .wrapping_add(2)
        .cast::<antumbra_hemi_options>();
    let mut mask_buffer = vec![0u32; 32 * n + 1];
    let misaligned_masks = mask_buffer
        .as_mut_ptr()
        .cast::<u8>()
        .wrapping_add(1)
        .cast::<antumbra_hemi_mask>();

    let good = BadCall {
        mesh: &good_view,
        positions: positions.as_ptr(),
        normals: normals.as_ptr(),
        count: n,
        options: ptr::null(),
        masks: None,
        code: ANTUMBRA_RESULT_OK,
        needle: "",
    };
    let cases = vec![
        BadCall {
            mesh: ptr::null(),
            code: ANTUMBRA_RESULT_NULL_ARGUMENT,
            needle: "mesh is NULL",
            ..good
        },
        BadCall {
            mesh: &views[0],
            code: ANTUMBRA_RESULT_NULL_ARGUMENT,
            needle: "mesh->positions is NULL",
            ..good
        },
        BadCall {
            mesh: &views[1],
            code: ANTUMBRA_RESULT_NON_FINITE,
            needle: "mesh->positions: vertex 4",
            ..good
        },
        BadCall {
            mesh: &views[2],
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "vertex 0 has a coordinate beyond",
            ..good
        },
        BadCall {
            mesh: &views[3],
            code: ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE,
            needle: "mesh->indices[5] (triangle 1) is 10000",
            ..good
        },
        BadCall {
            mesh: &views[4],
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "mesh->position_stride is 4",
            ..good
        },
        BadCall {
            positions: ptr::null(),
            code: ANTUMBRA_RESULT_NULL_ARGUMENT,
            needle: "receiver_positions is NULL",
            ..good
        },
        BadCall {
            normals: ptr::null(),
            code: ANTUMBRA_RESULT_NULL_ARGUMENT,
            needle: "receiver_normals is NULL",
            ..good
        },
        BadCall {
            masks: Some(ptr::null_mut()),
            code: ANTUMBRA_RESULT_NULL_ARGUMENT,
            needle: "masks is NULL",
            ..good
        },
        BadCall {
            positions: nan_position.as_ptr(),
            code: ANTUMBRA_RESULT_NON_FINITE,
            needle: "receiver_positions[1]",
            ..good
        },
        BadCall {
            positions: far_position.as_ptr(),
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "receiver_positions[1] (10000000000000, ",
            ..good
        },
        BadCall {
            normals: inf_normal.as_ptr(),
            code: ANTUMBRA_RESULT_NON_FINITE,
            needle: "receiver_normals[2] (inf, ",
            ..good
        },
        BadCall {
            normals: half_normal.as_ptr(),
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "receiver_normals[1] has length 0.5, not 1 (tolerance 0.001)",
            ..good
        },
        BadCall {
            normals: zero_normal.as_ptr(),
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "receiver_normals[1] has length 0, not 1",
            ..good
        },
        BadCall {
            options: &bad_options[0],
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "options->quality is 2",
            ..good
        },
        BadCall {
            options: &bad_options[1],
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "options->cull_backfaces is 2; expected 0 or 1",
            ..good
        },
        BadCall {
            options: &bad_options[2],
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "options->parallel is 7",
            ..good
        },
        BadCall {
            options: &bad_options[3],
            code: ANTUMBRA_RESULT_NON_FINITE,
            needle: "options->normal_offset is NaN",
            ..good
        },
        BadCall {
            options: &bad_options[4],
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "options->normal_offset is -0.1",
            ..good
        },
        BadCall {
            options: &bad_options[5],
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "options->normal_offset is 10000000000000",
            ..good
        },
        BadCall {
            options: misaligned_options,
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "options (",
            ..good
        },
        BadCall {
            positions: misaligned_positions,
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "receiver_positions (",
            ..good
        },
        BadCall {
            masks: Some(misaligned_masks),
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "masks (",
            ..good
        },
        BadCall {
            count: usize::MAX,
            code: ANTUMBRA_RESULT_INVALID_ARGUMENT,
            needle: "receiver_count",
            ..good
        },
    ];
    for case in cases {
        let mut masks = vec![antumbra_hemi_mask { rows: [0x5a5a; 32] }; n];
        let out = case.masks.unwrap_or(masks.as_mut_ptr());
        // SAFETY: every non-NULL pointer is live (misaligned ones are rejected
        // before any access); usize::MAX is rejected before any access.
        let result = unsafe {
            antumbra_hemi_rasterize(
                case.mesh,
                case.positions,
                case.normals,
                case.count,
                case.options,
                out,
            )
        };
        let message = last_error();
        assert_eq!(result, case.code, "{}: {message}", case.needle);
        assert!(
            message.starts_with("antumbra_hemi_rasterize: ") && message.contains(case.needle),
            "{message:?} should name {:?}",
            case.needle
        );
        assert!(masks.iter().all(|m| m.rows == [0x5a5a; 32]), "{message}");
        assert!(mask_buffer.iter().all(|&w| w == 0), "{message}");
    }
    // An empty batch with NULL arrays, and an empty mesh, are fine.
    let empty = antumbra_mesh_view {
        positions: ptr::null(),
        vertex_count: 0,
        position_stride: 0,
        indices: ptr::null(),
        triangle_count: 0,
    };
    // SAFETY: empty arrays may be NULL.
    let result = unsafe {
        antumbra_hemi_rasterize(
            &good_view,
            ptr::null(),
            ptr::null(),
            0,
            ptr::null(),
            ptr::null_mut(),
        )
    };
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    let (result, masks) = rasterize(&empty, positions, normals, None);
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    assert!(masks.iter().all(|m| m.rows == [0; 32]));
    // The table is ignored by the exact quality, used (and checked) by the table one.
    let (result, _) = rasterize(
        &good_view,
        positions,
        normals,
        Some(&antumbra_hemi_options {
            table: misaligned_options.cast(),
            ..default_options()
        }),
    );
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    let (result, _) = rasterize(
        &good_view,
        positions,
        normals,
        Some(&antumbra_hemi_options {
            quality: ANTUMBRA_HEMI_QUALITY_TABLE,
            table: misaligned_options.cast(),
            ..default_options()
        }),
    );
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(
        last_error().contains("options->table ("),
        "{}",
        last_error()
    );
}

#[test]
fn tables_are_created_with_checked_resolutions() {
    let mut table = 0x5a5a as *mut antumbra_hemi_table;
    // SAFETY: valid out pointers; NULL under test.
    unsafe {
        assert_eq!(
            antumbra_hemi_table_create(ANTUMBRA_HEMI_TABLE_MAX_RESOLUTION + 1, &mut table),
            ANTUMBRA_RESULT_INVALID_ARGUMENT
        );
        assert!(
            last_error().contains("resolution is 1025"),
            "{}",
            last_error()
        );
        assert_eq!(table, 0x5a5a as *mut antumbra_hemi_table);
        assert_eq!(
            antumbra_hemi_table_create(0, ptr::null_mut()),
            ANTUMBRA_RESULT_NULL_ARGUMENT
        );
        assert!(last_error().contains("out is NULL"));
        assert_eq!(
            antumbra_hemi_table_create(1, &mut table),
            ANTUMBRA_RESULT_OK
        );
        assert!(!table.is_null());
        antumbra_hemi_table_destroy(table);
        antumbra_hemi_table_destroy(ptr::null_mut());
    }
}

#[test]
fn cell_directions_match_core_and_invalid_cells_are_rejected() {
    let mut valid = 0;
    for j in 0..34u32 {
        for i in 0..34u32 {
            let mut d = [9.0f32; 3];
            // SAFETY: 3 floats.
            let result = unsafe { antumbra_hemi_cell_direction(i, j, d.as_mut_ptr()) };
            match hemi::cell_direction(i as usize, j as usize) {
                Some(want) => {
                    assert_eq!(result, ANTUMBRA_RESULT_OK);
                    assert_eq!(d, want.to_array(), "cell ({i}, {j})");
                    // The documented formula, in f32, gives the same bits.
                    let (u, v) = ((i as f32 + 0.5) / 16.0 - 1.0, (j as f32 + 0.5) / 16.0 - 1.0);
                    assert_eq!(d, [u, v, (1.0 - u * u - v * v).sqrt()]);
                    valid += 1;
                }
                None => {
                    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT, "cell ({i}, {j})");
                    let needle = if i >= 32 || j >= 32 {
                        "outside the 32x32 grid"
                    } else {
                        "outside the unit disk"
                    };
                    let message = last_error();
                    assert!(
                        message.contains(&format!("cell ({i}, {j})")) && message.contains(needle),
                        "{message}"
                    );
                    assert_eq!(d, [9.0; 3], "untouched");
                }
            }
        }
    }
    assert_eq!(valid, ANTUMBRA_HEMI_VALID_CELL_COUNT);
    // SAFETY: NULL and misaligned pointers under test.
    unsafe {
        assert_eq!(
            antumbra_hemi_cell_direction(u32::MAX, 3, [0.0f32; 3].as_mut_ptr()),
            ANTUMBRA_RESULT_INVALID_ARGUMENT
        );
        assert_eq!(
            antumbra_hemi_cell_direction(16, 16, ptr::null_mut()),
            ANTUMBRA_RESULT_NULL_ARGUMENT
        );
        assert!(last_error().contains("local_direction is NULL"));
        let mut buffer = [0u32; 4];
        let misaligned = buffer.as_mut_ptr().cast::<u8>().wrapping_add(1).cast();
        assert_eq!(
            antumbra_hemi_cell_direction(16, 16, misaligned),
            ANTUMBRA_RESULT_INVALID_ARGUMENT
        );
        assert_eq!(buffer, [0; 4]);
    }
}

// ---- Spherical harmonics --------------------------------------------------------

fn project(
    rgb: &[f32],
    width: u32,
    height: u32,
    stride: usize,
    bands: u32,
) -> (antumbra_result, Vec<f32>) {
    let mut out = vec![-7.0f32; 3 * (bands * bands) as usize];
    // SAFETY: `rgb` holds the map, `out` 3 bands² floats.
    let result = unsafe {
        antumbra_sh_project_equirect(rgb.as_ptr(), width, height, stride, bands, out.as_mut_ptr())
    };
    (result, out)
}

/// A `width × height` map sampled from `f` at texel centres, in the documented
/// direction convention (written out here, independently of core).
fn map_of(width: u32, height: u32, f: impl Fn(Vec3) -> [f32; 3]) -> Vec<f32> {
    let mut rgb = Vec::new();
    for row in 0..height {
        for column in 0..width {
            let u = (column as f64 + 0.5) / width as f64;
            let v = (row as f64 + 0.5) / height as f64;
            let (theta, phi) = (v * std::f64::consts::PI, (u - 0.5) * std::f64::consts::TAU);
            let d = Vec3::new(
                (theta.sin() * phi.cos()) as f32,
                theta.cos() as f32,
                (theta.sin() * phi.sin()) as f32,
            );
            rgb.extend_from_slice(&f(d));
        }
    }
    rgb
}

#[test]
fn a_constant_map_projects_onto_band_zero() {
    let (w, h) = (64u32, 32u32);
    let colour = [0.5f32, 1.0, 2.0];
    let rgb = map_of(w, h, |_| colour);
    let (result, c) = project(&rgb, w, h, 0, 8);
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    // c_0 = ∫ c Y_0 dω = c · 4π / (2√π) = 2√π c; the texel solid angles sum to 4π
    // exactly (up to rounding), so band 0 has no quadrature error.
    let two_sqrt_pi = 2.0 * std::f32::consts::PI.sqrt();
    for (channel, &value) in colour.iter().enumerate() {
        let coeffs = &c[64 * channel..64 * (channel + 1)];
        assert!(
            (coeffs[0] - two_sqrt_pi * value).abs() < 2e-6 * two_sqrt_pi * value,
            "channel {channel}: {} vs {}",
            coeffs[0],
            two_sqrt_pi * value
        );
        for (i, &c) in coeffs.iter().enumerate().skip(1) {
            // Odd bands vanish by symmetry (measured 3e-15); even ones keep the
            // midpoint rule's error in θ, O((π/h)²): measured at most 3.5e-3 per
            // unit of radiance at 64×32.
            let l = (i as f32).sqrt() as usize;
            let bound = if l % 2 == 1 { 1e-6 } else { 5e-3 } * value;
            assert!(c.abs() < bound, "channel {channel} c[{i}] (band {l}) = {c}");
        }
    }
    // Exactly core's result.
    let pixels: &[[f32; 3]] = bytemuck::cast_slice(&rgb);
    let core = sh::project_equirect::<64, _>(pixels, 64, 32, &EquirectMapping::Y_UP).unwrap();
    let flat: Vec<f32> = core.channels().iter().flat_map(|s| s.coeffs).collect();
    assert_eq!(c, flat);
}

#[test]
fn linear_maps_land_on_the_documented_band_one_indices() {
    // ∫ x (-0.488603 x) dω = -0.488603 · 4π/3: so L = (x, y, z) per channel gives
    // c_3 = -2.0466 in red, c_1 = -2.0466 in green and c_2 = +2.0466 in blue.
    let (w, h) = (128u32, 64u32);
    let rgb = map_of(w, h, |d| [d.x, d.y, d.z]);
    let (result, c) = project(&rgb, w, h, 0, 2);
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    let k = 0.488_602_5 * 4.0 * std::f32::consts::PI / 3.0;
    let want = [[0.0, 0.0, 0.0, -k], [0.0, -k, 0.0, 0.0], [0.0, 0.0, k, 0.0]];
    for ch in 0..3 {
        for i in 0..4 {
            assert!(
                (c[4 * ch + i] - want[ch][i]).abs() < 2e-3,
                "channel {ch} c[{i}] = {} (want {})",
                c[4 * ch + i],
                want[ch][i]
            );
        }
    }
}

#[test]
fn strided_maps_equal_packed_ones_and_eval_matches_core() {
    let (w, h) = (24u32, 12u32);
    let rgb = map_of(w, h, |d| [d.y.max(0.0), 0.5 + 0.5 * d.x, (3.0 * d.z).sin()]);
    let stride = 12 * w as usize + 8;
    let mut padded = vec![f32::NAN; stride / 4 * (h as usize - 1) + 3 * w as usize];
    for row in 0..h as usize {
        padded[row * stride / 4..][..3 * w as usize]
            .copy_from_slice(&rgb[row * 3 * w as usize..][..3 * w as usize]);
    }
    for bands in 1..=ANTUMBRA_SH_MAX_BANDS {
        let (r1, packed) = project(&rgb, w, h, 0, bands);
        let (r2, explicit) = project(&rgb, w, h, 12 * w as usize, bands);
        let (r3, strided) = project(&padded, w, h, stride, bands);
        assert_eq!([r1, r2, r3], [ANTUMBRA_RESULT_OK; 3], "{}", last_error());
        assert_eq!(packed, strided, "padding between rows is never read");
        assert_eq!(packed, explicit);
    }
    let d = Vec3::new(0.3, -0.5, 0.2).normalize();
    for bands in 1..=ANTUMBRA_SH_MAX_BANDS {
        let n = (bands * bands) as usize;
        let mut values = vec![9.0f32; n];
        // SAFETY: 3 floats in, bands² out.
        let result = unsafe { antumbra_sh_eval(d.to_array().as_ptr(), bands, values.as_mut_ptr()) };
        assert_eq!(result, ANTUMBRA_RESULT_OK);
        let mut want = vec![0.0f32; n];
        sh::eval_basis_into(d, &mut want).unwrap();
        assert_eq!(values, want);
    }
    // In place: values may be the direction's own array.
    let mut buffer = [0.0f32, 1.0, 0.0, 5.0];
    // SAFETY: 4 floats, the first 3 the direction.
    let result = unsafe { antumbra_sh_eval(buffer.as_ptr(), 2, buffer.as_mut_ptr()) };
    assert_eq!(result, ANTUMBRA_RESULT_OK);
    assert!((buffer[0] - 0.282_095).abs() < 1e-6);
    assert!((buffer[1] + 0.488_603).abs() < 1e-6, "Y_1 = -0.488603 y");
    assert_eq!((buffer[2], buffer[3]), (0.0, -0.0));
}

#[test]
fn bad_sh_inputs_are_rejected_with_their_codes() {
    let (w, h) = (8u32, 4u32);
    let rgb = map_of(w, h, |_| [1.0; 3]);
    let mut nan = rgb.clone();
    nan[3 * (2 * w as usize + 5) + 1] = f32::NAN;
    // Finite, but c_0 = 1e38 · 4π · 0.282 exceeds the float range (it was NaN).
    let bright = [1e38f32; 3];
    let mut misaligned = vec![0.0f32; rgb.len() + 1];
    misaligned[..rgb.len()].copy_from_slice(&rgb);
    let misaligned_rgb = misaligned
        .as_ptr()
        .cast::<u8>()
        .wrapping_add(2)
        .cast::<f32>();
    type Case<'a> = (*const f32, u32, u32, usize, u32, antumbra_result, &'a str);
    let cases: Vec<Case<'_>> = vec![
        (
            rgb.as_ptr(),
            w,
            h,
            0,
            0,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "bands is 0; expected 1 to 8",
        ),
        (
            rgb.as_ptr(),
            w,
            h,
            0,
            9,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "bands is 9",
        ),
        (
            rgb.as_ptr(),
            0,
            h,
            0,
            3,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "the map is 0x4 texels",
        ),
        (
            rgb.as_ptr(),
            w,
            0,
            0,
            3,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "the map is 8x0 texels",
        ),
        (
            rgb.as_ptr(),
            w,
            h,
            95,
            3,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "row_stride_bytes is 95, less than the 96 bytes",
        ),
        (
            rgb.as_ptr(),
            w,
            h,
            98,
            3,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "row_stride_bytes is 98, not a multiple of 4",
        ),
        (
            rgb.as_ptr(),
            w,
            h,
            usize::MAX - 3,
            3,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "overflow",
        ),
        (
            ptr::null(),
            w,
            h,
            0,
            3,
            ANTUMBRA_RESULT_NULL_ARGUMENT,
            "rgb is NULL",
        ),
        (
            misaligned_rgb,
            w,
            h,
            0,
            3,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "rgb (",
        ),
        (
            nan.as_ptr(),
            w,
            h,
            0,
            3,
            ANTUMBRA_RESULT_NON_FINITE,
            "rgb: texel (column 5, row 2) is (1, NaN, 1)",
        ),
        (
            bright.as_ptr(),
            1,
            1,
            0,
            3,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "rgb: coefficient 0 of channel 0 exceeds the float range: the texels are too \
             bright (the brightest of that channel is at column 0, row 0)",
        ),
    ];
    for (pixels, width, height, stride, bands, code, needle) in cases {
        let mut out = vec![-7.0f32; 3 * 64];
        // SAFETY: `out` is large enough for any band count; bad pointers are
        // rejected before any access.
        let result = unsafe {
            antumbra_sh_project_equirect(pixels, width, height, stride, bands, out.as_mut_ptr())
        };
        let message = last_error();
        assert_eq!(result, code, "{needle}: {message}");
        assert!(
            message.starts_with("antumbra_sh_project_equirect: ") && message.contains(needle),
            "{message:?} should contain {needle:?}"
        );
        assert!(out.iter().all(|&c| c == -7.0));
    }
    // SAFETY: NULL output under test.
    let result = unsafe { antumbra_sh_project_equirect(rgb.as_ptr(), w, h, 0, 2, ptr::null_mut()) };
    assert_eq!(result, ANTUMBRA_RESULT_NULL_ARGUMENT);
    assert!(last_error().contains("coefficients is NULL"));

    for (direction, bands, code, needle) in [
        (
            [f32::NAN, 0.0, 1.0],
            2,
            ANTUMBRA_RESULT_NON_FINITE,
            "direction (NaN, 0, 1) is not finite",
        ),
        (
            [0.0, 0.0, 2.0],
            2,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "direction has length 2, not 1",
        ),
        (
            [0.0, 0.0, 1.0],
            9,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "bands is 9",
        ),
    ] {
        let mut values = [-7.0f32; 64];
        // SAFETY: 3 floats in, up to 64 out.
        let result = unsafe { antumbra_sh_eval(direction.as_ptr(), bands, values.as_mut_ptr()) };
        assert_eq!(result, code, "{}", last_error());
        assert!(last_error().contains(needle), "{}", last_error());
        assert!(values.iter().all(|&v| v == -7.0));
    }
    // SAFETY: NULL pointers under test.
    unsafe {
        assert_eq!(
            antumbra_sh_eval(ptr::null(), 1, [0.0f32].as_mut_ptr()),
            ANTUMBRA_RESULT_NULL_ARGUMENT
        );
        assert!(last_error().contains("direction is NULL"));
        assert_eq!(
            antumbra_sh_eval([0.0f32, 0.0, 1.0].as_ptr(), 1, ptr::null_mut()),
            ANTUMBRA_RESULT_NULL_ARGUMENT
        );
        assert!(last_error().contains("values is NULL"));
    }
}
