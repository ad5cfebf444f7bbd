//! Hemispherical rasterization masks against Embree 4: for receivers at mesh
//! vertices, every valid cell's ray is cast by Embree and compared with the exact
//! and table masks.
//!
//! Run: `make test`, or `cargo test -p antumbra-tests --test embree_hemi -- --nocapture`
//! after `tests/oracle/setup_venv.sh target/pyenv`.
//!
//! Receivers: a few hundred vertices, evenly spaced in index order, with
//! area-weighted vertex normals (the sum of the incident triangles' unnormalised
//! geometric normals, normalised). The center of projection is lifted off the
//! surface: `o = p + 1e-3 * diag * n`, `diag` the bounding box diagonal, as a ray
//! tracer would offset a secondary ray; rays start exactly there (t in (0, +inf)).
//!
//! Thresholds (from the issue): the exact masks must agree with Embree on
//! ≥ 99.99 % of cells, and every disagreement must lie within a tiny angle of an
//! edge plane of a triangle the direction nearly touches (where rounding of the
//! corners, the frame or the ray decides, see `near_an_edge`); the default table
//! quality (the octant table with its exact short and long edges, see
//! `HalfSpaceTable`) must agree on ≥ 99.5 % on all four meshes: the bunny, the
//! teapot (open), the Stanford armadillo (52,000 triangles, most under two
//! degrees across from its vertices) and a random soup (every edge a
//! silhouette). Other table sizes, and the pure table (the paper's method, no
//! exact edges), are reported, not asserted.
//!
//! Measured: exact 100 % on all four; the default table (2 MiB) 99.955 % (bunny),
//! 99.974 % (teapot), 99.966 % (armadillo), 99.866 % (soup); the pure 2 MiB table
//! 99.79 / 99.87 / 97.49 / 99.08 %. The full table is in
//! `HalfSpaceTable::DEFAULT_RESOLUTION`'s docs.

use antumbra_core::hemi::{
    BatchOptions, HalfSpaceTable, HemiMask, HemiScene, Quality, RasterOptions, Receiver,
    TriangleClusters, VALID_CELL_COUNT, cell_directions, rasterize_receiver, scene_mask,
};
use antumbra_core::{MeshView, Ray};
use antumbra_tests::data::{Mesh, load_obj};
use antumbra_tests::oracle;
use antumbra_tests::scenes::triangle_soup;
use glam::{DVec3, Vec3};
use rand::SeedableRng;
use rand::rngs::SmallRng;

const RECEIVERS: usize = 300;
const EXACT_REQUIRED: f64 = 0.9999;
const TABLE_REQUIRED: f64 = 0.995;
/// Angle (radians) from an edge plane within which a disagreement is a rounding tie.
const EDGE_EPS: f64 = 1e-5;
/// Table resolutions reported besides the default, each with its default exact
/// edges and as a pure table.
const OTHER_TABLES: [u32; 7] = [32, 45, 64, 91, 128, 181, 256];

/// Area-weighted vertex normals; `None` where they cancel out.
fn vertex_normals(mesh: &Mesh) -> Vec<Option<Vec3>> {
    let mut sums = vec![Vec3::ZERO; mesh.positions.len()];
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(mesh.positions[t[k] as usize]));
        let n = (b - a).cross(c - a);
        for &v in t {
            sums[v as usize] += n;
        }
    }
    sums.into_iter().map(|n| n.try_normalize()).collect()
}

/// Whether world direction `dir` from `origin` lies near an edge plane of a
/// triangle whose cone, widened by the same tolerance, contains it.
///
/// The tolerance of an edge is `EDGE_EPS` plus the tilt that rounding coordinates
/// of magnitude `scale` by a few ulps gives its plane,
/// `32 · 2⁻²⁴ · scale / (distance from origin to the edge's line)`; it is below
/// 1e-6 unless the center of projection sits almost on the edge.
fn near_an_edge(view: &MeshView<'_>, origin: Vec3, dir: Vec3, scale: f64) -> bool {
    let d = dir.as_dvec3().normalize();
    let o = origin.as_dvec3();
    view.triangles().any(|t| {
        let [a, b, c] = t.map(|p| p.as_dvec3() - o);
        let sign = if a.cross(b).dot(c) < 0.0 { -1.0 } else { 1.0 };
        let mut inside = true;
        let mut near = false;
        for (p, q) in [(a, b), (b, c), (c, a)] {
            let n: DVec3 = p.cross(q);
            let length = n.length().max(f64::MIN_POSITIVE);
            let line_distance = length / (q - p).length().max(f64::MIN_POSITIVE);
            let tolerance = EDGE_EPS + 16.0 * f64::from(f32::EPSILON) * scale / line_distance;
            let s = sign * n.dot(d) / length;
            inside &= s >= -tolerance;
            near |= s.abs() <= tolerance;
        }
        inside && near
    })
}

#[derive(Default)]
struct Agreement {
    cells: u64,
    differ: u64,
    unexplained: Vec<String>,
}

impl Agreement {
    fn fraction(&self) -> f64 {
        1.0 - self.differ as f64 / self.cells.max(1) as f64
    }
}

