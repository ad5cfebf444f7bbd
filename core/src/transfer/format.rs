//! The bake file format, versions 1 to 3: a transfer set as little-endian bytes.
//!
//! ```text
//! offset size  field
//!      0    8  magic            b"ANTXFER\0"
//!      8    4  version          u32: 1, 2 for a clustered PCA, 3 for a lightmap
//!     12    4  kind             u32: 1 diffuse, 2 glossy SH, 3 MRT
//!     16    4  bands            u32 in 1..=8
//!     20    4  grid             u32: 2..=64 for MRT, 0 otherwise
//!     24    4  components       u32 K: 0 = dense payload; 1..=min(D, vertices) = PCA (MRT only)
//!     28    4  vertex_count     u32 V ≥ 1
//!     32    4  rays             u32 ≥ 1 (informational)
//!     36    4  bounces          u32 ≤ 64 (informational)
//!     40    4  albedo           f32 in [0, 1) (informational)
//!     44    4  brdf_kind        u32 ≤ 2 (BrdfInfo::kind; MRT only, else 0)
//!     48    8  brdf_params      2 × f32, finite
//!     56    8  payload_len      u64, must equal the length implied by the fields above
//! version 1:
//!     64    4  payload_crc32    CRC-32 (IEEE 802.3, reflected, as zlib) of the payload
//!     68    4  header_crc32     CRC-32 of bytes 0..68
//!     72       payload
//! version 2:
//!     64    4  clusters         u32 C in 2..=V (K ≥ 1: a clustered PCA)
//!     68    4  payload_crc32
//!     72    4  header_crc32     CRC-32 of bytes 0..72
//!     76       payload
//! version 3 (a lightmap: the set carries its texels):
//!     64    4  clusters         u32 C: 0 when K = 0, else 1..=V
//!     68    4  atlas_width      u32 W in 1..=16384
//!     72    4  atlas_height     u32 H in 1..=16384, W·H ≤ 2^26
//!     76    4  payload_crc32
//!     80    4  header_crc32     CRC-32 of bytes 0..80
//!     84       payload
//! ```
//!
//! Payload (`f32`, finite, except the cluster indices): positions `V × 3`, unit
//! normals `V × 3` (within 1e-3), then either the dense blocks `V × D` (`D` =
//! [`TransferKind::block_len`], layouts in the [transfer module docs](super)) or,
//! when `K > 0`, the PCA: means `C × D`, components `C × K × D` (cluster-major),
//! weights `V × K`, and when `C ≥ 2` each vertex's cluster, `V × u32` below `C`
//! (version 1 has one cluster); version 3 ends with each entry's texel, `V ×
//! u32` row-major indices `y·W + x`, strictly increasing and below `W·H`
//! ([`AtlasTexels`]). The file ends with the payload:
//! trailing bytes are an error.
//!
//! A set that version 1 can hold (dense, or one cluster, without texels) is
//! always written as version 1, so readers that predate clustering still load
//! it; version 2 only for two or more clusters, version 3 only for a set with
//! texels, and a file of a version its set did not need is refused, so every
//! file that loads writes back to the same bytes.
//!
//! Loading ([`TransferSet::from_bytes`]) checks, in order: the magic, the
//! version, the length of that version's header, the header checksum, every header field's range, the payload
//! length against the fields (with overflow-checked arithmetic) and against the
//! bytes actually present — before allocating anything — then the payload checksum,
//! then every value. Any failure is a [`FormatError`] naming the field; nothing
//! panics, and allocation never exceeds a small multiple of the input length.
//!
//! Tested by truncating a small file of each kind at every byte and flipping every
//! single bit (all rejected), by hostile header values, and by libFuzzer
//! (`cd core/fuzz && cargo +nightly fuzz run transfer_from_bytes`; each input is
//! also tried with both checksums recomputed, [`reseal`], so mutations reach the
//! field checks).

use alloc::vec::Vec;
use core::fmt;

use crate::fallible;

use super::pca::Pca;
use super::{
    AtlasTexels, BakeInfo, BrdfInfo, MAX_BOUNCES, MAX_GRID, Payload, TransferKind, TransferSet,
};

