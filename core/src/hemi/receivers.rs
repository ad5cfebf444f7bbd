//! Receiver level of detail: a deforming frame rasterizes only a subset of the
//! vertices (the *key* receivers, no two within `spacing` edges of each other
//! and every vertex within `spacing` edges of one) and gives every other vertex
//! its open hemisphere's transfer less the mean occlusion of the keys around
//! it, weighted by inverse squared distance (a key's occlusion: its open transfer less
//! its rasterized one), unless those keys disagree (a shadow's edge, a
//! crease) or turn away from it, where it is rasterized too.
//!
//! Low-frequency transfer varies slowly over a finely tessellated surface, so
//! on scanned meshes many vertices take their keys' mean; the test on the
//! keys' occlusion vectors keeps the interpolation off the places where it
//! varies fast. Interpolating the occlusion rather than the transfer keeps
//! each vertex's own cosine lobe exact: only the blocked part is borrowed. The
//! subset and the weights are made once from the rest pose (the topology a
//! deforming mesh keeps); each frame only reads them.

use alloc::vec::Vec;
use core::fmt;
use core::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;

use super::batch::{
    BatchError, TransferSpace, VertexShading, VertexSurface, check, for_each_entry, shade_mask,
    shade_vertex_towards, towards_eye, usable, vertex_transfer,
};
use super::lod::scene_mask;
use super::lod::{BatchOptions, HemiScene};
use super::mask::HemiMask;
use super::shading::{glossy_transfer, mirror_direction, shade_glossy};
use super::transfer::shade_diffuse;
use super::transfer::{TransferMethod, TransferRotation, frame_matrix};
use crate::fallible;
use crate::geom::{Frame, MeshView};
use crate::sh::{MAX_COEFFS, Sh, ShRgb, ShRotation};

/// Why a [`ReceiverSampling`] could not be made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReceiverSamplingError {
    /// `spacing` is 0 or above [`ReceiverSampling::MAX_SPACING`].
    Spacing(u32),
    /// The tolerance is negative, infinite or NaN.
    Tolerance(f32),
    /// A buffer could not be allocated.
    OutOfMemory {
        /// Its size.
        bytes: usize,
    },
}

impl fmt::Display for ReceiverSamplingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ReceiverSamplingError::Spacing(s) => write!(
                f,
                "the receiver spacing is {s}; it must be 1 to {}",
                ReceiverSampling::MAX_SPACING
            ),
            ReceiverSamplingError::Tolerance(t) => {
                write!(
                    f,
                    "the receiver tolerance is {t}; it must be a finite number >= 0"
                )
            }
            ReceiverSamplingError::OutOfMemory { bytes } => {
                write!(f, "no memory for the receiver sampling ({bytes} bytes)")
            }
        }
    }
}

impl core::error::Error for ReceiverSamplingError {}

/// How a shader spares receivers ([`ShaderSetup::receivers`](super::ShaderSetup::receivers)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReceiverLod {
    /// Edges between keys, 1 to [`ReceiverSampling::MAX_SPACING`]: about a
    /// quarter of a triangle mesh's vertices are keys at 1, a tenth at 2.
    pub spacing: u32,
    /// A vertex takes its keys' mean occlusion only when every key's
    /// occlusion lies within `tolerance` times the open hemisphere's transfer
    /// of that mean (SH norms) and no key's normal turns more than
    /// [`TURN_COSINE`] away from its own; else it is rasterized.
    pub tolerance: f32,
}

/// The least cosine between a vertex's normal and a key's it may interpolate
/// from (about 37°): past that the keys' cosine lobes lean too far from its own.
pub const TURN_COSINE: f32 = 0.8;

/// One key a vertex interpolates from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeySource {
    /// Index into [`ReceiverSampling::keys`].
    pub slot: u32,
    /// Normalised weight (the weights of a vertex sum to 1).
    pub weight: f32,
}

/// Which vertices a frame rasterizes and how the others are interpolated (see
/// the module docs).
#[derive(Clone, Debug)]
pub struct ReceiverSampling {
    spacing: u32,
    keys: Vec<u32>,
    /// Each vertex's index into `keys`, or `u32::MAX` for a vertex that
    /// interpolates.
    slot_of: Vec<u32>,
    /// `starts[v]..starts[v + 1]` are vertex `v`'s sources; empty for a key.
    starts: Vec<u32>,
    sources: Vec<KeySource>,
}

/// The most keys a vertex interpolates from (the nearest; farther ones would
/// carry little weight).
const MAX_SOURCES: usize = 8;

/// The most vertices one vertex's search for keys queues: the rings within
/// `spacing + 2` edges hold a few dozen on an ordinary mesh.
const MAX_VISITS: usize = 512;

/// The fewest keys a vertex interpolates from: with one or two, the check
/// that its keys agree sees nothing across the vertex.
pub const MIN_SOURCES: usize = 3;

impl ReceiverSampling {
    /// The widest spacing, in edges.
    pub const MAX_SPACING: u32 = 4;

