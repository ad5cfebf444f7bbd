//! The 32×32 hemispherical visibility mask and the geometry of its cells.
//!
//! The hemisphere above a receiver is flattened onto the unit disk by dropping the
//! normal component of each direction (the Nusselt analog: equal disk areas carry
//! equal cosine-weighted solid angle), and the square `[-1, 1]²` around the disk is
//! split into 32×32 cells (Kautz, Lehtinen and Aila 2004; Lehtinen's thesis §3.3).
//!
//! Invariants, fixed by the design (hemi.md) because external tools rebuild the
//! cell directions from them:
//!
//! - bit `i` of `rows[j]` is cell `(i, j)`, set = occluded;
//! - the center of cell `(i, j)` is `u = (i + 0.5)/16 - 1`, `v = (j + 0.5)/16 - 1`;
//! - a cell is valid when `u² + v² < 1` ([`HemiMask::VALID`], 812 cells), and invalid
//!   cells are always 0 in every mask this crate produces;
//! - the local direction of a valid cell is `(u, v, sqrt(1 - u² - v²))`, in the
//!   receiver frame `(t, b, n)` of [`Frame::from_normal`](crate::Frame::from_normal).
//!
//! Every coordinate above is exact in `f32` (`u = (2i - 31)/32`, and
//! `1 - u² - v² = (1024 - (2i-31)² - (2j-31)²)/1024`), so the only rounding in a cell
//! direction is the one correctly rounded square root, and the table below
//! reproduces `sqrtf` bit for bit.

use core::fmt;
use core::ops::{BitAnd, BitAndAssign, BitOr, BitOrAssign, BitXor};

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

/// Cells per side of the mask (and bits per row).
pub const GRID: usize = 32;

/// Number of valid cells (those whose center lies inside the unit disk).
pub const VALID_CELL_COUNT: u32 = count_valid();

/// A 32×32 bit mask over the hemisphere of a receiver: bit `i` of `rows[j]` is
/// cell `(i, j)`, set when the cell's direction is occluded.
///
/// Cell `(i, j)` has its center at `u = (i + 0.5)/16 - 1`, `v = (j + 0.5)/16 - 1` on
/// the disk, is valid when `u² + v² < 1`, and then stands for the local direction
/// `(u, v, sqrt(1 - u² - v²))` (see [`cell_direction`]); invalid cells are 0. The
/// layout is `#[repr(C)]` and [`Pod`]: 128 bytes, rows in order, so the C ABI and
/// external tools read it as 32 little- or native-endian `uint32_t`.
#[repr(C)]
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default, Pod, Zeroable)]
pub struct HemiMask {
    /// Row `j` of cells; bit `i` is cell `(i, j)`.
    pub rows: [u32; GRID],
}

impl HemiMask {
    /// No cell occluded.
    pub const EMPTY: HemiMask = HemiMask { rows: [0; GRID] };

    /// Every valid cell occluded: the cells whose centers satisfy `u² + v² < 1`.
    pub const VALID: HemiMask = HemiMask { rows: valid_rows() };

    /// The row bits of columns `first..=last` (`first <= last < 32`; other
    /// arguments give some bits, without overflow).
    #[inline(always)]
    pub(crate) fn columns(first: usize, last: usize) -> u32 {
        ((2u64 << (last & 31)).wrapping_sub(1u64 << (first & 31))) as u32
    }

    /// Whether every valid cell of the inclusive box `(i0, i1, j0, j1)` (inside
    /// the grid) is set: a cone whose cells lie in the box then adds nothing.
    #[inline]
    pub(crate) fn box_is_full(&self, (i0, i1, j0, j1): (usize, usize, usize, usize)) -> bool {
        let columns = HemiMask::columns(i0, i1);
        (j0..=j1).all(|j| {
            let wanted = columns & HemiMask::VALID.rows[j];
            self.rows[j] & wanted == wanted
        })
    }

    /// Whether cell `(i, j)` is set; `false` outside the grid.
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> bool {
        i < GRID && j < GRID && self.rows[j] >> i & 1 == 1
    }

    /// Sets or clears cell `(i, j)`. Invalid cells and cells outside the grid are
    /// left at 0, so the mask keeps the "invalid cells are 0" invariant.
    #[inline]
    pub fn set(&mut self, i: usize, j: usize, occluded: bool) {
        if !is_valid_cell(i, j) {
            return;
        }
        if occluded {
            self.rows[j] |= 1 << i;
        } else {
            self.rows[j] &= !(1 << i);
        }
    }

    /// Number of set (occluded) cells.
    #[inline]
    pub fn count_occluded(&self) -> u32 {
        self.rows.iter().map(|r| r.count_ones()).sum()
    }

