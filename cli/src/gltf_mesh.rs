//! glTF 2.0 meshes with texture coordinates for texel bakes (`antumbra bake
//! --texels`), read with the `gltf` crate from `.gltf` (buffers in external
//! files or base64 data URIs) and `.glb` files.
//!
//! Every triangle primitive of the nodes a viewer shows (the default scene,
//! else the first scene, else every node hierarchy) becomes part of one
//! [`TexturedMesh`]: positions placed by the node's world transform, the
//! lightmap UV set (`TEXCOORD_1`, else `TEXCOORD_0`) with `v` flipped to the
//! atlas convention, and the welded normals the OBJ path computes. The result
//! has one UV and one normal per vertex, indices in range, and does not depend
//! on whether the same geometry came from OBJ or glTF.

use std::path::Path;

use glam::{Mat4, Vec3};
use gltf::accessor::{Accessor, DataType, Dimensions};
use gltf::buffer::{Data as BufferData, View};
use gltf::mesh::{Mode, Primitive, Semantic};

use crate::error::{Context, Error, Result};
use crate::lightmap::{TexturedMesh, welded_normals};
use crate::mesh::TriangleMesh;

impl TexturedMesh {
    /// Loads every triangle primitive placed by the nodes of a glTF 2.0 file
    /// (`.gltf` or `.glb`; the format is recognised by its content).
    ///
    /// UVs are the primitive's `TEXCOORD_1` (a lightmap's own UV set) when it
    /// has one, else `TEXCOORD_0`; normalized unsigned byte and short
    /// coordinates are scaled to `[0, 1]` as glTF specifies. glTF puts the UV
    /// origin at the image's top-left (`v` down) while the atlas puts row 0 at
    /// `v = 0` with `v` up, as OBJ does, so `v` becomes `1 - v`: a glTF file and
    /// the equivalent OBJ give the same atlas.
    ///
    /// Positions are in world space: each node's transform composed with its
    /// parents', over the default scene, else the first scene, else every node
    /// hierarchy when the file has no scene; a mesh used by several nodes is
    /// copied for each. Under a mirroring transform the triangles' winding is
    /// reversed, as glTF requires, so the normals keep facing the same side.
    /// Normals are recomputed as for OBJ (welded, area-weighted); the file's
    /// own normals, skins and morph targets are not read.
    ///
    /// Errors name the file, mesh and primitive: a primitive that is not of
    /// mode TRIANGLES, that has no texture coordinates, or whose data does not
    /// fit its buffers or has the wrong type.
    pub fn load_gltf(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        if path.is_dir() {
            return Err(Error::msg(format!("{name} is a folder, not a glTF file")));
        }
        let gltf::Gltf { document, blob } =
            gltf::Gltf::open(path).with_context(|| format!("cannot read glTF mesh {name}"))?;
        // The gltf crate unwraps the UTF-8 of a decoded buffer URI: refuse
        // one that would not decode before it can panic.
        for buffer in document.buffers() {
            if let gltf::buffer::Source::Uri(uri) = buffer.source()
                && !uri.starts_with("data:")
                && !percent_decodes_to_utf8(uri)
            {
                return Err(Error::msg(format!(
                    "{name}: buffer {} has the URI {uri:?}, whose %-escapes are not UTF-8",
                    buffer.index()
                )));
            }
        }
        // External buffers are named relative to the glTF file.
        let folder = path.parent().unwrap_or(Path::new(""));
        let buffers = gltf::import_buffers(&document, Some(folder), blob)
            .with_context(|| format!("cannot load the buffers of glTF mesh {name}"))?;
        from_document(&name, &document, &buffers)
    }
}

/// Whether `uri`'s `%XX` escapes decode to UTF-8 text (a `%` without two hex
/// digits after it stays as it is).
fn percent_decodes_to_utf8(uri: &str) -> bool {
    let bytes = uri.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let escape = bytes
            .get(i + 1..i + 3)
            .filter(|_| bytes[i] == b'%')
            .and_then(|hex| std::str::from_utf8(hex).ok())
            .and_then(|hex| u8::from_str_radix(hex, 16).ok());
        match escape {
            Some(byte) => {
                decoded.push(byte);
                i += 3;
            }
            None => {
                decoded.push(bytes[i]);
                i += 1;
            }
        }
    }
    std::str::from_utf8(&decoded).is_ok()
}

