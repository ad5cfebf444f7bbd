//! The precomputation engine (P1 §3): `m = M R (I − T_i)^{-1} V E`, with the
//! Neumann series truncated after `bounces` interreflections.
//!
//! - Emission `E`: distant lighting in `bands²` real SH coefficients (world frame).
//! - Transport: for every vertex, `rays` stratified directions over its hemisphere
//!   (vertex frame of [`Frame::from_normal`]); pass 0 (`V E`) casts occlusion rays and
//!   sees the lighting basis `Y_j(ω)` where unoccluded; pass `k ≥ 1` (one more
//!   application of `T_i = G R`) casts closest-hit rays and sees the diffuse
//!   outgoing radiance of the previous pass at the hit, `ρ/π · E_{k-1}`,
//!   interpolated from the hit triangle's corners by its barycentrics. Hits on the
//!   back of a surface (ray along the interpolated normal) see nothing.
//! - Measurement `M R`, per vertex, over the same rays for every lighting column:
//!   irradiance transfer `E_k = ∫ L_in cos θ dω` (the diffuse kind, and what the next
//!   pass reads), or the SH projection of incident radiance `∫ L_in Y_i dω`
//!   over the hemisphere in world (glossy SH kind) or local (MRT) coordinates; MRT
//!   then applies the BRDF matrix ([`super::mrt`]).
//!
//! Each pass is a barrier over all vertices (pass `k` reads every vertex's pass
//! `k-1` result); within a pass vertices are independent and draw from their own
//! random streams, so the result is identical serial or parallel, for a seed.

use alloc::vec;
use alloc::vec::Vec;
use core::f32::consts::PI;
use core::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;

use super::mrt::brdf_matrix;
use super::rng::{Sampling, SplitMix64, Stratified, hemisphere_direction};
use super::{BakeError, BakeOptions, Measurement, Payload, TransferKind, TransferSet};
use crate::geom::{Frame, MeshView};
use crate::raycast::{Ray, RayCaster};
use crate::sh::{MAX_BANDS, MAX_COEFFS, eval_basis_into};

/// Largest ray count per vertex and pass.
pub const MAX_RAYS: u32 = 1 << 22;
/// Largest bounce count.
pub const MAX_BOUNCES: u32 = 64;
/// Largest MRT grid side.
pub const MAX_GRID: u32 = 64;

/// What one pass over a vertex needs to know.
struct PassContext<'a, C: ?Sized> {
    mesh: &'a MeshView<'a>,
    normals: &'a [Vec3],
    caster: &'a C,
    seed: u64,
    rays: u32,
    albedo: f32,
    ray_offset: f32,
    coeffs: usize,
    /// Which projection the pass accumulates besides irradiance.
    projection: Projection,
    sampling: Sampling,
    pass: u32,
    /// `E_{pass-1}` of every vertex (`coeffs` each), for passes ≥ 1.
    previous: &'a [f32],
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Projection {
    None,
    World,
    Local,
}

/// Validates the inputs; returns the coefficient count.
fn validate(
    mesh: &MeshView<'_>,
    normals: &[Vec3],
    options: &BakeOptions<'_>,
) -> Result<usize, BakeError> {
    if !(1..=MAX_BANDS as u32).contains(&options.bands) {
        return Err(BakeError::Bands(options.bands));
    }
    if !(1..=MAX_RAYS).contains(&options.rays) {
        return Err(BakeError::Rays(options.rays));
    }
    if options.bounces > MAX_BOUNCES {
        return Err(BakeError::Bounces(options.bounces));
    }
    if !(options.albedo.is_finite() && (0.0..1.0).contains(&options.albedo)) {
        return Err(BakeError::Albedo(options.albedo));
    }
    if !(options.ray_offset.is_finite() && options.ray_offset >= 0.0) {
        return Err(BakeError::RayOffset(options.ray_offset));
    }
    if let Measurement::Mrt { grid, .. } = options.measurement {
        if !(2..=MAX_GRID).contains(&grid) {
            return Err(BakeError::Grid(grid));
        }
    }
    if normals.len() != mesh.vertex_count() {
        return Err(BakeError::NormalCount {
            normals: normals.len(),
            vertices: mesh.vertex_count(),
        });
    }
    if mesh.vertex_count() > u32::MAX as usize {
        return Err(BakeError::TooManyVertices(mesh.vertex_count()));
    }
    for (index, n) in normals.iter().enumerate() {
        if !(n.is_finite() && (n.length() - 1.0).abs() < 1e-3) {
            return Err(BakeError::Normal { index });
        }
    }
    Ok((options.bands * options.bands) as usize)
}

/// Bakes a transfer set: every vertex of `mesh` with its unit normal, rays cast
/// through `caster`, which must hold the same triangles in the same order as
/// `mesh` (hit triangle indices address `mesh`). Vertices are spread over rayon's
/// pool with the `parallel` feature; the result is bit-for-bit that of
/// [`bake_serial`].
///
/// Returns an error naming the first invalid option or input.
pub fn bake<C: RayCaster + Sync + ?Sized>(
    mesh: &MeshView<'_>,
    normals: &[Vec3],
    caster: &C,
    options: &BakeOptions<'_>,
) -> Result<TransferSet, BakeError> {
    bake_impl(mesh, normals, caster, options, cfg!(feature = "parallel"))
}

