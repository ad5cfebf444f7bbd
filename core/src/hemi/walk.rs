//! The walk of a receiver over a mesh's hierarchy of cluster boxes. Speed: most
//! triangles of a closed mesh lie below a receiver's horizon, and each is still
//! read and culled. With [`TriangleClusters`](super::TriangleClusters) the
//! triangles are grouped once into clusters of nearby triangles (a k-d order
//! of their centroids), each cluster's bounding box is recomputed every frame
//! ([`TriangleClusters::update`](super::TriangleClusters::update)), and a whole
//! cluster is skipped when its box is at or below the receiver's tangent plane
//! through the center of projection, or entirely inside (far mesh) or outside
//! (full mesh) the near radius. The boxes form a hierarchy (each node the union
//! of 16 neighbours in the k-d order below it, refitted with the clusters),
//! traversed per receiver depth first, each node's children nearest first
//! (after Laine and Karras 2010, method 2): a node failing a test fails it for
//! every box below, and a node whose reachable cells ([`BoxCells`]: a rectangle
//! of the grid and a ring of elevations) are all set already, or hold no cell
//! center, is skipped whole (exact quality: a table mask may set cells just
//! outside its cone), since the mask, an OR, would not change. A node whose
//! rectangle and ring hold at most [`LISTED`] clear cells lists them and keeps
//! those whose center rays meet its box ([`RayList`]; the rectangle of a small
//! far box holds about seven times the cells its rays meet); its children then
//! test only those rays, as a ray tracer's traversal would, instead of bounding
//! their own rectangles. A cluster met by at most [`CELL_PATH`] rays tests the
//! three edge planes of its triangles on those cells alone (`test_cells`
//! (chunk.rs)), each run of four triangles only on the rays that meet its
//! own box (the clusters' span boxes): the cells no triangle of the box can
//! set are exactly those left out, and the test is the exact mask's predicate
//! on the same `f32` values, so the bits are the same. Inside a box of cells that the mask already covers, a
//! cone's exact rasterization adds nothing and is skipped. The masks are
//! identical to the unclustered loop's, bit for bit (the counts of `rasterized`
//! triangles drop by those of the skipped nodes): the box tests evaluate the
//! same `f32` expressions as the per-triangle tests on the box corner that
//! maximises them, and `f32` subtraction, multiplication by a fixed factor and
//! addition are monotone, so a box that fails a test proves every corner in it
//! fails the same test in the same arithmetic. The mask, an OR over triangles,
//! does not depend on their order (tested on spheres in `lod.rs` and on the twisting
//! bunny in `tests/tests/hemi_lod.rs`).

use glam::Vec3;

use super::Accumulator;
use super::box_cells::BoxCells;
use super::chunk::{CellPath, Projected, chunk_loop, take};
use super::clusters::{Aabb, ClusteredMesh, GROUP};
use super::cone_mask::ConeMask;
use super::lod::{Pass, Select};
use super::rays::{
    LIST_CAPACITY, OpenCells, PATH_CAPACITY, PaddedBox, PathRays, RayList, RaySet, ray_pad,
};

