//! The center rays of a node's few open cells, tested against boxes: the
//! ray tracer's side of the per-receiver walk (after Laine and Karras 2010,
//! method 2). A node whose reachable cells are few lists them once, with the
//! inverses of their center directions as four-wide lanes ([`RayList`]);
//! that node and every box below it keep the rays that meet them as a bit
//! set over the one list ([`RaySet`]), found four rays at a time by slab
//! tests against the box widened by a pad ([`ray_pad`]). A triangle inside
//! a box sets only cells whose center rays meet it, so the cells left out
//! are cells no triangle of the box can set. The list is one per walk: every
//! node that inherits rays descends from the node that listed them, and the
//! walk is depth first, so a new list is only made once the old one's
//! subtree is done.

use glam::{Vec3, Vec4};

use super::clusters::Aabb;
use super::mask::{CELL_COORD, CELL_Z, GRID, HemiMask};
use crate::geom::Frame;

/// The most cells a [`RayList`] holds.
pub(crate) const LIST_CAPACITY: usize = 128;

/// Lanes of four rays in a [`RayList`].
const LIST_LANES: usize = LIST_CAPACITY / 4;

/// Entries of a [`RayList`]: bit `k` for its `k`-th ray.
pub(crate) type RaySet = u128;

const _: () = assert!(LIST_CAPACITY <= RaySet::BITS as usize && LIST_CAPACITY.is_multiple_of(4));

/// The most rays of a [`PathRays`]: a triangle's cells are a `u32` of
/// positions in it (`test_cells` in chunk.rs).
pub(crate) const PATH_CAPACITY: usize = 32;

/// Four cells' center rays as lanes: the inverses of their directions, one
/// vector per axis, tested against a box at once.
/// Plain arrays rather than vectors: copying one lane is then a load and a
/// store, where indexing a vector's lane is a jump through a table.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(crate) struct RayLanes {
    inverse: [[f32; 4]; 3],
}

impl RayLanes {
    /// Lanes not yet written.
    pub(crate) const EMPTY: RayLanes = RayLanes {
        inverse: [[0.0; 4]; 3],
    };

    /// Bit `k` set when ray `k` meets `padded` (all four lanes): lane by
    /// lane the expressions of `RayCell::meets` (the test twin). Vec3's `min` and `max`
    /// take their second operand unless the first compares smaller (larger),
    /// as the vector instructions do, so a NaN lane gives the same verdict.
    #[inline(always)]
    pub(crate) fn meet(&self, padded: &PaddedBox) -> u32 {
        let slab = |axis: usize, lo: f32, hi: f32| {
            let inverse = Vec4::from_array(self.inverse[axis]);
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
        !missed.bitmask() & 0xf
    }
}

/// A box widened by a pad on every side ([`ray_pad`]), relative to the
/// center of projection: what the rays are tested against.
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

/// The widening of `bounds` for the ray tests: [`RAY_SLACK`] times the sum
/// of the farthest corner's offsets from `origin` along the axes (at least
/// its distance, at most √3 times it, without a square root that could
/// overflow or underflow), so every point of the box gets at least the
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
/// own slack (a hundredth of a cell, `6e-4`; see box_cells.rs).
const RAY_SLACK: f32 = 1e-3;

/// At most [`LIST_CAPACITY`] clear cells of the grid, by rows: what a node
/// lists ([`BoxCells::open_cells_into`](super::box_cells::BoxCells::open_cells_into)).
#[derive(Clone, Copy, Debug)]
pub(crate) struct OpenCells {
    /// Bit `i` of row `j` for cell `(i, j)`; rows outside `rows` are not read.
    pub(crate) bits: [u32; GRID],
    /// The rows holding the cells, first and last (none when first > last).
    pub(crate) rows: (usize, usize),
}

impl OpenCells {
    /// No cell.
    pub(crate) const NONE: OpenCells = OpenCells {
        bits: [0; GRID],
        rows: (1, 0),
    };

    /// The cells, in row order and left to right within a row.
    #[cfg(test)]
    pub(crate) fn cells(&self) -> alloc::vec::Vec<(u8, u8)> {
        let mut cells = alloc::vec::Vec::new();
        for j in self.rows.0..=self.rows.1 {
            for i in 0..GRID {
                if self.bits[j] >> i & 1 == 1 {
                    cells.push((i as u8, j as u8));
                }
            }
        }
        cells
    }
}

/// The cells a node listed, with their center rays from the center of
/// projection as [`RayLanes`]: what the node and the boxes below it test.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayList {
    lanes: [RayLanes; LIST_LANES],
    /// Column and row of each ray (eight more, written past the end when
    /// listing).
    columns: [u8; LIST_CAPACITY + 8],
    rows: [u8; LIST_CAPACITY + 8],
}

