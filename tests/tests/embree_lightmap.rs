//! Lightmap transfer (diffuse, 0 bounces) baked at texel receivers by
//! `antumbra_core::lightmap` and `transfer::bake_points`, against a dense
//! reference traced by Embree from the same receivers.
//!
//! Run: `make test`, or `cargo test -p antumbra-tests --test embree_lightmap --
//! --nocapture` after `tests/oracle/setup_venv.sh target/pyenv`.
//!
//! Scenes (each quad its own UV chart, 64 × 32 texels): a box standing on a floor
//! (the scene the lightmap code was written against), and, held out, a floor with
//! a thin wall and a low block leaning on it, so receivers meet creases and a
//! wall two hundredths thick. Receivers: 64 per scene, half of them floor texels
//! within two texels of a contact line (where leaks show), half spread over the
//! atlas; after the lift out of geometry.
//!
//! Reference: `t_j = ∫_H V(ω) Y_j(ω) cos θ dω`, 4 bands, by the midpoint rule of
//! `embree_transfer.rs` (128 rings uniform in `sin²θ` × 512 sectors) from the
//! bake's own ray origins, every ray's visibility answered by Embree.
//!
//! Checks (the lightmap issue's acceptance): the relative RMS error over all
//! receivers and coefficients at 1,024 bake rays is at most 3 %, printed with the
//! Monte Carlo noise measured from two seeds; and leaks: no near-contact texel
//! is brighter than the reference by more than its noise. A leak is a bias, so
//! a texel's brightness is its expected constant coefficient (the mean of 16
//! bakes with different seeds, a quarter of one bake's noise) and its noise the
//! standard deviation of one bake over those seeds; the references are the one
//! above and, for texels whose centre lies on the visible floor, the same rule
//! traced from the surface point before the lift, which would show a receiver
//! the lift pushed through a wall or under a block.

use antumbra_core::MeshView;
use antumbra_core::Ray;
use antumbra_core::lightmap::{AtlasOptions, LiftOptions, TexelAtlas, TexelReceiver};
use antumbra_core::raycast::BvhScene;
use antumbra_core::sh::eval_basis_into;
use antumbra_core::transfer::{BakeOptions, BakePoint, BounceReads, Measurement, bake_points};
use antumbra_tests::data::Mesh;
use antumbra_tests::oracle;
use glam::{DVec3, Vec2, Vec3};

const COEFFS: usize = 16;
const REF_RINGS: usize = 128;
const REF_SECTORS: usize = 512;
const RECEIVERS: usize = 64;
const BAKE_RAYS: u32 = 1024;
const ACCEPTED: f64 = 0.03;
/// Independent bakes whose mean estimates each texel's expected value (to a
/// quarter of one bake's noise) and whose spread its noise.
const SEEDS: u64 = 16;
/// The rounding of a constant coefficient summed in `f32` over a bake's rays
/// (about `BAKE_RAYS` roundings of a value near 0.9, relative 6e-8 each).
const ROUNDING: f64 = 1e-5;

/// A scene of quads, each its own UV chart, with flat vertex normals.
#[derive(Default)]
struct Charted {
    mesh: Mesh,
    uvs: Vec<[f32; 2]>,
    normals: Vec<Vec3>,
}

impl Charted {
    /// Adds a quad (corners counter-clockwise seen from where it faces) with
    /// the UV chart `[lo, lo + size]`.
    fn quad(&mut self, corners: [Vec3; 4], lo: Vec2, size: Vec2) {
        let base = self.mesh.positions.len() as u32;
        let normal = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize();
        let uvs = [
            lo,
            lo + Vec2::new(size.x, 0.0),
            lo + size,
            lo + Vec2::new(0.0, size.y),
        ];
        for (p, uv) in corners.iter().zip(uvs) {
            self.mesh.positions.push(p.to_array());
            self.uvs.push(uv.to_array());
            self.normals.push(normal);
        }
        self.mesh
            .indices
            .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }

