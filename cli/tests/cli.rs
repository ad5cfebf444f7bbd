//! End-to-end tests of the `antumbra` binary: every command runs, writes real
//! output, and fails cleanly on bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the built binary with `args`.
fn antumbra(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_antumbra"))
        .args(args)
        .output()
        .expect("the antumbra binary runs")
}

fn stdout(output: &Output) -> String {
    String::from_utf8_lossy(&output.stdout).into_owned()
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// Asserts success and shows the command's output otherwise.
fn assert_success(output: &Output) {
    assert!(
        output.status.success(),
        "exit {:?}\nstdout:\n{}\nstderr:\n{}",
        output.status,
        stdout(output),
        stderr(output)
    );
}

/// A fresh, empty folder for one test's files.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("antumbra-cli")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A committed test file (`tests/data/` at the workspace root).
fn data(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

#[test]
fn help_lists_every_command_and_each_has_its_own_help() {
    let output = antumbra(&["--help"]);
    assert_success(&output);
    let text = stdout(&output);
    for command in ["demo", "render", "bake", "merge", "bench", "verify"] {
        assert!(
            text.contains(command),
            "--help does not mention {command}:\n{text}"
        );
    }
    for args in [
        &["demo", "--help"][..],
        &["render", "--help"],
        &["bake", "--help"],
        &["merge", "--help"],
        &["bench", "--help"],
        &["bench", "raycast", "--help"],
        &["verify", "--help"],
    ] {
        let output = antumbra(args);
        assert_success(&output);
        assert!(stdout(&output).contains("Usage: antumbra"), "{args:?}");
    }
}

#[test]
fn demo_writes_decodable_pictures_with_content() {
    let dir = scratch("demo");
    let output = antumbra(&["demo", "--size", "32", "--out", dir.to_str().unwrap()]);
    assert_success(&output);
    let summary = stdout(&output);
    for name in [
        "bunny-ambient-occlusion.png",
        "bunny-sunrise.png",
        "sunrise-environment.png",
        "bunny-hemi-diffuse.png",
        "bunny-hemi-glossy.png",
        "bunny-hemi-twist.png",
        "bunny-mrt-rotating-sky.png",
        "lightmap-boxes.png",
        "bunny-soft-shadows.png",
        "bunny-soft-shadows-difference.png",
    ] {
        let path = dir.join(name);
        assert!(
            summary.contains(&path.display().to_string()),
            "summary lacks {name}:\n{summary}"
        );
        let picture = image::open(&path)
            .unwrap_or_else(|e| panic!("{} does not decode: {e}", path.display()))
            .into_rgb8();
        // The twist and the rotating sky are contact sheets of 2x2 frames, each
        // as wide as the others.
        let frames = if name.ends_with("twist.png") || name.ends_with("sky.png") {
            2
        } else {
            1
        };
        assert_eq!(picture.width(), 32 * frames, "{name}");
        let first = picture.get_pixel(0, 0);
        assert!(
            picture.pixels().any(|p| p != first),
            "{name} is all one colour"
        );
    }
    // The hemi pictures: the diffuse and glossy bunnies differ, and the twist
    // reports a time for each of its four frames.
    let diffuse = image::open(dir.join("bunny-hemi-diffuse.png")).unwrap();
    let glossy = image::open(dir.join("bunny-hemi-glossy.png")).unwrap();
    assert_ne!(diffuse.as_bytes(), glossy.as_bytes());
    let twist = summary
        .lines()
        .find(|line| line.contains("per frame"))
        .unwrap_or_else(|| panic!("no per-frame timings:\n{summary}"));
    assert_eq!(twist.matches(" ms").count(), 4, "{twist}");
    // The soft shadows equal tracing the same 256 rays per pixel, bit for bit.
    let difference = summary
        .lines()
        .find(|line| line.starts_with("soft shadows against ray tracing: "))
        .unwrap_or_else(|| panic!("no soft-shadow difference count:\n{summary}"));
    assert!(difference.contains(": 0 of "), "{difference}");
}

#[test]
fn render_writes_ambient_occlusion_and_environment_lighting() {
    let dir = scratch("render");
    for (env, name) in [(None, "ao.png"), (Some(data("sunrise.exr")), "env.png")] {
        let out = dir.join(name);
        let teapot = data("teapot.obj");
        let mut args = vec![
            "render",
            "--mesh",
            &teapot,
            "--size",
            "24",
            "--samples",
            "2",
        ];
        let out_str = out.to_str().unwrap();
        args.extend(["--out", out_str]);
        if let Some(env) = &env {
            args.extend(["--env", env.as_str()]);
        }
        let output = antumbra(&args);
        assert_success(&output);
        let picture = image::open(&out).unwrap().into_rgb8();
        assert_eq!((picture.width(), picture.height()), (24, 18));
    }
}

#[test]
fn verify_reports_agreement_and_its_exit_status_follows_it() {
    let output = antumbra(&["verify", "--rays", "2000"]);
    let text = stdout(&output);
    for heading in [
        "built-in bunny",
        "built-in teapot",
        "at vertex",
        "long direction",
    ] {
        assert!(text.contains(heading), "{heading} missing:\n{text}");
    }
    let all_agree = text.contains("agreement: 4000/4000");
    assert!(text.contains("agreement: "), "{text}");
    assert_eq!(
        output.status.success(),
        all_agree,
        "{text}\n{}",
        stderr(&output)
    );
    assert!(all_agree || stderr(&output).contains("disagree"));
    assert!(!stderr(&output).contains("panicked"));
}

/// The BVH must agree exactly with brute force: both use the same watertight test.
#[test]
fn verify_agrees_exactly_on_the_built_in_meshes() {
    let output = antumbra(&["verify"]);
    assert_success(&output);
}

#[test]
fn bake_writes_one_line_per_vertex_plus_a_header() {
    let dir = scratch("bake");
    let teapot = data("teapot.obj");
    for name in ["teapot.ao", "teapot.csv"] {
        let out = dir.join(name);
        let output = antumbra(&[
            "bake",
            "--mesh",
            &teapot,
            "--out",
            out.to_str().unwrap(),
            "--rays",
            "16",
        ]);
        assert_success(&output);
        let text = std::fs::read_to_string(&out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 792 + 1, "{name}");
        for line in &lines[1..] {
            let value: f32 = line.rsplit(',').next().unwrap().parse().unwrap();
            assert!((0.0..=1.0).contains(&value), "{name}: {line}");
        }
    }
}

#[test]
fn transfer_bakes_round_trip_through_render() {
    let dir = scratch("bake-transfer");
    let teapot = data("teapot.obj");
    let bunny = data("bunny.obj");
    for (kind, extra) in [
        ("diffuse", &["--bounces", "1"][..]),
        ("glossy-sh", &["--bands", "3"][..]),
        ("mrt", &["--grid", "4", "--pca", "4"][..]),
        ("mrt", &["--grid", "4", "--pca", "4", "--clusters", "3"][..]),
        ("mrt", &["--grid", "4", "--ward", "0.2,0.5"][..]),
    ] {
        let out = dir.join(format!("teapot-{kind}-{}.xfer", extra.len()));
        let mut args = vec![
            "bake",
            "--mesh",
            &teapot,
            "--kind",
            kind,
            "--rays",
            "16",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let output = antumbra(&args);
        assert_success(&output);
        let text = stdout(&output);
        assert!(text.contains("792 vertices"), "{text}");
        if extra.contains(&"--pca") {
            assert!(text.contains("K =   4: relative RMS error"), "{text}");
        }
        if extra.contains(&"--clusters") {
            assert!(
                text.contains("clustered PCA to 3 clusters of 4 components"),
                "{text}"
            );
            // Clustered sets are bake-file version 2.
            assert_eq!(std::fs::read(&out).unwrap()[8], 2);
        }
        let png = dir.join(format!("teapot-{kind}-{}.png", extra.len()));
        let output = antumbra(&[
            "render",
            "--mesh",
            &teapot,
            "--bake",
            out.to_str().unwrap(),
            "--rotate",
            "45",
            "--size",
            "40",
            "--out",
            png.to_str().unwrap(),
        ]);
        assert_success(&output);
        let picture = image::open(&png).unwrap().into_rgb8();
        assert_eq!(picture.width(), 40);
        let first = picture.get_pixel(0, 0);
        assert!(picture.pixels().any(|p| p != first), "{kind}: one colour");
        // A bake relit on another mesh is refused by name.
        let output = antumbra(&[
            "render",
            "--mesh",
            &bunny,
            "--bake",
            out.to_str().unwrap(),
            "--out",
            png.to_str().unwrap(),
        ]);
        assert!(!output.status.success());
        assert!(
            stderr(&output).contains("bake it from this mesh"),
            "{}",
            stderr(&output)
        );
    }
    // --pca needs an MRT bake; a corrupt file is refused with a message.
    let output = antumbra(&[
        "bake", "--mesh", &teapot, "--kind", "diffuse", "--pca", "2", "-o", "x.xfer",
    ]);
    assert!(!output.status.success());
    assert!(stderr(&output).contains("--pca"), "{}", stderr(&output));
    // --clusters needs --pca.
    let output = antumbra(&[
        "bake",
        "--mesh",
        &teapot,
        "--kind",
        "mrt",
        "--clusters",
        "2",
        "-o",
        "x.xfer",
    ]);
    assert!(!output.status.success());
    assert!(stderr(&output).contains("--pca"), "{}", stderr(&output));
    let bad = dir.join("bad.xfer");
    std::fs::write(&bad, b"ANTXFER\0 not really").unwrap();
    let output = antumbra(&["render", "--mesh", &teapot, "--bake", bad.to_str().unwrap()]);
    assert!(!output.status.success());
    assert!(
        stderr(&output).contains("is not a valid bake file"),
        "{}",
        stderr(&output)
    );
}

#[test]
fn bench_transfer_prints_every_figure() {
    let output = antumbra(&[
        "bench",
        "transfer",
        "--mesh",
        &data("teapot.obj"),
        "--bands",
        "2,3",
        "--rays",
        "4",
        "--min-time",
        "1",
        "--max-components",
        "4",
        "--clusters",
        "3",
        "--cluster-components",
        "2",
        "--no-embree",
    ]);
    assert_success(&output);
    let text = stdout(&output);
    for needle in [
        "clustered PCA (Sloan et al. 2003)",
        "global at equal bytes",
        "worst row: C = 3, K = 2",
        "bake, one thread",
        "obvhs occluded alone",
        "glossy SH, view-first",
        "glossy SH, 2002 order",
        "MRT from PCA, K = 4",
        "cheaper than glossy SH",
        "K =   4",
        "bytes per vertex",
    ] {
        assert!(text.contains(needle), "{needle} missing:\n{text}");
    }
    assert_eq!(
        text.matches("shading cost per vertex, ").count(),
        2,
        "{text}"
    );
}

#[test]
fn bench_prints_both_casters_and_the_ratio() {
    let output = antumbra(&["bench", "raycast", "--rays", "300", "--min-time", "10"]);
    assert_success(&output);
    let text = stdout(&output);
    assert!(
        text.contains("brute force") && text.contains("BVH") && text.contains('x'),
        "{text}"
    );
}

/// `bench lightmap` prints the texel and vertex rows with their ratios, on
/// the built-in scene and on a mesh without UVs (an error naming it).
#[test]
fn bench_lightmap_prints_texels_against_vertices() {
    let output = antumbra(&[
        "bench",
        "lightmap",
        "--texels",
        "32",
        "--rays",
        "8",
        "--repeats",
        "1",
    ]);
    assert_success(&output);
    let text = stdout(&output);
    for row in ["atlas and lift", "diffuse", "glossy SH", "texel/vertex"] {
        assert!(text.contains(row), "{row}: {text}");
    }
    let output = antumbra(&["bench", "lightmap", "--mesh", &data("teapot.obj")]);
    assert!(!output.status.success());
    assert!(
        stderr(&output).contains("texture coordinates"),
        "{}",
        stderr(&output)
    );
}

#[test]
fn missing_and_bad_files_fail_with_a_message_naming_them() {
    let dir = scratch("errors");
    let missing = dir.join("no-such-mesh.obj");
    let output = antumbra(&["bake", "--mesh", missing.to_str().unwrap(), "--out", "x.ao"]);
    assert!(!output.status.success());
    let message = stderr(&output);
    assert!(message.contains("no-such-mesh.obj"), "{message}");
    assert!(!message.contains("panicked"), "{message}");

    // An OBJ given as an environment map is neither EXR nor PNG.
    let teapot = data("teapot.obj");
    let out = dir.join("never.png");
    let output = antumbra(&[
        "render",
        "--mesh",
        &teapot,
        "--env",
        &teapot,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!output.status.success());
    let message = stderr(&output);
    assert!(
        message.contains("teapot.obj") && message.contains("OpenEXR"),
        "{message}"
    );
    assert!(!out.exists());

    // A file that is not an OBJ at all.
    let garbage = dir.join("garbage.obj");
    std::fs::write(&garbage, [0xff, 0xfe, 0x00, 0x12]).unwrap();
    let output = antumbra(&["verify", "--mesh", garbage.to_str().unwrap()]);
    assert!(!output.status.success());
    let message = stderr(&output);
    assert!(
        message.contains("garbage.obj") && !message.contains("panicked"),
        "{message}"
    );
}

#[test]
fn verify_hemi_prints_the_agreement_line_and_passes_on_the_bunny() {
    let output = antumbra(&["verify", "hemi", "--receivers", "20"]);
    assert_success(&output);
    let text = stdout(&output);
    let last = text.lines().last().unwrap_or_default();
    assert!(
        last.starts_with("hemi exact agreement: ") && last.ends_with("cells, 20 receivers"),
        "{text}"
    );
}

#[test]
fn verify_ssv_prints_the_agreement_line_and_passes_on_the_bunny() {
    let output = antumbra(&[
        "verify",
        "ssv",
        "--samples",
        "64",
        "--floor-grid",
        "6",
        "--mesh-points",
        "40",
    ]);
    assert_success(&output);
    let text = stdout(&output);
    let last = text.lines().last().unwrap_or_default();
    // 3 light orientations x (36 floor + 40 mesh receivers) x 64 samples.
    assert!(
        last.starts_with("ssv agreement: ") && last.contains("% of 14592 bits, "),
        "{text}"
    );
    assert!(last.ends_with(" mismatches"), "{text}");
}

#[test]
fn bench_hemi_scaling_has_a_row_per_mesh_and_far_field_setting() {
    let mesh = data("teapot.obj");
    let output = antumbra(&[
        "bench",
        "hemi",
        "--scaling",
        "--mesh",
        mesh.as_str(),
        "--receivers",
        "5",
        "--min-time",
        "1",
        "--no-embree",
    ]);
    assert_success(&output);
    let text = stdout(&output);
    // The far field (the field after the mesh's name and its triangle count)
    // and the receivers (the first field after the far field's).
    let fields = |line: &str, mesh: &str| -> Option<(String, String)> {
        let rest: Vec<&str> = line.strip_prefix(mesh)?.split_whitespace().collect();
        let far = rest.get(1)?.to_string();
        // "none", or "T x L" with an optional "(n/4)".
        let mut next = if far == "none" { 2 } else { 4 };
        if rest.get(next) == Some(&"(n/4)") {
            next += 1;
        }
        Some((far, rest.get(next)?.to_string()))
    };
    // Receivers "all" (timed receivers), "every" (the whole frame) or a
    // sparse setting "spacing/tolerance".
    let rows = |mesh: &str, far: &str, kind: &str| {
        text.lines()
            .filter_map(|l| fields(l, mesh))
            .filter(|(f, r)| f == far && (r == kind || (kind == "sparse" && r.contains('/'))))
            .count()
    };
    // The exact path for every mesh; far fields only below a quarter of the
    // triangles: the armadillo's 52,000, not the teapot's 992.
    assert_eq!(rows("built-in bunny", "none", "all"), 1, "{text}");
    assert_eq!(rows("teapot.obj", "none", "all"), 1, "{text}");
    assert_eq!(rows("teapot.obj", "2000", "all"), 0, "{text}");
    assert_eq!(rows("built-in armadillo", "2000", "all"), 2, "{text}");
    assert_eq!(rows("built-in armadillo", "8000", "all"), 2, "{text}");
    // The whole exact frame, then three sparse-receiver settings, each with
    // the full mesh and the (n/4) far field.
    assert_eq!(rows("teapot.obj", "none", "every"), 1, "{text}");
    assert_eq!(rows("teapot.obj", "none", "sparse"), 3, "{text}");
    assert_eq!(rows("built-in armadillo", "13000", "sparse"), 3, "{text}");
    // Far-field and sparse-receiver rows carry their error, the exact rows
    // say so.
    for line in text.lines().filter(|l| l.starts_with("built-in armadillo")) {
        let (far, receivers) = fields(line, "built-in armadillo").expect("a row");
        let exact = far == "none" && (receivers == "all" || receivers == "every");
        assert_eq!(line.contains("exact"), exact, "{line}");
        assert_eq!(line.contains('%'), !exact, "{line}");
    }
}

#[test]
fn bench_ssv_reports_every_structure_and_orientation() {
    let output = antumbra(&[
        "bench",
        "ssv",
        "--samples",
        "16",
        "--floor-grid",
        "2",
        "--mesh-points",
        "4",
        "--min-time",
        "1",
        "--no-embree",
    ]);
    assert_success(&output);
    let text = stdout(&output);
    for needle in [
        "light horizontal",
        "light tilted 45°",
        "light side 80°",
        "hemicube",
        "obvhs rays",
        "candidates:",
        "light orientation changes the hierarchy's time per receiver",
    ] {
        assert!(text.contains(needle), "no {needle:?} in:\n{text}");
    }
}

#[test]
fn bench_ssv_frame_reports_every_row_and_the_worst_of_each_figure() {
    let mesh = data("teapot.obj");
    let output = antumbra(&[
        "bench",
        "ssv",
        "--frame",
        "--mesh",
        mesh.as_str(),
        "--ground",
        "12",
        "--mesh-points",
        "4",
        "--samples",
        "64",
        "--passes",
        "1",
        "--no-embree",
    ]);
    assert_success(&output);
    let text = stdout(&output);
    for size in ["1/4", "4/5"] {
        for orientation in ["horizontal", "tilted 45°", "side 80°"] {
            assert!(
                text.lines()
                    .any(|l| l.trim_start().starts_with(size) && l.contains(orientation)),
                "no row {size} {orientation} in:\n{text}"
            );
        }
    }
    for needle in [
        "cold frame / warm frame: worst ",
        "hemicube's cold frame / hierarchy's cold frame, light 1/4: worst ",
        "hemicube's cold frame / hierarchy's cold frame, light 4/5: worst ",
        "ground candidates / with a root fitted to the receivers: worst ",
        "against the hemicube 0 rows differ",
    ] {
        assert!(text.contains(needle), "no {needle:?} in:\n{text}");
    }
}

#[test]
fn bench_hemi_reports_ratios_against_the_bvh() {
    let output = antumbra(&[
        "bench",
        "hemi",
        "--receivers",
        "10",
        "--min-time",
        "1",
        "--no-embree",
    ]);
    assert_success(&output);
    let text = stdout(&output);
    assert!(
        text.contains("less time per receiver than the BVH"),
        "{text}"
    );
    assert!(text.contains("ns per rasterized triangle"), "{text}");
    // The frames-per-second table: both rows, both thread counts, the far mesh.
    for needle in [
        "frames per second shading every vertex",
        "far mesh: ",
        "near radius",
        "1 thread",
        "far mesh speed-up",
        "far levels speed-up",
        "sparse receivers speed-up",
        "colour error",
    ] {
        assert!(text.contains(needle), "{needle} missing:\n{text}");
    }
    for row in [
        "full mesh ",
        "full near + far mesh ",
        "full near + 3 far levels ",
        "full mesh, sparse receivers (1, 0.1) ",
        "far mesh, sparse receivers (1, 0.1) ",
    ] {
        let line = text
            .lines()
            .find(|line| line.starts_with(row))
            .unwrap_or_else(|| panic!("no row {row}:\n{text}"));
        assert_eq!(line.matches(" fps (").count(), 2, "{line}");
        // The last two fields: the colour error against the full mesh's colours
        // (the reference, so 0 on its own row) and the share rasterized.
        let percents: Vec<f64> = line
            .split('%')
            .filter_map(|piece| piece.split_whitespace().last()?.parse().ok())
            .collect();
        let [.., error, share] = percents[..] else {
            panic!("no error and share in {line}");
        };
        assert!(
            error >= 0.0 && (row != "full mesh " || error == 0.0),
            "{line}"
        );
        let sparse = row.contains("sparse");
        assert!(
            share > 0.0 && share <= 100.0 && (sparse || share == 100.0),
            "{line}"
        );
    }
}

/// `--on-ground`: the frames table alone, of the mesh standing on the demo's
/// ground, with its three rows.
#[test]
fn bench_hemi_on_ground_times_the_mesh_on_the_demos_ground() {
    let output = antumbra(&[
        "bench",
        "hemi",
        "--on-ground",
        "--mesh",
        &data("teapot.obj"),
        "--min-time",
        "1",
    ]);
    assert_success(&output);
    let text = stdout(&output);
    for needle in [
        "teapot.obj on a ground",
        "full near + far mesh",
        "far levels",
        "far levels speed-up",
    ] {
        assert!(text.contains(needle), "{needle}: {text}");
    }
    // Only the frames table: no masks table, no Embree.
    assert!(!text.contains("ns per rasterized triangle"), "{text}");
    assert!(!text.contains("Embree"), "{text}");
}

#[test]
fn bench_hemi_frames_run_on_another_mesh_with_table_quality() {
    let output = antumbra(&[
        "bench",
        "hemi",
        "--mesh",
        &data("teapot.obj"),
        "--receivers",
        "5",
        "--min-time",
        "1",
        "--no-embree",
        "--quality",
        "table",
    ]);
    assert_success(&output);
    let text = stdout(&output);
    assert!(text.contains("table masks"), "{text}");
    assert!(text.contains("triangles of 992"), "{text}");
    assert!(text.contains("full near + far mesh"), "{text}");
}

/// The CLI review's reproducer: `bench hemi` on a mesh whose vertices are all
/// at one point panicked after its timing tables (an `assert!` on the far
/// mesh's cell size); it is refused before any timing.
#[test]
fn bench_hemi_refuses_a_mesh_of_zero_extent() {
    let dir = scratch("zero-extent");
    let point = dir.join("point.obj");
    std::fs::write(&point, "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n").unwrap();
    let output = antumbra(&[
        "bench",
        "hemi",
        "--mesh",
        point.to_str().unwrap(),
        "--no-embree",
        "--min-time",
        "1",
    ]);
    assert!(!output.status.success());
    let text = stderr(&output);
    assert!(text.contains("zero extent"), "{text}");
    assert!(!text.contains("panicked"), "{text}");
    assert!(
        !stdout(&output).contains("rasterizer"),
        "timed before refusing"
    );
}

/// The CLI review's reproducers: `--rays 4294967295` made `bench raycast` and
/// `verify` ask for 155 GB and abort; the option is bounded by the parser.
#[test]
fn ray_counts_beyond_memory_are_refused_by_the_parser() {
    for args in [
        &["bench", "raycast", "--rays", "4294967295"][..],
        &["verify", "--rays", "4294967295"],
    ] {
        let output = antumbra(args);
        assert_eq!(output.status.code(), Some(2), "{args:?}");
        assert!(
            stderr(&output).contains("is not in 1..=16777216"),
            "{args:?}"
        );
    }
}

/// The CLI review's reproducers of silent wrong output: a small PNG that could
/// not be written was reported as written (its bytes sat in an unflushed
/// buffer), and `--rotate nan` rendered a black mesh.
#[cfg(target_os = "linux")]
#[test]
fn failed_writes_and_non_finite_rotations_are_errors() {
    let teapot = data("teapot.obj");
    let common = ["render", "--mesh", &teapot, "--size", "8", "--samples", "1"];
    let output = antumbra(&[&common[..], &["--out", "/dev/full"]].concat());
    assert!(!output.status.success());
    assert!(
        stderr(&output).contains("cannot write PNG"),
        "{}",
        stderr(&output)
    );
    let dir = scratch("rotate-nan");
    let out = dir.join("x.png");
    let output = antumbra(
        &[
            &common[..],
            &["--rotate=nan", "--out", out.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(!output.status.success());
    assert!(stderr(&output).contains("--rotate"), "{}", stderr(&output));
    assert!(!out.exists());
}

/// A mesh name with a line break kept the AO text format's header on one
/// line only by luck; it is escaped.
#[cfg(target_os = "linux")]
#[test]
fn the_ao_text_header_is_one_line_whatever_the_mesh_name() {
    let dir = scratch("newline-name");
    let mesh = dir.join("new\nline.obj");
    std::fs::copy(data("teapot.obj"), &mesh).unwrap();
    let out = dir.join("ao.txt");
    let output = antumbra(&[
        "bake",
        "--mesh",
        mesh.to_str().unwrap(),
        "--rays",
        "2",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_success(&output);
    let text = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("# antumbra ambient occlusion"));
    assert!(lines[0].contains("new\\nline.obj"), "{}", lines[0]);
    assert_eq!(lines.len(), 1 + 792, "teapot: 792 vertices");
}

/// A bake split into parts run side by side (`xargs -P`, as a job runner would)
/// and merged is the single bake's file, byte for byte; merge refuses parts that
/// overlap, leave vertices out, or come from another bake.
#[test]
fn sharded_bakes_merge_into_the_single_bake_byte_for_byte() {
    let dir = scratch("shards");
    let teapot = data("teapot.obj");
    let exe = env!("CARGO_BIN_EXE_antumbra");
    for (kind, extra) in [
        ("diffuse", "--bounces 1"),
        ("glossy-sh", "--bands 3"),
        ("mrt", "--grid 4 --bands 3"),
    ] {
        let common = format!("--mesh {teapot} --kind {kind} --rays 16 {extra} --seed 5");
        let whole = dir.join(format!("{kind}-whole.xfer"));
        let args: Vec<String> = format!("bake {common} -o {}", whole.display())
            .split_whitespace()
            .map(String::from)
            .collect();
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_success(&antumbra(&refs));
        let part = |i: u32| dir.join(format!("{kind}-part-{i}.xpart"));
        let script = format!(
            "seq 0 2 | xargs -P 3 -I{{}} {exe} bake {common} --shard {{}}/3 -o {}/{kind}-part-{{}}.xpart",
            dir.display()
        );
        let run = Command::new("sh").arg("-c").arg(&script).output().unwrap();
        assert_success(&run);
        let merged = dir.join(format!("{kind}-merged.xfer"));
        let (p0, p1, p2) = (part(0), part(1), part(2));
        // Any order of the parts.
        let output = antumbra(&[
            "merge",
            p2.to_str().unwrap(),
            p0.to_str().unwrap(),
            p1.to_str().unwrap(),
            "-o",
            merged.to_str().unwrap(),
        ]);
        assert_success(&output);
        assert_eq!(
            std::fs::read(&merged).unwrap(),
            std::fs::read(&whole).unwrap(),
            "{kind}: the merged parts differ from the single bake"
        );
        if kind == "mrt" {
            // Clustered PCA at the merge equals it at the single bake.
            let compressed = |command: &str, out: &Path| {
                let args: Vec<String> =
                    format!("{command} --pca 3 --clusters 4 -o {}", out.display())
                        .split_whitespace()
                        .map(String::from)
                        .collect();
                let refs: Vec<&str> = args.iter().map(String::as_str).collect();
                assert_success(&antumbra(&refs));
                std::fs::read(out).unwrap()
            };
            let whole = compressed(&format!("bake {common}"), &dir.join("cpca-whole.xfer"));
            let merged = compressed(
                &format!("merge {} {} {}", p1.display(), p2.display(), p0.display()),
                &dir.join("cpca-merged.xfer"),
            );
            assert_eq!(merged, whole, "clustered PCA of the merged parts");
        }
        if kind != "diffuse" {
            continue;
        }
        let refused = |parts: &[&Path], needle: &str| {
            let mut args = vec!["merge"];
            args.extend(parts.iter().map(|p| p.to_str().unwrap()));
            let out = dir.join("refused.xfer");
            args.extend(["-o", out.to_str().unwrap()]);
            let output = antumbra(&args);
            assert!(!output.status.success(), "merged {parts:?}");
            assert!(
                stderr(&output).contains(needle),
                "{needle:?} not in {}",
                stderr(&output)
            );
        };
        refused(&[&p0, &p1, &p1, &p2], "overlaps");
        refused(&[&p0, &p2], "are missing");
        refused(&[&p0, &p1], "are missing");
        // A part of the same mesh and split with another seed.
        let other = dir.join("other-seed.xpart");
        let args: Vec<String> = format!(
            "bake {} --seed 6 --shard 1/3 -o {}",
            common.replace(" --seed 5", ""),
            other.display()
        )
        .split_whitespace()
        .map(String::from)
        .collect();
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_success(&antumbra(&refs));
        refused(
            &[&p0, &other, &p2],
            "come from different bakes: seed 6 against 5",
        );
        refused(&[&whole], "is not a part file");
    }
    // Parts with PCA are refused; merge compresses instead.
    let output = antumbra(&[
        "bake",
        "--mesh",
        &teapot,
        "--kind",
        "mrt",
        "--pca",
        "4",
        "--shard",
        "0/2",
        "-o",
        dir.join("x.xpart").to_str().unwrap(),
    ]);
    assert!(!output.status.success());
    assert!(stderr(&output).contains("antumbra merge --pca K"));
}

/// A floor with a box standing on it as OBJ with texture coordinates: the
/// floor on the left half of the atlas, each box face its own chart on the
/// right half. `overlap` puts two box faces on one chart.
fn floor_and_box_obj(overlap: bool) -> String {
    let mut text = String::new();
    let (mut v, mut vt) = (0, 0);
    let mut quad = |text: &mut String, corners: [[f32; 3]; 4], lo: [f32; 2], hi: [f32; 2]| {
        let uvs = [lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]];
        for (p, t) in corners.iter().zip(uvs) {
            text.push_str(&format!(
                "v {} {} {}\nvt {} {}\n",
                p[0], p[1], p[2], t[0], t[1]
            ));
        }
        let i = |k: usize| format!("{}/{}", v + k + 1, vt + k + 1);
        text.push_str(&format!("f {} {} {} {}\n", i(0), i(1), i(2), i(3)));
        v += 4;
        vt += 4;
    };
    quad(
        &mut text,
        [
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
        ],
        [0.0, 0.0],
        [0.5, 1.0],
    );
    let (s, h) = (0.3, 0.4);
    let faces = [
        [[-s, -s, h], [s, -s, h], [s, s, h], [-s, s, h]],
        [[-s, s, 0.0], [s, s, 0.0], [s, -s, 0.0], [-s, -s, 0.0]],
        [[-s, -s, 0.0], [s, -s, 0.0], [s, -s, h], [-s, -s, h]],
        [[s, s, 0.0], [-s, s, 0.0], [-s, s, h], [s, s, h]],
        [[s, -s, 0.0], [s, s, 0.0], [s, s, h], [s, -s, h]],
        [[-s, s, 0.0], [-s, -s, 0.0], [-s, -s, h], [-s, s, h]],
    ];
    for (k, face) in faces.into_iter().enumerate() {
        let k = if overlap && k == 1 { 0 } else { k };
        let lo = [0.55 + 0.22 * (k % 2) as f32, 0.05 + 0.3 * (k / 2) as f32];
        quad(&mut text, face, lo, [lo[0] + 0.15, lo[1] + 0.15]);
    }
    text
}

/// `bake --texels`: the lightmap of a box on a floor, read back from its
/// OpenEXR image: one channel per coefficient, open floor near the unoccluded
/// value, the floor by the box darker, nothing outside the charts and gutter;
/// meshes without UVs, overlapping charts and bad sizes are clear errors.
#[test]
fn bake_texels_writes_a_lightmap_of_the_uv_atlas() {
    let dir = scratch("bake-texels");
    let obj = dir.join("floor-box.obj");
    std::fs::write(&obj, floor_and_box_obj(false)).unwrap();
    let exr_path = dir.join("floor-box.exr");
    let output = antumbra(&[
        "bake",
        "--kind",
        "diffuse",
        "--bands",
        "4",
        "--rays",
        "1024",
        "--texels",
        "64x32",
        "--mesh",
        obj.to_str().unwrap(),
        "-o",
        exr_path.to_str().unwrap(),
    ]);
    assert_success(&output);
    assert!(
        stdout(&output).contains("out of geometry"),
        "{}",
        stdout(&output)
    );
    use exr::prelude::*;
    let image = read_all_flat_layers_from_file(&exr_path).unwrap();
    let layer = &image.layer_data[0];
    assert_eq!((layer.size.0, layer.size.1), (64, 32));
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let expected: Vec<String> = (0..16).map(|j| format!("T.{j:02}")).collect();
    assert_eq!(names, expected);
    // Texel (x, y) is at image row 31 - y.
    let dc = |x: usize, y: usize| match &layer.channel_data.list[0].sample_data {
        FlatSamples::F32(samples) => samples[(31 - y) * 64 + x],
        other => panic!("{other:?}"),
    };
    // The floor's corner sees nearly the whole sky: Y00 π = 0.886 unoccluded.
    let corner = dc(0, 0);
    assert!(corner > 0.82 && corner < 0.9, "{corner}");
    // Beside the box's wall (floor x = 0.31..0.38, the texel after the wall's).
    let beside = dc(21, 16);
    println!("lightmap DC: open floor {corner}, beside the box {beside}");
    assert!(
        beside < corner - 0.1,
        "{beside} by the box, {corner} in the open"
    );
    // Above and right of the box's charts, beyond the gutter: nothing baked.
    assert_eq!(dc(62, 30), 0.0);
    // Every value finite.
    for channel in &layer.channel_data.list {
        let FlatSamples::F32(samples) = &channel.sample_data else {
            panic!()
        };
        assert!(samples.iter().all(|v| v.is_finite()));
    }

    let bare = dir.join("no-uv.obj");
    std::fs::write(&bare, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let output = antumbra(&[
        "bake",
        "--kind",
        "diffuse",
        "--texels",
        "16",
        "--mesh",
        bare.to_str().unwrap(),
        "-o",
        dir.join("x.exr").to_str().unwrap(),
    ]);
    assert!(!output.status.success());
    assert!(
        stderr(&output).contains("texture coordinates"),
        "{}",
        stderr(&output)
    );
    let overlapping = dir.join("overlap.obj");
    std::fs::write(&overlapping, floor_and_box_obj(true)).unwrap();
    let output = antumbra(&[
        "bake",
        "--kind",
        "diffuse",
        "--texels",
        "64x32",
        "--mesh",
        overlapping.to_str().unwrap(),
        "-o",
        dir.join("y.exr").to_str().unwrap(),
    ]);
    assert!(!output.status.success());
    assert!(stderr(&output).contains("overlap"), "{}", stderr(&output));
    assert!(!dir.join("y.exr").exists());
    for bad in ["0", "16x0", "20000", "axb"] {
        let output = antumbra(&[
            "bake",
            "--kind",
            "diffuse",
            "--texels",
            bad,
            "--mesh",
            obj.to_str().unwrap(),
            "-o",
            dir.join("z.exr").to_str().unwrap(),
        ]);
        assert!(!output.status.success(), "--texels {bad}");
        assert!(
            stderr(&output).contains("atlas side"),
            "{}",
            stderr(&output)
        );
    }
}

/// `bake --texels` into a bake file: version 3 with the atlas's texels; three
/// `--shard` parts merge into it byte for byte (with a bounce, which reads
/// every texel); a part of another atlas size is refused; `render --bake`
/// shades it into a lightmap texture and a picture of the mesh; a mesh whose
/// UVs differ is refused.
#[test]
fn texel_bakes_shard_merge_and_render() {
    let dir = scratch("bake-texels-file");
    let obj = dir.join("floor-box.obj");
    std::fs::write(&obj, floor_and_box_obj(false)).unwrap();
    let bake = |out: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "bake",
            "--kind",
            "diffuse",
            "--bands",
            "3",
            "--rays",
            "32",
            "--bounces",
            "1",
            "--texels",
            "32x16",
            "--mesh",
            obj.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let output = antumbra(&args);
        assert_success(&output);
        output
    };
    let whole = dir.join("whole.xfer");
    let output = bake(&whole, &[]);
    assert!(stdout(&output).contains("version 3"), "{}", stdout(&output));
    let whole_bytes = std::fs::read(&whole).unwrap();
    let set = antumbra_core::transfer::TransferSet::from_bytes(&whole_bytes).unwrap();
    let texels = set.texels().expect("a texel bake file carries its texels");
    assert_eq!((texels.width(), texels.height()), (32, 16));
    assert_eq!(texels.texels().len(), set.vertex_count());

    let parts: Vec<std::path::PathBuf> = (0..3)
        .map(|i| {
            let part = dir.join(format!("part{i}.xpart"));
            bake(&part, &["--shard", &format!("{i}/3")]);
            part
        })
        .collect();
    let merged = dir.join("merged.xfer");
    let mut args = vec!["merge", "-o", merged.to_str().unwrap()];
    args.extend(parts.iter().rev().map(|p| p.to_str().unwrap()));
    assert_success(&antumbra(&args));
    assert!(
        std::fs::read(&merged).unwrap() == whole_bytes,
        "merged parts differ from the whole bake"
    );
    // Merged straight into OpenEXR: the image the whole bake writes.
    let merged_exr = dir.join("merged.exr");
    let mut args = vec!["merge", "-o", merged_exr.to_str().unwrap()];
    args.extend(parts.iter().map(|p| p.to_str().unwrap()));
    assert_success(&antumbra(&args));
    let whole_exr = dir.join("whole.exr");
    bake(&whole_exr, &[]);
    {
        use exr::prelude::*;
        let read = |path: &std::path::Path| {
            let image = read_all_flat_layers_from_file(path).unwrap();
            let layer = &image.layer_data[0];
            layer
                .channel_data
                .list
                .iter()
                .map(|c| match &c.sample_data {
                    FlatSamples::F32(samples) => samples.clone(),
                    other => panic!("{other:?}"),
                })
                .collect::<Vec<_>>()
        };
        assert!(
            read(&merged_exr) == read(&whole_exr),
            "merged OpenEXR differs"
        );
    }
    // A part of a lightmap of another size does not join.
    let other = dir.join("other.xpart");
    let mut args = vec![
        "bake",
        "--kind",
        "diffuse",
        "--bands",
        "3",
        "--rays",
        "32",
        "--bounces",
        "1",
        "--texels",
        "32x32",
        "--shard",
        "2/3",
        "--mesh",
        obj.to_str().unwrap(),
        "-o",
        other.to_str().unwrap(),
    ];
    assert_success(&antumbra(&args));
    args.clear();
    args.extend(["merge", "-o", "never.xfer"]);
    args.extend(parts[..2].iter().map(|p| p.to_str().unwrap()));
    args.push(other.to_str().unwrap());
    let output = antumbra(&args);
    assert!(!output.status.success());
    assert!(
        stderr(&output).contains("different bakes"),
        "{}",
        stderr(&output)
    );

    let picture = dir.join("relit.png");
    let output = antumbra(&[
        "render",
        "--mesh",
        obj.to_str().unwrap(),
        "--bake",
        whole.to_str().unwrap(),
        "--size",
        "96",
        "--out",
        picture.to_str().unwrap(),
    ]);
    assert_success(&output);
    assert!(picture.exists());
    use exr::prelude::*;
    let texture = read_all_flat_layers_from_file(dir.join("relit-lightmap.exr")).unwrap();
    let layer = &texture.layer_data[0];
    assert_eq!((layer.size.0, layer.size.1), (32, 16));
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(names, ["B", "G", "R"]);
    let FlatSamples::F32(red) = &layer.channel_data.list[2].sample_data else {
        panic!("32-bit red")
    };
    // The open floor's corner (texel (0, 0), image row 15) is lit; texels
    // beyond the charts and gutter stay 0.
    assert!(red[15 * 32] > 0.0, "{}", red[15 * 32]);
    assert_eq!(red[31], 0.0);

    // The same mesh with its UVs moved: not the lightmap's texels.
    let moved = dir.join("moved.obj");
    let text = floor_and_box_obj(false).replace("vt 0.5 ", "vt 0.45 ");
    assert_ne!(text, floor_and_box_obj(false));
    std::fs::write(&moved, text).unwrap();
    let output = antumbra(&[
        "render",
        "--mesh",
        moved.to_str().unwrap(),
        "--bake",
        whole.to_str().unwrap(),
        "--out",
        dir.join("never.png").to_str().unwrap(),
    ]);
    assert!(!output.status.success());
    assert!(
        stderr(&output).contains("another mesh or UV set"),
        "{}",
        stderr(&output)
    );
}
