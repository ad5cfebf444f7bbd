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
#[cfg(test)]
use super::mask::CELL_COORD;
use super::mask::HemiMask;
use super::rays::{LIST_CAPACITY, OpenCells};
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

    /// [`BoxCells::open_cells_into`] as a value, for tests.
    #[cfg(test)]
    pub(crate) fn open_cells<const N: usize>(self, mask: &HemiMask) -> Option<OpenCells> {
        let mut open = OpenCells::NONE;
        self.open_cells_into::<N>(mask, &mut open).then_some(open)
    }

    /// Writes into `open` (whatever it held) the cells triangles in the box
    /// can still set in `mask`, and returns true, when there are at most `N`
    /// (reached as `BoxCells::can_add_to` bounds them, so a few more than
    /// `BoxCells::reaches` may be listed, valid and clear); false when there
    /// are more, or the box is close enough to reach any cell. Few cells are
    /// cheaper to test one by one against the box's triangles than the
    /// triangles are to rasterize. Written in place: the rows are not
    /// copied.
    #[inline(always)]
    pub(crate) fn open_cells_into<const N: usize>(
        self,
        mask: &HemiMask,
        open: &mut OpenCells,
    ) -> bool {
        const { assert!(N <= LIST_CAPACITY) };
        let BoxCells::Cells {
            rect: (i0, i1, j0, j1),
            ring,
        } = self
        else {
            open.rows = OpenCells::NONE.rows;
            return self == BoxCells::None;
        };
        open.rows = (j0, j1);
        let rect = HemiMask::columns(i0, i1);
        let band = RingBand::new(ring);
        let mut count = 0;
        // Counted before any cell is written out: the nodes near a receiver
        // reach many.
        for j in j0..=j1 {
            let clear = rect & HemiMask::VALID.rows[j] & !mask.rows[j];
            if clear == 0 {
                open.bits[j] = 0;
                continue;
            }
            let row = clear & band.row(j);
            open.bits[j] = row;
            count += row.count_ones() as usize;
            if count > N {
                return false;
            }
        }
        true
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hemi::rays::{PaddedBox, RayCell, ray_pad};
    use crate::hemi::test_meshes::Rng;
    use crate::hemi::{Receiver, TriangleCone};
    use alloc::vec::Vec;

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
            let padded =
                PaddedBox::new(&bounds, receiver.origin, ray_pad(&bounds, receiver.origin));
            let hit = crate::hemi::cell_directions()
                .filter(|&(i, j, _)| RayCell::of(i, j, &frame).meets(&padded))
                .fold(HemiMask::EMPTY, |mut m, (i, j, _)| {
                    m.set(i, j, true);
                    m
                });
            assert_eq!(inside & hit, inside, "case {case}: set cells missed");
            let met = hit.count_occluded();
            missed_some += usize::from(inside != HemiMask::EMPTY && met < 400);
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
                    let listed = listed.cells();
                    assert!(clear.iter().all(|c| listed.contains(c)), "case {case}");
                    let BoxCells::Cells { rect, .. } = cells else {
                        assert!(listed.is_empty(), "case {case}");
                        continue;
                    };
                    for &(i, j) in &listed {
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
            listed_some += usize::from(listed.is_some_and(|l| !l.cells().is_empty()));
        }
        // The test means something only if many boxes get a rectangle and
        // some none.
        assert!(
            rects > 1000 && nones > 50 && listed_some > 100 && missed_some > 300,
            "{rects} rectangles, {nones} none, {listed_some} short lists, \
             {missed_some} boxes setting cells whose rays miss most cells"
        );
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