    /// The five visible faces of the box `[lo, hi]` standing on z = 0, charts
    /// laid out in a row from `chart` with `step` between them.
    fn block(&mut self, lo: Vec3, hi: Vec3, chart: Vec2, size: f32) {
        let v = Vec3::new;
        let faces = [
            [
                v(lo.x, lo.y, hi.z),
                v(hi.x, lo.y, hi.z),
                v(hi.x, hi.y, hi.z),
                v(lo.x, hi.y, hi.z),
            ],
            [
                v(lo.x, lo.y, lo.z),
                v(hi.x, lo.y, lo.z),
                v(hi.x, lo.y, hi.z),
                v(lo.x, lo.y, hi.z),
            ],
            [
                v(hi.x, hi.y, lo.z),
                v(lo.x, hi.y, lo.z),
                v(lo.x, hi.y, hi.z),
                v(hi.x, hi.y, hi.z),
            ],
            [
                v(hi.x, lo.y, lo.z),
                v(hi.x, hi.y, lo.z),
                v(hi.x, hi.y, hi.z),
                v(hi.x, lo.y, hi.z),
            ],
            [
                v(lo.x, hi.y, lo.z),
                v(lo.x, lo.y, lo.z),
                v(lo.x, lo.y, hi.z),
                v(lo.x, hi.y, hi.z),
            ],
        ];
        for (k, face) in faces.into_iter().enumerate() {
            let at = chart + Vec2::new(0.0, k as f32 * (size + 0.02));
            self.quad(face, at, Vec2::splat(size));
        }
    }
}

/// The floor `[-1, 1]²` on the left half of the atlas.
fn floor() -> Charted {
    let mut scene = Charted::default();
    let v = Vec3::new;
    scene.quad(
        [
            v(-1.0, -1.0, 0.0),
            v(1.0, -1.0, 0.0),
            v(1.0, 1.0, 0.0),
            v(-1.0, 1.0, 0.0),
        ],
        Vec2::ZERO,
        Vec2::new(0.5, 1.0),
    );
    scene
}

/// A box on the floor; its footprint for the contact test.
fn box_on_floor() -> (Charted, [Vec2; 2]) {
    let mut scene = floor();
    let (lo, hi) = (Vec3::new(-0.3, -0.3, 0.0), Vec3::new(0.3, 0.3, 0.4));
    scene.block(lo, hi, Vec2::new(0.55, 0.01), 0.17);
    (scene, [lo.truncate(), hi.truncate()])
}

/// Held out: a thin wall across the floor and a low block against it.
fn wall_and_block() -> (Charted, [Vec2; 2]) {
    let mut scene = floor();
    let (lo, hi) = (Vec3::new(-0.6, -0.01, 0.0), Vec3::new(0.6, 0.01, 0.5));
    scene.block(lo, hi, Vec2::new(0.55, 0.01), 0.17);
    scene.block(
        Vec3::new(-0.2, 0.01, 0.0),
        Vec3::new(0.25, 0.35, 0.15),
        Vec2::new(0.77, 0.01),
        0.17,
    );
    (scene, [lo.truncate(), hi.truncate()])
}

/// An orthonormal frame of the unit normal `n`.
fn frame(n: DVec3) -> (DVec3, DVec3) {
    let helper = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = (helper - n * helper.dot(n)).normalize();
    (t, n.cross(t))
}

/// The reference grid's direction of ring `i`, sector `k`.
fn grid_direction(n: DVec3, (t, b): (DVec3, DVec3), i: usize, k: usize) -> Vec3 {
    let sin2 = (i as f64 + 0.5) / REF_RINGS as f64;
    let (sin, cos) = (sin2.sqrt(), (1.0 - sin2).sqrt());
    let phi = std::f64::consts::TAU * (k as f64 + 0.5) / REF_SECTORS as f64;
    (t * (sin * phi.cos()) + b * (sin * phi.sin()) + n * cos).as_vec3()
}

fn relative_rms(got: &[f32], want: &[f64]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (g, w) in got.iter().zip(want) {
        num += (f64::from(*g) - w).powi(2);
        den += w * w;
    }
    (num / den).sqrt()
}

