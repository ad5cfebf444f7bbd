//! A validated, borrowed view of an indexed triangle mesh.
//!
//! Positions are `f32` xyz triples at a byte stride inside caller memory (so an
//! engine can hand over its interleaved vertex buffer as it is), indices are `u32`,
//! three per triangle. Construction checks everything the algorithms rely on: the
//! stride holds a position, the bytes cover every vertex, every index is in range,
//! and every coordinate is finite. After that, reads cannot fail.

use core::fmt;

use glam::Vec3;

/// Bytes of one position: three `f32`.
pub const POSITION_BYTES: usize = 12;

/// Why a mesh view was rejected. Each variant names the offending item.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshError {
    /// The byte stride between positions is smaller than one position (12 bytes).
    StrideTooSmall {
        /// The stride given, in bytes.
        stride: usize,
    },
    /// `vertex_count * stride` does not fit in `usize`.
    SizeOverflow {
        /// The vertex count given.
        vertex_count: usize,
        /// The stride given, in bytes.
        stride: usize,
    },
    /// The position bytes end before the last vertex does.
    PositionsTooShort {
        /// Bytes needed to hold every vertex at the stride.
        required: usize,
        /// Bytes available.
        available: usize,
    },
    /// The index count is not a multiple of three.
    IndicesNotTriangles {
        /// Number of indices given.
        len: usize,
    },
    /// An index refers to a vertex that does not exist.
    IndexOutOfRange {
        /// Position of the bad index in the index array (triangle = `at / 3`).
        at: usize,
        /// The index value.
        index: u32,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// A vertex has a NaN or infinite coordinate.
    NonFinitePosition {
        /// The vertex.
        vertex: usize,
    },
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            MeshError::StrideTooSmall { stride } => write!(
                f,
                "position stride {stride} is smaller than one position ({POSITION_BYTES} bytes)"
            ),
            MeshError::SizeOverflow {
                vertex_count,
                stride,
            } => write!(
                f,
                "{vertex_count} vertices at a stride of {stride} bytes overflow the address space"
            ),
            MeshError::PositionsTooShort {
                required,
                available,
            } => write!(
                f,
                "positions hold {available} bytes but the vertices need {required}"
            ),
            MeshError::IndicesNotTriangles { len } => {
                write!(f, "{len} indices is not a multiple of 3")
            }
            MeshError::IndexOutOfRange {
                at,
                index,
                vertex_count,
            } => write!(
                f,
                "indices[{at}] (triangle {}) is {index}, not below vertex_count {vertex_count}",
                at / 3
            ),
            MeshError::NonFinitePosition { vertex } => {
                write!(f, "position of vertex {vertex} is not finite")
            }
        }
    }
}

impl core::error::Error for MeshError {}

/// A borrowed triangle mesh whose every position is finite and every index valid.
///
/// Triangle `i` has corners `indices[3i..3i+3]`, counter-clockwise when seen from
/// the side its geometric normal `(b - a) × (c - a)` points to.
#[derive(Clone, Copy, Debug)]
pub struct MeshView<'a> {
    position_bytes: &'a [u8],
    stride: usize,
    vertex_count: usize,
    indices: &'a [u32],
    /// Smallest and largest coordinates of every vertex, found while the
    /// positions are checked.
    bounds: (Vec3, Vec3),
}

impl<'a> MeshView<'a> {
    /// A view of tightly packed positions.
    pub fn new(positions: &'a [[f32; 3]], indices: &'a [u32]) -> Result<Self, MeshError> {
        Self::from_strided_bytes(
            bytemuck::cast_slice(positions),
            positions.len(),
            POSITION_BYTES,
            indices,
        )
    }

    /// A view of `vertex_count` positions, vertex `i` at byte offset `i * stride` of
    /// `position_bytes` as three native-endian `f32` (no alignment needed).
    pub fn from_strided_bytes(
        position_bytes: &'a [u8],
        vertex_count: usize,
        stride: usize,
        indices: &'a [u32],
    ) -> Result<Self, MeshError> {
        if stride < POSITION_BYTES {
            return Err(MeshError::StrideTooSmall { stride });
        }
        let required = required_position_bytes(vertex_count, stride)?;
        if position_bytes.len() < required {
            return Err(MeshError::PositionsTooShort {
                required,
                available: position_bytes.len(),
            });
        }
        if !indices.len().is_multiple_of(3) {
            return Err(MeshError::IndicesNotTriangles { len: indices.len() });
        }
        if let Some((at, &index)) = indices
            .iter()
            .enumerate()
            .find(|&(_, &index)| index as usize >= vertex_count)
        {
            return Err(MeshError::IndexOutOfRange {
                at,
                index,
                vertex_count,
            });
        }
        let mut view = MeshView {
            position_bytes,
            stride,
            vertex_count,
            indices,
            bounds: (Vec3::INFINITY, Vec3::NEG_INFINITY),
        };
        let (mut min, mut max) = view.bounds;
        for vertex in 0..vertex_count {
            let p = view.position(vertex);
            if !p.is_finite() {
                return Err(MeshError::NonFinitePosition { vertex });
            }
            min = min.min(p);
            max = max.max(p);
        }
        view.bounds = (min, max);
        Ok(view)
    }

    /// Number of vertices.
    #[inline]
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The smallest and the largest coordinates over every vertex (referenced by
    /// a triangle or not): the corners of the mesh's axis-aligned bounding box.
    /// `(+inf, -inf)` for a mesh without vertices.
    #[inline]
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }

