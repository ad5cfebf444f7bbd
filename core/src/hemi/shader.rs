//! A deforming mesh's shading from frame to frame, as one owned value: the
//! triangle clusters (grouped once, boxes updated per frame), the library's far
//! field or the clusters of a caller's far mesh, the per-vertex normals and
//! shading buffers, and the per-frame step that poses all of them from the
//! frame's positions before the batch functions run (Kautz, Lehtinen and Aila
//! 2004: no precomputation depends on the animation).
//!
//! The C library's `antumbra_hemi_shader_*` handle and its one-shot calls are this
//! type behind argument checks.

use alloc::vec::Vec;
use core::fmt;

use glam::Vec3;

use super::batch::{
    BatchError, TransferSpace, VertexShading, VertexSurface, shade_batch_per_vertex,
    transfer_batch, vertex_normals,
};
use super::clusters::{ClusteredMesh, TriangleClusters};
use super::far_field::{FarField, FarLevels};
use super::far_mesh::FarMeshError;
use super::lod::{BatchOptions, HemiScene};
use super::receivers::{ReceiverLod, ReceiverSampling, ReceiverSamplingError, SparseReceivers};
use super::transfer::TransferMethod;
use crate::fallible;
use crate::geom::MeshView;
use crate::sh::{Sh, ShRgb};

/// The library's own far field: the first level's triangles and the levels
/// ([`FarField::new`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FarFieldSetup {
    /// Triangles of the finest far mesh (at least 1, below the mesh's count).
    pub triangles: usize,
    /// Far meshes, 1 to [`MAX_FAR_LEVELS`](super::MAX_FAR_LEVELS) (clamped).
    pub levels: usize,
}

/// How a [`HemiShader`] is set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShaderSetup {
    /// Group the triangles into clusters (the same results; pays for itself
    /// from a few dozen receivers).
    pub clusters: bool,
    /// The library's own far field, made from the mesh at creation and posed
    /// from every frame; `None` for none (a caller may pass a far mesh instead).
    pub far_field: Option<FarFieldSetup>,
    /// The near radius (see [`HemiScene::near_radius`]). With the library's far
    /// field, `+inf` means its rule ([`FarField::near_radius`]) and a finite
    /// value sets its first level's, which must be at least
    /// [`FarField::min_near_radius`] (else [`FarMeshError::NearRadius`]).
    pub near_radius: f32,
    /// Keep a per-vertex shading buffer for [`ShaderFrame::shade`].
    pub shading: bool,
    /// Rasterize only some receivers in [`ShaderFrame::transfer`] and
    /// [`ShaderFrame::shade`] and interpolate the rest (see [`ReceiverLod`]);
    /// `None` rasterizes every vertex.
    pub receivers: Option<ReceiverLod>,
}

impl Default for ShaderSetup {
    /// Clusters, no far field, the full mesh everywhere, no shading buffer,
    /// every receiver rasterized.
    fn default() -> Self {
        ShaderSetup {
            clusters: true,
            far_field: None,
            near_radius: f32::INFINITY,
            shading: false,
            receivers: None,
        }
    }
}

/// Why a shader could not be made or could not run a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShaderError {
    /// The far field could not be made.
    FarField(FarMeshError),
    /// A far mesh was given together with a far field of the library's.
    FarMeshAndFarField,
    /// The receiver sampling could not be made.
    Receivers(ReceiverSamplingError),
    /// The frame's mesh has another vertex count than the shader's.
    VertexCount {
        /// The shader's.
        expected: usize,
        /// The frame's.
        got: usize,
    },
    /// The frame's normals are not one per vertex.
    NormalCount {
        /// The shader's vertices.
        expected: usize,
        /// Normals given.
        got: usize,
    },
    /// A buffer could not be allocated.
    OutOfMemory {
        /// What it was for.
        what: &'static str,
        /// Its size.
        bytes: usize,
    },
}

impl fmt::Display for ShaderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ShaderError::FarField(e) => write!(f, "{e}"),
            ShaderError::Receivers(e) => write!(f, "{e}"),
            ShaderError::FarMeshAndFarField => {
                write!(f, "a far mesh was given to a shader that makes its own")
            }
            ShaderError::VertexCount { expected, got } => write!(
                f,
                "the mesh has {got} vertices, but the shader was made for {expected}"
            ),
            ShaderError::NormalCount { expected, got } => {
                write!(f, "{got} normals given for a mesh of {expected} vertices")
            }
            ShaderError::OutOfMemory { what, bytes } => {
                write!(f, "no memory for {what} ({bytes} bytes)")
            }
        }
    }
}

