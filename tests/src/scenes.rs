//! Procedural scenes and ray sets for cross-checks.

use antumbra_core::Ray;
use glam::Vec3;
use rand::{Rng, rngs::SmallRng};

use crate::data::Mesh;

/// `triangles` random triangles of edge length up to about `size` inside the cube
/// `[-1, 1]^3`: many intersecting, overlapping and sliver triangles.
pub fn triangle_soup(rng: &mut SmallRng, triangles: usize, size: f32) -> Mesh {
    let mut mesh = Mesh::default();
    for t in 0..triangles {
        let center = random_in_cube(rng, 1.0);
        for _ in 0..3 {
            let corner = center + random_in_cube(rng, size * 0.5);
            mesh.positions.push(corner.to_array());
        }
        let base = 3 * t as u32;
        mesh.indices.extend_from_slice(&[base, base + 1, base + 2]);
    }
    mesh
}

/// A point uniformly inside `[-half, half]^3`.
pub fn random_in_cube(rng: &mut SmallRng, half: f32) -> Vec3 {
    Vec3::new(
        rng.random_range(-half..half),
        rng.random_range(-half..half),
        rng.random_range(-half..half),
    )
}

/// A uniformly distributed unit vector.
pub fn random_unit(rng: &mut SmallRng) -> Vec3 {
    loop {
        let v = random_in_cube(rng, 1.0);
        let l2 = v.length_squared();
        if l2 > 1e-4 && l2 <= 1.0 {
            return v / l2.sqrt();
        }
    }
}

/// A mix of the rays the algorithms cast, for a mesh with the given bounds:
/// - from outside the bounds toward random points inside (camera-like, unbounded);
/// - from random points on triangles, offset along the normal, in random directions
///   with a finite length (ambient-occlusion-like, the common query);
/// - segments that end anywhere from well before to past their target.
///
/// Directions have random lengths: `t` is in units of the direction.
pub fn mixed_rays(rng: &mut SmallRng, mesh: &Mesh, count: usize) -> Vec<Ray> {
    rays_of_kinds(rng, mesh, count, &[0, 1, 3])
}

/// Rays aimed exactly at vertices and edge midpoints from outside the bounds: the
/// adversarial cases where rounding decides which triangle, if any, is hit (a
/// silhouette vertex touched from outside may count either way).
pub fn vertex_and_edge_rays(rng: &mut SmallRng, mesh: &Mesh, count: usize) -> Vec<Ray> {
    rays_of_kinds(rng, mesh, count, &[2])
}

fn rays_of_kinds(rng: &mut SmallRng, mesh: &Mesh, count: usize, kinds: &[usize]) -> Vec<Ray> {
    let (lo, hi) = mesh.bounds();
    let center = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    let view = mesh.view();
    let mut rays = Vec::with_capacity(count);
    while rays.len() < count {
        let scale = rng.random_range(0.5..3.0);
        let ray = match kinds[rays.len() % kinds.len()] {
            0 => {
                let origin = center + random_unit(rng) * radius * rng.random_range(1.2..3.0);
                let target = center + random_in_cube(rng, 1.0) * (hi - lo) * 0.5;
                Ray::new(origin, (target - origin) * scale, f32::INFINITY)
            }
            1 => {
                let t = rng.random_range(0..view.triangle_count());
                let [a, b, c] = view.triangle(t);
                let (u, v) = (rng.random::<f32>(), rng.random::<f32>());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let point = a + (b - a) * u + (c - a) * v;
                let normal = (b - a).cross(c - a).normalize_or_zero();
                let mut dir = random_unit(rng);
                if dir.dot(normal) < 0.0 {
                    dir = -dir;
                }
                let origin = point + normal * radius * 1e-3;
                Ray::new(
                    origin,
                    dir * scale,
                    radius * rng.random_range(0.05..2.0) / scale,
                )
            }
            2 => {
                let t = rng.random_range(0..view.triangle_count());
                let [a, b, c] = view.triangle(t);
                let target = match rng.random_range(0..4) {
                    0 => a,
                    1 => (a + b) * 0.5,
                    2 => (b + c) * 0.5,
                    _ => (c + a) * 0.5,
                };
                let origin = center + random_unit(rng) * radius * rng.random_range(1.2..3.0);
                Ray::new(origin, (target - origin) * scale, f32::INFINITY)
            }
            _ => {
                let origin = center + random_unit(rng) * radius * rng.random_range(1.2..3.0);
                let target = center + random_in_cube(rng, 1.0) * (hi - lo) * 0.5;
                let dir = target - origin;
                // Segments that stop anywhere from well before to past the target.
                Ray::new(origin, dir * scale, rng.random_range(0.3..1.2) / scale)
            }
        };
        rays.push(ray);
    }
    rays
}

