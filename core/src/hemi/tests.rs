//! Tests of triangle and receiver rasterization: the exact masks against the
//! per-cell predicate and against rays cast with the brute-force caster, the
//! mesh invariants (a quad is its two triangles, splitting and translating change
//! nothing beyond rounding), and analytic scenes.

// Printing measured figures needs std even in --no-default-features runs.
extern crate std;

use alloc::vec::Vec;
use std::println;

use glam::Vec3;
use proptest::prelude::*;
use rand::{Rng, SeedableRng, rngs::SmallRng};

use super::test_meshes::bumpy_sphere;
use super::*;
use crate::raycast::BruteForceCaster;

// --- scenes ---

/// `count` random triangles with corners within `size` of centers in the cube
/// `[-half, half]³`.
fn soup(rng: &mut SmallRng, count: usize, half: f32, size: f32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut positions = Vec::new();
    for _ in 0..count {
        let center = random_in_cube(rng, half);
        for _ in 0..3 {
            positions.push((center + random_in_cube(rng, size)).to_array());
        }
    }
    let indices = (0..3 * count as u32).collect();
    (positions, indices)
}

fn random_in_cube(rng: &mut SmallRng, half: f32) -> Vec3 {
    Vec3::new(
        rng.random_range(-half..half),
        rng.random_range(-half..half),
        rng.random_range(-half..half),
    )
}

fn random_unit(rng: &mut SmallRng) -> Vec3 {
    loop {
        let v = random_in_cube(rng, 1.0);
        let l = v.length();
        if l > 1e-2 && l <= 1.0 {
            return v / l;
        }
    }
}

/// Area-weighted vertex normals.
fn vertex_normals(positions: &[[f32; 3]], indices: &[u32]) -> Vec<Vec3> {
    let mut normals = alloc::vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(positions[t[k] as usize]));
        let n = (b - a).cross(c - a);
        for &v in t {
            normals[v as usize] += n;
        }
    }
    normals.iter().map(|n| n.normalize_or(Vec3::Z)).collect()
}

/// World-space corners of triangles given in a receiver's local frame.
fn to_world(receiver: &Receiver, local: &[[Vec3; 3]]) -> (Vec<[f32; 3]>, Vec<u32>) {
    let positions = local
        .iter()
        .flatten()
        .map(|&p| (receiver.origin + receiver.frame.to_world(p)).to_array())
        .collect();
    (positions, (0..3 * local.len() as u32).collect())
}

// --- classification of disagreements ---

/// Whether world direction `dir` from `origin` lies near an edge plane of some
/// triangle whose cone, widened by the same tolerance, contains it: the
/// directions where rounding of the corners, the frame or the ray may decide.
///
/// The tolerance of an edge is `eps` radians plus the tilt that rounding the
/// coordinates (magnitude up to `scale`) by a few ulps gives its plane:
/// `32 · 2⁻²⁴ · scale / (distance from origin to the edge's line)`. For the
/// scenes here that is below 1e-6 unless a receiver sits almost on an edge.
fn near_an_edge(triangles: &[[Vec3; 3]], origin: Vec3, dir: Vec3, eps: f64, scale: f64) -> bool {
    let d = dir.as_dvec3().normalize();
    let o = origin.as_dvec3();
    triangles.iter().any(|t| {
        let [a, b, c] = t.map(|p| p.as_dvec3() - o);
        let edges = [(a, b), (b, c), (c, a)];
        let sign = if a.cross(b).dot(c) < 0.0 { -1.0 } else { 1.0 };
        let mut inside = true;
        let mut near = false;
        for (p, q) in edges {
            let n = p.cross(q);
            let line_distance = n.length() / (q - p).length().max(f64::MIN_POSITIVE);
            let tolerance = eps + 32.0 * f64::from(f32::EPSILON) * 0.5 * scale / line_distance;
            let s = sign * n.dot(d) / n.length().max(f64::MIN_POSITIVE);
            inside &= s >= -tolerance;
            near |= s.abs() <= tolerance;
        }
        inside && near
    })
}

/// Whether `dir` is within `eps` radians of one of the directions `corners`.
fn near_a_corner(corners: &[Vec3], dir: Vec3, eps: f64) -> bool {
    let d = dir.as_dvec3().normalize();
    corners
        .iter()
        .any(|c| c.as_dvec3().normalize().angle_between(d) <= eps)
}

#[derive(Debug, Default)]
struct Agreement {
    cells: u64,
    differ: u64,
    explained: u64,
}

impl Agreement {
    fn fraction(&self) -> f64 {
        1.0 - self.differ as f64 / self.cells as f64
    }
}