impl core::error::Error for ShaderError {}

/// A deforming mesh's shader (see the module docs).
#[derive(Clone, Debug)]
pub struct HemiShader {
    normals: Vec<Vec3>,
    /// One entry per vertex when set up for shading, else empty.
    shading: Vec<VertexShading>,
    clusters: Option<TriangleClusters>,
    /// The clusters of a caller's far mesh.
    far_clusters: Option<TriangleClusters>,
    far_field: Option<FarField>,
    near_radius: f32,
    receivers: Option<SparseReceivers>,
}

/// One frame of a [`HemiShader`]: its meshes posed, its normals filled.
pub struct ShaderFrame<'a> {
    mesh: ClusteredMesh<'a>,
    far: Option<ClusteredMesh<'a>>,
    levels: Option<FarLevels<'a>>,
    near_radius: f32,
    normals: &'a [Vec3],
    shading: &'a mut [VertexShading],
    receivers: Option<&'a mut SparseReceivers>,
    rasterized: usize,
}

fn buffer<T: Clone>(count: usize, value: T, what: &'static str) -> Result<Vec<T>, ShaderError> {
    fallible::filled(value, count).map_err(|_| ShaderError::OutOfMemory {
        what,
        bytes: count.saturating_mul(core::mem::size_of::<T>()),
    })
}

impl HemiShader {
    /// A shader for `mesh` (its rest pose: clusters and the far field are made
    /// from it) and, if the caller will pass one, the rest pose of its far mesh.
    pub fn new(
        mesh: &MeshView<'_>,
        far: Option<&MeshView<'_>>,
        setup: &ShaderSetup,
    ) -> Result<Self, ShaderError> {
        let far_field = match setup.far_field {
            None => None,
            Some(_) if far.is_some() => return Err(ShaderError::FarMeshAndFarField),
            Some(FarFieldSetup { triangles, levels }) => {
                let mut field =
                    FarField::new(mesh, triangles, levels).map_err(ShaderError::FarField)?;
                // Anything but the rule's `+inf` (NaN included) is a radius
                // to check.
                if setup.near_radius != f32::INFINITY {
                    field
                        .set_near_radius(setup.near_radius)
                        .map_err(ShaderError::FarField)?;
                }
                Some(field)
            }
        };
        let near_radius = match &far_field {
            Some(field) => field.near_radius(0),
            None => setup.near_radius,
        };
        let count = mesh.vertex_count();
        let group = |m: &MeshView<'_>| TriangleClusters::new(m, TriangleClusters::DEFAULT_SIZE);
        Ok(HemiShader {
            normals: buffer(count, Vec3::ZERO, "the normals")?,
            shading: if setup.shading {
                buffer(count, VertexShading::default(), "the shading")?
            } else {
                Vec::new()
            },
            clusters: setup.clusters.then(|| group(mesh)),
            far_clusters: far.filter(|_| setup.clusters).map(group),
            far_field,
            near_radius,
            receivers: setup
                .receivers
                .map(|lod| sparse(mesh, lod, setup.shading))
                .transpose()?,
        })
    }

    /// The vertices of the mesh it was made for.
    pub fn vertex_count(&self) -> usize {
        self.normals.len()
    }

    /// The near radius in use (the far field's first level's with the library's
    /// far field).
    pub fn near_radius(&self) -> f32 {
        self.near_radius
    }

    /// Sets how [`ShaderFrame::transfer`] and [`ShaderFrame::shade`] spare
    /// receivers (`None`: every vertex rasterized), measuring the keys' weights in `mesh` (the rest
    /// pose, or any pose with the shader's topology). On error the old
    /// setting stays.
    pub fn set_receivers(
        &mut self,
        mesh: &MeshView<'_>,
        lod: Option<ReceiverLod>,
    ) -> Result<(), ShaderError> {
        self.check_vertices(mesh)?;
        let shading = !self.shading.is_empty();
        self.receivers = lod.map(|lod| sparse(mesh, lod, shading)).transpose()?;
        Ok(())
    }

    /// The receiver sampling in use, if receivers are spared.
    pub fn receiver_sampling(&self) -> Option<&ReceiverSampling> {
        self.receivers.as_ref().map(SparseReceivers::sampling)
    }

