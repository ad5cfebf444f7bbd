//! Inside a cluster the triangles are in chunks of at most 32, each with its
//! own list of distinct vertices (built with the grouping, rebuilt when the
//! index buffer changes). Per receiver a chunk's vertices are moved into the
//! receiver's frame four at a time, once per vertex instead of once per corner;
//! its triangles are culled against the horizon (and the near/far rule) without
//! branches; and those left are classified four at a time (`classify_four` in
//! `triangle.rs`): culling and exact quality's proven cell box, lane by lane
//! the same `f32` expressions as the one-triangle code, so the same verdicts. A
//! box with no cell center is done; boxes of at most 4 × 2 cells are evaluated
//! in the same pass for all four lanes; larger ones one triangle at a time from
//! their box; wide and tiny cones, and table quality's cones with a table
//! plane, take the one-triangle path. Masks and counts equal the unclustered
//! loop's (tests below, and `classify_four`'s against `TriangleCone::new` and
//! the per-cell predicate).
//!
//! Cost per receiver: the walk over the node boxes (about a third), moving the
//! vertices of the clusters opened into the frame, and per triangle either the
//! plane tests on a cluster's few cells (most clusters of a large mesh: about
//! 30 vector operations per four triangles plus 12 per cell) or, for the near
//! clusters that many open cells meet, the classification (about 125 vector
//! operations per triangle: crosses, culling, three square roots and a
//! division, the proven box, the 4 × 2 windows) and the rest one at a time
//! (larger boxes, ORing the windows in, wide cones). Figures: `antumbra bench
//! hemi`.

use glam::{Vec3, Vec4};

use super::clusters::{CHUNK, CHUNK_SPANS, CHUNK_VERTICES, Chunk, SPAN, TriangleClusters};
#[cfg(feature = "std")]
use super::cone_mask::TableCones;
use super::cone_mask::{ConeMask, ExactCones};
use super::lod::{Pass, Select};
use super::mask::{CELL_COORD, CELL_Z, HemiMask};
use super::rays::{PaddedBox, PathRays};
use super::triangle::{ConesFour, classify_four};
use super::{Accumulator, Quality, Receiver, TriangleCone, TriangleCounts};
use crate::geom::MeshView;

/// The few cells a cluster's triangles can still set, with what tests their
/// rays against the cluster's span boxes: the center of projection and the
/// cluster's pad ([`ray_pad`](super::rays::ray_pad); its spans lie inside
/// it, so it holds theirs).
#[derive(Clone, Copy)]
pub(super) struct CellPath<'c> {
    /// At most 32 cells, clear when gathered.
    pub(super) rays: &'c PathRays,
    pub(super) origin: Vec3,
    pub(super) pad: f32,
}

/// A chunk's spans as the bits of a `u32` (`chunk_loop`).
const _: () = assert!(CHUNK_SPANS < 32);

/// One chunk's vertices moved into the receiver's frame: local positions and
/// flags, indexed by position in the chunk's list.
/// On the stack, reused from chunk to chunk.
pub(super) struct Projected {
    /// `(x, y, z, 0)`.
    local: [Vec4; CHUNK_VERTICES],
    /// [`ABOVE`], [`INNER`] and [`OUTER`]: one byte per vertex, so that a
    /// triangle's three are ORed at once.
    flags: [u8; CHUNK_VERTICES],
}

/// Not local `z <= 0`.
const ABOVE: u8 = 1;
/// Within the pass's inner radius.
const INNER: u8 = 2;
/// Within the pass's outer radius.
const OUTER: u8 = 4;

impl Projected {
    pub(super) const EMPTY: Projected = Projected {
        local: [Vec4::ZERO; CHUNK_VERTICES],
        flags: [0; CHUNK_VERTICES],
    };

    /// The flags of any of the corners `[a, b, c]`.
    #[inline(always)]
    fn any([a, b, c]: [u8; 3], flags: &[u8; CHUNK_VERTICES]) -> u8 {
        flags[usize::from(a)] | flags[usize::from(b)] | flags[usize::from(c)]
    }
}

/// Bit `k` of the low four bits of `bits` moved to bit `8 k`: the four
/// shifted copies of the multiplication do not overlap, so nothing carries.
#[inline(always)]
fn bits_to_bytes(bits: u32) -> u32 {
    (bits * 0x0020_4081) & 0x0101_0101
}