/// Whether a floor receiver lies within `reach` of the footprint's outline.
fn near_contact(r: &TexelReceiver, footprint: [Vec2; 2], reach: f32) -> bool {
    let p = r.position.truncate();
    let [lo, hi] = footprint;
    let outside = (lo - p).max(p - hi).max(Vec2::ZERO).length();
    let inside = (p - lo).min(hi - p).min_element();
    r.triangle < 2 && outside < reach && (outside > 0.0 || inside < reach)
}

/// The midpoint-rule reference of every point's transfer vector (`COEFFS` per
/// point), each reference ray's visibility answered by Embree from the point
/// moved by the bake's ray offset along its normal.
fn reference_of(mesh: &Mesh, points: &[BakePoint]) -> Vec<f64> {
    let offset = BakeOptions::new(Measurement::Diffuse).ray_offset;
    let cells = REF_RINGS * REF_SECTORS;
    let mut rays = Vec::with_capacity(points.len() * cells);
    let mut directions = Vec::with_capacity(points.len() * cells);
    for p in points {
        let origin = p.position + p.normal * offset;
        let n = p.normal.as_dvec3().normalize();
        let axes = frame(n);
        for i in 0..REF_RINGS {
            for k in 0..REF_SECTORS {
                let d = grid_direction(n, axes, i, k);
                rays.push(Ray::new(origin, d, f32::INFINITY));
                directions.push(d);
            }
        }
    }
    let hits = oracle::cast(mesh, &rays, false);
    assert_eq!(hits.len(), rays.len());
    let weight = std::f64::consts::PI / cells as f64;
    let mut reference = vec![0.0f64; points.len() * COEFFS];
    let mut y = [0.0f32; COEFFS];
    for (index, (hit, d)) in hits.iter().zip(&directions).enumerate() {
        if hit.occluded {
            continue;
        }
        eval_basis_into(*d, &mut y).unwrap();
        for (j, yj) in y.iter().enumerate() {
            reference[(index / cells) * COEFFS + j] += weight * f64::from(*yj);
        }
    }
    reference
}

/// The point on the surface a receiver was made from, before the lift moved
/// it: its triangle at its barycentric weights.
fn surface_point(mesh: &Mesh, r: &TexelReceiver) -> Vec3 {
    let t = r.triangle as usize;
    let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(mesh.positions[mesh.indices[3 * t + k] as usize]));
    let [u, v] = r.barycentric;
    a * (1.0 - u - v) + b * u + c * v
}

