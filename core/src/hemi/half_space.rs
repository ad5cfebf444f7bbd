//! Half-space masks: the valid cells on the non-negative side of a plane through
//! the center of projection, the building block of triangle rasterization (Kautz,
//! Lehtinen and Aila 2004, §3; each triangle is the AND of three of them).
//!
//! The predicate, fixed for every quality and every caller, is
//!
//! ```text
//! inside(m, i, j) = (m.x * u_i + m.y * v_j) + m.z * z_ij >= 0.0     (no fused multiply-add)
//! ```
//!
//! with `(u_i, v_j, z_ij)` the direction of [`cell_direction`](super::cell_direction),
//! evaluated on `m` scaled by a power of two so its largest component is in
//! `[1, 2)` (exact; it only keeps tiny and huge normals out of the subnormal and
//! infinite ranges). The half-space is closed, the tie rule: cells exactly on the
//! plane (the sum is `+0.0` or `-0.0`) are inside. Negating `m` negates every product and sum exactly in IEEE
//! arithmetic, so `inside(-m)` is exactly `m·d <= 0`: a plane's two sides cover
//! every valid cell and share only the cells exactly on it. Two triangles sharing an
//! edge get opposite normals `a×b` and `b×a = -(a×b)` (also exact), which is why
//! meshes rasterized with the exact masks have no pinholes along shared edges.
//!
//! [`half_space_mask`] builds the mask row by row: the cells of a row are a circle
//! arc, the plane cuts it in at most two points, so the inside cells are one run
//! (when `m.z >= 0`, where the predicate is concave along the row) or the complement
//! of one (`m.z < 0`). The run's ends are solved analytically and then the cells at
//! each end are re-tested with the predicate above, walking until it changes; when
//! both guessed ends fail, the row is scanned. The result equals
//! [`half_space_mask_reference`] (every cell tested) bit for bit as long as the
//! predicate's cells on a row are one run. Concavity gives that unless rounding
//! flips a cell in the middle of a run, which needs three neighbouring cells within
//! rounding (`4e-7 |m|`) of the plane; a row's values are at least about `|m|/128`
//! in size, or change that much from cell to cell near a tangency. Property tests
//! check the equality on random, tie, near-horizon and near-tangent planes.

use glam::Vec3;

use super::mask::{
    CELL_COORD, CELL_Z, GRID, HemiMask, ROW_FIRST, ROW_LAST, ROW_RADIUS, ROW_RADIUS_SQ,
};

pub(crate) use crate::geom::normalize_exponent;

/// The closed half-space predicate `m·d >= 0` at valid cell `(i, j)`, with the one
/// fixed evaluation order every mask of this module uses. Callers pass normals
/// already through [`normalize_exponent`].
#[inline(always)]
pub(crate) fn inside(m: Vec3, i: usize, j: usize) -> bool {
    // Written out, not `Vec3::dot`, so the order of the sum is ours to guarantee.
    m.x * CELL_COORD[i] + m.y * CELL_COORD[j] + m.z * CELL_Z[j][i] >= 0.0
}

/// The mask of valid cells with `m·d >= 0`, testing every cell: the obviously
/// right twin of [`half_space_mask`].
///
/// `m` need not be normalised; the predicate is evaluated on `m` scaled by a power
/// of two (exact, see the module docs). `m = 0` gives [`HemiMask::VALID`]
/// (`0 >= 0`); a non-finite `m` gives an unspecified mask (never a panic).
pub fn half_space_mask_reference(m: Vec3) -> HemiMask {
    let m = normalize_exponent(m);
    let mut mask = HemiMask::EMPTY;
    for j in 0..GRID {
        for i in ROW_FIRST[j] as usize..=ROW_LAST[j] as usize {
            if inside(m, i, j) {
                mask.rows[j] |= 1 << i;
            }
        }
    }
    mask
}

