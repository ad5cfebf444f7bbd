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

use alloc::vec::Vec;
use core::f32::consts::PI;
use core::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;

use super::mrt::brdf_matrix;
use super::rng::{Sampling, SplitMix64, Stratified, hemisphere_direction};
use super::{BakeError, BakeOptions, Measurement, Payload, TransferKind, TransferSet};
use crate::geom::{Frame, MeshView};
use crate::raycast::{Hit, Ray, RayCaster};
use crate::sh::{MAX_BANDS, eval_basis};

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
    /// `E_{pass-1}` of every vertex, or of every point when `reads` says so
    /// (`coeffs` each), for passes ≥ 1.
    previous: &'a [f32],
    /// Where a bounce's hit reads `previous`.
    reads: BounceReads<'a>,
}

/// Where a bounce ray's hit reads the previous pass, in [`bake_points`].
#[derive(Clone, Copy)]
pub enum BounceReads<'a> {
    /// The mesh's vertices' previous pass, interpolated at the hit from the
    /// hit triangle's corners (the vertices' passes run too).
    Vertices,
    /// The points' own previous pass, at the point `lookup(triangle, u, v)`
    /// gives for a hit (`u`, `v` the barycentric weights of the triangle's
    /// second and third corners, as in [`crate::Hit`]), such as the lightmap
    /// texel under the hit's UV; a hit that maps to no point sees nothing.
    /// Only the points' passes run.
    Points(&'a (dyn Fn(usize, f32, f32) -> Option<usize> + Sync)),
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
    validate_options(options)?;
    if normals.len() != mesh.vertex_count() {
        return Err(BakeError::NormalCount {
            normals: normals.len(),
            vertices: mesh.vertex_count(),
        });
    }
    if mesh.vertex_count() > u32::MAX as usize {
        return Err(BakeError::TooManyVertices(mesh.vertex_count()));
    }
    if mesh.vertex_count() == 0 {
        return Err(BakeError::NoVertices);
    }
    for (index, n) in normals.iter().enumerate() {
        if !unit_normal(*n) {
            return Err(BakeError::Normal { index });
        }
    }
    Ok((options.bands * options.bands) as usize)
}

/// What [`bake`] accepts as a normal, and so what a bake file's loader accepts: every
/// set a bake makes can be saved and loaded again.
pub(super) fn unit_normal(n: Vec3) -> bool {
    n.is_finite() && (n.length() - 1.0).abs() < 1e-3
}

/// The checks of [`validate`] that do not look at the mesh.
fn validate_options(options: &BakeOptions<'_>) -> Result<(), BakeError> {
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
    if let Measurement::Mrt { grid, .. } = options.measurement
        && !(2..=MAX_GRID).contains(&grid)
    {
        return Err(BakeError::Grid(grid));
    }
    Ok(())
}

/// The hemisphere sampling of a measurement: cosine-weighted for diffuse transfer
/// (irradiance only), uniform for the projections.
fn sampling_of(measurement: &Measurement<'_>) -> Sampling {
    match measurement {
        Measurement::Diffuse => Sampling::Cosine,
        Measurement::GlossySh | Measurement::Mrt { .. } => Sampling::Uniform,
    }
}

/// One ray a bake casts: the ray (world) and its direction in the vertex frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeRay {
    /// The ray, from the vertex position moved `ray_offset` along the normal, with
    /// `t_max = ∞`. Pass 0 casts it with [`RayCaster::occluded`], later passes with
    /// [`RayCaster::closest_hit`].
    pub ray: Ray,
    /// Its direction in the vertex frame ([`Frame::from_normal`] of the normal;
    /// `z ≥ 0`, unit).
    pub local: Vec3,
}