    /// The sampling of `mesh` (its rest pose) with keys `spacing` edges
    /// apart: a vertex is a key unless a key lies within `spacing` edges of it
    /// (greedily, in vertex order); every other vertex interpolates from the
    /// keys within `spacing + 1` edges (`spacing + 2` where fewer than
    /// [`MIN_SOURCES`] lie that close; a vertex with fewer still is
    /// rasterized every frame), weighted by the inverse squared rest distance.
    /// Vertices in no triangle are keys.
    pub fn new(mesh: &MeshView<'_>, spacing: u32) -> Result<Self, ReceiverSamplingError> {
        if spacing == 0 || spacing > Self::MAX_SPACING {
            return Err(ReceiverSamplingError::Spacing(spacing));
        }
        let oom = |bytes| ReceiverSamplingError::OutOfMemory { bytes };
        let n = mesh.vertex_count();
        let (adjacency_starts, adjacency) = adjacency(mesh).map_err(oom)?;
        let neighbours =
            |v: usize| &adjacency[adjacency_starts[v] as usize..adjacency_starts[v + 1] as usize];
        // Hop distance to the nearest key so far (capped).
        let mut distance: Vec<u8> = fallible::filled(u8::MAX, n).map_err(|_| oom(n))?;
        let mut slot_of: Vec<u32> = fallible::filled(u32::MAX, n).map_err(|_| oom(4 * n))?;
        let mut keys: Vec<u32> = Vec::new();
        let mut queue: Vec<(u32, u8)> = Vec::new();
        for v in 0..n {
            if u32::from(distance[v]) <= spacing {
                continue;
            }
            slot_of[v] = keys.len() as u32;
            fallible::push(&mut keys, v as u32).map_err(|_| oom(4 * n))?;
            distance[v] = 0;
            queue.clear();
            fallible::push(&mut queue, (v as u32, 0)).map_err(|_| oom(8 * n))?;
            let mut head = 0;
            while head < queue.len() {
                let (u, d) = queue[head];
                head += 1;
                if u32::from(d) == spacing {
                    continue;
                }
                for &w in neighbours(u as usize) {
                    if distance[w as usize] > d + 1 {
                        distance[w as usize] = d + 1;
                        fallible::push(&mut queue, (w, d + 1)).map_err(|_| oom(8 * n))?;
                    }
                }
            }
        }
        // Sources: the keys within `spacing + 1` edges, or `spacing + 2`,
        // nearest first.
        let mut starts: Vec<u32> = fallible::filled(0, n + 1).map_err(|_| oom(4 * n))?;
        let mut sources: Vec<KeySource> = Vec::new();
        let mut stamp: Vec<u32> = fallible::filled(u32::MAX, n).map_err(|_| oom(4 * n))?;
        let mut found: Vec<(f32, u32, u8)> = Vec::new();
        for v in 0..n {
            starts[v] = sources.len() as u32;
            if slot_of[v] != u32::MAX {
                continue;
            }
            let p = mesh.position(v);
            queue.clear();
            found.clear();
            stamp[v] = v as u32;
            fallible::push(&mut queue, (v as u32, 0)).map_err(|_| oom(8 * n))?;
            let mut head = 0;
            while head < queue.len() {
                let (u, d) = queue[head];
                head += 1;
                if slot_of[u as usize] != u32::MAX {
                    let gap = (mesh.position(u as usize) - p).length_squared();
                    fallible::push(&mut found, (gap, slot_of[u as usize], d))
                        .map_err(|_| oom(12 * n))?;
                }
                // Around a vertex of very high valence (a fan's centre, a UV
                // sphere's pole) the rings hold most of the mesh: stop
                // searching once enough vertices are queued.
                if u32::from(d) > spacing + 1 || queue.len() >= MAX_VISITS {
                    continue;
                }
                for &w in neighbours(u as usize) {
                    if stamp[w as usize] != v as u32 {
                        stamp[w as usize] = v as u32;
                        fallible::push(&mut queue, (w, d + 1)).map_err(|_| oom(8 * n))?;
                    }
                }
            }
            let close = found
                .iter()
                .filter(|k| u32::from(k.2) <= spacing + 1)
                .count();
            if close >= MIN_SOURCES {
                found.retain(|k| u32::from(k.2) <= spacing + 1);
            } else if found.len() < MIN_SOURCES {
                found.clear();
            }
            found.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            found.truncate(MAX_SOURCES);
            let inverse = |gap: f32| 1.0 / gap.max(f32::MIN_POSITIVE);
            let total: f32 = found.iter().map(|&(gap, _, _)| inverse(gap)).sum();
            for &(gap, slot, _) in &found {
                let weight = if total.is_finite() && total > 0.0 {
                    inverse(gap) / total
                } else {
                    1.0 / found.len() as f32
                };
                fallible::push(&mut sources, KeySource { slot, weight })
                    .map_err(|_| oom(8 * sources.len()))?;
            }
        }
        starts[n] = sources.len() as u32;
        Ok(ReceiverSampling {
            spacing,
            keys,
            slot_of,
            starts,
            sources,
        })
    }

    /// The spacing it was made with.
    pub fn spacing(&self) -> u32 {
        self.spacing
    }

    /// The key vertices, in increasing order.
    pub fn keys(&self) -> &[u32] {
        &self.keys
    }

    /// The vertices it was made for.
    pub fn vertex_count(&self) -> usize {
        self.starts.len() - 1
    }

    /// Whether `vertex` is a key.
    #[inline]
    pub fn is_key(&self, vertex: usize) -> bool {
        self.slot_of[vertex] != u32::MAX
    }

    /// The keys `vertex` interpolates from; empty for a key and for a vertex
    /// with fewer than [`MIN_SOURCES`] keys near (rasterized every frame).
    pub fn sources(&self, vertex: usize) -> &[KeySource] {
        &self.sources[self.starts[vertex] as usize..self.starts[vertex + 1] as usize]
    }
}

/// A [`ReceiverSampling`] with its tolerance and the per-frame buffer of the
/// keys' occlusion: what a shader keeps to run frames with sparse receivers.
#[derive(Clone, Debug)]
pub(super) struct SparseReceivers {
    sampling: ReceiverSampling,
    tolerance: f32,
    /// Per key, [`MAX_COEFFS`] floats: the world-space occlusion, the open
    /// hemisphere's transfer minus the key's, in the first `N`. With shading,
    /// [`SHADING_STRIDE`] floats per key instead (see [`Self::shade`]).
    occlusion: Vec<f32>,
}

