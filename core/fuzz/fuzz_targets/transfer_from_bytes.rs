//! Fuzzes the bake file loader: any input must give `Ok` or a `FormatError`, never
//! a panic, and whatever loads must write back to the same bytes and shade without
//! panicking.
#![no_main]

use antumbra_core::transfer::{Material, TransferSet, View};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(set) = TransferSet::from_bytes(data) else {
        return;
    };
    assert_eq!(set.to_bytes(), data, "a loaded file must round-trip");
    let lighting = vec![[0.5f32, 0.25, 0.125]; set.coeff_count()];
    let mut out = vec![[0.0f32; 3]; set.vertex_count()];
    set.shade(&lighting, View::Eye([0.3, 2.0, 1.0]), &Material::default(), None, &mut out)
        .expect("valid arguments");
});
