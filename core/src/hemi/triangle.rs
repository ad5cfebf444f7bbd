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

use glam::{BVec4A, DVec3, Vec3, Vec4, Vec4Swizzles};

use super::half_space::{RowSolver, inside, normalize_exponent};
use super::mask::{CELL_COORD, CELL_Z, GRID, HemiMask, ROW_FIRST, ROW_LAST};
use super::table::{ALL, EdgeClasses, Entry, HalfSpaceTable, and_entries};
use crate::geom::{length, length_f64, sqrt4};

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
    /// `|(a×b)·c|` as computed from the `f32` cross product (before the normals'
    /// power-of-two scaling): the size of the cone, for [`TriangleCone::proven_box`].
    det_abs: f32,
}

/// A triangle that passed culling, its normals oriented but not yet scaled.
#[derive(Clone, Copy)]
struct RawCone {
    corners: [Vec3; 3],
    normals: [Vec3; 3],
    det_abs: f32,
}

impl RawCone {
    /// The culling of [`TriangleCone::new`].
    #[inline(always)]
    fn new(a: Vec3, b: Vec3, c: Vec3, cull_backfaces: bool) -> Result<Self, Culled> {
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
        Ok(RawCone {
            corners: [a, b, c],
            normals,
            det_abs: det.abs(),
        })
    }

    /// ORs the exact mask into `mask`, scaling the normals only when the proven
    /// box holds a cell.
    #[inline(always)]
    fn or_exact_into(self, mask: &mut HemiMask) {
        match proven_box(self.corners, self.det_abs) {
            Proven::Cells(None) => {}
            Proven::Cells(Some(cells)) => self.finish().or_in_proven_box(cells, mask),
            Proven::Wide => self.finish().or_general_into(mask),
            Proven::Tiny => self.finish().or_tiny_into(mask),
        }
    }