/// The first eight bytes of a bake file.
pub const MAGIC: [u8; 8] = *b"ANTXFER\0";
/// The newest version, written for texel sets (lightmaps).
pub const VERSION: u32 = 3;
/// Bytes before the payload in version 1.
pub const HEADER_LEN: usize = 72;
/// Bytes before the payload in version 2.
pub const HEADER_LEN_V2: usize = 76;
/// Bytes before the payload in version 3.
pub const HEADER_LEN_V3: usize = 84;

/// Header length of `version` (1 to 3; the version-1 length for others).
fn header_len(version: u32) -> usize {
    match version {
        2 => HEADER_LEN_V2,
        3 => HEADER_LEN_V3,
        _ => HEADER_LEN,
    }
}

/// Recomputes both checksums of a bake file of version 1 to 3 in place (for
/// tools and tests that edit a field); does nothing to bytes too short for the
/// header their version field names.
pub fn reseal(bytes: &mut [u8]) {
    if bytes.len() < 12 {
        return;
    }
    let len = header_len(u32_at(bytes, 8));
    if bytes.len() < len {
        return;
    }
    let payload_crc = crc32(&bytes[len..]);
    bytes[len - 8..len - 4].copy_from_slice(&payload_crc.to_le_bytes());
    let header_crc = crc32(&bytes[..len - 4]);
    bytes[len - 4..len].copy_from_slice(&header_crc.to_le_bytes());
}

/// Why bytes are not a valid bake file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormatError {
    /// Fewer bytes than the header or the declared payload needs.
    Truncated {
        /// Bytes needed.
        needed: u64,
        /// Bytes present.
        found: u64,
    },
    /// The magic bytes are wrong: not a bake file.
    Magic,
    /// A version this reader does not know.
    Version(u32),
    /// A header field is out of range or inconsistent.
    Field {
        /// The field's name as in the format table.
        field: &'static str,
        /// Its value (floats as their bits).
        value: u64,
    },
    /// A checksum does not match: the file is corrupted.
    Checksum {
        /// `"header_crc32"` or `"payload_crc32"`.
        field: &'static str,
    },
    /// Bytes after the payload.
    TrailingBytes {
        /// How many.
        count: u64,
    },
    /// A payload value is not finite (or a normal not unit length).
    Value {
        /// `"positions"`, `"normals"`, `"data"`, `"mean"`, `"components"`,
        /// `"weights"`, `"clusters"` (an index not below the cluster count) or
        /// `"texels"` (outside the atlas, or not above the one before).
        field: &'static str,
        /// Index of the offending `f32` (or vector, for normals; `u32` for
        /// clusters and texels) in that array.
        index: u64,
    },
    /// The allocator could not supply memory for an array of the file (only
    /// allocators that can run out, such as a bare-metal application's, get here).
    OutOfMemory {
        /// The array, named as in [`FormatError::Value`].
        field: &'static str,
        /// Bytes asked for.
        bytes: u64,
    },
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            FormatError::Truncated { needed, found } => {
                write!(f, "truncated: {needed} bytes needed, {found} present")
            }
            FormatError::Magic => f.write_str("bad magic: not an Antumbra transfer file"),
            FormatError::Version(v) => {
                write!(f, "version {v} is not supported (only 1 to {VERSION})")
            }
            FormatError::Field { field, value } => {
                write!(f, "header field {field} has an invalid value {value}")
            }
            FormatError::Checksum { field } => write!(f, "{field} does not match: corrupted"),
            FormatError::TrailingBytes { count } => {
                write!(f, "{count} bytes after the payload")
            }
            FormatError::Value { field, index } => {
                write!(
                    f,
                    "{field}[{index}] is not finite (or not a unit normal, not a cluster, or a \
                     texel outside the atlas or out of order)"
                )
            }
            FormatError::OutOfMemory { field, bytes } => {
                write!(f, "no memory for {field} ({bytes} bytes)")
            }
        }
    }
}

impl core::error::Error for FormatError {}

const CRC_TABLE: [u32; 256] = {
    let mut table = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
};

/// CRC-32 (IEEE, reflected, initial and final XOR `0xFFFFFFFF`), as zlib's `crc32`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c = CRC_TABLE[((c ^ u32::from(b)) & 0xFF) as usize] ^ (c >> 8);
    }
    c ^ 0xFFFF_FFFF
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(b, at))
}

/// Payload value counts: (dense or PCA parts) for validated header fields.
struct Layout {
    vertices: usize,
    block: usize,
    components: usize,
    clusters: usize,
    /// Version 3: one texel index per vertex at the end.
    texels: bool,
}

