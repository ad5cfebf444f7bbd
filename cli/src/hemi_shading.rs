//! Per-vertex shading of deforming meshes with the hemispherical rasterizer, as
//! `antumbra demo` and `antumbra bench hemi` use it: SH lighting from an
//! environment map, a far level of detail built once, a twist deformation applied
//! to both levels every frame, and the library's deforming-mesh shader (core's
//! `HemiShader`: normals, cluster boxes, far levels and the shading of every
//! vertex, posed from each frame's positions).
//!
//! Choices, shared by the demo and the benchmark:
//!
//! - [`COEFFICIENTS`] = 16 (4 bands) rather than 9. The glossy term needs band 3:
//!   the normalised Phong lobe of exponent 32 keeps 97 %, 91 % and 84 % of bands
//!   1, 2 and 3 (`antumbra_core::sh::phong_factor`), so 9 coefficients would cut it
//!   down to a quadratic, a far wider lobe than exponent 32. The shadowed transfer
//!   vectors carry band-3 content too (a crevice's horizon), which 9 coefficients
//!   would drop. The price is small: the 16-coefficient transfer, rotation and
//!   shading cost little next to the receiver's mask. (Side by side, the windowed
//!   diffuse pictures with 9 and 16 are hard to tell apart; the glossy highlights
//!   are tighter with 16.)
//! - The sky is windowed ([`hann_window`], 1, 0.90, 0.65, 0.35 per band). The
//!   sunrise's sun is thousands of times brighter than the sky, and its band-limited
//!   projection rings: unwindowed, the 16-coefficient radiance is negative in 53 %
//!   of directions, down to -1.9 (red) against 9.0 at the sun, and negative
//!   straight up, so glossy vertices reflecting the sky turned saturated blue.
//!   Windowed: -0.32 against 5.4, -0.22 against 5.0 after the Phong-32
//!   convolution, and the irradiance (clamped-cosine convolution) is positive
//!   everywhere. The cost is a broader sun, so softer sun shadows.
//! - Receivers are the vertices with their area-weighted normals, the center of
//!   projection lifted by [`OFFSET_OF_DIAGONAL`] of the bounding-box diagonal, as
//!   in `verify hemi`; no back-face culling (meshes need not be closed).
//! - The far mesh is the rest pose simplified by the library's vertex clustering
//!   ([`simplify`], core's `FarMesh`) with cells of [`FAR_CELL_OF_DIAGONAL`] = 1/30 of the
//!   diagonal; the near radius is [`NEAR_RADIUS_OF_DIAGONAL`] = 1/10 of it, three
//!   cells, so the coarse surface never stands in for the receiver's own
//!   neighbourhood. Coarser cells make a cheaper far mesh and a larger error. On
//!   the bunny (diffuse + glossy under the sunrise, exact masks, luminance
//!   relative to the mean) cells of 1/25 give 1,272 triangles and a mean
//!   difference from the full mesh of 0.42 % (p90 0.83 %); 1/40 gives 2,700
//!   triangles, 0.16 %. On the armadillo (52,000 triangles) 1/40 gives 3,106
//!   triangles, 0.80 % (p90 2 %). 1/30 sits between: 1,718 triangles for the
//!   bunny. Speed with and without the far mesh: `antumbra bench hemi`.
//! - Vertices move by a twist ([`Twist`]), a function of the rest position: the
//!   far mesh's vertices, each the mean rest position of the full vertices merged
//!   into it, are moved by the same function of their own rest positions, so both
//!   levels deform together with nothing else to keep per vertex.

use std::sync::OnceLock;
use std::time::{Duration, Instant};

use antumbra_core::MeshView;
use antumbra_core::hemi::{
    BatchOptions, FarField, FarFieldSetup, FarMesh, HalfSpaceTable, HemiShader, Material,
    PhongLobe, Quality, ReceiverLod, ShaderSetup, TransferMethod, TransferTable, VertexShading,
    VertexSurface,
};
use antumbra_core::sh::{EquirectMapping, Sh, ShRgb, ZonalKernel, project_equirect};
use glam::{Quat, Vec3};

