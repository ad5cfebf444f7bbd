use alloc::vec;
use alloc::vec::Vec;

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng, rngs::SmallRng};

use super::*;
use crate::raycast::BruteForceCaster;

/// A flat grid mesh in the z = 0 plane whose UVs equal its (x, y): `cells` ×
/// `cells` quads over `[lo, hi]²`, each split along a random diagonal and with
/// a random winding (mirrored charts face the other way).
fn grid(
    cells: usize,
    lo: f32,
    hi: f32,
    rng: &mut SmallRng,
) -> (Vec<[f32; 3]>, Vec<u32>, Vec<[f32; 2]>) {
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for j in 0..=cells {
        for i in 0..=cells {
            let u = lo + (hi - lo) * i as f32 / cells as f32;
            let v = lo + (hi - lo) * j as f32 / cells as f32;
            positions.push([u, v, 0.0]);
            uvs.push([u, v]);
        }
    }
    let at = |i: usize, j: usize| (j * (cells + 1) + i) as u32;
    let mut indices = Vec::new();
    for j in 0..cells {
        for i in 0..cells {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            let triangles = if rng.random_bool(0.5) {
                [[a, b, c], [a, c, d]]
            } else {
                [[a, b, d], [b, c, d]]
            };
            for mut t in triangles {
                if rng.random_bool(0.5) {
                    t.swap(1, 2);
                }
                indices.extend(t);
            }
        }
    }
    (positions, indices, uvs)
}

fn up_normals(count: usize) -> Vec<Vec3> {
    vec![Vec3::Z; count]
}

/// Grid lines through texel centres put centres exactly on edges and
/// vertices: each centre inside the grid belongs to exactly one triangle
/// whatever the diagonals and windings, and none outside it.
#[test]
fn centres_on_shared_edges_and_vertices_belong_to_one_triangle() {
    let mut rng = SmallRng::seed_from_u64(1);
    for round in 0..20 {
        let side = 16u32;
        // Lines at u = (k + 1/2) / 16 for k = 2..=13: every vertex a centre.
        let (lo, hi) = (2.5 / 16.0, 13.5 / 16.0);
        let (positions, indices, uvs) = grid(11, lo, hi, &mut rng);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let atlas = TexelAtlas::new(
            &mesh,
            &uvs,
            &up_normals(positions.len()),
            &AtlasOptions::new(side, side),
        )
        .unwrap_or_else(|e| panic!("round {round}: {e}"));
        // The grid's border runs through the centres of texel rows and columns
        // 2 and 13: the fill rule gives one side of each border to the chart,
        // so 11 x 11 centres in a block, and the rest of [2, 13]² touched.
        let centres: Vec<[u32; 2]> = atlas
            .receivers()
            .iter()
            .filter(|r| r.coverage == Coverage::Centre)
            .map(|r| r.texel)
            .collect();
        assert_eq!(centres.len(), 121, "round {round}");
        let (lo_x, lo_y) = (centres[0][0], centres[0][1]);
        assert!([2, 3].contains(&lo_x) && [2, 3].contains(&lo_y));
        let block: Vec<[u32; 2]> = (lo_y..lo_y + 11)
            .flat_map(|y| (lo_x..lo_x + 11).map(move |x| [x, y]))
            .collect();
        assert_eq!(centres, block, "round {round}");
        let all: Vec<[u32; 2]> = atlas.receivers().iter().map(|r| r.texel).collect();
        let square: Vec<[u32; 2]> = (2..=13)
            .flat_map(|y| (2..=13).map(move |x| [x, y]))
            .collect();
        assert_eq!(all, square, "round {round}");
        for r in atlas.receivers() {
            // The flat mesh's position is its UV: receivers of centres sit at
            // their centres, touched ones on the grid's border.
            let centre = (Vec2::new(r.texel[0] as f32, r.texel[1] as f32) + 0.5) / side as f32;
            let at = Vec2::new(r.position.x, r.position.y);
            match r.coverage {
                Coverage::Centre => assert!(at.distance(centre) < 1e-6, "{r:?}"),
                Coverage::Touched => {
                    assert!(
                        at.cmpge(Vec2::splat(lo - 1e-6)).all()
                            && at.cmple(Vec2::splat(hi + 1e-6)).all()
                    );
                    assert!(at.distance(centre) <= 0.5 / side as f32 + 1e-6, "{r:?}");
                }
            }
            assert_eq!(r.normal, Vec3::Z);
            assert!(
                (r.texel_size - 2.0 / side as f32).abs() < 1e-5
                    || (r.texel_size - 1.0 / side as f32).abs() < 1e-5
            );
        }
    }
}

