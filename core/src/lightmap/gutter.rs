//! Which receiver each texel reads: its own, or for a gutter texel the
//! receiver reached first by a breadth-first dilation in 8-neighbour steps.

use alloc::vec::Vec;

use super::{AtlasError, EMPTY, TexelReceiver};
use crate::fallible;

/// Per texel (row by row) the receiver it reads or [`EMPTY`]: receivers'
/// texels their own, and texels within `gutter` steps (8-neighbour) of one the
/// receiver of a texel one step nearer. Ties go to the neighbour met first
/// (rows, then columns, from the top-left), so the result is deterministic.
pub(super) fn reads(
    receivers: &[TexelReceiver],
    width: u32,
    height: u32,
    gutter: u32,
) -> Result<Vec<u32>, AtlasError> {
    let (w, h) = (width as usize, height as usize);
    let mut reads = fallible::filled(EMPTY, w * h)?;
    let mut frontier = fallible::with_capacity(receivers.len())?;
    for (index, receiver) in receivers.iter().enumerate() {
        let [x, y] = receiver.texel.map(|c| c as usize);
        reads[y * w + x] = index as u32;
        frontier.push(y * w + x);
    }
    let mut next = Vec::new();
    for _ in 0..gutter {
        // Frontier texels in row order, so ties resolve the same way every time.
        frontier.sort_unstable();
        for &texel in &frontier {
            let (x, y) = (texel % w, texel / w);
            let source = reads[texel];
            for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    let neighbour = ny * w + nx;
                    if reads[neighbour] == EMPTY {
                        reads[neighbour] = source;
                        fallible::push(&mut next, neighbour)?;
                    }
                }
            }
        }
        core::mem::swap(&mut frontier, &mut next);
        next.clear();
        if frontier.is_empty() {
            break;
        }
    }
    Ok(reads)
}