use crate::bounds::Bounds;
use crate::envmap::EnvironmentMap;
use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;

/// SH coefficients of the lighting and transfer vectors (see the module docs).
pub const COEFFICIENTS: usize = 16;

/// Exponent of the glossy Phong lobe.
pub const PHONG_EXPONENT: f32 = 32.0;

/// Center of projection offset along the normal, as a fraction of the diagonal.
pub const OFFSET_OF_DIAGONAL: f32 = 1e-3;

/// Cell size of the far mesh's vertex clustering, as a fraction of the diagonal.
pub const FAR_CELL_OF_DIAGONAL: f32 = 1.0 / 30.0;

/// Near radius of the two-level scene, as a fraction of the diagonal.
pub const NEAR_RADIUS_OF_DIAGONAL: f32 = 0.1;

/// World-space SH coefficients of an environment map's radiance, windowed by
/// [`hann_window`] against ringing (see the module docs).
pub fn sky_lighting(env: &EnvironmentMap) -> Result<ShRgb<COEFFICIENTS>> {
    let image = env.image();
    let projected: ShRgb<COEFFICIENTS> = project_equirect(
        image.pixels(),
        image.width(),
        image.height(),
        &EquirectMapping::Y_UP,
    )
    .map_err(|e| Error::msg(format!("cannot project the environment map to SH: {e}")))?;
    let window = hann_window(Sh::<COEFFICIENTS>::BANDS);
    Ok(projected.convolved(&ZonalKernel::from_factors(&window)))
}

/// The Hann window for `bands` bands, reaching zero at band `bands + 1`:
/// `(1 + cos(π l / (bands + 1))) / 2` for band `l`, so 1, 0.90, 0.65, 0.35 for 4
/// bands (Sloan, "Stupid Spherical Harmonics Tricks", 2008, on windowing against
/// ringing).
pub fn hann_window(bands: usize) -> Vec<f32> {
    let width = (bands + 1) as f32;
    (0..bands)
        .map(|l| 0.5 * (1.0 + (std::f32::consts::PI * l as f32 / width).cos()))
        .collect()
}

/// The shared half-space table of table quality, built on first use.
pub fn half_space_table() -> &'static HalfSpaceTable {
    static TABLE: OnceLock<HalfSpaceTable> = OnceLock::new();
    TABLE.get_or_init(HalfSpaceTable::default)
}

/// What shading needs besides the mesh: the transfer table and the glossy lobe,
/// each built once.
pub struct Shader {
    table: TransferTable<COEFFICIENTS>,
    lobe: PhongLobe,
}

impl Shader {
    /// Builds the tables (milliseconds).
    pub fn new() -> Self {
        Shader {
            table: TransferTable::new(),
            lobe: PhongLobe::new(PHONG_EXPONENT).expect("a valid exponent"),
        }
    }

    /// The glossy lobe, for a [`Material`].
    pub fn lobe(&self) -> &PhongLobe {
        &self.lobe
    }

    /// The transfer table (per-cell SH integrals).
    pub fn table(&self) -> &TransferTable<COEFFICIENTS> {
        &self.table
    }

    /// Exact masks, or the half-space table ([`half_space_table`]).
    pub fn quality(&self, table: bool) -> Quality<'static> {
        if table {
            Quality::Table(half_space_table())
        } else {
            Quality::Exact
        }
    }
}

/// A twist about the vertical (+Y) axis through the centre of a box: a point at
/// height `y` turns by `angle · (y - bottom) / height`, so the bottom stays put
/// and the top turns by the full angle.
#[derive(Clone, Copy, Debug)]
pub struct Twist {
    center: Vec3,
    bottom: f32,
    height: f32,
}

impl Twist {
    /// The twist of a mesh with these rest bounds.
    pub fn of_bounds(bounds: &Bounds) -> Self {
        Twist {
            center: bounds.center(),
            bottom: bounds.min.y,
            height: bounds.size().y.max(f32::MIN_POSITIVE),
        }
    }