/// Adds the triangles of `mesh` that `select` takes, cluster by cluster when there
/// are clusters.
#[inline(always)]
pub(super) fn mesh_loop<M: ConeMask>(
    mesh: &ClusteredMesh<'_>,
    acc: &mut Accumulator<'_>,
    pass: &Pass<M>,
    select: Select,
    projected: &mut Projected,
    walk: &mut Walk,
) {
    let view = &mesh.mesh;
    let Some(clusters) = mesh.clusters else {
        for t in 0..view.triangle_count() {
            take(view, t, acc, pass, select);
        }
        return;
    };
    // The scaled normal: the same expression as the triangles' horizon test.
    let (n, o) = (acc.frame.normal, acc.receiver.origin);
    // Depth first through the hierarchy, the children of a node nearest
    // first, so near occluders fill the mask before the boxes behind them
    // are tested against it. A node's box holds its children's, so each test
    // it fails, every box below it fails too (the tests are monotone in the
    // box).
    let Walk {
        stack,
        inherited,
        open,
        list,
        path,
    } = walk;
    let mut len = 0;
    let top = clusters.nodes.len() - 1;
    let roots = Push {
        boxes: &clusters.nodes[top],
        level: top,
        children: 0..clusters.nodes[top].len(),
        select,
        inherits: false,
    };
    push_nearest_first(roots, (n, o), pass, stack, &mut len);
    while len > 0 {
        len -= 1;
        let Visit {
            level,
            index,
            select,
            inherits,
        } = stack[len];
        let (level, index) = (level as usize, index as usize);
        // Tested here rather than when pushed: the mask has grown since.
        let bounds = &clusters.nodes[level][index];
        acc.counts.nodes += 1;
        // Each box its own pad: one for the whole mesh would be set by its
        // farthest part (a wide ground), and would widen every small box
        // near the receiver by as much.
        let pad = ray_pad(bounds, o);
        // The rays of `list` meeting the box and still clear, when listed.
        let mut met: Option<RaySet> = None;
        if pass.skip_hidden {
            let padded = PaddedBox::new(bounds, o, pad);
            met = if inherits {
                // The parent's rays that meet this box, still clear.
                Some(list.meet(inherited[level], &padded, &acc.mask))
            } else {
                // A few open cells in reach: those whose rays meet the box.
                // Many: every triangle is looked at.
                let reach = BoxCells::of(bounds, &acc.frame, o);
                reach.open_cells_into::<LISTED>(&acc.mask, open).then(|| {
                    let all = list.set_from(open, &acc.frame);
                    list.meet(all, &padded, &acc.mask)
                })
            };
            if met == Some(0) {
                continue;
            }
        }
        if level == 0 {
            // A cluster whose rays are few: its triangles tested on those
            // cells alone.
            let cells = met
                .filter(|met| met.count_ones() as usize <= CELL_PATH)
                .map(|met| {
                    path.gather(list, met);
                    CellPath {
                        rays: path,
                        origin: o,
                        pad,
                    }
                });
            let chunks = clusters.cluster_chunks[index] as usize
                ..clusters.cluster_chunks[index + 1] as usize;
            for chunk in &clusters.chunks[chunks] {
                chunk_loop(view, clusters, chunk, acc, pass, select, projected, cells);
            }
        } else {
            if let Some(met) = met {
                inherited[level - 1] = met;
            }
            let below = &clusters.nodes[level - 1];
            let children = Push {
                boxes: below,
                level: level - 1,
                children: index * GROUP..((index + 1) * GROUP).min(below.len()),
                select,
                inherits: met.is_some(),
            };
            push_nearest_first(children, (n, o), pass, stack, &mut len);
        }
    }
}

/// The most open cells a node may reach for them to be listed and tested
/// ray by ray against its box ([`BoxCells::open_cells_into`], [`RayList`]) and
/// then its children's: 128 is 4–9 % faster than 64 on meshes of 10k–90k
/// triangles and as fast on the bunny (256 is slower there), with far
/// levels or without (the walk keeps one list, so its state stays small).
const LISTED: usize = LIST_CAPACITY;

/// The most cells whose rays meet a cluster for its triangles to be tested on
/// them one by one (`test_cells` (chunk.rs)) rather than rasterized: the three plane
/// tests of four triangles on one cell cost about a tenth of classifying
/// them. At most 32: a triangle's cells are a `u32` of positions in the list
/// (16, 24 and 32 cost the same on the armadillo, 64 two fifths more).
const CELL_PATH: usize = 32;

const _: () = assert!(CELL_PATH <= PATH_CAPACITY);

/// Levels of the hierarchy at most: nine levels of sixteen hold more than
/// `u32::MAX` clusters.
const MAX_LEVELS: usize = 9;

/// What a receiver's walk over a hierarchy keeps on the stack, made once per
/// receiver and reused for each of its meshes: every entry is written before
/// it is read.
pub(super) struct Walk {
    /// Nodes still to visit.
    stack: [Visit; STACK],
    /// Per level, the rays of `list` that met the parent of the nodes of
    /// that level on the stack, clear then (depth first, those nodes share
    /// one parent): a child's rays are among them.
    inherited: [RaySet; MAX_LEVELS],
    /// The open cells of the node visited, when listed afresh.
    open: OpenCells,
    /// The cells listed by the node nearest the root on the path to the
    /// node visited, when it inherits: the only list a walk needs (see
    /// rays.rs).
    list: RayList,
    /// The few rays of the cluster visited.
    path: PathRays,
}

