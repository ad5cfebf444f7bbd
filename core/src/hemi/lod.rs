//! Deforming meshes: per frame, every vertex of a mesh is a receiver shadowed by
//! the mesh itself, with an optional simplified far mesh for distant occluders
//! (Kautz, Lehtinen and Aila 2004, the two-level LOD; Lehtinen's thesis §3.3). No
//! precomputation depends on the animation: the caller hands in the current
//! positions (skinned, simulated) every frame, the normals (or computes them with
//! [`vertex_normals`](super::vertex_normals)), and gets transfer vectors
//! ([`transfer_batch`](super::transfer_batch)) or shaded RGB
//! ([`shade_batch`](super::shade_batch)) per vertex in its own slices (the
//! `batch` module); this module is the loop that makes each receiver's mask
//! ([`scene_mask`]) from the scene's meshes and their clusters.
//!
//! The near/far rule, per receiver at vertex position `p` (the vertex itself, not
//! the lifted center of projection) and radius `near_radius`:
//!
//! - a triangle of the full mesh is rasterized when at least one of its corners is
//!   within the radius, `|c - p|² <= near_radius²`;
//! - a triangle of the far mesh is rasterized when all its corners are beyond it,
//!   `|c - p|² > near_radius²`, so the coarse surface never shadows the fine one
//!   near the receiver.
//!
//! Triangles straddling the radius come from the full mesh only, so choose a radius
//! of several far-mesh edge lengths: a far triangle is excluded as soon as one corner
//! is near, which leaves a thin gap in the far surface around the radius, and a
//! full triangle with one near corner may overlap the far surface it stands in for.
//! Without a far mesh every full-mesh triangle is rasterized and the radius is
//! unused.
//!
//! With coarser levels ([`HemiScene::coarser`], made by
//! [`FarField`](super::FarField)) the rule repeats outwards: each far level's
//! triangle is rasterized when all its corners are beyond that level's radius
//! and at least one is within the next level's (the coarsest has no outer
//! bound), so every distance band has exactly one level.
//!
//! Speed: most triangles of a closed mesh lie below a receiver's horizon, and each
//! is still read and culled. With [`TriangleClusters`] the triangles are grouped
//! once into clusters of nearby triangles (a Morton order of their centroids), each
//! cluster's bounding box is recomputed every frame ([`TriangleClusters::update`]),
//! and a whole cluster is skipped when its box is at or below the receiver's
//! tangent plane through the center of projection, or entirely inside (far mesh) or
//! outside (full mesh) the near radius. The boxes form a hierarchy (each node
//! the union of 16 neighbours in the Morton order below it, refitted with the
//! clusters), traversed per receiver depth first, each node's children
//! nearest first (after Laine and Karras 2010, method 2): a node failing a test
//! fails it for every box below, and a node whose reachable cells
//! ([`BoxCells`]: a rectangle of the grid and a ring of elevations) are all
//! set already, or hold no cell center, is skipped whole (exact quality: a
//! table mask may set cells just outside its cone), since the mask, an
//! OR, would not change. A node whose rectangle and ring hold at most
//! [`LISTED`] clear cells lists them and keeps those whose center rays meet
//! its box ([`RayCells`]; the rectangle of a small far box holds about seven
//! times the cells its rays meet); its children then test only those rays, as
//! a ray tracer's traversal would, instead of bounding their own rectangles.
//! A cluster met by at most [`CELL_PATH`] rays tests the three edge planes of
//! its triangles on those cells alone ([`test_cells`]): the cells no triangle
//! of the box can set are exactly those left out, and the test is the exact
//! mask's predicate on the same `f32` values, so the bits are the same. Inside
//! a box of cells that the mask already covers, a cone's exact rasterization
//! adds nothing and is skipped. The masks are
//! identical to the
//! unclustered loop's, bit for bit (the counts of `rasterized` triangles drop by
//! those of the skipped nodes): the box tests evaluate the same `f32` expressions
//! as the per-triangle tests on the box corner that maximises them, and `f32`
//! subtraction, multiplication by a fixed factor and addition are monotone, so a
//! box that fails a test proves every corner in it fails the same test in the same
//! arithmetic. The mask, an OR over triangles, does not depend on their order
//! (tested on spheres here and on the twisting bunny in `tests/tests/hemi_lod.rs`).
//!
//! Inside a cluster the triangles are in chunks of at most 32, each with its own
//! list of distinct vertices (built with the grouping, rebuilt when the index
//! buffer changes). Per receiver a chunk's vertices are moved into the
//! receiver's frame four at a time, once per vertex instead of once per corner;
//! its triangles are culled against the horizon (and the near/far rule)
//! without branches; and those left are classified four at a time
//! (`classify_four` in `triangle.rs`): culling and exact quality's proven cell
//! box, lane by lane the same `f32` expressions as the one-triangle code, so
//! the same verdicts. A box with no cell center is done; boxes of at most
//! 4 × 2 cells are evaluated in the same pass for all four lanes; larger ones
//! one triangle at a time from their box; wide and tiny cones, and table
//! quality's cones with a table plane, take the one-triangle path. Masks and
//! counts equal the unclustered loop's (tests below, and `classify_four`'s
//! against `TriangleCone::new` and the per-cell predicate).
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
//!
//! The far mesh (the bunny by vertex clustering on a 12³ grid, 902 triangles;
//! near radius a tenth of the diagonal) changes the bunny's transfer vectors by
//! 0.65 % on average (p90 2 %, max 7.5 %; `tests/tests/hemi_lod.rs`). Whole-frame
//! rates (every vertex, diffuse + glossy, with and without the far mesh) are
//! printed by `antumbra bench hemi`.
//!
//! Invariants: everything per receiver is on the stack; the batch functions
//! allocate nothing; they are safe to call from many threads at once (the scene is
//! only read); the `parallel` feature spreads vertices over rayon's pool with
//! identical results.

use glam::{Vec3, Vec4};

use super::box_cells::{BoxCells, RayCell, RayCells, ray_pad};
use super::clusters::{Aabb, CHUNK, CHUNK_VERTICES, Chunk, ClusteredMesh, GROUP, TriangleClusters};
use super::mask::{CELL_COORD, CELL_Z, HemiMask};
use super::table::HalfSpaceTable;
use super::triangle::{ConesFour, classify_four};
use super::{Accumulator, Culled, Quality, Receiver, TriangleCone, TriangleCounts, table_raster};
use crate::geom::MeshView;