/// Compares `ours` with the ray-cast reference of one receiver, classifying each
/// differing cell.
fn tally(
    agreement: &mut Agreement,
    ours: &HemiMask,
    reference: &HemiMask,
    receiver: &Receiver,
    triangles: &[[Vec3; 3]],
    eps: f64,
) {
    let scale = f64::from(
        triangles
            .iter()
            .flatten()
            .fold(receiver.origin.abs().max_element(), |m, p| {
                m.max(p.abs().max_element())
            }),
    );
    agreement.cells += u64::from(VALID_CELL_COUNT);
    for (i, j) in (*ours ^ *reference).occluded_cells() {
        agreement.differ += 1;
        let ray = receiver.cell_ray(i, j).unwrap();
        if near_an_edge(triangles, ray.origin, ray.direction, eps, scale) {
            agreement.explained += 1;
        }
    }
}

fn mesh_triangles(mesh: &MeshView<'_>) -> Vec<[Vec3; 3]> {
    mesh.triangles().collect()
}

// --- the exact mask is the per-cell predicate ---

fn coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => -2.0f32..2.0,
        1 => -1e-3f32..1e-3,
        1 => Just(0.0f32),
        1 => -200.0f32..200.0,
    ]
}

fn point() -> impl Strategy<Value = Vec3> {
    (coordinate(), coordinate(), coordinate()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// Triangles of every shape the rasterizer meets: random, tiny and far, slivers,
/// and nearly edge-on.
fn triangle() -> impl Strategy<Value = [Vec3; 3]> {
    prop_oneof![
        3 => (point(), point(), point()).prop_map(|(a, b, c)| [a, b, c]),
        1 => (point(), point(), point(), 1e-7f32..1e-2).prop_map(|(a, b, c, s)| {
            // Tiny, seen from far: rounding tilts the edge normals noticeably.
            [a * 100.0, a * 100.0 + b * s, a * 100.0 + c * s]
        }),
        1 => (point(), point(), 0.0f32..1.0, -1e-4f32..1e-4).prop_map(|(a, b, t, s)| {
            // A sliver: c almost on the segment ab.
            [a, b, a.lerp(b, t) + Vec3::splat(s)]
        }),
        1 => (point(), point(), -1e-4f32..1e-4).prop_map(|(a, b, s)| {
            // Nearly edge-on: c almost in the plane of a, b and the center.
            [a, b, a * 0.3 + b * 0.6 + a.cross(b) * s]
        }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn exact_triangle_mask_is_the_per_cell_predicate([a, b, c] in triangle()) {
        if let Ok(cone) = TriangleCone::new(a, b, c, false) {
            let [m0, m1, m2] = cone.normals();
            let reference = cone.mask_reference();
            prop_assert_eq!(
                reference,
                half_space_mask_reference(m0) & half_space_mask_reference(m1)
                    & half_space_mask_reference(m2)
            );
            prop_assert_eq!(cone.mask_exact(), reference);
            let mut ored = HemiMask::EMPTY;
            prop_assert_eq!(TriangleCone::or_exact_into(a, b, c, false, &mut ored), Ok(()));
            prop_assert_eq!(ored, reference);
        }
    }
}

// --- mesh invariants ---

/// A convex planar quad, not seen at a grazing angle from the origin, corners
/// counter-clockwise or clockwise.
fn convex_quad() -> impl Strategy<Value = [Vec3; 4]> {
    convex_quad_sized((0.02f32..3.0, 0.02f32..3.0))
}

/// [`convex_quad`] with the quad's two half-extents drawn from `sizes`.
pub(super) fn convex_quad_sized(
    sizes: impl Strategy<Value = (f32, f32)>,
) -> impl Strategy<Value = [Vec3; 4]> {
    (
        (-3.0f32..3.0, -3.0f32..3.0, -1.0f32..4.0),
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0),
        sizes,
        proptest::array::uniform4(-0.6f32..0.6),
        any::<bool>(),
    )
        .prop_map(|(q, w, (s1, s2), jitter, reverse)| {
            let q = Vec3::from(q);
            let w = Vec3::from(w).normalize_or(Vec3::Z);
            let (e1, e2) = w.any_orthonormal_pair();
            let mut corners = [0, 1, 2, 3].map(|k| {
                let angle = k as f32 * core::f32::consts::FRAC_PI_2 + jitter[k];
                q + e1 * s1 * libm::cosf(angle) + e2 * s2 * libm::sinf(angle)
            });
            if reverse {
                corners.reverse();
            }
            corners
        })
        .prop_filter("not grazing", |c| {
            let n = (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero();
            let center = (c[0] + c[1] + c[2] + c[3]) * 0.25;
            n.dot(center).abs() > 0.2 * center.length() && center.length() > 0.1
        })
}

fn exact(a: Vec3, b: Vec3, c: Vec3) -> HemiMask {
    TriangleCone::new(a, b, c, false).map_or(HemiMask::EMPTY, |cone| cone.mask_exact())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// A quad's two triangles give the quad's cone (four half-spaces), with no
    /// pinhole on the diagonal: the diagonal's two sides are exact complements, so
    /// every cell of the quad is in one triangle. The converse can fail only for a
    /// cell within rounding of a corner direction (none in practice).
    #[test]
    fn quad_equals_the_or_of_its_two_triangles([a, b, c, d] in convex_quad()) {
        let det = cross_f32(a, b).dot(c);
        prop_assume!(det != 0.0);
        let s = if det < 0.0 { -1.0 } else { 1.0 };
        let mut quad = HemiMask::VALID;
        for (p, q) in [(a, b), (b, c), (c, d), (d, a)] {
            quad &= half_space_mask(s * triangle::cross(p, q));
        }
        if a.z <= 0.0 && b.z <= 0.0 && c.z <= 0.0 && d.z <= 0.0 {
            quad = HemiMask::EMPTY;
        }
        for halves in [exact(a, b, c) | exact(a, c, d), exact(a, b, d) | exact(b, c, d)] {
            prop_assert_eq!(quad & halves, quad, "a cell of the quad is in neither triangle");
            for (i, j) in (halves ^ quad).occluded_cells() {
                let dir = cell_direction(i, j).unwrap();
                prop_assert!(near_a_corner(&[a, b, c, d], dir, 1e-4), "cell ({}, {})", i, j);
            }
        }
        // The same through a mesh and a receiver.
        let receiver = Receiver::new(Vec3::ZERO, Vec3::Z, 0.0);
        let positions = [a, b, c, d].map(|p| p.to_array());
        let mesh = MeshView::new(&positions, &[0, 1, 2, 0, 2, 3]).unwrap();
        prop_assert_eq!(receiver.origin, Vec3::ZERO);
        prop_assert_eq!(
            rasterize_receiver(&mesh, Vec3::ZERO, Vec3::Z, &RasterOptions::default()),
            exact(a, b, c) | exact(a, c, d)
        );
    }

    /// Splitting triangle abc at the midpoint m of ab: the halves amc and mbc
    /// share the edge mc, whose two sides are exact complements with the tie cells
    /// in both, so nothing opens along it. The halves' outer edges am and mb lie on
    /// the plane of ab only up to the rounding of m and of the cross products, so
    /// cells within rounding of that plane (or of a corner) may change; with
    /// small-integer corners everything is exact and the union is bit for bit the
    /// triangle.
    #[test]
    fn splitting_a_triangle_changes_nothing_but_rounding(
        [a, b, c] in (point(), point(), point()).prop_map(|(a, b, c)| [a, b, c])
    ) {
        // Nearly edge-on triangles can flip the orientation of a half by rounding.
        prop_assume!(a.cross(b).dot(c).abs() > 1e-4 * a.length() * b.length() * c.length());
        let m = (a + b) * 0.5;
        let whole = exact(a, b, c);
        let halves = exact(a, m, c) | exact(m, b, c);
        for (i, j) in (whole ^ halves).occluded_cells() {
            let d = cell_direction(i, j).unwrap();
            let tri = [[a, b, c]];
            prop_assert!(
                near_an_edge(&tri, Vec3::ZERO, d, 1e-5, 200.0) || near_a_corner(&[a, b, c], d, 1e-4),
                "cell ({}, {}) changed away from the edge ab", i, j
            );
        }
    }

    #[test]
    fn splitting_an_integer_triangle_changes_nothing(
        corners in proptest::array::uniform3(proptest::array::uniform3(-64i32..64)),
    ) {
        // Even coordinates: the midpoint is exact and every product below is too.
        let [a, b, c] = corners.map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) * 2.0);
        let m = (a + b) * 0.5;
        prop_assert_eq!(exact(a, m, c) | exact(m, b, c), exact(a, b, c));
    }
}

fn cross_f32(p: Vec3, q: Vec3) -> Vec3 {
    triangle::cross(p, q)
}

/// Translating scene and receiver together changes the corners relative to the
/// center of projection only by the rounding of `(a + T) - (o + T)`, at most
/// half an ulp of `|a| + |T|` per coordinate and step. That tilts the edge planes
/// by about `ulp(|T|) / distance` radians, so only cells that close to an edge
/// plane may change.
#[test]
fn translating_scene_and_receiver_changes_nothing_beyond_rounding() {
    let mut rng = SmallRng::seed_from_u64(0x7a5);
    let (positions, indices) = soup(&mut rng, 60, 1.5, 0.6);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let triangles = mesh_triangles(&mesh);
    let (mut cells, mut changed) = (0u64, 0u64);
    for _ in 0..100 {
        let p = random_in_cube(&mut rng, 0.5);
        let n = random_unit(&mut rng);
        let shift = random_in_cube(&mut rng, 100.0);
        let moved: Vec<[f32; 3]> = positions
            .iter()
            .map(|&q| (Vec3::from(q) + shift).to_array())
            .collect();
        let moved_mesh = MeshView::new(&moved, &indices).unwrap();
        let options = RasterOptions::default();
        let before = rasterize_receiver(&mesh, p, n, &options);
        let after = rasterize_receiver(&moved_mesh, p + shift, n, &options);
        cells += u64::from(VALID_CELL_COUNT);
        let receiver = Receiver::new(p, n, 0.0);
        // Coordinates of magnitude |shift| + 2 are rounded on the way.
        let scale = f64::from(shift.abs().max_element() + 2.0);
        for (i, j) in (before ^ after).occluded_cells() {
            changed += 1;
            let ray = receiver.cell_ray(i, j).unwrap();
            assert!(
                near_an_edge(&triangles, ray.origin, ray.direction, 1e-5, scale),
                "cell ({i}, {j}) changed away from every edge plane"
            );
        }
    }
    println!(
        "translation by up to 100: {changed} of {cells} cells changed, all near an edge plane"
    );
    assert!((changed as f64) < 1e-3 * cells as f64);
}

// --- analytic scenes ---

#[test]
fn nothing_occludes_nothing() {
    let mesh = MeshView::new(&[], &[]).unwrap();
    let (mask, counts) =
        rasterize_receiver_with_counts(&mesh, Vec3::ZERO, Vec3::Z, &RasterOptions::default());
    assert_eq!(mask, HemiMask::EMPTY);
    assert_eq!(counts, TriangleCounts::default());
    let caster = BruteForceCaster::new(mesh);
    assert_eq!(
        rasterize_receiver_reference(&caster, Vec3::ZERO, Vec3::Z, 0.0),
        HemiMask::EMPTY
    );
}

/// Receivers with a few normals, including ones whose frame takes the `n.z < 0`
/// branch and the `n.z = 0` tie.
fn some_receivers() -> [Receiver; 4] {
    [
        Receiver::new(Vec3::ZERO, Vec3::Z, 0.0),
        Receiver::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.6, 0.0, -0.8), 0.25),
        Receiver::new(Vec3::new(-5.0, 0.5, 0.0), Vec3::new(0.0, 1.0, 0.0), 0.0),
        Receiver::new(
            Vec3::new(0.1, 0.0, 0.2),
            Vec3::new(2.0, -3.0, 6.0) / 7.0,
            0.0,
        ),
    ]
}