    /// The library's far field, if it makes one.
    pub fn far_field(&self) -> Option<&FarField> {
        self.far_field.as_ref()
    }

    /// Groups the clusters again from the current positions (for a mesh that
    /// has moved far from the pose they were grouped in; the same results).
    pub fn regroup(
        &mut self,
        mesh: &MeshView<'_>,
        far: Option<&MeshView<'_>>,
    ) -> Result<(), ShaderError> {
        self.check_vertices(mesh)?;
        if let Some(clusters) = self.clusters.as_mut() {
            clusters.reorder(mesh);
        }
        if let (Some(far), Some(clusters)) = (far, self.far_clusters.as_mut()) {
            clusters.reorder(far);
        }
        if let Some(field) = self.far_field.as_mut() {
            field.regroup(mesh).map_err(ShaderError::FarField)?;
        }
        Ok(())
    }

    fn check_vertices(&self, mesh: &MeshView<'_>) -> Result<(), ShaderError> {
        if mesh.vertex_count() != self.vertex_count() {
            return Err(ShaderError::VertexCount {
                expected: self.vertex_count(),
                got: mesh.vertex_count(),
            });
        }
        Ok(())
    }

    /// Poses everything from this frame's `mesh` (and the caller's `far` mesh,
    /// if any) and fills the normals from `normals` (unit or zero, one per
    /// vertex) or computes them ([`vertex_normals`]). Allocates nothing.
    pub fn frame<'a>(
        &'a mut self,
        mesh: MeshView<'a>,
        normals: Option<&[[f32; 3]]>,
        far: Option<MeshView<'a>>,
    ) -> Result<ShaderFrame<'a>, ShaderError> {
        self.check_vertices(&mesh)?;
        if far.is_some() && self.far_field.is_some() {
            return Err(ShaderError::FarMeshAndFarField);
        }
        let given = normals.map_or(self.vertex_count(), <[[f32; 3]]>::len);
        if given != self.vertex_count() {
            return Err(ShaderError::NormalCount {
                expected: self.vertex_count(),
                got: given,
            });
        }
        let HemiShader {
            normals: own_normals,
            shading,
            clusters,
            far_clusters,
            far_field,
            near_radius,
            receivers,
        } = self;
        let levels = match far_field.as_mut() {
            Some(field) => Some(field.pose(&mesh).map_err(ShaderError::FarField)?),
            None => None,
        };
        match normals {
            Some(given) => {
                for (n, g) in own_normals.iter_mut().zip(given) {
                    *n = Vec3::from_array(*g);
                }
            }
            None => vertex_normals(&mesh, own_normals).expect("one normal per vertex"),
        }
        let full = match clusters {
            Some(c) => c.update(mesh),
            None => ClusteredMesh::unclustered(mesh),
        };
        let far = match (far, far_clusters) {
            (Some(far), Some(c)) => Some(c.update(far)),
            (Some(far), None) => Some(ClusteredMesh::unclustered(far)),
            (None, _) => None,
        };
        Ok(ShaderFrame {
            mesh: full,
            far,
            levels,
            near_radius: *near_radius,
            normals: own_normals,
            shading,
            receivers: receivers.as_mut(),
            rasterized: 0,
        })
    }
}

