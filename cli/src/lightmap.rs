//! Texel bakes for `antumbra bake --texels`: a mesh with texture coordinates
//! loaded from OBJ, its lightmap receivers (core's `lightmap`), the bake at
//! those receivers, and the coefficients written as OpenEXR channels.

use std::collections::HashMap;
use std::path::Path;

use antumbra_core::lightmap::{AtlasOptions, LiftOptions, TexelAtlas};
use antumbra_core::raycast::BvhScene;
use antumbra_core::transfer::{BakeOptions, TransferKind, TransferSet};
use glam::Vec3;

use crate::error::{Context, Error, Result};
use crate::mesh::{TriangleMesh, obj_models, open_obj};

/// A mesh with one UV and one unit normal per vertex.
pub struct TexturedMesh {
    /// The triangles (vertices split where the UVs are).
    pub mesh: TriangleMesh,
    /// One UV per vertex, OBJ's `vt` (`v` up).
    pub uvs: Vec<[f32; 2]>,
    /// Smooth normals, averaged over every triangle at the vertex's position, so
    /// vertices split at UV seams keep one normal.
    pub normals: Vec<Vec3>,
}

impl TexturedMesh {
    /// Loads a mesh with texture coordinates, by the file's extension: glTF 2.0
    /// for `.gltf` and `.glb` ([`Self::load_gltf`]), OBJ for anything else
    /// ([`Self::load_obj`]).
    #[cfg_attr(
        not(test),
        expect(
            dead_code,
            reason = "bake --texels switches from load_obj to this; remove this attribute then"
        )
    )]
    pub fn load(path: &Path) -> Result<Self> {
        let is_gltf = path.extension().is_some_and(|extension| {
            extension.eq_ignore_ascii_case("gltf") || extension.eq_ignore_ascii_case("glb")
        });
        if is_gltf {
            Self::load_gltf(path)
        } else {
            Self::load_obj(path)
        }
    }

    /// Loads every object of an OBJ file with its texture coordinates: an error
    /// naming the file when any face has none.
    pub fn load_obj(path: &Path) -> Result<Self> {
        let (name, mut reader) = open_obj(path)?;
        Self::parse_obj(&name, &mut reader)
    }

    /// [`Self::load_obj`] from text in memory.
    pub fn parse_obj(name: &str, reader: &mut impl std::io::BufRead) -> Result<Self> {
        // One index per vertex: position and UV pairs become the vertices.
        let models = obj_models(name, reader, true)?;
        let (mut positions, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::new());
        for model in models {
            let mesh = &model.mesh;
            if mesh.indices.is_empty() {
                continue;
            }
            if mesh.texcoords.len() / 2 != mesh.positions.len() / 3 {
                return Err(Error::msg(format!(
                    "{name}: object {} has no texture coordinates (OBJ vt on every face): \
                     a texel bake needs a UV atlas",
                    model.name
                )));
            }
            let base = u32::try_from(positions.len())
                .map_err(|_| Error::msg(format!("{name} has too many vertices")))?;
            positions.extend(mesh.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
            uvs.extend(mesh.texcoords.chunks_exact(2).map(|t| [t[0], t[1]]));
            indices.extend(mesh.indices.iter().map(|&i| base + i));
        }
        if indices.is_empty() {
            return Err(Error::msg(format!("{name} contains no triangles")));
        }
        let mesh = TriangleMesh::new(name, positions, indices)?;
        let normals = welded_normals(&mesh);
        Ok(TexturedMesh { mesh, uvs, normals })
    }
}

/// Area-weighted vertex normals over every triangle that touches the vertex's
/// position (so the copies of a vertex at a UV seam agree), normalised; +Z where
/// they cancel.
pub(crate) fn welded_normals(mesh: &TriangleMesh) -> Vec<Vec3> {
    let positions = mesh.positions();
    let mut welded: HashMap<[u32; 3], usize> = HashMap::new();
    let representative: Vec<usize> = (0..positions.len())
        .map(|v| {
            let key = positions[v].map(f32::to_bits);
            *welded.entry(key).or_insert(v)
        })
        .collect();
    let mut sums = vec![Vec3::ZERO; positions.len()];
    for triangle in mesh.indices().chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(positions[triangle[k] as usize]));
        let area_normal = (b - a).cross(c - a);
        for &v in triangle {
            sums[representative[v as usize]] += area_normal;
        }
    }
    representative
        .iter()
        .map(|&r| sums[r].try_normalize().unwrap_or(Vec3::Z))
        .collect()
}

