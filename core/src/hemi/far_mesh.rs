//! The far mesh of the two-level scene: a simplification of the full mesh by vertex
//! clustering (Rossignac and Borrel 1993) that follows the full mesh's pose.
//!
//! Space is cut into cubes of a chosen edge, aligned with the bounding box of the
//! vertices that triangles use; each occupied cube becomes one far vertex, and a
//! triangle survives when its corners fall in three different cubes, it repeats no
//! earlier survivor (the same three cubes in any order, which also drops the second
//! of two opposite-facing copies) and its area in the rest pose is not negligible.
//! Each far vertex is the mean of the full vertices in its cube, in whatever pose
//! they are: [`FarMesh::pose`] recomputes every far vertex from the full mesh's
//! current positions, so a skinned or otherwise deforming mesh needs nothing but
//! its own positions each frame.
//!
//! Clustering ignores topology (parts thinner than a cube collapse, parts within a
//! cube merge), which is acceptable for occluders beyond the near radius, all the
//! far mesh stands for. A mean lies in the convex hull of its points, so the far
//! mesh stays within the full mesh's bounds in every pose.
//!
//! [`FarMesh::with_triangles`] searches the cube edge whose far mesh has about the
//! requested number of triangles. The error per triangle is that of vertex
//! clustering: larger than a quadric-error simplifier's at the same count, spread
//! evenly over the mesh instead of kept where the shape is flat.

use alloc::vec;
use alloc::vec::Vec;
use core::fmt;

use glam::{DVec3, Vec3};

use crate::geom::{MeshView, length_f64};

/// Why a far mesh could not be made or posed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FarMeshError {
    /// The cube edge is not a positive finite number, or is finer than
    /// [`FarMesh::MIN_CELL_OF_EXTENT`] of the mesh's extent.
    CellSize(f32),
    /// The requested triangle count is 0 or not below the mesh's own.
    TriangleCount {
        /// The count asked for.
        requested: usize,
        /// The full mesh's triangles.
        available: usize,
    },
    /// No triangle survived (cubes as large as the mesh, or a mesh of
    /// degenerate triangles only).
    Empty,
    /// A near radius below [`FarMesh::MIN_NEAR_CELLS`] cube edges (or not a
    /// finite number) was asked of a far field.
    NearRadius {
        /// The radius asked for.
        radius: f32,
        /// The least radius the far field's cubes allow.
        minimum: f32,
    },
    /// [`FarMesh::pose`] was given a mesh with another vertex count.
    VertexCount {
        /// The vertex count of the mesh the far mesh was made from.
        expected: usize,
        /// The vertex count given.
        got: usize,
    },
}

impl fmt::Display for FarMeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            FarMeshError::CellSize(size) => write!(
                f,
                "the cell size {size} is not positive and finite, or finer than {} of the \
                 mesh's extent",
                FarMesh::MIN_CELL_OF_EXTENT
            ),
            FarMeshError::TriangleCount {
                requested,
                available,
            } => write!(
                f,
                "{requested} far triangles requested: must be at least 1 and below the \
                 mesh's {available}"
            ),
            FarMeshError::Empty => write!(f, "no triangle is left after simplification"),
            FarMeshError::NearRadius { radius, minimum } => write!(
                f,
                "the near radius {radius} is below {minimum}, {} edges of the far mesh's \
                 clustering cubes: its coarse triangles would pass over receivers",
                FarMesh::MIN_NEAR_CELLS
            ),
            FarMeshError::VertexCount { expected, got } => write!(
                f,
                "the mesh has {got} vertices, but the far mesh was made from one of {expected}"
            ),
        }
    }
}

/// A simplified mesh whose vertices are means of the full mesh's vertices (see
/// the module docs).
#[derive(Clone, Debug)]
pub struct FarMesh {
    cell_size: f32,
    full_vertex_count: usize,
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
    /// Far vertex `v` is the mean of full vertices
    /// `members[offsets[v]..offsets[v + 1]]`.
    offsets: Vec<u32>,
    members: Vec<u32>,
}

/// The cubes of the full mesh's used vertices: each used vertex's cube, and the
/// number of cubes.
struct Cells {
    /// Cube of each full vertex; `u32::MAX` for a vertex no triangle uses.
    of_vertex: Vec<u32>,
    count: usize,
}

