//! Hemispherical rasterization (Kautz, Lehtinen and Aila, "Hemispherical
//! Rasterization for Self-Shadowing of Dynamic Objects", EGSR 2004; Lehtinen's
//! thesis §3.3): the visibility of the hemisphere above a receiver as a 32×32 bit
//! mask, built by rasterizing every triangle of the current mesh, with no
//! precomputation per mesh.
//!
//! Data flow: a receiver (position `p`, unit normal `n`, optional offset along `n`)
//! fixes the center of projection `o = p + normal_offset * n` and the frame
//! `(t, b, n)` of [`Frame::from_normal`]; each triangle, moved into that frame, is
//! a cone of directions ([`TriangleCone`]), the AND of three half-space masks; the
//! receiver's [`HemiMask`] is the OR of all of them (correct occluder fusion: a
//! direction is occluded when any triangle blocks it).
//!
//! Two qualities ([`Quality`]):
//! - exact: half-space masks solved per row and re-tested at the boundary cells, so
//!   every cell is the closed predicate `m·d >= 0` evaluated in one fixed `f32`
//!   expression ([`half_space_mask`]). A cell is occluded exactly when its direction
//!   is in the closed cone of some triangle; shared edges leave no pinholes.
//! - table: the paper's precomputed masks for quantised plane normals (one
//!   octant, [`HalfSpaceTable`]), three lookups and ANDs per triangle, except
//!   that edges short or long for the table's error are rasterized exactly (a
//!   rule on the edge alone, so shared edges stay exact complements). A few
//!   wrong cells along silhouettes; figures in
//!   [`HalfSpaceTable::DEFAULT_RESOLUTION`].
//!
//! Against Embree (tests/tests/embree_hemi.rs, 300 vertex receivers each on the
//! bunny, the teapot, the armadillo and a 5,000-triangle soup), the exact masks
//! agree on every cell; the default table on 99.955 % (bunny), 99.974 % (teapot),
//! 99.966 % (armadillo) and 99.866 % (soup).
//!
//! Cost: per receiver, every triangle is read and culled against the horizon,
//! and those above it are rasterized. Exact quality decides most small cones
//! from a cell box proven from the corners (or, for tiny cones, the rounded
//! normals) alone, scaling the normals only when a cell center is within reach
//! and testing the box's cells four at a time (see `TriangleCone::mask_exact`).
//! The proven box costs a square root and a division per corner triple and is
//! latency-bound, so both loops cull and box four cones at a time
//! (`classify_four`, the same bits as one at a time): [`rasterize_receiver`]
//! after moving each triangle's corners into the frame, the clustered loop of
//! the batch functions ([`scene_mask`], [`TriangleClusters`]) after moving each
//! vertex of a chunk once (where the time goes: the `lod` module). Figures
//! against the BVH and Embree: `antumbra bench hemi` and `cargo bench -p
//! antumbra-core --features bvh --bench hemi`.
//!
//! Integration and shading (the rest of the paper's pipeline):
//! [`TransferTable`] turns a mask into a local SH transfer vector with exact
//! per-cell integrals (also by byte lookup, [`TransferLut`], or the paper's 8×8
//! downsampling), [`TransferRotation`] and [`shade_diffuse`] shade it under world
//! SH lighting, [`glossy_transfer`] and [`PhongLobe`] add a glossy lobe about the
//! view's mirror direction, and [`transfer_batch`] / [`shade_batch`] run every
//! vertex of a deforming mesh per frame with an optional far mesh
//! ([`HemiScene`]) and cluster culling ([`TriangleClusters`]); a
//! [`HemiShader`] may rasterize only key vertices and interpolate the others
//! where their keys agree ([`ReceiverLod`]). Against ray-traced
//! references on the bunny (tests/tests/hemi_transfer.rs) the exact transfer is
//! within 1.4 % on every vertex (0.38 % mean).
//!
//! Invariants (the design's fixed conventions, hemi.md): bit `i` of `rows[j]` is
//! cell `(i, j)`, set = occluded; cell centers `u = (i + 0.5)/16 - 1`,
//! `v = (j + 0.5)/16 - 1`; valid iff `u² + v² < 1`, invalid cells always 0; the
//! cell's world direction is `u t + v b + sqrt(1 - u² - v²) n`; "occluded" means
//! the ray from `o` along it hits a triangle at some `t > 0`
//! ([`rasterize_receiver_reference`] casts exactly those rays).
//!
//! ## Receivers at mesh vertices
//!
//! With `normal_offset = 0` and `p` exactly a vertex of the mesh, every triangle
//! incident to that vertex has a corner at the center of projection: its local
//! corner is exactly `(0, 0, 0)`, its edge normals through that corner are zero,
//! and it is culled as [`Culled::Degenerate`]. That matches the ray semantics: a ray
//! leaving a point of a triangle meets it only at `t = 0`. Neighbouring triangles
//! coplanar with `p` are degenerate too or cover only cells on their plane, which
//! lies below every cell for a flat neighbourhood (the lowest cell centers are 4.4°
//! above the horizon). With a positive offset the incident triangles are ordinary
//! occluders: below the horizon where the surface is flat or convex, blocking
//! grazing directions where it is concave, which is what rays from the offset
//! point see. [`RasterOptions::skip_triangles`] removes chosen triangles (for
//! instance the incident ones, or the near ones of a coarser LOD mesh) either way.
//!
//! ## Meshes of extreme size
//!
//! The cone of a triangle is decided from cross products and the triple product
//! `(a×b)·c` of its local corners, which scale with the cube of the corners'
//! distance: in `f32` they underflow to zero for corners about `1e-13` from the
//! center of projection (the triangle was dropped as degenerate) and overflow
//! beyond about `7e12`. So [`rasterize_receiver`] and the batch functions
//! ([`scene_mask`] and the rest) move the corners into a frame scaled by one power
//! of two per receiver ([`Receiver::scaled_frame`]): 1 when every vertex of the
//! mesh (and far mesh) is within `[2^-16, 2^16]` of the center of projection in
//! its largest coordinate, as the mesh's bounding box proves, and otherwise
//! the power of two that brings that bound into `[1, 2)`. Multiplying by a power
//! of two is exact, so every sign, comparison and cell is the unscaled one's
//! wherever nothing under- or overflowed (and exactly the same for meshes of
//! ordinary size, where the factor is 1); one factor for all triangles keeps the
//! two triangles of a shared edge exactly opposite. The cost is a few operations
//! per receiver. [`TriangleCone::new`] and [`rasterize_triangles_into`] take the
//! corners as given (unscaled).

