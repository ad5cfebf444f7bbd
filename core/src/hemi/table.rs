//! The precomputed half-space table: the paper's method (Kautz, Lehtinen and Aila
//! 2004, §3), where a triangle costs three table reads and a few ANDs.
//!
//! Plane normals are quantised with a hemi-octahedral map: a normal `m` with
//! `m.z >= 0` goes to `(x, y) = (m.x, m.y) / (|m.x| + |m.y| + |m.z|)`, the diamond
//! `|x| + |y| <= 1`, which the 45° rotation `(s, t) = (x + y, x - y)` turns into the
//! square `[-1, 1]²`. The square is cut into `N × N` entries; each holds the exact
//! half-space mask ([`half_space_mask`]) of the normal at its center, and a
//! lookup returns the entry the normal falls in (nearest in `(s, t)`).
//!
//! Normals of the lower half use `M(-m) = VALID & !M(m)`. The canonical half is
//! `z > 0`, or `z = 0` and `y > 0`, or `z = y = 0` and `x >= 0`, so `m` and `-m`
//! always read the same entry and their masks are exact complements: shared mesh
//! edges neither leave pinholes nor overlap in table mode. The price is the tie
//! rule: the exact closed half-spaces of `m` and `-m` share the cells exactly on the
//! plane, the table's never do, and which side gets such a cell depends on the
//! entry. Quantisation error dwarfs this anyway; see [`HalfSpaceTable::new`] for the
//! measured wrong cells per mask at each resolution.
//!
//! The table is built once (a few milliseconds) into one allocation and only read
//! afterwards, so it can be shared by every thread.

use alloc::boxed::Box;
use alloc::collections::TryReserveError;
use alloc::vec::Vec;

use glam::Vec3;

use super::half_space::half_space_mask;
use super::mask::{GRID, HemiMask};

/// Masks of half-spaces for a quantised set of plane normals (see the module
/// docs), looked up by nearest entry.
#[derive(Clone, PartialEq, Eq)]
pub struct HalfSpaceTable {
    resolution: usize,
    /// `resolution²` masks, entry `(k, l)` (s index, t index) at `l * resolution + k`.
    masks: Box<[HemiMask]>,
}

impl core::fmt::Debug for HalfSpaceTable {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("HalfSpaceTable")
            .field("resolution", &self.resolution)
            .field("size_bytes", &self.size_bytes())
            .finish()
    }
}

impl Default for HalfSpaceTable {
    /// A table of [`HalfSpaceTable::DEFAULT_RESOLUTION`] entries per side.
    fn default() -> Self {
        Self::new(Self::DEFAULT_RESOLUTION)
    }
}

impl HalfSpaceTable {
    /// Entries per side of the default table: 128 × 128 masks, 2 MiB.
    ///
    /// Measured wrong cells per half-space mask against [`half_space_mask`] (812
    /// valid cells; 20,000 uniformly random normals; `cargo test -p antumbra-core
    /// --lib table_size_versus_wrong_cells -- --nocapture`), and cell agreement of
    /// whole receivers with Embree (300 vertex receivers each;
    /// `cargo test -p antumbra-tests --test embree_hemi -- --nocapture`):
    ///
    /// | side | bytes   | wrong cells mean / max | bunny    | teapot   | random soup |
    /// |------|---------|------------------------|----------|----------|-------------|
    /// | 32   | 128 KiB | 9.3 / 28               | 97.95 %  | 98.84 %  | 96.09 %     |
    /// | 64   | 512 KiB | 4.7 / 18               | 99.18 %  | 99.53 %  | 97.74 %     |
    /// | 128  | 2 MiB   | 2.3 / 14               | 99.66 %  | 99.80 %  | 98.72 %     |
    /// | 256  | 8 MiB   | 1.2 / 9                | 99.88 %  | 99.92 %  | 99.36 %     |
    ///
    /// Wrong cells halve with each doubling of the side (they lie in a band along
    /// the plane's great circle as wide as the quantisation step) while memory
    /// quadruples. In a closed mesh only silhouette edges show the error (the two
    /// sides of a shared edge are exact complements); in a soup every edge is a
    /// silhouette. 128 is the smallest side that keeps the meshes above 99.5 %.
    pub const DEFAULT_RESOLUTION: u32 = 128;