impl FarMesh {
    /// Cubes finer than this fraction of the mesh's largest extent are refused:
    /// cube coordinates then fit 21 bits each.
    pub const MIN_CELL_OF_EXTENT: f32 = 1.0 / (1 << 20) as f32;

    /// The default near radius with a far mesh, in cube edges: the far surface,
    /// up to about a cube edge off the full one, then starts where that error is
    /// about a third of the distance to the receiver.
    pub const NEAR_CELLS: f32 = 3.0;

    /// The least near radius a far field accepts, in cube edges: a cube's
    /// diagonal. A far vertex lies anywhere in its cube, so from a smaller
    /// radius the far triangles made from the receiver's own cube count as
    /// distant, and they can pass right over it (an object on a large ground:
    /// the coarse surface joining the object's cube to the ground's spans the
    /// ground receivers around it and darkens them wholly).
    pub const MIN_NEAR_CELLS: f32 = 1.732_050_8; // √3

    /// The far mesh of `mesh` (in its rest pose) with cubes of edge `cell_size`.
    pub fn with_cell_size(mesh: &MeshView<'_>, cell_size: f32) -> Result<Self, FarMeshError> {
        let cells = Self::cells(mesh, cell_size)?;
        let rest = Self::means(mesh, &cells);
        let kept = Self::surviving_triangles(mesh, &cells, &rest, cell_size);
        if kept.is_empty() {
            return Err(FarMeshError::Empty);
        }
        // Far vertices are the cubes that keep a triangle, numbered by first use.
        let mut renumber = vec![u32::MAX; cells.count];
        let mut cube_of_far = Vec::new();
        let mut indices = Vec::with_capacity(3 * kept.len());
        for corners in &kept {
            for &cube in corners {
                let slot = &mut renumber[cube as usize];
                if *slot == u32::MAX {
                    *slot = cube_of_far.len() as u32;
                    cube_of_far.push(cube);
                }
                indices.push(*slot);
            }
        }
        let far_count = cube_of_far.len();
        let mut offsets = vec![0u32; far_count + 1];
        for &cube in &cells.of_vertex {
            if cube != u32::MAX && renumber[cube as usize] != u32::MAX {
                offsets[renumber[cube as usize] as usize + 1] += 1;
            }
        }
        for v in 0..far_count {
            offsets[v + 1] += offsets[v];
        }
        let mut members = vec![0u32; offsets[far_count] as usize];
        let mut next: Vec<u32> = offsets[..far_count].to_vec();
        for (vertex, &cube) in cells.of_vertex.iter().enumerate() {
            if cube != u32::MAX && renumber[cube as usize] != u32::MAX {
                let far = renumber[cube as usize] as usize;
                members[next[far] as usize] = vertex as u32;
                next[far] += 1;
            }
        }
        let mut far = FarMesh {
            cell_size,
            full_vertex_count: mesh.vertex_count(),
            positions: vec![[0.0; 3]; far_count],
            indices,
            offsets,
            members,
        };
        far.pose(mesh)?;
        Ok(far)
    }

    /// The far mesh of `mesh` (in its rest pose) with about `triangles` triangles:
    /// the cube edge is searched (about 20 clusterings of the mesh, each a sort of
    /// its vertices and triangles) and the count closest to the request is kept.
    pub fn with_triangles(mesh: &MeshView<'_>, triangles: usize) -> Result<Self, FarMeshError> {
        let available = mesh.triangle_count();
        if triangles == 0 || triangles >= available {
            return Err(FarMeshError::TriangleCount {
                requested: triangles,
                available,
            });
        }
        let extent = Self::used_extent(mesh).ok_or(FarMeshError::Empty)?;
        // log2 of the cube edge over the extent, between the finest allowed cube
        // and one as large as the mesh.
        let (mut fine, mut coarse) = (-19.5f32, 0.0f32);
        let mut best: Option<(usize, f32)> = None;
        for _ in 0..24 {
            let middle = 0.5 * (fine + coarse);
            let cell_size = extent * libm::exp2f(middle);
            let count = Self::triangle_count_with(mesh, cell_size)?;
            let miss = count.abs_diff(triangles);
            if best.is_none_or(|(best_miss, _)| miss < best_miss) {
                best = Some((miss, cell_size));
            }
            if miss <= triangles / 100 {
                break;
            }
            if count > triangles {
                fine = middle;
            } else {
                coarse = middle;
            }
        }
        let (_, cell_size) = best.expect("the search runs at least once");
        Self::with_cell_size(mesh, cell_size)
    }

