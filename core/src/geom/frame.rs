//! The receiver frame: an orthonormal basis (t, b, n) around a unit normal.
//!
//! This is the branchless construction of Duff et al., "Building an Orthonormal
//! Basis, Revisited" (JCGT 2017), exactly as fixed in the design (hemi.md): external
//! tools rebuild hemisphere cell directions from it, so the formula, including the
//! sign rule for `n.z == 0`, must never change.

use glam::Vec3;

/// A right-handed orthonormal frame around a unit normal.
///
/// `tangent × bitangent = normal`. Local coordinates `(x, y, z)` map to the world
/// direction `x * tangent + y * bitangent + z * normal`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent axis (local x).
    pub tangent: Vec3,
    /// Second tangent axis (local y).
    pub bitangent: Vec3,
    /// The unit normal (local z).
    pub normal: Vec3,
}

impl Frame {
    /// Builds the frame of Duff et al. 2017 around a unit normal `n`:
    ///
    /// ```text
    /// s = sign(n.z)  (+1 when n.z is +0.0 or -0.0)
    /// a = -1 / (s + n.z);  c = n.x * n.y * a
    /// t = (1 + s * n.x² * a, s * c, -s * n.x)
    /// b = (c, s + n.y² * a, -n.y)
    /// ```
    ///
    /// `n` must be unit length (within float rounding) for the result to be
    /// orthonormal; it is used as given, so a frame is exactly reproducible from the
    /// same input bits.
    #[inline]
    pub fn from_normal(n: Vec3) -> Self {
        // `>=` maps both +0.0 and -0.0 to +1, which is the documented tie rule
        // (f32::signum would send -0.0 to -1).
        let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
        let a = -1.0 / (s + n.z);
        let c = n.x * n.y * a;
        Frame {
            tangent: Vec3::new(1.0 + s * n.x * n.x * a, s * c, -s * n.x),
            bitangent: Vec3::new(c, s + n.y * n.y * a, -n.y),
            normal: n,
        }
    }

    /// Maps a local direction `(x, y, z)` to world space.
    #[inline]
    pub fn to_world(&self, local: Vec3) -> Vec3 {
        local.x * self.tangent + local.y * self.bitangent + local.z * self.normal
    }

    /// Maps a world direction to local coordinates `(t·v, b·v, n·v)`.
    #[inline]
    pub fn to_local(&self, world: Vec3) -> Vec3 {
        Vec3::new(
            self.tangent.dot(world),
            self.bitangent.dot(world),
            self.normal.dot(world),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn unit_vector() -> impl Strategy<Value = Vec3> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
            .prop_map(|(x, y, z)| Vec3::new(x, y, z))
            .prop_filter("away from zero", |v| v.length() > 0.1)
            .prop_map(Vec3::normalize)
    }

    proptest! {
        #[test]
        fn frame_is_orthonormal_and_right_handed(n in unit_vector()) {
            let f = Frame::from_normal(n);
            prop_assert!((f.tangent.length() - 1.0).abs() < 1e-5);
            prop_assert!((f.bitangent.length() - 1.0).abs() < 1e-5);
            prop_assert!(f.tangent.dot(f.bitangent).abs() < 1e-5);
            prop_assert!(f.tangent.dot(n).abs() < 1e-5);
            prop_assert!(f.bitangent.dot(n).abs() < 1e-5);
            prop_assert!((f.tangent.cross(f.bitangent) - n).length() < 1e-5);
        }

        #[test]
        fn matches_glam_any_orthonormal_pair_off_the_equator(n in unit_vector()) {
            // glam implements the same formula; they differ only at n.z == -0.0.
            prop_assume!(n.z != 0.0);
            let (t, b) = n.any_orthonormal_pair();
            let f = Frame::from_normal(n);
            prop_assert_eq!(f.tangent, t);
            prop_assert_eq!(f.bitangent, b);
        }

        #[test]
        fn local_world_round_trip(n in unit_vector(), v in unit_vector()) {
            let f = Frame::from_normal(n);
            prop_assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }

    #[test]
    fn zero_z_uses_plus_one_for_both_signed_zeros() {
        let plus = Frame::from_normal(Vec3::new(1.0, 0.0, 0.0));
        let minus = Frame::from_normal(Vec3::new(1.0, 0.0, -0.0));
        assert_eq!(plus.tangent, minus.tangent);
        assert_eq!(plus.bitangent, minus.bitangent);
        assert_eq!(plus.tangent, Vec3::new(0.0, 0.0, -1.0));
        assert_eq!(plus.bitangent, Vec3::new(0.0, 1.0, 0.0));
    }

    #[test]
    fn up_normal_gives_identity_axes() {
        let f = Frame::from_normal(Vec3::Z);
        assert_eq!(f.tangent, Vec3::X);
        assert_eq!(f.bitangent, Vec3::Y);
    }
}