mod batch;
mod box_cells;
mod chunk;
mod clusters;
mod cone_mask;
mod far_field;
mod far_mesh;
mod half_space;
mod lod;
mod mask;
mod rays;
mod receivers;
mod shader;
mod shading;
mod table;
mod transfer;
mod triangle;
mod walk;

#[cfg(test)]
mod test_meshes;
#[cfg(test)]
mod tests;

pub use batch::{
    BatchError, Material, TransferSpace, VertexShading, VertexSurface, mask_batch, shade_batch,
    shade_batch_per_vertex, shade_batch_split, shade_vertex, shade_vertex_towards, transfer_batch,
    vertex_normals, vertex_transfer,
};
pub use clusters::{Aabb, ClusteredMesh, TriangleClusters};
pub use far_field::{FarField, FarLevels, MAX_FAR_LEVELS};
pub use far_mesh::{FarMesh, FarMeshError};
pub use half_space::{half_space_mask, half_space_mask_reference};
pub use lod::{BatchOptions, FarLevel, HemiScene, scene_mask, scene_mask_with_counts};
pub use mask::{
    GRID, HemiMask, VALID_CELL_COUNT, cell_coordinate, cell_direction, cell_directions,
    is_valid_cell,
};
pub use receivers::{
    KeySource, MIN_SOURCES, ReceiverLod, ReceiverSampling, ReceiverSamplingError, TURN_COSINE,
};
pub use shader::{FarFieldSetup, HemiShader, ShaderError, ShaderFrame, ShaderSetup};
pub use shading::{LOBE_CUTOFF, PhongLobe, glossy_transfer, mirror_direction, shade_glossy};
pub use table::HalfSpaceTable;
pub use transfer::{
    BLOCK, BLOCKS, QUADRATURE_NODES, TransferLut, TransferMethod, TransferRotation, TransferTable,
    frame_matrix, shade_diffuse,
};
pub use triangle::{Culled, TriangleCone};