/// Calls `f` with exactly the rays [`bake`] casts from one vertex in pass `pass`
/// (0 = direct light; `k ≥ 1` = bounce `k`), in the order it casts them: the
/// vertex at `position` with unit `normal`, `vertex` its index in the mesh (it
/// selects the random stream), `options` those of the bake. The engine draws its
/// rays through the same function, so the two cannot drift apart; benchmarks use
/// it to cast the bake's own rays through other ray casters.
///
/// Errors: the option errors of [`bake`], and [`BakeError::Normal`] (with index
/// `vertex`) for a normal that is not finite and unit. `pass` above
/// `options.bounces` is allowed (the bake would not cast those rays).
pub fn bake_rays(
    position: Vec3,
    normal: Vec3,
    vertex: usize,
    pass: u32,
    options: &BakeOptions<'_>,
    f: impl FnMut(&BakeRay),
) -> Result<(), BakeError> {
    validate_options(options)?;
    if !unit_normal(normal) {
        return Err(BakeError::Normal { index: vertex });
    }
    for_each_ray(
        position,
        normal,
        options.ray_offset,
        options.seed,
        vertex as u64,
        pass,
        options.rays,
        sampling_of(&options.measurement),
        f,
    );
    Ok(())
}

/// The rays of one vertex and pass, in cast order: stratified `(u, v)` from the
/// vertex's own stream, mapped to the hemisphere by `sampling`, then to the world
/// by the vertex frame. The one code path of
/// [`bake`] (through `gather`) and [`bake_rays`].
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn for_each_ray(
    position: Vec3,
    normal: Vec3,
    ray_offset: f32,
    seed: u64,
    stream: u64,
    pass: u32,
    rays: u32,
    sampling: Sampling,
    mut f: impl FnMut(&BakeRay),
) {
    let frame = Frame::from_normal(normal);
    let origin = position + normal * ray_offset;
    let mut rng = SplitMix64::for_vertex(seed, stream, u64::from(pass));
    let mut strata = Stratified::new(rays);
    while let Some((u, v)) = strata.next(&mut rng) {
        let local = hemisphere_direction(sampling, u, v);
        let ray = Ray::new(origin, frame.to_world(local), f32::INFINITY);
        f(&BakeRay { ray, local });
    }
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
    let all = 0..mesh.vertex_count();
    bake_impl(
        mesh,
        normals,
        caster,
        options,
        Targets::Vertices(all),
        cfg!(feature = "parallel"),
    )
}

/// The part of [`bake`] that holds `vertices`: a set of those vertices only,
/// whose every value equals bit for bit the one a whole bake with the same options
/// gives (each vertex draws from its own random streams), so the sets of
/// consecutive ranges joined by [`TransferSet::concat`] are the whole bake. With
/// bounces, every pass but the last still runs over every vertex (a bounce reads
/// every vertex's previous pass); the last pass, and the result, cover the range.
/// This is how a bake is split across machines.
pub fn bake_vertices<C: RayCaster + Sync + ?Sized>(
    mesh: &MeshView<'_>,
    normals: &[Vec3],
    caster: &C,
    options: &BakeOptions<'_>,
    vertices: core::ops::Range<usize>,
) -> Result<TransferSet, BakeError> {
    check_range(&vertices, mesh.vertex_count())?;
    bake_impl(
        mesh,
        normals,
        caster,
        options,
        Targets::Vertices(vertices),
        cfg!(feature = "parallel"),
    )
}

/// [`bake`] on the calling thread only.
pub fn bake_serial<C: RayCaster + Sync + ?Sized>(
    mesh: &MeshView<'_>,
    normals: &[Vec3],
    caster: &C,
    options: &BakeOptions<'_>,
) -> Result<TransferSet, BakeError> {
    bake_impl(
        mesh,
        normals,
        caster,
        options,
        Targets::Vertices(0..mesh.vertex_count()),
        false,
    )
}