/// The triangles of one chunk: its vertices moved into the receiver's frame
/// once, then every triangle culled and rasterized from them. The same
/// expressions as [`take`] and [`Accumulator::add`] on the same values, so the
/// same counts and bits.
///
/// The triangles above the horizon are first classified four at a time
/// ([`classify_four`]): most of a dense mesh's are culled or
/// provably cover no cell center, and only the rest take the one-triangle path.
///
/// With `cells`, the only cells the triangles can still set (exact quality),
/// each triangle's three edge planes are instead tested on those cells alone
/// ([`test_cells`]).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn chunk_loop<M: ConeMask>(
    view: &MeshView<'_>,
    clusters: &TriangleClusters,
    chunk: &Chunk,
    acc: &mut Accumulator<'_>,
    pass: &Pass<M>,
    select: Select,
    projected: &mut Projected,
    cells: Option<CellPath<'_>>,
) {
    // On the cell path, the cells whose rays meet each span's box: a span
    // that none meets holds no triangle that can set one of them.
    let mut span_cells = [0u32; CHUNK_SPANS];
    // The spans whose triangles are read: on the cell path those a ray
    // meets (the triangles of the others are left out uncounted, as those of
    // a skipped cluster are), else all.
    let chunk_corners = &clusters.corners[chunk.triangle_range()];
    let mut spans = (1u32 << chunk_corners.len().div_ceil(SPAN)) - 1;
    if let Some(path) = &cells {
        let boxes = &clusters.spans[chunk.span_range()];
        // Four rays at a time against each span.
        let (lanes, all) = (path.rays.lanes(), path.rays.all());
        spans = 0;
        for (s, (met, bounds)) in span_cells.iter_mut().zip(boxes).enumerate() {
            let padded = PaddedBox::new(bounds, path.origin, path.pad);
            for (g, lane) in lanes.iter().enumerate() {
                *met |= lane.meet(&padded) << (4 * g);
            }
            *met &= all;
            spans |= u32::from(*met != 0) << s;
        }
        if spans == 0 {
            return;
        }
    }
    let vertices = &clusters.chunk_vertices[chunk.vertices.0 as usize..chunk.vertices.1 as usize];
    let all_in_range = project_chunk(view, vertices, acc, pass, select, projected);
    // The triangles taken and above the horizon: classified four at a time
    // below. Without branches on the data (the horizon test is a coin flip
    // for the triangles of a cluster crossing it): every triangle is written
    // to the batch, and the count moves only for those kept.
    let mut batch = [[0u8; 3]; CHUNK];
    let mut batched = 0;
    if !all_in_range {
        // A vertex at (nearly) the center of projection or extremely far:
        // one triangle at a time.
        for &corners in chunk_corners {
            let any = Projected::any(corners, &projected.flags);
            let taken = select.takes(any & INNER != 0, any & OUTER != 0);
            if !taken {
                acc.counts.skipped += 1;
            } else if any & ABOVE == 0 {
                acc.counts.below_horizon += 1;
            } else {
                one_triangle(projected, corners, acc, pass);
            }
        }
        return;
    }
    let (mut skipped, mut below) = (0u32, 0u32);
    // Per batch entry, the cells its span's box meets (cell path only).
    let mut picks = [0u32; CHUNK];
    while spans != 0 {
        let span = spans.trailing_zeros() as usize;
        spans &= spans - 1;
        let first = span * SPAN;
        let run = &chunk_corners[first..(first + SPAN).min(chunk_corners.len())];
        for &corners in run {
            let any = Projected::any(corners, &projected.flags);
            let taken = select.takes(any & INNER != 0, any & OUTER != 0);
            let above = any & ABOVE != 0;
            batch[batched] = corners;
            picks[batched] = span_cells[span];
            batched += usize::from(taken & above);
            skipped += u32::from(!taken);
            below += u32::from(taken & !above);
        }
    }
    acc.counts.skipped += skipped;
    acc.counts.below_horizon += below;
    let corners = |t: usize| {
        let [a, b, c] = batch[t];
        let local = &projected.local;
        [
            local[usize::from(a)],
            local[usize::from(b)],
            local[usize::from(c)],
        ]
    };
    match cells {
        Some(path) => test_cells(batched, corners, |t| picks[t], path.rays.cells(), acc, pass),
        None => classify_batch(batched, corners, acc, pass),
    }
}