    /// Where the rest position `rest` goes when the top has turned by `angle`
    /// radians.
    pub fn apply(&self, rest: Vec3, angle: f32) -> Vec3 {
        let turn = angle * ((rest.y - self.bottom) / self.height).clamp(0.0, 1.0);
        if turn == 0.0 {
            return rest;
        }
        self.center + Quat::from_rotation_y(turn) * (rest - self.center)
    }
}

/// `mesh` simplified by the library's vertex clustering (core's `FarMesh`) with
/// cubes of edge `cell_size`, as a mesh of its own.
pub fn simplify(mesh: &TriangleMesh, cell_size: f32) -> Result<TriangleMesh> {
    let far = FarMesh::with_cell_size(&mesh.view(), cell_size).map_err(|e| {
        Error::msg(format!(
            "cannot simplify {} with cells of {cell_size}: {e}",
            mesh.name()
        ))
    })?;
    TriangleMesh::new(
        format!("{} (vertex clustering, cell {cell_size:.4})", mesh.name()),
        far.positions().to_vec(),
        far.indices().to_vec(),
    )
}

/// A mesh and its far level of detail, both in the rest pose, with the near
/// radius.
pub struct LodMesh {
    /// The full mesh (its vertices are the receivers).
    pub full: TriangleMesh,
    /// The far mesh.
    pub far: TriangleMesh,
    /// Cell size of the vertex clustering that made the far mesh.
    pub far_cell: f32,
    /// Near radius of the two-level scene, mesh units.
    pub near_radius: f32,
    /// Center of projection offset, mesh units.
    pub normal_offset: f32,
}

impl LodMesh {
    /// Builds the far mesh of `full` (see the module docs for the sizes).
    pub fn new(full: TriangleMesh) -> Result<Self> {
        full.require_extent()?;
        let diagonal = full.bounds().diagonal();
        let far_cell = FAR_CELL_OF_DIAGONAL * diagonal;
        let far = simplify(&full, far_cell)?;
        Ok(Self::with_far(full, far, far_cell, diagonal))
    }

    /// `full` with a far mesh made by the caller (for example the clustering of
    /// one object, with cubes of `far_cell`, plus a coarse version of the rest),
    /// sizing the near radius and the normal offset from `diagonal`, the main
    /// object's bounding-box diagonal.
    pub fn with_far(full: TriangleMesh, far: TriangleMesh, far_cell: f32, diagonal: f32) -> Self {
        LodMesh {
            full,
            far,
            far_cell,
            near_radius: NEAR_RADIUS_OF_DIAGONAL * diagonal,
            normal_offset: OFFSET_OF_DIAGONAL * diagonal,
        }
    }
}

/// Which occluders a [`Posed`] mesh's receivers see beyond their neighbourhood.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Occluders {
    /// The full mesh everywhere.
    Full,
    /// The full mesh near, the [`LodMesh`]'s far mesh beyond its near radius.
    FarMesh,
    /// The full mesh near, then the library's own far field of this many
    /// levels (core's `FarField`), its finest level about the far mesh's size
    /// and its radii the library's rule (three of the level's cube edges).
    FarLevels(usize),
}

/// The current pose of a [`LodMesh`] and the library's deforming-mesh shader
/// (core's `HemiShader`: clusters, far levels, normals and shading buffers,
/// posed from each frame's positions); the positions of both levels are kept
/// here, since the deformation is the caller's.
pub struct Posed<'m> {
    lod: &'m LodMesh,
    occluders: Occluders,
    positions: Vec<[f32; 3]>,
    far_positions: Vec<[f32; 3]>,
    shader: HemiShader,
}

/// What one frame cost.
#[derive(Clone, Copy, Debug)]
pub struct FrameTime {
    /// Deforming the mesh, then posing the shader: normals, cluster boxes,
    /// far levels.
    pub pose: Duration,
    /// Shading every vertex.
    pub shade: Duration,
    /// Receivers rasterized (all but those a sparse shader interpolated).
    pub rasterized: usize,
}

impl FrameTime {
    /// The whole frame.
    pub fn total(&self) -> Duration {
        self.pose + self.shade
    }
}