fn compare(name: &str, mesh: &Mesh) {
    let view = mesh.view();
    let (lo, hi) = mesh.bounds();
    let diag = (hi - lo).length();
    let offset = 1e-3 * diag;
    let scale = f64::from(lo.abs().max(hi.abs()).max_element());
    let normals = vertex_normals(mesh);
    let candidates: Vec<usize> = (0..mesh.positions.len())
        .filter(|&v| normals[v].is_some())
        .collect();
    let step = (candidates.len() / RECEIVERS).max(1);
    let receivers: Vec<(Vec3, Vec3)> = candidates
        .iter()
        .step_by(step)
        .take(RECEIVERS)
        .map(|&v| (Vec3::from(mesh.positions[v]), normals[v].unwrap()))
        .collect();

    // Every valid cell's ray, receiver by receiver, in cell_directions() order.
    let mut rays: Vec<Ray> = Vec::with_capacity(receivers.len() * VALID_CELL_COUNT as usize);
    for &(p, n) in &receivers {
        let receiver = Receiver::new(p, n, offset);
        rays.extend(cell_directions().map(|(i, j, _)| receiver.cell_ray(i, j).unwrap()));
    }
    let embree = oracle::cast(mesh, &rays, false);
    let embree_masks: Vec<HemiMask> = embree
        .chunks_exact(VALID_CELL_COUNT as usize)
        .map(|hits| {
            let mut mask = HemiMask::EMPTY;
            for ((i, j, _), hit) in cell_directions().zip(hits) {
                mask.set(i, j, hit.occluded);
            }
            mask
        })
        .collect();

    let default_table = HalfSpaceTable::default();
    let other_tables: Vec<(String, HalfSpaceTable)> = OTHER_TABLES
        .iter()
        .flat_map(|&r| {
            let table = HalfSpaceTable::new(r);
            let size = table.size_bytes() as f64 / 1024.0;
            [
                (format!("table-{r} ({size:.0} KiB)"), table.clone()),
                (
                    format!("pure-table-{r} ({size:.0} KiB)"),
                    table.with_exact_edges(0.0, f32::INFINITY),
                ),
            ]
        })
        .collect();
    let mut qualities: Vec<(String, Quality<'_>)> = vec![
        ("exact".into(), Quality::Exact),
        ("table".into(), Quality::Table(&default_table)),
    ];
    qualities.extend(
        other_tables
            .iter()
            .map(|(name, t)| (name.clone(), Quality::Table(t))),
    );

    let mut results = Vec::new();
    for (quality_name, quality) in &qualities {
        let options = RasterOptions {
            quality: *quality,
            normal_offset: offset,
            ..RasterOptions::default()
        };
        let mut agreement = Agreement::default();
        for (&(p, n), reference) in receivers.iter().zip(&embree_masks) {
            let ours = rasterize_receiver(&view, p, n, &options);
            agreement.cells += u64::from(VALID_CELL_COUNT);
            let differ = ours ^ *reference;
            agreement.differ += u64::from(differ.count_occluded());
            if matches!(quality, Quality::Exact) {
                let receiver = Receiver::new(p, n, offset);
                for (i, j) in differ.occluded_cells() {
                    let ray = receiver.cell_ray(i, j).unwrap();
                    if !near_an_edge(&view, ray.origin, ray.direction, scale) {
                        agreement.unexplained.push(format!(
                            "receiver {p} n {n}, cell ({i}, {j}): ours {}, embree {}",
                            ours.get(i, j),
                            reference.get(i, j)
                        ));
                    }
                }
            }
        }
        println!(
            "{name}: hemi {quality_name} agreement: {:.4}% of {} cells, {} receivers \
             ({} cells differ{})",
            100.0 * agreement.fraction(),
            agreement.cells,
            receivers.len(),
            agreement.differ,
            if matches!(quality, Quality::Exact) {
                format!(
                    ", {} not within {EDGE_EPS:e} rad of an edge plane",
                    agreement.unexplained.len()
                )
            } else {
                String::new()
            }
        );
        for line in agreement.unexplained.iter().take(10) {
            println!("  unexplained: {line}");
        }
        results.push((quality_name.clone(), agreement));
    }
    // The per-receiver traversal of the cluster hierarchy (what the batch
    // calls and the shader run) sets the plain loop's bits, so Embree's.
    let mut clusters = TriangleClusters::new(&view, TriangleClusters::DEFAULT_SIZE);
    let scene = HemiScene::new(clusters.update(view));
    let options = BatchOptions {
        normal_offset: offset,
        ..BatchOptions::default()
    };
    let exact_options = RasterOptions {
        normal_offset: offset,
        ..RasterOptions::default()
    };
    for &(p, n) in &receivers {
        assert_eq!(
            scene_mask(&scene, p, n, &options),
            rasterize_receiver(&view, p, n, &exact_options),
            "{name}: the traversal's mask at receiver {p} differs from the plain loop's"
        );
    }
    println!(
        "{name}: hemi traversal: the plain loop's exact masks at all {} receivers",
        receivers.len()
    );
    let (_, exact) = &results[0];
    let (_, table) = &results[1];
    assert!(
        exact.fraction() >= EXACT_REQUIRED,
        "{name}: exact agreement {} below {EXACT_REQUIRED}",
        exact.fraction()
    );
    assert!(
        exact.unexplained.is_empty(),
        "{name}: exact disagreements away from every edge plane"
    );
    assert!(
        table.fraction() >= TABLE_REQUIRED,
        "{name}: table ({}) agreement {} below {TABLE_REQUIRED}",
        default_table.resolution(),
        table.fraction()
    );
}

#[test]
fn bunny_masks_agree_with_embree() {
    compare("bunny", &load_obj("bunny.obj"));
}

#[test]
fn teapot_masks_agree_with_embree() {
    compare("teapot", &load_obj("teapot.obj"));
}

#[test]
fn armadillo_masks_agree_with_embree() {
    compare("armadillo", &load_obj("armadillo.obj"));
}

#[test]
fn random_soup_masks_agree_with_embree() {
    let mut rng = SmallRng::seed_from_u64(0x4e41);
    compare("triangle soup", &triangle_soup(&mut rng, 5000, 0.3));
}
