//! The per-vertex API of a deforming mesh's frame: each vertex a receiver of
//! [`HemiScene`], its mask summed into a transfer vector ([`vertex_transfer`],
//! [`transfer_batch`]) or shaded under SH lighting ([`shade_vertex`],
//! [`shade_batch`]), with area-weighted [`vertex_normals`] for meshes that come
//! without them. The masks come from the `lod` module's loop.

use core::fmt;

use glam::Vec3;

use super::lod::{BatchOptions, HemiScene, scene_mask};
use super::mask::HemiMask;
use super::shading::{PhongLobe, glossy_transfer, mirror_direction, shade_glossy};
use super::transfer::{TransferMethod, TransferRotation, shade_diffuse};
use crate::geom::{MeshView, unit_or_zero};
use crate::sh::{Sh, ShRgb};

/// Why a batch call rejected its arguments (nothing was written).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BatchError {
    /// The normals slice does not hold one normal per vertex of the mesh.
    NormalCount {
        /// Vertices of the mesh.
        expected: usize,
        /// Normals given.
        got: usize,
    },
    /// An output slice does not hold one entry per vertex of the mesh.
    OutputLength {
        /// Vertices of the mesh.
        expected: usize,
        /// Entries given.
        got: usize,
    },
    /// `near_radius` is NaN or negative.
    NearRadius,
}

impl fmt::Display for BatchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            BatchError::NormalCount { expected, got } => {
                write!(f, "{got} normals given for a mesh of {expected} vertices")
            }
            BatchError::OutputLength { expected, got } => write!(
                f,
                "the output holds {got} entries for a mesh of {expected} vertices"
            ),
            BatchError::NearRadius => write!(f, "near_radius must be a number >= 0"),
        }
    }
}

impl core::error::Error for BatchError {}

/// Area-weighted vertex normals: per vertex, the sum of the unnormalised geometric
/// normals `(b - a) × (c - a)` of its triangles, normalised; zero where the sum is
/// zero or not finite (such vertices are skipped by the batch functions). The sum is
/// computed in `f32`: it overflows for edges beyond about `1e19` and is zero for
/// edges below about `1e-22` (their cross products underflow); anything between
/// normalises, whatever its size.
///
/// `out` must hold one normal per vertex.
pub fn vertex_normals(mesh: &MeshView<'_>, out: &mut [Vec3]) -> Result<(), BatchError> {
    if out.len() != mesh.vertex_count() {
        return Err(BatchError::OutputLength {
            expected: mesh.vertex_count(),
            got: out.len(),
        });
    }
    out.fill(Vec3::ZERO);
    for t in 0..mesh.triangle_count() {
        let [i, j, k] = mesh.triangle_indices(t);
        let [a, b, c] = mesh.triangle(t);
        let n = (b - a).cross(c - a);
        out[i as usize] += n;
        out[j as usize] += n;
        out[k as usize] += n;
    }
    for n in out.iter_mut() {
        // Edges above about 4e9 or below 1e-12 once gave zero normals: squaring
        // the sum's components overflowed or underflowed.
        *n = unit_or_zero(*n);
    }
    Ok(())
}

/// The space transfer vectors are written in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TransferSpace {
    /// World coefficients: dot them with world-space lighting.
    #[default]
    World,
    /// The receiver's local frame `(t, b, n)` of
    /// [`Frame::from_normal`](crate::Frame::from_normal).
    Local,
}

/// A surface's reflectance for [`shade_batch`]: Lambertian plus an optional
/// modified Phong lobe about the mirror direction of the view (see
/// [`PhongLobe`]).
#[derive(Clone, Copy, Debug)]
pub struct Material<'a> {
    /// Diffuse albedo per channel (`L = albedo/π · Σ T_k l_k`).
    pub albedo: Vec3,
    /// Specular reflectance `ρ_s` per channel (`L = ρ_s Σ G_k l_k`); the glossy
    /// term is skipped when it is zero or `lobe` is `None`.
    pub specular: Vec3,
    /// The glossy lobe, built once for its exponent.
    pub lobe: Option<&'a PhongLobe>,
    /// The viewer's world position, for the mirror directions.
    pub eye: Vec3,
}

/// Diffuse and glossy outgoing radiance of one vertex (linear RGB).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VertexShading {
    /// `albedo/π · Σ T_k l_k`.
    pub diffuse: Vec3,
    /// `ρ_s Σ G_k l_k`.
    pub glossy: Vec3,
}

