//! The cells a box of occluders can reach: the occlusion test of the
//! per-receiver traversal (after Laine and Karras 2010, method 2). Every cell
//! that a triangle inside an axis-aligned box sets has its center direction
//! pointing into the box, so a box whose reachable cells are all set already
//! (or that holds no cell center at all) can be skipped whole: the mask, an
//! OR over triangles, is the same with or without its triangles.
//!
//! The cells are a rectangle of the grid, bounded from the disk coordinates
//! `u = x / |q|`, `v = y / |q|` of the box's points `q` in the receiver's
//! frame: with `x` in `[x0, x1]` and `|q|` in `[d_near, d_far]`, `u` is at
//! most `x1 / d_near` (`x1 / d_far` when `x1 < 0`) and at least `x0 / d_near`
//! (`x0 / d_far` when `x0 > 0`). The frame's corners come from the same `f32`
//! expressions the rasterizers use, evaluated at the box corner that
//! maximises (or minimises) each: those are monotone in every coordinate, so
//! they bound every vertex's local coordinates as the rasterizers compute
//! them. The rest is widened by a margin far above `f32` rounding and far
//! below a cell (a cell is `1/16` of the disk's radius wide).

use glam::{Vec3, Vec3A, Vec4};

use super::clusters::Aabb;
use super::mask::{CELL_COORD, CELL_Z, HemiMask};
use crate::geom::{Frame, sqrt4};

/// Widening of the box's local coordinates, relative to their largest
/// magnitude (`f32` rounding of the corners' transforms is below `1e-6`).
const LOCAL_SLACK: f32 = 1e-5;

/// Widening of the disk-coordinate bounds, in cells.
const CELL_SLACK: f32 = 0.01;

/// Widening of the bounds of the elevation `z / |q|` and of the squared disk
/// radius `1 - (z / |q|)²`.
const RING_SLACK: f32 = 1e-3;

/// What a box of occluders can still add to a receiver's mask.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum BoxCells {
    /// The box is close to the center of projection: any cell.
    Any,
    /// No cell center points into the box.
    None,
    /// Every cell whose center points into the box is in the inclusive
    /// rectangle `(i0, i1, j0, j1)` of the grid and has its squared disk
    /// radius `u² + v²` in `[ring.0, ring.1]`: the elevation of the box's
    /// points bounds how far from the disk's center they project.
    Cells {
        rect: (usize, usize, usize, usize),
        ring: (f32, f32),
    },
}