impl<'m> Posed<'m> {
    /// The rest pose; clusters are grouped once here, from the rest positions,
    /// and the far levels built when `occluders` asks for them.
    pub fn new(lod: &'m LodMesh, occluders: Occluders) -> Result<Self> {
        let far_field = match occluders {
            Occluders::FarLevels(levels) => Some(FarFieldSetup {
                triangles: lod.far.triangle_count(),
                levels,
            }),
            Occluders::Full | Occluders::FarMesh => None,
        };
        let far_view = lod.far.view();
        let setup = ShaderSetup {
            far_field,
            near_radius: match occluders {
                Occluders::FarLevels(_) => f32::INFINITY,
                Occluders::Full | Occluders::FarMesh => lod.near_radius,
            },
            shading: true,
            ..ShaderSetup::default()
        };
        let far = (occluders == Occluders::FarMesh).then_some(&far_view);
        let shader = HemiShader::new(&lod.full.view(), far, &setup).map_err(|e| {
            Error::msg(format!(
                "cannot make the shader of {}: {e}",
                lod.full.name()
            ))
        })?;
        Ok(Posed {
            lod,
            occluders,
            positions: lod.full.positions().to_vec(),
            // Posed only for the caller's far mesh.
            far_positions: match occluders {
                Occluders::FarMesh => lod.far.positions().to_vec(),
                Occluders::Full | Occluders::FarLevels(_) => Vec::new(),
            },
            shader,
        })
    }

    /// Shades only the keys of `receivers` and the vertices whose keys
    /// disagree, the rest from their keys' occlusion (`None`: every vertex;
    /// core's `HemiShader::set_receivers`, weights from the rest pose).
    pub fn set_receivers(&mut self, receivers: Option<ReceiverLod>) -> Result<()> {
        self.shader
            .set_receivers(&self.lod.full.view(), receivers)
            .map_err(|e| Error::msg(format!("{}: {e}", self.lod.full.name())))
    }

    /// Current positions of the full mesh.
    pub fn positions(&self) -> &[[f32; 3]] {
        &self.positions
    }

    /// The library's far levels, if this pose has them.
    pub fn far_field(&self) -> Option<&FarField> {
        self.shader.far_field()
    }

    /// Moves every vertex of both levels to `deform(rest position)`: the far
    /// mesh's vertices are deformed by the same function at their own rest
    /// positions (the library's far levels follow the full mesh by
    /// themselves).
    pub fn set_pose(&mut self, deform: impl Fn(Vec3) -> Vec3) {
        let pose = |rest: &[[f32; 3]], out: &mut [[f32; 3]]| {
            for (o, &p) in out.iter_mut().zip(rest) {
                *o = deform(Vec3::from(p)).to_array();
            }
        };
        pose(self.lod.full.positions(), &mut self.positions);
        if self.occluders == Occluders::FarMesh {
            pose(self.lod.far.positions(), &mut self.far_positions);
        }
    }

    /// Shades every vertex of the current pose into `out` (diffuse and glossy
    /// radiance, linear RGB) on rayon's current pool: the shader's frame
    /// (normals, cluster boxes and far levels from the positions), then its
    /// shading. Returns the time of each step.
    pub fn shade(
        &mut self,
        shader: &Shader,
        quality: Quality<'_>,
        lighting: &ShRgb<COEFFICIENTS>,
        material: &Material<'_>,
        out: &mut [VertexShading],
    ) -> Result<FrameTime> {
        let started = Instant::now();
        let lod = self.lod;
        let failed = |e: &dyn std::fmt::Display| {
            Error::msg(format!("shading {} failed: {e}", lod.full.name()))
        };
        let mesh = MeshView::new(&self.positions, lod.full.indices()).map_err(|e| failed(&e))?;
        let far = match self.occluders {
            Occluders::FarMesh => Some(
                MeshView::new(&self.far_positions, lod.far.indices()).map_err(|e| failed(&e))?,
            ),
            Occluders::Full | Occluders::FarLevels(_) => None,
        };
        let mut frame = self.shader.frame(mesh, None, far).map_err(|e| failed(&e))?;
        let posed = Instant::now();
        let options = BatchOptions {
            quality,
            normal_offset: lod.normal_offset,
            ..BatchOptions::default()
        };
        let surface = |_| VertexSurface {
            material: *material,
            to_eye: None,
        };
        let shading = frame
            .shade(
                &options,
                TransferMethod::Cells(shader.table()),
                lighting,
                surface,
            )
            .map_err(|e| failed(&e))?;
        out.copy_from_slice(shading);
        Ok(FrameTime {
            pose: posed - started,
            shade: posed.elapsed(),
            rasterized: frame.rasterized(),
        })
    }