/// The texel size is the world length of a texel: a quad twice as large in
/// the world as in the atlas has texels of two atlas texels' width.
#[test]
fn texel_size_is_the_world_length_of_a_texel() {
    let positions = [
        [0.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 2.0, 0.0],
        [0.0, 2.0, 0.0],
    ];
    let indices = [0, 1, 2, 0, 2, 3];
    let uvs = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let atlas = TexelAtlas::new(&mesh, &uvs, &up_normals(4), &AtlasOptions::new(8, 8)).unwrap();
    assert_eq!(atlas.receivers().len(), 64);
    for r in atlas.receivers() {
        assert!((r.texel_size - 0.25).abs() < 1e-6, "{}", r.texel_size);
        assert_eq!(r.coverage, Coverage::Centre);
    }
}

/// Overlapping charts, UVs outside [0, 1], degenerate UV triangles, bad counts,
/// normals and resolutions are errors that name what is wrong.
#[test]
fn bad_atlases_are_errors() {
    let positions = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    let uvs = [[0.1, 0.1], [0.9, 0.1], [0.1, 0.9], [0.9, 0.9]];
    let normals = up_normals(4);
    let one = [0u32, 1, 2];
    let mesh = MeshView::new(&positions, &one).unwrap();
    let options = AtlasOptions::new(16, 16);
    assert!(TexelAtlas::new(&mesh, &uvs, &normals, &options).is_ok());
    // The same footprint twice.
    let twice = [0u32, 1, 2, 2, 1, 0];
    let doubled = MeshView::new(&positions, &twice).unwrap();
    assert!(matches!(
        TexelAtlas::new(&doubled, &uvs, &normals, &options),
        Err(AtlasError::Overlap {
            first: 0,
            second: 1,
            ..
        })
    ));
    // Partly overlapping: (0, 1, 2) and (1, 3, 2) share an edge, (0, 1, 3) overlaps both.
    let partly = [0u32, 1, 2, 0, 1, 3];
    let partly = MeshView::new(&positions, &partly).unwrap();
    assert!(matches!(
        TexelAtlas::new(&partly, &uvs, &normals, &options),
        Err(AtlasError::Overlap { .. })
    ));
    for bad in [
        [1.5, 0.5],
        [-0.01, 0.5],
        [f32::NAN, 0.5],
        [0.5, f32::INFINITY],
    ] {
        let mut u = uvs;
        u[2] = bad;
        assert_eq!(
            TexelAtlas::new(&mesh, &u, &normals, &options).unwrap_err(),
            AtlasError::UvOutOfRange { vertex: 2 }
        );
    }
    let mut collinear = uvs;
    collinear[2] = [0.5, 0.1];
    assert_eq!(
        TexelAtlas::new(&mesh, &collinear, &normals, &options).unwrap_err(),
        AtlasError::DegenerateUv { triangle: 0 }
    );
    assert!(matches!(
        TexelAtlas::new(&mesh, &uvs[..3], &normals, &options),
        Err(AtlasError::Count {
            argument: "uvs",
            expected: 4,
            found: 3
        })
    ));
    assert!(matches!(
        TexelAtlas::new(&mesh, &uvs, &normals[..2], &options),
        Err(AtlasError::Count {
            argument: "normals",
            ..
        })
    ));
    let mut zero = normals.clone();
    zero[1] = Vec3::ZERO;
    assert_eq!(
        TexelAtlas::new(&mesh, &uvs, &zero, &options).unwrap_err(),
        AtlasError::Normal { vertex: 1 }
    );
    for (width, height) in [
        (0, 16),
        (16, 0),
        (MAX_ATLAS_SIDE + 1, 1),
        (MAX_ATLAS_SIDE, MAX_ATLAS_SIDE),
    ] {
        assert_eq!(
            TexelAtlas::new(&mesh, &uvs, &normals, &AtlasOptions::new(width, height)).unwrap_err(),
            AtlasError::Resolution { width, height }
        );
    }
    let gutter = AtlasOptions {
        gutter: MAX_GUTTER + 1,
        ..options
    };
    assert_eq!(
        TexelAtlas::new(&mesh, &uvs, &normals, &gutter).unwrap_err(),
        AtlasError::Gutter {
            gutter: MAX_GUTTER + 1
        }
    );
}