fn square(center: Vec3, e1: Vec3, e2: Vec3) -> [[Vec3; 3]; 2] {
    let [a, b, c, d] = [
        center - e1 - e2,
        center + e1 - e2,
        center + e1 + e2,
        center - e1 + e2,
    ];
    [[a, b, c], [a, c, d]]
}

#[test]
fn large_plane_above_occludes_every_cell() {
    let table = HalfSpaceTable::default();
    for receiver in some_receivers() {
        let local = square(Vec3::Z, Vec3::X * 1e4, Vec3::Y * 1e4);
        let (positions, indices) = to_world(&receiver, &local);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let n = receiver.frame.normal;
        let p = receiver.origin;
        for quality in [Quality::Exact, Quality::Table(&table)] {
            let options = RasterOptions {
                quality,
                ..RasterOptions::default()
            };
            assert_eq!(
                rasterize_receiver(&mesh, p, n, &options),
                HemiMask::VALID,
                "{quality:?}"
            );
        }
        let caster = BruteForceCaster::new(mesh);
        assert_eq!(
            rasterize_receiver_reference(&caster, p, n, 0.0),
            HemiMask::VALID
        );
    }
}

#[test]
fn wall_beside_the_normal_occludes_the_half_with_u_positive() {
    // A huge wall in the plane u = 0.25 (local x), which contains the normal's
    // direction: it blocks exactly the directions with u > 0, and no cell center
    // has u = 0, so exactly the columns i >= 16.
    let mut half = HemiMask::EMPTY;
    for (i, j, _) in cell_directions() {
        half.set(i, j, i >= 16);
    }
    assert_eq!(half.count_occluded() * 2, VALID_CELL_COUNT);
    for receiver in some_receivers() {
        let local = square(Vec3::X * 0.25, Vec3::Y * 1e3, Vec3::Z * 1e3);
        let (positions, indices) = to_world(&receiver, &local);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let (p, n) = (receiver.origin, receiver.frame.normal);
        let mask = rasterize_receiver(&mesh, p, n, &RasterOptions::default());
        assert_eq!(mask, half, "{receiver:?}");
        let caster = BruteForceCaster::new(mesh);
        assert_eq!(rasterize_receiver_reference(&caster, p, n, 0.0), half);
    }
    // Through the center of projection itself the wall is seen edge-on: every
    // ray from there lies in its plane or misses it, so it occludes nothing.
    let local = square(Vec3::ZERO, Vec3::Y * 1e3, Vec3::Z * 1e3);
    let receiver = Receiver::new(Vec3::ZERO, Vec3::Z, 0.0);
    let (positions, indices) = to_world(&receiver, &local);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let (mask, counts) =
        rasterize_receiver_with_counts(&mesh, Vec3::ZERO, Vec3::Z, &RasterOptions::default());
    assert_eq!(mask, HemiMask::EMPTY);
    assert_eq!(counts.degenerate, 2);
    let caster = BruteForceCaster::new(mesh);
    assert_eq!(
        rasterize_receiver_reference(&caster, Vec3::ZERO, Vec3::Z, 0.0),
        HemiMask::EMPTY
    );
}