/// The largest excess, over the near-contact texels, of the bake's expected
/// constant coefficient (the mean of `SEEDS` bakes) over `reference`, in units
/// of one bake's noise at that texel (the standard deviation over the seeds):
/// a leak is a bias, which the mean shows and the noise of one bake does not
/// hide.
fn leak_in_noise_units(
    bakes: &[Vec<f32>],
    reference: &[f64],
    texels: impl Iterator<Item = usize>,
) -> (f64, f64) {
    let mut worst = (f64::NEG_INFINITY, 0.0);
    for k in texels {
        let values: Vec<f64> = bakes.iter().map(|b| f64::from(b[k * COEFFS])).collect();
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let sd = (values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        // A texel whose every bake agrees (a wall through its origin blocks
        // exactly half of every stratum) is exact up to `f32` sums of its
        // rays: noise no lower than that rounding.
        let ratio = (mean - reference[k * COEFFS]) / sd.max(ROUNDING);
        if ratio > worst.0 {
            worst = (ratio, sd);
        }
    }
    worst
}

fn check_scene(name: &str, scene: &Charted, footprint: [Vec2; 2]) -> (f64, f64) {
    let view: MeshView<'_> = scene.mesh.view();
    let mut atlas = TexelAtlas::new(
        &view,
        &scene.uvs,
        &scene.normals,
        &AtlasOptions::new(64, 32),
    )
    .unwrap();
    let bvh = BvhScene::new(&view).unwrap();
    let lifted = atlas.lift(&view, &bvh, &LiftOptions::default()).unwrap();
    let all = atlas.receivers();
    let texel = all[0].texel_size;
    let near: Vec<&TexelReceiver> = all
        .iter()
        .filter(|r| near_contact(r, footprint, 2.0 * texel))
        .collect();
    let mut chosen: Vec<&TexelReceiver> = near
        .iter()
        .step_by((near.len() / (RECEIVERS / 2)).max(1))
        .take(RECEIVERS / 2)
        .copied()
        .collect();
    let near_count = chosen.len();
    let step = all.len() / (RECEIVERS - near_count);
    chosen.extend(all.iter().step_by(step).take(RECEIVERS - near_count));
    let points: Vec<BakePoint> = chosen.iter().map(|r| BakePoint::from(*r)).collect();

    let reference = reference_of(&scene.mesh, &points);

    let bake = |seed: u64| {
        let options = BakeOptions {
            bands: 4,
            rays: BAKE_RAYS,
            seed,
            ..BakeOptions::new(Measurement::Diffuse)
        };
        let set = bake_points(
            &view,
            &scene.normals,
            &bvh,
            &points,
            BounceReads::Vertices,
            &options,
            true,
        )
        .unwrap();
        (0..points.len())
            .flat_map(|p| set.vertex_block(p).unwrap().to_vec())
            .collect::<Vec<f32>>()
    };
    let bakes: Vec<Vec<f32>> = (0..SEEDS).map(|k| bake(5 + k)).collect();
    let (first, second) = (bakes[0].clone(), bakes[1].clone());
    let error = relative_rms(&first, &reference);
    // Two independent estimates: their difference has twice one's variance.
    let second_f64: Vec<f64> = second.iter().map(|&x| f64::from(x)).collect();
    let noise = relative_rms(&first, &second_f64) / 2f64.sqrt();
    // Leaks: against the reference from the same receivers, and, for texels
    // whose centre lies on the visible floor, from the surface point before
    // the lift (a lift that pushed a receiver through a wall or under a block
    // would show there).
    let (leak, leak_noise) = leak_in_noise_units(&bakes, &reference, 0..near_count);
    let visible: Vec<usize> = (0..near_count)
        .filter(|&k| {
            let p = surface_point(&scene.mesh, chosen[k]).truncate();
            let [lo, hi] = footprint;
            (lo - p).max(p - hi).max_element() > 0.0
        })
        .collect();
    let surface_points: Vec<BakePoint> = visible
        .iter()
        .map(|&k| BakePoint {
            position: surface_point(&scene.mesh, chosen[k]),
            normal: points[k].normal,
        })
        .collect();
    let surface_reference = reference_of(&scene.mesh, &surface_points);
    let surface_bakes: Vec<Vec<f32>> = bakes
        .iter()
        .map(|b| {
            visible
                .iter()
                .flat_map(|&k| b[k * COEFFS..(k + 1) * COEFFS].to_vec())
                .collect()
        })
        .collect();
    let (surface_leak, _) =
        leak_in_noise_units(&surface_bakes, &surface_reference, 0..visible.len());
    println!(
        "{name}: {} receivers ({lifted} moved by the lift), {} compared ({near_count} within two texels of a \
         contact line); {BAKE_RAYS} rays: relative RMS error against Embree {:.3} %, Monte Carlo \
         noise {:.3} %; near contact, the largest excess of the expected constant coefficient \
         (mean of {SEEDS} bakes) over the reference from the same receivers is {leak:+.2} times \
         one bake's noise there ({leak_noise:.4}), over the reference from the unlifted surface \
         point {surface_leak:+.2} times ({} texels with visible centres)",
        all.len(),
        points.len(),
        100.0 * error,
        100.0 * noise,
        visible.len()
    );
    assert!(
        near_count >= RECEIVERS / 4,
        "{name}: {near_count} near-contact receivers"
    );
    assert!(error <= ACCEPTED, "{name}: error {error} above {ACCEPTED}");
    assert!(
        leak <= 1.0 && surface_leak <= 1.0,
        "{name}: a near-contact texel is brighter than the reference by more than its noise \
         ({leak} and {surface_leak} times)"
    );
    (error, noise)
}

#[test]
fn texel_transfer_agrees_with_embree_from_the_same_receivers() {
    let (scene, footprint) = box_on_floor();
    check_scene("box on a floor", &scene, footprint);
    let (scene, footprint) = wall_and_block();
    check_scene("thin wall and block (held out)", &scene, footprint);
}