/// The mask of valid cells with `m·d >= 0`, in the receiver's local frame, built
/// row by row from the analytic chord–plane intersection and re-tested at the
/// boundary cells. Equal to [`half_space_mask_reference`] bit for bit.
///
/// `m` is the plane's normal (the plane passes through the center of projection);
/// it need not be normalised. A non-finite `m` gives an unspecified mask.
pub fn half_space_mask(m: Vec3) -> HemiMask {
    let plane = RowSolver::new(normalize_exponent(m));
    let mut mask = HemiMask::EMPTY;
    for (j, row) in mask.rows.iter_mut().enumerate() {
        *row = plane.row(j);
    }
    mask
}

/// A plane prepared for row-by-row solving.
///
/// Along row `j` the predicate is `g(u) = m.x u + m.y v_j + m.z sqrt(r_j² - u²)`,
/// concave in `u` when `m.z >= 0`. For `m.z < 0` the solver works with `-m` (concave)
/// and the set `{-m·d > 0}`, the complement of the wanted one.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RowSolver {
    /// The plane normal as given; the only thing the predicate ever sees.
    m: Vec3,
    /// `m` or `-m`, whichever has `z >= 0`: the concave form solved analytically.
    g: Vec3,
    /// `1 / (g.x² + g.z²)`, infinite when the predicate is constant along rows.
    inv_len_xz_sq: f32,
    /// Whether `g = -m`, so the solved run is the complement of the result.
    complement: bool,
}

impl RowSolver {
    /// Prepares `m`, which must already be through [`normalize_exponent`].
    #[inline]
    pub(crate) fn new(m: Vec3) -> Self {
        let complement = m.z < 0.0;
        let g = if complement { -m } else { m };
        RowSolver {
            m,
            g,
            inv_len_xz_sq: 1.0 / (g.x * g.x + g.z * g.z),
            complement,
        }
    }

    /// Row `j` of the half-space mask.
    #[inline]
    pub(crate) fn row(&self, j: usize) -> u32 {
        let first = ROW_FIRST[j] as usize;
        let last = ROW_LAST[j] as usize;
        let valid = run_bits(first, last);
        let m = self.m;
        let run = if self.complement {
            // The run where -m·d > 0, i.e. where the predicate of m fails.
            solve_run(self.guess(j), first, last, |i| !inside(m, i, j))
        } else {
            solve_run(self.guess(j), first, last, |i| inside(m, i, j))
        };
        let bits = run.map_or(0, |(lo, hi)| run_bits(lo, hi));
        if self.complement { valid & !bits } else { bits }
    }

    /// The analytic run `{u : g(u) >= 0}` on row `j`, as a column interval or, when
    /// empty, the column nearest to where `g` peaks.
    #[inline]
    fn guess(&self, j: usize) -> Guess {
        let Vec3 {
            x: gx,
            y: gy,
            z: gz,
        } = self.g;
        let c = gy * CELL_COORD[j];
        if !self.inv_len_xz_sq.is_finite() {
            // g.x = g.z = 0: constant along the row (also catches NaN).
            return if c >= 0.0 {
                Guess::Run(-1.0, 1.0)
            } else {
                Guess::Empty(0.0)
            };
        }
        // The line g.x u + g.z w + c = 0 against the circle u² + w² = r²: with
        // u = r cos φ, w = r sin φ, g >= 0 on an arc centered on the direction of
        // (g.x, g.z), which lies in the upper half because g.z >= 0. Its ends are
        // u = (-g.x c ∓ g.z sqrt(r² (g.x² + g.z²) - c²)) / (g.x² + g.z²), and the run
        // reaches the rim u = -r (or +r) when g is non-negative there.
        let r = ROW_RADIUS[j];
        let len_xz_sq = gx * gx + gz * gz;
        let disc = ROW_RADIUS_SQ[j] * len_xz_sq - c * c;
        let peak = -gx * c * self.inv_len_xz_sq;
        if disc < 0.0 {
            // The plane misses the row's circle: all in or all out.
            return if c > 0.0 {
                Guess::Run(-1.0, 1.0)
            } else {
                Guess::Empty(peak)
            };
        }
        let s = gz * crate::geom::sqrtf(disc) * self.inv_len_xz_sq;
        let lo = if c - gx * r >= 0.0 { -1.0 } else { peak - s };
        let hi = if c + gx * r >= 0.0 { 1.0 } else { peak + s };
        if lo <= hi {
            Guess::Run(lo, hi)
        } else {
            Guess::Empty(peak)
        }
    }
}

