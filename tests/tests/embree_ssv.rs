//! Soft shadow visibility bits (`antumbra_core::ssv`, the default lazy hierarchy)
//! against Embree 4 occlusion rays: the bunny, the armadillo (52,000 triangles)
//! and the open Utah teapot over a floor under a quad light, 256 light samples;
//! and the bunny and the armadillo over a ground of receivers wider than the
//! default root box ([`GroundScene`], the layout of `bench ssv --frame`), under
//! lights of both sizes in every orientation, queried as a batch.
//!
//! Run: `make test`, or `cargo test -p antumbra-tests --test embree_ssv -- --nocapture`
//! after `tests/oracle/setup_venv.sh target/pyenv`.
//!
//! Scene and receivers: [`FloorScene`] (the same as `antumbra verify ssv` and
//! `antumbra bench ssv`): floor receivers exactly on the floor's triangles and
//! mesh vertices lifted 1e-3 along their normals; every light orientation on the
//! bunny, two on the teapot, one on the armadillo (whose lazy hierarchy grows to
//! hundreds of MiB over a thousand receivers, so it gets fewer). Each (receiver,
//! sample) bit is compared with Embree's occlusion ray over the open segment (see
//! `antumbra_tests::ssv`).
//!
//! Threshold (the acceptance): mismatches ≤ 1e-5 of all bits per mesh,
//! each one explained: the library agrees with the exact segment–triangle test
//! (so Embree's `f32` rounding decided) and the segment passes within 1e-5 of the
//! scene size of a triangle edge. A mismatch where the library disagrees with the
//! exact test fails the test. The brute-force structure must give the same bits
//! as the hierarchy on a subset of receivers.

use antumbra_core::MeshView;
use antumbra_core::ssv::{LightPolygon, SamplePattern, SoftShadows, SsvOptions, Structure};
use antumbra_tests::data::load_obj;
use antumbra_tests::scenes::{FloorScene, GroundScene, LightOrientation, LightSize};
use antumbra_tests::ssv::{Comparison, GRAZING_OF_SCENE, compare_with_embree, library_bits};

const SAMPLES: usize = 256;
/// Receivers compared with brute force (the first ones: floor grid points).
const BRUTE_FORCE_SUBSET: usize = 60;

fn soft_shadows(scene: &FloorScene, structure: Structure) -> SoftShadows {
    let light = LightPolygon::new(&scene.light).expect("the scene's light is a valid quad");
    let samples = light.samples(SAMPLES, SamplePattern::Jittered, 0x55f);
    let view: MeshView<'_> = scene.occluders.view();
    let options = SsvOptions {
        structure,
        ..SsvOptions::default()
    };
    SoftShadows::new(&view, light, &samples, options).expect("the scene is valid")
}

fn check(name: &str, obj: &str, orientations: &[LightOrientation], grid: usize, points: usize) {
    let mesh = load_obj(obj);
    let mut total = Comparison::default();
    let mut rows = Vec::new();
    for &orientation in orientations {
        let scene = FloorScene::new(&mesh.positions, &mesh.indices, orientation, grid, points);
        let receivers = scene.receivers();
        let ssv = soft_shadows(&scene, Structure::Hierarchy);
        let comparison = compare_with_embree(&scene.occluders, &ssv, &receivers)
            .unwrap_or_else(|e| panic!("{e}"));
        let brute = soft_shadows(&scene, Structure::BruteForce);
        let subset = &receivers[..BRUTE_FORCE_SUBSET.min(receivers.len())];
        let words = ssv.words_per_receiver();
        let hierarchy_bits = library_bits(&ssv, &receivers).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            library_bits(&brute, subset).unwrap_or_else(|e| panic!("{e}")),
            hierarchy_bits[..subset.len() * words],
            "{name}, light {}: brute force and hierarchy differ",
            orientation.name()
        );
        let stats = ssv.statistics();
        rows.push(format!(
            "{name}, light {}: {} receivers ({} on the floor, {} on the mesh), {} bits, {:.2} % visible, \
             {} mismatches; hierarchy {} nodes, {} KiB",
            orientation.name(),
            comparison.receivers,
            scene.floor_receivers.len(),
            scene.mesh_receivers.len(),
            comparison.bits,
            100.0 * comparison.visible_bits as f64 / comparison.bits as f64,
            comparison.mismatches.len(),
            stats.nodes,
            stats.bytes / 1024
        ));
        total.merge(comparison);
    }
    report(name, &rows, &total);
    assert!(
        total.visible_bits > total.bits / 10 && total.visible_bits < total.bits * 9 / 10,
        "{name}: the scene should be partly shadowed to mean anything"
    );
}

