//! The precomputed-transfer C ABI called from Rust as C would call it, against core:
//! a bake through the ABI is core's bake with the same options bit for bit (so every
//! option reaches core), shading equals `TransferSet::shade` with the channel-planar
//! lighting transposed, save/load round-trips, PCA with every component reproduces
//! the dense set, `antumbra_sh_rotate` equals `ShRotation`, and one set shades the
//! same from many threads at once.

use std::ffi::CStr;
use std::ptr;

use antumbra::*;
use antumbra_core::MeshView;
use antumbra_core::glam::{Mat3, Vec3};
use antumbra_core::raycast::BvhScene;
use antumbra_core::sh::{Sh, ShRotation};
use antumbra_core::transfer::{
    self, BakeOptions, Material, Measurement, PhongBrdf, TransferSet, View, WardBrdf,
};

fn last_error() -> String {
    // SAFETY: the library returns a valid NUL-terminated string.
    unsafe { CStr::from_ptr(antumbra_last_error_message()) }
        .to_string_lossy()
        .into_owned()
}

/// A bumpy 6×6 grid under a tilted quad that shadows part of it: enough geometry
/// for visibility to matter, small enough for debug builds.
struct Scene {
    positions: Vec<f32>,
    normals: Vec<f32>,
    indices: Vec<u32>,
}

fn scene() -> Scene {
    let n = 6;
    let mut positions = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, z) = (
                i as f32 / (n - 1) as f32 * 2.0 - 1.0,
                j as f32 / (n - 1) as f32 * 2.0 - 1.0,
            );
            positions.extend_from_slice(&[x, 0.05 * (3.0 * x).sin() * (2.0 * z).cos(), z]);
        }
    }
    let mut indices = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = (j * n + i) as u32;
            let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
            indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    let base = (positions.len() / 3) as u32;
    positions.extend_from_slice(&[
        -0.5, 0.5, -0.5, 0.5, 0.7, -0.5, 0.5, 0.7, 0.5, -0.5, 0.5, 0.5,
    ]);
    indices.extend_from_slice(&[base, base + 2, base + 1, base, base + 3, base + 2]);
    let mesh = MeshView::new(bytemuck::cast_slice(&positions), &indices).unwrap();
    let mut normals = vec![Vec3::ZERO; mesh.vertex_count()];
    antumbra_core::hemi::vertex_normals(&mesh, &mut normals).unwrap();
    let normals = normals.iter().flat_map(|n| n.to_array()).collect();
    Scene {
        positions,
        normals,
        indices,
    }
}

impl Scene {
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

    fn normals(&self) -> Vec<Vec3> {
        self.normals.chunks_exact(3).map(Vec3::from_slice).collect()
    }
}

fn options(kind: u32) -> antumbra_transfer_options {
    let mut o = std::mem::MaybeUninit::uninit();
    // SAFETY: a valid pointer to write.
    unsafe { antumbra_transfer_options_init(o.as_mut_ptr()) };
    // SAFETY: fully written by init.
    let mut o = unsafe { o.assume_init() };
    o.kind = kind;
    o.bands = 3;
    o.grid = 4;
    o.rays = 32;
    o.seed = 11;
    o
}

fn bake(scene: &Scene, normals: bool, o: &antumbra_transfer_options) -> *mut antumbra_transfer {
    let mut out = ptr::null_mut();
    let n = if normals {
        scene.normals.as_ptr()
    } else {
        ptr::null()
    };
    // SAFETY: live arrays and options, valid out pointer.
    let r = unsafe { antumbra_transfer_bake(&scene.view(), n, o, None, ptr::null_mut(), &mut out) };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    out
}

fn save(set: *const antumbra_transfer) -> Vec<u8> {
    let mut size = 0usize;
    // SAFETY: a size query; valid pointers.
    let r = unsafe { antumbra_transfer_save(set, ptr::null_mut(), 0, &mut size) };
    assert_eq!(r, ANTUMBRA_RESULT_BUFFER_TOO_SMALL);
    let mut bytes = vec![0u8; size];
    let mut written = 0usize;
    // SAFETY: `bytes` holds `size` bytes.
    let r = unsafe { antumbra_transfer_save(set, bytes.as_mut_ptr(), size, &mut written) };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    assert_eq!(written, size);
    bytes
}