/// Where the analytic solution puts a row's run, in disk coordinates.
#[derive(Clone, Copy, Debug)]
enum Guess {
    /// The run covers `u` in `[lo, hi]`.
    Run(f32, f32),
    /// No cell; the predicate is largest near this `u`.
    Empty(f32),
}

/// `(u + 1) * 16 - 0.5`: the fractional column of disk coordinate `u`, clamped to
/// a range where the integer conversions below are exact and cannot overflow.
#[inline(always)]
fn column(u: f32) -> f32 {
    // A NaN stays NaN here and converts to 0 in the `as` casts below (saturating,
    // never a panic); the result is then only a bad guess, which the cell tests fix.
    (u * 16.0 + 15.5).clamp(-2.0, 34.0)
}

/// `floor(x)` for `x` in `[-2, 34]` without a libm call (truncation of a positive).
#[inline(always)]
fn floor_small(x: f32) -> isize {
    (x + 8.0) as isize - 8
}

/// `ceil(x)` for `x` in `[-2, 34]`.
#[inline(always)]
fn ceil_small(x: f32) -> isize {
    8 - (8.0 - x) as isize
}

/// Bits `lo..=hi` set (`lo <= hi < 32`).
#[inline(always)]
fn run_bits(lo: usize, hi: usize) -> u32 {
    debug_assert!(lo <= hi && hi < GRID);
    ((u64::MAX >> (63 - hi)) as u32) & (u32::MAX << lo)
}

/// The run of columns `lo..=hi` of `first..=last` where `holds` is true, given
/// that those columns are one contiguous run (possibly empty) and an analytic
/// guess of where it is. Only the guessed ends (and the cells next to them) are
/// tested in the common case; when both guessed ends fail the row is scanned.
#[inline(always)]
fn solve_run(
    guess: Guess,
    first: usize,
    last: usize,
    holds: impl Fn(usize) -> bool,
) -> Option<(usize, usize)> {
    let clamp = |k: isize| k.clamp(first as isize, last as isize) as usize;
    match guess {
        Guess::Run(lo, hi) => {
            let (lo_col, hi_col) = (ceil_small(column(lo)), floor_small(column(hi)));
            if lo_col > hi_col || hi_col < first as isize || lo_col > last as isize {
                // The run falls between two cell centers (or off the row): rounding
                // can still put a cell on it, so test the two nearest.
                return seed_run(clamp(hi_col), clamp(lo_col), first, last, &holds);
            }
            let (gl, gh) = (clamp(lo_col), clamp(hi_col));
            match (holds(gl), holds(gh)) {
                (true, true) => Some((walk_down(gl, first, &holds), walk_up(gh, last, &holds))),
                (true, false) => {
                    // The run ends before gh: step back to its last cell.
                    let mut hi = gh - 1;
                    while !holds(hi) {
                        hi -= 1;
                    }
                    Some((walk_down(gl, first, &holds), hi))
                }
                (false, true) => {
                    let mut lo = gl + 1;
                    while !holds(lo) {
                        lo += 1;
                    }
                    Some((lo, walk_up(gh, last, &holds)))
                }
                (false, false) => scan_run(first, last, &holds),
            }
        }
        Guess::Empty(peak) => {
            let x = column(peak);
            seed_run(
                clamp(floor_small(x)),
                clamp(ceil_small(x)),
                first,
                last,
                &holds,
            )
        }
    }
}