    /// One frame: pose by `deform`, then [`Posed::shade`], timed.
    pub fn frame(
        &mut self,
        deform: impl Fn(Vec3) -> Vec3,
        shader: &Shader,
        quality: Quality<'_>,
        lighting: &ShRgb<COEFFICIENTS>,
        material: &Material<'_>,
        out: &mut [VertexShading],
    ) -> Result<FrameTime> {
        let started = Instant::now();
        self.set_pose(deform);
        let deformed = started.elapsed();
        let time = self.shade(shader, quality, lighting, material, out)?;
        Ok(FrameTime {
            pose: deformed + time.pose,
            ..time
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin;

    #[test]
    fn twist_keeps_the_bottom_and_turns_the_top() {
        let bounds = Bounds {
            min: Vec3::new(-1.0, 0.0, -1.0),
            max: Vec3::new(1.0, 2.0, 1.0),
        };
        let twist = Twist::of_bounds(&bounds);
        let angle = std::f32::consts::FRAC_PI_2;
        let bottom = twist.apply(Vec3::new(1.0, 0.0, 0.0), angle);
        assert!((bottom - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-6);
        // +X turns towards -Z by a positive rotation about +Y.
        let top = twist.apply(Vec3::new(1.0, 2.0, 0.0), angle);
        assert!((top - Vec3::new(0.0, 2.0, -1.0)).length() < 1e-6, "{top}");
        let middle = twist.apply(Vec3::new(0.0, 1.0, 0.0), angle);
        assert!((middle - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6);
    }

    #[test]
    fn a_shaded_frame_is_lit_and_the_far_mesh_changes_it_little() {
        let lod = LodMesh::new(builtin::bunny().unwrap()).unwrap();
        let shader = Shader::new();
        let mut lighting = ShRgb::<COEFFICIENTS>::ZERO;
        // Uniform white sky: radiance 1 everywhere.
        for channel in [&mut lighting.r, &mut lighting.g, &mut lighting.b] {
            channel[0] = 2.0 * std::f32::consts::PI.sqrt();
        }
        let material = Material {
            albedo: Vec3::ONE,
            specular: Vec3::ZERO,
            lobe: None,
            eye: Vec3::new(0.0, 0.0, 10.0),
        };
        let twist = Twist::of_bounds(&lod.full.bounds());
        let count = lod.full.vertex_count();
        let none = VertexShading::default();
        let (mut full, mut far) = (vec![none; count], vec![none; count]);
        for (out, occluders) in [(&mut full, Occluders::Full), (&mut far, Occluders::FarMesh)] {
            Posed::new(&lod, occluders)
                .unwrap()
                .frame(
                    |p| twist.apply(p, 0.5),
                    &shader,
                    Quality::Exact,
                    &lighting,
                    &material,
                    out,
                )
                .unwrap();
        }
        // Radiance under a white sky with albedo 1 is the unoccluded fraction of
        // the cosine-weighted hemisphere: in [0, 1], mostly close to 1.
        let mean = full.iter().map(|c| c.diffuse.x).sum::<f32>() / count as f32;
        assert!(
            full.iter()
                .all(|c| c.diffuse.x >= -1e-3 && c.diffuse.x <= 1.001 && c.glossy == Vec3::ZERO),
            "out of range"
        );
        assert!(mean > 0.7 && mean < 0.99, "mean visibility {mean}");
        let difference = full
            .iter()
            .zip(&far)
            .map(|(a, b)| (a.diffuse.x - b.diffuse.x).abs())
            .sum::<f32>()
            / count as f32;
        assert!(
            difference < 0.02,
            "far mesh changes the mean by {difference}"
        );
    }
}
