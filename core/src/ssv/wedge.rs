//! Penumbra wedges and silhouette regions, as conservative tests against
//! axis-aligned boxes (a point is a box of zero extent).
//!
//! The penumbra wedge of an edge `e` for the convex light `L` is
//! `W = { p : conv({p} ∪ L) meets e }`. Writing a point of the pyramid as
//! `x = (p + t l) / (1 + t)` gives `W = { x + t (x - l) : x ∈ e, l ∈ L, t >= 0 }`,
//! which is convex (an affine image of a convex set, followed by a union of rays
//! that preserves convexity because the parametrisation is jointly convex in
//! `(x, l)` over the segment and the polygon). An edge can change the depth
//! complexity of a receiver `p` over the light only if `p ∈ W` (the triangle
//! `(p, c, s)` swept by the integration lies in `conv({p} ∪ L)`).
//!
//! Along a direction `n`, `W`'s extent is `[lo, hi]` with
//! `hi = max_e n·x` when `max_e n·x <= min_L n·l` and `+∞` otherwise (a ray
//! `x + t (x - l)` then climbs without bound), and symmetrically for `lo`. Within
//! a box the rays are short: heights above the light's plane grow by `1 + t`, so
//! for an edge strictly on one side of that plane `t` is bounded by the box's
//! largest height over the edge's smallest, and `hi <= max_e n·x + t_max ·
//! max(0, max_e n·x - min_L n·l)`. That makes the wedge's own faces (where the
//! two sides are equal up to rounding) usable as separating planes. A box
//! whose extent along `n` is disjoint from that interval (beyond a relative
//! margin that covers `f64` rounding) is separated from the wedge. The directions
//! tried are the planes bounding the wedge: the three axes, the light's normal,
//! the planes through the edge and each light vertex (the two tangent ones among
//! them), and the planes through each endpoint and each light edge.
//!
//! The silhouette region of the edge: the weight (sum over adjacent triangles of
//! the orientation of the third vertex against the plane through `p` and the edge)
//! changes sign only across the triangles' planes. A box strictly on one side of
//! every adjacent triangle's plane has one constant weight; when that weight is
//! zero no point of the box sees the edge as a silhouette.

use glam::DVec3;

use super::edges::{Edge, EdgeGraph};

/// An axis-aligned box in `f64`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    pub fn half(&self) -> DVec3 {
        0.5 * (self.max - self.min)
    }

    /// Child `i` of the octree split at the centre (bit 0: x, 1: y, 2: z).
    pub fn octant(&self, i: usize) -> Aabb {
        let c = self.center();
        let pick = |bit: usize, lo: f64, mid: f64, hi: f64| {
            if i >> bit & 1 == 0 {
                (lo, mid)
            } else {
                (mid, hi)
            }
        };
        let (x0, x1) = pick(0, self.min.x, c.x, self.max.x);
        let (y0, y1) = pick(1, self.min.y, c.y, self.max.y);
        let (z0, z1) = pick(2, self.min.z, c.z, self.max.z);
        Aabb {
            min: DVec3::new(x0, y0, z0),
            max: DVec3::new(x1, y1, z1),
        }
    }

    /// Which octant holds `p` (points on a split plane go to the upper child).
    pub fn octant_of(&self, p: DVec3) -> usize {
        let c = self.center();
        usize::from(p.x >= c.x) | usize::from(p.y >= c.y) << 1 | usize::from(p.z >= c.z) << 2
    }

    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}

/// Relative slack of every conservative test: far above `f64` rounding of the
/// few operations involved, far below any geometric feature that matters.
const SLACK: f64 = 1e-9;

/// The light as the wedge tests need it.
#[derive(Clone, Debug)]
pub(crate) struct LightShape {
    pub vertices: alloc::vec::Vec<DVec3>,
    pub normal: DVec3,
    /// Absolute slack for samples off the polygon (the light's tolerance).
    pub tolerance: f64,
}

