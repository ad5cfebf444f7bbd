//! How a receiver's pass turns a triangle's local corners into mask cells, one
//! implementation per quality ([`ExactCones`], [`TableCones`]), so the loops of
//! the `walk` and `chunk` modules are monomorphic.

use glam::{Vec3, Vec4};

use super::mask::HemiMask;
use super::table::HalfSpaceTable;
use super::{Culled, TriangleCone, table_raster};

/// How a pass turns a triangle's local corners into mask cells: one
/// implementation per quality, so the loops are monomorphic.
pub(super) trait ConeMask: Copy {
    /// Whether the masks are the exact cones': each cell is set exactly when
    /// its center passes the three edge planes. Only then does a triangle
    /// inside a box set only cells the box reaches ([`BoxCells`](super::box_cells::BoxCells); a table
    /// mask may set cells a little outside its cone), and only then may a
    /// few cells be tested one by one instead of rasterizing the triangles.
    const EXACT: bool;

    /// Bit `k` set when the cone of triangle `k` (lanes of the local corners'
    /// x, y and z; not culled) gets its exact mask in this quality, so
    /// [`classify_four`](super::triangle::classify_four)'s proven box applies.
    fn exact_lanes(self, corners: [[Vec4; 3]; 3]) -> u32;

    /// Culls or ORs the cone of local corners `a, b, c` into `mask`.
    fn or_into(
        self,
        a: Vec3,
        b: Vec3,
        c: Vec3,
        cull: bool,
        mask: &mut HemiMask,
    ) -> Result<(), Culled>;
}

/// Exact quality.
#[derive(Clone, Copy)]
pub(super) struct ExactCones;

impl ConeMask for ExactCones {
    const EXACT: bool = true;

    #[inline(always)]
    fn exact_lanes(self, _corners: [[Vec4; 3]; 3]) -> u32 {
        0b1111
    }

    #[inline(always)]
    fn or_into(
        self,
        a: Vec3,
        b: Vec3,
        c: Vec3,
        cull: bool,
        mask: &mut HemiMask,
    ) -> Result<(), Culled> {
        TriangleCone::or_exact_into(a, b, c, cull, mask)
    }
}

/// Table quality.
#[derive(Clone, Copy)]
pub(super) struct TableCones<'t>(pub(super) &'t HalfSpaceTable);

impl ConeMask for TableCones<'_> {
    const EXACT: bool = false;

    /// Cones whose three edges the table's rule makes exact get the exact
    /// mask ([`TriangleCone::mask_table`]).
    #[inline(always)]
    fn exact_lanes(self, corners: [[Vec4; 3]; 3]) -> u32 {
        if self.0.has_exact_edges() {
            self.0.all_edges_exact_four(corners)
        } else {
            0
        }
    }

    #[inline(always)]
    fn or_into(
        self,
        a: Vec3,
        b: Vec3,
        c: Vec3,
        cull: bool,
        mask: &mut HemiMask,
    ) -> Result<(), Culled> {
        table_raster(self.0)(a, b, c, cull, mask)
    }
}
