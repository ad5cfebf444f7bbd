//! Mesh simplification by vertex clustering (Rossignac and Borrel 1993): the far
//! level of detail of the hemispherical rasterizer's deforming meshes.
//!
//! Space is cut into cubic cells of a chosen size, aligned with the mesh's
//! bounding box; every vertex used by a triangle moves to the mean position of
//! the vertices in its cell, and the cell becomes one vertex of the simplified
//! mesh. A triangle survives when its three corners land in three different
//! cells, it is not a duplicate of one kept before (the same three cells in any
//! order, which also drops the second of two opposite-facing copies), and its
//! area is not negligible. Unused cells get no vertex. The result is a real mesh of
//! its own (not a subset of the original's triangles). Each of its vertices is
//! the mean rest position of the original vertices merged into it, which is what
//! a deformation given as a function of the rest position (as the demo's twist)
//! needs to move it along with the original.
//!
//! Means of points lie in the convex hull of those points, so the simplified mesh
//! stays within the original's bounds. Clustering ignores topology: thin parts
//! narrower than a cell collapse, and separate parts within a cell merge. That is
//! acceptable for distant occluders, which is all the far mesh is used for.

use std::collections::{HashMap, HashSet};

use glam::{DVec3, Vec3};

use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;

/// A simplified mesh.
#[derive(Clone, Debug)]
pub struct Simplified {
    /// The simplified mesh.
    pub mesh: TriangleMesh,
    /// Edge length of the cubic cells.
    pub cell_size: f32,
}

/// Simplifies `mesh` by clustering its vertices in cubic cells of edge
/// `cell_size` (see the module docs); an error unless `cell_size` is positive
/// and finite.
pub fn cluster_vertices(mesh: &TriangleMesh, cell_size: f32) -> Result<Simplified> {
    if !(cell_size > 0.0 && cell_size.is_finite()) {
        return Err(Error::msg(format!(
            "cannot simplify {}: the cell size must be a positive number, got {cell_size}",
            mesh.name()
        )));
    }
    let origin = mesh.bounds().min;
    let cell_of = |p: Vec3| {
        let c = ((p - origin) / cell_size).floor();
        (c.x as i64, c.y as i64, c.z as i64)
    };
    let mut used = vec![false; mesh.vertex_count()];
    for &v in mesh.indices() {
        used[v as usize] = true;
    }
    // Cells in order of first use, with the sum and count of their vertices.
    let mut cells: HashMap<(i64, i64, i64), u32> = HashMap::new();
    let mut sums: Vec<(DVec3, u32)> = Vec::new();
    let cluster: Vec<Option<u32>> = mesh
        .positions()
        .iter()
        .zip(&used)
        .map(|(&p, &used)| {
            if !used {
                return None;
            }
            let next = sums.len() as u32;
            let id = *cells.entry(cell_of(Vec3::from(p))).or_insert(next);
            if id == next {
                sums.push((DVec3::ZERO, 0));
            }
            let sum = &mut sums[id as usize];
            sum.0 += Vec3::from(p).as_dvec3();
            sum.1 += 1;
            Some(id)
        })
        .collect();
    let centers: Vec<DVec3> = sums.iter().map(|&(s, n)| s / f64::from(n)).collect();
    // Triangles whose doubled area is below this are dropped as degenerate.
    let min_double_area = 1e-6 * f64::from(cell_size) * f64::from(cell_size);
    let mut seen = HashSet::new();
    let mut kept: Vec<[u32; 3]> = Vec::new();
    for corners in mesh.indices().chunks_exact(3) {
        let t = [0, 1, 2].map(|k| cluster[corners[k] as usize].expect("used by a triangle"));
        if t[0] == t[1] || t[1] == t[2] || t[2] == t[0] {
            continue;
        }
        let [a, b, c] = t.map(|v| centers[v as usize]);
        if (b - a).cross(c - a).length() <= min_double_area {
            continue;
        }
        let mut key = t;
        key.sort_unstable();
        if seen.insert(key) {
            kept.push(t);
        }
    }
    // Renumber the cells that kept a triangle, in order of first use.
    let mut renumber = vec![u32::MAX; centers.len()];
    let mut positions = Vec::new();
    let mut indices = Vec::with_capacity(3 * kept.len());
    for t in &kept {
        for &c in t {
            if renumber[c as usize] == u32::MAX {
                renumber[c as usize] = positions.len() as u32;
                positions.push(centers[c as usize].as_vec3().to_array());
            }
            indices.push(renumber[c as usize]);
        }
    }
    if kept.is_empty() {
        return Err(Error::msg(format!(
            "simplifying {} with cells of {cell_size} left no triangle",
            mesh.name()
        )));
    }
    let name = format!("{} (vertex clustering, cell {cell_size:.4})", mesh.name());
    Ok(Simplified {
        mesh: TriangleMesh::new(name, positions, indices)?,
        cell_size,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin;

    fn double_area(mesh: &TriangleMesh, t: usize) -> f32 {
        let [a, b, c] =
            [0, 1, 2].map(|k| Vec3::from(mesh.positions()[mesh.indices()[3 * t + k] as usize]));
        (b - a).cross(c - a).length()
    }

    #[test]
    fn the_simplified_bunny_is_smaller_within_bounds_and_clean() {
        let bunny = builtin::bunny().unwrap();
        let bounds = bunny.bounds();
        let cell = bounds.diagonal() / 25.0;
        let simplified = cluster_vertices(&bunny, cell).unwrap();
        let far = &simplified.mesh;
        assert!(
            far.triangle_count() * 2 < bunny.triangle_count(),
            "{} of {} triangles",
            far.triangle_count(),
            bunny.triangle_count()
        );
        assert!(far.triangle_count() > 200, "{}", far.triangle_count());
        let inner = far.bounds();
        let slack = 1e-5 * bounds.diagonal();
        assert!(
            inner.min.cmpge(bounds.min - slack).all() && inner.max.cmple(bounds.max + slack).all()
        );
        // No repeated corner, no zero area, no duplicate (in any order or winding).
        let mut keys = HashSet::new();
        for t in 0..far.triangle_count() {
            let mut corners = [0, 1, 2].map(|k| far.indices()[3 * t + k]);
            assert!(
                corners[0] != corners[1] && corners[1] != corners[2] && corners[2] != corners[0]
            );
            assert!(double_area(far, t) > 0.0, "triangle {t}");
            corners.sort_unstable();
            assert!(keys.insert(corners), "triangle {t} is a duplicate");
        }
        // Every simplified vertex is used.
        let mut used = vec![false; far.vertex_count()];
        for &v in far.indices() {
            used[v as usize] = true;
        }
        assert!(used.iter().all(|&u| u));
    }

    #[test]
    fn tiny_cells_keep_the_mesh_and_huge_cells_collapse_it() {
        let tetra = TriangleMesh::parse_obj_str(
            "tetra",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
        )
        .unwrap();
        let same = cluster_vertices(&tetra, 0.01).unwrap();
        assert_eq!(same.mesh.positions(), tetra.positions());
        assert_eq!(same.mesh.indices(), tetra.indices());
        assert!(cluster_vertices(&tetra, 10.0).is_err(), "nothing is left");
    }

    #[test]
    fn duplicates_and_opposite_copies_are_dropped() {
        let mesh = TriangleMesh::parse_obj_str(
            "doubled",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 2 3 1\nf 1 3 2\n",
        )
        .unwrap();
        let simplified = cluster_vertices(&mesh, 0.1).unwrap();
        assert_eq!(simplified.mesh.triangle_count(), 1);
    }
}
