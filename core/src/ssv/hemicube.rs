//! The 2005-style structure (Laine et al. 2005, §5): penumbra wedges projected
//! from the light's centroid `o` onto a cube of direction cells (6 faces of
//! `r × r`; a full cube rather than the paper's hemicube because our light
//! shades both sides of its plane), a baseline for the 3D hierarchy. A query
//! projects `p - o` to one cell and runs the exact tests on that cell's list
//! (every potential edge when `p == o`).
//!
//! Invariant: a cell lists every edge that can change a counter of a receiver
//! whose direction from `o` falls in the cell, so the bits equal brute force.
//!
//! What is listed. The kernel counts an edge `e = (a, b)` for `p` only if the
//! closed segment meets a triangle `(p, c, s)` with `c` the centroid and `s` a
//! sample, and the weight `w(p)` is non-zero. Both `c` and `s` lie in the
//! region `K` that [`LightPolygon::contains`](super::LightPolygon::contains)
//! accepts (a prism: the polygon grown by the tolerance in its plane, the
//! tolerance thick). Meeting at `y ∈ e` (`y ≠ p`, else `w(p) = 0`) puts `p` on
//! the ray from some `l ∈ K` through `y`, beyond `y`: `p = y + t (y - l)`, so
//! `p` is in the wedge `W(e, K)`. Along that line the plane through the edge and
//! `p` is the plane through the edge and `l`, with `p` and `l` on opposite
//! sides of the edge, so `w(p) = -w(l)`. Hence `p` can matter only if it lies
//! in `W(e, K ∩ S)`, `S` the points with non-zero weight: the wedge of the part
//! of the light from which the edge is a silhouette (the 2005 paper's
//! "potential silhouette edges", applied per part of the light). For an edge
//! with two triangles `S` is the union of the two closed sectors where both
//! orientations agree, so `K ∩ S` is `K` clipped by the two triangle planes one
//! way or the other (two convex pieces, either may be empty; an edge with no
//! piece is listed nowhere); other adjacencies keep `K` whole (conservative).
//!
//! Cells of a piece. The directions from `o` of `W(e, P)` for a convex `P` with
//! vertices `m_j` are exactly (up to closure) the cone spanned by `a - o`,
//! `b - o`, `a - m_j` and `b - m_j`: a wedge point is `x + t (x - l)`, with
//! `x - o` and `x - l` convex combinations of those. The cone is pointed (its
//! generators projected to a plane across its mean direction give a 2D convex
//! hull: its extreme rays in cyclic order), clipped by each face's pyramid
//! (grown by a margin) in homogeneous coordinates, projected onto the face, and
//! the convex polygon rasterised conservatively: a row of cells gets the
//! polygon's `u`-extent within the row's slab, both grown by the margin (far
//! above the rounding of these few `f64` operations, cells being `2 / r`
//! wide). A cone too wide to be pointed (an edge next to the light) puts the
//! edge in every cell.
//!
//! Resolution: [`SsvOptions::hemicube_resolution`](super::SsvOptions) cells per
//! face side, default 64. Finer cells cut the lists towards the wedges that
//! really hold the receiver's whole direction line, with diminishing returns,
//! at memory growing as the square. A coarser default would make the baseline
//! slower than it needs to be, a finer one spends more memory than the 2006
//! hierarchy it is compared with (candidates per query and memory: `cargo
//! bench -p antumbra-core --features bvh --bench ssv`).

use alloc::vec;
use alloc::vec::Vec;
use glam::{DVec2, DVec3};

use super::edges::{Edge, EdgeGraph};
use super::wedge::LightShape;

pub(crate) struct Hemicube {
    origin: DVec3,
    resolution: usize,
    /// Cell `(face, j, i)` at `(face * r + j) * r + i`: a range of `lists`.
    offsets: Vec<u32>,
    lists: Vec<u32>,
    all: Vec<u32>,
}