use glam::Vec3;

use crate::geom::{Frame, MeshView};
use crate::raycast::{Ray, RayCaster};

/// How half-space masks are obtained.
#[derive(Clone, Copy, Debug, Default)]
pub enum Quality<'t> {
    /// Solved per row and corrected at the boundary cells: equal to the per-cell
    /// predicate ([`half_space_mask`]).
    #[default]
    Exact,
    /// Looked up in a precomputed table: a few wrong cells per edge. Not faster
    /// than `Exact` on typical meshes, whose short edges it rasterizes exactly
    /// anyway (`antumbra bench hemi` compares them).
    Table(&'t HalfSpaceTable),
}

/// Options of [`rasterize_receiver`].
#[derive(Clone, Copy, Debug)]
pub struct RasterOptions<'a> {
    /// Exact or table masks.
    pub quality: Quality<'a>,
    /// Skip triangles whose back faces the center of projection ([`Culled::BackFacing`]).
    /// Right for closed, consistently wound meshes seen from outside; wrong for open
    /// meshes and for receivers inside a closed one.
    pub cull_backfaces: bool,
    /// Distance along the normal from the receiver position to the center of
    /// projection, in mesh units (`o = p + normal_offset * n`). 0 is exact for a
    /// receiver on the surface (see the module docs); a small positive value lifts
    /// it off the surface as ray tracers do.
    pub normal_offset: f32,
    /// Triangle indices to leave out, sorted ascending (duplicates allowed); for
    /// example the triangles incident to the receiver vertex. An unsorted list
    /// skips only some of its triangles (never panics).
    pub skip_triangles: &'a [u32],
}

impl Default for RasterOptions<'_> {
    /// Exact quality, no culling, no offset, nothing skipped.
    fn default() -> Self {
        RasterOptions {
            quality: Quality::Exact,
            cull_backfaces: false,
            normal_offset: 0.0,
            skip_triangles: &[],
        }
    }
}

/// The center of projection and local frame of one receiver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Receiver {
    /// The center of projection `o = p + normal_offset * n`.
    pub origin: Vec3,
    /// The frame `(t, b, n)` of [`Frame::from_normal`].
    pub frame: Frame,
}

impl Receiver {
    /// The receiver at `position` with unit `normal`, its center of projection
    /// lifted by `normal_offset` along the normal: `o = position + normal_offset * normal`
    /// (component-wise, as written). `normal` must be unit length for the frame to
    /// be orthonormal; it is used as given.
    #[inline]
    pub fn new(position: Vec3, normal: Vec3, normal_offset: f32) -> Self {
        Receiver {
            origin: position + normal_offset * normal,
            frame: Frame::from_normal(normal),
        }
    }

    /// A world-space point relative to the center of projection, in the local
    /// frame: `frame.to_local(point - origin)`.
    #[inline]
    pub fn to_local(&self, point: Vec3) -> Vec3 {
        self.frame.to_local(point - self.origin)
    }