/// The four texels a bilinear lookup reads, clamped to the atlas.
fn bilinear_texels(uv: Vec2, width: u32, height: u32) -> [[u32; 2]; 4] {
    let x = (uv.x * width as f32 - 0.5).floor() as i64;
    let y = (uv.y * height as f32 - 0.5).floor() as i64;
    let clamp = |c: i64, side: u32| c.clamp(0, i64::from(side) - 1) as u32;
    [
        [clamp(x, width), clamp(y, height)],
        [clamp(x + 1, width), clamp(y, height)],
        [clamp(x, width), clamp(y + 1, height)],
        [clamp(x + 1, width), clamp(y + 1, height)],
    ]
}

/// Random charts (slivers among them): with a gutter of 1 a bilinear lookup at
/// any UV inside a chart reads only texels with a receiver; without one, some
/// lookups read empty texels (so the check can fail).
#[test]
fn bilinear_lookups_inside_charts_read_only_baked_texels() {
    let mut rng = SmallRng::seed_from_u64(7);
    let (width, height) = (37u32, 23u32);
    // Small separate triangles, one per cell of a 4 x 4 layout, so none overlap.
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for cell in 0..16 {
        let origin = Vec2::new((cell % 4) as f32, (cell / 4) as f32) / 4.0;
        for _ in 0..3 {
            let uv = origin + Vec2::new(rng.random_range(0.01..0.24), rng.random_range(0.01..0.24));
            uvs.push(uv.to_array());
            positions.push([uv.x, uv.y, rng.random_range(0.0..0.1)]);
        }
    }
    let indices: Vec<u32> = (0..positions.len() as u32).collect();
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let normals = up_normals(positions.len());
    let lookups = |gutter: u32| {
        let options = AtlasOptions {
            gutter,
            ..AtlasOptions::new(width, height)
        };
        let atlas = TexelAtlas::new(&mesh, &uvs, &normals, &options).unwrap();
        let mut rng = SmallRng::seed_from_u64(11);
        let mut missing = 0;
        for _ in 0..20_000 {
            let t = rng.random_range(0..mesh.triangle_count());
            let [a, b, c] = mesh
                .triangle_indices(t)
                .map(|v| Vec2::from(uvs[v as usize]));
            let (mut s, mut r) = (rng.random::<f32>(), rng.random::<f32>());
            if s + r > 1.0 {
                (s, r) = (1.0 - s, 1.0 - r);
            }
            let uv = a + (b - a) * s + (c - a) * r;
            for [x, y] in bilinear_texels(uv, width, height) {
                if atlas.receiver_at(x, y).is_none() {
                    missing += 1;
                }
            }
        }
        missing
    };
    assert_eq!(lookups(1), 0);
    assert_eq!(lookups(2), 0);
    assert!(
        lookups(0) > 0,
        "without a gutter some lookups must read empty texels"
    );
}