/// [`bake`] on the calling thread only.
pub fn bake_serial<C: RayCaster + Sync + ?Sized>(
    mesh: &MeshView<'_>,
    normals: &[Vec3],
    caster: &C,
    options: &BakeOptions<'_>,
) -> Result<TransferSet, BakeError> {
    bake_impl(mesh, normals, caster, options, false)
}

fn bake_impl<C: RayCaster + Sync + ?Sized>(
    mesh: &MeshView<'_>,
    normals: &[Vec3],
    caster: &C,
    options: &BakeOptions<'_>,
    parallel: bool,
) -> Result<TransferSet, BakeError> {
    let coeffs = validate(mesh, normals, options)?;
    let vertices = mesh.vertex_count();
    let (kind, projection, sampling, grid) = match options.measurement {
        Measurement::Diffuse => (TransferKind::Diffuse, Projection::None, Sampling::Cosine, 0),
        Measurement::GlossySh => (
            TransferKind::GlossySh,
            Projection::World,
            Sampling::Uniform,
            0,
        ),
        Measurement::Mrt { grid, .. } => (
            TransferKind::Mrt,
            Projection::Local,
            Sampling::Uniform,
            grid,
        ),
    };
    // The BRDF matrix first: it is cheap next to the rays, and a BRDF that gives
    // non-finite values is refused before any ray is cast.
    let brdf_nodes = match options.measurement {
        Measurement::Mrt { grid, brdf } => {
            let b = brdf_matrix(brdf, grid, coeffs);
            if !b.iter().all(|x| x.is_finite()) {
                return Err(BakeError::BrdfNotFinite);
            }
            b
        }
        _ => Vec::new(),
    };
    let gathered = match projection {
        Projection::None => coeffs,
        _ => coeffs * coeffs,
    };
    let mut measured = vec![0.0f32; vertices * gathered];
    let mut previous = Vec::new();
    let done = AtomicUsize::new(0);
    let total = vertices * (options.bounces as usize + 1);
    for pass in 0..=options.bounces {
        let mut irradiance = vec![0.0f32; vertices * coeffs];
        let ctx = PassContext {
            mesh,
            normals,
            caster,
            seed: options.seed,
            rays: options.rays,
            albedo: options.albedo,
            ray_offset: options.ray_offset,
            coeffs,
            projection,
            sampling,
            pass,
            previous: &previous,
        };
        let progress = options.progress;
        let work = |vertex: usize, irr: &mut [f32], meas: &mut [f32], scratch: &mut Scratch| {
            gather(&ctx, vertex, irr, meas, scratch);
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            if let Some(progress) = progress {
                progress(d, total);
            }
        };
        run_vertices(
            parallel,
            &mut irradiance,
            coeffs,
            &mut measured,
            gathered,
            coeffs,
            &work,
        );
        if projection == Projection::None {
            for (m, e) in measured.iter_mut().zip(&irradiance) {
                *m += *e;
            }
        }
        previous = irradiance;
    }
    let data = if let Measurement::Mrt { grid, .. } = options.measurement {
        let b = &brdf_nodes;
        let rows = (grid * grid) as usize;
        let mut out = vec![0.0f32; vertices * rows * coeffs];
        let apply = |v: usize, dst: &mut [f32]| {
            let t = &measured[v * gathered..(v + 1) * gathered];
            for g in 0..rows {
                let row = &mut dst[g * coeffs..(g + 1) * coeffs];
                for (i, &bgi) in b[g * coeffs..(g + 1) * coeffs].iter().enumerate() {
                    for (o, &tij) in row.iter_mut().zip(&t[i * coeffs..(i + 1) * coeffs]) {
                        *o += bgi * tij;
                    }
                }
            }
        };
        map_vertices(parallel, &mut out, rows * coeffs, &apply);
        out
    } else {
        measured
    };
    Ok(TransferSet {
        kind,
        bands: options.bands,
        grid,
        info: super::BakeInfo {
            rays: options.rays,
            bounces: options.bounces,
            albedo: options.albedo,
            brdf: match options.measurement {
                Measurement::Mrt { brdf, .. } => brdf.info(),
                _ => super::BrdfInfo::CUSTOM,
            },
        },
        positions: (0..vertices).map(|v| mesh.position(v).to_array()).collect(),
        normals: normals.iter().map(|n| n.to_array()).collect(),
        payload: Payload::Dense(data),
    })
}

/// Per-thread buffers for one vertex.
struct Scratch {
    basis: [f32; MAX_COEFFS],
    local_basis: [f32; MAX_COEFFS],
    contribution: [f32; MAX_COEFFS],
}

impl Scratch {
    fn new() -> Self {
        Scratch {
            basis: [0.0; MAX_COEFFS],
            local_basis: [0.0; MAX_COEFFS],
            contribution: [0.0; MAX_COEFFS],
        }
    }
}

