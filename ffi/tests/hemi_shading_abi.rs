//! The per-vertex transfer and shading exports called from Rust exactly as C would
//! call them: bit-for-bit agreement with core's batch functions (one-shot calls and
//! shaders, every method, quality and space, with and without the far mesh,
//! parallel or not), the documented defaults and closed forms, the shader's
//! lifecycle, one code and a message naming the argument for every class of bad
//! input, outputs untouched on failure, and no allocation per frame.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ffi::CStr;
use std::ptr;

use antumbra::*;
use antumbra_core::MeshView;
use antumbra_core::glam::Vec3;
use antumbra_core::hemi::{
    BatchOptions, ClusteredMesh, HalfSpaceTable, HemiScene, Material, PhongLobe, Quality,
    TransferLut, TransferMethod, TransferSpace, TransferTable, VertexShading, shade_batch,
    shade_batch_split, shade_vertex, transfer_batch, vertex_normals,
};
use antumbra_core::sh::{Sh, ShRgb};

// ---------------------------------------------------------------------------
// Allocation counting (this thread only)
// ---------------------------------------------------------------------------

struct CountingAllocator;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; the counter is a const-initialised
// thread-local Cell, which needs no allocation.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: forwarded contract.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, pointer: *mut u8, layout: Layout) {
        // SAFETY: forwarded contract.
        unsafe { System.dealloc(pointer, layout) }
    }
    unsafe fn realloc(&self, pointer: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: forwarded contract.
        unsafe { System.realloc(pointer, layout, size) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

// ---------------------------------------------------------------------------
// Meshes
// ---------------------------------------------------------------------------

fn last_error() -> String {
    // SAFETY: the library returns a valid NUL-terminated string.
    unsafe { CStr::from_ptr(antumbra_last_error_message()) }
        .to_string_lossy()
        .into_owned()
}

/// A closed UV sphere with its radius modulated by `0.25 sin 5θ sin 4φ` (concave
/// enough that vertices shadow each other), twisted about +z by `twist` radians
/// per unit of height, wound counter-clockwise seen from outside.
#[derive(Clone)]
struct Mesh {
    positions: Vec<f32>,
    indices: Vec<u32>,
}

fn blob(rings: u32, segments: u32, twist: f32) -> Mesh {
    let (positions, indices) = antumbra_core::geom::uv_sphere(rings, segments, |theta, phi| {
        let radius = 1.0 + 0.25 * (5.0 * theta).sin() * (4.0 * phi).sin();
        let z = radius * theta.cos();
        let angle = phi + twist * z;
        [
            radius * theta.sin() * angle.cos(),
            radius * theta.sin() * angle.sin(),
            z,
        ]
    });
    Mesh {
        positions: positions.into_iter().flatten().collect(),
        indices,
    }
}

impl Mesh {
    fn view(&self) -> antumbra_mesh_view {
        antumbra_mesh_view {
            positions: self.positions.as_ptr(),
            vertex_count: self.vertex_count(),
            position_stride: 0,
            indices: self.indices.as_ptr(),
            triangle_count: self.indices.len() / 3,
        }
    }

    fn core(&self) -> MeshView<'_> {
        MeshView::new(bytemuck::cast_slice(&self.positions), &self.indices).unwrap()
    }

    fn vertex_count(&self) -> usize {
        self.positions.len() / 3
    }

    /// Core's area-weighted normals, flattened.
    fn normals(&self) -> Vec<f32> {
        let mut normals = vec![Vec3::ZERO; self.vertex_count()];
        vertex_normals(&self.core(), &mut normals).unwrap();
        normals.iter().flat_map(|n| n.to_array()).collect()
    }
}

fn default_options() -> antumbra_hemi_shading_options {
    let mut options = std::mem::MaybeUninit::<antumbra_hemi_shading_options>::uninit();
    // SAFETY: a valid pointer to one options struct; init writes every field.
    unsafe {
        antumbra_hemi_shading_options_init(options.as_mut_ptr());
        options.assume_init()
    }
}

fn options_with(
    f: impl FnOnce(&mut antumbra_hemi_shading_options),
) -> antumbra_hemi_shading_options {
    let mut options = default_options();
    f(&mut options);
    options
}

fn default_material() -> antumbra_hemi_material {
    let mut material = std::mem::MaybeUninit::<antumbra_hemi_material>::uninit();
    // SAFETY: a valid pointer to one material; init writes every field.
    unsafe {
        antumbra_hemi_material_init(material.as_mut_ptr());
        material.assume_init()
    }
}

/// A glossy, coloured material seen from a point off the blob.
fn glossy_material() -> antumbra_hemi_material {
    antumbra_hemi_material {
        albedo: [0.8, 0.6, 0.4],
        specular: [0.3, 0.25, 0.2],
        phong_exponent: 12.0,
        eye: [0.5, -4.0, 2.0],
        ..default_material()
    }
}

/// Some SH lighting of `bands` bands with energy in every coefficient.
fn lighting(bands: usize) -> Vec<f32> {
    let n = bands * bands;
    (0..3 * n)
        .map(|i| {
            let (channel, k) = (i / n, i % n);
            if k == 0 {
                3.0 + channel as f32 * 0.5
            } else {
                0.7 * ((i as f32) * 1.7).sin() / (1.0 + k as f32).sqrt()
            }
        })
        .collect()
}

// ---------------------------------------------------------------------------
// Core references
// ---------------------------------------------------------------------------

struct Reference<'a> {
    mesh: &'a Mesh,
    far: Option<&'a Mesh>,
    normals: Vec<Vec3>,
    options: antumbra_hemi_shading_options,
    table: &'a HalfSpaceTable,
}

impl<'a> Reference<'a> {
    fn new(
        mesh: &'a Mesh,
        far: Option<&'a Mesh>,
        normals: Option<&[f32]>,
        options: antumbra_hemi_shading_options,
        table: &'a HalfSpaceTable,
    ) -> Self {
        let normals = normals.map_or_else(|| mesh.normals(), <[f32]>::to_vec);
        Reference {
            mesh,
            far,
            normals: normals.chunks(3).map(Vec3::from_slice).collect(),
            options,
            table,
        }
    }

    fn scene(&self) -> HemiScene<'a> {
        let mesh = ClusteredMesh::unclustered(self.mesh.core());
        match self.far {
            None => HemiScene::new(mesh),
            Some(far) => HemiScene::with_far(
                mesh,
                ClusteredMesh::unclustered(far.core()),
                self.options.near_radius,
            ),
        }
    }

    fn batch_options(&self) -> BatchOptions<'a> {
        let raster = &self.options.raster;
        BatchOptions {
            quality: if raster.quality == ANTUMBRA_HEMI_QUALITY_TABLE {
                Quality::Table(self.table)
            } else {
                Quality::Exact
            },
            cull_backfaces: raster.cull_backfaces == 1,
            normal_offset: raster.normal_offset,
            parallel: raster.parallel == 1,
        }
    }

    fn transfer(&self) -> Vec<f32> {
        match self.options.bands {
            1 => self.transfer_n::<1>(),
            2 => self.transfer_n::<4>(),
            3 => self.transfer_n::<9>(),
            4 => self.transfer_n::<16>(),
            8 => self.transfer_n::<64>(),
            b => panic!("no reference for {b} bands"),
        }
    }

    fn transfer_n<const N: usize>(&self) -> Vec<f32> {
        let table = TransferTable::<N>::new();
        let lut;
        let method = match self.options.method {
            ANTUMBRA_HEMI_METHOD_CELLS => TransferMethod::Cells(&table),
            ANTUMBRA_HEMI_METHOD_LUT => {
                lut = TransferLut::new(table.clone());
                TransferMethod::Lut(&lut)
            }
            _ => TransferMethod::Downsampled(&table),
        };
        let space = if self.options.space == ANTUMBRA_HEMI_SPACE_LOCAL {
            TransferSpace::Local
        } else {
            TransferSpace::World
        };
        let mut out = vec![Sh::<N>::ZERO; self.mesh.vertex_count()];
        transfer_batch(
            &self.scene(),
            &self.normals,
            &self.batch_options(),
            method,
            space,
            &mut out,
        )
        .unwrap();
        out.iter().flat_map(|t| t.coeffs).collect()
    }

    /// `(rgb, diffuse, glossy)` from `shade_batch` and `shade_batch_split`, for a
    /// material without per-vertex arrays.
    fn shade(&self, lighting: &[f32], material: &antumbra_hemi_material) -> [Vec<f32>; 3] {
        match self.options.bands {
            1 => self.shade_n::<1>(lighting, material),
            3 => self.shade_n::<9>(lighting, material),
            4 => self.shade_n::<16>(lighting, material),
            8 => self.shade_n::<64>(lighting, material),
            b => panic!("no reference for {b} bands"),
        }
    }

    fn shade_n<const N: usize>(
        &self,
        lighting: &[f32],
        material: &antumbra_hemi_material,
    ) -> [Vec<f32>; 3] {
        assert!(material.vertex_albedo.is_null() && material.view_directions.is_null());
        let table = TransferTable::<N>::new();
        let lut;
        let method = match self.options.method {
            ANTUMBRA_HEMI_METHOD_CELLS => TransferMethod::Cells(&table),
            ANTUMBRA_HEMI_METHOD_LUT => {
                lut = TransferLut::new(table.clone());
                TransferMethod::Lut(&lut)
            }
            _ => TransferMethod::Downsampled(&table),
        };
        let light = sh_rgb::<N>(lighting);
        let lobe = PhongLobe::new(material.phong_exponent).unwrap();
        let core_material = Material {
            albedo: Vec3::from(material.albedo),
            specular: Vec3::from(material.specular),
            lobe: Some(&lobe),
            eye: Vec3::from(material.eye),
        };
        let count = self.mesh.vertex_count();
        let mut rgb = vec![Vec3::ZERO; count];
        let mut split = vec![VertexShading::default(); count];
        let (scene, options) = (self.scene(), self.batch_options());
        shade_batch(
            &scene,
            &self.normals,
            &options,
            method,
            &light,
            &core_material,
            &mut rgb,
        )
        .unwrap();
        shade_batch_split(
            &scene,
            &self.normals,
            &options,
            method,
            &light,
            &core_material,
            &mut split,
        )
        .unwrap();
        let flat = |v: &mut dyn Iterator<Item = Vec3>| v.flat_map(|c| c.to_array()).collect();
        [
            flat(&mut rgb.iter().copied()),
            flat(&mut split.iter().map(|s| s.diffuse)),
            flat(&mut split.iter().map(|s| s.glossy)),
        ]
    }
}