/// `expand` writes each receiver's value to its texel and to the gutter
/// texels that read it, and leaves the others.
#[test]
fn expand_fills_receivers_and_gutter() {
    let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let uvs = [[0.3, 0.3], [0.7, 0.3], [0.3, 0.7]];
    let indices = [0u32, 1, 2];
    let mesh = MeshView::new(&positions, &indices).unwrap();
    let atlas = TexelAtlas::new(&mesh, &uvs, &up_normals(3), &AtlasOptions::new(20, 20)).unwrap();
    let count = atlas.receivers().len();
    let values: Vec<f32> = (0..count).flat_map(|i| [i as f32, -(i as f32)]).collect();
    let mut image = vec![f32::NAN; 20 * 20 * 2];
    atlas.expand(&values, 2, &mut image).unwrap();
    let mut gutter = 0;
    for y in 0..20u32 {
        for x in 0..20u32 {
            let texel = &image[(y as usize * 20 + x as usize) * 2..][..2];
            match atlas.receiver_at(x, y) {
                Some(read) => {
                    assert_eq!(texel, [read as f32, -(read as f32)]);
                    let own = atlas.receivers()[read].texel;
                    if own != [x, y] {
                        gutter += 1;
                        // Within the gutter of its source.
                        assert!(own[0].abs_diff(x).max(own[1].abs_diff(y)) <= 2);
                    }
                }
                None => assert!(texel.iter().all(|v| v.is_nan())),
            }
        }
    }
    assert!(gutter > 0);
    // A texel set alone (a bake file's) spreads values over the same texels.
    let set_texels = crate::transfer::AtlasTexels::new(
        20,
        20,
        atlas
            .receivers()
            .iter()
            .map(|r| r.texel[1] * 20 + r.texel[0])
            .collect(),
    )
    .unwrap();
    let mut from_set = vec![f32::NAN; 20 * 20 * 2];
    set_texels
        .expand(atlas.gutter(), &values, 2, &mut from_set)
        .unwrap();
    assert_eq!(
        from_set.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        image.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        "set and atlas expand alike"
    );
    assert!(
        set_texels
            .expand(MAX_GUTTER + 1, &values, 2, &mut from_set)
            .is_none()
    );
    assert!(atlas.expand(&values[1..], 2, &mut image).is_none());
    assert!(atlas.expand(&values, 2, &mut image[1..]).is_none());
    assert!(atlas.expand(&values, 0, &mut image).is_none());
}