impl RayList {
    /// No ray.
    pub(crate) const EMPTY: RayList = RayList {
        lanes: [RayLanes::EMPTY; LIST_LANES],
        columns: [0; LIST_CAPACITY + 8],
        rows: [0; LIST_CAPACITY + 8],
    };

    /// Makes this list the cells of `open` (at most [`LIST_CAPACITY`]), in
    /// row order, with their rays: the center direction in world axes is
    /// `frame`'s axes weighted by the cell's `(u, v, z)`, the expression of
    /// [`Frame::to_world`] lane by lane (the frame's scale does not move
    /// where a ray meets a box). Returns the set of them all.
    #[inline(always)]
    pub(crate) fn set_from(&mut self, open: &OpenCells, frame: &Frame) -> RaySet {
        // A byte of a row at a time, without a branch per cell: the columns
        // of its set bits from a table, eight written whatever their count.
        let mut len = 0;
        for j in open.rows.0..=open.rows.1 {
            let row = open.bits[j];
            for byte in 0..4 {
                let bits = (row >> (8 * byte)) as u8;
                let columns = BYTE_COLUMNS[usize::from(bits)] + 0x0808_0808_0808_0808 * byte as u64;
                self.columns[len..len + 8].copy_from_slice(&columns.to_le_bytes());
                self.rows[len..len + 8].copy_from_slice(&[j as u8; 8]);
                len += bits.count_ones() as usize;
            }
        }
        let splat = |v: Vec3| (Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z));
        let (tx, ty, tz) = splat(frame.tangent);
        let (bx, by, bz) = splat(frame.bitangent);
        let (nx, ny, nz) = splat(frame.normal);
        // Lanes past the end hold cells of earlier lists, or the empty list's
        // (0, 0): inside the grid, and never in a set.
        for (lane, lanes) in self.lanes[..len.div_ceil(4)].iter_mut().enumerate() {
            let cell = |k: usize| {
                let (i, j) = (4 * lane + k, 4 * lane + k);
                (usize::from(self.columns[i]), usize::from(self.rows[j]))
            };
            let [(i0, j0), (i1, j1), (i2, j2), (i3, j3)] = [cell(0), cell(1), cell(2), cell(3)];
            let u = Vec4::new(
                CELL_COORD[i0],
                CELL_COORD[i1],
                CELL_COORD[i2],
                CELL_COORD[i3],
            );
            let v = Vec4::new(
                CELL_COORD[j0],
                CELL_COORD[j1],
                CELL_COORD[j2],
                CELL_COORD[j3],
            );
            let z = Vec4::new(
                CELL_Z[j0][i0],
                CELL_Z[j1][i1],
                CELL_Z[j2][i2],
                CELL_Z[j3][i3],
            );
            let x = u * tx + v * bx + z * nx;
            let y = u * ty + v * by + z * ny;
            let w = u * tz + v * bz + z * nz;
            lanes.inverse = [
                (Vec4::ONE / x).to_array(),
                (Vec4::ONE / y).to_array(),
                (Vec4::ONE / w).to_array(),
            ];
        }
        if len == 0 {
            0
        } else {
            RaySet::MAX >> (LIST_CAPACITY - len)
        }
    }

    /// The rays of `set` still clear in `mask` that meet `padded`.
    #[inline(always)]
    pub(crate) fn meet(&self, set: RaySet, padded: &PaddedBox, mask: &HemiMask) -> RaySet {
        let mut kept = 0;
        let mut rest = set;
        while rest != 0 {
            let lane = (rest.trailing_zeros() / 4) as usize;
            let shift = 4 * lane as u32;
            let wanted = (rest >> shift) as u32 & 0xf;
            rest &= !(0xf << shift);
            let met = self.lanes[lane].meet(padded) & wanted;
            // Clear cells, without a branch per ray.
            let mut clear = 0;
            for k in 0..4 {
                let (i, j) = (self.columns[4 * lane + k], self.rows[4 * lane + k]);
                clear |= (!mask.rows[usize::from(j)] >> i & 1) << k;
            }
            kept |= RaySet::from(met & clear) << shift;
        }
        kept
    }

    /// The cell of ray `k`, as `(column, row)`.
    #[inline(always)]
    fn cell(&self, k: usize) -> (u8, u8) {
        (self.columns[k], self.rows[k])
    }
}

/// Per byte value, the positions of its set bits, lowest first, one per
/// byte of the entry.
const BYTE_COLUMNS: [u64; 256] = {
    let mut table = [0; 256];
    let mut value = 0;
    while value < 256 {
        let (mut entry, mut count, mut bit) = (0u64, 0, 0);
        while bit < 8 {
            if value >> bit & 1 == 1 {
                entry |= (bit as u64) << (8 * count);
                count += 1;
            }
            bit += 1;
        }
        table[value] = entry;
        value += 1;
    }
    table
};