type VertexWork<'a> = dyn Fn(usize, &mut [f32], &mut [f32], &mut Scratch) + Sync + 'a;

/// Runs `work(vertex, irradiance_chunk, measured_chunk)` for every vertex.
fn run_vertices(
    parallel: bool,
    irradiance: &mut [f32],
    irr_len: usize,
    measured: &mut [f32],
    meas_len: usize,
    _coeffs: usize,
    work: &VertexWork<'_>,
) {
    #[cfg(feature = "parallel")]
    if parallel {
        use rayon::prelude::*;
        irradiance
            .par_chunks_mut(irr_len)
            .zip(measured.par_chunks_mut(meas_len))
            .enumerate()
            .for_each_init(Scratch::new, |scratch, (v, (irr, meas))| {
                work(v, irr, meas, scratch)
            });
        return;
    }
    let _ = parallel;
    let mut scratch = Scratch::new();
    for (v, (irr, meas)) in irradiance
        .chunks_mut(irr_len)
        .zip(measured.chunks_mut(meas_len))
        .enumerate()
    {
        work(v, irr, meas, &mut scratch);
    }
}

/// Runs `f(vertex, chunk)` over consecutive chunks of `out`.
fn map_vertices(
    parallel: bool,
    out: &mut [f32],
    len: usize,
    f: &(dyn Fn(usize, &mut [f32]) + Sync),
) {
    #[cfg(feature = "parallel")]
    if parallel {
        use rayon::prelude::*;
        out.par_chunks_mut(len)
            .enumerate()
            .for_each(|(v, c)| f(v, c));
        return;
    }
    let _ = parallel;
    for (v, c) in out.chunks_mut(len).enumerate() {
        f(v, c);
    }
}

/// One pass over one vertex: writes its irradiance transfer `E_pass` and adds the
/// pass's projection to `measured`.
fn gather<C: RayCaster + ?Sized>(
    ctx: &PassContext<'_, C>,
    vertex: usize,
    irradiance: &mut [f32],
    measured: &mut [f32],
    scratch: &mut Scratch,
) {
    let n = ctx.coeffs;
    let normal = ctx.normals[vertex];
    let frame = Frame::from_normal(normal);
    let origin = ctx.mesh.position(vertex) + normal * ctx.ray_offset;
    let mut rng = SplitMix64::for_vertex(ctx.seed, vertex as u64, u64::from(ctx.pass));
    let mut strata = Stratified::new(ctx.rays);
    let count = ctx.rays as f32;
    let albedo_over_pi = ctx.albedo / PI;
    while let Some((u, v)) = strata.next(&mut rng) {
        let local = hemisphere_direction(ctx.sampling, u, v);
        let world = frame.to_world(local);
        let contribution = &mut scratch.contribution[..n];
        if ctx.pass == 0 {
            if ctx.caster.occluded(&Ray::new(origin, world, f32::INFINITY)) {
                continue;
            }
            // The lighting basis itself: column j of the transfer sees Y_j(ω).
            let _ = eval_basis_into(world, contribution);
        } else {
            let Some(hit) = ctx
                .caster
                .closest_hit(&Ray::new(origin, world, f32::INFINITY))
            else {
                continue;
            };
            let [a, b, c] = ctx.mesh.triangle_indices(hit.triangle as usize);
            let (a, b, c) = (a as usize, b as usize, c as usize);
            let (wa, wb, wc) = (1.0 - hit.u - hit.v, hit.u, hit.v);
            let hit_normal = wa * ctx.normals[a] + wb * ctx.normals[b] + wc * ctx.normals[c];
            if hit_normal.dot(world) >= 0.0 {
                // The back of a surface: its outgoing radiance is not modelled.
                continue;
            }
            let (ea, eb, ec) = (
                &ctx.previous[a * n..(a + 1) * n],
                &ctx.previous[b * n..(b + 1) * n],
                &ctx.previous[c * n..(c + 1) * n],
            );
            for j in 0..n {
                contribution[j] = albedo_over_pi * (wa * ea[j] + wb * eb[j] + wc * ec[j]);
            }
        }
        // Irradiance: ∫ L cos θ dω.
        let w_irr = match ctx.sampling {
            Sampling::Cosine => PI / count,
            Sampling::Uniform => 2.0 * PI * local.z / count,
        };
        for (e, c) in irradiance.iter_mut().zip(contribution.iter()) {
            *e += w_irr * c;
        }
        // Projection of incident radiance on Y_i (uniform sampling, 2π/N).
        let w = 2.0 * PI / count;
        let basis: &[f32] = match ctx.projection {
            Projection::None => continue,
            Projection::World => {
                let _ = eval_basis_into(world, &mut scratch.basis[..n]);
                &scratch.basis[..n]
            }
            Projection::Local => {
                let _ = eval_basis_into(local, &mut scratch.local_basis[..n]);
                &scratch.local_basis[..n]
            }
        };
        for (i, &yi) in basis.iter().enumerate() {
            let s = w * yi;
            for (t, c) in measured[i * n..(i + 1) * n]
                .iter_mut()
                .zip(contribution.iter())
            {
                *t += s * c;
            }
        }
    }
}