/// Relative slack for positions (far above `f64` rounding of a few operations).
const SLACK: f64 = 1e-9;
/// Margin, in face coordinates (`[-1, 1]` per face side), of every cell test.
const MARGIN: f64 = 1e-6;
/// Smallest cosine between a generator and the cone's mean direction for the
/// cone to count as pointed.
const POINTED: f64 = 1e-6;

fn face_axes(axis: usize) -> (usize, usize) {
    ((axis + 1) % 3, (axis + 2) % 3)
}

/// The cell of face coordinate `x` (clamped to the face).
fn cell_of(x: f64, r: usize) -> usize {
    libm::floor((x + 1.0) * 0.5 * r as f64).clamp(0.0, (r - 1) as f64) as usize
}

/// The in-plane outline of the region `K` that `LightPolygon::contains`
/// accepts: every edge line moved outward by `tol` (the vertices of the grown
/// polygon), as points of the plane through `origin` normal to the light.
pub(crate) fn grown_light(
    shape: &LightShape,
    origin: DVec3,
    tol: f64,
) -> Result<Vec<DVec3>, crate::fallible::OutOfMemory> {
    let n = shape.normal;
    let (u, v) = n.any_orthonormal_pair();
    let k = shape.vertices.len();
    let flat = |p: DVec3| DVec2::new((p - origin).dot(u), (p - origin).dot(v));
    // Edge i (vertex i to i + 1) keeps the side `inward · (x - a_i) >= -tol`.
    let lines: Vec<(DVec2, f64)> = crate::fallible::collect((0..k).map(|i| {
        let (a, b) = (shape.vertices[i], shape.vertices[(i + 1) % k]);
        let inward = crate::geom::normalize_f64(n.cross(b - a));
        let inward = DVec2::new(inward.dot(u), inward.dot(v));
        (inward, inward.dot(flat(a)) - tol)
    }))?;
    crate::fallible::collect((0..k).map(|j| {
        let (i1, d1) = lines[(j + k - 1) % k];
        let (i2, d2) = lines[j];
        let det = i1.x * i2.y - i1.y * i2.x;
        let x = if det.abs() < 1e-9 && i1.dot(i2) > 0.0 {
            // Collinear neighbours: both lines are the same line.
            flat(shape.vertices[j]) - tol * i2
        } else {
            DVec2::new(d1 * i2.y - d2 * i1.y, i1.x * d2 - i2.x * d1) / det
        };
        origin + x.x * u + x.y * v
    }))
}

/// The parts of the grown light `region` (in-plane outline, thickness `tol`)
/// from which `edge` may be a silhouette (module docs): for an edge with two
/// triangles, `region` clipped by both triangle planes one way or the other
/// (with slack `tol` plus rounding at `scale`), non-empty pieces only; `None`
/// for other adjacencies or degenerate triangles (the whole region).
pub(crate) fn silhouette_pieces(
    graph: &EdgeGraph,
    edge: &Edge,
    region: &[DVec3],
    tol: f64,
    scale: f64,
) -> Option<Vec<Vec<DVec3>>> {
    let (a, across, plane_slack) = super::edge_bounds::adjacent_planes(graph, edge, tol, scale)?;
    let normals = across.map(crate::geom::normalize_f64);
    if !normals.iter().all(|m| m.is_finite()) {
        return None;
    }
    Some(
        [1.0, -1.0]
            .iter()
            .map(|&side| {
                let once = clip_points(region, |l| side * normals[0].dot(l - a) + plane_slack);
                clip_points(&once, |l| side * normals[1].dot(l - a) + plane_slack)
            })
            .filter(|piece| !piece.is_empty())
            .collect(),
    )
}

/// Sutherland–Hodgman: the convex polygon `poly` (coplanar points) cut to
/// `f(x) >= 0` for the affine `f`.
pub(crate) fn clip_points(poly: &[DVec3], f: impl Fn(DVec3) -> f64) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(poly.len() + 2);
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        let (fp, fq) = (f(p), f(q));
        if fp >= 0.0 {
            out.push(p);
        }
        if (fp >= 0.0) != (fq >= 0.0) {
            out.push(p + (q - p) * (fp / (fp - fq)));
        }
    }
    out
}