/// Floats per key when shading: the diffuse and the glossy occlusion (up to
/// [`MAX_COEFFS`] each) and the key's own diffuse and glossy colours.
const SHADING_STRIDE: usize = 2 * MAX_COEFFS + 6;

impl SparseReceivers {
    /// The sampling of `mesh` for `lod`, with its buffer (room for
    /// [`Self::shade`] when `shading`).
    pub(super) fn new(
        mesh: &MeshView<'_>,
        lod: ReceiverLod,
        shading: bool,
    ) -> Result<Self, ReceiverSamplingError> {
        if !(lod.tolerance >= 0.0 && lod.tolerance.is_finite()) {
            return Err(ReceiverSamplingError::Tolerance(lod.tolerance));
        }
        let sampling = ReceiverSampling::new(mesh, lod.spacing)?;
        let per_key = if shading { SHADING_STRIDE } else { MAX_COEFFS };
        let floats = sampling.keys.len().saturating_mul(per_key);
        let occlusion = fallible::filled(0.0, floats)
            .map_err(|_| ReceiverSamplingError::OutOfMemory { bytes: 4 * floats })?;
        Ok(SparseReceivers {
            sampling,
            tolerance: lod.tolerance,
            occlusion,
        })
    }

    /// The sampling.
    pub(super) fn sampling(&self) -> &ReceiverSampling {
        &self.sampling
    }

    /// [`transfer_batch`](super::transfer_batch)'s output with only the keys
    /// and the vertices whose keys disagree rasterized; returns how many
    /// receivers were. Keys and rasterized vertices get exactly
    /// [`vertex_transfer`]'s vector; the others `R_v open − Σ w_k occlusion_k`
    /// in world space (`R_v` the vertex's frame rotation, the occlusion of key
    /// `k` being `R_k open − transfer_k`), moved to the local frame when asked.
    /// Allocation-free.
    pub(super) fn transfer<const N: usize, T>(
        &mut self,
        scene: &HemiScene<'_>,
        normals: &[Vec3],
        options: &BatchOptions<'_>,
        method: TransferMethod<'_, N>,
        space: TransferSpace,
        out: &mut [T],
    ) -> Result<usize, BatchError>
    where
        T: From<Sh<N>> + Copy + Send + Sync,
        Sh<N>: From<T>,
    {
        check(scene, normals, out.len())?;
        if self.sampling.vertex_count() != out.len() {
            return Err(BatchError::OutputLength {
                expected: self.sampling.vertex_count(),
                got: out.len(),
            });
        }
        let mesh = scene.mesh.mesh;
        let sampling = &self.sampling;
        let exact = |v: usize| -> Sh<N> {
            let n = normals[v];
            if usable(n) {
                vertex_transfer(scene, mesh.position(v), n, options, method, space)
            } else {
                Sh::ZERO
            }
        };
        // The keys, exactly.
        for_each_entry(out, options.parallel, |v, o| {
            if sampling.is_key(v) {
                *o = T::from(exact(v));
            }
        });
        // Their occlusion in world space; NaN (so every vertex reading it is
        // rasterized) for a key without a usable normal.
        let open = method.transfer(&HemiMask::EMPTY);
        let keys = sampling.keys.len();
        let (occlusion, _) = self.occlusion[..keys * N].as_chunks_mut::<N>();
        let read: &[T] = out;
        for_each_entry(occlusion, options.parallel, |slot, o| {
            let v = sampling.keys[slot] as usize;
            let n = normals[v];
            *o = if usable(n) {
                let rotation = TransferRotation::new(&Frame::from_normal(n));
                let own = Sh::<N>::from(read[v]);
                match space {
                    TransferSpace::World => (rotation.to_world(&open) - own).coeffs,
                    TransferSpace::Local => rotation.to_world(&(open - own)).coeffs,
                }
            } else {
                [f32::NAN; N]
            };
        });
        let occlusion: &[[f32; N]] = occlusion;
        // Compared squared: no square root per key.
        let limit = self.tolerance * self.tolerance * open.dot(&open);
        let rasterized = AtomicUsize::new(keys);
        for_each_entry(out, options.parallel, |v, o| {
            if sampling.is_key(v) {
                return;
            }
            let n = normals[v];
            if !usable(n) {
                *o = T::from(Sh::ZERO);
                return;
            }
            let agreed = agreed_mean(
                sampling.sources(v),
                |slot| Sh::new(occlusion[slot]),
                limit,
                |slot| normals[sampling.keys[slot] as usize].dot(n) >= TURN_COSINE,
            );
            *o = T::from(if let Some(mean) = agreed {
                let frame = Frame::from_normal(n);
                match space {
                    TransferSpace::World => TransferRotation::new(&frame).to_world(&open) - mean,
                    TransferSpace::Local => {
                        open - ShRotation::<N>::new(frame_matrix(&frame).transpose()).apply(&mean)
                    }
                }
            } else {
                rasterized.fetch_add(1, Ordering::Relaxed);
                exact(v)
            });
        });
        Ok(rasterized.into_inner())
    }
}