    /// The frame the rasterizers move corners into for meshes with the given
    /// bounding boxes ([`MeshView::bounds`]): [`Receiver::frame`] with every axis
    /// multiplied by the same power of two `s`, so that `scaled.to_local(q - o)`
    /// is `s * frame.to_local(q - o)` (exactly, wherever nothing under- or
    /// overflows). `s` is 1 when the largest coordinate of `q - o` over the boxes
    /// (an upper bound for every vertex in them) is within `[2^-16, 2^16]`, zero
    /// or not finite, and otherwise brings it into `[1, 2)` (see the module docs).
    /// Empty boxes (min above max) are ignored.
    pub fn scaled_frame(&self, bounds: impl IntoIterator<Item = (Vec3, Vec3)>) -> Frame {
        let o = self.origin;
        let extent = bounds
            .into_iter()
            .filter(|(min, max)| min.cmple(*max).all())
            .map(|(min, max)| (max - o).abs().max((min - o).abs()).max_element())
            .fold(0.0f32, f32::max);
        let s = corner_scale(extent);
        let f = &self.frame;
        Frame {
            tangent: f.tangent * s,
            bitangent: f.bitangent * s,
            normal: f.normal * s,
        }
    }

    /// The ray from the center of projection along valid cell `(i, j)`'s world
    /// direction, over `(0, +inf)`; `None` for invalid cells.
    #[inline]
    pub fn cell_ray(&self, i: usize, j: usize) -> Option<Ray> {
        cell_direction(i, j).map(|d| Ray::new(self.origin, self.frame.to_world(d), f32::INFINITY))
    }
}

/// Extents (the largest local coordinate's bound) for which corners are not
/// scaled: `[2^-16, 2^16]`. Within it the triple product of corners at the
/// extent is between about `2^-48` and `2^50`, far from underflow and overflow,
/// and meshes of ordinary size keep exactly their unscaled bits.
const UNSCALED_EXTENT: core::ops::RangeInclusive<f32> = (1.0 / 65_536.0)..=65_536.0;

/// The power of two [`Receiver::scaled_frame`] multiplies by for `extent`.
#[inline]
fn corner_scale(extent: f32) -> f32 {
    if extent == 0.0 || !extent.is_finite() || UNSCALED_EXTENT.contains(&extent) {
        return 1.0;
    }
    // extent = 1.f * 2^e (subnormals have e = -127); 2^-e for |e| <= 126.
    let e = (((extent.to_bits() >> 23) & 0xff) as i32 - 127).clamp(-126, 126);
    f32::from_bits(((127 - e) as u32) << 23)
}

/// The build of the receiver loops that every mask, transfer and shading
/// call runs on this processor: `"AVX-512"` or `"AVX2"` (on x86-64, the
/// loops compiled again for those features and chosen at run time, with the
/// same bits) or `"portable"` (as the crate is compiled). For reports:
/// timings depend on it. The environment variable `ANTUMBRA_HEMI_BUILD`,
/// read once, caps it: `portable` or `avx2` (valgrind 3.19 stops at a
/// register move of the AVX2 build; `portable` runs under it).
pub fn receiver_build() -> &'static str {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    match crate::simd::widest_build() {
        crate::simd::Build::Avx512 => return "AVX-512",
        crate::simd::Build::Avx2 => return "AVX2",
        crate::simd::Build::Portable => {}
    }
    "portable"
}

/// What happened to the triangles of one rasterization.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TriangleCounts {
    /// Triangles whose cone was rasterized.
    pub rasterized: u32,
    /// Culled as [`Culled::BelowHorizon`].
    pub below_horizon: u32,
    /// Culled as [`Culled::Degenerate`].
    pub degenerate: u32,
    /// Culled as [`Culled::BackFacing`].
    pub back_facing: u32,
    /// Left out through [`RasterOptions::skip_triangles`].
    pub skipped: u32,
    /// Nodes of the cluster hierarchy whose boxes were tested against the
    /// mask ([`scene_mask_with_counts`] on clustered meshes; 0 otherwise): the
    /// traversal's work besides the triangles.
    pub nodes: u32,
}

impl TriangleCounts {
    #[inline]
    fn count(&mut self, culled: Culled) {
        match culled {
            Culled::BelowHorizon => self.below_horizon += 1,
            Culled::Degenerate => self.degenerate += 1,
            Culled::BackFacing => self.back_facing += 1,
        }
    }
}

