//! `antumbra_mesh_view`: the C description of a triangle mesh, and its conversion
//! into a validated core `MeshView`.

use antumbra_core::{MeshError, MeshView};

use crate::error::Error;
use crate::raw;
use crate::result::*;

/// A borrowed indexed triangle mesh. Antumbra never keeps these pointers past the
/// call they are passed to.
///
/// Positions need no particular alignment; indices must be 4-byte aligned.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct antumbra_mesh_view {
    /// xyz of vertex i at byte offset `i * position_stride`.
    pub positions: *const f32,
    /// Number of vertices.
    pub vertex_count: usize,
    /// Bytes between consecutive positions; 0 means 12 (tightly packed).
    pub position_stride: usize,
    /// 3 per triangle, each < `vertex_count`.
    pub indices: *const u32,
    /// Number of triangles.
    pub triangle_count: usize,
}

/// Validates `view` (named `argument` in messages) and borrows it as a core mesh.
///
/// # Safety
/// The pointers in `view` must be valid for the counts and stride they claim, for
/// the lifetime `'a`.
pub(crate) unsafe fn mesh_from_c<'a>(
    view: &antumbra_mesh_view,
    argument: &str,
) -> Result<MeshView<'a>, Error> {
    let stride = if view.position_stride == 0 {
        antumbra_core::geom::POSITION_BYTES
    } else {
        view.position_stride
    };
    if stride < antumbra_core::geom::POSITION_BYTES {
        return Err(Error::invalid(message!(
            "{argument}->position_stride is {stride}, less than the 12 bytes of one position"
        )));
    }
    let byte_len = match view.vertex_count {
        0 => 0,
        n => (n - 1)
            .checked_mul(stride)
            .and_then(|b| b.checked_add(antumbra_core::geom::POSITION_BYTES))
            .ok_or_else(|| {
                Error::invalid(message!(
                    "{argument}: vertex_count {n} at position_stride {stride} overflows size_t"
                ))
            })?,
    };
    // Names as `format_args!`: formatted only on error, so a valid call allocates
    // nothing.
    // SAFETY: forwarded contract on `view.positions` for `byte_len` bytes.
    let bytes = unsafe {
        raw::slice(
            view.positions.cast::<u8>(),
            byte_len,
            format_args!("{argument}->positions"),
        )
    }?;
    let index_count = raw::element_count(
        view.triangle_count,
        3,
        format_args!("{argument}->triangle_count"),
    )?;
    // SAFETY: forwarded contract on `view.indices`.
    let indices = unsafe {
        raw::slice(
            view.indices,
            index_count,
            format_args!("{argument}->indices"),
        )
    }?;
    MeshView::from_strided_bytes(bytes, view.vertex_count, stride, indices)
        .map_err(|e| mesh_error(e, argument))
}

fn mesh_error(error: MeshError, argument: &str) -> Error {
    let code = match error {
        MeshError::StrideTooSmall { .. }
        | MeshError::SizeOverflow { .. }
        | MeshError::PositionsTooShort { .. }
        | MeshError::IndicesNotTriangles { .. } => ANTUMBRA_RESULT_INVALID_ARGUMENT,
        MeshError::IndexOutOfRange { .. } => ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE,
        MeshError::NonFinitePosition { .. } => ANTUMBRA_RESULT_NON_FINITE,
    };
    let message = match error {
        MeshError::IndexOutOfRange {
            at,
            index,
            vertex_count,
        } => message!(
            "{argument}->indices[{at}] (triangle {}) is {index}, not below {argument}->vertex_count {vertex_count}",
            at / 3
        ),
        MeshError::NonFinitePosition { vertex } => {
            message!("{argument}->positions: vertex {vertex} has a NaN or infinite coordinate")
        }
        other => message!("{argument}: {other}"),
    };
    Error::new(code, message)
}
