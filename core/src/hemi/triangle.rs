//! Triangle rasterization: the cone of directions from the center of projection
//! through a triangle, as the AND of three half-space masks (Kautz, Lehtinen and
//! Aila 2004, §3).
//!
//! For corners `a, b, c` relative to the center of projection (in the receiver's
//! local frame), the ray along `d` hits the triangle at some `t > 0` exactly when
//! `d` is a non-negative combination of `a, b, c`: the intersection of the three
//! half-spaces with normals `a×b`, `b×c`, `c×a`, all negated when the triple product
//! `(a×b)·c` is negative. Triangles crossing the horizon need no clipping (the
//! mask has only upper cells), and the cone is right even for corners below it.
//!
//! Invariants:
//! - [`TriangleCone::mask_exact`] equals, bit for bit, the per-cell predicate "all
//!   three closed half-space tests pass" ([`TriangleCone::mask_reference`]). With
//!   exact negation of `a×b` into `b×a`, the two triangles on either side of a
//!   shared edge test opposite normals, so every cell is claimed by at least one of
//!   them: no pinholes.
//! - Culled: triangles with every corner at or below the horizon plane (`z <= 0`),
//!   degenerate ones (`(a×b)·c == 0`, an edge normal that rounds to zero, or a
//!   non-finite value), and, on request, back-facing ones (see [`Culled`]).

use glam::Vec3;

use super::half_space::{RowSolver, inside, normalize_exponent};
use super::mask::{GRID, HemiMask, ROW_FIRST, ROW_LAST};
use super::table::{ALL, EdgeClasses, Entry, HalfSpaceTable, and_entries};

/// Why a triangle contributes nothing and was skipped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Culled {
    /// Every corner has local `z <= 0`: the whole cone is at or below the horizon.
    BelowHorizon,
    /// The center of projection lies in the triangle's plane (`(a×b)·c == 0`,
    /// which includes zero-area triangles and a corner at the center), an edge
    /// normal rounds to zero, or a value is not finite. Such a triangle is seen
    /// edge-on and hides no direction of positive measure; rays from the center
    /// would only graze it.
    Degenerate,
    /// Culling was requested and the triangle's geometric normal `(b-a)×(c-a)`
    /// points away from the center of projection, i.e. the center sees its back
    /// (clockwise) side. `((b-a)×(c-a))·(a - o) = (a×b)·c` for corners relative to
    /// `o`, so back-facing means a positive triple product. In a closed mesh whose
    /// triangles wind counter-clockwise seen from outside, a center of projection
    /// outside the mesh sees every occluding surface from the front, so culling the
    /// back faces changes no cell away from the silhouette ties.
    BackFacing,
}

/// The cone of directions through a triangle, ready to rasterize.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleCone {
    corners: [Vec3; 3],
    /// Inward edge normals: `a×b, b×c, c×a`, negated when `(a×b)·c < 0`.
    normals: [Vec3; 3],
}

/// Margin (in disk `u` and `v`) added around the cone's extent when choosing which
/// cells to test or rows to solve. A cell passing all three predicates in `f32`
/// lies within 1e-6 rad of each half-space (the predicate's rounding), hence within
/// `1e-6 / sin(θ/2)` of the cone for a corner angle `θ`; with `θ >= 2e-3` (see
/// [`FLAT_OR_THIN_DOT`]) that is below 1e-3, far inside this margin, so pruning
/// never drops a cell the full AND would keep.
const BOX_MARGIN: f32 = 1.0 / 64.0;

/// Corners sharper than about 2e-3 rad (`n̂_k·n̂_l < -(1 - 2e-6)` for the inward
/// normals of the two edges) make the rounding band around the cone's tip long,
/// and corners within 2e-3 rad of straight (`n̂_k·n̂_l > 1 - 2e-6`) have an
/// ill-conditioned position; such cones get every row solved instead.
const FLAT_OR_THIN_DOT: f32 = 1.0 - 2e-6;

/// Cell boxes narrower than this many columns are tested cell by cell (three
/// predicates, a few nanoseconds each) instead of solved row by row (a square
/// root and a few predicates per plane and row).
const NARROW_BOX_COLUMNS: usize = 8;

/// Table quality looks for a triangle's cells in the box of its corners' disk
/// positions when every edge is shorter than 0.5 rad: `tan²(0.5)` (rounded
/// down). The box is then widened by at most `BOXED_SPREAD / 4 < 0.075` for the
/// arcs' bulge.
const BOXED_SPREAD: f32 = 0.298_4;