/// Whether the box may meet the wedge of `(a, b)` (false: provably not).
#[cfg(test)]
pub(crate) fn box_meets_wedge(light: &LightShape, a: DVec3, b: DVec3, bx: &Aabb) -> bool {
    let (c, h) = (bx.center(), bx.half());
    let scale = a.abs().max(b.abs()).max(c.abs() + h).max_element().max(
        light
            .vertices
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs().max_element())),
    );
    // How far along its ray `x + t (x - l)` a wedge point inside the box can be:
    // heights above the light's plane scale by `1 + t`, so with the edge
    // strictly on one side, `t <= (box's largest height) / (edge's smallest)`.
    let plane_slack = SLACK * scale + light.tolerance;
    let l0 = light.vertices[0];
    let (ha, hb) = (light.normal.dot(a - l0), light.normal.dot(b - l0));
    let (hbox_mid, hbox_rad) = (light.normal.dot(c - l0), light.normal.abs().dot(h));
    let reach = if ha > plane_slack && hb > plane_slack {
        (hbox_mid + hbox_rad).max(0.0) / ha.min(hb)
    } else if ha < -plane_slack && hb < -plane_slack {
        (-(hbox_mid - hbox_rad)).max(0.0) / (-ha.max(hb))
    } else {
        f64::INFINITY
    };
    let separated = |n: DVec3| -> bool {
        let len = n.length();
        if len.is_nan() || len <= 0.0 {
            return false;
        }
        let n = n / len;
        let slack = SLACK * scale + light.tolerance;
        let (ea, eb) = (n.dot(a), n.dot(b));
        let (emin, emax) = (ea.min(eb), ea.max(eb));
        let (mut lmin, mut lmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in &light.vertices {
            let d = n.dot(*v);
            lmin = lmin.min(d);
            lmax = lmax.max(d);
        }
        let (bmid, brad) = (n.dot(c), n.abs().dot(h));
        // The wedge's extent along n: a ray x + t (x - l) climbs at rate
        // n·(x - l) <= emax - lmin (plus rounding) for at most `reach`.
        let climb = (emax - lmin + slack).max(0.0);
        let hi = if climb == 0.0 {
            emax
        } else {
            emax + reach * climb
        };
        let fall = (lmax - emin + slack).max(0.0);
        let lo = if fall == 0.0 {
            emin
        } else {
            emin - reach * fall
        };
        bmid - brad > hi + slack || bmid + brad < lo - slack
    };
    if separated(DVec3::X) || separated(DVec3::Y) || separated(DVec3::Z) || separated(light.normal)
    {
        return false;
    }
    let k = light.vertices.len();
    for i in 0..k {
        let (l0, l1) = (light.vertices[i], light.vertices[(i + 1) % k]);
        if separated((b - a).cross(l0 - a))
            || separated((l1 - l0).cross(a - l0))
            || separated((l1 - l0).cross(b - l0))
        {
            return false;
        }
    }
    true
}

/// Whether some point of the box may have a non-zero weight for `edge` (false:
/// the box is strictly on one side of every adjacent plane and the weight there
/// is zero).
#[cfg(test)]
pub(crate) fn box_may_see_silhouette(graph: &EdgeGraph, edge: &Edge, bx: &Aabb) -> bool {
    let p = |i: u32| graph.positions[i as usize].as_dvec3();
    let (a, b) = (p(edge.a), p(edge.b));
    let (c, h) = (bx.center(), bx.half());
    let mut weight = 0i32;
    for &v in graph.third_of(edge) {
        let n = (b - a).cross(p(v) - a);
        let mid = n.dot(c - a);
        let rad = n.abs().dot(h);
        let slack = SLACK * n.abs().dot((c - a).abs() + h + b.abs() + a.abs());
        if mid - rad > slack {
            weight += 1;
        } else if mid + rad < -slack {
            weight -= 1;
        } else {
            return true;
        }
    }
    weight != 0
}

/// `box_meets_wedge` (the tests' one-box twin) for the eight octants of
/// `parent` at once (bit `i`: octant `i`, [`Aabb::octant`]), sharing each
/// direction's wedge extent among them. Each octant's own reach bounds its
/// rays; the slack uses the parent's scale (at least the octant's), so a bit
/// is clear only where the single-box test would also say no, up to that
/// larger slack.
pub(crate) fn octants_meeting_wedge(light: &LightShape, a: DVec3, b: DVec3, parent: &Aabb) -> u8 {
    let (pc, ph) = (parent.center(), parent.half());
    let scale = a.abs().max(b.abs()).max(pc.abs() + ph).max_element().max(
        light
            .vertices
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs().max_element())),
    );
    let slack = SLACK * scale + light.tolerance;
    let children: [Aabb; 8] = core::array::from_fn(|i| parent.octant(i));
    let l0 = light.vertices[0];
    let (ha, hb) = (light.normal.dot(a - l0), light.normal.dot(b - l0));
    let reach: [f64; 8] = core::array::from_fn(|i| {
        let (c, h) = (children[i].center(), children[i].half());
        let (hbox_mid, hbox_rad) = (light.normal.dot(c - l0), light.normal.abs().dot(h));
        if ha > slack && hb > slack {
            (hbox_mid + hbox_rad).max(0.0) / ha.min(hb)
        } else if ha < -slack && hb < -slack {
            (-(hbox_mid - hbox_rad)).max(0.0) / (-ha.max(hb))
        } else {
            f64::INFINITY
        }
    });
    let mut mask = 0xFFu8;
    let separate = |n: DVec3, mask: &mut u8| {
        let len = crate::geom::length_f64(n);
        if len.is_nan() || len <= 0.0 {
            return;
        }
        let n = n / len;
        let (ea, eb) = (n.dot(a), n.dot(b));
        let (emin, emax) = (ea.min(eb), ea.max(eb));
        let (mut lmin, mut lmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in &light.vertices {
            let d = n.dot(*v);
            lmin = lmin.min(d);
            lmax = lmax.max(d);
        }
        let climb = (emax - lmin + slack).max(0.0);
        let fall = (lmax - emin + slack).max(0.0);
        let brad = n.abs().dot(children[0].half());
        for (i, child) in children.iter().enumerate() {
            if *mask >> i & 1 == 0 {
                continue;
            }
            let hi = if climb == 0.0 {
                emax
            } else {
                emax + reach[i] * climb
            };
            let lo = if fall == 0.0 {
                emin
            } else {
                emin - reach[i] * fall
            };
            let bmid = n.dot(child.center());
            if bmid - brad > hi + slack || bmid + brad < lo - slack {
                *mask &= !(1 << i);
            }
        }
    };
    for n in [DVec3::X, DVec3::Y, DVec3::Z, light.normal] {
        separate(n, &mut mask);
        if mask == 0 {
            return 0;
        }
    }
    let k = light.vertices.len();
    for i in 0..k {
        let (l0, l1) = (light.vertices[i], light.vertices[(i + 1) % k]);
        for n in [
            (b - a).cross(l0 - a),
            (l1 - l0).cross(a - l0),
            (l1 - l0).cross(b - l0),
        ] {
            separate(n, &mut mask);
            if mask == 0 {
                return 0;
            }
        }
    }
    mask
}

