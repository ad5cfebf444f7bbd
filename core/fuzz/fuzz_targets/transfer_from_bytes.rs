//! Fuzzes the bake file loader: any input must give `Ok` or a `FormatError`, never
//! a panic, and whatever loads must write back to the same bytes and shade without
//! panicking.
//!
//! Each input is tried twice: as it is (so the checksums themselves are fuzzed),
//! and with both CRC-32 fields recomputed by `reseal`, at the offsets of the
//! version the input names (otherwise almost every mutation stops at the header
//! checksum, and the field and payload validation behind it would never be
//! reached).
#![no_main]

use antumbra_core::transfer::format::reseal;
use antumbra_core::transfer::{Material, TransferSet, View};
use libfuzzer_sys::fuzz_target;

fn check(data: &[u8]) {
    let Ok(set) = TransferSet::from_bytes(data) else {
        return;
    };
    assert_eq!(set.to_bytes(), data, "a loaded file must round-trip");
    let lighting = vec![[0.5f32, 0.25, 0.125]; set.coeff_count()];
    let mut out = vec![[0.0f32; 3]; set.vertex_count()];
    set.shade(&lighting, View::Eye([0.3, 2.0, 1.0]), &Material::glossy(1.0), None, &mut out)
        .expect("valid arguments");
    set.shade(&lighting, View::Eye([0.3, 2.0, 1.0]), &Material::glossy(1.0), Some(1), &mut out)
        .expect("valid arguments");
}

fuzz_target!(|data: &[u8]| {
    check(data);
    let mut fixed = data.to_vec();
    reseal(&mut fixed);
    if fixed != data {
        check(&fixed);
    }
});
