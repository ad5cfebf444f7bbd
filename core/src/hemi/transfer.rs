//! Transfer vectors from hemisphere masks: the integration step of Kautz,
//! Lehtinen and Aila 2004 (Lehtinen's thesis §3.3), which turns a receiver's
//! [`HemiMask`] into the spherical-harmonic coefficients of its shadowed cosine,
//!
//! ```text
//! T_k = ∫_H V(ω) y_k(ω) cosθ dω     (local frame (t, b, n) of the receiver, V = 1 unoccluded)
//! ```
//!
//! Because the mask lives on the disk the hemisphere projects to by dropping `z`
//! (the Nusselt analog), `du dv = cosθ dω`, and with `V` constant on each cell
//! region `R_c`,
//!
//! ```text
//! T_k = Σ_{unoccluded valid c} W_k(c),     W_k(c) = ∫_{R_c} y_k(u, v, sqrt(1 - u² - v²)) du dv.
//! ```
//!
//! [`TransferTable`] holds `W(c)` for every cell, integrated once when the table is
//! built. The regions `R_c` partition the unit disk exactly, so the unoccluded sum is
//! the exact unoccluded transfer (`T_0 = √π/2 = 0.886227`, `T_2 = 2π/3 · 0.488603 =
//! √(π/3) = 1.023327`, band `l` zonal `A_l Y_l^0(+z)`, everything else 0):
//!
//! - a valid cell owns its square `[u ± 1/32] × [v ± 1/32]` clipped to the disk
//!   ("exact rim weights": the clipped area, not the center rule);
//! - the disk area in squares whose center is outside the disk (invalid cells, never
//!   set in a mask) goes to the nearest valid cell of the same row: everything of a
//!   row's strip left of its first valid cell belongs to that cell, everything right
//!   of its last valid cell to that one. Every row has valid cells, so nothing is lost.
//!
//! The integrals are computed in `f64` by Gauss–Legendre quadrature after the change
//! of variables `(u, v) = (cos s sin t, sin s)`, `du dv = cos²s cos t ds dt`, which
//! turns the disk into the square `[-π/2, π/2]²` and the integrand into a smooth
//! trigonometric polynomial (no `sqrt(1 - r²)` at the rim). The cell's vertical edges
//! become the curves `t = asin(u_edge / cos s)`; `s` is split where they meet the rim
//! (`cos s = |u_edge|`), and each piece is integrated after a smoothstep substitution
//! that absorbs the square-root kink there. With [`QUADRATURE_NODES`] nodes per
//! direction the cell integrals agree with a quadrature of twice as many nodes to
//! the last bit of `f32` (2.3e-10 on weights up to 3.3e-3 at 25 coefficients), the
//! band-0 weights match an independent integral of each region's clipped area to
//! 2e-8, and the unoccluded sums match the closed forms to `f32` rounding (unit
//! tests).
//!
//! Three ways to sum a mask, all returning local-frame [`Sh<N>`]:
//!
//! - [`TransferTable::transfer`]: the full sum, subtracting the occluded cells from
//!   the unoccluded total (or adding the unoccluded ones, whichever is fewer);
//! - [`TransferLut::transfer`]: per row and byte, one lookup of the pre-summed
//!   weights of the byte's occluded cells (the design's byte lookup table); equal to
//!   the full sum up to `f32` rounding of the partial sums;
//! - [`TransferTable::transfer_downsampled`]: the paper's 4×4 block downsampling, an
//!   8×8 grid of coverage values (unoccluded fraction of each block's valid cells)
//!   times the blocks' integrals. Exact for empty and full blocks, blurred inside
//!   partly covered ones. On the bunny's vertices (`tests/tests/hemi_transfer.rs`)
//!   it is 0.99 % mean, 4.2 % max away from the full sum of the same masks, and
//!   1.13 % mean from the ray-traced reference against the full sum's 0.38 %.
//!
//! World space: a local vector `T` is turned into world coefficients by the SH
//! rotation of the frame matrix `[t b n]` ([`TransferRotation`]), after which
//! diffuse shading is `(albedo/π) Σ_k T_k l_k` per colour channel ([`shade_diffuse`])
//! with `l` the world-space SH coefficients of incident radiance. Rotating the
//! three lighting channels into the local frame instead would cost about the same
//! per vertex (building the band matrices of the rotation dominates, not applying
//! them); the transfer is rotated because it is one vector for diffuse and two
//! with glossy, against three lighting channels, and because world-space transfer
//! vectors are what callers store.
//!
//! Memory at N = 9 / 16: the per-cell sum's table 39 KB / 70 KB (the
//! downsampled mode's block integrals included); the byte LUT adds 1.18 MB /
//! 2.10 MB, the nibble LUT 74 KB / 131 KB. Per mask the per-cell sum reads the
//! fewer of the occluded and unoccluded cells, the LUTs one entry per non-zero
//! chunk, the downsampled mode 64 coverage values (figures: `cargo bench -p
//! antumbra-core --features bvh --bench hemi -- transfer`).
//!
//! The choice: the per-cell sum ([`TransferMethod::Cells`]) is the recommended
//! method. Every method costs a small fraction of the receiver's mask itself, so
//! the byte LUT saves little of a receiver's time while its 1–2 MB compete in
//! cache with the 2 MiB half-space table. The LUT is there for callers who
//! integrate masks produced elsewhere in bulk. Building a table takes a few
//! milliseconds.
//!
//! Invariants: tables are built once and only read afterwards (share them between
//! threads); every per-receiver operation is allocation-free and works on
//! fixed-size arrays on the stack.