/// Whether a vertex normal can carry a receiver.
#[inline]
pub(super) fn usable(normal: Vec3) -> bool {
    normal.is_finite() && normal != Vec3::ZERO
}

/// The transfer vector of the receiver at `position` with unit `normal`: mask,
/// sum by `method`, and rotation to world space when asked. Allocation-free.
pub fn vertex_transfer<const N: usize>(
    scene: &HemiScene<'_>,
    position: Vec3,
    normal: Vec3,
    options: &BatchOptions<'_>,
    method: TransferMethod<'_, N>,
    space: TransferSpace,
) -> Sh<N> {
    let mask = scene_mask(scene, position, normal, options);
    let local = method.transfer(&mask);
    match space {
        TransferSpace::Local => local,
        TransferSpace::World => {
            TransferRotation::new(&crate::Frame::from_normal(normal)).to_world(&local)
        }
    }
}

/// Diffuse and glossy radiance of the receiver at `position` with unit `normal`
/// under world-space SH `lighting` (incident radiance). Allocation-free.
///
/// The diffuse transfer uses `method`; the glossy one always sums the mask per
/// cell ([`glossy_transfer`] on `method.table()`), since its weights depend on the
/// view. The viewer behind the surface, or at the vertex, gets no glossy term.
pub fn shade_vertex<const N: usize>(
    scene: &HemiScene<'_>,
    position: Vec3,
    normal: Vec3,
    options: &BatchOptions<'_>,
    method: TransferMethod<'_, N>,
    lighting: &ShRgb<N>,
    material: &Material<'_>,
) -> VertexShading {
    // A far eye (beyond about 1e19) must not overflow the squared length into
    // a zero direction.
    let to_eye = unit_or_zero(material.eye - position);
    shade_vertex_towards(
        scene, position, normal, options, method, lighting, material, to_eye,
    )
}

/// [`shade_vertex`] for a viewer in the unit direction `to_eye` from the vertex
/// (orthographic or per-vertex views) instead of at `material.eye`, which is not
/// read: the same steps, so the same bits when `to_eye` is the direction
/// `shade_vertex` computes. A zero `to_eye` gets no glossy term.
#[allow(clippy::too_many_arguments)]
pub fn shade_vertex_towards<const N: usize>(
    scene: &HemiScene<'_>,
    position: Vec3,
    normal: Vec3,
    options: &BatchOptions<'_>,
    method: TransferMethod<'_, N>,
    lighting: &ShRgb<N>,
    material: &Material<'_>,
    to_eye: Vec3,
) -> VertexShading {
    let mask = scene_mask(scene, position, normal, options);
    shade_mask(&mask, normal, method, lighting, material, to_eye).shading
}

/// A receiver's shading from its mask, with what made it (for sparse
/// receivers, which borrow a key's occlusion).
pub(super) struct ShadedMask<const N: usize> {
    /// What [`shade_vertex_towards`] returns.
    pub shading: VertexShading,
    /// The receiver frame's SH rotation to world space.
    pub rotation: TransferRotation<N>,
    /// The local transfer vector.
    pub transfer: Sh<N>,
    /// The glossy lobe's local direction and transfer vector, when the
    /// material has a glossy term.
    pub glossy: Option<(Vec3, Sh<N>)>,
}

/// The steps of [`shade_vertex_towards`] after the mask.
#[inline]
pub(super) fn shade_mask<const N: usize>(
    mask: &HemiMask,
    normal: Vec3,
    method: TransferMethod<'_, N>,
    lighting: &ShRgb<N>,
    material: &Material<'_>,
    to_eye: Vec3,
) -> ShadedMask<N> {
    let frame = crate::Frame::from_normal(normal);
    // One SH rotation per vertex, applied to the one or two local vectors: cheaper
    // than rotating the three lighting channels into the local frame.
    let rotation = TransferRotation::new(&frame);
    let transfer = method.transfer(mask);
    let diffuse = shade_diffuse(&rotation.to_world(&transfer), lighting, material.albedo);
    let (glossy, parts) = match material.lobe {
        Some(lobe) if material.specular != Vec3::ZERO => {
            let mirror = frame.to_local(mirror_direction(normal, to_eye));
            let g = glossy_transfer(method.table(), mask, lobe, mirror);
            (
                shade_glossy(&rotation.to_world(&g), lighting, material.specular),
                Some((mirror, g)),
            )
        }
        _ => (Vec3::ZERO, None),
    };
    ShadedMask {
        shading: VertexShading { diffuse, glossy },
        rotation,
        transfer,
        glossy: parts,
    }
}

