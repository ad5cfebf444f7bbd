//! The hierarchy's conservative box tests ([`super::wedge`]) for the eight
//! octants of a node at once, in `f32` lanes, from per-edge bounds computed
//! once at creation.
//!
//! Everything the tests need that does not depend on the box is worked out per
//! potential edge in `f64` when the soft shadows are created and kept rounded
//! outward to `f32` ([`EdgeBounds`]): the edge's extent along each direction
//! tried, how far the wedge may climb beyond it per unit of `reach`, and the
//! unit normals of its adjacent triangles. A split then tests one edge against
//! its node's eight octants (lane `i` is octant `i`, [`Aabb::octant`], except
//! in the AVX kernel's loop over directions, whose lanes are directions) with a
//! few multiply-adds per direction, where the `f64` tests of [`super::wedge`]
//! normalise every direction and project the light afresh for every box.
//!
//! Directions. The penumbra wedge's faces (its own planes, so the ones that
//! separate it from boxes near it): the two planes through the edge that
//! support the light (the edge and one light vertex each, every other vertex on
//! one side), and for each light edge the plane through it and the endpoint
//! that leaves the other endpoint on the light's side; then the three axes for
//! boxes far from it. These are a subset of the `f64` test's directions (which
//! also tries the light's normal, every edge–vertex plane and both endpoints of
//! every light edge), so where the two keep an octant alike the bits cannot
//! differ, and both are conservative on their own: an octant is dropped only
//! when one direction separates it from the wedge, each extent bounded as in
//! [`super::wedge`].
//!
//! Rounding. A direction is rounded to `f32` before the extents along it are
//! computed (in `f64`, from the exact `f64` values of the `f32` positions), so
//! the bounds hold for the very direction the lanes use; they are rounded
//! outward to `f32`. The lanes' own arithmetic (a box's projection, `reach`
//! times a climb) is a handful of `f32` operations on numbers bounded by the
//! scene's and the box's largest coordinates: every comparison carries a margin
//! of [`REL`] times those magnitudes, some 80 times the worst rounding. Scenes
//! or boxes beyond `2^±100` (where `f32` products could overflow or lose
//! everything to underflow) and edges whose bounds are not finite take the
//! `f64` tests instead.

use alloc::vec::Vec;
use glam::DVec3;

use super::edges::Edge;
use super::edges::EdgeGraph;
use super::hemicube::grown_light;
use super::wedge::{Aabb, LightShape, octants_meeting_wedge, octants_seeing_silhouette};
use crate::fallible::{self, OutOfMemory};
use crate::geom::{f32_down as down, f32_up as up};
use crate::prefetch::prefetch;
use crate::simd::edge_record::{
    AXES, COUNT, DIRECTION, DIRECTIONS, GROUP, GROUP_LANES, INVERSE, PLANES, SIDE,
};
use crate::simd::{OCTANT_SIGN as SIGN, Octants8};

/// Octants tested at once.
const LANES: usize = 8;
type Lanes = [f32; LANES];

/// Relative margin of every lane comparison (of the magnitudes involved).
const REL: f32 = 1e-5;

/// Relative slack of the `f64` extents (as [`super::wedge`]'s).
const SLACK: f64 = 1e-9;

/// Relative rounding slack of the pieces' vertices (as the hemicube's).
const PIECE_SLACK: f64 = 1e-9;

/// Largest magnitude (scene or box coordinate) the lanes accept: products of
/// two such stay far inside `f32`, and `REL` times one stays far above the
/// smallest normal `f32`.
const LANE_RANGE: f64 = 1e30;
const LANE_FLOOR: f64 = 1e-30;

/// The box-independent bounds of every potential edge (module docs).
pub(crate) struct EdgeBounds {
    /// `f32`s per edge: [`DIRECTIONS`] + [`GROUP`] per group of directions.
    stride: usize,
    /// The edges kept (those that may be a silhouette from the light), by
    /// slot: lists of the hierarchy hold slots.
    edges: Vec<u32>,
    /// One record per slot.
    records: Vec<f32>,
    /// Per slot: bit 0, the silhouette test goes through `f64` (not exactly
    /// two adjacent triangles, or an unusable plane); bit 1, the wedge test
    /// does (a bound is not finite).
    fallback: Vec<u8>,
    /// Whether the scene's coordinates suit the lanes at all.
    lanes: bool,
    /// Largest coordinate of the occluders and the light.
    scale: f64,
    /// `SLACK * scale + tolerance`: the `f64` tests' absolute slack.
    slack: f64,
    /// The light's lowest point along its normal.
    light_base: DVec3,
}

const SILHOUETTE_F64: u8 = 1;
const WEDGE_F64: u8 = 2;

/// `v` normalised in `f64` and rounded to `f32` (exact in `f64` again), or
/// `None` when it has no direction.
fn unit_f32(v: DVec3) -> Option<DVec3> {
    // Products of f32 coordinates: the squared length stays inside f64.
    let r = crate::geom::normalize_or_zero_f64(v).as_vec3().as_dvec3();
    (r != DVec3::ZERO && r.is_finite()).then_some(r)
}

