//! The area light: a validated convex planar polygon, and the light sample sets
//! (stratified and jittered, deterministic from a seed; user-supplied samples
//! validated against the polygon).

use alloc::vec::Vec;
use glam::{DVec3, Vec3};

/// Most vertices a [`LightPolygon`] may have.
pub const MAX_LIGHT_VERTICES: usize = 16;

/// Relative tolerance (of the light's diameter) for planarity of the polygon and
/// for user samples being on the plane and inside the polygon; see
/// [`LightPolygon::tolerance`] for the absolute one.
pub const LIGHT_TOLERANCE: f32 = 1e-4;

/// Units of `f32` rounding at the light's largest coordinate below which the
/// tolerance never goes: rounding a point of the polygon to `f32` moves it by up
/// to `√3/2` units, the stored centroid by as much, and the stored normal tilts
/// by a unit over at most the diameter; twice their sum, rounded up.
const ROUNDING_UNITS: f64 = 8.0;

/// Why a light polygon or a sample set was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightError {
    /// Fewer than 3 or more than [`MAX_LIGHT_VERTICES`] vertices.
    VertexCount {
        /// The count given.
        count: usize,
    },
    /// A coordinate is NaN or infinite.
    NonFinite,
    /// Zero area, or two consecutive vertices equal.
    Degenerate,
    /// A vertex is farther than the tolerance ([`LightPolygon::tolerance`])
    /// from the plane.
    NotPlanar {
        /// The offending vertex.
        vertex: usize,
    },
    /// The polygon is not convex (or its vertices wind both ways).
    NotConvex {
        /// The vertex where the turn has the wrong sign.
        vertex: usize,
    },
    /// A sample is off the light's plane or outside the polygon (beyond the
    /// tolerance), or not finite.
    SampleOffLight {
        /// The offending sample.
        index: usize,
    },
    /// The allocator refused memory (only allocators that can run out, such as a
    /// bare-metal application's, get here).
    OutOfMemory,
}

impl core::fmt::Display for LightError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LightError::VertexCount { count } => {
                write!(
                    f,
                    "a light polygon needs 3 to {MAX_LIGHT_VERTICES} vertices, got {count}"
                )
            }
            LightError::NonFinite => write!(f, "light vertex is not finite"),
            LightError::Degenerate => write!(
                f,
                "light polygon is degenerate (zero area or repeated vertex)"
            ),
            LightError::NotPlanar { vertex } => {
                write!(f, "light vertex {vertex} is off the polygon's plane")
            }
            LightError::NotConvex { vertex } => {
                write!(f, "light polygon is not convex at vertex {vertex}")
            }
            LightError::SampleOffLight { index } => {
                write!(f, "light sample {index} is off the light polygon")
            }
            LightError::OutOfMemory => f.write_str("no memory for the light polygon"),
        }
    }
}

impl core::error::Error for LightError {}

/// A convex planar polygonal area light (3 to 16 vertices, either winding).
///
/// Validated on creation: finite, no repeated consecutive vertices, non-zero area,
/// every vertex within the tolerance ([`LightPolygon::tolerance`]) of the best-fit plane
/// (through the centroid, Newell normal), and convex (every turn the same sign,
/// total turning one revolution). The light is never an occluder and emits from
/// both sides as far as visibility is concerned: receivers on either side see it.
#[derive(Clone, Debug, PartialEq)]
pub struct LightPolygon {
    vertices: Vec<Vec3>,
    centroid: Vec3,
    normal: Vec3,
    area: f32,
    diameter: f32,
    tolerance: f32,
}