#[test]
fn cap_about_the_normal_occludes_the_disk_of_radius_sin_alpha() {
    // A 1024-gon fan at height 1 subtending half-angle α. Squared cell radii are
    // k/1024 with k = 2 mod 8, so sin²α = (8m + 6)/1024 keeps every cell at least
    // 4/1024 in ρ² from the rim, far beyond the polygon's 5e-6 sag.
    const SIDES: usize = 1024;
    let table = HalfSpaceTable::default();
    let mut worst_table = 0.0f32;
    for m in [0, 8, 31, 63, 95, 126] {
        let sin2 = (8 * m + 6) as f32 / 1024.0;
        let radius = libm::sqrtf(sin2 / (1.0 - sin2)); // tan α at height 1
        let rim: Vec<Vec3> = (0..SIDES)
            .map(|k| {
                let angle = core::f32::consts::TAU * k as f32 / SIDES as f32;
                Vec3::new(radius * libm::cosf(angle), radius * libm::sinf(angle), 1.0)
            })
            .collect();
        let local: Vec<[Vec3; 3]> = (0..SIDES)
            .map(|k| [Vec3::Z, rim[k], rim[(k + 1) % SIDES]])
            .collect();
        let mut expected = HemiMask::EMPTY;
        for (i, j, d) in cell_directions() {
            expected.set(i, j, d.x * d.x + d.y * d.y < sin2);
        }
        for receiver in some_receivers() {
            let (positions, indices) = to_world(&receiver, &local);
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let (p, n) = (receiver.origin, receiver.frame.normal);
            assert_eq!(
                rasterize_receiver(&mesh, p, n, &RasterOptions::default()),
                expected
            );
            let options = RasterOptions {
                quality: Quality::Table(&table),
                ..Default::default()
            };
            let wrong = rasterize_receiver(&mesh, p, n, &options).count_differences(&expected);
            // The spokes are shared edges, exact complements in the table too, so
            // table masks err only along the rim: a band of a fraction of a cell.
            let rim_cells = core::f32::consts::TAU * libm::sqrtf(sin2) * 16.0;
            worst_table = worst_table.max(wrong as f32 / rim_cells);
        }
        let fraction = expected.count_occluded() as f32 / VALID_CELL_COUNT as f32;
        println!("cap sin²α = {sin2:.4}: occluded fraction of cells {fraction:.4}");
    }
    println!(
        "cap, table {}: at most {worst_table:.2} wrong cells per cell of rim",
        table.resolution()
    );
    assert!(worst_table < 0.4);
}