impl EdgeBounds {
    /// The bounds of those edges of `potential` (of `graph`) that may be a
    /// silhouette from some point of the light (the others can never change a
    /// receiver's counters, [`super::hemicube`] module docs), by slot.
    pub fn new(
        graph: &EdgeGraph,
        shape: &LightShape,
        potential: &[u32],
    ) -> Result<Self, OutOfMemory> {
        let k = shape.vertices.len();
        // A piece of the light has at most two more vertices than the light.
        let directions = 2 + k + 2;
        let stride = DIRECTIONS + GROUP * directions.div_ceil(GROUP_LANES);
        let scale = graph
            .positions
            .iter()
            .map(|p| f64::from(p.abs().max_element()))
            .chain(shape.vertices.iter().map(|v| v.abs().max_element()))
            .fold(0.0f64, f64::max);
        let lanes = scale < LANE_RANGE && (scale > LANE_FLOOR || scale == 0.0);
        // The light grown by its tolerance, cut per edge to the part from
        // which the edge may be a silhouette (as the hemicube's).
        let origin = shape.vertices.iter().fold(DVec3::ZERO, |s, v| s + *v) / k as f64;
        let light_scale = shape
            .vertices
            .iter()
            .fold(origin.abs().max_element(), |m, v| {
                m.max(v.abs().max_element())
            });
        let piece_tol = shape.tolerance + PIECE_SLACK * light_scale;
        let region = grown_light(shape, origin, piece_tol)?;
        let disk = RegionDisk::of(&region, shape.normal);
        let mut edges = Vec::new();
        let mut records = Vec::new();
        let mut fallback = Vec::new();
        let mut record = fallible::filled(0.0f32, stride)?;
        let mut piece = Polygon::default();
        for &e in potential {
            let edge = &graph.edges[e as usize];
            let (light, tol): (&[DVec3], f64) = match silhouette_part(
                graph,
                edge,
                &region,
                disk.as_ref(),
                piece_tol,
                light_scale,
                &mut piece,
            ) {
                Part::None => continue,
                Part::Piece => (piece.points(), piece_tol),
                Part::Whole => (&shape.vertices, shape.tolerance),
            };
            let slack = SLACK * scale + tol;
            fallible::push(
                &mut fallback,
                Self::record(graph, shape, light, e, slack, &mut record),
            )?;
            records.try_reserve(record.len())?;
            records.extend_from_slice(&record);
            fallible::push(&mut edges, e)?;
        }
        Ok(EdgeBounds {
            stride,
            edges,
            records,
            fallback,
            lanes,
            scale,
            slack: SLACK * scale + shape.tolerance.max(piece_tol),
            light_base: shape.vertices[0],
        })
    }

    /// The edge of each slot.
    pub fn edges(&self) -> &[u32] {
        &self.edges
    }

    /// Fills `out` with edge `e`'s record; returns its fallback bits.
    /// `light` is the polygon whose wedge is bounded (the light, or the piece
    /// of it from which the edge may be a silhouette), in the plane of `shape`.
    fn record(
        graph: &EdgeGraph,
        shape: &LightShape,
        light: &[DVec3],
        e: u32,
        slack: f64,
        out: &mut [f32],
    ) -> u8 {
        let edge = &graph.edges[e as usize];
        let at = |i: u32| graph.positions[i as usize].as_dvec3();
        let (a, b) = (at(edge.a), at(edge.b));
        let mut fallback = 0;
        // How far wedge rays may run within a box: `reach = height / inverse`.
        let l0 = shape.vertices[0];
        let (ha, hb) = (shape.normal.dot(a - l0), shape.normal.dot(b - l0));
        let (side, inverse) = if ha > slack && hb > slack {
            (1.0, 1.0 / ha.min(hb))
        } else if ha < -slack && hb < -slack {
            (-1.0, 1.0 / -ha.max(hb))
        } else {
            (0.0, 0.0)
        };
        out[SIDE] = side;
        out[INVERSE] = up(inverse);
        let put = |out: &mut [f32], n: DVec3| -> bool {
            let (ea, eb) = (n.dot(a), n.dot(b));
            let (emin, emax) = (ea.min(eb), ea.max(eb));
            let (mut lmin, mut lmax) = (f64::INFINITY, f64::NEG_INFINITY);
            for v in light {
                let d = n.dot(*v);
                lmin = lmin.min(d);
                lmax = lmax.max(d);
            }
            out[0] = down(emin);
            out[1] = up(emax);
            // The rounding of `reach` times these is folded in (REL of them).
            let grow = 1.0 + f64::from(REL);
            out[2] = up((emax - lmin + slack).max(0.0) * grow);
            out[3] = up((lmax - emin + slack).max(0.0) * grow);
            out[..4].iter().all(|x| x.is_finite())
        };
        // Every direction lane padding until written (the buffer is reused).
        for group in out[DIRECTIONS..].chunks_exact_mut(GROUP) {
            let (normal, rest) = group.split_at_mut(3 * GROUP_LANES);
            let (bounds, reach) = rest.split_at_mut(2 * GROUP_LANES);
            normal.fill(0.0);
            bounds.fill(f32::NAN);
            reach.fill(0.0);
        }
        // Direction `found`'s seven fields: the normal, then `put`'s four.
        let direction = |out: &mut [f32], found: usize, n: DVec3| -> bool {
            let mut fields = [0.0f32; DIRECTION];
            fields[..3].copy_from_slice(&n.as_vec3().to_array());
            let finite = put(&mut fields[3..], n);
            let group = &mut out[DIRECTIONS + GROUP * (found / GROUP_LANES)..][..GROUP];
            for (f, &value) in fields.iter().enumerate() {
                group[f * GROUP_LANES + found % GROUP_LANES] = value;
            }
            finite
        };
        let mut finite = true;
        for axis in 0..3 {
            let n = DVec3::AXES[axis];
            finite &= put(&mut out[AXES + 4 * axis..], n);
        }
        // The adjacent triangles' unit normals and offsets.
        let third = graph.third_of(edge);
        if third.len() == 2 {
            for (j, &v) in third.iter().enumerate() {
                let plane = &mut out[PLANES + 4 * j..][..4];
                match unit_f32((b - a).cross(at(v) - a)) {
                    Some(n) => {
                        plane[..3].copy_from_slice(&n.as_vec3().to_array());
                        // Rounded to nearest: the margin covers it (and the
                        // products below).
                        plane[3] = n.dot(a) as f32;
                        if !plane[3].is_finite() {
                            fallback |= SILHOUETTE_F64;
                        }
                    }
                    None => fallback |= SILHOUETTE_F64,
                }
            }
        } else {
            fallback |= SILHOUETTE_F64;
        }
        // The wedge's faces: two planes through the edge supporting the light,
        let k = light.len();
        let along = b - a;
        let mut found = 0;
        for j in 0..k {
            let n = along.cross(light[j] - a);
            let (mut below, mut above) = (false, false);
            for (m, v) in light.iter().enumerate() {
                if m != j {
                    let s = n.dot(*v - a);
                    below |= s < 0.0;
                    above |= s > 0.0;
                    if below && above {
                        break;
                    }
                }
            }
            if found < 2
                && !(below && above)
                && let Some(n) = unit_f32(n)
            {
                finite &= direction(out, found, n);
                found += 1;
            }
        }
        // (fewer than two when the edge's line passes through the light), and
        // per light edge, the plane through it and the endpoint that keeps
        // the other endpoint on the light's side.
        for j in 0..k {
            let (l0, l1) = (light[j], light[(j + 1) % k]);
            let inside = light[(j + 2) % k];
            let plane = |x: DVec3| (l1 - l0).cross(x - l0);
            let na = plane(a);
            let n = if na.dot(b - l0) * na.dot(inside - l0) >= 0.0 {
                na
            } else {
                plane(b)
            };
            if let Some(n) = unit_f32(n) {
                finite &= direction(out, found, n);
                found += 1;
            }
        }
        out[COUNT] = found as f32;
        if !finite {
            fallback |= WEDGE_F64;
        }
        fallback
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.records.capacity() * core::mem::size_of::<f32>()
            + self.fallback.capacity()
            + self.edges.capacity() * core::mem::size_of::<u32>()
    }

