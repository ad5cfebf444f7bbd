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

use crate::fallible::{self, OutOfMemory};
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
    /// Each edge's corners as the set-up lanes read them, `f32` triples of
    /// `a`, `b` and the third vertices `u`, `v` (NaN where the edge has not
    /// exactly two adjacent triangles): one read per candidate instead of the
    /// edge, its third vertices and four positions. Empty unless
    /// [`EdgeGraph::make_lane_records`] made them.
    pub lane_records: Vec<[f32; 12]>,
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
    #[cfg(test)]
    pub fn new(triangles: impl Iterator<Item = [Vec3; 3]>) -> Self {
        let tris: Vec<[Vec3; 3]> = triangles
            .filter(|&[a, b, c]| !degenerate(a, b, c))
            .collect();
        let positions: Vec<Vec3> = tris.iter().flatten().copied().collect();
        let indexed: Vec<[u32; 3]> = (0..tris.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        Self::from_indexed(&positions, &indexed).expect("memory for a test graph")
    }

    /// `EdgeGraph::new` (the tests' constructor from corners) for triangles
    /// given as indices into `positions`, none of them degenerate (the caller
    /// has checked).
    ///
    /// Both steps are sorts of integer keys, not map insertions: the used
    /// vertices by position (fewer than the corners), the half-edges by their
    /// lower welded end (a counting sort) and then within each end. On a
    /// 52k-triangle mesh a few milliseconds.
    pub fn from_indexed(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Self, OutOfMemory> {
        // Used input vertices by position key (96 bits), then input number.
        let mut used = fallible::filled(false, positions.len())?;
        for &v in triangles.iter().flatten() {
            used[v as usize] = true;
        }
        let mut keyed: Vec<u128> =
            fallible::collect((0..positions.len()).filter(|&v| used[v]).map(|v| {
                let [x, y, z] = key(positions[v]);
                u128::from(x) << 96 | u128::from(y) << 64 | u128::from(z) << 32 | v as u128
            }))?;
        keyed.sort_unstable();
        let mut welded_positions = Vec::new();
        let mut welded = fallible::filled(0u32, positions.len())?;
        let mut last = None;
        for &k in &keyed {
            let position_key = k >> 32;
            if last != Some(position_key) {
                last = Some(position_key);
                let un = |b: u32| f32::from_bits(if b >> 31 == 1 { b & 0x7FFF_FFFF } else { !b });
                let part = |shift: u32| un((position_key >> shift) as u32);
                fallible::push(
                    &mut welded_positions,
                    Vec3::new(part(64), part(32), part(0)),
                )?;
            }
            welded[(k & 0xFFFF_FFFF) as usize] = welded_positions.len() as u32 - 1;
        }
        let triangles: Vec<[u32; 3]> =
            fallible::collect(triangles.iter().map(|t| t.map(|v| welded[v as usize])))?;
        // Half-edges `(upper end, third vertex)` bucketed by lower end, then
        // each bucket sorted: edges come out by (lower, upper), their third
        // vertices ascending.
        let vertex_count = welded_positions.len();
        let mut starts = fallible::filled(0u32, vertex_count + 1)?;
        for &[x, y, z] in &triangles {
            for (u, v) in [(x, y), (y, z), (z, x)] {
                starts[u.min(v) as usize + 1] += 1;
            }
        }
        for i in 0..vertex_count {
            starts[i + 1] += starts[i];
        }
        let mut fill = fallible::collect(starts.iter().copied())?;
        let mut half = fallible::filled(0u64, 3 * triangles.len())?;
        for &[x, y, z] in &triangles {
            for (u, v, w) in [(x, y, z), (y, z, x), (z, x, y)] {
                let slot = &mut fill[u.min(v) as usize];
                half[*slot as usize] = u64::from(u.max(v)) << 32 | u64::from(w);
                *slot += 1;
            }
        }
        let mut edges = Vec::new();
        // (Within its capacity: pushing allocates nothing.)
        let mut third = fallible::with_capacity(half.len())?;
        for a in 0..vertex_count {
            let bucket = &mut half[starts[a] as usize..starts[a + 1] as usize];
            bucket.sort_unstable();
            let mut i = 0;
            while i < bucket.len() {
                let b = bucket[i] >> 32;
                let first = third.len() as u32;
                while i < bucket.len() && bucket[i] >> 32 == b {
                    third.push(bucket[i] as u32);
                    i += 1;
                }
                fallible::push(
                    &mut edges,
                    Edge {
                        a: a as u32,
                        b: b as u32,
                        first,
                        count: third.len() as u32 - first,
                    },
                )?;
            }
        }
        Ok(EdgeGraph {
            positions: welded_positions,
            lane_records: Vec::new(),
            triangles,
            edges,
            third,
        })
    }

    /// The two endpoints of edge `e`.
    #[inline]
    pub fn endpoints(&self, e: u32) -> (Vec3, Vec3) {
        let edge = &self.edges[e as usize];
        (
            self.positions[edge.a as usize],
            self.positions[edge.b as usize],
        )
    }

    /// The corners of triangle `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [Vec3; 3] {
        self.triangles[t].map(|v| self.positions[v as usize])
    }

    /// Makes [`EdgeGraph::lane_records`].
    #[cfg_attr(not(all(target_arch = "x86_64", feature = "std")), allow(dead_code))]
    pub fn make_lane_records(&mut self) -> Result<(), OutOfMemory> {
        let at = |v: u32| self.positions[v as usize].to_array();
        self.lane_records = fallible::collect(self.edges.iter().map(|edge| {
            let (u, v) = match self.third_of(edge) {
                &[u, v] => (at(u), at(v)),
                _ => ([f32::NAN; 3], [f32::NAN; 3]),
            };
            let mut record = [0.0; 12];
            for (i, q) in [at(edge.a), at(edge.b), u, v].iter().enumerate() {
                record[3 * i..3 * i + 3].copy_from_slice(q);
            }
            record
        }))?;
        Ok(())
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