/// Four triangles' local corners, `(x, y, z, 0)` each, as lanes: x, y and z
/// of each corner, the layout of [`classify_four`] and [`ConesFour`]. A
/// short group (`len < 4`) repeats its first triangle in the missing lanes.
#[inline(always)]
fn gather_four(
    corners: &impl Fn(usize) -> [Vec4; 3],
    start: usize,
    len: usize,
) -> ([[Vec4; 3]; 4], [[Vec4; 3]; 3]) {
    // Written out: `array::map` is not reliably inlined here.
    let four = [
        corners(start),
        corners(start + 1.min(len - 1)),
        corners(start + 2.min(len - 1)),
        corners(start + 3.min(len - 1)),
    ];
    let gather = |corner: usize| {
        let m = glam::Mat4::from_cols(
            four[0][corner],
            four[1][corner],
            four[2][corner],
            four[3][corner],
        )
        .transpose();
        [m.x_axis, m.y_axis, m.z_axis]
    };
    (four, [gather(0), gather(1), gather(2)])
}

/// [`classify_batch`] for triangles that can only set `cells` (exact quality;
/// [`BoxCells::open_cells_into`](super::box_cells::BoxCells::open_cells_into)): the three edge planes of four triangles at a
/// time ([`ConesFour`]) tested on each of those cells still clear. The same
/// predicate as the exact mask on the same `f32` values, so the same bits;
/// the same culling and counts.
#[inline(always)]
fn test_cells<M: ConeMask>(
    count: usize,
    corners: impl Fn(usize) -> [Vec4; 3],
    picks: impl Fn(usize) -> u32,
    cells: &[(u8, u8)],
    acc: &mut Accumulator<'_>,
    pass: &Pass<M>,
) {
    let mut start = 0;
    while start < count {
        let len = (count - start).min(4);
        let (four, lanes) = gather_four(&corners, start, len);
        start += len;
        let cones = ConesFour::new(lanes, pass.cull);
        let used = (1u32 << len) - 1;
        acc.counts.degenerate += (cones.degenerate & used).count_ones();
        acc.counts.back_facing += (cones.back_facing & used).count_ones();
        let live = used & !(cones.degenerate | cones.back_facing);
        let tested = live & cones.scale_free;
        acc.counts.rasterized += tested.count_ones();
        // The cells any of the four may set: those meeting their spans.
        let mut pick = 0;
        for t in start - len..start {
            pick |= picks(t);
        }
        if tested != 0 {
            while pick != 0 {
                let (i, j) = cells[pick.trailing_zeros() as usize];
                pick &= pick - 1;
                let (i, j) = (usize::from(i), usize::from(j));
                if acc.mask.rows[j] >> i & 1 == 1 {
                    continue;
                }
                let (u, v) = (Vec4::splat(CELL_COORD[i]), Vec4::splat(CELL_COORD[j]));
                let z = Vec4::splat(CELL_Z[j][i]);
                if cones.inside(u, v, z) & tested != 0 {
                    acc.mask.rows[j] |= 1 << i;
                }
            }
        }
        // Normals of extreme scale: the one-triangle path.
        one_by_one(live & !cones.scale_free, &four, acc, pass);
    }
}

/// The triangles of `four` in the lanes `lanes` through the one-triangle
/// path ([`ConeMask::or_into`]), with their counts.
#[inline(always)]
fn one_by_one<M: ConeMask>(
    mut lanes: u32,
    four: &[[Vec4; 3]; 4],
    acc: &mut Accumulator<'_>,
    pass: &Pass<M>,
) {
    while lanes != 0 {
        let k = lanes.trailing_zeros() as usize;
        lanes &= lanes - 1;
        let [a, b, c] = four[k];
        match (pass.cone_mask).or_into(
            a.truncate(),
            b.truncate(),
            c.truncate(),
            pass.cull,
            &mut acc.mask,
        ) {
            Ok(()) => acc.counts.rasterized += 1,
            Err(culled) => acc.counts.count(culled),
        }
    }
}