/// The pointed cone `cone` (extreme rays in cyclic order) cut by the
/// half-space `h · g >= 0` through the origin, into `out`.
fn clip_cone(cone: &[DVec3], h: DVec3, out: &mut Vec<DVec3>) {
    out.clear();
    for i in 0..cone.len() {
        let (p, q) = (cone[i], cone[(i + 1) % cone.len()]);
        let (dp, dq) = (h.dot(p), h.dot(q));
        if dp >= 0.0 {
            out.push(p);
        }
        if (dp >= 0.0) != (dq >= 0.0) {
            // A non-negative combination of p and q on the plane h · g = 0.
            let x = if dp >= 0.0 {
                dp * q - dq * p
            } else {
                dq * p - dp * q
            };
            out.push(crate::geom::normalize_or_zero_f64(x));
        }
    }
}

/// The extreme rays, in cyclic order, of the cone spanned by `generators`
/// (unit vectors), or `None` when it is not safely pointed.
fn cone_hull(generators: &[DVec3]) -> Option<Vec<DVec3>> {
    let mean =
        crate::geom::normalize_or_zero_f64(generators.iter().fold(DVec3::ZERO, |s, g| s + *g));
    // NaN fails too.
    if !generators.iter().all(|g| g.dot(mean) > POINTED) {
        return None;
    }
    let (e1, e2) = mean.any_orthonormal_pair();
    let mut points: Vec<(DVec2, DVec3)> = generators
        .iter()
        .map(|&g| {
            let y = g / g.dot(mean);
            (DVec2::new(y.dot(e1), y.dot(e2)), g)
        })
        .collect();
    points.sort_by(|p, q| p.0.x.total_cmp(&q.0.x).then(p.0.y.total_cmp(&q.0.y)));
    // Andrew's monotone chain; collinear points dropped (they are on the hull's
    // edges, inside the cone).
    let turn = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<(DVec2, DVec3)> = Vec::with_capacity(points.len() + 1);
    for pass in 0..2 {
        let start = hull.len();
        let ordered: &mut dyn Iterator<Item = &(DVec2, DVec3)> = if pass == 0 {
            &mut points.iter()
        } else {
            &mut points.iter().rev()
        };
        for &p in ordered {
            while hull.len() >= start + 2
                && turn(hull[hull.len() - 2].0, hull[hull.len() - 1].0, p.0) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    if hull.is_empty() {
        hull.push(points[0]);
    }
    Some(hull.into_iter().map(|p| p.1).collect())
}

/// Calls `mark` with every cell whose direction pyramid may meet the cone
/// spanned by `generators` (unit vectors), possibly more than once per cell.
fn rasterise_cone(generators: &[DVec3], r: usize, mut mark: impl FnMut(usize)) {
    let Some(cone) = cone_hull(generators) else {
        (0..6 * r * r).for_each(mark);
        return;
    };
    let (mut a, mut b) = (Vec::with_capacity(16), Vec::with_capacity(16));
    let mut polygon: Vec<DVec2> = Vec::with_capacity(16);
    let grown = 1.0 + MARGIN;
    for face in 0..6 {
        let (axis, sign) = (face / 2, if face % 2 == 0 { 1.0 } else { -1.0 });
        let (u, v) = face_axes(axis);
        // The face's pyramid `|g_u|, |g_v| <= (1 + MARGIN) sign g_axis`.
        let plane = |along: usize, side: f64| {
            let mut h = DVec3::ZERO;
            h[axis] = grown * sign;
            h[along] = side;
            h
        };
        clip_cone(&cone, plane(u, 1.0), &mut a);
        clip_cone(&a, plane(u, -1.0), &mut b);
        clip_cone(&b, plane(v, 1.0), &mut a);
        clip_cone(&a, plane(v, -1.0), &mut b);
        if b.is_empty() {
            continue;
        }
        polygon.clear();
        let mut whole = false;
        for g in &b {
            let along = sign * g[axis];
            if along.is_nan() || along <= 0.0 {
                whole = true;
                break;
            }
            polygon.push(DVec2::new(g[u] / along, g[v] / along));
        }
        if whole || polygon.iter().any(|q| !q.is_finite()) {
            (face * r * r..(face + 1) * r * r).for_each(&mut mark);
            continue;
        }
        let (vmin, vmax) = polygon
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                (lo.min(q.y), hi.max(q.y))
            });
        let width = 2.0 / r as f64;
        for j in cell_of(vmin - MARGIN, r)..=cell_of(vmax + MARGIN, r) {
            // The polygon's u-extent within the row's slab (grown): for a convex
            // polygon the extent of its boundary.
            let lo = -1.0 + width * j as f64 - MARGIN;
            let hi = -1.0 + width * (j + 1) as f64 + MARGIN;
            let (mut umin, mut umax) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..polygon.len() {
                let (p, q) = (polygon[i], polygon[(i + 1) % polygon.len()]);
                let (mut t0, mut t1) = (0.0f64, 1.0f64);
                let dv = q.y - p.y;
                if dv == 0.0 {
                    if p.y < lo || p.y > hi {
                        continue;
                    }
                } else {
                    let (ta, tb) = ((lo - p.y) / dv, (hi - p.y) / dv);
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb));
                    if t0 > t1 {
                        continue;
                    }
                }
                let (u0, u1) = (p.x + t0 * (q.x - p.x), p.x + t1 * (q.x - p.x));
                umin = umin.min(u0.min(u1));
                umax = umax.max(u0.max(u1));
            }
            if umin > umax {
                continue;
            }
            for i in cell_of(umin - MARGIN, r)..=cell_of(umax + MARGIN, r) {
                mark((face * r + j) * r + i);
            }
        }
    }
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
        let scale = shape
            .vertices
            .iter()
            .fold(origin.abs().max_element(), |m, v| {
                m.max(v.abs().max_element())
            });
        let tol = shape.tolerance + SLACK * scale;
        let region = grown_light(shape, origin, tol).expect("memory for the grown light");
        let n = shape.normal;
        let mut per_cell: Vec<Vec<u32>> = vec![Vec::new(); cells];
        // The last edge pushed to each cell (an edge's pieces may share cells).
        let mut stamp: Vec<u32> = vec![u32::MAX; cells];
        let mut generators: Vec<DVec3> = Vec::new();
        for &e in potential {
            let edge = &graph.edges[e as usize];
            let at = |i: u32| graph.positions[i as usize].as_dvec3();
            let (a, b) = (at(edge.a), at(edge.b));
            let pieces = silhouette_pieces(graph, edge, &region, tol, scale)
                .unwrap_or_else(|| vec![region.clone()]);
            for piece in &pieces {
                generators.clear();
                generators.push(a - origin);
                generators.push(b - origin);
                for &m in piece {
                    for l in [m + tol * n, m - tol * n] {
                        generators.push(a - l);
                        generators.push(b - l);
                    }
                }
                let mut mark = |cell: usize| {
                    if stamp[cell] != e {
                        stamp[cell] = e;
                        per_cell[cell].push(e);
                    }
                };
                if generators
                    .iter()
                    .all(|g| g.is_finite() && *g != DVec3::ZERO)
                {
                    generators
                        .iter_mut()
                        .for_each(|g| *g = crate::geom::normalize_f64(*g));
                    rasterise_cone(&generators, r, &mut mark);
                } else {
                    (0..cells).for_each(&mut mark);
                }
            }
        }
        let mut offsets = Vec::with_capacity(cells + 1);
        let mut lists = Vec::with_capacity(per_cell.iter().map(Vec::len).sum());
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

    /// The list of the cell holding `p`'s direction from the centroid.
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
        let index = (face * r + cell_of(d[v] / m[axis], r)) * r + cell_of(d[u] / m[axis], r);
        let (lo, hi) = (
            self.offsets[index] as usize,
            self.offsets[index + 1] as usize,
        );
        self.lists[lo..hi].iter().for_each(|&e| visit(e));
    }
}