    /// The cone, its normals scaled by powers of two (exact, and still exactly
    /// opposite across a shared edge) so every quality sees the same normals.
    #[inline(always)]
    fn finish(self) -> TriangleCone {
        let [m0, m1, m2] = self.normals;
        TriangleCone {
            corners: self.corners,
            normals: [
                normalize_exponent(m0),
                normalize_exponent(m1),
                normalize_exponent(m2),
            ],
            det_abs: self.det_abs,
        }
    }
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
        let raw = RawCone::new(a, b, c, cull_backfaces)?;
        Ok(raw.finish())
    }

    /// `TriangleCone::new(a, b, c, cull_backfaces)?.mask_exact()` ORed into
    /// `mask`, bit for bit, with less work: the proven box needs only the
    /// corners and the determinant, so the normals are scaled only when a cell
    /// center is within reach (for about half of a dense mesh's rasterized
    /// triangles, none is).
    #[inline(always)]
    pub(crate) fn or_exact_into(
        a: Vec3,
        b: Vec3,
        c: Vec3,
        cull_backfaces: bool,
        mask: &mut HemiMask,
    ) -> Result<(), Culled> {
        RawCone::new(a, b, c, cull_backfaces)?.or_exact_into(mask);
        Ok(())
    }

    /// The exact mask of the cone of local corners `a, b, c` ORed into `mask`,
    /// for a triangle that [`classify_four`] found not culled with the
    /// non-empty proven box `(first_i, last_i, first_j, last_j)` (inclusive):
    /// what [`TriangleCone::or_exact_into`] does for it, bit for bit,
    /// without computing the box again. Boxes of at most four columns and two
    /// rows (most of them) are evaluated without loops.
    #[inline(always)]
    pub(crate) fn or_exact_in_box(
        [a, b, c]: [Vec3; 3],
        (i0, i1, j0, j1): (usize, usize, usize, usize),
        mask: &mut HemiMask,
    ) {
        let (ab, bc, ca) = (cross(a, b), cross(b, c), cross(c, a));
        let det = dot(ab, c);
        let normals = if det < 0.0 {
            [-ab, -bc, -ca]
        } else {
            [ab, bc, ca]
        };
        let normals = normals.map(normalize_exponent);
        Self::or_planes_in_box(normals, (i0, i1, j0, j1), mask);
    }

    /// The cells of the inclusive box `(i0, i1, j0, j1)` on the inner side
    /// of the three planes through the center of projection with normals
    /// `normals` ORed into `mask`: [`TriangleCone::or_exact_in_box`]'s
    /// evaluation, for a cone whose box is known and whose (scaled, or
    /// scale-free: [`FourVerdicts::scale_free`]) normals are at hand.
    #[inline(always)]
    pub(crate) fn or_planes_in_box(
        normals: [Vec3; 3],
        (i0, i1, j0, j1): (usize, usize, usize, usize),
        mask: &mut HemiMask,
    ) {
        let planes = normals.map(PlaneRow::new);
        if i1 < i0 + 4 && j1 <= j0 + 1 {
            let columns = HemiMask::columns(i0, i1);
            let bits =
                |j: usize| planes[0].bits(i0, j) & planes[1].bits(i0, j) & planes[2].bits(i0, j);
            // Row j1 is j0 again for one-row boxes: ORing it twice changes nothing.
            mask.rows[j0] |= (bits(j0) << i0) & columns & HemiMask::VALID.rows[j0];
            mask.rows[j1] |= (bits(j1) << i0) & columns & HemiMask::VALID.rows[j1];
            return;
        }
        or_planes_in_proven_box(&planes, (i0, i1 + 1, j0, j1 + 1), mask);
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
        match self.proven_box() {
            Proven::Cells(None) => HemiMask::EMPTY,
            Proven::Cells(Some(cells)) => {
                let mut mask = HemiMask::EMPTY;
                self.or_in_proven_box(cells, &mut mask);
                mask
            }
            Proven::Wide => {
                let mut mask = HemiMask::EMPTY;
                self.or_general_into(&mut mask);
                mask
            }
            Proven::Tiny => {
                let mut mask = HemiMask::EMPTY;
                self.or_tiny_into(&mut mask);
                mask
            }
        }
    }

    /// ORs the exact mask of a cone too small for the corners' proven box into
    /// `mask`: through the normals' proven box ([`proven_box_from_normals`]),
    /// then, for cones whose planes nearly share a line (a triangle far
    /// smaller than a cell, seen from afar), the few cells around that line
    /// ([`thin_cone_axis`]), or every row for slivers and extreme scales.
    #[inline(never)]
    fn or_tiny_into(&self, mask: &mut HemiMask) {
        match proven_box_from_normals(self.normals) {
            Proven::Cells(None) => {}
            Proven::Cells(Some(cells)) => self.or_in_proven_box(cells, mask),
            Proven::Wide => self.or_general_into(mask),
            Proven::Tiny => match thin_cone_axis(self.normals) {
                Some((axis, reach)) => self.or_near_axis(axis, reach, mask),
                None => *mask |= self.mask_every_row(),
            },
        }
    }

    /// ORs into `mask` the cells within `reach` (in disk coordinates) of the
    /// directions `axis` and `-axis` that pass the three predicates: every
    /// cell the predicate sets, when [`thin_cone_axis`] gave them.
    #[cold]
    fn or_near_axis(&self, axis: DVec3, reach: f64, mask: &mut HemiMask) {
        // The 1e-6 covers rounding the axis and the reach to `f32`.
        let margin = reach as f32 + 1e-6;
        for end in [axis, -axis] {
            let (x, y) = (end.x as f32, end.y as f32);
            let (i0, i_end) = cell_range(x, x, margin);
            let (j0, j_end) = cell_range(y, y, margin);
            if i0 < i_end && j0 < j_end {
                self.or_in_proven_box((i0, i_end, j0, j_end), mask);
            }
        }
    }

    /// Every row solved for the three planes: exact whatever the cone (the row
    /// solver is the half-space predicate), for the rare cones too small or
    /// too extreme for any box ([`Proven::Tiny`]), whose rounded normals can
    /// bound a cone far from the triangle.
    #[cold]
    fn mask_every_row(&self) -> HemiMask {
        let solvers = self.normals.map(RowSolver::new);
        let mut mask = HemiMask::EMPTY;
        for (j, row) in mask.rows.iter_mut().enumerate() {
            let mut bits = solvers[0].row(j);
            if bits != 0 {
                bits &= solvers[1].row(j);
                if bits != 0 {
                    bits &= solvers[2].row(j);
                }
            }
            *row = bits;
        }
        mask
    }

    /// [`TriangleCone::mask_exact`] without the proven box: the box of the cone
    /// the normals bound ([`TriangleCone::cell_box`]), solved row by row or cell
    /// by cell, for every cone: the slow twin of the proven boxes and of the
    /// wide cones' path ([`TriangleCone::or_general_into`], the same box
    /// evaluated four cells at a time).
    #[cfg(test)]
    pub(crate) fn mask_exact_general(&self) -> HemiMask {
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

    /// A box of cells outside which, provably, no cell passes the three `f32`
    /// predicates ([`Proven::Cells`]; `None` when it holds no cell center, the
    /// common case for the small, far triangles of a dense mesh), or why there
    /// is none: [`Proven::Wide`] for cones with corners more than 60° apart,
    /// [`Proven::Tiny`] for cones too small (`D < 1e-5`, then the rounded normals
    /// may bound a cone far from the triangle) or too extreme in scale.
    ///
    /// Why no cell outside passes. Let `â, b̂, ĉ` be the unit corners, `g` their
    /// mean, `D = |det(â, b̂, ĉ)|` and `u = 2⁻²⁴`. The `f32` normal `m = fl(a×b)`
    /// is off by at most `3.5u |a||b|`, and the predicate `fl(m·d)` by `3u |m|`,
    /// so a cell `d` that passes has `(â×b̂)·d >= -6.5u` (likewise for the other
    /// edges; the power-of-two scaling and the orientation flip are exact, and
    /// with corner lengths in `[1e-9, 1e9]` no product underflows or overflows
    /// noticeably). Writing `d = α â + β b̂ + γ ĉ` gives `(â×b̂)·d = γ D`, so every
    /// weight is at least `-τ`, `τ = 6.5u / D`. Then `d = σ p - 3τ g` with `p` in
    /// the flat triangle `T` of the unit corners and `σ >= 1 - u - 3τ`, so `d` is
    /// a positive multiple of `p + κ (p - g)` with `κ <= 3τ / (1 - u - 6τ)`: `d`
    /// is in the cone of `T` scaled by `1 + κ` about `g`, whose points are within
    /// `e = κ ℓ` of `T` (`ℓ` the longest chord between corners). Every point of
    /// `T` has length at least `sqrt(cos_min) >= cos_min` (pairwise cosines at
    /// least `cos_min >= 0`), so those of the scaled one at least `n = cos_min -
    /// e`, and at most `1 + e`: the disk coordinates of a passing cell are within
    /// `e + (1 + e) max(1/n - 1, e)` of the corners' box. Every quantity is
    /// bounded from the safe side: the corners come from an inverse square root
    /// good to 3u (a correctly rounded square root and division), `D` from the computed determinant less
    /// its rounding, and `cos_min` less the cosines' rounding; [`cell_range`]
    /// keeps the cells whose exact center coordinate is in the widened range (its
    /// own rounding is far inside the extra 5e-5).
    #[inline(always)]
    fn proven_box(&self) -> Proven {
        proven_box(self.corners, self.det_abs)
    }

    /// ORs the exact mask of a cone inside its proven box (columns
    /// `i0..i_end`, rows `j0..j_end`, see [`TriangleCone::proven_box`]) into
    /// `mask`, evaluating the predicate on four cells at a time ([`PlaneRow`]:
    /// the same products and sums in the same order, lane by lane, so the same
    /// bits). Branch-free per row; cheaper than solving rows even for boxes as
    /// wide as the grid.
    #[inline(always)]
    fn or_in_proven_box(
        &self,
        (i0, i_end, j0, j_end): (usize, usize, usize, usize),
        mask: &mut HemiMask,
    ) {
        or_planes_in_proven_box(
            &self.normals.map(PlaneRow::new),
            (i0, i_end, j0, j_end),
            mask,
        );
    }

    /// `TriangleCone::mask_exact_general` (the tests' twin) ORed into
    /// `mask`, its box evaluated four cells at a time: the path of wide
    /// cones.
    #[inline(never)]
    fn or_general_into(&self, mask: &mut HemiMask) {
        if let Some(CellBox { i0, i1, j0, j1 }) = self.cell_box() {
            self.or_in_proven_box((i0, i1 + 1, j0, j1 + 1), mask);
        }
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
    /// - every edge exact: the exact mask ([`TriangleCone::mask_exact`]), the
    ///   three exact predicates on every cell;
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
    /// table's error of it, so leaving them out drops only table errors. With
    /// the default rule, most triangles of a dense mesh seen from its vertices
    /// have all edges short and never touch the table: they cost what exact
    /// quality does, and the clustered loop gives them its fast path.
    #[inline]
    pub fn mask_table(&self, table: &HalfSpaceTable) -> HemiMask {
        if !table.has_exact_edges() {
            return self.mask_from_table(table);
        }
        let classes = table.classify_edges(self.corners);
        if classes.exact == 0 {
            return self.mask_from_table(table);
        }
        if classes.exact == 0b111 {
            // No table plane: the exact mask (the three exact predicates on
            // every cell the cone can reach).
            return self.mask_exact();
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
            // Two planes each off by up to the table's error move the corner
            // where they meet by up to error / sin(α/2), α the corner's
            // interior angle (cos α = -n_k · n_l for the inward edge normals):
            // more than the error itself at every corner narrower than 60°.
            let unit = self.normals.map(|m| m * (1.0 / length(m)));
            let least_dot = dot(unit[0], unit[1])
                .min(dot(unit[1], unit[2]))
                .min(dot(unit[2], unit[0]));
            let sin_half = crate::geom::sqrtf((0.5 * (1.0 + least_dot)).max(0.0));
            (table.max_error() / sin_half.max(1e-3)).min(4.0)
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
                p * (1.0 / length(p))
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
        let unit = self.normals.map(|m| m * (1.0 / length(m)));
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
            let p = p * (1.0 / length(p));
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

/// [`TriangleCone::proven_box`] of `corners` and `|det|`.
#[inline(always)]
fn proven_box(corners: [Vec3; 3], det_abs: f32) -> Proven {
    let [a, b, c] = corners;
    // The corners in lanes (a, b, c, a): one square root and one division for
    // all three lengths, no dependent chains per corner.
    let xs = Vec4::new(a.x, b.x, c.x, a.x);
    let ys = Vec4::new(a.y, b.y, c.y, a.y);
    let zs = Vec4::new(a.z, b.z, c.z, a.z);
    let lengths_sq = xs * xs + ys * ys + zs * zs;
    let in_range = lengths_sq.cmpge(Vec4::splat(1e-18)) & lengths_sq.cmple(Vec4::splat(1e18));
    if !in_range.all() {
        return Proven::Tiny;
    }
    // Correctly rounded square root and division: 1/|p| to within 3u.
    let inv = Vec4::ONE / sqrt4(lengths_sq);
    // det(â, b̂, ĉ) from below: the computed |det| is within 6.5u |a||b||c| of
    // the true one, and the product of the inverses within 1e-5 of
    // 1 / (|a||b||c|). Weights of passing cells are at least -6.5u / D
    // (3.9e-7 / D, rounded up).
    let d_lo = det_abs * (inv.x * inv.y * inv.z) * (1.0 - 1e-4) - 1e-6;
    box_of_corners(xs * inv, ys * inv, zs * inv, 4e-7 / d_lo, 0.0)
}

/// What [`classify_four`] found about four triangles, as lane bitmasks (bit
/// `k` for lane `k`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct FourVerdicts {
    /// [`RawCone::new`] culls the lane as [`Culled::Degenerate`].
    pub(crate) degenerate: u32,
    /// Not degenerate, and culled as [`Culled::BackFacing`].
    pub(crate) back_facing: u32,
    /// Not culled, and the proven box holds no cell center
    /// ([`Proven::Cells`]`(None)`): the cone sets no cell.
    pub(crate) empty: u32,
    /// Not culled, and the proven box is [`Proven::Cells`]: lanes of `cells`
    /// hold it (empty or not).
    pub(crate) boxed: u32,
    /// Per lane, the proven box's first and last column and first and last
    /// row (inclusive, whole numbers in `0..=31` when the box is not empty).
    pub(crate) cells: [Vec4; 4],
    /// Lanes whose box is not empty, at most four columns wide and two rows
    /// high, and whose normals need no power-of-two scaling (see
    /// [`classify_four`]): `window` holds their mask.
    pub(crate) small: u32,
    /// Per lane, the predicate's bits on the four columns from the box's
    /// first one, in the box's first row (`[k][0]`) and the next (`[k][1]`);
    /// meaningful for `small` lanes, before masking with the box and
    /// [`HemiMask::VALID`].
    pub(crate) window: [[u32; 2]; 4],
    /// Lanes whose normals need no power-of-two scaling
    /// ([`ConesFour::scale_free`]): the predicate on `normals` is the exact
    /// mask's, bit for bit.
    pub(crate) scale_free: u32,
    /// The inward edge normals `a×b`, `b×c`, `c×a` of [`ConesFour`], x, y
    /// and z lanes.
    pub(crate) normals: [[Vec4; 3]; 3],
}

impl FourVerdicts {
    /// Lane `k`'s three inward edge normals.
    #[inline(always)]
    pub(crate) fn lane_normals(&self, k: usize) -> [Vec3; 3] {
        // Written out: `array::map` is not reliably inlined here.
        let lane =
            |[x, y, z]: [Vec4; 3]| Vec3::new(x.to_array()[k], y.to_array()[k], z.to_array()[k]);
        [
            lane(self.normals[0]),
            lane(self.normals[1]),
            lane(self.normals[2]),
        ]
    }
}

/// Four triangles' cones as [`RawCone::new`] culls them and orients their
/// edge planes: the part of [`classify_four`] that the per-cell path of the
/// traversal ([`ConesFour::inside`]) shares with it.
#[derive(Clone, Copy)]
pub(crate) struct ConesFour {
    /// `det(a, b, c)` per lane.
    det: Vec4,
    /// Lanes [`RawCone::new`] culls as [`Culled::Degenerate`].
    pub(crate) degenerate: u32,
    /// Lanes not degenerate and culled as [`Culled::BackFacing`].
    pub(crate) back_facing: u32,
    /// The inward edge normals `a×b`, `b×c`, `c×a` (negated where the
    /// determinant is negative, which is exact), x, y and z lanes.
    normals: [[Vec4; 3]; 3],
    /// Lanes whose normals need no power-of-two scaling: every component is
    /// zero or within `2^±60` in size. Then every product with a cell
    /// coordinate (at least 1/32 in size) and its scaled twin are in the
    /// normal range, so each product, and each sum of them (an exact
    /// cancellation included), is [`TriangleCone`]'s scaled one times the
    /// same power of two, and has the same sign: the predicate on these
    /// normals is the exact mask's, bit for bit.
    pub(crate) scale_free: u32,
}

impl ConesFour {
    /// The cones of the triangles with local corners `corners` (lanes as in
    /// [`classify_four`]), each lane the scalar code's expressions in the
    /// same order.
    #[inline(always)]
    pub(crate) fn new(corners: [[Vec4; 3]; 3], cull_backfaces: bool) -> ConesFour {
        let [[ax, ay, az], [bx, by, bz], [cx, cy, cz]] = corners;
        // cross(p, q), lane by lane.
        let cross = |px: Vec4, py: Vec4, pz: Vec4, qx: Vec4, qy: Vec4, qz: Vec4| {
            (py * qz - qy * pz, pz * qx - qz * px, px * qy - qx * py)
        };
        let (abx, aby, abz) = cross(ax, ay, az, bx, by, bz);
        let (bcx, bcy, bcz) = cross(bx, by, bz, cx, cy, cz);
        let (cax, cay, caz) = cross(cx, cy, cz, ax, ay, az);
        let det = abx * cx + aby * cy + abz * cz;
        let finite = Vec4::is_finite_mask;
        let all_finite = finite(det)
            & finite(abx + bcx + cax)
            & finite(aby + bcy + cay)
            & finite(abz + bcz + caz);
        let zero = Vec4::ZERO;
        let is_zero = |x: Vec4, y: Vec4, z: Vec4| x.cmpeq(zero) & y.cmpeq(zero) & z.cmpeq(zero);
        let degenerate = !all_finite
            | det.cmpeq(zero)
            | is_zero(abx, aby, abz)
            | is_zero(bcx, bcy, bcz)
            | is_zero(cax, cay, caz);
        let degenerate = degenerate.bitmask();
        let back_facing = if cull_backfaces {
            det.cmpgt(zero).bitmask() & !degenerate
        } else {
            0
        };
        let flip = det.cmplt(zero);
        let orient = |v: Vec4| Vec4::select(flip, -v, v);
        let normals = [
            [orient(abx), orient(aby), orient(abz)],
            [orient(bcx), orient(bcy), orient(bcz)],
            [orient(cax), orient(cay), orient(caz)],
        ];
        let unscaled_ok = |v: Vec4| {
            let a = v.abs();
            a.cmpeq(zero)
                | (a.cmpge(Vec4::splat(SCALE_FREE_MIN)) & a.cmple(Vec4::splat(SCALE_FREE_MAX)))
        };
        let mut scale_free = glam::BVec4A::splat(true);
        for m in &normals {
            for &c in m {
                scale_free &= unscaled_ok(c);
            }
        }
        ConesFour {
            det,
            degenerate,
            back_facing,
            normals,
            scale_free: scale_free.bitmask(),
        }
    }

    /// Lanes whose three planes hold the cell center `(u, v, z)` (splatted
    /// [`CELL_COORD`] and [`CELL_Z`] values): for `scale_free` lanes, whether
    /// the exact mask sets the cell ([`inside`]'s expression).
    #[inline(always)]
    pub(crate) fn inside(&self, u: Vec4, v: Vec4, z: Vec4) -> u32 {
        let mut inside = glam::BVec4A::splat(true);
        for [mx, my, mz] in self.normals {
            inside &= ((mx * u + my * v) + mz * z).cmpge(Vec4::ZERO);
        }
        inside.bitmask()
    }
}

/// [`RawCone::new`]'s culling (after the horizon test) and
/// [`proven_box`]'s box for four triangles at once, lane `k`
/// evaluating the same `f32` expressions in the same order as the scalar code
/// on triangle `k`, so the same verdicts. `corners[k]` holds the x, y and z
/// lanes of corner `k` (local, relative to the center of projection); every
/// corner's squared length must be in `[1e-18, 1e18]` (else [`proven_box`]
/// gives up on the triangle, which the caller sends down the one-triangle
/// path). Throughput instead of latency: the square roots and divisions of
/// four boxes overlap.
#[inline(always)]
pub(crate) fn classify_four(corners: [[Vec4; 3]; 3], cull_backfaces: bool) -> FourVerdicts {
    let [[ax, ay, az], [bx, by, bz], [cx, cy, cz]] = corners;
    let cones = ConesFour::new(corners, cull_backfaces);
    let (det, degenerate, back_facing) = (cones.det, cones.degenerate, cones.back_facing);
    let zero = Vec4::ZERO;
    // proven_box and box_of_corners, lane by lane.
    // The corners' unit directions and inverse lengths, as proven_box
    // computes them: |p|² = (x² + y²) + z², a correctly rounded square root
    // and division, then the products.
    let unit = |x: Vec4, y: Vec4, z: Vec4| {
        let inv = Vec4::ONE / sqrt4(x * x + y * y + z * z);
        (x * inv, y * inv, z * inv, inv)
    };
    let (uax, uay, uaz, ia) = unit(ax, ay, az);
    let (ubx, uby, ubz, ib) = unit(bx, by, bz);
    let (ucx, ucy, ucz, ic) = unit(cx, cy, cz);
    let d_lo = det.abs() * (ia * ib * ic) * (1.0 - 1e-4) - Vec4::splat(1e-6);
    let tau = Vec4::splat(4e-7) / d_lo;
    let tau_ok = tau.cmpge(zero) & tau.cmple(Vec4::splat(1.0 / 12.0));
    let cab = uax * ubx + uay * uby + uaz * ubz;
    let cbc = ubx * ucx + uby * ucy + ubz * ucz;
    let cca = ucx * uax + ucy * uay + ucz * uaz;
    let cos_min = cab.min(cbc).min(cca) - Vec4::splat(1e-4);
    let cos_ok = cos_min.cmpge(Vec4::splat(0.5));
    let kappa = 6.01 * tau;
    let chord = sqrt4(Vec4::splat(2.0) - 2.0 * cos_min) + Vec4::splat(1e-5);
    let e = kappa * chord;
    let n = cos_min - e;
    let n_ok = !n.cmplt(Vec4::splat(0.5));
    let one = Vec4::ONE;
    let bulge = ((one - n) * (one + 2.0 * (one - n))).max(e);
    let margin = e + (one + e) * bulge + Vec4::splat(6e-5);
    let (first_u, last_u) = cell_range_four(uax.min(ubx).min(ucx), uax.max(ubx).max(ucx), margin);
    let (first_v, last_v) = cell_range_four(uay.min(uby).min(ucy), uay.max(uby).max(ucy), margin);
    let no_cell = first_u.cmpgt(last_u) | first_v.cmpgt(last_v);
    let boxed = (tau_ok & cos_ok & n_ok).bitmask() & !degenerate & !back_facing;
    // Below every cell center: box_of_corners' test, each arc a lane set.
    let (ab_low, ab_z) = arc_below_cells([uax, uay, uaz], [ubx, uby, ubz], cab, e);
    let (bc_low, bc_z) = arc_below_cells([ubx, uby, ubz], [ucx, ucy, ucz], cbc, e);
    let (ca_low, ca_z) = arc_below_cells([ucx, ucy, ucz], [uax, uay, uaz], cca, e);
    let below_cells = ab_low & bc_low & ca_low & zenith_outside(ab_z, bc_z, ca_z);
    let empty = boxed & (no_cell | below_cells).bitmask();
    // Small boxes: the three predicates on a window of 4 x 2 cells, all four
    // lanes at once, on the normals of ConesFour (scale-free lanes only).
    let narrow = (last_u - first_u).cmple(Vec4::splat(3.0)) & (last_v - first_v).cmple(Vec4::ONE);
    let small = narrow.bitmask() & cones.scale_free & boxed & !empty;
    let mut window = [[0u32; 2]; 4];
    if small != 0 {
        // Cell centers as CELL_COORD and CELL_Z give them, bit for bit:
        // (k + 0.5)/16 - 1 is exact, and so is 1 - u² - v² (multiples of
        // 1/1024 below 2), whose correctly rounded square root CELL_Z holds.
        let coordinate = |k: Vec4| (k + Vec4::splat(0.5)) * (1.0 / 16.0) - one;
        // Bit 16 dj + 4 di + k: window cell (di, dj) of lane k.
        let mut bits = 0u32;
        for (dj, row_v) in [first_v, first_v + one].into_iter().enumerate() {
            let v = coordinate(row_v);
            for di in 0..4 {
                let u = coordinate(first_u + Vec4::splat(di as f32));
                let z = sqrt4((one - u * u) - v * v);
                bits |= cones.inside(u, v, z) << (16 * dj + 4 * di);
            }
        }
        // Transpose each 4 x 4 block of bits (delta swaps) to bit
        // 16 dj + 4 k + di: lane k's row dj is then one nibble.
        let t = (bits ^ (bits >> 3)) & 0x0a0a_0a0a;
        let bits = bits ^ t ^ (t << 3);
        let t = (bits ^ (bits >> 6)) & 0x00cc_00cc;
        let bits = bits ^ t ^ (t << 6);
        for (k, lane) in window.iter_mut().enumerate() {
            *lane = [bits >> (4 * k) & 0xf, bits >> (16 + 4 * k) & 0xf];
        }
    }
    FourVerdicts {
        degenerate,
        back_facing,
        empty,
        boxed,
        cells: [first_u, last_u, first_v, last_v],
        small,
        window,
        scale_free: cones.scale_free,
        normals: cones.normals,
    }
}

/// Normal components with no power-of-two scaling in the small-box window
/// of [`classify_four`] are zero or within `[2^-60, 2^60]` in size.
const SCALE_FREE_MIN: f32 = f32::from_bits((127 - 60) << 23);
const SCALE_FREE_MAX: f32 = f32::from_bits((127 + 60) << 23);

/// [`cell_range`]`(lo, hi, margin)` on four lanes (finite inputs), in `f32`
/// alone, as the first and last column (inclusive; empty when first > last):
/// [`cell_range`]'s `first` is `max(ceil(lo'), 0)` and its `end` is
/// `min(floor(hi') + 1, 32)` for the clamped fractional columns `lo'`, `hi'`
/// computed here by the same expressions. Floors and ceilings of values in
/// `[-1, 32]` are exact: adding and subtracting `1.5 * 2^23` rounds to the
/// nearest integer, then one comparison corrects it.
#[inline(always)]
fn cell_range_four(lo: Vec4, hi: Vec4, margin: Vec4) -> (Vec4, Vec4) {
    let (below, above) = (Vec4::splat(-1.0), Vec4::splat(32.0));
    let lo = ((lo - margin) * 16.0 + Vec4::splat(15.5))
        .min(above)
        .max(below);
    let hi = ((hi + margin) * 16.0 + Vec4::splat(15.5))
        .min(above)
        .max(below);
    // 1.5 * 2^23: sums with values in [-1, 32] lie in [2^23, 2^24), where
    // the spacing of f32 is exactly 1.
    let magic = Vec4::splat(12_582_912.0);
    let (lo_near, hi_near) = ((lo + magic) - magic, (hi + magic) - magic);
    let one = Vec4::ONE;
    let ceil_lo = lo_near + Vec4::select(lo_near.cmplt(lo), one, Vec4::ZERO);
    let floor_hi = hi_near - Vec4::select(hi_near.cmpgt(hi), one, Vec4::ZERO);
    let first = ceil_lo.max(Vec4::ZERO);
    let last = floor_hi.min(Vec4::splat((GRID - 1) as f32));
    (first, last)
}

/// The proven box of a cone from its scaled normals, for cones too small for
/// [`proven_box`] (whose bound grows as the inverse square of the size) but
/// not slivers: only the predicate's own rounding is left to bound.
///
/// The predicate sees the cone `K'` of the `f32` normals `N_k` exactly; a cell
/// `d` passing `fl(N_k·d) >= 0` has `n̂_k·d >= -3.1u` (rounding of the dot,
/// and of underflowing products, which are tiny against `|N_k| >= 1`). The
/// corners of `K'` are `N_0×N_1`, `N_1×N_2`, `N_2×N_0` (positive multiples
/// of the triangle's corners when `det(N) > 0`, which `D_n` below proves),
/// and the weight of a passing cell on the corner opposite plane `k` is at
/// least `-3.1u / (n̂_k·r̂)`, where `n̂_k·r̂ = D_n / |n̂_l×n̂_m| >= D_n =
/// det(n̂_0, n̂_1, n̂_2)`: the argument of [`TriangleCone::proven_box`] with
/// `τ = 3.1u / D_n` (about `u / size` for a small triangle, against
/// `u / size²` from the corners). The unit normals come from a correctly
/// rounded square root and division (3u), so the computed `D_n` is within
/// 2e-6 and each computed corner direction within `1.5e-6 / sin θ + 1e-6`
/// for the angle `θ` between its two planes; corners between planes closer
/// than 1e-3 rad (slivers) give up.
#[inline(always)]
fn proven_box_from_normals(normals: [Vec3; 3]) -> Proven {
    let [m0, m1, m2] = normals;
    let xs = Vec4::new(m0.x, m1.x, m2.x, m0.x);
    let ys = Vec4::new(m0.y, m1.y, m2.y, m0.y);
    let zs = Vec4::new(m0.z, m1.z, m2.z, m0.z);
    // Scaled normals have their largest component in [1, 2): no range issue.
    let inv = Vec4::ONE / sqrt4(xs * xs + ys * ys + zs * zs);
    let (nx, ny, nz) = (xs * inv, ys * inv, zs * inv);
    // Corners in lanes (n0×n1, n1×n2, n2×n0, n0×n1).
    let (px, py, pz) = (nx.yzxy(), ny.yzxy(), nz.yzxy());
    let cx = ny * pz - py * nz;
    let cy = nz * px - pz * nx;
    let cz = nx * py - px * ny;
    // det(n̂0, n̂1, n̂2) = (n̂0×n̂1)·n̂2, lane 0 against n̂2 (lane 2 of n).
    let dn_lo = cx.x * nx.z + cy.x * ny.z + cz.x * nz.z - 2e-6;
    let sines_sq = cx * cx + cy * cy + cz * cz;
    let sin_min = crate::geom::sqrtf(sines_sq.min_element()) - 7e-7;
    if dn_lo.is_nan() || dn_lo <= 0.0 || sin_min.is_nan() || sin_min < 1e-3 {
        return Proven::Tiny;
    }
    let inv_sin = Vec4::ONE / sqrt4(sines_sq);
    let corner_error = 1.5e-6 / sin_min + 1e-6;
    box_of_corners(
        cx * inv_sin,
        cy * inv_sin,
        cz * inv_sin,
        2e-7 / dn_lo,
        corner_error,
    )
}

/// Largest distance, in disk coordinates, from a thin cone's axis to the
/// cells [`thin_cone_axis`] lets [`TriangleCone::or_near_axis`] test: beyond
/// it every row is solved (a few cells either side of the axis).
const THIN_REACH: f64 = 0.05;

/// Bound on `-n̂·d` for a cell direction `d` passing the predicate
/// `fl(N·d) >= 0` ([`inside`]): the three-term `f32` dot is within
/// `γ₃ Σ|N_i d_i| <= 1.8e-7 |N|` of `N·d` (`|d|` within 2e-7 of 1, products
/// underflowing by at most `2^-149` against `|N| >= 1`); five times that.
const PREDICATE_SLACK: f64 = 1e-6;

/// For a cone whose three planes nearly share a line (the edge planes of a
/// triangle far smaller than a cell, or seen from far away, where
/// [`proven_box_from_normals`] cannot orient its corners): that line's
/// direction `e` and a reach `r` such that every cell the predicate sets is
/// within `r` of `e` or `-e` in disk coordinates; `None` when the normals do
/// not surround the line with a margin, or the reach exceeds [`THIN_REACH`].
///
/// Why: with unit normals `n̂_k` (in `f64`, exact to 1e-15 from the `f32`
/// ones), `e` the unit cross product of the two most distinct of them and
/// `δ = max |n̂_k·e|`, write a passing unit direction `d = α e + β t`, `t`
/// a unit vector perpendicular to `e`. The normals' projections onto the
/// plane perpendicular to `e` surround it with largest angular gap `g < π`,
/// so `-t` lies in a gap and some projection is within `g/2` of it:
/// `n̂_k·t <= -ρ cos(g/2)`, `ρ = sqrt(1 - δ²)` the shortest projection
/// (`cos(g/2)` is the least distance from `e` to the chords between the unit
/// projections, computed without angles). The
/// predicate gives `n̂_k·d = α n̂_k·e + β n̂_k·t >= -ε`
/// ([`PREDICATE_SLACK`]), so `β <= (ε + δ) / (ρ cos(g/2))`: `d` is within
/// angle `asin β` of `e` or `-e`, and its disk coordinates within
/// `β sqrt(1 + β²)` of theirs (the 1 % and 1e-6 added below cover that and
/// `|d| != 1`). The cone's own size enters through `δ`.
#[inline(never)]
fn thin_cone_axis(normals: [Vec3; 3]) -> Option<(DVec3, f64)> {
    let unit = normals.map(|m| {
        let m = m.as_dvec3();
        m / length_f64(m)
    });
    if !unit.iter().all(|n| n.is_finite()) {
        return None;
    }
    let crosses = [
        unit[0].cross(unit[1]),
        unit[1].cross(unit[2]),
        unit[2].cross(unit[0]),
    ];
    let widest = crosses
        .into_iter()
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))?;
    let length = length_f64(widest);
    if length <= 1e-6 {
        return None;
    }
    let axis = widest / length;
    let delta = unit.iter().map(|n| n.dot(axis).abs()).fold(0.0, f64::max) + 1e-12;
    if delta >= 0.5 {
        return None;
    }
    // The projections onto the plane perpendicular to the axis, unit: they
    // surround it when they turn the same way pair after pair, and the
    // chord between neighbours at angle γ passes at cos(γ/2) from it.
    let projected = unit.map(|n| {
        let p = n - axis * n.dot(axis);
        p / length_f64(p)
    });
    let mut margin = f64::INFINITY;
    let mut turns = [0.0; 3];
    for k in 0..3 {
        let (p, q) = (projected[k], projected[(k + 1) % 3]);
        turns[k] = p.cross(q).dot(axis);
        margin = margin.min(turns[k].abs() / length_f64(p - q));
    }
    let surround = turns.iter().all(|&t| t > 0.0) || turns.iter().all(|&t| t < 0.0);
    // Less the rounding of the f64 steps, far below it.
    let margin = margin - 1e-9;
    if !surround || margin <= 1e-3 {
        return None;
    }
    let rho = crate::geom::sqrt(1.0 - delta * delta);
    let beta = (PREDICATE_SLACK + delta) / (rho * margin);
    let reach = 1.01 * beta + 1e-6;
    (reach <= THIN_REACH).then_some((axis, reach))
}

/// The box of the cells whose directions can have every barycentric weight
/// at least `-tau` against unit corners (lanes `(a, b, c, a)` of `ux, uy, uz`,
/// each coordinate within `corner_error` of the true one): see
/// [`TriangleCone::proven_box`]. None for a triangle lying wholly below the
/// lowest cell centers ([`below_every_cell`]): a surface's own triangles
/// around a receiver often graze its horizon there, their corners' box
/// holding rim cells they cannot reach. `tau <= 1/12` keeps `κ = 3τ / (1 - u - 6τ)`
/// below `6.01 τ`.
#[inline(always)]
fn box_of_corners(ux: Vec4, uy: Vec4, uz: Vec4, tau: f32, corner_error: f32) -> Proven {
    if tau.is_nan() || !(0.0..=1.0 / 12.0).contains(&tau) {
        return Proven::Tiny;
    }
    // Lanes (a·b, b·c, c·a, a·b), less their error (the corners' error twice,
    // and 3u per corner and the dot's rounding, far inside 1e-4).
    let cosines = ux * ux.yzxy() + uy * uy.yzxy() + uz * uz.yzxy();
    let cos_min = cosines.min_element() - 1e-4 - 2.0 * corner_error;
    if cos_min.is_nan() || cos_min < 0.5 {
        return Proven::Wide;
    }
    let kappa = 6.01 * tau;
    // The longest chord, from the smallest cosine (which is below the true
    // one); the 1e-5 covers the square root's rounding.
    let chord = crate::geom::sqrtf(2.0 - 2.0 * cos_min) + 1e-5;
    let e = kappa * chord;
    let n = cos_min - e;
    if n < 0.5 {
        return Proven::Wide;
    }
    if below_every_cell(
        [ux, uy, uz],
        [ux.yzxy(), uy.yzxy(), uz.yzxy()],
        cosines,
        e + corner_error,
    ) {
        return Proven::Cells(None);
    }
    // 1/n - 1 = (1 - n)/n <= (1 - n)(1 + 2(1 - n)) for n >= 0.5, without a
    // division (the bound is (1 - n)(1 + (1 - n)/n)).
    let bulge = ((1.0 - n) * (1.0 + 2.0 * (1.0 - n))).max(e);
    // 1e-5 for the corners' rounding, 5e-5 for the range's.
    let margin = e + (1.0 + e) * bulge + 6e-5 + corner_error;
    let (i0, i_end) = cell_range(ux.min_element(), ux.max_element(), margin);
    let (j0, j_end) = cell_range(uy.min_element(), uy.max_element(), margin);
    Proven::Cells((i0 < i_end && j0 < j_end).then_some((i0, i_end, j0, j_end)))
}

/// The lowest elevation of a valid cell's center, as `z` on the unit
/// sphere, rounded down: the outermost centers have squared disk radius
/// `1018 / 1024`, so `z = √(6 / 1024) = 0.076547…`.
const LOWEST_CELL_Z: f32 = 0.0765;

// The constant is the lowest valid center's `z` in the cells' own table,
// rounded down by less than the margin `arc_below_cells` keeps.
const _: () = {
    let mut lowest = 1.0f32;
    let mut j = 0;
    while j < GRID {
        let mut i = 0;
        while i < GRID {
            let z = CELL_Z[j][i];
            if z > 0.0 && z < lowest {
                lowest = z;
            }
            i += 1;
        }
        j += 1;
    }
    assert!(LOWEST_CELL_Z <= lowest && lowest - LOWEST_CELL_Z < 1e-4);
};

/// Per lane, whether the great-circle arc from unit corner `p` to unit corner
/// `q` (cosine `cosine` between them, under 60°) stays below elevation
/// `LOWEST_CELL_Z` with room for `slack` (a passing cell's distance from the
/// cone, [`box_of_corners`]'s `e`): both ends below it, and the circle's
/// highest point either off the arc or itself below it. The highest point
/// `h` of the circle with pole `g = p × q` lies strictly between `p` and `q`
/// exactly when `q_z - (p·q) p_z` and `p_z - (p·q) q_z` are both positive
/// (`(p × z)·g` and `(z × q)·g`), and its elevation is `|g_xy| / |g|`. Near
/// zero, a sign is taken as the one that keeps the triangle. Also gives,
/// per lane, `g_z` for [`zenith_outside`].
#[inline(always)]
fn arc_below_cells(p: [Vec4; 3], q: [Vec4; 3], cosine: Vec4, slack: Vec4) -> (BVec4A, Vec4) {
    let [px, py, pz] = p;
    let [qx, qy, qz] = q;
    // A cell at distance `slack` from a point of elevation `w` (over the
    // flat triangle's distance from the center, at least 1/2) is at most
    // about 4 slack higher; 1e-4 covers the unit corners' rounding.
    let limit = Vec4::splat(LOWEST_CELL_Z) - 5.0 * slack - Vec4::splat(1e-4);
    let low_ends = pz.cmplt(limit) & qz.cmplt(limit) & limit.cmpgt(Vec4::splat(0.01));
    let off = Vec4::splat(-1e-5);
    let top_between = (qz - cosine * pz).cmpgt(off) & (pz - cosine * qz).cmpgt(off);
    let gx = py * qz - pz * qy;
    let gy = pz * qx - px * qz;
    let gz = px * qy - py * qx;
    let gxy = gx * gx + gy * gy;
    let top_high = gxy.cmpge((gxy + gz * gz) * (limit * limit * 0.999));
    (low_ends & !(top_between & top_high), gz)
}

/// Per lane, whether the zenith is certainly outside the triangle whose
/// arcs' poles have `z` components `ab`, `bc` and `ca` ([`arc_below_cells`]):
/// some clearly negative, some clearly positive. On the sphere `z` has no
/// maximum but the zenith, so a triangle without it is highest on its arcs.
#[inline(always)]
fn zenith_outside(ab: Vec4, bc: Vec4, ca: Vec4) -> BVec4A {
    let apart = Vec4::splat(1e-5);
    let below = ab.cmplt(-apart) | bc.cmplt(-apart) | ca.cmplt(-apart);
    let above = ab.cmpgt(apart) | bc.cmpgt(apart) | ca.cmpgt(apart);
    below & above
}

/// Whether no cell center can be set by the triangle with unit corners in
/// lanes `(a, b, c, a)` of `p` (and `(b, c, a, b)` of `q`, `cosines` their
/// lane-wise cosines): every arc below the lowest centers' elevation and the
/// zenith outside it, so every point of it is below those centers.
#[inline(always)]
fn below_every_cell(p: [Vec4; 3], q: [Vec4; 3], cosines: Vec4, slack: f32) -> bool {
    let (low, gz) = arc_below_cells(p, q, cosines, Vec4::splat(slack));
    low.all() && zenith_outside(gz.xxxx(), gz.yyyy(), gz.zzzz()).all()
}

/// [`TriangleCone::or_in_proven_box`] on the planes `planes`.
#[inline(always)]
fn or_planes_in_proven_box(
    planes: &[PlaneRow; 3],
    (i0, i_end, j0, j_end): (usize, usize, usize, usize),
    mask: &mut HemiMask,
) {
    let columns = ((1u64 << i_end).wrapping_sub(1u64 << i0)) as u32;
    for j in j0..j_end {
        let mut row = 0;
        let mut i = i0;
        while i < i_end {
            let bits = planes[0].bits(i, j) & planes[1].bits(i, j) & planes[2].bits(i, j);
            row |= bits << i;
            i += 4;
        }
        mask.rows[j] |= row & columns & HemiMask::VALID.rows[j];
    }
}

/// One plane's predicate on four neighbouring cells of a row at once.
#[derive(Clone, Copy)]
struct PlaneRow {
    m: Vec3,
    x: Vec4,
    z: Vec4,
}

impl PlaneRow {
    #[inline(always)]
    fn new(m: Vec3) -> Self {
        PlaneRow {
            m,
            x: Vec4::splat(m.x),
            z: Vec4::splat(m.z),
        }
    }

    /// Bits 0..4: [`inside`] at cells `(i..i + 4, j)`, each lane the scalar
    /// expression `(m.x u + m.y v) + m.z z` (no fused multiply-add in either),
    /// so bit `k` is exactly `inside(m, i + k, j)` for valid cells; cells past
    /// the grid read zero padding (masked off by the caller).
    #[inline(always)]
    fn bits(&self, i: usize, j: usize) -> u32 {
        let u = Vec4::from_slice(&CELL_COORD_PADDED[i..i + 4]);
        let z = Vec4::from_slice(&CELL_Z_PADDED[j][i..i + 4]);
        let v = Vec4::splat(self.m.y * CELL_COORD[j]);
        ((self.x * u + v) + self.z * z).cmpge(Vec4::ZERO).bitmask()
    }
}

/// Columns past the grid, so [`PlaneRow::bits`] can read four from any column.
const PADDED: usize = GRID + 4;

/// [`CELL_COORD`] with zero padding.
static CELL_COORD_PADDED: [f32; PADDED] = {
    let mut out = [0.0; PADDED];
    let mut i = 0;
    while i < GRID {
        out[i] = CELL_COORD[i];
        i += 1;
    }
    out
};

/// [`CELL_Z`] with zero padding.
static CELL_Z_PADDED: [[f32; PADDED]; GRID] = {
    let mut out = [[0.0; PADDED]; GRID];
    let mut j = 0;
    while j < GRID {
        let mut i = 0;
        while i < GRID {
            out[j][i] = CELL_Z[j][i];
            i += 1;
        }
        j += 1;
    }
    out
};

/// What [`TriangleCone::proven_box`] found.
#[derive(Clone, Copy, Debug)]
enum Proven {
    /// Columns `i0..i_end` and rows `j0..j_end` hold every cell the predicate
    /// sets; `None` when they hold no cell center.
    Cells(Option<(usize, usize, usize, usize)>),
    /// Corners more than 60° apart: [`TriangleCone::cell_box`] bounds the cone.
    Wide,
    /// Too small or too extreme in scale to bound: every row is solved.
    Tiny,
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
        let top = || crate::geom::sqrtf((1.0 - axis(m) * axis(m)).max(0.0));
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

    /// A quad (found by `quad_has_no_pinholes_in_table_quality` on a random
    /// seed) whose diagonal reads the table in both triangles and meets table
    /// edges at acute corners: the cone's box was widened by the table's error
    /// alone, but two table planes off by that error move their corner by
    /// error / sin(α/2), so cell (9, 11) of the quad fell outside both boxes.
    #[test]
    fn table_quality_keeps_acute_table_corners_without_a_pinhole() {
        let [a, b, c, d] = [
            Vec3::new(-1.7418975, -0.87627107, 3.8172474),
            Vec3::new(-1.801111, 2.2654705, 3.910523),
            Vec3::new(-1.8593441, 0.9545593, 3.871603),
            Vec3::new(-1.8148206, -2.213231, 3.7775545),
        ];
        let (t1, t2) = (
            TriangleCone::new(a, b, c, false).unwrap(),
            TriangleCone::new(a, c, d, false).unwrap(),
        );
        let s = if cross(a, b).dot(c) < 0.0 { -1.0 } else { 1.0 };
        for table in tables() {
            let (first, second) = (
                table.classify_edges([a, b, c]),
                table.classify_edges([a, c, d]),
            );
            let plane = |p: Vec3, q: Vec3, exact: u32| {
                let m = s * cross(p, q);
                if exact == 1 {
                    half_space_mask(m)
                } else {
                    table.lookup(m)
                }
            };
            let outer = plane(a, b, first.exact & 1)
                & plane(b, c, first.exact >> 1 & 1)
                & plane(c, d, second.exact >> 1 & 1)
                & plane(d, a, second.exact >> 2 & 1);
            let covered = t1.mask_table(&table) | t2.mask_table(&table);
            assert_eq!(
                outer & covered.complement(),
                HemiMask::EMPTY,
                "pinhole, {table:?}"
            );
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

#[cfg(test)]
mod proven_box_tests {
    //! The proven box of exact quality ([`TriangleCone::proven_box`]) against its
    //! slow twins: the per-cell predicate on every cell and the general exact
    //! path, on small triangles of every kind around cell centers.

    use super::*;
    use crate::hemi::mask::{VALID_CELL_COUNT, cell_directions};
    use proptest::prelude::*;

    /// The direction of valid cell `k` (row by row), nudged by `jitter`.
    fn cell_dir(k: usize, jitter: Vec3) -> Vec3 {
        let (_, _, d) = cell_directions()
            .nth(k % VALID_CELL_COUNT as usize)
            .unwrap();
        (d + jitter).normalize()
    }

    /// Triangles the proven box is for and around its limits: small ones about a
    /// cell center (or the horizon) at distances from 1e-4 to 1e4, with a corner
    /// exactly on a cell's ray, slivers, nearly edge-on ones, and huge and tiny
    /// scales where the box must give up.
    fn small_triangle() -> impl Strategy<Value = [Vec3; 3]> {
        let cell = 0usize..VALID_CELL_COUNT as usize;
        let jitter = (-0.05f32..0.05, -0.05f32..0.05, -0.05f32..0.05).prop_map(Vec3::from);
        let offset = (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(Vec3::from);
        let distance = (-4.0f32..4.0).prop_map(|e| libm::powf(10.0, e));
        let size = (-6.0f32..-0.3).prop_map(|e| libm::powf(10.0, e));
        prop_oneof![
            // About a cell center.
            4 => (cell.clone(), jitter.clone(), distance.clone(), size.clone(), offset.clone(), offset.clone())
                .prop_map(|(k, j, r, s, p, q)| {
                    let c = cell_dir(k, j) * r;
                    [c + p * (s * r), c + q * (s * r), c - (p + q) * (s * r)]
                }),
            // A corner exactly on a cell's ray (a tie for the predicate's rounding).
            2 => (cell.clone(), distance.clone(), size.clone(), offset.clone(), offset.clone())
                .prop_map(|(k, r, s, p, q)| {
                    let c = cell_dir(k, Vec3::ZERO) * r;
                    [c, c + p * (s * r), c + q * (s * r)]
                }),
            // Straddling the horizon.
            2 => (-1.0f32..1.0, -0.05f32..0.05, distance.clone(), size.clone(), offset.clone(), offset.clone())
                .prop_map(|(phi, z, r, s, p, q)| {
                    let c = Vec3::new(libm::cosf(3.2 * phi), libm::sinf(3.2 * phi), z) * r;
                    [c + p * (s * r), c + q * (s * r), c - (p + q) * (s * r)]
                }),
            // Slivers and nearly edge-on.
            1 => (cell.clone(), distance.clone(), size.clone(), offset.clone(), -1e-4f32..1e-4)
                .prop_map(|(k, r, s, p, e)| {
                    let c = cell_dir(k, Vec3::ZERO) * r;
                    let b = c + p * (s * r);
                    [c, b, c.lerp(b, 0.4) + Vec3::splat(e * s * r)]
                }),
            1 => (cell.clone(), distance, size, offset.clone(), -1e-4f32..1e-4)
                .prop_map(|(k, r, s, p, e)| {
                    let c = cell_dir(k, Vec3::ZERO) * r;
                    let b = c + p * (s * r);
                    [c, b, c * 0.3 + b * 0.6 + c.cross(b) * e]
                }),
            // Extreme scales.
            1 => (cell, prop_oneof![Just(1e-12f32), Just(1e-9f32), Just(1e9f32), Just(1e15f32)], 1e-3f32..0.2, offset.clone(), offset)
                .prop_map(|(k, r, s, p, q)| {
                    let c = cell_dir(k, Vec3::ZERO) * r;
                    [c + p * (s * r), c + q * (s * r), c - p * (s * r)]
                }),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(6000))]

        /// The exact mask with the proven box is the per-cell predicate and the
        /// general path, and the box holds every cell the predicate sets.
        #[test]
        fn proven_box_is_exact([a, b, c] in small_triangle(), cull in any::<bool>()) {
            // The fused path culls as TriangleCone::new and ORs the same mask in.
            let start = HemiMask { rows: core::array::from_fn(|j| 0x0f0f_0f0f_u32.rotate_left(j as u32)) }
                & HemiMask::VALID;
            let mut ored = start;
            let fused = TriangleCone::or_exact_into(a, b, c, cull, &mut ored);
            let cone = match TriangleCone::new(a, b, c, cull) {
                Ok(cone) => cone,
                Err(culled) => {
                    prop_assert_eq!(fused, Err(culled));
                    prop_assert_eq!(ored, start);
                    return Ok(());
                }
            };
            let reference = cone.mask_reference();
            prop_assert_eq!(fused, Ok(()));
            prop_assert_eq!(ored, start | reference);
            prop_assert_eq!(cone.mask_exact(), reference);
            prop_assert_eq!(cone.mask_every_row(), reference);
            if let Some((axis, reach)) = thin_cone_axis(cone.normals) {
                // Every cell the predicate sets is near the axis or its opposite.
                for (i, j) in reference.occluded_cells() {
                    let near = |end: DVec3| {
                        (f64::from(CELL_COORD[i]) - end.x).abs() <= reach
                            && (f64::from(CELL_COORD[j]) - end.y).abs() <= reach
                    };
                    prop_assert!(near(axis) || near(-axis),
                        "cell ({}, {}) beyond {} of ±{:?}", i, j, reach, axis);
                }
                let mut near_axis = HemiMask::EMPTY;
                cone.or_near_axis(axis, reach, &mut near_axis);
                prop_assert_eq!(near_axis, reference);
            }
            for proven in [cone.proven_box(), proven_box_from_normals(cone.normals)] {
                match proven {
                    Proven::Wide => prop_assert_eq!(cone.mask_exact_general(), reference),
                    Proven::Tiny => {}
                    Proven::Cells(None) => prop_assert_eq!(reference, HemiMask::EMPTY),
                    Proven::Cells(Some((i0, i_end, j0, j_end))) => {
                        for (i, j) in reference.occluded_cells() {
                            prop_assert!((i0..i_end).contains(&i) && (j0..j_end).contains(&j),
                                "cell ({}, {}) outside {:?}", i, j, (i0, i_end, j0, j_end));
                        }
                    }
                }
            }
        }
    }

    /// `classify_four` and `or_exact_in_box` on four triangles, as the
    /// clustered loop uses them: the mask each lane gets, or `None` for a
    /// culled lane (with its reason) or one left to the one-triangle path.
    fn through_four(
        triangles: [[Vec3; 3]; 4],
        cull: bool,
    ) -> [Result<Option<HemiMask>, Culled>; 4] {
        let lanes = |corner: usize, axis: usize| {
            Vec4::from_array(core::array::from_fn(|k| triangles[k][corner][axis]))
        };
        let corners = core::array::from_fn(|c| [lanes(c, 0), lanes(c, 1), lanes(c, 2)]);
        let v = classify_four(corners, cull);
        core::array::from_fn(|k| {
            if v.degenerate >> k & 1 == 1 {
                return Err(Culled::Degenerate);
            }
            if v.back_facing >> k & 1 == 1 {
                return Err(Culled::BackFacing);
            }
            if v.boxed >> k & 1 == 0 {
                return Ok(None);
            }
            let mut mask = HemiMask::EMPTY;
            if v.empty >> k & 1 == 0 {
                let [fi, li, fj, lj] = v.cells;
                let cells = (
                    fi[k] as usize,
                    li[k] as usize,
                    fj[k] as usize,
                    lj[k] as usize,
                );
                TriangleCone::or_exact_in_box(triangles[k], cells, &mut mask);
                if v.scale_free >> k & 1 == 1 {
                    // The lane's own normals give the same bits.
                    let mut planes = HemiMask::EMPTY;
                    TriangleCone::or_planes_in_box(v.lane_normals(k), cells, &mut planes);
                    assert_eq!(planes, mask, "lane {k}");
                    if v.small >> k & 1 == 0 {
                        LARGE_LANES.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
                    }
                }
                if v.small >> k & 1 == 1 {
                    // The window's bits, masked to the box, are the same.
                    let (i0, i1, j0, j1) = cells;
                    let columns = HemiMask::columns(i0, i1);
                    let mut window = HemiMask::EMPTY;
                    for (dj, &bits) in v.window[k].iter().enumerate() {
                        let j = j0 + dj;
                        if j <= j1 {
                            window.rows[j] = (bits << i0) & columns & HemiMask::VALID.rows[j];
                        }
                    }
                    assert_eq!(window, mask, "lane {k}");
                    SMALL_LANES.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
                }
            }
            Ok(Some(mask))
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]

        /// Four triangles classified at once: the same culling as
        /// `TriangleCone::new`, and where the box path is taken, the mask of
        /// the per-cell predicate, bit for bit.
        #[test]
        fn four_at_once_is_one_at_a_time(
            t0 in small_triangle(), t1 in small_triangle(), t2 in small_triangle(),
            t3 in small_triangle(), cull in any::<bool>(),
        ) {
            // The caller's contract: some corner above the horizon, all in
            // range; other triangles are replaced by a small one near the zenith.
            let usable = |[a, b, c]: [Vec3; 3]| {
                !(a.z <= 0.0 && b.z <= 0.0 && c.z <= 0.0) && [a, b, c].iter().all(|&p| (1e-18..=1e18).contains(&p.length_squared()))
            };
            let stand_in = [Vec3::new(0.01, 0.0, 1.0), Vec3::new(0.0, 0.02, 1.0), Vec3::new(-0.01, 0.0, 1.0)];
            let triangles = [t0, t1, t2, t3].map(|t| if usable(t) { t } else { stand_in });
            for (k, got) in through_four(triangles, cull).into_iter().enumerate() {
                let [a, b, c] = triangles[k];
                match (TriangleCone::new(a, b, c, cull), got) {
                    (Err(expected), got) => prop_assert_eq!(got, Err(expected)),
                    (Ok(_), Err(culled)) => prop_assert!(false, "lane {} culled as {:?}", k, culled),
                    (Ok(_), Ok(None)) => {}
                    (Ok(cone), Ok(Some(mask))) => prop_assert_eq!(mask, cone.mask_reference(), "lane {}", k),
                }
            }
        }
    }

    /// Triangles grazing the horizon: corners from 3° below it to 6° above
    /// (the lowest cell centers are 4.39° up), up to 55° apart in azimuth
    /// (their arcs rise between the corners), at distances a hundredfold apart.
    fn grazing_triangle() -> impl Strategy<Value = [Vec3; 3]> {
        let corner = (-0.05f32..0.1, -0.5f32..0.5, -1.0f32..1.0).prop_map(|(up, around, d)| {
            let r = libm::powf(10.0, d);
            let (sin_up, cos_up) = (libm::sinf(up), libm::cosf(up));
            Vec3::new(
                r * cos_up * libm::cosf(around),
                r * cos_up * libm::sinf(around),
                r * sin_up,
            )
        });
        (
            0.0f32..core::f32::consts::TAU,
            corner.clone(),
            corner.clone(),
            corner,
        )
            .prop_map(|(turn, a, b, c)| {
                let (sin, cos) = (libm::sinf(turn), libm::cosf(turn));
                [a, b, c].map(|p| Vec3::new(cos * p.x - sin * p.y, sin * p.x + cos * p.y, p.z))
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]

        /// A triangle found below every cell center sets none: one at a time
        /// and four at once, the masks are the per-cell predicate's.
        #[test]
        fn grazing_triangles_keep_their_cells(
            t0 in grazing_triangle(), t1 in grazing_triangle(), t2 in grazing_triangle(),
            t3 in grazing_triangle(),
        ) {
            let triangles = [t0, t1, t2, t3];
            let got = through_four(triangles, false);
            for (k, [a, b, c]) in triangles.into_iter().enumerate() {
                let Ok(cone) = TriangleCone::new(a, b, c, false) else {
                    continue;
                };
                prop_assert_eq!(cone.mask_exact(), cone.mask_reference(), "triangle {}", k);
                if let Ok(Some(mask)) = got[k] {
                    prop_assert_eq!(mask, cone.mask_reference(), "lane {}", k);
                }
            }
        }
    }

    #[test]
    fn triangles_below_the_lowest_cells_are_found() {
        // Low triangles 30° wide at 2° up all round the horizon: no cell
        // center can be in them, and the box of their corners holds some.
        let (mut found, mut total) = (0, 0);
        for k in 0..36 {
            let around = k as f32 * 10f32.to_radians();
            let at = |turn: f32, up: f32, r: f32| {
                let (a, u) = (around + turn.to_radians(), up.to_radians());
                Vec3::new(r * u.cos() * a.cos(), r * u.cos() * a.sin(), r * u.sin())
            };
            let t = [at(-15.0, 2.0, 1.0), at(15.0, 2.0, 1.0), at(0.0, 3.0, 2.0)];
            let cone = TriangleCone::new(t[0], t[1], t[2], false).unwrap();
            assert_eq!(cone.mask_reference(), HemiMask::EMPTY);
            total += 1;
            found += usize::from(matches!(cone.proven_box(), Proven::Cells(None)));
            for got in through_four([t; 4], false) {
                assert_eq!(got, Ok(Some(HemiMask::EMPTY)));
            }
        }
        assert_eq!(found, total);
        // One whose arc rises over the lowest centers between its corners
        // (120° apart at 4° up: the arc's middle is at about 8°) is kept.
        let at = |a: f32, up: f32| {
            let (a, u) = (a.to_radians(), up.to_radians());
            Vec3::new(u.cos() * a.cos(), u.cos() * a.sin(), u.sin())
        };
        let wide = [at(-60.0, 4.0), at(60.0, 4.0), at(0.0, 3.0) * 0.5];
        let cone = TriangleCone::new(wide[0], wide[1], wide[2], false).unwrap();
        assert_ne!(cone.mask_reference(), HemiMask::EMPTY);
        assert_eq!(cone.mask_exact(), cone.mask_reference());
    }

    /// Lanes that took the window in `through_four`, so the test can tell it
    /// was exercised.
    static SMALL_LANES: core::sync::atomic::AtomicUsize = core::sync::atomic::AtomicUsize::new(0);

    /// Lanes whose box was larger than the window and whose own normals
    /// were checked in `through_four`.
    static LARGE_LANES: core::sync::atomic::AtomicUsize = core::sync::atomic::AtomicUsize::new(0);

    /// Triangles `size` rad across around every tenth cell center, four at
    /// once, against the per-cell reference; returns how much `lanes` grew.
    fn around_every_tenth_cell(size: f32, lanes: &core::sync::atomic::AtomicUsize) -> usize {
        let before = lanes.load(core::sync::atomic::Ordering::Relaxed);
        for k in (0..VALID_CELL_COUNT as usize).step_by(10) {
            let c = cell_dir(k, Vec3::new(0.004, 0.003, 0.0)) * 3.0;
            let (e1, e2) = c.normalize().any_orthonormal_pair();
            let t = [c + e1 * size, c + e2 * size, c - (e1 + e2) * size];
            let cone = TriangleCone::new(t[0], t[1], t[2], false).unwrap();
            for got in through_four([t; 4], false) {
                assert_eq!(got, Ok(Some(cone.mask_reference())), "cell {k}");
            }
        }
        lanes.load(core::sync::atomic::Ordering::Relaxed) - before
    }

    #[test]
    fn four_at_once_takes_the_window_for_small_boxes() {
        let taken = around_every_tenth_cell(0.05, &SMALL_LANES);
        assert!(taken >= 4 * 60, "{taken} small lanes");
    }

    #[test]
    fn four_at_once_boxes_larger_than_the_window_take_the_lanes_normals() {
        // Boxes of several cells each way.
        let taken = around_every_tenth_cell(0.3, &LARGE_LANES);
        assert!(taken >= 4 * 60, "{taken} large lanes");
    }

    #[test]
    fn four_at_once_on_a_grazing_bunny_triangle() {
        let t = [
            Vec3::new(-2.6647358, -0.8712141, 0.054670885),
            Vec3::new(-2.5519676, -0.43020418, 0.21368954),
            Vec3::new(-2.739491, -0.693104, 0.4280038),
        ];
        let cone = TriangleCone::new(t[0], t[1], t[2], false).unwrap();
        for got in through_four([t; 4], false) {
            assert_eq!(got, Ok(Some(cone.mask_reference())));
        }
    }

    #[test]
    fn tiny_triangles_take_the_normals_box() {
        // 1e-3 rad across: too small for the corners' bound, not for the
        // normals'; the far triangles of a 50k-triangle mesh look like this.
        let (mut tiny, mut proven) = (0, 0);
        for k in 0..VALID_CELL_COUNT as usize {
            let c = cell_dir(k, Vec3::new(0.02, 0.01, 0.0)) * 5.0;
            let (e1, e2) = c.normalize().any_orthonormal_pair();
            let s = 5e-3;
            let cone = TriangleCone::new(c + e1 * s, c + e2 * s, c - (e1 + e2) * s, false).unwrap();
            assert!(matches!(cone.proven_box(), Proven::Tiny));
            tiny += 1;
            if matches!(proven_box_from_normals(cone.normals), Proven::Cells(_)) {
                proven += 1;
            }
            assert_eq!(cone.mask_exact(), cone.mask_reference());
        }
        assert_eq!(proven, tiny);
    }

    #[test]
    fn far_tiny_triangles_take_the_axis() {
        // 1e-6 to 1e-5 rad across (a triangle of a thousandth of the mesh
        // seen from a thousand mesh sizes away), about every cell center:
        // too small for both proven boxes, whose corners cannot be oriented.
        // The axis must decide them all (else the every-row solve, a thousand
        // times slower, is back), with the predicate's bits.
        let (mut tiny, mut axis) = (0, 0);
        for k in 0..VALID_CELL_COUNT as usize {
            for (jitter, s) in [
                (Vec3::ZERO, 1e-5),
                (Vec3::new(0.02, 0.01, 0.0), 1e-5),
                (Vec3::ZERO, 1e-6),
            ] {
                let c = cell_dir(k, jitter) * 300.0;
                let (e1, e2) = c.normalize().any_orthonormal_pair();
                let s = s * 300.0;
                let corners = [c + e1 * s, c + e2 * s, c - (e1 + e2) * s];
                let cone = TriangleCone::new(corners[0], corners[1], corners[2], false).unwrap();
                if !matches!(proven_box_from_normals(cone.normals), Proven::Tiny) {
                    continue;
                }
                tiny += 1;
                axis += usize::from(thin_cone_axis(cone.normals).is_some());
                assert_eq!(cone.mask_exact(), cone.mask_reference());
            }
        }
        assert!(tiny > VALID_CELL_COUNT as usize, "{tiny} tiny cones");
        assert_eq!(axis, tiny);
    }

    #[test]
    fn thin_cones_about_a_cell_center_set_it() {
        // Three planes through a cell's direction d, turned 120° apart about
        // it and tilted towards it by 1e-7 to 1e-6 rad: a cone around d too
        // thin for the normals' box. The axis path must keep d's cell (the
        // predicate's bits), not only drop the cones that set nothing.
        let (mut decided, mut holding) = (0, 0);
        for k in 0..VALID_CELL_COUNT as usize {
            let d = cell_dir(k, Vec3::ZERO);
            let (e1, e2) = d.any_orthonormal_pair();
            for tilt in [1e-7f32, 3e-7, 1e-6] {
                let normals = [0.0f32, 2.1, 4.2].map(|angle| {
                    let t = e1 * libm::cosf(angle) + e2 * libm::sinf(angle);
                    normalize_exponent(t + d * tilt)
                });
                let cone = TriangleCone {
                    corners: [d; 3],
                    normals,
                    det_abs: 1.0,
                };
                if !matches!(proven_box_from_normals(normals), Proven::Tiny) {
                    continue;
                }
                let Some((axis, reach)) = thin_cone_axis(normals) else {
                    continue;
                };
                decided += 1;
                let reference = cone.mask_reference();
                let mut near_axis = HemiMask::EMPTY;
                cone.or_near_axis(axis, reach, &mut near_axis);
                assert_eq!(near_axis, reference);
                let mut tiny = HemiMask::EMPTY;
                cone.or_tiny_into(&mut tiny);
                assert_eq!(tiny, reference);
                holding += usize::from(reference != HemiMask::EMPTY);
            }
        }
        let cones = 3 * VALID_CELL_COUNT as usize;
        assert!(
            decided > cones * 9 / 10,
            "{decided} of {cones} thin cones decided"
        );
        assert!(
            holding > decided / 2,
            "{holding} of {decided} thin cones hold a cell"
        );
    }

    #[test]
    fn small_triangles_take_the_proven_box() {
        // Triangles 0.02 to 0.3 rad across about every cell center: the proven
        // box must decide nearly all of them (else the fast path is dead code),
        // and most boxes hold no cell or only a few.
        let (mut total, mut proven, mut empty) = (0, 0, 0);
        for k in 0..VALID_CELL_COUNT as usize {
            // The smallest ones sit between four cell centers (half a cell off).
            for (s, r, off) in [
                (0.005f32, 1.0f32, 0.031f32),
                (0.05, 30.0, 0.013),
                (0.15, 0.01, 0.0),
            ] {
                let c = cell_dir(k, Vec3::new(off, off, 0.0)) * r;
                let (e1, e2) = c.normalize().any_orthonormal_pair();
                let corners = [c + e1 * (s * r), c + e2 * (s * r), c - (e1 + e2) * (s * r)];
                let cone = TriangleCone::new(corners[0], corners[1], corners[2], false).unwrap();
                total += 1;
                match cone.proven_box() {
                    Proven::Cells(None) => {
                        proven += 1;
                        empty += 1;
                    }
                    Proven::Cells(Some(_)) => proven += 1,
                    Proven::Wide | Proven::Tiny => {}
                }
                assert_eq!(cone.mask_exact(), cone.mask_reference());
            }
        }
        assert!(proven * 100 >= total * 95, "{proven} of {total} proven");
        assert!(empty > 0 && empty < total, "{empty} of {total} empty");
    }
}
