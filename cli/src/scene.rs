//! A renderable scene: one mesh, optionally standing on a procedural ground
//! plane, in a BVH, with smooth shading normals and a grey albedo per part.

use antumbra_core::raycast::BvhScene;
use antumbra_core::{Hit, MeshView, Ray, RayCaster};
use glam::Vec3;

use crate::bounds::Bounds;
use crate::error::{Context, Result};
use crate::mesh::TriangleMesh;

/// Diffuse reflectance of the object.
const OBJECT_ALBEDO: Vec3 = Vec3::new(0.80, 0.78, 0.74);
/// Diffuse reflectance of the ground plane.
const GROUND_ALBEDO: Vec3 = Vec3::splat(0.5);
/// Half the ground plane's side, in units of the object's bounding-box diagonal:
/// big enough that its edge is near the horizon in every framing.
const GROUND_HALF_SIZE: f32 = 100.0;

/// Geometry to trace rays against, with what shading needs at each hit.
pub struct Scene {
    /// Positions of the object followed by the ground's four corners.
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
    normals: Vec<Vec3>,
    object_triangles: usize,
    object_bounds: Bounds,
    bvh: BvhScene,
}

/// What a ray sees where it hits the scene.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    /// The hit point.
    pub position: Vec3,
    /// Unit normal of the triangle, turned towards the ray's origin.
    pub geometric_normal: Vec3,
    /// Unit interpolated vertex normal, on the same side as `geometric_normal`.
    pub shading_normal: Vec3,
    /// Diffuse reflectance.
    pub albedo: Vec3,
}

impl Scene {
    /// A scene of `mesh` alone, or on a large square ground plane at the bottom of
    /// its bounds (y = min y; the data is +Y up) when `ground` is true.
    pub fn new(mesh: &TriangleMesh, ground: bool) -> Result<Self> {
        let object_bounds = mesh.bounds();
        let mut positions = mesh.positions().to_vec();
        let mut indices = mesh.indices().to_vec();
        let mut normals = mesh.vertex_normals();
        if ground {
            let half = GROUND_HALF_SIZE * object_bounds.diagonal().max(f32::MIN_POSITIVE);
            let c = object_bounds.center();
            let y = object_bounds.min.y;
            let base = positions.len() as u32;
            positions.extend([
                [c.x - half, y, c.z - half],
                [c.x - half, y, c.z + half],
                [c.x + half, y, c.z + half],
                [c.x + half, y, c.z - half],
            ]);
            // Counter-clockwise seen from above, so the geometric normal is +Y.
            indices.extend([0, 1, 2, 0, 2, 3].map(|k| base + k));
            normals.extend([Vec3::Y; 4]);
        }
        let view = MeshView::new(&positions, &indices)
            .with_context(|| format!("{} with a ground plane is not a valid mesh", mesh.name()))?;
        let bvh = BvhScene::new(&view).with_context(|| {
            if ground {
                // The ground is 100 diagonals wide: a mesh within range can
                // put its corners out of range.
                format!(
                    "cannot build the ray-casting scene of {} with its ground plane (try \
                     --no-ground)",
                    mesh.name()
                )
            } else {
                format!("cannot build the ray-casting scene of {}", mesh.name())
            }
        })?;
        Ok(Scene {
            positions,
            indices,
            normals,
            object_triangles: mesh.triangle_count(),
            object_bounds,
            bvh,
        })
    }

    /// Bounds of the object (without the ground).
    pub fn object_bounds(&self) -> Bounds {
        self.object_bounds
    }

    /// A distance far below the object's detail and far above float rounding at
    /// its scale: the offset that keeps secondary rays off the surface they leave.
    pub fn ray_epsilon(&self) -> f32 {
        1e-4 * self.object_bounds.diagonal()
    }

    /// The ray caster over every triangle.
    pub fn caster(&self) -> &BvhScene {
        &self.bvh
    }

    /// Closest surface along `ray`, with its shading data.
    pub fn intersect(&self, ray: &Ray) -> Option<SurfacePoint> {
        let hit = self.bvh.closest_hit(ray)?;
        Some(self.surface(ray, &hit))
    }

    /// Whether anything blocks `ray`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.bvh.occluded(ray)
    }

    fn surface(&self, ray: &Ray, hit: &Hit) -> SurfacePoint {
        let triangle = hit.triangle as usize;
        let corners = [0, 1, 2].map(|k| self.indices[3 * triangle + k] as usize);
        let [a, b, c] = corners.map(|v| Vec3::from(self.positions[v]));
        let [na, nb, nc] = corners.map(|v| self.normals[v]);
        let weights = Vec3::new(1.0 - hit.u - hit.v, hit.u, hit.v);
        let position = weights.x * a + weights.y * b + weights.z * c;
        let mut geometric_normal = (b - a).cross(c - a).normalize_or_zero();
        // Triangles are two-sided: shade the side the ray arrived from.
        if geometric_normal.dot(ray.direction) > 0.0 {
            geometric_normal = -geometric_normal;
        }
        let mut shading_normal =
            (weights.x * na + weights.y * nb + weights.z * nc).normalize_or_zero();
        if shading_normal == Vec3::ZERO {
            shading_normal = geometric_normal;
        } else if shading_normal.dot(geometric_normal) < 0.0 {
            shading_normal = -shading_normal;
        }
        let albedo = if triangle < self.object_triangles {
            OBJECT_ALBEDO
        } else {
            GROUND_ALBEDO
        };
        SurfacePoint {
            position,
            geometric_normal,
            shading_normal,
            albedo,
        }
    }
}