fn core_bake(
    scene: &Scene,
    measurement: Measurement<'_>,
    o: &antumbra_transfer_options,
) -> TransferSet {
    let mesh = scene.core();
    let bvh = BvhScene::new(&mesh).unwrap();
    let options = BakeOptions {
        measurement,
        bands: o.bands,
        rays: o.rays,
        bounces: o.bounces,
        albedo: o.albedo,
        ray_offset: o.ray_offset,
        seed: o.seed,
        progress: None,
    };
    transfer::bake_serial(&mesh, &scene.normals(), &bvh, &options).unwrap()
}

/// Channel-planar lighting (as C passes it) and its coefficient-major twin (core's).
fn lighting(bands: u32) -> (Vec<f32>, Vec<[f32; 3]>) {
    let n = (bands * bands) as usize;
    let planar: Vec<f32> = (0..3 * n)
        .map(|i| {
            let (c, j) = (i / n, i % n);
            if j == 0 {
                1.0 + 0.2 * c as f32
            } else {
                0.3 * ((j * 7 + c * 3) as f32).sin()
            }
        })
        .collect();
    let interleaved = (0..n)
        .map(|j| [planar[j], planar[n + j], planar[2 * n + j]])
        .collect();
    (planar, interleaved)
}

fn shade(
    set: *const antumbra_transfer,
    lighting: &[f32],
    material: &antumbra_transfer_material,
    components: u32,
    vertices: usize,
) -> Vec<[f32; 3]> {
    let mut rgb = vec![[0.0f32; 3]; vertices];
    // SAFETY: live arrays of the documented sizes.
    let r = unsafe {
        antumbra_transfer_shade(
            set,
            lighting.as_ptr(),
            lighting.len(),
            material,
            components,
            rgb.as_mut_ptr().cast(),
            vertices,
        )
    };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    rgb
}

fn material(eye: [f32; 3]) -> antumbra_transfer_material {
    let mut m = std::mem::MaybeUninit::uninit();
    // SAFETY: a valid pointer to write.
    unsafe { antumbra_transfer_material_init(m.as_mut_ptr()) };
    // SAFETY: fully written by init.
    let mut m = unsafe { m.assume_init() };
    m.eye = eye;
    m.albedo = [0.9, 0.7, 0.5];
    m.specular = [0.5, 0.6, 0.7];
    m.phong_exponent = 12.0;
    m
}

fn core_material(m: &antumbra_transfer_material) -> Material {
    Material {
        albedo: m.albedo,
        specular: m.specular,
        phong_exponent: m.phong_exponent,
    }
}