/// Where the quad light of a [`FloorScene`] hangs: it always faces the mesh from
/// 1.8 units away, turned about the x axis by this angle from straight above.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightOrientation {
    /// Straight above the mesh, horizontal.
    Horizontal,
    /// 45° from the vertical, tilted.
    Tilted,
    /// 80° from the vertical: low, to the side, almost vertical (the floor
    /// crosses the light's plane outside the light).
    Side,
}

impl LightOrientation {
    /// Every orientation, in order.
    pub const ALL: [LightOrientation; 3] = [
        LightOrientation::Horizontal,
        LightOrientation::Tilted,
        LightOrientation::Side,
    ];

    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            LightOrientation::Horizontal => "horizontal",
            LightOrientation::Tilted => "tilted 45°",
            LightOrientation::Side => "side 80°",
        }
    }

    /// Angle of the light's direction (seen from the mesh) from +Y, in degrees.
    pub fn degrees(self) -> f64 {
        match self {
            LightOrientation::Horizontal => 0.0,
            LightOrientation::Tilted => 45.0,
            LightOrientation::Side => 80.0,
        }
    }
}

/// Gap between the floor and the bottom of the mesh in a [`FloorScene`].
pub const FLOOR_GAP: f32 = 0.05;
/// Half the side of the floor square (`y = 0`, centred on the origin).
pub const FLOOR_HALF_SIDE: f32 = 2.0;
/// Half the side of the quad light.
pub const LIGHT_HALF_SIDE: f32 = 0.25;
/// Distance from the aim point (`(0, 0.5, 0)`) to the light's centre.
pub const LIGHT_DISTANCE: f64 = 1.8;
/// How far mesh receivers are lifted off the surface along the area-weighted
/// vertex normal (the mesh's largest extent is 1).
pub const MESH_RECEIVER_OFFSET: f32 = 1e-3;

/// The soft-shadow cross-check scene shared by the Embree test, `antumbra verify
/// ssv` and `antumbra bench ssv`: a mesh scaled to a largest extent of 1, centred
/// over the origin with its bottom [`FLOOR_GAP`] above a floor square at `y = 0`
/// (two triangles, the last of the occluders), under a square quad light.
///
/// Receivers: a grid on the floor, exactly at `y = 0` (the floor's own triangles
/// contain them and so do not occlude them), and mesh vertices spread evenly over
/// the vertex order, lifted by [`MESH_RECEIVER_OFFSET`] along their area-weighted
/// normals (vertices whose normals cancel are skipped). Visibility of a receiver
/// `p` for a sample `s`: no occluder triangle meets the open segment `p → s`.
#[derive(Clone, Debug)]
pub struct FloorScene {
    /// The normalised mesh followed by the two floor triangles.
    pub occluders: Mesh,
    /// Triangles of the mesh (the floor's two come after them).
    pub mesh_triangles: usize,
    /// The light's four corners, in order around the quad.
    pub light: [Vec3; 4],
    /// Receivers on the floor.
    pub floor_receivers: Vec<Vec3>,
    /// Receivers just off the mesh.
    pub mesh_receivers: Vec<Vec3>,
}

