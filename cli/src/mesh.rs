//! Triangle meshes owned by the command: loading Wavefront OBJ files (with
//! `tobj`), bounds, and smooth vertex normals.
//!
//! Core only borrows meshes ([`MeshView`]); file formats stay out of it, here.

use std::io::BufReader;
use std::path::Path;

use antumbra_core::MeshView;
use antumbra_core::raycast::MAX_COORDINATE;
use glam::Vec3;

use crate::bounds::Bounds;
use crate::error::{Context, Error, Result};

/// Opens an OBJ file for [`obj_models`]; the path as the name for messages.
pub(crate) fn open_obj(path: &Path) -> Result<(String, BufReader<std::fs::File>)> {
    let name = path.display().to_string();
    if path.is_dir() {
        return Err(Error::msg(format!("{name} is a folder, not an OBJ file")));
    }
    let file = std::fs::File::open(path).with_context(|| format!("cannot open mesh {name}"))?;
    Ok((name, BufReader::new(file)))
}

/// The objects of an OBJ file, triangulated; `single_index` gives one index per
/// vertex (positions split where their texture coordinates differ).
pub(crate) fn obj_models(
    name: &str,
    reader: &mut impl std::io::BufRead,
    single_index: bool,
) -> Result<Vec<tobj::Model>> {
    // tobj's optional features add fields; the update keeps this compiling with them.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    // Materials do not matter here: never read .mtl files.
    let (models, _materials) =
        tobj::load_obj_buf(reader, &options, |_| Err(tobj::LoadError::OpenFileFailed))
            .with_context(|| format!("cannot parse OBJ mesh {name}"))?;
    Ok(models)
}

/// An owned, validated indexed triangle mesh.
#[derive(Clone, Debug)]
pub struct TriangleMesh {
    name: String,
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

impl TriangleMesh {
    /// A mesh from raw arrays; fails with the core's reason when they do not form a
    /// valid mesh view (index out of range, non-finite position, ...) or a
    /// coordinate is beyond the ray caster's [`MAX_COORDINATE`].
    pub fn new(
        name: impl Into<String>,
        positions: Vec<[f32; 3]>,
        indices: Vec<u32>,
    ) -> Result<Self> {
        let name = name.into();
        MeshView::new(&positions, &indices)
            .with_context(|| format!("{name} is not a valid triangle mesh"))?;
        // The BVH's limit, checked here once so every caster built from this mesh
        // can be built.
        if let Some(vertex) = positions
            .iter()
            .position(|p| p.iter().any(|c| c.abs() > MAX_COORDINATE))
        {
            return Err(Error::msg(format!(
                "{name}: vertex {vertex} has a coordinate beyond the supported range of ±{MAX_COORDINATE:e}"
            )));
        }
        Ok(TriangleMesh {
            name,
            positions,
            indices,
        })
    }

    /// Loads every object of an OBJ file, triangulated, into one mesh.
    pub fn load_obj(path: &Path) -> Result<Self> {
        let (name, mut reader) = open_obj(path)?;
        Self::parse_obj(&name, &mut reader)
    }

    /// Parses OBJ text from memory (the built-in meshes); `name` is used in messages.
    pub fn parse_obj_str(name: &str, text: &str) -> Result<Self> {
        Self::parse_obj(name, &mut text.as_bytes())
    }

    fn parse_obj(name: &str, reader: &mut impl std::io::BufRead) -> Result<Self> {
        let models = obj_models(name, reader, false)?;
        let mut positions: Vec<[f32; 3]> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        for model in models {
            let base = u32::try_from(positions.len())
                .map_err(|_| Error::msg(format!("{name} has too many vertices")))?;
            positions.extend(
                model
                    .mesh
                    .positions
                    .chunks_exact(3)
                    .map(|p| [p[0], p[1], p[2]]),
            );
            indices.extend(model.mesh.indices.iter().map(|&i| base + i));
        }
        if indices.is_empty() {
            return Err(Error::msg(format!("{name} contains no triangles")));
        }
        Self::new(name, positions, indices)
    }

    /// Name for messages: the path or the built-in name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Vertex positions.
    pub fn positions(&self) -> &[[f32; 3]] {
        &self.positions
    }

    /// Three vertex indices per triangle, counter-clockwise seen from outside.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The core's view of this mesh.
    pub fn view(&self) -> MeshView<'_> {
        MeshView::new(&self.positions, &self.indices).expect("validated when the mesh was built")
    }

    /// Bounds of the vertices.
    pub fn bounds(&self) -> Bounds {
        Bounds::of_points(self.positions.iter().map(|&p| Vec3::from(p)))
    }

    /// An error unless the bounding-box diagonal is positive and finite in
    /// `f32`: commands that size things from it (cameras, far meshes) need one.
    pub fn require_extent(&self) -> Result<()> {
        let diagonal = self.bounds().diagonal();
        if diagonal > 0.0 && diagonal.is_finite() {
            Ok(())
        } else {
            Err(Error::msg(format!(
                "{} has zero extent (or one too small for f32): all its vertices are at one point",
                self.name()
            )))
        }
    }

    /// Area-weighted average of the normals of the triangles around each vertex,
    /// normalised; `Vec3::ZERO` for a vertex that touches only degenerate triangles
    /// (or none).
    ///
    /// Area weighting comes for free: the unnormalised cross product is twice the
    /// triangle's area times its unit normal.
    pub fn vertex_normals(&self) -> Vec<Vec3> {
        let mut normals = vec![Vec3::ZERO; self.positions.len()];
        antumbra_core::hemi::vertex_normals(&self.view(), &mut normals)
            .expect("one normal per vertex");
        normals
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TETRA: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

    #[test]
    fn parses_obj_and_computes_outward_normals() {
        let mesh = TriangleMesh::parse_obj_str("tetra", TETRA).unwrap();
        assert_eq!(mesh.vertex_count(), 4);
        assert_eq!(mesh.triangle_count(), 4);
        let normals = mesh.vertex_normals();
        // Vertex 0 sits at the corner facing (-1, -1, -1).
        let expected = Vec3::splat(-1.0).normalize();
        assert!((normals[0] - expected).length() < 1e-6, "{:?}", normals[0]);
        for n in normals {
            assert!((n.length() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn quads_are_triangulated() {
        let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
        let mesh = TriangleMesh::parse_obj_str("quad", quad).unwrap();
        assert_eq!(mesh.triangle_count(), 2);
    }

    #[test]
    fn rejects_files_without_triangles() {
        let error = TriangleMesh::parse_obj_str("points.obj", "v 0 0 0\n").unwrap_err();
        assert!(error.chain().contains("points.obj"), "{}", error.chain());
    }
}