/// One frame of a deforming mesh as the receivers see it: the full mesh (whose
/// vertices are the receivers), optional simplified far meshes with their own
/// current positions, and the radii between them (see the module docs for the
/// rule).
#[derive(Clone, Copy, Debug)]
pub struct HemiScene<'a> {
    /// The full-resolution mesh.
    pub mesh: ClusteredMesh<'a>,
    /// The simplified mesh for distant occluders, if any.
    pub far: Option<ClusteredMesh<'a>>,
    /// Distance from a receiver's vertex within which occluders come from the full
    /// mesh (mesh units, `>= 0`; `+inf` uses the full mesh everywhere). Unused
    /// without a far mesh.
    pub near_radius: f32,
    /// Coarser far meshes beyond `far`, from fine to coarse, each used beyond
    /// its own radius, which must grow from level to level and exceed
    /// `near_radius` (a [`FarField`](super::FarField) makes them). Empty for the
    /// two-level scene; unused without `far`.
    pub coarser: &'a [FarLevel<'a>],
}

/// A far mesh of a multi-level scene and the distance beyond which it stands in
/// for the finer levels (see [`HemiScene::coarser`]).
#[derive(Clone, Copy, Debug)]
pub struct FarLevel<'a> {
    /// The simplified mesh with its current positions.
    pub mesh: ClusteredMesh<'a>,
    /// Distance from a receiver's vertex within which the finer levels are used:
    /// a triangle of this level is rasterized when all its corners are beyond
    /// it (and, unless this is the coarsest level, at least one corner is within
    /// the next level's radius).
    pub near_radius: f32,
}

impl<'a> HemiScene<'a> {
    /// The full mesh alone, every triangle an occluder.
    #[inline]
    pub fn new(mesh: ClusteredMesh<'a>) -> Self {
        HemiScene {
            mesh,
            far: None,
            near_radius: f32::INFINITY,
            coarser: &[],
        }
    }

    /// The full mesh near the receivers and `far` beyond `near_radius`.
    #[inline]
    pub fn with_far(mesh: ClusteredMesh<'a>, far: ClusteredMesh<'a>, near_radius: f32) -> Self {
        HemiScene {
            mesh,
            far: Some(far),
            near_radius,
            coarser: &[],
        }
    }
}

/// Rasterization options of the batch functions.
#[derive(Clone, Copy, Debug)]
pub struct BatchOptions<'a> {
    /// Exact or table half-space masks.
    pub quality: Quality<'a>,
    /// Skip back-facing triangles (closed, consistently wound meshes only; see
    /// [`Culled::BackFacing`](super::Culled::BackFacing)).
    pub cull_backfaces: bool,
    /// Center of projection `p + normal_offset * n` (see
    /// [`RasterOptions::normal_offset`](super::RasterOptions::normal_offset)).
    pub normal_offset: f32,
    /// Spread the vertices of the batch functions ([`transfer_batch`](super::transfer_batch)
    /// and the `shade_batch*` ones) over rayon's pool. Results are identical
    /// either way. Only the `parallel` feature has a pool; without it the flag
    /// is ignored.
    pub parallel: bool,
}

impl Default for BatchOptions<'_> {
    /// Exact quality, no culling, no offset; on the pool when the `parallel`
    /// feature is on.
    fn default() -> Self {
        BatchOptions {
            quality: Quality::Exact,
            cull_backfaces: false,
            normal_offset: 0.0,
            parallel: cfg!(feature = "parallel"),
        }
    }
}

/// Which triangles of a mesh a receiver takes, by distance (the radii are the
/// pass's).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Select {
    /// Every triangle.
    All,
    /// Triangles with a corner within the outer radius.
    Near,
    /// Triangles with every corner beyond the inner radius.
    Far,
    /// Triangles with every corner beyond the inner radius and a corner within
    /// the outer one: a far level between two others.
    Band,
}

impl Select {
    /// Whether a triangle is taken, from its corners' flags: within the inner
    /// radius, within the outer one.
    #[inline(always)]
    fn takes(self, inner: [bool; 3], outer: [bool; 3]) -> bool {
        let any_inner = inner[0] | inner[1] | inner[2];
        let any_outer = outer[0] | outer[1] | outer[2];
        match self {
            Select::All => true,
            Select::Near => any_outer,
            Select::Far => !any_inner,
            Select::Band => !any_inner & any_outer,
        }
    }
}

/// The mask of the receiver at vertex position `position` with unit `normal`
/// against `scene` (near/far rule of the module docs). Allocation-free.
pub fn scene_mask(
    scene: &HemiScene<'_>,
    position: Vec3,
    normal: Vec3,
    options: &BatchOptions<'_>,
) -> HemiMask {
    scene_mask_with_counts(scene, position, normal, options).0
}

/// [`scene_mask`], also counting the triangles rasterized and culled (triangles of
/// skipped clusters are not counted; the far-mesh ones excluded by distance count
/// as `skipped`).
pub fn scene_mask_with_counts(
    scene: &HemiScene<'_>,
    position: Vec3,
    normal: Vec3,
    options: &BatchOptions<'_>,
) -> (HemiMask, TriangleCounts) {
    traverse(scene, position, normal, options, true)
}

/// [`scene_mask_with_counts`], with the skipping of boxes whose cells are all
/// covered (exact quality only, see [`ConeMask::EXACT`]) as a switch
/// (`skip_hidden`), so tests can compare the counts of everything else with
/// the unclustered loop's.
#[inline(always)]
fn traverse(
    scene: &HemiScene<'_>,
    position: Vec3,
    normal: Vec3,
    options: &BatchOptions<'_>,
    skip_hidden: bool,
) -> (HemiMask, TriangleCounts) {
    let receiver = Receiver::new(position, normal, options.normal_offset);
    let cull = options.cull_backfaces;
    if scene.far.is_none() && !scene.mesh.is_clustered() {
        // One mesh without clusters: the plain rasterizer's batched loop (the
        // same expressions, so the same bits and counts).
        return rasterize_mesh_batched(&scene.mesh.mesh, &receiver, &[], cull, options.quality);
    }
    // One loop per quality so the per-triangle work is monomorphic.
    match options.quality {
        Quality::Exact => scene_loop(scene, &receiver, position, cull, skip_hidden, ExactCones),
        Quality::Table(table) => {
            let cones = TableCones(table);
            scene_loop(scene, &receiver, position, cull, skip_hidden, cones)
        }
    }
}

