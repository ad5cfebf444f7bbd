//! The precomputed half-space table: the paper's method (Kautz, Lehtinen and Aila
//! 2004, §3), where a triangle costs three table reads and a few ANDs, and the
//! rule by which table quality rasterizes some triangle edges exactly instead.
//!
//! # One octant of plane normals
//!
//! The valid disk and the cell grid are symmetric under `u → -u` (cell `i` ↔
//! `31 - i`) and `v → -v` (row `j` ↔ `31 - j`), and the half-space predicate is
//! exactly equivariant under them: `u_{31-i} = -u_i` in `f32`, so the mask of
//! `(-x, y, z)` is the mask of `(x, y, z)` with every row's bits reversed
//! (`u32::reverse_bits`), and the mask of `(x, -y, z)` is it with the rows in
//! reverse order. With `M(-m) = VALID & !M(m)` for the third sign, every plane
//! normal folds into the octant `x, y, z >= 0`.
//!
//! A normal `m` first picks its canonical sign `g = ±m` (`g.z > 0`, or `g.z = 0`
//! and `g.y > 0`, or `g.z = g.y = 0` and `g.x >= 0`; exactly one of `m`, `-m` is
//! canonical, and both pick the same `g` bit for bit), then the octant point
//! `(|g.x|, |g.y|, |g.z|)` goes to the triangle `p = |g.x| / l1`, `q = |g.y| / l1`
//! (`l1 = |g.x| + |g.y| + |g.z|`, the octahedral map of the octant). The
//! triangle carries a vertex-centred grid of `n` points per side, `(p, q) = (k,
//! l) / (n - 1)` with `k + l <= n - 1`: `n (n + 1) / 2` distinct normals, each
//! with the exact half-space mask ([`half_space_mask`]) of the integer normal
//! `(k, l, n-1-k-l)`, looked up by rounding to the nearest grid point. The mask
//! is then mapped back: rows reversed when `g.y < 0` (a shuffle in the fused AND
//! loop), bits reversed when `g.x < 0`, complemented when `g = -m`. x86-64 has
//! no bit-reverse instruction, and reversing at lookup time (about 20 SSE2
//! operations per four rows) costs more than the memory saved, so each mask is
//! stored next to its bit-reversed copy: `n (n + 1) × 128` bytes. The octant holds a quarter of a
//! half sphere's normals, so with the copies the table takes half the memory of
//! a half-sphere table of the same density. Entry `(k, l)` is at `2 (l (2n - l +
//! 1) / 2 + k)`, its mirror next.
//!
//! Invariants:
//! - `m` and `-m` read the same entry with the same mirrors and give exact
//!   complements (`lookup(m) | lookup(-m) = VALID`, `&` empty), signed zeros
//!   included: shared mesh edges neither leave pinholes nor overlap in table
//!   mode. The price is the tie rule: the exact closed half-spaces of `m` and `-m`
//!   share the cells exactly on the plane, the table's never do.
//! - Grid points on the octant's boundary have normals exactly on the symmetry
//!   planes (`k = 0`: `x = 0`; `l = 0`: `y = 0`), whose exact masks are
//!   themselves mirror-symmetric, so `lookup` is exactly equivariant under both
//!   mirrors, whatever the sign of a zero component.
//! - Every normal is within [`HalfSpaceTable::max_error`] (an angle, computed when
//!   the table is built) of the normal of the entry it reads: the table's plane
//!   lies within that angle of the true one, so only cells that close to the
//!   plane can be wrong.
//!
//! # Exact edges
//!
//! A triangle from the table is the AND of three quantised planes, which no
//! longer meet at the triangle's corners: the table's triangle lies between the
//! true one shrunk and grown about its incenter by `1 ∓ max_error / inradius`.
//! That is harmless for triangles much larger than the error, but a receiver on
//! the Stanford armadillo sees about 14,000 triangles, 80 % of them under two
//! degrees across, and each becomes a blob or spike of the error's size; along
//! silhouettes those are wrong cells (the pure 2 MiB table agrees with Embree
//! on only 97.5 % of the armadillo's cells, 84 % at 132 KiB). Long edges have
//! the opposite problem: their band of possibly wrong cells grows with their
//! length, which dominates on soups, where every edge is a silhouette.
//!
//! So table quality rasterizes an edge's plane exactly when the edge's angular
//! length `ℓ` (seen from the center of projection) is short,
//! `ℓ < 4√3 max_error` (the table's error would exceed half the inradius of an
//! equilateral triangle with that edge), or long, `ℓ max_error > 1/256` (the band
//! of possibly wrong directions along it would exceed one cell's solid angle),
//! and reads the table for the edges in between
//! ([`HalfSpaceTable::default_exact_edges`], [`HalfSpaceTable::with_exact_edges`]).
//! The rule depends on the edge alone (its two corners, in either order, bit for
//! bit), so the two triangles sharing an edge treat it the same way and their
//! masks stay complements across it; how the mixed triangles are rasterized
//! cheaply is in [`TriangleCone::mask_table`](super::TriangleCone::mask_table).
//! The two thresholds meet at `max_error = 0.0237` (`n ≈ 91`): coarser tables
//! rasterize every edge exactly.
//!
//! The table is built once (about 4 ms at the default size) into one allocation
//! and only read afterwards, so it can be shared by every thread.