impl SparseReceivers {
    /// [`shade_batch_per_vertex`](super::shade_batch_per_vertex)'s output
    /// with only the keys and the vertices whose keys disagree rasterized;
    /// returns how many receivers were. Keys and rasterized vertices get
    /// exactly its colours. Every other vertex is shaded from borrowed
    /// occlusion: its diffuse transfer is `R_v open − Σ w_k D_k` and its
    /// glossy one `R_v G_v − Σ w_k O_k`, with `G_v` the open hemisphere's
    /// glossy transfer about its own mirror direction and `D_k`, `O_k` key
    /// `k`'s world-space diffuse and glossy occlusion (the open transfer less
    /// the rasterized one, about the key's own mirror direction). A vertex with
    /// a glossy term is rasterized unless every key has one with the same
    /// lobe, and the glossy gaps pass the test the diffuse ones do, measured
    /// against `|G_v|`. Allocation-free; the shader must have been set up for
    /// shading (else [`BatchError::OutputLength`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn shade<'m, const N: usize>(
        &mut self,
        scene: &HemiScene<'_>,
        normals: &[Vec3],
        options: &BatchOptions<'_>,
        method: TransferMethod<'_, N>,
        lighting: &ShRgb<N>,
        surface: impl Fn(usize) -> VertexSurface<'m> + Sync,
        out: &mut [VertexShading],
    ) -> Result<usize, BatchError> {
        check(scene, normals, out.len())?;
        let keys = self.sampling.keys.len();
        // A shader set up without shading has no shading buffer either, so
        // `check` refused it already; this guards direct use.
        if self.sampling.vertex_count() != out.len() || self.occlusion.len() < keys * SHADING_STRIDE
        {
            return Err(BatchError::OutputLength {
                expected: self.sampling.vertex_count(),
                got: out.len(),
            });
        }
        let mesh = scene.mesh.mesh;
        let sampling = &self.sampling;
        let table = method.table();
        let open = method.transfer(&HemiMask::EMPTY);
        let stride = 2 * N + 6;
        // The keys: their colours and their occlusion, from one mask each.
        let buffer = &mut self.occlusion[..keys * stride];
        for_each_chunk(buffer, stride, options.parallel, |slot, chunk| {
            let v = sampling.keys[slot] as usize;
            let n = normals[v];
            chunk.fill(f32::NAN);
            if !usable(n) {
                chunk[2 * N..].fill(0.0);
                return;
            }
            let position = mesh.position(v);
            let here = surface(v);
            let to_eye = towards_eye(&here, position);
            let mask = scene_mask(scene, position, n, options);
            let parts = shade_mask(&mask, n, method, lighting, &here.material, to_eye);
            // As the world-space transfer frames compute it (the same bits).
            let blocked = parts.rotation.to_world(&open) - parts.rotation.to_world(&parts.transfer);
            chunk[..N].copy_from_slice(&blocked.coeffs);
            // A key whose viewer is behind it (or at it) has no glossy lobe
            // to lend: its NaN makes its dependents rasterize.
            if let (Some((mirror, glossy)), Some(lobe)) = (parts.glossy, here.material.lobe)
                && mirror.is_finite()
                && mirror.z >= 0.0
            {
                let unblocked = glossy_transfer(table, &HemiMask::EMPTY, lobe, mirror);
                chunk[N..2 * N]
                    .copy_from_slice(&parts.rotation.to_world(&(unblocked - glossy)).coeffs);
            }
            let VertexShading { diffuse, glossy } = parts.shading;
            chunk[2 * N..2 * N + 3].copy_from_slice(&diffuse.to_array());
            chunk[2 * N + 3..2 * N + 6].copy_from_slice(&glossy.to_array());
        });
        let buffer: &[f32] = buffer;
        let key = |slot: usize| &buffer[slot * stride..(slot + 1) * stride];
        let diffuse_of = |chunk: &[f32]| Sh::<N>::new(core::array::from_fn(|i| chunk[i]));
        let glossy_of = |chunk: &[f32]| Sh::<N>::new(core::array::from_fn(|i| chunk[N + i]));
        let limit = self.tolerance * self.tolerance * open.dot(&open);
        let tolerance = self.tolerance;
        let rasterized = AtomicUsize::new(keys);
        for_each_entry(out, options.parallel, |v, o| {
            if sampling.is_key(v) {
                let chunk = key(sampling.slot_of[v] as usize);
                *o = VertexShading {
                    diffuse: Vec3::from_slice(&chunk[2 * N..]),
                    glossy: Vec3::from_slice(&chunk[2 * N + 3..]),
                };
                return;
            }
            let n = normals[v];
            if !usable(n) {
                *o = VertexShading::default();
                return;
            }
            let sources = sampling.sources(v);
            let position = mesh.position(v);
            let here = surface(v);
            let material = &here.material;
            let to_eye = towards_eye(&here, position);
            let glossy_lobe = material.lobe.filter(|_| material.specular != Vec3::ZERO);
            let frame = Frame::from_normal(n);
            let diffuse_mean = agreed_mean(
                sources,
                |slot| diffuse_of(key(slot)),
                limit,
                |slot| normals[sampling.keys[slot] as usize].dot(n) >= TURN_COSINE,
            );
            // This vertex's glossy lobe, when it has one: a viewer behind it
            // (or at it) sees no glossy term, as in the exact path.
            let lobe_here = glossy_lobe.and_then(|lobe| {
                let mirror = frame.to_local(mirror_direction(n, to_eye));
                (mirror.is_finite() && mirror.z >= 0.0).then_some((lobe, mirror))
            });
            // The rotation and the open glossy lobe only for vertices whose
            // keys agree on the diffuse occlusion.
            let borrowed = diffuse_mean.and_then(|diffuse_mean| {
                let rotation = TransferRotation::new(&frame);
                let glossy = match lobe_here {
                    None => None,
                    Some((lobe, mirror)) => {
                        let unblocked = rotation.to_world(&glossy_transfer(
                            table,
                            &HemiMask::EMPTY,
                            lobe,
                            mirror,
                        ));
                        let glossy_limit = tolerance * tolerance * unblocked.dot(&unblocked);
                        let same_lobe = |slot: usize| {
                            let k = sampling.keys[slot] as usize;
                            surface(k)
                                .material
                                .lobe
                                .is_some_and(|l| core::ptr::eq(l, lobe))
                        };
                        let mean = agreed_mean(
                            sources,
                            |slot| glossy_of(key(slot)),
                            glossy_limit,
                            same_lobe,
                        )?;
                        Some(unblocked - mean)
                    }
                };
                Some((rotation, diffuse_mean, glossy))
            });
            *o = if let Some((rotation, diffuse_mean, glossy)) = borrowed {
                let diffuse = shade_diffuse(
                    &(rotation.to_world(&open) - diffuse_mean),
                    lighting,
                    material.albedo,
                );
                let glossy = match glossy {
                    Some(glossy) => shade_glossy(&glossy, lighting, material.specular),
                    None => Vec3::ZERO,
                };
                VertexShading { diffuse, glossy }
            } else {
                rasterized.fetch_add(1, Ordering::Relaxed);
                shade_vertex_towards(
                    scene, position, n, options, method, lighting, material, to_eye,
                )
            };
        });
        Ok(rasterized.into_inner())
    }
}

