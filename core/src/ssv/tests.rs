//! Soft shadow bits against the exact oracle (every triangle against every
//! segment with [`segment_meets_triangle`]) on the scene families of ssv.md, the
//! structures against each other bit for bit, and the hierarchy's work against
//! brute force.

use alloc::vec;
use alloc::vec::Vec;
use glam::{DVec3, Vec3};
use proptest::prelude::*;

use super::*;

/// An owned triangle soup.
#[derive(Clone, Debug, Default)]
struct Soup {
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

impl Soup {
    fn view(&self) -> MeshView<'_> {
        MeshView::new(&self.positions, &self.indices).unwrap()
    }

    fn push(&mut self, [a, b, c]: [Vec3; 3]) {
        let base = self.positions.len() as u32;
        self.positions
            .extend([a.to_array(), b.to_array(), c.to_array()]);
        self.indices.extend([base, base + 1, base + 2]);
    }

    fn append(&mut self, other: &Soup) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }

    fn triangles(&self) -> Vec<[Vec3; 3]> {
        self.view().triangles().collect()
    }

    /// The same triangles, every one with its own three vertices.
    fn unwelded(&self) -> Soup {
        let mut out = Soup::default();
        for t in self.triangles() {
            out.push(t);
        }
        out
    }

    fn transformed(&self, f: impl Fn(Vec3) -> Vec3) -> Soup {
        Soup {
            positions: self
                .positions
                .iter()
                .map(|&p| f(Vec3::from(p)).to_array())
                .collect(),
            indices: self.indices.clone(),
        }
    }
}

/// A `(u, v)` grid surface `f(u, v)`, `u, v` in `[0, 1]`, two triangles a cell.
fn grid(nu: usize, nv: usize, f: impl Fn(f32, f32) -> Vec3) -> Soup {
    let mut s = Soup::default();
    for j in 0..=nv {
        for i in 0..=nu {
            s.positions
                .push(f(i as f32 / nu as f32, j as f32 / nv as f32).to_array());
        }
    }
    let at = |i: usize, j: usize| (j * (nu + 1) + i) as u32;
    for j in 0..nv {
        for i in 0..nu {
            s.indices.extend([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            s.indices.extend([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    s
}

fn sphere(center: Vec3, r: f32, n: usize) -> Soup {
    use core::f32::consts::{PI, TAU};
    // Poles collapse to one position per pole after welding; those rows'
    // degenerate triangles are dropped consistently.
    grid(2 * n, n, |u, v| {
        let (t, p) = (u * TAU, v * PI);
        center
            + r * Vec3::new(
                libm::sinf(p) * libm::cosf(t),
                libm::sinf(p) * libm::sinf(t),
                libm::cosf(p),
            )
    })
}

fn torus(center: Vec3, big: f32, small: f32, n: usize) -> Soup {
    use core::f32::consts::TAU;
    grid(2 * n, n, |u, v| {
        let (a, b) = (u * TAU, v * TAU);
        let ring = big + small * libm::cosf(b);
        center
            + Vec3::new(
                ring * libm::cosf(a),
                ring * libm::sinf(a),
                small * libm::sinf(b),
            )
    })
}

fn cube(center: Vec3, h: f32) -> Soup {
    let mut s = Soup::default();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let face = grid(2, 2, |u, v| {
                let mut p = [0.0; 3];
                p[axis] = sign * h;
                p[(axis + 1) % 3] = (2.0 * u - 1.0) * h * sign;
                p[(axis + 2) % 3] = (2.0 * v - 1.0) * h;
                center + Vec3::from(p)
            });
            s.append(&face);
        }
    }
    s
}

fn quad_light(center: Vec3, half: f32) -> LightPolygon {
    LightPolygon::new(&[
        center + Vec3::new(-half, -half, 0.0),
        center + Vec3::new(half, -half, 0.0),
        center + Vec3::new(half, half, 0.0),
        center + Vec3::new(-half, half, 0.0),
    ])
    .unwrap()
}

fn oracle(tris: &[[Vec3; 3]], p: Vec3, samples: &[Vec3]) -> Vec<u64> {
    let mut bits = vec![0u64; samples.len().div_ceil(64)];
    for (i, &s) in samples.iter().enumerate() {
        if !tris
            .iter()
            .any(|&[a, b, c]| segment_meets_triangle(p, s, a, b, c))
        {
            bits[i / 64] |= 1 << (i % 64);
        }
    }
    bits
}

const ALL: [Structure; 4] = [
    Structure::Hierarchy,
    Structure::Hemicube,
    Structure::BruteForce,
    Structure::RayTrace,
];

fn build(soup: &Soup, light: &LightPolygon, samples: &[Vec3], structure: Structure) -> SoftShadows {
    let options = SsvOptions {
        structure,
        leaf_edges: 8,
        ..SsvOptions::default()
    };
    SoftShadows::new(&soup.view(), light.clone(), samples, options).unwrap()
}

/// Every structure against the oracle at every receiver, bit for bit; returns
/// the bits of the brute force, receiver after receiver.
fn check(soup: &Soup, light: &LightPolygon, samples: &[Vec3], receivers: &[Vec3]) -> Vec<u64> {
    check_structures(soup, light, samples, receivers, false)
}

/// [`check`], except that where `rays_may_graze` [`Structure::RayTrace`]'s
/// `f32` rays may differ from the oracle on a sample whose segment grazes an
/// edge ([`ray_may_differ`]): on random scenes, where such a segment turns up
/// now and then, as the structure's contract allows. The other structures are
/// exact everywhere.
fn check_structures(
    soup: &Soup,
    light: &LightPolygon,
    samples: &[Vec3],
    receivers: &[Vec3],
    rays_may_graze: bool,
) -> Vec<u64> {
    let tris = soup.triangles();
    let expected: Vec<Vec<u64>> = receivers
        .iter()
        .map(|&p| oracle(&tris, p, samples))
        .collect();
    let mut brute = Vec::new();
    // The four structures, plus a hierarchy whose root box misses most receivers
    // (they go to the shells around it) and cuts through the mesh.
    let small_root = SsvOptions {
        structure: Structure::Hierarchy,
        leaf_edges: 4,
        root_bounds: Some([Vec3::new(-0.5, -0.5, 0.0), Vec3::new(0.7, 0.6, 1.5)]),
        ..SsvOptions::default()
    };
    let sets = ALL
        .iter()
        .map(|&s| (s, build(soup, light, samples, s)))
        .chain([(
            Structure::Hierarchy,
            SoftShadows::new(&soup.view(), light.clone(), samples, small_root).unwrap(),
        )]);
    for (structure, ss) in sets {
        let words = ss.words_per_receiver();
        for (r, &p) in receivers.iter().enumerate() {
            let mut bits = vec![0u64; words];
            let visible = ss.query(p, &mut bits).unwrap();
            if rays_may_graze && structure == Structure::RayTrace {
                for (i, &s) in samples.iter().enumerate() {
                    let (word, bit) = (i / 64, i % 64);
                    let visible = bits[word] >> bit & 1 == 1;
                    let differs = visible != (expected[r][word] >> bit & 1 == 1);
                    assert!(
                        !differs || ray_may_differ(&tris, p, s, visible),
                        "RayTrace: receiver {r} at {p:?}, sample {i} at {s:?} differs from \
                         the exact oracle without grazing an edge"
                    );
                }
                // The last word's bits past the samples stay clear.
                let tail = samples.len() % 64;
                assert!(
                    tail == 0 || bits[bits.len() - 1] >> tail == 0,
                    "receiver {r}: {bits:?}"
                );
            } else {
                assert_eq!(
                    bits, expected[r],
                    "{structure:?}: receiver {r} at {p:?} differs from the exact oracle"
                );
            }
            assert_eq!(visible, bits.iter().map(|w| w.count_ones()).sum::<u32>());
            if structure == Structure::BruteForce {
                brute.extend_from_slice(&bits);
            }
        }
    }
    brute
}

/// Whether an `f32` ray from `p` to `s` may answer `ray_visible` where the
/// exact segment test answers the other way: the segment crosses a triangle
/// within [`GRAZING`] of one of its edges (a hit the ray can lose), or, for a
/// ray that reports a hit, passes within it of an edge of a triangle it
/// misses (a hit the ray can gain). Edges through the receiver are left out:
/// every segment from a receiver on a vertex touches them. Distances are
/// relative to the largest coordinate of the scene, the receiver and the
/// sample.
fn ray_may_differ(tris: &[[Vec3; 3]], p: Vec3, s: Vec3, ray_visible: bool) -> bool {
    let largest = |v: Vec3| v.abs().max_element();
    let scale = tris
        .iter()
        .flatten()
        .fold(largest(p).max(largest(s)), |m, &v| m.max(largest(v)));
    let limit = GRAZING * f64::from(scale);
    let (pd, sd) = (p.as_dvec3(), s.as_dvec3());
    tris.iter().any(|t| {
        let crossed = segment_meets_triangle(p, s, t[0], t[1], t[2]);
        let [a, b, c] = t.map(|v| v.as_dvec3());
        let edges = [(a, b), (b, c), (c, a)];
        if crossed && ray_visible {
            // The segment's crossing with the triangle's plane near an edge.
            let normal = (b - a).cross(c - a);
            let x = pd + (sd - pd) * ((a - pd).dot(normal) / (sd - pd).dot(normal));
            edges
                .iter()
                .any(|&(u, v)| segment_distance(x, x, u, v) <= limit)
        } else if !crossed && !ray_visible {
            edges.iter().any(|&(u, v)| {
                segment_distance(pd, pd, u, v) > limit && segment_distance(pd, sd, u, v) <= limit
            })
        } else {
            false
        }
    })
}

/// Grazing distance of [`ray_may_differ`], a fraction of the scene's largest
/// coordinate: two orders of magnitude above `f32` rounding.
const GRAZING: f64 = 1e-5;

/// The distance between the segments `p0`–`p1` and `q0`–`q1` (their closest
/// points: the parameters of the infinite lines' closest points, clamped to
/// the segments and each re-projected on the other).
fn segment_distance(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> f64 {
    let (d, e, w) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, b, c) = (d.dot(d), d.dot(e), e.dot(e));
    let (f, g) = (d.dot(w), e.dot(w));
    let on_q = |t: f64| ((t * b + g) / c).clamp(0.0, 1.0);
    let on_p = |u: f64| ((u * b - f) / a).clamp(0.0, 1.0);
    let (t, u) = if a == 0.0 && c == 0.0 {
        (0.0, 0.0)
    } else if a == 0.0 {
        (0.0, on_q(0.0))
    } else if c == 0.0 {
        (on_p(0.0), 0.0)
    } else {
        let denominator = a * c - b * b;
        let t = if denominator > 0.0 {
            ((b * g - c * f) / denominator).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let u = on_q(t);
        (on_p(u), u)
    };
    ((p0 + d * t) - (q0 + e * u)).length()
}

#[test]
fn segment_distance_of_crossing_skew_and_parallel_segments() {
    let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    // (case, p0, p1, q0, q1, distance)
    let cases = [
        (
            "crossing at the origin, 0.5 apart in z",
            [v(-1.0, 0.0, 0.0), v(1.0, 0.0, 0.0)],
            [v(0.0, -1.0, 0.5), v(0.0, 1.0, 0.5)],
            0.5,
        ),
        (
            "the closest points clamped to an end of each",
            [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)],
            [v(2.0, 1.0, 0.0), v(3.0, 5.0, 0.0)],
            2f64.sqrt(),
        ),
        (
            "parallel, overlapping: their gap",
            [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0)],
            [v(1.0, 0.3, 0.0), v(4.0, 0.3, 0.0)],
            0.3,
        ),
        (
            "a point against a segment",
            [v(1.0, 1.0, 0.0), v(1.0, 1.0, 0.0)],
            [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0)],
            1.0,
        ),
        (
            "a segment against a point beyond its end",
            [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0)],
            [v(3.0, 0.0, 4.0), v(3.0, 0.0, 4.0)],
            17f64.sqrt(),
        ),
        (
            "two points",
            [v(1.0, 2.0, 3.0), v(1.0, 2.0, 3.0)],
            [v(1.0, 2.0, 5.0), v(1.0, 2.0, 5.0)],
            2.0,
        ),
        (
            "parallel, apart along their line: end to end",
            [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)],
            [v(4.0, 4.0, 0.0), v(6.0, 4.0, 0.0)],
            5.0,
        ),
    ];
    for (case, [p0, p1], [q0, q1], want) in cases {
        let d = segment_distance(p0, p1, q0, q1);
        assert!((d - want).abs() < 1e-12, "{case}: {d}");
    }
}

fn receivers_box(lo: Vec3, hi: Vec3, n: usize, seed: u64) -> Vec<Vec3> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| {
            let t = Vec3::new(
                rng.next_f64() as f32,
                rng.next_f64() as f32,
                rng.next_f64() as f32,
            );
            lo + (hi - lo) * t
        })
        .collect()
}

