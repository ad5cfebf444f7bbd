//! A binary hierarchy collapsed to the compressed eight-wide form greedily,
//! for [`BuildQuality::Fast`](super::BuildQuality::Fast).
//!
//! obvhs's conversion chooses each node's children by the cost model of
//! Ylitie et al. 2017, a dynamic programme over seven decisions per binary
//! node: on a scene of 89,000 triangles it writes about 15 MB of decisions
//! and takes as long as the PLOC build itself. A scene that answers one ray
//! per receiver does not earn that back. Here each wide node takes its binary
//! node's two children and opens the child of largest surface area (of those
//! holding more than three triangles) until it has eight, the usual greedy
//! rule for wide hierarchies; a child of at most three triangles becomes a
//! leaf. One backward pass counts each subtree's triangles, one pass from
//! the root collapses: no table of decisions.
//!
//! The layout is obvhs's, so the traversal, the refit and the leaf blocks
//! read it unchanged: a node's inner children follow each other from
//! `child_base_idx` in slot order and are numbered after it (depth first),
//! a leaf's triangles follow each other from `primitive_base_idx` at the
//! offset its meta byte holds, with the count in unary in the meta's top
//! bits, and the child boxes are quantised conservatively by the refit's own
//! rule.

use alloc::collections::TryReserveError;
use alloc::vec::Vec;

use glam::Vec3;
use obvhs::{
    aabb::Aabb,
    bvh2::Bvh2,
    cwbvh::{CwBvh, node::CwBvhNode},
};

use super::refit::quantise;

/// Triangles a leaf holds at most (the meta byte's three unary bits).
const LEAF_TRIANGLES: u32 = 3;

/// Children of a wide node.
const WIDTH: usize = 8;

/// `bvh2` collapsed to eight-wide nodes (module docs); `None` when a binary
/// leaf holds more triangles than a wide leaf can (the caller then converts
/// with obvhs), or `Err` when memory runs out.
pub(super) fn collapse(bvh2: &Bvh2) -> Result<Option<CwBvh>, TryReserveError> {
    let Some(root) = bvh2.nodes.first() else {
        return Ok(Some(CwBvh::default()));
    };
    let Some(counts) = subtree_triangles(bvh2)? else {
        return Ok(None);
    };
    let mut nodes: Vec<CwBvhNode> = Vec::new();
    nodes.try_reserve_exact(bvh2.nodes.len() / 4 + 1)?;
    let mut primitive_indices: Vec<u32> = Vec::new();
    primitive_indices.try_reserve_exact(bvh2.primitive_indices.len())?;
    nodes.push(CwBvhNode::default());
    // (wide node, binary node it stands for), depth first.
    let mut pending: Vec<(usize, usize)> = Vec::new();
    pending.try_reserve(64)?;
    pending.push((0, 0));
    let mut below: Vec<usize> = Vec::new();
    below.try_reserve(64)?;
    while let Some((wide, binary)) = pending.pop() {
        let children = children_of(bvh2, &counts, binary);
        let mut node = CwBvhNode {
            primitive_base_idx: primitive_indices.len() as u32,
            child_base_idx: nodes.len() as u32,
            ..CwBvhNode::default()
        };
        let mut boxes = [None; WIDTH];
        let mut offset = 0u32;
        below.clear();
        for (slot, &child) in children.iter().enumerate() {
            let Some(child) = child else { continue };
            let aabb = bvh2.nodes[child].aabb();
            boxes[slot] = Some([Vec3::from(aabb.min), Vec3::from(aabb.max)]);
            let count = counts[child];
            if count <= LEAF_TRIANGLES {
                node.child_meta[slot] = offset as u8 | UNARY[count as usize];
                offset += count;
                push_triangles(bvh2, child, &mut primitive_indices)?;
            } else {
                node.imask |= 1 << slot;
                node.child_meta[slot] = (24 + slot as u8) | 0b0010_0000;
                // Within the capacity reserved above: at most eight.
                below.push(child);
            }
        }
        quantise(&mut node, &boxes);
        let first = nodes.len();
        nodes.try_reserve(below.len())?;
        nodes.extend(core::iter::repeat_n(CwBvhNode::default(), below.len()));
        nodes[wide] = node;
        // Slot order next: the first inner child on top of the stack.
        pending.try_reserve(below.len())?;
        pending.extend(below.iter().enumerate().rev().map(|(k, &b)| (first + k, b)));
    }
    Ok(Some(CwBvh {
        nodes,
        primitive_indices,
        total_aabb: *root.aabb(),
        exact_node_aabbs: None,
        uses_spatial_splits: bvh2.uses_spatial_splits,
    }))
}