// --- culling ---

#[test]
fn culling_classes() {
    let below = TriangleCone::new(
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, -1.0),
        Vec3::new(-1.0, 0.0, 0.0),
        false,
    );
    assert_eq!(below, Err(Culled::BelowHorizon));
    let through_center = TriangleCone::new(Vec3::ZERO, Vec3::X + Vec3::Z, Vec3::Y + Vec3::Z, false);
    assert_eq!(through_center, Err(Culled::Degenerate));
    let collinear = TriangleCone::new(
        Vec3::Z,
        Vec3::Z * 2.0 + Vec3::X,
        Vec3::Z * 3.0 + Vec3::X * 2.0,
        false,
    );
    assert_eq!(collinear, Err(Culled::Degenerate));
    // Counter-clockwise seen from above, so the center below sees its back.
    let [a, b, c] = [Vec3::Z, Vec3::X + Vec3::Z, Vec3::Y + Vec3::Z];
    assert_eq!((b - a).cross(c - a), Vec3::Z);
    assert_eq!(TriangleCone::new(a, b, c, true), Err(Culled::BackFacing));
    let back = TriangleCone::new(a, b, c, false).unwrap();
    let front = TriangleCone::new(a, c, b, true).unwrap();
    assert_eq!(back.mask_exact(), front.mask_exact());
    assert!(!front.mask_exact().is_empty());
    assert!(front.covers_cell(16, 16));
}

/// For a closed mesh seen from outside, every ray that hits a back face has
/// entered through a front face first, so culling back faces changes only cells
/// grazing the silhouette.
#[test]
fn backface_culling_changes_only_silhouette_ties_on_a_closed_mesh() {
    let (positions, indices) = bumpy_sphere(24, 48, 0.15, 0.0);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let triangles = mesh_triangles(&mesh);
    let normals = vertex_normals(&positions, &indices);
    let mut agreement = Agreement::default();
    let mut rasterized = [0u32; 2];
    for v in (0..positions.len()).step_by(17) {
        let p = Vec3::from(positions[v]);
        let receiver = Receiver::new(p, normals[v], 1e-3);
        let mut masks = [HemiMask::EMPTY; 2];
        for (k, cull) in [false, true].into_iter().enumerate() {
            let options = RasterOptions {
                cull_backfaces: cull,
                normal_offset: 1e-3,
                ..Default::default()
            };
            let (mask, counts) = rasterize_receiver_with_counts(&mesh, p, normals[v], &options);
            masks[k] = mask;
            rasterized[k] += counts.rasterized;
        }
        tally(
            &mut agreement,
            &masks[1],
            &masks[0],
            &receiver,
            &triangles,
            1e-5,
        );
    }
    println!(
        "back-face culling: {agreement:?}, triangles rasterized without / with: {rasterized:?}"
    );
    assert_eq!(agreement.differ, agreement.explained);
    assert!(rasterized[1] < rasterized[0]);
}