    /// The octants of `parent` (bit `i`: [`Aabb::octant`] `i`) that may meet
    /// the wedge and the silhouette region of the edge of slot `slots[k]`,
    /// into `masks[k]`, for each `k` in `which` (indices into both). Never clears a
    /// bit the `f64` tests would keep for the same directions (module docs).
    pub fn octant_masks(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        parent: &Aabb,
        slots: &[u32],
        which: impl Iterator<Item = usize> + Clone,
        masks: &mut [u8],
    ) {
        let Some(boxes) = self.lane_boxes(shape, parent) else {
            for k in which {
                masks[k] = f64_mask(graph, shape, self.edges[slots[k] as usize], parent);
            }
            return;
        };
        #[cfg(all(target_arch = "x86_64", feature = "std"))]
        if crate::simd::avx_available() {
            let test = |record: &[f32], octants: &Octants8, silhouette: bool, wedge: bool| {
                #[allow(unsafe_code)]
                // SAFETY: the processor runs AVX (checked above).
                unsafe {
                    crate::simd::avx::edge_octants8(record, octants, silhouette, wedge)
                }
            };
            self.lane_masks(graph, shape, parent, &boxes, slots, which, masks, test);
            return;
        }
        self.lane_masks(
            graph,
            shape,
            parent,
            &boxes,
            slots,
            which,
            masks,
            edge_octants,
        );
    }

    /// [`Self::octant_masks`] in lanes, each edge through `test` (the
    /// portable [`edge_octants`] or its AVX twin).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn lane_masks(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        parent: &Aabb,
        octants: &Octants8,
        slots: &[u32],
        which: impl Iterator<Item = usize> + Clone,
        masks: &mut [u8],
        test: impl Fn(&[f32], &Octants8, bool, bool) -> u8,
    ) {
        // The records are scattered: ask for the next ones ahead.
        let mut ahead = which.clone().skip(RECORDS_AHEAD);
        for k in which {
            if let Some(next) = ahead.next() {
                let at = slots[next] as usize * self.stride;
                for line in (0..self.stride).step_by(16) {
                    prefetch(&self.records, at + line);
                }
            }
            let slot = slots[k] as usize;
            let e = self.edges[slot];
            let fallback = self.fallback[slot];
            let record = &self.records[slot * self.stride..][..self.stride];
            masks[k] = if fallback == 0 {
                test(record, octants, true, true)
            } else {
                // Either test in f64 where its bounds could not be kept in f32.
                let edge = &graph.edges[e as usize];
                let silhouette = if fallback & SILHOUETTE_F64 == 0 {
                    test(record, octants, true, false)
                } else {
                    octants_seeing_silhouette(graph, edge, parent)
                };
                if silhouette == 0 || fallback & WEDGE_F64 == 0 {
                    silhouette & test(record, octants, false, true)
                } else {
                    let [a, b] = [edge.a, edge.b].map(|v| graph.positions[v as usize].as_dvec3());
                    silhouette & octants_meeting_wedge(shape, a, b, parent)
                }
            };
        }
    }

    /// The octants' lane data, or `None` when the box is beyond the lanes'
    /// range.
    fn lane_boxes(&self, shape: &LightShape, parent: &Aabb) -> Option<Octants8> {
        let (pc, ph) = (parent.center(), parent.half());
        let magnitude = pc.abs().max_element() + ph.max_element();
        // (NaN fails too.)
        if !self.lanes || magnitude.partial_cmp(&LANE_RANGE) != Some(core::cmp::Ordering::Less) {
            return None;
        }
        let q = 0.5 * ph;
        // Each octant's highest point above, and lowest below, the light's
        // first vertex along its normal (f64, rounded up).
        let n = shape.normal;
        let rad = n.abs().dot(q);
        let mut above = [0.0f32; LANES];
        let mut below = [0.0f32; LANES];
        for i in 0..LANES {
            let c = pc + DVec3::new(SIGN[0][i].into(), SIGN[1][i].into(), SIGN[2][i].into()) * q;
            let mid = n.dot(c - self.light_base);
            above[i] = up((mid + rad).max(0.0));
            below[i] = up((-(mid - rad)).max(0.0));
        }
        let centre = pc.as_vec3().to_array();
        let quarter = [q.x as f32, q.y as f32, q.z as f32];
        // Magnitudes of everything a comparison sums: the box's projection
        // (at most 3 |c| + 3 |h| for a unit direction), the edge's and the
        // light's (at most 3 scale).
        let margin = REL * up(3.0 * magnitude + 3.0 * self.scale) + up(self.slack);
        Some(Octants8 {
            axis_mid: core::array::from_fn(|axis| {
                core::array::from_fn(|i| centre[axis] + SIGN[axis][i] * quarter[axis])
            }),
            above,
            below,
            centre,
            quarter,
            margin,
        })
    }
}