/// Bakes the transfer of `points` (lightmap texels, probes) against `mesh`
/// instead of its vertices: the set holds one entry per point, in order, with
/// the point's position and normal. Each point draws its rays from its own
/// random streams, so a point's result does not depend on the others, and the
/// set is identical serial or parallel (`parallel` runs on rayon's pool with
/// the `parallel` feature).
///
/// With bounces, pass `k` at a point reads pass `k - 1` at the hit as `reads`
/// says: [`BounceReads::Vertices`] interpolates the mesh's vertices' pass (every
/// pass but the last also runs over the vertices, as [`bake`]'s do, so the cost
/// is the points' `bounces + 1` passes plus the vertices' `bounces`);
/// [`BounceReads::Points`] reads the points' own pass at the point a hit maps to
/// (a lightmap's texels: only the points' passes run).
///
/// Errors: those of [`bake`], [`BakeError::NoVertices`] for no points, and
/// [`BakeError::Point`] for a point whose position is not finite or whose normal
/// is not unit length.
pub fn bake_points<C: RayCaster + Sync + ?Sized>(
    mesh: &MeshView<'_>,
    normals: &[Vec3],
    caster: &C,
    points: &[BakePoint],
    reads: BounceReads<'_>,
    options: &BakeOptions<'_>,
    parallel: bool,
) -> Result<TransferSet, BakeError> {
    check_points(points)?;
    bake_impl(
        mesh,
        normals,
        caster,
        options,
        Targets::Points(points, reads, 0..points.len()),
        parallel,
    )
}

/// The part of [`bake_points`] that holds the points in `kept`: a set of those
/// only, each value bit for bit the one the whole bake gives (each point draws
/// from its own random streams), so the sets of consecutive ranges joined by
/// [`TransferSet::concat`] are the whole bake. With bounces every pass but the
/// last still runs over every point (a bounce may read any of them). This is
/// how a lightmap bake is split across machines; it runs on rayon's pool with
/// the `parallel` feature.
///
/// Errors: those of [`bake_points`], and [`BakeError::VertexRange`] when `kept`
/// is empty or runs past the points.
pub fn bake_point_range<C: RayCaster + Sync + ?Sized>(
    mesh: &MeshView<'_>,
    normals: &[Vec3],
    caster: &C,
    points: &[BakePoint],
    reads: BounceReads<'_>,
    options: &BakeOptions<'_>,
    kept: core::ops::Range<usize>,
) -> Result<TransferSet, BakeError> {
    check_range(&kept, points.len())?;
    check_points(points)?;
    bake_impl(
        mesh,
        normals,
        caster,
        options,
        Targets::Points(points, reads, kept),
        cfg!(feature = "parallel"),
    )
}

/// [`BakeError::VertexRange`] unless `range` is a non-empty range of `len`
/// vertices or points.
fn check_range(range: &core::ops::Range<usize>, len: usize) -> Result<(), BakeError> {
    if range.is_empty() || range.end > len {
        return Err(BakeError::VertexRange {
            start: range.start,
            end: range.end,
            vertices: len,
        });
    }
    Ok(())
}

/// [`BakeError::NoVertices`], [`BakeError::TooManyVertices`] or
/// [`BakeError::Point`] for points a bake cannot start from.
fn check_points(points: &[BakePoint]) -> Result<(), BakeError> {
    if points.is_empty() {
        return Err(BakeError::NoVertices);
    }
    if points.len() > u32::MAX as usize {
        return Err(BakeError::TooManyVertices(points.len()));
    }
    match points
        .iter()
        .position(|p| !p.position.is_finite() || !unit_normal(p.normal))
    {
        Some(index) => Err(BakeError::Point { index }),
        None => Ok(()),
    }
}