use alloc::boxed::Box;
use alloc::collections::TryReserveError;
use alloc::vec::Vec;

use glam::{BVec4A, Vec3, Vec4};

use super::half_space::{half_space_mask, normalize_exponent};
use super::mask::{GRID, HemiMask};

/// The tangent-squared test of an angle threshold, without square roots.
#[derive(Clone, Copy, Debug, PartialEq)]
struct AngleTest {
    /// `sin²` and `cos²` of the threshold.
    sin2: f32,
    cos2: f32,
    /// The threshold is above a right angle.
    obtuse: bool,
}

impl AngleTest {
    fn new(angle: f32) -> Self {
        let angle = if angle.is_nan() {
            0.0
        } else {
            angle.clamp(0.0, core::f32::consts::PI)
        };
        let (s, c) = (libm::sinf(angle), libm::cosf(angle));
        AngleTest {
            sin2: s * s,
            cos2: c * c,
            obtuse: angle > core::f32::consts::FRAC_PI_2,
        }
    }

    /// [`AngleTest::below`] on four lanes, the same expressions.
    #[inline(always)]
    fn below_four(&self, s2: Vec4, d: Vec4) -> BVec4A {
        let (lhs, rhs) = (s2 * self.cos2, d * d * self.sin2);
        if self.obtuse {
            d.cmpge(Vec4::ZERO) | lhs.cmpgt(rhs)
        } else {
            d.cmpgt(Vec4::ZERO) & lhs.cmplt(rhs)
        }
    }

    /// Whether the angle between `p` and `q` is below the threshold, from
    /// `s2 = |p×q|²` and `d = p·q` (so `tan² = s2 / d²`).
    #[inline(always)]
    fn below(&self, s2: f32, d: f32) -> bool {
        // Non-short-circuit operators: no branches on the data.
        let (lhs, rhs) = (s2 * self.cos2, d * d * self.sin2);
        if self.obtuse {
            (d >= 0.0) | (lhs > rhs)
        } else {
            (d > 0.0) & (lhs < rhs)
        }
    }
}

/// Masks of half-spaces for one octant of plane normals (see the module docs),
/// looked up by nearest entry, and the rule for which triangle edges table
/// quality rasterizes exactly.
#[derive(Clone, PartialEq)]
pub struct HalfSpaceTable {
    /// Grid points per side of the octant triangle, `n >= 2`.
    resolution: usize,
    /// `n (n + 1)` masks: grid point `(k, l)`'s at `2 i` and its `u` mirror
    /// (bits reversed) at `2 i + 1`, `i = l (2n - l + 1) / 2 + k`.
    masks: Box<[HemiMask]>,
    /// Largest angle between a normal and its entry's normal (radians).
    max_error: f32,
    /// Edges shorter / longer than these angles (radians) are exact.
    shorter_than: f32,
    longer_than: f32,
    short: AngleTest,
    long: AngleTest,
    long_enabled: bool,
}

impl core::fmt::Debug for HalfSpaceTable {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("HalfSpaceTable")
            .field("resolution", &self.resolution)
            .field("size_bytes", &self.size_bytes())
            .field("max_error", &self.max_error)
            .field("shorter_than", &self.shorter_than)
            .field("longer_than", &self.longer_than)
            .finish()
    }
}

impl Default for HalfSpaceTable {
    /// A table of [`HalfSpaceTable::DEFAULT_RESOLUTION`] points per side with the
    /// default exact edges.
    fn default() -> Self {
        Self::new(Self::DEFAULT_RESOLUTION)
    }
}

/// One entry as a lookup maps it back: row `j` of the plane's mask is
/// `rows[j ^ v] ^ flip` (then ANDed with [`HemiMask::VALID`]), where `v` is 31
/// when `mirror_v` (rows in reverse order) and 0 otherwise. The `u` mirror is
/// already in `rows`: the table stores each mask next to its bit-reversed copy.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Entry<'t> {
    pub(crate) rows: &'t [u32; GRID],
    pub(crate) flip: u32,
    pub(crate) mirror_v: bool,
}

impl Entry<'_> {
    /// Row `j` of the mapped-back mask, before the final `VALID`.
    #[inline(always)]
    pub(crate) fn row(&self, j: usize) -> u32 {
        let v = if self.mirror_v { GRID - 1 } else { 0 };
        self.rows[j ^ v] ^ self.flip
    }
}

/// `out[j] = a(j) & b(j) & c(j) & VALID[j]` for three entries, with their row
/// orders fixed at compile time so the loop vectorises (a reversed row order is
/// one shuffle per vector).
#[inline(always)]
fn and3<const RA: bool, const RB: bool, const RC: bool>(
    a: &Entry<'_>,
    b: &Entry<'_>,
    c: &Entry<'_>,
) -> [u32; GRID] {
    let (ra, rb, rc) = (a.rows, b.rows, c.rows);
    let (fa, fb, fc) = (a.flip, b.flip, c.flip);
    let pick = |rows: &[u32; GRID], reversed: bool, j: usize| {
        if reversed {
            rows[GRID - 1 - j]
        } else {
            rows[j]
        }
    };
    let mut out = [0u32; GRID];
    for (j, (out, valid)) in out.iter_mut().zip(HemiMask::VALID.rows).enumerate() {
        *out = (pick(ra, RA, j) ^ fa) & (pick(rb, RB, j) ^ fb) & (pick(rc, RC, j) ^ fc) & valid;
    }
    out
}

