//! The bake file format as documented, read by someone else: an independent
//! Python reader (`tests/oracle/bake_reader.py`, written from
//! docs/bake-format.md alone, sharing no code with the library) loads the
//! library's files of every version and reconstructs every compressed block.
//!
//! Run: `make test`, or `cargo test -p antumbra-tests --test bake_reader` after
//! `tests/oracle/setup_venv.sh target/pyenv`.
//!
//! Checks: the reader accepts a dense MRT file, a global PCA (version 1) and a
//! clustered PCA (version 2) of it, reports the header fields the library wrote,
//! and its reconstruction error (in `f64`, from the documented formula) equals
//! the library's own `pca_levels` to 1e-5 relative; it refuses a file with a
//! flipped payload byte. The same for a lightmap (version 3: dense, one
//! cluster and clustered), whose atlas size, texel count and texels' CRC it
//! reports as the library wrote them; it refuses a resealed lightmap with a
//! texel out of order.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use antumbra_core::MeshView;
use antumbra_core::raycast::BvhScene;
use antumbra_core::transfer::format::{crc32, reseal};
use antumbra_core::transfer::{
    BakeOptions, FormatError, Measurement, PhongBrdf, TransferSet, bake,
};
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

/// The dense MRT bake of the bunny (1839 vertices), baked once for every test.
fn bunny_mrt() -> &'static TransferSet {
    static SET: OnceLock<TransferSet> = OnceLock::new();
    SET.get_or_init(|| {
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
        bake(&view, &normals, &scene, &options).unwrap()
    })
}

/// A fresh folder for one test's files.
fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "antumbra-bake-reader-{test}-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Checks the reader's error for `compressed` against the dense set's,
/// `pca_levels` at all of its components.
fn assert_same_error(fields: &[(String, String)], dense: &TransferSet, compressed: &TransferSet) {
    let components: usize = field(fields, "components").parse().unwrap();
    let theirs: f64 = field(fields, "relative_rms_error").parse().unwrap();
    let ours = dense.pca_levels(compressed, &[components]).unwrap()[0].relative_rms_error;
    let clusters = field(fields, "clusters");
    println!("C = {clusters}, K = {components}: reader {theirs:.6}, library {ours:.6}");
    assert!(
        (theirs - ours).abs() <= 1e-5 * ours.max(1e-3),
        "C = {clusters}: the reader's error {theirs} against the library's {ours}"
    );
}

#[test]
fn an_independent_reader_loads_both_versions_and_reconstructs_the_blocks() {
    let dense = bunny_mrt();
    let dir = scratch("vertices");
    let write = |name: &str, set: &TransferSet| {
        let path = dir.join(name);
        std::fs::write(&path, set.to_bytes()).unwrap();
        path
    };
    let dense_path = write("dense.xfer", dense);
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
        assert_same_error(&fields, dense, &set);
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

#[test]
fn an_independent_reader_loads_lightmaps_and_refuses_texels_out_of_order() {
    let vertices = bunny_mrt();
    // The bunny's entries as texels of an 80 × 50 atlas (not square, so a
    // reader that swaps the sides reads other texels): two apart, a third of
    // them one further, strictly increasing, the last 3676 below 4000.
    let (width, height) = (80, 50);
    let texels: Vec<u32> = (0..vertices.vertex_count() as u32)
        .map(|i| 2 * i + u32::from(i % 3 == 0))
        .collect();
    let dense = vertices
        .clone()
        .with_texels(width, height, texels.clone())
        .unwrap();
    let texel_bytes: Vec<u8> = texels.iter().flat_map(|t| t.to_le_bytes()).collect();
    let dir = scratch("texels");
    let write = |name: &str, set: &TransferSet| {
        let path = dir.join(name);
        let bytes = set.to_bytes();
        assert_eq!(
            &bytes[8..12],
            &3u32.to_le_bytes(),
            "{name} is a version-3 file"
        );
        assert_eq!(TransferSet::from_bytes(&bytes).as_ref(), Ok(set));
        std::fs::write(&path, bytes).unwrap();
        path
    };
    let assert_lightmap = |fields: &[(String, String)], clusters: usize, components: usize| {
        assert_eq!(field(fields, "version"), "3");
        assert_eq!(field(fields, "kind"), "3");
        assert_eq!(field(fields, "bands"), "3");
        assert_eq!(field(fields, "grid"), "4");
        assert_eq!(field(fields, "clusters"), clusters.to_string());
        assert_eq!(field(fields, "components"), components.to_string());
        assert_eq!(field(fields, "vertex_count"), texels.len().to_string());
        assert_eq!(field(fields, "atlas_width"), width.to_string());
        assert_eq!(field(fields, "atlas_height"), height.to_string());
        assert_eq!(field(fields, "texel_count"), texels.len().to_string());
        assert_eq!(
            field(fields, "texels_crc32"),
            crc32(&texel_bytes).to_string()
        );
    };
    let dense_path = write("dense.xfer", &dense);
    assert_lightmap(&run(&[&dense_path], "describe").unwrap(), 0, 0);
    let compressed = [
        ("global", dense.compress(6).unwrap(), 1, 6),
        ("c8", dense.compress_clustered(8, 6, 0).unwrap(), 8, 6),
        ("c30", dense.compress_clustered(30, 3, 0).unwrap(), 30, 3),
    ];
    for (name, set, clusters, components) in &compressed {
        assert_eq!(
            set.texels().map(|t| (t.width(), t.height(), t.texels())),
            Some((width, height, texels.as_slice())),
            "{name} keeps the texels"
        );
        let path = write(&format!("{name}.xfer"), set);
        let fields = run(&[&dense_path, &path], "compare").unwrap();
        assert_lightmap(&fields, *clusters, *components);
        assert_same_error(&fields, &dense, set);
    }
    // The last texel equal to the one before it, both checksums recomputed: only
    // the texels' order is wrong, so only the reader's texel check can see it.
    for (name, set, ..) in &compressed[1..] {
        let mut bytes = set.to_bytes();
        let len = bytes.len();
        let before: [u8; 4] = bytes[len - 8..len - 4].try_into().unwrap();
        bytes[len - 4..].copy_from_slice(&before);
        reseal(&mut bytes);
        let last = texels.len() - 1;
        assert_eq!(
            TransferSet::from_bytes(&bytes),
            Err(FormatError::Value {
                field: "texels",
                index: last as u64,
            })
        );
        let disordered = dir.join(format!("{name}-disordered.xfer"));
        std::fs::write(&disordered, &bytes).unwrap();
        let refused = run(&[&disordered], "describe").unwrap_err();
        assert!(refused.contains(&format!("texels[{last}]")), "{refused}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