#[test]
fn bake_through_the_abi_is_cores_bake_and_shades_like_core() {
    let scene = scene();
    let vertices = scene.positions.len() / 3;
    let phong = PhongBrdf::new(16.0).unwrap();
    let ward = WardBrdf::new(0.2, 0.5).unwrap();
    let mut cases = vec![
        (
            options(ANTUMBRA_TRANSFER_KIND_DIFFUSE),
            Measurement::Diffuse,
        ),
        (
            options(ANTUMBRA_TRANSFER_KIND_GLOSSY_SH),
            Measurement::GlossySh,
        ),
        (
            options(ANTUMBRA_TRANSFER_KIND_MRT),
            Measurement::Mrt {
                grid: 4,
                brdf: &phong,
            },
        ),
    ];
    let mut with_bounces = options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    with_bounces.bounces = 2;
    with_bounces.albedo = 0.7;
    with_bounces.ray_offset = 1e-3;
    with_bounces.seed = 99;
    cases.push((with_bounces, Measurement::Diffuse));
    let mut ward_options = options(ANTUMBRA_TRANSFER_KIND_MRT);
    ward_options.brdf = ANTUMBRA_TRANSFER_BRDF_WARD;
    ward_options.brdf_params = [0.2, 0.5];
    ward_options.grid = 3;
    cases.push((
        ward_options,
        Measurement::Mrt {
            grid: 3,
            brdf: &ward,
        },
    ));
    let (planar, interleaved) = lighting(3);
    let m = material([0.3, 2.0, 1.5]);
    for (o, measurement) in cases {
        let expected = core_bake(&scene, measurement, &o);
        let set = bake(&scene, true, &o);
        let mut serial_options = o;
        serial_options.parallel = 0;
        let serial = bake(&scene, true, &serial_options);
        // Bit for bit: the file bytes are the whole set.
        assert_eq!(save(set), expected.to_bytes(), "{measurement:?}");
        assert_eq!(save(serial), expected.to_bytes(), "{measurement:?} serial");
        let got = shade(set, &planar, &m, 0, vertices);
        let mut want = vec![[0.0f32; 3]; vertices];
        expected
            .shade(
                &interleaved,
                View::Eye(m.eye),
                &core_material(&m),
                None,
                &mut want,
            )
            .unwrap();
        assert_eq!(got, want, "{measurement:?}");
        // Per-vertex view directions.
        let dirs: Vec<f32> = (0..vertices)
            .flat_map(|v| [0.1 * v as f32, 1.0, 0.3])
            .collect();
        let mut md = m;
        md.view_directions = dirs.as_ptr();
        let got = shade(set, &planar, &md, 0, vertices);
        let dir3: Vec<[f32; 3]> = dirs.chunks_exact(3).map(|d| [d[0], d[1], d[2]]).collect();
        expected
            .shade(
                &interleaved,
                View::Directions(&dir3),
                &core_material(&m),
                None,
                &mut want,
            )
            .unwrap();
        assert_eq!(got, want, "{measurement:?} with view directions");
        // SAFETY: from bake, destroyed once.
        unsafe {
            antumbra_transfer_destroy(set);
            antumbra_transfer_destroy(serial);
        }
    }
}

#[test]
fn save_load_round_trips_and_describe_reports_the_set() {
    let scene = scene();
    let set = bake(&scene, false, &options(ANTUMBRA_TRANSFER_KIND_MRT));
    let bytes = save(set);
    let mut loaded = ptr::null_mut();
    // SAFETY: live bytes, valid out pointer.
    let r = unsafe { antumbra_transfer_load(bytes.as_ptr(), bytes.len(), &mut loaded) };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    assert_eq!(save(loaded), bytes);
    let mut info = std::mem::MaybeUninit::uninit();
    // SAFETY: live set, valid out pointer.
    let r = unsafe { antumbra_transfer_describe(loaded, info.as_mut_ptr()) };
    assert_eq!(r, ANTUMBRA_RESULT_OK);
    // SAFETY: written on success.
    let info = unsafe { info.assume_init() };
    let core = TransferSet::from_bytes(&bytes).unwrap();
    assert_eq!(info.kind, ANTUMBRA_TRANSFER_KIND_MRT);
    assert_eq!(info.bands, 3);
    assert_eq!(info.coeff_count, 9);
    assert_eq!(info.grid, 4);
    assert_eq!(info.components, 0);
    assert_eq!(info.vertex_count as usize, scene.positions.len() / 3);
    assert_eq!(info.rays, 32);
    assert_eq!(info.brdf, ANTUMBRA_TRANSFER_BRDF_PHONG);
    assert_eq!(info.brdf_params, [16.0, 0.0]);
    assert_eq!(info.data_bytes, core.data_bytes());
    assert_eq!(info.file_bytes, bytes.len());
    // Geometry: the positions baked, and the computed normals core computes.
    let mut positions = vec![0.0f32; scene.positions.len()];
    let mut normals = vec![0.0f32; scene.positions.len()];
    // SAFETY: arrays of 3 floats per vertex.
    let r = unsafe {
        antumbra_transfer_geometry(
            loaded,
            positions.as_mut_ptr(),
            normals.as_mut_ptr(),
            info.vertex_count as usize,
        )
    };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    assert_eq!(positions, scene.positions);
    assert_eq!(normals, scene.normals);
    // SAFETY: each destroyed once.
    unsafe {
        antumbra_transfer_destroy(set);
        antumbra_transfer_destroy(loaded);
    }
}