impl BoxCells {
    /// The cells the points of `bounds` can be seen in from `origin`, with
    /// `frame` the (scaled) frame the rasterizers move `q - origin` into.
    #[inline(always)]
    pub(crate) fn of(bounds: &Aabb, frame: &Frame, origin: Vec3) -> BoxCells {
        let (lo, hi) = (bounds.min - origin, bounds.max - origin);
        // The same expression as Frame::to_local, at the corners bounding it,
        // for the three axes at once (lanes x, y, z: tangent, bitangent,
        // normal): `x·x' + y·y' + z·z'` in that order, each product with the
        // corner's coordinate that minimises (maximises) it.
        let (t, b, n) = (frame.tangent, frame.bitangent, frame.normal);
        let mut low = Vec3A::ZERO;
        let mut high = Vec3A::ZERO;
        for (axes, l, h) in [
            (Vec3A::new(t.x, b.x, n.x), lo.x, hi.x),
            (Vec3A::new(t.y, b.y, n.y), lo.y, hi.y),
            (Vec3A::new(t.z, b.z, n.z), lo.z, hi.z),
        ] {
            let up = axes.cmpge(Vec3A::ZERO);
            let (l, h) = (Vec3A::splat(l), Vec3A::splat(h));
            low += axes * Vec3A::select(up, l, h);
            high += axes * Vec3A::select(up, h, l);
        }
        let slack = Vec3A::splat(LOCAL_SLACK * low.abs().max(high.abs()).max_element());
        let (low, high) = (low - slack, high + slack);
        let nearest = low.max(Vec3A::ZERO).min(high);
        let farthest = low.abs().max(high.abs());
        let (near_sq, far_sq) = (nearest.length_squared(), farthest.length_squared());
        // Not `>` for NaN too: a box this close sees every direction, and so
        // does one whose bounds are not finite.
        let close = near_sq.partial_cmp(&(1e-6 * far_sq)) != Some(core::cmp::Ordering::Greater);
        if close || !far_sq.is_finite() || !(low.is_finite() && high.is_finite()) {
            return BoxCells::Any;
        }
        let roots = sqrt4(Vec4::new(near_sq, far_sq, near_sq, far_sq));
        let (near, far) = (Vec3A::splat(roots.x), Vec3A::splat(roots.y));
        // The bounds of the disk coordinates and elevation: a positive upper
        // coordinate over the nearest distance, a negative one over the
        // farthest (and the reverse for lower ones).
        let upper = high / Vec3A::select(high.cmpge(Vec3A::ZERO), near, far);
        let lower = low / Vec3A::select(low.cmple(Vec3A::ZERO), near, far);
        // Cell k's center is at (2k - 31) / 32, so centers in [a, b] are
        // k in [16 a + 15.5, 16 b + 15.5].
        let cells = |l: f32, h: f32| {
            let first = ceil_clamped(l * 16.0 + 15.5 - CELL_SLACK);
            let last = floor_clamped(h * 16.0 + 15.5 + CELL_SLACK);
            (first, last)
        };
        let (i0, i1) = cells(lower.x, upper.x);
        let (j0, j1) = cells(lower.y, upper.y);
        // A cell center (u, v, w) has u² + v² = 1 - w², and its elevation w
        // is the box point's z / |q|.
        let (w0, w1) = (
            (lower.z - RING_SLACK).clamp(0.0, 1.0),
            (upper.z + RING_SLACK).clamp(0.0, 1.0),
        );
        let ring = (1.0 - w1 * w1 - RING_SLACK, 1.0 - w0 * w0 + RING_SLACK);
        let no_ring = ring.1.partial_cmp(&ring.0).is_none_or(|o| o.is_lt());
        if i0 > i1 || j0 > j1 || no_ring {
            return BoxCells::None;
        }
        BoxCells::Cells {
            rect: (i0 as usize, i1 as usize, j0 as usize, j1 as usize),
            ring,
        }
    }

    /// Whether cell `(i, j)` may be set by a triangle in the box (one cell
    /// at a time: the definition [`BoxCells::can_add_to`] and
    /// [`BoxCells::open_cells`] are tested against).
    #[cfg(test)]
    fn reaches(self, i: usize, j: usize) -> bool {
        match self {
            BoxCells::Any => true,
            BoxCells::None => false,
            BoxCells::Cells {
                rect: (i0, i1, j0, j1),
                ring: (r0, r1),
            } => {
                let (u, v) = (CELL_COORD[i], CELL_COORD[j]);
                let r2 = u * u + v * v;
                (i0..=i1).contains(&i) && (j0..=j1).contains(&j) && r0 <= r2 && r2 <= r1
            }
        }
    }

    /// The cells triangles in the box can still set in `mask`, when there
    /// are at most `N` (reached as `BoxCells::can_add_to` bounds them, so
    /// a few more than `BoxCells::reaches` may be listed, valid and clear);
    /// `None` when there are more, or the box is close enough to reach any
    /// cell. Few cells are cheaper to test one by one against the box's
    /// triangles than the triangles are to rasterize.
    #[inline(always)]
    pub(crate) fn open_cells<const N: usize>(self, mask: &HemiMask) -> Option<OpenCells<N>> {
        let mut open = OpenCells {
            cells: [(0, 0); N],
            len: 0,
        };
        let BoxCells::Cells {
            rect: (i0, i1, j0, j1),
            ring,
        } = self
        else {
            return (self == BoxCells::None).then_some(open);
        };
        let rect = HemiMask::columns(i0, i1);
        let band = RingBand::new(ring);
        for j in j0..=j1 {
            let clear = rect & HemiMask::VALID.rows[j] & !mask.rows[j];
            if clear == 0 {
                continue;
            }
            let mut row = clear & band.row(j);
            if open.len + row.count_ones() as usize > N {
                return None;
            }
            while row != 0 {
                let i = row.trailing_zeros() as usize;
                row &= row - 1;
                open.cells[open.len] = (i as u8, j as u8);
                open.len += 1;
            }
        }
        Some(open)
    }

