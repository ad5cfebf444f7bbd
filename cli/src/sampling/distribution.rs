//! Piecewise-constant distributions over `[0, 1)` and `[0, 1)²`, for importance
//! sampling tabulated functions such as an environment map's brightness
//! (the construction of Pharr, Jakob and Humphreys, *PBRT*, 3rd ed., §13.6.7).

use glam::Vec2;

/// A density proportional to a non-negative step function with `n` equal steps.
#[derive(Clone, Debug)]
struct Distribution1D {
    func: Vec<f32>,
    /// `cdf[i]` = probability of the steps before `i`; `cdf[n] = 1`.
    cdf: Vec<f32>,
    /// Integral of `func` over `[0, 1)`.
    integral: f32,
}

impl Distribution1D {
    /// The distribution of `func` (non-negative, non-empty); uniform when `func`
    /// integrates to zero, so sampling never divides by zero.
    fn new(func: Vec<f32>) -> Self {
        let n = func.len();
        let mut cdf = Vec::with_capacity(n + 1);
        // Sum in f64: a 1024-step row of very different magnitudes loses too much in f32.
        let mut running = 0.0f64;
        cdf.push(0.0);
        for &f in &func {
            running += f64::from(f) / n as f64;
            cdf.push(running as f32);
        }
        let integral = running as f32;
        if running > 0.0 {
            for c in &mut cdf[1..] {
                *c = (f64::from(*c) / running) as f32;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        }
        cdf[n] = 1.0;
        Distribution1D {
            func,
            cdf,
            integral,
        }
    }

    /// Density at step `i` relative to the uniform density on `[0, 1)`.
    fn density(&self, i: usize) -> f32 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }

    /// Maps uniform `u ∈ [0, 1)` to `(x ∈ [0, 1), density at x, step index)`.
    fn sample(&self, u: f32) -> (f32, f32, usize) {
        let n = self.func.len();
        // Last i with cdf[i] <= u; steps with zero probability are never chosen
        // because their cdf interval is empty.
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .saturating_sub(1)
            .min(n - 1);
        let width = self.cdf[i + 1] - self.cdf[i];
        let within = if width > 0.0 {
            ((u - self.cdf[i]) / width).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let x = ((i as f32 + within) / n as f32).min(1.0 - f32::EPSILON / 2.0);
        (x, self.density(i), i)
    }
}

/// A density on `[0, 1)²` proportional to a non-negative `width × height` table
/// (row-major, row 0 at `y = 0`): rows are chosen by their total, then a column
/// within the row.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// The distribution of `values`, which must hold `width * height` entries
    /// (`width, height > 0`); negative or non-finite entries count as zero.
    pub fn new(values: &[f32], width: usize, height: usize) -> Self {
        assert!(width > 0 && height > 0 && values.len() == width * height);
        let rows: Vec<Distribution1D> = values
            .chunks_exact(width)
            .map(|row| {
                Distribution1D::new(
                    row.iter()
                        .map(|&v| if v.is_finite() { v.max(0.0) } else { 0.0 })
                        .collect(),
                )
            })
            .collect();
        let marginal = Distribution1D::new(rows.iter().map(|row| row.integral).collect());
        Distribution2D { rows, marginal }
    }

    /// Maps a uniform point to `(point in [0, 1)², density there)`.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (y, row_density, row) = self.marginal.sample(u.y);
        let (x, column_density, _) = self.rows[row].sample(u.x);
        (Vec2::new(x, y), row_density * column_density)
    }

    /// Density at a point of `[0, 1)²` (clamped into the table).
    pub fn density(&self, p: Vec2) -> f32 {
        let height = self.rows.len();
        let width = self.rows[0].func.len();
        let row = ((p.y * height as f32) as usize).min(height - 1);
        let column = ((p.x * width as f32) as usize).min(width - 1);
        self.marginal.density(row) * self.rows[row].density(column)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::SampleRng;

    #[test]
    fn samples_follow_the_table_and_densities_agree() {
        // 2×2 table: weights 1, 0 / 2, 5 → probabilities 1/8, 0, 2/8, 5/8.
        let dist = Distribution2D::new(&[1.0, 0.0, 2.0, 5.0], 2, 2);
        let mut rng = SampleRng::new(9);
        let n = 80_000;
        let mut counts = [0u32; 4];
        for _ in 0..n {
            let (p, density) = dist.sample(rng.next_vec2());
            let cell = (p.x * 2.0) as usize + 2 * (p.y * 2.0) as usize;
            counts[cell] += 1;
            assert!((density - dist.density(p)).abs() < 1e-5);
        }
        let expected = [1.0, 0.0, 2.0, 5.0].map(|w| w / 8.0);
        for (count, p) in counts.iter().zip(expected) {
            assert!((*count as f32 / n as f32 - p).abs() < 0.01, "{counts:?}");
        }
        // Density is probability / cell area (1/4).
        assert!((dist.density(Vec2::new(0.75, 0.75)) - 2.5).abs() < 1e-5);
    }

    #[test]
    fn all_zero_table_is_uniform() {
        let dist = Distribution2D::new(&[0.0; 6], 3, 2);
        let (p, density) = dist.sample(Vec2::new(0.5, 0.5));
        assert!((density - 1.0).abs() < 1e-6);
        assert!(p.cmplt(Vec2::ONE).all());
    }
}