    /// Moves every far vertex to the mean of its full vertices in `mesh`, the full
    /// mesh in its current pose (the vertex count it was made from; the indices
    /// are not read). Allocates nothing.
    pub fn pose(&mut self, mesh: &MeshView<'_>) -> Result<(), FarMeshError> {
        if mesh.vertex_count() != self.full_vertex_count {
            return Err(FarMeshError::VertexCount {
                expected: self.full_vertex_count,
                got: mesh.vertex_count(),
            });
        }
        for (far, position) in self.positions.iter_mut().enumerate() {
            let members = &self.members[self.offsets[far] as usize..self.offsets[far + 1] as usize];
            let sum = members
                .iter()
                .fold(Vec3::ZERO, |sum, &v| sum + mesh.position(v as usize));
            *position = (sum / members.len() as f32).to_array();
        }
        Ok(())
    }

    /// The far mesh in the pose of the last [`FarMesh::pose`].
    pub fn view(&self) -> MeshView<'_> {
        MeshView::new(&self.positions, &self.indices)
            .expect("far vertices are means of finite positions and indices are in range")
    }

    /// Far vertex positions (the pose of the last [`FarMesh::pose`]).
    pub fn positions(&self) -> &[[f32; 3]] {
        &self.positions
    }

    /// Three far vertex indices per triangle.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// Number of far triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Edge of the clustering cubes, in mesh units.
    pub fn cell_size(&self) -> f32 {
        self.cell_size
    }

    /// The default near radius of a two-level scene with this far mesh:
    /// [`FarMesh::NEAR_CELLS`] cube edges.
    pub fn default_near_radius(&self) -> f32 {
        Self::NEAR_CELLS * self.cell_size
    }

    /// The full vertices whose mean far vertex `far` is.
    pub fn members(&self, far: usize) -> &[u32] {
        &self.members[self.offsets[far] as usize..self.offsets[far + 1] as usize]
    }

    /// Bytes held (positions, indices and the map from full to far vertices).
    pub fn heap_bytes(&self) -> usize {
        12 * self.positions.capacity()
            + 4 * (self.indices.capacity() + self.offsets.capacity() + self.members.capacity())
    }

    fn triangle_count_with(mesh: &MeshView<'_>, cell_size: f32) -> Result<usize, FarMeshError> {
        let cells = Self::cells(mesh, cell_size)?;
        let rest = Self::means(mesh, &cells);
        Ok(Self::surviving_triangles(mesh, &cells, &rest, cell_size).len())
    }

    /// The largest extent of the vertices triangles use; None without triangles.
    fn used_extent(mesh: &MeshView<'_>) -> Option<f32> {
        let (min, max) = Self::used_bounds(mesh)?;
        Some((max - min).max_element())
    }

    fn used_bounds(mesh: &MeshView<'_>) -> Option<(Vec3, Vec3)> {
        let mut bounds: Option<(Vec3, Vec3)> = None;
        for &v in mesh.indices() {
            let p = mesh.position(v as usize);
            bounds = Some(match bounds {
                None => (p, p),
                Some((min, max)) => (min.min(p), max.max(p)),
            });
        }
        bounds
    }

    fn cells(mesh: &MeshView<'_>, cell_size: f32) -> Result<Cells, FarMeshError> {
        let (min, max) = Self::used_bounds(mesh).ok_or(FarMeshError::Empty)?;
        let extent = (max - min).max_element();
        if !(cell_size.is_finite() && cell_size > 0.0)
            || extent * Self::MIN_CELL_OF_EXTENT > cell_size
        {
            return Err(FarMeshError::CellSize(cell_size));
        }
        let mut used = vec![false; mesh.vertex_count()];
        for &v in mesh.indices() {
            used[v as usize] = true;
        }
        // Packed cube coordinates (21 bits each) of every used vertex, sorted, so
        // that equal cubes are adjacent.
        let inverse = 1.0 / f64::from(cell_size);
        let origin = min.as_dvec3();
        let limit = (1u64 << 21) - 1;
        let mut keyed: Vec<(u64, u32)> = used
            .iter()
            .enumerate()
            .filter(|&(_, &used)| used)
            .map(|(v, _)| {
                let c = ((mesh.position(v).as_dvec3() - origin) * inverse).floor();
                let axis = |x: f64| (x.max(0.0) as u64).min(limit);
                ((axis(c.x) << 42) | (axis(c.y) << 21) | axis(c.z), v as u32)
            })
            .collect();
        keyed.sort_unstable();
        let mut of_vertex = vec![u32::MAX; mesh.vertex_count()];
        let mut count = 0usize;
        for (i, &(key, v)) in keyed.iter().enumerate() {
            if i > 0 && keyed[i - 1].0 != key {
                count += 1;
            }
            of_vertex[v as usize] = count as u32;
        }
        Ok(Cells {
            of_vertex,
            count: if keyed.is_empty() { 0 } else { count + 1 },
        })
    }

    /// The mean rest position of each cube's vertices, in double precision.
    fn means(mesh: &MeshView<'_>, cells: &Cells) -> Vec<DVec3> {
        let mut sums = vec![(DVec3::ZERO, 0u32); cells.count];
        for (v, &cube) in cells.of_vertex.iter().enumerate() {
            if cube != u32::MAX {
                let sum = &mut sums[cube as usize];
                sum.0 += mesh.position(v).as_dvec3();
                sum.1 += 1;
            }
        }
        sums.iter().map(|&(sum, n)| sum / f64::from(n)).collect()
    }

    /// The cubes of the triangles that survive, in the full mesh's order.
    fn surviving_triangles(
        mesh: &MeshView<'_>,
        cells: &Cells,
        rest: &[DVec3],
        cell_size: f32,
    ) -> Vec<[u32; 3]> {
        let min_double_area = 1e-6 * f64::from(cell_size) * f64::from(cell_size);
        let mut candidates: Vec<([u32; 3], u32)> = Vec::new();
        for (t, corners) in mesh.indices().chunks_exact(3).enumerate() {
            let cubes = [0, 1, 2].map(|k| cells.of_vertex[corners[k] as usize]);
            if cubes[0] == cubes[1] || cubes[1] == cubes[2] || cubes[2] == cubes[0] {
                continue;
            }
            let [a, b, c] = cubes.map(|cube| rest[cube as usize]);
            if length_f64((b - a).cross(c - a)) <= min_double_area {
                continue;
            }
            candidates.push((cubes, t as u32));
        }
        // The first of the triangles over the same three cubes survives.
        let mut sorted: Vec<([u32; 3], u32)> = candidates
            .iter()
            .map(|&(mut cubes, t)| {
                cubes.sort_unstable();
                (cubes, t)
            })
            .collect();
        sorted.sort_unstable();
        let mut survives = vec![false; mesh.triangle_count()];
        for (i, &(cubes, t)) in sorted.iter().enumerate() {
            if i == 0 || sorted[i - 1].0 != cubes {
                survives[t as usize] = true;
            }
        }
        candidates
            .into_iter()
            .filter(|&(_, t)| survives[t as usize])
            .map(|(cubes, _)| cubes)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> (Vec<[f32; 3]>, Vec<u32>) {
        (
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3],
        )
    }

    /// A closed, finely tessellated sphere (latitude-longitude grid).
    fn sphere(rings: u32, segments: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut positions = vec![[0.0, 0.0, 1.0]];
        for r in 1..rings {
            let theta = core::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..segments {
                let phi = 2.0 * core::f32::consts::PI * s as f32 / segments as f32;
                positions.push([
                    libm::sinf(theta) * libm::cosf(phi),
                    libm::sinf(theta) * libm::sinf(phi),
                    libm::cosf(theta),
                ]);
            }
        }
        positions.push([0.0, 0.0, -1.0]);
        let south = positions.len() as u32 - 1;
        let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
        let mut indices = Vec::new();
        for s in 0..segments {
            indices.extend_from_slice(&[0, ring(1, s), ring(1, s + 1)]);
            indices.extend_from_slice(&[south, ring(rings - 1, s + 1), ring(rings - 1, s)]);
        }
        for r in 1..rings - 1 {
            for s in 0..segments {
                let (a, b, c, d) = (
                    ring(r, s),
                    ring(r, s + 1),
                    ring(r + 1, s),
                    ring(r + 1, s + 1),
                );
                indices.extend_from_slice(&[a, c, b, b, c, d]);
            }
        }
        (positions, indices)
    }

    #[test]
    fn tiny_cells_keep_the_mesh_and_huge_cells_collapse_it() {
        let (positions, indices) = tetra();
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let same = FarMesh::with_cell_size(&mesh, 0.01).unwrap();
        // The same triangles, corner by corner (far vertices are numbered by first use).
        let corners = |p: &[[f32; 3]], i: &[u32]| -> Vec<[f32; 3]> {
            i.iter().map(|&v| p[v as usize]).collect()
        };
        assert_eq!(
            corners(same.positions(), same.indices()),
            corners(&positions, &indices)
        );
        assert_eq!(
            FarMesh::with_cell_size(&mesh, 10.0).unwrap_err(),
            FarMeshError::Empty
        );
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY, 1e-9] {
            assert!(
                matches!(
                    FarMesh::with_cell_size(&mesh, bad),
                    Err(FarMeshError::CellSize(_))
                ),
                "{bad}"
            );
        }
    }

    #[test]
    fn duplicates_and_opposite_copies_are_dropped() {
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let indices = [0, 1, 2, 1, 2, 0, 0, 2, 1];
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let far = FarMesh::with_cell_size(&mesh, 0.1).unwrap();
        assert_eq!(far.indices(), &[0, 1, 2]);
    }

    #[test]
    fn a_simplified_sphere_is_clean_within_bounds_and_near_the_requested_size() {
        let (positions, indices) = sphere(64, 128);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let full = mesh.triangle_count();
        for target in [200, 1_000, 4_000] {
            let far = FarMesh::with_triangles(&mesh, target).unwrap();
            let got = far.triangle_count();
            assert!(
                got.abs_diff(target) * 5 <= target,
                "{got} triangles for {target} of {full}"
            );
            // Every far vertex used, within the sphere's bounds, near its surface.
            let mut used = vec![false; far.positions().len()];
            for &v in far.indices() {
                used[v as usize] = true;
            }
            assert!(used.iter().all(|&u| u));
            for p in far.positions() {
                let r = Vec3::from(*p).length();
                assert!(r <= 1.0 + 1e-6 && r > 1.0 - far.cell_size(), "radius {r}");
            }
            // No repeated corner, no duplicate in any order.
            let mut keys: Vec<[u32; 3]> = far
                .indices()
                .chunks_exact(3)
                .map(|t| {
                    assert!(t[0] != t[1] && t[1] != t[2] && t[2] != t[0]);
                    let mut k = [t[0], t[1], t[2]];
                    k.sort_unstable();
                    k
                })
                .collect();
            keys.sort_unstable();
            keys.dedup();
            assert_eq!(keys.len(), got);
        }
        assert!(matches!(
            FarMesh::with_triangles(&mesh, full),
            Err(FarMeshError::TriangleCount { .. })
        ));
        assert!(matches!(
            FarMesh::with_triangles(&mesh, 0),
            Err(FarMeshError::TriangleCount { .. })
        ));
    }

    #[test]
    fn the_pose_follows_the_full_mesh() {
        let (positions, indices) = sphere(24, 48);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut far = FarMesh::with_triangles(&mesh, 300).unwrap();
        let rest = far.positions().to_vec();
        // Each far vertex is the mean of its members, and the members partition
        // the vertices of surviving cubes.
        for (v, p) in rest.iter().enumerate() {
            let members = far.members(v);
            assert!(!members.is_empty());
            let mean = members
                .iter()
                .fold(Vec3::ZERO, |s, &m| s + Vec3::from(positions[m as usize]))
                / members.len() as f32;
            assert_eq!(mean.to_array(), *p);
        }
        // A rigid motion of the full mesh moves the far mesh the same way.
        let moved: Vec<[f32; 3]> = positions
            .iter()
            .map(|&p| (Vec3::from(p) * 2.0 + Vec3::new(3.0, -1.0, 0.5)).to_array())
            .collect();
        far.pose(&MeshView::new(&moved, &indices).unwrap()).unwrap();
        for (p, r) in far.positions().iter().zip(&rest) {
            let want = Vec3::from(*r) * 2.0 + Vec3::new(3.0, -1.0, 0.5);
            assert!((Vec3::from(*p) - want).length() < 1e-5, "{p:?} vs {want}");
        }
        let fewer = &moved[..moved.len() - 1];
        assert_eq!(
            far.pose(&MeshView::new(fewer, &[]).unwrap()).unwrap_err(),
            FarMeshError::VertexCount {
                expected: positions.len(),
                got: positions.len() - 1
            }
        );
    }
}