/// How a pass turns a triangle's local corners into mask cells: one
/// implementation per quality, so the loops are monomorphic.
trait ConeMask: Copy {
    /// Whether the masks are the exact cones': each cell is set exactly when
    /// its center passes the three edge planes. Only then does a triangle
    /// inside a box set only cells the box reaches ([`BoxCells`]; a table
    /// mask may set cells a little outside its cone), and only then may a
    /// few cells be tested one by one instead of rasterizing the triangles.
    const EXACT: bool;

    /// Bit `k` set when the cone of triangle `k` (lanes of the local corners'
    /// x, y and z; not culled) gets its exact mask in this quality, so
    /// [`classify_four`]'s proven box applies.
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
struct ExactCones;

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
struct TableCones<'t>(&'t HalfSpaceTable);

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

/// What every triangle of one receiver's pass is tested and rasterized with.
#[derive(Clone, Copy)]
struct Pass<M> {
    /// The receiver's vertex position, for the near/far rule.
    position: Vec3,
    /// The squared radius within which finer levels stand in for this mesh
    /// ([`Select::Far`] and [`Select::Band`]).
    inner_r2: f32,
    /// The squared radius within which this mesh stands in for coarser levels
    /// ([`Select::Near`] and [`Select::Band`]).
    outer_r2: f32,
    cull: bool,
    /// Skip boxes whose reachable cells are all set ([`BoxCells`]), and test
    /// the triangles of clusters that reach at most [`FEW_CELLS`] open cells
    /// on those cells alone. Exact quality only.
    skip_hidden: bool,
    cone_mask: M,
}

impl<M: ConeMask> Pass<M> {
    /// Whether `p` is within the inner and the outer radius.
    #[inline(always)]
    fn within(&self, p: Vec3) -> (bool, bool) {
        let d2 = (p - self.position).length_squared();
        (d2 <= self.inner_r2, d2 <= self.outer_r2)
    }
}

/// One chunk's vertices moved into the receiver's frame: local positions and
/// flags, indexed by position in the chunk's list.
/// On the stack, reused from chunk to chunk.
struct Projected {
    /// `(x, y, z, 0)`.
    local: [Vec4; CHUNK_VERTICES],
    /// Not local `z <= 0`.
    above: [bool; CHUNK_VERTICES],
    /// Within the pass's inner radius.
    inner: [bool; CHUNK_VERTICES],
    /// Within the pass's outer radius.
    outer: [bool; CHUNK_VERTICES],
}

impl Projected {
    const EMPTY: Projected = Projected {
        local: [Vec4::ZERO; CHUNK_VERTICES],
        above: [false; CHUNK_VERTICES],
        inner: [false; CHUNK_VERTICES],
        outer: [false; CHUNK_VERTICES],
    };
}

#[inline(always)]
fn scene_loop<M: ConeMask>(
    scene: &HemiScene<'_>,
    receiver: &Receiver,
    position: Vec3,
    cull: bool,
    skip_hidden: bool,
    cone_mask: M,
) -> (HemiMask, TriangleCounts) {
    // One scale for every mesh (see Receiver::scaled_frame).
    let levels = match scene.far {
        Some(_) => scene.coarser,
        None => &[],
    };
    let far_bounds = scene.far.as_ref().map(|far| far.mesh.bounds());
    let bounds = core::iter::once(scene.mesh.mesh.bounds())
        .chain(far_bounds)
        .chain(levels.iter().map(|level| level.mesh.mesh.bounds()));
    let mut acc = Accumulator::new(receiver, bounds);
    let pass = |inner: f32, outer: f32| Pass {
        position,
        inner_r2: inner * inner,
        outer_r2: outer * outer,
        cull,
        skip_hidden: skip_hidden && M::EXACT,
        cone_mask,
    };
    let mut projected = Projected::EMPTY;
    let mut walk = Walk::EMPTY;
    let Some(far) = &scene.far else {
        let all = pass(f32::INFINITY, f32::INFINITY);
        mesh_loop(
            &scene.mesh,
            &mut acc,
            &all,
            Select::All,
            &mut projected,
            &mut walk,
        );
        return (acc.mask, acc.counts);
    };
    let near = pass(0.0, scene.near_radius);
    mesh_loop(
        &scene.mesh,
        &mut acc,
        &near,
        Select::Near,
        &mut projected,
        &mut walk,
    );
    // Each far level between its own radius and the next one's.
    let radii = core::iter::once(scene.near_radius).chain(levels.iter().map(|l| l.near_radius));
    let meshes = core::iter::once(far).chain(levels.iter().map(|l| &l.mesh));
    let mut outer = levels.iter().map(|l| l.near_radius);
    for (mesh, inner) in meshes.zip(radii) {
        match outer.next() {
            Some(outer) => {
                let band = pass(inner, outer);
                mesh_loop(
                    mesh,
                    &mut acc,
                    &band,
                    Select::Band,
                    &mut projected,
                    &mut walk,
                );
            }
            None => {
                let far = pass(inner, f32::INFINITY);
                mesh_loop(mesh, &mut acc, &far, Select::Far, &mut projected, &mut walk);
            }
        }
    }
    (acc.mask, acc.counts)
}