    /// Whether triangles in the box can still set a cell of `mask`: a valid
    /// cell it reaches is clear (the row-wise bound [`BoxCells::open_cells`]
    /// lists, tested against [`BoxCells::reaches`]).
    #[cfg(test)]
    fn can_add_to(self, mask: &HemiMask) -> bool {
        let BoxCells::Cells {
            rect: (i0, i1, j0, j1),
            ring,
        } = self
        else {
            return self == BoxCells::Any;
        };
        let rect = HemiMask::columns(i0, i1);
        let band = RingBand::new(ring);
        (j0..=j1).any(|j| {
            let open = rect & HemiMask::VALID.rows[j] & !mask.rows[j];
            open != 0 && open & band.row(j) != 0
        })
    }
}

/// `ceil(x)` clamped to `[0, 33]` (NaN to 0, reaching every column), with
/// no call into `libm`.
#[inline(always)]
fn ceil_clamped(x: f32) -> f32 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 33.0) };
    ceil_by_truncation(x).max(0) as f32
}

/// `floor(x)` clamped to `[-2, 31]` (NaN to 31, reaching every column).
#[inline(always)]
fn floor_clamped(x: f32) -> f32 {
    let x = if x.is_nan() {
        31.0
    } else {
        x.clamp(-2.0, 32.0)
    };
    floor_by_truncation(x).min(31) as f32
}

/// `ceil(x)` for finite `x` well inside the range of `i32`: truncation
/// toward zero, then one comparison (exact).
#[inline(always)]
fn ceil_by_truncation(x: f32) -> i32 {
    let t = x as i32;
    t + i32::from((t as f32) < x)
}

/// `floor(x)` for finite `x` well inside the range of `i32`.
#[inline(always)]
fn floor_by_truncation(x: f32) -> i32 {
    let t = x as i32;
    t - i32::from((t as f32) > x)
}

/// Row `j`'s columns whose centers have their squared disk radius `u² + v²`
/// in `ring`, and those within [`RING_UNITS`] of it ([`RingBand::row`]).
#[cfg(test)]
fn ring_band(j: usize, ring: (f32, f32)) -> u32 {
    RingBand::new(ring).row(j)
}

/// A ring of squared disk radii as integer bounds on the rows' cells. A
/// cell center's squared radius is `((2i - 31)² + (2j - 31)²) / 1024`
/// exactly, so each row's band comes from integers and a table instead of
/// square roots; the ring's own conversions are made once per box, since the
/// walk asks for the band on every row of every box it lists.
#[derive(Clone, Copy)]
struct RingBand {
    /// `1024` times the outer squared radius, rounded down, plus
    /// [`RING_UNITS`]; `i32::MIN` when the ring bounds nothing in (a NaN or
    /// negative outer radius).
    outer: i32,
    /// `1024` times the inner squared radius, rounded up, less
    /// [`RING_UNITS`]; `i32::MIN` when the ring has no inside to leave out.
    inner: i32,
}

impl RingBand {
    #[inline(always)]
    fn new((r0, r1): (f32, f32)) -> RingBand {
        let high = r1 * 1024.0;
        // A NaN outer radius bounds nothing in.
        let outer = if high.is_nan() || high < 0.0 {
            i32::MIN
        } else {
            floor_by_truncation(high.min(4096.0)) + RING_UNITS
        };
        let low = r0 * 1024.0;
        let inner = if low > 0.0 {
            ceil_by_truncation(low.min(4096.0)) - RING_UNITS
        } else {
            i32::MIN
        };
        RingBand { outer, inner }
    }

    /// Row `j`'s columns in the band.
    #[inline(always)]
    fn row(self, j: usize) -> u32 {
        let row = ROW_SQUARE[j];
        // Saturating: the sentinel stays below 1.
        let outer = self.outer.saturating_sub(row);
        if outer < 1 {
            return 0;
        }
        let mut band = centered_columns(ODD_SQUARES_WITHIN[outer.min(961) as usize]);
        // Columns with (2i - 31)² below this are strictly inside the ring.
        let inner = self.inner.saturating_sub(row);
        if inner > 1 {
            band &= !centered_columns(ODD_SQUARES_WITHIN[(inner - 1).min(961) as usize]);
        }
        band
    }
}