use alloc::boxed::Box;
use alloc::vec::Vec;

use glam::{Mat3, Vec3};

use super::mask::{GRID, HemiMask, ROW_FIRST, ROW_LAST};
use crate::fallible::{self, OutOfMemory};
use crate::geom::Frame;
use crate::sh::{Sh, ShRgb, ShRotation, eval_basis};

use core::f64::consts::{FRAC_PI_2, PI};

/// Gauss–Legendre nodes per direction (and per piece of a rim cell) used to
/// integrate the cell weights. 20 is past convergence for every supported band
/// count: doubling it changes no stored `f32` weight by more than one ulp.
pub const QUADRATURE_NODES: usize = 20;

/// Cells per block side in the downsampled mode (the paper's 4×4 blocks).
pub const BLOCK: usize = 4;

/// Blocks per side of the downsampled grid (8×8 coverage values).
pub const BLOCKS: usize = GRID / BLOCK;

/// Per-cell SH integrals `W_k(c) = ∫_{R_c} y_k cosθ dω` of the 32×32 mask (see the
/// module docs for the cell regions `R_c` and the quadrature), and what is derived
/// from them: the unoccluded total and the 8×8 block integrals.
///
/// Coefficients follow [`Sh<N>`] (real orthonormal SH, Condon–Shortley phase, index
/// `l(l+1) + m`), in the receiver's local frame `(t, b, n)` = `(x, y, z)`. Built once
/// ([`TransferTable::new`], a few to a few tens of milliseconds depending on `N`),
/// `1024 × N` floats plus `64 × N` for the blocks; read-only afterwards.
#[derive(Clone, PartialEq)]
pub struct TransferTable<const N: usize> {
    /// `W(c)` for cell `(i, j)` at `j * 32 + i`; 0 for invalid cells.
    cells: Box<[[f32; N]]>,
    /// `Σ_c W(c)` over valid cells, accumulated in `f64`.
    unoccluded: Sh<N>,
    /// Per block `(bi, bj)` at `bj * 8 + bi`: the block's integral divided by its
    /// number of valid cells (what each occluded valid cell removes in the
    /// downsampled mode); 0 for blocks without valid cells.
    block_share: Box<[[f32; N]]>,
}

impl<const N: usize> core::fmt::Debug for TransferTable<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("TransferTable")
            .field("coefficients", &N)
            .field("unoccluded", &self.unoccluded)
            .field("size_bytes", &self.size_bytes())
            .finish()
    }
}

impl<const N: usize> Default for TransferTable<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> TransferTable<N> {
    /// Integrates every cell with [`QUADRATURE_NODES`] nodes per direction.
    pub fn new() -> Self {
        Self::with_nodes(QUADRATURE_NODES)
    }

    /// Integrates every cell with `nodes` Gauss–Legendre nodes per direction (at
    /// least 2, at most 64); for convergence studies. Prefer [`TransferTable::new`].
    pub fn with_nodes(nodes: usize) -> Self {
        Self::try_with_nodes(nodes).expect("memory for a transfer table")
    }

    /// [`TransferTable::new`], or an error when its `GRID² × N` floats cannot be
    /// allocated (for callers whose allocator may run out, such as bare metal).
    pub fn try_new() -> Result<Self, OutOfMemory> {
        Self::try_with_nodes(QUADRATURE_NODES)
    }

    fn try_with_nodes(nodes: usize) -> Result<Self, OutOfMemory> {
        let _ = Sh::<N>::BANDS;
        let rule = GaussLegendre::new(nodes.clamp(2, 64));
        let mut cells = fallible::filled([0.0f32; N], GRID * GRID)?.into_boxed_slice();
        let mut total = [0.0f64; N];
        let mut blocks = [[0.0f64; N]; BLOCKS * BLOCKS];
        let mut block_valid = [0u32; BLOCKS * BLOCKS];
        let step = 1.0 / 16.0;
        for j in 0..GRID {
            let (first, last) = (ROW_FIRST[j] as usize, ROW_LAST[j] as usize);
            let v0 = j as f64 * step - 1.0;
            for i in first..=last {
                // Row ends take the rim slivers of the invalid cells beside them.
                let u0 = if i == first {
                    f64::NEG_INFINITY
                } else {
                    i as f64 * step - 1.0
                };
                let u1 = if i == last {
                    f64::INFINITY
                } else {
                    (i + 1) as f64 * step - 1.0
                };
                let w = integrate_region::<N>(&rule, u0, u1, v0, v0 + step);
                let b = (j / BLOCK) * BLOCKS + i / BLOCK;
                block_valid[b] += 1;
                for k in 0..N {
                    total[k] += w[k];
                    blocks[b][k] += w[k];
                    cells[j * GRID + i][k] = w[k] as f32;
                }
            }
        }
        let mut block_share = fallible::with_capacity(blocks.len())?;
        block_share.extend(blocks.iter().zip(block_valid).map(|(w, count)| {
            if count == 0 {
                [0.0; N]
            } else {
                w.map(|x| (x / f64::from(count)) as f32)
            }
        }));
        Ok(TransferTable {
            cells,
            unoccluded: Sh::new(total.map(|x| x as f32)),
            block_share: block_share.into_boxed_slice(),
        })
    }