impl TriangleCone {
    /// Prepares triangle `(a, b, c)`, corners relative to the center of projection
    /// in the receiver's local frame, or says why it is culled (see [`Culled`]).
    /// Back faces are culled only when `cull_backfaces` is set.
    #[inline]
    pub fn new(a: Vec3, b: Vec3, c: Vec3, cull_backfaces: bool) -> Result<Self, Culled> {
        if a.z <= 0.0 && b.z <= 0.0 && c.z <= 0.0 {
            return Err(Culled::BelowHorizon);
        }
        let (ab, bc, ca) = (cross(a, b), cross(b, c), cross(c, a));
        let det = dot(ab, c);
        let finite = det.is_finite() && (ab + bc + ca).is_finite();
        if !finite || det == 0.0 || ab == Vec3::ZERO || bc == Vec3::ZERO || ca == Vec3::ZERO {
            return Err(Culled::Degenerate);
        }
        if cull_backfaces && det > 0.0 {
            return Err(Culled::BackFacing);
        }
        // Negation is exact, so a shared edge still gets exactly opposite normals
        // in its two triangles whenever both are seen with the same orientation.
        let normals = if det < 0.0 {
            [-ab, -bc, -ca]
        } else {
            [ab, bc, ca]
        };
        // Scaled by powers of two once here (exact, and still exactly opposite
        // across a shared edge) so every quality sees the same normals.
        let normals = normals.map(normalize_exponent);
        Ok(TriangleCone {
            corners: [a, b, c],
            normals,
        })
    }

    /// The corners as given.
    #[inline]
    pub fn corners(&self) -> [Vec3; 3] {
        self.corners
    }

    /// The inward edge-plane normals (unnormalised, scaled by powers of two so the
    /// largest component is in `[1, 2)`): the cone is the set of `d` with
    /// `normal·d >= 0` for all three.
    #[inline]
    pub fn normals(&self) -> [Vec3; 3] {
        self.normals
    }

    /// Whether valid cell `(i, j)` is in the cone: the per-cell predicate every
    /// quality approximates and the exact one reproduces. `false` for invalid cells.
    #[inline]
    pub fn covers_cell(&self, i: usize, j: usize) -> bool {
        super::mask::is_valid_cell(i, j) && self.normals.iter().all(|&m| inside(m, i, j))
    }

    /// The per-cell predicate on every valid cell: the reference for
    /// [`TriangleCone::mask_exact`].
    pub fn mask_reference(&self) -> HemiMask {
        let mut mask = HemiMask::EMPTY;
        for j in 0..GRID {
            for i in ROW_FIRST[j] as usize..=ROW_LAST[j] as usize {
                if self.normals.iter().all(|&m| inside(m, i, j)) {
                    mask.rows[j] |= 1 << i;
                }
            }
        }
        mask
    }

    /// The cone's mask in the given quality.
    #[inline]
    pub fn mask(&self, quality: super::Quality<'_>) -> HemiMask {
        match quality {
            super::Quality::Exact => self.mask_exact(),
            super::Quality::Table(table) => self.mask_table(table),
        }
    }

    /// The exact mask: the AND of the three exact half-space masks, equal to
    /// [`TriangleCone::mask_reference`] bit for bit. Only the cells the cone can
    /// reach are looked at: a narrow box of cells is tested cell by cell, a wider
    /// one solved row by row as in [`half_space_mask`](super::half_space_mask).
    pub fn mask_exact(&self) -> HemiMask {
        let mut mask = HemiMask::EMPTY;
        let Some(CellBox { i0, i1, j0, j1 }) = self.cell_box() else {
            return mask;
        };
        if i1 - i0 < NARROW_BOX_COLUMNS {
            // A few columns: testing each cell costs less than solving the rows.
            for j in j0..=j1 {
                let first = i0.max(ROW_FIRST[j] as usize);
                let last = i1.min(ROW_LAST[j] as usize);
                let mut row = 0;
                for i in first..=last {
                    let hit = self.normals.iter().all(|&m| inside(m, i, j));
                    row |= u32::from(hit) << i;
                }
                mask.rows[j] = row;
            }
            return mask;
        }
        let solvers = self.normals.map(RowSolver::new);
        for j in j0..=j1 {
            // Later planes only matter where the earlier ones left something.
            let mut row = solvers[0].row(j);
            if row != 0 {
                row &= solvers[1].row(j);
                if row != 0 {
                    row &= solvers[2].row(j);
                }
            }
            mask.rows[j] = row;
        }
        mask
    }

