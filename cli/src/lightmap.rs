//! Texel bakes for `antumbra bake --texels` and `antumbra render`: a mesh with
//! texture coordinates (OBJ or glTF), its lightmap receivers (core's
//! `lightmap`), the bake at those receivers (whole or a shard's part), the
//! coefficients written as OpenEXR channels, and a mesh drawn with a lightmap.

use std::collections::HashMap;
use std::path::Path;

use std::ops::Range;

use antumbra_core::lightmap::{AtlasOptions, LiftOptions, TexelAtlas};
use antumbra_core::raycast::BvhScene;
use antumbra_core::transfer::{AtlasTexels, BakeOptions, TransferKind, TransferSet};
use glam::{Vec2, Vec3};

use crate::camera::Camera;
use crate::error::{Context, Error, Result};
use crate::mesh::{TriangleMesh, obj_models, open_obj};
use crate::raster::Framebuffer;
use crate::shard::Shard;

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

/// The gutter of texel bakes' textures, in texels: one keeps bilinear lookups
/// inside charts on baked values, the second one level of mipmaps (core's
/// default).
pub const GUTTER: u32 = 2;

/// A texel bake: the atlas and the set of its receivers' transfer (entry `i`
/// for receiver `range.start + i`, the set carrying their texels).
pub struct TexelBake {
    /// The receivers and which each texel reads.
    pub atlas: TexelAtlas,
    /// Their transfer.
    pub set: TransferSet,
    /// The receivers baked: all, or a shard's part.
    pub range: Range<usize>,
    /// Receivers the lift moved (off an edge into their triangle, or out of
    /// geometry).
    pub lifted: usize,
}

/// Builds the `width × height` atlas of `textured`, lifts its receivers out of
/// geometry, and bakes them with `options`: every receiver, or with `shard`
/// that part of them (the atlas and lift are the whole mesh's either way, so
/// the parts join into the whole bake).
pub fn bake_texels(
    textured: &TexturedMesh,
    width: u32,
    height: u32,
    options: &BakeOptions<'_>,
    shard: Option<Shard>,
) -> Result<TexelBake> {
    let view = textured.mesh.view();
    let mut atlas = atlas_of(textured, width, height)?;
    let receivers = atlas.receivers().len();
    let range = shard.map_or(0..receivers, |s| s.range(receivers));
    if range.is_empty() {
        return Err(Error::msg(format!(
            "{}: the {width}x{height} atlas has {receivers} texels, fewer than the parts",
            textured.mesh.name()
        )));
    }
    let bvh = BvhScene::new(&view).map_err(|e| Error::msg(e.to_string()))?;
    let lifted = atlas
        .lift(&view, &bvh, &LiftOptions::default())
        .expect("the default lift options are valid");
    // Bounces read the texels under their hits' UVs.
    let set = if range.len() == receivers {
        atlas.bake(&view, &textured.normals, &bvh, options, true)
    } else {
        atlas.bake_part(&view, &textured.normals, &bvh, options, range.clone())
    }
    .map_err(|e| Error::msg(format!("cannot bake: {e}")))?;
    Ok(TexelBake {
        atlas,
        set,
        range,
        lifted,
    })
}

/// The `width × height` atlas of `textured` with the [`GUTTER`], receivers on
/// the surface; an error naming the mesh when its UVs cannot make one or its
/// charts cover no texel.
pub fn atlas_of(textured: &TexturedMesh, width: u32, height: u32) -> Result<TexelAtlas> {
    let options = AtlasOptions {
        gutter: GUTTER,
        ..AtlasOptions::new(width, height)
    };
    let atlas = TexelAtlas::new(
        &textured.mesh.view(),
        &textured.uvs,
        &textured.normals,
        &options,
    )
    .map_err(|e| Error::msg(format!("{}: {e}", textured.mesh.name())))?;
    if atlas.receivers().is_empty() {
        return Err(Error::msg(format!(
            "{}: its charts cover no texel of a {width}x{height} atlas",
            textured.mesh.name()
        )));
    }
    Ok(atlas)
}

