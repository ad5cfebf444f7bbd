//! Runs the Embree oracle (`tests/oracle/embree_oracle.py`) on a mesh and rays.
//!
//! The interpreter is `$ANTUMBRA_ORACLE_PYTHON`, else `target/pyenv/bin/python`
//! (what `make test` creates with `tests/oracle/setup_venv.sh`). A missing or
//! broken oracle is a test failure that says how to set it up, never a skip.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};

use antumbra_core::Ray;

use crate::data::Mesh;

/// Embree's answer for one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleHit {
    /// Whether Embree's occlusion query found a hit in `(0, t_max)`.
    pub occluded: bool,
    /// Closest hit distance, `+inf` on a miss.
    pub t: f32,
    /// Closest triangle, `u32::MAX` on a miss.
    pub triangle: u32,
    /// Barycentric weight of the second corner.
    pub u: f32,
    /// Barycentric weight of the third corner.
    pub v: f32,
    /// Surfaces crossed on `(0, t_max)` (only with crossings requested).
    pub crossings: u32,
}

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The oracle's Python interpreter.
pub fn python() -> PathBuf {
    std::env::var_os("ANTUMBRA_ORACLE_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join("target/pyenv/bin/python"))
}

const SETUP_HINT: &str = "The Embree oracle needs its virtualenv: run `make test` (or \
`tests/oracle/setup_venv.sh target/pyenv`), or point ANTUMBRA_ORACLE_PYTHON at a Python \
with embreex installed.";

fn scratch_path(kind: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!("antumbra-oracle-{}-{n}.{kind}", std::process::id()))
}

fn header(magic: &[u8; 4], a: u32, b: u32, c: u32) -> Vec<u8> {
    let mut bytes = magic.to_vec();
    for v in [a, b, c] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes
}

fn mesh_bytes(mesh: &Mesh) -> Vec<u8> {
    let mut bytes = header(
        b"ANTM",
        1,
        mesh.positions.len() as u32,
        (mesh.indices.len() / 3) as u32,
    );
    for c in mesh.positions.iter().flatten() {
        bytes.extend_from_slice(&c.to_le_bytes());
    }
    for i in &mesh.indices {
        bytes.extend_from_slice(&i.to_le_bytes());
    }
    bytes
}

fn ray_bytes(rays: &[Ray]) -> Vec<u8> {
    let mut bytes = header(b"ANTR", 1, rays.len() as u32, 0);
    for ray in rays {
        assert_eq!(ray.t_min, 0.0, "the oracle casts over (0, t_max)");
        let values = ray.origin.to_array().into_iter();
        for v in values.chain(ray.direction.to_array()).chain([ray.t_max]) {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    bytes
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

fn f32_at(bytes: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

/// Casts `rays` against `mesh` with Embree. Panics (fails the test) with a setup
/// hint when the oracle cannot run.
pub fn cast(mesh: &Mesh, rays: &[Ray], crossings: bool) -> Vec<OracleHit> {
    let python = python();
    assert!(
        python.exists(),
        "Embree oracle interpreter {} does not exist. {SETUP_HINT}",
        python.display()
    );
    let (mesh_path, rays_path, out_path) = (
        scratch_path("mesh"),
        scratch_path("rays"),
        scratch_path("out"),
    );
    for (path, bytes) in [
        (&mesh_path, mesh_bytes(mesh)),
        (&rays_path, ray_bytes(rays)),
    ] {
        std::fs::File::create(path)
            .and_then(|mut f| f.write_all(&bytes))
            .unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
    }
    let mut command = Command::new(&python);
    command
        .arg(repo_root().join("tests/oracle/embree_oracle.py"))
        .args([&mesh_path, &rays_path, &out_path]);
    if crossings {
        command.arg("--crossings");
    }
    let output = command
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}. {SETUP_HINT}", python.display()));
    let result = std::fs::read(&out_path);
    for path in [&mesh_path, &rays_path, &out_path] {
        let _ = std::fs::remove_file(path);
    }
    assert!(
        output.status.success(),
        "Embree oracle failed ({}): {}\n{SETUP_HINT}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    let bytes = result.expect("oracle wrote no result file");
    assert_eq!(&bytes[0..4], b"ANTO", "oracle result magic");
    assert_eq!(u32_at(&bytes, 4), 1, "oracle result version");
    assert_eq!(u32_at(&bytes, 8) as usize, rays.len(), "oracle ray count");
    assert_eq!(bytes.len(), 16 + 24 * rays.len(), "oracle result size");
    (0..rays.len())
        .map(|i| {
            let at = 16 + 24 * i;
            OracleHit {
                occluded: u32_at(&bytes, at) != 0,
                t: f32_at(&bytes, at + 4),
                triangle: u32_at(&bytes, at + 8),
                u: f32_at(&bytes, at + 12),
                v: f32_at(&bytes, at + 16),
                crossings: u32_at(&bytes, at + 20),
            }
        })
        .collect()
}
