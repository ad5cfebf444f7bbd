//! Data compiled into the binary, so `antumbra demo`, `bench` and `verify` work
//! from any folder with no arguments. Provenance and licences (all public
//! domain or CC0) are in `tests/data/SOURCES.md`.

use crate::envmap::EnvironmentMap;
use crate::error::Result;
use crate::mesh::TriangleMesh;

/// The Stanford bunny (npm `bunny@1.0.1`): 1,839 vertices, 3,674 triangles, closed, +Y up.
pub const BUNNY_OBJ: &str = include_str!("../../tests/data/bunny.obj");

/// The Utah teapot (npm `teapot@1.0.0`): 792 vertices, 992 triangles, open, +Y up.
pub const TEAPOT_OBJ: &str = include_str!("../../tests/data/teapot.obj");

/// The Stanford armadillo (Debian `libcgal-demo` 5.5.1): 26,002 vertices, 52,000
/// triangles, closed, +Y up; the large mesh of the benchmarks.
pub const ARMADILLO_OBJ: &str = include_str!("../../tests/data/armadillo.obj");

/// Blender's `sunrise.exr` studio light: 1024×512 equirectangular HDR, a low sun.
pub const SUNRISE_EXR: &[u8] = include_bytes!("../../tests/data/sunrise.exr");

/// The built-in bunny.
pub fn bunny() -> Result<TriangleMesh> {
    TriangleMesh::parse_obj_str("built-in bunny", BUNNY_OBJ)
}

/// The built-in teapot.
pub fn teapot() -> Result<TriangleMesh> {
    TriangleMesh::parse_obj_str("built-in teapot", TEAPOT_OBJ)
}

/// The built-in armadillo.
pub fn armadillo() -> Result<TriangleMesh> {
    TriangleMesh::parse_obj_str("built-in armadillo", ARMADILLO_OBJ)
}

/// The built-in sunrise environment map.
pub fn sunrise() -> Result<EnvironmentMap> {
    EnvironmentMap::decode("built-in sunrise.exr", SUNRISE_EXR)
}

#[cfg(test)]
mod tests {
    #[test]
    fn built_in_meshes_have_the_documented_sizes() {
        let bunny = super::bunny().unwrap();
        assert_eq!((bunny.vertex_count(), bunny.triangle_count()), (1839, 3674));
        let teapot = super::teapot().unwrap();
        assert_eq!((teapot.vertex_count(), teapot.triangle_count()), (792, 992));
        let armadillo = super::armadillo().unwrap();
        assert_eq!(armadillo.triangle_count(), 52000);
    }
}
