//! # The Antumbra C ABI
//!
//! `libantumbra.a` / `libantumbra.so` and the generated `include/antumbra.h`.
//! Every export follows the same rules (see `CONVENTIONS.md` in the design notes):
//!
//! - fallible functions return an [`antumbra_result`]; [`ANTUMBRA_RESULT_OK`] is 0;
//! - every argument is validated before any work: pointers, counts, strides,
//!   indices, finite values; each class of bad input has its own code and a
//!   message (see [`antumbra_last_error_message`]) naming the argument;
//! - outputs are written only on success;
//! - no panic crosses the boundary: it becomes [`ANTUMBRA_RESULT_PANIC`] and the
//!   handle involved is poisoned;
//! - queries on a const handle may run on many threads at once.
//!
//! Items carry exactly their C names so grep works across languages.
//!
//! Two builds share the header. The default (`std` feature) is the hosted library.
//! Without it the crate is `#![no_std]` for bare metal: the application supplies
//! the allocator (`antumbra_set_allocator`) and a panic hook
//! (`antumbra_set_panic_hook`), error messages live in static memory, and the
//! functions that need an operating system (threads, the BVH ray caster) are not
//! in the library at all; the header wraps them in `#if defined(ANTUMBRA_HAS_STD)`.
#![cfg_attr(not(feature = "std"), no_std)]
// Without std an error carries its message inline (240 bytes) so that reporting
// it never allocates: a deliberate trade of stack for never failing to report.
#![cfg_attr(not(feature = "std"), allow(clippy::result_large_err))]
#![allow(non_camel_case_types)]
#![warn(missing_docs)]

extern crate alloc;

#[macro_use]
mod error;
#[cfg(not(feature = "std"))]
mod allocator;
mod boundary;
mod fallible;
mod frame;
mod hemi;
mod hemi_shading;
mod lightmap;
mod mesh;
#[cfg(not(feature = "std"))]
mod panic_hook;
mod raw;
mod result;
#[cfg(feature = "std")]
mod scene;
mod sh;
mod ssv;
mod transfer;
mod transfer_texels;
mod version;

#[cfg(not(feature = "std"))]
pub use allocator::{antumbra_alloc_fn, antumbra_free_fn, antumbra_set_allocator};
#[cfg(not(feature = "std"))]
pub use panic_hook::{antumbra_panic_hook, antumbra_set_panic_hook};