/// Checks that `texels` (a bake file's) are the texels `textured`'s atlas of
/// that size covers, so the lightmap's entries land where this mesh's UVs look
/// them up. It compares texel coverage only: a mesh with the same UVs and
/// other positions passes (the file keeps no checksum of the mesh).
pub fn check_texels_match(textured: &TexturedMesh, texels: &AtlasTexels) -> Result<()> {
    let atlas = atlas_of(textured, texels.width(), texels.height())?;
    let width = texels.width();
    let same = atlas.receivers().len() == texels.texels().len()
        && atlas
            .receivers()
            .iter()
            .zip(texels.texels())
            .all(|(r, &t)| r.texel_index(width) == t);
    if same {
        Ok(())
    } else {
        Err(Error::msg(format!(
            "the lightmap's {} texels of a {}x{} atlas are not those {}'s UVs cover ({}): it \
             was baked from another mesh or UV set",
            texels.texels().len(),
            texels.width(),
            texels.height(),
            textured.mesh.name(),
            atlas.receivers().len()
        )))
    }
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

/// Writes a dense texel set's coefficients as one 32-bit float channel each
/// (see [`channel_name`]) of an OpenEXR image of its atlas, with the
/// [`GUTTER`], 0 outside the charts. Row 0 of the image is the atlas's top
/// (`v = 1`), as textures are drawn.
pub fn write_exr(set: &TransferSet, path: &Path) -> Result<()> {
    let texels = set
        .texels()
        .ok_or_else(|| Error::msg("not a texel bake: it has no lightmap texels"))?;
    let values = set
        .dense_data()
        .ok_or_else(|| Error::msg("an OpenEXR lightmap holds dense coefficients, not a PCA"))?;
    let block = set.block_len();
    let (width, height) = (texels.width() as usize, texels.height() as usize);
    let mut image = vec![0.0f32; width * height * block];
    texels
        .expand(GUTTER, values, block, &mut image)
        .ok_or_else(|| Error::msg("the bake does not match its texels"))?;
    let names: Vec<String> = (0..block)
        .map(|k| channel_name(set.kind(), set.coeff_count(), k))
        .collect();
    write_channels(&image, (width, height), &names, path)
}

/// Writes `image` (`names.len()` values per texel, row 0 at `v = 0`) as a
/// 32-bit float OpenEXR image with those channel names, row 0 of the file at
/// `v = 1`.
pub fn write_channels(
    image: &[f32],
    (width, height): (usize, usize),
    names: &[String],
    path: &Path,
) -> Result<()> {
    use exr::prelude::{AnyChannel, AnyChannels, FlatSamples, Image, WritableImage};
    let block = names.len();
    let channels: Vec<AnyChannel<FlatSamples>> = names
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let mut samples = Vec::with_capacity(width * height);
            for row in (0..height).rev() {
                samples.extend((0..width).map(|x| image[(row * width + x) * block + k]));
            }
            AnyChannel::new(name.as_str(), FlatSamples::F32(samples))
        })
        .collect();
    let exr_image = Image::from_channels((width, height), AnyChannels::sort(channels.into()));
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create folder {}", parent.display()))?;
    }
    exr_image
        .write()
        .to_file(path)
        .map_err(|e| Error::msg(format!("cannot write {}: {e}", path.display())))
}

/// Bilinear lookup of an RGB texture (`width × height`, row 0 at v = 0) at `uv`,
/// clamped to the edge.
pub fn bilinear(texture: &[f32], width: usize, height: usize, uv: Vec2) -> Vec3 {
    let x = uv.x * width as f32 - 0.5;
    let y = uv.y * height as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let texel = |tx: f32, ty: f32| {
        let tx = (tx.max(0.0) as usize).min(width - 1);
        let ty = (ty.max(0.0) as usize).min(height - 1);
        Vec3::from_slice(&texture[(ty * width + tx) * 3..])
    };
    let top = texel(x0, y0).lerp(texel(x0 + 1.0, y0), fx);
    let bottom = texel(x0, y0 + 1.0).lerp(texel(x0 + 1.0, y0 + 1.0), fx);
    top.lerp(bottom, fy)
}

/// Draws `textured` seen by `camera` into a `size` framebuffer, each pixel the
/// RGB `texture` (`texture_size`, row 0 at v = 0) looked up bilinearly at its
/// UV: a deferred pass, UVs drawn as colours first, as an engine samples a
/// lightmap.
pub fn draw_lightmapped(
    camera: &Camera,
    textured: &TexturedMesh,
    texture: &[f32],
    (texture_width, texture_height): (usize, usize),
    size: (usize, usize),
) -> Framebuffer {
    let uv_colors: Vec<Vec3> = textured
        .uvs
        .iter()
        .map(|uv| Vec3::new(uv[0], uv[1], 0.0))
        .collect();
    let mut frame = Framebuffer::new(size.0, size.1);
    frame.draw_mesh(
        camera,
        textured.mesh.positions(),
        textured.mesh.indices(),
        &uv_colors,
    );
    frame.map_colors(|uv| bilinear(texture, texture_width, texture_height, uv.truncate()));
    frame
}