/// At most [`PATH_CAPACITY`] rays of a [`RayList`], packed: those meeting a
/// cluster, which its spans and triangles test (`chunk_loop` in chunk.rs).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PathRays {
    lanes: [RayLanes; PATH_CAPACITY / 4],
    cells: [(u8, u8); PATH_CAPACITY],
    len: usize,
}

impl PathRays {
    /// No ray.
    pub(crate) const EMPTY: PathRays = PathRays {
        lanes: [RayLanes::EMPTY; PATH_CAPACITY / 4],
        cells: [(0, 0); PATH_CAPACITY],
        len: 0,
    };

    /// Makes these the rays of `set` (at most [`PATH_CAPACITY`]) in `list`,
    /// in the list's order.
    #[inline(always)]
    pub(crate) fn gather(&mut self, list: &RayList, set: RaySet) {
        let mut len = 0;
        let mut rest = set;
        while rest != 0 {
            let k = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            let (from, to) = (&list.lanes[k / 4].inverse, &mut self.lanes[len / 4].inverse);
            for axis in 0..3 {
                to[axis][len % 4] = from[axis][k % 4];
            }
            self.cells[len] = list.cell(k);
            len += 1;
        }
        self.len = len;
    }

    /// The lanes holding the rays (the last one's lanes past them hold
    /// others: leave out [`PathRays::all`]'s missing bits).
    #[inline(always)]
    pub(crate) fn lanes(&self) -> &[RayLanes] {
        &self.lanes[..self.len.div_ceil(4)]
    }

    /// A bit per ray.
    #[inline(always)]
    pub(crate) fn all(&self) -> u32 {
        ((1u64 << self.len) - 1) as u32
    }

    /// The cells, as `(column, row)`, bit `k` of [`PathRays::all`] for the
    /// `k`-th.
    #[inline(always)]
    pub(crate) fn cells(&self) -> &[(u8, u8)] {
        &self.cells[..self.len]
    }
}

/// A cell's center ray on its own: the slow twin of the lanes.
#[cfg(test)]
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayCell {
    /// `1 / d` per axis for the center direction `d` in world axes (`±inf`
    /// for a zero component).
    inverse: Vec3,
}

#[cfg(test)]
impl RayCell {
    /// Cell `(i, j)`'s center ray in `frame`'s world axes.
    pub(crate) fn of(i: usize, j: usize, frame: &Frame) -> RayCell {
        let d = frame.to_world(Vec3::new(CELL_COORD[i], CELL_COORD[j], CELL_Z[j][i]));
        RayCell { inverse: d.recip() }
    }