/// Records requested this many edges ahead of the one tested.
const RECORDS_AHEAD: usize = 4;

/// Each octant's centre projected on `n`, and the octants' common radius.
#[inline(always)]
fn project(n: &[f32], octants: &Octants8) -> (Lanes, f32) {
    let t: [f32; 3] = core::array::from_fn(|j| n[j] * octants.quarter[j]);
    let base = n[0] * octants.centre[0] + n[1] * octants.centre[1] + n[2] * octants.centre[2];
    let mid =
        core::array::from_fn(|i| base + SIGN[0][i] * t[0] + SIGN[1][i] * t[1] + SIGN[2][i] * t[2]);
    (mid, t[0].abs() + t[1].abs() + t[2].abs())
}

/// The eight-octant tests of one edge (record layout
/// [`crate::simd::edge_record`]): the octants that may see it as a
/// silhouette (all eight unless `silhouette`) and that may meet its wedge (all
/// eight unless `wedge`). The portable twin of
/// [`crate::simd::avx::edge_octants8`].
fn edge_octants(record: &[f32], octants: &Octants8, silhouette: bool, wedge: bool) -> u8 {
    let mut keep = 0xFF;
    if silhouette {
        keep = silhouette_lanes(record, octants);
        if keep == 0 {
            return 0;
        }
    }
    if wedge {
        keep &= wedge_lanes(record, octants);
    }
    keep
}

/// The wedge test over the eight octants: each direction's extent of the
/// wedge, `[min - reach fall, max + reach climb]` (the climbs' rounding folded
/// in), against each octant's projection `[mid - rad, mid + rad]`, with the
/// margin on both.
#[inline(always)]
fn wedge_lanes(record: &[f32], octants: &Octants8) -> u8 {
    let (side, inverse) = (record[SIDE], record[INVERSE]);
    let reach: Lanes = if side > 0.0 {
        core::array::from_fn(|i| octants.above[i] * inverse)
    } else if side < 0.0 {
        core::array::from_fn(|i| octants.below[i] * inverse)
    } else {
        [f32::MAX; LANES]
    };
    let mut separated = [false; LANES];
    let mut separate = |bounds: &[f32], mid: &Lanes, rad: f32| {
        let (top, bottom) = (bounds[1] + octants.margin, bounds[0] - octants.margin);
        let (climb, fall) = (bounds[2], bounds[3]);
        for i in 0..LANES {
            // `reach` may be f32::MAX: times a zero climb it is 0, times any
            // other +inf (never NaN).
            let hi = top + reach[i] * climb;
            let lo = bottom - reach[i] * fall;
            separated[i] |= (mid[i] - rad > hi) | (mid[i] + rad < lo);
        }
    };
    for (axis, bounds) in record[AXES..AXES + 12].chunks_exact(4).enumerate() {
        separate(bounds, &octants.axis_mid[axis], octants.quarter[axis]);
    }
    let count = record[COUNT] as usize;
    for d in 0..count {
        let group = &record[DIRECTIONS + GROUP * (d / GROUP_LANES)..][..GROUP];
        let field: [f32; DIRECTION] =
            core::array::from_fn(|f| group[f * GROUP_LANES + d % GROUP_LANES]);
        let (mid, rad) = project(&field[..3], octants);
        separate(&field[3..], &mid, rad);
    }
    let mut mask = 0u8;
    for (i, &s) in separated.iter().enumerate() {
        mask |= u8::from(!s) << i;
    }
    mask
}

/// The silhouette-region test over the eight octants: an octant strictly on
/// one side of both adjacent planes has the constant weight (±1 per plane);
/// it is dropped when the two cancel.
#[inline(always)]
fn silhouette_lanes(record: &[f32], octants: &Octants8) -> u8 {
    let mut weight = [0i32; LANES];
    let mut open = [false; LANES];
    for plane in record[PLANES..PLANES + 8].chunks_exact(4) {
        let (mid, rad) = project(&plane[..3], octants);
        for i in 0..LANES {
            let m = mid[i] - plane[3];
            let above = m - rad > octants.margin;
            let below = m + rad < -octants.margin;
            weight[i] += i32::from(above) - i32::from(below);
            open[i] |= !(above | below);
        }
    }
    let mut mask = 0u8;
    for i in 0..LANES {
        mask |= u8::from(open[i] || weight[i] != 0) << i;
    }
    mask
}

/// Most vertices of a part of the light: the light's, plus one per cut.
const PART_VERTICES: usize = super::MAX_LIGHT_VERTICES + 2;

/// A convex polygon of at most [`PART_VERTICES`] points, on the stack.
#[derive(Clone, Copy)]
struct Polygon {
    points: [DVec3; PART_VERTICES],
    len: usize,
}

