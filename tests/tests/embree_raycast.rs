//! Our ray caster (obvhs CWBVH + watertight test) against Embree 4 on real and
//! random geometry: hit/miss agreement and closest-hit distances.
//!
//! Run: `make test`, or `cargo test -p antumbra-tests --test embree_raycast -- --nocapture`
//! after `tests/oracle/setup_venv.sh target/pyenv`.
//!
//! Thresholds: both tracers are watertight and exact up to float rounding, so
//! they can only disagree where rounding decides: rays through an edge or vertex
//! (either neighbour may take the hit, a silhouette touched at one point may count
//! either way, or a ray may slip past and hit something behind), hits at the ends
//! of the interval, and distances below the float resolution of the coordinates.
//! Those are classified and counted. On the rays the algorithms cast (camera,
//! ambient occlusion, segments) the test requires >= 99.99 % hit/miss agreement
//! and distances within 1e-4 relative on >= 99.99 % of common hits. On rays aimed
//! exactly at vertices and edges it reports the agreement and requires every
//! disagreement to be one of those classes.

use antumbra_core::raycast::BvhScene;
use antumbra_core::{Ray, RayCaster};
use antumbra_tests::data::{Mesh, load_obj};
use antumbra_tests::oracle::{self, OracleHit};
use antumbra_tests::scenes::{mixed_rays, triangle_soup, vertex_and_edge_rays};
use rand::SeedableRng;
use rand::rngs::SmallRng;

/// Barycentric distance from an edge below which a hit is "grazing".
const EDGE_EPS: f32 = 1e-4;
/// Relative distance tolerance for closest hits.
const DISTANCE_REL: f32 = 1e-4;
/// Required agreement fraction.
const REQUIRED: f64 = 0.9999;
const RAYS: usize = 100_000;

/// Units in the last place of the coordinates that two correct f32 ray–triangle
/// tests may differ by (each rounds the hit point's coordinates a few times).
const COORDINATE_ULPS: f32 = 16.0;

#[derive(Default, Debug)]
struct Tally {
    rays: usize,
    hit_miss_agree: usize,
    common_hits: usize,
    distance_agree: usize,
    grazing: usize,
    interval_end: usize,
    only_ours_hit: usize,
    float_resolution: usize,
    unexplained: Vec<String>,
}

fn grazing(u: f32, v: f32) -> bool {
    u.min(v).min(1.0 - u - v) < EDGE_EPS
}

fn near_interval_end(t: f32, ray: &Ray) -> bool {
    (t - ray.t_max).abs() <= DISTANCE_REL * ray.t_max.abs() || t <= DISTANCE_REL * t.abs().max(1e-6)
}

/// Explains a disagreement, or returns None when nothing does.
fn classify(
    ray: &Ray,
    ours: Option<antumbra_core::Hit>,
    embree: &OracleHit,
    tally: &mut Tally,
) -> bool {
    let ours_grazing = ours.is_some_and(|h| grazing(h.u, h.v));
    let embree_hit = embree.t.is_finite();
    let embree_grazing = embree_hit && grazing(embree.u, embree.v);
    if ours_grazing || embree_grazing {
        tally.grazing += 1;
        return true;
    }
    let ends = ours.is_some_and(|h| near_interval_end(h.t, ray))
        || (embree_hit && near_interval_end(embree.t, ray));
    if ends {
        tally.interval_end += 1;
        return true;
    }
    if let Some(h) = ours.filter(|_| embree_hit) {
        let scale = ray.origin.abs().max_element().max(1.0);
        let resolution = COORDINATE_ULPS * f32::EPSILON * scale / ray.direction.length();
        if (h.t - embree.t).abs() <= resolution {
            tally.float_resolution += 1;
            return true;
        }
    }
    false
}

/// Which agreement the ray population must reach.
#[derive(Clone, Copy, PartialEq)]
enum Population {
    /// The queries the algorithms make: thresholds apply.
    Typical,
    /// Aimed at vertices and edges: reported; every disagreement must be explained.
    Adversarial,
}