/// [`rasterize_receiver_with_counts`](super::rasterize_receiver_with_counts):
/// every triangle of `mesh` but the sorted `skip` list, each corner moved into
/// the receiver's frame (three times per vertex, as there are no vertex
/// lists), the horizon tested one triangle at a time, and the triangles above
/// it rasterized [`classify_batch`]es of up to [`CHUNK`] at a time. The same
/// expressions as [`Accumulator::add`], so the same bits and counts.
pub(super) fn rasterize_mesh_batched(
    mesh: &MeshView<'_>,
    receiver: &Receiver,
    skip: &[u32],
    cull: bool,
    quality: Quality<'_>,
) -> (HemiMask, TriangleCounts) {
    // SAFETY: the widest build is one the processor runs.
    #[allow(unsafe_code)]
    unsafe {
        batched_in(
            crate::simd::widest_build(),
            mesh,
            receiver,
            skip,
            cull,
            quality,
        )
    }
}

crate::simd::in_builds! {
    /// [`batched`] as compiled for `build`: the same bits and counts in
    /// every build.
    pub(super) fn batched_in(
        mesh: &MeshView<'_>,
        receiver: &Receiver,
        skip: &[u32],
        cull: bool,
        quality: Quality<'_>,
    ) -> (HemiMask, TriangleCounts) {
        batched(mesh, receiver, skip, cull, quality)
    }
}

/// [`rasterize_mesh_batched`] as built, whatever the processor.
#[inline(always)]
pub(super) fn batched(
    mesh: &MeshView<'_>,
    receiver: &Receiver,
    skip: &[u32],
    cull: bool,
    quality: Quality<'_>,
) -> (HemiMask, TriangleCounts) {
    match quality {
        Quality::Exact => batched_loop(mesh, receiver, skip, cull, ExactCones),
        #[cfg(feature = "std")]
        Quality::Table(table) => batched_loop(mesh, receiver, skip, cull, TableCones(table)),
        // Each copy of the four-wide loop is about 34 KB of Cortex-M4 code; bare
        // metal (no `std`) keeps the exact quality's only, and rasterizes the table
        // quality one triangle at a time: the same bits and counts, slower.
        #[cfg(not(feature = "std"))]
        Quality::Table(table) => super::rasterize_mesh(mesh, receiver, skip, |a, b, c, acc| {
            acc.add(a, b, c, cull, super::table_raster(table))
        }),
    }
}

#[inline(always)]
fn batched_loop(
    mesh: &MeshView<'_>,
    receiver: &Receiver,
    skip: &[u32],
    cull: bool,
    cone_mask: impl ConeMask,
) -> (HemiMask, TriangleCounts) {
    let frame = receiver.scaled_frame([mesh.bounds()]);
    let mut acc = Accumulator {
        receiver,
        frame,
        mask: HemiMask::EMPTY,
        counts: TriangleCounts::default(),
    };
    let pass = Pass {
        position: receiver.origin,
        inner_r2: f32::INFINITY,
        outer_r2: f32::INFINITY,
        cull,
        skip_hidden: false,
        cone_mask,
    };
    let o = receiver.origin;
    let in_range = |p: Vec3| (1e-18..=1e18).contains(&(p.x * p.x + p.y * p.y + p.z * p.z));
    let mut batch = [[Vec4::ZERO; 3]; CHUNK];
    let mut batched = 0;
    let mut skip = skip.iter().copied().peekable();
    for t in 0..mesh.triangle_count() {
        // Merge walk over the sorted skip list: O(1) per triangle.
        while skip.next_if(|&s| (s as usize) < t).is_some() {}
        if skip.next_if_eq(&(t as u32)).is_some() {
            acc.counts.skipped += 1;
            while skip.next_if_eq(&(t as u32)).is_some() {}
            continue;
        }
        let [i0, i1, i2] = mesh.triangle_indices(t);
        let a = frame.to_local(mesh.position(i0 as usize) - o);
        let b = frame.to_local(mesh.position(i1 as usize) - o);
        let c = frame.to_local(mesh.position(i2 as usize) - o);
        if a.z <= 0.0 && b.z <= 0.0 && c.z <= 0.0 {
            acc.counts.below_horizon += 1;
            continue;
        }
        if !(in_range(a) & in_range(b) & in_range(c)) {
            match pass.cone_mask.or_into(a, b, c, cull, &mut acc.mask) {
                Ok(()) => acc.counts.rasterized += 1,
                Err(culled) => acc.counts.count(culled),
            }
            continue;
        }
        batch[batched] = [a.extend(0.0), b.extend(0.0), c.extend(0.0)];
        batched += 1;
        if batched == CHUNK {
            classify_batch(batched, |t| batch[t], &mut acc, &pass);
            batched = 0;
        }
    }
    classify_batch(batched, |t| batch[t], &mut acc, &pass);
    (acc.mask, acc.counts)
}