impl Default for Polygon {
    fn default() -> Self {
        Polygon {
            points: [DVec3::ZERO; PART_VERTICES],
            len: 0,
        }
    }
}

impl Polygon {
    fn points(&self) -> &[DVec3] {
        &self.points[..self.len]
    }

    /// Sutherland–Hodgman: `poly` cut to `f(x) >= 0` for the affine `f` (at
    /// most one more point than `poly`), into `self`.
    fn clip(&mut self, poly: &[DVec3], f: impl Fn(DVec3) -> f64) {
        self.len = 0;
        for i in 0..poly.len() {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            let (fp, fq) = (f(p), f(q));
            if fp >= 0.0 {
                self.points[self.len] = p;
                self.len += 1;
            }
            if (fp >= 0.0) != (fq >= 0.0) {
                self.points[self.len] = p + (q - p) * (fp / (fp - fq));
                self.len += 1;
            }
        }
    }
}

/// Which part of the light an edge's wedge is bounded with.
enum Part {
    /// No point of the light sees the edge as a silhouette.
    None,
    /// One convex piece does (written to the caller's polygon).
    Piece,
    /// The whole light (two pieces, another adjacency, or degenerate planes).
    Whole,
}

/// [`super::hemicube::silhouette_pieces`] without allocation: the grown light
/// `region` clipped by both adjacent triangles' planes one way or the other,
/// with the same slack (same arithmetic, so the same pieces).
fn silhouette_part(
    graph: &EdgeGraph,
    edge: &Edge,
    region: &[DVec3],
    disk: Option<&RegionDisk>,
    tol: f64,
    scale: f64,
    piece: &mut Polygon,
) -> Part {
    let Some((a, across, plane_slack)) = adjacent_planes(graph, edge, tol, scale) else {
        return Part::Whole;
    };
    // Most edges of a mesh face the light from both triangles or from
    // neither: decided from the region's disk with one product per plane,
    // and only where that is unsure from each vertex below.
    if disk.is_some_and(|disk| disk.beyond_both_sides(a, across, plane_slack)) {
        return Part::None;
    }
    let normals = across.map(crate::geom::normalize_f64);
    if !normals.iter().all(|m| m.is_finite()) {
        return Part::Whole;
    }
    // Where every vertex of the region is strictly outside one of the two
    // half-planes of a side, that side's piece is empty (the clip keeps no
    // vertex and meets no crossing): the common case, decided without
    // clipping.
    let mut outside = [[true; 2]; 2];
    for &l in region {
        for (j, n) in normals.iter().enumerate() {
            let d = n.dot(l - a);
            outside[0][j] &= d + plane_slack < 0.0;
            outside[1][j] &= -d + plane_slack < 0.0;
        }
    }
    let mut found = 0;
    let mut once = Polygon::default();
    for (k, side) in [1.0, -1.0].into_iter().enumerate() {
        if outside[k][0] || outside[k][1] {
            continue;
        }
        once.clip(region, |l| side * normals[0].dot(l - a) + plane_slack);
        let mut twice = Polygon::default();
        twice.clip(once.points(), |l| {
            side * normals[1].dot(l - a) + plane_slack
        });
        if twice.len > 0 {
            found += 1;
            *piece = twice;
        }
    }
    match found {
        0 => Part::None,
        1 => Part::Piece,
        _ => Part::Whole,
    }
}

/// The planes of the two triangles on `edge` (through its first end `a`,
/// normals `(b - a) × (v - a)` at any length) and the slack of
/// [`silhouette_part`]'s tests; `None` unless exactly two triangles share it.
pub(super) fn adjacent_planes(
    graph: &EdgeGraph,
    edge: &Edge,
    tol: f64,
    scale: f64,
) -> Option<(DVec3, [DVec3; 2], f64)> {
    let third = graph.third_of(edge);
    if third.len() != 2 {
        return None;
    }
    let at = |i: u32| graph.positions[i as usize].as_dvec3();
    let (a, b) = (at(edge.a), at(edge.b));
    let slack = SLACK * scale.max(a.abs().max(b.abs()).max_element()) + tol;
    Some((
        a,
        [third[0], third[1]].map(|v| (b - a).cross(at(v) - a)),
        slack,
    ))
}

/// A disk in the light's plane (and a slab about it) holding every vertex of
/// the grown light: enough to show, with one product per plane, that the
/// whole light lies strictly beyond a plane through an edge, which is the
/// common answer of [`silhouette_part`]'s test over the vertices.
#[derive(Clone, Copy, Debug)]
struct RegionDisk {
    centre: DVec3,
    /// Unit normal of the light's plane.
    normal: DVec3,
    /// Largest distance of a vertex from the centre within the plane, and
    /// along its normal, each rounded up.
    radius: f64,
    thickness: f64,
}

impl RegionDisk {
    /// The disk of `region` about its mean, in the plane of unit `normal`
    /// (normalised here); `None` when either is not finite.
    fn of(region: &[DVec3], normal: DVec3) -> Option<Self> {
        let normal = crate::geom::normalize_f64(normal);
        if region.is_empty() || !normal.is_finite() {
            return None;
        }
        let centre = region.iter().fold(DVec3::ZERO, |s, l| s + *l) / region.len() as f64;
        let (mut radius, mut thickness) = (0.0f64, 0.0f64);
        for &l in region {
            let d = l - centre;
            let height = d.dot(normal);
            thickness = thickness.max(height.abs());
            radius = radius.max(crate::geom::length_f64(d - height * normal));
        }
        // The differences and products above round by a few units of the
        // coordinates' magnitude: far less than this.
        let pad = DISK_ROUNDING * (centre.abs().max_element() + radius + thickness);
        let disk = RegionDisk {
            centre,
            normal,
            radius: radius + pad,
            thickness: thickness + pad,
        };
        (centre.is_finite() && disk.radius.is_finite() && disk.thickness.is_finite())
            .then_some(disk)
    }