impl FloorScene {
    /// Builds the scene from a mesh, with a `floor_grid × floor_grid` grid of floor
    /// receivers over `[-1.5, 1.5]²` and up to `mesh_points` mesh receivers.
    pub fn new(
        positions: &[[f32; 3]],
        indices: &[u32],
        orientation: LightOrientation,
        floor_grid: usize,
        mesh_points: usize,
    ) -> FloorScene {
        let mut occluders = normalised_over_floor(positions, indices);
        let mesh_triangles = indices.len() / 3;
        let mesh_receivers = receivers_on_mesh(&occluders, mesh_points);
        let vertices = occluders.positions.len();
        let base = vertices as u32;
        let h = FLOOR_HALF_SIDE;
        occluders
            .positions
            .extend([[-h, 0.0, -h], [h, 0.0, -h], [h, 0.0, h], [-h, 0.0, h]]);
        occluders
            .indices
            .extend([base, base + 2, base + 1, base, base + 3, base + 2]);
        let n = floor_grid.max(1);
        let floor_receivers = (0..n * n)
            .map(|k| {
                let at = |i: usize| {
                    if n == 1 {
                        0.0
                    } else {
                        -1.5 + 3.0 * i as f32 / (n - 1) as f32
                    }
                };
                Vec3::new(at(k % n), 0.0, at(k / n))
            })
            .collect();
        let light = quad_light(orientation, LIGHT_DISTANCE, f64::from(LIGHT_HALF_SIDE));
        FloorScene {
            occluders,
            mesh_triangles,
            light,
            floor_receivers,
            mesh_receivers,
        }
    }

    /// Every receiver: the floor's, then the mesh's.
    pub fn receivers(&self) -> Vec<Vec3> {
        self.floor_receivers
            .iter()
            .chain(&self.mesh_receivers)
            .copied()
            .collect()
    }
}

/// Area-weighted vertex normals (the normalised sum of the incident triangles'
/// unnormalised normals); `None` where they cancel out.
pub fn area_weighted_normals(mesh: &Mesh) -> Vec<Option<Vec3>> {
    let mut sums = vec![glam::DVec3::ZERO; mesh.positions.len()];
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(mesh.positions[t[k] as usize]).as_dvec3());
        let n = (b - a).cross(c - a);
        for &v in t {
            sums[v as usize] += n;
        }
    }
    sums.into_iter()
        .map(|s| {
            let n = s.normalize_or_zero();
            (n != glam::DVec3::ZERO).then(|| n.as_vec3())
        })
        .collect()
}

/// Side of a [`GroundScene`]'s quad light as a fraction of the mesh's largest
/// extent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightSize {
    /// A quarter of the extent: sharp shadows, narrow penumbrae.
    Small,
    /// Four fifths of the extent: wide penumbrae, many silhouettes per receiver.
    Large,
}

impl LightSize {
    /// Both sizes, small first.
    pub const ALL: [LightSize; 2] = [LightSize::Small, LightSize::Large];

    /// The side over the mesh's largest extent.
    pub fn fraction(self) -> f64 {
        match self {
            LightSize::Small => 0.25,
            LightSize::Large => 0.8,
        }
    }

    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            LightSize::Small => "1/4",
            LightSize::Large => "4/5",
        }
    }
}

/// Distance from a [`GroundScene`]'s aim point (`(0, 0.5, 0)`) to its light's
/// centre, in mesh extents.
pub const GROUND_LIGHT_DISTANCE: f64 = 2.5;
/// Half the side of a [`GroundScene`]'s square of ground receivers, in mesh
/// extents.
pub const GROUND_HALF_SIDE: f32 = 1.5;

/// A frame as a user lays it out: the mesh scaled to a largest extent of 1,
/// centred over the origin with its bottom [`FLOOR_GAP`] above the ground `y =
/// 0`, and a square quad light [`GROUND_LIGHT_DISTANCE`] from the mesh's centre
/// in one of the [`LightOrientation`]s. Unlike [`FloorScene`] the ground is not
/// an occluder: it is only where the receivers are (a W × W grid over
/// `[-GROUND_HALF_SIDE, GROUND_HALF_SIDE]²`, reaching well beyond the mesh and
/// the light), so a structure fitted to the occluders and the light does not
/// cover it. Receivers on the mesh as in [`FloorScene`].
#[derive(Clone, Debug)]
pub struct GroundScene {
    /// The normalised mesh (the only occluders).
    pub occluders: Mesh,
    /// The light's four corners, in order around the quad.
    pub light: [Vec3; 4],
    /// Receivers on the ground.
    pub ground_receivers: Vec<Vec3>,
    /// Receivers just off the mesh.
    pub mesh_receivers: Vec<Vec3>,
}