    /// Number of valid cells that are not set, assuming the invariant that invalid
    /// cells are 0.
    #[inline]
    pub fn count_unoccluded(&self) -> u32 {
        (*self ^ Self::VALID).count_occluded()
    }

    /// Number of cells where `self` and `other` differ.
    #[inline]
    pub fn count_differences(&self, other: &HemiMask) -> u32 {
        (*self ^ *other).count_occluded()
    }

    /// Whether no cell is set.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.rows.iter().all(|&r| r == 0)
    }

    /// The valid cells not set in `self`: `VALID & !self`.
    #[inline]
    pub fn complement(&self) -> HemiMask {
        let mut out = *self;
        for (row, valid) in out.rows.iter_mut().zip(Self::VALID.rows) {
            *row = !*row & valid;
        }
        out
    }

    /// The set cells as `(i, j)`, row by row.
    pub fn occluded_cells(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..GRID).flat_map(move |j| {
            let row = self.rows[j];
            (0..GRID)
                .filter(move |&i| row >> i & 1 == 1)
                .map(move |i| (i, j))
        })
    }
}

impl BitOr for HemiMask {
    type Output = HemiMask;
    #[inline]
    fn bitor(mut self, rhs: HemiMask) -> HemiMask {
        self |= rhs;
        self
    }
}

impl BitOrAssign for HemiMask {
    #[inline]
    fn bitor_assign(&mut self, rhs: HemiMask) {
        for (a, b) in self.rows.iter_mut().zip(rhs.rows) {
            *a |= b;
        }
    }
}

impl BitAnd for HemiMask {
    type Output = HemiMask;
    #[inline]
    fn bitand(mut self, rhs: HemiMask) -> HemiMask {
        self &= rhs;
        self
    }
}

impl BitAndAssign for HemiMask {
    #[inline]
    fn bitand_assign(&mut self, rhs: HemiMask) {
        for (a, b) in self.rows.iter_mut().zip(rhs.rows) {
            *a &= b;
        }
    }
}

impl BitXor for HemiMask {
    type Output = HemiMask;
    #[inline]
    fn bitxor(mut self, rhs: HemiMask) -> HemiMask {
        for (a, b) in self.rows.iter_mut().zip(rhs.rows) {
            *a ^= b;
        }
        self
    }
}

/// One line per row, `j = 31` (v near +1) first so the picture is upright:
/// `#` occluded, `.` free, blank outside the disk.
impl fmt::Display for HemiMask {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for j in (0..GRID).rev() {
            for i in 0..GRID {
                let c = if !is_valid_cell(i, j) {
                    ' '
                } else if self.get(i, j) {
                    '#'
                } else {
                    '.'
                };
                write!(f, "{c}")?;
            }
            writeln!(f)?;
        }
        Ok(())
    }
}

impl fmt::Debug for HemiMask {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "HemiMask({} occluded of {VALID_CELL_COUNT})\n{self}",
            self.count_occluded()
        )
    }
}

/// The disk coordinate of column (or row) `k`: `(k + 0.5)/16 - 1`, exactly.
#[inline]
pub fn cell_coordinate(k: usize) -> f32 {
    (k as f32 + 0.5) / 16.0 - 1.0
}

/// Whether cell `(i, j)` is inside the grid and its center inside the unit disk.
#[inline]
pub fn is_valid_cell(i: usize, j: usize) -> bool {
    HemiMask::VALID.get(i, j)
}

/// The local direction `(u, v, sqrt(1 - u² - v²))` of valid cell `(i, j)`, unit
/// length up to one rounding of the square root; `None` for invalid cells.
///
/// Map it to world space with [`Frame::to_world`](crate::Frame::to_world) of the
/// receiver's frame: `u * t + v * b + sqrt(1 - u² - v²) * n`.
#[inline]
pub fn cell_direction(i: usize, j: usize) -> Option<Vec3> {
    is_valid_cell(i, j).then(|| Vec3::new(CELL_COORD[i], CELL_COORD[j], CELL_Z[j][i]))
}

/// Every valid cell with its local direction, row by row (`j` outer, `i` inner).
pub fn cell_directions() -> impl Iterator<Item = (usize, usize, Vec3)> {
    (0..GRID).flat_map(|j| (0..GRID).filter_map(move |i| cell_direction(i, j).map(|d| (i, j, d))))
}

// --- Tables, all built at compile time from integers so they are exact. ---