/// The unit direction towards the viewer of [`shade_batch_per_vertex`]'s
/// vertex at `position`.
#[inline]
pub(super) fn towards_eye(surface: &VertexSurface<'_>, position: Vec3) -> Vec3 {
    surface
        .to_eye
        .unwrap_or_else(|| unit_or_zero(surface.material.eye - position))
}

pub(super) fn check(
    scene: &HemiScene<'_>,
    normals: &[Vec3],
    out_len: usize,
) -> Result<(), BatchError> {
    let expected = scene.mesh.mesh.vertex_count();
    if normals.len() != expected {
        return Err(BatchError::NormalCount {
            expected,
            got: normals.len(),
        });
    }
    if out_len != expected {
        return Err(BatchError::OutputLength {
            expected,
            got: out_len,
        });
    }
    if scene.near_radius.is_nan() || scene.near_radius < 0.0 {
        return Err(BatchError::NearRadius);
    }
    Ok(())
}

/// `out[v] = f(v)` for every vertex, over rayon's pool when `parallel` is set
/// and the `parallel` feature is on.
#[inline]
fn for_each_vertex<T: Send>(out: &mut [T], parallel: bool, f: impl Fn(usize) -> T + Sync) {
    #[cfg(feature = "parallel")]
    if parallel {
        use rayon::prelude::*;
        out.par_iter_mut()
            .enumerate()
            .with_min_len(VERTEX_GRAIN)
            .for_each(|(v, o)| *o = f(v));
        return;
    }
    let _ = parallel;
    for (v, o) in out.iter_mut().enumerate() {
        *o = f(v);
    }
}

/// `f(k, &mut out[k])` for every entry, over rayon's pool when `parallel` is
/// set and the `parallel` feature is on (entries `f` leaves alone keep their
/// values).
#[inline]
pub(super) fn for_each_entry<T: Send>(
    out: &mut [T],
    parallel: bool,
    f: impl Fn(usize, &mut T) + Sync,
) {
    #[cfg(feature = "parallel")]
    if parallel {
        use rayon::prelude::*;
        out.par_iter_mut()
            .enumerate()
            .with_min_len(VERTEX_GRAIN)
            .for_each(|(k, o)| f(k, o));
        return;
    }
    let _ = parallel;
    for (k, o) in out.iter_mut().enumerate() {
        f(k, o);
    }
}

/// Vertices per rayon task: a receiver costs tens of microseconds, so a few
/// dozen amortise the scheduling.
#[cfg(feature = "parallel")]
const VERTEX_GRAIN: usize = 16;

/// Checks the arguments, then `out[v] = receiver(v, position, normal)` for every
/// vertex whose normal is usable and `zero` (a zero vector, black) for the rest.
fn for_each_receiver<T: Send + Copy + Sync>(
    scene: &HemiScene<'_>,
    normals: &[Vec3],
    options: &BatchOptions<'_>,
    out: &mut [T],
    zero: T,
    receiver: impl Fn(usize, Vec3, Vec3) -> T + Sync,
) -> Result<(), BatchError> {
    check(scene, normals, out.len())?;
    let mesh = scene.mesh.mesh;
    for_each_vertex(out, options.parallel, |v| {
        let n = normals[v];
        if usable(n) {
            receiver(v, mesh.position(v), n)
        } else {
            zero
        }
    });
    Ok(())
}

/// The masks of `out.len()` receivers against `scene`: receiver `k` at
/// `receiver(k)`, a position and a unit normal (the vertex the near/far rule
/// measures from, and the normal the center of projection is lifted along).
/// `out[k]` is the mask or anything made from it. Allocation-free; with
/// `options.parallel` (and the `parallel` feature), spread over rayon's pool
/// with identical results.
pub fn mask_batch<T: From<HemiMask> + Send>(
    scene: &HemiScene<'_>,
    receiver: impl Fn(usize) -> (Vec3, Vec3) + Sync,
    options: &BatchOptions<'_>,
    out: &mut [T],
) {
    for_each_vertex(out, options.parallel, |k| {
        let (position, normal) = receiver(k);
        T::from(scene_mask(scene, position, normal, options))
    });
}