/// A 2-band, 3 × 3 MRT bake of the test scene, its vertex count and the most
/// components it can be compressed to.
fn small_mrt() -> (*mut antumbra_transfer, usize, u32) {
    let scene = scene();
    let vertices = scene.positions.len() / 3;
    let mut o = options(ANTUMBRA_TRANSFER_KIND_MRT);
    o.bands = 2;
    o.grid = 3;
    let set = bake(&scene, true, &o);
    (set, vertices, (vertices as u32).min(3 * 3 * 4))
}

#[test]
fn pca_with_every_component_reproduces_the_dense_set() {
    let (set, vertices, all) = small_mrt();
    let mut pca = ptr::null_mut();
    // SAFETY: live set, valid out pointer.
    let r = unsafe { antumbra_transfer_compress(set, all, &mut pca) };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    let (planar, interleaved) = lighting(2);
    let m = material([0.0, 3.0, 0.5]);
    let dense = shade(set, &planar, &m, 0, vertices);
    let max = dense.iter().flatten().fold(0.0f32, |a, &b| a.max(b.abs()));
    for components in [0, all, all + 5] {
        let got = shade(pca, &planar, &m, components, vertices);
        for (g, d) in got.iter().flatten().zip(dense.iter().flatten()) {
            assert!((g - d).abs() <= 1e-5 * max, "K = {components}: {g} vs {d}");
        }
    }
    // Fewer components: core's compressed shading with the same K.
    let core = TransferSet::from_bytes(&save(pca)).unwrap();
    let got = shade(pca, &planar, &m, 2, vertices);
    let mut want = vec![[0.0f32; 3]; vertices];
    core.shade(
        &interleaved,
        View::Eye(m.eye),
        &core_material(&m),
        Some(2),
        &mut want,
    )
    .unwrap();
    assert_eq!(got, want);
    // SAFETY: each destroyed once.
    unsafe {
        antumbra_transfer_destroy(set);
        antumbra_transfer_destroy(pca);
    }
}

#[test]
fn clustered_pca_is_cores_and_reproduces_the_dense_set_with_every_component() {
    let (set, vertices, all) = small_mrt();
    let mut cpca = ptr::null_mut();
    // SAFETY: live set, valid out pointer.
    let r = unsafe { antumbra_transfer_compress_clustered(set, 3, all, &mut cpca) };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    // The same bytes as core's clustered PCA (seed 0) of the same set.
    let dense_core = TransferSet::from_bytes(&save(set)).unwrap();
    let want = dense_core
        .compress_clustered(3, all as usize, 0)
        .unwrap()
        .to_bytes();
    assert_eq!(save(cpca), want);
    let mut info = std::mem::MaybeUninit::uninit();
    // SAFETY: live set, valid out pointer.
    let r = unsafe { antumbra_transfer_describe(cpca, info.as_mut_ptr()) };
    assert_eq!(r, ANTUMBRA_RESULT_OK);
    // SAFETY: written on success.
    let info = unsafe { info.assume_init() };
    assert_eq!((info.clusters, info.components, info.reserved), (3, all, 0));
    assert_eq!(info.file_bytes, want.len());
    let (planar, _) = lighting(2);
    let m = material([0.0, 3.0, 0.5]);
    let dense = shade(set, &planar, &m, 0, vertices);
    let got = shade(cpca, &planar, &m, 0, vertices);
    let max = dense.iter().flatten().fold(0.0f32, |a, &b| a.max(b.abs()));
    for (g, d) in got.iter().flatten().zip(dense.iter().flatten()) {
        assert!((g - d).abs() <= 1e-5 * max, "{g} vs {d}");
    }
    // SAFETY: each destroyed once.
    unsafe {
        antumbra_transfer_destroy(set);
        antumbra_transfer_destroy(cpca);
    }
}

