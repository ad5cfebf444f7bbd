//! Where a texel bake's entries lie in its lightmap: the atlas size and, per
//! entry, the texel it was baked for. A set that carries them is a lightmap
//! (written as bake file version 3); one without is a per-vertex bake.
//!
//! The texels are stored as indices `y · width + x` in strictly increasing
//! order, the order [`crate::lightmap::TexelAtlas`] lays its receivers out in
//! (row by row from `(0, 0)`, row 0 at `v = 0`). Strict order makes every texel
//! appear once and makes the parts of a sharded bake (consecutive ranges of
//! entries) join by concatenation.

use alloc::vec::Vec;
use core::fmt;

use crate::lightmap::{MAX_ATLAS_SIDE, MAX_ATLAS_TEXELS, MAX_GUTTER, gutter};

use super::TransferSet;

/// The lightmap texels of a set's entries.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AtlasTexels {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) texels: Vec<u32>,
}

/// Why texels do not fit a set ([`TransferSet::with_texels`]) or a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TexelsError {
    /// A side is 0 or above [`MAX_ATLAS_SIDE`], or the texels are more than
    /// [`MAX_ATLAS_TEXELS`].
    Resolution {
        /// The width given.
        width: u32,
        /// The height given.
        height: u32,
    },
    /// Not one texel per entry of the set.
    Count {
        /// The set's entries.
        expected: usize,
        /// Texels given.
        found: usize,
    },
    /// Texel `index` of the list is outside the atlas, or not above the one
    /// before it.
    Order {
        /// Its position in the list.
        index: usize,
    },
}

impl fmt::Display for TexelsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            TexelsError::Resolution { width, height } => write!(
                f,
                "atlas resolution {width} x {height}: each side must be 1..={MAX_ATLAS_SIDE} \
                 and the texels at most {MAX_ATLAS_TEXELS}"
            ),
            TexelsError::Count { expected, found } => write!(
                f,
                "texels: {found} given, the set has {expected} entries (one each)"
            ),
            TexelsError::Order { index } => write!(
                f,
                "texels[{index}] lies outside the atlas or is not above texels[{}] \
                 (row-major texel indices, strictly increasing)",
                index.saturating_sub(1)
            ),
        }
    }
}

impl core::error::Error for TexelsError {}

impl AtlasTexels {
    /// Checks an atlas size and a texel list (indices `y · width + x`,
    /// strictly increasing, each below `width · height`).
    pub fn new(width: u32, height: u32, texels: Vec<u32>) -> Result<Self, TexelsError> {
        check_resolution(width, height)?;
        if let Some(index) = first_disorder(&texels, width, height) {
            return Err(TexelsError::Order { index });
        }
        Ok(AtlasTexels {
            width,
            height,
            texels,
        })
    }

    /// Atlas width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Atlas height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Per entry of the set, its texel `y · width + x`, strictly increasing.
    pub fn texels(&self) -> &[u32] {
        &self.texels
    }

    /// Entry `index`'s texel as `(x, y)`.
    pub fn texel(&self, index: usize) -> Option<[u32; 2]> {
        let t = *self.texels.get(index)?;
        Some([t % self.width, t / self.width])
    }

    /// Fills `image` (`width × height` texels of `channels` values, row by
    /// row from `v = 0`) from `values` (`channels` per entry, in entry order):
    /// each entry's texel its value, and texels within `gutter` texels of one
    /// (8-neighbour steps, at most [`MAX_GUTTER`]) the nearest entry's, as
    /// [`TexelAtlas::expand`](crate::lightmap::TexelAtlas::expand) does with
    /// its own gutter. Other texels are left as they are. `None` when a length
    /// does not match, the gutter is too wide, or memory for the per-texel
    /// reads (4 bytes a texel) runs out.
    pub fn expand(
        &self,
        gutter: u32,
        values: &[f32],
        channels: usize,
        image: &mut [f32],
    ) -> Option<()> {
        if gutter > MAX_GUTTER {
            return None;
        }
        let texels = self.texels.iter().map(|&t| t as usize);
        let reads = gutter::reads(texels, self.width, self.height, gutter).ok()?;
        gutter::fill(&reads, self.texels.len(), values, channels, image)
    }
}

/// [`TexelsError::Resolution`] unless the sides and their product are in range.
pub(crate) fn check_resolution(width: u32, height: u32) -> Result<(), TexelsError> {
    let side = 1..=MAX_ATLAS_SIDE;
    if side.contains(&width)
        && side.contains(&height)
        && u64::from(width) * u64::from(height) <= MAX_ATLAS_TEXELS
    {
        Ok(())
    } else {
        Err(TexelsError::Resolution { width, height })
    }
}

/// The first texel outside a valid `width × height` atlas or not above its
/// predecessor.
pub(crate) fn first_disorder(texels: &[u32], width: u32, height: u32) -> Option<usize> {
    let count = u64::from(width) * u64::from(height);
    texels
        .iter()
        .enumerate()
        .position(|(i, &t)| u64::from(t) >= count || (i > 0 && t <= texels[i - 1]))
}

impl TransferSet {
    /// The set as a lightmap: entry `i` baked for texel `texels[i]` (row-major
    /// index `y · width + x`, strictly increasing) of a `width × height` atlas.
    /// [`crate::lightmap::TexelAtlas::bake`] does this itself.
    pub fn with_texels(
        mut self,
        width: u32,
        height: u32,
        texels: Vec<u32>,
    ) -> Result<TransferSet, TexelsError> {
        if texels.len() != self.vertex_count() {
            return Err(TexelsError::Count {
                expected: self.vertex_count(),
                found: texels.len(),
            });
        }
        self.texels = Some(AtlasTexels::new(width, height, texels)?);
        Ok(self)
    }

    /// The lightmap texels of the entries, for a texel bake; `None` for a
    /// per-vertex bake.
    pub fn texels(&self) -> Option<&AtlasTexels> {
        self.texels.as_ref()
    }
}
