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

/// The oracle script, built in so callers outside this checkout (the CLI) can run it.
const ORACLE_SCRIPT: &str = include_str!("../oracle/embree_oracle.py");

/// What to ask the oracle for besides hits.
#[derive(Clone, Copy, Debug, Default)]
pub struct OracleOptions {
    /// Count the surfaces crossed on each segment.
    pub crossings: bool,
    /// Time a batch occlusion query over all rays (one thread).
    pub timing: bool,
    /// Timed passes when `timing` (0 counts as 1); the fastest is reported, so
    /// that on a shared machine the figure measures Embree rather than the
    /// other processes.
    pub timing_passes: u32,
}

/// Embree's answers for a batch, and optionally its timing.
#[derive(Clone, Debug)]
pub struct OracleRun {
    /// One answer per ray.
    pub hits: Vec<OracleHit>,
    /// Wall time of one batch occlusion query (the fastest of the timed
    /// passes), when asked for.
    pub occluded_seconds: Option<f64>,
}

/// Casts `rays` against the triangles `(positions, indices)` with Embree; an error
/// says what failed and how to set the oracle up.
pub fn try_cast(
    positions: &[[f32; 3]],
    indices: &[u32],
    rays: &[Ray],
    options: OracleOptions,
) -> Result<OracleRun, String> {
    let python = python();
    if !python.exists() {
        return Err(format!(
            "Embree oracle interpreter {} does not exist. {SETUP_HINT}",
            python.display()
        ));
    }
    if rays.iter().any(|r| r.t_min != 0.0) {
        return Err("the oracle casts over (0, t_max): t_min must be 0".into());
    }
    let mesh = Mesh {
        positions: positions.to_vec(),
        indices: indices.to_vec(),
    };
    let paths = ["py", "mesh", "rays", "out", "timing"].map(scratch_path);
    let [script, mesh_path, rays_path, out_path, timing_path] = &paths;
    let cleanup = || {
        for path in &paths {
            let _ = std::fs::remove_file(path);
        }
    };
    let written = [
        (script, ORACLE_SCRIPT.as_bytes().to_vec()),
        (mesh_path, mesh_bytes(&mesh)),
        (rays_path, ray_bytes(rays)),
    ]
    .into_iter()
    .try_for_each(|(path, bytes)| {
        std::fs::File::create(path)
            .and_then(|mut f| f.write_all(&bytes))
            .map_err(|e| format!("cannot write {}: {e}", path.display()))
    });
    if let Err(e) = written {
        cleanup();
        return Err(e);
    }
    let mut command = Command::new(&python);
    command.arg(script).args([mesh_path, rays_path, out_path]);
    if options.crossings {
        command.arg("--crossings");
    }
    if options.timing {
        command.arg("--timing").arg(timing_path);
        command
            .arg("--timing-passes")
            .arg(options.timing_passes.max(1).to_string());
    }
    let output = command.output();
    let result = std::fs::read(out_path);
    let timing = std::fs::read_to_string(timing_path);
    cleanup();
    let output =
        output.map_err(|e| format!("cannot run {}: {e}. {SETUP_HINT}", python.display()))?;
    if !output.status.success() {
        return Err(format!(
            "Embree oracle failed ({}): {}\n{SETUP_HINT}",
            output.status,
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    let bytes = result.map_err(|e| format!("oracle wrote no result file: {e}"))?;
    let hits = parse_result(&bytes, rays.len())?;
    let occluded_seconds = if options.timing {
        let text = timing.map_err(|e| format!("oracle wrote no timing file: {e}"))?;
        let value = text
            .trim()
            .strip_prefix("occluded_seconds=")
            .and_then(|v| v.parse::<f64>().ok())
            .ok_or_else(|| format!("unreadable oracle timing: {text:?}"))?;
        Some(value)
    } else {
        None
    };
    Ok(OracleRun {
        hits,
        occluded_seconds,
    })
}

/// Embree's frame: every receiver's shadow rays to every light sample.
#[derive(Clone, Debug)]
pub struct FrameRun {
    /// Seconds to create and commit the scene (one core), in the fastest frame.
    pub build_seconds: f64,
    /// Seconds of the occlusion queries of every ray (one core), in the fastest
    /// frame.
    pub rays_seconds: f64,
    /// Per receiver `ceil(samples / 64)` words; bit `i`: the ray to sample `i`
    /// is not occluded (Embree's closed interval `[0, 1]` along `s - p`).
    pub visible: Vec<u64>,
}

impl FrameRun {
    /// What the frame costs: the scene's build plus every ray.
    pub fn seconds(&self) -> f64 {
        self.build_seconds + self.rays_seconds
    }
}

/// Runs Embree on a frame (`embree_oracle.py frame`): builds the scene of
/// `(positions, indices)` and casts the shadow ray of every (receiver,
/// sample) pair on one core, the fastest of `passes` frames each with a new
/// scene. An error says what failed and how to set the oracle up.
pub fn try_frame(
    positions: &[[f32; 3]],
    indices: &[u32],
    receivers: &[glam::Vec3],
    samples: &[glam::Vec3],
    passes: u32,
) -> Result<FrameRun, String> {
    let python = python();
    if !python.exists() {
        return Err(format!(
            "Embree oracle interpreter {} does not exist. {SETUP_HINT}",
            python.display()
        ));
    }
    let mesh = Mesh {
        positions: positions.to_vec(),
        indices: indices.to_vec(),
    };
    let mut frame = header(b"ANTF", 1, receivers.len() as u32, samples.len() as u32);
    for p in receivers.iter().chain(samples) {
        for c in p.to_array() {
            frame.extend_from_slice(&c.to_le_bytes());
        }
    }
    let paths = ["py", "mesh", "frame", "bits"].map(scratch_path);
    let [script, mesh_path, frame_path, out_path] = &paths;
    let cleanup = || {
        for path in &paths {
            let _ = std::fs::remove_file(path);
        }
    };
    let written = [
        (script, ORACLE_SCRIPT.as_bytes().to_vec()),
        (mesh_path, mesh_bytes(&mesh)),
        (frame_path, frame),
    ]
    .into_iter()
    .try_for_each(|(path, bytes)| {
        std::fs::File::create(path)
            .and_then(|mut f| f.write_all(&bytes))
            .map_err(|e| format!("cannot write {}: {e}", path.display()))
    });
    if let Err(e) = written {
        cleanup();
        return Err(e);
    }
    let output = Command::new(&python)
        .arg(script)
        .arg("frame")
        .args([mesh_path, frame_path, out_path])
        .arg("--passes")
        .arg(passes.max(1).to_string())
        .output();
    let result = std::fs::read(out_path);
    cleanup();
    let output =
        output.map_err(|e| format!("cannot run {}: {e}. {SETUP_HINT}", python.display()))?;
    if !output.status.success() {
        return Err(format!(
            "Embree oracle failed ({}): {}\n{SETUP_HINT}",
            output.status,
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    let bytes = result.map_err(|e| format!("oracle wrote no frame result: {e}"))?;
    let words = samples.len().div_ceil(64);
    let expected = 32 + 8 * words * receivers.len();
    if bytes.len() != expected
        || &bytes[0..4] != b"ANTB"
        || u32_at(&bytes, 4) != 1
        || u32_at(&bytes, 8) as usize != receivers.len()
        || u32_at(&bytes, 12) as usize != samples.len()
    {
        return Err(format!(
            "oracle frame result: bad header or {} bytes (expected {expected})",
            bytes.len()
        ));
    }
    let f64_at = |at: usize| f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
    Ok(FrameRun {
        build_seconds: f64_at(16),
        rays_seconds: f64_at(24),
        visible: bytes[32..]
            .chunks_exact(8)
            .map(|w| u64::from_le_bytes(w.try_into().unwrap()))
            .collect(),
    })
}

fn parse_result(bytes: &[u8], rays: usize) -> Result<Vec<OracleHit>, String> {
    if bytes.len() < 16 || &bytes[0..4] != b"ANTO" || u32_at(bytes, 4) != 1 {
        return Err("oracle result has a bad header".into());
    }
    if u32_at(bytes, 8) as usize != rays || bytes.len() != 16 + 24 * rays {
        return Err(format!(
            "oracle result holds {} bytes for {} rays; expected {}",
            bytes.len(),
            u32_at(bytes, 8),
            16 + 24 * rays
        ));
    }
    Ok((0..rays)
        .map(|i| {
            let at = 16 + 24 * i;
            OracleHit {
                occluded: u32_at(bytes, at) != 0,
                t: f32_at(bytes, at + 4),
                triangle: u32_at(bytes, at + 8),
                u: f32_at(bytes, at + 12),
                v: f32_at(bytes, at + 16),
                crossings: u32_at(bytes, at + 20),
            }
        })
        .collect())
}

/// Casts `rays` against `mesh` with Embree. Panics (fails the test) with a setup
/// hint when the oracle cannot run.
pub fn cast(mesh: &Mesh, rays: &[Ray], crossings: bool) -> Vec<OracleHit> {
    let options = OracleOptions {
        crossings,
        ..OracleOptions::default()
    };
    match try_cast(&mesh.positions, &mesh.indices, rays, options) {
        Ok(run) => run.hits,
        Err(message) => panic!("{message}"),
    }
}