/// Transfer vectors of every vertex of `scene.mesh`, each vertex a receiver with
/// its normal from `normals` (unit length; zero or non-finite normals give a zero
/// vector). `out[v]` in the requested `space`, as an [`Sh`] or as its bare
/// `[f32; N]` coefficients (a flat buffer seen through
/// `bytemuck::cast_slice_mut`).
///
/// Errors (nothing written): `normals` or `out` not one per vertex, a negative or
/// NaN `near_radius`. Allocation-free; safe to call from several threads; with
/// `options.parallel` (and the `parallel` feature), spread over rayon's pool
/// with identical results.
pub fn transfer_batch<const N: usize, T: From<Sh<N>> + Copy + Send + Sync>(
    scene: &HemiScene<'_>,
    normals: &[Vec3],
    options: &BatchOptions<'_>,
    method: TransferMethod<'_, N>,
    space: TransferSpace,
    out: &mut [T],
) -> Result<(), BatchError> {
    for_each_receiver(
        scene,
        normals,
        options,
        out,
        T::from(Sh::ZERO),
        |_, p, n| T::from(vertex_transfer(scene, p, n, options, method, space)),
    )
}

/// Outgoing radiance (diffuse + glossy, linear RGB) of every vertex of
/// `scene.mesh` under world-space SH `lighting`, each vertex a receiver with its
/// normal from `normals` (unit; zero or non-finite normals give black).
///
/// Errors, allocation and threading as [`transfer_batch`].
pub fn shade_batch<const N: usize>(
    scene: &HemiScene<'_>,
    normals: &[Vec3],
    options: &BatchOptions<'_>,
    method: TransferMethod<'_, N>,
    lighting: &ShRgb<N>,
    material: &Material<'_>,
    out: &mut [Vec3],
) -> Result<(), BatchError> {
    for_each_receiver(scene, normals, options, out, Vec3::ZERO, |_, p, n| {
        let s = shade_vertex(scene, p, n, options, method, lighting, material);
        s.diffuse + s.glossy
    })
}

/// [`shade_batch`] keeping the diffuse and glossy parts apart.
pub fn shade_batch_split<const N: usize>(
    scene: &HemiScene<'_>,
    normals: &[Vec3],
    options: &BatchOptions<'_>,
    method: TransferMethod<'_, N>,
    lighting: &ShRgb<N>,
    material: &Material<'_>,
    out: &mut [VertexShading],
) -> Result<(), BatchError> {
    let zero = VertexShading::default();
    for_each_receiver(scene, normals, options, out, zero, |_, p, n| {
        shade_vertex(scene, p, n, options, method, lighting, material)
    })
}

/// One vertex's surface and viewer for [`shade_batch_per_vertex`].
#[derive(Clone, Copy, Debug)]
pub struct VertexSurface<'a> {
    /// The vertex's material (its `eye` is read only without `to_eye`).
    pub material: Material<'a>,
    /// The unit direction from the vertex towards the viewer
    /// ([`shade_vertex_towards`]), or `None` for the direction to
    /// `material.eye` ([`shade_vertex`]).
    pub to_eye: Option<Vec3>,
}

/// [`shade_batch_split`] with a material and viewer per vertex, `surface(v)`
/// (per-vertex albedo, orthographic or per-vertex views).
///
/// Errors, allocation and threading as [`transfer_batch`].
pub fn shade_batch_per_vertex<'a, const N: usize>(
    scene: &HemiScene<'_>,
    normals: &[Vec3],
    options: &BatchOptions<'_>,
    method: TransferMethod<'_, N>,
    lighting: &ShRgb<N>,
    surface: impl Fn(usize) -> VertexSurface<'a> + Sync,
    out: &mut [VertexShading],
) -> Result<(), BatchError> {
    let zero = VertexShading::default();
    for_each_receiver(scene, normals, options, out, zero, |v, p, n| {
        let here = surface(v);
        let to_eye = towards_eye(&here, p);
        shade_vertex_towards(
            scene,
            p,
            n,
            options,
            method,
            lighting,
            &here.material,
            to_eye,
        )
    })
}

#[cfg(test)]
mod tests {
    use super::super::test_meshes::{bumpy_sphere, normals_of};
    use super::*;
    use crate::hemi::*;
    use crate::sh::{Sh, ShRgb};
    use alloc::vec;

