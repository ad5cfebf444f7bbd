//! `antumbra verify`: the BVH caster against the brute-force reference.

use antumbra_core::raycast::{BvhScene, PreparedRay};
use antumbra_core::{BruteForceCaster, Hit, Ray, RayCaster};
use rayon::prelude::*;

use crate::builtin;
use crate::cli::VerifyRaycastArgs;
use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;
use crate::progress;
use crate::ray_batch::{RayClass, random_rays};

/// Mismatches described in full before the rest are only counted.
const SHOWN_MISMATCHES: usize = 5;

/// How one ray compared.
enum Outcome {
    /// Same answers; `hit` says whether it hit.
    Agree { hit: bool },
    /// Same distance, different triangle, and the BVH's triangle really is hit at
    /// that distance: an exact tie (e.g. a ray through a shared vertex).
    Tie,
    /// Different answers.
    Mismatch(Mismatch),
}

/// A disagreement: its class, for the summary, and the details.
struct Mismatch {
    kind: MismatchKind,
    detail: String,
}

/// Classes of disagreement, so a summary points at the likely cause.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum MismatchKind {
    /// The BVH found no hit where the reference did.
    MissedEverything,
    /// The BVH's closest hit is a few ulps farther: a nearer triangle was culled
    /// by a node test that is not conservative against rounding.
    FartherByUlps,
    /// The BVH's closest hit is farther by more than rounding.
    Farther,
    /// The BVH's closest hit is nearer than the reference's, or it hit where the
    /// reference found nothing.
    Nearer,
    /// Same `t`, but the BVH's triangle is not hit at that `t`.
    WrongTriangle,
    /// Same triangle, different barycentrics.
    Barycentrics,
    /// Occlusion answers differ, or disagree with the caster's own closest hit.
    Occlusion,
}

impl MismatchKind {
    fn describe(self) -> &'static str {
        match self {
            MismatchKind::MissedEverything => "BVH missed every hit",
            MismatchKind::FartherByUlps => "BVH closest hit farther by <= 8 ulps",
            MismatchKind::Farther => "BVH closest hit farther by more",
            MismatchKind::Nearer => "BVH closest hit nearer",
            MismatchKind::WrongTriangle => "wrong triangle at the same t",
            MismatchKind::Barycentrics => "barycentrics differ",
            MismatchKind::Occlusion => "occlusion answers differ",
        }
    }
}

fn mismatch(kind: MismatchKind, detail: String) -> Outcome {
    Outcome::Mismatch(Mismatch { kind, detail })
}

/// Per-class tallies.
#[derive(Default)]
struct Tally {
    rays: usize,
    hits: usize,
    ties: usize,
    mismatches: usize,
}

/// Checks every mesh and fails when any ray disagrees.
pub fn run(args: &VerifyRaycastArgs) -> Result<()> {
    let meshes = if args.mesh.is_empty() {
        vec![builtin::bunny()?, builtin::teapot()?]
    } else {
        args.mesh
            .iter()
            .map(|path| TriangleMesh::load_obj(path))
            .collect::<Result<Vec<_>>>()?
    };
    println!(
        "verify: BVH (obvhs CWBVH) against brute force, {} random rays per mesh, seed {}",
        args.rays, args.seed
    );
    let mut total_rays = 0;
    let mut total_mismatches = 0;
    for mesh in &meshes {
        let (rays, mismatches) = verify_mesh(mesh, args.rays as usize, args.seed);
        total_rays += rays;
        total_mismatches += mismatches;
    }
    let agreeing = total_rays - total_mismatches;
    println!(
        "agreement: {agreeing}/{total_rays} rays ({:.4}%)",
        100.0 * agreeing as f64 / total_rays.max(1) as f64
    );
    if total_mismatches > 0 {
        return Err(Error::msg(format!(
            "{total_mismatches} of {total_rays} rays disagree between the BVH and brute force"
        )));
    }
    Ok(())
}

/// Compares both casters on `count` rays; prints a table and returns
/// `(rays, mismatches)`.
fn verify_mesh(mesh: &TriangleMesh, count: usize, seed: u64) -> (usize, usize) {
    let rays = random_rays(mesh, &RayClass::ALL, count, seed);
    let bvh = BvhScene::new(&mesh.view()).expect("TriangleMesh keeps coordinates in range");
    let brute_force = BruteForceCaster::new(mesh.view());
    let bar = progress::bar(rays.len() as u64, mesh.name(), "rays");
    let outcomes: Vec<Outcome> = rays
        .par_iter()
        .map(|(_, ray)| {
            bar.inc(1);
            compare(mesh, &bvh, &brute_force, ray)
        })
        .collect();
    bar.finish_and_clear();

    println!();
    println!("{} ({} triangles)", mesh.name(), mesh.triangle_count());
    println!(
        "  {:<14} {:>8} {:>8} {:>6} {:>11}",
        "rays", "count", "hits", "ties", "mismatches"
    );
    let mut shown = 0;
    let mut kinds: std::collections::BTreeMap<MismatchKind, usize> = Default::default();
    for class in RayClass::ALL {
        let mut tally = Tally::default();
        for ((c, ray), outcome) in rays.iter().zip(&outcomes) {
            if *c != class {
                continue;
            }
            tally.rays += 1;
            match outcome {
                Outcome::Agree { hit } => tally.hits += usize::from(*hit),
                Outcome::Tie => {
                    tally.hits += 1;
                    tally.ties += 1;
                }
                Outcome::Mismatch(Mismatch { kind, detail }) => {
                    tally.mismatches += 1;
                    *kinds.entry(*kind).or_default() += 1;
                    if shown < SHOWN_MISMATCHES {
                        shown += 1;
                        eprintln!("  MISMATCH ({}) {ray:?}: {detail}", class.name());
                    }
                }
            }
        }
        println!(
            "  {:<14} {:>8} {:>8} {:>6} {:>11}",
            class.name(),
            tally.rays,
            tally.hits,
            tally.ties,
            tally.mismatches
        );
    }
    for (kind, count) in &kinds {
        println!("  mismatches, {}: {count}", kind.describe());
    }
    (rays.len(), kinds.values().sum())
}

