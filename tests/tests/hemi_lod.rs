//! Deforming-mesh batches on the Stanford bunny: cluster culling changes no bit,
//! with or without a far mesh, over frames of a twisting deformation; and the far
//! mesh's effect on the transfer vectors, measured against the full mesh.
//!
//! Run: `cargo test -p antumbra-tests --test hemi_lod -- --nocapture`.
//!
//! The far mesh is a vertex clustering of the bunny (Rossignac–Borrel: vertices
//! snapped to the mean of their cell of a 12³ grid over the rest pose's bounds,
//! collapsed triangles dropped), deformed with the same twist as the full mesh. The
//! near radius is a tenth of the bounding diagonal; the normal offset 1e-3 of it.

use antumbra_core::MeshView;
use antumbra_core::hemi::{
    BatchOptions, ClusteredMesh, HemiScene, TransferMethod, TransferSpace, TransferTable,
    TriangleClusters, transfer_batch, vertex_normals,
};
use antumbra_core::sh::Sh;
use antumbra_tests::data::load_obj;
use glam::{Quat, Vec3};
use std::collections::HashMap;

const N: usize = 9;

/// Vertex clustering on a `cells³` grid (see the module docs): the far positions,
/// the far triangles, and for each full vertex its far vertex (for deforming the
/// far mesh along with the full one).
fn vertex_clustering(
    positions: &[[f32; 3]],
    indices: &[u32],
    cells: u32,
) -> (Vec<[f32; 3]>, Vec<u32>) {
    let (lo, hi) = positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p.into()), hi.max(p.into()))
        });
    let size = (hi - lo) / cells as f32;
    let mut ids = HashMap::new();
    let mut sums: Vec<(Vec3, f32)> = Vec::new();
    let cluster: Vec<u32> = positions
        .iter()
        .map(|&p| {
            let c = ((Vec3::from(p) - lo) / size)
                .floor()
                .min(Vec3::splat(cells as f32 - 1.0));
            let key = (c.x as u32 * cells + c.y as u32) * cells + c.z as u32;
            let next = sums.len() as u32;
            let id = *ids.entry(key).or_insert(next);
            if id == next {
                sums.push((Vec3::ZERO, 0.0));
            }
            sums[id as usize].0 += Vec3::from(p);
            sums[id as usize].1 += 1.0;
            id
        })
        .collect();
    let far_positions = sums.iter().map(|(s, n)| (*s / *n).to_array()).collect();
    let far_indices = indices
        .chunks_exact(3)
        .map(|t| [0, 1, 2].map(|k| cluster[t[k] as usize]))
        .filter(|[a, b, c]| a != b && b != c && c != a)
        .flatten()
        .collect();
    (far_positions, far_indices)
}

/// A twist about the vertical (y) axis through `center`, `turns` radians per unit
/// of height.
fn twisted(positions: &[[f32; 3]], center: Vec3, turns: f32) -> Vec<[f32; 3]> {
    positions
        .iter()
        .map(|&p| {
            let p = Vec3::from(p) - center;
            (center + Quat::from_rotation_y(turns * p.y) * p).to_array()
        })
        .collect()
}

#[test]
fn bunny_clusters_change_no_bit_and_far_mesh_error_is_reported() {
    let bunny = load_obj("bunny.obj");
    let (lo, hi) = bunny.bounds();
    let diagonal = (hi - lo).length();
    let center = 0.5 * (lo + hi);
    let (far_rest, far_indices) = vertex_clustering(&bunny.positions, &bunny.indices, 12);
    println!(
        "far mesh: {} triangles for the bunny's {}",
        far_indices.len() / 3,
        bunny.indices.len() / 3
    );
    let table = TransferTable::<N>::new();
    let method = TransferMethod::Cells(&table);
    let options = BatchOptions {
        normal_offset: 1e-3 * diagonal,
        ..BatchOptions::default()
    };
    let near_radius = 0.1 * diagonal;
    let mut clusters = TriangleClusters::new(&bunny.view(), TriangleClusters::DEFAULT_SIZE);
    let mut far_clusters = TriangleClusters::new(
        &MeshView::new(&far_rest, &far_indices).unwrap(),
        TriangleClusters::DEFAULT_SIZE,
    );
    let count = bunny.positions.len();
    for (frame, turns) in [0.0f32, 0.08].into_iter().enumerate() {
        let positions = twisted(&bunny.positions, center, turns);
        let far_positions = twisted(&far_rest, center, turns);
        let mesh = MeshView::new(&positions, &bunny.indices).unwrap();
        let far = MeshView::new(&far_positions, &far_indices).unwrap();
        let mut normals = vec![Vec3::ZERO; count];
        vertex_normals(&mesh, &mut normals).unwrap();

        let fast_mesh = clusters.update(mesh);
        let fast_far = far_clusters.update(far);
        let scenes = [
            (
                "full, plain",
                HemiScene::new(ClusteredMesh::unclustered(mesh)),
            ),
            ("full, clusters", HemiScene::new(fast_mesh)),
            (
                "far, plain",
                HemiScene::with_far(
                    ClusteredMesh::unclustered(mesh),
                    ClusteredMesh::unclustered(far),
                    near_radius,
                ),
            ),
            (
                "far, clusters",
                HemiScene::with_far(fast_mesh, fast_far, near_radius),
            ),
        ];
        let results: Vec<Vec<Sh<N>>> = scenes
            .iter()
            .map(|(_, scene)| {
                let mut out = vec![Sh::<N>::ZERO; count];
                transfer_batch(
                    scene,
                    &normals,
                    &options,
                    method,
                    TransferSpace::World,
                    &mut out,
                )
                .unwrap();
                out
            })
            .collect();
        assert!(
            results[0] == results[1],
            "frame {frame}: clusters changed the full-mesh transfer"
        );
        assert!(
            results[2] == results[3],
            "frame {frame}: clusters changed the far-mesh transfer"
        );

        // The far mesh's effect: relative L2 difference per vertex against the full
        // mesh, over vertices with a usable normal.
        let mut errors: Vec<f64> = results[0]
            .iter()
            .zip(&results[2])
            .filter(|(full, _)| full.coeffs.iter().any(|&c| c != 0.0))
            .map(|(full, lod)| {
                let squared =
                    |v: &Sh<N>| v.coeffs.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>();
                (squared(&(*lod - *full)) / squared(full)).sqrt()
            })
            .collect();
        errors.sort_by(f64::total_cmp);
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        println!(
            "frame {frame} (twist {turns} rad per unit height): far mesh vs full mesh transfer, \
             {} vertices: mean {:.2}%, median {:.2}%, p90 {:.2}%, max {:.2}%",
            errors.len(),
            100.0 * mean,
            100.0 * errors[errors.len() / 2],
            100.0 * errors[errors.len() * 9 / 10],
            100.0 * errors[errors.len() - 1],
        );
        // A regression bound, not an accuracy claim: a broken near/far rule (the
        // far surface shadowing the near one) gives tens of percent.
        assert!(mean < 0.05, "far mesh mean difference {mean}");
    }
}
