//! # antumbra-core
//!
//! The algorithms of Antumbra: physically-based visibility and lighting kernels for
//! engines. This crate is always `#![no_std]` + `alloc`, so it builds for
//! microcontrollers (`thumbv7em-none-eabihf`) as well as for desktop engines.
//!
//! Modules:
//!
//! - [`geom`]: validated triangle-mesh views ([`MeshView`]) over caller-owned,
//!   possibly strided vertex data, and the receiver frame ([`Frame`]) every
//!   hemispherical algorithm uses.
//! - [`raycast`]: the [`RayCaster`] trait (any-hit occlusion on a segment and closest
//!   hit), a watertight ray–triangle test, a brute-force caster that is the obviously
//!   right reference, and, behind the `bvh` feature, a compressed wide BVH ([`raycast::BvhScene`],
//!   built with obvhs).
//! - [`hemi`]: hemispherical rasterization of whole meshes per receiver, and the
//!   spherical-harmonic transfer and shading built on it ([`sh`]).
//! - [`lightmap`]: per-texel receivers from a mesh's UV atlas (covered and
//!   touched texels, a gutter for bilinear filtering, and a lift out of
//!   geometry against leaks), for bakes stored in textures.
//! - [`ssv`]: exact soft shadows from planar area lights (soft shadow volumes with
//!   the lazily built 3D wedge hierarchy): per receiver, the visibility bits of `N`
//!   light samples, exactly the answers of `N` shadow rays, from silhouette edges,
//!   depth complexity and one reference ray ([`ssv::SoftShadows`]).
//! - [`transfer`]: precomputed radiance transfer (P1, P2): one bake engine whose
//!   configurations are diffuse PRT, glossy SH transfer and matrix radiance transfer
//!   ([`transfer::bake`]), their run-time shading, PCA compression of MRT, and a
//!   versioned, checksummed bake file format ([`transfer::TransferSet`]).
//!
//! ## Example
//!
//! ```
//! use antumbra_core::{BruteForceCaster, MeshView, Ray, RayCaster};
//! use antumbra_core::glam::Vec3;
//!
//! // A quad in the z = 1 plane, as two triangles.
//! let positions = [[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]];
//! let indices = [0, 1, 2, 0, 2, 3];
//! let mesh = MeshView::new(&positions, &indices)?;
//! let caster = BruteForceCaster::new(mesh); // or raycast::BvhScene::new(&mesh) with `bvh`
//!
//! let up = Ray::new(Vec3::ZERO, Vec3::Z, f32::INFINITY);
//! assert!(caster.occluded(&up));
//! assert_eq!(caster.closest_hit(&up).map(|hit| hit.t), Some(1.0));
//! // Segments end before t_max: this one stops short of the quad.
//! assert!(!caster.occluded(&Ray::new(Vec3::ZERO, Vec3::Z, 0.5)));
//! # Ok::<(), antumbra_core::MeshError>(())
//! ```
//!
//! ## Features
//!
//! - `std` (default): error trait interop and what the backends below need.
//! - `bvh`: the obvhs (CWBVH) ray caster.
//! - `parallel`: rayon-parallel batch entry points. Features are additive and never
//!   change numeric results.
//!
//! ## Conventions
//!
//! Right-handed coordinates, `f32` everywhere, angles in radians. A ray hits a
//! triangle at parameter `t` when `t_min < t < t_max`, with `t` measured in units
//! of the ray direction's length (directions need not be normalised).
#![no_std]
#![deny(unsafe_code)]
#![warn(missing_docs)]

// Owned structures (BVH, tables, wedge trees) allocate; kernels never do.
#[allow(unused_extern_crates)]
extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

pub mod fallible;
pub mod geom;
pub mod hemi;
pub mod lightmap;
mod prefetch;
pub mod raycast;
pub mod rng;
pub mod sh;
// Hand-written kernels: the BVH's traversal (with `bvh`) and the soft-shadow
// hierarchy's octant tests.
mod simd;
pub mod ssv;
pub mod transfer;

pub use geom::{Frame, MeshError, MeshView};
pub use raycast::{BruteForceCaster, Hit, Ray, RayCaster};

/// Re-export of the math library used in every public signature, so callers use
/// exactly the same `glam` version.
pub use glam;