/// The ground frames of `obj`: every light size and orientation, `grid`²
/// ground receivers and up to `points` on the mesh, queried as one batch
/// (`query_batch`, so the hierarchy is built by `prepare`, through its shells
/// beyond the root), against Embree, and against brute force and the
/// hemicube on every receiver.
fn check_ground(name: &str, obj: &str, grid: usize, points: usize) {
    let mesh = load_obj(obj);
    let mut total = Comparison::default();
    let mut rows = Vec::new();
    for size in LightSize::ALL {
        for orientation in LightOrientation::ALL {
            let scene = GroundScene::new(
                &mesh.positions,
                &mesh.indices,
                orientation,
                size,
                grid,
                points,
            );
            let receivers = scene.receivers();
            let light = LightPolygon::new(&scene.light).expect("a valid quad");
            let samples = light.samples(SAMPLES, SamplePattern::Jittered, 0x55f);
            let build = |structure| {
                let options = SsvOptions {
                    structure,
                    ..SsvOptions::default()
                };
                SoftShadows::new(&scene.occluders.view(), light.clone(), &samples, options)
                    .expect("the scene is valid")
            };
            let bits_of = |ssv: &SoftShadows| {
                let mut bits = vec![0u64; receivers.len() * ssv.words_per_receiver()];
                ssv.query_batch(&receivers, &mut bits, None, true)
                    .expect("valid receivers");
                bits
            };
            let hierarchy = build(Structure::Hierarchy);
            let bits = bits_of(&hierarchy);
            for structure in [Structure::BruteForce, Structure::Hemicube] {
                assert_eq!(
                    bits_of(&build(structure)),
                    bits,
                    "{name}, light {} {}: {structure:?} and the hierarchy differ",
                    size.name(),
                    orientation.name()
                );
            }
            let comparison = compare_with_embree(&scene.occluders, &hierarchy, &receivers)
                .unwrap_or_else(|e| panic!("{e}"));
            let stats = hierarchy.statistics();
            rows.push(format!(
                "{name}, light {} {}: {} receivers ({} on the ground, {} on the mesh), {} bits, \
                 {:.2} % visible, {} mismatches; hierarchy {} nodes, {} KiB",
                size.name(),
                orientation.name(),
                comparison.receivers,
                scene.ground_receivers.len(),
                scene.mesh_receivers.len(),
                comparison.bits,
                100.0 * comparison.visible_bits as f64 / comparison.bits as f64,
                comparison.mismatches.len(),
                stats.nodes,
                stats.bytes / 1024
            ));
            total.merge(comparison);
        }
    }
    report(name, &rows, &total);
    // The ground is mostly lit; some of it must be shadowed to mean anything.
    assert!(
        total.visible_bits < total.bits * 99 / 100 && total.visible_bits > total.bits / 2,
        "{name}: the ground should be partly shadowed to mean anything"
    );
}

/// Prints the rows and the mismatches, and checks the acceptance.
fn report(name: &str, rows: &[String], total: &Comparison) {
    for row in rows {
        println!("{row}");
    }
    let fraction = total.mismatches.len() as f64 / total.bits as f64;
    println!(
        "{name}: ssv agreement {:.6} % of {} bits, {} mismatches ({fraction:.2e} of the bits), \
         {} where the library agrees with the exact test and the segment grazes an edge \
         (farthest {:.2e} of the scene size from it; grazing means ≤ {GRAZING_OF_SCENE:e}), \
         {} library errors",
        100.0 * total.agreement(),
        total.bits,
        total.mismatches.len(),
        total
            .mismatches
            .iter()
            .filter(|m| m.is_grazing(total.scale))
            .count(),
        total.worst_edge_distance(),
        total.library_errors().count(),
    );
    for m in total.mismatches.iter().take(20) {
        println!(
            "  receiver {} {:?} sample {} {:?}: library {}, exact {}, Embree {}, triangle {:?}, edge distance {:.3e}",
            m.receiver,
            m.point,
            m.sample,
            m.target,
            vis(m.library),
            vis(m.exact),
            vis(!m.library),
            m.triangle,
            m.edge_distance
        );
    }
    assert_eq!(
        total.library_errors().count(),
        0,
        "{name}: the library disagrees with the exact segment test"
    );
    assert!(
        total.passes(),
        "{name}: mismatches above 1e-5 of the bits or not explained as grazing"
    );
}

fn vis(visible: bool) -> &'static str {
    if visible { "visible" } else { "blocked" }
}

#[test]
fn bunny_over_a_floor_agrees_with_embree() {
    check("bunny", "bunny.obj", &LightOrientation::ALL, 20, 400);
}

#[test]
fn armadillo_over_a_floor_agrees_with_embree() {
    check(
        "armadillo",
        "armadillo.obj",
        &[LightOrientation::Tilted],
        16,
        300,
    );
}

#[test]
fn open_teapot_over_a_floor_agrees_with_embree() {
    check(
        "teapot",
        "teapot.obj",
        &[LightOrientation::Side, LightOrientation::Horizontal],
        20,
        400,
    );
}

#[test]
fn bunny_over_a_wide_ground_agrees_with_embree() {
    check_ground("bunny on the ground", "bunny.obj", 40, 300);
}

#[test]
fn armadillo_over_a_wide_ground_agrees_with_embree() {
    check_ground("armadillo on the ground", "armadillo.obj", 24, 200);
}
