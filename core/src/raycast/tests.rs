//! Tests of the triangle test against an independent f64 Möller–Trumbore, of
//! watertightness on closed meshes, and of the BVH against brute force.

use alloc::vec::Vec;

use glam::Vec3;
use rand::{Rng, SeedableRng, rngs::SmallRng};

use super::*;

/// Möller–Trumbore in f64: the independent twin of the watertight f32 test.
/// Returns `(t, u, v)` and the smallest barycentric, so callers can tell
/// edge-grazing rays apart from clear hits.
fn moller_trumbore_f64(ray: &Ray, [a, b, c]: [Vec3; 3]) -> Option<(f64, f64, f64, f64)> {
    type V = [f64; 3];
    let wide = |v: Vec3| -> V { [v.x.into(), v.y.into(), v.z.into()] };
    let sub = |p: V, q: V| -> V { [p[0] - q[0], p[1] - q[1], p[2] - q[2]] };
    let dot = |p: V, q: V| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
    let cross = |p: V, q: V| -> V {
        [
            p[1] * q[2] - p[2] * q[1],
            p[2] * q[0] - p[0] * q[2],
            p[0] * q[1] - p[1] * q[0],
        ]
    };
    let (o, d) = (wide(ray.origin), wide(ray.direction));
    let (a, b, c) = (wide(a), wide(b), wide(c));
    let e1 = sub(b, a);
    let e2 = sub(c, a);
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det == 0.0 {
        return None;
    }
    let s = sub(o, a);
    let u = dot(s, p) / det;
    let q = cross(s, e1);
    let v = dot(d, q) / det;
    let t = dot(e2, q) / det;
    let w = 1.0 - u - v;
    Some((t, u, v, u.min(v).min(w)))
}

fn random_triangle(rng: &mut SmallRng) -> [Vec3; 3] {
    let mut p = || {
        Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
    };
    [p(), p(), p()]
}

fn random_ray(rng: &mut SmallRng, spread: f32) -> Ray {
    let origin = Vec3::new(
        rng.random_range(-spread..spread),
        rng.random_range(-spread..spread),
        rng.random_range(-spread..spread),
    );
    let target = Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    // Unnormalised on purpose: t is in units of the direction's length.
    let t_max = if rng.random_bool(0.5) {
        f32::INFINITY
    } else {
        rng.random_range(0.1..2.0)
    };
    Ray::new(
        origin,
        (target - origin) * rng.random_range(0.25..4.0),
        t_max,
    )
}

#[test]
fn watertight_test_agrees_with_f64_moller_trumbore_off_the_edges() {
    let mut rng = SmallRng::seed_from_u64(1);
    let mut hits = 0;
    for _ in 0..200_000 {
        let tri = random_triangle(&mut rng);
        let ray = random_ray(&mut rng, 3.0);
        let ours = PreparedRay::new(&ray)
            .unwrap()
            .intersect(tri[0], tri[1], tri[2]);
        let reference = moller_trumbore_f64(&ray, tri);
        // Away from edges (smallest barycentric > 1e-4) and interval ends the
        // answers must agree exactly; grazing cases may go either way.
        let Some((t, u, v, min_bary)) = reference else {
            assert!(ours.is_none());
            continue;
        };
        let inside = min_bary > 1e-4;
        let outside = min_bary < -1e-4;
        let t_clear = t > 1e-4 * t.abs().max(1.0) && t < f64::from(ray.t_max) * (1.0 - 1e-4);
        let t_out = t < -1e-4 || t > f64::from(ray.t_max) * (1.0 + 1e-4);
        if inside && t_clear {
            let hit = ours.expect("clear hit missed");
            hits += 1;
            assert!((f64::from(hit.t) - t).abs() <= 1e-4 * t.abs().max(1.0));
            assert!((f64::from(hit.u) - u).abs() < 1e-3);
            assert!((f64::from(hit.v) - v).abs() < 1e-3);
        } else if outside || t_out {
            assert!(ours.is_none(), "clear miss hit: {ray:?} {tri:?}");
        }
    }
    assert!(hits > 5_000, "too few hits to mean anything: {hits}");
}

#[test]
fn hit_requires_t_strictly_inside_the_interval() {
    let tri = [
        Vec3::new(-1.0, -1.0, 1.0),
        Vec3::new(1.0, -1.0, 1.0),
        Vec3::new(0.0, 1.0, 1.0),
    ];
    let hit = |t_min: f32, t_max: f32, scale: f32| {
        let ray = Ray {
            origin: Vec3::ZERO,
            direction: Vec3::Z * scale,
            t_min,
            t_max,
        };
        PreparedRay::new(&ray)
            .unwrap()
            .intersect(tri[0], tri[1], tri[2])
            .map(|h| h.t)
    };
    assert_eq!(hit(0.0, f32::INFINITY, 1.0), Some(1.0));
    assert_eq!(hit(0.0, 1.0, 1.0), None, "t == t_max is not a hit");
    assert_eq!(hit(1.0, 2.0, 1.0), None, "t == t_min is not a hit");
    assert_eq!(
        hit(0.0, f32::INFINITY, 2.0),
        Some(0.5),
        "t in direction lengths"
    );
    assert_eq!(hit(0.0, f32::INFINITY, -1.0), None, "behind the origin");
}

#[test]
fn extreme_scales_are_exact_through_the_wide_path() {
    // A unit quad scaled by s, hit head-on from the origin at t = s: f32 edge
    // products overflow above ~5e12 and underflow below ~1e-13.
    for s in [1e-30f32, 1e-19, 1e-15, 1e-6, 1.0, 3e12, 1e13, 1e20, 1e30] {
        let quad = [
            Vec3::new(-s, -s, s),
            Vec3::new(s, -s, s),
            Vec3::new(s, s, s),
            Vec3::new(-s, s, s),
        ];
        let ray = Ray::new(Vec3::ZERO, Vec3::new(0.1, 0.2, 1.0), f32::INFINITY);
        let prepared = PreparedRay::new(&ray).unwrap();
        let hit = prepared
            .intersect(quad[0], quad[1], quad[2])
            .or_else(|| prepared.intersect(quad[0], quad[2], quad[3]))
            .unwrap_or_else(|| panic!("scale {s}: missed"));
        assert!(
            (hit.t - s).abs() <= 4.0 * f32::EPSILON * s,
            "scale {s}: t = {}",
            hit.t
        );
    }
}