impl LightPolygon {
    /// Validates `vertices` (in order around the polygon).
    pub fn new(vertices: &[Vec3]) -> Result<Self, LightError> {
        let count = vertices.len();
        if !(3..=MAX_LIGHT_VERTICES).contains(&count) {
            return Err(LightError::VertexCount { count });
        }
        if vertices.iter().any(|v| !v.is_finite()) {
            return Err(LightError::NonFinite);
        }
        let mut widened = [DVec3::ZERO; MAX_LIGHT_VERTICES];
        for (w, v) in widened.iter_mut().zip(vertices) {
            *w = v.as_dvec3();
        }
        let wide = &widened[..count];
        let centroid = wide.iter().sum::<DVec3>() / count as f64;
        // Newell's normal: twice the vector area, robust for any planar polygon.
        let mut newell = DVec3::ZERO;
        let mut diameter: f64 = 0.0;
        for i in 0..count {
            let (a, b) = (wide[i], wide[(i + 1) % count]);
            if a == b {
                return Err(LightError::Degenerate);
            }
            newell += (a - centroid).cross(b - centroid);
            for w in wide {
                diameter = diameter.max(crate::geom::length_f64(*w - a));
            }
        }
        let twice_area = crate::geom::length_f64(newell);
        if twice_area.is_nan() || twice_area <= 0.0 || !twice_area.is_finite() {
            return Err(LightError::Degenerate);
        }
        let normal = newell / twice_area;
        let largest = wide
            .iter()
            .map(|w| w.abs().max_element())
            .fold(0.0, f64::max);
        let rounding = ROUNDING_UNITS * f64::from(f32::EPSILON) * largest;
        let tolerance = (f64::from(LIGHT_TOLERANCE) * diameter).max(rounding);
        for (vertex, w) in wide.iter().enumerate() {
            if (*w - centroid).dot(normal).abs() > tolerance {
                return Err(LightError::NotPlanar { vertex });
            }
        }
        // Convex: every turn agrees with the Newell normal (which fixes the
        // winding); a star polygon would wind more than once, caught by the
        // angle sum below.
        let mut turning = 0.0;
        for i in 0..count {
            let (a, b, c) = (wide[i], wide[(i + 1) % count], wide[(i + 2) % count]);
            let (u, v) = (b - a, c - b);
            let turn = u.cross(v).dot(normal);
            if turn < -tolerance * (crate::geom::length_f64(u) + crate::geom::length_f64(v)) {
                return Err(LightError::NotConvex {
                    vertex: (i + 1) % count,
                });
            }
            turning += libm::atan2(turn, u.dot(v));
        }
        if (turning - core::f64::consts::TAU).abs() > 1e-3 {
            return Err(LightError::NotConvex { vertex: 0 });
        }
        let kept = crate::fallible::copied(vertices).map_err(|_| LightError::OutOfMemory)?;
        Ok(LightPolygon {
            vertices: kept,
            centroid: centroid.as_vec3(),
            normal: normal.as_vec3(),
            area: (0.5 * twice_area) as f32,
            diameter: diameter as f32,
            tolerance: tolerance as f32,
        })
    }

    /// The vertices, as given.
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    /// The vertex average, a point of the polygon.
    pub fn centroid(&self) -> Vec3 {
        self.centroid
    }

    /// Unit normal; the vertices wind counter-clockwise about it.
    pub fn normal(&self) -> Vec3 {
        self.normal
    }

    /// Area.
    pub fn area(&self) -> f32 {
        self.area
    }

    /// Largest distance between two vertices.
    pub fn diameter(&self) -> f32 {
        self.diameter
    }

    /// Absolute tolerance: [`LIGHT_TOLERANCE`] × diameter, or, for a light small
    /// against its distance from the origin, eight units of `f32` rounding at
    /// its largest coordinate if that is more (so that the samples
    /// [`LightPolygon::samples`] rounds to `f32` are on the light by
    /// [`LightPolygon::contains`]).
    pub fn tolerance(&self) -> f32 {
        self.tolerance
    }

    /// Whether `point` is within the tolerance of the plane and of the polygon.
    pub fn contains(&self, point: Vec3) -> bool {
        if !point.is_finite() {
            return false;
        }
        let tol = f64::from(self.tolerance());
        let (p, c, n) = (
            point.as_dvec3(),
            self.centroid.as_dvec3(),
            self.normal.as_dvec3(),
        );
        if (p - c).dot(n).abs() > tol {
            return false;
        }
        let count = self.vertices.len();
        (0..count).all(|i| {
            let a = self.vertices[i].as_dvec3();
            let b = self.vertices[(i + 1) % count].as_dvec3();
            let inward = crate::geom::normalize_f64(n.cross(b - a));
            (p - a).dot(inward) >= -tol
        })
    }

    /// Checks every sample with [`LightPolygon::contains`].
    pub fn validate_samples(&self, samples: &[Vec3]) -> Result<(), LightError> {
        match samples.iter().position(|&s| !self.contains(s)) {
            Some(index) => Err(LightError::SampleOffLight { index }),
            None => Ok(()),
        }
    }

    /// `count` samples on the polygon, deterministic in `seed`.
    ///
    /// The polygon is cut into a fan of triangles from vertex 0; each gets a share
    /// of the samples proportional to its area (largest remainders); a triangle
    /// with `m` samples has a `k × k` grid of strata (`k² >= m`) over the unit
    /// square, of which `m` are chosen by a seeded shuffle, mapped to the triangle
    /// by the area-preserving square-to-triangle warp. [`SamplePattern::Stratified`]
    /// takes the strata centres, [`SamplePattern::Jittered`] one uniform point in
    /// each.
    pub fn samples(&self, count: usize, pattern: SamplePattern, seed: u64) -> Vec<Vec3> {
        self.try_samples(count, pattern, seed)
            .expect("memory for the light samples")
    }