/// The weighted mean of the keys' vectors (`vector(slot)`) when every key
/// passes `accept(slot)` and lies within `limit` (a squared SH norm) of it;
/// `None` otherwise, and for a vertex without keys. A NaN vector refuses.
#[inline]
fn agreed_mean<const N: usize>(
    sources: &[KeySource],
    vector: impl Fn(usize) -> Sh<N>,
    limit: f32,
    accept: impl Fn(usize) -> bool,
) -> Option<Sh<N>> {
    let mut mean = Sh::<N>::ZERO;
    for s in sources {
        mean += vector(s.slot as usize) * s.weight;
    }
    let agree = !sources.is_empty()
        && sources.iter().all(|s| {
            let gap = vector(s.slot as usize) - mean;
            // Written so that NaN refuses.
            gap.dot(&gap) <= limit && accept(s.slot as usize)
        });
    agree.then_some(mean)
}

/// `f(k, chunk k)` for every `stride`-float chunk of `buffer`, over rayon's
/// pool when `parallel` is set and the `parallel` feature is on.
fn for_each_chunk(
    buffer: &mut [f32],
    stride: usize,
    parallel: bool,
    f: impl Fn(usize, &mut [f32]) + Sync,
) {
    #[cfg(feature = "parallel")]
    if parallel {
        use rayon::prelude::*;
        buffer
            .par_chunks_exact_mut(stride)
            .enumerate()
            .with_min_len(4)
            .for_each(|(k, chunk)| f(k, chunk));
        return;
    }
    let _ = parallel;
    for (k, chunk) in buffer.chunks_exact_mut(stride).enumerate() {
        f(k, chunk);
    }
}

/// The mesh's vertex adjacency (each undirected edge once per end), as
/// starts and neighbours.
fn adjacency(mesh: &MeshView<'_>) -> Result<(Vec<u32>, Vec<u32>), usize> {
    let n = mesh.vertex_count();
    let indices = mesh.indices();
    // Twice the corners per vertex; the starts are u32, so a mesh of more
    // than about 700 million triangles is refused as memory it would take.
    let entries = indices.len().saturating_mul(2);
    if entries > u32::MAX as usize {
        return Err(entries.saturating_mul(4));
    }
    let mut degree: Vec<u32> = fallible::filled(0, n + 1).map_err(|_| 4 * n)?;
    for t in indices.chunks_exact(3) {
        for k in 0..3 {
            degree[t[k] as usize] += 2;
        }
    }
    let mut starts: Vec<u32> = fallible::filled(0, n + 1).map_err(|_| 4 * n)?;
    let mut total = 0u32;
    for v in 0..n {
        starts[v] = total;
        total += degree[v];
    }
    starts[n] = total;
    let mut neighbours: Vec<u32> =
        fallible::filled(u32::MAX, total as usize).map_err(|_| 4 * total as usize)?;
    let mut fill: Vec<u32> = fallible::copied(&starts).map_err(|_| 4 * n)?;
    for t in indices.chunks_exact(3) {
        for k in 0..3 {
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            for w in [b, c] {
                neighbours[fill[a as usize] as usize] = w;
                fill[a as usize] += 1;
            }
        }
    }
    // Each edge is listed by both its triangles: drop the repeats (and
    // degenerate self-loops) in place.
    let mut compact: Vec<u32> = fallible::filled(0, n + 1).map_err(|_| 4 * n)?;
    let mut out = 0usize;
    for v in 0..n {
        let (s, e) = (starts[v] as usize, starts[v + 1] as usize);
        neighbours[s..e].sort_unstable();
        compact[v] = out as u32;
        let mut last = u32::MAX;
        for i in s..e {
            let w = neighbours[i];
            if w != last && w as usize != v {
                neighbours[out] = w;
                out += 1;
            }
            last = w;
        }
    }
    compact[n] = out as u32;
    neighbours.truncate(out);
    Ok((compact, neighbours))
}

#[cfg(test)]
mod tests {
    use super::super::test_meshes::{bumpy_sphere, normals_of};
    use super::super::{HemiShader, ShaderSetup, TransferTable, transfer_batch};
    use super::*;
    use alloc::vec;

