//! Spherical-harmonic kernels, each next to its baseline in the same run:
//!
//! - basis evaluation: the closed-form polynomials (`eval_basis`, bands ≤ 5) against
//!   the Legendre recurrence (`eval_basis_recurrence`) at the same sizes, and the
//!   recurrence alone above that;
//! - rotation: building an `ShRotation` and applying it, against evaluating the basis
//!   at one direction (the unit of cost everything else is measured in);
//! - equirectangular projection of a 512×256 RGB image: the separable quadrature
//!   against the obvious per-texel evaluation of every basis function (the same sum).
//!
//! Run: `cargo bench -p antumbra-core --bench sh`.

use antumbra_core::sh::{
    EquirectMapping, Sh, ShRotation, equirect_texel_solid_angle, eval_basis, eval_basis_recurrence,
    project_equirect,
};
use glam::{Mat3, Quat, Vec2, Vec3};
use rand::{Rng, SeedableRng, rngs::SmallRng};

fn main() {
    divan::main();
}

const DIRECTIONS: usize = 1024;

fn directions() -> Vec<Vec3> {
    let mut rng = SmallRng::seed_from_u64(3);
    (0..DIRECTIONS)
        .map(|_| {
            loop {
                let v = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                if v.length() > 0.1 && v.length() <= 1.0 {
                    break v.normalize();
                }
            }
        })
        .collect()
}

#[divan::bench(consts = [9, 16, 25])]
fn eval_polynomial<const N: usize>(bencher: divan::Bencher<'_, '_>) {
    let dirs = directions();
    bencher
        .counter(divan::counter::ItemsCount::new(DIRECTIONS))
        .bench_local(|| {
            dirs.iter()
                .map(|&d| eval_basis::<N>(divan::black_box(d))[N - 1])
                .sum::<f32>()
        });
}

#[divan::bench(consts = [9, 16, 25, 36, 49, 64])]
fn eval_recurrence<const N: usize>(bencher: divan::Bencher<'_, '_>) {
    let dirs = directions();
    bencher
        .counter(divan::counter::ItemsCount::new(DIRECTIONS))
        .bench_local(|| {
            dirs.iter()
                .map(|&d| eval_basis_recurrence::<N>(divan::black_box(d))[N - 1])
                .sum::<f32>()
        });
}

fn rotation() -> Mat3 {
    Mat3::from_quat(Quat::from_euler(glam::EulerRot::ZYX, 0.3, -1.1, 2.0))
}

#[divan::bench(consts = [9, 16, 25, 49, 64])]
fn rotation_build<const N: usize>() -> ShRotation<N> {
    ShRotation::<N>::new(divan::black_box(rotation()))
}

#[divan::bench(consts = [9, 25, 49, 64])]
fn rotation_apply<const N: usize>(bencher: divan::Bencher<'_, '_>) {
    let rot = ShRotation::<N>::new(rotation());
    let sh = Sh::<N>::new(core::array::from_fn(|i| (i as f32 * 0.37).sin()));
    bencher.bench_local(|| rot.apply(divan::black_box(&sh)));
}

const WIDTH: usize = 512;
const HEIGHT: usize = 256;

fn image() -> Vec<[f32; 3]> {
    let mut rng = SmallRng::seed_from_u64(5);
    (0..WIDTH * HEIGHT)
        .map(|_| [rng.random(), rng.random(), rng.random()])
        .collect()
}

#[divan::bench(consts = [9, 25, 64])]
fn equirect_separable<const N: usize>(bencher: divan::Bencher<'_, '_>) {
    let pixels = image();
    let mapping = EquirectMapping::Y_UP;
    bencher
        .counter(divan::counter::ItemsCount::new(WIDTH * HEIGHT))
        .bench_local(|| project_equirect::<N, _>(&pixels, WIDTH, HEIGHT, &mapping).unwrap());
}

/// Baseline: the same quadrature, every basis function at every texel centre.
#[divan::bench(consts = [9, 25, 64])]
fn equirect_per_texel<const N: usize>(bencher: divan::Bencher<'_, '_>) {
    let pixels = image();
    let mapping = EquirectMapping::Y_UP;
    bencher
        .counter(divan::counter::ItemsCount::new(WIDTH * HEIGHT))
        .bench_local(|| {
            let mut sums = [[0.0f64; N]; 3];
            for row in 0..HEIGHT {
                let weight = equirect_texel_solid_angle(row, WIDTH, HEIGHT);
                for column in 0..WIDTH {
                    let uv = Vec2::new(
                        (column as f32 + 0.5) / WIDTH as f32,
                        (row as f32 + 0.5) / HEIGHT as f32,
                    );
                    let y = eval_basis::<N>(mapping.direction(uv));
                    let value = pixels[row * WIDTH + column];
                    for (sum, v) in sums.iter_mut().zip(value) {
                        for (s, yi) in sum.iter_mut().zip(y) {
                            *s += weight * f64::from(v) * f64::from(yi);
                        }
                    }
                }
            }
            sums
        });
}