fn sh_rgb<const N: usize>(l: &[f32]) -> ShRgb<N> {
    let channel = |c: usize| Sh::new(std::array::from_fn(|k| l[c * N + k]));
    ShRgb::from_channels([channel(0), channel(1), channel(2)])
}

// ---------------------------------------------------------------------------
// Calling the exports
// ---------------------------------------------------------------------------

const SENTINEL: f32 = -1234.5;

fn bands_of(options: &antumbra_hemi_shading_options) -> usize {
    options.bands as usize
}

fn transfer(
    mesh: &antumbra_mesh_view,
    normals: Option<&[f32]>,
    far: Option<&antumbra_mesh_view>,
    options: Option<&antumbra_hemi_shading_options>,
    bands: usize,
) -> (antumbra_result, Vec<f32>) {
    let mut out = vec![SENTINEL; mesh.vertex_count * bands * bands];
    // SAFETY: arrays of the sizes the call expects.
    let result = unsafe {
        antumbra_hemi_transfer(
            mesh,
            normals.map_or(ptr::null(), <[f32]>::as_ptr),
            far.map_or(ptr::null(), |f| f as *const _),
            options.map_or(ptr::null(), |o| o as *const _),
            out.as_mut_ptr(),
        )
    };
    (result, out)
}

#[allow(clippy::too_many_arguments)]
fn shade(
    mesh: &antumbra_mesh_view,
    normals: Option<&[f32]>,
    far: Option<&antumbra_mesh_view>,
    options: Option<&antumbra_hemi_shading_options>,
    lighting: &[f32],
    material: &antumbra_hemi_material,
) -> (antumbra_result, [Vec<f32>; 3]) {
    let mut out: [Vec<f32>; 3] = std::array::from_fn(|_| vec![SENTINEL; 3 * mesh.vertex_count]);
    let [rgb, diffuse, glossy] = &mut out;
    // SAFETY: arrays of the sizes the call expects.
    let result = unsafe {
        antumbra_hemi_shade(
            mesh,
            normals.map_or(ptr::null(), <[f32]>::as_ptr),
            far.map_or(ptr::null(), |f| f as *const _),
            options.map_or(ptr::null(), |o| o as *const _),
            lighting.as_ptr(),
            material,
            rgb.as_mut_ptr(),
            diffuse.as_mut_ptr(),
            glossy.as_mut_ptr(),
        )
    };
    (result, out)
}

/// An owned shader, destroyed on drop.
struct Shader(*mut antumbra_hemi_shader);

impl Shader {
    fn new(
        mesh: &antumbra_mesh_view,
        far: Option<&antumbra_mesh_view>,
        options: Option<&antumbra_hemi_shading_options>,
    ) -> Self {
        let mut shader = ptr::null_mut();
        // SAFETY: valid meshes, options and out pointer.
        let result = unsafe {
            antumbra_hemi_shader_create(
                mesh,
                far.map_or(ptr::null(), |f| f as *const _),
                options.map_or(ptr::null(), |o| o as *const _),
                &mut shader,
            )
        };
        assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
        assert!(!shader.is_null());
        Shader(shader)
    }

    fn transfer(
        &self,
        mesh: &antumbra_mesh_view,
        normals: Option<&[f32]>,
        far: Option<&antumbra_mesh_view>,
        bands: usize,
    ) -> (antumbra_result, Vec<f32>) {
        let mut out = vec![SENTINEL; mesh.vertex_count * bands * bands];
        // SAFETY: a live shader and arrays of the sizes the call expects.
        let result = unsafe {
            antumbra_hemi_shader_transfer(
                self.0,
                mesh,
                normals.map_or(ptr::null(), <[f32]>::as_ptr),
                far.map_or(ptr::null(), |f| f as *const _),
                out.as_mut_ptr(),
            )
        };
        (result, out)
    }

    fn shade(
        &self,
        mesh: &antumbra_mesh_view,
        normals: Option<&[f32]>,
        far: Option<&antumbra_mesh_view>,
        lighting: &[f32],
        material: &antumbra_hemi_material,
    ) -> (antumbra_result, [Vec<f32>; 3]) {
        let mut out: [Vec<f32>; 3] = std::array::from_fn(|_| vec![SENTINEL; 3 * mesh.vertex_count]);
        let [rgb, diffuse, glossy] = &mut out;
        // SAFETY: a live shader and arrays of the sizes the call expects.
        let result = unsafe {
            antumbra_hemi_shader_shade(
                self.0,
                mesh,
                normals.map_or(ptr::null(), <[f32]>::as_ptr),
                far.map_or(ptr::null(), |f| f as *const _),
                lighting.as_ptr(),
                material,
                rgb.as_mut_ptr(),
                diffuse.as_mut_ptr(),
                glossy.as_mut_ptr(),
            )
        };
        (result, out)
    }
}

