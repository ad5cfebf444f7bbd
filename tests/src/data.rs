//! The committed test meshes (`tests/data/`, see SOURCES.md), loaded with tobj.

use std::path::{Path, PathBuf};

/// An owned indexed triangle mesh.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Three vertex indices per triangle.
    pub indices: Vec<u32>,
}

impl Mesh {
    /// A borrowed, validated view for the core algorithms.
    pub fn view(&self) -> antumbra_core::MeshView<'_> {
        antumbra_core::MeshView::new(&self.positions, &self.indices).expect("test meshes are valid")
    }

    /// Axis-aligned bounds `(min, max)`.
    pub fn bounds(&self) -> (glam::Vec3, glam::Vec3) {
        self.positions.iter().fold(
            (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY),
            |(lo, hi), &p| (lo.min(p.into()), hi.max(p.into())),
        )
    }
}

/// `tests/data/` in this checkout.
pub fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data")
}

/// Loads an OBJ from `tests/data/`, triangulated, all objects merged.
pub fn load_obj(name: &str) -> Mesh {
    let path = data_dir().join(name);
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let (models, _) = tobj::load_obj(&path, &options)
        .unwrap_or_else(|e| panic!("cannot load {}: {e}", path.display()));
    let mut mesh = Mesh::default();
    for model in models {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(
            model
                .mesh
                .positions
                .chunks_exact(3)
                .map(|p| [p[0], p[1], p[2]]),
        );
        mesh.indices
            .extend(model.mesh.indices.iter().map(|&i| base + i));
    }
    mesh
}
