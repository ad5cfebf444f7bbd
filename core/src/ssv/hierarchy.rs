//! The 2006 query structure (Lehtinen, Laine and Aila 2006, §4): an octree over
//! the receivers' space whose node keeps the potential silhouette edges whose
//! penumbra wedge and silhouette region may touch the node's box (both tests
//! conservative, [`super::wedge`]), subdivided lazily where queries arrive.
//!
//! The wedge test is also run per part of the light: an edge matters to `p`
//! only if `p` lies in the wedge of the part of the light from which the edge
//! is a silhouette (the argument and the pieces are the hemicube's,
//! [`super::hemicube`] module docs), so a node keeps an edge only when its box
//! may meet the wedge of one of those pieces (after the whole-light tests,
//! which are cheaper and reject most). Measured with `antumbra bench ssv
//! --samples 256` (leaf edges 32, depth 12): node memory 12 → 6.4 MiB on the
//! armadillo (52k triangles), 920 → 420 KiB on the bunny, 330 → 121 KiB on the
//! teapot; candidates per query 14.0 / 14.0 / 13.2 → 12.8 / 11.4 / 9.3 on the
//! bunny (horizontal / 45° / 80° light), about unchanged on the armadillo
//! (80 / 74 / 33 → 81 / 72 / 31), where some 73% of the candidates already
//! have a non-zero weight at the receiver (real silhouettes).
//!
//! Invariant: an edge left out of a node contributes nothing to any receiver in
//! the node's box, so a query that walks to the leaf holding its point and runs
//! the exact tests on the leaf's list gets exactly the brute-force bits.
//!
//! A node with more than `leaf_edges` edges and depth below `max_depth` tries a
//! split the first time a query passes through it, and keeps the eight children
//! only when the split pays: a query's cost is about its leaf's list length
//! times the per-candidate cost, so a split is kept when the children's mean
//! list is at most [`SPLIT_GAIN`] of the parent's; otherwise the node stays a
//! leaf for good (the trial children are dropped). Near penumbrae many wedges
//! cover a whole node and its children alike; without this rule such nodes split
//! to the depth limit (tens of thousands of nodes for a floor of receivers), with
//! it construction stays a small fraction of a dense image's query time. With
//! `std` the split decision is a `OnceLock`: concurrent queries may race to make
//! it, one wins, the others wait for it (never a torn node). Without `std` there is no
//! portable blocking once-cell and `unsafe` is off, so the octree is subdivided
//! eagerly at creation to depth [`super::NO_STD_EAGER_DEPTH`] and queries walk
//! what exists.

use alloc::boxed::Box;
use alloc::vec::Vec;
use core::sync::atomic::{AtomicUsize, Ordering};
use glam::DVec3;

use super::SsvOptions;
use super::edges::EdgeGraph;
use super::hemicube::{grown_light, silhouette_pieces};
use super::wedge::{
    Aabb, LightShape, box_may_see_silhouette, box_meets_wedge, octants_meeting_wedge,
    octants_seeing_silhouette,
};
use crate::prefetch::prefetch;

/// A split is kept when the children's mean list length is at most this
/// fraction of the parent's (module docs).
pub(crate) const SPLIT_GAIN: f64 = 0.75;

#[cfg(feature = "std")]
type Children = std::sync::OnceLock<Option<Box<[Node; 8]>>>;
#[cfg(not(feature = "std"))]
type Children = Option<Box<[Node; 8]>>;

/// The light as the per-piece cut needs it: the grown region `K` (in-plane
/// outline), its thickness `tol` and the scale of the rounding slack.
struct Cut {
    region: Vec<DVec3>,
    tol: f64,
    scale: f64,
}

impl Cut {
    fn new(shape: &LightShape, origin: DVec3) -> Self {
        let scale = shape
            .vertices
            .iter()
            .fold(origin.abs().max_element(), |m, v| {
                m.max(v.abs().max_element())
            });
        let tol = shape.tolerance + PIECE_SLACK * scale;
        Cut {
            region: grown_light(shape, origin, tol),
            tol,
            scale,
        }
    }