impl ShaderFrame<'_> {
    /// The frame's scene: the full mesh, and the caller's far mesh or the
    /// library's far levels.
    pub fn scene(&self) -> HemiScene<'_> {
        scene(self.mesh, self.far, self.levels.as_ref(), self.near_radius)
    }

    /// The frame's vertex normals.
    pub fn normals(&self) -> &[Vec3] {
        self.normals
    }

    /// [`transfer_batch`] over every vertex of the frame, or, when the shader
    /// spares receivers ([`ShaderSetup::receivers`]), over its keys and the
    /// vertices whose keys disagree, the others interpolated. Returns how many
    /// receivers were rasterized. Allocation-free.
    pub fn transfer<const N: usize, T>(
        &mut self,
        options: &BatchOptions<'_>,
        method: TransferMethod<'_, N>,
        space: TransferSpace,
        out: &mut [T],
    ) -> Result<usize, BatchError>
    where
        T: From<Sh<N>> + Copy + Send + Sync,
        Sh<N>: From<T>,
    {
        let scene = scene(self.mesh, self.far, self.levels.as_ref(), self.near_radius);
        self.rasterized = match self.receivers.as_deref_mut() {
            Some(sparse) => sparse.transfer(&scene, self.normals, options, method, space, out)?,
            None => {
                transfer_batch(&scene, self.normals, options, method, space, out)?;
                out.len()
            }
        };
        Ok(self.rasterized)
    }

    /// [`shade_batch_per_vertex`] over every vertex of the frame, or, when the
    /// shader spares receivers, over its keys and the vertices whose keys
    /// disagree, the others shaded from their keys' occlusion (see
    /// [`ReceiverLod`]), into the shader's buffer (empty unless it was set up
    /// for shading, which is then an [`BatchError::OutputLength`]).
    /// [`ShaderFrame::rasterized`] then tells how many were rasterized.
    pub fn shade<'m, const N: usize>(
        &mut self,
        options: &BatchOptions<'_>,
        method: TransferMethod<'_, N>,
        lighting: &ShRgb<N>,
        surface: impl Fn(usize) -> VertexSurface<'m> + Sync,
    ) -> Result<&[VertexShading], BatchError> {
        let scene = scene(self.mesh, self.far, self.levels.as_ref(), self.near_radius);
        self.rasterized = match self.receivers.as_deref_mut() {
            Some(sparse) => sparse.shade(
                &scene,
                self.normals,
                options,
                method,
                lighting,
                surface,
                self.shading,
            )?,
            None => {
                shade_batch_per_vertex(
                    &scene,
                    self.normals,
                    options,
                    method,
                    lighting,
                    surface,
                    self.shading,
                )?;
                self.shading.len()
            }
        };
        Ok(self.shading)
    }

    /// How many receivers the last [`ShaderFrame::shade`] or
    /// [`ShaderFrame::transfer`] of this frame rasterized (0 before either).
    pub fn rasterized(&self) -> usize {
        self.rasterized
    }
}

fn sparse(
    mesh: &MeshView<'_>,
    lod: ReceiverLod,
    shading: bool,
) -> Result<SparseReceivers, ShaderError> {
    SparseReceivers::new(mesh, lod, shading).map_err(ShaderError::Receivers)
}