impl Walk {
    pub(super) const EMPTY: Walk = Walk {
        stack: [Visit {
            level: 0,
            index: 0,
            select: Select::All,
            inherits: false,
        }; STACK],
        inherited: [0; MAX_LEVELS],
        open: OpenCells::NONE,
        list: RayList::EMPTY,
        path: PathRays::EMPTY,
    };
}

/// A node of [`TriangleClusters::nodes`](super::TriangleClusters) still to visit, with the rule its
/// triangles still need.
#[derive(Clone, Copy)]
struct Visit {
    level: u32,
    index: u32,
    select: Select,
    /// Whether the parent's rays (the level's entry of the inherited sets)
    /// hold every cell the node can still set.
    inherits: bool,
}

/// Visits on the stack at most: each level of the hierarchy holds at most
/// [`GROUP`] of them (the children of the node last opened there).
const STACK: usize = MAX_LEVELS * GROUP;

/// Sibling nodes to push: `children` of level `level` (boxes `boxes`), under
/// the rule `select`, and whether they inherit their parent's rays.
struct Push<'b> {
    boxes: &'b [Aabb],
    level: usize,
    children: core::ops::Range<usize>,
    select: Select,
    inherits: bool,
}

/// Pushes the nodes of `push` that the receiver may take (horizon test
/// with scaled normal `n` through the center of projection `o`, and the
/// pass's radii), the farthest from `o` first, so the nearest is visited
/// next.
#[inline(always)]
fn push_nearest_first<M: ConeMask>(
    push: Push<'_>,
    (n, o): (Vec3, Vec3),
    pass: &Pass<M>,
    stack: &mut [Visit; STACK],
    len: &mut usize,
) {
    let Push {
        boxes,
        level,
        children,
        select,
        inherits,
    } = push;
    let mut sorted = [(
        0f32,
        Visit {
            level: level as u32,
            index: 0,
            select,
            inherits,
        },
    ); GROUP];
    let mut count = 0;
    for c in children {
        let bounds = &boxes[c];
        let Some(here) = narrow(bounds, n, o, pass, select) else {
            continue;
        };
        let key = bounds.distance_sq(o);
        // Insertion into the descending order: at most 16 entries.
        let mut k = count;
        while k > 0 && sorted[k - 1].0 < key {
            sorted[k] = sorted[k - 1];
            k -= 1;
        }
        sorted[k] = (
            key,
            Visit {
                level: level as u32,
                index: c as u32,
                select: here,
                inherits,
            },
        );
        count += 1;
    }
    for &(_, visit) in &sorted[..count] {
        stack[*len] = visit;
        *len += 1;
    }
}

/// What a receiver takes of the triangles in box `bounds` under `select`: `None`
/// when none (the box at or below the tangent plane through `o` with scaled
/// normal `n`, every corner within the inner radius, or none within the outer
/// one), else the rule that still needs testing per triangle (`All` when every
/// corner passes the distance tests alike).
#[inline(always)]
fn narrow<M: ConeMask>(
    bounds: &Aabb,
    n: Vec3,
    o: Vec3,
    pass: &Pass<M>,
    select: Select,
) -> Option<Select> {
    if bounds.below_plane(n, o) {
        return None;
    }
    if select == Select::All {
        return Some(Select::All);
    }
    let (near, far) = bounds.distance_range_sq(pass.position);
    // Which of the two tests every corner passes or fails alike.
    let needs_inner = select != Select::Near;
    let needs_outer = select != Select::Far;
    let (all_beyond_inner, all_within_inner) = (near > pass.inner_r2, far <= pass.inner_r2);
    let (all_beyond_outer, all_within_outer) = (near > pass.outer_r2, far <= pass.outer_r2);
    if (needs_inner && all_within_inner) || (needs_outer && all_beyond_outer) {
        return None;
    }
    Some(
        match (
            needs_inner && !all_beyond_inner,
            needs_outer && !all_within_outer,
        ) {
            (false, false) => Select::All,
            (false, true) => Select::Near,
            (true, false) => Select::Far,
            (true, true) => Select::Band,
        },
    )
}