/// The run through `a` or `b` (adjacent columns), if either holds.
#[inline(always)]
fn seed_run(
    a: usize,
    b: usize,
    first: usize,
    last: usize,
    holds: &impl Fn(usize) -> bool,
) -> Option<(usize, usize)> {
    let seed = if holds(a) {
        a
    } else if b != a && holds(b) {
        b
    } else {
        return None;
    };
    Some((walk_down(seed, first, holds), walk_up(seed, last, holds)))
}

/// Lowest column of the run containing `k`.
#[inline(always)]
fn walk_down(mut k: usize, first: usize, holds: &impl Fn(usize) -> bool) -> usize {
    while k > first && holds(k - 1) {
        k -= 1;
    }
    k
}

/// Highest column of the run containing `k`.
#[inline(always)]
fn walk_up(mut k: usize, last: usize, holds: &impl Fn(usize) -> bool) -> usize {
    while k < last && holds(k + 1) {
        k += 1;
    }
    k
}

/// Every column tested: the fallback when the guess is off by more than its ends.
#[cold]
fn scan_run(first: usize, last: usize, holds: &impl Fn(usize) -> bool) -> Option<(usize, usize)> {
    let lo = (first..=last).find(|&k| holds(k))?;
    Some((lo, walk_up(lo, last, holds)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hemi::mask::{VALID_CELL_COUNT, cell_directions};
    use proptest::prelude::*;

    fn component() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => -1.0f32..1.0,
            1 => Just(0.0f32),
            1 => Just(-0.0f32),
            1 => -1e-6f32..1e-6,
            1 => prop_oneof![Just(1.0f32), Just(-1.0f32), Just(0.5f32), Just(1.0 / 32.0)],
        ]
    }

    fn normal() -> impl Strategy<Value = Vec3> {
        (component(), component(), component(), -20i32..20)
            .prop_map(|(x, y, z, e)| Vec3::new(x, y, z) * libm::exp2f(e as f32))
    }

    /// Planes through (or within rounding of) the direction of a cell: the ties.
    fn plane_through_a_cell() -> impl Strategy<Value = Vec3> {
        (
            0usize..VALID_CELL_COUNT as usize,
            -1.0f32..1.0,
            -1.0f32..1.0,
            -1.0f32..1.0,
        )
            .prop_map(|(k, x, y, z)| {
                let (_, _, d) = cell_directions().nth(k).unwrap();
                Vec3::new(x, y, z).cross(d)
            })
    }

    /// Near-horizon planes: normals close to the local z axis, either sign.
    fn near_horizon() -> impl Strategy<Value = Vec3> {
        (
            -1e-2f32..1e-2,
            -1e-2f32..1e-2,
            prop_oneof![Just(1.0f32), Just(-1.0f32)],
        )
            .prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    /// Planes nearly tangent to a row's circle: m·d = 0 has a double root there.
    fn near_tangent() -> impl Strategy<Value = Vec3> {
        (0usize..GRID, -3.0f32..3.0, -1e-4f32..1e-4, any::<bool>()).prop_map(
            |(j, phi, eps, flip)| {
                // The circle P(φ) = (r cos φ, v, r sin φ); P(φ0) × P'(φ0) is
                // proportional to (v cos φ0, -r, v sin φ0), tangent at φ0.
                let (v, r) = (CELL_COORD[j], ROW_RADIUS[j]);
                let (s, c) = (libm::sinf(phi), libm::cosf(phi));
                let m = Vec3::new(v * c, -(r + eps), v * s);
                if flip { -m } else { m }
            },
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]

        #[test]
        fn exact_equals_reference(m in normal()) {
            prop_assert_eq!(half_space_mask(m), half_space_mask_reference(m));
        }

        #[test]
        fn exact_equals_reference_on_ties(m in plane_through_a_cell()) {
            prop_assert_eq!(half_space_mask(m), half_space_mask_reference(m));
        }

        #[test]
        fn exact_equals_reference_near_horizon(m in near_horizon()) {
            prop_assert_eq!(half_space_mask(m), half_space_mask_reference(m));
        }

        #[test]
        fn exact_equals_reference_near_tangency(m in near_tangent()) {
            prop_assert_eq!(half_space_mask(m), half_space_mask_reference(m));
        }

        #[test]
        fn opposite_planes_cover_every_cell_and_share_only_ties(m in normal()) {
            let (pos, neg) = (half_space_mask(m), half_space_mask(-m));
            prop_assert_eq!(pos | neg, HemiMask::VALID);
            for (i, j) in (pos & neg).occluded_cells() {
                let d = crate::hemi::mask::cell_direction(i, j).unwrap();
                prop_assert!(m.x * d.x + m.y * d.y + m.z * d.z == 0.0);
            }
        }
    }

    #[test]
    fn special_planes() {
        assert_eq!(half_space_mask(Vec3::ZERO), HemiMask::VALID);
        assert_eq!(half_space_mask(Vec3::Z), HemiMask::VALID);
        assert_eq!(half_space_mask(-Vec3::Z), HemiMask::EMPTY);
        // The plane u = 0: no cell center lies on it, so the halves are i >= 16.
        let right = half_space_mask(Vec3::X);
        for (i, j, _) in cell_directions() {
            assert_eq!(right.get(i, j), i >= 16);
        }
        assert_eq!(right.count_occluded() * 2, VALID_CELL_COUNT);
        for m in [
            Vec3::new(f32::NAN, 0.0, 1.0),
            Vec3::new(f32::INFINITY, 1.0, 0.0),
            Vec3::splat(f32::NEG_INFINITY),
            Vec3::new(f32::MAX, f32::MAX, -f32::MAX),
            Vec3::new(1e-40, -1e-42, 1e-45),
        ] {
            // Whatever comes out, it comes out without a panic and within the disk.
            let mask = half_space_mask(m);
            assert_eq!(mask & HemiMask::VALID, mask);
        }
        for m in [
            Vec3::new(1e-40, -1e-42, 1e-45),
            Vec3::new(3e38, -2e38, 1e37),
            Vec3::new(f32::MAX, f32::MAX, -f32::MAX),
            Vec3::new(0.0, -1e-45, 0.0),
        ] {
            assert_eq!(
                half_space_mask(m),
                half_space_mask_reference(m),
                "m = {m:?}"
            );
        }
        // Power-of-two scaling changes nothing for ordinary normals.
        let m = Vec3::new(0.3, -0.7, 0.2);
        assert_eq!(
            half_space_mask_reference(m),
            half_space_mask_reference(m * 1024.0)
        );
        assert_eq!(
            normalize_exponent(m * libm::exp2f(-100.0)),
            normalize_exponent(m)
        );
        assert_eq!(normalize_exponent(-m), -normalize_exponent(m));
        assert_eq!(
            normalize_exponent(Vec3::new(0.0, 3.0, -1.0)),
            Vec3::new(0.0, 1.5, -0.5)
        );
    }

    #[test]
    fn dense_sweep_matches_reference() {
        // Planes through pairs of cell directions and their neighbours: ties and
        // near-ties everywhere on the grid.
        let dirs: alloc::vec::Vec<Vec3> = cell_directions().map(|(_, _, d)| d).collect();
        let mut checked = 0;
        for (k, &a) in dirs.iter().enumerate().step_by(7) {
            for &b in dirs.iter().skip(k % 5).step_by(13) {
                let m = a.cross(b);
                assert_eq!(
                    half_space_mask(m),
                    half_space_mask_reference(m),
                    "m = {m:?}"
                );
                assert_eq!(
                    half_space_mask(-m),
                    half_space_mask_reference(-m),
                    "m = {:?}",
                    -m
                );
                checked += 1;
            }
        }
        assert!(checked > 5000);
    }
}