/// The widening of [`RingBand`], in units of `1/1024` of the squared disk
/// radius: a hundredth of a cell ([`CELL_SLACK`]) moves `u²` by at most
/// `2 · 0.01 / 16 = 1.25` units.
const RING_UNITS: i32 = 2;

/// `(2j - 31)²` for row `j`: `1024 v²` of its centers.
const ROW_SQUARE: [i32; 32] = {
    let mut squares = [0; 32];
    let mut j = 0;
    while j < 32 {
        let m = 2 * j as i32 - 31;
        squares[j] = m * m;
        j += 1;
    }
    squares
};

/// How many of the odd numbers `1, 3, …, 31` (the column offsets
/// `|2i - 31|`) have their square at most the index.
const ODD_SQUARES_WITHIN: [u8; 962] = {
    let mut within = [0; 962];
    let mut x = 0;
    while x < 962 {
        let mut count = 0;
        while count < 16 && (2 * count + 1) * (2 * count + 1) <= x {
            count += 1;
        }
        within[x] = count as u8;
        x += 1;
    }
    within
};

/// The `2c` columns nearest the disk's center, `16 - c..=15 + c`, as row bits.
#[inline(always)]
fn centered_columns(c: u8) -> u32 {
    let c = u32::from(c);
    (((1u64 << (2 * c)) - 1) << (16 - c)) as u32
}

/// At most `N` cells of the grid, as (column, row).
#[derive(Clone, Copy, Debug)]
pub(crate) struct OpenCells<const N: usize> {
    cells: [(u8, u8); N],
    len: usize,
}

impl<const N: usize> OpenCells<N> {
    /// The cells, in row order and left to right within a row.
    #[inline(always)]
    pub(crate) fn as_slice(&self) -> &[(u8, u8)] {
        &self.cells[..self.len]
    }
}

/// A cell with the inverse of its center direction in world axes, for the
/// slab test of [`RayCells::meet_into`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayCell {
    /// Column.
    pub(crate) i: u8,
    /// Row.
    pub(crate) j: u8,
    /// `1 / d` per axis for the center direction `d` in world axes (`±inf`
    /// for a zero component).
    inverse: Vec3,
}

impl RayCell {
    /// Cell `(i, j)` without its ray, for tests of what uses only the cell.
    #[cfg(test)]
    pub(crate) fn at(i: u8, j: u8) -> RayCell {
        RayCell {
            i,
            j,
            inverse: Vec3::ZERO,
        }
    }

    /// Whether the cell's center ray meets `padded`: the slow twin of
    /// [`RaysFour::meet`].
    #[cfg(test)]
    fn meets(&self, padded: &PaddedBox) -> bool {
        // The slabs' parameter intervals. An axis with a zero direction
        // component and the origin on a face multiplies 0 by infinity: NaN.
        // Vec3's min and max take the second operand when the comparison
        // fails, so the ray then reads as met (NaN bounds compare false) or
        // as running along the padded face, outside the box by the pad:
        // either way no triangle inside the box is missed.
        let (t0, t1) = (padded.lo * self.inverse, padded.hi * self.inverse);
        let near = t0.min(t1).max_element();
        let far = t0.max(t1).min_element();
        // Not `near > far` or `far < 0` (NaN included): met.
        !(near > far || far < 0.0)
    }
}

/// Four cells' center rays as lanes (their inverse directions, one vector
/// per axis), tested against a box at once: a cluster's spans and a node's
/// children test the same few rays against many boxes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RaysFour {
    inverse: [Vec4; 3],
    /// A bit per lane holding one of the rays given.
    used: u32,
}

impl RaysFour {
    /// No ray: lanes not yet written.
    pub(crate) const EMPTY: RaysFour = RaysFour {
        inverse: [Vec4::ZERO; 3],
        used: 0,
    };

    /// The rays of `cells`, one to four of them (missing lanes repeat the
    /// first; [`RaysFour::meet`] leaves their bits out).
    #[inline(always)]
    pub(crate) fn new(cells: &[RayCell]) -> RaysFour {
        let last = cells.len() - 1;
        let lane = |k: usize| cells[k.min(last)].inverse;
        let (a, b, c, d) = (lane(0), lane(1), lane(2), lane(3));
        RaysFour {
            inverse: [
                Vec4::new(a.x, b.x, c.x, d.x),
                Vec4::new(a.y, b.y, c.y, d.y),
                Vec4::new(a.z, b.z, c.z, d.z),
            ],
            used: (1 << cells.len().min(4)) - 1,
        }
    }