#[test]
fn negative_t_min_reaches_behind_the_origin() {
    let tri = [
        Vec3::new(-1.0, -1.0, 1.0),
        Vec3::new(1.0, -1.0, 1.0),
        Vec3::new(0.0, 1.0, 1.0),
    ];
    let ray = Ray {
        origin: Vec3::new(0.1, 0.2, 3.0),
        direction: Vec3::Z,
        t_min: -5.0,
        t_max: 0.0,
    };
    let hit = PreparedRay::new(&ray)
        .unwrap()
        .intersect(tri[0], tri[1], tri[2]);
    assert_eq!(hit.map(|h| h.t), Some(-2.0));
}

#[test]
fn invalid_rays_hit_nothing() {
    for ray in [
        Ray::new(Vec3::ZERO, Vec3::ZERO, 1.0),
        Ray::new(Vec3::NAN, Vec3::Z, 1.0),
        Ray::new(Vec3::ZERO, Vec3::new(0.0, f32::INFINITY, 1.0), 1.0),
        Ray::new(Vec3::ZERO, Vec3::Z, f32::NAN),
    ] {
        assert!(PreparedRay::new(&ray).is_none(), "{ray:?}");
    }
}

/// Checks [`PreparedRay::intersect_lanes`] on `triangles` (1 to 4) against
/// [`PreparedRay::intersect`] lane by lane: a decided lane must give the scalar
/// answer bit for bit. Returns the number of undecided lanes.
fn lanes_agree_with_scalar(ray: &Ray, triangles: &[[Vec3; 3]]) -> u32 {
    let prepared = PreparedRay::new(ray).unwrap();
    let decided = prepared.intersect_lanes(&TriangleLanes::new(triangles));
    let mut undecided = 0;
    for (lane, &[a, b, c]) in triangles.iter().enumerate() {
        let scalar = prepared.intersect(a, b, c);
        let bit = 1 << lane;
        assert!(
            decided.hits & decided.undecided & bit == 0,
            "lane {lane} both hit and undecided"
        );
        if decided.undecided & bit != 0 {
            undecided += 1;
            continue;
        }
        let lanes = (decided.hits & bit != 0)
            .then(|| [decided.t[lane], decided.u[lane], decided.v[lane]].map(f32::to_bits));
        let scalar_bits = scalar.map(|h| [h.t, h.u, h.v].map(f32::to_bits));
        assert_eq!(
            lanes, scalar_bits,
            "lane {lane}: {ray:?} {triangles:?}: lanes {decided:?}, scalar {scalar:?}"
        );
    }
    undecided
}

/// `count` random triangles and a random ray: the ordinary lane-test case.
fn ordinary_lane_case(rng: &mut SmallRng, count: usize) -> (Ray, Vec<[Vec3; 3]>) {
    let triangles = (0..count).map(|_| random_triangle(rng)).collect();
    (random_ray(rng, 3.0), triangles)
}