/// Meta bits of a leaf of `n` triangles (index `n`), in unary.
const UNARY: [u8; 4] = [0, 0b0010_0000, 0b0110_0000, 0b1110_0000];

/// Triangles under each binary node; `None` when a leaf holds more than
/// [`LEAF_TRIANGLES`], or when a node's children do not come after it (the
/// order obvhs's PLOC builder writes, which lets one backward pass see
/// children first; a builder that wrote another order falls back to
/// obvhs's conversion rather than to a slower pass here).
fn subtree_triangles(bvh2: &Bvh2) -> Result<Option<Vec<u32>>, TryReserveError> {
    let mut counts: Vec<u32> = Vec::new();
    counts.try_reserve_exact(bvh2.nodes.len())?;
    counts.resize(bvh2.nodes.len(), 0);
    for (index, node) in bvh2.nodes.iter().enumerate().rev() {
        counts[index] = if node.prim_count != 0 {
            if node.prim_count > LEAF_TRIANGLES {
                return Ok(None);
            }
            node.prim_count
        } else {
            let first = node.first_index as usize;
            if first <= index || first + 1 >= counts.len() {
                return Ok(None);
            }
            counts[first] + counts[first + 1]
        };
    }
    Ok(Some(counts))
}

/// The binary nodes that become the wide node of `binary`'s children: its
/// two children, then, while there are fewer than eight, the child of largest
/// surface area among those too large for a leaf replaced by its own two
/// (a binary leaf stands alone).
fn children_of(bvh2: &Bvh2, counts: &[u32], binary: usize) -> [Option<usize>; WIDTH] {
    let mut children = [None; WIDTH];
    let node = &bvh2.nodes[binary];
    if node.prim_count != 0 {
        children[0] = Some(binary);
        return children;
    }
    let first = node.first_index as usize;
    children[0] = Some(first);
    children[1] = Some(first + 1);
    let mut count = 2;
    while count < WIDTH {
        let mut widest: Option<(usize, f32)> = None;
        for (slot, child) in children[..count].iter().enumerate() {
            let child = child.expect("the first `count` slots are filled");
            if counts[child] <= LEAF_TRIANGLES || bvh2.nodes[child].prim_count != 0 {
                continue;
            }
            let area = half_area(bvh2.nodes[child].aabb());
            if widest.is_none_or(|(_, most)| area > most) {
                widest = Some((slot, area));
            }
        }
        let Some((slot, _)) = widest else { break };
        let opened = bvh2.nodes[children[slot].expect("a filled slot")].first_index as usize;
        children[slot] = Some(opened);
        children[count] = Some(opened + 1);
        count += 1;
    }
    children
}

/// Half the surface area of `aabb` (the greedy rule's measure).
fn half_area(aabb: &Aabb) -> f32 {
    let d = aabb.max - aabb.min;
    (d.x + d.y) * d.z + d.x * d.y
}

/// Appends the triangles under binary node `index` (at most three) in
/// depth-first order.
fn push_triangles(bvh2: &Bvh2, index: usize, out: &mut Vec<u32>) -> Result<(), TryReserveError> {
    let mut stack = [0usize; 2 * LEAF_TRIANGLES as usize];
    let mut len = 1;
    stack[0] = index;
    while len > 0 {
        len -= 1;
        let node = &bvh2.nodes[stack[len]];
        if node.prim_count != 0 {
            let first = node.first_index as usize;
            let leaf = &bvh2.primitive_indices[first..first + node.prim_count as usize];
            out.try_reserve(leaf.len())?;
            out.extend_from_slice(leaf);
        } else {
            // Right first, so the left comes out first.
            stack[len] = node.first_index as usize + 1;
            stack[len + 1] = node.first_index as usize;
            len += 2;
        }
    }
    Ok(())
}