impl GroundScene {
    /// Builds the scene with a `ground_grid × ground_grid` grid of ground
    /// receivers and up to `mesh_points` mesh receivers.
    pub fn new(
        positions: &[[f32; 3]],
        indices: &[u32],
        orientation: LightOrientation,
        size: LightSize,
        ground_grid: usize,
        mesh_points: usize,
    ) -> GroundScene {
        let occluders = normalised_over_floor(positions, indices);
        let mesh_receivers = receivers_on_mesh(&occluders, mesh_points);
        let n = ground_grid.max(1);
        let h = GROUND_HALF_SIDE;
        let at = |i: usize| {
            if n == 1 {
                0.0
            } else {
                -h + 2.0 * h * i as f32 / (n - 1) as f32
            }
        };
        let ground_receivers = (0..n * n)
            .map(|k| Vec3::new(at(k % n), 0.0, at(k / n)))
            .collect();
        let light = quad_light(orientation, GROUND_LIGHT_DISTANCE, 0.5 * size.fraction());
        GroundScene {
            occluders,
            light,
            ground_receivers,
            mesh_receivers,
        }
    }

    /// Every receiver: the ground's, then the mesh's.
    pub fn receivers(&self) -> Vec<Vec3> {
        self.ground_receivers
            .iter()
            .chain(&self.mesh_receivers)
            .copied()
            .collect()
    }
}

/// The mesh scaled to a largest extent of 1, centred over the origin in x and
/// z, its bottom [`FLOOR_GAP`] above `y = 0`.
fn normalised_over_floor(positions: &[[f32; 3]], indices: &[u32]) -> Mesh {
    let (lo, hi) = positions.iter().fold(
        (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY),
        |(lo, hi), p| {
            let p = Vec3::from(*p).as_dvec3();
            (lo.min(p), hi.max(p))
        },
    );
    let scale = 1.0 / (hi - lo).max_element().max(1e-30);
    let shift = glam::DVec3::new(
        -(lo.x + hi.x) * 0.5,
        -lo.y + f64::from(FLOOR_GAP) / scale,
        -(lo.z + hi.z) * 0.5,
    );
    Mesh {
        positions: positions
            .iter()
            .map(|p| {
                ((Vec3::from(*p).as_dvec3() + shift) * scale)
                    .as_vec3()
                    .to_array()
            })
            .collect(),
        indices: indices.to_vec(),
    }
}

/// Up to `count` vertices spread evenly over the vertex order, lifted by
/// [`MESH_RECEIVER_OFFSET`] along their area-weighted normals (vertices whose
/// normals cancel are skipped).
fn receivers_on_mesh(mesh: &Mesh, count: usize) -> Vec<Vec3> {
    let normals = area_weighted_normals(mesh);
    let vertices = mesh.positions.len();
    let step = (vertices as f64 / count.max(1) as f64).max(1.0);
    (0..count.min(vertices))
        .map(|k| (k as f64 * step) as usize)
        .filter_map(|v| {
            normals[v].map(|n| Vec3::from(mesh.positions[v]) + n * MESH_RECEIVER_OFFSET)
        })
        .collect()
}

/// A square light of half side `half_side` facing the aim point `(0, 0.5, 0)`
/// from `distance` away in `orientation` (turned about the x axis).
fn quad_light(orientation: LightOrientation, distance: f64, half_side: f64) -> [Vec3; 4] {
    let angle = orientation.degrees().to_radians();
    let toward = glam::DVec3::new(0.0, angle.cos(), angle.sin());
    let centre = glam::DVec3::new(0.0, 0.5, 0.0) + toward * distance;
    let u = glam::DVec3::X * half_side;
    let v = glam::DVec3::new(0.0, -angle.sin(), angle.cos()) * half_side;
    [
        centre - u - v,
        centre + u - v,
        centre + u + v,
        centre - u + v,
    ]
    .map(|c| c.as_vec3())
}