#[test]
fn closed_meshes_over_a_floor() {
    let mut soup = sphere(Vec3::new(0.0, 0.0, 1.5), 0.8, 8);
    soup.append(&torus(Vec3::new(1.5, 0.5, 1.0), 0.6, 0.2, 8));
    soup.append(&cube(Vec3::new(-1.5, -0.5, 1.0), 0.4));
    let floor = grid(6, 6, |u, v| Vec3::new(8.0 * u - 4.0, 8.0 * v - 4.0, 0.0));
    soup.append(&floor);
    let light = quad_light(Vec3::new(0.3, 0.2, 4.0), 0.7);
    let samples = light.samples(64, SamplePattern::Jittered, 3);
    // Free space, and exactly on the floor (z = 0, a surface).
    let mut receivers = receivers_box(Vec3::new(-3.0, -3.0, 0.01), Vec3::new(3.0, 3.0, 3.5), 40, 1);
    receivers.extend(receivers_box(
        Vec3::new(-3.0, -3.0, 0.0),
        Vec3::new(3.0, 3.0, 0.0),
        40,
        2,
    ));
    // At mesh vertices (on the surfaces; triangles through p are edge-on).
    receivers.extend(soup.positions.iter().step_by(7).map(|&p| Vec3::from(p)));
    let bits = check(&soup, &light, &samples, &receivers);
    let visible: u32 = bits.iter().map(|w| w.count_ones()).sum();
    let total = 64 * receivers.len() as u32;
    // A scene with real penumbrae: neither all lit nor all dark.
    assert!(
        visible > total / 10 && visible < total * 9 / 10,
        "{visible} of {total}"
    );
}

#[test]
fn open_folded_and_non_manifold() {
    // An open wavy sheet, a sheet folded onto itself, and a fan of five
    // triangles around one edge.
    let mut soup = grid(6, 6, |u, v| {
        Vec3::new(
            3.0 * u - 1.5,
            3.0 * v - 1.5,
            1.0 + 0.3 * libm::sinf(5.0 * u) * libm::cosf(4.0 * v),
        )
    });
    soup.append(&grid(4, 2, |u, v| {
        let x = 2.0 * u;
        let fold = if x < 1.0 { x } else { 2.0 - x };
        Vec3::new(fold - 2.0, v - 0.5, 2.0 + 0.4 * x)
    }));
    let (a, b) = (Vec3::new(1.0, -0.5, 2.2), Vec3::new(1.0, 0.5, 2.2));
    for k in 0..5 {
        let ang = k as f32 * 1.1;
        soup.push([
            a,
            b,
            a + Vec3::new(libm::cosf(ang), 0.3, libm::sinf(ang)) * 0.6,
        ]);
    }
    let light = quad_light(Vec3::new(0.0, 0.0, 4.0), 1.0);
    let samples = light.samples(256, SamplePattern::Jittered, 9);
    let mut receivers = receivers_box(Vec3::new(-2.5, -2.5, -1.0), Vec3::new(2.5, 2.5, 3.5), 40, 3);
    receivers.extend(soup.positions.iter().step_by(5).map(|&p| Vec3::from(p)));
    check(&soup, &light, &samples, &receivers);
    // Unwelded copy: identical bits for every structure.
    let welded = check(&soup, &light, &samples, &receivers);
    let unwelded = check(&soup.unwelded(), &light, &samples, &receivers);
    assert_eq!(welded, unwelded);
}

#[test]
fn thin_triangles_behind_receivers_and_crossing_the_light_plane() {
    let mut soup = Soup::default();
    // Long thin slivers.
    for k in 0..12 {
        let y = -1.0 + k as f32 * 0.17;
        soup.push([
            Vec3::new(-3.0, y, 1.0 + 0.05 * k as f32),
            Vec3::new(3.0, y + 0.01, 1.2),
            Vec3::new(3.0, y + 0.03, 1.21),
        ]);
    }
    // Triangles crossing the light's plane (z = 3) outside the light.
    soup.push([
        Vec3::new(2.0, -1.0, 2.0),
        Vec3::new(2.5, 1.0, 4.0),
        Vec3::new(3.0, 0.0, 2.5),
    ]);
    soup.push([
        Vec3::new(-2.5, -2.0, 4.0),
        Vec3::new(-2.0, 2.0, 2.0),
        Vec3::new(-3.0, 0.0, 3.5),
    ]);
    // Geometry below every receiver, i.e. behind p as seen from the light.
    soup.append(&grid(3, 3, |u, v| {
        Vec3::new(4.0 * u - 2.0, 4.0 * v - 2.0, -1.0 + u * v)
    }));
    // The emitter itself as occluder triangles: never blocks.
    let light = quad_light(Vec3::new(0.0, 0.0, 3.0), 0.8);
    let v = light.vertices();
    soup.push([v[0], v[1], v[2]]);
    soup.push([v[0], v[2], v[3]]);
    let samples = light.samples(16, SamplePattern::Stratified, 0);
    let receivers = receivers_box(Vec3::new(-2.0, -2.0, 0.0), Vec3::new(2.0, 2.0, 2.5), 60, 4);
    check(&soup, &light, &samples, &receivers);
    // Receivers above the light (the other side of its plane) and on its plane.
    let above = receivers_box(Vec3::new(-2.0, -2.0, 3.5), Vec3::new(2.0, 2.0, 5.0), 20, 5);
    check(&soup, &light, &samples, &above);
    let on_plane = receivers_box(Vec3::new(-2.0, -2.0, 3.0), Vec3::new(2.0, 2.0, 3.0), 10, 6);
    check(&soup, &light, &samples, &on_plane);
}

#[test]
fn light_sizes_and_sample_counts() {
    let mut soup = sphere(Vec3::new(0.0, 0.0, 1.2), 0.5, 6);
    soup.append(&grid(4, 4, |u, v| {
        Vec3::new(4.0 * u - 2.0, 4.0 * v - 2.0, 0.0)
    }));
    let receivers = receivers_box(Vec3::new(-1.5, -1.5, 0.0), Vec3::new(1.5, 1.5, 0.0), 12, 7);
    for (half, n) in [(0.05, 16), (0.5, 64), (2.0, 256), (1.0, 1024)] {
        let light = quad_light(Vec3::new(0.2, -0.1, 3.0), half);
        let samples = light.samples(n, SamplePattern::Jittered, n as u64);
        check(&soup, &light, &samples, &receivers);
    }
    // A tilted hexagonal light.
    let hex: Vec<Vec3> = (0..6)
        .map(|i| {
            let a = i as f32 * core::f32::consts::TAU / 6.0;
            Vec3::new(
                libm::cosf(a),
                libm::sinf(a) * 0.8,
                3.0 + 0.6 * libm::sinf(a),
            )
        })
        .collect();
    let light = LightPolygon::new(&hex).unwrap();
    check(
        &soup,
        &light,
        &light.samples(100, SamplePattern::Jittered, 1),
        &receivers,
    );
}

#[test]
fn errors() {
    let soup = cube(Vec3::ZERO, 1.0);
    let light = quad_light(Vec3::new(0.0, 0.0, 3.0), 1.0);
    let samples = light.samples(70, SamplePattern::Jittered, 0);
    let ss =
        SoftShadows::new(&soup.view(), light.clone(), &samples, SsvOptions::default()).unwrap();
    assert_eq!(ss.words_per_receiver(), 2);
    let mut one = [0u64; 1];
    assert_eq!(
        ss.query(Vec3::ZERO, &mut one),
        Err(SsvError::BitsTooShort { needed: 2, got: 1 })
    );
    let mut bits = [u64::MAX; 3];
    assert_eq!(
        ss.query(Vec3::splat(f32::NAN), &mut bits),
        Err(SsvError::NonFiniteReceiver)
    );
    // Far above everything: all 70 visible, the unused high bits and the extra
    // word untouched / cleared as documented.
    assert_eq!(ss.query(Vec3::new(0.0, 0.0, 10.0), &mut bits), Ok(70));
    assert_eq!(bits, [u64::MAX, (1 << 6) - 1, u64::MAX]);
    // Inside the closed cube: all blocked.
    assert_eq!(ss.query(Vec3::new(0.1, 0.2, 0.3), &mut bits), Ok(0));
    // No occluders at all: everything visible.
    let empty = Soup::default();
    let open = SoftShadows::new(
        &empty.view(),
        light.clone(),
        &samples,
        SsvOptions::default(),
    )
    .unwrap();
    assert_eq!(open.query(Vec3::ZERO, &mut bits), Ok(70));
    let off = [Vec3::new(5.0, 0.0, 3.0)];
    assert!(matches!(
        SoftShadows::new(&soup.view(), light.clone(), &off, SsvOptions::default()),
        Err(SsvError::Light(LightError::SampleOffLight { index: 0 }))
    ));
    assert!(matches!(
        SoftShadows::new(&soup.view(), light.clone(), &[], SsvOptions::default()),
        Err(SsvError::SampleCount { count: 0 })
    ));
    let bad = SsvOptions {
        leaf_edges: 0,
        ..SsvOptions::default()
    };
    assert_eq!(
        SoftShadows::new(&soup.view(), light, &samples, bad).err(),
        Some(SsvError::InvalidOptions)
    );
}

/// The hierarchy's point: far fewer candidates than brute force per query.
#[test]
fn hierarchy_does_less_work_than_brute_force() {
    let mut soup = Soup::default();
    for k in 0..6 {
        soup.append(&sphere(
            Vec3::new(-2.5 + k as f32, 0.3 * k as f32 - 1.0, 1.0 + 0.1 * k as f32),
            0.4,
            8,
        ));
    }
    soup.append(&grid(10, 10, |u, v| {
        Vec3::new(10.0 * u - 5.0, 10.0 * v - 5.0, 0.0)
    }));
    let light = quad_light(Vec3::new(0.0, 0.0, 5.0), 0.5);
    let samples = light.samples(64, SamplePattern::Jittered, 0);
    let receivers = receivers_box(
        Vec3::new(-4.5, -4.5, 0.0),
        Vec3::new(4.5, 4.5, 0.0),
        200,
        11,
    );
    let mut totals = [0u64; 3];
    let mut bits = [[0u64; 1]; 3];
    let structures = [
        Structure::Hierarchy,
        Structure::Hemicube,
        Structure::BruteForce,
    ];
    let sets: Vec<SoftShadows> = structures
        .iter()
        .map(|&s| {
            SoftShadows::new(
                &soup.view(),
                light.clone(),
                &samples,
                SsvOptions {
                    structure: s,
                    ..SsvOptions::default()
                },
            )
            .unwrap()
        })
        .collect();
    for &p in &receivers {
        for (k, ss) in sets.iter().enumerate() {
            totals[k] += u64::from(ss.query_detailed(p, &mut bits[k]).unwrap().candidates);
        }
        assert_eq!(bits[0], bits[2]);
        assert_eq!(bits[1], bits[2]);
    }
    let stats = sets[0].statistics();
    assert!(stats.nodes > 1 && stats.bytes > 0);
    assert_eq!(stats.queries, receivers.len());
    assert_eq!(stats.candidates as u64, totals[0]);
    assert_eq!(Structure::try_from(1), Ok(Structure::Hemicube));
    assert_eq!(Structure::try_from(4), Err(SsvError::InvalidOptions));
    // Brute force hands over every potential edge; the hierarchy a small
    // fraction (wedges of a small light are thin; the floor's flat edges are
    // gone everywhere).
    assert_eq!(
        totals[2],
        receivers.len() as u64 * stats.potential_edges as u64
    );
    // Lazy subdivision goes as deep as the queries need (with or without
    // std).
    assert!(
        totals[0] * 5 < totals[2],
        "hierarchy {} vs brute {}",
        totals[0],
        totals[2]
    );
    assert!(
        totals[1] < totals[2],
        "hemicube {} vs brute {}",
        totals[1],
        totals[2]
    );
}