    #[test]
    fn mask_batches_are_scene_masks_on_and_off_the_pool() {
        let (positions, indices) = bumpy_sphere(12, 18, 0.25, 0.5);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        let mut clusters = TriangleClusters::new(&mesh, 16);
        let clustered = clusters.update(mesh);
        for scene in [
            HemiScene::new(ClusteredMesh::unclustered(mesh)),
            HemiScene::new(clustered),
        ] {
            for parallel in [false, true] {
                let options = BatchOptions {
                    normal_offset: 0.01,
                    parallel,
                    ..BatchOptions::default()
                };
                let receiver = |k: usize| (mesh.position(k), normals[k]);
                let mut out = vec![HemiMask::VALID; mesh.vertex_count()];
                mask_batch(&scene, receiver, &options, &mut out);
                for (k, mask) in out.iter().enumerate() {
                    let (p, n) = receiver(k);
                    assert_eq!(*mask, scene_mask(&scene, p, n, &options), "receiver {k}");
                }
            }
        }
    }

    #[test]
    fn batches_match_single_vertices_and_check_their_arguments() {
        let (positions, indices) = bumpy_sphere(10, 16, 0.25, 0.3);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut normals = normals_of(&mesh);
        normals[3] = Vec3::ZERO;
        let table = TransferTable::<9>::new();
        let method = TransferMethod::Cells(&table);
        let scene = HemiScene::new(ClusteredMesh::unclustered(mesh));
        let options = BatchOptions {
            normal_offset: 0.01,
            ..BatchOptions::default()
        };
        let count = mesh.vertex_count();
        let mut transfers = vec![Sh::<9>::ZERO; count];
        transfer_batch(
            &scene,
            &normals,
            &options,
            method,
            TransferSpace::World,
            &mut transfers,
        )
        .unwrap();
        let mut light = ShRgb::<9>::ZERO;
        light.r[0] = 1.0;
        light.g[2] = 0.5;
        light.b[3] = -0.2;
        let lobe = PhongLobe::new(10.0).unwrap();
        let material = Material {
            albedo: Vec3::new(0.8, 0.6, 0.4),
            specular: Vec3::splat(0.2),
            lobe: Some(&lobe),
            eye: Vec3::new(0.0, -5.0, 2.0),
        };
        let mut rgb = vec![Vec3::ZERO; count];
        let mut split = vec![VertexShading::default(); count];
        shade_batch(
            &scene, &normals, &options, method, &light, &material, &mut rgb,
        )
        .unwrap();
        shade_batch_split(
            &scene, &normals, &options, method, &light, &material, &mut split,
        )
        .unwrap();
        // The other side of `parallel`, the bare-array output and per-vertex
        // surfaces give the same bits.
        let flipped = BatchOptions {
            parallel: !options.parallel,
            ..options
        };
        let mut arrays = vec![[f32::NAN; 9]; count];
        transfer_batch(
            &scene,
            &normals,
            &flipped,
            method,
            TransferSpace::World,
            &mut arrays,
        )
        .unwrap();
        assert!(arrays.iter().zip(&transfers).all(|(a, t)| *a == t.coeffs));
        let mut per_vertex = vec![VertexShading::default(); count];
        let surface = |v: usize| VertexSurface {
            material,
            to_eye: (v % 2 == 1).then(|| (material.eye - mesh.position(v)).normalize_or_zero()),
        };
        shade_batch_per_vertex(
            &scene,
            &normals,
            &flipped,
            method,
            &light,
            surface,
            &mut per_vertex,
        )
        .unwrap();
        for v in 0..count {
            let (p, n) = (mesh.position(v), normals[v]);
            if v != 3 && v % 2 == 1 {
                let to_eye = (material.eye - p).normalize_or_zero();
                let towards =
                    shade_vertex_towards(&scene, p, n, &options, method, &light, &material, to_eye);
                assert_eq!(per_vertex[v], towards);
                assert_eq!(towards, split[v]);
            } else {
                assert_eq!(per_vertex[v], split[v]);
            }
        }
        for v in 0..count {
            let (p, n) = (mesh.position(v), normals[v]);
            if v == 3 {
                assert_eq!(transfers[v], Sh::ZERO);
                assert_eq!(rgb[v], Vec3::ZERO);
                continue;
            }
            assert_eq!(
                transfers[v],
                vertex_transfer(&scene, p, n, &options, method, TransferSpace::World)
            );
            let s = shade_vertex(&scene, p, n, &options, method, &light, &material);
            assert_eq!(split[v], s);
            assert_eq!(rgb[v], s.diffuse + s.glossy);
            let expected = shade_diffuse(&transfers[v], &light, material.albedo);
            assert!((s.diffuse - expected).abs().max_element() < 1e-6);
        }
        assert!(split.iter().any(|s| s.glossy != Vec3::ZERO));
        // Argument checks; nothing written on error.
        let before = transfers.clone();
        assert_eq!(
            transfer_batch(
                &scene,
                &normals[1..],
                &options,
                method,
                TransferSpace::Local,
                &mut transfers
            ),
            Err(BatchError::NormalCount {
                expected: count,
                got: count - 1
            })
        );
        assert_eq!(
            transfer_batch(
                &scene,
                &normals,
                &options,
                method,
                TransferSpace::Local,
                &mut transfers[1..]
            ),
            Err(BatchError::OutputLength {
                expected: count,
                got: count - 1
            })
        );
        let far_scene = HemiScene::with_far(scene.mesh, scene.mesh, f32::NAN);
        assert_eq!(
            transfer_batch(
                &far_scene,
                &normals,
                &options,
                method,
                TransferSpace::Local,
                &mut transfers
            ),
            Err(BatchError::NearRadius)
        );
        assert_eq!(transfers, before);
        let mut short = vec![Vec3::ZERO; count - 1];
        assert!(vertex_normals(&mesh, &mut short).is_err());
    }