    /// Largest accepted resolution (`1024² × 128` bytes = 128 MiB).
    pub const MAX_RESOLUTION: u32 = 1024;

    /// Builds the table with `resolution` entries per side, clamped to
    /// `1..=MAX_RESOLUTION`: `resolution² × 128` bytes. Aborts like any Rust allocation when memory runs out;
    /// [`HalfSpaceTable::try_new`] reports it.
    pub fn new(resolution: u32) -> Self {
        match Self::try_new(resolution) {
            Ok(table) => table,
            Err(_) => alloc::alloc::handle_alloc_error(core::alloc::Layout::new::<HemiMask>()),
        }
    }

    /// Builds the table, reporting failure to allocate it instead of aborting.
    pub fn try_new(resolution: u32) -> Result<Self, TryReserveError> {
        let n = resolution.clamp(1, Self::MAX_RESOLUTION) as usize;
        let mut masks = Vec::new();
        masks.try_reserve_exact(n * n)?;
        for l in 0..n {
            for k in 0..n {
                masks.push(half_space_mask(entry_normal(n, k, l)));
            }
        }
        Ok(HalfSpaceTable {
            resolution: n,
            masks: masks.into_boxed_slice(),
        })
    }

    /// Entries per side.
    #[inline]
    pub fn resolution(&self) -> u32 {
        self.resolution as u32
    }

    /// Bytes held by the masks: `resolution² × 128`.
    #[inline]
    pub fn size_bytes(&self) -> usize {
        self.masks.len() * core::mem::size_of::<HemiMask>()
    }

    /// The normal (unnormalised, `z > 0`) whose exact mask entry `(k, l)` holds;
    /// `None` outside the table.
    pub fn entry_normal(&self, k: usize, l: usize) -> Option<Vec3> {
        (k < self.resolution && l < self.resolution).then(|| entry_normal(self.resolution, k, l))
    }

    /// The table's approximation of [`half_space_mask(m)`](half_space_mask): the
    /// entry nearest to `m` (or the complement of `-m`'s). `m = 0` gives
    /// [`HemiMask::VALID`], like the exact predicate; a non-finite `m` gives an
    /// unspecified mask.
    #[inline]
    pub fn lookup(&self, m: Vec3) -> HemiMask {
        let (entry, flip) = self.entry(m);
        let mut out = HemiMask::EMPTY;
        for j in 0..GRID {
            out.rows[j] = (entry.rows[j] ^ flip) & HemiMask::VALID.rows[j];
        }
        out
    }

    /// The entry for `m` and the word to XOR it with (`0`, or `!0` for the
    /// complement); the caller ANDs with [`HemiMask::VALID`] after the XOR.
    #[inline]
    pub(crate) fn entry(&self, m: Vec3) -> (&HemiMask, u32) {
        match self.index(m) {
            Some((index, flip)) => (&self.masks[index], flip),
            // m = 0: every cell is on the plane, and inside. Non-finite: anything.
            None => (&HemiMask::VALID, 0),
        }
    }

    /// Index of the entry for `m` and the XOR word; `None` for a zero or
    /// non-finite `m`.
    #[inline]
    fn index(&self, m: Vec3) -> Option<(usize, u32)> {
        let canonical = m.z > 0.0 || (m.z == 0.0 && (m.y > 0.0 || (m.y == 0.0 && m.x >= 0.0)));
        let (g, flip) = if canonical { (m, 0) } else { (-m, u32::MAX) };
        let l1 = g.x.abs() + g.y.abs() + g.z.abs();
        if !(l1 > 0.0 && l1.is_finite()) {
            return None;
        }
        let n = self.resolution as f32;
        let scale = 0.5 * n / l1;
        // (s + 1) / 2 * n with s = (x + y) / l1; truncation is floor for these
        // non-negative values, and the clamp keeps s = 1 (and rounding) in range.
        let index = |w: f32| ((w * scale + 0.5 * n).max(0.0) as usize).min(self.resolution - 1);
        let (k, l) = (index(g.x + g.y), index(g.x - g.y));
        Some((l * self.resolution + k, flip))
    }
}