impl Drop for Shader {
    fn drop(&mut self) {
        // SAFETY: from create, destroyed once.
        unsafe { antumbra_hemi_shader_destroy(self.0) };
    }
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[track_caller]
fn assert_bits_eq(a: &[f32], b: &[f32], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    if let Some(i) = (0..a.len()).find(|&i| a[i].to_bits() != b[i].to_bits()) {
        panic!(
            "{what}: element {i} is {} here and {} in the reference",
            a[i], b[i]
        );
    }
}

// ---------------------------------------------------------------------------
// Agreement with core
// ---------------------------------------------------------------------------

#[test]
fn transfer_equals_core_bit_for_bit_in_every_mode() {
    let mesh = blob(10, 14, 0.4);
    let far = blob(5, 7, 0.4);
    let (view, far_view) = (mesh.view(), far.view());
    let normals = mesh.normals();
    let table = HalfSpaceTable::default();
    let mut user_table = ptr::null_mut();
    // SAFETY: a valid out pointer.
    let created = unsafe { antumbra_hemi_table_create(0, &mut user_table) };
    assert_eq!(created, ANTUMBRA_RESULT_OK);
    let mut cases = 0;
    for bands in [1u32, 3, 4, 8] {
        for method in [
            ANTUMBRA_HEMI_METHOD_CELLS,
            ANTUMBRA_HEMI_METHOD_LUT,
            ANTUMBRA_HEMI_METHOD_DOWNSAMPLED,
        ] {
            for (k, quality) in [ANTUMBRA_HEMI_QUALITY_EXACT, ANTUMBRA_HEMI_QUALITY_TABLE]
                .into_iter()
                .enumerate()
            {
                let with_far = (bands + method + k as u32).is_multiple_of(2);
                let options = options_with(|o| {
                    o.bands = bands;
                    o.method = method;
                    o.raster.quality = quality;
                    o.raster.normal_offset = if k == 0 { 0.0 } else { 0.01 };
                    o.raster.cull_backfaces = (bands == 4) as u32;
                    o.raster.parallel = (method != ANTUMBRA_HEMI_METHOD_LUT) as u32;
                    // The caller-owned table equals the shared one (same resolution).
                    o.raster.table = if bands == 3 { user_table } else { ptr::null() };
                    o.space = if bands == 4 {
                        ANTUMBRA_HEMI_SPACE_LOCAL
                    } else {
                        ANTUMBRA_HEMI_SPACE_WORLD
                    };
                    o.near_radius = 0.6;
                });
                let far_mesh = with_far.then_some(&far);
                let reference = Reference::new(&mesh, far_mesh, None, options, &table).transfer();
                let b = bands_of(&options);
                let far_arg = with_far.then_some(&far_view);
                let what =
                    format!("bands {bands} method {method} quality {quality} far {with_far}");
                // Computed normals, one-shot.
                let (result, out) = transfer(&view, None, far_arg, Some(&options), b);
                assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
                assert_bits_eq(&out, &reference, &what);
                // The same normals given.
                let (result, out) = transfer(&view, Some(&normals), far_arg, Some(&options), b);
                assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
                assert_bits_eq(&out, &reference, &what);
                // Through a shader (clusters), twice: the second frame reuses it.
                let shader = Shader::new(&view, Some(&far_view), Some(&options));
                for _ in 0..2 {
                    let (result, out) = shader.transfer(&view, None, far_arg, b);
                    assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
                    assert_bits_eq(&out, &reference, &what);
                }
                cases += 1;
            }
        }
    }
    assert_eq!(cases, 24);
    // NULL options are the defaults: 3 bands, cells, exact, world, no far mesh.
    let reference = Reference::new(&mesh, None, None, default_options(), &table).transfer();
    let (result, out) = transfer(&view, None, None, None, 3);
    assert_eq!(result, ANTUMBRA_RESULT_OK);
    assert_bits_eq(&out, &reference, "defaults");
    // SAFETY: from create, no call running.
    unsafe { antumbra_hemi_table_destroy(user_table) };
}

#[test]
fn shading_equals_core_bit_for_bit() {
    let mesh = blob(10, 14, -0.3);
    let far = blob(5, 7, -0.3);
    let (view, far_view) = (mesh.view(), far.view());
    let table = HalfSpaceTable::default();
    for (bands, method, quality, with_far) in [
        (
            3u32,
            ANTUMBRA_HEMI_METHOD_CELLS,
            ANTUMBRA_HEMI_QUALITY_EXACT,
            false,
        ),
        (
            3,
            ANTUMBRA_HEMI_METHOD_CELLS,
            ANTUMBRA_HEMI_QUALITY_TABLE,
            true,
        ),
        (
            4,
            ANTUMBRA_HEMI_METHOD_LUT,
            ANTUMBRA_HEMI_QUALITY_EXACT,
            true,
        ),
        (
            1,
            ANTUMBRA_HEMI_METHOD_DOWNSAMPLED,
            ANTUMBRA_HEMI_QUALITY_TABLE,
            false,
        ),
        (
            8,
            ANTUMBRA_HEMI_METHOD_DOWNSAMPLED,
            ANTUMBRA_HEMI_QUALITY_EXACT,
            true,
        ),
    ] {
        let options = options_with(|o| {
            o.bands = bands;
            o.method = method;
            o.raster.quality = quality;
            o.raster.normal_offset = 0.005;
            o.raster.parallel = 1;
            o.near_radius = 0.5;
        });
        let b = bands_of(&options);
        let light = lighting(b);
        let material = glossy_material();
        let far_mesh = with_far.then_some(&far);
        let far_arg = with_far.then_some(&far_view);
        let reference = Reference::new(&mesh, far_mesh, None, options, &table);
        let expected = reference.shade(&light, &material);
        let what = format!("bands {bands} method {method} quality {quality} far {with_far}");
        let (result, out) = shade(&view, None, far_arg, Some(&options), &light, &material);
        assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
        for (got, want) in out.iter().zip(&expected) {
            assert_bits_eq(got, want, &what);
        }
        let shader = Shader::new(&view, Some(&far_view), Some(&options));
        for _ in 0..2 {
            let (result, out) = shader.shade(&view, None, far_arg, &light, &material);
            assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
            for (got, want) in out.iter().zip(&expected) {
                assert_bits_eq(got, want, &what);
            }
        }
        // The glossy term is really there, and diffuse + glossy is the sum.
        assert!(out[2].iter().any(|&g| g > 0.01), "{what}");
        for ((rgb, diffuse), glossy) in out[0].iter().zip(&out[1]).zip(&out[2]) {
            assert_eq!(rgb.to_bits(), (diffuse + glossy).to_bits());
        }
    }
}

#[test]
fn per_vertex_albedo_and_view_directions_match_core_per_vertex() {
    let mesh = blob(9, 12, 0.2);
    let view = mesh.view();
    let core_mesh = mesh.core();
    let normals: Vec<Vec3> = mesh.normals().chunks(3).map(Vec3::from_slice).collect();
    let options = options_with(|o| o.raster.normal_offset = 0.01);
    let light = lighting(3);
    let base = glossy_material();
    let count = mesh.vertex_count();
    let albedo: Vec<f32> = (0..3 * count).map(|i| (i % 7) as f32 * 0.1).collect();
    let eye = Vec3::from(base.eye);
    // The direction towards the eye exactly as core computes it: the two paths
    // must then agree bit for bit.
    let towards_eye: Vec<f32> = (0..count)
        .flat_map(|v| (eye - core_mesh.position(v)).normalize_or_zero().to_array())
        .collect();
    let material = antumbra_hemi_material {
        vertex_albedo: albedo.as_ptr(),
        ..base
    };
    let (result, with_albedo) = shade(&view, None, None, Some(&options), &light, &material);
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    let (result, towards) = shade(
        &view,
        None,
        None,
        Some(&options),
        &light,
        &antumbra_hemi_material {
            view_directions: towards_eye.as_ptr(),
            ..material
        },
    );
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    let table = TransferTable::<9>::new();
    let lobe = PhongLobe::new(base.phong_exponent).unwrap();
    let scene = HemiScene::new(ClusteredMesh::unclustered(core_mesh));
    let batch = BatchOptions {
        normal_offset: 0.01,
        ..BatchOptions::default()
    };
    let sh = sh_rgb::<9>(&light);
    for v in 0..count {
        let s = shade_vertex(
            &scene,
            core_mesh.position(v),
            normals[v],
            &batch,
            TransferMethod::Cells(&table),
            &sh,
            &Material {
                albedo: Vec3::from_slice(&albedo[3 * v..]),
                specular: Vec3::from(base.specular),
                lobe: Some(&lobe),
                eye,
            },
        );
        let at = 3 * v..3 * v + 3;
        assert_eq!(
            bits(&with_albedo[1][at.clone()]),
            bits(&s.diffuse.to_array()),
            "vertex {v}"
        );
        assert_eq!(
            bits(&with_albedo[2][at.clone()]),
            bits(&s.glossy.to_array()),
            "vertex {v}"
        );
        for k in 0..3 {
            assert_eq!(
                bits(&towards[k][at.clone()]),
                bits(&with_albedo[k][at.clone()]),
                "{v}"
            );
        }
    }
    // An orthographic view (one direction for every vertex) is not the eye's.
    let along: Vec<f32> = (0..count).flat_map(|_| [0.0, -1.0, 0.0]).collect();
    let (result, ortho) = shade(
        &view,
        None,
        None,
        Some(&options),
        &light,
        &antumbra_hemi_material {
            view_directions: along.as_ptr(),
            ..base
        },
    );
    assert_eq!(result, ANTUMBRA_RESULT_OK);
    assert_ne!(bits(&ortho[2]), bits(&with_albedo[2]));
}

#[test]
fn parallel_on_and_off_give_identical_results() {
    let mesh = blob(10, 14, 0.8);
    let far = blob(5, 7, 0.8);
    let (view, far_view) = (mesh.view(), far.view());
    for quality in [ANTUMBRA_HEMI_QUALITY_EXACT, ANTUMBRA_HEMI_QUALITY_TABLE] {
        let serial = options_with(|o| {
            o.raster.quality = quality;
            o.near_radius = 0.7;
            o.bands = 4;
        });
        let parallel = options_with(|o| {
            *o = serial;
            o.raster.parallel = 1;
        });
        let light = lighting(4);
        let material = glossy_material();
        let a = transfer(&view, None, Some(&far_view), Some(&serial), 4);
        let b = transfer(&view, None, Some(&far_view), Some(&parallel), 4);
        assert_eq!((a.0, bits(&a.1)), (b.0, bits(&b.1)));
        let a = shade(
            &view,
            None,
            Some(&far_view),
            Some(&serial),
            &light,
            &material,
        );
        let b = shade(
            &view,
            None,
            Some(&far_view),
            Some(&parallel),
            &light,
            &material,
        );
        assert_eq!(a.0, ANTUMBRA_RESULT_OK);
        assert_eq!(b.0, ANTUMBRA_RESULT_OK);
        for k in 0..3 {
            assert_eq!(bits(&a.1[k]), bits(&b.1[k]));
        }
        let s = Shader::new(&view, Some(&far_view), Some(&serial));
        let p = Shader::new(&view, Some(&far_view), Some(&parallel));
        let a = s.shade(&view, None, Some(&far_view), &light, &material);
        let c = p.shade(&view, None, Some(&far_view), &light, &material);
        for k in 0..3 {
            assert_eq!(bits(&a.1[k]), bits(&c.1[k]));
            assert_eq!(bits(&a.1[k]), bits(&b.1[k]));
        }
    }
}

// ---------------------------------------------------------------------------
// Closed forms
// ---------------------------------------------------------------------------

#[test]
fn a_lone_triangle_gets_the_unoccluded_closed_forms() {
    // Each vertex of a lone triangle sees nothing (its own triangle is edge-on).
    let mesh = Mesh {
        positions: vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
        indices: vec![0, 1, 2],
    };
    let view = mesh.view();
    let (result, world) = transfer(&view, None, None, None, 3);
    assert_eq!(result, ANTUMBRA_RESULT_OK);
    // Normal +z: T_0 = √π/2, T_2 (Y_1^0 ∝ z) = √(π/3), the rest 0; band 2 zonal
    // A_2 Y_2^0(+z) = (π/4)(0.630783) = 0.495416.
    let expected = [
        0.886_227, 0.0, 1.023_327, 0.0, 0.0, 0.0, 0.495_416, 0.0, 0.0,
    ];
    for v in 0..3 {
        for (k, e) in expected.iter().enumerate() {
            assert!(
                (world[9 * v + k] - e).abs() < 2e-6,
                "vertex {v} coefficient {k}"
            );
        }
    }
    // Local space is the same for a +z normal; a -z normal flips the odd bands in
    // world space but not in local space.
    let flipped = Mesh {
        indices: vec![0, 2, 1],
        ..mesh.clone()
    };
    let local = options_with(|o| o.space = ANTUMBRA_HEMI_SPACE_LOCAL);
    let (_, world_down) = transfer(&flipped.view(), None, None, None, 3);
    let (_, local_down) = transfer(&flipped.view(), None, None, Some(&local), 3);
    assert!((world_down[2] + 1.023_327).abs() < 2e-6);
    assert!((local_down[2] - 1.023_327).abs() < 2e-6);
    // Constant radiance L: diffuse = albedo · L; glossy seen along the normal is
    // about specular · L (the lobe is sampled at cell centers).
    let radiance = 0.75;
    let mut light = vec![0.0; 27];
    for c in 0..3 {
        light[9 * c] = 2.0 * std::f32::consts::PI.sqrt() * radiance;
    }
    let material = antumbra_hemi_material {
        albedo: [0.5, 0.25, 1.0],
        specular: [0.2, 0.4, 0.0],
        phong_exponent: 8.0,
        view_directions: [0.0f32, 0.0, 1.0].repeat(3).leak().as_ptr(),
        ..default_material()
    };
    let (result, out) = shade(&view, None, None, None, &light, &material);
    assert_eq!(result, ANTUMBRA_RESULT_OK);
    for v in 0..3 {
        for c in 0..3 {
            let diffuse = out[1][3 * v + c];
            assert!((diffuse - material.albedo[c] * radiance).abs() < 1e-5);
            let glossy = out[2][3 * v + c];
            let want = material.specular[c] * radiance;
            assert!(
                (glossy - want).abs() <= 0.01 * want + 1e-7,
                "{glossy} vs {want}"
            );
        }
    }
}

#[test]
fn zero_normals_give_zero_results_and_unused_vertices_are_skipped() {
    let mut mesh = blob(6, 8, 0.0);
    // An extra vertex in no triangle: its computed normal is zero.
    mesh.positions.extend_from_slice(&[5.0, 5.0, 5.0]);
    let view = mesh.view();
    let count = mesh.vertex_count();
    let (result, out) = transfer(&view, None, None, None, 3);
    assert_eq!(result, ANTUMBRA_RESULT_OK);
    assert!(out[9 * (count - 1)..].iter().all(|&c| c == 0.0));
    assert!(out[0] > 0.1);
    let mut normals = mesh.normals();
    normals[3..6].fill(0.0);
    let (result, out) = shade(
        &view,
        Some(&normals),
        None,
        None,
        &lighting(3),
        &glossy_material(),
    );
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    for channel in &out {
        assert_eq!(&channel[3..6], &[0.0; 3]);
        assert!(channel[count * 3 - 3..].iter().all(|&c| c == 0.0));
    }
}

// ---------------------------------------------------------------------------
// Defaults, layout and the shader's life
// ---------------------------------------------------------------------------

#[test]
fn init_functions_write_the_documented_defaults() {
    let mut options = antumbra_hemi_shading_options {
        raster: antumbra_hemi_options {
            quality: 7,
            cull_backfaces: 7,
            normal_offset: f32::NAN,
            parallel: 7,
            table: 0x40 as *const antumbra_hemi_table,
        },
        bands: 0,
        method: 9,
        space: 9,
        near_radius: f32::NAN,
        far_triangles: 9,
        far_levels: 9,
    };
    // SAFETY: a valid struct.
    unsafe { antumbra_hemi_shading_options_init(&mut options) };
    assert_eq!(last_error(), "");
    let mut raster = options.raster;
    // SAFETY: a valid struct.
    unsafe { antumbra_hemi_options_init(&mut raster) };
    assert_eq!(options.raster, raster);
    assert_eq!(
        (options.bands, options.method, options.space),
        (3, ANTUMBRA_HEMI_METHOD_CELLS, ANTUMBRA_HEMI_SPACE_WORLD)
    );
    assert_eq!(options.near_radius, f32::INFINITY);
    assert_eq!((options.far_triangles, options.far_levels), (0, 0));
    let mut material = antumbra_hemi_material {
        albedo: [f32::NAN; 3],
        specular: [f32::NAN; 3],
        phong_exponent: -1.0,
        eye: [f32::NAN; 3],
        vertex_albedo: 0x40 as *const f32,
        view_directions: 0x40 as *const f32,
    };
    // SAFETY: a valid struct.
    unsafe { antumbra_hemi_material_init(&mut material) };
    assert_eq!(material.albedo, [1.0; 3]);
    assert_eq!(material.specular, [0.0; 3]);
    assert_eq!(material.phong_exponent, 16.0);
    assert_eq!(material.eye, [0.0; 3]);
    assert!(material.vertex_albedo.is_null() && material.view_directions.is_null());
    // Layout (no padding): the raster options first.
    use std::mem::{offset_of, size_of};
    let raster_size = size_of::<antumbra_hemi_options>();
    assert_eq!(offset_of!(antumbra_hemi_shading_options, raster), 0);
    assert_eq!(
        offset_of!(antumbra_hemi_shading_options, bands),
        raster_size
    );
    assert_eq!(
        offset_of!(antumbra_hemi_shading_options, method),
        raster_size + 4
    );
    assert_eq!(
        offset_of!(antumbra_hemi_shading_options, space),
        raster_size + 8
    );
    assert_eq!(
        offset_of!(antumbra_hemi_shading_options, near_radius),
        raster_size + 12
    );
    assert_eq!(
        offset_of!(antumbra_hemi_shading_options, far_triangles),
        raster_size + 16
    );
    assert_eq!(
        offset_of!(antumbra_hemi_shading_options, far_levels),
        raster_size + 20
    );
    assert_eq!(size_of::<antumbra_hemi_shading_options>(), raster_size + 24);
    assert_eq!(offset_of!(antumbra_hemi_material, specular), 12);
    assert_eq!(offset_of!(antumbra_hemi_material, phong_exponent), 24);
    assert_eq!(offset_of!(antumbra_hemi_material, eye), 28);
    assert_eq!(offset_of!(antumbra_hemi_material, vertex_albedo), 40);
    assert_eq!(
        offset_of!(antumbra_hemi_material, view_directions),
        40 + size_of::<*const f32>()
    );
    assert_eq!(
        size_of::<antumbra_hemi_material>(),
        40 + 2 * size_of::<*const f32>()
    );
    // NULL and misaligned pointers write nothing and say so.
    // SAFETY: NULL and misaligned pointers under test.
    unsafe { antumbra_hemi_shading_options_init(ptr::null_mut()) };
    assert!(last_error().contains("options is NULL"), "{}", last_error());
    // SAFETY: as above.
    unsafe { antumbra_hemi_material_init(ptr::null_mut()) };
    assert!(
        last_error().contains("material is NULL"),
        "{}",
        last_error()
    );
    let mut bytes = [0u8; 128];
    // SAFETY: misaligned, checked before any write.
    unsafe { antumbra_hemi_material_init(bytes.as_mut_ptr().add(1).cast()) };
    assert!(last_error().contains("not aligned"), "{}", last_error());
    assert!(bytes.iter().all(|&b| b == 0));
}

#[test]
fn a_shader_follows_a_deforming_mesh_frame_after_frame() {
    let rest = blob(9, 12, 0.0);
    let far_rest = blob(5, 6, 0.0);
    let options = options_with(|o| {
        o.near_radius = 0.6;
        o.raster.quality = ANTUMBRA_HEMI_QUALITY_TABLE;
    });
    let shader = Shader::new(&rest.view(), Some(&far_rest.view()), Some(&options));
    let light = lighting(3);
    let mut material = glossy_material();
    for (frame, twist) in [0.0f32, 0.5, 1.2, 2.0].into_iter().enumerate() {
        let (mesh, far) = (blob(9, 12, twist), blob(5, 6, twist));
        let (view, far_view) = (mesh.view(), far.view());
        material.phong_exponent = [12.0, 12.0, 40.0, 3.0][frame];
        let what = format!("frame {frame}");
        let mut with_and_without = Vec::new();
        for far_arg in [Some(&far_view), None] {
            let (result, by_shader) = shader.shade(&view, None, far_arg, &light, &material);
            assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
            let (result, one_shot) = shade(&view, None, far_arg, Some(&options), &light, &material);
            assert_eq!(result, ANTUMBRA_RESULT_OK);
            for k in 0..3 {
                assert_bits_eq(&by_shader[k], &one_shot[k], &what);
            }
            let (_, t_shader) = shader.transfer(&view, None, far_arg, 3);
            let (_, t_once) = transfer(&view, None, far_arg, Some(&options), 3);
            assert_bits_eq(&t_shader, &t_once, &what);
            with_and_without.push(bits(&t_shader));
        }
        // The far mesh matters (it stands in for the distant full mesh).
        assert_ne!(with_and_without[0], with_and_without[1], "{what}");
        // Regrouping from the current pose changes speed, never results.
        if frame == 2 {
            // SAFETY: a live shader and valid meshes.
            let result = unsafe { antumbra_hemi_shader_regroup(shader.0, &view, &far_view) };
            assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
            let (_, after) = shader.transfer(&view, None, Some(&far_view), 3);
            let (_, once) = transfer(&view, None, Some(&far_view), Some(&options), 3);
            assert_bits_eq(&after, &once, "after regroup");
        }
    }
}

/// The library's far mesh (`far_triangles`): a shader gives the bits of the same
/// calls with that far mesh passed by the caller, posed from each frame's full
/// mesh, and the near radius of the documented rule (so does a one-shot call on
/// the pose the shader was made from); it is refused together with a caller's
/// far mesh.
#[test]
fn the_librarys_far_mesh_follows_the_full_mesh_as_a_callers_would() {
    let rest = blob(24, 32, 0.0);
    let options = options_with(|o| {
        o.far_triangles = 300;
        o.raster.quality = ANTUMBRA_HEMI_QUALITY_TABLE;
    });
    let rest_core = MeshView::new(bytemuck_positions(&rest.positions), &rest.indices).unwrap();
    let mut far = antumbra_core::hemi::FarMesh::with_triangles(&rest_core, 300).unwrap();
    assert_eq!(
        ANTUMBRA_HEMI_NEAR_CELLS,
        antumbra_core::hemi::FarMesh::NEAR_CELLS
    );
    assert!(
        far.triangle_count().abs_diff(300) <= 60,
        "{}",
        far.triangle_count()
    );
    let by_hand = options_with(|o| {
        o.near_radius = ANTUMBRA_HEMI_NEAR_CELLS * far.cell_size();
        o.raster.quality = ANTUMBRA_HEMI_QUALITY_TABLE;
    });
    let shader = Shader::new(&rest.view(), None, Some(&options));
    let light = lighting(3);
    let material = glossy_material();
    let mut differs_from_full = false;
    for twist in [0.0f32, 0.7, 1.6] {
        let mesh = blob(24, 32, twist);
        let view = mesh.view();
        far.pose(&MeshView::new(bytemuck_positions(&mesh.positions), &mesh.indices).unwrap())
            .unwrap();
        let far_mesh = Mesh {
            positions: far.positions().iter().flatten().copied().collect(),
            indices: far.indices().to_vec(),
        };
        let what = format!("twist {twist}");
        let (result, want) = transfer(&view, None, Some(&far_mesh.view()), Some(&by_hand), 3);
        assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
        let (result, by_shader) = shader.transfer(&view, None, None, 3);
        assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
        assert_bits_eq(&by_shader, &want, &what);
        // A one-shot call simplifies the mesh as it is given: in the rest pose it
        // makes the shader's far mesh; in another pose its own.
        let (result, once) = transfer(&view, None, None, Some(&options), 3);
        assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
        if twist == 0.0 {
            assert_bits_eq(&once, &want, &what);
        }
        let (_, shaded) = shader.shade(&view, None, None, &light, &material);
        let (_, shaded_by_hand) = shade(
            &view,
            None,
            Some(&far_mesh.view()),
            Some(&by_hand),
            &light,
            &material,
        );
        for k in 0..3 {
            assert_bits_eq(&shaded[k], &shaded_by_hand[k], &what);
        }
        let (_, full) = transfer(&view, None, None, None, 3);
        differs_from_full |= bits(&full) != bits(&want);
    }
    assert!(
        differs_from_full,
        "the far mesh never stood in for the full one"
    );
    // A caller's far mesh and far_triangles together are refused, at creation and
    // per frame.
    let caller_far = blob(5, 6, 0.0);
    let (result, out) = transfer(
        &rest.view(),
        None,
        Some(&caller_far.view()),
        Some(&options),
        3,
    );
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(
        last_error().contains("far_mesh is given together with options->far_triangles = 300"),
        "{}",
        last_error()
    );
    assert!(out.iter().all(|&c| c == SENTINEL));
    let mut refused = ptr::null_mut();
    // SAFETY: valid pointers; the conflicting far mesh is under test.
    let result = unsafe {
        antumbra_hemi_shader_create(&rest.view(), &caller_far.view(), &options, &mut refused)
    };
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(refused.is_null());
    let (result, _) = shader.transfer(&rest.view(), None, Some(&caller_far.view()), 3);
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(
        last_error().contains("the shader makes its own far mesh"),
        "{}",
        last_error()
    );
}

/// With the library's far mesh a finite near radius below
/// `ANTUMBRA_HEMI_MIN_NEAR_CELLS` cube edges is refused, by a shader and by a
/// one-shot call alike, with the least radius in the message and the outputs
/// untouched; the least radius itself is taken.
#[test]
fn a_near_radius_under_the_far_meshs_cube_diagonal_is_refused() {
    assert_eq!(
        ANTUMBRA_HEMI_MIN_NEAR_CELLS,
        antumbra_core::hemi::FarMesh::MIN_NEAR_CELLS
    );
    let rest = blob(24, 32, 0.0);
    let rest_core = MeshView::new(bytemuck_positions(&rest.positions), &rest.indices).unwrap();
    let far = antumbra_core::hemi::FarMesh::with_triangles(&rest_core, 300).unwrap();
    let minimum = ANTUMBRA_HEMI_MIN_NEAR_CELLS * far.cell_size();
    let with_radius = |radius: f32| {
        options_with(|o| {
            o.far_triangles = 300;
            o.far_levels = 3;
            o.near_radius = radius;
        })
    };
    let small = with_radius(0.9 * minimum);
    let (result, out) = transfer(&rest.view(), None, None, Some(&small), 3);
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    let message = last_error();
    assert!(
        message.contains("options->near_radius is") && message.contains(&minimum.to_string()),
        "{message}"
    );
    assert!(out.iter().all(|&c| c == SENTINEL));
    let mut refused = ptr::null_mut();
    // SAFETY: valid pointers; the radius is under test.
    let result =
        unsafe { antumbra_hemi_shader_create(&rest.view(), ptr::null(), &small, &mut refused) };
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(refused.is_null());
    assert!(
        last_error().contains("options->near_radius is"),
        "{}",
        last_error()
    );
    let (result, _) = transfer(&rest.view(), None, None, Some(&with_radius(minimum)), 3);
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
}

/// The library's far field in several levels (`far_levels`): a shader gives
/// the bits of core's `FarField` scene, posed from each frame's full mesh; a
/// one-shot call on the rest pose gives the same; 0 and 1 level are the same
/// single far mesh, and more levels change the result.
#[test]
fn far_levels_are_cores_far_field_posed_per_frame() {
    let rest = blob(32, 48, 0.0);
    let levels = 3;
    // A near radius of about a third of the blob, just above the least the
    // first level's cubes allow: every level has a band on it.
    let radius = 0.6;
    let options = options_with(|o| {
        o.far_triangles = 400;
        o.far_levels = levels;
        o.near_radius = radius;
    });
    let one_level = options_with(|o| {
        o.far_triangles = 400;
        o.near_radius = radius;
    });
    let explicit_one = antumbra_hemi_shading_options {
        far_levels: 1,
        ..one_level
    };
    let mut field = antumbra_core::hemi::FarField::new(&rest.core(), 400, levels as usize).unwrap();
    field.set_near_radius(radius).unwrap();
    assert_eq!(field.level_count(), levels as usize);
    let shader = Shader::new(&rest.view(), None, Some(&options));
    let single = Shader::new(&rest.view(), None, Some(&one_level));
    let table = HalfSpaceTable::default();
    let mut differs_from_one_level = false;
    for twist in [0.0f32, 0.9] {
        let mesh = blob(32, 48, twist);
        let view = mesh.view();
        let what = format!("twist {twist}");
        let posed = field.pose(&mesh.core()).unwrap();
        let scene = posed.scene(ClusteredMesh::unclustered(mesh.core()));
        let reference = Reference::new(&mesh, None, None, options, &table);
        let mut want = vec![Sh::<9>::ZERO; mesh.vertex_count()];
        transfer_batch(
            &scene,
            &reference.normals,
            &reference.batch_options(),
            TransferMethod::Cells(&TransferTable::<9>::new()),
            TransferSpace::World,
            &mut want,
        )
        .unwrap();
        let want: Vec<f32> = want.iter().flat_map(|t| t.coeffs).collect();
        let (result, by_shader) = shader.transfer(&view, None, None, 3);
        assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
        assert_bits_eq(&by_shader, &want, &what);
        if twist == 0.0 {
            let (result, once) = transfer(&view, None, None, Some(&options), 3);
            assert_eq!(result, ANTUMBRA_RESULT_OK, "{what}: {}", last_error());
            assert_bits_eq(&once, &want, &what);
            let (_, zero) = transfer(&view, None, None, Some(&one_level), 3);
            let (_, one) = transfer(&view, None, None, Some(&explicit_one), 3);
            assert_bits_eq(&zero, &one, &what);
        }
        let (_, by_single) = single.transfer(&view, None, None, 3);
        differs_from_one_level |= bits(&by_single) != bits(&by_shader);
    }
    assert!(differs_from_one_level, "the coarser levels were never used");
}

fn bytemuck_positions(flat: &[f32]) -> &[[f32; 3]] {
    bytemuck::cast_slice(flat)
}

#[test]
fn shaders_check_their_topology_and_destroy_null() {
    let mesh = blob(6, 8, 0.0);
    let far = blob(3, 5, 0.0);
    let other = blob(7, 8, 0.0);
    let (view, far_view, other_view) = (mesh.view(), far.view(), other.view());
    let light = lighting(3);
    let material = default_material();
    // SAFETY: NULL is a no-op.
    unsafe { antumbra_hemi_shader_destroy(ptr::null_mut()) };
    let plain = Shader::new(&view, None, None);
    let (result, out) = plain.transfer(&other_view, None, None, 3);
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(
        last_error().contains("the shader was created for 56 vertices"),
        "{}",
        last_error()
    );
    assert!(out.iter().all(|&c| c == SENTINEL));
    let (result, out) = plain.transfer(&view, None, Some(&far_view), 3);
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(last_error().contains("created without a far mesh"));
    assert!(out.iter().all(|&c| c == SENTINEL));
    let with_far = Shader::new(&view, Some(&far_view), None);
    let (result, out) = with_far.shade(&view, None, Some(&other_view), &light, &material);
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(
        last_error().contains("far_mesh has 64 vertices"),
        "{}",
        last_error()
    );
    assert!(out.iter().flatten().all(|&c| c == SENTINEL));
    // SAFETY: a live shader, a mismatched mesh.
    let result = unsafe { antumbra_hemi_shader_regroup(with_far.0, &other_view, ptr::null()) };
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    // A NULL shader.
    let mut out = vec![SENTINEL; 9 * mesh.vertex_count()];
    // SAFETY: NULL shader under test.
    let result = unsafe {
        antumbra_hemi_shader_transfer(
            ptr::null_mut(),
            &view,
            ptr::null(),
            ptr::null(),
            out.as_mut_ptr(),
        )
    };
    assert_eq!(result, ANTUMBRA_RESULT_NULL_ARGUMENT);
    assert!(last_error().contains("shader is NULL"));
    // Create checks its arguments and leaves `out` alone on failure.
    let mut shader = 0x40 as *mut antumbra_hemi_shader;
    let bad = options_with(|o| o.bands = 9);
    // SAFETY: valid pointers; bad options under test.
    let result = unsafe { antumbra_hemi_shader_create(&view, ptr::null(), &bad, &mut shader) };
    assert_eq!(result, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(
        last_error().contains("options->bands is 9"),
        "{}",
        last_error()
    );
    assert_eq!(shader as usize, 0x40);
    // SAFETY: NULL out under test.
    let result =
        unsafe { antumbra_hemi_shader_create(&view, ptr::null(), ptr::null(), ptr::null_mut()) };
    assert_eq!(result, ANTUMBRA_RESULT_NULL_ARGUMENT);
    // SAFETY: NULL mesh under test.
    let result =
        unsafe { antumbra_hemi_shader_create(ptr::null(), ptr::null(), ptr::null(), &mut shader) };
    assert_eq!(result, ANTUMBRA_RESULT_NULL_ARGUMENT);
    assert!(last_error().contains("mesh is NULL"));
    assert_eq!(shader as usize, 0x40);
}

#[test]
fn many_threads_share_one_shader_and_the_one_shot_calls() {
    let mesh = blob(8, 10, 0.3);
    let view = mesh.view();
    let table_options = || options_with(|o| o.raster.quality = ANTUMBRA_HEMI_QUALITY_TABLE);
    let options = table_options();
    let shader = Shader::new(&view, None, Some(&options));
    let light = lighting(3);
    let material = glossy_material();
    let (_, expected) = shade(&view, None, None, Some(&options), &light, &material);
    // Raw pointers are not Send; everything shared is only read (the shader's
    // calls take its lock).
    let shader_address = shader.0 as usize;
    let results: Vec<[Vec<f32>; 3]> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..4)
            .map(|k| {
                let (mesh, light) = (&mesh, &light);
                scope.spawn(move || {
                    // Raw pointers are not Send: each thread builds its own
                    // (equal) material and options.
                    let (material, options) = (&glossy_material(), &table_options());
                    let view = mesh.view();
                    if k % 2 == 0 {
                        let shader = Shader(shader_address as *mut antumbra_hemi_shader);
                        let out = shader.shade(&view, None, None, light, material);
                        std::mem::forget(shader);
                        assert_eq!(out.0, ANTUMBRA_RESULT_OK);
                        out.1
                    } else {
                        let out = shade(&view, None, None, Some(options), light, material);
                        assert_eq!(out.0, ANTUMBRA_RESULT_OK);
                        out.1
                    }
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for out in &results {
        for k in 0..3 {
            assert_eq!(bits(&out[k]), bits(&expected[k]));
        }
    }
}

#[test]
fn a_frame_through_a_shader_allocates_nothing() {
    let mesh = blob(8, 10, 0.3);
    let far = blob(4, 6, 0.3);
    let (view, far_view) = (mesh.view(), far.view());
    // The caller's far mesh with two transfer methods, then the library's own,
    // then that with sparse receivers.
    for (method, far_triangles, sparse) in [
        (ANTUMBRA_HEMI_METHOD_CELLS, 0, false),
        (ANTUMBRA_HEMI_METHOD_LUT, 0, false),
        (ANTUMBRA_HEMI_METHOD_CELLS, 60, false),
        (ANTUMBRA_HEMI_METHOD_CELLS, 60, true),
    ] {
        let options = options_with(|o| {
            // The library's own far mesh takes its own rule.
            o.near_radius = if far_triangles == 0 {
                0.5
            } else {
                f32::INFINITY
            };
            o.method = method;
            o.far_triangles = far_triangles;
            o.raster.quality = ANTUMBRA_HEMI_QUALITY_TABLE;
        });
        let far_arg: *const antumbra_mesh_view = if far_triangles == 0 {
            &far_view
        } else {
            ptr::null()
        };
        let shader = Shader::new(
            &view,
            (far_triangles == 0).then_some(&far_view),
            Some(&options),
        );
        if sparse {
            // SAFETY: a live shader and a valid mesh.
            let result = unsafe { antumbra_hemi_shader_set_receivers(shader.0, &view, 1, 0.1) };
            assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
        }
        let light = lighting(3);
        let mut material = glossy_material();
        let count = mesh.vertex_count();
        let mut rgb = vec![0.0f32; 3 * count];
        let mut transfer_out = vec![0.0f32; 9 * count];
        // The counter sees this thread's allocations.
        let before = allocations();
        let probe = std::hint::black_box(vec![1u8; 16]);
        assert!(allocations() > before && probe.len() == 16);
        for (frame, exponent) in [10.0f32, 10.0, 30.0].into_iter().enumerate() {
            material.phong_exponent = exponent;
            let before = allocations();
            // SAFETY: a live shader and arrays of the right sizes.
            let results = unsafe {
                [
                    antumbra_hemi_shader_shade(
                        shader.0,
                        &view,
                        ptr::null(),
                        far_arg,
                        light.as_ptr(),
                        &material,
                        rgb.as_mut_ptr(),
                        ptr::null_mut(),
                        ptr::null_mut(),
                    ),
                    antumbra_hemi_shader_transfer(
                        shader.0,
                        &view,
                        ptr::null(),
                        far_arg,
                        transfer_out.as_mut_ptr(),
                    ),
                ]
            };
            let allocated = allocations() - before;
            assert_eq!(results, [ANTUMBRA_RESULT_OK; 2], "{}", last_error());
            assert_eq!(
                allocated, 0,
                "method {method} (sparse {sparse}) frame {frame}: {allocated} allocations"
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Bad input
// ---------------------------------------------------------------------------

/// What a bad call changes, the code it must return, and a needle its message
/// must contain.
struct Bad {
    code: antumbra_result,
    needle: &'static str,
}

fn expect(code: antumbra_result, needle: &'static str) -> Bad {
    Bad { code, needle }
}

#[test]
fn every_bad_input_has_its_code_a_message_naming_it_and_leaves_outputs_untouched() {
    let mesh = blob(5, 6, 0.0);
    let far = blob(3, 4, 0.0);
    let (view, far_view) = (mesh.view(), far.view());
    let count = mesh.vertex_count();
    let normals = mesh.normals();
    let light = lighting(3);
    let good = glossy_material();
    let options = default_options();

    let with = |k: usize, value: f32, of: &[f32]| {
        let mut v = of.to_vec();
        v[k] = value;
        v
    };
    let nan_normal = with(3 * 4 + 1, f32::NAN, &normals);
    let short_normal: Vec<f32> = normals
        .iter()
        .enumerate()
        .map(|(i, &c)| if i / 3 == 7 { 0.5 * c } else { c })
        .collect();
    let mut huge_vertex = mesh.clone();
    // A vertex in no triangle still is a receiver.
    huge_vertex.positions.extend_from_slice(&[1e13, 0.0, 0.0]);
    let mut nan_far = far.clone();
    nan_far.positions[4] = f32::NAN;
    let mut bad_far_indices = far.clone();
    bad_far_indices.indices[2] = 999;
    let nan_light = with(10, f32::NAN, &light);
    let negative_albedo: Vec<f32> = with(3 * 5 + 2, -0.1, &vec![0.5; 3 * count]);
    let long_direction: Vec<f32> = (0..count).flat_map(|_| [0.0, 0.0, 2.0]).collect();

    // (what, options, normals, far, call) cases for the transfer entry points.
    let option_cases: Vec<(antumbra_hemi_shading_options, Bad)> = vec![
        (
            options_with(|o| o.bands = 0),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->bands is 0; expected 1 to 8",
            ),
        ),
        (
            options_with(|o| o.bands = 9),
            expect(ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->bands is 9"),
        ),
        (
            options_with(|o| o.method = 3),
            expect(ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->method is 3"),
        ),
        (
            options_with(|o| o.space = 2),
            expect(ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->space is 2"),
        ),
        (
            options_with(|o| o.near_radius = f32::NAN),
            expect(ANTUMBRA_RESULT_NON_FINITE, "options->near_radius is NaN"),
        ),
        (
            options_with(|o| o.near_radius = -1.0),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->near_radius is -1",
            ),
        ),
        (
            options_with(|o| o.far_triangles = 48),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->far_triangles is 48: 48 far triangles requested: must be at least 1 \
                 and below the mesh's 48",
            ),
        ),
        (
            options_with(|o| o.far_triangles = u32::MAX),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->far_triangles is 4294967295",
            ),
        ),
        (
            options_with(|o| {
                o.far_triangles = 20;
                o.far_levels = ANTUMBRA_HEMI_MAX_FAR_LEVELS + 1;
            }),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->far_levels is 9; expected 0 to ANTUMBRA_HEMI_MAX_FAR_LEVELS (8)",
            ),
        ),
        (
            options_with(|o| o.far_levels = 2),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->far_levels is 2 but options->far_triangles is 0",
            ),
        ),
        (
            options_with(|o| o.raster.quality = 2),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->raster.quality is 2",
            ),
        ),
        (
            options_with(|o| o.raster.parallel = 2),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->raster.parallel is 2",
            ),
        ),
        (
            options_with(|o| o.raster.cull_backfaces = 5),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->raster.cull_backfaces is 5",
            ),
        ),
        (
            options_with(|o| o.raster.normal_offset = f32::INFINITY),
            expect(
                ANTUMBRA_RESULT_NON_FINITE,
                "options->raster.normal_offset is inf",
            ),
        ),
        (
            options_with(|o| o.raster.normal_offset = -0.5),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "options->raster.normal_offset is -0.5",
            ),
        ),
    ];
    let check = |result: antumbra_result, bad: &Bad, outputs: &[&[f32]], what: &str| {
        assert_eq!(
            result,
            bad.code,
            "{what}: got {} ({})",
            result,
            last_error()
        );
        let message = last_error();
        assert!(
            message.contains(bad.needle),
            "{what}: message {message:?} lacks {:?}",
            bad.needle
        );
        for out in outputs {
            assert!(out.iter().all(|&c| c == SENTINEL), "{what}: output written");
        }
    };
    for (o, bad) in &option_cases {
        let (result, out) = transfer(&view, None, None, Some(o), 3);
        check(result, bad, &[&out], "transfer");
        assert!(last_error().starts_with("antumbra_hemi_transfer: "));
        let (result, out) = shade(&view, None, None, Some(o), &light, &good);
        check(result, bad, &[&out[0], &out[1], &out[2]], "shade");
        let mut shader = ptr::null_mut();
        // SAFETY: valid pointers; bad options under test.
        let result = unsafe { antumbra_hemi_shader_create(&view, ptr::null(), o, &mut shader) };
        check(result, bad, &[], "shader_create");
        assert!(shader.is_null());
    }

    // Mesh, far mesh and normals.
    /// (mesh, normals, far mesh, expected failure)
    type FrameCase<'a> = (
        Option<antumbra_mesh_view>,
        Option<&'a [f32]>,
        Option<antumbra_mesh_view>,
        Bad,
    );
    let frame_cases: Vec<FrameCase<'_>> = vec![
        (
            None,
            None,
            None,
            expect(ANTUMBRA_RESULT_NULL_ARGUMENT, "mesh is NULL"),
        ),
        (
            Some(antumbra_mesh_view {
                indices: ptr::null(),
                ..view
            }),
            None,
            None,
            expect(ANTUMBRA_RESULT_NULL_ARGUMENT, "mesh->indices is NULL"),
        ),
        (
            Some(huge_vertex.view()),
            None,
            None,
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "mesh->positions: vertex 36 has a coordinate beyond",
            ),
        ),
        (
            Some(view),
            Some(&nan_normal),
            None,
            expect(ANTUMBRA_RESULT_NON_FINITE, "normals[4]"),
        ),
        (
            Some(view),
            Some(&short_normal),
            None,
            expect(ANTUMBRA_RESULT_INVALID_ARGUMENT, "normals[7] has length"),
        ),
        (
            Some(view),
            None,
            Some(nan_far.view()),
            expect(ANTUMBRA_RESULT_NON_FINITE, "far_mesh->positions: vertex 1"),
        ),
        (
            Some(view),
            None,
            Some(bad_far_indices.view()),
            expect(
                ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE,
                "far_mesh->indices[2] (triangle 0) is 999",
            ),
        ),
        (
            Some(view),
            None,
            Some(antumbra_mesh_view {
                position_stride: 8,
                ..far_view
            }),
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "far_mesh->position_stride is 8",
            ),
        ),
    ];
    for (m, n, f, bad) in &frame_cases {
        let m_ptr = m.as_ref().map_or(ptr::null(), |m| m as *const _);
        let f_ptr = f.as_ref().map_or(ptr::null(), |f| f as *const _);
        let n_ptr = n.map_or(ptr::null(), <[f32]>::as_ptr);
        let vertices = m.map_or(count, |m| m.vertex_count);
        let mut out = vec![SENTINEL; 9 * vertices];
        // SAFETY: arrays of the right sizes; the bad input under test.
        let result =
            unsafe { antumbra_hemi_transfer(m_ptr, n_ptr, f_ptr, &options, out.as_mut_ptr()) };
        check(result, bad, &[&out], "transfer");
        let mut rgb = vec![SENTINEL; 3 * vertices];
        // SAFETY: as above.
        let result = unsafe {
            antumbra_hemi_shade(
                m_ptr,
                n_ptr,
                f_ptr,
                &options,
                light.as_ptr(),
                &good,
                rgb.as_mut_ptr(),
                ptr::null_mut(),
                ptr::null_mut(),
            )
        };
        check(result, bad, &[&rgb], "shade");
    }
    // Through a shader, the same checks apply every frame.
    let shader = Shader::new(&view, Some(&far_view), Some(&options));
    let (result, out) = shader.transfer(&view, Some(&short_normal), None, 3);
    check(
        result,
        &expect(ANTUMBRA_RESULT_INVALID_ARGUMENT, "normals[7] has length"),
        &[&out],
        "shader transfer",
    );
    assert!(last_error().starts_with("antumbra_hemi_shader_transfer: "));

    // Shading inputs.
    let material_cases: Vec<(antumbra_hemi_material, Bad)> = vec![
        (
            antumbra_hemi_material {
                albedo: [0.5, f32::NAN, 0.5],
                ..good
            },
            expect(ANTUMBRA_RESULT_NON_FINITE, "material->albedo"),
        ),
        (
            antumbra_hemi_material {
                specular: [0.5, -0.5, 0.5],
                ..good
            },
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "material->specular (0.5, -0.5, 0.5) has a negative channel",
            ),
        ),
        (
            antumbra_hemi_material {
                phong_exponent: -2.0,
                ..good
            },
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "material->phong_exponent is -2",
            ),
        ),
        (
            antumbra_hemi_material {
                phong_exponent: f32::INFINITY,
                ..good
            },
            expect(
                ANTUMBRA_RESULT_NON_FINITE,
                "material->phong_exponent is inf",
            ),
        ),
        (
            antumbra_hemi_material {
                eye: [0.0, 2e12, 0.0],
                ..good
            },
            expect(ANTUMBRA_RESULT_INVALID_ARGUMENT, "material->eye"),
        ),
        (
            antumbra_hemi_material {
                eye: [0.0, f32::NAN, 0.0],
                ..good
            },
            expect(ANTUMBRA_RESULT_NON_FINITE, "material->eye"),
        ),
        (
            antumbra_hemi_material {
                vertex_albedo: negative_albedo.as_ptr(),
                ..good
            },
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "material->vertex_albedo[5]",
            ),
        ),
        (
            antumbra_hemi_material {
                view_directions: long_direction.as_ptr(),
                ..good
            },
            expect(
                ANTUMBRA_RESULT_INVALID_ARGUMENT,
                "material->view_directions[0] has length 2",
            ),
        ),
        (
            antumbra_hemi_material {
                vertex_albedo: light.as_ptr().cast::<u8>().wrapping_add(1).cast(),
                ..good
            },
            expect(ANTUMBRA_RESULT_INVALID_ARGUMENT, "material->vertex_albedo"),
        ),
    ];
    for (material, bad) in &material_cases {
        let (result, out) = shade(&view, None, None, None, &light, material);
        check(result, bad, &[&out[0], &out[1], &out[2]], "shade");
        let (result, out) = shader.shade(&view, None, None, &light, material);
        check(result, bad, &[&out[0], &out[1], &out[2]], "shader shade");
    }
    let (result, out) = shade(&view, None, None, None, &nan_light, &good);
    check(
        result,
        &expect(
            ANTUMBRA_RESULT_NON_FINITE,
            "lighting[10] (channel green, coefficient 1) is NaN",
        ),
        &[&out[0], &out[1], &out[2]],
        "lighting",
    );
    // NULL lighting, material and outputs.
    let mut rgb = vec![SENTINEL; 3 * count];
    let mut glossy = vec![SENTINEL; 3 * count];
    let call = |lighting: *const f32,
                material: *const antumbra_hemi_material,
                rgb: *mut f32,
                diffuse: *mut f32,
                glossy: *mut f32| {
        // SAFETY: every non-NULL array has the right size.
        unsafe {
            antumbra_hemi_shade(
                &view,
                ptr::null(),
                ptr::null(),
                ptr::null(),
                lighting,
                material,
                rgb,
                diffuse,
                glossy,
            )
        }
    };
    let r = call(
        ptr::null(),
        &good,
        rgb.as_mut_ptr(),
        ptr::null_mut(),
        ptr::null_mut(),
    );
    check(
        r,
        &expect(ANTUMBRA_RESULT_NULL_ARGUMENT, "lighting is NULL"),
        &[&rgb],
        "lighting",
    );
    let r = call(
        light.as_ptr(),
        ptr::null(),
        rgb.as_mut_ptr(),
        ptr::null_mut(),
        ptr::null_mut(),
    );
    check(
        r,
        &expect(ANTUMBRA_RESULT_NULL_ARGUMENT, "material is NULL"),
        &[&rgb],
        "material",
    );
    let r = call(
        light.as_ptr(),
        &good,
        ptr::null_mut(),
        ptr::null_mut(),
        ptr::null_mut(),
    );
    check(
        r,
        &expect(
            ANTUMBRA_RESULT_NULL_ARGUMENT,
            "rgb, diffuse and glossy are all NULL",
        ),
        &[],
        "outputs",
    );
    // Overlapping outputs, and an output over an input.
    let r = call(
        light.as_ptr(),
        &good,
        rgb.as_mut_ptr(),
        ptr::null_mut(),
        rgb.as_mut_ptr(),
    );
    check(
        r,
        &expect(ANTUMBRA_RESULT_INVALID_ARGUMENT, "rgb overlaps glossy"),
        &[&rgb],
        "overlap",
    );
    let mut positions_copy = mesh.positions.clone();
    positions_copy.resize(3 * count + 64, 0.0);
    let aliased = antumbra_mesh_view {
        positions: positions_copy.as_ptr(),
        ..view
    };
    // SAFETY: the output aliases the positions on purpose; it must be refused
    // before anything is written.
    let r = unsafe {
        antumbra_hemi_transfer(
            &aliased,
            ptr::null(),
            ptr::null(),
            ptr::null(),
            positions_copy.as_mut_ptr().add(3),
        )
    };
    assert_eq!(r, ANTUMBRA_RESULT_INVALID_ARGUMENT);
    assert!(
        last_error().contains("transfer overlaps mesh->positions"),
        "{}",
        last_error()
    );
    assert_eq!(&positions_copy[..3 * count], &mesh.positions[..]);
    let misaligned = glossy
        .as_mut_ptr()
        .cast::<u8>()
        .wrapping_add(2)
        .cast::<f32>();
    let r = call(
        light.as_ptr(),
        &good,
        ptr::null_mut(),
        ptr::null_mut(),
        misaligned,
    );
    check(
        r,
        &expect(ANTUMBRA_RESULT_INVALID_ARGUMENT, "glossy"),
        &[&glossy],
        "misaligned",
    );
    let (result, out) = transfer(&view, None, None, None, 3);
    assert_eq!(result, ANTUMBRA_RESULT_OK);
    assert!(out.iter().all(|&c| c != SENTINEL));
    // NULL transfer output.
    // SAFETY: NULL output under test.
    let r = unsafe {
        antumbra_hemi_transfer(
            &view,
            ptr::null(),
            ptr::null(),
            ptr::null(),
            ptr::null_mut(),
        )
    };
    assert_eq!(r, ANTUMBRA_RESULT_NULL_ARGUMENT);
    assert!(
        last_error().contains("transfer is NULL"),
        "{}",
        last_error()
    );
    // An empty mesh needs no arrays at all.
    let empty = antumbra_mesh_view {
        positions: ptr::null(),
        vertex_count: 0,
        position_stride: 0,
        indices: ptr::null(),
        triangle_count: 0,
    };
    // SAFETY: an empty mesh, NULL outputs.
    let r = unsafe {
        antumbra_hemi_transfer(
            &empty,
            ptr::null(),
            ptr::null(),
            ptr::null(),
            ptr::null_mut(),
        )
    };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    // SAFETY: as above.
    let r = unsafe {
        antumbra_hemi_shade(
            &empty,
            ptr::null(),
            ptr::null(),
            ptr::null(),
            light.as_ptr(),
            &good,
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
        )
    };
    assert_eq!(r, ANTUMBRA_RESULT_OK, "{}", last_error());
    assert_eq!(last_error(), "");
}