#[cfg(feature = "std")]
#[test]
fn concurrent_queries_give_the_serial_bits() {
    let mut soup = torus(Vec3::new(0.0, 0.0, 1.0), 1.0, 0.3, 12);
    soup.append(&grid(6, 6, |u, v| {
        Vec3::new(6.0 * u - 3.0, 6.0 * v - 3.0, 0.0)
    }));
    let light = quad_light(Vec3::new(0.0, 0.0, 4.0), 1.0);
    let samples = light.samples(128, SamplePattern::Jittered, 5);
    let receivers = receivers_box(Vec3::new(-2.5, -2.5, 0.0), Vec3::new(2.5, 2.5, 0.5), 64, 8);
    let serial = build(&soup, &light, &samples, Structure::Hierarchy);
    let expected: Vec<[u64; 2]> = receivers
        .iter()
        .map(|&p| {
            let mut b = [0u64; 2];
            serial.query(p, &mut b).unwrap();
            b
        })
        .collect();
    let shared = build(&soup, &light, &samples, Structure::Hierarchy);
    std::thread::scope(|scope| {
        for t in 0..4 {
            let (shared, receivers, expected) = (&shared, &receivers, &expected);
            scope.spawn(move || {
                for (i, &p) in receivers.iter().enumerate().skip(t) {
                    let mut b = [0u64; 2];
                    shared.query(p, &mut b).unwrap();
                    assert_eq!(b, expected[i]);
                }
            });
        }
    });
    // The tree itself depends on the order queries arrive in (a node splits
    // after serving a few), never the bits; both were refined.
    assert!(shared.statistics().nodes > 8 && serial.statistics().nodes > 8);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Random soups (a triangle's corners near a random centre) under a random
    /// light, receivers anywhere: every exact structure equals the exact
    /// oracle, and the `f32` rays differ from it only where a segment grazes an
    /// edge.
    #[test]
    fn random_soups(seed in any::<u64>(), count in 5usize..60, half in 0.05f32..2.0, n in prop::sample::select(vec![16usize, 64, 200])) {
        let mut rng = SplitMix64::new(seed);
        let mut u = || rng.next_f64() as f32;
        let mut soup = Soup::default();
        for _ in 0..count {
            let c = Vec3::new(4.0 * u() - 2.0, 4.0 * u() - 2.0, 3.0 * u());
            let mut corner = || c + Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * 1.5;
            soup.push([corner(), corner(), corner()]);
        }
        let tilt = u() - 0.5;
        let light = LightPolygon::new(&[
            Vec3::new(-half, -half, 3.5 + tilt),
            Vec3::new(half, -half, 3.5 - tilt),
            Vec3::new(half, half, 3.5 - tilt),
            Vec3::new(-half, half, 3.5 + tilt),
        ]).unwrap();
        let samples = light.samples(n, SamplePattern::Jittered, seed ^ 1);
        let receivers = receivers_box(Vec3::new(-3.0, -3.0, -1.0), Vec3::new(3.0, 3.0, 3.0), 12, seed ^ 2);
        let welded = check_structures(&soup, &light, &samples, &receivers, true);
        // Welded (shared vertices by position) vs the soup as given.
        let mut shuffled = soup.unwelded();
        shuffled.indices.reverse();
        let again = check_structures(&shuffled.transformed(|p| p), &light, &samples, &receivers, true);
        // Reversing the index list reverses triangle order and winding: same bits.
        prop_assert_eq!(welded, again);
    }
}

/// The relative depth complexity equals the oracle's exact counts up to the
/// per-receiver constant, for every structure; the batch query equals single
/// queries; the irradiance estimate of a fully visible light matches the
/// analytic point-source limit for a far small light.
#[test]
fn depth_complexity_batch_and_irradiance() {
    let mut soup = sphere(Vec3::new(0.0, 0.0, 1.5), 0.8, 6);
    soup.append(&torus(Vec3::new(0.3, 0.2, 2.2), 0.6, 0.15, 6));
    soup.append(&grid(3, 3, |u, v| {
        Vec3::new(4.0 * u - 2.0, 4.0 * v - 2.0, 0.0)
    }));
    let light = quad_light(Vec3::new(0.1, 0.2, 4.0), 1.0);
    let samples = light.samples(64, SamplePattern::Jittered, 4);
    let tris = soup.triangles();
    let mut receivers = receivers_box(Vec3::new(-2.0, -2.0, 0.0), Vec3::new(2.0, 2.0, 1.0), 24, 13);
    receivers.push(Vec3::new(0.0, 0.0, 4.0)); // in the light's plane
    for structure in ALL {
        let ss = build(&soup, &light, &samples, structure);
        for &p in &receivers {
            let mut got = [0i32; 64];
            ss.relative_depth_complexity(p, &mut got).unwrap();
            let exact: Vec<i32> = samples
                .iter()
                .map(|&s| {
                    tris.iter()
                        .filter(|&&[a, b, c]| segment_meets_triangle(p, s, a, b, c))
                        .count() as i32
                })
                .collect();
            let min = *exact.iter().min().unwrap();
            let exact: Vec<i32> = exact.iter().map(|d| d - min).collect();
            assert_eq!(&got[..], &exact[..], "{structure:?} at {p:?}");
        }
        let mut batch = vec![0u64; receivers.len()];
        let mut counts = vec![0u32; receivers.len()];
        let work = ss
            .query_batch(&receivers, &mut batch, Some(&mut counts), false)
            .unwrap();
        let mut summed = QueryWork::default();
        for (r, &p) in receivers.iter().enumerate() {
            let mut one = [0u64; 1];
            let info = ss.query_detailed(p, &mut one).unwrap();
            assert_eq!(info.visible, counts[r]);
            assert_eq!(one[0], batch[r]);
            summed = summed.with(&info);
        }
        // The batch's work is its queries' work, on the pool or not, and the
        // same bits either way. (Candidates and silhouettes depend on the
        // nodes the lazy hierarchy has built by then, not on the receiver.)
        let fixed = |w: QueryWork| (w.queries, w.visible, w.rays);
        assert_eq!(fixed(work), fixed(summed));
        assert_eq!(work.queries, receivers.len() as u64);
        assert!(work.candidates >= work.silhouettes);
        let (mut pooled, mut pooled_counts) =
            (vec![0u64; receivers.len()], vec![0u32; receivers.len()]);
        let pooled_work = ss
            .query_batch(&receivers, &mut pooled, Some(&mut pooled_counts), true)
            .unwrap();
        assert_eq!((pooled, pooled_counts), (batch, counts));
        assert_eq!(fixed(pooled_work), fixed(work));
    }
    // A small light far above an empty scene: E = A cos cos / r^2.
    let small = quad_light(Vec3::new(0.0, 0.0, 100.0), 0.01);
    let ss = SoftShadows::new(
        &Soup::default().view(),
        small.clone(),
        &small.samples(16, SamplePattern::Stratified, 0),
        SsvOptions::default(),
    )
    .unwrap();
    let mut bits = [0u64; 1];
    assert_eq!(ss.query(Vec3::ZERO, &mut bits), Ok(16));
    let e = ss.irradiance(Vec3::ZERO, Vec3::Z, &bits);
    let expected = small.area() / (100.0 * 100.0);
    assert!((e / expected - 1.0).abs() < 1e-4, "{e} vs {expected}");
    assert_eq!(ss.irradiance(Vec3::ZERO, -Vec3::Z, &bits), 0.0);
}

/// Coplanar neighbours (a flat triangulated plate: its interior edges never
/// count), a coplanar overlapping duplicate plate (counts twice), and the same
/// scene far from the origin, where `f32` spacing is coarse (the margins of the
/// culling tests are relative).
#[test]
fn coplanar_neighbours_and_far_from_the_origin() {
    let mut soup = grid(5, 5, |u, v| Vec3::new(2.0 * u - 1.0, 2.0 * v - 1.0, 1.0));
    soup.append(&grid(2, 3, |u, v| {
        Vec3::new(1.2 * u - 0.2, 1.1 * v - 0.5, 1.0)
    }));
    soup.append(&sphere(Vec3::new(-0.6, 0.7, 2.0), 0.3, 5));
    soup.append(&grid(4, 4, |u, v| {
        Vec3::new(6.0 * u - 3.0, 6.0 * v - 3.0, 0.0)
    }));
    let light = quad_light(Vec3::new(0.2, 0.1, 3.5), 0.9);
    let samples = light.samples(64, SamplePattern::Jittered, 21);
    let mut receivers = receivers_box(Vec3::new(-2.5, -2.5, 0.0), Vec3::new(2.5, 2.5, 0.0), 30, 17);
    // In the plate's plane (edge-on to it) and at its vertices.
    receivers.extend(receivers_box(
        Vec3::new(-1.5, -1.5, 1.0),
        Vec3::new(1.5, 1.5, 1.0),
        15,
        18,
    ));
    receivers.extend(
        soup.positions
            .iter()
            .take(36)
            .step_by(5)
            .map(|&p| Vec3::from(p)),
    );
    check(&soup, &light, &samples, &receivers);
    let ss = build(&soup, &light, &samples, Structure::Hierarchy);
    let stats = ss.statistics();
    assert!(
        stats.potential_edges < stats.edges,
        "flat edges are left out"
    );

    let offset = Vec3::new(1024.0, -2048.0, 512.0);
    let far = soup.transformed(|p| p + offset);
    let far_light = LightPolygon::new(
        &light
            .vertices()
            .iter()
            .map(|&v| v + offset)
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let far_samples: Vec<Vec3> = samples.iter().map(|&s| s + offset).collect();
    let far_receivers: Vec<Vec3> = receivers.iter().map(|&p| p + offset).collect();
    check(&far, &far_light, &far_samples, &far_receivers);
}

/// The hemicube is conservative: on a few scenes and light orientations, (1)
/// points sampled inside an edge's penumbra wedge (`x + t (x - l)`, `x` on the
/// edge, `l` on the light, in `f64`) where the edge's weight is clearly non-zero
/// find the edge in their cell, and (2) at random receivers every potential edge
/// missing from the cell's list changes no counter in the brute-force kernel.
#[test]
fn hemicube_lists_every_relevant_edge() {
    let mut bumpy = sphere(Vec3::new(0.2, -0.1, 1.6), 0.7, 10);
    bumpy.append(&grid(6, 6, |u, v| {
        Vec3::new(6.0 * u - 3.0, 6.0 * v - 3.0, 0.0)
    }));
    let mut folded = grid(5, 5, |u, v| {
        Vec3::new(
            3.0 * u - 1.5,
            3.0 * v - 1.5,
            1.0 + 0.3 * libm::sinf(5.0 * u) * libm::cosf(4.0 * v),
        )
    });
    let (a, b) = (Vec3::new(1.0, -0.5, 2.2), Vec3::new(1.0, 0.5, 2.2));
    for k in 0..5 {
        let ang = k as f32 * 1.1;
        folded.push([
            a,
            b,
            a + Vec3::new(libm::cosf(ang), 0.3, libm::sinf(ang)) * 0.6,
        ]);
    }
    // A soup, some triangles crossing the light's plane outside the light.
    let mut soup = Soup::default();
    let mut rng = SplitMix64::new(77);
    for _ in 0..40 {
        let mut u = || rng.next_f64() as f32;
        let c = Vec3::new(6.0 * u() - 3.0, 6.0 * u() - 3.0, 4.0 * u());
        let (d1, d2) = (
            Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5),
            Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5),
        );
        soup.push([c, c + d1, c + d2]);
    }
    let mut listed = 0usize;
    let mut wedge_points = 0usize;
    let mut unsure = 0usize;
    for (scene, soup) in [bumpy, folded, soup].iter().enumerate() {
        for tilt in [0.0f32, 0.7, 1.4] {
            let (c, s) = (libm::cosf(tilt), libm::sinf(tilt));
            let corner = |x: f32, y: f32| Vec3::new(0.3 + x * c, 0.1 + y, 3.5 + x * s);
            let light = LightPolygon::new(&[
                corner(-0.6, -0.5),
                corner(0.6, -0.5),
                corner(0.6, 0.5),
                corner(-0.6, 0.5),
            ])
            .unwrap();
            let samples = light.samples(256, SamplePattern::Jittered, 5);
            let ss = build(soup, &light, &samples, Structure::Hemicube);
            let cube = ss.hemicube.as_deref().unwrap();
            let mut rng = SplitMix64::new(scene as u64 * 10 + 3);
            // (1) Points inside wedges (some, rounded to f32, also go to (2)).
            let mut near: Vec<Vec3> = Vec::new();
            let light_v: Vec<DVec3> = light.vertices().iter().map(|v| v.as_dvec3()).collect();
            for &e in &ss.potential {
                let edge = &ss.graph.edges[e as usize];
                let at = |i: u32| ss.graph.positions[i as usize].as_dvec3();
                let (a, b) = (at(edge.a), at(edge.b));
                for _ in 0..8 {
                    let x = a + (b - a) * rng.next_f64();
                    let w: Vec<f64> = light_v.iter().map(|_| rng.next_f64() + 1e-3).collect();
                    let sum: f64 = w.iter().sum();
                    let l = light_v
                        .iter()
                        .zip(&w)
                        .fold(DVec3::ZERO, |s, (v, w)| s + *v * (w / sum));
                    let p = x + (x - l) * (4.0 * rng.next_f64());
                    // The weight at p in f64; terms within rounding of zero make
                    // the point unsure (counted, not asserted).
                    let mut weight = 0;
                    let mut sure = true;
                    for &v in ss.graph.third_of(edge) {
                        let n = (b - a).cross(at(v) - a);
                        let d = n.dot(p - a);
                        if d.abs() <= 1e-9 * n.length() * (p - a).length().max(1.0) {
                            sure = false;
                        }
                        weight += d.signum() as i32;
                    }
                    if !sure {
                        unsure += 1;
                        continue;
                    }
                    if weight == 0 {
                        continue;
                    }
                    wedge_points += 1;
                    if wedge_points.is_multiple_of(4) {
                        near.push(p.as_vec3());
                    }
                    let mut found = false;
                    cube.for_each_candidate(p, |c| found |= c == e);
                    assert!(
                        found,
                        "scene {scene}, tilt {tilt}: edge {e} missing at {p:?}"
                    );
                }
            }
            // (2) Random receivers (free space, above the light) and receivers
            // inside wedges against the kernel.
            let mut receivers = receivers_box(
                Vec3::new(-3.0, -3.0, -0.5),
                Vec3::new(3.0, 3.0, 3.3),
                24,
                40,
            );
            receivers.extend(receivers_box(
                Vec3::new(-3.0, -3.0, 3.8),
                Vec3::new(3.0, 3.0, 5.0),
                8,
                41,
            ));
            receivers.extend(near);
            let mut in_list = vec![false; ss.graph.edges.len()];
            for &p in &receivers {
                in_list.fill(false);
                cube.for_each_candidate(p.as_dvec3(), |c| in_list[c as usize] = true);
                listed += in_list.iter().filter(|&&x| x).count();
                let mut silhouettes = Silhouettes::new();
                let mut kernel = Kernel::new(&ss, p, &mut silhouettes);
                let mut counters = vec![0i32; samples.len()];
                for &e in &ss.potential {
                    if !in_list[e as usize] {
                        kernel.add_edge(&ss, e, &mut counters);
                        assert!(
                            counters.iter().all(|&c| c == 0),
                            "scene {scene}, tilt {tilt}: unlisted edge {e} counts at {p:?}"
                        );
                    }
                }
            }
        }
    }
    // The sampled points really test something, and rounding rarely interferes.
    assert!(wedge_points > 1000, "{wedge_points} wedge points");
    assert!(
        unsure * 100 < wedge_points,
        "{unsure} unsure of {wedge_points}"
    );
    assert!(listed > 0);
}