/// Adds the triangles of `mesh` that `select` takes, cluster by cluster when there
/// are clusters.
#[inline(always)]
fn mesh_loop<M: ConeMask>(
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
        rays,
        listing,
    } = walk;
    let mut len = 0;
    let top = clusters.nodes.len() - 1;
    let pad = match clusters.nodes[top].split_first() {
        Some((first, rest)) => {
            let root = rest.iter().fold(*first, |all, b| all.union(b));
            ray_pad(&root, o)
        }
        None => 0.0,
    };
    let near = Near { n, o, pass };
    let roots = Push {
        boxes: &clusters.nodes[top],
        level: top,
        children: 0..clusters.nodes[top].len(),
        select,
        inherits: false,
    };
    near.push_nearest_first(roots, stack, &mut len);
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
        let mut listed = false;
        if pass.skip_hidden {
            let met = if inherits {
                // The parent's rays that meet this box, still clear.
                Some(inherited[level].meet_into(bounds, o, pad, &acc.mask, rays))
            } else {
                // A few open cells in reach: those whose rays meet the box.
                // Many: every triangle is looked at.
                let reach = BoxCells::of(bounds, &acc.frame, o);
                reach.open_cells::<LISTED>(&acc.mask).map(|cells| {
                    listing.set_from(&cells, &acc.frame);
                    listing.meet_into(bounds, o, pad, &HemiMask::EMPTY, rays)
                })
            };
            match met {
                Some(0) => continue,
                Some(_) => listed = true,
                None => {}
            }
        }
        if level == 0 {
            // A cluster whose rays are few: its triangles tested on those
            // cells alone.
            let cells = listed
                .then(|| rays.as_slice())
                .filter(|cells| cells.len() <= CELL_PATH);
            let chunks = clusters.cluster_chunks[index] as usize
                ..clusters.cluster_chunks[index + 1] as usize;
            for chunk in &clusters.chunks[chunks] {
                chunk_loop(view, clusters, chunk, acc, pass, select, projected, cells);
            }
        } else {
            if listed {
                inherited[level - 1].copy_from(rays);
            }
            let below = &clusters.nodes[level - 1];
            let children = Push {
                boxes: below,
                level: level - 1,
                children: index * GROUP..((index + 1) * GROUP).min(below.len()),
                select,
                inherits: listed,
            };
            near.push_nearest_first(children, stack, &mut len);
        }
    }
}

/// The most open cells a node may reach for them to be listed and tested
/// ray by ray against its box ([`BoxCells::open_cells`], [`RayCells`]) and
/// then its children's.
const LISTED: usize = 64;

/// The most cells whose rays meet a cluster for its triangles to be tested on
/// them one by one ([`test_cells`]) rather than rasterized: the three plane
/// tests of four triangles on one cell cost about a tenth of classifying
/// them.
const CELL_PATH: usize = 32;

/// Levels of the hierarchy at most: nine levels of sixteen hold more than
/// `u32::MAX` clusters.
const MAX_LEVELS: usize = 9;

/// What a receiver's walk over a hierarchy keeps on the stack, made once per
/// receiver and reused for each of its meshes: every entry is written before
/// it is read.
struct Walk {
    /// Nodes still to visit.
    stack: [Visit; STACK],
    /// Per level, the cells whose rays met the parent of the nodes of that
    /// level on the stack (depth first, those nodes share one parent): a
    /// child's rays are among them.
    inherited: [RayCells<LISTED>; MAX_LEVELS],
    /// The rays meeting the node visited.
    rays: RayCells<LISTED>,
    /// The cells of a node listed afresh.
    listing: RayCells<LISTED>,
}

impl Walk {
    const EMPTY: Walk = Walk {
        stack: [Visit {
            level: 0,
            index: 0,
            select: Select::All,
            inherits: false,
        }; STACK],
        inherited: [RayCells::EMPTY; MAX_LEVELS],
        rays: RayCells::EMPTY,
        listing: RayCells::EMPTY,
    };
}

/// A node of [`TriangleClusters::nodes`] still to visit, with the rule its
/// triangles still need.
#[derive(Clone, Copy)]
struct Visit {
    level: u32,
    index: u32,
    select: Select,
    /// Whether the parent's rays (the level's entry of the inherited lists)
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

/// What decides whether a receiver takes a node and in which order.
struct Near<'p, M> {
    /// Scaled normal of the horizon test.
    n: Vec3,
    /// Center of projection.
    o: Vec3,
    pass: &'p Pass<M>,
}