fn bake_impl<C: RayCaster + Sync + ?Sized>(
    mesh: &MeshView<'_>,
    normals: &[Vec3],
    caster: &C,
    options: &BakeOptions<'_>,
    targets: Targets<'_>,
    parallel: bool,
) -> Result<TransferSet, BakeError> {
    let coeffs = validate(mesh, normals, options)?;
    let vertices = mesh.vertex_count();
    let kept = match &targets {
        Targets::Vertices(range) => range.len(),
        Targets::Points(_, _, kept) => kept.len(),
    };
    let (kind, projection, grid) = match options.measurement {
        Measurement::Diffuse => (TransferKind::Diffuse, Projection::None, 0),
        Measurement::GlossySh => (TransferKind::GlossySh, Projection::World, 0),
        Measurement::Mrt { grid, .. } => (TransferKind::Mrt, Projection::Local, grid),
    };
    let sampling = sampling_of(&options.measurement);
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
    // The big buffers first, fallibly: a grid and band count inside their
    // ranges can still ask for more memory than there is on a large mesh (MRT
    // at grid 64 and 8 bands is 1 MiB per vertex), and that must be an error
    // before any ray, not an abort after the rays.
    let rows = (grid * grid) as usize;
    let mut out = match options.measurement {
        Measurement::Mrt { .. } => zeros(kept.checked_mul(rows * coeffs))?,
        _ => Vec::new(),
    };
    let sites = match &targets {
        Targets::Vertices(_) => vertices,
        Targets::Points(points, _, _) => points.len(),
    };
    let mut measured = zeros(sites.checked_mul(gathered))?;
    let mut previous = Vec::new();
    let done = AtomicUsize::new(0);
    let total = match &targets {
        Targets::Vertices(_) => vertices * options.bounces as usize + kept,
        Targets::Points(points, BounceReads::Vertices, _) => {
            (vertices + points.len()) * options.bounces as usize + kept
        }
        Targets::Points(points, BounceReads::Points(_), _) => {
            points.len() * options.bounces as usize + kept
        }
    };
    let report = options.progress;
    let progress = |count: usize| {
        let d = done.fetch_add(count, Ordering::Relaxed) + count;
        if let Some(report) = report {
            report(d, total);
        }
    };
    for pass in 0..=options.bounces {
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
            reads: match &targets {
                Targets::Points(_, reads, _) => *reads,
                Targets::Vertices(_) => BounceReads::Vertices,
            },
        };
        // The last pass only for the sites kept; earlier ones for every vertex,
        // which the next pass reads.
        let last = pass == options.bounces;
        // This pass at every site it covers: the vertices or the points (the
        // last pass only those in range).
        let site = |index: usize| match &targets {
            Targets::Vertices(range) => {
                (!last || range.contains(&index)).then(|| Site::vertex(mesh, normals, index))
            }
            Targets::Points(points, _, kept) => (!last || kept.contains(&index)).then(|| Site {
                position: points[index].position,
                normal: points[index].normal,
                stream: POINT_STREAMS | index as u64,
            }),
        };
        let mut irradiance = zeros(sites.checked_mul(coeffs))?;
        let work = |index: usize, irr: &mut [f32], meas: &mut [f32]| {
            if let Some(site) = site(index) {
                gather(&ctx, site, irr, meas);
                progress(1);
            }
        };
        run_vertices(
            parallel,
            &mut irradiance,
            coeffs,
            &mut measured,
            gathered,
            &work,
        );
        if projection == Projection::None {
            for (m, e) in measured.iter_mut().zip(&irradiance) {
                *m += *e;
            }
        }
        // What the next pass's bounces read: this pass, or, for points that
        // read the mesh's vertices, the vertices' own pass (irradiance only).
        previous = match &targets {
            Targets::Points(_, BounceReads::Vertices, _) if !last => {
                let mut vertex_irradiance = zeros(vertices.checked_mul(coeffs))?;
                let mut unused = zeros(Some(vertices))?;
                let ctx = PassContext {
                    projection: Projection::None,
                    reads: BounceReads::Vertices,
                    ..ctx
                };
                let work = |vertex: usize, irr: &mut [f32], meas: &mut [f32]| {
                    gather(&ctx, Site::vertex(mesh, normals, vertex), irr, meas);
                    progress(1);
                };
                run_vertices(
                    parallel,
                    &mut vertex_irradiance,
                    coeffs,
                    &mut unused,
                    1,
                    &work,
                );
                vertex_irradiance
            }
            _ => irradiance,
        };
    }
    let (Targets::Vertices(range) | Targets::Points(_, _, range)) = &targets;
    measured.truncate(range.end * gathered);
    measured.drain(..range.start * gathered);
    let data = if let Measurement::Mrt { .. } = options.measurement {
        let b = &brdf_nodes;
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
    let (positions, normals): (Vec<[f32; 3]>, Vec<[f32; 3]>) = match &targets {
        Targets::Vertices(range) => (
            range.clone().map(|v| mesh.position(v).to_array()).collect(),
            normals[range.clone()]
                .iter()
                .map(|n| n.to_array())
                .collect(),
        ),
        Targets::Points(points, _, kept) => (
            points[kept.clone()]
                .iter()
                .map(|p| p.position.to_array())
                .collect(),
            points[kept.clone()]
                .iter()
                .map(|p| p.normal.to_array())
                .collect(),
        ),
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
        positions,
        frames: super::frames_of(&normals),
        normals,
        payload: Payload::Dense(data),
        texels: None,
    })
}