    /// The table mask (the paper's method, with exact edges): each edge plane
    /// either from the nearest table entry or exact, as the table's rule decides
    /// for the edge ([`HalfSpaceTable::with_exact_edges`]), then ANDed.
    /// Approximate; see [`HalfSpaceTable`] for its error.
    ///
    /// The rule looks at the edge alone (its corners, in either order), so both
    /// triangles of a shared edge read the same table entry (as exact
    /// complements) or both test it exactly (sharing only the cells exactly on
    /// it): no pinholes either way. The work depends on the mix:
    /// - no exact edge: three table reads and one fused AND;
    /// - otherwise only the cells that can hold the cone are looked at, the table
    ///   planes read there and the exact planes tested on the cells they leave:
    ///   for a cone whose edges are all under 0.5 rad, the cells within 1/64
    ///   plus the arcs' bulge (`tan²ℓ / 4`) of the box of the corners' disk
    ///   positions, found with an approximate (1.8e-3) inverse square root; else
    ///   the box [`TriangleCone::mask_exact`] uses. Wide boxes solve the exact
    ///   planes row by row.
    ///
    /// The box is widened by the table's `max_error` when a table plane is in
    /// play: a cell up to that far outside the cone can be on the table's side
    /// of a shared edge, and dropping it would leave it to neither triangle.
    /// Cells outside the widened box are neither in this cone nor within the
    /// table's error of it, so leaving them out drops only table errors. With the default rule, most triangles of a
    /// dense mesh seen from its vertices have all edges short and never touch
    /// the table: that path costs about 45–60 ns against 95 for
    /// [`TriangleCone::mask_exact`] (its corner box avoids the exact path's six
    /// normalisations), which is why table quality stays faster than exact
    /// quality while rasterizing most edges exactly.
    #[inline]
    pub fn mask_table(&self, table: &HalfSpaceTable) -> HemiMask {
        if !table.has_exact_edges() {
            return self.mask_from_table(table);
        }
        let classes = table.classify_edges(self.corners);
        if classes.exact == 0 {
            return self.mask_from_table(table);
        }
        self.mask_with_exact_edges(table, classes)
    }

    /// Every plane from the table: three reads, mapped back and ANDed.
    #[inline(always)]
    fn mask_from_table(&self, table: &HalfSpaceTable) -> HemiMask {
        // Written out: `array::map` is not reliably inlined here.
        let [m0, m1, m2] = self.normals;
        let (e0, e1, e2) = (table.entry(m0), table.entry(m1), table.entry(m2));
        HemiMask {
            rows: and_entries(&e0, &e1, &e2),
        }
    }

    /// [`TriangleCone::mask_table`] when some edge is exact.
    #[inline(never)]
    fn mask_with_exact_edges(&self, table: &HalfSpaceTable, classes: EdgeClasses) -> HemiMask {
        let exact = classes.exact;
        let entry = |k: usize| {
            if exact >> k & 1 == 0 {
                table.entry(self.normals[k])
            } else {
                ALL
            }
        };
        let entries = [entry(0), entry(1), entry(2)];
        // A table plane lies within the table's error of the true one, so cells
        // up to that far outside the cone can belong to it on a table edge; the
        // box keeps them, or the neighbour across the edge (which reads the
        // complement) would leave them uncovered.
        let widen = if exact == 0b111 {
            0.0
        } else {
            table.max_error()
        };
        if classes.spread < BOXED_SPREAD {
            return self.mask_boxed(&entries, exact, 0.25 * classes.spread + widen);
        }
        let Some(CellBox { i0, i1, j0, j1 }) = self.cell_box_widened(widen) else {
            return HemiMask::EMPTY;
        };
        let columns = (u32::MAX >> (GRID - 1 - i1)) & (u32::MAX << i0);
        let mut mask = HemiMask::EMPTY;
        if i1 - i0 < NARROW_BOX_COLUMNS {
            // A few columns: the exact planes' predicate on the cells the table
            // planes leave.
            for j in j0..=j1 {
                let mut candidates = HemiMask::VALID.rows[j]
                    & columns
                    & entries[0].row(j)
                    & entries[1].row(j)
                    & entries[2].row(j);
                let mut row = 0;
                while candidates != 0 {
                    let i = candidates.trailing_zeros() as usize;
                    row |= u32::from(self.exact_planes_cover(exact, i, j)) << i;
                    candidates &= candidates - 1;
                }
                mask.rows[j] = row;
            }
            return mask;
        }
        let solver = |k: usize| (exact >> k & 1 == 1).then(|| RowSolver::new(self.normals[k]));
        let solvers = [solver(0), solver(1), solver(2)];
        for j in j0..=j1 {
            let mut row = HemiMask::VALID.rows[j]
                & columns
                & entries[0].row(j)
                & entries[1].row(j)
                & entries[2].row(j);
            for solver in solvers.iter().flatten() {
                if row == 0 {
                    break;
                }
                row &= solver.row(j);
            }
            mask.rows[j] = row;
        }
        mask
    }

