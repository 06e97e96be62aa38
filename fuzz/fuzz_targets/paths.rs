//! Fuzzes the headless scripts: probe paths (palpation) and coordinate paths (network
//! scenes). Any text gives a path or an error, never a panic; a path that reads is
//! evaluated at its ends and beyond. Run: `scripts/fuzz.sh 60 paths`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use palpa_app::network::path::CoordinatePath;
use palpa_app::offscreen::ProbePath;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(p) = ProbePath::from_json(&text) {
        for t in [-1.0, 0.0, 0.5, 1e9, f64::MAX] {
            let _ = p.at(t);
        }
    }
    let _ = CoordinatePath::from_json(&text);
});