/// `len` zeros, or [`BakeError::TooLarge`] when `len` (`None`: it overflowed)
/// floats cannot be allocated.
fn zeros(len: Option<usize>) -> Result<Vec<f32>, BakeError> {
    let too_large = |len: Option<usize>| BakeError::TooLarge {
        bytes: len.map_or(u64::MAX, |n| (n as u64).saturating_mul(4)),
    };
    let n = len.ok_or(too_large(len))?;
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| too_large(len))?;
    v.resize(n, 0.0);
    Ok(v)
}

type VertexWork<'a> = dyn Fn(usize, &mut [f32], &mut [f32]) + Sync + 'a;

/// Runs `work(vertex, irradiance_chunk, measured_chunk)` for every vertex.
fn run_vertices(
    parallel: bool,
    irradiance: &mut [f32],
    irr_len: usize,
    measured: &mut [f32],
    meas_len: usize,
    work: &VertexWork<'_>,
) {
    #[cfg(feature = "parallel")]
    if parallel {
        use rayon::prelude::*;
        irradiance
            .par_chunks_mut(irr_len)
            .zip(measured.par_chunks_mut(meas_len))
            .enumerate()
            .for_each(|(v, (irr, meas))| work(v, irr, meas));
        return;
    }
    let _ = parallel;
    for (v, (irr, meas)) in irradiance
        .chunks_mut(irr_len)
        .zip(measured.chunks_mut(meas_len))
        .enumerate()
    {
        work(v, irr, meas);
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

/// Where one gather happens: a mesh vertex, or a point of [`bake_points`].
#[derive(Clone, Copy)]
struct Site {
    position: Vec3,
    normal: Vec3,
    /// The random stream: the vertex index, or [`POINT_STREAMS`] plus the
    /// point's index.
    stream: u64,
}

/// The first random stream of [`bake_points`]'s points, above every vertex's,
/// so a point never repeats a vertex's rays.
const POINT_STREAMS: u64 = 1 << 63;

impl Site {
    fn vertex(mesh: &MeshView<'_>, normals: &[Vec3], vertex: usize) -> Self {
        Site {
            position: mesh.position(vertex),
            normal: normals[vertex],
            stream: vertex as u64,
        }
    }
}

/// A point [`bake_points`] gathers at instead of a mesh vertex, such as a
/// lightmap texel's receiver ([`crate::lightmap::TexelReceiver`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakePoint {
    /// Where its rays start (moved `ray_offset` along the normal first).
    pub position: Vec3,
    /// Its unit normal: the hemisphere and frame of its rays.
    pub normal: Vec3,
}

/// What the last pass of a bake covers, and so what its set holds.
enum Targets<'a> {
    /// These vertices of the mesh.
    Vertices(core::ops::Range<usize>),
    /// These points, their bounces reading as given; the result holds those
    /// in the range (every pass but the last runs over all of them).
    Points(&'a [BakePoint], BounceReads<'a>, core::ops::Range<usize>),
}