/// `CELL_COORD[k] = (k + 0.5)/16 - 1 = (2k - 31)/32`.
pub(crate) const CELL_COORD: [f32; GRID] = {
    let mut out = [0.0; GRID];
    let mut k = 0;
    while k < GRID {
        out[k] = (2 * k as i32 - 31) as f32 / 32.0;
        k += 1;
    }
    out
};

/// `CELL_Z[j][i] = sqrt(1 - u² - v²)` for valid cells (correctly rounded, equal to
/// `sqrtf` of the exact argument), 0 for invalid ones.
pub(crate) const CELL_Z: [[f32; GRID]; GRID] = {
    let mut out = [[0.0; GRID]; GRID];
    let mut j = 0;
    while j < GRID {
        let mut i = 0;
        while i < GRID {
            let n = 1024 - odd_square(i) - odd_square(j);
            if n > 0 {
                // sqrt(n / 1024) = sqrt(n) / 32, and dividing by 32 is exact.
                out[j][i] = sqrt_of_integer(n as u64) / 32.0;
            }
            i += 1;
        }
        j += 1;
    }
    out
};

/// `ROW_RADIUS_SQ[j] = 1 - v_j²`, exact: the squared half-width of row `j`'s chord.
pub(crate) const ROW_RADIUS_SQ: [f32; GRID] = {
    let mut out = [0.0; GRID];
    let mut j = 0;
    while j < GRID {
        out[j] = (1024 - odd_square(j)) as f32 / 1024.0;
        j += 1;
    }
    out
};

/// `ROW_RADIUS[j] = sqrt(1 - v_j²)`, correctly rounded.
pub(crate) const ROW_RADIUS: [f32; GRID] = {
    let mut out = [0.0; GRID];
    let mut j = 0;
    while j < GRID {
        out[j] = sqrt_of_integer((1024 - odd_square(j)) as u64) / 32.0;
        j += 1;
    }
    out
};

/// First valid column of each row.
pub(crate) const ROW_FIRST: [u8; GRID] = {
    let rows = valid_rows();
    let mut out = [0; GRID];
    let mut j = 0;
    while j < GRID {
        out[j] = rows[j].trailing_zeros() as u8;
        j += 1;
    }
    out
};

/// Last valid column of each row.
pub(crate) const ROW_LAST: [u8; GRID] = {
    let rows = valid_rows();
    let mut out = [0; GRID];
    let mut j = 0;
    while j < GRID {
        out[j] = (31 - rows[j].leading_zeros()) as u8;
        j += 1;
    }
    out
};

/// `(2k - 31)²`: 1024 times the squared disk coordinate of column `k`.
const fn odd_square(k: usize) -> i32 {
    let a = 2 * k as i32 - 31;
    a * a
}

const fn valid_rows() -> [u32; GRID] {
    let mut rows = [0; GRID];
    let mut j = 0;
    while j < GRID {
        let mut i = 0;
        while i < GRID {
            // u² + v² < 1, multiplied by 1024: integers, so no rounding question.
            if odd_square(i) + odd_square(j) < 1024 {
                rows[j] |= 1 << i;
            }
            i += 1;
        }
        j += 1;
    }
    rows
}

const fn count_valid() -> u32 {
    let rows = valid_rows();
    let mut n = 0;
    let mut j = 0;
    while j < GRID {
        n += rows[j].count_ones();
        j += 1;
    }
    n
}

