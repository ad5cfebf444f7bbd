//! Edge extraction with adjacency, and the silhouette weight of an edge.
//!
//! Vertices are welded by exact position (bit-equal `f32` triples, `-0.0 == 0.0`)
//! and numbered in a canonical order of their positions, so the numbering, the
//! edges and every predicate's argument order depend only on the geometry, never
//! on how the mesh was indexed: an unwelded copy of a mesh gives identical bits.
//! An edge is an unordered pair of welded vertices (stored lower number first);
//! it lists every triangle that has it, by the triangle's third vertex. Boundary
//! edges have one, folds and ordinary manifold edges two, non-manifold fans more;
//! a triangle given twice counts twice (it also occludes twice).
//!
//! Degenerate triangles (collinear corners, decided exactly) are dropped here and
//! by the reference ray caster alike: the exact oracle never counts them either
//! (see [`super::segment_meets_triangle`]).

use alloc::collections::BTreeMap;
use alloc::vec::Vec;
use glam::Vec3;

use super::predicates::orient3d;

/// A welded edge: vertices `a < b` and a range of `third` holding the opposite
/// vertex of each adjacent triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Edge {
    pub a: u32,
    pub b: u32,
    pub first: u32,
    pub count: u32,
}

/// The welded edge graph of a triangle soup.
#[derive(Clone, Debug, Default)]
pub(crate) struct EdgeGraph {
    /// Welded positions, in canonical (position) order.
    pub positions: Vec<Vec3>,
    /// Non-degenerate triangles as welded vertex triples.
    pub triangles: Vec<[u32; 3]>,
    pub edges: Vec<Edge>,
    /// Third vertices of the triangles adjacent to each edge.
    pub third: Vec<u32>,
}

/// A total order key for a position in which `-0.0 == 0.0`.
fn key(p: Vec3) -> [u32; 3] {
    let k = |x: f32| {
        let bits = (x + 0.0).to_bits(); // -0.0 + 0.0 == +0.0
        // Sortable: flip all bits of negatives, the sign bit of positives.
        if bits >> 31 == 1 {
            !bits
        } else {
            bits | 0x8000_0000
        }
    };
    [k(p.x), k(p.y), k(p.z)]
}

/// Whether the corners are collinear (or coincide), exactly: all three
/// coordinate-plane projections have zero signed area.
pub(crate) fn degenerate(a: Vec3, b: Vec3, c: Vec3) -> bool {
    // orient2d in the plane z = const equals orient3d against a point one unit
    // above (exact arithmetic underneath); likewise for the other two planes.
    let flat = |f: fn(Vec3) -> Vec3| {
        let (a, b, c) = (f(a), f(b), f(c));
        orient3d(a, b, c, a + Vec3::Z) == 0
    };
    flat(|v| Vec3::new(v.x, v.y, 0.0))
        && flat(|v| Vec3::new(v.y, v.z, 0.0))
        && flat(|v| Vec3::new(v.z, v.x, 0.0))
}