    /// Whether every point `l` of the region has `n̂·(l - a) + slack < 0` for
    /// one of the two planes `n` of `across` (through `a`, any length), and
    /// `-n̂·(l - a) + slack < 0` for one of them: then [`silhouette_part`]'s
    /// test over the vertices finds both sides empty. The bound
    /// `n·(l - c) <= |n across the normal|·radius + |n·normal|·thickness`
    /// holds for every point of the disk's slab, and the margin of
    /// [`DISK_ROUNDING`] times the distances covers the rounding of this
    /// test and of the one over the vertices, so a `true` here is a `true`
    /// there. Not finite planes give `false`.
    fn beyond_both_sides(&self, a: DVec3, across: [DVec3; 2], slack: f64) -> bool {
        let to_centre = self.centre - a;
        let rounding =
            DISK_ROUNDING * (to_centre.abs().max_element() + self.radius + self.thickness);
        let (mut front, mut back) = (false, false);
        for n in across {
            let squared = n.length_squared();
            let along = n.dot(self.normal);
            // An upper bound on |n| within the plane: the difference cancels
            // for a plane parallel to the light's, so it is grown.
            let within =
                crate::geom::sqrt((squared - along * along).max(0.0) + DISK_ROUNDING * squared);
            let spread = within * self.radius
                + along.abs() * self.thickness
                + crate::geom::sqrt(squared) * (slack + rounding);
            let middle = n.dot(to_centre);
            front |= middle + spread < 0.0;
            back |= spread - middle < 0.0;
        }
        front && back
    }
}

/// Relative margin of [`RegionDisk`]'s bounds over `f64` rounding (a few
/// units of `2^-53` per operation).
const DISK_ROUNDING: f64 = 1e-12;

/// The `f64` tests of [`super::wedge`] for one edge and the octants of `parent`.
fn f64_mask(graph: &EdgeGraph, shape: &LightShape, e: u32, parent: &Aabb) -> u8 {
    let edge = &graph.edges[e as usize];
    let mask = octants_seeing_silhouette(graph, edge, parent);
    if mask == 0 {
        return 0;
    }
    let [a, b] = [edge.a, edge.b].map(|v| graph.positions[v as usize].as_dvec3());
    mask & octants_meeting_wedge(shape, a, b, parent)
}

#[cfg(test)]
mod tests {
    use super::super::SplitMix64;
    use super::*;
    use glam::Vec3;

    /// The lanes against the `f64` tests of [`super::super::wedge`] with the
    /// same part of the light, on random edges (pairs of triangles, lone
    /// triangles), lights and boxes, some far from the origin: the lanes never
    /// clear an octant the `f64` tests keep (both conservative, the lanes with
    /// wider margins and a subset of the directions), and they clear most of
    /// what the `f64` tests clear.
    #[test]
    fn lanes_keep_every_octant_the_f64_tests_keep() {
        let mut rng = SplitMix64::new(7);
        let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
        let (mut f64_cleared, mut both_cleared, mut edges_tested) = (0usize, 0usize, 0usize);
        for round in 0..600 {
            let offset = if round % 3 == 0 {
                DVec3::new(r(-1e3, 1e3), r(-1e3, 1e3), r(-1e3, 1e3))
            } else {
                DVec3::ZERO
            };
            let mut v = || (DVec3::new(r(-1.0, 1.0), r(-1.0, 1.0), r(0.5, 2.0)) + offset).as_vec3();
            let (a, b, c, d) = (v(), v(), v(), v());
            let triangles: Vec<[Vec3; 3]> = if round % 5 == 0 {
                alloc::vec![[a, b, c]]
            } else {
                alloc::vec![[a, b, c], [b, a, d]]
            };
            let graph = EdgeGraph::new(triangles.into_iter());
            let (z, tilt, size) = (r(2.5, 4.0), r(-1.0, 1.0), r(0.05, 1.0));
            let sides = if round % 2 == 0 { 4 } else { 6 };
            let vertices: Vec<DVec3> = (0..sides)
                .map(|i| {
                    let angle = core::f64::consts::TAU * i as f64 / sides as f64;
                    let (x, y) = (size * angle.cos(), size * angle.sin());
                    (DVec3::new(x, y, z + x * tilt) + offset)
                        .as_vec3()
                        .as_dvec3()
                })
                .collect();
            let shape = LightShape {
                vertices,
                normal: DVec3::new(-tilt, 0.0, 1.0).normalize(),
                tolerance: 1e-6 * (1.0 + offset.abs().max_element()),
            };
            let potential: Vec<u32> = (0..graph.edges.len() as u32).collect();
            let bounds = EdgeBounds::new(&graph, &shape, &potential).unwrap();
            let lo = DVec3::new(r(-3.0, 1.0), r(-3.0, 1.0), r(-1.0, 1.5)) + offset;
            let parent = Aabb {
                min: lo,
                max: lo + DVec3::splat(r(0.01, 3.0)),
            };
            let slots: Vec<u32> = (0..bounds.edges().len() as u32).collect();
            let mut masks = alloc::vec![0u8; slots.len()];
            bounds.octant_masks(&graph, &shape, &parent, &slots, 0..slots.len(), &mut masks);
            // The same part of the light the bounds were made with.
            let k = shape.vertices.len();
            let origin = shape.vertices.iter().fold(DVec3::ZERO, |s, v| s + *v) / k as f64;
            let light_scale = shape
                .vertices
                .iter()
                .fold(origin.abs().max_element(), |m, v| {
                    m.max(v.abs().max_element())
                });
            let piece_tol = shape.tolerance + PIECE_SLACK * light_scale;
            let region = grown_light(&shape, origin, piece_tol).unwrap();
            let disk = RegionDisk::of(&region, shape.normal);
            for (slot, &e) in bounds.edges().iter().enumerate() {
                let edge = &graph.edges[e as usize];
                let mut piece = Polygon::default();
                let part = silhouette_part(
                    &graph,
                    edge,
                    &region,
                    disk.as_ref(),
                    piece_tol,
                    light_scale,
                    &mut piece,
                );
                let light = match part {
                    Part::None => unreachable!("slots hold only edges with a part"),
                    Part::Piece => LightShape {
                        vertices: piece.points().to_vec(),
                        normal: shape.normal,
                        tolerance: piece_tol,
                    },
                    Part::Whole => shape.clone(),
                };
                let [pa, pb] = [edge.a, edge.b].map(|v| graph.positions[v as usize].as_dvec3());
                let reference = octants_seeing_silhouette(&graph, edge, &parent)
                    & octants_meeting_wedge(&light, pa, pb, &parent);
                assert_eq!(
                    masks[slot] & reference,
                    reference,
                    "round {round} edge {e}: lanes {:08b} drop an octant of {reference:08b}",
                    masks[slot]
                );
                f64_cleared += (!reference).count_ones() as usize;
                both_cleared += (!masks[slot]).count_ones() as usize;
                edges_tested += 1;
            }
        }
        // Not vacuous: many edges, many cleared octants, and the lanes clear
        // nearly what the f64 tests (more directions, tighter margins) clear.
        assert!(edges_tested > 1000, "{edges_tested}");
        assert!(f64_cleared > 2000, "{f64_cleared}");
        assert!(
            both_cleared * 100 >= 90 * f64_cleared,
            "lanes clear {both_cleared} of {f64_cleared}"
        );
    }

