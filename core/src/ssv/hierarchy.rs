//! The 2006 query structure (Lehtinen, Laine and Aila 2006, §4): an octree over
//! the receivers' space whose node keeps the potential silhouette edges whose
//! penumbra wedge and silhouette region may touch the node's box (both tests
//! conservative: [`super::edge_bounds`] in `f32` lanes, [`super::wedge`] in
//! `f64` where the lanes do not apply), subdivided lazily where queries arrive.
//!
//! Invariant: an edge left out of a node contributes nothing to any receiver in
//! the node's box, so a query that walks to the leaf holding its point and runs
//! the exact tests on the leaf's list gets exactly the brute-force bits.
//!
//! Space beyond the root. The root box `B₀` is a hint (by default a cube twice
//! the size of the occluders and the light). A receiver outside it goes to the
//! first of the boxes `B_k` (`B₀`'s centre, `2^k` times its half-extent) that
//! holds it; `B_k` is cut into 4 × 4 × 4 cells, the inner eight of which make
//! `B_{k-1}`, and each of the 56 outer cells (as large as an octant of
//! `B_{k-1}`) is the root of an octree of its own, made when the first query
//! lands in it by testing every potential edge against its box. So every point
//! a query can name is covered by a node as fine as its surroundings need:
//! a receiver never falls back to every edge, wherever the caller puts it
//! (shells reach every finite `f32` point). Cost: one test of every potential
//! edge per cell that receives queries.
//!
//! When a node splits. Splitting a node of `L` edges tests each against the
//! eight octants (about 60 ns per edge in AVX lanes); a query through it tests
//! `L` candidates (a few tens of nanoseconds each that are not silhouettes).
//! So a node is split where enough receivers are to pay for it: a batch
//! ([`Hierarchy::prepare`]) splits it when [`BATCH_SPLIT`] of its receivers
//! fall in it, before any of them is answered; receivers queried alone split
//! it once it has served [`SPLIT_AFTER`] queries (the rent-or-buy rule: the
//! split costs about what those queries cost). A split needs more than
//! `leaf_edges` edges and a level left above the depth limit, and the children
//! are kept only when they pay: their mean list must be at most
//! [`SPLIT_GAIN`] of the node's, or, in a batch, the candidates they save its
//! receivers must be worth the split's tests ([`SPLIT_COST`]); else the node
//! stays a leaf for good (a sample of [`SAMPLED_EDGES`] edges refuses most
//! such splits before the rest are tested). Children's lists are written when
//! a query first enters them (a ground of receivers enters four of every
//! eight), from one octant mask per parent edge.
//!
//! Threads: every lazily made part (a split decision, a child, a shell, a cell)
//! is a once-cell. With `std` a `OnceLock`: concurrent queries that need the
//! same part wait for the one making it. Without `std` a lock-free
//! `once_cell::race::OnceBox`: racing queries may each make it and all but one
//! copy is dropped. Either way a node is never seen half built.

use alloc::boxed::Box;
use alloc::vec::Vec;
use core::sync::atomic::{AtomicU32, AtomicUsize, Ordering};
use glam::DVec3;

use super::SsvOptions;
use super::edge_bounds::EdgeBounds;
use super::edges::EdgeGraph;
use super::wedge::{Aabb, LightShape};
use crate::fallible::{self, OutOfMemory};
use crate::prefetch::prefetch;

/// A split is kept when the children's mean list length is at most this
/// fraction of the parent's (module docs).
pub(crate) const SPLIT_GAIN: f64 = 0.75;

/// Queries a node serves before it tries to split (module docs): as many as
/// the receivers of a batch that make [`Hierarchy::prepare`] split it, so a
/// static scene queried frame after frame refines where a single frame did
/// not pay for it.
pub(crate) const SPLIT_AFTER: u32 = BATCH_SPLIT as u32;

/// Receivers of a batch in a node for [`Hierarchy::prepare`] to split it.
const BATCH_SPLIT: usize = 8;

/// A batch's split pays for itself when it saves its receivers more
/// candidates than this many times the node's list ([`Hierarchy::prepare`]).
/// Testing one edge against eight octants costs about 60 ns in AVX lanes, a
/// candidate that a finer node would have left out 25–30 ns of a query's
/// time under a large light: a ratio of 2–2.5. The rule does not count the
/// splits a kept split makes possible below it, so the constant is set
/// above that ratio: 3 and 5 gave the same frames on the Chinese dragon and
/// the armadillo (5 with fewer nodes), 10 and 20 slower ones.
const SPLIT_COST: f64 = 5.0;