    /// [`LightPolygon::samples`], or [`OutOfMemory`](crate::fallible::OutOfMemory)
    /// when the allocator refuses.
    pub fn try_samples(
        &self,
        count: usize,
        pattern: SamplePattern,
        seed: u64,
    ) -> Result<Vec<Vec3>, crate::fallible::OutOfMemory> {
        use crate::fallible::{collect, with_capacity};
        let mut rng = SplitMix64::new(seed);
        let v = &self.vertices;
        // Areas in f64: in f32 the squared length of a thin or tiny light's
        // cross products underflows to zero (the polygon was accepted in f64).
        let fan: Vec<(Vec3, Vec3, Vec3, f64)> = collect((1..v.len() - 1).map(|i| {
            let (a, b, c) = (v[0].as_dvec3(), v[i].as_dvec3(), v[i + 1].as_dvec3());
            (
                v[0],
                v[i],
                v[i + 1],
                crate::geom::length_f64((b - a).cross(c - a)),
            )
        }))?;
        let total: f64 = fan.iter().map(|t| t.3).sum();
        // Equal shares if even f64 cannot weigh the triangles.
        let weight = |area: f64| {
            if total > 0.0 && total.is_finite() {
                area / total
            } else {
                1.0 / fan.len() as f64
            }
        };
        // Largest-remainder apportionment of `count` among the fan triangles.
        let mut shares: Vec<(usize, f64)> = collect(fan.iter().map(|t| {
            let exact = count as f64 * weight(t.3);
            (exact as usize, exact - libm::floor(exact))
        }))?;
        let assigned: usize = shares.iter().map(|s| s.0).sum();
        let mut order: Vec<usize> = collect(0..shares.len())?;
        // Unstable sort (no scratch memory): the index breaks every tie.
        order.sort_unstable_by(|&i, &j| shares[j].1.total_cmp(&shares[i].1).then(i.cmp(&j)));
        for &i in order.iter().cycle().take(count.saturating_sub(assigned)) {
            shares[i].0 += 1;
        }
        let mut out = with_capacity(count)?;
        for (t, &(m, _)) in fan.iter().zip(&shares) {
            if m == 0 {
                continue;
            }
            let mut k = 1;
            while k * k < m {
                k += 1;
            }
            let mut strata: Vec<usize> = collect(0..k * k)?;
            for i in (1..strata.len()).rev() {
                let j = (rng.next_u64() % (i as u64 + 1)) as usize;
                strata.swap(i, j);
            }
            for &cell in &strata[..m] {
                let (jx, jy) = match pattern {
                    SamplePattern::Stratified => (0.5, 0.5),
                    SamplePattern::Jittered => (rng.next_f64(), rng.next_f64()),
                };
                let u = ((cell % k) as f64 + jx) / k as f64;
                let w = ((cell / k) as f64 + jy) / k as f64;
                // Square to triangle, area preserving: (1 - sqrt u, sqrt u (1 - w)).
                let su = crate::geom::sqrt(u);
                let (b1, b2) = (su * (1.0 - w), su * w);
                let (a, b, c) = (t.0.as_dvec3(), t.1.as_dvec3(), t.2.as_dvec3());
                out.push((a + (b - a) * b1 + (c - a) * b2).as_vec3());
            }
        }
        Ok(out)
    }
}

/// How [`LightPolygon::samples`] places a sample in its stratum.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SamplePattern {
    /// One uniformly random point per stratum (the default).
    #[default]
    Jittered,
    /// The stratum's centre.
    Stratified,
}