    /// The AVX kernel gives the portable twin's bits on every edge, box and
    /// combination of the two tests (where the processor runs AVX).
    #[cfg(all(target_arch = "x86_64", feature = "std"))]
    #[test]
    fn avx_octants_equal_the_portable_ones() {
        if !crate::simd::avx_available() {
            return;
        }
        let mut rng = SplitMix64::new(21);
        let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
        let mut compared = 0usize;
        // Fewer rounds under Miri (`make miri`), which runs this for the AVX
        // kernel's unsafe loads and stores.
        let rounds = if cfg!(miri) { 4 } else { 300 };
        // Records whose directions reach a second and a third group of lanes.
        let (mut second, mut third) = (0usize, 0usize);
        for round in 0..rounds {
            // Edges below the light, above it (the other reach) and across
            // its plane (no reach).
            let (low, high) = [(0.3, 2.0), (0.3, 2.0), (4.5, 7.0), (0.3, 7.0)][round % 4];
            let mut v = || {
                Vec3::new(
                    r(-1.0, 1.0) as f32,
                    r(-1.0, 1.0) as f32,
                    r(low, high) as f32,
                )
            };
            let (a, b, c, d) = (v(), v(), v(), v());
            let graph = EdgeGraph::new([[a, b, c], [b, a, d]].into_iter());
            let (z, tilt, size) = (r(2.5, 4.0), r(-1.0, 1.0), r(0.05, 1.0));
            // Triangles and quads (one group of lanes, some padded), 7- and
            // 16-gons (up to 2 + k directions, a second and a third group).
            let k = [4, 16, 3, 7, 4][round % 5];
            let shape = LightShape {
                vertices: (0..k)
                    .map(|j| {
                        let angle = core::f64::consts::TAU * (j as f64 + 0.5) / k as f64;
                        let (x, y) = (angle.cos(), angle.sin());
                        DVec3::new(size * x, size * y, z + size * x * tilt)
                            .as_vec3()
                            .as_dvec3()
                    })
                    .collect(),
                normal: DVec3::new(-tilt, 0.0, 1.0).normalize(),
                tolerance: 1e-6,
            };
            let potential: Vec<u32> = (0..graph.edges.len() as u32).collect();
            let bounds = EdgeBounds::new(&graph, &shape, &potential).unwrap();
            let lo = DVec3::new(r(-3.0, 1.0), r(-3.0, 1.0), r(-1.0, 3.0));
            let parent = Aabb {
                min: lo,
                max: lo + DVec3::splat(r(0.01, 3.0)),
            };
            let octants = bounds.lane_boxes(&shape, &parent).expect("in range");
            for slot in 0..bounds.edges().len() {
                let record = &bounds.records[slot * bounds.stride..][..bounds.stride];
                second += usize::from(record[COUNT] > GROUP_LANES as f32);
                third += usize::from(record[COUNT] > 2.0 * GROUP_LANES as f32);
                for (silhouette, wedge) in [(true, true), (true, false), (false, true)] {
                    let portable = edge_octants(record, &octants, silhouette, wedge);
                    #[allow(unsafe_code)]
                    // SAFETY: the processor runs AVX (checked above).
                    let avx = unsafe {
                        crate::simd::avx::edge_octants8(record, &octants, silhouette, wedge)
                    };
                    assert_eq!(portable, avx, "round {round} slot {slot}");
                    compared += 1;
                }
            }
        }
        // Up to five edges and three combinations per round.
        assert!(compared >= 10 * rounds, "{compared}");
        if !cfg!(miri) {
            assert!(second > 0 && third > 0, "{second} {third}");
        }
    }