    /// Bit `k` set when ray `k` meets `padded`, for the rays given:
    /// lane by lane the expressions of [`RayCell::meets`]. Vec3's `min` and
    /// `max` take their second operand unless the first compares smaller
    /// (larger), as the vector instructions do, so a NaN lane gives the same
    /// verdict.
    #[inline(always)]
    pub(crate) fn meet(&self, padded: &PaddedBox) -> u32 {
        let slab = |axis: usize, lo: f32, hi: f32| {
            let inverse = self.inverse[axis];
            let (t0, t1) = (Vec4::splat(lo) * inverse, Vec4::splat(hi) * inverse);
            (t0.min(t1), t0.max(t1))
        };
        let (near_x, far_x) = slab(0, padded.lo.x, padded.hi.x);
        let (near_y, far_y) = slab(1, padded.lo.y, padded.hi.y);
        let (near_z, far_z) = slab(2, padded.lo.z, padded.hi.z);
        // `max_element` and `min_element` of Vec3: x against (y against z).
        let near = near_x.max(near_y.max(near_z));
        let far = far_x.min(far_y.min(far_z));
        let missed = near.cmpgt(far) | far.cmplt(Vec4::ZERO);
        !missed.bitmask() & self.used
    }
}

/// A box widened by a pad on every side ([`ray_pad`]), relative to the
/// center of projection: what [`RayCell::meets`] tests.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PaddedBox {
    lo: Vec3,
    hi: Vec3,
}

impl PaddedBox {
    /// `bounds` widened by `pad`, relative to `origin`: moved first, then
    /// widened, so that the pad (a small fraction of the box's distance) is
    /// not lost to the rounding of world coordinates far larger than it.
    #[inline(always)]
    pub(crate) fn new(bounds: &Aabb, origin: Vec3, pad: f32) -> PaddedBox {
        PaddedBox {
            lo: (bounds.min - origin) - pad,
            hi: (bounds.max - origin) + pad,
        }
    }
}

/// At most `N` cells whose center rays a box met: the open cells of a node,
/// which its children test again (a child's box is inside its parent's, so
/// the rays meeting it are among its parent's).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayCells<const N: usize> {
    cells: [RayCell; N],
    len: usize,
}

impl<const N: usize> RayCells<N> {
    /// No cell.
    pub(crate) const EMPTY: RayCells<N> = RayCells {
        cells: [RayCell {
            i: 0,
            j: 0,
            inverse: Vec3::ZERO,
        }; N],
        len: 0,
    };

    /// Makes this list the cells of `open` with their rays from the center of projection,
    /// `frame` the (scaled) frame the rasterizers use: the center direction
    /// in world axes is `frame`'s axes weighted by the cell's `(u, v, z)`
    /// (the frame's scale does not move where a ray meets a box).
    #[inline(always)]
    pub(crate) fn set_from(&mut self, open: &OpenCells<N>, frame: &Frame) {
        for (ray, &(i, j)) in self.cells.iter_mut().zip(open.as_slice()) {
            let (iu, ju) = (usize::from(i), usize::from(j));
            let d = frame.to_world(Vec3::new(CELL_COORD[iu], CELL_COORD[ju], CELL_Z[ju][iu]));
            *ray = RayCell {
                i,
                j,
                inverse: d.recip(),
            };
        }
        self.len = open.len;
    }

    /// Writes into `out` the cells still clear in `mask` whose center rays
    /// from `origin` meet `bounds` widened by `pad` on every side
    /// ([`ray_pad`]); returns how many. A triangle inside the box sets only
    /// cells whose center direction points into it (within the predicate's
    /// rounding, far below the pad); the rectangle of [`BoxCells::of`] holds
    /// about seven times the cells whose rays meet a small box.
    #[inline(always)]
    pub(crate) fn meet_into(
        &self,
        bounds: &Aabb,
        origin: Vec3,
        pad: f32,
        mask: &HemiMask,
        out: &mut Self,
    ) -> usize {
        let padded = PaddedBox::new(bounds, origin, pad);
        let mut kept = 0;
        for four in self.as_slice().chunks(4) {
            let met = RaysFour::new(four).meet(&padded);
            for (k, ray) in four.iter().enumerate() {
                let clear = mask.rows[usize::from(ray.j)] >> ray.i & 1 == 0;
                out.cells[kept] = *ray;
                kept += usize::from((met >> k & 1 == 1) & clear);
            }
        }
        out.len = kept;
        kept
    }