/// A quad light at height 2 over [`edges_along_x`].
fn light_over_edges_along_x() -> LightPolygon {
    LightPolygon::new(&[
        Vec3::new(-1.0, -0.9, 2.0),
        Vec3::new(1.0, -0.9, 2.0),
        Vec3::new(1.0, 1.1, 2.0),
        Vec3::new(-1.0, 1.1, 2.0),
    ])
    .unwrap()
}

/// Points of [`light_over_edges_along_x`] exactly on the lines its edges
/// project to from the origin (`y' = 2 y`).
fn on_projected_edges() -> impl Iterator<Item = Vec3> {
    (0..6).flat_map(|k| {
        (0..5).map(move |j| {
            Vec3::new(
                -0.8 + 0.375 * j as f32,
                2.0 * (-0.375 + 0.125 * k as f32),
                2.0,
            )
        })
    })
}

/// Six triangles whose edges run along x at height 1 (at `y = -0.375 +
/// 0.125 k`), so that from the origin they project onto the plane `z = 2` at
/// `y = 2 y_k`, and a small sphere beside them: a scene whose decisions can be
/// put exactly on their bounds.
fn edges_along_x() -> Soup {
    let mut soup = Soup::default();
    for k in 0..6 {
        let y = -0.375 + 0.125 * k as f32;
        soup.push([
            Vec3::new(-1.0, y, 1.0),
            Vec3::new(1.0, y, 1.0),
            Vec3::new(0.0, y - 0.0625, 1.0 + 0.25 * (k % 2) as f32),
        ]);
    }
    soup.append(&sphere(Vec3::new(0.3, 0.2, 1.2), 0.2, 8));
    soup
}

/// Receivers for [`edges_along_x`]: the origin (whose projected edges hold
/// samples of [`on_projected_edges`]) and a box around the scene.
fn receivers_under_edges_along_x() -> impl Iterator<Item = Vec3> {
    [Vec3::ZERO].into_iter().chain(receivers_box(
        Vec3::new(-1.5, -1.5, -0.5),
        Vec3::new(1.5, 1.5, 0.5),
        40,
        9,
    ))
}

/// The slow twin's counters at `p`: every sample through the exact
/// per-sample test, no arc.
fn slow_counters(ss: &SoftShadows, p: Vec3) -> Vec<i32> {
    let mut counters = vec![0i32; ss.samples.len()];
    let mut silhouettes = Silhouettes::new();
    let mut k = Kernel::new(ss, p, &mut silhouettes);
    k.slow = true;
    ss.sweep_with(k, &mut counters, &mut QueryInfo::default());
    counters
}

/// The branch-free sample pass against its slow twin (every sample through the
/// per-sample certified test): equal counters, on a scene built so that many
/// samples lie exactly on a projected silhouette edge (the plane through the
/// receiver and the edge holds them), where the float filters cannot decide
/// and the exact path must; and on an ordinary scene.
#[test]
fn branch_free_sample_pass_equals_the_per_sample_test() {
    // Receivers at the origin-ish, edges at height 1 along x, samples on the
    // light at height 2 exactly on the lines the edges project to (y' = 2 y).
    let soup = edges_along_x();
    let light = light_over_edges_along_x();
    let mut samples = light.samples(64, SamplePattern::Jittered, 5);
    samples.extend(on_projected_edges());
    let ss = build(&soup, &light, &samples, Structure::BruteForce);
    let n = samples.len();
    let mut unsure = 0;
    for p in receivers_under_edges_along_x() {
        let mut fast = vec![0i32; n];
        let mut silhouettes = Silhouettes::new();
        let mut k = Kernel::new(&ss, p, &mut silhouettes);
        for &e in &ss.potential {
            k.add_edge(&ss, e, &mut fast);
        }
        unsure += k.unsure;
        assert_eq!(fast, slow_counters(&ss, p), "receiver {p:?}");
    }
    // The exact path was exercised (30 samples lie on the origin's projected
    // edges; those the edge's own culling does not reach are unsure).
    assert!(unsure >= 20, "{unsure} unsure samples");
}

/// Edges along x under a light whose samples include points exactly on (and
/// a few units of rounding beside) the lines the edges project to from
/// probe receivers, with a last block of five samples; and those probes.
fn samples_on_projected_edges() -> (SoftShadows, Vec<Vec3>) {
    let soup = edges_along_x();
    let light = light_over_edges_along_x();
    let mut samples = light.samples(64, SamplePattern::Jittered, 5);
    // On the lines the origin's edges project to, and a few units of
    // rounding beside them (where a bound too small takes the wrong side).
    for on in on_projected_edges() {
        samples.push(on);
        for ulps in [-3i32, -1, 1, 3] {
            let step = if on.y == 0.0 {
                1e-9
            } else {
                on.y.abs() * f32::EPSILON
            };
            samples.push(Vec3::new(on.x, on.y + ulps as f32 * step, 2.0));
        }
    }
    // Samples within rounding of the planes through a probe receiver and an
    // edge, or the receiver, an endpoint and the centroid: the projections
    // of edge points from the probe onto the light, rounded to `f32`.
    let probes = receivers_box(Vec3::new(-0.8, -0.8, -0.5), Vec3::new(0.8, 0.8, 0.5), 6, 31);
    let first = build(&soup, &light, &samples, Structure::BruteForce);
    let centroid = light.centroid();
    for &p0 in &probes {
        for &e in first.potential.iter().step_by(5) {
            let edge = &first.graph.edges[e as usize];
            let [a, b] = [edge.a, edge.b].map(|v| first.graph.positions[v as usize]);
            let onto_light = |w: Vec3| p0 + (w - p0) * ((2.0 - p0.z) / (w.z - p0.z));
            let ends = [
                onto_light(0.5 * (a + b)),
                centroid + 0.7 * (onto_light(a) - centroid),
            ];
            for s in ends {
                let inside = s.x.abs() < 0.99 && s.y > -0.89 && s.y < 1.09;
                if a.z < 1.9 && b.z < 1.9 && inside && samples.len() < 900 {
                    samples.push(Vec3::new(s.x, s.y, 2.0));
                }
            }
        }
    }
    // A last block of fewer than eight samples, whose hits take the
    // one-at-a-time addition (the others are added eight at a time).
    let short = (8 + 5 - samples.len() % 8) % 8;
    samples.extend(light.samples(short.max(1), SamplePattern::Jittered, 6));
    samples.truncate(samples.len() / 8 * 8 + 5);
    let ss = build(&soup, &light, &samples, Structure::BruteForce);
    assert_eq!(samples.len() % 8, 5);
    (ss, probes)
}

/// The same scene through the sweep with its lanes (where AVX runs): the
/// planes, arcs and `f32` sample pass of the lanes give the slow twin's
/// counters, samples exactly on projected edges included.
#[test]
fn lane_sample_pass_equals_the_per_sample_test() {
    let (ss, probes) = samples_on_projected_edges();
    let n = ss.sample_count();
    let (mut unsure, mut swept, mut arcs, mut held) = (0, 0, 0, 0);
    for p in probes.into_iter().chain(receivers_under_edges_along_x()) {
        let mut lanes = vec![0i32; n];
        let mut silhouettes = Silhouettes::new();
        let mut k = Kernel::new(&ss, p, &mut silhouettes);
        let receiver = ss.sweep_receiver(&k);
        let mut chunks = ss.potential.chunks_exact(silhouette_lanes::LANES);
        for chunk in &mut chunks {
            let edges: [u32; silhouette_lanes::LANES] = chunk.try_into().unwrap();
            ss.sweep_candidates(&mut k, &receiver, &edges, &mut lanes);
        }
        for &e in chunks.remainder() {
            k.add_edge(&ss, e, &mut lanes);
        }
        (unsure, swept, arcs) = (unsure + k.unsure, swept + k.lane_swept, arcs + k.lane_arcs);
        held += k.held_swept;
        assert_eq!(lanes, slow_counters(&ss, p), "receiver {p:?}");
    }
    #[cfg(all(target_arch = "x86_64", feature = "std"))]
    if crate::simd::avx_available() {
        // The lanes swept most silhouettes, with their arcs, and the exact
        // path took the samples on the projected edges.
        assert!(
            swept > 500 && arcs * 4 > swept * 3,
            "{arcs} arcs of {swept}"
        );
        assert!(unsure >= 20, "{unsure} unsure samples");
        // Nearly every silhouette the lanes swept had samples to test, all
        // of them in the held arcs' pass.
        assert!(
            held > 500 && held * 4 > swept * 3,
            "{held} held arcs of {swept}"
        );
    }
    let _ = (unsure, swept, arcs, held);
}

/// The sample pass of eight edges at once, each over its own ranges,
/// against the pass of one edge at a time with the planes
/// [`SweepPlanes8::lane`](crate::simd::SweepPlanes8) gives: the same
/// counters, and the same samples left to the exact test. Every decided lane
/// of every batch of edges, at every probe, over up to three ranges per lane
/// (of up to 20 samples each, some empty, one often in the last eight
/// samples, where the counters are added one by one) that together cover
/// every sample, with random starts, lengths and contributions; a fixed rule
/// stands in for the exact test, so that any unsure sample one pass leaves
/// and the other does not shows.
#[cfg(all(target_arch = "x86_64", feature = "std"))]
#[test]
#[allow(unsafe_code)]
fn held_arcs_at_once_equal_one_edge_at_a_time() {
    use crate::simd::avx::{crossings_lanes8, crossings8, silhouette_planes8};
    if !crate::simd::avx_available() {
        return;
    }
    let (ss, probes) = samples_on_projected_edges();
    let n = ss.sample_count();
    let soa = ss.samples32();
    let mut rng = SplitMix64::new(41);
    let mut below = |m: usize| (rng.next_f64() * m as f64) as usize;
    let rule = |lane: usize, i: usize| (7 * lane + i).is_multiple_of(3);
    let (mut asked, mut lanes_tested, mut counted) = (0, 0, 0);
    for p in probes.into_iter().chain(receivers_under_edges_along_x()) {
        let mut silhouettes = Silhouettes::new();
        let k = Kernel::new(&ss, p, &mut silhouettes);
        let receiver = ss.sweep_receiver(&k).expect("AVX runs");
        for chunk in ss.potential.chunks_exact(silhouette_lanes::LANES) {
            let edges: [u32; silhouette_lanes::LANES] = chunk.try_into().unwrap();
            let mut corners = crate::simd::EdgeCorners8::default();
            ss.lane_corners(&edges, &mut corners);
            // SAFETY: AVX runs (checked above).
            let planes = unsafe { silhouette_planes8(&receiver, &corners) };
            // Each lane's first ranges together cover every sample; the
            // second and third ones fall anywhere, the third often at the
            // end.
            for base in (0..n).step_by(12) {
                let mut ranges = [[(0u32, 0u32); 3]; 8];
                let mut contributions = [0i32; 8];
                for lane in (0..8).filter(|&lane| planes.decided >> lane & 1 == 1) {
                    let start = base.saturating_sub(below(3));
                    let end = (base + 12 + below(9)).min(n);
                    let other = below(n);
                    let last = n - below(12).min(n);
                    ranges[lane] = [
                        (start, end),
                        (other, (other + below(21)).min(n)),
                        (last, (last + below(4) * below(4)).min(n)),
                    ]
                    .map(|(lo, hi)| (lo as u32, hi as u32));
                    contributions[lane] = [-2, -1, 1, 2][below(4)];
                }
                let mut one = vec![0i32; n];
                let mut asked_one = Vec::new();
                for (lane, lane_ranges) in ranges.iter().enumerate() {
                    for &(lo, hi) in lane_ranges.iter().filter(|(lo, hi)| lo < hi) {
                        let test = |i: usize| {
                            asked_one.push((lane, i));
                            rule(lane, i)
                        };
                        // SAFETY: AVX runs.
                        unsafe {
                            crossings8(
                                &planes.lane(lane),
                                p.to_array(),
                                soa,
                                lo as usize,
                                hi as usize,
                                &mut one,
                                contributions[lane],
                                test,
                            )
                        };
                    }
                }
                // The lanes with samples, as `HeldArcs::hold` marks them.
                let held = (0..8)
                    .filter(|&lane| ranges[lane].iter().any(|(lo, hi)| lo < hi))
                    .fold(0u32, |mask, lane| mask | 1 << lane);
                let mut all = vec![0i32; n];
                let mut asked_all = Vec::new();
                let test = |lane: usize, i: usize| {
                    asked_all.push((lane, i));
                    rule(lane, i)
                };
                // SAFETY: AVX runs.
                unsafe {
                    crossings_lanes8(
                        &planes,
                        p.to_array(),
                        soa,
                        held,
                        &ranges,
                        &contributions,
                        &mut all,
                        test,
                    )
                };
                asked_one.sort_unstable();
                asked_all.sort_unstable();
                assert_eq!(one, all, "receiver {p:?}, edges {edges:?}");
                assert_eq!(asked_one, asked_all, "receiver {p:?}, edges {edges:?}");
                asked += asked_one.len();
                lanes_tested += ranges
                    .iter()
                    .filter(|r| r.iter().any(|(lo, hi)| lo < hi))
                    .count();
                counted += one.iter().filter(|&&c| c != 0).count();
            }
        }
    }
    assert!(
        asked >= 1_000 && lanes_tested >= 1_000_000 && counted >= 200_000,
        "{asked} unsure samples, {lanes_tested} lanes, {counted} counters changed"
    );
}