/// The visibility mask of the receiver at `position` with unit `normal` against
/// every triangle of `mesh`: set cells are occluded.
///
/// `normal` must be unit length (it is used as given, see [`Receiver::new`]).
/// Allocation-free; `O(triangles)`. Safe to call from many threads at once (the
/// mesh and table are only read).
pub fn rasterize_receiver(
    mesh: &MeshView<'_>,
    position: Vec3,
    normal: Vec3,
    options: &RasterOptions<'_>,
) -> HemiMask {
    rasterize_receiver_with_counts(mesh, position, normal, options).0
}

/// [`rasterize_receiver`], also reporting how many triangles were rasterized,
/// culled (by reason) and skipped.
pub fn rasterize_receiver_with_counts(
    mesh: &MeshView<'_>,
    position: Vec3,
    normal: Vec3,
    options: &RasterOptions<'_>,
) -> (HemiMask, TriangleCounts) {
    let receiver = Receiver::new(position, normal, options.normal_offset);
    chunk::rasterize_mesh_batched(
        mesh,
        &receiver,
        options.skip_triangles,
        options.cull_backfaces,
        options.quality,
    )
}

/// [`rasterize_receiver_with_counts`] one triangle at a time through
/// [`Accumulator::add`]: the slow twin of the batched loop, for tests.
#[cfg(test)]
pub(crate) fn rasterize_receiver_one_at_a_time(
    mesh: &MeshView<'_>,
    position: Vec3,
    normal: Vec3,
    options: &RasterOptions<'_>,
) -> (HemiMask, TriangleCounts) {
    let receiver = Receiver::new(position, normal, options.normal_offset);
    let cull = options.cull_backfaces;
    match options.quality {
        Quality::Exact => {
            rasterize_mesh(mesh, &receiver, options.skip_triangles, |a, b, c, acc| {
                acc.add(a, b, c, cull, TriangleCone::or_exact_into)
            })
        }
        Quality::Table(table) => {
            rasterize_mesh(mesh, &receiver, options.skip_triangles, |a, b, c, acc| {
                acc.add(a, b, c, cull, table_raster(table))
            })
        }
    }
}

/// ORs the cones of world-space `triangles`, seen from `receiver`, into `mask`:
/// the building block for callers that choose triangles themselves (LOD, spatial
/// queries). Returns the counts; `skipped` is left 0. The corners are moved into
/// the receiver's own frame, unscaled: the same cells as [`rasterize_receiver`]
/// for meshes of ordinary size, but triangles whose triple product under- or
/// overflows (corners within about `1e-13` or beyond `7e12` of the center) are
/// culled as degenerate (see the module docs).
pub fn rasterize_triangles_into<I: IntoIterator<Item = [Vec3; 3]>>(
    mask: &mut HemiMask,
    receiver: &Receiver,
    triangles: I,
    quality: Quality<'_>,
    cull_backfaces: bool,
) -> TriangleCounts {
    // Unknown bounds: the receiver's own frame (no scaling).
    let mut acc = Accumulator {
        mask: *mask,
        ..Accumulator::new(receiver, [])
    };
    match quality {
        Quality::Exact => {
            for [a, b, c] in triangles {
                acc.add(a, b, c, cull_backfaces, TriangleCone::or_exact_into);
            }
        }
        Quality::Table(table) => {
            for [a, b, c] in triangles {
                acc.add(a, b, c, cull_backfaces, table_raster(table));
            }
        }
    }
    *mask = acc.mask;
    acc.counts
}