pub use crate::rng::SplitMix64;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thin_and_tiny_lights_get_every_sample() {
        // Accepted in f64, but in f32 their fan triangles' squared cross
        // products underflow: every share came out NaN and each triangle got
        // one sample, two of sixteen.
        let thin = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1e-24, 0.0),
            Vec3::new(0.0, 1e-24, 0.0),
        ];
        let h = 1e-12;
        let tiny = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(h, 0.0, 0.0),
            Vec3::new(h, h, 0.0),
            Vec3::new(0.0, h, 0.0),
        ];
        for polygon in [thin, tiny] {
            let light = LightPolygon::new(&polygon).expect("a valid light");
            for pattern in [SamplePattern::Stratified, SamplePattern::Jittered] {
                for count in [1, 16, 257] {
                    let samples = light.samples(count, pattern, 1);
                    assert_eq!(samples.len(), count, "{polygon:?} {pattern:?}");
                    light.validate_samples(&samples).unwrap();
                }
            }
        }
    }

    fn quad() -> LightPolygon {
        LightPolygon::new(&[
            Vec3::new(-1.0, -1.0, 5.0),
            Vec3::new(1.0, -1.0, 5.0),
            Vec3::new(1.0, 1.0, 5.0),
            Vec3::new(-1.0, 1.0, 5.0),
        ])
        .unwrap()
    }

    #[test]
    fn validation() {
        assert_eq!(quad().area(), 4.0);
        assert_eq!(quad().normal(), Vec3::Z);
        let bow = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        assert_eq!(LightPolygon::new(&bow), Err(LightError::Degenerate)); // zero net area
        let dart = [
            Vec3::ZERO,
            Vec3::X * 2.0,
            Vec3::new(0.5, 0.5, 0.0),
            Vec3::Y * 2.0,
        ];
        assert_eq!(
            LightPolygon::new(&dart),
            Err(LightError::NotConvex { vertex: 2 })
        );
        let bent = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.1), Vec3::Y];
        assert!(matches!(
            LightPolygon::new(&bent),
            Err(LightError::NotPlanar { .. })
        ));
        let line = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert_eq!(LightPolygon::new(&line), Err(LightError::Degenerate));
        assert_eq!(
            LightPolygon::new(&bow[..2]),
            Err(LightError::VertexCount { count: 2 })
        );
        let nan = [Vec3::ZERO, Vec3::X, Vec3::new(0.0, f32::NAN, 0.0)];
        assert_eq!(LightPolygon::new(&nan), Err(LightError::NonFinite));
        // Clockwise is fine: the normal flips.
        let cw: Vec<Vec3> = quad().vertices().iter().rev().copied().collect();
        assert_eq!(LightPolygon::new(&cw).unwrap().normal(), -Vec3::Z);
    }

    #[test]
    fn samples_are_on_the_light_deterministic_and_counted() {
        let hex: Vec<Vec3> = (0..6)
            .map(|i| {
                let a = i as f32 * core::f32::consts::TAU / 6.0;
                Vec3::new(libm::cosf(a), 0.3, libm::sinf(a))
            })
            .collect();
        for light in [quad(), LightPolygon::new(&hex).unwrap()] {
            for n in [1, 16, 63, 256, 1024] {
                for pattern in [SamplePattern::Jittered, SamplePattern::Stratified] {
                    let s = light.samples(n, pattern, 7);
                    assert_eq!(s.len(), n);
                    assert_eq!(light.validate_samples(&s), Ok(()));
                    assert_eq!(s, light.samples(n, pattern, 7));
                }
            }
            let s = light.samples(256, SamplePattern::Jittered, 1);
            assert_ne!(s, light.samples(256, SamplePattern::Jittered, 2));
            // Stratification: every quarter of the area holds about a quarter of
            // the samples (a strict bound would fail only for a broken warp).
            let c = light.centroid();
            let left = s.iter().filter(|p| p.x < c.x).count();
            assert!((96..=160).contains(&left), "{left}");
        }
        let q = quad();
        assert_eq!(
            q.validate_samples(&[Vec3::new(0.0, 0.0, 5.0), Vec3::new(1.1, 0.0, 5.0)]),
            Err(LightError::SampleOffLight { index: 1 })
        );
        assert_eq!(
            q.validate_samples(&[Vec3::new(0.0, 0.0, 5.01)]),
            Err(LightError::SampleOffLight { index: 0 })
        );
    }

    /// The C API review's reproducer: a small tilted light far from the
    /// origin, whose generated samples (rounded to `f32`) lay farther off its
    /// plane than 1e-4 of its diameter, so creating soft shadows with them
    /// failed. Lights of several sizes and distances, both patterns.
    #[test]
    fn generated_samples_of_small_far_lights_are_on_the_light() {
        for (side, offset) in [(0.1f32, 1000.0f32), (1.0, 1e4), (0.01, 100.0), (1e-3, 3.0)] {
            let o = Vec3::splat(offset);
            let light = LightPolygon::new(&[
                o + Vec3::new(side, 0.0, 0.0),
                o + Vec3::new(0.0, side, 0.0),
                o + Vec3::new(0.0, 0.0, side),
            ])
            .unwrap();
            for pattern in [SamplePattern::Stratified, SamplePattern::Jittered] {
                let samples = light.samples(64, pattern, 1);
                assert_eq!(
                    light.validate_samples(&samples),
                    Ok(()),
                    "{side} at {offset}"
                );
            }
        }
        // Near the origin the relative tolerance stands: a point 2e-4 of the
        // diameter off the plane is still refused.
        let light = LightPolygon::new(&[Vec3::X, Vec3::Y, Vec3::Z]).unwrap();
        let off = light.centroid() + 2e-4 * light.diameter() * light.normal();
        assert!(!light.contains(off));
        assert_eq!(light.tolerance(), LIGHT_TOLERANCE * light.diameter());
    }
}
