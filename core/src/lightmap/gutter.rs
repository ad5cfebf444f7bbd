//! Which receiver each texel reads: its own, or for a gutter texel the
//! receiver reached first by a breadth-first dilation in 8-neighbour steps;
//! and a lightmap's values spread over its texels that way, for the atlas
//! ([`TexelAtlas::expand`](super::TexelAtlas::expand)) and for a texel set
//! alone ([`AtlasTexels::expand`](crate::transfer::AtlasTexels::expand)).

use alloc::vec::Vec;

use super::{AtlasError, EMPTY};
use crate::fallible;

/// Per texel (row by row) the receiver it reads or [`EMPTY`]: receivers'
/// texels their own, and texels within `gutter` steps (8-neighbour) of one the
/// receiver of a texel one step nearer. Ties go to the neighbour met first
/// (rows, then columns, from the top-left), so the result is deterministic.
/// `texels` are the receivers' row-major texel indices, each below
/// `width · height`.
pub(crate) fn reads(
    texels: impl ExactSizeIterator<Item = usize>,
    width: u32,
    height: u32,
    gutter: u32,
) -> Result<Vec<u32>, AtlasError> {
    let (w, h) = (width as usize, height as usize);
    let mut reads = fallible::filled(EMPTY, w * h)?;
    let mut frontier = fallible::with_capacity(texels.len())?;
    for (index, texel) in texels.enumerate() {
        reads[texel] = index as u32;
        frontier.push(texel);
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

/// Fills `image` (`channels` values per texel, row by row) from `values`
/// (`channels` per receiver) through `reads`; texels that read none are left
/// as they are. `None` when a length does not match.
pub(crate) fn fill(
    reads: &[u32],
    receivers: usize,
    values: &[f32],
    channels: usize,
    image: &mut [f32],
) -> Option<()> {
    if channels == 0
        || values.len() != receivers.checked_mul(channels)?
        || image.len() != reads.len().checked_mul(channels)?
    {
        return None;
    }
    for (texel, &read) in image.chunks_exact_mut(channels).zip(reads) {
        if read != EMPTY {
            let start = read as usize * channels;
            texel.copy_from_slice(&values[start..start + channels]);
        }
    }
    Some(())
}