/// The textured mesh of a parsed glTF document whose buffers are loaded.
fn from_document(
    name: &str,
    document: &gltf::Document,
    buffers: &[BufferData],
) -> Result<TexturedMesh> {
    let mut parts = Parts::default();
    for (node, world) in placed_nodes(name, document)? {
        let Some(mesh) = node.mesh() else {
            continue;
        };
        for primitive in mesh.primitives() {
            let label = match mesh.name() {
                Some(mesh_name) => format!(
                    "{name}: mesh {} {mesh_name:?}, primitive {}",
                    mesh.index(),
                    primitive.index()
                ),
                None => format!(
                    "{name}: mesh {}, primitive {}",
                    mesh.index(),
                    primitive.index()
                ),
            };
            parts.append(&label, &primitive, world, buffers)?;
        }
    }
    if parts.indices.is_empty() {
        return Err(Error::msg(format!("{name} contains no triangles")));
    }
    let mesh = TriangleMesh::new(name, parts.positions, parts.indices)?;
    let normals = welded_normals(&mesh);
    Ok(TexturedMesh {
        mesh,
        uvs: parts.uvs,
        normals,
    })
}

/// Every node a viewer shows, with its world transform, parents before
/// children: the default scene, else the first scene, else every node that is
/// no other's child.
fn placed_nodes<'a>(
    name: &str,
    document: &'a gltf::Document,
) -> Result<Vec<(gltf::Node<'a>, Mat4)>> {
    let node_count = document.nodes().len();
    let roots: Vec<gltf::Node<'a>> = match document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; node_count];
            for child in document.nodes().flat_map(|node| node.children()) {
                is_child[child.index()] = true;
            }
            document
                .nodes()
                .filter(|node| !is_child[node.index()])
                .collect()
        }
    };
    // A stack, not recursion, so a deep hierarchy cannot overflow the call
    // stack; `reached` stops a cyclic or shared one, which glTF forbids.
    let mut reached = vec![false; node_count];
    let mut pending: Vec<(gltf::Node<'a>, Mat4)> = roots
        .into_iter()
        .rev()
        .map(|node| (node, Mat4::IDENTITY))
        .collect();
    let mut placed = Vec::new();
    while let Some((node, parent)) = pending.pop() {
        if std::mem::replace(&mut reached[node.index()], true) {
            return Err(Error::msg(format!(
                "{name}: node {} is reached twice from its scene (glTF nodes must form trees)",
                node.index()
            )));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let children: Vec<gltf::Node<'a>> = node.children().collect();
        pending.extend(children.into_iter().rev().map(|child| (child, world)));
        placed.push((node, world));
    }
    Ok(placed)
}

/// The mesh's arrays, primitive after primitive.
#[derive(Default)]
struct Parts {
    positions: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

impl Parts {
    /// Appends `primitive` placed by `world`; `label` names it in errors.
    fn append(
        &mut self,
        label: &str,
        primitive: &Primitive<'_>,
        world: Mat4,
        buffers: &[BufferData],
    ) -> Result<()> {
        if primitive.mode() != Mode::Triangles {
            return Err(Error::msg(format!(
                "{label} is of mode {}, not TRIANGLES: a texel bake needs triangles",
                mode_name(primitive.mode())
            )));
        }
        let reader = primitive.reader(|buffer| buffers.get(buffer.index()).map(|data| &**data));

        let position_accessor = primitive
            .get(&Semantic::Positions)
            .ok_or_else(|| Error::msg(format!("{label} has no POSITION")))?;
        check_accessor(
            label,
            "POSITION",
            &position_accessor,
            &[DataType::F32],
            Dimensions::Vec3,
            buffers,
        )?;
        let vertex_count = position_accessor.count();
        let positions = reader
            .read_positions()
            .ok_or_else(|| no_data(label, "POSITION"))?
            .map(|p| world.transform_point3(Vec3::from(p)).to_array());

        let (uv_set, uv_accessor) = [1, 0]
            .into_iter()
            .find_map(|set| Some((set, primitive.get(&Semantic::TexCoords(set))?)))
            .ok_or_else(|| {
                Error::msg(format!(
                    "{label} has no texture coordinates (TEXCOORD_1 or TEXCOORD_0): a texel \
                     bake needs a UV atlas"
                ))
            })?;
        let uv_attribute = format!("TEXCOORD_{uv_set}");
        check_accessor(
            label,
            &uv_attribute,
            &uv_accessor,
            &[DataType::F32, DataType::U8, DataType::U16],
            Dimensions::Vec2,
            buffers,
        )?;
        // Integer UVs without `normalized` are KHR_mesh_quantization's, whose
        // scale lives in a texture transform that this loader does not read.
        if uv_accessor.data_type() != DataType::F32 && !uv_accessor.normalized() {
            return Err(Error::msg(format!(
                "{label}: {uv_attribute} holds integers that are not normalized (glTF allows \
                 normalized unsigned bytes or shorts, or floats)"
            )));
        }
        if uv_accessor.count() != vertex_count {
            return Err(Error::msg(format!(
                "{label}: {uv_attribute} has {} entries for {vertex_count} positions",
                uv_accessor.count()
            )));
        }
        let uvs = reader
            .read_tex_coords(uv_set)
            .ok_or_else(|| no_data(label, &uv_attribute))?
            .into_f32()
            .map(|[u, v]| [u, 1.0 - v]);

        let mut indices: Vec<u32> = match primitive.indices() {
            Some(index_accessor) => {
                check_accessor(
                    label,
                    "indices",
                    &index_accessor,
                    &[DataType::U8, DataType::U16, DataType::U32],
                    Dimensions::Scalar,
                    buffers,
                )?;
                reader
                    .read_indices()
                    .ok_or_else(|| no_data(label, "indices"))?
                    .into_u32()
                    .collect()
            }
            None => {
                let count = u32::try_from(vertex_count)
                    .map_err(|_| Error::msg(format!("{label} has too many vertices")))?;
                (0..count).collect()
            }
        };
        if !indices.len().is_multiple_of(3) {
            return Err(Error::msg(format!(
                "{label} has {} indices, not a whole number of triangles",
                indices.len()
            )));
        }
        if let Some(at) = indices.iter().position(|&i| i as usize >= vertex_count) {
            return Err(Error::msg(format!(
                "{label}: index {at} is {}, not below its {vertex_count} vertices",
                indices[at]
            )));
        }
        // A mirroring transform turns counter-clockwise triangles clockwise;
        // glTF says such a node's front faces are the clockwise ones.
        if world.determinant() < 0.0 {
            for triangle in indices.chunks_exact_mut(3) {
                triangle.swap(1, 2);
            }
        }

        // Every vertex of the whole mesh must have a `u32` index.
        if u32::try_from(self.positions.len() + vertex_count).is_err() {
            return Err(Error::msg(format!(
                "{label}: the file has too many vertices"
            )));
        }
        let base = self.positions.len() as u32;
        self.positions.extend(positions);
        self.uvs.extend(uvs);
        self.indices.extend(indices.iter().map(|&i| base + i));
        debug_assert_eq!(self.positions.len(), self.uvs.len());
        Ok(())
    }
}

/// The error of an accessor that has neither a buffer view nor sparse values.
fn no_data(label: &str, attribute: &str) -> Error {
    Error::msg(format!("{label}: {attribute} has no data (no buffer view)"))
}

/// Refuses an accessor of another type than `data_types` × `dimensions`, with
/// no elements, or reaching past its buffer view or buffer: the `gltf` crate's
/// reader trusts all of these and would panic or misread.
fn check_accessor(
    label: &str,
    attribute: &str,
    accessor: &Accessor<'_>,
    data_types: &[DataType],
    dimensions: Dimensions,
    buffers: &[BufferData],
) -> Result<()> {
    let index = accessor.index();
    if accessor.dimensions() != dimensions || !data_types.contains(&accessor.data_type()) {
        return Err(Error::msg(format!(
            "{label}: {attribute} (accessor {index}) is {:?} of {:?}, not {dimensions:?} of \
             one of {data_types:?}",
            accessor.dimensions(),
            accessor.data_type()
        )));
    }
    let size = accessor.size();
    let count = accessor.count();
    let mut fits = count > 0
        && accessor
            .view()
            .is_none_or(|view| view_holds(&view, accessor.offset(), count, size, buffers));
    if let Some(sparse) = accessor.sparse() {
        let indices = sparse.indices();
        let values = sparse.values();
        fits = fits
            && (1..=count).contains(&sparse.count())
            && view_holds(
                &indices.view(),
                indices.offset(),
                sparse.count(),
                indices.index_type().size(),
                buffers,
            )
            && view_holds(
                &values.view(),
                values.offset(),
                sparse.count(),
                size,
                buffers,
            );
    }
    if fits {
        Ok(())
    } else {
        Err(Error::msg(format!(
            "{label}: {attribute} (accessor {index}, {count} elements) is empty or reaches \
             outside its buffer view or buffer"
        )))
    }
}

/// Whether `count` elements of `size` bytes from `offset` in `view`, at its
/// stride, lie inside the view, and the view inside its loaded buffer.
fn view_holds(
    view: &View<'_>,
    offset: usize,
    count: usize,
    size: usize,
    buffers: &[BufferData],
) -> bool {
    let stride = view.stride().unwrap_or(size);
    let view_in_buffer = view
        .offset()
        .checked_add(view.length())
        .zip(buffers.get(view.buffer().index()))
        .is_some_and(|(end, data)| end <= data.len());
    let end = count
        .checked_sub(1)
        .and_then(|last| last.checked_mul(stride))
        .and_then(|start| start.checked_add(offset))
        .and_then(|start| start.checked_add(size));
    stride >= size && view_in_buffer && end.is_some_and(|end| end <= view.length())
}

/// glTF's name of a primitive mode.
fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Points => "POINTS",
        Mode::Lines => "LINES",
        Mode::LineLoop => "LINE_LOOP",
        Mode::LineStrip => "LINE_STRIP",
        Mode::Triangles => "TRIANGLES",
        Mode::TriangleStrip => "TRIANGLE_STRIP",
        Mode::TriangleFan => "TRIANGLE_FAN",
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    /// A folder of its own under the system's temporary folder, removed when
    /// dropped.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new(test: &str) -> Self {
            static NEXT: AtomicUsize = AtomicUsize::new(0);
            let path = std::env::temp_dir().join(format!(
                "antumbra-gltf-{}-{test}-{}",
                std::process::id(),
                NEXT.fetch_add(1, Ordering::Relaxed)
            ));
            std::fs::create_dir_all(&path).unwrap();
            TempDir(path)
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            // Best effort: a leftover temporary folder harms nothing.
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// glTF's component type numbers.
    const FLOAT: u32 = 5126;
    const UNSIGNED_BYTE: u32 = 5121;
    const UNSIGNED_SHORT: u32 = 5123;

    /// A unit quad in the z = 0 plane, facing +Z, as two triangles.
    const QUAD_POSITIONS: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    const QUAD_INDICES: [u16; 6] = [0, 1, 2, 0, 2, 3];
    /// The quad's UVs with glTF's `v` down: (x, 1 - y).
    const QUAD_GLTF_UVS: [[f32; 2]; 4] = [[0., 1.], [1., 1.], [1., 0.], [0., 0.]];
    /// The quad's UVs as OBJ and the atlas see them: (x, y).
    const QUAD_ATLAS_UVS: [[f32; 2]; 4] = [[0., 0.], [1., 0.], [1., 1.], [0., 1.]];

    /// The same quad as OBJ text.
    const QUAD_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                            vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
                            f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";

    /// A glTF asset under construction: one binary buffer, a view per
    /// accessor, and the accessors as JSON.
    #[derive(Default)]
    struct Asset {
        bin: Vec<u8>,
        views: Vec<String>,
        accessors: Vec<String>,
    }

    impl Asset {
        /// Adds `bytes` as a view (with `stride` when given) and an accessor
        /// of it with the JSON members `fields`; returns the accessor's index.
        fn add(&mut self, bytes: &[u8], stride: Option<usize>, fields: &str) -> usize {
            while !self.bin.len().is_multiple_of(4) {
                self.bin.push(0);
            }
            let stride = stride.map_or(String::new(), |s| format!(r#","byteStride":{s}"#));
            self.views.push(format!(
                r#"{{"buffer":0,"byteOffset":{},"byteLength":{}{stride}}}"#,
                self.bin.len(),
                bytes.len()
            ));
            self.bin.extend_from_slice(bytes);
            self.accessors.push(format!(
                r#"{{"bufferView":{},{fields}}}"#,
                self.views.len() - 1
            ));
            self.accessors.len() - 1
        }

        fn positions(&mut self, points: &[[f32; 3]]) -> usize {
            let mut min = [f32::INFINITY; 3];
            let mut max = [f32::NEG_INFINITY; 3];
            for p in points {
                for k in 0..3 {
                    min[k] = min[k].min(p[k]);
                    max[k] = max[k].max(p[k]);
                }
            }
            let bytes: Vec<u8> = points
                .iter()
                .flatten()
                .flat_map(|c| c.to_le_bytes())
                .collect();
            self.add(
                &bytes,
                None,
                &format!(
                    r#""componentType":{FLOAT},"type":"VEC3","count":{},"min":{min:?},"max":{max:?}"#,
                    points.len()
                ),
            )
        }

        fn float_uvs(&mut self, uvs: &[[f32; 2]]) -> usize {
            let bytes: Vec<u8> = uvs.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
            self.add(
                &bytes,
                None,
                &format!(
                    r#""componentType":{FLOAT},"type":"VEC2","count":{}"#,
                    uvs.len()
                ),
            )
        }

        fn indices(&mut self, indices: &[u16]) -> usize {
            let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
            self.add(
                &bytes,
                None,
                &format!(
                    r#""componentType":{UNSIGNED_SHORT},"type":"SCALAR","count":{}"#,
                    indices.len()
                ),
            )
        }

        /// The quad's positions and indices, and its primitive's JSON with
        /// the extra attribute members `texcoords` (`,"TEXCOORD_0":2`).
        fn quad_primitive(&mut self, texcoords: &str) -> String {
            let position = self.positions(&QUAD_POSITIONS);
            let indices = self.indices(&QUAD_INDICES);
            format!(r#"{{"attributes":{{"POSITION":{position}{texcoords}}},"indices":{indices}}}"#)
        }

        /// The document: one mesh named "Quad" of `primitives`, then
        /// `placement` (the `nodes` and `scenes` members), with `buffer_uri`
        /// (none for a GLB's own buffer).
        fn json(&self, primitives: &str, placement: &str, buffer_uri: Option<&str>) -> String {
            let uri = buffer_uri.map_or(String::new(), |uri| format!(r#""uri":"{uri}","#));
            format!(
                r#"{{"asset":{{"version":"2.0"}},{placement},
                "meshes":[{{"name":"Quad","primitives":[{primitives}]}}],
                "buffers":[{{{uri}"byteLength":{}}}],
                "bufferViews":[{}],"accessors":[{}]}}"#,
                self.bin.len(),
                self.views.join(","),
                self.accessors.join(",")
            )
        }

        /// Writes `stem.gltf` (the buffer as a base64 data URI) and
        /// `stem.glb` in `dir`.
        fn write(
            &self,
            dir: &TempDir,
            stem: &str,
            primitives: &str,
            placement: &str,
        ) -> [PathBuf; 2] {
            let uri = format!("data:application/octet-stream;base64,{}", base64(&self.bin));
            let gltf = dir.0.join(format!("{stem}.gltf"));
            std::fs::write(&gltf, self.json(primitives, placement, Some(&uri))).unwrap();
            let glb = dir.0.join(format!("{stem}.glb"));
            std::fs::write(
                &glb,
                glb_bytes(&self.json(primitives, placement, None), &self.bin),
            )
            .unwrap();
            [gltf, glb]
        }
    }

    /// One node showing mesh 0, in the default scene.
    const ONE_NODE: &str = r#""scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}]"#;

    /// Standard base64 with padding, as data URIs hold it.
    fn base64(bytes: &[u8]) -> String {
        const ALPHABET: &[u8; 64] =
            b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut text = String::new();
        for chunk in bytes.chunks(3) {
            let byte = |k: usize| u32::from(chunk.get(k).copied().unwrap_or(0));
            let group = (byte(0) << 16) | (byte(1) << 8) | byte(2);
            for k in 0..4 {
                // A chunk of n bytes carries n + 1 characters; '=' pads to 4.
                if k <= chunk.len() {
                    text.push(ALPHABET[(group >> (18 - 6 * k)) as usize & 63] as char);
                } else {
                    text.push('=');
                }
            }
        }
        text
    }

    /// A binary glTF: the header, the JSON chunk (padded with spaces) and the
    /// BIN chunk (padded with zeros).
    fn glb_bytes(json: &str, bin: &[u8]) -> Vec<u8> {
        let mut json = json.as_bytes().to_vec();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut bin = bin.to_vec();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }

    fn obj_quad() -> TexturedMesh {
        TexturedMesh::parse_obj("quad.obj", &mut QUAD_OBJ.as_bytes()).unwrap()
    }

    /// The quad with float `TEXCOORD_0` only, written as .gltf and .glb.
    fn texcoord_0_quad(dir: &TempDir, placement: &str) -> [PathBuf; 2] {
        let mut asset = Asset::default();
        let uv = asset.float_uvs(&QUAD_GLTF_UVS);
        let primitive = asset.quad_primitive(&format!(r#","TEXCOORD_0":{uv}"#));
        asset.write(dir, "quad", &primitive, placement)
    }

    #[test]
    fn gltf_and_glb_quads_with_texcoord_0_load_as_the_obj_quad() {
        let dir = TempDir::new("texcoord0");
        let obj = obj_quad();
        for path in texcoord_0_quad(&dir, ONE_NODE) {
            let gltf = TexturedMesh::load(&path).unwrap();
            assert_eq!(gltf.mesh.name(), path.display().to_string());
            assert_eq!(gltf.mesh.positions(), QUAD_POSITIONS);
            assert_eq!(gltf.uvs, QUAD_ATLAS_UVS, "{}: v flipped", path.display());
            assert_eq!(gltf.normals, [Vec3::Z; 4]);
            assert_eq!(gltf.mesh.indices(), QUAD_INDICES.map(u32::from));
            // The same mesh as from OBJ: the atlas cannot tell the formats apart.
            assert_eq!(gltf.mesh.positions(), obj.mesh.positions());
            assert_eq!(gltf.mesh.indices(), obj.mesh.indices());
            assert_eq!(gltf.uvs, obj.uvs);
            assert_eq!(gltf.normals, obj.normals);
        }
    }

    #[test]
    fn gltf_texcoord_1_wins_over_texcoord_0() {
        let dir = TempDir::new("texcoord1");
        let mut asset = Asset::default();
        let material_uvs = asset.float_uvs(&[[0.25; 2]; 4]);
        let lightmap_uvs = asset.float_uvs(&QUAD_GLTF_UVS);
        let primitive = asset.quad_primitive(&format!(
            r#","TEXCOORD_0":{material_uvs},"TEXCOORD_1":{lightmap_uvs}"#
        ));
        for path in asset.write(&dir, "two-sets", &primitive, ONE_NODE) {
            let gltf = TexturedMesh::load(&path).unwrap();
            assert_eq!(gltf.uvs, QUAD_ATLAS_UVS, "{}", path.display());
        }
    }

    #[test]
    fn gltf_node_transforms_move_the_positions() {
        let dir = TempDir::new("nodes");
        // A parent moved up 5 in z holds the mesh's node, moved by (2, 3, -1).
        let placement = r#""scene":0,"scenes":[{"nodes":[0]}],"nodes":[
            {"translation":[0,0,5],"children":[1]},
            {"translation":[2,3,-1],"mesh":0}]"#;
        for path in texcoord_0_quad(&dir, placement) {
            let gltf = TexturedMesh::load(&path).unwrap();
            let moved = QUAD_POSITIONS.map(|[x, y, z]| [x + 2.0, y + 3.0, z + 4.0]);
            assert_eq!(gltf.mesh.positions(), moved, "{}", path.display());
            assert_eq!(gltf.uvs, QUAD_ATLAS_UVS);
            assert_eq!(gltf.normals, [Vec3::Z; 4]);
        }
    }

    #[test]
    fn gltf_without_a_scene_places_every_node_hierarchy() {
        let dir = TempDir::new("no-scene");
        let placement = r#""nodes":[{"translation":[1,0,0],"children":[1]},{"mesh":0}]"#;
        let [gltf_path, _] = texcoord_0_quad(&dir, placement);
        let gltf = TexturedMesh::load(&gltf_path).unwrap();
        let moved = QUAD_POSITIONS.map(|[x, y, z]| [x + 1.0, y, z]);
        assert_eq!(gltf.mesh.positions(), moved);
    }

    #[test]
    fn gltf_mirroring_node_keeps_the_quad_facing_its_side() {
        let dir = TempDir::new("mirror");
        let placement =
            r#""scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"scale":[-1,1,1],"mesh":0}]"#;
        for path in texcoord_0_quad(&dir, placement) {
            let gltf = TexturedMesh::load(&path).unwrap();
            let mirrored = QUAD_POSITIONS.map(|[x, y, z]| [-x, y, z]);
            assert_eq!(gltf.mesh.positions(), mirrored);
            // glTF: under a negative determinant the front faces are clockwise.
            assert_eq!(gltf.mesh.indices(), [0, 2, 1, 0, 3, 2]);
            assert_eq!(gltf.normals, [Vec3::Z; 4], "{}", path.display());
        }
    }

    #[test]
    fn gltf_normalized_unsigned_byte_and_short_uvs_are_scaled_to_unit() {
        let dir = TempDir::new("normalized");
        let mut asset = Asset::default();
        // Vertex attributes are 4-byte aligned: a byte pair per 4-byte stride.
        let byte_uvs: Vec<u8> = QUAD_GLTF_UVS
            .iter()
            .flat_map(|&[u, v]| [(u * 255.0) as u8, (v * 255.0) as u8, 0, 0])
            .collect();
        let bytes = asset.add(
            &byte_uvs,
            Some(4),
            &format!(
                r#""componentType":{UNSIGNED_BYTE},"normalized":true,"type":"VEC2","count":4"#
            ),
        );
        let byte_primitive = asset.quad_primitive(&format!(r#","TEXCOORD_0":{bytes}"#));
        // A short's midpoint, 0x8000 / 0xFFFF, sits just above one half.
        let short_uvs: Vec<u8> = [
            [0u16, 0xFFFF],
            [0xFFFF, 0xFFFF],
            [0xFFFF, 0x8000],
            [0, 0x8000],
        ]
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
        let shorts = asset.add(
            &short_uvs,
            None,
            &format!(
                r#""componentType":{UNSIGNED_SHORT},"normalized":true,"type":"VEC2","count":4"#
            ),
        );
        let short_primitive = asset.quad_primitive(&format!(r#","TEXCOORD_1":{shorts}"#));
        let primitives = format!("{byte_primitive},{short_primitive}");
        for path in asset.write(&dir, "normalized", &primitives, ONE_NODE) {
            let gltf = TexturedMesh::load(&path).unwrap();
            assert_eq!(gltf.uvs[..4], QUAD_ATLAS_UVS, "{}", path.display());
            let below_half = 1.0 - 32768.0 / 65535.0;
            assert_eq!(
                gltf.uvs[4..],
                [[0.0, 0.0], [1.0, 0.0], [1.0, below_half], [0.0, below_half]]
            );
            assert_eq!(gltf.mesh.indices()[6..], [4, 5, 6, 4, 6, 7]);
        }
    }

    #[test]
    fn gltf_non_indexed_primitive_gets_sequential_indices() {
        let dir = TempDir::new("non-indexed");
        let mut asset = Asset::default();
        let corners = QUAD_INDICES.map(usize::from);
        let position = asset.positions(&corners.map(|i| QUAD_POSITIONS[i]));
        let uv = asset.float_uvs(&corners.map(|i| QUAD_GLTF_UVS[i]));
        let primitive = format!(r#"{{"attributes":{{"POSITION":{position},"TEXCOORD_0":{uv}}}}}"#);
        for path in asset.write(&dir, "soup", &primitive, ONE_NODE) {
            let gltf = TexturedMesh::load(&path).unwrap();
            assert_eq!(gltf.mesh.indices(), [0, 1, 2, 3, 4, 5]);
            assert_eq!(gltf.uvs, corners.map(|i| QUAD_ATLAS_UVS[i]));
            // Welded over the shared corners, as the OBJ path does.
            assert_eq!(gltf.normals, [Vec3::Z; 6]);
        }
    }

    #[test]
    fn gltf_external_bin_buffer_with_an_escaped_name_loads() {
        let dir = TempDir::new("external");
        let mut asset = Asset::default();
        let uv = asset.float_uvs(&QUAD_GLTF_UVS);
        let primitive = asset.quad_primitive(&format!(r#","TEXCOORD_0":{uv}"#));
        std::fs::write(dir.0.join("quad data.bin"), &asset.bin).unwrap();
        let path = dir.0.join("external.gltf");
        let json = asset.json(&primitive, ONE_NODE, Some("quad%20data.bin"));
        std::fs::write(&path, json).unwrap();
        let gltf = TexturedMesh::load(&path).unwrap();
        assert_eq!(gltf.mesh.positions(), QUAD_POSITIONS);
        assert_eq!(gltf.uvs, QUAD_ATLAS_UVS);
    }

    #[test]
    fn gltf_primitive_without_texcoords_is_an_error_naming_it() {
        let dir = TempDir::new("no-uv");
        let mut asset = Asset::default();
        let uv = asset.float_uvs(&QUAD_GLTF_UVS);
        let textured = asset.quad_primitive(&format!(r#","TEXCOORD_0":{uv}"#));
        let bare = asset.quad_primitive("");
        let primitives = format!("{textured},{bare}");
        for path in asset.write(&dir, "bare", &primitives, ONE_NODE) {
            let error = TexturedMesh::load(&path).err().unwrap().chain();
            assert_eq!(
                error,
                format!(
                    "{}: mesh 0 \"Quad\", primitive 1 has no texture coordinates (TEXCOORD_1 \
                     or TEXCOORD_0): a texel bake needs a UV atlas",
                    path.display()
                )
            );
        }
    }

    #[test]
    fn gltf_points_are_an_error_naming_the_primitive() {
        let dir = TempDir::new("points");
        let mut asset = Asset::default();
        let uv = asset.float_uvs(&QUAD_GLTF_UVS);
        let position = asset.positions(&QUAD_POSITIONS);
        let primitive =
            format!(r#"{{"attributes":{{"POSITION":{position},"TEXCOORD_0":{uv}}},"mode":0}}"#);
        let [path, _] = asset.write(&dir, "points", &primitive, ONE_NODE);
        let error = TexturedMesh::load(&path).err().unwrap().chain();
        assert!(
            error.ends_with("mesh 0 \"Quad\", primitive 0 is of mode POINTS, not TRIANGLES: a texel bake needs triangles"),
            "{error}"
        );
    }

    #[test]
    fn gltf_accessor_past_its_buffer_is_an_error_not_a_panic() {
        let dir = TempDir::new("overrun");
        let mut asset = Asset::default();
        // Four UVs stored, five claimed (the positions claim five too).
        let bytes: Vec<u8> = QUAD_GLTF_UVS
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let uv = asset.add(
            &bytes,
            None,
            &format!(r#""componentType":{FLOAT},"type":"VEC2","count":5"#),
        );
        let position = asset.positions(&[[0.0; 3]; 5]);
        let primitive = format!(r#"{{"attributes":{{"POSITION":{position},"TEXCOORD_0":{uv}}}}}"#);
        let [path, _] = asset.write(&dir, "overrun", &primitive, ONE_NODE);
        let error = TexturedMesh::load(&path).err().unwrap().chain();
        assert!(
            error.contains("primitive 0: TEXCOORD_0 (accessor 0, 5 elements)"),
            "{error}"
        );
    }

    #[test]
    fn buffer_uris_that_do_not_decode_to_utf8_are_refused() {
        assert!(percent_decodes_to_utf8("quad%20data.bin"));
        assert!(percent_decodes_to_utf8("100%.bin"));
        assert!(!percent_decodes_to_utf8("%FF.bin"));
    }

    #[test]
    fn gltf_missing_file_is_an_error_naming_it() {
        let dir = TempDir::new("missing");
        let path = dir.0.join("absent.glb");
        let error = TexturedMesh::load(&path).err().unwrap().chain();
        assert!(
            error.starts_with(&format!("cannot read glTF mesh {}: ", path.display())),
            "{error}"
        );
    }
}