/// A texel bake: the atlas and the set of its receivers' transfer (entry `i`
/// for receiver `i`).
pub struct TexelBake {
    /// The receivers and which each texel reads.
    pub atlas: TexelAtlas,
    /// Their transfer.
    pub set: TransferSet,
    /// Receivers the lift moved (off an edge into their triangle, or out of
    /// geometry).
    pub lifted: usize,
}

/// Builds the `width × height` atlas of `textured`, lifts its receivers out of
/// geometry, and bakes them with `options`.
pub fn bake_texels(
    textured: &TexturedMesh,
    width: u32,
    height: u32,
    options: &BakeOptions<'_>,
) -> Result<TexelBake> {
    let view = textured.mesh.view();
    let mut atlas = TexelAtlas::new(
        &view,
        &textured.uvs,
        &textured.normals,
        &AtlasOptions::new(width, height),
    )
    .map_err(|e| Error::msg(format!("{}: {e}", textured.mesh.name())))?;
    if atlas.receivers().is_empty() {
        return Err(Error::msg(format!(
            "{}: its charts cover no texel of a {width}x{height} atlas",
            textured.mesh.name()
        )));
    }
    let bvh = BvhScene::new(&view).map_err(|e| Error::msg(e.to_string()))?;
    let lifted = atlas
        .lift(&view, &bvh, &LiftOptions::default())
        .expect("the default lift options are valid");
    // Bounces read the texels under their hits' UVs.
    let set = atlas
        .bake(&view, &textured.normals, &bvh, options, true)
        .map_err(|e| Error::msg(format!("cannot bake: {e}")))?;
    Ok(TexelBake { atlas, set, lifted })
}

/// The EXR channel name of coefficient `k` of a receiver's block: `T.j` for a
/// diffuse transfer vector, `M.i.j` for glossy SH's matrix (row `i`), `R.g.j`
/// for MRT's node `g`.
fn channel_name(kind: TransferKind, coeffs: usize, k: usize) -> String {
    match kind {
        TransferKind::Diffuse => format!("T.{k:02}"),
        TransferKind::GlossySh => format!("M.{:02}.{:02}", k / coeffs, k % coeffs),
        TransferKind::Mrt => format!("R.{:04}.{:02}", k / coeffs, k % coeffs),
    }
}

/// Writes the bake's coefficients as one 32-bit float channel each (see
/// [`channel_name`]) of a `width × height` OpenEXR image, gutter included, 0
/// outside the charts. Row 0 of the image is the atlas's top (`v = 1`), as
/// textures are drawn.
pub fn write_exr(bake: &TexelBake, path: &Path) -> Result<()> {
    use exr::prelude::{AnyChannel, AnyChannels, FlatSamples, Image, WritableImage};
    let (width, height) = (bake.atlas.width() as usize, bake.atlas.height() as usize);
    let set = &bake.set;
    let block = set.vertex_block(0).map_or(0, <[f32]>::len);
    let coeffs = set.coeff_count();
    let mut values = Vec::with_capacity(set.vertex_count() * block);
    for receiver in 0..set.vertex_count() {
        values.extend_from_slice(set.vertex_block(receiver).unwrap_or(&[]));
    }
    let mut texels = vec![0.0f32; width * height * block];
    bake.atlas
        .expand(&values, block, &mut texels)
        .ok_or_else(|| Error::msg("the bake does not match its atlas"))?;
    let channels: Vec<AnyChannel<FlatSamples>> = (0..block)
        .map(|k| {
            let mut samples = Vec::with_capacity(width * height);
            for row in (0..height).rev() {
                samples.extend((0..width).map(|x| texels[(row * width + x) * block + k]));
            }
            AnyChannel::new(
                channel_name(set.kind(), coeffs, k).as_str(),
                FlatSamples::F32(samples),
            )
        })
        .collect();
    let image = Image::from_channels((width, height), AnyChannels::sort(channels.into()));
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create folder {}", parent.display()))?;
    }
    image
        .write()
        .to_file(path)
        .map_err(|e| Error::msg(format!("cannot write {}: {e}", path.display())))
}