    /// Of the octants in `mask`, those that may meet the wedge of some part of
    /// the light from which the edge may be a silhouette.
    fn octants(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        e: u32,
        bounds: &Aabb,
        mask: u8,
    ) -> u8 {
        let edge = &graph.edges[e as usize];
        let Some(pieces) = silhouette_pieces(graph, edge, &self.region, self.tol, self.scale)
        else {
            return mask;
        };
        let a = graph.positions[edge.a as usize].as_dvec3();
        let b = graph.positions[edge.b as usize].as_dvec3();
        let mut out = 0;
        for piece in pieces {
            let light = LightShape {
                vertices: piece,
                normal: shape.normal,
                tolerance: self.tol,
            };
            out |= octants_meeting_wedge(&light, a, b, bounds);
            if out & mask == mask {
                break;
            }
        }
        out & mask
    }

    fn keep(&self, graph: &EdgeGraph, shape: &LightShape, e: u32, bounds: &Aabb) -> bool {
        let edge = &graph.edges[e as usize];
        let Some(pieces) = silhouette_pieces(graph, edge, &self.region, self.tol, self.scale)
        else {
            return true;
        };
        let a = graph.positions[edge.a as usize].as_dvec3();
        let b = graph.positions[edge.b as usize].as_dvec3();
        pieces.into_iter().any(|piece| {
            let light = LightShape {
                vertices: piece,
                normal: shape.normal,
                tolerance: self.tol,
            };
            box_meets_wedge(&light, a, b, bounds)
        })
    }
}

/// Relative rounding slack of the pieces' vertices (as the hemicube's).
const PIECE_SLACK: f64 = 1e-9;

struct Node {
    bounds: Aabb,
    depth: u32,
    edges: Vec<u32>,
    children: Children,
}

pub(crate) struct Hierarchy {
    root: Node,
    cut: Cut,
    all: Vec<u32>,
    leaf_edges: usize,
    max_depth: u32,
    nodes: AtomicUsize,
    bytes: AtomicUsize,
}

fn keep(graph: &EdgeGraph, shape: &LightShape, e: u32, bounds: &Aabb) -> bool {
    let edge = &graph.edges[e as usize];
    let a = graph.positions[edge.a as usize].as_dvec3();
    let b = graph.positions[edge.b as usize].as_dvec3();
    box_may_see_silhouette(graph, edge, bounds) && box_meets_wedge(shape, a, b, bounds)
}

fn node_bytes(node: &Node) -> usize {
    core::mem::size_of::<Node>() + node.edges.capacity() * core::mem::size_of::<u32>()
}

impl Hierarchy {
    pub fn new(
        graph: &EdgeGraph,
        shape: &LightShape,
        potential: &[u32],
        root: Aabb,
        origin: DVec3,
        options: SsvOptions,
    ) -> Self {
        let cut = Cut::new(shape, origin);
        let edges: Vec<u32> = potential
            .iter()
            .copied()
            .filter(|&e| keep(graph, shape, e, &root) && cut.keep(graph, shape, e, &root))
            .collect();
        let root = Node {
            bounds: root,
            depth: 0,
            edges,
            children: Children::default(),
        };
        let bytes = node_bytes(&root) + core::mem::size_of_val(potential);
        #[allow(unused_mut)]
        let mut h = Hierarchy {
            root,
            cut,
            all: potential.to_vec(),
            leaf_edges: options.leaf_edges as usize,
            max_depth: options.max_depth,
            nodes: AtomicUsize::new(1),
            bytes: AtomicUsize::new(bytes),
        };
        #[cfg(not(feature = "std"))]
        {
            let (leaf, max) = (h.leaf_edges, h.max_depth.min(super::NO_STD_EAGER_DEPTH));
            // Nodes added and their bytes.
            let mut added = (0, 0);
            Self::subdivide_eagerly(graph, shape, &h.cut, &mut h.root, (leaf, max), &mut added);
            let (count, total) = added;
            h.nodes.fetch_add(count, Ordering::Relaxed);
            h.bytes.fetch_add(total, Ordering::Relaxed);
        }
        h
    }

    #[cfg(not(feature = "std"))]
    fn subdivide_eagerly(
        graph: &EdgeGraph,
        shape: &LightShape,
        cut: &Cut,
        node: &mut Node,
        (leaf, max_depth): (usize, u32),
        added: &mut (usize, usize),
    ) {
        if node.edges.len() <= leaf || node.depth >= max_depth {
            return;
        }
        let Some(mut children) = Self::split(graph, shape, cut, node) else {
            return;
        };
        added.0 += 8;
        added.1 += children.iter().map(node_bytes).sum::<usize>();
        for child in children.iter_mut() {
            Self::subdivide_eagerly(graph, shape, cut, child, (leaf, max_depth), added);
        }
        node.children = Some(children);
    }