/// Receivers under a node for [`Hierarchy::prepare`] to build its subtrees
/// on several threads.
#[cfg(feature = "parallel")]
const PARALLEL_RECEIVERS: usize = 2048;

/// Edges of the strided sample a split tests first (module docs).
const SAMPLED_EDGES: usize = 32;

/// A split is refused from its sample when the sample's children lists
/// exceed the limits of both rules by this factor (room for the sample's
/// noise: a refused split that would have paid costs more than one made in
/// vain).
const REFUSE_MARGIN: f64 = 1.0;

/// Shells beyond the root: enough for any finite `f32` point around any root
/// (half-extents of at least `2^-150`, points within `2^128`).
const MAX_SHELLS: usize = 288;

/// A value made once, on first use, by whichever thread needs it first.
#[cfg(feature = "std")]
struct Once<T>(std::sync::OnceLock<T>);
#[cfg(not(feature = "std"))]
struct Once<T>(once_cell::race::OnceBox<T>);

impl<T> Once<T> {
    fn new() -> Self {
        Once(Default::default())
    }

    #[cfg(feature = "std")]
    fn with(value: T) -> Result<Self, OutOfMemory> {
        Ok(Once(std::sync::OnceLock::from(value)))
    }

    #[cfg(not(feature = "std"))]
    fn with(value: T) -> Result<Self, OutOfMemory> {
        Ok(Once(once_cell::race::OnceBox::with_value(fallible::boxed(
            value,
        )?)))
    }

    fn get(&self) -> Option<&T> {
        self.0.get()
    }

    /// The value, made by `make` if there is none yet; `None` (and still no
    /// value) when `make` or the memory for it fails.
    ///
    /// Hosted, racing callers wait for the one that makes it, so a node is built
    /// once; a failure there (the system allocator refusing) panics, which the
    /// C boundary returns as ANTUMBRA_RESULT_PANIC. Without std, racing callers
    /// may each make one; one is kept.
    #[cfg(feature = "std")]
    fn get_or_try_init(&self, make: impl FnOnce() -> Option<T>) -> Option<&T> {
        Some(
            self.0
                .get_or_init(|| make().expect("memory for a soft-shadow hierarchy node")),
        )
    }

    #[cfg(not(feature = "std"))]
    fn get_or_try_init(&self, make: impl FnOnce() -> Option<T>) -> Option<&T> {
        self.0
            .get_or_try_init(|| {
                make()
                    .and_then(|value| fallible::boxed(value).ok())
                    .ok_or(())
            })
            .ok()
    }
}

/// What became of a node: a leaf for good, or eight children.
enum Split {
    Leaf,
    Children(Box<Children>),
}

struct Children {
    /// Per edge of the parent (same order), the octants it belongs to.
    masks: Box<[u8]>,
    /// Edges per octant.
    counts: [u32; 8],
    /// Made when a query first enters them.
    nodes: [Once<Node>; 8],
}

struct Node {
    bounds: Aabb,
    /// Splits still allowed below this node (the depth limit).
    levels: u32,
    edges: Box<[u32]>,
    /// Queries served while the split was undecided.
    visits: AtomicU32,
    split: Once<Split>,
}

struct Shell {
    /// Cell `(i, j, k)` (per axis 0..4) at `i + 4 j + 16 k`; the inner eight
    /// stay empty (they are the shell inside).
    cells: [Once<Node>; 64],
}

pub(crate) struct Hierarchy {
    root: Node,
    /// `B₀`'s corners, centre and half-extent.
    root_min: DVec3,
    root_max: DVec3,
    centre: DVec3,
    half: DVec3,
    shells: Vec<Once<Box<Shell>>>,
    bounds: EdgeBounds,
    /// Every slot of `bounds`: lists hold slots, not edges (the lists of
    /// shell cells are cut from this one).
    all: Vec<u32>,
    leaf_edges: usize,
    max_depth: u32,
    nodes: AtomicUsize,
    bytes: AtomicUsize,
}