fn compare(name: &str, mesh: &Mesh, rays: &[Ray], population: Population) -> Tally {
    let scene = BvhScene::new(&mesh.view()).expect("test meshes are in range");
    let embree = oracle::cast(mesh, rays, false);
    let mut tally = Tally {
        rays: rays.len(),
        ..Tally::default()
    };
    for (i, (ray, e)) in rays.iter().zip(&embree).enumerate() {
        let occluded = scene.occluded(ray);
        let hit = scene.closest_hit(ray);
        assert_eq!(
            occluded,
            hit.is_some(),
            "{name} ray {i}: our two queries disagree"
        );
        assert_eq!(
            e.occluded,
            e.t.is_finite(),
            "{name} ray {i}: Embree's two queries disagree"
        );
        if occluded == e.occluded {
            tally.hit_miss_agree += 1;
        } else if occluded {
            tally.only_ours_hit += 1;
        }
        if occluded == e.occluded {
        } else if !classify(ray, hit, e, &mut tally) {
            tally.unexplained.push(format!(
                "{name} ray {i} {ray:?}: ours {hit:?}, embree {e:?}"
            ));
        }
        if let (Some(h), true) = (hit, e.t.is_finite()) {
            tally.common_hits += 1;
            if (h.t - e.t).abs() <= DISTANCE_REL * e.t.abs() {
                tally.distance_agree += 1;
            } else if occluded != e.occluded {
                // Already classified above; count each ray once.
            } else if !classify(ray, Some(h), e, &mut tally) {
                tally
                    .unexplained
                    .push(format!("{name} ray {i} {ray:?}: ours {h:?}, embree {e:?}"));
            }
        }
    }
    let hit_miss = tally.hit_miss_agree as f64 / tally.rays as f64;
    let distance = tally.distance_agree as f64 / tally.common_hits.max(1) as f64;
    println!(
        "{name}: {} triangles, {} rays: hit/miss agreement {:.4} % ({} differ, {} of them hit by us only), \
         distances within {DISTANCE_REL:e} relative on {:.4} % of {} common hits; \
         disagreements explained as grazing an edge: {}, at an interval end: {}, \
         below coordinate float resolution: {}, unexplained: {}",
        mesh.indices.len() / 3,
        tally.rays,
        100.0 * hit_miss,
        tally.rays - tally.hit_miss_agree,
        tally.only_ours_hit,
        100.0 * distance,
        tally.common_hits,
        tally.grazing,
        tally.interval_end,
        tally.float_resolution,
        tally.unexplained.len()
    );
    for line in tally.unexplained.iter().take(10) {
        println!("  unexplained: {line}");
    }
    assert!(
        tally.common_hits > tally.rays / 10,
        "{name}: too few hits to mean anything"
    );
    if population == Population::Typical {
        assert!(
            hit_miss >= REQUIRED,
            "{name}: hit/miss agreement {hit_miss} below {REQUIRED}"
        );
        assert!(
            distance >= REQUIRED,
            "{name}: distance agreement {distance} below {REQUIRED}"
        );
    }
    assert!(
        tally.unexplained.is_empty(),
        "{name}: disagreements no grazing or interval end explains"
    );
    tally
}

#[test]
fn bunny_agrees_with_embree() {
    let mesh = load_obj("bunny.obj");
    assert_eq!((mesh.positions.len(), mesh.indices.len() / 3), (1839, 3674));
    let mut rng = SmallRng::seed_from_u64(0xb077);
    let rays = mixed_rays(&mut rng, &mesh, RAYS);
    compare("bunny", &mesh, &rays, Population::Typical);
    let rays = vertex_and_edge_rays(&mut rng, &mesh, RAYS / 4);
    compare(
        "bunny, aimed at vertices and edges",
        &mesh,
        &rays,
        Population::Adversarial,
    );
}

#[test]
fn teapot_agrees_with_embree() {
    let mesh = load_obj("teapot.obj");
    let mut rng = SmallRng::seed_from_u64(0x7ea);
    let rays = mixed_rays(&mut rng, &mesh, RAYS / 2);
    compare("teapot", &mesh, &rays, Population::Typical);
}

#[test]
fn random_triangle_soup_agrees_with_embree() {
    let mut rng = SmallRng::seed_from_u64(0x50b);
    let mesh = triangle_soup(&mut rng, 5000, 0.3);
    let rays = mixed_rays(&mut rng, &mesh, RAYS);
    compare("triangle soup", &mesh, &rays, Population::Typical);
}