/// Culls and rasterizes `count` triangles above the horizon whose local
/// corners (`(x, y, z, 0)`, squared lengths in `[1e-18, 1e18]`) are
/// `corners(t)`, four at a time ([`classify_four`]); adds their counts.
#[inline(always)]
fn classify_batch<M: ConeMask>(
    count: usize,
    corners: impl Fn(usize) -> [Vec4; 3],
    acc: &mut Accumulator<'_>,
    pass: &Pass<M>,
) {
    let mut start = 0;
    while start < count {
        let len = (count - start).min(4);
        // A short last group's missing lanes: verdicts ignored.
        let (four, lanes) = gather_four(&corners, start, len);
        start += len;
        let verdicts = classify_four(lanes, pass.cull);
        let used = (1u32 << len) - 1;
        acc.counts.degenerate += (verdicts.degenerate & used).count_ones();
        acc.counts.back_facing += (verdicts.back_facing & used).count_ones();
        let settled = verdicts.degenerate | verdicts.back_facing;
        let local = |k: usize| {
            let [a, b, c] = four[k];
            [a.truncate(), b.truncate(), c.truncate()]
        };
        // The lanes whose mask is the exact one (all of them in exact
        // quality): the box verdicts apply to them.
        // Table quality: cones with a table plane take the one-triangle path.
        let exact = used & !settled & verdicts.boxed & pass.cone_mask.exact_lanes(lanes);
        // Exact cones are counted here; those whose box is empty need nothing
        // else.
        acc.counts.rasterized += exact.count_ones();
        // Small boxes: the window's bits, already evaluated.
        // Every lane, without branches: lanes that are not small OR nothing.
        let small = verdicts.small & exact;
        let [first_i, last_i, first_j, last_j] = verdicts.cells;
        for (k, &[row0, row1]) in verdicts.window.iter().enumerate() {
            let on = 0u32.wrapping_sub(small >> k & 1);
            // Other lanes' bounds may be anything in [-1, 32] (or NaN, which
            // converts to 0): clamped only to stay in the grid.
            let (i0, i1) = ((first_i[k] as usize).min(31), (last_i[k] as usize).min(31));
            let (j0, j1) = ((first_j[k] as usize).min(31), (last_j[k] as usize).min(31));
            let columns = HemiMask::columns(i0, i1) & on;
            acc.mask.rows[j0] |= (row0 << i0) & columns & HemiMask::VALID.rows[j0];
            // One-row boxes OR their first row again (no change).
            let row1 = if j1 > j0 { row1 } else { row0 };
            acc.mask.rows[j1] |= (row1 << i0) & columns & HemiMask::VALID.rows[j1];
        }
        // Larger boxes: their cells one triangle at a time.
        let mut boxed = exact & !verdicts.empty & !verdicts.small;
        while boxed != 0 {
            let k = boxed.trailing_zeros() as usize;
            boxed &= boxed - 1;
            let [first_i, last_i, first_j, last_j] = verdicts.cells;
            let cells = (
                first_i[k] as usize,
                last_i[k] as usize,
                first_j[k] as usize,
                last_j[k] as usize,
            );
            // Every cell the cone can set is in its box: when the box is
            // already occluded, ORing the cone in changes nothing.
            if acc.mask.box_is_full(cells) {
                continue;
            }
            // Normals of ordinary scale: the lane's own, computed already.
            if verdicts.scale_free >> k & 1 == 1 {
                TriangleCone::or_planes_in_box(verdicts.lane_normals(k), cells, &mut acc.mask);
            } else {
                TriangleCone::or_exact_in_box(local(k), cells, &mut acc.mask);
            }
        }
        // The rest (wide or tiny cones, table planes): the one-triangle path.
        one_by_one(used & !settled & !exact, &four, acc, pass);
    }
}