    fn options(parallel: bool) -> BatchOptions<'static> {
        BatchOptions {
            normal_offset: 0.005,
            parallel,
            ..BatchOptions::default()
        }
    }

    /// Hop distances from `from` in `mesh`, by breadth-first search.
    fn hops(mesh: &MeshView<'_>, from: usize) -> Vec<u32> {
        let mut distance = vec![u32::MAX; mesh.vertex_count()];
        distance[from] = 0;
        let mut frontier = vec![from];
        let mut d = 0;
        while !frontier.is_empty() {
            d += 1;
            let mut next = Vec::new();
            for t in mesh.indices().chunks_exact(3) {
                for k in 0..3 {
                    let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
                    for (u, w) in [(a, b), (b, a)] {
                        if frontier.contains(&u) && distance[w] == u32::MAX {
                            distance[w] = d;
                            next.push(w);
                        }
                    }
                }
            }
            frontier = next;
        }
        distance
    }

    #[test]
    fn keys_are_spaced_and_every_vertex_reaches_one() {
        let (positions, indices) = bumpy_sphere(10, 16, 0.2, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        for spacing in 1..=3 {
            let sampling = ReceiverSampling::new(&mesh, spacing).unwrap();
            assert_eq!(sampling.spacing(), spacing);
            let keys = sampling.keys();
            assert!(keys.windows(2).all(|w| w[0] < w[1]));
            let from_keys: Vec<Vec<u32>> = keys.iter().map(|&k| hops(&mesh, k as usize)).collect();
            for (i, d) in from_keys.iter().enumerate() {
                for (j, &other) in keys.iter().enumerate() {
                    if i != j {
                        assert!(d[other as usize] > spacing, "keys {i} and {j} too close");
                    }
                }
            }
            for v in 0..mesh.vertex_count() {
                let nearest = from_keys.iter().map(|d| d[v]).min().unwrap();
                assert!(
                    nearest <= spacing,
                    "vertex {v} is {nearest} edges from a key"
                );
                let sources = sampling.sources(v);
                assert_eq!(sampling.is_key(v), nearest == 0);
                if sampling.is_key(v) {
                    assert!(sources.is_empty());
                    continue;
                }
                if sources.is_empty() {
                    let near = from_keys.iter().filter(|d| d[v] <= spacing + 2).count();
                    assert!(near < MIN_SOURCES, "vertex {v} has {near} keys near");
                    continue;
                }
                assert!((MIN_SOURCES..=MAX_SOURCES).contains(&sources.len()));
                let total: f32 = sources.iter().map(|s| s.weight).sum();
                assert!((total - 1.0).abs() < 1e-5, "weights of {v} sum to {total}");
                let close = from_keys.iter().filter(|d| d[v] <= spacing + 1).count();
                let reach = if close >= MIN_SOURCES {
                    spacing + 1
                } else {
                    spacing + 2
                };
                for s in sources {
                    assert!(from_keys[s.slot as usize][v] <= reach);
                }
            }
            // Wider spacing, fewer keys.
            if spacing > 1 {
                let closer = ReceiverSampling::new(&mesh, spacing - 1).unwrap();
                assert!(keys.len() < closer.keys().len());
            }
        }
        assert_eq!(
            ReceiverSampling::new(&mesh, 0).unwrap_err(),
            ReceiverSamplingError::Spacing(0)
        );
        assert!(ReceiverSampling::new(&mesh, ReceiverSampling::MAX_SPACING + 1).is_err());
    }

    /// The rule by hand from every vertex's exact world transfer: keys and
    /// disagreeing vertices exact, the rest the open hemisphere less their
    /// keys' weighted occlusion.
    fn by_hand(
        sampling: &ReceiverSampling,
        exact: &[Sh<9>],
        normals: &[Vec3],
        open: Sh<9>,
        tolerance: f32,
    ) -> (Vec<Sh<9>>, usize) {
        let open_world = |n: Vec3| TransferRotation::new(&Frame::from_normal(n)).to_world(&open);
        let mut rasterized = 0;
        let out = (0..exact.len())
            .map(|v| {
                if sampling.is_key(v) {
                    rasterized += 1;
                    return exact[v];
                }
                let occlusion = |s: &KeySource| {
                    let k = sampling.keys()[s.slot as usize] as usize;
                    open_world(normals[k]) - exact[k]
                };
                let mut mean = Sh::ZERO;
                for s in sampling.sources(v) {
                    mean += occlusion(s) * s.weight;
                }
                let limit = tolerance * open.dot(&open).sqrt();
                let agree = !sampling.sources(v).is_empty()
                    && sampling.sources(v).iter().all(|s| {
                        let gap = occlusion(s) - mean;
                        let k = sampling.keys()[s.slot as usize] as usize;
                        gap.dot(&gap).sqrt() <= limit && normals[k].dot(normals[v]) >= TURN_COSINE
                    });
                if agree {
                    open_world(normals[v]) - mean
                } else {
                    rasterized += 1;
                    exact[v]
                }
            })
            .collect();
        (out, rasterized)
    }

    #[test]
    fn sparse_frames_are_exact_at_keys_and_the_rule_elsewhere() {
        let (rest, indices) = bumpy_sphere(64, 96, 0.15, 0.0);
        let rest_mesh = MeshView::new(&rest, &indices).unwrap();
        let table = TransferTable::<9>::new();
        let method = TransferMethod::Cells(&table);
        let open = method.transfer(&HemiMask::EMPTY);
        for (spacing, tolerance) in [(1, 0.05), (2, 0.1), (2, 0.0)] {
            let lod = ReceiverLod { spacing, tolerance };
            let setup = ShaderSetup {
                receivers: Some(lod),
                ..ShaderSetup::default()
            };
            let mut shader = HemiShader::new(&rest_mesh, None, &setup).unwrap();
            let (positions, _) = bumpy_sphere(64, 96, 0.15, 0.6);
            let mesh = MeshView::new(&positions, &indices).unwrap();
            let normals = normals_of(&mesh);
            let mut exact = vec![Sh::<9>::ZERO; mesh.vertex_count()];
            let scene = HemiScene::new(super::super::ClusteredMesh::unclustered(mesh));
            transfer_batch(
                &scene,
                &normals,
                &options(false),
                method,
                TransferSpace::World,
                &mut exact,
            )
            .unwrap();
            let sampling = shader.receiver_sampling().unwrap().clone();
            let (want, want_rasterized) = by_hand(&sampling, &exact, &normals, open, tolerance);
            let mut frame = shader.frame(mesh, None, None).unwrap();
            let mut got = vec![Sh::<9>::ZERO; mesh.vertex_count()];
            let mut local = vec![Sh::<9>::ZERO; mesh.vertex_count()];
            let mut pooled = vec![Sh::<9>::ZERO; mesh.vertex_count()];
            let rasterized = frame
                .transfer(&options(false), method, TransferSpace::World, &mut got)
                .unwrap();
            frame
                .transfer(&options(false), method, TransferSpace::Local, &mut local)
                .unwrap();
            frame
                .transfer(&options(true), method, TransferSpace::World, &mut pooled)
                .unwrap();
            assert_eq!(got, pooled, "the pool changes nothing");
            assert_eq!(
                rasterized, want_rasterized,
                "spacing {spacing}, tolerance {tolerance}"
            );
            assert!(
                rasterized < mesh.vertex_count(),
                "no vertex interpolated with spacing {spacing}, tolerance {tolerance}"
            );
            let scale = open.dot(&open).sqrt();
            let (mut squared, mut mean) = (0.0f64, 0.0f64);
            for v in 0..mesh.vertex_count() {
                if sampling.is_key(v) || want[v] == exact[v] {
                    assert_eq!(got[v], exact[v], "vertex {v} is rasterized");
                }
                let gap = got[v] - want[v];
                assert!(gap.dot(&gap).sqrt() <= 1e-5 * scale, "vertex {v}");
                // The local vector is the world one in the vertex's frame.
                let frame = Frame::from_normal(normals[v]);
                let back = TransferRotation::new(&frame).to_world(&local[v]) - got[v];
                assert!(back.dot(&back).sqrt() <= 1e-4 * scale, "vertex {v}, local");
                let error = f64::from(got[v][0] - exact[v][0]);
                squared += error * error;
                mean += f64::from(exact[v][0]);
            }
            // Where occlusion varies smoothly, a vertex's lies within its
            // keys' spread, at most `tolerance` of the open transfer from their
            // mean: the ambient occlusion's RMS error stays under that.
            let n = mesh.vertex_count() as f64;
            let relative = (squared / n).sqrt() / (mean / n);
            let bound = f64::from(tolerance.max(0.01) * scale) / (mean / n);
            assert!(relative <= bound, "spacing {spacing}: {relative} > {bound}");
        }
    }

    #[test]
    fn keys_without_a_normal_leave_their_vertices_rasterized() {
        let (positions, indices) = bumpy_sphere(16, 24, 0.25, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let table = TransferTable::<4>::new();
        let method = TransferMethod::Cells(&table);
        let lod = ReceiverLod {
            spacing: 1,
            tolerance: 1.0,
        };
        let setup = ShaderSetup {
            receivers: Some(lod),
            ..ShaderSetup::default()
        };
        let mut shader = HemiShader::new(&mesh, None, &setup).unwrap();
        let sampling = shader.receiver_sampling().unwrap().clone();
        let mut normals: Vec<[f32; 3]> = normals_of(&mesh).iter().map(|n| n.to_array()).collect();
        let blind = sampling.keys()[sampling.keys().len() / 2] as usize;
        normals[blind] = [0.0; 3];
        let mut plain = HemiShader::new(&mesh, None, &ShaderSetup::default()).unwrap();
        let mut exact = vec![[0.0f32; 4]; mesh.vertex_count()];
        plain
            .frame(mesh, Some(&normals), None)
            .unwrap()
            .transfer(&options(false), method, TransferSpace::World, &mut exact)
            .unwrap();
        let mut got = vec![[0.0f32; 4]; mesh.vertex_count()];
        shader
            .frame(mesh, Some(&normals), None)
            .unwrap()
            .transfer(&options(false), method, TransferSpace::World, &mut got)
            .unwrap();
        assert_eq!(got[blind], [0.0; 4]);
        let mut dependents = 0;
        for v in 0..mesh.vertex_count() {
            if sampling
                .sources(v)
                .iter()
                .any(|s| sampling.keys()[s.slot as usize] as usize == blind)
            {
                assert_eq!(got[v], exact[v], "vertex {v} reads the blind key");
                dependents += 1;
            }
        }
        assert!(dependents > 0);
    }

    #[test]
    fn sparse_shading_is_exact_at_keys_and_borrows_occlusion_elsewhere() {
        use super::super::{Material, PhongLobe, VertexSurface};
        let (rest, indices) = bumpy_sphere(64, 96, 0.15, 0.0);
        let rest_mesh = MeshView::new(&rest, &indices).unwrap();
        let table = TransferTable::<9>::new();
        let method = TransferMethod::Cells(&table);
        let (positions, _) = bumpy_sphere(64, 96, 0.15, 0.6);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut light = ShRgb::<9>::ZERO;
        light.r[0] = 1.0;
        light.g[0] = 0.8;
        light.b[0] = 0.6;
        light.r[2] = 0.5;
        light.b[3] = -0.3;
        let (sharp, broad) = (PhongLobe::new(20.0).unwrap(), PhongLobe::new(4.0).unwrap());
        let material = |lobe: Option<&'static PhongLobe>| Material {
            albedo: Vec3::new(0.8, 0.6, 0.4),
            specular: Vec3::splat(0.3),
            lobe,
            eye: Vec3::new(0.5, -4.0, 2.0),
        };
        // 'static lobes for the closures below.
        let sharp: &'static PhongLobe = alloc::boxed::Box::leak(alloc::boxed::Box::new(sharp));
        let broad: &'static PhongLobe = alloc::boxed::Box::leak(alloc::boxed::Box::new(broad));
        let lod = ReceiverLod {
            spacing: 1,
            tolerance: 0.1,
        };
        let shading = ShaderSetup {
            shading: true,
            ..ShaderSetup::default()
        };
        let mut plain = HemiShader::new(&rest_mesh, None, &shading).unwrap();
        let mut sparse = HemiShader::new(
            &rest_mesh,
            None,
            &ShaderSetup {
                receivers: Some(lod),
                ..shading
            },
        )
        .unwrap();
        let sampling = sparse.receiver_sampling().unwrap().clone();
        let n = mesh.vertex_count();
        for (what, lobes) in [
            ("matte", [None, None]),
            ("glossy", [Some(sharp), Some(sharp)]),
            ("two lobes", [Some(sharp), Some(broad)]),
        ] {
            let surface = |v: usize| VertexSurface {
                material: material(lobes[v % 2]),
                to_eye: None,
            };
            let exact = plain
                .frame(mesh, None, None)
                .unwrap()
                .shade(&options(false), method, &light, surface)
                .unwrap()
                .to_vec();
            let mut frame = sparse.frame(mesh, None, None).unwrap();
            let got = frame
                .shade(&options(false), method, &light, surface)
                .unwrap()
                .to_vec();
            let rasterized = frame.rasterized();
            let pooled = frame
                .shade(&options(true), method, &light, surface)
                .unwrap()
                .to_vec();
            assert_eq!(got, pooled, "{what}: the pool changes nothing");
            let mut transfer = vec![Sh::<9>::ZERO; n];
            frame
                .transfer(&options(false), method, TransferSpace::World, &mut transfer)
                .unwrap();
            let same = (0..n).filter(|&v| got[v] == exact[v]).count();
            assert!(
                same >= rasterized && rasterized < n,
                "{what}: {same} exact, {rasterized} rasterized of {n}"
            );
            let (mut diffuse_error, mut glossy_error) = (0.0f64, 0.0f64);
            let (mut diffuse_total, mut glossy_total) = (0.0f64, 0.0f64);
            for v in 0..n {
                if sampling.is_key(v) {
                    assert_eq!(got[v], exact[v], "{what}: key {v}");
                }
                if got[v] != exact[v] {
                    // Interpolated: its diffuse is the sparse transfer's
                    // (the same borrowed occlusion), whose keys agreed too.
                    let m = material(lobes[v % 2]);
                    let diffuse = shade_diffuse(&transfer[v], &light, m.albedo);
                    assert_eq!(got[v].diffuse, diffuse, "{what}: vertex {v}");
                }
                diffuse_error += f64::from((got[v].diffuse - exact[v].diffuse).length_squared());
                glossy_error += f64::from((got[v].glossy - exact[v].glossy).length_squared());
                diffuse_total += f64::from(exact[v].diffuse.length_squared());
                glossy_total += f64::from(exact[v].glossy.length_squared());
            }
            if what == "glossy" {
                // A key facing away from the viewer has no glossy lobe to
                // lend (its mirror direction is below its horizon).
                let eye = material(None).eye;
                let normals = normals_of(&mesh);
                let faces_viewer = |k: usize| normals[k].dot(eye - mesh.position(k)) >= 0.0;
                let borrowing_from_the_back = (0..n)
                    .filter(|&v| got[v] != exact[v] && normals[v].dot(eye - mesh.position(v)) > 0.0)
                    .filter(|&v| {
                        sampling
                            .sources(v)
                            .iter()
                            .any(|s| !faces_viewer(sampling.keys()[s.slot as usize] as usize))
                    })
                    .count();
                assert_eq!(borrowing_from_the_back, 0, "{what}");
            }
            if what == "two lobes" {
                // A vertex borrows only from keys with its own lobe (some
                // do: along a ring of the sphere indices keep their parity).
                // (A vertex facing away from the viewer has no glossy term,
                // and borrows only diffuse occlusion.)
                let eye = material(None).eye;
                let normals = normals_of(&mesh);
                let borrowed: Vec<usize> = (0..n)
                    .filter(|&v| got[v] != exact[v])
                    .filter(|&v| normals[v].dot(eye - mesh.position(v)) > 0.0)
                    .collect();
                assert!(!borrowed.is_empty(), "{what}: nothing interpolated");
                for &v in &borrowed {
                    for k in sampling.sources(v) {
                        let key = sampling.keys()[k.slot as usize] as usize;
                        assert_eq!(key % 2, v % 2, "vertex {v} borrows from key {key}");
                    }
                }
            }
            // The borrowed occlusion lies within the tolerance of the open
            // transfer from each key's, so the colours' RMS error stays under it.
            let bound = f64::from(lod.tolerance);
            assert!(
                (diffuse_error / diffuse_total).sqrt() <= bound,
                "{what}: diffuse"
            );
            if glossy_total > 0.0 {
                assert!(
                    (glossy_error / glossy_total).sqrt() <= bound,
                    "{what}: glossy"
                );
            }
        }
    }

    #[test]
    fn bad_settings_are_refused_and_the_old_one_stays() {
        let (positions, indices) = bumpy_sphere(8, 12, 0.2, 0.0);
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let mut shader = HemiShader::new(&mesh, None, &ShaderSetup::default()).unwrap();
        let good = ReceiverLod {
            spacing: 2,
            tolerance: 0.1,
        };
        shader.set_receivers(&mesh, Some(good)).unwrap();
        for (spacing, tolerance) in [
            (0, 0.1),
            (5, 0.1),
            (1, f32::NAN),
            (1, -0.5),
            (1, f32::INFINITY),
        ] {
            let e = shader
                .set_receivers(&mesh, Some(ReceiverLod { spacing, tolerance }))
                .unwrap_err();
            assert!(matches!(e, super::super::ShaderError::Receivers(_)), "{e}");
            assert_eq!(shader.receiver_sampling().unwrap().spacing(), 2);
        }
        shader.set_receivers(&mesh, None).unwrap();
        assert!(shader.receiver_sampling().is_none());
    }
}