/// Sparse receivers (`antumbra_hemi_shader_set_receivers`): the keys keep the
/// exact bits, other vertices interpolate, spacing 0 restores every bit, and
/// bad settings are refused with the argument named and the old setting kept.
#[test]
fn sparse_receivers_keep_the_keys_exact_and_refuse_bad_settings() {
    let mesh = blob(48, 64, 0.0);
    let view = mesh.view();
    let shader = Shader::new(&view, None, None);
    let (result, exact) = shader.transfer(&view, None, None, 3);
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    let set = |mesh: *const antumbra_mesh_view, spacing: u32, tolerance: f32| {
        // SAFETY: a live shader; the mesh NULL or valid.
        unsafe { antumbra_hemi_shader_set_receivers(shader.0, mesh, spacing, tolerance) }
    };
    assert_eq!(set(&view, 1, 0.05), ANTUMBRA_RESULT_OK, "{}", last_error());
    let (result, sparse) = shader.transfer(&view, None, None, 3);
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    let sampling = antumbra_core::hemi::ReceiverSampling::new(&mesh.core(), 1).unwrap();
    let vector = |t: &[f32], v: usize| bits(&t[9 * v..9 * v + 9]);
    for &key in sampling.keys() {
        assert_eq!(vector(&sparse, key as usize), vector(&exact, key as usize));
    }
    let interpolated = (0..mesh.vertex_count())
        .filter(|&v| vector(&sparse, v) != vector(&exact, v))
        .count();
    assert!(
        interpolated > 0 && interpolated < mesh.vertex_count() - sampling.keys().len(),
        "{interpolated} of {} interpolated",
        mesh.vertex_count()
    );
    // Shading borrows occlusion too: the keys keep their colours (rgb,
    // diffuse and glossy), and some other vertices are interpolated.
    let light = lighting(3);
    let glossy = glossy_material();
    let (result, sparse_colours) = shader.shade(&view, None, None, &light, &glossy);
    assert_eq!(result, ANTUMBRA_RESULT_OK, "{}", last_error());
    assert_eq!(set(&view, 0, 0.0), ANTUMBRA_RESULT_OK);
    let (_, exact_colours) = shader.shade(&view, None, None, &light, &glossy);
    assert_eq!(set(&view, 1, 0.05), ANTUMBRA_RESULT_OK);
    let colour = |c: &[f32], v: usize| bits(&c[3 * v..3 * v + 3]);
    for k in 0..3 {
        for &key in sampling.keys() {
            let key = key as usize;
            assert_eq!(
                colour(&sparse_colours[k], key),
                colour(&exact_colours[k], key)
            );
        }
    }
    assert!(
        (0..mesh.vertex_count())
            .any(|v| colour(&sparse_colours[0], v) != colour(&exact_colours[0], v)),
        "some colours interpolated"
    );
    let other = blob(9, 12, 0.0);
    let refusals: [(*const antumbra_mesh_view, u32, f32, antumbra_result, &str); 5] = [
        (
            &view,
            ANTUMBRA_HEMI_MAX_RECEIVER_SPACING + 1,
            0.05,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "spacing is 5",
        ),
        (
            &view,
            1,
            f32::NAN,
            ANTUMBRA_RESULT_NON_FINITE,
            "tolerance is NaN",
        ),
        (
            &view,
            2,
            -0.5,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "tolerance is -0.5",
        ),
        (ptr::null(), 1, 0.05, ANTUMBRA_RESULT_NULL_ARGUMENT, "mesh"),
        (
            &other.view(),
            1,
            0.05,
            ANTUMBRA_RESULT_INVALID_ARGUMENT,
            "vertices",
        ),
    ];
    for (mesh_arg, spacing, tolerance, code, needle) in refusals {
        assert_eq!(set(mesh_arg, spacing, tolerance), code, "{needle}");
        assert!(last_error().contains(needle), "{needle}: {}", last_error());
        let (_, again) = shader.transfer(&view, None, None, 3);
        assert_bits_eq(&again, &sparse, "the old setting stays");
    }
    // SAFETY: a NULL shader is refused before anything is read.
    let result = unsafe { antumbra_hemi_shader_set_receivers(ptr::null_mut(), &view, 1, 0.05) };
    assert_eq!(result, ANTUMBRA_RESULT_NULL_ARGUMENT);
    // Spacing 0 rasterizes every vertex again; its tolerance is not read.
    assert_eq!(
        set(&view, 0, f32::NAN),
        ANTUMBRA_RESULT_OK,
        "{}",
        last_error()
    );
    let (_, every) = shader.transfer(&view, None, None, 3);
    assert_bits_eq(&every, &exact, "spacing 0");
}