    /// The allocation-free pieces are those of the hemicube's function.
    #[test]
    fn silhouette_part_matches_silhouette_pieces() {
        let mut rng = SplitMix64::new(3);
        let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
        let mut seen = [0usize; 3];
        for _ in 0..500 {
            let mut v = || Vec3::new(r(-1.0, 1.0) as f32, r(-1.0, 1.0) as f32, r(0.0, 2.5) as f32);
            let (a, b, c, d) = (v(), v(), v(), v());
            let graph = EdgeGraph::new([[a, b, c], [b, a, d]].into_iter());
            let shape = LightShape {
                vertices: [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                    .iter()
                    .map(|&(x, y): &(f64, f64)| DVec3::new(0.5 * x, 0.5 * y, 3.0))
                    .collect(),
                normal: DVec3::Z,
                tolerance: 1e-6,
            };
            let region = grown_light(&shape, DVec3::new(0.0, 0.0, 3.0), 1e-6).unwrap();
            for edge in &graph.edges {
                let mut piece = Polygon::default();
                let part = silhouette_part(&graph, edge, &region, None, 1e-6, 3.0, &mut piece);
                let pieces =
                    super::super::hemicube::silhouette_pieces(&graph, edge, &region, 1e-6, 3.0);
                match (part, pieces) {
                    (Part::Whole, None) => seen[2] += 1,
                    (Part::None, Some(p)) if p.is_empty() => seen[0] += 1,
                    (Part::Piece, Some(p)) if p.len() == 1 => {
                        assert_eq!(piece.points(), &p[0][..]);
                        seen[1] += 1;
                    }
                    (Part::Whole, Some(p)) if p.len() == 2 => seen[2] += 1,
                    (_, p) => panic!("part and pieces differ: {p:?}"),
                }
            }
        }
        assert!(seen.iter().all(|&n| n > 50), "{seen:?}");
    }

    /// The disk's quick answer is the vertex test's: wherever it says no
    /// point of the light sees the edge as a silhouette, the test over the
    /// region's vertices (without the disk) says so too. Random edges and
    /// lights, with triangles in and parallel to the light's plane, edges
    /// beside the light and lights from a speck to wider than the mesh.
    #[test]
    fn region_disk_decides_as_the_vertices() {
        let mut rng = SplitMix64::new(11);
        let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
        let (mut quick, mut slow_none, mut others) = (0usize, 0usize, 0usize);
        for round in 0..4000 {
            // A quad light of random size and tilt, at height 2.
            let size = [1e-4, 0.05, 0.5, 3.0][round % 4];
            let tilt = r(-1.2, 1.2);
            let normal = DVec3::new(tilt.sin(), 0.0, tilt.cos());
            let (u, v) = normal.any_orthonormal_pair();
            let centre = DVec3::new(r(-0.5, 0.5), r(-0.5, 0.5), 2.0);
            let shape = LightShape {
                vertices: [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                    .iter()
                    .map(|&(x, y): &(f64, f64)| centre + 0.5 * size * (x * u + y * v))
                    .collect(),
                normal,
                tolerance: 1e-6,
            };
            let tol = 1e-6;
            let region = grown_light(&shape, centre, tol).unwrap();
            let disk = RegionDisk::of(&region, shape.normal).unwrap();
            // Two triangles on a random edge: some flat in the light's plane
            // or parallel to it, some with the edge near the light.
            let mut p = || Vec3::new(r(-1.0, 1.0) as f32, r(-1.0, 1.0) as f32, r(0.0, 2.5) as f32);
            let (a, b, mut c, mut d) = (p(), p(), p(), p());
            match round % 5 {
                0 => {
                    // Parallel to the light's plane (as far as f32 allows).
                    let lift = |x: Vec3| x - (x - a).dot(normal.as_vec3()) * normal.as_vec3();
                    c = lift(c);
                    d = lift(d);
                }
                1 => {
                    // The far corners in the light's plane.
                    c = (centre + 0.7 * size * u).as_vec3();
                    d = (centre - 0.6 * size * v).as_vec3();
                }
                2 | 3 => {
                    // A gentle fold, as on a smooth mesh: `d` is `c` turned
                    // about the edge by nearly half a turn.
                    let axis = (b - a).normalize();
                    let offset = c - a;
                    let along = axis * offset.dot(axis);
                    let bend = r(-0.3, 0.3) as f32;
                    let across = offset - along;
                    let turned = -across * bend.cos() + axis.cross(across) * bend.sin();
                    d = a + along * 0.5 + turned;
                }
                _ => {}
            }
            let graph = EdgeGraph::new([[a, b, c], [b, a, d]].into_iter());
            for edge in &graph.edges {
                let mut piece = Polygon::default();
                let with =
                    silhouette_part(&graph, edge, &region, Some(&disk), tol, 3.0, &mut piece);
                let without = silhouette_part(&graph, edge, &region, None, tol, 3.0, &mut piece);
                match (with, without) {
                    (Part::None, Part::None) => {
                        let (a, across, slack) = adjacent_planes(&graph, edge, tol, 3.0)
                            .expect("only an edge of two triangles has no part");
                        if disk.beyond_both_sides(a, across, slack) {
                            quick += 1;
                        } else {
                            slow_none += 1;
                        }
                    }
                    (Part::None, _) => {
                        panic!("round {round}: the disk drops an edge the vertices keep")
                    }
                    (_, Part::None) => {
                        panic!("round {round}: the disk keeps an edge the vertices drop")
                    }
                    _ => others += 1,
                }
            }
        }
        // Not vacuous: the disk decides most of the edges that no point sees
        // as a silhouette, and leaves some to the vertices.
        assert!(quick > 1000, "{quick}");
        assert!(slow_none > 10, "{slow_none}");
        assert!(others > 1000, "{others}");
    }
}