    /// Whether the ray meets `padded`.
    pub(crate) fn meets(&self, padded: &PaddedBox) -> bool {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hemi::Receiver;
    use crate::hemi::test_meshes::Rng;
    use alloc::vec::Vec;

    /// A box with corners in `[-2, 2]`, some of them on the origin's planes.
    fn random_box(rng: &mut Rng) -> PaddedBox {
        let mut coordinate = || match (rng.next() * 6.0) as u32 {
            0 => 0.0,
            _ => rng.next() * 4.0 - 2.0,
        };
        let a = Vec3::new(coordinate(), coordinate(), coordinate());
        let b = Vec3::new(coordinate(), coordinate(), coordinate());
        PaddedBox {
            lo: a.min(b),
            hi: a.max(b),
        }
    }

    /// The slow twin of [`RayLanes::meet`]: each ray's own slab test, on
    /// random boxes and directions and on the cases that make NaN (a zero
    /// direction component with the origin on a face).
    #[test]
    fn four_lanes_meet_a_box_as_each_ray_does() {
        let mut rng = Rng(0x7261_7973);
        let component = |rng: &mut Rng| match (rng.next() * 8.0) as u32 {
            0 => 0.0,
            1 => -0.0,
            _ => rng.next() * 2.0 - 1.0,
        };
        let mut met = 0;
        for _ in 0..20_000 {
            let rays: [RayCell; 4] = core::array::from_fn(|_| RayCell {
                inverse: Vec3::new(
                    component(&mut rng),
                    component(&mut rng),
                    component(&mut rng),
                )
                .recip(),
            });
            let lanes = RayLanes {
                inverse: core::array::from_fn(|axis| {
                    core::array::from_fn(|k| rays[k].inverse[axis])
                }),
            };
            let padded = random_box(&mut rng);
            let bits = lanes.meet(&padded);
            for (k, ray) in rays.iter().enumerate() {
                assert_eq!(
                    bits >> k & 1 == 1,
                    ray.meets(&padded),
                    "ray {k} of {rays:?}, {padded:?}"
                );
            }
            assert_eq!(bits >> 4, 0, "bits past the lanes");
            met += bits.count_ones();
        }
        assert!(met > 5_000 && met < 75_000, "{met} rays met");
    }

    /// A list made from open cells holds them in row order with each cell's
    /// own ray, keeps of any subset exactly the clear rays that meet a box,
    /// and packs a few of them into a path with the same rays.
    #[test]
    fn lists_keep_the_clear_rays_meeting_a_box_as_each_ray_does() {
        let mut rng = Rng(0x6c69_7374);
        let every: Vec<(usize, usize)> = crate::hemi::cell_directions()
            .map(|(i, j, _)| (i, j))
            .collect();
        let (mut kept_some, mut paths) = (0, 0);
        let mut list = RayList::EMPTY;
        let mut path = PathRays::EMPTY;
        for case in 0..2_000 {
            let normal = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5)
                .try_normalize()
                .unwrap_or(Vec3::Z);
            let receiver = Receiver::new(Vec3::ZERO, normal, 0.0);
            let frame = receiver.scaled_frame([(Vec3::splat(-1.0), Vec3::splat(2.0))]);
            // Up to the capacity of random cells, or none.
            let share = rng.next() * LIST_CAPACITY as f32 / every.len() as f32;
            let mut open = OpenCells::NONE;
            let mut chosen = Vec::new();
            for &(i, j) in &every {
                if chosen.len() < LIST_CAPACITY && rng.next() < share {
                    open.bits[j] |= 1 << i;
                    open.rows = (open.rows.0.min(j), j);
                    chosen.push((i as u8, j as u8));
                }
            }
            if chosen.is_empty() {
                open.rows = (1, 0);
            } else {
                open.rows.0 = usize::from(chosen[0].1);
            }
            assert_eq!(open.cells(), chosen, "case {case}");
            let all = list.set_from(&open, &frame);
            assert_eq!(all.count_ones() as usize, chosen.len(), "case {case}");
            assert_eq!(all.trailing_ones() as usize, chosen.len(), "case {case}");
            let rays: Vec<RayCell> = chosen
                .iter()
                .enumerate()
                .map(|(k, &(i, j))| {
                    assert_eq!(list.cell(k), (i, j), "case {case}");
                    let ray = RayCell::of(usize::from(i), usize::from(j), &frame);
                    for axis in 0..3 {
                        let lane = list.lanes[k / 4].inverse[axis][k % 4];
                        assert_eq!(lane.to_bits(), ray.inverse[axis].to_bits(), "case {case}");
                    }
                    ray
                })
                .collect();
            let mut mask = HemiMask::EMPTY;
            for &(i, j) in &every {
                mask.set(i, j, rng.next() < 0.3);
            }
            let padded = random_box(&mut rng);
            let subset =
                (0..LIST_CAPACITY).fold(0, |s, k| s | RaySet::from(rng.next() < 0.5) << k) & all;
            for set in [all, subset] {
                let kept = list.meet(set, &padded, &mask);
                for (k, (ray, &(i, j))) in rays.iter().zip(&chosen).enumerate() {
                    let expected = set >> k & 1 == 1
                        && !mask.get(usize::from(i), usize::from(j))
                        && ray.meets(&padded);
                    assert_eq!(kept >> k & 1 == 1, expected, "case {case} ray {k}");
                }
                assert_eq!(kept & !set, 0, "case {case}");
                kept_some += usize::from(kept != 0 && kept != set);
                // The first 32 kept rays as a path: the same cells and rays.
                let mut few = kept;
                while few.count_ones() as usize > PATH_CAPACITY {
                    few &= !(1 << (127 - few.leading_zeros()));
                }
                path.gather(&list, few);
                let picked: Vec<usize> =
                    (0..LIST_CAPACITY).filter(|&k| few >> k & 1 == 1).collect();
                let cells: Vec<(u8, u8)> = picked.iter().map(|&k| chosen[k]).collect();
                assert_eq!(path.cells(), cells.as_slice(), "case {case}");
                assert_eq!(
                    path.all().count_ones() as usize,
                    picked.len(),
                    "case {case}"
                );
                let other = random_box(&mut rng);
                let mut bits = 0;
                for (g, lanes) in path.lanes().iter().enumerate() {
                    bits |= lanes.meet(&other) << (4 * g);
                }
                bits &= path.all();
                for (n, &k) in picked.iter().enumerate() {
                    assert_eq!(
                        bits >> n & 1 == 1,
                        rays[k].meets(&other),
                        "case {case} path ray {n}"
                    );
                }
                paths += usize::from(picked.len() > 4);
            }
        }
        // The test means something only if many sets are cut down, and many
        // paths hold more than one lane.
        assert!(
            kept_some > 1_000 && paths > 500,
            "{kept_some} cut sets, {paths} paths"
        );
    }
}