    /// Whether cell `(i, j)` passes the exact predicate of every plane whose bit
    /// is set in `exact` (without branches: all three are evaluated).
    #[inline(always)]
    fn exact_planes_cover(&self, exact: u32, i: usize, j: usize) -> bool {
        let [m0, m1, m2] = self.normals;
        ((exact & 1 == 0) | inside(m0, i, j))
            & ((exact & 2 == 0) | inside(m1, i, j))
            & ((exact & 4 == 0) | inside(m2, i, j))
    }

    /// The mask of a cone whose edges are all shorter than 0.5 rad, with the
    /// given planes (table `entries`, [`ALL`] for the `exact` ones), looking only
    /// at the cells whose centers lie within [`BOX_MARGIN`]` + widen` of the box
    /// of the corners' disk positions. With `widen` at least the arcs' bulge, that
    /// holds the whole cone: a point of the cone is `(αa + βb + γc) / |αa + βb +
    /// γc|` for unit corners and non-negative weights summing to one; with
    /// pairwise angles up to `ℓ` the norm is at least `sqrt(cos ℓ)`, so its disk
    /// position is within `1 - sqrt(cos ℓ) <= tan²ℓ / 4` of the box.
    ///
    /// For the small triangles of a dense mesh the box holds one cell center or
    /// none (half of the armadillo's triangles seen from its vertices), so the
    /// first candidate of a row is tested without branches and only further ones
    /// loop; wide boxes solve the exact planes row by row.
    #[inline(always)]
    fn mask_boxed(&self, entries: &[Entry<'_>; 3], exact: u32, widen: f32) -> HemiMask {
        // The corners' directions, to within a relative 1.8e-3 (far inside
        // BOX_MARGIN): one Newton step on the bit-trick inverse square root
        // (Lomont's constant) instead of three square roots and divisions, whose
        // latency dominated this path. Corners are finite and non-zero (the cone
        // would be culled otherwise); squared lengths outside the normal range
        // are rescaled first.
        let [a, b, c] = self.corners;
        let (la, lb, lc) = (a.length_squared(), b.length_squared(), c.length_squared());
        let normal = |l: f32| (f32::MIN_POSITIVE..=1e37).contains(&l);
        let (a, b, c) = if normal(la) & normal(lb) & normal(lc) {
            (
                a * inv_sqrt_approx(la),
                b * inv_sqrt_approx(lb),
                c * inv_sqrt_approx(lc),
            )
        } else {
            let unit = |p: Vec3| {
                let p = normalize_exponent(p);
                p * (1.0 / p.length())
            };
            (unit(a), unit(b), unit(c))
        };
        let margin = BOX_MARGIN + widen;
        let (i0, i_end) = cell_range(min3(a.x, b.x, c.x), max3(a.x, b.x, c.x), margin);
        let (j0, j_end) = cell_range(min3(a.y, b.y, c.y), max3(a.y, b.y, c.y), margin);
        // Bits i0..i_end, none when the box is empty; and at least one row is
        // visited, so the common single-row case has no data-dependent branch.
        let columns = ((1u64 << i_end).wrapping_sub(1u64 << i0)) as u32;
        let columns = if i0 < i_end && j0 < j_end { columns } else { 0 };
        let j0 = j0.min(GRID - 1);
        let j_end = j_end.max(j0 + 1);
        let mut mask = HemiMask::EMPTY;
        if i_end <= i0 + NARROW_BOX_COLUMNS {
            for j in j0..j_end {
                let mut candidates = HemiMask::VALID.rows[j]
                    & columns
                    & entries[0].row(j)
                    & entries[1].row(j)
                    & entries[2].row(j);
                let i = (candidates.trailing_zeros() as usize).min(GRID - 1);
                let hit = (candidates != 0) & self.exact_planes_cover(exact, i, j);
                let mut row = u32::from(hit) << i;
                candidates &= candidates.wrapping_sub(1);
                while candidates != 0 {
                    let i = candidates.trailing_zeros() as usize;
                    row |= u32::from(self.exact_planes_cover(exact, i, j)) << i;
                    candidates &= candidates - 1;
                }
                mask.rows[j] = row;
            }
        } else {
            let solver = |k: usize| (exact >> k & 1 == 1).then(|| RowSolver::new(self.normals[k]));
            let solvers = [solver(0), solver(1), solver(2)];
            for j in j0..j_end {
                let mut row = HemiMask::VALID.rows[j]
                    & columns
                    & entries[0].row(j)
                    & entries[1].row(j)
                    & entries[2].row(j);
                for solver in solvers.iter().flatten() {
                    if row == 0 {
                        break;
                    }
                    row &= solver.row(j);
                }
                mask.rows[j] = row;
            }
        }
        mask
    }

    /// The box of cells (columns `i0..=i1`, rows `j0..=j1`) that may hold cells of
    /// the cone: the cone's extent in `u` and `v` widened by [`BOX_MARGIN`]; the
    /// whole grid when a corner is sliver-thin or nearly flat; `None` when no cell
    /// center is within reach.
    ///
    /// The extent is that of the cone the `f32` normals bound (its corners are the
    /// pairwise cross products of the normals), not of the corners as given: for a
    /// far, tiny triangle the rounded normals can bound a noticeably different cone,
    /// and the predicate only ever sees the normals.
    fn cell_box(&self) -> Option<CellBox> {
        self.cell_box_widened(0.0)
    }

    /// [`TriangleCone::cell_box`] with the extent widened by `extra` on every side
    /// (table quality widens by the table's error, see
    /// [`TriangleCone::mask_table`]).
    #[inline]
    fn cell_box_widened(&self, extra: f32) -> Option<CellBox> {
        const WHOLE: CellBox = CellBox {
            i0: 0,
            i1: GRID - 1,
            j0: 0,
            j1: GRID - 1,
        };
        let unit = self.normals.map(|m| m * (1.0 / m.length()));
        let dots = [
            dot(unit[0], unit[1]),
            dot(unit[1], unit[2]),
            dot(unit[2], unit[0]),
        ];
        if dots
            .iter()
            .any(|d| d.abs() > FLAT_OR_THIN_DOT || d.is_nan())
        {
            // Thin: a long rounding band beyond the tip. Flat: the corner's position
            // along the nearly straight boundary is ill-conditioned. (Also NaN.)
            return Some(WHOLE);
        }
        // Corner between edge planes k and k+1 (a between ca and ab, and so on),
        // oriented into the third half-space.
        let corner = |k: usize, l: usize, opposite: usize| {
            let p = cross(unit[k], unit[l]);
            let p = p * (1.0 / p.length());
            if dot(p, unit[opposite]) < 0.0 { -p } else { p }
        };
        let corners = [corner(2, 0, 1), corner(0, 1, 2), corner(1, 2, 0)];
        let (u_lo, u_hi) = extent(corners, unit, |v| v.x);
        let (v_lo, v_hi) = extent(corners, unit, |v| v.y);
        let (i0, i1) = cells_within(u_lo - extra, u_hi + extra)?;
        let (j0, j1) = cells_within(v_lo - extra, v_hi + extra)?;
        Some(CellBox { i0, i1, j0, j1 })
    }
}

/// A rectangle of cells, bounds inclusive.
#[derive(Clone, Copy, Debug)]
struct CellBox {
    i0: usize,
    i1: usize,
    j0: usize,
    j1: usize,
}

/// The range of one coordinate (`axis`: x or y of a unit direction) over the
/// spherical triangle with unit `corners` and unit inward edge `normals`: reached at
/// a corner, inside an edge's arc, or ±1 when the cone contains that axis.
#[inline(always)]
fn extent(corners: [Vec3; 3], normals: [Vec3; 3], axis: impl Fn(Vec3) -> f32) -> (f32, f32) {
    let mut lo = f32::INFINITY;
    let mut hi = f32::NEG_INFINITY;
    for p in corners {
        lo = lo.min(axis(p));
        hi = hi.max(axis(p));
    }
    for k in 0..3 {
        let (p, q, m) = (corners[k], corners[(k + 1) % 3], normals[k]);
        // Along the minor arc from p to q (unit), the coordinate rises at p when the
        // tangent (p×q)×p = q - p (p·q) does, and falls past q when (p×q)×q =
        // q (p·q) - p does; then the top of the arc's great circle,
        // sqrt(1 - m̂_axis²), is inside the arc (and likewise the bottom).
        let pq = dot(p, q);
        let rise_at_p = axis(q) - axis(p) * pq;
        let rise_past_q = axis(q) * pq - axis(p);
        let top = || libm::sqrtf((1.0 - axis(m) * axis(m)).max(0.0));
        if rise_at_p > 0.0 && rise_past_q < 0.0 {
            hi = hi.max(top());
        }
        if rise_at_p < 0.0 && rise_past_q > 0.0 {
            lo = lo.min(-top());
        }
    }
    if normals.iter().all(|&m| axis(m) >= 0.0) {
        hi = 1.0;
    }
    if normals.iter().all(|&m| axis(m) <= 0.0) {
        lo = -1.0;
    }
    if lo > hi || lo.is_nan() || hi.is_nan() {
        return (-1.0, 1.0);
    }
    (lo, hi)
}

/// Cells `k` whose center coordinate `(k + 0.5)/16 - 1` lies in `[lo, hi]` widened
/// by [`BOX_MARGIN`]; `None` when there are none.
#[inline(always)]
fn cells_within(lo: f32, hi: f32) -> Option<(usize, usize)> {
    let first = ((lo - BOX_MARGIN + 1.0) * 16.0 - 0.5).max(0.0);
    let last = ((hi + BOX_MARGIN + 1.0) * 16.0 - 0.5).min(31.0);
    if last < 0.0 || first > 31.0 {
        return None;
    }
    // Both are in [0, 31] now, where truncation is floor.
    let first = first as usize + usize::from(first > (first as usize) as f32);
    let last = last as usize;
    (first <= last).then_some((first, last))
}

/// Columns (or rows) `k` whose center coordinate `(k + 0.5)/16 - 1` lies in
/// `[lo, hi]` widened by `margin`, as the half-open range `first..end`
/// (`first` in `0..=32`, `end` in `0..=32`, empty when `first >= end`). Like
/// [`cells_within`], without branches; a NaN gives some range, never a panic.
#[inline(always)]
fn cell_range(lo: f32, hi: f32, margin: f32) -> (usize, usize) {
    // The fractional column of each end, clamped so the conversions are exact:
    // ceil(x) = 64 - trunc(64 - x) and floor(x) + 1 = trunc(x + 65) - 64.
    let lo = ((lo - margin) * 16.0 + 15.5).clamp(-1.0, 32.0);
    let hi = ((hi + margin) * 16.0 + 15.5).clamp(-1.0, 32.0);
    let first = (64 - (64.0 - lo) as i32).max(0);
    let end = ((hi + 65.0) as i32 - 64).min(GRID as i32);
    (first as usize, end as usize)
}

/// `1/sqrt(x)` to within a relative 1.8e-3, for `x` in the normal range: the
/// bit-level first guess with Lomont's constant and one Newton step.
#[inline(always)]
fn inv_sqrt_approx(x: f32) -> f32 {
    let y = f32::from_bits(0x5f37_5a86_u32.wrapping_sub(x.to_bits() >> 1));
    y * (1.5 - 0.5 * x * y * y)
}

#[inline(always)]
fn min3(a: f32, b: f32, c: f32) -> f32 {
    let m = if a < b { a } else { b };
    if m < c { m } else { c }
}

#[inline(always)]
fn max3(a: f32, b: f32, c: f32) -> f32 {
    let m = if a > b { a } else { b };
    if m > c { m } else { c }
}

/// `p × q`, written out so `q × p` is exactly `-(p × q)` whatever glam does.
#[inline(always)]
pub(crate) fn cross(p: Vec3, q: Vec3) -> Vec3 {
    Vec3::new(
        p.y * q.z - q.y * p.z,
        p.z * q.x - q.z * p.x,
        p.x * q.y - q.x * p.y,
    )
}

/// `p · q` in a fixed order.
#[inline(always)]
fn dot(p: Vec3, q: Vec3) -> f32 {
    p.x * q.x + p.y * q.y + p.z * q.z
}

#[cfg(test)]
mod table_quality_tests {
    //! Table quality's triangle masks: the exact-edge paths against the per-cell
    //! predicate, and shared edges without pinholes.

