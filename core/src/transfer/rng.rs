//! Deterministic random numbers and stratified hemisphere directions for the bake.
//!
//! Every vertex and pass draws from its own [`SplitMix64`] stream, seeded by a hash
//! of (bake seed, vertex index, pass), so results do not depend on the order or the
//! thread in which vertices are processed: parallel and serial bakes agree bit for
//! bit. SplitMix64 (Steele, Lea and Flood, "Fast Splittable Pseudorandom Number
//! Generators", OOPSLA 2014) passes BigCrush and is a few instructions per draw.

use core::f32::consts::PI;

use glam::Vec3;

pub use crate::rng::SplitMix64;

/// How directions over the hemisphere are drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Sampling {
    /// Density `cos θ / π`: the estimator of `∫ f cos θ dω` is `π/N Σ f`.
    Cosine,
    /// Density `1 / 2π`: the estimator of `∫ f dω` is `2π/N Σ f`.
    Uniform,
}

/// `count` stratified points of the unit square: a jittered `s × s` grid with
/// `s = ⌊√count⌋`, and the remaining `count - s²` points uniformly random. Every
/// point has the same weight, so the estimator stays unbiased.
#[derive(Clone, Debug)]
pub(crate) struct Stratified {
    side: u32,
    count: u32,
    next: u32,
    /// `1 / side`, once per vertex rather than once per point.
    inverse_side: f32,
    /// Column and row of the next grid point, `next % side` and `next / side`
    /// kept by counting (an integer division per point costs measurably in bakes).
    column: u32,
    row: u32,
}

impl Stratified {
    pub(crate) fn new(count: u32) -> Self {
        let mut side = crate::geom::sqrt(f64::from(count)) as u32;
        // Guard the float square root's rounding both ways.
        while side * side > count {
            side -= 1;
        }
        while (side + 1) * (side + 1) <= count {
            side += 1;
        }
        Stratified {
            side,
            count,
            next: 0,
            inverse_side: 1.0 / side as f32,
            column: 0,
            row: 0,
        }
    }

    /// The next point, or `None` after `count` points.
    #[inline]
    pub(crate) fn next(&mut self, rng: &mut SplitMix64) -> Option<(f32, f32)> {
        if self.next >= self.count {
            return None;
        }
        let k = self.next;
        self.next += 1;
        let (ju, jv) = (rng.next_f32(), rng.next_f32());
        if k < self.side * self.side {
            let inv = self.inverse_side;
            let (i, j) = (self.column, self.row);
            self.column += 1;
            if self.column == self.side {
                self.column = 0;
                self.row += 1;
            }
            // min keeps rounding of (i + ju) / side strictly inside [0, 1).
            Some((
                ((i as f32 + ju) * inv).min(1.0 - f32::EPSILON),
                ((j as f32 + jv) * inv).min(1.0 - f32::EPSILON),
            ))
        } else {
            Some((ju, jv))
        }
    }
}

/// Local direction (z up) for the square point `(u, v)`.
#[inline]
pub(crate) fn hemisphere_direction(sampling: Sampling, u: f32, v: f32) -> Vec3 {
    match sampling {
        Sampling::Uniform => {
            let z = u;
            let r = crate::geom::sqrtf((1.0 - z * z).max(0.0));
            let phi = 2.0 * PI * v;
            // One shared range reduction for both (the same bits as sinf, cosf).
            let (sin, cos) = libm::sincosf(phi);
            Vec3::new(r * cos, r * sin, z)
        }
        Sampling::Cosine => {
            // Shirley–Chiu concentric map to the disk, lifted to the hemisphere
            // (Malley's method): strata stay compact near the pole.
            let a = 2.0 * u - 1.0;
            let b = 2.0 * v - 1.0;
            let (r, phi) = if a == 0.0 && b == 0.0 {
                (0.0, 0.0)
            } else if a * a > b * b {
                (a, (PI / 4.0) * (b / a))
            } else {
                (b, PI / 2.0 - (PI / 4.0) * (a / b))
            };
            let (sin, cos) = libm::sincosf(phi);
            let (x, y) = (r * cos, r * sin);
            let z = crate::geom::sqrtf((1.0 - x * x - y * y).max(0.0));
            Vec3::new(x, y, z)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stratified_points_cover_each_stratum_once() {
        let mut rng = SplitMix64::new(7);
        let mut s = Stratified::new(16);
        let mut seen = [false; 16];
        while let Some((u, v)) = s.next(&mut rng) {
            assert!((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v));
            let cell = (v * 4.0) as usize * 4 + (u * 4.0) as usize;
            assert!(!seen[cell]);
            seen[cell] = true;
        }
        assert!(seen.iter().all(|&b| b));
        let mut s = Stratified::new(20);
        let mut n = 0;
        while s.next(&mut rng).is_some() {
            n += 1;
        }
        assert_eq!(n, 20);
    }

    #[test]
    fn sampled_directions_have_the_stated_densities() {
        // ∫ cos θ dω = π: with cosine sampling the estimator is π/N Σ 1 exactly,
        // with uniform sampling 2π/N Σ cos θ ≈ π.
        let mut rng = SplitMix64::new(1);
        let mut s = Stratified::new(4096);
        let mut acc = 0.0f64;
        let mut mean_z = 0.0f64;
        while let Some((u, v)) = s.next(&mut rng) {
            let d = hemisphere_direction(Sampling::Uniform, u, v);
            assert!((d.length() - 1.0).abs() < 1e-5 && d.z >= 0.0);
            acc += f64::from(d.z);
            let c = hemisphere_direction(Sampling::Cosine, u, v);
            assert!((c.length() - 1.0).abs() < 1e-5 && c.z >= 0.0);
            mean_z += f64::from(c.z);
        }
        let pi = core::f64::consts::PI;
        let est = acc * 2.0 * pi / 4096.0;
        // Jittered strata: the estimate's σ is 2π/(4096·√12) ≈ 4.4e-4; allow 5σ.
        assert!((est - pi).abs() < 2.2e-3, "{est}");
        // E[cos θ] under cos θ / π is 2/3.
        assert!((mean_z / 4096.0 - 2.0 / 3.0).abs() < 1e-3);
    }

    #[test]
    fn vertex_streams_differ_and_repeat() {
        let a = SplitMix64::for_vertex(1, 2, 0).next_u64();
        assert_eq!(a, SplitMix64::for_vertex(1, 2, 0).next_u64());
        assert_ne!(a, SplitMix64::for_vertex(1, 3, 0).next_u64());
        assert_ne!(a, SplitMix64::for_vertex(1, 2, 1).next_u64());
        assert_ne!(a, SplitMix64::for_vertex(2, 2, 0).next_u64());
    }
}