/// The normals the lanes record (eight at once, in AVX) against the scalar
/// record's, bit for bit: random edges and receivers over many scales, and
/// edges whose normal is zero (an endpoint repeated, endpoints in line with
/// the receiver), where the scale is 1.
#[cfg(all(target_arch = "x86_64", feature = "std"))]
#[test]
#[allow(unsafe_code)]
fn lane_recorded_normals_equal_the_scalar_ones() {
    use super::reference::scaled_normal;
    use crate::simd::avx::recorded_normals8;
    if !crate::simd::avx_available() {
        return;
    }
    let mut rng = SplitMix64::new(97);
    let mut point = |scale: f32| {
        Vec3::new(
            rng.next_f64() as f32 - 0.5,
            rng.next_f64() as f32 - 0.5,
            rng.next_f64() as f32 - 0.5,
        ) * scale
    };
    let (mut zero, mut tested) = (0, 0);
    for round in 0..2000 {
        let scale = [1e-30, 1e-6, 1.0, 1e6, 1e30][round % 5];
        let p = point(scale);
        let mut corners = crate::simd::EdgeCorners8::default();
        let mut edges = [(Vec3::ZERO, Vec3::ZERO); 8];
        for (lane, edge) in edges.iter_mut().enumerate() {
            let a = point(scale);
            *edge = match (round + lane) % 8 {
                // The same endpoint twice.
                0 => (a, a),
                // In line with the receiver: `b - p` twice `a - p`, exactly
                // (a receiver at the origin, coordinates with few bits).
                1 => {
                    let a = Vec3::new(1.5, -2.25, 3.0) * scale;
                    (a, 2.0 * a)
                }
                _ => (a, point(scale)),
            };
            for axis in 0..3 {
                corners.a[axis][lane] = edge.0[axis];
                corners.b[axis][lane] = edge.1[axis];
            }
        }
        // The in-line lanes need the receiver at the origin.
        let p = if round % 3 == 0 { Vec3::ZERO } else { p };
        let pw = p.as_dvec3();
        // SAFETY: AVX runs (checked above).
        let lanes = unsafe { recorded_normals8(pw.to_array(), &corners) };
        for (lane, &(a, b)) in edges.iter().enumerate() {
            let normal = (a.as_dvec3() - pw).cross(b.as_dvec3() - pw);
            let expected = scaled_normal(normal).map(f32::to_bits);
            let got = [0, 1, 2].map(|axis| lanes[axis][lane].to_bits());
            assert_eq!(got, expected, "lane {lane}: {a:?} {b:?} from {p:?}");
            zero += usize::from(normal == DVec3::ZERO);
            tested += 1;
        }
    }
    assert!(
        zero >= 2_000 && tested == 16_000,
        "{zero} zero normals of {tested}"
    );
}

/// Near-light triangles (planes piercing the light) go through the
/// precomputed-side path: receivers on each side of their planes, exactly in
/// them, and in the light's band, with samples on both sides of each plane and
/// exactly in one, across several bit words.
#[test]
fn near_light_triangles_with_receivers_on_every_side() {
    let light = quad_light(Vec3::new(0.0, 0.0, 3.0), 0.8);
    // A grid through x = 0 and y = 0.25 exactly (samples in the planes below),
    // then stratified samples: 81 + 60 = 141 samples, three words.
    let mut samples: Vec<Vec3> = (0..81)
        .map(|k| {
            Vec3::new(
                (k % 9) as f32 * 0.125 - 0.5,
                (k / 9) as f32 * 0.125 - 0.5,
                3.0,
            )
        })
        .collect();
    samples.extend(light.samples(60, SamplePattern::Stratified, 3));
    let mut soup = Soup::default();
    // The plane x = 0, through the light.
    soup.push([
        Vec3::new(0.0, -2.0, 2.0),
        Vec3::new(0.0, 2.0, 2.5),
        Vec3::new(0.0, 0.0, 4.0),
    ]);
    // The plane y = 0.25, through the light the other way, a floor-like
    // triangle reaching far below.
    soup.push([
        Vec3::new(-3.0, 0.25, 0.5),
        Vec3::new(3.0, 0.25, 0.5),
        Vec3::new(0.5, 0.25, 3.5),
    ]);
    // A slanted triangle through the light's corner region.
    soup.push([
        Vec3::new(0.3, -0.9, 2.6),
        Vec3::new(0.9, -0.2, 3.4),
        Vec3::new(0.7, -0.7, 3.3),
    ]);
    // Some regular geometry too.
    soup.append(&cube(Vec3::new(-0.6, -0.6, 1.5), 0.2));
    let ss = build(&soup, &light, &samples, Structure::Hierarchy);
    assert_eq!(ss.statistics().near_light_triangles, 3);
    let mut receivers = receivers_box(Vec3::new(-1.5, -1.5, 0.0), Vec3::new(1.5, 1.5, 2.5), 40, 11);
    // Exactly in the plane x = 0 and in y = 0.25 (on the triangles and beside).
    for k in 0..8 {
        let t = k as f32 * 0.25 - 1.0;
        receivers.push(Vec3::new(0.0, t, 1.0 + 0.1 * k as f32));
        receivers.push(Vec3::new(t, 0.25, 0.8 + 0.15 * k as f32));
    }
    // Above the light, and in its plane (the band).
    receivers.extend(receivers_box(
        Vec3::new(-1.5, -1.5, 3.5),
        Vec3::new(1.5, 1.5, 4.5),
        10,
        12,
    ));
    receivers.extend(receivers_box(
        Vec3::new(-1.5, -1.5, 3.0),
        Vec3::new(1.5, 1.5, 3.0),
        10,
        13,
    ));
    let bits = check(&soup, &light, &samples, &receivers);
    // Not a test that cannot fail: the near-light triangles block some samples
    // and leave others, on both sides of x = 0.
    let words = samples.len().div_ceil(64);
    let visible = |r: usize| -> u32 {
        bits[r * words..][..words]
            .iter()
            .map(|w| w.count_ones())
            .sum()
    };
    let partial = |want_x_negative: bool| {
        receivers.iter().enumerate().any(|(r, p)| {
            (p.x < 0.0) == want_x_negative && p.z < 2.5 && {
                let v = visible(r) as usize;
                v > 0 && v < samples.len()
            }
        })
    };
    assert!(partial(true) && partial(false));
}

/// The axis-aligned plane shortcut gives `orient3d`'s sign: points on the
/// plane, one ulp off it either way, and far off, for planes at zero, small,
/// negative and huge coordinates, both windings.
#[test]
fn axis_plane_side_equals_orient3d() {
    let mut rng = SplitMix64::new(21);
    let mut checked = 0;
    for value in [0.0f32, 0.25, -3.5, 1.0e-30, 3.0e7, -3.0e30] {
        for axis in 0..3 {
            for flip in [false, true] {
                let corner = |x: f32, y: f32| {
                    let mut v = Vec3::ZERO;
                    v[axis] = value;
                    v[(axis + 1) % 3] = x;
                    v[(axis + 2) % 3] = y;
                    v
                };
                let (a, mut b, mut c) = (corner(-1.0, -1.0), corner(2.0, -0.5), corner(0.5, 1.5));
                if flip {
                    core::mem::swap(&mut b, &mut c);
                }
                let plane = AxisPlane::of(&[a, b, c]).expect("axis-aligned");
                for k in 0..40 {
                    let mut p = Vec3::new(
                        (rng.next_f64() as f32) * 8.0 - 4.0,
                        (rng.next_f64() as f32) * 8.0 - 4.0,
                        (rng.next_f64() as f32) * 8.0 - 4.0,
                    );
                    p[axis] = match k % 4 {
                        0 => value,
                        1 => f32::from_bits(value.to_bits() + 1),
                        2 => value - value.abs().max(1.0) * (rng.next_f64() as f32),
                        _ => p[axis] + value,
                    };
                    assert_eq!(plane.side(p), orient3d(a, b, c, p), "{value} {axis} {p:?}");
                    checked += usize::from(plane.side(p) == 0);
                }
            }
        }
    }
    assert!(checked > 0);
    // Not axis-aligned: no shortcut.
    assert!(AxisPlane::of(&[Vec3::ZERO, Vec3::X, Vec3::new(0.0, 1.0, 1.0)]).is_none());
}

/// A structure whose sample table the tests below read: `count` jittered
/// samples (seed `seed`) of a square light over one triangle.
fn sample_table(count: usize, seed: u64) -> SoftShadows {
    let light = quad_light(Vec3::new(0.0, 0.0, 3.0), 1.0);
    let samples = light.samples(count, SamplePattern::Jittered, seed);
    let mut soup = Soup::default();
    soup.push([Vec3::ZERO, Vec3::X, Vec3::Y]);
    build(&soup, &light, &samples, Structure::BruteForce)
}

proptest! {
    // The bucket lookup of a pseudo-angle range holds every sample the two
    // binary searches it replaced find, and adds only samples of the two end
    // buckets. Sample counts that are not multiples of 64, and ranges ending
    // exactly on bucket bounds and on sample angles.
    #[test]
    fn angle_buckets_cover_the_searched_range(
        count in prop::sample::select(vec![16usize, 100, 256, 300, 1024]),
        seed in 0u64..1000,
        lo_pick in 0usize..2048, hi_pick in 0usize..2048,
        snap in 0u32..3,
    ) {
        let ss = sample_table(count, seed);
        let angles = &ss.angles;
        let at = |pick: usize| match snap {
            0 => pick as f64 / 512.0,
            1 => angles[pick % angles.len()],
            _ => (pick as f64 + 0.37) / 512.0,
        };
        let (lo, hi) = (at(lo_pick), at(hi_pick));
        prop_assume!(lo <= hi && hi < 4.0);
        let bucket = |t: f64| ((t * ANGLE_SCALE) as usize).min(ANGLE_BUCKETS - 1);
        let first = ss.angle_starts[bucket(lo)] as usize;
        let last = ss.angle_starts[bucket(hi) + 1] as usize;
        let exact_first = angles.partition_point(|&t| t < lo);
        let exact_last = angles.partition_point(|&t| t <= hi);
        prop_assert!(first <= exact_first && exact_last <= last);
        for &t in &angles[first..exact_first] {
            prop_assert_eq!(bucket(t), bucket(lo));
        }
        for &t in &angles[exact_last..last] {
            prop_assert_eq!(bucket(t), bucket(hi));
        }
    }

    // An arc's sample ranges, straight or wrapped past the pseudo-angle 4
    // (ends in one bucket, in each other's, far apart): each sample at most
    // once, every sample of the cyclic arc and every one too close to the
    // centroid for an angle, and besides those only samples of the two end
    // buckets (or every sample, where a wrapped arc's widened ends overlap).
    #[test]
    fn arc_ranges_hold_the_cyclic_arc_once(
        count in prop::sample::select(vec![16usize, 100, 256, 300]),
        seed in 0u64..1000,
        lo_pick in 0usize..2048, width in prop::sample::select(vec![0usize, 1, 3, 40, 900, 2040, 2047]),
        jitter in 0.0f64..1.0,
    ) {
        let ss = sample_table(count, seed);
        let (angles, n) = (&ss.angles, ss.sample_count());
        let lo = (lo_pick as f64 + jitter) / 512.0;
        let hi = ((lo_pick + width) % 2048) as f64 / 512.0 + jitter / 512.0;
        let bucket = |t: f64| ((t * ANGLE_SCALE) as usize).min(ANGLE_BUCKETS - 1);
        let mut held = vec![0u32; n];
        for (start, end) in ss.arc_ranges(Some((lo, hi))) {
            for i in start..end.max(start) {
                held[i as usize] += 1;
            }
        }
        prop_assert!(held.iter().all(|&h| h <= 1), "a sample twice");
        let in_arc = |t: f64| if lo <= hi { lo <= t && t <= hi } else { t >= lo || t <= hi };
        let overlapping = lo > hi && bucket(lo) <= bucket(hi);
        for (k, &h) in held.iter().enumerate() {
            let Some(&t) = angles.get(k) else {
                prop_assert_eq!(h, 1, "central sample {} left out", k);
                continue;
            };
            if in_arc(t) {
                prop_assert_eq!(h, 1, "sample {} at {} left out of [{}, {}]", k, t, lo, hi);
            } else if h == 1 && !overlapping {
                prop_assert!(bucket(t) == bucket(lo) || bucket(t) == bucket(hi));
            }
        }
    }
}