/// Rays through shared vertices and edges of a fan (edge functions exactly
/// zero), triangles at the extreme scales of the wide path, degenerate ones
/// (collinear corners, every corner on the ray's line), and interval ends at the
/// hit itself: the cases where the lanes must defer or agree.
fn special_lane_cases(rng: &mut SmallRng) -> Vec<(Ray, Vec<[Vec3; 3]>)> {
    let mut cases = Vec::new();
    let fan = |scale: f32| {
        let centre = Vec3::new(0.0, 0.0, scale);
        let rim = |k: u32| {
            let angle = k as f32 * core::f32::consts::TAU / 4.0;
            centre + scale * Vec3::new(libm::cosf(angle), libm::sinf(angle), 0.0)
        };
        (0..4)
            .map(|k| [centre, rim(k), rim(k + 1)])
            .collect::<Vec<_>>()
    };
    for scale in [1e-30f32, 1e-20, 1e-15, 1e-7, 1.0, 1e6, 3e12, 1e20, 1e30] {
        let triangles = fan(scale);
        let targets = [
            triangles[0][0],
            triangles[0][1],
            triangles[1][1],
            (triangles[0][0] + triangles[0][1]) * 0.5,
            (triangles[1][1] + triangles[1][2]) * 0.5,
            Vec3::new(0.3 * scale, 0.2 * scale, scale),
        ];
        for target in targets {
            for origin in [Vec3::ZERO, Vec3::new(0.1, -0.2, -0.5) * scale] {
                // Long directions (on the small scenes, where they stay finite)
                // put the hit at a tiny t, so that `t · det` underflows even
                // where `det` does not.
                let lengths: &[f32] = if scale <= 1.0 { &[1.0, 1e12] } else { &[1.0] };
                for &length in lengths {
                    let hit_t = 1.0 / length;
                    for t_max in [f32::INFINITY, hit_t, 2.0 * hit_t, 0.5 * hit_t] {
                        let ray = Ray::new(origin, (target - origin) * length, t_max);
                        cases.push((ray, triangles.clone()));
                    }
                }
            }
        }
    }
    let collinear = alloc::vec![
        [Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
        [Vec3::Z, Vec3::Z * 2.0, Vec3::Z * 3.0],
        [Vec3::ONE, Vec3::ONE, Vec3::ONE],
        [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ],
    ];
    for _ in 0..2_000 {
        let ray = if rng.random_bool(0.5) {
            Ray::new(Vec3::ZERO, Vec3::Z, f32::INFINITY)
        } else {
            random_ray(rng, 2.0)
        };
        cases.push((ray, collinear.clone()));
    }
    cases
}

#[test]
fn four_lane_test_equals_the_scalar_test_lane_by_lane() {
    let mut rng = SmallRng::seed_from_u64(12);
    // Ordinary triangles and rays: almost every lane is decided in the lanes.
    let (mut lanes, mut undecided, mut hits) = (0, 0, 0);
    for _ in 0..50_000 {
        let count = rng.random_range(1..=4);
        let (ray, triangles) = ordinary_lane_case(&mut rng, count);
        undecided += lanes_agree_with_scalar(&ray, &triangles);
        let prepared = PreparedRay::new(&ray).unwrap();
        hits += triangles
            .iter()
            .filter(|[a, b, c]| prepared.intersect(*a, *b, *c).is_some())
            .count();
        lanes += count;
    }
    assert!(hits > 5_000, "too few hits to mean anything: {hits}");
    assert!(
        undecided * 1000 < lanes as u32,
        "{undecided} of {lanes} ordinary lanes undecided"
    );
    let special_undecided: u32 = special_lane_cases(&mut rng)
        .iter()
        .map(|(ray, triangles)| lanes_agree_with_scalar(ray, triangles))
        .sum();
    assert!(
        special_undecided > 100,
        "the special cases never left the lanes ({special_undecided}): they test nothing"
    );
}

/// The eight-lane AVX triangle test on two blocks gives, lane by lane and bit
/// for bit, what the four-lane test gives on each block (which is checked
/// against the scalar test above): the twin of the leaf test wide searches take.
#[cfg(all(feature = "bvh", target_arch = "x86_64"))]
#[test]
fn eight_lane_test_equals_the_four_lane_test_on_each_block() {
    if !crate::simd::avx_available() {
        std::println!("this processor has no AVX: the eight-lane test is never used here");
        return;
    }
    let check = |ray: &Ray, low: &[[Vec3; 3]], high: &[[Vec3; 3]]| {
        let prepared = PreparedRay::new(ray).unwrap();
        let (low, high) = (TriangleLanes::new(low), TriangleLanes::new(high));
        // SAFETY: AVX was detected above.
        #[allow(unsafe_code)]
        let eight = unsafe {
            crate::simd::avx::intersect8(
                &prepared.sheared(),
                prepared.t_max(),
                &low.corners,
                &high.corners,
                WIDE_EXTENT,
                WIDE_DETERMINANT,
            )
        };
        for (half, lanes) in [low, high].iter().enumerate() {
            let four = prepared.intersect_lanes(lanes);
            let bits = |mask: u32| (mask >> (4 * half)) & 0xf;
            assert_eq!(bits(eight.hits), four.hits, "{ray:?} half {half}");
            assert_eq!(bits(eight.undecided), four.undecided, "{ray:?} half {half}");
            for lane in 0..4 {
                if four.hits & (1 << lane) != 0 {
                    let of_four = [four.t[lane], four.u[lane], four.v[lane]];
                    let i = 4 * half + lane;
                    let of_eight = [eight.t[i], eight.u[i], eight.v[i]];
                    assert_eq!(
                        of_eight.map(f32::to_bits),
                        of_four.map(f32::to_bits),
                        "{ray:?} lane {i}"
                    );
                }
            }
        }
        (eight.hits.count_ones(), eight.undecided.count_ones())
    };
    let mut rng = SmallRng::seed_from_u64(13);
    let mut hits = 0;
    for _ in 0..30_000 {
        let counts = [rng.random_range(1..=4), rng.random_range(1..=4)];
        let (ray, low) = ordinary_lane_case(&mut rng, counts[0]);
        let (_, high) = ordinary_lane_case(&mut rng, counts[1]);
        hits += check(&ray, &low, &high).0;
    }
    assert!(hits > 3_000, "too few hits to mean anything: {hits}");
    // Every special case in either half, beside ordinary triangles.
    let mut undecided = 0;
    for (ray, special) in special_lane_cases(&mut rng) {
        let (_, ordinary) = ordinary_lane_case(&mut rng, 4);
        undecided += check(&ray, &special, &ordinary).1;
        undecided += check(&ray, &ordinary, &special).1;
    }
    assert!(
        undecided > 200,
        "the special cases never left the lanes ({undecided})"
    );
}

/// A closed octahedron-subdivided sphere: rays from inside must always hit.
fn closed_sphere(subdivisions: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut indices = Vec::new();
    // Each octant face of an octahedron as an n×n triangulated grid, vertices
    // shared along octant boundaries through exact, order-independent keys.
    let n = subdivisions;
    let mut lookup = alloc::collections::BTreeMap::new();
    let mut vertex = |p: [i32; 3]| -> u32 {
        *lookup.entry(p).or_insert_with(|| {
            let v = Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32).normalize();
            positions.push(v.to_array());
            (positions.len() - 1) as u32
        })
    };
    for sx in [-1i32, 1] {
        for sy in [-1i32, 1] {
            for sz in [-1i32, 1] {
                let grid = |i: u32, j: u32| {
                    let (i, j) = (i as i32, j as i32);
                    [sx * i, sy * j, sz * (n as i32 - i - j)]
                };
                for i in 0..n {
                    for j in 0..n - i {
                        let a = vertex(grid(i, j));
                        let b = vertex(grid(i + 1, j));
                        let c = vertex(grid(i, j + 1));
                        indices.extend_from_slice(&[a, b, c]);
                        if i + j + 1 < n {
                            let d = vertex(grid(i + 1, j + 1));
                            indices.extend_from_slice(&[b, d, c]);
                        }
                    }
                }
            }
        }
    }
    (positions, indices)
}

#[test]
fn closed_mesh_has_no_pinholes_even_through_vertices_and_edges() {
    let (positions, indices) = closed_sphere(6);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let caster = BruteForceCaster::new(mesh);
    let mut rng = SmallRng::seed_from_u64(2);
    // Aim straight at vertices and edge midpoints, the classic pinhole spots.
    let mut targets: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t);
        targets.extend([(a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5]);
    }
    for target in targets {
        for origin in [Vec3::ZERO, Vec3::new(0.1, -0.2, 0.05)] {
            let origin = origin + Vec3::splat(rng.random_range(-1e-3..1e-3));
            let ray = Ray::new(origin, target - origin, f32::INFINITY);
            assert!(caster.occluded(&ray), "pinhole at {target:?}");
        }
    }
}

#[cfg(feature = "bvh")]
mod bvh_against_brute_force {
    use super::*;
    use proptest::prelude::*;