impl Hierarchy {
    pub fn new(
        graph: &EdgeGraph,
        shape: &LightShape,
        potential: &[u32],
        root: Aabb,
        options: SsvOptions,
    ) -> Result<Self, OutOfMemory> {
        let bounds = EdgeBounds::new(graph, shape, potential)?;
        let all = fallible::collect(0..bounds.edges().len() as u32)?;
        let mut h = Hierarchy {
            root: Node {
                bounds: root,
                levels: 0,
                edges: Box::new([]),
                visits: AtomicU32::new(0),
                split: Once::with(Split::Leaf)?,
            },
            root_min: root.min,
            root_max: root.max,
            centre: root.center(),
            half: root.half(),
            shells: fallible::collect((0..MAX_SHELLS).map(|_| Once::new()))?,
            bounds,
            all,
            leaf_edges: options.leaf_edges as usize,
            max_depth: options.max_depth,
            nodes: AtomicUsize::new(0),
            bytes: AtomicUsize::new(0),
        };
        h.bytes.store(
            h.bounds.bytes() + h.all.capacity() * 4 + h.shells.capacity() * 8,
            Ordering::Relaxed,
        );
        h.root = h.cell(graph, shape, root, h.max_depth)?;
        Ok(h)
    }

    pub fn nodes(&self) -> usize {
        self.nodes.load(Ordering::Relaxed)
    }

    pub fn bytes(&self) -> usize {
        self.bytes.load(Ordering::Relaxed)
    }

    /// A node over `bounds` cut from every potential edge.
    fn cell(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        bounds: Aabb,
        levels: u32,
    ) -> Result<Node, OutOfMemory> {
        // The box is octant 0 of a box twice its size.
        let parent = Aabb {
            min: bounds.min,
            max: bounds.max + (bounds.max - bounds.min),
        };
        let mut masks = fallible::filled(0u8, self.all.len())?;
        self.bounds.octant_masks(
            graph,
            shape,
            &parent,
            &self.all,
            0..self.all.len(),
            &mut masks,
        );
        let kept = masks.iter().filter(|&&m| m & 1 == 1).count();
        let mut edges = fallible::with_capacity(kept)?;
        edges.extend(
            self.all
                .iter()
                .zip(&masks)
                .filter(|&(_, &m)| m & 1 == 1)
                .map(|(&e, _)| e),
        );
        self.node(bounds, levels, edges.into_boxed_slice())
    }

    fn node(&self, bounds: Aabb, levels: u32, edges: Box<[u32]>) -> Result<Node, OutOfMemory> {
        let split = if edges.len() > self.leaf_edges && levels > 0 {
            Once::new()
        } else {
            Once::with(Split::Leaf)?
        };
        self.nodes.fetch_add(1, Ordering::Relaxed);
        self.bytes.fetch_add(
            core::mem::size_of::<Node>() + edges.len() * core::mem::size_of::<u32>(),
            Ordering::Relaxed,
        );
        Ok(Node {
            bounds,
            levels,
            edges,
            visits: AtomicU32::new(0),
            split,
        })
    }

    /// The node's children, when they pay: when their mean list is at most
    /// [`SPLIT_GAIN`] of the node's, or, for a batch whose receivers fall
    /// `receivers[i]` in octant `i`, when the candidates the split saves them
    /// (`Σ receivers[i] (L - L_i)` for lists of `L` and `L_i` edges) are at
    /// least [`SPLIT_COST`] times `L`. (The first rule alone is not weighted
    /// by where the receivers are: a floor of receivers sits in the lower
    /// octants of a root whose upper ones hold the light, and those lower
    /// octants keep nearly every edge at the first split; weighted by a
    /// ratio, the split that the levels below need was refused. The second
    /// adds the splits that pay their batch: deep under a mesh, where a
    /// large light keeps long lists in the octants without receivers, the
    /// first refuses them.)
    /// `None` when there is no memory for the decision (the node stays
    /// undecided, and queries use its list).
    fn split(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        node: &Node,
        receivers: Option<&[u32; 8]>,
    ) -> Option<Split> {
        let edges = &node.edges;
        let mut masks = fallible::filled(0u8, edges.len()).ok()?.into_boxed_slice();
        let pays = |counts, looked_at, margin| split_pays(counts, looked_at, receivers, margin);
        // A strided sample first: most splits that will not pay are refused
        // after testing it alone.
        let step = (edges.len() / SAMPLED_EDGES).max(1);
        let sample = (0..edges.len()).step_by(step);
        if step > 1 {
            self.bounds.octant_masks(
                graph,
                shape,
                &node.bounds,
                edges,
                sample.clone(),
                &mut masks,
            );
            if !pays(
                octant_counts(masks.iter().step_by(step)),
                sample.len(),
                REFUSE_MARGIN,
            ) {
                return Some(Split::Leaf);
            }
            // The edges between the sampled ones.
            let len = edges.len();
            let rest = (0..len)
                .step_by(step)
                .flat_map(move |first| first + 1..(first + step).min(len));
            self.bounds
                .octant_masks(graph, shape, &node.bounds, edges, rest, &mut masks);
        } else {
            self.bounds
                .octant_masks(graph, shape, &node.bounds, edges, sample, &mut masks);
        }
        let counts = octant_counts(masks.iter());
        if !pays(counts, edges.len(), 1.0) {
            return Some(Split::Leaf);
        }
        self.bytes.fetch_add(
            core::mem::size_of::<Children>() + masks.len(),
            Ordering::Relaxed,
        );
        let children = fallible::boxed(Children {
            masks,
            counts,
            nodes: core::array::from_fn(|_| Once::new()),
        })
        .ok()?;
        Some(Split::Children(children))
    }