/// The normal at the center of entry `(k, l)` of an `n × n` table.
fn entry_normal(n: usize, k: usize, l: usize) -> Vec3 {
    let s = (2 * k + 1) as f32 / n as f32 - 1.0;
    let t = (2 * l + 1) as f32 / n as f32 - 1.0;
    let (x, y) = (0.5 * (s + t), 0.5 * (s - t));
    Vec3::new(x, y, 1.0 - x.abs() - y.abs())
}

#[cfg(test)]
mod tests {
    // Printing the measured figures needs std even in --no-default-features runs.
    extern crate std;

    use super::*;
    use crate::hemi::mask::VALID_CELL_COUNT;
    use rand::{Rng, SeedableRng, rngs::SmallRng};

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
        assert_eq!(table.size_bytes(), 16 * 16 * 128);
        for l in 0..16 {
            for k in 0..16 {
                let m = table.entry_normal(k, l).unwrap();
                assert!(m.z > 0.0);
                // An entry's own normal (scaled, too) finds the entry.
                assert_eq!(table.lookup(m), half_space_mask(m));
                assert_eq!(table.lookup(m * 3.5), half_space_mask(m));
                assert_eq!(table.lookup(-m), half_space_mask(m).complement());
            }
        }
        assert_eq!(table.entry_normal(16, 0), None);
    }

    #[test]
    fn opposite_normals_are_exact_complements() {
        let table = HalfSpaceTable::new(32);
        let mut rng = SmallRng::seed_from_u64(3);
        let mut normals: Vec<Vec3> = (0..2000).map(|_| random_unit(&mut rng)).collect();
        // On the equator and on the axes, where the canonical half is decided by
        // the tie-breaking rules.
        normals.extend([
            Vec3::X,
            Vec3::Y,
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.3, 0.0, -0.0),
        ]);
        for m in normals {
            let (pos, neg) = (table.lookup(m), table.lookup(-m));
            assert_eq!(pos & neg, HemiMask::EMPTY, "m = {m:?}");
            assert_eq!(pos | neg, HemiMask::VALID, "m = {m:?}");
        }
    }

    #[test]
    fn degenerate_normals_do_not_panic() {
        let table = HalfSpaceTable::new(0);
        assert_eq!(table.resolution(), 1);
        assert_eq!(table.lookup(Vec3::ZERO), HemiMask::VALID);
        assert_eq!(table.lookup(-Vec3::ZERO), HemiMask::VALID);
        for m in [
            Vec3::NAN,
            Vec3::INFINITY,
            Vec3::new(f32::MAX, f32::MAX, 1.0),
        ] {
            let mask = table.lookup(m);
            assert_eq!(mask & HemiMask::VALID, mask);
        }
    }

    /// The figures of [`HalfSpaceTable::DEFAULT_RESOLUTION`]'s docs. Run with
    /// `cargo test -p antumbra-core --lib table_size_versus_wrong_cells -- --nocapture`.
    #[test]
    fn table_size_versus_wrong_cells() {
        const SAMPLES: usize = 20_000;
        let mut rng = SmallRng::seed_from_u64(0x7ab1e);
        let normals: Vec<Vec3> = (0..SAMPLES).map(|_| random_unit(&mut rng)).collect();
        let exact: Vec<HemiMask> = normals.iter().map(|&m| half_space_mask(m)).collect();
        let mut previous_mean = f64::INFINITY;
        for resolution in [32, 64, 128, 256] {
            let table = HalfSpaceTable::new(resolution);
            let (mut total, mut max) = (0u64, 0u32);
            for (&m, e) in normals.iter().zip(&exact) {
                let wrong = table.lookup(m).count_differences(e);
                total += u64::from(wrong);
                max = max.max(wrong);
            }
            let mean = total as f64 / SAMPLES as f64;
            std::println!(
                "half-space table {resolution:>3}x{resolution:<3}: {:>8} bytes, wrong cells per mask: \
                 mean {mean:.2}, max {max} (of {VALID_CELL_COUNT}), {SAMPLES} random normals",
                table.size_bytes()
            );
            // Each doubling of the side should roughly halve the error.
            assert!(mean < previous_mean * 0.7, "{resolution}: mean {mean}");
            previous_mean = mean;
            if resolution == HalfSpaceTable::DEFAULT_RESOLUTION {
                assert!(
                    mean < 3.0 && max <= 20,
                    "default table: mean {mean}, max {max}"
                );
            }
        }
    }
}