/// The AND of three mapped-back entries (and [`HemiMask::VALID`]): one fused
/// loop per combination of row orders.
#[inline(always)]
pub(crate) fn and_entries(a: &Entry<'_>, b: &Entry<'_>, c: &Entry<'_>) -> [u32; GRID] {
    match (a.mirror_v, b.mirror_v, c.mirror_v) {
        (false, false, false) => and3::<false, false, false>(a, b, c),
        (false, false, true) => and3::<false, false, true>(a, b, c),
        (false, true, false) => and3::<false, true, false>(a, b, c),
        (false, true, true) => and3::<false, true, true>(a, b, c),
        (true, false, false) => and3::<true, false, false>(a, b, c),
        (true, false, true) => and3::<true, false, true>(a, b, c),
        (true, true, false) => and3::<true, true, false>(a, b, c),
        (true, true, true) => and3::<true, true, true>(a, b, c),
    }
}

/// An entry whose mask is every valid cell: the neutral element of
/// [`and_entries`], for callers with fewer than three table planes.
pub(crate) const ALL: Entry<'static> = Entry {
    rows: &HemiMask::VALID.rows,
    flip: 0,
    mirror_v: false,
};

impl HalfSpaceTable {
    /// Grid points per side of the default table: 128, so 8,256 normals and
    /// 2 MiB (with the bit-reversed copies); `max_error` 0.0167 rad, exact edges
    /// below 6.6° and above 13.4°.
    ///
    /// Accuracy by size (`cargo test -p antumbra-core --lib
    /// table_size_versus_wrong_cells -- --nocapture` for the wrong cells of 20,000
    /// random half-space masks against [`half_space_mask`], of 812 cells; `cargo
    /// test -p antumbra-tests --test embree_hemi -- --nocapture` for the agreement
    /// with Embree, 300 vertex receivers per mesh, in the order bunny / teapot /
    /// armadillo / 5,000-triangle soup):
    ///
    /// | n   | memory  | max error | wrong cells mean / max | exact edges  | pure table: agreement %         | default rule: agreement %          |
    /// |-----|---------|-----------|------------------------|--------------|---------------------------------|------------------------------------|
    /// | 32  | 132 KiB | 0.0684    | 6.75 / 26              | all          | 98.62 / 99.11 / 84.09 / 96.78   | 100 / 100 / 100 / 100              |
    /// | 45  | 259 KiB | 0.0482    | 4.71 / 19              | all          | 99.08 / 99.48 / 89.23 / 97.65   | 100 / 100 / 100 / 100              |
    /// | 64  | 520 KiB | 0.0337    | 3.29 / 16              | all          | 99.47 / 99.69 / 93.25 / 98.28   | 100 / 100 / 100 / 100              |
    /// | 91  | 1 MiB   | 0.0236    | 2.30 / 16              | < 9.4°, > 9.5° | 99.67 / 99.80 / 95.81 / 98.71 | 99.997 / 99.999 / 99.9996 / 99.997 |
    /// | 128 | 2 MiB   | 0.0167    | 1.64 / 11              | < 6.6°, > 13.4° | 99.79 / 99.87 / 97.49 / 99.08 | 99.955 / 99.974 / 99.966 / 99.866 |
    /// | 181 | 4 MiB   | 0.0118    | 1.16 / 10              | < 4.7°, > 19.0° | 99.88 / 99.93 / 98.58 / 99.36 | 99.943 / 99.970 / 99.950 / 99.805 |
    /// | 256 | 8 MiB   | 0.0083    | 0.80 / 8               | < 3.3°, > 27.0° | 99.91 / 99.95 / 99.20 / 99.53 | 99.940 / 99.967 / 99.950 / 99.769 |
    ///
    /// Wrong cells per mask halve when the memory quadruples (they lie in a band
    /// along the plane as wide as the error). The pure table needs 8 MiB to pass
    /// 99.5 % on the soup and never does on the armadillo; the default rule
    /// passes on all four from the smallest table. Up to `n = 91` the two
    /// thresholds meet, every edge is exact and table quality equals exact
    /// quality (its exact paths are cheaper than [`TriangleCone::mask_exact`],
    /// see [`TriangleCone::mask_table`]); 128 is the smallest table that still
    /// serves a real share of edges (14 % of the bunny's, 36 % of the teapot's,
    /// 41 % of the soup's) while staying within 0.15 % of Embree on every mesh.
    /// Larger tables take more edges from the table and lose accuracy.
    ///
    /// [`TriangleCone::mask_table`]: super::TriangleCone::mask_table
    /// [`TriangleCone::mask_exact`]: super::TriangleCone::mask_exact
    pub const DEFAULT_RESOLUTION: u32 = 128;

    /// Largest accepted resolution: `1024 × 1025 / 2` normals, 128 MiB with the
    /// bit-reversed copies.
    pub const MAX_RESOLUTION: u32 = 1024;