/// One pass over one vertex: writes its irradiance transfer `E_pass` and adds the
/// pass's projection to `measured`. Dispatches to [`gather_n`] compiled for the
/// coefficient count, so the SH basis per ray is the fixed-band evaluation and the
/// accumulations are fixed-size loops.
fn gather<C: RayCaster + ?Sized>(
    ctx: &PassContext<'_, C>,
    site: Site,
    irradiance: &mut [f32],
    measured: &mut [f32],
) {
    match ctx.coeffs {
        1 => gather_n::<C, 1>(ctx, site, irradiance, measured),
        4 => gather_n::<C, 4>(ctx, site, irradiance, measured),
        9 => gather_n::<C, 9>(ctx, site, irradiance, measured),
        16 => gather_n::<C, 16>(ctx, site, irradiance, measured),
        25 => gather_n::<C, 25>(ctx, site, irradiance, measured),
        36 => gather_n::<C, 36>(ctx, site, irradiance, measured),
        49 => gather_n::<C, 49>(ctx, site, irradiance, measured),
        64 => gather_n::<C, 64>(ctx, site, irradiance, measured),
        // `validate` admits only 1..=MAX_BANDS bands.
        n => unreachable!("{n} coefficients"),
    }
}

fn gather_n<C: RayCaster + ?Sized, const N: usize>(
    ctx: &PassContext<'_, C>,
    site: Site,
    irradiance: &mut [f32],
    measured: &mut [f32],
) {
    let Some(irradiance) = irradiance.first_chunk_mut::<N>() else {
        return;
    };
    let count = ctx.rays as f32;
    let albedo_over_pi = ctx.albedo / PI;
    // Projection of incident radiance on Y_i (uniform sampling, 2π/N).
    let w = 2.0 * PI / count;
    // Adds one ray's incident radiance (per lighting column) to both integrals.
    let mut accumulate = |local: Vec3, world: Vec3, contribution: &[f32; N]| {
        // Irradiance: ∫ L cos θ dω.
        let w_irr = match ctx.sampling {
            Sampling::Cosine => PI / count,
            Sampling::Uniform => 2.0 * PI * local.z / count,
        };
        for (e, c) in irradiance.iter_mut().zip(contribution) {
            *e += w_irr * c;
        }
        let basis = match ctx.projection {
            Projection::None => return,
            Projection::World => eval_basis::<N>(world),
            Projection::Local => eval_basis::<N>(local),
        };
        for (row, &yi) in measured.chunks_exact_mut(N).zip(&basis) {
            let s = w * yi;
            for (t, c) in row.iter_mut().zip(contribution) {
                *t += s * c;
            }
        }
    };
    if ctx.pass == 0 {
        // The lighting basis itself: column j of the transfer sees Y_j(ω).
        for_each_unoccluded_ray(ctx, site, |cast| {
            let world = cast.ray.direction;
            accumulate(cast.local, world, &eval_basis::<N>(world));
        });
        return;
    }
    for_each_hit(ctx, site, |cast, hit| {
        let (world, local) = (cast.ray.direction, cast.local);
        let [a, b, c] = ctx.mesh.triangle_indices(hit.triangle as usize);
        let (a, b, c) = (a as usize, b as usize, c as usize);
        let (wa, wb, wc) = (1.0 - hit.u - hit.v, hit.u, hit.v);
        let hit_normal = wa * ctx.normals[a] + wb * ctx.normals[b] + wc * ctx.normals[c];
        if hit_normal.dot(world) >= 0.0 {
            // The back of a surface: its outgoing radiance is not modelled.
            return;
        }
        let contribution: [f32; N] = match ctx.reads {
            BounceReads::Vertices => {
                let corner = |i: usize| ctx.previous[i * N..].first_chunk::<N>();
                let (Some(ea), Some(eb), Some(ec)) = (corner(a), corner(b), corner(c)) else {
                    return;
                };
                core::array::from_fn(|j| albedo_over_pi * (wa * ea[j] + wb * eb[j] + wc * ec[j]))
            }
            BounceReads::Points(lookup) => {
                let Some(e) = lookup(hit.triangle as usize, hit.u, hit.v)
                    .and_then(|p| ctx.previous.get(p * N..)?.first_chunk::<N>())
                else {
                    return;
                };
                core::array::from_fn(|j| albedo_over_pi * e[j])
            }
        };
        accumulate(local, world, &contribution);
    });
}