/// Compares a caster's answers for one ray with the reference's.
fn compare(
    mesh: &TriangleMesh,
    candidate: &impl RayCaster,
    reference: &impl RayCaster,
    ray: &Ray,
) -> Outcome {
    let expected = reference.closest_hit(ray);
    let found = candidate.closest_hit(ray);
    let expected_occluded = reference.occluded(ray);
    let found_occluded = candidate.occluded(ray);
    if expected_occluded != expected.is_some() || found_occluded != found.is_some() {
        return mismatch(
            MismatchKind::Occlusion,
            format!(
                "occluded: brute force {expected_occluded}, BVH {found_occluded}; \
                 closest hit: brute force {expected:?}, BVH {found:?}"
            ),
        );
    }
    match (expected, found) {
        (None, None) => Outcome::Agree { hit: false },
        (Some(e), Some(f)) => compare_hits(mesh, ray, &e, &f),
        (Some(e), None) => mismatch(
            MismatchKind::MissedEverything,
            format!("brute force hits {e:?}, the BVH nothing"),
        ),
        (None, Some(f)) => mismatch(
            MismatchKind::Nearer,
            format!("brute force hits nothing, the BVH {f:?}"),
        ),
    }
}

fn compare_hits(mesh: &TriangleMesh, ray: &Ray, expected: &Hit, found: &Hit) -> Outcome {
    if expected.t.to_bits() != found.t.to_bits() {
        let detail = format!(
            "t differs: brute force {} (triangle {}), BVH {} (triangle {})",
            expected.t, expected.triangle, found.t, found.triangle
        );
        // Hit distances are positive floats, whose bit patterns order like their values.
        let kind = if found.t < expected.t {
            MismatchKind::Nearer
        } else if found.t.to_bits() - expected.t.to_bits() <= 8 {
            MismatchKind::FartherByUlps
        } else {
            MismatchKind::Farther
        };
        return mismatch(kind, detail);
    }
    if expected.triangle == found.triangle {
        // Same triangle, same ray, same test: the barycentrics must be identical too.
        return if expected.u.to_bits() == found.u.to_bits()
            && expected.v.to_bits() == found.v.to_bits()
        {
            Outcome::Agree { hit: true }
        } else {
            mismatch(
                MismatchKind::Barycentrics,
                format!("brute force {expected:?}, BVH {found:?}"),
            )
        };
    }
    // Different triangles at the same t: a tie only if the BVH's triangle really
    // is hit at exactly that t.
    let [a, b, c] = mesh.view().triangle(found.triangle as usize);
    let retest = PreparedRay::new(ray).and_then(|prepared| prepared.intersect(a, b, c));
    match retest {
        Some(hit) if hit.t.to_bits() == expected.t.to_bits() => Outcome::Tie,
        other => mismatch(
            MismatchKind::WrongTriangle,
            format!(
                "triangle {} reported by the BVH at t = {} re-tests as {other:?}",
                found.triangle, found.t
            ),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// Two triangles sharing the edge x = 0 in the z = 0 plane.
    fn two_triangles() -> TriangleMesh {
        TriangleMesh::new(
            "pair",
            vec![
                [0.0, -1.0, 0.0],
                [0.0, 1.0, 0.0],
                [-1.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
            ],
            vec![0, 1, 2, 0, 3, 1],
        )
        .unwrap()
    }

    /// A caster that answers from a fixed closest hit.
    struct Fixed(Option<Hit>);

    impl RayCaster for Fixed {
        fn occluded(&self, _: &Ray) -> bool {
            self.0.is_some()
        }
        fn closest_hit(&self, _: &Ray) -> Option<Hit> {
            self.0
        }
    }

    #[test]
    fn classifies_agreement_ties_and_mismatches() {
        let mesh = two_triangles();
        let reference = BruteForceCaster::new(mesh.view());
        // Straight down through the shared edge: both triangles are hit at t = 1.
        let ray = Ray::new(Vec3::new(0.0, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY);
        let expected = reference.closest_hit(&ray).unwrap();
        assert!(matches!(
            compare(&mesh, &reference, &reference, &ray),
            Outcome::Agree { hit: true }
        ));
        let other = Hit {
            triangle: 1 - expected.triangle,
            ..expected
        };
        assert!(matches!(
            compare(&mesh, &Fixed(Some(other)), &reference, &ray),
            Outcome::Tie
        ));
        let farther = Hit { t: 1.5, ..expected };
        assert!(matches!(
            compare(&mesh, &Fixed(Some(farther)), &reference, &ray),
            Outcome::Mismatch(_)
        ));
        assert!(matches!(
            compare(&mesh, &Fixed(None), &reference, &ray),
            Outcome::Mismatch(_)
        ));
        // A "tie" on a triangle the ray does not touch is a mismatch.
        let inside = Ray::new(Vec3::new(-0.5, 0.0, 1.0), Vec3::NEG_Z, f32::INFINITY);
        let hit = reference.closest_hit(&inside).unwrap();
        let wrong = Hit {
            triangle: 1 - hit.triangle,
            ..hit
        };
        assert!(matches!(
            compare(&mesh, &Fixed(Some(wrong)), &reference, &inside),
            Outcome::Mismatch(_)
        ));
    }
}