    /// `W(c)` of cell `(i, j)`: zero for invalid cells and outside the grid.
    #[inline]
    pub fn cell(&self, i: usize, j: usize) -> Sh<N> {
        if i < GRID && j < GRID {
            Sh::new(self.cells[j * GRID + i])
        } else {
            Sh::ZERO
        }
    }

    /// `W(c)` of the cell at `index = j * 32 + i`, unchecked beyond the slice bound.
    #[inline(always)]
    pub(crate) fn cell_weights(&self, index: usize) -> &[f32; N] {
        &self.cells[index]
    }

    /// The transfer vector of the empty mask: the unshadowed clamped cosine about
    /// `+z`, exact up to the quadrature (`T_0 = √π/2`, `T_2 = 1.023327`, ...).
    #[inline]
    pub fn unoccluded(&self) -> Sh<N> {
        self.unoccluded
    }

    /// Bytes held by the table's arrays.
    pub fn size_bytes(&self) -> usize {
        (self.cells.len() + self.block_share.len()) * core::mem::size_of::<[f32; N]>()
    }

    /// The local transfer vector of `mask` (set cells occluded): the sum of `W(c)`
    /// over its unoccluded valid cells. Bits of invalid cells are ignored.
    ///
    /// Computed as the unoccluded total minus the occluded cells, or as the sum of
    /// the unoccluded cells when fewer than half are unoccluded, so at most 406
    /// cells are visited.
    #[inline]
    pub fn transfer(&self, mask: &HemiMask) -> Sh<N> {
        let occluded = (*mask & HemiMask::VALID).count_occluded();
        let (mut acc, sign, cells) = if 2 * occluded <= super::VALID_CELL_COUNT {
            (self.unoccluded.coeffs, -1.0, *mask & HemiMask::VALID)
        } else {
            ([0.0; N], 1.0, mask.complement())
        };
        for (j, &row) in cells.rows.iter().enumerate() {
            if row == 0 {
                continue;
            }
            // Each row summed on its own first: small sums round finely, so the
            // result stays within about 1e-6 of the exact sum of the stored weights
            // (one long f32 running sum drifted by 1e-5).
            let mut row_sum = [0.0f32; N];
            let mut bits = row;
            while bits != 0 {
                let i = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let w = &self.cells[j * GRID + i];
                for k in 0..N {
                    row_sum[k] += w[k];
                }
            }
            for k in 0..N {
                acc[k] += sign * row_sum[k];
            }
        }
        Sh::new(acc)
    }

    /// The paper's downsampled transfer: the mask reduced to 8×8 blocks of 4×4
    /// cells, each block contributing its integral times its coverage (the fraction
    /// of its valid cells that are unoccluded). Equal to [`TransferTable::transfer`]
    /// when every block is empty or full; otherwise occlusion is spread evenly over
    /// the block's cells. 64 block updates at most.
    #[inline]
    pub fn transfer_downsampled(&self, mask: &HemiMask) -> Sh<N> {
        let mut acc = self.unoccluded.coeffs;
        let valid = *mask & HemiMask::VALID;
        for bj in 0..BLOCKS {
            // Per-nibble popcounts of the block row's four rows, SWAR: bytes of
            // `even` count nibbles 0, 2, 4, 6 (blocks 0, 2, 4, 6), bytes of `odd` the
            // others; each byte reaches at most 16.
            let mut even = 0u32;
            let mut odd = 0u32;
            for &row in &valid.rows[bj * BLOCK..bj * BLOCK + BLOCK] {
                let n = row - ((row >> 1) & 0x5555_5555);
                let n = (n & 0x3333_3333) + ((n >> 2) & 0x3333_3333);
                even += n & 0x0f0f_0f0f;
                odd += (n >> 4) & 0x0f0f_0f0f;
            }
            if even | odd == 0 {
                continue;
            }
            for q in 0..4 {
                for (bi, counts) in [(2 * q, even), (2 * q + 1, odd)] {
                    let occluded = (counts >> (8 * q)) & 0xff;
                    if occluded != 0 {
                        let share = &self.block_share[bj * BLOCKS + bi];
                        let n = occluded as f32;
                        for k in 0..N {
                            acc[k] -= n * share[k];
                        }
                    }
                }
            }
        }
        Sh::new(acc)
    }
}