/// Moves the chunk's `vertices` into the receiver's scaled frame, four at a
/// time (lane by lane the expressions of [`Frame::to_local`](crate::Frame::to_local)
/// on `p - o` in [`Receiver::scaled_frame`], as [`Accumulator::add`] does, and of
/// [`Pass::within`]), into `projected`; returns whether every one's squared
/// length `(x² + y²) + z²` is in `[1e-18, 1e18]`, the range in which
/// [`classify_four`] applies.
#[inline(always)]
fn project_chunk<M: ConeMask>(
    view: &MeshView<'_>,
    vertices: &[u32],
    acc: &Accumulator<'_>,
    pass: &Pass<M>,
    select: Select,
    projected: &mut Projected,
) -> bool {
    let (o, frame) = (acc.receiver.origin, &acc.frame);
    let splat = |v: Vec3| (Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z));
    let (tx, ty, tz) = splat(frame.tangent);
    let (bx, by, bz) = splat(frame.bitangent);
    let (nx, ny, nz) = splat(frame.normal);
    let (ox, oy, oz) = splat(o);
    let (qx, qy, qz) = splat(pass.position);
    let (inner_r2, outer_r2) = (Vec4::splat(pass.inner_r2), Vec4::splat(pass.outer_r2));
    let mut in_range = true;
    let last = vertices.len() - 1;
    let mut g = 0;
    while g <= last {
        // Lanes past the end repeat the last vertex (their slots are unused).
        let p = |k: usize| {
            view.position(vertices[(g + k).min(last)] as usize)
                .extend(0.0)
        };
        let m = glam::Mat4::from_cols(p(0), p(1), p(2), p(3)).transpose();
        let (px, py, pz) = (m.x_axis, m.y_axis, m.z_axis);
        let (wx, wy, wz) = (px - ox, py - oy, pz - oz);
        let x = tx * wx + ty * wy + tz * wz;
        let y = bx * wx + by * wy + bz * wz;
        let z = nx * wx + ny * wy + nz * wz;
        let length_sq = x * x + y * y + z * z;
        let ok = length_sq.cmpge(Vec4::splat(1e-18)) & length_sq.cmple(Vec4::splat(1e18));
        in_range &= ok.all();
        let local = glam::Mat4::from_cols(x, y, z, Vec4::ZERO).transpose();
        // Not `z <= 0` (NaN included), the horizon test's negation.
        let above = !z.cmple(Vec4::ZERO).bitmask() & 0xf;
        let (inner, outer) = if select == Select::All {
            (0, 0)
        } else {
            let (dx, dy, dz) = (px - qx, py - qy, pz - qz);
            let d2 = dx * dx + dy * dy + dz * dz;
            (d2.cmple(inner_r2).bitmask(), d2.cmple(outer_r2).bitmask())
        };
        for k in 0..4 {
            projected.local[g + k] = local.col(k);
        }
        let flags = (bits_to_bytes(above) * u32::from(ABOVE))
            | (bits_to_bytes(inner) * u32::from(INNER))
            | (bits_to_bytes(outer) * u32::from(OUTER));
        projected.flags[g..g + 4].copy_from_slice(&flags.to_le_bytes());
        g += 4;
    }
    in_range
}

/// One triangle of a chunk through the cone mask, with its counts.
#[inline(always)]
fn one_triangle<M: ConeMask>(
    projected: &Projected,
    corners: [u8; 3],
    acc: &mut Accumulator<'_>,
    pass: &Pass<M>,
) {
    let [a, b, c] =
        [corners[0], corners[1], corners[2]].map(|k| projected.local[usize::from(k)].truncate());
    match pass.cone_mask.or_into(a, b, c, pass.cull, &mut acc.mask) {
        Ok(()) => acc.counts.rasterized += 1,
        Err(culled) => acc.counts.count(culled),
    }
}