// --- receivers at vertices ---

#[test]
fn receiver_at_a_vertex_culls_its_incident_triangles() {
    let (positions, indices) = bumpy_sphere(16, 32, 0.2, 0.0);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let triangles = mesh_triangles(&mesh);
    let normals = vertex_normals(&positions, &indices);
    let caster = BruteForceCaster::new(mesh);
    let mut agreement = Agreement::default();
    for v in (0..positions.len()).step_by(5) {
        let p = Vec3::from(positions[v]);
        let incident: Vec<u32> = (0..mesh.triangle_count() as u32)
            .filter(|&t| mesh.triangle_indices(t as usize).contains(&(v as u32)))
            .collect();
        let (mask, counts) =
            rasterize_receiver_with_counts(&mesh, p, normals[v], &RasterOptions::default());
        let skipping = RasterOptions {
            skip_triangles: &incident,
            ..Default::default()
        };
        let (skipped_mask, skipped_counts) =
            rasterize_receiver_with_counts(&mesh, p, normals[v], &skipping);
        // Incident triangles are culled anyway (degenerate, or below the horizon
        // when their other corners are), so skipping them changes nothing.
        assert_eq!(skipped_mask, mask);
        assert_eq!(skipped_counts.skipped as usize, incident.len());
        assert_eq!(skipped_counts.rasterized, counts.rasterized, "vertex {v}");
        let receiver = Receiver::new(p, normals[v], 0.0);
        for &t in &incident {
            let [a, b, c] = mesh.triangle(t as usize).map(|q| receiver.to_local(q));
            // The receiver's own corner is exactly the center of projection.
            assert!([a, b, c].contains(&Vec3::ZERO));
            assert!(TriangleCone::new(a, b, c, false).is_err());
        }
        let reference = rasterize_receiver_reference(&caster, p, normals[v], 0.0);
        tally(
            &mut agreement,
            &mask,
            &reference,
            &Receiver::new(p, normals[v], 0.0),
            &triangles,
            1e-5,
        );
    }
    println!("receivers at vertices, no offset, exact vs ray cast: {agreement:?}");
    assert_eq!(agreement.differ, agreement.explained);
    assert!(agreement.fraction() >= 0.9999);
}

// --- exact rasterization against rays ---

/// Exact masks against the brute-force caster's rays on random soups, a bumpy
/// closed mesh seen from its vertices, and receivers inside and outside a closed
/// sphere: every differing cell must lie within 1e-5 rad of an edge plane of a
/// triangle it nearly touches, and ≥ 99.99 % of cells must agree.
#[test]
fn exact_rasterization_agrees_with_ray_casting() {
    let mut rng = SmallRng::seed_from_u64(0xe1ac7);
    let table = HalfSpaceTable::default();
    let mut exact_agreement = Agreement::default();
    // Table agreement on soups (every edge a silhouette) and on the closed mesh.
    let mut table_agreement = [Agreement::default(), Agreement::default()];
    let mut check =
        |positions: &[[f32; 3]], indices: &[u32], receivers: &[(Vec3, Vec3, f32)], closed: bool| {
            let mesh = MeshView::new(positions, indices).unwrap();
            let triangles = mesh_triangles(&mesh);
            let caster = BruteForceCaster::new(mesh);
            for &(p, n, offset) in receivers {
                let receiver = Receiver::new(p, n, offset);
                let reference = rasterize_receiver_reference(&caster, p, n, offset);
                let options = RasterOptions {
                    normal_offset: offset,
                    ..Default::default()
                };
                let exact = rasterize_receiver(&mesh, p, n, &options);
                tally(
                    &mut exact_agreement,
                    &exact,
                    &reference,
                    &receiver,
                    &triangles,
                    1e-5,
                );
                let options = RasterOptions {
                    quality: Quality::Table(&table),
                    ..options
                };
                let approx = rasterize_receiver(&mesh, p, n, &options);
                tally(
                    &mut table_agreement[usize::from(closed)],
                    &approx,
                    &reference,
                    &receiver,
                    &triangles,
                    1e-5,
                );
            }
        };
    for _ in 0..6 {
        let (positions, indices) = soup(&mut rng, 80, 2.0, 0.7);
        let receivers: Vec<_> = (0..40)
            .map(|_| (random_in_cube(&mut rng, 1.5), random_unit(&mut rng), 0.0))
            .collect();
        check(&positions, &indices, &receivers, false);
    }
    let (positions, indices) = bumpy_sphere(20, 40, 0.2, 0.0);
    let normals = vertex_normals(&positions, &indices);
    let receivers: Vec<_> = (0..positions.len())
        .step_by(7)
        .map(|v| (Vec3::from(positions[v]), normals[v], 2e-3))
        .collect();
    check(&positions, &indices, &receivers, true);
    let receivers: Vec<_> = (0..60)
        .map(|_| (random_in_cube(&mut rng, 2.5), random_unit(&mut rng), 0.0))
        .collect();
    check(&positions, &indices, &receivers, true);
    println!(
        "exact vs ray cast: {:.5} % agreement, {exact_agreement:?}",
        100.0 * exact_agreement.fraction()
    );
    for (scene, agreement) in ["soups", "closed mesh"].iter().zip(&table_agreement) {
        println!(
            "table {} vs ray cast, {scene}: {:.4} % agreement, {agreement:?}",
            table.resolution(),
            100.0 * agreement.fraction()
        );
    }
    assert_eq!(
        exact_agreement.differ, exact_agreement.explained,
        "unexplained disagreements"
    );
    assert!(exact_agreement.fraction() >= 0.9999);
    // The table's error sits along silhouette edges (see HalfSpaceTable): a soup
    // seen from inside is all silhouettes.
    assert!(table_agreement[0].fraction() >= 0.97);
    assert!(table_agreement[1].fraction() >= 0.995);
}