/// Segments that pass within `f32` rounding of an edge (and through no edge or
/// vertex exactly): the reference ray is an `f32` ray, which near a silhouette
/// edge can miss a triangle the segment crosses (or the reverse), so the
/// reference sample must be one whose segment keeps clear of the silhouettes,
/// or the decision exact. Lone triangles (every edge a boundary, so a
/// silhouette) and a closed box grazed along its edges, one sample each (the
/// reference decides the whole answer), and 16 samples with one of them grazing.
#[test]
fn segments_grazing_an_edge_match_the_exact_oracle() {
    let light = quad_light(Vec3::new(0.0, 0.0, 2.0), 1.0);
    let mut rng = SplitMix64::new(77);
    let mut uniform = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f32();
    let (mut cases, mut ray_wrong) = (0, 0);
    for case in 0..600 {
        let closed = case % 3 == 2;
        let mut soup = Soup::default();
        let tri = if closed {
            let c = cube(
                Vec3::new(uniform(-0.3, 0.3), uniform(-0.3, 0.3), 1.2),
                uniform(0.1, 0.3),
            );
            soup.append(&c);
            c.triangles()[(uniform(0.0, 11.99)) as usize]
        } else {
            let t = [0, 1, 2]
                .map(|_| Vec3::new(uniform(-0.6, 0.6), uniform(-0.6, 0.6), uniform(1.0, 1.5)));
            soup.push(t);
            t
        };
        let p = Vec3::new(uniform(-0.5, 0.5), uniform(-0.5, 0.5), uniform(-0.5, 0.0));
        // A point on an edge, nudged by about one f32 unit, seen from p and
        // carried to the light's plane.
        let e = (uniform(0.0, 2.99)) as usize;
        let (a, b) = (tri[e], tri[(e + 1) % 3]);
        let on_edge = a + (b - a) * uniform(0.05, 0.95);
        let nudge = Vec3::new(uniform(-1.0, 1.0), uniform(-1.0, 1.0), uniform(-1.0, 1.0)) * 3e-7;
        let x = on_edge + nudge;
        let s = p + (x - p) * ((2.0 - p.z) / (x.z - p.z));
        let s = Vec3::new(s.x, s.y, 2.0);
        if s.x.abs() >= 1.0 || s.y.abs() >= 1.0 {
            continue;
        }
        let tris = soup.triangles();
        // Non-degenerate: the segment passes exactly through no edge or vertex.
        let exactly_on_an_edge = tris.iter().any(|&[a, b, c]| {
            [(a, b), (b, c), (c, a)]
                .iter()
                .any(|&(u, v)| orient3d(p, s, u, v) == 0)
        });
        if exactly_on_an_edge {
            continue;
        }
        let mut samples = vec![s];
        if case % 2 == 1 {
            samples.extend(light.samples(15, SamplePattern::Jittered, case));
        }
        let expected = oracle(&tris, p, &samples);
        for structure in [
            Structure::Hierarchy,
            Structure::Hemicube,
            Structure::BruteForce,
        ] {
            let ss = build(&soup, &light, &samples, structure);
            let mut bits = vec![0u64; ss.words_per_receiver()];
            ss.query(p, &mut bits).unwrap();
            assert_eq!(
                bits, expected,
                "case {case}, {structure:?}: p {p:?}, s {s:?}"
            );
        }
        // How often the plain f32 ray gets the grazing sample wrong: the
        // test reaches the cases it is about.
        let rays = build(&soup, &light, &[s], Structure::RayTrace);
        let mut bits = [0u64];
        rays.query(p, &mut bits).unwrap();
        ray_wrong += usize::from(bits[0] != oracle(&tris, p, &[s])[0]);
        cases += 1;
    }
    assert!(cases > 300, "{cases} cases");
    assert!(
        ray_wrong >= 5,
        "the f32 ray was wrong in only {ray_wrong} of {cases} cases"
    );
}

/// The reproducer of the grazing bug: a lone triangle whose edge passes within
/// rounding of the segment, blocked exactly and missed by the `f32` ray.
#[test]
fn a_segment_just_inside_a_boundary_edge_is_blocked() {
    let p = Vec3::new(0.15151036, 0.2620139, -0.17061268);
    let s = Vec3::new(-0.034059882, -0.21629325, 2.0);
    let (a, b, c) = (
        Vec3::new(-0.15460931, -0.11188279, 1.3279531),
        Vec3::new(0.3832815, 0.018400433, 1.336507),
        Vec3::new(0.65337294, 0.7792056, 1.3009845),
    );
    assert!(orient3d(p, s, a, b) != 0 && orient3d(p, s, b, c) != 0 && orient3d(p, s, c, a) != 0);
    assert!(segment_meets_triangle(p, s, a, b, c));
    let mut soup = Soup::default();
    soup.push([a, b, c]);
    let light = quad_light(Vec3::new(0.0, 0.0, 2.0), 1.0);
    for structure in [
        Structure::Hierarchy,
        Structure::Hemicube,
        Structure::BruteForce,
    ] {
        let ss = build(&soup, &light, &[s], structure);
        let mut bits = [0u64];
        assert_eq!(ss.query(p, &mut bits).unwrap(), 0, "{structure:?}");
    }
}

/// A light whose area overflows `f32` gave NaN irradiance (0 · ∞) at a receiver
/// that sees none of its samples.
#[test]
fn irradiance_of_an_unlit_receiver_is_zero_for_any_light() {
    let h = 2e19f32;
    let light = LightPolygon::new(&[
        Vec3::new(-h, -h, 10.0),
        Vec3::new(h, -h, 10.0),
        Vec3::new(h, h, 10.0),
        Vec3::new(-h, h, 10.0),
    ])
    .unwrap();
    assert!(light.area().is_infinite());
    let soup = Soup::default();
    let ss = build(
        &soup,
        &light,
        &[Vec3::new(0.0, 0.0, 10.0)],
        Structure::Hierarchy,
    );
    assert_eq!(ss.irradiance(Vec3::ZERO, Vec3::Z, &[0]), 0.0);
    assert!(ss.irradiance(Vec3::ZERO, Vec3::Z, &[1]) > 0.0);
}

/// Whether some segment from `p` to a sample passes exactly through an edge or
/// a vertex of a triangle it crosses (where bits are a matter of convention).
fn touches_an_edge(tris: &[[Vec3; 3]], p: Vec3, samples: &[Vec3]) -> bool {
    samples.iter().any(|&s| {
        tris.iter().any(|&[a, b, c]| {
            if orient3d(a, b, c, p) * orient3d(a, b, c, s) >= 0 {
                return false;
            }
            let e = [
                orient3d(p, s, a, b),
                orient3d(p, s, b, c),
                orient3d(p, s, c, a),
            ];
            e.contains(&0) && !(e.contains(&1) && e.contains(&-1))
        })
    })
}

/// A receiver whose segment to the light's centroid passes exactly through an
/// occluder vertex: the sweep starts on the projections of every edge at that
/// vertex. Treating each such tie as "negative" on its own put the centroid on
/// the negative side of every one of those planes at once, which no point is,
/// so the relative depth complexity came out wrong and every sample was
/// reported blocked (the review's reproducer: 0 of 64 visible, 48 exact). No
/// segment to a sample passes through an edge or vertex here (checked), so the
/// oracle's answer is the only right one.
#[test]
fn a_receiver_in_line_with_the_centroid_and_a_vertex_gets_the_oracle_bits() {
    let light = quad_light(Vec3::new(0.0, 0.0, 2.0), 0.5);
    let c = light.centroid();
    assert_eq!(c, Vec3::new(0.0, 0.0, 2.0));
    // The review's lone triangle over the origin, with a corner on the line
    // from the origin to the centroid.
    let mut lone = Soup::default();
    lone.push([
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.5),
        Vec3::new(0.0, 1.0, 0.5),
    ]);
    let stratified = light.samples(64, SamplePattern::Stratified, 1);
    assert!(!touches_an_edge(&lone.triangles(), Vec3::ZERO, &stratified));
    check(&lone, &light, &stratified, &[Vec3::ZERO]);
    // An axis-aligned square, a cube and a pyramid with dyadic corners, and
    // receivers at 2v - c for every corner v: v is then exactly the midpoint
    // of the receiver and the centroid.
    let square = grid(1, 1, |u, v| Vec3::new(0.3 * u, 0.3 * v, 1.0));
    let mut solids = cube(Vec3::new(0.0625, -0.03125, 1.0), 0.125);
    let apex = Vec3::new(-0.25, 0.125, 1.25);
    let base = [(-0.5, -0.125), (0.0, -0.125), (0.0, 0.375), (-0.5, 0.375)]
        .map(|(x, y)| Vec3::new(x, y, 1.0));
    for k in 0..4 {
        solids.push([base[k], base[(k + 1) % 4], apex]);
    }
    solids.push([base[0], base[2], base[1]]);
    solids.push([base[0], base[3], base[2]]);
    for seed in [1, 2] {
        let samples = light.samples(64, SamplePattern::Jittered, seed);
        for soup in [&lone, &square, &solids] {
            let receivers: Vec<Vec3> = soup
                .positions
                .iter()
                .map(|&v| 2.0 * Vec3::from(v) - c)
                .collect();
            for (&p, &v) in receivers.iter().zip(&soup.positions) {
                let v = Vec3::from(v);
                assert_eq!(orient3d(p, v, c, Vec3::X), 0);
                assert_eq!(orient3d(p, v, c, Vec3::Y), 0);
                assert!(!touches_an_edge(&soup.triangles(), p, &samples));
            }
            check(soup, &light, &samples, &receivers);
        }
    }
}

/// Receivers anywhere: those outside the root box (the default one, fitted
/// to the occluders and the light, or a small hint) go to the shells around
/// it. Every bit is brute force's, at any distance, and a receiver on a
/// ground much wider than the root tests about as many candidates as under a
/// root fitted to all the receivers: none falls back to every edge.
#[test]
fn receivers_beyond_the_root_get_exact_bits_without_falling_back() {
    let mut soup = torus(Vec3::new(0.0, 0.0, 1.0), 0.6, 0.2, 16);
    soup.append(&sphere(Vec3::new(0.4, 0.3, 1.6), 0.25, 10));
    let light = quad_light(Vec3::new(0.2, 0.1, 3.0), 0.3);
    let samples = light.samples(64, SamplePattern::Jittered, 9);
    // A ground four times as wide as the default root, lit from above.
    let mut ground = Vec::new();
    for j in 0..40 {
        for i in 0..40 {
            let at = |k: usize| -6.0 + 12.0 * k as f32 / 39.0;
            ground.push(Vec3::new(at(i), at(j), 0.0));
        }
    }
    let far = [
        Vec3::new(1e3, -2e3, 5.0),
        Vec3::new(-3e7, 1.0, -4e6),
        Vec3::new(0.1, 0.2, -1e20),
        Vec3::new(3e38, -3e38, 1e38),
        Vec3::new(0.0, 0.0, 3.0e5),
    ];
    let with = |root: Option<[Vec3; 2]>| {
        SoftShadows::new(
            &soup.view(),
            light.clone(),
            &samples,
            SsvOptions {
                root_bounds: root,
                ..SsvOptions::default()
            },
        )
        .unwrap()
    };
    let default = with(None);
    let hint = with(Some([Vec3::new(-0.2, -0.2, 0.9), Vec3::new(0.3, 0.1, 1.3)]));
    let fitted = with(Some([
        Vec3::new(-6.0, -6.0, -0.1),
        Vec3::new(6.0, 6.0, 3.4),
    ]));
    let brute = build(&soup, &light, &samples, Structure::BruteForce);
    let mut candidates = [0u64; 3];
    for (r, &p) in ground.iter().chain(&far).enumerate() {
        let mut expected = [0u64; 1];
        brute.query(p, &mut expected).unwrap();
        for (k, ss) in [&default, &hint, &fitted].into_iter().enumerate() {
            let mut bits = [0u64; 1];
            let info = ss.query_detailed(p, &mut bits).unwrap();
            assert_eq!(bits, expected, "structure {k}, receiver {r} at {p:?}");
            if r < ground.len() {
                candidates[k] += u64::from(info.candidates);
            }
        }
    }
    // Shadows reach the ground, so some bits are clear and some set.
    let potential = brute.statistics().potential_edges as u64;
    let ground_count = ground.len() as u64;
    assert!(candidates[2] > 0 && candidates[2] * 10 < potential * ground_count);
    for k in 0..2 {
        assert!(
            candidates[k] <= 2 * candidates[2],
            "structure {k}: {} candidates against {} with a fitted root",
            candidates[k],
            candidates[2]
        );
    }
}

/// Receivers whose pyramid to the light misses the occluders' box are
/// answered without a walk or a ray; near the shadow's edge, where the pyramid
/// just grazes the box or the object, the bits are still the oracle's. The
/// light is slanted and large, the object a thin open sheet (no symmetry to
/// hide a wrong plane orientation).
#[test]
fn receivers_outside_the_shadow_pyramid_are_lit_without_a_ray() {
    let mut soup = grid(6, 3, |u, v| {
        Vec3::new(0.8 * u - 0.3, 0.5 * v - 0.2, 1.0 + 0.3 * u * v)
    });
    soup.append(&sphere(Vec3::new(0.6, 0.4, 1.4), 0.15, 6));
    let light = LightPolygon::new(&[
        Vec3::new(-0.4, -0.3, 3.0),
        Vec3::new(0.7, -0.2, 3.3),
        Vec3::new(0.6, 0.5, 3.4),
        Vec3::new(-0.5, 0.4, 3.1),
    ])
    .unwrap();
    let samples = light.samples(64, SamplePattern::Jittered, 4);
    let tris = soup.triangles();
    let mut receivers = receivers_box(
        Vec3::new(-4.0, -4.0, -0.5),
        Vec3::new(4.0, 4.0, 0.5),
        400,
        13,
    );
    // And a ring hugging the occluders' box just below it.
    for k in 0..64 {
        let a = core::f32::consts::TAU * k as f32 / 64.0;
        receivers.push(Vec3::new(0.2 + 0.9 * a.cos(), 0.2 + 0.9 * a.sin(), 0.9));
    }
    let mut counts = [0usize; 2];
    for structure in [
        Structure::Hierarchy,
        Structure::Hemicube,
        Structure::BruteForce,
    ] {
        let ss = build(&soup, &light, &samples, structure);
        for (r, &p) in receivers.iter().enumerate() {
            let mut bits = [0u64; 1];
            let info = ss.query_detailed(p, &mut bits).unwrap();
            assert_eq!(
                bits.to_vec(),
                oracle(&tris, p, &samples),
                "{structure:?}: receiver {r} at {p:?}"
            );
            counts[usize::from(info.rays == 0)] += 1;
        }
    }
    // Both paths are taken often.
    assert!(counts[0] > 150 && counts[1] > 300, "{counts:?}");
}