    /// The node's eight children, when they pay ([`SPLIT_GAIN`]). Each edge is
    /// tested against the eight octants at once (shared per-direction work).
    fn split(
        graph: &EdgeGraph,
        shape: &LightShape,
        cut: &Cut,
        node: &Node,
    ) -> Option<Box<[Node; 8]>> {
        let mut lists: [Vec<u32>; 8] = Default::default();
        for &e in &node.edges {
            let edge = &graph.edges[e as usize];
            let mut mask = octants_seeing_silhouette(graph, edge, &node.bounds);
            if mask != 0 {
                let a = graph.positions[edge.a as usize].as_dvec3();
                let b = graph.positions[edge.b as usize].as_dvec3();
                mask &= octants_meeting_wedge(shape, a, b, &node.bounds);
            }
            if mask != 0 {
                mask = cut.octants(graph, shape, e, &node.bounds, mask);
            }
            for (i, list) in lists.iter_mut().enumerate() {
                if mask >> i & 1 == 1 {
                    list.push(e);
                }
            }
        }
        let total: usize = lists.iter().map(Vec::len).sum();
        if total as f64 > 8.0 * SPLIT_GAIN * node.edges.len() as f64 {
            return None;
        }
        let mut lists = lists.into_iter();
        Some(Box::new(core::array::from_fn(|i| {
            let mut edges = lists.next().unwrap_or_default();
            edges.shrink_to_fit();
            Node {
                bounds: node.bounds.octant(i),
                depth: node.depth + 1,
                edges,
                children: Children::default(),
            }
        })))
    }

    pub fn nodes(&self) -> usize {
        self.nodes.load(Ordering::Relaxed)
    }

    pub fn bytes(&self) -> usize {
        self.bytes.load(Ordering::Relaxed)
    }

    /// Calls `visit` with every edge of the leaf holding `p` (every potential
    /// edge when `p` is outside the root), building nodes on the way.
    pub fn for_each_candidate(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        p: DVec3,
        visit: impl FnMut(u32),
    ) {
        if !self.root.bounds.contains(p) {
            visit_prefetched(graph, &self.all, visit);
            return;
        }
        let mut node = &self.root;
        loop {
            let children = if node.edges.len() > self.leaf_edges && node.depth < self.max_depth {
                self.children(graph, shape, node)
            } else {
                None
            };
            match children {
                Some(c) => node = &c[node.bounds.octant_of(p)],
                None => break,
            }
        }
        visit_prefetched(graph, &node.edges, visit);
    }

    #[cfg(feature = "std")]
    fn children<'a>(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        node: &'a Node,
    ) -> Option<&'a [Node; 8]> {
        node.children
            .get_or_init(|| {
                let children = Self::split(graph, shape, &self.cut, node)?;
                self.nodes.fetch_add(8, Ordering::Relaxed);
                self.bytes
                    .fetch_add(children.iter().map(node_bytes).sum(), Ordering::Relaxed);
                Some(children)
            })
            .as_deref()
    }

    #[cfg(not(feature = "std"))]
    fn children<'a>(&self, _: &EdgeGraph, _: &LightShape, node: &'a Node) -> Option<&'a [Node; 8]> {
        node.children.as_deref()
    }
}

/// How far ahead of the candidate being visited its reads are requested:
/// the edge record first, then (its record arrived by then) the endpoints'
/// positions and the list of third vertices.
const EDGES_AHEAD: usize = 8;
const POSITIONS_AHEAD: usize = 4;

/// Visits `edges` in order, asking the cache ahead of time for what each
/// visit reads first: a leaf's candidates are scattered over the mesh, and
/// the chain edge record → endpoint positions is two dependent misses per
/// candidate (measured with `perf`: the largest single stall of a query).
/// The second stage reads only records the first one requested. (Requesting
/// the third vertices' positions as well measured no better.)
#[inline(always)]
fn visit_prefetched(graph: &EdgeGraph, edges: &[u32], mut visit: impl FnMut(u32)) {
    for (i, &e) in edges.iter().enumerate() {
        if let Some(&ahead) = edges.get(i + EDGES_AHEAD) {
            prefetch(&graph.edges, ahead as usize);
        }
        if let Some(&ahead) = edges.get(i + POSITIONS_AHEAD) {
            let edge = &graph.edges[ahead as usize];
            prefetch(&graph.positions, edge.a as usize);
            prefetch(&graph.positions, edge.b as usize);
            prefetch(&graph.third, edge.first as usize);
        }
        visit(e);
    }
}
