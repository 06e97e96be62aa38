//! Fuzzes the region file reader and the selector syntax: any text gives regions or an
//! error, never a panic; selectors that parse are evaluated. Run:
//! `scripts/fuzz.sh 60 regions`.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use palpa_core::organ::region_file::RegionFile;
use palpa_core::organ::syntax::parse;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(sel) = parse(&text) {
        let _ = sel.contains([1.0, 2.0, 3.0], [0.0, 1.0, 0.0]);
    }
    if let Ok(r) = RegionFile::from_text(&text, Path::new("fuzz.toml")) {
        if let Ok((f, p)) = r.selectors(Path::new("fuzz.toml")) {
            let _ = f.contains([0.0; 3], [0.0, 0.0, 1.0]);
            let _ = p.contains([0.0; 3], [0.0, 0.0, 1.0]);
        }
    }
});
