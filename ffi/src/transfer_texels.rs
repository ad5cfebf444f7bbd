//! A texel set's lightmap through the C API: the texel of every entry of a set
//! that `antumbra_lightmap_bake` made or `antumbra_transfer_load` read from a
//! version-3 bake file, and per-entry values spread over the atlas with a
//! gutter, so an engine that loads a lightmap file needs nothing else to build
//! its texture. Both work without the standard library.

use antumbra_core::transfer::{AtlasTexels, TransferSet};

use crate::boundary::with_handle;
use crate::error::Error;
use crate::raw::{self, Span, Spans, check_disjoint};
use crate::result::{ANTUMBRA_RESULT_OUT_OF_MEMORY, antumbra_result};
use crate::transfer::antumbra_transfer;

/// Copies the texel of every entry of a texel set (a lightmap): entry `i` was
/// baked for texel `texels[i] = y * atlas_width + x` (column `x` from u = 0, row
/// `y` from v = 0), strictly increasing. `antumbra_transfer_describe` gives the
/// atlas size (0 × 0 for a per-vertex set, which has no texels).
///
/// @param transfer a texel set.
/// @param texels room for `count` indices.
/// @param count the set's entry count (`vertex_count`).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (transfer, texels); INVALID_ARGUMENT
///         (a per-vertex set, count not the set's, misaligned texels); POISONED;
///         PANIC. `texels` is untouched on failure.
///
/// Thread safety: any number of threads may use the same set at once.
///
/// # Safety
/// `transfer` NULL or a live set; `texels` NULL or valid for `count` writes.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_texels(
    transfer: *const antumbra_transfer,
    texels: *mut u32,
    count: usize,
) -> antumbra_result {
    with_handle("antumbra_transfer_texels", transfer, |t| {
        let atlas = texels_of(&t.set)?;
        if texels.is_null() {
            return Err(Error::null("texels"));
        }
        if count != atlas.texels().len() {
            return Err(Error::invalid(message!(
                "count is {count}; the set has {} entries",
                atlas.texels().len()
            )));
        }
        // SAFETY: caller contract; checked for NULL, alignment and size.
        let out = unsafe { raw::slice_mut(texels, count, "texels") }?;
        out.copy_from_slice(atlas.texels());
        Ok(())
    })
}

/// Writes a lightmap texture from per-entry values of a texel set: each entry's
/// texel its values, and texels within `gutter` texels of one (8-neighbour
/// steps) the nearest entry's, so bilinear lookups inside the charts read only
/// baked values; other texels are left as they are. The same texture
/// `antumbra_lightmap_expand` writes when the gutters are equal. Row `y` of the
/// image is texel row `y` (v from `y / atlas_height`).
///
/// @param transfer a texel set.
/// @param gutter texels of gutter, at most 64 (ANTUMBRA_LIGHTMAP_MAX_GUTTER in
///        hosted builds); 2 is the lightmap default.
/// @param values `channels` floats per entry, in entry order (for example
///        `antumbra_transfer_shade`'s RGB output; copied as given).
/// @param value_count `vertex_count × channels`.
/// @param channels floats per texel, at least 1.
/// @param image `atlas_width × atlas_height × channels` floats.
/// @param image_count its length.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT; INVALID_ARGUMENT (a per-vertex
///         set, gutter too wide, counts that do not match, channels 0,
///         misaligned or overlapping arrays); OUT_OF_MEMORY (the per-texel
///         lookups, 4 bytes a texel); POISONED; PANIC. The image is untouched on
///         failure.
///
/// Cost: linear in the atlas's texels; allocates 4 bytes per texel for the
/// gutter's lookups. Thread safety: any number of threads may use the same set
/// at once.
///
/// # Safety
/// `values` valid for `value_count` reads, `image` for `image_count` writes,
/// not overlapping.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_transfer_expand(
    transfer: *const antumbra_transfer,
    gutter: u32,
    values: *const f32,
    value_count: usize,
    channels: u32,
    image: *mut f32,
    image_count: usize,
) -> antumbra_result {
    with_handle("antumbra_transfer_expand", transfer, |t| {
        let atlas = texels_of(&t.set)?;
        let max_gutter = antumbra_core::lightmap::MAX_GUTTER;
        if gutter > max_gutter {
            return Err(Error::invalid(message!(
                "gutter is {gutter}; at most {max_gutter} texels"
            )));
        }
        let entries = atlas.texels().len();
        let size = (atlas.width(), atlas.height());
        let texels = size.0 as usize * size.1 as usize;
        // SAFETY: caller contract on the arrays.
        let (values, image, channels) = unsafe {
            expand_arguments(
                (values, value_count),
                channels,
                (image, image_count),
                (entries, "entries"),
                size,
            )
        }?;
        atlas
            .expand(gutter, values, channels, image)
            .ok_or_else(|| {
                Error::new(
                    ANTUMBRA_RESULT_OUT_OF_MEMORY,
                    message!("no memory for the lookups of {texels} texels"),
                )
            })
    })
}

/// A set's lightmap texels, or the error naming a per-vertex set.
fn texels_of(set: &TransferSet) -> Result<&AtlasTexels, Error> {
    set.texels()
        .ok_or_else(|| Error::invalid("transfer is a per-vertex set: it has no lightmap texels"))
}

/// The checked arrays of an expand call (`antumbra_transfer_expand`,
/// `antumbra_lightmap_expand`): `values`, `channels` floats for each of
/// `entries` (named `noun` in messages), and `image`, `channels` floats for
/// each texel of a `width × height` atlas, non-NULL, aligned, of exactly those
/// lengths and not overlapping; with the channel count as `usize`.
///
/// # Safety
/// `values` valid for `value_count` reads, `image` for `image_count` writes.
pub(crate) unsafe fn expand_arguments<'a>(
    (values, value_count): (*const f32, usize),
    channels: u32,
    (image, image_count): (*mut f32, usize),
    (entries, noun): (usize, &str),
    (width, height): (u32, u32),
) -> Result<(&'a [f32], &'a mut [f32], usize), Error> {
    if values.is_null() {
        return Err(Error::null("values"));
    }
    if image.is_null() {
        return Err(Error::null("image"));
    }
    if channels == 0 {
        return Err(Error::invalid("channels is 0"));
    }
    let channels = channels as usize;
    let texels = width as usize * height as usize;
    let want_values = raw::element_count(entries, channels, "channels")?;
    let want_image = raw::element_count(texels, channels, "channels")?;
    if value_count != want_values {
        return Err(Error::invalid(message!(
            "value_count is {value_count}; {entries} {noun} × {channels} channels is \
             {want_values}"
        )));
    }
    if image_count != want_image {
        return Err(Error::invalid(message!(
            "image_count is {image_count}; {width} × {height} texels × {channels} channels is \
             {want_image}"
        )));
    }
    let mut inputs = Spans::default();
    inputs.push(Span::of("values", values, value_count));
    check_disjoint(&[Span::of("image", image, image_count)], &inputs)?;
    // SAFETY: caller contract; checked for alignment and overlap.
    let values = unsafe { raw::slice(values, value_count, "values") }?;
    // SAFETY: as above.
    let image = unsafe { raw::slice_mut(image, image_count, "image") }?;
    Ok((values, image, channels))
}