/// Creation on rayon's threads (`SsvOptions::parallel`) and a batch built in
/// parallel give the sequential bits.
#[cfg(feature = "parallel")]
#[test]
fn parallel_creation_and_batches_give_the_sequential_bits() {
    let mut soup = torus(Vec3::new(0.0, 0.0, 1.0), 1.0, 0.3, 12);
    soup.append(&sphere(Vec3::new(0.3, 0.2, 1.8), 0.3, 8));
    let light = quad_light(Vec3::new(0.2, 0.0, 4.0), 0.8);
    let samples = light.samples(128, SamplePattern::Jittered, 6);
    let receivers = receivers_box(
        Vec3::new(-4.0, -4.0, 0.0),
        Vec3::new(4.0, 4.0, 0.3),
        3000,
        2,
    );
    let bits = |parallel: bool, structure: Structure| {
        let options = SsvOptions {
            structure,
            parallel,
            ..SsvOptions::default()
        };
        let ss = SoftShadows::new(&soup.view(), light.clone(), &samples, options).unwrap();
        let mut bits = vec![0u64; receivers.len() * ss.words_per_receiver()];
        ss.query_batch(&receivers, &mut bits, None, true).unwrap();
        bits
    };
    let serial = bits(false, Structure::BruteForce);
    assert_eq!(bits(true, Structure::Hierarchy), serial);
    assert_eq!(bits(false, Structure::Hierarchy), serial);
    assert_eq!(bits(true, Structure::Hemicube), serial);
    assert!(serial.iter().any(|&w| w != 0) && serial.iter().any(|&w| w != !0));
}

/// A small scene through the hierarchy (with its edge bounds) against the
/// exact oracle: small enough for `make miri`, which runs it to check the
/// unsafe code a build and a query reach (the AVX lanes of the edge bounds,
/// the silhouette record's uninitialised slots, fallible allocation, the BVH
/// of the reference ray).
#[test]
fn miri_small_scene_gets_the_oracle_bits() {
    let mut soup = sphere(Vec3::new(0.0, 0.0, 1.2), 0.5, 3);
    soup.append(&grid(2, 2, |u, v| {
        Vec3::new(2.0 * u - 1.0, 2.0 * v - 1.0, 0.0)
    }));
    let light = quad_light(Vec3::new(0.1, 0.2, 3.0), 0.6);
    let samples = light.samples(16, SamplePattern::Jittered, 3);
    let receivers = receivers_box(Vec3::new(-0.6, -0.6, 0.0), Vec3::new(0.6, 0.6, 0.3), 3, 5);
    let ss = build(&soup, &light, &samples, Structure::Hierarchy);
    let tris = soup.triangles();
    let mut visible = 0;
    for &p in &receivers {
        let mut bits = vec![0u64; ss.words_per_receiver()];
        visible += ss.query(p, &mut bits).unwrap();
        assert_eq!(bits, oracle(&tris, p, &samples), "at {p:?}");
    }
    // Some samples blocked and some visible: the scene casts a penumbra.
    assert!(
        visible > 0 && visible < 16 * receivers.len() as u32,
        "{visible}"
    );
}

/// `update` against `new` on the moved occluders: the same bits at every
/// receiver (and the oracle's on a subset), for every structure, through
/// motions that keep the reference BVH's triangles (rigid, a twist: refitted)
/// and one that changes them (a sphere added: built anew); an update that
/// fails leaves the structure answering as before.
#[test]
fn updated_structures_answer_as_new_ones() {
    let mut soup = torus(Vec3::new(0.0, 0.0, 1.0), 1.0, 0.3, 12);
    soup.append(&cube(Vec3::new(0.3, 0.2, 1.8), 0.25));
    let light = quad_light(Vec3::new(0.2, 0.0, 4.0), 0.9);
    let samples = light.samples(64, SamplePattern::Jittered, 9);
    let receivers = receivers_box(Vec3::new(-3.0, -3.0, 0.0), Vec3::new(3.0, 3.0, 0.5), 400, 4);
    let twisted = |angle: f32, shift: Vec3| {
        soup.transformed(|p| glam::Quat::from_rotation_z(angle * (p.z - 1.0)) * p + shift)
    };
    let mut bigger = twisted(0.3, Vec3::ZERO);
    bigger.append(&sphere(Vec3::new(-0.8, 0.5, 2.2), 0.3, 6));
    let motions = [
        twisted(0.0, Vec3::new(0.4, -0.3, 0.2)),
        twisted(0.8, Vec3::ZERO),
        bigger,
        twisted(-0.5, Vec3::new(0.0, 0.2, -0.1)),
    ];
    for structure in ALL {
        let mut ss = build(&soup, &light, &samples, structure);
        let words = ss.words_per_receiver();
        for (m, moved) in motions.iter().enumerate() {
            ss.update(&moved.view()).unwrap();
            let fresh = build(moved, &light, &samples, structure);
            let tris = moved.triangles();
            for (r, &p) in receivers.iter().enumerate() {
                let (mut got, mut want) = (vec![0u64; words], vec![0u64; words]);
                ss.query(p, &mut got).unwrap();
                fresh.query(p, &mut want).unwrap();
                assert_eq!(
                    got, want,
                    "{structure:?}, motion {m}, receiver {r} at {p:?}"
                );
                if r % 20 == 0 {
                    assert_eq!(got, oracle(&tris, p, &samples), "{structure:?}, motion {m}");
                }
            }
        }
        // Refused: a coordinate beyond the BVH's range (the one occluder a
        // structure can refuse); the last scene stays.
        if !cfg!(feature = "bvh") {
            continue;
        }
        let last = motions.last().unwrap();
        let far = last.transformed(|p| if p.z > 1.2 { p * 1e13 } else { p });
        assert!(ss.update(&far.view()).is_err());
        let tris = last.triangles();
        for &p in receivers.iter().step_by(10) {
            let mut got = vec![0u64; words];
            ss.query(p, &mut got).unwrap();
            assert_eq!(
                got,
                oracle(&tris, p, &samples),
                "{structure:?} after a refused update"
            );
        }
    }
}

/// The corners the lanes read for a batch of edges (the edge records
/// transposed in registers, [`crate::simd::avx::edge_corners8`]) against the
/// graph's: each lane's endpoints and third vertices, and the lanes marked
/// irregular exactly where the edge has not two adjacent triangles (a
/// grid's border, a fin shared by three triangles), for batches of edges in
/// scattered order. Under Miri (`make miri`, for the records' loads) on a
/// few batches only.
#[cfg(all(target_arch = "x86_64", feature = "std"))]
#[test]
fn miri_lane_corners_are_the_graphs() {
    if !crate::simd::avx_available() {
        return;
    }
    let mut soup = sphere(Vec3::new(0.0, 0.0, 1.2), 0.5, 3);
    soup.append(&grid(3, 2, |u, v| Vec3::new(2.0 * u - 1.0, v - 0.5, 0.0)));
    // A third triangle on one of the grid's edges.
    let fin = soup.triangles()[soup.triangles().len() - 1];
    soup.push([fin[0], fin[1], Vec3::new(0.1, 0.2, 0.7)]);
    let light = quad_light(Vec3::new(0.1, 0.2, 3.0), 0.6);
    let samples = light.samples(16, SamplePattern::Jittered, 3);
    let ss = build(&soup, &light, &samples, Structure::BruteForce);
    let g = &ss.graph;
    let count = g.edges.len() as u32;
    let mut rng = SplitMix64::new(17);
    let batches = if cfg!(miri) { 3 } else { 400 };
    let mut irregular_seen = 0;
    for _ in 0..batches {
        let edges: [u32; 8] =
            core::array::from_fn(|_| ((rng.next_f64() * f64::from(count)) as u32).min(count - 1));
        let mut corners = crate::simd::EdgeCorners8::default();
        let irregular = ss.lane_corners(&edges, &mut corners);
        for (lane, &e) in edges.iter().enumerate() {
            let edge = &g.edges[e as usize];
            let at = |v: u32| g.positions[v as usize].to_array();
            let lane_of = |w: &[[f32; 8]; 3]| [0, 1, 2].map(|axis| w[axis][lane]);
            assert_eq!(lane_of(&corners.a), at(edge.a), "edge {e}");
            assert_eq!(lane_of(&corners.b), at(edge.b), "edge {e}");
            match g.third_of(edge) {
                &[u, v] => {
                    assert_eq!(irregular >> lane & 1, 0, "edge {e}");
                    assert_eq!(lane_of(&corners.u), at(u), "edge {e}");
                    assert_eq!(lane_of(&corners.v), at(v), "edge {e}");
                }
                _ => {
                    assert_eq!(irregular >> lane & 1, 1, "edge {e}");
                    irregular_seen += 1;
                }
            }
        }
    }
    assert!(irregular_seen > 0 || cfg!(miri), "no irregular edge drawn");
}

/// The reference sample's prefilter over the recorded silhouettes, eight at
/// a time in `f32` lanes where AVX runs, against the `f64` test alone: the
/// same answer for every direction, with normals at every angle to it and
/// many within a hair of the bound (on either side), zero and unscaled
/// normals among them, and records of every length (the lanes' remainder).
/// Under Miri (`make miri`, for the lanes' loads) on a few directions only.
#[test]
fn miri_recorded_planes_clear_as_the_f64_test() {
    use super::reference::scaled_normal;
    let mut rng = SplitMix64::new(29);
    let mut unit = || {
        let v = DVec3::new(
            rng.next_f64() - 0.5,
            rng.next_f64() - 0.5,
            rng.next_f64() - 0.5,
        );
        v / v.length()
    };
    let bound = NEAR_ANGLE + 1e-6;
    let tries = if cfg!(miri) { 4 } else { 3000 };
    let (mut cleared, mut refused) = (0, 0);
    for t in 0..tries {
        let sw = unit() * [1e-3, 0.7, 3.0, 250.0][t % 4];
        let bound_squared = bound * bound * sw.length_squared();
        let mut silhouettes = Silhouettes::new();
        let count = 1 + (7 * t + 9) % 29;
        for e in 0..count {
            let other = unit();
            let perpendicular = other - sw * (other.dot(sw) / sw.length_squared());
            let perpendicular = perpendicular / perpendicular.length();
            // The sine of the angle between the plane and `sw`: about the
            // bound (either side), or anywhere.
            let sine = match e % 4 {
                0 => bound * (1.0 + (unit().x) * 1e-6),
                1 => bound * (1.0 + (unit().x) * 1e-2),
                2 => unit().x.abs(),
                _ => bound * 2.0,
            };
            let n = perpendicular * (1.0 - sine * sine).sqrt() + sw / sw.length() * sine;
            let n = match e % 11 {
                7 => DVec3::ZERO,
                9 => n * 1e-3,
                _ => n * [1e-9, 1.0, 1e12][e % 3],
            };
            let normal = if e % 11 == 9 {
                n.as_vec3().to_array()
            } else {
                scaled_normal(n)
            };
            silhouettes.record_scaled(e as u32, normal);
        }
        // `near` answers "near" for every edge: the answer is the
        // prefilter's alone.
        let near = |_: DVec3, _: u32| true;
        let f64_test = silhouettes.recorded().all(|(_, n)| {
            let n = n.as_dvec3();
            let along = n.dot(sw);
            along * along > bound_squared * n.length_squared()
        });
        assert_eq!(
            silhouettes.clear_of(sw, bound, near),
            f64_test,
            "direction {sw:?}, {count} recorded"
        );
        // Each edge alone too (the answer of a one-edge record).
        for (e, n) in silhouettes.recorded().collect::<Vec<_>>() {
            let mut one = Silhouettes::new();
            for _ in 0..8 {
                one.record_scaled(e, n.to_array());
            }
            let n64 = n.as_dvec3();
            let along = n64.dot(sw);
            let want = along * along > bound_squared * n64.length_squared();
            assert_eq!(one.clear_of(sw, bound, near), want, "{n:?} at {sw:?}");
            if want {
                cleared += 1;
            } else {
                refused += 1;
            }
        }
    }
    assert!(
        cleared > 100 && refused > 100 || cfg!(miri),
        "{cleared} cleared, {refused} refused"
    );
}