pub use error::{
    antumbra_error_callback, antumbra_last_error_message, antumbra_last_error_message_copy,
    antumbra_set_error_callback,
};
pub use frame::antumbra_frame_from_normal;
pub use hemi::{
    ANTUMBRA_HEMI_GRID, ANTUMBRA_HEMI_QUALITY_EXACT, ANTUMBRA_HEMI_QUALITY_TABLE,
    ANTUMBRA_HEMI_TABLE_DEFAULT_RESOLUTION, ANTUMBRA_HEMI_TABLE_MAX_RESOLUTION,
    ANTUMBRA_HEMI_VALID_CELL_COUNT, antumbra_hemi_cell_direction, antumbra_hemi_mask,
    antumbra_hemi_options, antumbra_hemi_options_init, antumbra_hemi_rasterize,
    antumbra_hemi_table, antumbra_hemi_valid_mask,
};
#[cfg(feature = "std")]
pub use hemi::{antumbra_hemi_table_create, antumbra_hemi_table_destroy};
pub use hemi_shading::{
    ANTUMBRA_HEMI_MAX_FAR_LEVELS, ANTUMBRA_HEMI_MAX_RECEIVER_SPACING, ANTUMBRA_HEMI_METHOD_CELLS,
    ANTUMBRA_HEMI_METHOD_DOWNSAMPLED, ANTUMBRA_HEMI_METHOD_LUT, ANTUMBRA_HEMI_MIN_NEAR_CELLS,
    ANTUMBRA_HEMI_NEAR_CELLS, ANTUMBRA_HEMI_SPACE_LOCAL, ANTUMBRA_HEMI_SPACE_WORLD,
    antumbra_hemi_material, antumbra_hemi_material_init, antumbra_hemi_shade,
    antumbra_hemi_shading_options, antumbra_hemi_shading_options_init, antumbra_hemi_transfer,
};
#[cfg(feature = "std")]
pub use hemi_shading::{
    antumbra_hemi_shader, antumbra_hemi_shader_create, antumbra_hemi_shader_destroy,
    antumbra_hemi_shader_regroup, antumbra_hemi_shader_set_receivers, antumbra_hemi_shader_shade,
    antumbra_hemi_shader_transfer,
};
#[cfg(feature = "std")]
pub use lightmap::{
    ANTUMBRA_LIGHTMAP_MAX_GUTTER, ANTUMBRA_LIGHTMAP_MAX_PROBES, ANTUMBRA_LIGHTMAP_MAX_SIDE,
    ANTUMBRA_LIGHTMAP_MAX_TEXELS, antumbra_lightmap, antumbra_lightmap_bake,
    antumbra_lightmap_create, antumbra_lightmap_describe, antumbra_lightmap_destroy,
    antumbra_lightmap_expand, antumbra_lightmap_info, antumbra_lightmap_options,
    antumbra_lightmap_options_init, antumbra_lightmap_receivers,
};
pub use mesh::antumbra_mesh_view;
pub use result::*;
#[cfg(feature = "std")]
pub use scene::{
    ANTUMBRA_INVALID_INDEX, antumbra_hit, antumbra_scene, antumbra_scene_create,
    antumbra_scene_destroy, antumbra_scene_intersect, antumbra_scene_occluded,
};
pub use sh::{
    ANTUMBRA_SH_MAX_BANDS, antumbra_sh_eval, antumbra_sh_project_equirect, antumbra_sh_rotate,
};
pub use ssv::{
    ANTUMBRA_SSV_MAX_DEPTH_LIMIT, ANTUMBRA_SSV_MAX_HEMICUBE_RESOLUTION,
    ANTUMBRA_SSV_MAX_LIGHT_VERTICES, ANTUMBRA_SSV_MAX_SAMPLES, ANTUMBRA_SSV_SAMPLES_JITTERED,
    ANTUMBRA_SSV_SAMPLES_STRATIFIED, ANTUMBRA_SSV_STRUCTURE_BRUTE_FORCE,
    ANTUMBRA_SSV_STRUCTURE_HEMICUBE, ANTUMBRA_SSV_STRUCTURE_HIERARCHY,
    ANTUMBRA_SSV_STRUCTURE_RAY_TRACE, antumbra_ssv, antumbra_ssv_create, antumbra_ssv_destroy,
    antumbra_ssv_generate_samples, antumbra_ssv_get_statistics, antumbra_ssv_options,
    antumbra_ssv_options_init, antumbra_ssv_query, antumbra_ssv_statistics,
};
pub use transfer::{
    ANTUMBRA_TRANSFER_BRDF_PHONG, ANTUMBRA_TRANSFER_BRDF_WARD, ANTUMBRA_TRANSFER_KIND_DIFFUSE,
    ANTUMBRA_TRANSFER_KIND_GLOSSY_SH, ANTUMBRA_TRANSFER_KIND_MRT, ANTUMBRA_TRANSFER_MAX_BOUNCES,
    ANTUMBRA_TRANSFER_MAX_GRID, ANTUMBRA_TRANSFER_MAX_RAYS, antumbra_transfer,
    antumbra_transfer_describe, antumbra_transfer_destroy, antumbra_transfer_geometry,
    antumbra_transfer_info, antumbra_transfer_load, antumbra_transfer_material,
    antumbra_transfer_material_init, antumbra_transfer_save, antumbra_transfer_shade,
};
#[cfg(feature = "std")]
pub use transfer::{
    antumbra_transfer_bake, antumbra_transfer_compress, antumbra_transfer_compress_clustered,
    antumbra_transfer_options, antumbra_transfer_options_init, antumbra_transfer_progress_fn,
};
pub use transfer_texels::{antumbra_transfer_expand, antumbra_transfer_texels};
pub use version::{antumbra_version, antumbra_version_string};

/// The crate version's parts, parsed at compile time from `Cargo.toml`; the header's
/// `ANTUMBRA_VERSION_*` macros are generated from the same values.
pub(crate) mod crate_version {
    /// Major version.
    pub(crate) const MAJOR: u32 = parse(env!("CARGO_PKG_VERSION_MAJOR"));
    /// Minor version.
    pub(crate) const MINOR: u32 = parse(env!("CARGO_PKG_VERSION_MINOR"));
    /// Patch version.
    pub(crate) const PATCH: u32 = parse(env!("CARGO_PKG_VERSION_PATCH"));
    /// `MAJOR << 16 | MINOR << 8 | PATCH`, what `antumbra_version()` returns.
    pub(crate) const PACKED: u32 = (MAJOR << 16) | (MINOR << 8) | PATCH;

    const fn parse(digits: &str) -> u32 {
        let bytes = digits.as_bytes();
        let mut value = 0u32;
        let mut i = 0;
        while i < bytes.len() {
            assert!(bytes[i].is_ascii_digit(), "version part is not a number");
            value = value * 10 + (bytes[i] - b'0') as u32;
            i += 1;
        }
        assert!(value < 256, "version part does not fit in 8 bits");
        value
    }
}