/// A floor with a closed box standing on it, each box face its own chart:
/// floor receivers under the box start inside it; the lift moves those within
/// its probes' reach of a wall out and leaves receivers away from the box where
/// they are.
#[test]
fn lift_moves_receivers_out_of_a_box_on_the_floor() {
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut uvs: Vec<[f32; 2]> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    // One quad (counter-clockwise seen from where it faces) as a chart.
    let mut quad = |corners: [Vec3; 4], chart: [Vec2; 2]| {
        let base = positions.len() as u32;
        let [lo, hi] = chart;
        let chart_uvs = [lo, Vec2::new(hi.x, lo.y), hi, Vec2::new(lo.x, hi.y)];
        for (p, uv) in corners.iter().zip(chart_uvs) {
            positions.push(p.to_array());
            uvs.push(uv.to_array());
        }
        indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    };
    let v = Vec3::new;
    // The floor, [-1, 1]², facing up, on the left half of the atlas.
    quad(
        [
            v(-1.0, -1.0, 0.0),
            v(1.0, -1.0, 0.0),
            v(1.0, 1.0, 0.0),
            v(-1.0, 1.0, 0.0),
        ],
        [Vec2::new(0.0, 0.0), Vec2::new(0.5, 1.0)],
    );
    // The box [-0.3, 0.3]² × [0, 0.4], faces outwards, one chart per face.
    let (s, h) = (0.3, 0.4);
    let faces = [
        [v(-s, -s, h), v(s, -s, h), v(s, s, h), v(-s, s, h)],
        [v(-s, s, 0.0), v(s, s, 0.0), v(s, -s, 0.0), v(-s, -s, 0.0)],
        [v(-s, -s, 0.0), v(s, -s, 0.0), v(s, -s, h), v(-s, -s, h)],
        [v(s, s, 0.0), v(-s, s, 0.0), v(-s, s, h), v(s, s, h)],
        [v(s, -s, 0.0), v(s, s, 0.0), v(s, s, h), v(s, -s, h)],
        [v(-s, s, 0.0), v(-s, -s, 0.0), v(-s, -s, h), v(-s, s, h)],
    ];
    for (k, face) in faces.into_iter().enumerate() {
        let lo = Vec2::new(0.55 + 0.22 * (k % 2) as f32, 0.05 + 0.3 * (k / 2) as f32);
        quad(face, [lo, lo + Vec2::splat(0.2)]);
    }
    let mesh = MeshView::new(&positions, &indices).unwrap();
    // Flat faces: the geometric normals as vertex normals.
    let normals: Vec<Vec3> = (0..positions.len())
        .map(|vertex| {
            let t = indices.iter().position(|&i| i as usize == vertex).unwrap() / 3;
            let [a, b, c] = mesh.triangle(t);
            (b - a).cross(c - a).normalize()
        })
        .collect();
    let mut atlas = TexelAtlas::new(&mesh, &uvs, &normals, &AtlasOptions::new(64, 32)).unwrap();
    let inside = |p: Vec3| p.x.abs() < s && p.y.abs() < s && p.z > -1e-6 && p.z < h;
    let on_floor = |r: &&TexelReceiver| r.triangle < 2;
    let before: Vec<TexelReceiver> = atlas.receivers().to_vec();
    let trapped = before
        .iter()
        .filter(on_floor)
        .filter(|r| inside(r.position))
        .count();
    assert!(trapped > 20, "{trapped} floor receivers under the box");
    let caster = BruteForceCaster::new(mesh);
    let moved = atlas.lift(&mesh, &caster, &LiftOptions::default()).unwrap();
    let mut near_wall = 0;
    for (old, new) in before.iter().zip(atlas.receivers()) {
        if old.triangle >= 2 {
            // The box's own receivers start outside it and see no back face;
            // those on an edge of their face move a sliver into it.
            let sliver = 1e-3 * old.texel_size * 1.001;
            assert!(
                old.position.distance(new.position) <= sliver,
                "{old:?} -> {new:?}"
            );
            continue;
        }
        let depth = s - old.position.x.abs().max(old.position.y.abs());
        if inside(old.position) && depth < 0.99 * old.texel_size {
            // Under the box within the probes' reach of a wall (the texels a
            // bilinear lookup of the visible floor reads): moved out, to just
            // outside the nearest wall, on the floor.
            near_wall += 1;
            assert!(!inside(new.position), "{old:?} -> {new:?}");
            let out = new.position.x.abs().max(new.position.y.abs());
            assert!(out >= s && out < s + 0.1 * old.texel_size, "{new:?}");
            assert!(new.position.z > 0.0 && new.position.z < 0.01 * old.texel_size);
        } else if !inside(old.position) && -depth > 1.01 * old.texel_size {
            // Away from the box, nothing moves but a sliver off the floor's
            // border.
            assert!(old.position.distance(new.position) <= 1e-3 * old.texel_size * 1.001);
        }
    }
    assert!(
        near_wall > 20 && moved >= near_wall,
        "{near_wall} near a wall, {moved} moved"
    );
    assert!(
        atlas
            .lift(
                &mesh,
                &caster,
                &LiftOptions {
                    reach: 0.0,
                    ..LiftOptions::default()
                }
            )
            .is_none()
    );
}