/// `box_may_see_silhouette` (the tests' one-box twin) for the eight octants
/// of `parent` at once (bit `i`: octant `i`), the same test per octant.
pub(crate) fn octants_seeing_silhouette(graph: &EdgeGraph, edge: &Edge, parent: &Aabb) -> u8 {
    let p = |i: u32| graph.positions[i as usize].as_dvec3();
    let (a, b) = (p(edge.a), p(edge.b));
    let children: [Aabb; 8] = core::array::from_fn(|i| parent.octant(i));
    let mut weight = [0i32; 8];
    let mut open = 0u8;
    for &v in graph.third_of(edge) {
        let n = (b - a).cross(p(v) - a);
        for (i, child) in children.iter().enumerate() {
            if open >> i & 1 == 1 {
                continue;
            }
            let (c, h) = (child.center(), child.half());
            let mid = n.dot(c - a);
            let rad = n.abs().dot(h);
            let slack = SLACK * n.abs().dot((c - a).abs() + h + b.abs() + a.abs());
            if mid - rad > slack {
                weight[i] += 1;
            } else if mid + rad < -slack {
                weight[i] -= 1;
            } else {
                open |= 1 << i;
            }
        }
    }
    (0..8).fold(open, |m, i| m | u8::from(weight[i] != 0) << i)
}

#[cfg(test)]
mod tests {
    use super::super::SplitMix64;
    use super::*;
    use glam::Vec3;

    /// The eight-octant masks against the single-box tests on random edges,
    /// lights and boxes: the silhouette mask is the same test per octant
    /// (equal), the wedge mask may only keep more (its slack uses the parent's
    /// scale), and it keeps every octant the single-box test keeps.
    #[test]
    fn octant_masks_agree_with_single_boxes() {
        let mut rng = SplitMix64::new(11);
        let mut r = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f64() as f32;
        let (mut kept, mut extra) = (0usize, 0usize);
        for _ in 0..400 {
            let mut v = || Vec3::new(r(-1.0, 1.0), r(-1.0, 1.0), r(0.5, 2.0));
            let (a, b, c, d) = (v(), v(), v(), v());
            let graph = EdgeGraph::new([[a, b, c], [b, a, d]].into_iter());
            let (z, tilt, size) = (r(2.5, 4.0), r(-1.0, 1.0), r(0.1, 1.0));
            let light = LightShape {
                vertices: [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                    .iter()
                    .map(|&(x, y): &(f64, f64)| {
                        let x = x * f64::from(size);
                        DVec3::new(x, y * f64::from(size), f64::from(z) + x * f64::from(tilt))
                    })
                    .collect(),
                normal: DVec3::new(-f64::from(tilt), 0.0, 1.0).normalize(),
                tolerance: 1e-6,
            };
            let lo = DVec3::new(f64::from(r(-3.0, 1.0)), f64::from(r(-3.0, 1.0)), -1.0);
            let parent = Aabb {
                min: lo,
                max: lo + DVec3::splat(f64::from(r(0.05, 3.0))),
            };
            for edge in &graph.edges {
                let (pa, pb) = (
                    graph.positions[edge.a as usize].as_dvec3(),
                    graph.positions[edge.b as usize].as_dvec3(),
                );
                let sil = octants_seeing_silhouette(&graph, edge, &parent);
                let wedge = octants_meeting_wedge(&light, pa, pb, &parent);
                for i in 0..8 {
                    let child = parent.octant(i);
                    assert_eq!(
                        sil >> i & 1 == 1,
                        box_may_see_silhouette(&graph, edge, &child)
                    );
                    let single = box_meets_wedge(&light, pa, pb, &child);
                    let bit = wedge >> i & 1 == 1;
                    assert!(bit || !single, "octant {i} dropped, single box keeps it");
                    kept += usize::from(single);
                    extra += usize::from(bit && !single);
                }
            }
        }
        // The tests are not vacuous, and the shared slack rarely keeps more.
        assert!(kept > 1000, "{kept}");
        assert!(extra * 100 <= kept, "{extra} of {kept}");
    }
}
