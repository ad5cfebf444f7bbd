//! The 2006 query structure (Lehtinen, Laine and Aila 2006, §4): an octree over
//! the receivers' space whose node keeps the potential silhouette edges whose
//! penumbra wedge and silhouette region may touch the node's box (both tests
//! conservative, [`super::wedge`]), subdivided lazily where queries arrive.
//!
//! Invariant: an edge left out of a node contributes nothing to any receiver in
//! the node's box, so a query that walks to the leaf holding its point and runs
//! the exact tests on the leaf's list gets exactly the brute-force bits.
//!
//! A node with more than `leaf_edges` edges and depth below `max_depth` gets its
//! eight children the first time a query passes through it. With `std` the
//! children array is a `OnceLock`: concurrent queries may race to build it, one
//! wins, the others wait for it (never a torn node). Without `std` there is no
//! portable blocking once-cell and `unsafe` is off, so the octree is subdivided
//! eagerly at creation to depth [`super::NO_STD_EAGER_DEPTH`] and queries walk
//! what exists.

use alloc::boxed::Box;
use alloc::vec::Vec;
use core::sync::atomic::{AtomicUsize, Ordering};
use glam::DVec3;

use super::SsvOptions;
use super::edges::EdgeGraph;
use super::wedge::{Aabb, LightShape, box_may_see_silhouette, box_meets_wedge};

#[cfg(feature = "std")]
type Children = std::sync::OnceLock<Box<[Node; 8]>>;
#[cfg(not(feature = "std"))]
type Children = Option<Box<[Node; 8]>>;

struct Node {
    bounds: Aabb,
    depth: u32,
    edges: Vec<u32>,
    children: Children,
}

pub(crate) struct Hierarchy {
    root: Node,
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
        options: SsvOptions,
    ) -> Self {
        let edges: Vec<u32> = potential
            .iter()
            .copied()
            .filter(|&e| keep(graph, shape, e, &root))
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
            all: potential.to_vec(),
            leaf_edges: options.leaf_edges as usize,
            max_depth: options.max_depth,
            nodes: AtomicUsize::new(1),
            bytes: AtomicUsize::new(bytes),
        };
        #[cfg(not(feature = "std"))]
        {
            let (leaf, max) = (h.leaf_edges, h.max_depth.min(super::NO_STD_EAGER_DEPTH));
            let (mut count, mut total) = (0, 0);
            Self::subdivide_eagerly(graph, shape, &mut h.root, leaf, max, &mut count, &mut total);
            h.nodes.fetch_add(count, Ordering::Relaxed);
            h.bytes.fetch_add(total, Ordering::Relaxed);
        }
        h
    }

    #[cfg(not(feature = "std"))]
    fn subdivide_eagerly(
        graph: &EdgeGraph,
        shape: &LightShape,
        node: &mut Node,
        leaf: usize,
        max_depth: u32,
        count: &mut usize,
        bytes: &mut usize,
    ) {
        if node.edges.len() <= leaf || node.depth >= max_depth {
            return;
        }
        let mut children = Self::split(graph, shape, node);
        *count += 8;
        *bytes += children.iter().map(node_bytes).sum::<usize>();
        for child in children.iter_mut() {
            Self::subdivide_eagerly(graph, shape, child, leaf, max_depth, count, bytes);
        }
        node.children = Some(children);
    }

    fn split(graph: &EdgeGraph, shape: &LightShape, node: &Node) -> Box<[Node; 8]> {
        Box::new(core::array::from_fn(|i| {
            let bounds = node.bounds.octant(i);
            Node {
                bounds,
                depth: node.depth + 1,
                edges: node
                    .edges
                    .iter()
                    .copied()
                    .filter(|&e| keep(graph, shape, e, &bounds))
                    .collect(),
                children: Children::default(),
            }
        }))
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
        mut visit: impl FnMut(u32),
    ) {
        if !self.root.bounds.contains(p) {
            self.all.iter().for_each(|&e| visit(e));
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
        node.edges.iter().for_each(|&e| visit(e));
    }

    #[cfg(feature = "std")]
    fn children<'a>(
        &self,
        graph: &EdgeGraph,
        shape: &LightShape,
        node: &'a Node,
    ) -> Option<&'a [Node; 8]> {
        Some(node.children.get_or_init(|| {
            let children = Self::split(graph, shape, node);
            self.nodes.fetch_add(8, Ordering::Relaxed);
            self.bytes
                .fetch_add(children.iter().map(node_bytes).sum(), Ordering::Relaxed);
            children
        }))
    }

    #[cfg(not(feature = "std"))]
    fn children<'a>(&self, _: &EdgeGraph, _: &LightShape, node: &'a Node) -> Option<&'a [Node; 8]> {
        node.children.as_deref()
    }
}