    use super::*;
    use crate::hemi::half_space::{half_space_mask, normalize_exponent};
    use crate::hemi::mask::cell_direction;
    use proptest::prelude::*;

    fn coordinate() -> impl Strategy<Value = f32> {
        prop_oneof![
            6 => -2.0f32..2.0,
            1 => -1e-3f32..1e-3,
            1 => Just(0.0f32),
            1 => -200.0f32..200.0,
        ]
    }

    fn point() -> impl Strategy<Value = Vec3> {
        (coordinate(), coordinate(), coordinate()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    /// Random, small and far, sliver, and nearly edge-on triangles.
    fn triangle() -> impl Strategy<Value = [Vec3; 3]> {
        prop_oneof![
            3 => (point(), point(), point()).prop_map(|(a, b, c)| [a, b, c]),
            2 => (point(), point(), point(), 1e-4f32..0.3).prop_map(|(a, b, c, s)| {
                [a * 10.0, a * 10.0 + b * s, a * 10.0 + c * s]
            }),
            1 => (point(), point(), 0.0f32..1.0, -1e-4f32..1e-4).prop_map(|(a, b, t, s)| {
                [a, b, a.lerp(b, t) + Vec3::splat(s)]
            }),
            1 => (point(), point(), -1e-4f32..1e-4).prop_map(|(a, b, s)| {
                [a, b, a * 0.3 + b * 0.6 + a.cross(b) * s]
            }),
        ]
    }

    /// A convex planar quad not seen at a grazing angle, either winding, including
    /// tiny ones (the table mode's exact-edge rule matters most there).
    fn convex_quad() -> impl Strategy<Value = [Vec3; 4]> {
        crate::hemi::tests::convex_quad_sized(prop_oneof![
            (0.02f32..3.0, 0.02f32..3.0),
            (0.002f32..0.1, 0.002f32..0.1)
        ])
    }

    /// Tables whose rules route edges every way: the default, a coarse one
    /// whose rules make every edge exact, the pure table, and a fine table with
    /// a wide table window.
    fn tables() -> [HalfSpaceTable; 4] {
        [
            HalfSpaceTable::default(),
            HalfSpaceTable::new(24),
            HalfSpaceTable::new(48).with_exact_edges(0.0, f32::INFINITY),
            HalfSpaceTable::new(64).with_exact_edges(0.05, 0.6),
        ]
    }

    /// A cell direction within `eps` (radians) of one of the corners' directions.
    fn near_a_corner(corners: &[Vec3], i: usize, j: usize, eps: f32) -> bool {
        let d = cell_direction(i, j).unwrap();
        corners
            .iter()
            .any(|c| c.normalize_or_zero().dot(d) > libm::cosf(eps))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]

        /// With every edge exact, the paths of table quality (small cones in the
        /// box of their corners, larger ones in the exact box) give the per-cell
        /// predicate; with none exact, the AND of the three lookups.
        #[test]
        fn exact_and_pure_rules_match_their_definitions([a, b, c] in triangle()) {
            let Ok(cone) = TriangleCone::new(a, b, c, false) else {
                return Ok(());
            };
            let reference = cone.mask_reference();
            let all_exact = HalfSpaceTable::new(16).with_exact_edges(core::f32::consts::FRAC_PI_2, 0.0);
            let boxed = cone.mask_table(&all_exact);
            // The box of the corners may miss f32 cells of a cone whose rounded
            // normals bound a visibly different cone (tiny, far triangles): only
            // cells far from it and near no corner would show that, and the
            // triangle itself never covers them.
            prop_assert_eq!(boxed & reference.complement(), HemiMask::EMPTY);
            for (i, j) in (boxed ^ reference).occluded_cells() {
                prop_assert!(near_a_corner(&cone.corners(), i, j, 0.2), "cell ({}, {})", i, j);
            }
            let pure = HalfSpaceTable::new(40).with_exact_edges(0.0, f32::INFINITY);
            let [m0, m1, m2] = cone.normals();
            prop_assert_eq!(
                cone.mask_table(&pure),
                pure.lookup(m0) & pure.lookup(m1) & pure.lookup(m2)
            );
        }

        /// Two triangles sharing an edge classify it alike, whatever the order
        /// of its corners.
        #[test]
        fn a_shared_edge_gets_one_class((a, b, c, d) in (point(), point(), point(), point())) {
            for table in tables() {
                let first = table.classify_edges([a, b, c]).exact & 1;
                prop_assert_eq!(table.classify_edges([b, a, d]).exact & 1, first);
                prop_assert_eq!(table.classify_edges([d, b, a]).exact >> 1 & 1, first);
                prop_assert_eq!(table.classify_edges([a, d, b]).exact >> 2 & 1, first);
            }
        }

        /// A quad's two triangles in table quality: no cell in both (the diagonal's
        /// two sides are exact complements, or share only cells exactly on it when
        /// the diagonal is exact), and no pinhole: every cell of the quad that the
        /// quad's own outer planes (table or exact, as their edges are classified)
        /// keep is in one of the triangles, bit for bit.
        #[test]
        fn quad_has_no_pinholes_in_table_quality([a, b, c, d] in convex_quad()) {
            let (Ok(t1), Ok(t2)) = (
                TriangleCone::new(a, b, c, false),
                TriangleCone::new(a, c, d, false),
            ) else {
                return Ok(());
            };
            let det = cross(a, b).dot(c);
            let s = if det < 0.0 { -1.0 } else { 1.0 };
            let mut quad = HemiMask::VALID;
            for (p, q) in [(a, b), (b, c), (c, d), (d, a)] {
                quad &= half_space_mask(s * cross(p, q));
            }
            let diagonal = normalize_exponent(s * cross(c, a));
            for table in tables() {
                let (first, second) = (table.classify_edges([a, b, c]), table.classify_edges([a, c, d]));
                let diagonal_exact = first.exact >> 2 & 1;
                prop_assert_eq!(second.exact & 1, diagonal_exact);
                let plane = |p: Vec3, q: Vec3, exact: u32| {
                    let m = s * cross(p, q);
                    if exact == 1 { half_space_mask(m) } else { table.lookup(m) }
                };
                let outer = plane(a, b, first.exact & 1)
                    & plane(b, c, first.exact >> 1 & 1)
                    & plane(c, d, second.exact >> 1 & 1)
                    & plane(d, a, second.exact >> 2 & 1);
                let (m1, m2) = (t1.mask_table(&table), t2.mask_table(&table));
                for (i, j) in (m1 & m2).occluded_cells() {
                    // Only ties: cells exactly on an exact diagonal's plane.
                    prop_assert!(diagonal_exact == 1 && inside(diagonal, i, j) && inside(-diagonal, i, j),
                        "cell ({}, {}) in both triangles, {:?}", i, j, table);
                }
                prop_assert_eq!(quad & outer & (m1 | m2).complement(), HemiMask::EMPTY, "pinhole, {:?}", table);
            }
        }
    }

    #[test]
    fn tiny_and_huge_scales_take_the_same_cells() {
        // About 0.08 rad across around the center of cell (21, 18): every edge
        // short, the small-cone path.
        let corners = [(0.31f32, 0.12f32), (0.38, 0.14), (0.34, 0.20)]
            .map(|(u, v)| Vec3::new(u, v, libm::sqrtf(1.0 - u * u - v * v)));
        let table = HalfSpaceTable::default();
        let base = TriangleCone::new(corners[0], corners[1], corners[2], false).unwrap();
        assert_eq!(table.classify_edges(base.corners()).exact, 0b111);
        let expected = base.mask_table(&table);
        assert_eq!(expected, base.mask_reference());
        assert!(expected.get(21, 18));
        // Scales where the determinant stays finite and non-zero.
        for scale in [1e-12f32, 1e-6, 1e6, 1e12] {
            let [a, b, c] = corners.map(|p| p * scale);
            let cone = TriangleCone::new(a, b, c, false).unwrap();
            assert_eq!(cone.mask_table(&table), expected, "scale {scale}");
        }
        // A corner so close to the center that its squared length is subnormal
        // takes the rescaling branch; the cone is then a wide one, and exact.
        let cone = TriangleCone::new(corners[0] * 1e-21, corners[1], corners[2], false).unwrap();
        let all_exact = HalfSpaceTable::new(16).with_exact_edges(core::f32::consts::FRAC_PI_2, 0.0);
        assert_eq!(cone.mask_table(&all_exact), cone.mask_reference());
    }
}