    /// Child `i` of `node`, made from the parent's masks on first use.
    /// `None` when there is no memory for it (the caller stays at `node`).
    fn child<'a>(&self, node: &Node, children: &'a Children, i: usize) -> Option<&'a Node> {
        children.nodes[i].get_or_try_init(|| {
            let mut edges = fallible::with_capacity(children.counts[i] as usize).ok()?;
            edges.extend(
                node.edges
                    .iter()
                    .zip(children.masks.iter())
                    .filter(|&(_, &m)| m >> i & 1 == 1)
                    .map(|(&e, _)| e),
            );
            self.node(
                node.bounds.octant(i),
                node.levels - 1,
                edges.into_boxed_slice(),
            )
            .ok()
        })
    }

    /// Where `p` starts its walk: the root, or a cell of the first shell
    /// around the root that holds it (module docs); `None` only beyond every
    /// shell (no finite `f32` point).
    fn top_slot(&self, p: DVec3) -> Option<TopSlot> {
        if self.root.bounds.contains(p) {
            return Some(TopSlot::Root);
        }
        // Shell k spans centre ± 2^(k+1) half; its inner part is shell k - 1
        // (the root for k = 0).
        let (mut inner_min, mut inner_max) = (self.root_min, self.root_max);
        let mut scale = 2.0;
        for shell in 0..MAX_SHELLS {
            let outer_min = self.centre - scale * self.half;
            let outer_max = self.centre + scale * self.half;
            if p.cmpge(outer_min).all() && p.cmple(outer_max).all() {
                let cuts = [outer_min, inner_min, self.centre, inner_max, outer_max];
                let slot = |axis: usize| {
                    let x = p[axis];
                    usize::from(x >= cuts[1][axis])
                        + usize::from(x >= cuts[2][axis])
                        + usize::from(x >= cuts[3][axis])
                };
                let (i, j, l) = (slot(0), slot(1), slot(2));
                let corner = |s: [usize; 3]| DVec3::new(cuts[s[0]].x, cuts[s[1]].y, cuts[s[2]].z);
                return Some(TopSlot::Cell {
                    shell,
                    cell: i + 4 * j + 16 * l,
                    bounds: Aabb {
                        min: corner([i, j, l]),
                        max: corner([i + 1, j + 1, l + 1]),
                    },
                });
            }
            (inner_min, inner_max) = (outer_min, outer_max);
            scale *= 2.0;
        }
        None
    }

    /// The node of a [`TopSlot`], made (one test of every edge against its
    /// box) the first time a query starts there.
    /// `None` when there is no memory for it (the caller tests every edge).
    fn top_node(&self, graph: &EdgeGraph, shape: &LightShape, slot: TopSlot) -> Option<&Node> {
        let TopSlot::Cell {
            shell,
            cell,
            bounds,
        } = slot
        else {
            return Some(&self.root);
        };
        let shell_cells = self.shells[shell].get_or_try_init(|| {
            let shell = fallible::boxed(Shell {
                cells: core::array::from_fn(|_| Once::new()),
            })
            .ok()?;
            self.bytes
                .fetch_add(core::mem::size_of::<Shell>(), Ordering::Relaxed);
            Some(shell)
        })?;
        shell_cells.cells[cell].get_or_try_init(|| {
            // As fine as the root's octants allow, at any distance.
            let levels = self.max_depth.saturating_sub(1) + shell as u32;
            self.cell(graph, shape, bounds, levels).ok()
        })
    }

    /// Builds, ahead of a batch of queries, the nodes its receivers `points`
    /// need: from each top node down, a node is split (if undecided) when
    /// [`BATCH_SPLIT`] or more of the receivers fall in it, its children kept
    /// when they pay ([`SPLIT_GAIN`], or [`SPLIT_COST`] for the receivers in
    /// them), and the walk goes on in the children that hold receivers.
    /// Unlike the split rule of single queries (which counts the queries a
    /// node has served), no query pays for a coarse node that the batch will
    /// split, and a node few receivers reach is not refined for them. With
    /// `parallel` (and the `parallel` feature) the subtrees are built on
    /// rayon's threads. The bits of the queries are the same either way.
    ///
    /// Without memory for its bookkeeping it builds nothing: the queries then
    /// build what they need themselves (or use coarser nodes).
    pub fn prepare(&self, graph: &EdgeGraph, shape: &LightShape, points: &[DVec3], parallel: bool) {
        let _ = self.try_prepare(graph, shape, points, parallel);
    }

    fn try_prepare(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        points: &[DVec3],
        parallel: bool,
    ) -> Result<(), OutOfMemory> {
        // Receivers grouped by top node: the root's (key 0), then each shell
        // cell's (key 1 + 64 shell + cell), by a counting sort.
        let keys: Vec<u32> = fallible::collect(points.iter().map(|&p| match self.top_slot(p) {
            Some(TopSlot::Root) => 0,
            Some(TopSlot::Cell { shell, cell, .. }) => 1 + 64 * shell as u32 + cell as u32,
            None => u32::MAX,
        }))?;
        let buckets = 1 + 64 * MAX_SHELLS;
        let mut starts = fallible::filled(0u32, buckets + 1)?;
        for &k in &keys {
            if k != u32::MAX {
                starts[k as usize + 1] += 1;
            }
        }
        for b in 0..buckets {
            starts[b + 1] += starts[b];
        }
        let mut fill = fallible::collect(starts.iter().copied())?;
        let placed = starts[buckets] as usize;
        let mut order = fallible::filled(0u32, placed)?;
        for (i, &k) in keys.iter().enumerate() {
            if k != u32::MAX {
                let slot = &mut fill[k as usize];
                order[*slot as usize] = i as u32;
                *slot += 1;
            }
        }
        let mut scratch = fallible::filled(0u32, placed)?;
        for b in 0..buckets {
            let (lo, hi) = (starts[b] as usize, starts[b + 1] as usize);
            if lo == hi {
                continue;
            }
            let p = points[order[lo] as usize];
            let Some(slot) = self.top_slot(p) else {
                continue;
            };
            let Some(node) = self.top_node(graph, shape, slot) else {
                continue;
            };
            let job = Batch {
                hierarchy: self,
                graph,
                shape,
                points,
                parallel,
            };
            job.refine(node, &mut order[lo..hi], &mut scratch[lo..hi]);
        }
        Ok(())
    }

    /// Calls `visit` with every edge of the leaf holding `p`, building nodes
    /// on the way: an undecided node splits once it has served
    /// [`SPLIT_AFTER`] queries (the rule for receivers that come one at a
    /// time; [`Self::prepare`] decides for a batch before its queries).
    pub fn for_each_candidate(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        p: DVec3,
        visit: impl FnMut(u32),
    ) {
        let Some(slot) = self.top_slot(p) else {
            // Unreachable for finite points (MAX_SHELLS); every edge is right.
            visit_prefetched(graph, self.bounds.edges(), &self.all, visit);
            return;
        };
        // Where memory for a node runs out, the walk stops at the coarser node
        // it reached (or tests every edge): its list holds every candidate of
        // the finer ones, so the bits are the same.
        let Some(mut node) = self.top_node(graph, shape, slot) else {
            visit_prefetched(graph, self.bounds.edges(), &self.all, visit);
            return;
        };
        loop {
            let split = match node.split.get() {
                Some(split) => split,
                None => {
                    if node.visits.fetch_add(1, Ordering::Relaxed) + 1 < SPLIT_AFTER {
                        break;
                    }
                    match node
                        .split
                        .get_or_try_init(|| self.split(graph, shape, node, None))
                    {
                        Some(split) => split,
                        None => break,
                    }
                }
            };
            match split {
                Split::Leaf => break,
                Split::Children(children) => {
                    match self.child(node, children, node.bounds.octant_of(p)) {
                        Some(child) => node = child,
                        None => break,
                    }
                }
            }
        }
        visit_prefetched(graph, self.bounds.edges(), &node.edges, visit);
    }
}

