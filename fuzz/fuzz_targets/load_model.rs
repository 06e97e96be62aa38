//! Fuzzes the meta-model loader: any byte string must give a model or an error, never a
//! panic, an abort, or an allocation larger than the input justifies.
//! Run: `cargo fuzz run load_model` (see scripts/fuzz.sh).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(model) = palpa_core::file::load_any_from_bytes(data) {
        // A model that loads must also evaluate without panicking on its first node.
        let m = model.into_f64();
        let mut c = vec![0.0; m.modes()];
        let mut out = vec![0.0; m.rows().min(3)];
        c.fill(1.0);
        m.reconstruct_range(0, &c, &mut out);
    }
});
