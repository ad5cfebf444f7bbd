//! Bakes split across machines: `antumbra bake --shard I/N` bakes part `I` of `N`
//! (a contiguous range of the vertices, or of a lightmap's texel entries with
//! `--texels`) into a part file, and `antumbra merge` joins the parts into the
//! bake file a single process would have written, byte for byte (every vertex
//! and texel draws from its own random streams; see core's
//! `transfer::bake_vertices` and `transfer::bake_point_range`).
//!
//! A part file is a 68-byte header followed by an ordinary bake file holding the
//! part's entries (layout in docs/bake-format.md, "Part files"). The header
//! carries what the bake file does not record and a merge must check: the shard's
//! place, the whole bake's entry count and a checksum of what they depend on
//! (the mesh's positions and indices, and for a lightmap its UVs and atlas
//! size), the seed and the ray offset.

use std::ops::Range;

use antumbra_core::transfer::{TransferSet, format::crc32};

use crate::error::{Context, Error, Result};
use crate::mesh::TriangleMesh;

/// The first bytes of a part file.
const MAGIC: &[u8; 8] = b"ANTXPART";
/// Version of the part header.
const VERSION: u32 = 1;
/// Bytes of the part header.
pub const HEADER_LEN: usize = 68;

/// Part `index` of `count` (`--shard I/N`, `0 <= I < N`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which part, from 0.
    pub index: u32,
    /// How many parts.
    pub count: u32,
}

impl Shard {
    /// Parses `I/N`.
    pub fn parse(text: &str) -> std::result::Result<Shard, String> {
        let (index, count) = text
            .split_once('/')
            .ok_or_else(|| format!("'{text}' is not I/N (for example 0/4)"))?;
        let index: u32 = index
            .trim()
            .parse()
            .map_err(|e| format!("shard index '{index}': {e}"))?;
        let count: u32 = count
            .trim()
            .parse()
            .map_err(|e| format!("shard count '{count}': {e}"))?;
        if count == 0 || index >= count {
            return Err(format!("shard {index}/{count}: need 0 <= I < N"));
        }
        Ok(Shard { index, count })
    }

    /// The vertices of this part of a mesh of `vertices`: `[I·V/N, (I+1)·V/N)`.
    pub fn range(&self, vertices: usize) -> Range<usize> {
        let at = |k: u32| (u128::from(k) * vertices as u128 / u128::from(self.count)) as usize;
        at(self.index)..at(self.index + 1)
    }
}

/// What a part's header records.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartHeader {
    /// The part.
    pub shard: Shard,
    /// Its vertices.
    pub first: u64,
    /// One past its last vertex.
    pub end: u64,
    /// Vertices of the whole mesh.
    pub total: u64,
    /// Seed of the bake.
    pub seed: u64,
    /// Ray offset of the bake (mesh units).
    pub ray_offset: f32,
    /// CRC-32 of the whole mesh's positions and indices.
    pub mesh_crc: u32,
}

