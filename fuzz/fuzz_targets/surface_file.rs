//! Fuzzes the surface readers (OBJ, STL, PLY, told apart by content) and what follows
//! a read: validation, repairs and the signed distance. Any byte string gives a surface
//! or an error, never a panic. Run: `scripts/fuzz.sh 60 surface_file`.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use palpa_core::mesh::stuffing::Implicit;
use palpa_core::surface_import::read::read_bytes;
use palpa_core::surface_import::repair::close_holes;
use palpa_core::surface_import::SurfaceSolid;

fuzz_target!(|data: &[u8]| {
    let Ok(r) = read_bytes(Path::new("fuzz.obj"), data) else {
        return;
    };
    let mut s = r.surface;
    // Keep the quadratic checks bounded.
    if s.triangles.len() > 5000 {
        return;
    }
    close_holes(&mut s, 8);
    if s.validate().is_ok() {
        let solid = SurfaceSolid::new(s);
        let (lo, hi) = solid.bounds();
        let _ = solid.value(lo);
        let _ = solid.value(hi);
    }
});