/// Reads triangle `t`, applies the near/far rule and rasterizes it if taken.
#[inline(always)]
pub(super) fn take<M: ConeMask>(
    view: &MeshView<'_>,
    t: usize,
    acc: &mut Accumulator<'_>,
    pass: &Pass<M>,
    select: Select,
) {
    let [i0, i1, i2] = view.triangle_indices(t);
    let (a, b, c) = (
        view.position(i0 as usize),
        view.position(i1 as usize),
        view.position(i2 as usize),
    );
    let ((ia, oa), (ib, ob), (ic, oc)) = (pass.within(a), pass.within(b), pass.within(c));
    let taken = select.takes(ia | ib | ic, oa | ob | oc);
    if taken {
        let m = pass.cone_mask;
        acc.add(a, b, c, pass.cull, |a, b, c, cull, mask| {
            m.or_into(a, b, c, cull, mask)
        });
    } else {
        acc.counts.skipped += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_meshes::{bumpy_sphere, normals_of};
    use super::*;
    use crate::hemi::cone_mask::ExactCones;
    use crate::hemi::lod::traverse;
    use crate::hemi::*;
    use alloc::vec::Vec;

    #[test]
    fn chunked_clusters_match_the_plain_loop_in_counts_and_bits() {
        // Cluster sizes below, at and above the chunk size (several chunks per
        // cluster, a short last one), both qualities, culling on and off, with
        // and without a far mesh: masks and counts as the unclustered loop.
        let (positions, indices) = bumpy_sphere(14, 22, 0.25, 0.4);
        let (far_positions, far_indices) = bumpy_sphere(6, 9, 0.25, 0.4);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let far = MeshView::new(&far_positions, &far_indices).unwrap();
        let normals = normals_of(&mesh);
        let table = HalfSpaceTable::new(32);
        for size in [1, 31, 32, 33, 100, 5000] {
            let mut clusters = TriangleClusters::new(&mesh, size);
            let mut far_clusters = TriangleClusters::new(&far, size);
            let (near, coarse) = (clusters.update(mesh), far_clusters.update(far));
            for quality in [Quality::Exact, Quality::Table(&table)] {
                for cull_backfaces in [false, true] {
                    let options = BatchOptions {
                        quality,
                        cull_backfaces,
                        normal_offset: 0.003,
                        ..BatchOptions::default()
                    };
                    for radius in [f32::INFINITY, 0.5] {
                        let plain = HemiScene::with_far(
                            ClusteredMesh::unclustered(mesh),
                            ClusteredMesh::unclustered(far),
                            radius,
                        );
                        let fast = HemiScene::with_far(near, coarse, radius);
                        let (plain, fast) = if radius.is_finite() {
                            (plain, fast)
                        } else {
                            (HemiScene::new(plain.mesh), HemiScene::new(fast.mesh))
                        };
                        for v in (0..mesh.vertex_count()).step_by(5) {
                            let (p, n) = (mesh.position(v), normals[v]);
                            let (a, ca) = scene_mask_with_counts(&plain, p, n, &options);
                            let (b, hidden) = scene_mask_with_counts(&fast, p, n, &options);
                            assert_eq!(a, b, "size {size} vertex {v} radius {radius}");
                            // Boxes of covered cells skip triangles that
                            // would have been rasterized, and only those.
                            assert!(hidden.rasterized <= ca.rasterized);
                            // Without that skip: skipped clusters are not
                            // counted; what is read is counted alike.
                            let (c, cb) = traverse(&fast, p, n, &options, false);
                            assert_eq!(a, c, "size {size} vertex {v} radius {radius}");
                            assert_eq!(ca.rasterized, cb.rasterized, "size {size} vertex {v}");
                            assert_eq!(ca.degenerate, cb.degenerate, "size {size} vertex {v}");
                            assert_eq!(ca.back_facing, cb.back_facing, "size {size} vertex {v}");
                        }
                    }
                }
            }
        }
    }

    /// Far from the world's origin a box's pad (a thousandth of its distance
    /// from the receiver) is far smaller than the rounding of its corners'
    /// coordinates: the clustered walk still gives the plain loop's masks.
    #[test]
    fn clusters_far_from_the_world_origin_match_the_plain_loop() {
        let (rest, indices) = bumpy_sphere(14, 22, 0.25, 0.4);
        for shift in [Vec3::new(1e3, -2e3, 5e2), Vec3::new(-3e4, 1e4, 2e4)] {
            let positions: Vec<[f32; 3]> = rest
                .iter()
                .map(|&p| (Vec3::from(p) + shift).to_array())
                .collect();
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let normals = normals_of(&mesh);
            let mut clusters = TriangleClusters::new(&mesh, TriangleClusters::DEFAULT_SIZE);
            let plain = HemiScene::new(ClusteredMesh::unclustered(mesh));
            let fast = HemiScene::new(clusters.update(mesh));
            let options = BatchOptions {
                normal_offset: 0.003,
                ..BatchOptions::default()
            };
            for (v, &n) in normals.iter().enumerate() {
                let p = mesh.position(v);
                let a = scene_mask_with_counts(&plain, p, n, &options).0;
                let b = scene_mask_with_counts(&fast, p, n, &options).0;
                assert_eq!(a, b, "shift {shift} vertex {v}");
            }
        }
    }

    #[test]
    fn four_bits_spread_to_four_bytes() {
        for bits in 0..16u32 {
            let bytes = bits_to_bytes(bits).to_le_bytes();
            for (k, &byte) in bytes.iter().enumerate() {
                assert_eq!(u32::from(byte), bits >> k & 1, "bits {bits:04b} byte {k}");
            }
        }
    }

    /// The per-cell path's slow twin: the triangles' edge planes tested on
    /// every valid cell set the bits [`classify_batch`] rasterizes, with the
    /// same counts, for triangles of every kind (small, tiny, seen edge-on,
    /// wide, of extreme scale, degenerate, back-facing).
    #[test]
    fn cell_tests_set_the_rasterized_bits() {
        use rand::{Rng, SeedableRng, rngs::SmallRng};
        let mut rng = SmallRng::seed_from_u64(0x5eed_ce11);
        let receiver = Receiver::new(Vec3::ZERO, Vec3::Z, 0.0);
        let every_cell: Vec<(u8, u8)> = crate::hemi::cell_directions()
            .map(|(i, j, _)| (i as u8, j as u8))
            .collect();
        let mut differing_lanes = 0;
        for case in 0..400 {
            let scale = 10f32.powi(rng.random_range(-8..=8));
            let count = rng.random_range(1..=CHUNK);
            // Above the horizon and in range, as the loops batch them.
            let batchable = |t: &[Vec4; 3]| {
                t.iter().any(|p| p.z > 0.0)
                    && t.iter()
                        .all(|p| (1e-18..=1e18).contains(&((p.x * p.x + p.y * p.y) + p.z * p.z)))
            };
            let triangles: Vec<[Vec4; 3]> = core::iter::repeat_with(|| {
                let centre = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(0.05..1.0),
                );
                let size = 10f32.powf(rng.random_range(-6.0..0.3));
                let corner = |rng: &mut SmallRng| {
                    centre
                        + Vec3::new(
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                        ) * size
                };
                let (a, b) = (corner(&mut rng), corner(&mut rng));
                let c = match rng.random_range(0..6) {
                    // Edge-on: the third corner nearly in the plane of
                    // the first two and the center of projection.
                    0 => a * rng.random_range(0.5..2.0) + b * rng.random_range(-0.5..0.5),
                    // Degenerate: a repeated corner.
                    1 if rng.random_bool(0.2) => a,
                    _ => corner(&mut rng),
                };
                [a, b, c].map(|p| (p * scale).extend(0.0))
            })
            .filter(batchable)
            .take(count)
            .collect();
            for cull in [false, true] {
                let pass = Pass {
                    position: Vec3::ZERO,
                    inner_r2: f32::INFINITY,
                    outer_r2: f32::INFINITY,
                    cull,
                    skip_hidden: true,
                    cone_mask: ExactCones,
                };
                let accumulator = || Accumulator {
                    receiver: &receiver,
                    frame: receiver.scaled_frame([]),
                    mask: HemiMask::EMPTY,
                    counts: TriangleCounts::default(),
                };
                let (mut rasterized, mut tested) = (accumulator(), accumulator());
                classify_batch(count, |t| triangles[t], &mut rasterized, &pass);
                // At most 32 cells per call (a triangle's picks are a `u32`):
                // the mask grows from slice to slice, the counts are one call's.
                for (k, slice) in every_cell.chunks(32).enumerate() {
                    let mut part = accumulator();
                    part.mask = tested.mask;
                    let all = (u64::MAX >> (64 - slice.len())) as u32;
                    test_cells(count, |t| triangles[t], |_| all, slice, &mut part, &pass);
                    tested.mask = part.mask;
                    if k == 0 {
                        tested.counts = part.counts;
                    }
                }
                assert_eq!(rasterized.mask, tested.mask, "case {case} cull {cull}");
                assert_eq!(rasterized.counts, tested.counts, "case {case} cull {cull}");
                differing_lanes += usize::from(tested.mask != HemiMask::EMPTY);
            }
        }
        // The test means something only if many batches set cells.
        assert!(differing_lanes > 200, "{differing_lanes} batches set cells");
    }
}