    /// Builds the table with `resolution` grid points per side of the octant,
    /// clamped to `2..=MAX_RESOLUTION`: `resolution (resolution + 1) × 128` bytes
    /// (each normal's mask and its bit-reversed copy), and the default exact
    /// edges for its error ([`default_exact_edges`](Self::default_exact_edges)).
    /// Aborts like any Rust allocation when memory runs out;
    /// [`HalfSpaceTable::try_new`] reports it.
    pub fn new(resolution: u32) -> Self {
        match Self::try_new(resolution) {
            Ok(table) => table,
            Err(_) => alloc::alloc::handle_alloc_error(core::alloc::Layout::new::<HemiMask>()),
        }
    }

    /// Builds the table, reporting failure to allocate it instead of aborting.
    pub fn try_new(resolution: u32) -> Result<Self, TryReserveError> {
        let n = resolution.clamp(2, Self::MAX_RESOLUTION) as usize;
        let count = n * (n + 1) / 2;
        let mut masks = Vec::new();
        masks.try_reserve_exact(2 * count)?;
        let mut max_error = 0.0f64;
        for l in 0..n {
            for k in 0..n - l {
                let mask = half_space_mask(entry_normal(n, k, l));
                masks.push(mask);
                // The u mirror, the mask of (-k, l, n-1-k-l), stored alongside:
                // x86-64 has no bit-reverse instruction, and reversing rows at
                // lookup time costs more than the extra memory.
                masks.push(HemiMask {
                    rows: mask.rows.map(u32::reverse_bits),
                });
                max_error = max_error.max(region_error(n, k, l));
            }
        }
        // The f32 lookup can round a normal within an ulp or so of a region's
        // border into the neighbouring region; 1e-6 rad covers that.
        let max_error = (max_error + 1e-6) as f32;
        let mut table = HalfSpaceTable {
            resolution: n,
            masks: masks.into_boxed_slice(),
            max_error,
            shorter_than: 0.0,
            longer_than: f32::INFINITY,
            short: AngleTest::new(0.0),
            long: AngleTest::new(core::f32::consts::PI),
            long_enabled: false,
        };
        let (shorter, longer) = Self::default_exact_edges(max_error);
        table.set_exact_edges(shorter, longer);
        Ok(table)
    }

    /// An edge shorter than this many times [`max_error`](Self::max_error) is
    /// rasterized exactly by default: `4√3`, where the table's error is half the
    /// inradius of an equilateral triangle with that edge (the table's triangle
    /// lies between the true one shrunk and grown about its incenter by the
    /// factor `1 ∓ max_error / inradius`).
    pub const SHORT_EDGE_ERRORS: f32 = 6.928_203;

    /// An edge whose band of possibly wrong directions, `length × max_error`
    /// (steradians), exceeds this is rasterized exactly by default: `1/256`, the
    /// solid angle of one cell at the zenith (a cell is 1/16 × 1/16 of the
    /// disk). About `31 × max_error` cells per radian of edge are wrong in a
    /// table plane (measured on random planes), so such an edge would average
    /// over 0.1 wrong cells on a silhouette.
    pub const LONG_EDGE_ERROR_AREA: f32 = 1.0 / 256.0;

    /// The default exact-edge angles for a table of error `max_error`: shorter
    /// than [`SHORT_EDGE_ERRORS`](Self::SHORT_EDGE_ERRORS)` × max_error`, longer
    /// than [`LONG_EDGE_ERROR_AREA`](Self::LONG_EDGE_ERROR_AREA)` / max_error`.
    pub fn default_exact_edges(max_error: f32) -> (f32, f32) {
        (
            (Self::SHORT_EDGE_ERRORS * max_error).min(core::f32::consts::FRAC_PI_2),
            Self::LONG_EDGE_ERROR_AREA / max_error,
        )
    }

    /// The same table with another rule for which triangle edges table quality
    /// rasterizes exactly instead of from the table: those whose angular length
    /// (the angle between its corners, seen from the center of projection) is
    /// below `shorter_than` or above `longer_than`, in radians.
    /// `with_exact_edges(0.0, f32::INFINITY)` gives the pure table, the paper's
    /// method.
    pub fn with_exact_edges(mut self, shorter_than: f32, longer_than: f32) -> Self {
        self.set_exact_edges(shorter_than, longer_than);
        self
    }

    fn set_exact_edges(&mut self, shorter_than: f32, longer_than: f32) {
        self.shorter_than = shorter_than;
        self.longer_than = longer_than;
        self.short = AngleTest::new(shorter_than);
        self.long_enabled = longer_than < core::f32::consts::PI;
        self.long = AngleTest::new(longer_than);
    }

    /// The exact-edge angles in force, `(shorter_than, longer_than)` (see
    /// [`with_exact_edges`](Self::with_exact_edges)).
    #[inline]
    pub fn exact_edges(&self) -> (f32, f32) {
        (self.shorter_than, self.longer_than)
    }

    /// Grid points per side of the octant triangle.
    #[inline]
    pub fn resolution(&self) -> u32 {
        self.resolution as u32
    }

    /// Bytes held by the masks: `resolution (resolution + 1) × 128` (each grid
    /// point's mask and its bit-reversed copy).
    #[inline]
    pub fn size_bytes(&self) -> usize {
        self.masks.len() * core::mem::size_of::<HemiMask>()
    }