/// The set-up in `f32` lanes against the scalar set-up, candidate by
/// candidate: the same counters, silhouette count and recorded silhouettes at
/// every receiver, on an ordinary scene and on one built so that decisions
/// sit exactly on their bounds (light vertices on the planes through the
/// receiver and an edge, receivers on triangles' planes and on edges'
/// lines), where the lanes must leave them to the scalar set-up. Also that the
/// lanes decide most candidates where the processor runs AVX. Under Miri
/// (`make miri`, for the lanes' unsafe loads) on a few receivers only.
#[test]
fn miri_lanes_set_up_equals_the_scalar_one() {
    // Edges along x at height 1; with the receiver at the origin, the light's
    // corners at y = ±0.5, z = 2 lie on the planes through two of them.
    let mut soup = edges_along_x();
    soup.append(&torus(Vec3::new(-0.4, -0.3, 1.1), 0.25, 0.08, 8));
    let light = LightPolygon::new(&[
        Vec3::new(-1.0, -0.5, 2.0),
        Vec3::new(1.0, -0.5, 2.0),
        Vec3::new(1.0, 0.5, 2.0),
        Vec3::new(-1.0, 0.5, 2.0),
    ])
    .unwrap();
    let samples = light.samples(64, SamplePattern::Jittered, 5);
    let ss = build(&soup, &light, &samples, Structure::BruteForce);
    let mut receivers = vec![Vec3::ZERO];
    receivers.extend(receivers_box(
        Vec3::new(-1.5, -1.5, -0.5),
        Vec3::new(1.5, 1.5, 0.9),
        120,
        17,
    ));
    // On triangles' planes and on edges' lines (rounded to f32).
    let mut rng = SplitMix64::new(23);
    for t in soup.triangles().iter().step_by(7) {
        let (s, r) = (rng.next_f64() as f32, rng.next_f64() as f32);
        receivers.push(t[0] + 2.0 * s * (t[1] - t[0]) + 2.0 * r * (t[2] - t[0]));
        receivers.push(t[0] + (3.0 * s - 1.0) * (t[1] - t[0]));
    }
    let potential: Vec<u32> = ss.potential.clone();
    let (mut decided, mut lanes, mut swept) = (0usize, 0usize, 0u32);
    let tried = if cfg!(miri) { 2 } else { receivers.len() };
    for &p in &receivers[..tried] {
        let n = samples.len();
        let mut scalar_silhouettes = Silhouettes::new();
        let mut scalar = Kernel::new(&ss, p, &mut scalar_silhouettes);
        let mut scalar_counters = vec![0i32; n];
        let mut scalar_count = 0u32;
        for &e in &potential {
            scalar_count += u32::from(scalar.add_edge(&ss, e, &mut scalar_counters));
        }
        let mut lane_silhouettes = Silhouettes::new();
        let mut lane = Kernel::new(&ss, p, &mut lane_silhouettes);
        let receiver = ss.sweep_receiver(&lane);
        let mut lane_counters = vec![0i32; n];
        let mut lane_count = 0u32;
        let mut chunks = potential.chunks_exact(silhouette_lanes::LANES);
        for chunk in &mut chunks {
            let edges: [u32; silhouette_lanes::LANES] = chunk.try_into().unwrap();
            if let Some(d) = ss.setup_masks(&receiver, &edges) {
                decided += (!d.undecided & 0xFF).count_ones() as usize;
                lanes += silhouette_lanes::LANES;
            }
            lane_count += ss.sweep_candidates(&mut lane, &receiver, &edges, &mut lane_counters);
        }
        for &e in chunks.remainder() {
            lane_count += u32::from(lane.add_edge(&ss, e, &mut lane_counters));
        }
        swept += lane.lane_swept;
        assert_eq!(lane_counters, scalar_counters, "counters at {p:?}");
        assert_eq!(lane_count, scalar_count, "silhouettes at {p:?}");
        let recorded = |s: &Silhouettes| s.recorded().collect::<Vec<_>>();
        assert_eq!(
            recorded(&lane_silhouettes),
            recorded(&scalar_silhouettes),
            "recorded silhouettes at {p:?}"
        );
        assert_eq!(lane_silhouettes.overflow, scalar_silhouettes.overflow);
    }
    #[cfg(all(target_arch = "x86_64", feature = "std"))]
    if crate::simd::avx_available() {
        assert!(
            decided * 4 > lanes * 3,
            "the lanes decided {decided} of {lanes} candidates"
        );
        // Their planes, arcs and sample pass ran (under Miri too).
        assert!(swept > 0, "no silhouette swept in lanes");
    }
    let _ = (decided, lanes, swept);
}

/// The lanes' arcs hold the exact pseudo-angles of both endpoints'
/// projections (the `f64` projection, whose rounding is far below the
/// lanes'), the short way round: a margin below the lanes' rounding leaves
/// some outside.
#[cfg(all(target_arch = "x86_64", feature = "std"))]
#[test]
fn lane_arcs_hold_the_exact_endpoint_angles() {
    if !crate::simd::avx_available() {
        return;
    }
    let soup = torus(Vec3::new(0.1, -0.2, 1.0), 0.5, 0.15, 24);
    let light = light_over_edges_along_x();
    let samples = light.samples(64, SamplePattern::Jittered, 5);
    let ss = build(&soup, &light, &samples, Structure::BruteForce);
    let mut checked = 0;
    let receivers = receivers_box(Vec3::new(-1.5, -1.5, -0.5), Vec3::new(1.5, 1.5, 0.8), 60, 3);
    for p in receivers {
        let mut silhouettes = Silhouettes::new();
        let kernel = Kernel::new(&ss, p, &mut silhouettes);
        let Some(receiver) = ss.sweep_receiver(&kernel) else {
            continue;
        };
        for chunk in ss.potential.chunks_exact(silhouette_lanes::LANES) {
            let edges: [u32; silhouette_lanes::LANES] = chunk.try_into().unwrap();
            let mut corners = crate::simd::EdgeCorners8::default();
            ss.lane_corners(&edges, &mut corners);
            #[allow(unsafe_code)]
            // SAFETY: AVX runs (checked above).
            let planes = unsafe { crate::simd::avx::silhouette_planes8(&receiver, &corners) };
            for (i, &e) in edges.iter().enumerate() {
                if planes.arc >> i & 1 == 0 {
                    continue;
                }
                let edge = &ss.graph.edges[e as usize];
                let angle = |v: u32| {
                    let w = ss.graph.positions[v as usize].as_dvec3() - kernel.pw;
                    let q = w * (kernel.hc / w.dot(kernel.toward)) - kernel.cp;
                    pseudo_angle(q.dot(ss.u_axis), q.dot(ss.v_axis))
                };
                let (lo, hi) = (f64::from(planes.lo[i]), f64::from(planes.hi[i]));
                // The lanes' buckets are the sweep's for the same ends.
                let bucket = |t: f64| ((t * ANGLE_SCALE) as usize).min(ANGLE_BUCKETS - 1);
                assert_eq!(
                    planes.buckets.map(|b| b[i] as usize),
                    [bucket(lo), bucket(hi)],
                    "buckets of [{lo}, {hi}]"
                );
                let inside = |t: f64| {
                    if lo <= hi {
                        lo <= t && t <= hi
                    } else {
                        t >= lo || t <= hi
                    }
                };
                let (ta, tb) = (angle(edge.a), angle(edge.b));
                assert!(
                    inside(ta) && inside(tb),
                    "{ta} {tb} outside [{lo}, {hi}] at {p:?}"
                );
                // The short way: the arc is under a half turn plus margins.
                let length = if lo <= hi { hi - lo } else { hi + 4.0 - lo };
                assert!(length < 2.5, "arc of {length} at {p:?}");
                checked += 1;
            }
        }
    }
    assert!(checked > 1000, "{checked} arcs checked");
}

/// `direction_near_edge` (its plane test in squares first) against its
/// definition in angles (lengths by square roots), on directions at angles
/// from the edge's plane on both sides of `NEAR_ANGLE` (never within 1e-6 of
/// it, where rounding may take either side), beside and beyond the edge's
/// ends, and on edges seen end-on.
#[test]
fn near_edge_test_equals_its_definition_in_angles() {
    let by_angles = |s: DVec3, a: DVec3, b: DVec3| {
        let n = a.cross(b);
        let (ls, la, lb, ln) = (s.length(), a.length(), b.length(), n.length());
        let near_endpoint =
            |e: DVec3, le: f64| e.cross(s).length() <= NEAR_ANGLE * le * ls && e.dot(s) > 0.0;
        if ln <= 1e-9 * la * lb {
            return near_endpoint(a, la) || near_endpoint(b, lb);
        }
        if n.dot(s).abs() > NEAR_ANGLE * ln * ls {
            return false;
        }
        let inside_a = a.cross(s).dot(n) >= -NEAR_ANGLE * la * ls * ln;
        let inside_b = s.cross(b).dot(n) >= -NEAR_ANGLE * ls * lb * ln;
        (inside_a && inside_b) || near_endpoint(a, la) || near_endpoint(b, lb)
    };
    let mut rng = SplitMix64::new(29);
    let mut unit = || {
        DVec3::new(
            rng.next_f64() - 0.5,
            rng.next_f64() - 0.5,
            rng.next_f64() - 0.5,
        )
        .normalize()
    };
    let (mut near, mut far) = (0, 0);
    for k in 0..20_000 {
        let a = unit() * (0.5 + (k % 7) as f64);
        let b = if k % 10 == 0 {
            // Seen end-on: b along a (within rounding).
            a * 1.7
        } else {
            unit() * (0.3 + (k % 5) as f64)
        };
        let n = a.cross(b).normalize_or_zero();
        // A direction along the edge (between, beside or beyond its ends),
        // tilted off the plane by a multiple of the near angle.
        let t = 1.4 * (k % 11) as f64 / 10.0 - 0.2;
        let along = (a + (b - a) * t).normalize_or_zero();
        let tilt = NEAR_ANGLE * [0.0, 0.5, 0.999, 1.001, 2.0, 1e3][k % 6];
        let s = (along + n * libm::tan(tilt)) * (0.1 + (k % 3) as f64);
        let got = direction_near_edge(s, a, b);
        assert_eq!(got, by_angles(s, a, b), "s {s:?} a {a:?} b {b:?}");
        if got {
            near += 1;
        } else {
            far += 1;
        }
    }
    assert!(near > 3_000 && far > 3_000, "{near} near, {far} far");
}

/// A receiver under more near silhouettes than a query records: the
/// reference sample chosen (the recorded edges, then the structure's
/// candidates from the first edge that did not fit) equals the slow
/// definition (no candidate that is a silhouette at the receiver comes near
/// the sample's direction), over windows of candidate samples of which many
/// lie on the projections of the edges.
#[test]
fn reference_sample_past_the_record_equals_its_definition() {
    // 700 separate small triangles (2,100 boundary edges, each a silhouette
    // from every receiver below) between the receiver and a large light.
    let mut soup = Soup::default();
    let mut rng = SplitMix64::new(41);
    for _ in 0..700 {
        let c = Vec3::new(
            rng.next_f64() as f32 * 1.6 - 0.8,
            rng.next_f64() as f32 * 1.6 - 0.8,
            rng.next_f64() as f32 * 0.8 + 0.6,
        );
        let r = 0.01 + 0.02 * rng.next_f64() as f32;
        let t = rng.next_f64() as f32 * 6.0;
        let corner = |k: f32| c + r * Vec3::new((t + k * 2.1).cos(), (t + k * 2.1).sin(), 0.0);
        soup.push([corner(0.0), corner(1.0), corner(2.0)]);
    }
    let light = quad_light(Vec3::new(0.0, 0.0, 2.0), 1.0);
    let p = Vec3::new(0.03, -0.02, 0.0);
    // Samples on the projections of edge points from `p`, some nudged a few
    // units of rounding off them, then jittered ones.
    let mut samples = Vec::new();
    for (i, [a, b, _]) in soup.triangles().into_iter().enumerate().step_by(3) {
        let w = a + (b - a) * (0.2 + 0.6 * (i % 5) as f32 / 4.0);
        let s = p + (w - p) * ((2.0 - p.z) / (w.z - p.z));
        if s.x.abs() < 0.95 && s.y.abs() < 0.95 && samples.len() < 200 {
            let nudge = [0.0, 1e-6, -3e-5, 2e-4][i % 4];
            samples.push(Vec3::new(s.x + nudge, s.y, 2.0));
        }
    }
    samples.extend(light.samples(56, SamplePattern::Jittered, 7));
    let ss = build(&soup, &light, &samples, Structure::Hierarchy);
    let n = samples.len();
    let mut counters = vec![0i32; n];
    let mut silhouettes = Silhouettes::new();
    ss.sweep(
        p,
        &mut counters,
        &mut QueryInfo::default(),
        &mut silhouettes,
    );
    assert!(silhouettes.overflow, "{} recorded", silhouettes.len);
    let pw = p.as_dvec3();
    let height = (ss.plane_point - pw).dot(ss.plane_normal).abs();
    let near_silhouette = |sw: DVec3, e: u32| {
        let edge = &ss.graph.edges[e as usize];
        let [a, b] = [edge.a, edge.b].map(|v| ss.graph.positions[v as usize].as_dvec3() - pw);
        direction_near_edge(sw, a, b) && ss.silhouette_weight(p, e) != 0
    };
    let (mut chosen, mut refused) = (0, 0);
    for start in 0..n {
        let window: Vec<usize> = (start..n.min(start + 8)).collect();
        let slow = window
            .iter()
            .take(reference::REFERENCE_TRIES)
            .find(|&&k| {
                let sw = ss.samples[ss.order[k] as usize].as_dvec3() - pw;
                let deep = ss.insets[k] > 4.0 * NEAR_ANGLE * sw.length_squared() / height;
                let mut clear = true;
                ss.for_each_candidate(p, |e| clear &= !near_silhouette(sw, e));
                if deep && !clear {
                    refused += 1;
                }
                deep && clear
            })
            .map(|&k| ss.samples[ss.order[k] as usize]);
        let fast = ss.reference_sample(p, window.iter().copied(), &silhouettes);
        assert_eq!(fast, slow, "window from {start}");
        chosen += usize::from(slow.is_some());
    }
    // Both answers occur, and samples were refused for a near silhouette.
    assert!(
        chosen > 0 && chosen < n && refused > 0,
        "{chosen} chosen of {n}, {refused} refused"
    );
}