    #[test]
    fn vertex_normals_of_a_sphere_point_outwards() {
        let (positions, indices) = bumpy_sphere(12, 16, 0.25, 0.0);
        // The bumps tilt them, but they point outwards.
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        for (v, n) in normals.iter().enumerate() {
            let p = mesh.position(v);
            assert!((n.length() - 1.0).abs() < 1e-5);
            assert!(n.dot(p.normalize()) > 0.0, "vertex {v}");
        }
    }

    #[test]
    fn vertex_normals_of_huge_and_tiny_triangles_are_unit() {
        // The summed normal's squared length overflowed (1e10 edges: 1e40) or
        // underflowed (1e-13 edges: 1e-52) into a zero normal.
        let indices = [0u32, 1, 2];
        for scale in [1e10f32, 1e18, 1e-13, 1e-19] {
            let positions = [[0.0, 0.0, 0.0], [scale, 0.0, 0.0], [0.0, scale, 0.0]];
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let mut normals = [Vec3::ZERO; 3];
            vertex_normals(&mesh, &mut normals).unwrap();
            assert_eq!(normals, [Vec3::Z; 3], "edges of {scale}");
        }
        // Still zero where the sum is zero (a flat fan cancels).
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let mesh = MeshView::new(&positions, &[0, 1, 2, 0, 2, 1]).unwrap();
        let mut normals = [Vec3::ONE; 3];
        vertex_normals(&mesh, &mut normals).unwrap();
        assert_eq!(normals, [Vec3::ZERO; 3]);
    }

    #[test]
    fn a_far_eye_still_gets_the_glossy_term() {
        // (eye - position).length_squared() overflowed for an eye 1e20 away, so
        // the view direction was zero and the glossy term vanished.
        let (positions, indices) = bumpy_sphere(10, 16, 0.25, 0.3);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        let scene = HemiScene::new(ClusteredMesh::unclustered(mesh));
        let table = TransferTable::<9>::new();
        let method = TransferMethod::Cells(&table);
        let mut light = ShRgb::<9>::ZERO;
        light.r[0] = 1.0;
        light.g[2] = 0.5;
        light.b[3] = -0.2;
        let lobe = PhongLobe::new(10.0).unwrap();
        let v = 20;
        let (p, n) = (mesh.position(v), normals[v]);
        let direction = (n + Vec3::new(0.1, 0.2, 0.0)).normalize();
        let shade = |distance: f32| {
            let material = Material {
                albedo: Vec3::splat(0.5),
                specular: Vec3::splat(0.3),
                lobe: Some(&lobe),
                eye: p + distance * direction,
            };
            let options = BatchOptions::default();
            shade_vertex(&scene, p, n, &options, method, &light, &material).glossy
        };
        let near = shade(1e3);
        assert_ne!(near, Vec3::ZERO);
        for distance in [1e20f32, 1e30] {
            let far = shade(distance);
            assert!(
                (far - near).abs().max_element() < 1e-4 * near.abs().max_element(),
                "{distance}: {far} vs {near}"
            );
        }
    }
}