    /// Number of grid points (distinct plane normals): `resolution (resolution +
    /// 1) / 2`.
    #[inline]
    pub fn entry_count(&self) -> usize {
        self.masks.len() / 2
    }

    /// The largest angle (radians) between a plane normal and the normal of the
    /// entry it reads: every table plane lies within this angle of the true one.
    #[inline]
    pub fn max_error(&self) -> f32 {
        self.max_error
    }

    /// The normal (unnormalised, in the octant) whose exact mask entry `(k, l)`
    /// holds, for `k + l < resolution`; `None` outside the table.
    pub fn entry_normal(&self, k: usize, l: usize) -> Option<Vec3> {
        // Checked: `k + l` wraps (or panics in debug builds) for huge indices.
        k.checked_add(l)
            .is_some_and(|sum| sum < self.resolution)
            .then(|| entry_normal(self.resolution, k, l))
    }

    /// The normal of the entry that `m` reads, mapped back (mirrored and negated
    /// as `m` was folded): the plane the table puts in place of `m`'s. `None` for
    /// a zero or non-finite `m`.
    pub fn quantized_normal(&self, m: Vec3) -> Option<Vec3> {
        let (g, flip) = canonical(normalize_exponent(m));
        let (k, l) = self.grid_point(g)?;
        let e = entry_normal(self.resolution, k, l);
        let e = Vec3::new(
            if g.x < 0.0 { -e.x } else { e.x },
            if g.y < 0.0 { -e.y } else { e.y },
            e.z,
        );
        Some(if flip != 0 { -e } else { e })
    }

    /// The table's approximation of [`half_space_mask(m)`](half_space_mask): the
    /// entry nearest to `m`, mapped back. `m = 0` gives [`HemiMask::VALID`], like
    /// the exact predicate; a non-finite `m` gives an unspecified mask.
    #[inline]
    pub fn lookup(&self, m: Vec3) -> HemiMask {
        let entry = self.entry(normalize_exponent(m));
        HemiMask {
            rows: and_entries(&entry, &ALL, &ALL),
        }
    }

    /// The entry for `m` and how to map it back. `m` should be through
    /// [`normalize_exponent`] (the cone normals are); other normals only risk a
    /// worse entry, never a panic.
    #[inline(always)]
    pub(crate) fn entry(&self, m: Vec3) -> Entry<'_> {
        let (g, flip) = canonical(m);
        match self.grid_point(g) {
            Some((k, l)) => {
                let i = l * (2 * self.resolution - l + 1) / 2 + k;
                Entry {
                    rows: &self.masks[2 * i + usize::from(g.x < 0.0)].rows,
                    flip,
                    mirror_v: g.y < 0.0,
                }
            }
            // m = 0: every cell is on the plane, and inside. Non-finite: anything.
            None => ALL,
        }
    }

    /// The grid point `(k, l)` nearest to the octant point of `g`; `None` for a
    /// zero or non-finite `g`.
    #[inline(always)]
    fn grid_point(&self, g: Vec3) -> Option<(usize, usize)> {
        let (x, y, z) = (g.x.abs(), g.y.abs(), g.z.abs());
        let l1 = x + y + z;
        if !(l1 > 0.0 && l1.is_finite()) {
            return None;
        }
        let side = (self.resolution - 1) as f32;
        let scale = side / l1;
        // p, q in [0, n - 1] (up to rounding); the casts round half up and
        // saturate (a NaN from an overflowing scale gives 0, never a panic).
        let (p, q) = (x * scale, y * scale);
        let mut k = ((p + 0.5) as usize).min(self.resolution - 1);
        let mut l = ((q + 0.5) as usize).min(self.resolution - 1);
        if k + l > self.resolution - 1 {
            // Past the diagonal: the nearer of (k - 1, l) and (k, l - 1).
            if p - (k as f32) < q - (l as f32) {
                k -= 1;
            } else {
                l -= 1;
            }
            if k + l > self.resolution - 1 {
                l = self.resolution - 1 - k;
            }
        }
        Some((k, l))
    }

    /// Whether any edge can be exact (false for the pure table).
    #[inline(always)]
    pub(crate) fn has_exact_edges(&self) -> bool {
        self.long_enabled | (self.short.sin2 > 0.0)
    }

    /// For four triangles (lanes of the corners' x, y and z, relative to the
    /// center of projection): bit `k` set when every edge of triangle `k` is
    /// exact, i.e. [`HalfSpaceTable::classify_edges`] gives `exact == 0b111`,
    /// lane by lane the same expressions, so the same answer.
    #[inline(always)]
    pub(crate) fn all_edges_exact_four(&self, corners: [[Vec4; 3]; 3]) -> u32 {
        let edge = |p: [Vec4; 3], q: [Vec4; 3]| {
            let [px, py, pz] = p;
            let [qx, qy, qz] = q;
            let e = [py * qz - qy * pz, pz * qx - qz * px, px * qy - qx * py];
            let s2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
            let d = px * qx + py * qy + pz * qz;
            let short = self.short.below_four(s2, d);
            let long = if self.long_enabled {
                !self.long.below_four(s2, d)
            } else {
                BVec4A::splat(false)
            };
            short | long
        };
        let [a, b, c] = corners;
        (edge(a, b) & edge(b, c) & edge(c, a)).bitmask()
    }

    /// How table quality treats the three edges `(c0, c1)`, `(c1, c2)`, `(c2,
    /// c0)` of a triangle with corners `c` (relative to the center of
    /// projection): bit `k` of [`EdgeClasses::exact`] is set when edge `k` is
    /// short or long (see [`with_exact_edges`](Self::with_exact_edges)).
    ///
    /// Edge by edge, a function of the unordered pair of corners: `(q, p)` gets the
    /// same answer as `(p, q)` bit for bit, since `q×p = -(p×q)` and `q·p = p·q`
    /// exactly, so the two triangles of a shared edge always agree.
    #[inline(always)]
    pub(crate) fn classify_edges(&self, c: [Vec3; 3]) -> EdgeClasses {
        // The three edges side by side in four lanes (the last a copy), so the
        // arithmetic vectorises; each lane is the same expression as a scalar
        // edge would use.
        let p = [c[0], c[1], c[2], c[2]];
        let q = [c[1], c[2], c[0], c[0]];
        let mut s2 = [0.0f32; 4];
        let mut d = [0.0f32; 4];
        for k in 0..4 {
            let (p, q) = (p[k], q[k]);
            let e = [
                p.y * q.z - q.y * p.z,
                p.z * q.x - q.z * p.x,
                p.x * q.y - q.x * p.y,
            ];
            s2[k] = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
            d[k] = p.x * q.x + p.y * q.y + p.z * q.z;
        }
        let mut exact = 0u32;
        let mut spread = 0.0f32;
        for k in 0..3 {
            let short = self.short.below(s2[k], d[k]);
            let long = self.long_enabled & !self.long.below(s2[k], d[k]);
            exact |= u32::from(short | long) << k;
            // tan² of the edge's angle; an edge of 90° or more spreads without
            // bound (NaN and infinity fail the callers' `<` tests).
            let tan2 = if d[k] > 0.0 {
                s2[k] / (d[k] * d[k])
            } else {
                f32::INFINITY
            };
            spread = if tan2 > spread || tan2.is_nan() {
                tan2
            } else {
                spread
            };
        }
        EdgeClasses { exact, spread }
    }
}