/// Where a walk starts.
#[derive(Clone, Copy)]
enum TopSlot {
    Root,
    Cell {
        shell: usize,
        cell: usize,
        bounds: Aabb,
    },
}

/// Whether a split pays ([`Hierarchy::split`]'s rules), from the children's
/// list lengths `counts` over `looked_at` edges of the node's list: the
/// candidates the expected queries would test in the children (an edge in
/// `m` children is tested there by `m` eighths of them) against
/// [`SPLIT_GAIN`] of those they test in the node, or, for a batch with
/// `receivers[i]` in octant `i`, the candidates those receivers would test
/// in the children against those they test in the node less [`SPLIT_COST`]
/// node lists. `margin` scales both limits (the sample's room).
fn split_pays(
    counts: [u32; 8],
    looked_at: usize,
    receivers: Option<&[u32; 8]>,
    margin: f64,
) -> bool {
    let n = looked_at as f64;
    let after: f64 = counts.iter().map(|&c| f64::from(c)).sum();
    if after <= margin * SPLIT_GAIN * 8.0 * n {
        return true;
    }
    let Some(receivers) = receivers else {
        return false;
    };
    let weighted: f64 = counts
        .iter()
        .zip(receivers)
        .map(|(&c, &r)| f64::from(c) * f64::from(r))
        .sum();
    let receivers_in: f64 = receivers.iter().map(|&r| f64::from(r)).sum();
    weighted <= margin * (receivers_in - SPLIT_COST) * n
}