/// The byte lookup table of the design (hemi.md §3): for every row, chunk position
/// and chunk value, the summed weights of the chunk's set (occluded) cells, so a
/// mask's transfer is the unoccluded total minus one lookup per non-zero chunk.
///
/// With 8-bit chunks ([`TransferLut::new`]) that is 32 rows × 4 bytes × 256 values
/// × `N` floats (1.2 MB at `N = 9`, 2 MB at 16, 3.3 MB at 25) and at most 128
/// lookups per mask; 4-bit chunks ([`TransferLut::with_chunk_bits`]) need 16×
/// less memory (74, 131, 205 KB) and at most 256 lookups. The result equals
/// [`TransferTable::transfer`] up to `f32` rounding of the pre-summed entries.
/// Both chunk sizes are cheaper per mask than the per-cell sum, bytes more so
/// (costs in the module docs of `hemi::transfer`, `core/src/hemi/transfer.rs`).
#[derive(Clone, PartialEq)]
pub struct TransferLut<const N: usize> {
    table: TransferTable<N>,
    /// Bits per chunk: 4 or 8.
    bits: u32,
    /// Entry `((j * chunks_per_row + c) << bits) | value`.
    entries: Box<[[f32; N]]>,
}

impl<const N: usize> core::fmt::Debug for TransferLut<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("TransferLut")
            .field("coefficients", &N)
            .field("chunk_bits", &self.bits)
            .field("size_bytes", &self.size_bytes())
            .finish()
    }
}

impl<const N: usize> TransferLut<N> {
    /// The byte (8-bit chunk) table over `table`, which it keeps (glossy shading
    /// and the other modes still need the per-cell weights).
    pub fn new(table: TransferTable<N>) -> Self {
        Self::with_chunk_bits(table, 8)
    }

    /// The table with chunks of `bits` bits: 8 (bytes) or 4 (nibbles); any other
    /// value is taken as 8.
    pub fn with_chunk_bits(table: TransferTable<N>, bits: u32) -> Self {
        Self::try_with_chunk_bits(table, bits).expect("memory for a transfer lookup table")
    }

    /// [`TransferLut::new`], or an error when its `32 × 4 × 256 × N` floats cannot
    /// be allocated.
    pub fn try_new(table: TransferTable<N>) -> Result<Self, OutOfMemory> {
        Self::try_with_chunk_bits(table, 8)
    }

    fn try_with_chunk_bits(table: TransferTable<N>, bits: u32) -> Result<Self, OutOfMemory> {
        let bits = if bits == 4 { 4 } else { 8 };
        let values = 1usize << bits;
        let chunks = GRID / bits as usize;
        let mut entries: Vec<[f32; N]> = fallible::with_capacity(GRID * chunks * values)?;
        let mut sums = fallible::filled([0.0f64; N], values)?;
        for j in 0..GRID {
            for c in 0..chunks {
                // sums[v] = sums[v without its lowest bit] + W(lowest bit's cell),
                // accumulated in f64 so an entry is the correctly rounded sum.
                sums[0] = [0.0; N];
                for v in 1..values {
                    let low = v.trailing_zeros() as usize;
                    let w = &table.cells[j * GRID + c * bits as usize + low];
                    let mut s = sums[v & (v - 1)];
                    for k in 0..N {
                        s[k] += f64::from(w[k]);
                    }
                    sums[v] = s;
                }
                entries.extend(sums.iter().map(|s| s.map(|x| x as f32)));
            }
        }
        Ok(TransferLut {
            table,
            bits,
            entries: entries.into_boxed_slice(),
        })
    }

    /// The per-cell table this one was built from.
    #[inline]
    pub fn table(&self) -> &TransferTable<N> {
        &self.table
    }

    /// Bits per chunk (4 or 8).
    #[inline]
    pub fn chunk_bits(&self) -> u32 {
        self.bits
    }

    /// Bytes held by the lookup entries (not counting the per-cell table).
    pub fn size_bytes(&self) -> usize {
        self.entries.len() * core::mem::size_of::<[f32; N]>()
    }

    /// The local transfer vector of `mask`: [`TransferTable::transfer`] by lookups.
    /// Bits of invalid cells are ignored (their weights are 0).
    #[inline]
    pub fn transfer(&self, mask: &HemiMask) -> Sh<N> {
        if self.bits == 8 {
            self.transfer_chunks::<8>(mask)
        } else {
            self.transfer_chunks::<4>(mask)
        }
    }

    #[inline(always)]
    fn transfer_chunks<const BITS: u32>(&self, mask: &HemiMask) -> Sh<N> {
        let chunks = GRID / BITS as usize;
        let low = (1u32 << BITS) - 1;
        let mut acc = self.table.unoccluded.coeffs;
        for (j, &row) in mask.rows.iter().enumerate() {
            if row == 0 {
                continue;
            }
            // Per-row partial sums, as in TransferTable::transfer, for accuracy.
            let mut row_sum = [0.0f32; N];
            for c in 0..chunks {
                let value = (row >> (c as u32 * BITS)) & low;
                if value != 0 {
                    let e = &self.entries[((j * chunks + c) << BITS) | value as usize];
                    for k in 0..N {
                        row_sum[k] += e[k];
                    }
                }
            }
            for k in 0..N {
                acc[k] -= row_sum[k];
            }
        }
        Sh::new(acc)
    }
}

