//! The 2005-style structure (Laine et al. 2005, §5): penumbra wedges projected
//! from the light's centroid `o` onto a cube of direction cells (6 faces of
//! `r × r`), a baseline for the 3D hierarchy.
//!
//! Conservative projection: every point `x + t (x - l)` of a wedge (module
//! [`super::wedge`]) has direction `(x - o) + t (x - l)` from `o`, a non-negative
//! combination of the generators `a - o`, `b - o`, `a - l_i`, `b - l_i`. On a face
//! whose axis every generator points along (beyond a relative slack) the cone's
//! footprint is the convex hull of the generators' projections, so the cells of
//! their bounding rectangle (grown by a margin for rounding) hold the edge; a face
//! the cone only may touch gets the edge in every cell; a face every generator
//! points away from gets nothing. A query projects `p - o` to one cell and tests
//! that cell's list (every potential edge when `p == o`).

use alloc::vec;
use alloc::vec::Vec;
use glam::DVec3;

use super::edges::EdgeGraph;
use super::wedge::LightShape;

pub(crate) struct Hemicube {
    origin: DVec3,
    resolution: usize,
    /// Cell `(face, j, i)` at `(face * r + j) * r + i`: a range of `lists`.
    offsets: Vec<u32>,
    lists: Vec<u32>,
    all: Vec<u32>,
}

const SLACK: f64 = 1e-9;
const MARGIN: f64 = 1e-6;

fn face_axes(axis: usize) -> (usize, usize) {
    ((axis + 1) % 3, (axis + 2) % 3)
}

impl Hemicube {
    pub fn new(
        graph: &EdgeGraph,
        shape: &LightShape,
        potential: &[u32],
        origin: DVec3,
        resolution: usize,
    ) -> Self {
        let r = resolution;
        let cells = 6 * r * r;
        let mut per_cell: Vec<Vec<u32>> = vec![Vec::new(); cells];
        let mut generators: Vec<DVec3> = Vec::with_capacity(2 + 2 * shape.vertices.len());
        for &e in potential {
            let edge = &graph.edges[e as usize];
            let a = graph.positions[edge.a as usize].as_dvec3();
            let b = graph.positions[edge.b as usize].as_dvec3();
            generators.clear();
            generators.push(a - origin);
            generators.push(b - origin);
            for l in &shape.vertices {
                generators.push(a - *l);
                generators.push(b - *l);
            }
            for face in 0..6 {
                let (axis, sign) = (face / 2, if face % 2 == 0 { 1.0 } else { -1.0 });
                let (u, v) = face_axes(axis);
                let (mut all_in, mut all_out) = (true, true);
                let (mut u0, mut u1, mut v0, mut v1) = (
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                );
                for g in &generators {
                    let along = sign * g[axis];
                    let slack = SLACK * g.length() + shape.tolerance;
                    all_in &= along > slack;
                    all_out &= along < -slack;
                    if along > 0.0 {
                        u0 = u0.min(g[u] / along);
                        u1 = u1.max(g[u] / along);
                        v0 = v0.min(g[v] / along);
                        v1 = v1.max(g[v] / along);
                    }
                }
                if all_out {
                    continue;
                }
                let (i0, i1, j0, j1) = if all_in {
                    let cell = |x: f64| {
                        (libm::floor((x + 1.0) * 0.5 * r as f64).clamp(0.0, (r - 1) as f64))
                            as usize
                    };
                    (
                        cell(u0 - MARGIN),
                        cell(u1 + MARGIN),
                        cell(v0 - MARGIN),
                        cell(v1 + MARGIN),
                    )
                } else {
                    (0, r - 1, 0, r - 1)
                };
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        per_cell[(face * r + j) * r + i].push(e);
                    }
                }
            }
        }
        let mut offsets = Vec::with_capacity(cells + 1);
        let mut lists = Vec::new();
        offsets.push(0);
        for cell in per_cell {
            lists.extend_from_slice(&cell);
            offsets.push(lists.len() as u32);
        }
        Hemicube {
            origin,
            resolution,
            offsets,
            lists,
            all: potential.to_vec(),
        }
    }

    pub fn cells(&self) -> usize {
        6 * self.resolution * self.resolution
    }

    pub fn bytes(&self) -> usize {
        4 * (self.offsets.len() + self.lists.len() + self.all.len())
    }

    pub fn for_each_candidate(&self, p: DVec3, mut visit: impl FnMut(u32)) {
        let d = p - self.origin;
        let m = d.abs();
        if m.max_element() == 0.0 {
            self.all.iter().for_each(|&e| visit(e));
            return;
        }
        let axis = if m.x >= m.y && m.x >= m.z {
            0
        } else if m.y >= m.z {
            1
        } else {
            2
        };
        let face = 2 * axis + usize::from(d[axis] < 0.0);
        let (u, v) = face_axes(axis);
        let r = self.resolution;
        let cell = |x: f64| {
            (libm::floor((x / m[axis] + 1.0) * 0.5 * r as f64).clamp(0.0, (r - 1) as f64)) as usize
        };
        let index = (face * r + cell(d[v])) * r + cell(d[u]);
        let (lo, hi) = (
            self.offsets[index] as usize,
            self.offsets[index + 1] as usize,
        );
        self.lists[lo..hi].iter().for_each(|&e| visit(e));
    }
}