#[test]
fn sh_rotate_equals_core_rotation_in_place_and_not() {
    let angle = 0.7f32;
    let axis = Vec3::new(0.3, 1.0, -0.2).normalize();
    let matrix = Mat3::from_axis_angle(axis, angle);
    // Row-major for C.
    let rows: [f32; 9] = matrix.transpose().to_cols_array();
    let coeffs: Vec<f32> = (0..3 * 25).map(|i| ((i * 13) as f32).cos()).collect();
    let mut out = vec![0.0f32; coeffs.len()];
    // SAFETY: arrays of 3 × 25 floats.
    let r = unsafe { antumbra_sh_rotate(rows.as_ptr(), 5, coeffs.as_ptr(), 3, out.as_mut_ptr()) };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    let rotation = ShRotation::<25>::new(matrix);
    for v in 0..3 {
        let c: [f32; 25] = coeffs[25 * v..25 * v + 25].try_into().unwrap();
        assert_eq!(
            &out[25 * v..25 * v + 25],
            &rotation.apply(&Sh::new(c)).coeffs
        );
    }
    let mut in_place = coeffs.clone();
    // SAFETY: the same array in and out, which the function allows.
    let r = unsafe {
        antumbra_sh_rotate(
            rows.as_ptr(),
            5,
            in_place.as_ptr(),
            3,
            in_place.as_mut_ptr(),
        )
    };
    assert_eq!(r, ANTUMBRA_RESULT_OK);
    assert_eq!(in_place, out);
}

#[test]
fn one_set_shades_identically_from_many_threads() {
    let scene = scene();
    let vertices = scene.positions.len() / 3;
    let set = bake(&scene, true, &options(ANTUMBRA_TRANSFER_KIND_GLOSSY_SH));
    let (planar, _) = lighting(3);
    let m = material([0.5, 2.0, 0.0]);
    let expected = shade(set, &planar, &m, 0, vertices);
    struct Shared(*mut antumbra_transfer);
    // SAFETY: the handle is documented thread-safe for shading (Send + Sync inside).
    unsafe impl Sync for Shared {}
    let shared = Shared(set);
    std::thread::scope(|s| {
        for _ in 0..4 {
            s.spawn(|| {
                let shared = &shared;
                // The material holds a raw pointer (not Send): one per thread.
                let m = material([0.5, 2.0, 0.0]);
                for _ in 0..20 {
                    assert_eq!(shade(shared.0, &planar, &m, 0, vertices), expected);
                }
            });
        }
    });
    // SAFETY: from bake, destroyed once.
    unsafe { antumbra_transfer_destroy(set) };
}

/// The two materials of the C API speak one vocabulary: the fields of the same
/// name start from the same defaults (a white Lambertian surface, no glossy
/// term, Phong exponent 16, eye at the origin).
#[test]
fn hemi_and_transfer_materials_default_alike() {
    let mut transfer = std::mem::MaybeUninit::<antumbra_transfer_material>::uninit();
    let mut hemi = std::mem::MaybeUninit::<antumbra_hemi_material>::uninit();
    // SAFETY: valid pointers to write; each init writes every field.
    let (transfer, hemi) = unsafe {
        antumbra_transfer_material_init(transfer.as_mut_ptr());
        antumbra_hemi_material_init(hemi.as_mut_ptr());
        (transfer.assume_init(), hemi.assume_init())
    };
    assert_eq!(transfer.albedo, hemi.albedo);
    assert_eq!(transfer.specular, hemi.specular);
    assert_eq!(transfer.phong_exponent, hemi.phong_exponent);
    assert_eq!(transfer.eye, hemi.eye);
    assert_eq!(
        (transfer.albedo, transfer.specular, transfer.phong_exponent),
        ([1.0; 3], [0.0; 3], 16.0)
    );
    // Core's Rust material has the same defaults.
    let core = Material::default();
    assert_eq!(
        (core.albedo, core.specular, core.phong_exponent),
        (transfer.albedo, transfer.specular, transfer.phong_exponent)
    );
}