/// How a mask becomes a transfer vector; every variant borrows a table built once.
#[derive(Clone, Copy, Debug)]
pub enum TransferMethod<'t, const N: usize> {
    /// The full per-cell sum ([`TransferTable::transfer`]).
    Cells(&'t TransferTable<N>),
    /// The same sum by byte (or nibble) lookups ([`TransferLut::transfer`]).
    Lut(&'t TransferLut<N>),
    /// The paper's 4×4 block downsampling ([`TransferTable::transfer_downsampled`]).
    Downsampled(&'t TransferTable<N>),
}

impl<'t, const N: usize> TransferMethod<'t, N> {
    /// The local transfer vector of `mask`.
    #[inline]
    pub fn transfer(&self, mask: &HemiMask) -> Sh<N> {
        match self {
            TransferMethod::Cells(table) => table.transfer(mask),
            TransferMethod::Lut(lut) => lut.transfer(mask),
            TransferMethod::Downsampled(table) => table.transfer_downsampled(mask),
        }
    }

    /// The per-cell table behind the method.
    #[inline]
    pub fn table(&self) -> &'t TransferTable<N> {
        match self {
            TransferMethod::Cells(table) | TransferMethod::Downsampled(table) => table,
            TransferMethod::Lut(lut) => lut.table(),
        }
    }
}

/// The rotation matrix of a receiver frame: columns `t, b, n`, so `M · local =
/// world`. Proper (determinant +1) for a unit normal.
#[inline]
pub fn frame_matrix(frame: &Frame) -> Mat3 {
    Mat3::from_cols(frame.tangent, frame.bitangent, frame.normal)
}

/// The SH rotation from a receiver's local frame to world space, built once per
/// receiver and applied to its local vectors (transfer, glossy transfer).
#[derive(Clone, Debug)]
pub struct TransferRotation<const N: usize> {
    rotation: ShRotation<N>,
}

impl<const N: usize> TransferRotation<N> {
    /// The rotation of `frame` ([`frame_matrix`]).
    #[inline]
    pub fn new(frame: &Frame) -> Self {
        TransferRotation {
            rotation: ShRotation::new(frame_matrix(frame)),
        }
    }

    /// A local vector's world-space coefficients: the function `g(ω_local)` as
    /// `g(M⁻¹ ω_world)`.
    #[inline]
    pub fn to_world(&self, local: &Sh<N>) -> Sh<N> {
        self.rotation.apply(local)
    }
}

/// Diffuse outgoing radiance `(albedo/π) Σ_k T_k l_k` per channel, for a world-space
/// transfer vector and world-space SH coefficients of incident radiance.
#[inline]
pub fn shade_diffuse<const N: usize>(
    transfer_world: &Sh<N>,
    lighting: &ShRgb<N>,
    albedo: Vec3,
) -> Vec3 {
    let irradiance = Vec3::new(
        transfer_world.dot(&lighting.r),
        transfer_world.dot(&lighting.g),
        transfer_world.dot(&lighting.b),
    );
    albedo * irradiance * (1.0 / core::f32::consts::PI)
}

// --- quadrature ---

/// Gauss–Legendre nodes and weights on `[0, 1]`.
struct GaussLegendre {
    /// (node, weight) pairs; only the first `len` are used. A fixed array, so that
    /// building a table allocates nothing but the table.
    pairs: [(f64, f64); 64],
    len: usize,
}

impl GaussLegendre {
    /// `n` nodes, by Newton's method on `P_n` from the Chebyshev guesses.
    fn new(n: usize) -> Self {
        let n = n.min(64);
        let mut rule = GaussLegendre {
            pairs: [(0.0, 0.0); 64],
            len: n,
        };
        for i in 0..n {
            let mut x = libm::cos(PI * (i as f64 + 0.75) / (n as f64 + 0.5));
            let mut derivative = 1.0;
            for _ in 0..100 {
                let (p, dp) = legendre_and_derivative(n, x);
                derivative = dp;
                let dx = p / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            let (_, dp) = legendre_and_derivative(n, x);
            derivative = if dp != 0.0 { dp } else { derivative };
            let weight = 2.0 / ((1.0 - x * x) * derivative * derivative);
            // Mapped from [-1, 1] to [0, 1].
            rule.pairs[i] = (0.5 * (x + 1.0), 0.5 * weight);
        }
        rule
    }

    fn nodes(&self) -> &[(f64, f64)] {
        &self.pairs[..self.len]
    }
}

/// `P_n(x)` and `P_n'(x)` by Bonnet's recurrence.
fn legendre_and_derivative(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    for k in 2..=n {
        let k = k as f64;
        let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    let dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, dp)
}

/// `∫ y_k(u, v, sqrt(1 - u² - v²)) du dv` over `[u0, u1] × [v0, v1]` inside the unit
/// disk (`u0` may be `-inf`, `u1` `+inf`), in `f64` (see the module docs).
fn integrate_region<const N: usize>(
    rule: &GaussLegendre,
    u0: f64,
    u1: f64,
    v0: f64,
    v1: f64,
) -> [f64; N] {
    let mut out = [0.0f64; N];
    let s0 = libm::asin(v0.clamp(-1.0, 1.0));
    let s1 = libm::asin(v1.clamp(-1.0, 1.0));
    // Where a vertical edge meets the rim, cos s = |u|, the t-limits kink.
    let mut breaks = [s0, s1, 0.0, 0.0, 0.0, 0.0];
    let mut count = 2;
    for u in [u0, u1] {
        if u.is_finite() && u.abs() < 1.0 {
            let s = libm::acos(u.abs());
            for s in [s, -s] {
                if s > s0 && s < s1 {
                    breaks[count] = s;
                    count += 1;
                }
            }
        }
    }
    let breaks = &mut breaks[..count];
    breaks.sort_by(f64::total_cmp);
    let limit = |u: f64, a: f64| {
        if u == f64::NEG_INFINITY {
            -FRAC_PI_2
        } else if u == f64::INFINITY {
            FRAC_PI_2
        } else {
            libm::asin((u / a).clamp(-1.0, 1.0))
        }
    };
    for piece in breaks.windows(2) {
        let (sa, sb) = (piece[0], piece[1]);
        if sb <= sa {
            continue;
        }
        for &(w, ww) in rule.nodes() {
            // Smoothstep: zero derivative at both ends absorbs sqrt kinks there.
            let g = w * w * (3.0 - 2.0 * w);
            let dg = 6.0 * w * (1.0 - w);
            let s = sa + (sb - sa) * g;
            let ds = (sb - sa) * dg * ww;
            let (sin_s, cos_s) = (libm::sin(s), libm::cos(s));
            if cos_s <= 0.0 {
                continue;
            }
            let (ta, tb) = (limit(u0, cos_s), limit(u1, cos_s));
            if tb <= ta {
                continue;
            }
            for &(x, wx) in rule.nodes() {
                let t = ta + (tb - ta) * x;
                let (sin_t, cos_t) = (libm::sin(t), libm::cos(t));
                let weight = (tb - ta) * wx * ds * cos_s * cos_s * cos_t;
                let d = Vec3::new((cos_s * sin_t) as f32, sin_s as f32, (cos_s * cos_t) as f32);
                let y = eval_basis::<N>(d);
                for k in 0..N {
                    out[k] += weight * f64::from(y[k]);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    // Printing measured figures needs std even in --no-default-features runs.
    extern crate std;

    use super::*;
    use crate::hemi::{VALID_CELL_COUNT, cell_directions};
    use crate::sh::{Sh16, ZonalKernel};

    fn close(a: f32, b: f32, tol: f32) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn unoccluded_transfer_is_the_clamped_cosine() {
        let table = TransferTable::<16>::new();
        let t = table.unoccluded();
        assert!(close(t[0], 0.886_226_9, 1e-6), "{}", t[0]);
        assert!(close(t[2], 1.023_326_7, 1e-6), "{}", t[2]);
        let expected: Sh16 = ZonalKernel::clamped_cosine().along(Vec3::Z);
        for k in 0..16 {
            assert!(
                close(t[k], expected[k], 2e-6),
                "{k}: {} vs {}",
                t[k],
                expected[k]
            );
        }
        assert_eq!(table.transfer(&HemiMask::EMPTY), t);
        assert!(
            table
                .transfer(&HemiMask::VALID)
                .coeffs
                .iter()
                .all(|&x| x == 0.0)
        );
        // Sixty-four coefficients too (the recurrence path of eval_basis).
        let big = TransferTable::<64>::new().unoccluded();
        let expected: crate::sh::Sh64 = ZonalKernel::clamped_cosine().along(Vec3::Z);
        for k in 0..64 {
            assert!(close(big[k], expected[k], 3e-6), "{k}");
        }
    }

    #[test]
    fn cell_weights_have_converged() {
        let a = TransferTable::<25>::new();
        let b = TransferTable::<25>::with_nodes(2 * QUADRATURE_NODES);
        let mut worst = 0.0f32;
        let mut largest = 0.0f32;
        for j in 0..GRID {
            for i in 0..GRID {
                for k in 0..25 {
                    worst = worst.max((a.cell(i, j)[k] - b.cell(i, j)[k]).abs());
                    largest = largest.max(b.cell(i, j)[k].abs());
                }
            }
        }
        std::println!(
            "cell weights, {QUADRATURE_NODES} vs {} nodes: worst difference {worst:e} of largest {largest:e}",
            2 * QUADRATURE_NODES
        );
        assert!(worst <= 1e-6 * largest, "{worst} of {largest}");
    }

    #[test]
    fn band_zero_weight_is_the_clipped_area() {
        // W_0 = Y_0 × area of the cell's region, by an independent 1D integral of
        // the chord length (midpoint rule, 20,000 strips per cell).
        let table = TransferTable::<1>::new();
        let y0 = 0.5 / PI.sqrt();
        let mut sum = 0.0;
        for j in 0..GRID {
            let (first, last) = (ROW_FIRST[j] as usize, ROW_LAST[j] as usize);
            let (v0, v1) = (j as f64 / 16.0 - 1.0, (j + 1) as f64 / 16.0 - 1.0);
            for i in first..=last {
                let u0 = if i == first {
                    -1.0
                } else {
                    i as f64 / 16.0 - 1.0
                };
                let u1 = if i == last {
                    1.0
                } else {
                    (i + 1) as f64 / 16.0 - 1.0
                };
                let strips = 20_000;
                let mut area = 0.0;
                for s in 0..strips {
                    let u = u0 + (u1 - u0) * (s as f64 + 0.5) / strips as f64;
                    let h = libm::sqrt((1.0 - u * u).max(0.0));
                    area += (v1.min(h) - v0.max(-h)).max(0.0);
                }
                area *= (u1 - u0) / strips as f64;
                sum += area;
                let w = f64::from(table.cell(i, j)[0]);
                assert!(
                    (w - y0 * area).abs() < 2e-8,
                    "cell ({i}, {j}): {w} vs {}",
                    y0 * area
                );
            }
        }
        assert!((sum - PI).abs() < 1e-6);
        for j in 0..GRID {
            for i in 0..GRID {
                if !crate::hemi::is_valid_cell(i, j) {
                    assert_eq!(table.cell(i, j)[0], 0.0);
                }
            }
        }
    }

    fn masks() -> alloc::vec::Vec<HemiMask> {
        // Half planes, a cap, a checkerboard and a pseudo-random pattern.
        let mut out = alloc::vec::Vec::new();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for kind in 0..6 {
            let mut m = HemiMask::EMPTY;
            for (i, j, d) in cell_directions() {
                let set = match kind {
                    0 => d.x > 0.0,
                    1 => d.x + 0.3 * d.y > 0.2,
                    2 => d.z > 0.8,
                    3 => (i + j) % 2 == 0,
                    4 => next() % 3 == 0,
                    _ => d.z < 0.3,
                };
                m.set(i, j, set);
            }
            out.push(m);
        }
        out
    }

    #[test]
    fn lut_and_cells_agree() {
        let table = TransferTable::<16>::new();
        let bytes = TransferLut::new(table.clone());
        let nibbles = TransferLut::with_chunk_bits(table.clone(), 4);
        assert_eq!(bytes.size_bytes(), 32 * 4 * 256 * 16 * 4);
        assert_eq!(nibbles.size_bytes(), 32 * 8 * 16 * 16 * 4);
        for mask in masks() {
            // Direct per-cell sum in f64 as the reference.
            let mut reference = [0.0f64; 16];
            for (i, j, _) in cell_directions() {
                if !mask.get(i, j) {
                    for (r, w) in reference.iter_mut().zip(table.cell(i, j).coeffs) {
                        *r += f64::from(w);
                    }
                }
            }
            for t in [
                table.transfer(&mask),
                bytes.transfer(&mask),
                nibbles.transfer(&mask),
            ] {
                for k in 0..16 {
                    assert!(
                        (f64::from(t[k]) - reference[k]).abs() < 2e-6,
                        "{k}: {} vs {}",
                        t[k],
                        reference[k]
                    );
                }
            }
        }
    }

    #[test]
    fn downsampling_is_exact_on_whole_blocks() {
        let table = TransferTable::<9>::new();
        // Occlude whole blocks (all valid cells of blocks with bi + bj odd).
        let mut mask = HemiMask::EMPTY;
        for (i, j, _) in cell_directions() {
            mask.set(i, j, (i / BLOCK + j / BLOCK) % 2 == 1);
        }
        let (full, down) = (table.transfer(&mask), table.transfer_downsampled(&mask));
        for k in 0..9 {
            assert!(
                close(full[k], down[k], 2e-6),
                "{k}: {} {}",
                full[k],
                down[k]
            );
        }
        assert_eq!(
            table.transfer_downsampled(&HemiMask::EMPTY),
            table.unoccluded()
        );
        assert!(
            table
                .transfer_downsampled(&HemiMask::VALID)
                .coeffs
                .iter()
                .all(|x| x.abs() < 2e-6)
        );
        // A partly covered block spreads its occlusion: the same count of occluded
        // cells anywhere in the block gives the same result.
        let mut a = HemiMask::EMPTY;
        let mut b = HemiMask::EMPTY;
        a.set(16, 16, true);
        b.set(19, 19, true);
        assert_eq!(
            table.transfer_downsampled(&a),
            table.transfer_downsampled(&b)
        );
        assert_ne!(table.transfer(&a), table.transfer(&b));
        let _ = VALID_CELL_COUNT;
    }

    #[test]
    fn rotation_to_world_matches_the_rotated_clamped_cosine() {
        let table = TransferTable::<16>::new();
        for n in [
            Vec3::Z,
            Vec3::new(0.6, 0.0, -0.8),
            Vec3::new(2.0, -3.0, 6.0) / 7.0,
            Vec3::Y,
        ] {
            let frame = Frame::from_normal(n);
            let world = TransferRotation::new(&frame).to_world(&table.unoccluded());
            let expected: Sh16 = ZonalKernel::clamped_cosine().along(n);
            for k in 0..16 {
                assert!(close(world[k], expected[k], 1e-5), "{n} {k}");
            }
            // Diffuse under constant radiance 1 (l_0 = 2√π) is the albedo.
            let mut l = Sh16::ZERO;
            l[0] = 2.0 * core::f32::consts::PI.sqrt();
            let rgb = ShRgb::from_channels([l, l * 0.5, l * 0.0]);
            let out = shade_diffuse(&world, &rgb, Vec3::new(0.8, 0.8, 0.8));
            assert!((out - Vec3::new(0.8, 0.4, 0.0)).abs().max_element() < 1e-5);
        }
    }

    /// Rasterizes world triangles for the receiver at the origin with normal +z,
    /// whose frame is the identity.
    fn mask_of(triangles: &[[Vec3; 3]]) -> HemiMask {
        let receiver = crate::hemi::Receiver::new(Vec3::ZERO, Vec3::Z, 0.0);
        assert_eq!(frame_matrix(&receiver.frame), Mat3::IDENTITY);
        let mut mask = HemiMask::EMPTY;
        crate::hemi::rasterize_triangles_into(
            &mut mask,
            &receiver,
            triangles.iter().copied(),
            crate::hemi::Quality::Exact,
            false,
        );
        mask
    }

    #[test]
    fn wall_beside_the_normal_halves_the_transfer() {
        // The wall of the mask tests: the plane x = 0.25, which contains the normal's
        // direction, blocks exactly u > 0 (columns 16..32, a straight cell
        // boundary), so the result is the analytic half-hemisphere integral.
        let (y, z) = (Vec3::Y * 1e3, Vec3::Z * 1e3);
        let c = Vec3::X * 0.25;
        let mask = mask_of(&[
            [c - y - z, c + y - z, c + y + z],
            [c - y - z, c + y + z, c - y + z],
        ]);
        assert_eq!(2 * mask.count_occluded(), VALID_CELL_COUNT);
        let table = TransferTable::<9>::new();
        let t = table.transfer(&mask);
        let c1 = 0.488_602_5f32;
        // T_0 = √π/4; T_2 (y_1^0) = c1 π/3; T_3 (y_1^1 = -c1 x) = c1 ∫_{x<0} |x| z dω = 2 c1/3;
        // T_1 (y_1^{-1} ∝ y) = 0 by symmetry.
        let expected = [
            0.443_113_46,
            0.0,
            c1 * core::f32::consts::PI / 3.0,
            2.0 * c1 / 3.0,
        ];
        for (k, e) in expected.into_iter().enumerate() {
            assert!(close(t[k], e, 2e-6), "T_{k} = {} vs {e}", t[k]);
        }
    }

    #[test]
    fn cap_about_the_normal_blocks_sin_squared_alpha() {
        // A 1024-gon fan at height 1 of half-angle α: the blocked share of T_0 is
        // sin²α up to the staircase of cells along the rim of the cap.
        const SIDES: usize = 1024;
        let table = TransferTable::<4>::new();
        let total = table.unoccluded();
        let c1 = 0.488_602_5f64;
        for sin2 in [0.1f64, 0.25, 0.5, 0.75, 0.9] {
            let radius = libm::sqrt(sin2 / (1.0 - sin2)) as f32;
            let rim: Vec<Vec3> = (0..SIDES)
                .map(|k| {
                    let a = core::f32::consts::TAU * k as f32 / SIDES as f32;
                    Vec3::new(radius * libm::cosf(a), radius * libm::sinf(a), 1.0)
                })
                .collect();
            let fan: Vec<[Vec3; 3]> = (0..SIDES)
                .map(|k| [Vec3::Z, rim[k], rim[(k + 1) % SIDES]])
                .collect();
            let t = table.transfer(&mask_of(&fan));
            let blocked = 1.0 - f64::from(t[0] / total[0]);
            // y_1^0 over the cap: c1 2π (1 - cos³α)/3.
            let cos3 = libm::pow(1.0 - sin2, 1.5);
            let blocked_z = c1 * 2.0 * PI * (1.0 - cos3) / 3.0;
            let got_z = f64::from(total[2] - t[2]);
            // The staircase error: a fraction of a cell along the cap's rim, about
            // (2π sinα · 16 cells) × (1/256 area) / π × 1/4 on average.
            let rim_share = 2.0 * libm::sqrt(sin2) * 16.0 / 256.0 / 4.0;
            std::println!(
                "cap sin²α = {sin2}: blocked T_0 share {blocked:.5}, T_2 {got_z:.5} vs {blocked_z:.5}"
            );
            assert!((blocked - sin2).abs() < rim_share, "{blocked} vs {sin2}");
            assert!(
                (got_z - blocked_z).abs() < rim_share * 1.1,
                "{got_z} vs {blocked_z}"
            );
        }
    }
}
