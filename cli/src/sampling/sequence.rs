//! The R2 low-discrepancy sequence (Roberts 2018), randomised per pixel.
//!
//! Stratified directions converge much faster than independent ones for ambient
//! occlusion and lighting; R2 gives that for any sample count (no power-of-two
//! constraint) at the cost of two multiply-adds per point. A Cranley–Patterson
//! rotation (a random toroidal shift per pixel) keeps the estimate unbiased and
//! turns structured artefacts into noise.

use glam::Vec2;

/// `1/g` and `1/g²`, where `g` is the plastic number, the real root of `x³ = x + 1`.
const ALPHA: [f64; 2] = [0.754_877_666_246_692_8, 0.569_840_290_998_053_3];

/// The R2 points `frac(shift + (i + 1) * alpha)`.
#[derive(Clone, Copy, Debug)]
pub struct R2Sequence {
    shift: Vec2,
}

impl R2Sequence {
    /// The sequence shifted by `shift` (each component in `[0, 1)`).
    pub fn new(shift: Vec2) -> Self {
        R2Sequence { shift }
    }

    /// Point `index`, in `[0, 1)²`.
    pub fn point(&self, index: u32) -> Vec2 {
        let i = f64::from(index) + 1.0;
        let x = (f64::from(self.shift.x) + i * ALPHA[0]).fract();
        let y = (f64::from(self.shift.y) + i * ALPHA[1]).fract();
        // Rounding to f32 can give exactly 1.0; keep the half-open interval.
        Vec2::new(below_one(x as f32), below_one(y as f32))
    }
}

fn below_one(x: f32) -> f32 {
    x.min(1.0 - f32::EPSILON / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_fill_the_square_evenly() {
        // Every cell of a 4×4 grid gets 1/16 of 1600 points, give or take a few.
        let sequence = R2Sequence::new(Vec2::new(0.3, 0.7));
        let mut cells = [0u32; 16];
        for i in 0..1600 {
            let p = sequence.point(i);
            assert!(p.cmpge(Vec2::ZERO).all() && p.cmplt(Vec2::ONE).all());
            cells[(p.x * 4.0) as usize + 4 * (p.y * 4.0) as usize] += 1;
        }
        for count in cells {
            assert!((95..=105).contains(&count), "{cells:?}");
        }
    }
}