/// The scene of a frame's meshes: the library's far levels when there are,
/// else the caller's far mesh (or none).
fn scene<'s>(
    mesh: ClusteredMesh<'s>,
    far: Option<ClusteredMesh<'s>>,
    levels: Option<&'s FarLevels<'_>>,
    near_radius: f32,
) -> HemiScene<'s> {
    match levels {
        Some(levels) => levels.scene(mesh),
        None => HemiScene {
            mesh,
            far,
            near_radius,
            coarser: &[],
        },
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_meshes::bumpy_sphere;
    use super::*;
    use crate::hemi::{Material, PhongLobe, TransferTable, shade_vertex};
    use alloc::vec;

    fn options() -> BatchOptions<'static> {
        BatchOptions {
            normal_offset: 0.005,
            ..BatchOptions::default()
        }
    }

    #[test]
    fn frames_are_the_batches_on_the_scene_built_by_hand() {
        let (rest, indices) = bumpy_sphere(24, 36, 0.2, 0.0);
        let rest_mesh = MeshView::new(&rest, &indices).unwrap();
        let (far_rest, far_indices) = bumpy_sphere(8, 12, 0.2, 0.0);
        let far_rest_mesh = MeshView::new(&far_rest, &far_indices).unwrap();
        let table = TransferTable::<9>::new();
        let method = TransferMethod::Cells(&table);
        let own = ShaderSetup {
            far_field: Some(FarFieldSetup {
                triangles: 300,
                levels: 3,
            }),
            near_radius: 0.7,
            shading: true,
            ..ShaderSetup::default()
        };
        let callers = ShaderSetup {
            near_radius: 0.6,
            ..ShaderSetup::default()
        };
        let mut with_field = HemiShader::new(&rest_mesh, None, &own).unwrap();
        let mut plain = HemiShader::new(
            &rest_mesh,
            None,
            &ShaderSetup {
                clusters: false,
                ..own
            },
        )
        .unwrap();
        let mut with_far = HemiShader::new(&rest_mesh, Some(&far_rest_mesh), &callers).unwrap();
        let mut field = FarField::new(&rest_mesh, 300, 3).unwrap();
        field.set_near_radius(0.7).unwrap();
        assert_eq!(with_field.near_radius(), 0.7);
        let lobe = PhongLobe::new(8.0).unwrap();
        let material = Material {
            albedo: Vec3::splat(0.7),
            specular: Vec3::splat(0.3),
            lobe: Some(&lobe),
            eye: Vec3::new(0.0, -4.0, 1.0),
        };
        let mut light = ShRgb::<9>::ZERO;
        light.r[0] = 1.0;
        light.g[2] = 0.4;
        for twist in [0.0f32, 0.8] {
            let (positions, _) = bumpy_sphere(24, 36, 0.2, twist);
            let (far_positions, _) = bumpy_sphere(8, 12, 0.2, twist);
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let far = MeshView::new(&far_positions, &far_indices).unwrap();
            let mut normals = vec![Vec3::ZERO; mesh.vertex_count()];
            vertex_normals(&mesh, &mut normals).unwrap();
            let levels = field.pose(&mesh).unwrap();
            let by_hand = levels.scene(ClusteredMesh::unclustered(mesh));
            let callers_scene = HemiScene::with_far(
                ClusteredMesh::unclustered(mesh),
                ClusteredMesh::unclustered(far),
                0.6,
            );
            for (shader, scene, far) in [
                (&mut with_field, by_hand, None),
                (&mut plain, by_hand, None),
                (&mut with_far, callers_scene, Some(far)),
            ] {
                let mut want = vec![Sh::<9>::ZERO; mesh.vertex_count()];
                transfer_batch(
                    &scene,
                    &normals,
                    &options(),
                    method,
                    TransferSpace::World,
                    &mut want,
                )
                .unwrap();
                let mut frame = shader.frame(mesh, None, far).unwrap();
                assert_eq!(frame.normals(), &normals[..]);
                let mut got = vec![Sh::<9>::ZERO; mesh.vertex_count()];
                frame
                    .transfer(&options(), method, TransferSpace::World, &mut got)
                    .unwrap();
                assert_eq!(got, want, "twist {twist}");
                let surface = |_| VertexSurface {
                    material,
                    to_eye: None,
                };
                match frame.shade(&options(), method, &light, surface) {
                    Ok(shaded) => {
                        for (v, s) in shaded.iter().enumerate().step_by(7) {
                            let (p, n) = (mesh.position(v), normals[v]);
                            assert_eq!(
                                *s,
                                shade_vertex(&scene, p, n, &options(), method, &light, &material)
                            );
                        }
                    }
                    // Set up without a shading buffer.
                    Err(e) => assert!(matches!(e, BatchError::OutputLength { got: 0, .. })),
                }
            }
        }
    }

    #[test]
    fn shaders_refuse_what_does_not_fit() {
        let (positions, indices) = bumpy_sphere(8, 12, 0.2, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let (other, other_indices) = bumpy_sphere(6, 12, 0.2, 0.0);
        let other_mesh = MeshView::new(&other, &other_indices).unwrap();
        let own = ShaderSetup {
            far_field: Some(FarFieldSetup {
                triangles: 40,
                levels: 2,
            }),
            ..ShaderSetup::default()
        };
        assert_eq!(
            HemiShader::new(&mesh, Some(&mesh), &own).unwrap_err(),
            ShaderError::FarMeshAndFarField
        );
        let too_many = ShaderSetup {
            far_field: Some(FarFieldSetup {
                triangles: 5000,
                levels: 1,
            }),
            ..ShaderSetup::default()
        };
        assert!(matches!(
            HemiShader::new(&mesh, None, &too_many),
            Err(ShaderError::FarField(FarMeshError::TriangleCount { .. }))
        ));
        let mut shader = HemiShader::new(&mesh, None, &own).unwrap();
        assert!(matches!(
            shader.frame(other_mesh, None, None),
            Err(ShaderError::VertexCount { .. })
        ));
        assert!(matches!(
            shader.frame(mesh, Some(&[[0.0, 0.0, 1.0]]), None),
            Err(ShaderError::NormalCount { got: 1, .. })
        ));
        assert!(matches!(
            shader.frame(mesh, None, Some(mesh)),
            Err(ShaderError::FarMeshAndFarField)
        ));
        assert!(shader.regroup(&other_mesh, None).is_err());
        assert!(shader.regroup(&mesh, None).is_ok());
    }
}