impl Layout {
    /// Number of 4-byte values in the payload, overflow-checked in `u64`.
    fn values(&self) -> Option<u64> {
        let v = self.vertices as u64;
        let d = self.block as u64;
        let k = self.components as u64;
        let c = self.clusters as u64;
        let frames = v.checked_mul(if self.texels { 7 } else { 6 })?;
        let data = if k == 0 {
            v.checked_mul(d)?
        } else {
            let indices = if c > 1 { v } else { 0 };
            c.checked_mul(d)?
                .checked_mul(k.checked_add(1)?)?
                .checked_add(v.checked_mul(k)?)?
                .checked_add(indices)?
        };
        frames.checked_add(data)
    }
}

impl TransferSet {
    /// Bytes of [`to_bytes`](Self::to_bytes)' output.
    pub fn byte_len(&self) -> usize {
        let per_entry = if self.texels.is_some() { 7 } else { 6 };
        let values = per_entry * self.vertex_count()
            + match &self.payload {
                Payload::Dense(d) => d.len(),
                Payload::Pca(p) => p.value_count(),
            };
        header_len(self.file_version()) + 4 * values
    }

    /// The version [`to_bytes`](Self::to_bytes) writes: 3 for a texel set, 2
    /// for a clustered PCA, 1 for everything version 1 holds.
    pub fn file_version(&self) -> u32 {
        match self.pca() {
            _ if self.texels.is_some() => 3,
            Some(p) if p.clusters > 1 => 2,
            _ => 1,
        }
    }