    fn soup(rng: &mut SmallRng, triangles: usize) -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut positions = Vec::new();
        for _ in 0..triangles {
            let center = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            for _ in 0..3 {
                let offset = Vec3::new(
                    rng.random_range(-0.2..0.2),
                    rng.random_range(-0.2..0.2),
                    rng.random_range(-0.2..0.2),
                );
                positions.push((center + offset).to_array());
            }
        }
        let indices = (0..positions.len() as u32).collect();
        (positions, indices)
    }

    /// Compares every ray, through the scene of each build quality (obvhs's
    /// conversion and the greedy collapse); returns the fewer hits of the
    /// two so callers can check coverage.
    fn compare(positions: &[[f32; 3]], indices: &[u32], rays: usize, rng: &mut SmallRng) -> usize {
        let mesh = MeshView::new(positions, indices).unwrap();
        [BuildQuality::Medium, BuildQuality::Fast]
            .into_iter()
            .map(|quality| {
                let bvh = BvhScene::with_quality(&mesh, quality).unwrap();
                // The collapse's boxes are quantised by the refit's rule:
                // every triangle under the root exactly once, inside every
                // box above it, exactly (obvhs's own rounding is covered by
                // the search's padding instead).
                if quality == BuildQuality::Fast {
                    let mut below = bvh.assert_boxes_hold(&mesh, 0);
                    below.sort_unstable();
                    assert!(below.iter().copied().eq(0..mesh.triangle_count() as u32));
                }
                compare_scene(&mesh, &bvh, rays, rng)
            })
            .min()
            .expect("two qualities")
    }

    /// [`compare`] for a scene already made over `mesh` (built or refitted).
    fn compare_scene(
        mesh: &MeshView<'_>,
        bvh: &BvhScene,
        rays: usize,
        rng: &mut SmallRng,
    ) -> usize {
        let mesh = *mesh;
        let brute = BruteForceCaster::new(mesh);
        assert_eq!(bvh.triangle_count(), mesh.triangle_count());
        // The portable four-lane box test (the only one off x86-64 or without
        // AVX) against the same reference.
        let narrow = bvh.clone().with_avx(false);
        assert_eq!(bvh.uses_avx(), crate::simd::avx_available());
        assert!(!narrow.uses_avx());
        // Queries take our own traversal loop; check obvhs's `traverse!` path too
        // (whose 32-entry stack holds these trees).
        assert!(bvh.depth() <= 32);
        // The packet search on the same kind of rays, and on fans from one point.
        let mixed: Vec<Ray> = (0..rays.min(70)).map(|_| random_ray(rng, 2.0)).collect();
        many_equal_each(&mesh, &[bvh, &narrow], &mixed);
        let fan_origin = mesh.triangle(0)[0] + Vec3::splat(1e-3);
        let fan_rays = fan(rng, fan_origin, Vec3::Z, rays.min(70));
        many_equal_each(&mesh, &[bvh, &narrow], &fan_rays);
        let mut hits = 0;
        for _ in 0..rays {
            let ray = random_ray(rng, 2.0);
            let expected = brute.closest_hit(&ray);
            let got = bvh.closest_hit(&ray);
            assert_eq!(bvh.occluded(&ray), expected.is_some(), "{ray:?}");
            assert_eq!(narrow.occluded(&ray), expected.is_some(), "{ray:?}");
            // The triangle an occlusion names is one the ray hits on its own.
            let prepared = PreparedRay::new(&ray);
            for scene in [bvh, &narrow] {
                if let Some(t) = scene.occluding_triangle(&ray) {
                    let [a, b, c] = mesh.triangle(t as usize);
                    let hit = prepared.as_ref().and_then(|r| r.intersect(a, b, c));
                    assert!(hit.is_some(), "triangle {t} named for {ray:?}");
                }
            }
            assert_eq!(narrow.closest_hit(&ray), got, "{ray:?}");
            assert_eq!(
                bvh.occluded_through_traverse_macro(&ray),
                expected.is_some(),
                "{ray:?}"
            );
            assert_eq!(
                bvh.closest_hit_through_traverse_macro(&ray).map(|h| h.t),
                expected.map(|h| h.t),
                "{ray:?}"
            );
            match (expected, got) {
                (None, None) => {}
                (Some(e), Some(g)) => {
                    hits += 1;
                    // Same watertight test on the same data: the same t exactly.
                    // The triangle may differ only on an exact tie in t.
                    assert_eq!(e.t, g.t, "{ray:?}");
                    if e.triangle != g.triangle {
                        let [a, b, c] = mesh.triangle(g.triangle as usize);
                        let again = PreparedRay::new(&ray).unwrap().intersect(a, b, c);
                        assert_eq!(again.map(|h| h.t), Some(e.t));
                    } else {
                        assert_eq!((e.u, e.v), (g.u, g.v));
                    }
                }
                _ => panic!("{ray:?}: brute {expected:?} bvh {got:?}"),
            }
        }
        hits
    }

    /// `steps` books of `pages` triangles shrinking geometrically towards the
    /// origin by `ratio` per step: book `k` covers `x ∈ [ratio^(k+1), ratio^k]`,
    /// `y ∈ [0, w]` (`w` its width) with right triangles parallel to the xy plane
    /// at heights `z ∈ [0, 0.3 w)`, alternately facing the two halves of the
    /// square. A book's triangles merge first (their boxes nearly coincide), then
    /// the smallest remaining cluster with the next smaller book, so PLOC builds a
    /// chain as deep as there are books, and every book is an inner node (more
    /// triangles than eight leaves of three hold) beside the rest of the chain.
    fn shrinking_books(steps: usize, ratio: f32, pages: usize) -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut positions = Vec::new();
        let mut x = 1.0f32;
        for _ in 0..steps {
            let next = x * ratio;
            let w = x - next;
            for j in 0..pages {
                let z = 0.3 * w * j as f32 / pages as f32;
                if j % 2 == 0 {
                    positions.extend([[next, 0.0, z], [x, 0.0, z], [x, w, z]]);
                } else {
                    positions.extend([[next, 0.0, z], [x, w, z], [next, w, z]]);
                }
            }
            x = next;
        }
        let indices = (0..positions.len() as u32).collect();
        (positions, indices)
    }

    /// A hierarchy far deeper than obvhs's 32-entry traversal stack (which
    /// overwrites on overflow): our traversal sizes its stack by the depth and
    /// must agree with brute force everywhere, down to the smallest steps.
    #[test]
    fn deep_hierarchies_match_brute_force() {
        let (positions, indices) = shrinking_books(70, 0.3, 30);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let brute = BruteForceCaster::new(mesh);
        let bvh = BvhScene::new(&mesh).unwrap();
        assert!(bvh.depth() > 64, "not deep enough: {}", bvh.depth());
        let fast = BvhScene::with_quality(&mesh, BuildQuality::Fast).unwrap();
        assert!(fast.depth() > 32, "not deep enough: {}", fast.depth());
        let mut rng = SmallRng::seed_from_u64(21);
        let mut hits = 0;
        for k in 0..4000 {
            let ray = if k % 2 == 0 {
                // A point near a random triangle, at its scale, aimed at it.
                let [a, b, c] = mesh.triangle(rng.random_range(0..mesh.triangle_count()));
                let (u, v) = (rng.random_range(0.0..1.0f32), rng.random_range(0.0..1.0f32));
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let target = a + u * (b - a) + v * (c - a);
                let offset = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ) * (b - a).length()
                    * rng.random_range(0.5..4.0);
                Ray::new(target + offset, -offset, f32::INFINITY)
            } else {
                // From the small end along the chain, inside every book's box:
                // at every level the rest of the chain is nearer and the book
                // waits on the stack.
                let direction = Vec3::new(
                    1.0,
                    rng.random_range(0.02..0.3),
                    rng.random_range(0.02..0.2),
                );
                Ray::new(direction * -1e-30, direction, f32::INFINITY)
            };
            let expected = brute.closest_hit(&ray);
            for scene in [&bvh, &fast] {
                assert_eq!(scene.occluded(&ray), expected.is_some(), "{ray:?}");
                let got = scene.closest_hit(&ray);
                assert_eq!(got.map(|h| h.t), expected.map(|h| h.t), "{ray:?}");
            }
            hits += usize::from(expected.is_some());
        }
        assert!(hits > 1000, "too few hits to mean anything: {hits}");
    }

    #[test]
    fn random_soups_match_brute_force() {
        let mut rng = SmallRng::seed_from_u64(3);
        let mut hits = 0;
        for triangles in [1, 2, 7, 100, 3000] {
            let (positions, indices) = soup(&mut rng, triangles);
            hits += compare(&positions, &indices, 4000, &mut rng);
        }
        assert!(hits > 2000, "too few hits to mean anything: {hits}");
    }

    /// A small closed mesh through every path (the AVX and portable box
    /// tests, both traversal loops) against brute force: small enough for
    /// `make miri`, which runs it to check the unsafe AVX and prefetch code.
    #[test]
    fn miri_small_mesh_takes_every_path() {
        let mut rng = SmallRng::seed_from_u64(7);
        let (positions, indices) = closed_sphere(2);
        let hits = compare(&positions, &indices, 48, &mut rng);
        assert!(hits > 4, "too few hits to mean anything: {hits}");
    }

    #[test]
    fn closed_sphere_matches_brute_force() {
        let mut rng = SmallRng::seed_from_u64(4);
        let (positions, indices) = closed_sphere(12);
        let hits = compare(&positions, &indices, 20_000, &mut rng);
        assert!(hits > 5000, "too few hits to mean anything: {hits}");
    }

    /// Rays aimed exactly at the vertices and edge midpoints of a closed mesh
    /// (edge functions exactly zero, so the leaf lanes hand those triangles to
    /// the scalar test next to lanes they decide) are never lost through the
    /// hierarchy either, on both paths, and find brute force's closest hit.
    #[test]
    fn closed_mesh_has_no_pinholes_through_the_bvh() {
        let (positions, indices) = closed_sphere(6);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let brute = BruteForceCaster::new(mesh);
        let scenes = [
            BvhScene::new(&mesh).unwrap(),
            BvhScene::new(&mesh).unwrap().with_avx(false),
        ];
        let mut targets: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.triangle(t);
            targets.extend([(a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5]);
        }
        super::bvh::SCALAR_LANES.with(|lanes| lanes.set(0));
        for target in &targets {
            for origin in [Vec3::ZERO, Vec3::new(0.1, -0.2, 0.05)] {
                let ray = Ray::new(origin, *target - origin, f32::INFINITY);
                let expected = brute.closest_hit(&ray).expect("brute force: pinhole");
                for scene in &scenes {
                    assert!(scene.occluded(&ray), "pinhole at {target:?}");
                    let got = scene.closest_hit(&ray).expect("pinhole");
                    assert_eq!(got.t, expected.t, "{ray:?}");
                    if got.triangle == expected.triangle {
                        assert_eq!((got.u, got.v), (expected.u, expected.v), "{ray:?}");
                    }
                }
            }
        }
        let scalar = super::bvh::SCALAR_LANES.with(|lanes| lanes.get());
        assert!(
            scalar > targets.len(),
            "only {scalar} lanes went to the scalar test: the rays missed the exact edges"
        );
    }

    #[test]
    fn empty_scene_hits_nothing() {
        let mesh = MeshView::new(&[], &[]).unwrap();
        let bvh = BvhScene::new(&mesh).unwrap();
        let ray = Ray::new(Vec3::ZERO, Vec3::Z, f32::INFINITY);
        assert!(!bvh.occluded(&ray));
        assert!(bvh.closest_hit(&ray).is_none());
    }

    #[test]
    fn bvh_scene_is_send_and_sync() {
        fn assert_send_sync<T: Send + Sync>() {}
        assert_send_sync::<BvhScene>();
    }

    /// Rays whose parameters stress the traversal rather than the triangle test:
    /// direction lengths from 1e-6 to 1e6, and axis-aligned directions with +0.0
    /// and -0.0 components.
    fn extreme_ray(rng: &mut SmallRng) -> Ray {
        let mut ray = random_ray(rng, 2.0);
        let scale = 10f32.powf(rng.random_range(-6.0..6.0));
        ray.direction *= scale;
        ray.t_max /= scale;
        if rng.random_bool(0.25) {
            let axis = rng.random_range(0..3);
            let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let mut d = [if rng.random_bool(0.5) { 0.0 } else { -0.0 }; 3];
            d[axis] = sign * scale;
            ray.direction = Vec3::from_array(d);
        }
        ray
    }

    #[test]
    fn extreme_direction_lengths_and_signed_zeros_match_brute_force() {
        let mut rng = SmallRng::seed_from_u64(6);
        let (positions, indices) = soup(&mut rng, 2000);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let brute = BruteForceCaster::new(mesh);
        let bvh = BvhScene::new(&mesh).unwrap();
        let mut hits = 0;
        for _ in 0..20_000 {
            let ray = extreme_ray(&mut rng);
            let expected = brute.closest_hit(&ray);
            assert_eq!(
                bvh.closest_hit(&ray).map(|h| h.t),
                expected.map(|h| h.t),
                "{ray:?}"
            );
            assert_eq!(bvh.occluded(&ray), expected.is_some(), "{ray:?}");
            hits += usize::from(expected.is_some());
        }
        assert!(hits > 2000, "too few hits to mean anything: {hits}");
    }

    #[test]
    fn rays_at_the_fast_box_test_limits_match_brute_force() {
        // Direction components from 2^-45 to 2^45 in magnitude, on both sides of
        // the range where the BVH switches from its fast box test (in the query's
        // own units) to the general one (unit direction, parallel axes).
        let mut rng = SmallRng::seed_from_u64(12);
        let (positions, indices) = closed_sphere(8);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let brute = BruteForceCaster::new(mesh);
        let bvh = BvhScene::new(&mesh).unwrap();
        let mut hits = 0;
        for _ in 0..8000 {
            let mut ray = random_ray(&mut rng, 2.0);
            let scale = 2f32.powf(rng.random_range(-45.0..45.0));
            ray.direction *= scale;
            ray.t_max /= scale;
            if rng.random_bool(0.5) {
                let axis = rng.random_range(0..3);
                ray.direction[axis] *= 2f32.powf(-rng.random_range(0.0..50.0));
            }
            let expected = brute.closest_hit(&ray);
            assert_eq!(
                bvh.closest_hit(&ray).map(|h| h.t),
                expected.map(|h| h.t),
                "{ray:?}"
            );
            assert_eq!(bvh.occluded(&ray), expected.is_some(), "{ray:?}");
            hits += usize::from(expected.is_some());
        }
        assert!(hits > 2000, "too few hits to mean anything: {hits}");
    }

    #[test]
    fn tiny_and_far_scenes_match_brute_force() {
        // Scenes far below and above unit scale, and far from the origin: obvhs's
        // fixed 1e-4 box epsilon would cull whole scenes at 1e-5 scale.
        for (scale, offset) in [(1e-5f32, 0.0f32), (1e-3, 0.0), (1e4, 0.0), (1.0, 1e4)] {
            let mut rng = SmallRng::seed_from_u64(7);
            let (mut positions, indices) = soup(&mut rng, 500);
            for p in &mut positions {
                *p = (Vec3::from(*p) * scale + offset).to_array();
            }
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let brute = BruteForceCaster::new(mesh);
            let bvh = BvhScene::new(&mesh).unwrap();
            let mut hits = 0;
            for _ in 0..4000 {
                let mut ray = random_ray(&mut rng, 2.0);
                ray.origin = ray.origin * scale + offset;
                let expected = brute.closest_hit(&ray);
                assert_eq!(
                    bvh.closest_hit(&ray).map(|h| h.t),
                    expected.map(|h| h.t),
                    "scale {scale}: {ray:?}"
                );
                assert_eq!(
                    bvh.occluded(&ray),
                    expected.is_some(),
                    "scale {scale}: {ray:?}"
                );
                hits += usize::from(expected.is_some());
            }
            assert!(hits > 400, "scale {scale}: too few hits: {hits}");
        }
    }

    #[test]
    fn axis_parallel_rays_find_thin_far_geometry() {
        // A sliver 2e-20 wide at z = 1e11 on the z axis: the ray's x and y
        // components are exactly zero, so the box test must treat those slabs as
        // parallel rather than use a finite stand-in for 1/0.
        let positions = [[-1e-20, -1.0, 1e11], [1e-20, -1.0, 1e11], [0.0, 1.0, 1e11]];
        let indices = [0, 1, 2];
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let bvh = BvhScene::new(&mesh).unwrap();
        let ray = Ray::new(Vec3::ZERO, Vec3::Z, f32::INFINITY);
        let expected = BruteForceCaster::new(mesh).closest_hit(&ray);
        assert_eq!(expected.map(|h| h.t), Some(1e11));
        assert_eq!(bvh.closest_hit(&ray).map(|h| h.t), Some(1e11));
        assert!(bvh.occluded(&ray));
    }

    #[test]
    fn intervals_wholly_behind_the_origin_match_brute_force() {
        // t_min < t_max < 0: the culling bound t_max is negative and must still be
        // rounded towards +infinity. A third of the rays are axis-parallel, for the
        // general box test.
        let mut rng = SmallRng::seed_from_u64(13);
        let (positions, indices) = soup(&mut rng, 300);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let brute = BruteForceCaster::new(mesh);
        let bvh = BvhScene::new(&mesh).unwrap();
        let mut hits = 0;
        for _ in 0..6000 {
            let mut ray = random_ray(&mut rng, 2.0);
            // Turned round, so the soup lies behind the origin.
            ray.direction = -ray.direction;
            if rng.random_bool(0.33) {
                let mut d = [0.0; 3];
                d[rng.random_range(0..3)] = rng.random_range(-2.0..2.0);
                ray.direction = Vec3::from_array(d);
            }
            ray.t_min = -rng.random_range(1.0..4.0);
            ray.t_max = -rng.random_range(0.0..0.5);
            let expected = brute.closest_hit(&ray);
            assert_eq!(
                bvh.closest_hit(&ray).map(|h| h.t),
                expected.map(|h| h.t),
                "{ray:?}"
            );
            assert_eq!(bvh.occluded(&ray), expected.is_some(), "{ray:?}");
            hits += usize::from(expected.is_some());
        }
        assert!(hits > 300, "too few hits behind the origin: {hits}");
    }

    #[test]
    fn negative_t_min_finds_hits_behind_the_origin() {
        let mut rng = SmallRng::seed_from_u64(8);
        let (positions, indices) = soup(&mut rng, 300);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let brute = BruteForceCaster::new(mesh);
        let bvh = BvhScene::new(&mesh).unwrap();
        let mut behind = 0;
        for _ in 0..6000 {
            let mut ray = random_ray(&mut rng, 2.0);
            ray.t_min = -rng.random_range(0.0..3.0);
            let expected = brute.closest_hit(&ray);
            assert_eq!(
                bvh.closest_hit(&ray).map(|h| h.t),
                expected.map(|h| h.t),
                "{ray:?}"
            );
            assert_eq!(bvh.occluded(&ray), expected.is_some());
            behind += usize::from(expected.is_some_and(|h| h.t < 0.0));
        }
        assert!(behind > 100, "too few hits behind the origin: {behind}");
    }

    #[test]
    fn coordinates_beyond_the_limit_are_an_error_not_a_panic() {
        for scale in [1e12f32, 1e13, 1e20, 3e38] {
            let positions = [
                [-scale, -scale, 1.0],
                [scale, -scale, 1.0],
                [0.0, scale, 1.0],
            ];
            let indices = [0, 1, 2];
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let built = BvhScene::new(&mesh);
            if scale <= MAX_COORDINATE {
                let bvh = built.unwrap();
                let ray = Ray::new(Vec3::ZERO, Vec3::Z, f32::INFINITY);
                assert_eq!(bvh.closest_hit(&ray).map(|h| h.t), Some(1.0));
            } else {
                assert_eq!(
                    built.unwrap_err(),
                    BvhError::CoordinateOutOfRange { vertex: 0 }
                );
            }
        }
    }

    /// Up to `count` rays from `origin` over the hemisphere around `normal`,
    /// covering `(0, ∞)` like a bake's: the shared-origin packets.
    fn fan(rng: &mut SmallRng, origin: Vec3, normal: Vec3, count: usize) -> Vec<Ray> {
        (0..count)
            .map(|_| {
                let mut d = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                if d.dot(normal) < 0.0 {
                    d = -d;
                }
                Ray::new(origin, d * rng.random_range(0.5..2.0), f32::INFINITY)
            })
            .collect()
    }

    /// `occluded_many` against `occluded` and `closest_hit_many` against
    /// `closest_hit`, ray by ray, on the AVX and the portable scene: the same
    /// bit, and the same `t` with the same triangle, or another hit at exactly
    /// that `t` (a tie). Returns the rays occluded.
    fn many_equal_each(mesh: &MeshView<'_>, scenes: &[&BvhScene], rays: &[Ray]) -> usize {
        let mut occluded = alloc::vec![false; rays.len()];
        let mut hits = alloc::vec![None; rays.len()];
        for scene in scenes {
            occluded.fill(false);
            scene.occluded_many(rays, &mut occluded);
            scene.closest_hit_many(rays, &mut hits);
            for ((ray, &got), hit) in rays.iter().zip(&occluded).zip(&hits) {
                assert_eq!(got, scene.occluded(ray), "{ray:?}");
                let alone = scene.closest_hit(ray);
                assert_eq!(hit.map(|h| h.t), alone.map(|h| h.t), "{ray:?}");
                if let (Some(hit), Some(alone)) = (hit, alone)
                    && hit.triangle != alone.triangle
                {
                    let [a, b, c] = mesh.triangle(hit.triangle as usize);
                    let again = PreparedRay::new(ray).unwrap().intersect(a, b, c);
                    assert_eq!(again.map(|h| (h.t, h.u, h.v)), Some((hit.t, hit.u, hit.v)));
                } else {
                    assert_eq!(*hit, alone, "{ray:?}");
                }
            }
        }
        occluded.iter().filter(|&&o| o).count()
    }

    /// The packet searches (`occluded_many`, `closest_hit_many`) against their
    /// slow twins: every ray answered as `occluded` and `closest_hit` answer it
    /// alone, for bake-like fans from points
    /// on and near the surface (the shared-origin leaf test), fans aimed exactly
    /// at corners and edge midpoints (where that test must leave the ray to the
    /// watertight one) and from a corner itself and from points in a
    /// triangle's plane, and mixed packets (other origins, finite ends,
    /// negative starts, invalid and axis-parallel rays) that take the
    /// per-ray leaf test; partial packets of 1 to 200 rays.
    #[test]
    fn packets_answer_as_one_ray_at_a_time() {
        let mut rng = SmallRng::seed_from_u64(41);
        let (sphere_positions, sphere_indices) = closed_sphere(6);
        let (soup_positions, soup_indices) = soup(&mut rng, 400);
        let (mut occluded, mut rays_cast, mut aimed) = (0, 0, 0);
        for (positions, indices) in [
            (&sphere_positions, &sphere_indices),
            (&soup_positions, &soup_indices),
        ] {
            let mesh = MeshView::new(positions, indices).unwrap();
            let bvh = BvhScene::new(&mesh).unwrap();
            let narrow = bvh.clone().with_avx(false);
            let scenes = [&bvh, &narrow];
            for k in 0..120 {
                let [a, b, c] = mesh.triangle(rng.random_range(0..mesh.triangle_count()));
                let normal = (b - a).cross(c - a).normalize_or(Vec3::Z);
                let count = [1, 7, 64, 65, 200][k % 5];
                let origin = match k % 4 {
                    // A corner itself, and a point on the triangle: the
                    // origin in the plane of the triangles around it.
                    0 => a,
                    1 => (a + b + c) / 3.0,
                    // Just off the surface, as a bake starts its rays.
                    2 => (a + b + c) / 3.0 + normal * 1e-4,
                    _ => (a + b + c) / 3.0 + normal * rng.random_range(0.01..0.5),
                };
                let mut rays = fan(&mut rng, origin, normal, count);
                if k % 3 == 0 {
                    // Exactly at corners and edge midpoints of other triangles.
                    for ray in rays.iter_mut().step_by(2) {
                        let [p, q, r] = mesh.triangle(rng.random_range(0..mesh.triangle_count()));
                        let target =
                            [p, q, r, (p + q) / 2.0, (q + r) / 2.0][rng.random_range(0..5)];
                        if target != origin {
                            ray.direction = target - origin;
                            aimed += 1;
                        }
                    }
                }
                occluded += many_equal_each(&mesh, &scenes, &rays);
                rays_cast += rays.len();
                // The same rays mixed: no longer one origin and one interval.
                for ray in rays.iter_mut() {
                    match rng.random_range(0..8) {
                        0 => ray.origin += Vec3::splat(1e-3),
                        1 => ray.t_max = rng.random_range(0.0..1.0),
                        2 => ray.t_min = -rng.random_range(0.0..0.5),
                        3 => ray.direction = Vec3::new(0.0, 0.0, -1.0),
                        4 => ray.direction = Vec3::new(f32::NAN, 1.0, 0.0),
                        5 => ray.direction = Vec3::ZERO,
                        _ => {}
                    }
                }
                occluded += many_equal_each(&mesh, &scenes, &rays);
                rays_cast += rays.len();
            }
        }
        assert!(
            occluded > rays_cast / 10 && occluded < rays_cast * 9 / 10 && aimed > 1000,
            "{occluded} of {rays_cast} rays occluded, {aimed} aimed at corners and edges"
        );
        // Scenes so small or so large that the shared-origin test must leave
        // corners nearer than 2^-40 or farther than 2^40 to the watertight one.
        for scale in [1e-13f32, 1e-6, 4e11] {
            let positions: Vec<[f32; 3]> = soup_positions
                .iter()
                .map(|p| (Vec3::from(*p) * scale).to_array())
                .collect();
            let mesh = MeshView::new(&positions, &soup_indices).unwrap();
            let bvh = BvhScene::new(&mesh).unwrap();
            let mut scale_occluded = 0;
            for k in 0..20 {
                let [a, b, c] = mesh.triangle(k);
                let normal = (b - a).cross(c - a).normalize_or(Vec3::Z);
                let origin = (a + b + c) / 3.0 + normal * (1e-3 * scale);
                let rays = fan(&mut rng, origin, normal, 64);
                scale_occluded += many_equal_each(&mesh, &[&bvh], &rays);
            }
            assert!(scale_occluded > 0, "scale {scale}: nothing occluded");
        }
        // Hierarchies deeper than the packet's stack take rays one at a time.
        let (positions, indices) = shrinking_books(70, 0.3, 30);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let deep = BvhScene::new(&mesh).unwrap();
        assert!(deep.depth() > 64);
        let rays = fan(&mut rng, Vec3::new(0.0, 0.0, -1e-3), Vec3::X, 200);
        many_equal_each(&mesh, &[&deep], &rays);
        // And an empty scene hits nothing.
        let nothing = MeshView::new(&[], &[]).unwrap();
        let empty = BvhScene::new(&nothing).unwrap();
        assert_eq!(many_equal_each(&nothing, &[&empty], &rays), 0);
    }

    /// A refitted scene against brute force on the moved mesh, through every
    /// query path (single rays AVX and portable, obvhs's traversal of the
    /// re-quantised nodes, packets): motions that keep the hierarchy's shape
    /// good (rigid, a twist, a shrink by 1e-6) and one that ruins it (every
    /// vertex sent to another's place), refitted one after another; and
    /// refits that must fail leave the scene answering as before.
    #[test]
    fn refitted_scenes_answer_as_built_ones() {
        let mut rng = SmallRng::seed_from_u64(23);
        let (sphere_positions, sphere_indices) = closed_sphere(5);
        let (soup_positions, soup_indices) = soup(&mut rng, 300);
        let mut hits = 0;
        for (positions, indices) in [
            (&sphere_positions, &sphere_indices),
            (&soup_positions, &soup_indices),
        ] {
            let mesh = MeshView::new(positions, indices).unwrap();
            for quality in [BuildQuality::Medium, BuildQuality::Fast] {
                let mut scene = BvhScene::with_quality(&mesh, quality).unwrap();
                let count = positions.len();
                for motion in 0..4 {
                    let moved: Vec<[f32; 3]> = (0..count)
                        .map(|v| {
                            let p = Vec3::from(positions[v]);
                            match motion {
                                0 => {
                                    glam::Quat::from_rotation_y(0.7) * p + Vec3::new(0.3, -0.2, 0.1)
                                }
                                1 => glam::Quat::from_rotation_y(1.5 * p.y) * p,
                                2 => p * 1e-6,
                                _ => Vec3::from(positions[(v * 7919 + 13) % count]),
                            }
                            .to_array()
                        })
                        .collect();
                    let moved_mesh = MeshView::new(&moved, indices).unwrap();
                    scene.refit(&moved_mesh).unwrap();
                    let below = scene.assert_boxes_hold(&moved_mesh, 0);
                    assert_eq!(below.len(), moved_mesh.triangle_count());
                    hits += compare_scene(&moved_mesh, &scene, 300, &mut rng);
                }
                // Another triangle count, a coordinate out of range: errors, and
                // the scene still answers for the last mesh it was fitted to.
                let last: Vec<[f32; 3]> = (0..count)
                    .map(|v| positions[(v * 7919 + 13) % count])
                    .collect();
                let last_mesh = MeshView::new(&last, indices).unwrap();
                let fewer = MeshView::new(&last, &indices[3..]).unwrap();
                assert_eq!(
                    scene.refit(&fewer).unwrap_err(),
                    BvhError::TriangleCountChanged {
                        scene: mesh.triangle_count(),
                        mesh: mesh.triangle_count() - 1
                    }
                );
                let mut far = last.clone();
                far[indices[5] as usize] = [0.0, 2e12, 0.0];
                let far_mesh = MeshView::new(&far, indices).unwrap();
                assert_eq!(
                    scene.refit(&far_mesh).unwrap_err(),
                    BvhError::CoordinateOutOfRange { vertex: indices[5] }
                );
                compare_scene(&last_mesh, &scene, 100, &mut rng);
            }
        }
        assert!(hits > 1000, "{hits} hits");
        // A hierarchy deeper than the search's stack: children still follow
        // their parents, and packets and single rays agree with brute force.
        let (positions, indices) = shrinking_books(70, 0.3, 30);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut deep = BvhScene::new(&mesh).unwrap();
        assert!(deep.depth() > 64);
        let moved: Vec<[f32; 3]> = positions
            .iter()
            .map(|p| (glam::Quat::from_rotation_z(0.4) * Vec3::from(*p)).to_array())
            .collect();
        let moved_mesh = MeshView::new(&moved, &indices).unwrap();
        deep.refit(&moved_mesh).unwrap();
        assert_eq!(
            deep.assert_boxes_hold(&moved_mesh, 0).len(),
            indices.len() / 3
        );
        let brute = BruteForceCaster::new(moved_mesh);
        let rays = fan(&mut rng, Vec3::new(0.0, 0.0, -1e-3), Vec3::X, 200);
        many_equal_each(&moved_mesh, &[&deep], &rays);
        for ray in &rays {
            assert_eq!(
                deep.closest_hit(ray).map(|h| h.t),
                brute.closest_hit(ray).map(|h| h.t)
            );
        }
    }

    #[test]
    fn batches_equal_one_ray_at_a_time() {
        let mut rng = SmallRng::seed_from_u64(5);
        let (positions, indices) = soup(&mut rng, 500);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let bvh = BvhScene::new(&mesh).unwrap();
        let rays: Vec<Ray> = (0..5000).map(|_| random_ray(&mut rng, 2.0)).collect();
        let mut occluded = alloc::vec![false; rays.len()];
        let mut hits = alloc::vec![None; rays.len()];
        occluded_batch(&bvh, &rays, &mut occluded);
        closest_hit_batch(&bvh, &rays, &mut hits);
        for (i, ray) in rays.iter().enumerate() {
            assert_eq!(occluded[i], bvh.occluded(ray));
            assert_eq!(hits[i], bvh.closest_hit(ray));
        }
        assert!(occluded.iter().any(|&o| o) && occluded.iter().any(|&o| !o));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn any_soup_and_ray_agree(seed in any::<u64>(), triangles in 1usize..200) {
            let mut rng = SmallRng::seed_from_u64(seed);
            let (positions, indices) = soup(&mut rng, triangles);
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let brute = BruteForceCaster::new(mesh);
            let bvh = BvhScene::new(&mesh).unwrap();
            for _ in 0..64 {
                let ray = random_ray(&mut rng, 2.0);
                prop_assert_eq!(bvh.occluded(&ray), brute.occluded(&ray));
                prop_assert_eq!(bvh.closest_hit(&ray).map(|h| h.t), brute.closest_hit(&ray).map(|h| h.t));
            }
        }
    }
}

#[test]
fn f64_reference_is_exact_on_a_simple_case() {
    // Keeps the reference itself honest on a case with exact answers.
    let ray = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z, f32::INFINITY);
    let (t, u, v, _) = moller_trumbore_f64(&ray, [Vec3::ZERO, Vec3::X, Vec3::Y]).unwrap();
    assert_eq!((t, u, v), (1.0, 0.25, 0.25));
}