/// The furnace of the transfer tests, baked at texels with texel bounces: inside
/// a spherical cavity open to a uniform sky through a cap of area fraction `f`,
/// every point receives `π L f` directly, and each bounce of albedo `ρ`
/// multiplies it by `ρ (1 − f)`. Each triangle is its own chart, so a hit reads
/// the texel of the very triangle it lands on.
#[cfg(feature = "bvh")]
#[test]
fn texel_bounces_fill_a_furnace_as_the_geometric_series() {
    use crate::transfer::{BakeOptions, Measurement};
    // 24 rings: the cap's rim (cos θ = 0.5) is ring 8 exactly.
    let (positions, all) = crate::geom::uv_sphere(24, 48, |theta, phi| {
        let s = libm::sinf(theta);
        [s * libm::cosf(phi), s * libm::sinf(phi), libm::cosf(theta)]
    });
    let mut corners = Vec::new();
    for t in all.chunks_exact(3) {
        let centroid: Vec3 = t
            .iter()
            .map(|&i| Vec3::from(positions[i as usize]))
            .sum::<Vec3>()
            / 3.0;
        if centroid.z < 0.5 {
            corners.push([t[0], t[1], t[2]]);
        }
    }
    // Every triangle its own vertices and its own cell of a 48 x 48 UV grid.
    let cells = 48usize;
    let (mut flat, mut uvs, mut normals, mut indices) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (k, t) in corners.iter().enumerate() {
        let cell = Vec2::new((k % cells) as f32, (k / cells) as f32);
        let local = [
            Vec2::new(0.1, 0.1),
            Vec2::new(0.9, 0.1),
            Vec2::new(0.1, 0.9),
        ];
        for (&i, l) in t.iter().zip(local) {
            let p = Vec3::from(positions[i as usize]);
            indices.push(flat.len() as u32);
            flat.push(p.to_array());
            uvs.push(((cell + l) / cells as f32).to_array());
            // Inward: the cavity's inside is lit.
            normals.push(-p.normalize());
        }
    }
    let mesh = MeshView::new(&flat, &indices).unwrap();
    let side = (cells * 4) as u32;
    let atlas = TexelAtlas::new(&mesh, &uvs, &normals, &AtlasOptions::new(side, side)).unwrap();
    let bvh = crate::raycast::BvhScene::new(&mesh).unwrap();
    let f = 0.25f64;
    let albedo = 0.8f32;
    let l0 = 2.0 * core::f32::consts::PI.sqrt();
    for bounces in [0u32, 2] {
        let options = BakeOptions {
            bands: 2,
            rays: 64,
            bounces,
            albedo,
            seed: 3,
            ..BakeOptions::new(Measurement::Diffuse)
        };
        let set = atlas.bake(&mesh, &normals, &bvh, &options, true).unwrap();
        let q = f64::from(albedo) * (1.0 - f);
        let want = core::f64::consts::PI * f * (0..=bounces).map(|i| q.powi(i as i32)).sum::<f64>();
        let mean = (0..set.vertex_count())
            .map(|p| f64::from(set.vertex_block(p).unwrap()[0] * l0))
            .sum::<f64>()
            / set.vertex_count() as f64;
        let error = mean / want - 1.0;
        std::println!(
            "texel furnace, {bounces} bounces, {} texels: closed form {want:.5}, mean error {:+.3} %",
            set.vertex_count(),
            error * 100.0
        );
        assert!(error.abs() < 0.02, "{bounces} bounces: {error}");
    }
    // Split in three parts, the bounces' bake joins into the whole, bit for
    // bit, texels included.
    let options = BakeOptions {
        bands: 2,
        rays: 16,
        bounces: 1,
        albedo,
        seed: 5,
        ..BakeOptions::new(Measurement::Diffuse)
    };
    let whole = atlas.bake(&mesh, &normals, &bvh, &options, false).unwrap();
    let count = atlas.receivers().len();
    let cuts = [0, count / 3, count / 2, count];
    let parts: Vec<_> = cuts
        .windows(2)
        .map(|c| {
            atlas
                .bake_part(&mesh, &normals, &bvh, &options, c[0]..c[1])
                .unwrap()
        })
        .collect();
    assert_eq!(crate::transfer::TransferSet::concat(&parts).unwrap(), whole);
    assert_eq!(whole.texels().unwrap().texels().len(), count);
    assert!(
        atlas
            .bake_part(&mesh, &normals, &bvh, &options, count..count + 1)
            .is_err()
    );
    // Every hit on the mesh maps to a texel: the centroid of each triangle.
    for t in 0..mesh.triangle_count() {
        assert!(
            atlas
                .receiver_at_hit(&mesh, t, 1.0 / 3.0, 1.0 / 3.0)
                .is_some(),
            "{t}"
        );
    }
    assert_eq!(
        atlas.receiver_at_hit(&mesh, mesh.triangle_count(), 0.3, 0.3),
        None
    );
}