impl EdgeGraph {
    /// Welds `triangles`, drops degenerate ones, and builds the edge list.
    pub fn new(triangles: impl Iterator<Item = [Vec3; 3]>) -> Self {
        let tris: Vec<[Vec3; 3]> = triangles
            .filter(|&[a, b, c]| !degenerate(a, b, c))
            .collect();
        let mut ids: BTreeMap<[u32; 3], u32> = BTreeMap::new();
        for t in &tris {
            for &v in t {
                ids.insert(key(v), 0);
            }
        }
        let mut positions = Vec::with_capacity(ids.len());
        for (rank, (k, id)) in ids.iter_mut().enumerate() {
            *id = rank as u32;
            let un = |b: u32| f32::from_bits(if b >> 31 == 1 { b & 0x7FFF_FFFF } else { !b });
            positions.push(Vec3::new(un(k[0]), un(k[1]), un(k[2])));
        }
        let triangles: Vec<[u32; 3]> = tris
            .iter()
            .map(|t| [ids[&key(t[0])], ids[&key(t[1])], ids[&key(t[2])]])
            .collect();
        let mut half: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * triangles.len());
        for &[x, y, z] in &triangles {
            for (u, v, w) in [(x, y, z), (y, z, x), (z, x, y)] {
                half.push((u.min(v), u.max(v), w));
            }
        }
        half.sort_unstable();
        let mut edges = Vec::new();
        let mut third = Vec::with_capacity(half.len());
        let mut i = 0;
        while i < half.len() {
            let (a, b, _) = half[i];
            let first = third.len() as u32;
            while i < half.len() && half[i].0 == a && half[i].1 == b {
                third.push(half[i].2);
                i += 1;
            }
            edges.push(Edge {
                a,
                b,
                first,
                count: third.len() as u32 - first,
            });
        }
        EdgeGraph {
            positions,
            triangles,
            edges,
            third,
        }
    }

    /// The third vertices adjacent to `edge`.
    #[inline]
    pub fn third_of(&self, edge: &Edge) -> &[u32] {
        &self.third[edge.first as usize..(edge.first + edge.count) as usize]
    }

    /// Whether the edge's weight is zero from every point: exactly two adjacent
    /// triangles, coplanar, on opposite sides of the edge (a flat interior edge,
    /// the "coplanar neighbours" case). Such an edge never changes the depth
    /// complexity and is left out of every structure.
    pub fn is_flat(&self, edge: &Edge) -> bool {
        let t = self.third_of(edge);
        if t.len() != 2 {
            return false;
        }
        let p = |i: u32| self.positions[i as usize];
        let (a, b, u, v) = (p(edge.a), p(edge.b), p(t[0]), p(t[1]));
        if orient3d(a, b, u, v) != 0 {
            return false;
        }
        // Coplanar: opposite sides of the line ab within the plane, tested against
        // an apex off the plane (the plane's normal has a non-zero axis).
        [Vec3::X, Vec3::Y, Vec3::Z].iter().any(|&axis| {
            let apex = a + axis;
            let su = orient3d(a, b, u, apex);
            let sv = orient3d(a, b, v, apex);
            su != 0 && su == -sv
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welding_and_adjacency() {
        // Two triangles sharing an edge, unwelded, plus a third on the same edge
        // (non-manifold), plus a degenerate one.
        let (a, b) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0));
        let (c, d, e) = (
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        );
        let minus_zero = Vec3::new(-0.0, 0.0, -0.0);
        let tris = [[a, b, c], [b, minus_zero, d], [a, e, b], [a, b, b * 2.0]];
        let g = EdgeGraph::new(tris.into_iter());
        assert_eq!(g.positions.len(), 5);
        assert_eq!(g.triangles.len(), 3);
        let ab = g
            .edges
            .iter()
            .find(|e| g.positions[e.a as usize] == a && g.positions[e.b as usize] == b)
            .unwrap();
        assert_eq!(ab.count, 3);
        assert_eq!(g.edges.len(), 7);
        assert_eq!(g.edges.iter().filter(|e| e.count == 1).count(), 6);
        // Canonical numbering: reversed input gives the same graph.
        let h = EdgeGraph::new(tris.iter().rev().map(|t| [t[2], t[0], t[1]]));
        assert_eq!(g.positions, h.positions);
        assert_eq!(g.edges.len(), h.edges.len());
        // Flat: the pair (a b c), (b a d) is coplanar on opposite sides.
        let flat = EdgeGraph::new([[a, b, c], [b, a, d]].into_iter());
        assert!(flat.is_flat(&flat.edges.iter().find(|e| e.count == 2).unwrap().clone()));
        let fold = EdgeGraph::new([[a, b, c], [b, a, c + Vec3::Z]].into_iter());
        assert!(!fold.is_flat(&fold.edges.iter().find(|e| e.count == 2).unwrap().clone()));
    }
}