    /// Number of triangles.
    #[inline]
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The index array, three per triangle.
    #[inline]
    pub fn indices(&self) -> &'a [u32] {
        self.indices
    }

    /// Position of vertex `vertex`. Panics when `vertex >= vertex_count()`.
    #[inline]
    pub fn position(&self, vertex: usize) -> Vec3 {
        let start = vertex * self.stride;
        let bytes = &self.position_bytes[start..start + POSITION_BYTES];
        let read = |k: usize| {
            f32::from_ne_bytes([
                bytes[4 * k],
                bytes[4 * k + 1],
                bytes[4 * k + 2],
                bytes[4 * k + 3],
            ])
        };
        Vec3::new(read(0), read(1), read(2))
    }

    /// Vertex indices of triangle `triangle`. Panics when out of range.
    #[inline]
    pub fn triangle_indices(&self, triangle: usize) -> [u32; 3] {
        let i = &self.indices[3 * triangle..3 * triangle + 3];
        [i[0], i[1], i[2]]
    }

    /// Corner positions of triangle `triangle`. Panics when out of range.
    #[inline]
    pub fn triangle(&self, triangle: usize) -> [Vec3; 3] {
        // Spelled out rather than `array::map`, which does not always inline and
        // then moves the corners through the stack in hot loops.
        let [a, b, c] = self.triangle_indices(triangle);
        [
            self.position(a as usize),
            self.position(b as usize),
            self.position(c as usize),
        ]
    }

    /// Corner positions of every triangle, in order.
    pub fn triangles(&self) -> impl ExactSizeIterator<Item = [Vec3; 3]> + '_ {
        (0..self.triangle_count()).map(|t| self.triangle(t))
    }
}

/// Bytes needed for `vertex_count` positions at `stride`: the last one needs only
/// its 12 bytes, not a whole stride.
fn required_position_bytes(vertex_count: usize, stride: usize) -> Result<usize, MeshError> {
    if vertex_count == 0 {
        return Ok(0);
    }
    (vertex_count - 1)
        .checked_mul(stride)
        .and_then(|bytes| bytes.checked_add(POSITION_BYTES))
        .ok_or(MeshError::SizeOverflow {
            vertex_count,
            stride,
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;
    use alloc::vec::Vec;

    const QUAD: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    const QUAD_INDICES: [u32; 6] = [0, 1, 2, 0, 2, 3];

    #[test]
    fn packed_view_reads_positions_and_triangles() {
        let mesh = MeshView::new(&QUAD, &QUAD_INDICES).unwrap();
        assert_eq!(mesh.vertex_count(), 4);
        assert_eq!(mesh.triangle_count(), 2);
        assert_eq!(mesh.position(2), Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(
            mesh.triangle(1),
            [
                Vec3::ZERO,
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0)
            ]
        );
    }

    #[test]
    fn interleaved_unaligned_view_reads_the_same_positions() {
        // 7 floats per vertex (position, normal, 1 pad), shifted by one byte so
        // nothing is 4-byte aligned.
        let stride = 28;
        let mut bytes = vec![0u8; 1 + stride * QUAD.len()];
        for (v, p) in QUAD.iter().enumerate() {
            for (k, c) in p.iter().enumerate() {
                let at = 1 + v * stride + 4 * k;
                bytes[at..at + 4].copy_from_slice(&c.to_ne_bytes());
            }
        }
        // The last vertex needs only 12 bytes, so trim the rest of its stride.
        let used = 1 + 3 * stride + 12;
        let mesh = MeshView::from_strided_bytes(&bytes[1..used], 4, stride, &QUAD_INDICES).unwrap();
        let packed = MeshView::new(&QUAD, &QUAD_INDICES).unwrap();
        let a: Vec<_> = mesh.triangles().collect();
        let b: Vec<_> = packed.triangles().collect();
        assert_eq!(a, b);
    }

    #[test]
    fn rejects_each_class_of_bad_input() {
        let bytes: &[u8] = bytemuck::cast_slice(&QUAD);
        assert_eq!(
            MeshView::from_strided_bytes(bytes, 4, 8, &QUAD_INDICES).unwrap_err(),
            MeshError::StrideTooSmall { stride: 8 }
        );
        assert_eq!(
            MeshView::from_strided_bytes(bytes, 5, 12, &QUAD_INDICES).unwrap_err(),
            MeshError::PositionsTooShort {
                required: 60,
                available: 48
            }
        );
        assert!(matches!(
            MeshView::from_strided_bytes(bytes, usize::MAX, 16, &QUAD_INDICES).unwrap_err(),
            MeshError::SizeOverflow { .. }
        ));
        assert_eq!(
            MeshView::new(&QUAD, &QUAD_INDICES[..5]).unwrap_err(),
            MeshError::IndicesNotTriangles { len: 5 }
        );
        assert_eq!(
            MeshView::new(&QUAD, &[0, 1, 2, 0, 2, 4]).unwrap_err(),
            MeshError::IndexOutOfRange {
                at: 5,
                index: 4,
                vertex_count: 4
            }
        );
        let mut bad = QUAD;
        bad[3][1] = f32::NAN;
        assert_eq!(
            MeshView::new(&bad, &QUAD_INDICES).unwrap_err(),
            MeshError::NonFinitePosition { vertex: 3 }
        );
        bad[3][1] = f32::INFINITY;
        assert!(MeshView::new(&bad, &QUAD_INDICES).is_err());
    }

    #[test]
    fn empty_mesh_is_a_valid_view() {
        let mesh = MeshView::new(&[], &[]).unwrap();
        assert_eq!(mesh.triangle_count(), 0);
        assert_eq!(mesh.triangles().count(), 0);
    }

    #[test]
    fn messages_name_the_offending_item() {
        let e = MeshError::IndexOutOfRange {
            at: 7,
            index: 9,
            vertex_count: 4,
        };
        assert_eq!(
            alloc::format!("{e}"),
            "indices[7] (triangle 2) is 9, not below vertex_count 4"
        );
    }
}