/// Rays of a gather traced together through [`RayCaster::occluded_many`] or
/// [`RayCaster::closest_hit_many`]: as many as one packet of the BVH holds.
const PACKET: usize = 64;

/// Calls `f`, in cast order, with each ray of `site`'s pass-0 gather that
/// nothing occludes. The rays are traced [`PACKET`] at a time in one
/// [`RayCaster::occluded_many`] call (rays from one point, traced together),
/// with the answers of [`RayCaster::occluded`], so the gather's sums are the
/// same to the bit.
fn for_each_unoccluded_ray<C: RayCaster + ?Sized>(
    ctx: &PassContext<'_, C>,
    site: Site,
    mut f: impl FnMut(&BakeRay),
) {
    let mut occluded = [false; PACKET];
    for_each_packet(ctx, site, |rays, locals| {
        let occluded = &mut occluded[..rays.len()];
        ctx.caster.occluded_many(rays, occluded);
        for ((ray, &local), _) in rays
            .iter()
            .zip(locals)
            .zip(occluded.iter())
            .filter(|(_, o)| !**o)
        {
            f(&BakeRay { ray: *ray, local });
        }
    });
}

/// Calls `f`, in cast order, with each ray of `site`'s bounce gather that hits
/// a triangle and its closest hit, traced [`PACKET`] at a time in one
/// [`RayCaster::closest_hit_many`] call. The hits are those of
/// [`RayCaster::closest_hit`] but for ties between triangles at the same `t`,
/// which either may take.
fn for_each_hit<C: RayCaster + ?Sized>(
    ctx: &PassContext<'_, C>,
    site: Site,
    mut f: impl FnMut(&BakeRay, &Hit),
) {
    let mut hits = [None; PACKET];
    for_each_packet(ctx, site, |rays, locals| {
        let hits = &mut hits[..rays.len()];
        ctx.caster.closest_hit_many(rays, hits);
        for ((ray, &local), hit) in rays.iter().zip(locals).zip(hits.iter()) {
            if let Some(hit) = hit {
                f(&BakeRay { ray: *ray, local }, hit);
            }
        }
    });
}

/// Calls `trace` with the rays of `site`'s gather in pass `ctx.pass` and their
/// local directions, [`PACKET`] at a time, in cast order.
fn for_each_packet<C: RayCaster + ?Sized>(
    ctx: &PassContext<'_, C>,
    site: Site,
    mut trace: impl FnMut(&[Ray], &[Vec3]),
) {
    let unused = Ray::new(Vec3::ZERO, Vec3::Z, 0.0);
    let mut rays = [unused; PACKET];
    let mut locals = [Vec3::Z; PACKET];
    let mut count = 0;
    for_each_ray(
        site.position,
        site.normal,
        ctx.ray_offset,
        ctx.seed,
        site.stream,
        ctx.pass,
        ctx.rays,
        ctx.sampling,
        |cast| {
            rays[count] = cast.ray;
            locals[count] = cast.local;
            count += 1;
            if count == PACKET {
                trace(&rays, &locals);
                count = 0;
            }
        },
    );
    trace(&rays[..count], &locals[..count]);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An MRT bake at grid 64 and 8 bands on 25,600 vertices needs 26.8 GB, so
    /// the buffers are reserved fallibly: a size that overflows, or that no
    /// allocator can give, is an error (a real out-of-memory depends on the
    /// machine, so it is not provoked here).
    #[test]
    fn buffers_too_large_to_allocate_are_an_error() {
        assert_eq!(zeros(None), Err(BakeError::TooLarge { bytes: u64::MAX }));
        let half = usize::MAX / 2;
        assert_eq!(
            zeros(Some(half)),
            Err(BakeError::TooLarge {
                bytes: (half as u64).saturating_mul(4)
            })
        );
        assert_eq!(zeros(Some(3)), Ok(alloc::vec![0.0; 3]));
    }
}