#[test]
fn receiver_helpers_follow_the_conventions() {
    let n = Vec3::new(2.0, -3.0, 6.0) / 7.0;
    let receiver = Receiver::new(Vec3::new(1.0, 2.0, 3.0), n, 0.5);
    assert_eq!(receiver.origin, Vec3::new(1.0, 2.0, 3.0) + 0.5 * n);
    assert_eq!(receiver.frame, crate::Frame::from_normal(n));
    let ray = receiver.cell_ray(16, 16).unwrap();
    let (u, v) = (cell_coordinate(16), cell_coordinate(16));
    let z = libm::sqrtf(1.0 - u * u - v * v);
    let f = receiver.frame;
    assert_eq!(
        ray.direction,
        u * f.tangent + v * f.bitangent + z * f.normal
    );
    assert_eq!(ray.t_max, f32::INFINITY);
    assert!(receiver.cell_ray(0, 0).is_none());
    let p = Vec3::new(4.0, -1.0, 2.0);
    assert!((f.to_world(receiver.to_local(p)) + receiver.origin - p).length() < 1e-5);
}

/// The batched loop of `rasterize_receiver_with_counts` against its slow twin,
/// one triangle at a time through `Accumulator::add`: masks and counts equal on
/// a closed bumpy sphere, a soup of large and tiny triangles (some far, some
/// touching the receiver), with and without skip lists, back-face culling and
/// offsets, in both qualities.
#[test]
fn batched_receiver_loop_is_the_one_triangle_loop() {
    let mut rng = SmallRng::seed_from_u64(0x5eed_4a11);
    let table = HalfSpaceTable::new(64);
    let (sphere_p, sphere_i) = bumpy_sphere(18, 30, 0.2, 0.0);
    let (mut soup_p, mut soup_i) = soup(&mut rng, 400, 3.0, 0.4);
    let (tiny_p, tiny_i) = soup(&mut rng, 300, 3.0, 1e-3);
    let base = soup_p.len() as u32;
    soup_p.extend_from_slice(&tiny_p);
    soup_i.extend(tiny_i.iter().map(|i| i + base));
    // Triangles with a corner at the origin (a receiver below): degenerate
    // for offset 0, out of the batched range either way.
    let base = soup_p.len() as u32;
    soup_p.extend_from_slice(&[[0.0, 0.0, 0.0], [1.0, 0.2, 0.5], [0.3, 1.0, 0.7]]);
    soup_i.extend_from_slice(&[base, base + 1, base + 2]);
    let scenes = [(sphere_p, sphere_i), (soup_p, soup_i)];
    let mut checked = 0;
    for (positions, indices) in &scenes {
        let mesh = MeshView::new(positions, indices).unwrap();
        let count = mesh.triangle_count() as u32;
        let normals = vertex_normals(positions, indices);
        let mut receivers: Vec<(Vec3, Vec3)> = (0..mesh.vertex_count())
            .step_by(37)
            .filter(|&v| normals[v].length_squared() > 0.5)
            .map(|v| (mesh.position(v), normals[v]))
            .collect();
        receivers.push((Vec3::ZERO, Vec3::Z));
        receivers.extend((0..8).map(|_| (random_in_cube(&mut rng, 2.0), random_unit(&mut rng))));
        for (k, &(p, n)) in receivers.iter().enumerate() {
            let mut skip: Vec<u32> = (0..k % 4 * 5).map(|_| rng.random_range(0..count)).collect();
            skip.sort_unstable();
            for quality in [Quality::Exact, Quality::Table(&table)] {
                for cull_backfaces in [false, true] {
                    for normal_offset in [0.0, 0.01] {
                        let options = RasterOptions {
                            quality,
                            cull_backfaces,
                            normal_offset,
                            skip_triangles: &skip,
                        };
                        let fast = rasterize_receiver_with_counts(&mesh, p, n, &options);
                        let slow = rasterize_receiver_one_at_a_time(&mesh, p, n, &options);
                        assert_eq!(fast, slow, "receiver {k} {options:?}");
                        checked += 1;
                    }
                }
            }
        }
    }
    assert!(checked > 300, "{checked}");
}

