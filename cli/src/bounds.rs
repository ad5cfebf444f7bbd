//! Axis-aligned bounding boxes, used to frame cameras, size ground planes and
//! scale ray epsilons to the scene.

use glam::Vec3;

/// An axis-aligned box `min..=max` ([`Bounds::EMPTY`] when built from no points).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Bounds {
    /// The box that contains nothing; growing it by a point gives that point.
    pub const EMPTY: Bounds = Bounds {
        min: Vec3::INFINITY,
        max: Vec3::NEG_INFINITY,
    };

    /// The smallest box holding every point.
    pub fn of_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, |bounds, p| Bounds {
            min: bounds.min.min(p),
            max: bounds.max.max(p),
        })
    }

    /// Centre of the box.
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// Edge lengths.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    /// Length of the main diagonal: the scene scale every epsilon is relative to.
    pub fn diagonal(&self) -> f32 {
        self.size().length()
    }

    /// The eight corners.
    pub fn corners(&self) -> [Vec3; 8] {
        let (lo, hi) = (self.min, self.max);
        [
            Vec3::new(lo.x, lo.y, lo.z),
            Vec3::new(hi.x, lo.y, lo.z),
            Vec3::new(lo.x, hi.y, lo.z),
            Vec3::new(hi.x, hi.y, lo.z),
            Vec3::new(lo.x, lo.y, hi.z),
            Vec3::new(hi.x, lo.y, hi.z),
            Vec3::new(lo.x, hi.y, hi.z),
            Vec3::new(hi.x, hi.y, hi.z),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_of_points() {
        let b = Bounds::of_points([Vec3::new(1.0, -2.0, 0.0), Vec3::new(-1.0, 2.0, 3.0)]);
        assert_eq!(b.min, Vec3::new(-1.0, -2.0, 0.0));
        assert_eq!(b.max, Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(b.center(), Vec3::new(0.0, 0.0, 1.5));
        assert_eq!(Bounds::of_points([]), Bounds::EMPTY);
    }
}