    /// [`RayCells::meet_into`] a new list.
    #[cfg(test)]
    fn meeting(&self, bounds: &Aabb, origin: Vec3, pad: f32, mask: &HemiMask) -> Self {
        let mut out = Self::EMPTY;
        self.meet_into(bounds, origin, pad, mask, &mut out);
        out
    }

    /// Makes this list a copy of `other` (only its cells are copied).
    #[inline(always)]
    pub(crate) fn copy_from(&mut self, other: &Self) {
        self.cells[..other.len].copy_from_slice(other.as_slice());
        self.len = other.len;
    }

    /// The cells, in the order given.
    #[inline(always)]
    pub(crate) fn as_slice(&self) -> &[RayCell] {
        &self.cells[..self.len]
    }
}

/// The widening of `bounds` for [`RayCells::meet_into`]: [`RAY_SLACK`] times
/// the sum of the farthest corner's offsets from `origin` along the axes (at
/// least its distance, at most √3 times it, without a square root that
/// could overflow or underflow), so every point of the box gets at least the
/// slack times its own distance, in angle. The parent's pad holds its
/// children's, though each test stands on its own: a box's rays are all
/// those its triangles may set.
#[inline(always)]
pub(crate) fn ray_pad(bounds: &Aabb, origin: Vec3) -> f32 {
    let farthest = (bounds.min - origin).abs().max((bounds.max - origin).abs());
    RAY_SLACK * ((farthest.x + farthest.y) + farthest.z)
}