// --- meshes of extreme size ---

/// A square of side 20 s at height s above the receiver at the origin: corners
/// about 1e-19 away for s = 1e-20 made `(a×b)·c` underflow to zero, and the
/// triangles were culled as degenerate while the rays still hit them (beyond
/// about 7e12 it overflowed). The corners are moved into a frame scaled
/// by a power of two per receiver.
#[test]
fn meshes_of_extreme_size_rasterize_like_rays() {
    let i = [0u32, 1, 2, 0, 2, 3];
    for s in [1e-20f32, 1e-16, 1e-13, 1e13, 1e17] {
        let p: Vec<[f32; 3]> = [
            [-10.0, -10.0, 1.0],
            [10.0, -10.0, 1.0],
            [10.0, 10.0, 1.0],
            [-10.0, 10.0, 1.0],
        ]
        .iter()
        .map(|v| v.map(|c: f32| c * s))
        .collect();
        let mesh = MeshView::new(&p, &i).unwrap();
        let rays =
            rasterize_receiver_reference(&BruteForceCaster::new(mesh), Vec3::ZERO, Vec3::Z, 0.0);
        assert_eq!(rays.count_occluded(), 804, "{s}");
        let table = HalfSpaceTable::new(32);
        for quality in [Quality::Exact, Quality::Table(&table)] {
            let options = RasterOptions {
                quality,
                ..Default::default()
            };
            let (mask, counts) =
                rasterize_receiver_with_counts(&mesh, Vec3::ZERO, Vec3::Z, &options);
            assert_eq!(mask, rays, "{s}: {counts:?}");
            assert_eq!(counts.rasterized, 2, "{s}: {counts:?}");
            let scene = HemiScene::new(ClusteredMesh::unclustered(mesh));
            let batch = BatchOptions {
                quality,
                ..Default::default()
            };
            assert_eq!(scene_mask(&scene, Vec3::ZERO, Vec3::Z, &batch), rays, "{s}");
        }
    }
}

/// Scaling a mesh, its receivers and their offset by a power of two changes no
/// cell and no count, in every loop (one triangle at a time, batched, clustered
/// and not, both qualities), from 2^-100 to 2^100: each receiver's corners are
/// scaled back into the same range, exactly.
#[test]
fn power_of_two_scaled_meshes_keep_their_masks_in_every_loop() {
    let (positions, indices) = bumpy_sphere(12, 20, 0.2, 0.0);
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let normals = vertex_normals(&positions, &indices);
    let table = HalfSpaceTable::new(64);
    let mut clusters = TriangleClusters::new(&mesh, 32);
    for k in [-100, -66, -30, 30, 60, 100] {
        let s = libm::exp2f(k as f32);
        let scaled: Vec<[f32; 3]> = positions.iter().map(|p| p.map(|c| c * s)).collect();
        let scaled_mesh = MeshView::new(&scaled, &indices).unwrap();
        let clustered = HemiScene::new(clusters.update(scaled_mesh));
        let plain = HemiScene::new(ClusteredMesh::unclustered(scaled_mesh));
        for v in (0..mesh.vertex_count()).step_by(5) {
            let (p, n) = (mesh.position(v), normals[v]);
            if n.length_squared() < 0.5 {
                continue;
            }
            for quality in [Quality::Exact, Quality::Table(&table)] {
                for offset in [0.0, 0.01] {
                    let options = RasterOptions {
                        quality,
                        normal_offset: offset,
                        ..Default::default()
                    };
                    let expected = rasterize_receiver_with_counts(&mesh, p, n, &options);
                    let options = RasterOptions {
                        normal_offset: offset * s,
                        ..options
                    };
                    let ps = p * s;
                    let got = rasterize_receiver_with_counts(&scaled_mesh, ps, n, &options);
                    assert_eq!(got, expected, "2^{k} vertex {v}");
                    let one = rasterize_receiver_one_at_a_time(&scaled_mesh, ps, n, &options);
                    assert_eq!(one, expected, "2^{k} vertex {v}");
                    let batch = BatchOptions {
                        quality,
                        normal_offset: offset * s,
                        ..Default::default()
                    };
                    assert_eq!(
                        scene_mask(&plain, ps, n, &batch),
                        expected.0,
                        "2^{k} vertex {v}"
                    );
                    assert_eq!(
                        scene_mask(&clustered, ps, n, &batch),
                        expected.0,
                        "2^{k} vertex {v}"
                    );
                }
            }
        }
    }
}