/// How many of `masks` hold each octant: the children's list lengths.
fn octant_counts<'a>(masks: impl Iterator<Item = &'a u8>) -> [u32; 8] {
    let mut counts = [0u32; 8];
    for &m in masks {
        for (i, count) in counts.iter_mut().enumerate() {
            *count += u32::from(m >> i & 1);
        }
    }
    counts
}

/// What [`Hierarchy::prepare`]'s recursion carries.
#[derive(Clone, Copy)]
struct Batch<'a> {
    hierarchy: &'a Hierarchy,
    graph: &'a EdgeGraph,
    shape: &'a LightShape,
    points: &'a [DVec3],
    #[cfg_attr(not(feature = "parallel"), allow(dead_code))]
    parallel: bool,
}

impl Batch<'_> {
    /// Refines `node` for the receivers `indices` (into `points`), `scratch`
    /// as long as `indices` for their partition by octant.
    fn refine(&self, node: &Node, indices: &mut [u32], scratch: &mut [u32]) {
        let h = self.hierarchy;
        let octant = |i: u32| node.bounds.octant_of(self.points[i as usize]);
        let mut counts = [0u32; 8];
        for &i in indices.iter() {
            counts[octant(i)] += 1;
        }
        let split = match node.split.get() {
            Some(split) => split,
            None if indices.len() < BATCH_SPLIT => return,
            None => match node
                .split
                .get_or_try_init(|| h.split(self.graph, self.shape, node, Some(&counts)))
            {
                Some(split) => split,
                None => return,
            },
        };
        let Split::Children(children) = split else {
            return;
        };
        let mut starts = [0usize; 9];
        for i in 0..8 {
            starts[i + 1] = starts[i] + counts[i] as usize;
        }
        let mut fill = starts;
        for &i in indices.iter() {
            let o = octant(i);
            scratch[fill[o]] = i;
            fill[o] += 1;
        }
        indices.copy_from_slice(scratch);
        // The children's ranges, each with its own part of both buffers.
        let Ok(mut parts) = fallible::with_capacity::<(usize, &mut [u32], &mut [u32])>(8) else {
            return;
        };
        let (mut rest, mut rest_scratch) = (indices, scratch);
        for (i, &count) in counts.iter().enumerate() {
            let n = count as usize;
            let (part, tail) = core::mem::take(&mut rest).split_at_mut(n);
            let (part_scratch, tail_scratch) = core::mem::take(&mut rest_scratch).split_at_mut(n);
            (rest, rest_scratch) = (tail, tail_scratch);
            if n > 0 {
                parts.push((i, part, part_scratch));
            }
        }
        let run = |(i, part, part_scratch): (usize, &mut [u32], &mut [u32])| {
            if let Some(child) = h.child(node, children, i) {
                self.refine(child, part, part_scratch);
            }
        };
        #[cfg(feature = "parallel")]
        if self.parallel && starts[8] >= PARALLEL_RECEIVERS {
            use rayon::prelude::*;
            parts.into_par_iter().for_each(run);
            return;
        }
        parts.into_iter().for_each(run);
    }
}