/// The `f32` nearest to `sqrt(n)` for `1 <= n < 2^24`, by integer arithmetic, so it
/// can run at compile time and is correctly rounded by construction.
const fn sqrt_of_integer(n: u64) -> f32 {
    // sqrt(n) lies in [2^e, 2^(e+1)); its f32 is m * 2^(e - 23) with m in
    // [2^23, 2^24], and m = round(sqrt(n * 2^(46 - 2e))).
    let e = (63 - n.leading_zeros()) / 2;
    let x = n << (46 - 2 * e);
    let s = x.isqrt();
    // Round to nearest: sqrt(x) >= s + 1/2 iff x >= s² + s + 1/4, i.e. x > s² + s
    // for integers; a tie cannot happen.
    let m = if x > s * s + s { s + 1 } else { s };
    // m < 2^25 is exact in f32, and scaling by a power of two is exact.
    let mut value = m as f32;
    let mut k = 0;
    while k < 23 - e {
        value /= 2.0;
        k += 1;
    }
    value
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_is_full_when_each_valid_cell_in_it_is_set() {
        let boxes = [
            (0, 31, 0, 31),
            (3, 9, 1, 4),
            (14, 17, 14, 17),
            (30, 31, 12, 19),
            (5, 5, 7, 7),
        ];
        for (i0, i1, j0, j1) in boxes {
            // The reference: every valid cell of the box, one by one.
            let full = |mask: &HemiMask| {
                (j0..=j1).all(|j| (i0..=i1).all(|i| !is_valid_cell(i, j) || mask.get(i, j)))
            };
            let mut mask = HemiMask::EMPTY;
            for j in j0..=j1 {
                for i in i0..=i1 {
                    mask.set(i, j, true);
                }
            }
            assert!(mask.box_is_full((i0, i1, j0, j1)) && full(&mask));
            assert!(HemiMask::VALID.box_is_full((i0, i1, j0, j1)));
            // Clearing any valid cell of the box empties it.
            for j in j0..=j1 {
                for i in (i0..=i1).filter(|&i| is_valid_cell(i, j)) {
                    let mut holed = mask;
                    holed.set(i, j, false);
                    assert!(!holed.box_is_full((i0, i1, j0, j1)) && !full(&holed));
                }
            }
        }
    }

    #[test]
    fn valid_cells_are_the_disk() {
        assert_eq!(VALID_CELL_COUNT, 812);
        for j in 0..GRID {
            for (i, &coordinate) in CELL_COORD.iter().enumerate() {
                let (u, v) = (cell_coordinate(i), cell_coordinate(j));
                assert_eq!(is_valid_cell(i, j), u * u + v * v < 1.0, "cell ({i}, {j})");
                assert_eq!(coordinate, u);
            }
            let row = HemiMask::VALID.rows[j];
            let (first, last) = (ROW_FIRST[j] as u32, ROW_LAST[j] as u32);
            // Each row's valid cells are one contiguous run, symmetric about the middle.
            assert_eq!(first + last, 31);
            assert_eq!(
                row,
                (((1u64 << (last + 1)) - 1) as u32) & !((1u32 << first) - 1)
            );
        }
        assert!(!is_valid_cell(32, 0) && !is_valid_cell(0, 0));
    }

    #[test]
    fn directions_match_the_documented_formula_bit_for_bit() {
        let mut n = 0;
        for (i, j, d) in cell_directions() {
            let u = (i as f32 + 0.5) / 16.0 - 1.0;
            let v = (j as f32 + 0.5) / 16.0 - 1.0;
            let z = libm::sqrtf(1.0 - u * u - v * v);
            assert_eq!(d, Vec3::new(u, v, z), "cell ({i}, {j})");
            assert!((d.length() - 1.0).abs() < 1e-6);
            n += 1;
        }
        assert_eq!(n, VALID_CELL_COUNT);
        for (j, (&r2, &r)) in ROW_RADIUS_SQ.iter().zip(&ROW_RADIUS).enumerate() {
            let v = cell_coordinate(j);
            assert_eq!(r2, 1.0 - v * v);
            assert_eq!(r, libm::sqrtf(1.0 - v * v));
        }
        assert_eq!(cell_direction(0, 0), None);
    }

    #[test]
    fn sqrt_of_integer_is_correctly_rounded() {
        for n in (1..5000u64).chain([1 << 20, (1 << 24) - 1]) {
            assert_eq!(sqrt_of_integer(n), libm::sqrtf(n as f32), "sqrt({n})");
        }
    }

    #[test]
    fn set_get_count_and_set_operations() {
        let mut m = HemiMask::EMPTY;
        assert!(m.is_empty());
        m.set(16, 16, true);
        m.set(0, 0, true); // invalid: ignored
        m.set(40, 3, true); // outside: ignored
        assert!(m.get(16, 16) && !m.get(0, 0));
        assert_eq!(m.count_occluded(), 1);
        assert_eq!(m.count_unoccluded(), VALID_CELL_COUNT - 1);
        assert_eq!(m.complement().count_occluded(), VALID_CELL_COUNT - 1);
        assert_eq!(m | m.complement(), HemiMask::VALID);
        assert_eq!(m & m.complement(), HemiMask::EMPTY);
        assert_eq!(m.count_differences(&HemiMask::VALID), VALID_CELL_COUNT - 1);
        assert_eq!(
            m.occluded_cells().collect::<alloc::vec::Vec<_>>(),
            [(16, 16)]
        );
        m.set(16, 16, false);
        assert!(m.is_empty());
        assert_eq!(core::mem::size_of::<HemiMask>(), 128);
        let bytes: &[u8] = bytemuck::bytes_of(&HemiMask::VALID);
        assert_eq!(bytes.len(), 128);
    }

    #[test]
    fn display_draws_the_disk() {
        let text = alloc::format!("{}", HemiMask::VALID.complement());
        assert_eq!(text.lines().count(), 32);
        assert_eq!(text.matches('.').count(), VALID_CELL_COUNT as usize);
    }
}
