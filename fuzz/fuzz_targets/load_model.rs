//! Fuzzes the meta-model loaders: any byte string must give a model or an error, never
//! a panic, an abort, or an allocation larger than the input justifies. Every kind is
//! tried: separated palpation and network models (f32, f64), tensor trains, views
//! models and tissue (hyperelastic vademecum) files.
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
    if let Ok(m) = palpa_core::cme::model::load_from_bytes(data) {
        // A network model that loads must evaluate at the start and at its parameters'
        // lower ends.
        let at: Vec<(String, f64)> = m.parameters().into_iter().map(|(n, lo, _)| (n, lo)).collect();
        let _ = m.evaluate(0.0, &at, 4);
    }
    if let Ok(t) = palpa_core::tissue::law::TissueLaw::from_bytes(data, std::path::Path::new("<memory>")) {
        let _ = t.check();
    }
});