/// How table quality treats a triangle's edges: see
/// [`HalfSpaceTable::classify_edges`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct EdgeClasses {
    /// Bit `k`: edge `k` is rasterized exactly.
    pub(crate) exact: u32,
    /// The largest `tan²` of the three edges' angles (infinite for an edge of
    /// 90° or more).
    pub(crate) spread: f32,
}

/// `m` or `-m`, whichever is canonical (module docs), and the XOR word: `0`, or
/// `!0` when `-m` was taken. Exactly one of `m` and `-m` is canonical unless `m`
/// is zero, and both give the same `g` bit for bit.
#[inline(always)]
fn canonical(m: Vec3) -> (Vec3, u32) {
    let keep = m.z > 0.0 || (m.z == 0.0 && (m.y > 0.0 || (m.y == 0.0 && m.x >= 0.0)));
    if keep { (m, 0) } else { (-m, u32::MAX) }
}

/// The integer normal `(k, l, n - 1 - k - l)` of grid point `(k, l)` (exact in
/// `f32` for `n <= 2^24`).
fn entry_normal(n: usize, k: usize, l: usize) -> Vec3 {
    Vec3::new(k as f32, l as f32, (n - 1 - k - l) as f32)
}

/// The largest angle between the normal of grid point `(k, l)` and a point of
/// its region: the square of side one grid step around it, clipped to the
/// triangle. The angle to a fixed direction is quasi-convex on the plane of the
/// triangle (its sublevel sets are cones cut by a plane: ellipses), so the
/// maximum is at a vertex of the clipped square.
fn region_error(n: usize, k: usize, l: usize) -> f64 {
    let side = (n - 1) as f64;
    let to_dir = |p: f64, q: f64| {
        let r = side - p - q;
        let len = crate::geom::sqrt(p * p + q * q + r * r);
        [p / len, q / len, r / len]
    };
    let center = to_dir(k as f64, l as f64);
    let angle = |d: [f64; 3]| {
        let cos = center[0] * d[0] + center[1] * d[1] + center[2] * d[2];
        libm::acos(cos.clamp(-1.0, 1.0))
    };
    // Clip the square against p >= 0, q >= 0, p + q <= side (Sutherland–Hodgman;
    // each clip adds at most one vertex, so 7 suffice).
    let (k, l) = (k as f64, l as f64);
    let mut poly = [(0.0f64, 0.0f64); 8];
    poly[..4].copy_from_slice(&[
        (k - 0.5, l - 0.5),
        (k + 0.5, l - 0.5),
        (k + 0.5, l + 0.5),
        (k - 0.5, l + 0.5),
    ]);
    let mut len = 4;
    let planes: [fn(f64, f64, f64) -> f64; 3] =
        [|p, _, _| p, |_, q, _| q, |p, q, side| side - p - q];
    for plane in planes {
        let mut out = [(0.0f64, 0.0f64); 8];
        let mut out_len = 0;
        for i in 0..len {
            let (a, b) = (poly[i], poly[(i + 1) % len]);
            let (fa, fb) = (plane(a.0, a.1, side), plane(b.0, b.1, side));
            if fa >= 0.0 {
                out[out_len] = a;
                out_len += 1;
            }
            if (fa >= 0.0) != (fb >= 0.0) {
                let t = fa / (fa - fb);
                out[out_len] = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
                out_len += 1;
            }
        }
        poly = out;
        len = out_len;
    }
    poly[..len]
        .iter()
        .map(|&(p, q)| angle(to_dir(p, q)))
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    // Printing the measured figures needs std even in --no-default-features runs.
    extern crate std;

    use super::*;
    use crate::hemi::mask::VALID_CELL_COUNT;
    use rand::{Rng, SeedableRng, rngs::SmallRng};

    #[test]
    fn four_lanes_classify_edges_as_one() {
        // Triangles of every size seen from the origin, with edges at and
        // around the thresholds of several tables (exact short and long
        // edges, the pure table, tables with only short edges exact).
        let mut rng = SmallRng::seed_from_u64(7);
        let tables = [
            HalfSpaceTable::new(16),
            HalfSpaceTable::new(128),
            HalfSpaceTable::new(24).with_exact_edges(0.0, f32::INFINITY),
            HalfSpaceTable::new(24).with_exact_edges(0.3, 0.9),
            HalfSpaceTable::new(24).with_exact_edges(2.0, 3.0),
        ];
        let (mut seen, mut all) = (0, 0);
        for _ in 0..4000 {
            let size = libm::exp2f(rng.random_range(-12.0..1.5));
            let center = random_unit(&mut rng) * rng.random_range(0.1f32..10.0);
            let triangles: [[Vec3; 3]; 4] = core::array::from_fn(|_| {
                core::array::from_fn(|_| center + random_unit(&mut rng) * size * center.length())
            });
            let lanes = |corner: usize| {
                [0, 1, 2].map(|axis| {
                    Vec4::from_array(core::array::from_fn(|k| triangles[k][corner][axis]))
                })
            };
            for table in &tables {
                let four = table.all_edges_exact_four([lanes(0), lanes(1), lanes(2)]);
                for (k, t) in triangles.iter().enumerate() {
                    let one = table.classify_edges(*t).exact == 0b111;
                    assert_eq!(four >> k & 1 == 1, one, "{table:?} {t:?}");
                    seen += 1;
                    all += usize::from(one);
                }
            }
        }
        assert!(all > seen / 10 && all < seen * 9 / 10, "{all} of {seen}");
    }

    fn random_unit(rng: &mut SmallRng) -> Vec3 {
        loop {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let l = v.length();
            if l > 1e-3 && l <= 1.0 {
                return v / l;
            }
        }
    }

    #[test]
    fn entries_hold_exact_masks_and_lookup_finds_them() {
        let table = HalfSpaceTable::new(16);
        assert_eq!(table.resolution(), 16);
        assert_eq!(table.entry_count(), 16 * 17 / 2);
        assert_eq!(table.size_bytes(), 16 * 17 * 128);
        for l in 0..16 {
            for k in 0..16 - l {
                let m = table.entry_normal(k, l).unwrap();
                assert!(m.x >= 0.0 && m.y >= 0.0 && m.z >= 0.0);
                // An entry's own normal (scaled, too), and its mirror images, find
                // the entry, mapped back exactly.
                for s in [1.0, 3.5, 1e-30, 1e30] {
                    for (sx, sy, sz) in [
                        (1.0, 1.0, 1.0),
                        (-1.0, 1.0, 1.0),
                        (1.0, -1.0, 1.0),
                        (-1.0, -1.0, -1.0),
                        (1.0, -1.0, -1.0),
                    ] {
                        let mirrored = Vec3::new(sx * m.x, sy * m.y, sz * m.z) * s;
                        assert_eq!(
                            table.lookup(mirrored),
                            half_space_mask(mirrored),
                            "entry ({k}, {l}), {mirrored:?}"
                        );
                    }
                }
            }
        }
        assert_eq!(table.entry_normal(16, 0), None);
        assert_eq!(table.entry_normal(8, 8), None);
    }

    #[test]
    fn entry_normal_is_none_when_the_indices_overflow() {
        // `k + l` wrapped to 0 < resolution in release builds (a garbage normal)
        // and panicked in debug builds.
        let table = HalfSpaceTable::new(4);
        assert_eq!(table.entry_normal(usize::MAX, 1), None);
        assert_eq!(table.entry_normal(1, usize::MAX), None);
        assert_eq!(table.entry_normal(usize::MAX, usize::MAX), None);
        assert!(table.entry_normal(3, 0).is_some());
    }

    #[test]
    fn opposite_normals_are_exact_complements() {
        let table = HalfSpaceTable::new(32);
        let mut rng = SmallRng::seed_from_u64(3);
        let mut normals: Vec<Vec3> = (0..4000).map(|_| random_unit(&mut rng)).collect();
        // On the symmetry planes and axes, with both signs of zero: where the
        // canonical sign and the mirrors are decided by the tie rules.
        for x in [0.0f32, -0.0, 0.3, -0.3] {
            for y in [0.0f32, -0.0, 0.7, -0.7] {
                for z in [0.0f32, -0.0, 0.2, -0.2] {
                    normals.push(Vec3::new(x, y, z));
                }
            }
        }
        normals.extend([Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 1.0)]);
        for m in normals {
            if m == Vec3::ZERO {
                continue;
            }
            let (pos, neg) = (table.lookup(m), table.lookup(-m));
            assert_eq!(pos & neg, HemiMask::EMPTY, "m = {m:?}");
            assert_eq!(pos | neg, HemiMask::VALID, "m = {m:?}");
            assert_eq!(
                table.quantized_normal(-m),
                table.quantized_normal(m).map(|e| -e)
            );
        }
    }

    #[test]
    fn lookup_is_equivariant_under_the_mirrors() {
        let table = HalfSpaceTable::new(24);
        let mut rng = SmallRng::seed_from_u64(9);
        let mirror_u = |mask: HemiMask| HemiMask {
            rows: mask.rows.map(u32::reverse_bits),
        };
        let mirror_v = |mut mask: HemiMask| {
            mask.rows.reverse();
            mask
        };
        for _ in 0..2000 {
            let m = random_unit(&mut rng);
            let mask = table.lookup(m);
            assert_eq!(table.lookup(Vec3::new(-m.x, m.y, m.z)), mirror_u(mask));
            assert_eq!(table.lookup(Vec3::new(m.x, -m.y, m.z)), mirror_v(mask));
        }
        // Zero components of either sign read a mirror-symmetric entry.
        for m in [Vec3::new(0.0, 0.4, 0.6), Vec3::new(-0.0, 0.4, 0.6)] {
            assert_eq!(mirror_u(table.lookup(m)), table.lookup(m));
        }
        for m in [Vec3::new(0.4, 0.0, 0.6), Vec3::new(0.4, -0.0, -0.6)] {
            assert_eq!(mirror_v(table.lookup(m)), table.lookup(m));
        }
    }

    #[test]
    fn every_normal_is_within_max_error_of_its_entry() {
        for resolution in [2, 7, 64] {
            let table = HalfSpaceTable::new(resolution);
            let mut rng = SmallRng::seed_from_u64(resolution as u64);
            let mut worst = 0.0f32;
            for _ in 0..20_000 {
                let m = random_unit(&mut rng);
                let e = table.quantized_normal(m).unwrap().normalize();
                worst = worst.max(e.dot(m).clamp(-1.0, 1.0).acos());
            }
            assert!(
                worst <= table.max_error(),
                "{resolution}: {worst} > {}",
                table.max_error()
            );
            // The bound is tight: random normals come close to it.
            assert!(worst > 0.8 * table.max_error(), "{resolution}: {worst}");
        }
    }

    #[test]
    fn degenerate_normals_do_not_panic() {
        let table = HalfSpaceTable::new(0);
        assert_eq!(table.resolution(), 2);
        assert_eq!(table.lookup(Vec3::ZERO), HemiMask::VALID);
        assert_eq!(table.lookup(-Vec3::ZERO), HemiMask::VALID);
        let table = HalfSpaceTable::new(u32::MAX);
        assert_eq!(table.resolution(), HalfSpaceTable::MAX_RESOLUTION);
        for m in [
            Vec3::NAN,
            Vec3::INFINITY,
            Vec3::new(f32::MAX, f32::MAX, 1.0),
            Vec3::new(1e-45, -1e-45, 0.0),
            Vec3::new(f32::MAX, -f32::MAX, f32::MAX),
        ] {
            let mask = table.lookup(m);
            assert_eq!(mask & HemiMask::VALID, mask);
        }
    }

    /// Wrong cells per half-space mask against [`half_space_mask`] for 20,000
    /// uniformly random normals, and each table's `max_error`. Run with
    /// `cargo test -p antumbra-core --lib table_size_versus_wrong_cells -- --nocapture`.
    #[test]
    fn table_size_versus_wrong_cells() {
        const SAMPLES: usize = 20_000;
        let mut rng = SmallRng::seed_from_u64(0x7ab1e);
        let normals: Vec<Vec3> = (0..SAMPLES).map(|_| random_unit(&mut rng)).collect();
        let exact: Vec<HemiMask> = normals.iter().map(|&m| half_space_mask(m)).collect();
        let mut previous_mean = f64::INFINITY;
        for resolution in [32, 45, 64, 91, 128, 181, 256] {
            let table = HalfSpaceTable::new(resolution);
            let (mut total, mut max) = (0u64, 0u32);
            for (&m, e) in normals.iter().zip(&exact) {
                let wrong = table.lookup(m).count_differences(e);
                total += u64::from(wrong);
                max = max.max(wrong);
            }
            let mean = total as f64 / SAMPLES as f64;
            std::println!(
                "half-space table n = {resolution:>3}: {:>5} entries, {:>8} bytes, max error \
                 {:.4} rad; wrong cells per mask: mean {mean:.2}, max {max} (of {VALID_CELL_COUNT})",
                table.entry_count(),
                table.size_bytes(),
                table.max_error(),
            );
            assert!(mean < previous_mean, "{resolution}: mean {mean}");
            previous_mean = mean;
            if resolution == HalfSpaceTable::DEFAULT_RESOLUTION {
                assert!(
                    mean < 2.0 && max <= 16,
                    "default table: mean {mean}, max {max}"
                );
            }
        }
    }
}