/// CRC-32 of a mesh's positions and indices (little-endian), which a merge
/// compares so that parts of different meshes are refused.
pub fn mesh_checksum(mesh: &TriangleMesh) -> u32 {
    let mut bytes = Vec::with_capacity(12 * mesh.vertex_count() + 4 * mesh.indices().len());
    for p in mesh.positions() {
        for c in p {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in mesh.indices() {
        bytes.extend_from_slice(&i.to_le_bytes());
    }
    crc32(&bytes)
}

/// CRC-32 of what a texel bake's receivers depend on (the mesh's positions,
/// indices and UVs, and the atlas size), which `antumbra merge` compares so
/// that parts of different lightmaps are refused.
pub fn texel_checksum(textured: &crate::lightmap::TexturedMesh, width: u32, height: u32) -> u32 {
    let mut bytes = mesh_checksum(&textured.mesh).to_le_bytes().to_vec();
    for value in textured.uvs.as_flattened() {
        bytes.extend_from_slice(&value.to_le_bytes());
    }
    bytes.extend_from_slice(&width.to_le_bytes());
    bytes.extend_from_slice(&height.to_le_bytes());
    crc32(&bytes)
}

/// The part file: header, then the bake file of the part's vertices.
pub fn part_bytes(header: &PartHeader, set: &TransferSet) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(HEADER_LEN);
    bytes.extend_from_slice(MAGIC);
    for word in [VERSION, header.shard.index, header.shard.count, 0] {
        bytes.extend_from_slice(&word.to_le_bytes());
    }
    for word in [header.first, header.end, header.total, header.seed] {
        bytes.extend_from_slice(&word.to_le_bytes());
    }
    bytes.extend_from_slice(&header.ray_offset.to_le_bytes());
    bytes.extend_from_slice(&header.mesh_crc.to_le_bytes());
    let crc = crc32(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    debug_assert_eq!(bytes.len(), HEADER_LEN);
    bytes.extend_from_slice(&set.to_bytes());
    bytes
}

/// Reads a part file's header and bake file; `name` names it in errors.
pub fn read_part(bytes: &[u8], name: &str) -> Result<(PartHeader, TransferSet)> {
    if bytes.len() < HEADER_LEN || &bytes[..8] != MAGIC {
        return Err(Error::msg(format!(
            "{name} is not a part file of `antumbra bake --shard` (no ANTXPART header)"
        )));
    }
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    let u64_at = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
    if u32_at(64) != crc32(&bytes[..64]) {
        return Err(Error::msg(format!(
            "{name}: the part header's checksum does not match (damaged file)"
        )));
    }
    let version = u32_at(8);
    if version != VERSION {
        return Err(Error::msg(format!(
            "{name}: part header version {version} is not supported (only {VERSION})"
        )));
    }
    let shard = Shard {
        index: u32_at(12),
        count: u32_at(16),
    };
    if shard.count == 0 || shard.index >= shard.count || u32_at(20) != 0 {
        return Err(Error::msg(format!("{name}: the part header is invalid")));
    }
    let header = PartHeader {
        shard,
        first: u64_at(24),
        end: u64_at(32),
        total: u64_at(40),
        seed: u64_at(48),
        ray_offset: f32::from_bits(u32_at(56)),
        mesh_crc: u32_at(60),
    };
    let expected = shard.range(header.total as usize);
    if (header.first, header.end) != (expected.start as u64, expected.end as u64) {
        return Err(Error::msg(format!(
            "{name}: vertices {}..{} are not part {}/{} of {} vertices",
            header.first, header.end, shard.index, shard.count, header.total
        )));
    }
    let set = TransferSet::from_bytes(&bytes[HEADER_LEN..])
        .map_err(|e| Error::msg(format!("{name}: its bake file is invalid: {e}")))?;
    if set.vertex_count() as u64 != header.end - header.first {
        return Err(Error::msg(format!(
            "{name}: holds {} vertices, its header says {}",
            set.vertex_count(),
            header.end - header.first
        )));
    }
    Ok((header, set))
}

/// Joins parts (any order) into the whole bake; refuses parts of different
/// bakes, overlapping parts and missing vertices, naming the files.
pub fn merge(parts: Vec<(String, PartHeader, TransferSet)>) -> Result<TransferSet> {
    let Some((first_name, first, _)) = parts.first().map(|(n, h, s)| (n.clone(), *h, s)) else {
        return Err(Error::msg("no part to merge"));
    };
    for (name, header, _) in &parts {
        let differs = |what: &str, here: String, there: String| {
            Error::msg(format!(
                "{name} and {first_name} come from different bakes: {what} {here} against {there}"
            ))
        };
        if header.shard.count != first.shard.count {
            return Err(differs(
                "shard count",
                header.shard.count.to_string(),
                first.shard.count.to_string(),
            ));
        }
        if header.total != first.total || header.mesh_crc != first.mesh_crc {
            return Err(differs(
                "mesh (vertex count, checksum)",
                format!("({}, {:08x})", header.total, header.mesh_crc),
                format!("({}, {:08x})", first.total, first.mesh_crc),
            ));
        }
        if header.seed != first.seed {
            return Err(differs(
                "seed",
                header.seed.to_string(),
                first.seed.to_string(),
            ));
        }
        if header.ray_offset.to_bits() != first.ray_offset.to_bits() {
            return Err(differs(
                "ray offset",
                header.ray_offset.to_string(),
                first.ray_offset.to_string(),
            ));
        }
    }
    let mut parts = parts;
    parts.sort_by_key(|(_, h, _)| (h.first, h.end));
    let mut covered = 0u64;
    let mut previous = String::new();
    for (name, header, _) in &parts {
        if header.first < covered {
            return Err(Error::msg(format!(
                "{name} (part {}/{}) overlaps {previous}: both hold vertex {}",
                header.shard.index, header.shard.count, header.first
            )));
        }
        if header.first > covered {
            return Err(Error::msg(format!(
                "vertices {covered}..{} are missing: no part holds them (part {}/{} of the \
                 same bake is not given)",
                header.first,
                missing_shard(header, covered),
                header.shard.count
            )));
        }
        covered = header.end;
        previous.clone_from(name);
    }
    if covered != first.total {
        let last = parts.last().map(|(_, h, _)| *h).unwrap_or(first);
        return Err(Error::msg(format!(
            "vertices {covered}..{} are missing: no part holds them (part {}/{} of the same \
             bake is not given)",
            first.total,
            missing_shard(&last, covered),
            first.shard.count
        )));
    }
    let sets: Vec<TransferSet> = parts.into_iter().map(|(_, _, set)| set).collect();
    TransferSet::concat(&sets).map_err(|e| {
        Error::msg(format!(
            "the parts come from different bakes (settings of the bake files): {e}"
        ))
    })
}

/// The shard whose range starts at vertex `at` in a bake split like `header`'s.
fn missing_shard(header: &PartHeader, at: u64) -> u32 {
    (0..header.shard.count)
        .find(|&k| {
            Shard {
                index: k,
                count: header.shard.count,
            }
            .range(header.total as usize)
            .start as u64
                == at
        })
        .unwrap_or(0)
}

/// Reads every part file.
pub fn read_parts(paths: &[std::path::PathBuf]) -> Result<Vec<(String, PartHeader, TransferSet)>> {
    paths
        .iter()
        .map(|path| {
            let name = path.display().to_string();
            let bytes = std::fs::read(path).with_context(|| format!("cannot read {name}"))?;
            let (header, set) = read_part(&bytes, &name)?;
            Ok((name, header, set))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cut_the_vertices_into_consecutive_ranges() {
        for vertices in [1usize, 7, 1839, 1 << 20] {
            for count in [1u32, 2, 3, 7] {
                let mut next = 0;
                for index in 0..count {
                    let range = Shard { index, count }.range(vertices);
                    assert_eq!(range.start, next);
                    next = range.end;
                }
                assert_eq!(next, vertices);
            }
        }
        assert_eq!(Shard::parse("2/5"), Ok(Shard { index: 2, count: 5 }));
        for bad in ["5/5", "0/0", "1", "a/2", "-1/3"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }
}
