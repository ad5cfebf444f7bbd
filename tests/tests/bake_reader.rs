//! The bake file format as documented, read by someone else: an independent
//! Python reader (`tests/oracle/bake_reader.py`, written from
//! docs/bake-format.md alone, sharing no code with the library) loads the
//! library's files of both versions and reconstructs every compressed block.
//!
//! Run: `make test`, or `cargo test -p antumbra-tests --test bake_reader` after
//! `tests/oracle/setup_venv.sh target/pyenv`.
//!
//! Checks: the reader accepts a dense MRT file, a global PCA (version 1) and a
//! clustered PCA (version 2) of it, reports the header fields the library wrote,
//! and its reconstruction error (in `f64`, from the documented formula) equals
//! the library's own `pca_levels` to 1e-5 relative; it refuses a file with a
//! flipped payload byte.

use std::path::{Path, PathBuf};
use std::process::Command;

use antumbra_core::MeshView;
use antumbra_core::raycast::BvhScene;
use antumbra_core::transfer::{BakeOptions, Measurement, PhongBrdf, TransferSet, bake};
use antumbra_tests::data::load_obj;
use antumbra_tests::oracle;

fn reader() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("oracle/bake_reader.py")
}

/// Runs the reader; its `name value` lines on success, or its error line.
fn run(args: &[&Path], command: &str) -> Result<Vec<(String, String)>, String> {
    let output = Command::new(oracle::python())
        .arg(reader())
        .arg(command)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", oracle::python().display()));
    if !output.status.success() {
        return Err(String::from_utf8_lossy(&output.stderr).into_owned());
    }
    Ok(String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter_map(|l| l.split_once(' '))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect())
}

fn field<'a>(fields: &'a [(String, String)], name: &str) -> &'a str {
    fields
        .iter()
        .find(|(k, _)| k == name)
        .map(|(_, v)| v.as_str())
        .unwrap_or_else(|| panic!("no {name} in {fields:?}"))
}

#[test]
fn an_independent_reader_loads_both_versions_and_reconstructs_the_blocks() {
    let mesh = load_obj("bunny.obj");
    let view: MeshView<'_> = mesh.view();
    let mut normals = vec![glam::Vec3::ZERO; view.vertex_count()];
    antumbra_core::hemi::vertex_normals(&view, &mut normals).unwrap();
    let scene = BvhScene::new(&view).unwrap();
    let brdf = PhongBrdf::new(16.0).unwrap();
    let options = BakeOptions {
        bands: 3,
        rays: 64,
        seed: 3,
        ..BakeOptions::new(Measurement::Mrt {
            grid: 4,
            brdf: &brdf,
        })
    };
    let dense = bake(&view, &normals, &scene, &options).unwrap();
    let dir = std::env::temp_dir().join(format!("antumbra-bake-reader-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let write = |name: &str, set: &TransferSet| {
        let path = dir.join(name);
        std::fs::write(&path, set.to_bytes()).unwrap();
        path
    };
    let dense_path = write("dense.xfer", &dense);
    let described = run(&[&dense_path], "describe").unwrap();
    assert_eq!(field(&described, "version"), "1");
    assert_eq!(field(&described, "components"), "0");
    assert_eq!(field(&described, "vertex_count"), "1839");
    for (clusters, components, version) in [(1, 6, 1), (8, 6, 2), (30, 3, 2)] {
        let set = dense.compress_clustered(clusters, components, 0).unwrap();
        let path = write(&format!("c{clusters}-k{components}.xfer"), &set);
        let fields = run(&[&dense_path, &path], "compare").unwrap();
        assert_eq!(field(&fields, "version"), version.to_string());
        assert_eq!(field(&fields, "clusters"), clusters.to_string());
        assert_eq!(field(&fields, "components"), components.to_string());
        let theirs: f64 = field(&fields, "relative_rms_error").parse().unwrap();
        let ours = dense.pca_levels(&set, &[components]).unwrap()[0].relative_rms_error;
        println!("C = {clusters}, K = {components}: reader {theirs:.6}, library {ours:.6}");
        assert!(
            (theirs - ours).abs() <= 1e-5 * ours.max(1e-3),
            "C = {clusters}: the reader's error {theirs} against the library's {ours}"
        );
    }
    // A flipped payload byte: the reader checks the payload's CRC too.
    let mut bytes = dense.compress_clustered(8, 6, 0).unwrap().to_bytes();
    let last = bytes.len() - 9;
    bytes[last] ^= 0x10;
    let corrupt = dir.join("corrupt.xfer");
    std::fs::write(&corrupt, &bytes).unwrap();
    let refused = run(&[&corrupt], "describe").unwrap_err();
    assert!(refused.contains("payload_crc32"), "{refused}");
    std::fs::remove_dir_all(&dir).ok();
}