/// How far ahead of the candidate being visited its reads are requested:
/// the edge (or, where the lane records exist, its record) first, then
/// (without them, the edge arrived by then) the endpoints' positions and
/// the list of third vertices.
const EDGES_AHEAD: usize = 8;
const POSITIONS_AHEAD: usize = 4;

/// Visits the edges of `slots` (`of_slot` maps a slot to its edge) in
/// order, asking the cache ahead of time for what each visit reads first: a
/// leaf's candidates are scattered over the mesh. Where the lane records
/// exist (the processor runs AVX) the set-up lanes read one record per edge
/// ([`EdgeGraph::lane_records`]), and those are asked for (the rare walks
/// that read edges instead go without); without them the chain
/// edge → endpoint positions is two dependent misses per candidate, so a
/// second stage reads only edges the first one requested.
#[inline(always)]
fn visit_prefetched(graph: &EdgeGraph, of_slot: &[u32], slots: &[u32], mut visit: impl FnMut(u32)) {
    if !graph.lane_records.is_empty() {
        // The set-up lanes read an edge's record alone (both its cache
        // lines, where it spans two).
        let words: &[f32] = bytemuck::cast_slice(&graph.lane_records);
        for (i, &slot) in slots.iter().enumerate() {
            if let Some(&ahead) = slots.get(i + EDGES_AHEAD) {
                let first = of_slot[ahead as usize] as usize * 12;
                prefetch(words, first);
                prefetch(words, first + 11);
            }
            visit(of_slot[slot as usize]);
        }
        return;
    }
    for (i, &slot) in slots.iter().enumerate() {
        if let Some(&ahead) = slots.get(i + EDGES_AHEAD) {
            prefetch(&graph.edges, of_slot[ahead as usize] as usize);
        }
        if let Some(&ahead) = slots.get(i + POSITIONS_AHEAD) {
            let edge = &graph.edges[of_slot[ahead as usize] as usize];
            prefetch(&graph.positions, edge.a as usize);
            prefetch(&graph.positions, edge.b as usize);
            prefetch(&graph.third, edge.first as usize);
        }
        visit(of_slot[slot as usize]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The batch rule keeps a split whose children save its receivers more
    /// than [`SPLIT_COST`] node lists where the mean rule refuses it, and
    /// refuses one that saves fewer; without receivers only the mean counts.
    #[test]
    fn a_batch_split_pays_for_the_candidates_it_saves_its_receivers() {
        let list = 1000;
        // Every child keeps every edge but octant 0, which keeps half: the
        // mean (0.94 of the list) is above SPLIT_GAIN.
        let mut counts = [list as u32; 8];
        counts[0] = list as u32 / 2;
        assert!(!split_pays(counts, list, None, 1.0));
        // Receivers in octant 0 save half a list each.
        let mut receivers = [0u32; 8];
        receivers[0] = 2 * SPLIT_COST as u32 + 1;
        assert!(split_pays(counts, list, Some(&receivers), 1.0));
        receivers[0] = 2 * SPLIT_COST as u32 - 1;
        assert!(!split_pays(counts, list, Some(&receivers), 1.0));
        // Receivers where the children keep every edge save nothing.
        let mut elsewhere = [0u32; 8];
        elsewhere[3] = 1000;
        assert!(!split_pays(counts, list, Some(&elsewhere), 1.0));
        // The mean rule alone still keeps a split that halves every list,
        // whoever the receivers are.
        let halved = [list as u32 / 2; 8];
        assert!(split_pays(halved, list, None, 1.0));
        assert!(split_pays(halved, list, Some(&elsewhere), 1.0));
    }
}