impl<M: ConeMask> Near<'_, M> {
    /// Pushes the nodes of `push` that its rule may take, the farthest from
    /// the center of projection first, so the nearest is visited next.
    #[inline(always)]
    fn push_nearest_first(&self, push: Push<'_>, stack: &mut [Visit; STACK], len: &mut usize) {
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
            let Some(here) = narrow(bounds, self.n, self.o, self.pass, select) else {
                continue;
            };
            let key = bounds.distance_sq(self.o);
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

/// The triangles of one chunk: its vertices moved into the receiver's frame
/// once, then every triangle culled and rasterized from them. The same
/// expressions as [`take`] and [`Accumulator::add`] on the same values, so the
/// same counts and bits.
///
/// The triangles above the horizon are first classified four at a time
/// ([`ConeMask::classify_four`]): most of a dense mesh's are culled or
/// provably cover no cell center, and only the rest take the one-triangle path.
///
/// With `cells`, the only cells the triangles can still set (exact quality),
/// each triangle's three edge planes are instead tested on those cells alone
/// ([`test_cells`]).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn chunk_loop<M: ConeMask>(
    view: &MeshView<'_>,
    clusters: &TriangleClusters,
    chunk: &Chunk,
    acc: &mut Accumulator<'_>,
    pass: &Pass<M>,
    select: Select,
    projected: &mut Projected,
    cells: Option<&[RayCell]>,
) {
    let vertices = &clusters.chunk_vertices[chunk.vertices.0 as usize..chunk.vertices.1 as usize];
    let all_in_range = project_chunk(view, vertices, acc, pass, select, projected);
    // The triangles taken and above the horizon: classified four at a time
    // below. Without branches on the data (the horizon test is a coin flip
    // for the triangles of a cluster crossing it): every triangle is written
    // to the batch, and the count moves only for those kept.
    let mut batch = [[0u8; 3]; CHUNK];
    let mut batched = 0;
    let triangles = chunk.triangles.0 as usize..chunk.triangles.1 as usize;
    if !all_in_range {
        // A vertex at (nearly) the center of projection or extremely far:
        // one triangle at a time.
        for &corners in &clusters.corners[triangles] {
            let [ia, ib, ic] = [corners[0], corners[1], corners[2]].map(usize::from);
            let (inner, outer) = (&projected.inner, &projected.outer);
            let taken = select.takes(
                [inner[ia], inner[ib], inner[ic]],
                [outer[ia], outer[ib], outer[ic]],
            );
            if !taken {
                acc.counts.skipped += 1;
            } else if !(projected.above[ia] | projected.above[ib] | projected.above[ic]) {
                acc.counts.below_horizon += 1;
            } else {
                one_triangle(projected, corners, acc, pass);
            }
        }
        return;
    }
    let (mut skipped, mut below) = (0u32, 0u32);
    for &corners in &clusters.corners[triangles] {
        let [ia, ib, ic] = [corners[0], corners[1], corners[2]].map(usize::from);
        let (inner, outer) = (&projected.inner, &projected.outer);
        let taken = select.takes(
            [inner[ia], inner[ib], inner[ic]],
            [outer[ia], outer[ib], outer[ic]],
        );
        let above = projected.above[ia] | projected.above[ib] | projected.above[ic];
        batch[batched] = corners;
        batched += usize::from(taken & above);
        skipped += u32::from(!taken);
        below += u32::from(taken & !above);
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
        Some(cells) => test_cells(batched, corners, cells, acc, pass),
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
/// [`BoxCells::open_cells`]): the three edge planes of four triangles at a
/// time ([`ConesFour`]) tested on each of those cells still clear. The same
/// predicate as the exact mask on the same `f32` values, so the same bits;
/// the same culling and counts.
#[inline(always)]
fn test_cells<M: ConeMask>(
    count: usize,
    corners: impl Fn(usize) -> [Vec4; 3],
    cells: &[RayCell],
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
        if tested != 0 {
            for cell in cells {
                let (i, j) = (usize::from(cell.i), usize::from(cell.j));
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
    match quality {
        Quality::Exact => batched_loop(mesh, receiver, skip, cull, ExactCones),
        #[cfg(feature = "std")]
        Quality::Table(table) => batched_loop(mesh, receiver, skip, cull, TableCones(table)),
        // Each copy of the four-wide loop is about 34 KB of Cortex-M4 code; bare
        // metal (no `std`) keeps the exact quality's only, and rasterizes the table
        // quality one triangle at a time: the same bits and counts, slower.
        #[cfg(not(feature = "std"))]
        Quality::Table(table) => super::rasterize_mesh(mesh, receiver, skip, |a, b, c, acc| {
            acc.add(a, b, c, cull, table_raster(table))
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
            if !acc.mask.box_is_full(cells) {
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
/// [`Pass::near`]), into `projected`; returns whether every one's squared
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
            projected.above[g + k] = above >> k & 1 == 1;
            projected.inner[g + k] = inner >> k & 1 == 1;
            projected.outer[g + k] = outer >> k & 1 == 1;
        }
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
fn take<M: ConeMask>(
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
    let taken = select.takes([ia, ib, ic], [oa, ob, oc]);
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
    use super::*;
    use crate::hemi::{
        BatchError, Material, PhongLobe, TransferMethod, TransferSpace, VertexShading,
        VertexSurface, mask_batch, shade_batch, shade_batch_per_vertex, shade_batch_split,
        shade_diffuse, shade_vertex, shade_vertex_towards, transfer_batch, vertex_normals,
        vertex_transfer,
    };
    use crate::hemi::{
        HalfSpaceTable, RasterOptions, TransferTable, rasterize_receiver, rasterize_triangles_into,
    };
    use crate::sh::{Sh, ShRgb};
    use alloc::vec;
    use alloc::vec::Vec;

    /// A closed UV sphere with its radius modulated (concave regions), twisted about
    /// +z by `twist` radians per unit of height.
    fn twisted_sphere(rings: u32, segments: u32, twist: f32) -> (Vec<[f32; 3]>, Vec<u32>) {
        crate::geom::uv_sphere(rings, segments, |theta, phi| {
            let radius = 1.0 + 0.25 * libm::sinf(5.0 * theta) * libm::sinf(4.0 * phi);
            let z = radius * libm::cosf(theta);
            let angle = phi + twist * z;
            [
                radius * libm::sinf(theta) * libm::cosf(angle),
                radius * libm::sinf(theta) * libm::sinf(angle),
                z,
            ]
        })
    }

    fn normals_of(mesh: &MeshView<'_>) -> Vec<Vec3> {
        let mut normals = vec![Vec3::ZERO; mesh.vertex_count()];
        vertex_normals(mesh, &mut normals).unwrap();
        normals
    }

    #[test]
    fn scene_without_far_mesh_is_rasterize_receiver() {
        let (positions, indices) = twisted_sphere(16, 24, 0.7);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        let table = HalfSpaceTable::new(32);
        let mut clusters = TriangleClusters::new(&mesh, 16);
        let clustered = clusters.update(mesh);
        for quality in [Quality::Exact, Quality::Table(&table)] {
            let options = BatchOptions {
                quality,
                normal_offset: 0.01,
                ..BatchOptions::default()
            };
            let raster = RasterOptions {
                quality,
                normal_offset: 0.01,
                ..RasterOptions::default()
            };
            for (v, &n) in normals.iter().enumerate() {
                let p = mesh.position(v);
                let expected = rasterize_receiver(&mesh, p, n, &raster);
                let plain = scene_mask(
                    &HemiScene::new(ClusteredMesh::unclustered(mesh)),
                    p,
                    n,
                    &options,
                );
                let fast = scene_mask(&HemiScene::new(clustered), p, n, &options);
                assert_eq!(plain, expected, "vertex {v}");
                assert_eq!(fast, expected, "vertex {v}");
            }
        }
    }

    #[test]
    fn clusters_change_nothing_with_a_far_mesh_while_deforming() {
        let (rest, indices) = twisted_sphere(20, 32, 0.0);
        let (far_rest, far_indices) = twisted_sphere(8, 12, 0.0);
        let rest_mesh = MeshView::new(&rest, &indices).unwrap();
        let far_rest_mesh = MeshView::new(&far_rest, &far_indices).unwrap();
        let mut clusters = TriangleClusters::new(&rest_mesh, 8);
        let mut far_clusters = TriangleClusters::new(&far_rest_mesh, 8);
        for twist in [0.0f32, 0.5, 1.5] {
            let (positions, _) = twisted_sphere(20, 32, twist);
            let (far_positions, _) = twisted_sphere(8, 12, twist);
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let far = MeshView::new(&far_positions, &far_indices).unwrap();
            let normals = normals_of(&mesh);
            let options = BatchOptions {
                normal_offset: 0.005,
                ..BatchOptions::default()
            };
            let fast_mesh = clusters.update(mesh);
            let fast_far = far_clusters.update(far);
            for radius in [0.0f32, 0.3, 0.8, f32::INFINITY] {
                let plain = HemiScene::with_far(
                    ClusteredMesh::unclustered(mesh),
                    ClusteredMesh::unclustered(far),
                    radius,
                );
                let fast = HemiScene::with_far(fast_mesh, fast_far, radius);
                let r2 = radius * radius;
                for v in (0..mesh.vertex_count()).step_by(3) {
                    let (p, n) = (mesh.position(v), normals[v]);
                    let a = scene_mask(&plain, p, n, &options);
                    let b = scene_mask(&fast, p, n, &options);
                    assert_eq!(a, b, "twist {twist} radius {radius} vertex {v}");
                    // The rule, spelled out.
                    let near = |q: Vec3| (q - p).length_squared() <= r2;
                    let receiver = Receiver::new(p, n, options.normal_offset);
                    let mut expected = HemiMask::EMPTY;
                    let full = mesh.triangles().filter(|t| t.iter().any(|&q| near(q)));
                    let coarse = far.triangles().filter(|t| t.iter().all(|&q| !near(q)));
                    rasterize_triangles_into(
                        &mut expected,
                        &receiver,
                        full.chain(coarse),
                        Quality::Exact,
                        false,
                    );
                    assert_eq!(a, expected, "twist {twist} radius {radius} vertex {v}");
                }
            }
        }
    }

    #[test]
    fn far_levels_take_their_bands_with_and_without_clusters() {
        // The full mesh and three coarser spheres, posed together.
        let grids = [(20, 32), (12, 18), (8, 12), (5, 8)];
        let rest: Vec<_> = grids.map(|(r, s)| twisted_sphere(r, s, 0.0)).into();
        let mut clusters: Vec<TriangleClusters> = rest
            .iter()
            .map(|(p, i)| TriangleClusters::new(&MeshView::new(p, i).unwrap(), 8))
            .collect();
        for twist in [0.0f32, 0.9] {
            let posed: Vec<_> = grids.map(|(r, s)| twisted_sphere(r, s, twist).0).into();
            let views: Vec<MeshView<'_>> = posed
                .iter()
                .zip(&rest)
                .map(|(p, (_, i))| MeshView::new(p, i).unwrap())
                .collect();
            let fast: Vec<ClusteredMesh<'_>> = clusters
                .iter_mut()
                .zip(&views)
                .map(|(c, &v)| c.update(v))
                .collect();
            let mesh = views[0];
            let normals = normals_of(&mesh);
            let options = BatchOptions {
                normal_offset: 0.005,
                ..BatchOptions::default()
            };
            // Radii of the far mesh and its two coarser levels: growing, a
            // band left empty by equal radii, and everything far.
            for radii in [
                [0.3f32, 0.6, 1.2],
                [0.2, 0.2, 0.9],
                [0.0, 0.5, 0.5],
                [0.4, 0.8, f32::INFINITY],
            ] {
                fn level<'m>(
                    meshes: &[ClusteredMesh<'m>],
                    radii: [f32; 3],
                    k: usize,
                ) -> FarLevel<'m> {
                    FarLevel {
                        mesh: meshes[k + 1],
                        near_radius: radii[k],
                    }
                }
                let plain_meshes: Vec<_> = views
                    .iter()
                    .map(|&v| ClusteredMesh::unclustered(v))
                    .collect();
                let plain_levels = [
                    level(&plain_meshes, radii, 1),
                    level(&plain_meshes, radii, 2),
                ];
                let fast_levels = [level(&fast, radii, 1), level(&fast, radii, 2)];
                let plain = HemiScene {
                    coarser: &plain_levels,
                    ..HemiScene::with_far(plain_meshes[0], plain_meshes[1], radii[0])
                };
                let clustered = HemiScene {
                    coarser: &fast_levels,
                    ..HemiScene::with_far(fast[0], fast[1], radii[0])
                };
                for v in (0..mesh.vertex_count()).step_by(5) {
                    let (p, n) = (mesh.position(v), normals[v]);
                    let (a, counts) = scene_mask_with_counts(&plain, p, n, &options);
                    let (b, _) = scene_mask_with_counts(&clustered, p, n, &options);
                    assert_eq!(a, b, "twist {twist} radii {radii:?} vertex {v}");
                    let (_, fast_counts) = traverse(&clustered, p, n, &options, false);
                    assert_eq!(counts.rasterized, fast_counts.rasterized);
                    // The rule, spelled out: level k's triangles with every
                    // corner beyond its radius and one within the next's.
                    let within = |q: Vec3, r: f32| (q - p).length_squared() <= r * r;
                    let bounds = [0.0, radii[0], radii[1], radii[2], f32::INFINITY];
                    let mut expected = HemiMask::EMPTY;
                    let receiver = Receiver::new(p, n, options.normal_offset);
                    for (k, view) in views.iter().enumerate() {
                        let (inner, outer) = (bounds[k], bounds[k + 1]);
                        let taken = view.triangles().filter(|t| {
                            (k == 0 || t.iter().all(|&q| !within(q, inner)))
                                && (k == 3 || t.iter().any(|&q| within(q, outer)))
                        });
                        rasterize_triangles_into(
                            &mut expected,
                            &receiver,
                            taken,
                            Quality::Exact,
                            false,
                        );
                    }
                    assert_eq!(a, expected, "twist {twist} radii {radii:?} vertex {v}");
                }
            }
        }
    }

    #[test]
    fn chunked_clusters_match_the_plain_loop_in_counts_and_bits() {
        // Cluster sizes below, at and above the chunk size (several chunks per
        // cluster, a short last one), both qualities, culling on and off, with
        // and without a far mesh: masks and counts as the unclustered loop.
        let (positions, indices) = twisted_sphere(14, 22, 0.4);
        let (far_positions, far_indices) = twisted_sphere(6, 9, 0.4);
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

    /// The per-cell path's slow twin: the triangles' edge planes tested on
    /// every valid cell set the bits [`classify_batch`] rasterizes, with the
    /// same counts, for triangles of every kind (small, tiny, seen edge-on,
    /// wide, of extreme scale, degenerate, back-facing).
    #[test]
    fn cell_tests_set_the_rasterized_bits() {
        use rand::{Rng, SeedableRng, rngs::SmallRng};
        let mut rng = SmallRng::seed_from_u64(0x5eed_ce11);
        let receiver = Receiver::new(Vec3::ZERO, Vec3::Z, 0.0);
        let every_cell: Vec<RayCell> = crate::hemi::cell_directions()
            .map(|(i, j, _)| RayCell::at(i as u8, j as u8))
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
                test_cells(count, |t| triangles[t], &every_cell, &mut tested, &pass);
                assert_eq!(rasterized.mask, tested.mask, "case {case} cull {cull}");
                assert_eq!(rasterized.counts, tested.counts, "case {case} cull {cull}");
                differing_lanes += usize::from(tested.mask != HemiMask::EMPTY);
            }
        }
        // The test means something only if many batches set cells.
        assert!(differing_lanes > 200, "{differing_lanes} batches set cells");
    }

    #[test]
    fn clusters_regroup_when_the_indices_change() {
        let (positions, indices) = twisted_sphere(10, 16, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut clusters = TriangleClusters::new(&mesh, 40);
        let _ = clusters.update(mesh);
        // Same triangle count, other corners: every triangle's winding flipped
        // and the triangles reversed.
        let mut flipped: Vec<u32> = indices
            .chunks(3)
            .rev()
            .flat_map(|t| [t[0], t[2], t[1]])
            .collect();
        flipped.truncate(indices.len());
        let other = MeshView::new(&positions, &flipped).unwrap();
        let normals = normals_of(&mesh);
        let clustered = clusters.update(other);
        let options = BatchOptions {
            cull_backfaces: true,
            normal_offset: 0.01,
            ..BatchOptions::default()
        };
        for v in (0..mesh.vertex_count()).step_by(3) {
            let (p, n) = (mesh.position(v), normals[v]);
            let plain = scene_mask(
                &HemiScene::new(ClusteredMesh::unclustered(other)),
                p,
                n,
                &options,
            );
            assert_eq!(
                scene_mask(&HemiScene::new(clustered), p, n, &options),
                plain,
                "vertex {v}"
            );
        }
    }

    #[test]
    fn clusters_cull_most_triangles_below_the_horizon() {
        let (positions, indices) = twisted_sphere(30, 64, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        let mut clusters = TriangleClusters::new(&mesh, TriangleClusters::DEFAULT_SIZE);
        assert_eq!(clusters.cluster_count(), mesh.triangle_count().div_ceil(32));
        let scene = HemiScene::new(clusters.update(mesh));
        let options = BatchOptions::default();
        let (mut seen, mut total) = (0u64, 0u64);
        for v in (0..mesh.vertex_count()).step_by(7) {
            let (_, counts) =
                scene_mask_with_counts(&scene, mesh.position(v), normals[v], &options);
            seen += u64::from(counts.rasterized + counts.below_horizon + counts.degenerate);
            total += mesh.triangle_count() as u64;
        }
        // Triangles of skipped clusters are not even read (measured: 36 %).
        assert!(seen * 2 < total, "{seen} of {total} triangles read");
    }

    #[test]
    fn mask_batches_are_scene_masks_on_and_off_the_pool() {
        let (positions, indices) = twisted_sphere(12, 18, 0.5);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        let mut clusters = TriangleClusters::new(&mesh, 16);
        let clustered = clusters.update(mesh);
        for scene in [
            HemiScene::new(ClusteredMesh::unclustered(mesh)),
            HemiScene::new(clustered),
        ] {
            for parallel in [false, true] {
                let options = BatchOptions {
                    normal_offset: 0.01,
                    parallel,
                    ..BatchOptions::default()
                };
                let receiver = |k: usize| (mesh.position(k), normals[k]);
                let mut out = vec![HemiMask::VALID; mesh.vertex_count()];
                mask_batch(&scene, receiver, &options, &mut out);
                for (k, mask) in out.iter().enumerate() {
                    let (p, n) = receiver(k);
                    assert_eq!(*mask, scene_mask(&scene, p, n, &options), "receiver {k}");
                }
            }
        }
    }

    #[test]
    fn batches_match_single_vertices_and_check_their_arguments() {
        let (positions, indices) = twisted_sphere(10, 16, 0.3);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut normals = normals_of(&mesh);
        normals[3] = Vec3::ZERO;
        let table = TransferTable::<9>::new();
        let method = TransferMethod::Cells(&table);
        let scene = HemiScene::new(ClusteredMesh::unclustered(mesh));
        let options = BatchOptions {
            normal_offset: 0.01,
            ..BatchOptions::default()
        };
        let count = mesh.vertex_count();
        let mut transfers = vec![Sh::<9>::ZERO; count];
        transfer_batch(
            &scene,
            &normals,
            &options,
            method,
            TransferSpace::World,
            &mut transfers,
        )
        .unwrap();
        let mut light = ShRgb::<9>::ZERO;
        light.r[0] = 1.0;
        light.g[2] = 0.5;
        light.b[3] = -0.2;
        let lobe = PhongLobe::new(10.0).unwrap();
        let material = Material {
            albedo: Vec3::new(0.8, 0.6, 0.4),
            specular: Vec3::splat(0.2),
            lobe: Some(&lobe),
            eye: Vec3::new(0.0, -5.0, 2.0),
        };
        let mut rgb = vec![Vec3::ZERO; count];
        let mut split = vec![VertexShading::default(); count];
        shade_batch(
            &scene, &normals, &options, method, &light, &material, &mut rgb,
        )
        .unwrap();
        shade_batch_split(
            &scene, &normals, &options, method, &light, &material, &mut split,
        )
        .unwrap();
        // The other side of `parallel`, the bare-array output and per-vertex
        // surfaces give the same bits.
        let flipped = BatchOptions {
            parallel: !options.parallel,
            ..options
        };
        let mut arrays = vec![[f32::NAN; 9]; count];
        transfer_batch(
            &scene,
            &normals,
            &flipped,
            method,
            TransferSpace::World,
            &mut arrays,
        )
        .unwrap();
        assert!(arrays.iter().zip(&transfers).all(|(a, t)| *a == t.coeffs));
        let mut per_vertex = vec![VertexShading::default(); count];
        let surface = |v: usize| VertexSurface {
            material,
            to_eye: (v % 2 == 1).then(|| (material.eye - mesh.position(v)).normalize_or_zero()),
        };
        shade_batch_per_vertex(
            &scene,
            &normals,
            &flipped,
            method,
            &light,
            surface,
            &mut per_vertex,
        )
        .unwrap();
        for v in 0..count {
            let (p, n) = (mesh.position(v), normals[v]);
            if v != 3 && v % 2 == 1 {
                let to_eye = (material.eye - p).normalize_or_zero();
                let towards =
                    shade_vertex_towards(&scene, p, n, &options, method, &light, &material, to_eye);
                assert_eq!(per_vertex[v], towards);
                assert_eq!(towards, split[v]);
            } else {
                assert_eq!(per_vertex[v], split[v]);
            }
        }
        for v in 0..count {
            let (p, n) = (mesh.position(v), normals[v]);
            if v == 3 {
                assert_eq!(transfers[v], Sh::ZERO);
                assert_eq!(rgb[v], Vec3::ZERO);
                continue;
            }
            assert_eq!(
                transfers[v],
                vertex_transfer(&scene, p, n, &options, method, TransferSpace::World)
            );
            let s = shade_vertex(&scene, p, n, &options, method, &light, &material);
            assert_eq!(split[v], s);
            assert_eq!(rgb[v], s.diffuse + s.glossy);
            let expected = shade_diffuse(&transfers[v], &light, material.albedo);
            assert!((s.diffuse - expected).abs().max_element() < 1e-6);
        }
        assert!(split.iter().any(|s| s.glossy != Vec3::ZERO));
        // Argument checks; nothing written on error.
        let before = transfers.clone();
        assert_eq!(
            transfer_batch(
                &scene,
                &normals[1..],
                &options,
                method,
                TransferSpace::Local,
                &mut transfers
            ),
            Err(BatchError::NormalCount {
                expected: count,
                got: count - 1
            })
        );
        assert_eq!(
            transfer_batch(
                &scene,
                &normals,
                &options,
                method,
                TransferSpace::Local,
                &mut transfers[1..]
            ),
            Err(BatchError::OutputLength {
                expected: count,
                got: count - 1
            })
        );
        let far_scene = HemiScene::with_far(scene.mesh, scene.mesh, f32::NAN);
        assert_eq!(
            transfer_batch(
                &far_scene,
                &normals,
                &options,
                method,
                TransferSpace::Local,
                &mut transfers
            ),
            Err(BatchError::NearRadius)
        );
        assert_eq!(transfers, before);
        let mut short = vec![Vec3::ZERO; count - 1];
        assert!(vertex_normals(&mesh, &mut short).is_err());
    }

    #[test]
    fn vertex_normals_of_a_sphere_point_outwards() {
        let (positions, indices) = twisted_sphere(12, 16, 0.0);
        // The bumps tilt them, but they point outwards.
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        for (v, n) in normals.iter().enumerate() {
            let p = mesh.position(v);
            assert!((n.length() - 1.0).abs() < 1e-5);
            assert!(n.dot(p.normalize()) > 0.0, "vertex {v}");
        }
    }

    #[test]
    fn vertex_normals_of_huge_and_tiny_triangles_are_unit() {
        // The summed normal's squared length overflowed (1e10 edges: 1e40) or
        // underflowed (1e-13 edges: 1e-52) into a zero normal.
        let indices = [0u32, 1, 2];
        for scale in [1e10f32, 1e18, 1e-13, 1e-19] {
            let positions = [[0.0, 0.0, 0.0], [scale, 0.0, 0.0], [0.0, scale, 0.0]];
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let mut normals = [Vec3::ZERO; 3];
            vertex_normals(&mesh, &mut normals).unwrap();
            assert_eq!(normals, [Vec3::Z; 3], "edges of {scale}");
        }
        // Still zero where the sum is zero (a flat fan cancels).
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let mesh = MeshView::new(&positions, &[0, 1, 2, 0, 2, 1]).unwrap();
        let mut normals = [Vec3::ONE; 3];
        vertex_normals(&mesh, &mut normals).unwrap();
        assert_eq!(normals, [Vec3::ZERO; 3]);
    }

    #[test]
    fn a_far_eye_still_gets_the_glossy_term() {
        // (eye - position).length_squared() overflowed for an eye 1e20 away, so
        // the view direction was zero and the glossy term vanished.
        let (positions, indices) = twisted_sphere(10, 16, 0.3);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let normals = normals_of(&mesh);
        let scene = HemiScene::new(ClusteredMesh::unclustered(mesh));
        let table = TransferTable::<9>::new();
        let method = TransferMethod::Cells(&table);
        let mut light = ShRgb::<9>::ZERO;
        light.r[0] = 1.0;
        light.g[2] = 0.5;
        light.b[3] = -0.2;
        let lobe = PhongLobe::new(10.0).unwrap();
        let v = 20;
        let (p, n) = (mesh.position(v), normals[v]);
        let direction = (n + Vec3::new(0.1, 0.2, 0.0)).normalize();
        let shade = |distance: f32| {
            let material = Material {
                albedo: Vec3::splat(0.5),
                specular: Vec3::splat(0.3),
                lobe: Some(&lobe),
                eye: p + distance * direction,
            };
            let options = BatchOptions::default();
            shade_vertex(&scene, p, n, &options, method, &light, &material).glossy
        };
        let near = shade(1e3);
        assert_ne!(near, Vec3::ZERO);
        for distance in [1e20f32, 1e30] {
            let far = shade(distance);
            assert!(
                (far - near).abs().max_element() < 1e-4 * near.abs().max_element(),
                "{distance}: {far} vs {near}"
            );
        }
    }
}