    /// The set as a bake file (format in the [module docs](self)).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = alloc::vec![0u8; self.byte_len()];
        self.write_to(&mut out);
        out
    }

    /// Writes the bake file of [`TransferSet::to_bytes`] into `out`, which must
    /// hold exactly [`TransferSet::byte_len`] bytes (allocates nothing).
    ///
    /// # Panics
    /// When `out` has another length.
    pub fn write_to(&self, out: &mut [u8]) {
        assert_eq!(out.len(), self.byte_len(), "a bake file's length");
        let components = self.pca().map_or(0, |p| p.components);
        let version = self.file_version();
        let header = header_len(version);
        let mut at = header;
        let mut put = |values: &[f32]| {
            for x in values {
                out[at..at + 4].copy_from_slice(&x.to_le_bytes());
                at += 4;
            }
        };
        put(self.positions.as_flattened());
        put(self.normals.as_flattened());
        match &self.payload {
            Payload::Dense(d) => put(d),
            Payload::Pca(p) => {
                put(&p.mean);
                put(&p.basis);
                put(&p.weights);
                for c in &p.cluster_of {
                    out[at..at + 4].copy_from_slice(&c.to_le_bytes());
                    at += 4;
                }
            }
        }
        for t in self.texels.iter().flat_map(|t| &t.texels) {
            out[at..at + 4].copy_from_slice(&t.to_le_bytes());
            at += 4;
        }
        let payload_len = (out.len() - header) as u64;
        let h = &mut out[..header];
        h.fill(0);
        h[0..8].copy_from_slice(&MAGIC);
        let fields = [
            version,
            self.kind as u32,
            self.bands,
            self.grid,
            components as u32,
            self.vertex_count() as u32,
            self.info.rays,
            self.info.bounces,
            self.info.albedo.to_bits(),
            self.info.brdf.kind,
            self.info.brdf.params[0].to_bits(),
            self.info.brdf.params[1].to_bits(),
        ];
        for (i, f) in fields.iter().enumerate() {
            h[8 + 4 * i..12 + 4 * i].copy_from_slice(&f.to_le_bytes());
        }
        h[56..64].copy_from_slice(&payload_len.to_le_bytes());
        if version >= 2 {
            let clusters = self.pca().map_or(0, |p| p.clusters as u32);
            h[64..68].copy_from_slice(&clusters.to_le_bytes());
        }
        if let Some(t) = &self.texels {
            h[68..72].copy_from_slice(&t.width.to_le_bytes());
            h[72..76].copy_from_slice(&t.height.to_le_bytes());
        }
        reseal(out);
    }

    /// Reads and validates a bake file (format in the [module docs](self)).
    pub fn from_bytes(bytes: &[u8]) -> Result<TransferSet, FormatError> {
        let found = bytes.len() as u64;
        if bytes.len() < 8 {
            return Err(FormatError::Truncated {
                needed: HEADER_LEN as u64,
                found,
            });
        }
        if bytes[..8] != MAGIC {
            return Err(FormatError::Magic);
        }
        if bytes.len() < 12 {
            return Err(FormatError::Truncated {
                needed: HEADER_LEN as u64,
                found,
            });
        }
        let version = u32_at(bytes, 8);
        if !(1..=VERSION).contains(&version) {
            return Err(FormatError::Version(version));
        }
        let header = header_len(version);
        if bytes.len() < header {
            return Err(FormatError::Truncated {
                needed: header as u64,
                found,
            });
        }
        let h = &bytes[..header];
        if crc32(&h[..header - 4]) != u32_at(h, header - 4) {
            return Err(FormatError::Checksum {
                field: "header_crc32",
            });
        }
        let field = |field: &'static str, value: u32| FormatError::Field {
            field,
            value: u64::from(value),
        };
        let kind_code = u32_at(h, 12);
        let kind = TransferKind::from_code(kind_code).ok_or(field("kind", kind_code))?;
        let bands = u32_at(h, 16);
        if !(1..=8).contains(&bands) {
            return Err(field("bands", bands));
        }
        let grid = u32_at(h, 20);
        let grid_ok = match kind {
            TransferKind::Mrt => (2..=MAX_GRID).contains(&grid),
            _ => grid == 0,
        };
        if !grid_ok {
            return Err(field("grid", grid));
        }
        let block = kind.block_len(bands, grid);
        let vertices = u32_at(h, 28);
        if vertices == 0 {
            return Err(field("vertex_count", vertices));
        }
        let components = u32_at(h, 24);
        if components != 0
            && (kind != TransferKind::Mrt || components as usize > block.min(vertices as usize))
        {
            return Err(field("components", components));
        }
        let rays = u32_at(h, 32);
        if rays == 0 {
            return Err(field("rays", rays));
        }
        let bounces = u32_at(h, 36);
        if bounces > MAX_BOUNCES {
            return Err(field("bounces", bounces));
        }
        let albedo = f32_at(h, 40);
        if !(albedo.is_finite() && (0.0..1.0).contains(&albedo)) {
            return Err(field("albedo", albedo.to_bits()));
        }
        let brdf_kind = u32_at(h, 44);
        if brdf_kind > BrdfInfo::MAX_KIND || (kind != TransferKind::Mrt && brdf_kind != 0) {
            return Err(field("brdf_kind", brdf_kind));
        }
        let params = [f32_at(h, 48), f32_at(h, 52)];
        for p in params {
            if !p.is_finite() {
                return Err(field("brdf_params", p.to_bits()));
            }
        }
        let clusters = match version {
            2 => {
                let clusters = u32_at(h, 64);
                if components == 0 || !(2..=vertices).contains(&clusters) {
                    return Err(field("clusters", clusters));
                }
                clusters
            }
            3 => {
                let clusters = u32_at(h, 64);
                let allowed = if components == 0 { 0..=0 } else { 1..=vertices };
                if !allowed.contains(&clusters) {
                    return Err(field("clusters", clusters));
                }
                clusters
            }
            _ => u32::from(components != 0),
        };
        let atlas = if version == 3 {
            let (width, height) = (u32_at(h, 68), u32_at(h, 72));
            if super::texels::check_resolution(width, 1).is_err() {
                return Err(field("atlas_width", width));
            }
            if super::texels::check_resolution(width, height).is_err() {
                return Err(field("atlas_height", height));
            }
            Some((width, height))
        } else {
            None
        };
        let layout = Layout {
            vertices: vertices as usize,
            block,
            components: components as usize,
            clusters: clusters as usize,
            texels: atlas.is_some(),
        };
        let payload_len = u64::from_le_bytes(h[56..64].try_into().unwrap_or([0xFF; 8]));
        let expected = layout.values().and_then(|v| v.checked_mul(4));
        if expected != Some(payload_len) {
            return Err(FormatError::Field {
                field: "payload_len",
                value: payload_len,
            });
        }
        let needed = (header as u64).saturating_add(payload_len);
        if found < needed {
            return Err(FormatError::Truncated { needed, found });
        }
        if found > needed {
            return Err(FormatError::TrailingBytes {
                count: found - needed,
            });
        }
        // From here on every size is bounded by the input's length.
        let payload = &bytes[header..];
        if crc32(payload) != u32_at(h, header - 8) {
            return Err(FormatError::Checksum {
                field: "payload_crc32",
            });
        }
        let mut cursor = 0usize;
        // Reads the next `count` floats of `payload` as `N`-float items,
        // refusing non-finite values (named by their float index).
        fn read<const N: usize>(
            payload: &[u8],
            cursor: &mut usize,
            count: usize,
            name: &'static str,
        ) -> Result<Vec<[f32; N]>, FormatError> {
            let bytes = &payload[*cursor..*cursor + 4 * N * count];
            *cursor += 4 * N * count;
            let mut out = fallible::with_capacity(count).map_err(|_| FormatError::OutOfMemory {
                field: name,
                bytes: (4 * N * count) as u64,
            })?;
            for (k, item) in bytes.chunks_exact(4 * N).enumerate() {
                let mut values = [0.0f32; N];
                for (j, (x, c)) in values.iter_mut().zip(item.chunks_exact(4)).enumerate() {
                    *x = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                    if !x.is_finite() {
                        return Err(FormatError::Value {
                            field: name,
                            index: (N * k + j) as u64,
                        });
                    }
                }
                out.push(values);
            }
            Ok(out)
        }
        let v = vertices as usize;
        let positions = read::<3>(payload, &mut cursor, v, "positions")?;
        let normals = read::<3>(payload, &mut cursor, v, "normals")?;
        let mut take = |count: usize, name: &'static str| -> Result<Vec<f32>, FormatError> {
            let items = read::<1>(payload, &mut cursor, count, name)?;
            // `[f32; 1]` and `f32` share size and alignment: no copy.
            Ok(bytemuck::allocation::cast_vec(items))
        };
        for (i, n) in normals.iter().enumerate() {
            if !super::engine::unit_normal(glam::Vec3::from(*n)) {
                return Err(FormatError::Value {
                    field: "normals",
                    index: i as u64,
                });
            }
        }
        let payload = if components == 0 {
            Payload::Dense(take(v * block, "data")?)
        } else {
            let k = components as usize;
            let c = clusters as usize;
            let mean = take(c * block, "mean")?;
            let basis = take(c * k * block, "components")?;
            let weights = take(v * k, "weights")?;
            let cluster_of = if c > 1 {
                let indices = read_indices(&payload[cursor..cursor + 4 * v], "clusters")?;
                cursor += 4 * v;
                if let Some(index) = indices.iter().position(|&i| i >= clusters) {
                    return Err(FormatError::Value {
                        field: "clusters",
                        index: index as u64,
                    });
                }
                indices
            } else {
                Vec::new()
            };
            Payload::Pca(Pca {
                rows: (grid * grid) as usize,
                coeffs: (bands * bands) as usize,
                components: k,
                vertices: v,
                clusters: c,
                mean,
                basis,
                weights,
                cluster_of,
            })
        };
        let texels = match atlas {
            Some((width, height)) => {
                let texels = read_indices(&bytes[header + cursor..], "texels")?;
                if let Some(index) = super::texels::first_disorder(&texels, width, height) {
                    return Err(FormatError::Value {
                        field: "texels",
                        index: index as u64,
                    });
                }
                Some(AtlasTexels {
                    width,
                    height,
                    texels,
                })
            }
            None => None,
        };
        Ok(TransferSet {
            kind,
            bands,
            grid,
            info: BakeInfo {
                rays,
                bounces,
                albedo,
                brdf: BrdfInfo {
                    kind: brdf_kind,
                    params,
                },
            },
            positions,
            frames: super::try_frames_of(&normals).map_err(|_| FormatError::OutOfMemory {
                field: "frames",
                bytes: (v * core::mem::size_of::<crate::Frame>()) as u64,
            })?,
            normals,
            payload,
            texels,
        })
    }
}

/// A section of `u32` (the vertices' clusters, or a lightmap's texels):
/// `bytes` holds exactly them; `field` names it if memory runs out.
fn read_indices(bytes: &[u8], field: &'static str) -> Result<Vec<u32>, FormatError> {
    let count = bytes.len() / 4;
    let mut out: Vec<u32> =
        fallible::with_capacity(count).map_err(|_| FormatError::OutOfMemory {
            field,
            bytes: bytes.len() as u64,
        })?;
    out.extend(
        bytes
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
    );
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_matches_the_standard_check_value() {
        // The CRC catalogue's check value for "123456789".
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }
}
