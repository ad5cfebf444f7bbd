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
use super::table::HalfSpaceTable;

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

    /// The table mask: the AND of the three nearest table entries (the paper's
    /// method). Approximate; see [`HalfSpaceTable`] for its error.
    #[inline]
    pub fn mask_table(&self, table: &HalfSpaceTable) -> HemiMask {
        let (e0, f0) = table.entry(self.normals[0]);
        let (e1, f1) = table.entry(self.normals[1]);
        let (e2, f2) = table.entry(self.normals[2]);
        let mut mask = HemiMask::EMPTY;
        for j in 0..GRID {
            mask.rows[j] =
                (e0.rows[j] ^ f0) & (e1.rows[j] ^ f1) & (e2.rows[j] ^ f2) & HemiMask::VALID.rows[j];
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
        let (i0, i1) = cells_within(u_lo, u_hi)?;
        let (j0, j1) = cells_within(v_lo, v_hi)?;
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