/// The angle, in radians, by which a box is widened as seen from a receiver
/// for the ray test: far above the predicate's rounding (about `1e-6` for all
/// but cones of nearly flat triangles seen edge on) and near the rectangle's
/// own slack ([`CELL_SLACK`] of a cell, `6e-4`).
const RAY_SLACK: f32 = 1e-3;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hemi::{Receiver, TriangleCone};
    use alloc::vec::Vec;

    /// A small deterministic generator (xorshift), in `[0, 1)`.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// The slow twin: every cell an exact cone of a triangle inside the box
    /// sets lies in the box's rectangle (and none when the box reaches none).
    #[test]
    fn triangles_inside_a_box_set_only_its_cells() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let (mut rects, mut nones, mut listed_some, mut missed_some) = (0, 0, 0, 0);
        for case in 0..3000 {
            let normal = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5)
                .try_normalize()
                .unwrap_or(Vec3::Z);
            let position = Vec3::new(rng.next(), rng.next(), rng.next()) * 2.0 - 1.0;
            let receiver = Receiver::new(position, normal, 0.0);
            // Boxes of every size, some grazing the horizon, some touching
            // the receiver.
            let size = 10f32.powf(-3.0 + 3.5 * rng.next());
            let min = Vec3::new(rng.next(), rng.next(), rng.next()) * 3.0 - 1.5;
            let bounds = Aabb {
                min,
                max: min + Vec3::new(rng.next(), rng.next(), rng.next()) * size,
            };
            let frame = receiver.scaled_frame([(bounds.min, bounds.max)]);
            let cells = BoxCells::of(&bounds, &frame, receiver.origin);
            match cells {
                BoxCells::Cells { .. } => rects += 1,
                BoxCells::None => nones += 1,
                BoxCells::Any => {}
            }
            // Triangles with corners inside the box, on its faces and at its
            // corners, so the rectangle's edges are reached.
            let mut inside = HemiMask::EMPTY;
            for _ in 0..12 {
                let mut corner = || {
                    let mut t = Vec3::new(rng.next(), rng.next(), rng.next());
                    if rng.next() < 0.5 {
                        t = t.round();
                    }
                    frame.to_local(bounds.min + (bounds.max - bounds.min) * t - receiver.origin)
                };
                let (a, b, c) = (corner(), corner(), corner());
                let _ = TriangleCone::or_exact_into(a, b, c, false, &mut inside);
            }
            // The ray test keeps every cell they set, with the box's own pad.
            let mut every = OpenCells::<812> {
                cells: [(0, 0); 812],
                len: 0,
            };
            for (i, j, _) in crate::hemi::cell_directions() {
                every.cells[every.len] = (i as u8, j as u8);
                every.len += 1;
            }
            let pad = ray_pad(&bounds, receiver.origin);
            let mut rays = RayCells::EMPTY;
            rays.set_from(&every, &frame);
            let every = rays.meeting(&bounds, receiver.origin, pad, &HemiMask::EMPTY);
            let hit = every.as_slice().iter().fold(HemiMask::EMPTY, |mut m, ray| {
                m.set(usize::from(ray.i), usize::from(ray.j), true);
                m
            });
            assert_eq!(inside & hit, inside, "case {case}: set cells missed");
            missed_some += usize::from(inside != HemiMask::EMPTY && every.len < 400);
            match cells {
                BoxCells::Any => {}
                BoxCells::None => assert_eq!(inside, HemiMask::EMPTY, "case {case}"),
                BoxCells::Cells { .. } => {
                    for (i, j, _) in crate::hemi::cell_directions() {
                        if inside.get(i, j) {
                            assert!(
                                cells.reaches(i, j),
                                "case {case}: cell ({i}, {j}) outside {cells:?}",
                            );
                        }
                    }
                }
            }
            // The row test against the cell-by-cell definition: true
            // whenever a reached cell is clear (masks with every reached
            // cell but one set, and random ones).
            let reached: Vec<_> = crate::hemi::cell_directions()
                .filter(|&(i, j, _)| cells.reaches(i, j))
                .collect();
            let all = reached.iter().fold(HemiMask::EMPTY, |mut m, &(i, j, _)| {
                m.set(i, j, true);
                m
            });
            // A full mask takes nothing more.
            let full = HemiMask::VALID;
            assert_eq!(
                cells.can_add_to(&full),
                cells == BoxCells::Any,
                "case {case}"
            );
            for (k, &(i, j, _)) in reached.iter().enumerate().step_by(7) {
                let mut one_open = all;
                one_open.set(i, j, false);
                assert!(cells.can_add_to(&one_open), "case {case} cell {k}");
            }
            let mut random = HemiMask::EMPTY;
            for (i, j, _) in crate::hemi::cell_directions() {
                random.set(i, j, rng.next() < 0.9);
            }
            // The cells met again, against a mask: those still clear.
            let again = every.meeting(&bounds, receiver.origin, pad, &random);
            let clear_met: Vec<(u8, u8)> = every
                .as_slice()
                .iter()
                .filter(|ray| !random.get(usize::from(ray.i), usize::from(ray.j)))
                .map(|ray| (ray.i, ray.j))
                .collect();
            let again: Vec<(u8, u8)> = again.as_slice().iter().map(|r| (r.i, r.j)).collect();
            assert_eq!(again, clear_met, "case {case}");
            let open = reached.iter().any(|&(i, j, _)| !random.get(i, j));
            assert!(!open || cells.can_add_to(&random), "case {case}");
            // The open cells listed: the reached ones still clear, in row
            // order, when there are at most N of them.
            let clear: Vec<(u8, u8)> = reached
                .iter()
                .filter(|&&(i, j, _)| !random.get(i, j))
                .map(|&(i, j, _)| (i as u8, j as u8))
                .collect();
            let listed = cells.open_cells::<8>(&random);
            match (cells, listed) {
                (BoxCells::Any, listed) => assert!(listed.is_none(), "case {case}"),
                (_, Some(listed)) => {
                    // Every clear reached cell, and only valid clear cells of
                    // the rectangle (its band's slack may add a few).
                    let listed = listed.as_slice();
                    assert!(clear.iter().all(|c| listed.contains(c)), "case {case}");
                    let BoxCells::Cells { rect, .. } = cells else {
                        assert!(listed.is_empty(), "case {case}");
                        continue;
                    };
                    for &(i, j) in listed {
                        let (i, j) = (usize::from(i), usize::from(j));
                        assert!(
                            HemiMask::VALID.get(i, j) && !random.get(i, j),
                            "case {case}"
                        );
                        assert!((rect.0..=rect.1).contains(&i), "case {case}");
                        assert!((rect.2..=rect.3).contains(&j), "case {case}");
                    }
                }
                (_, None) => assert!(cells.can_add_to(&random), "case {case}"),
            }
            listed_some += usize::from(listed.is_some_and(|l| !l.as_slice().is_empty()));
        }
        // The test means something only if many boxes get a rectangle and
        // some none.
        assert!(
            rects > 1000 && nones > 50 && listed_some > 100 && missed_some > 300,
            "{rects} rectangles, {nones} none, {listed_some} short lists, \
             {missed_some} boxes setting cells whose rays miss most cells"
        );
    }

    /// The slow twin of [`RaysFour::meet`]: each ray's own slab test, on
    /// random boxes and directions and on the cases that make NaN (a zero
    /// direction component with the origin on a face), with one to four
    /// rays.
    #[test]
    fn four_rays_meet_a_box_as_each_ray_does() {
        let mut rng = Rng(0x7261_7973);
        let component = |rng: &mut Rng| match (rng.next() * 8.0) as u32 {
            0 => 0.0,
            1 => -0.0,
            _ => rng.next() * 2.0 - 1.0,
        };
        let mut checked = 0;
        for _ in 0..20_000 {
            let rays: Vec<RayCell> = (0..1 + (rng.next() * 4.0) as usize)
                .map(|_| {
                    let d = Vec3::new(
                        component(&mut rng),
                        component(&mut rng),
                        component(&mut rng),
                    );
                    RayCell {
                        i: 0,
                        j: 0,
                        inverse: d.recip(),
                    }
                })
                .collect();
            // Faces through the origin, boxes around it, beside it, behind it.
            let coordinate = |rng: &mut Rng| match (rng.next() * 6.0) as u32 {
                0 => 0.0,
                _ => rng.next() * 4.0 - 2.0,
            };
            let (a, b) = (
                Vec3::new(
                    coordinate(&mut rng),
                    coordinate(&mut rng),
                    coordinate(&mut rng),
                ),
                Vec3::new(
                    coordinate(&mut rng),
                    coordinate(&mut rng),
                    coordinate(&mut rng),
                ),
            );
            let padded = PaddedBox {
                lo: a.min(b),
                hi: a.max(b),
            };
            let lanes = RaysFour::new(&rays).meet(&padded);
            for (k, ray) in rays.iter().enumerate() {
                assert_eq!(
                    lanes >> k & 1 == 1,
                    ray.meets(&padded),
                    "ray {k} of {rays:?}, {padded:?}"
                );
                checked += 1;
            }
            assert_eq!(lanes >> rays.len(), 0, "bits past the rays");
        }
        assert!(checked > 40_000);
    }

    /// The slow twin of [`ring_band`]: each cell's squared radius compared
    /// with the ring in `f32`. The band holds every cell of the ring and no
    /// cell farther than [`RING_UNITS`] and a unit of rounding outside it.
    #[test]
    fn ring_bands_hold_the_ring_and_little_more() {
        let mut rng = Rng(0x7269_6e67);
        let mut rings: Vec<(f32, f32)> = (0..4000)
            .map(|_| {
                let (a, b) = (rng.next() * 1.1 - 0.05, rng.next() * 1.1 - 0.05);
                (a.min(b), a.max(b))
            })
            .collect();
        rings.extend([
            (0.0, 1.0),
            (-1.0, 2.0),
            (0.5, 0.4),
            (f32::NAN, 0.5),
            (0.5, f32::NAN),
            (f32::NEG_INFINITY, f32::INFINITY),
        ]);
        // Exact cell radii: the integers of the docs over 1024.
        let slack = (RING_UNITS + 1) as f32 / 1024.0;
        for (r0, r1) in rings {
            for (j, &v) in CELL_COORD.iter().enumerate() {
                let band = ring_band(j, (r0, r1));
                for (i, &u) in CELL_COORD.iter().enumerate() {
                    let r2 = u * u + v * v;
                    let inside = band >> i & 1 == 1;
                    if r0 <= r2 && r2 <= r1 {
                        assert!(inside, "cell ({i}, {j}) of ring ({r0}, {r1})");
                    }
                    if inside && !r0.is_nan() && !r1.is_nan() {
                        assert!(
                            r0 - slack <= r2 && r2 <= r1 + slack,
                            "cell ({i}, {j}) far outside ring ({r0}, {r1})"
                        );
                    }
                }
            }
        }
    }
}