/// The loop over a mesh's triangles, minus the skip list.
#[cfg(any(test, not(feature = "std")))]
#[inline(always)]
fn rasterize_mesh(
    mesh: &MeshView<'_>,
    receiver: &Receiver,
    skip: &[u32],
    mut add: impl FnMut(Vec3, Vec3, Vec3, &mut Accumulator<'_>),
) -> (HemiMask, TriangleCounts) {
    let mut acc = Accumulator::new(receiver, [mesh.bounds()]);
    let mut skip = skip.iter().copied().peekable();
    // Indices and corners are read here, in the loop, rather than through an
    // iterator of corner arrays: returning [Vec3; 3] through a non-inlined
    // iterator round-trips it through the stack, which cost more than the culling.
    for t in 0..mesh.triangle_count() {
        // Merge walk over the sorted skip list: O(1) per triangle.
        while skip.next_if(|&s| (s as usize) < t).is_some() {}
        if skip.next_if_eq(&(t as u32)).is_some() {
            acc.counts.skipped += 1;
            while skip.next_if_eq(&(t as u32)).is_some() {}
            continue;
        }
        let [i0, i1, i2] = mesh.triangle_indices(t);
        add(
            mesh.position(i0 as usize),
            mesh.position(i1 as usize),
            mesh.position(i2 as usize),
            &mut acc,
        );
    }
    (acc.mask, acc.counts)
}

/// Table quality as a rasterizer for [`Accumulator::add`]: the cone of the
/// local corners, its table mask ORed in.
#[inline(always)]
fn table_raster(
    table: &HalfSpaceTable,
) -> impl Fn(Vec3, Vec3, Vec3, bool, &mut HemiMask) -> Result<(), Culled> + Copy + '_ {
    move |a, b, c, cull, mask| {
        *mask |= TriangleCone::new(a, b, c, cull)?.mask_table(table);
        Ok(())
    }
}

/// A receiver's mask and counts while its triangles are added.
struct Accumulator<'r> {
    receiver: &'r Receiver,
    /// The frame corners are moved into: [`Receiver::scaled_frame`] for the
    /// meshes of this pass (the receiver's own frame when they are unknown).
    frame: Frame,
    mask: HemiMask,
    counts: TriangleCounts,
}

impl<'r> Accumulator<'r> {
    /// Empty, for triangles of meshes with the given bounds.
    #[inline]
    fn new(receiver: &'r Receiver, bounds: impl IntoIterator<Item = (Vec3, Vec3)>) -> Self {
        Accumulator {
            receiver,
            frame: receiver.scaled_frame(bounds),
            mask: HemiMask::EMPTY,
            counts: TriangleCounts::default(),
        }
    }
}

impl Accumulator<'_> {
    /// Culls or rasterizes the world-space triangle `(a, b, c)`.
    #[inline(always)]
    fn add(
        &mut self,
        a: Vec3,
        b: Vec3,
        c: Vec3,
        cull_backfaces: bool,
        raster: impl FnOnce(Vec3, Vec3, Vec3, bool, &mut HemiMask) -> Result<(), Culled>,
    ) {
        let o = self.receiver.origin;
        let (a, b, c) = (a - o, b - o, c - o);
        let frame = &self.frame;
        // The horizon test first, on the local z alone (the same expression
        // Frame::to_local uses), since it culls most triangles of a typical mesh.
        let n = frame.normal;
        if n.dot(a) <= 0.0 && n.dot(b) <= 0.0 && n.dot(c) <= 0.0 {
            self.counts.below_horizon += 1;
            return;
        }
        match raster(
            frame.to_local(a),
            frame.to_local(b),
            frame.to_local(c),
            cull_backfaces,
            &mut self.mask,
        ) {
            Ok(()) => self.counts.rasterized += 1,
            Err(culled) => self.counts.count(culled),
        }
    }
}

/// The obviously right twin of [`rasterize_receiver`]: casts the ray of every
/// valid cell ([`Receiver::cell_ray`]) with `caster` and sets the cells whose ray
/// hits something. No culling, no skipping; two-sided like every [`RayCaster`].
pub fn rasterize_receiver_reference<C: RayCaster + ?Sized>(
    caster: &C,
    position: Vec3,
    normal: Vec3,
    normal_offset: f32,
) -> HemiMask {
    let receiver = Receiver::new(position, normal, normal_offset);
    let mut mask = HemiMask::EMPTY;
    for (i, j, _) in cell_directions() {
        if receiver
            .cell_ray(i, j)
            .is_some_and(|ray| caster.occluded(&ray))
        {
            mask.set(i, j, true);
        }
    }
    mask
}
