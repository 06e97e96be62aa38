//! The meta-model file: round trips, and one distinct error for each kind of bad file.

use std::fs;
use std::path::{Path, PathBuf};

use palpa_core::file::{self, FORMAT_VERSION, FileError, Header, MAGIC};
use palpa_core::{AnyModel, Discretization, SeparatedModel};
use palpa_tests::small_model;
use proptest::prelude::*;

fn saved(dir: &Path) -> (PathBuf, SeparatedModel<f64>) {
    let m = small_model::<f64>(20, 7, 1);
    let path = dir.join("m.palpa");
    file::save(&m, &path).expect("save");
    (path, m)
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    fs::write(&p, bytes).expect("write");
    p
}

/// Re-encodes a (possibly edited) header in front of `payload`, with valid checksums:
/// the format spelled out independently of the writer, to craft consistent-looking files.
fn craft(header: &Header, payload: &[u8]) -> Vec<u8> {
    let h = bincode::serde::encode_to_vec(header, bincode::config::standard()).expect("encode");
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(h.len() as u64).to_le_bytes());
    out.extend_from_slice(&xxhash_rust::xxh3::xxh3_64(&h).to_le_bytes());
    out.extend_from_slice(&h);
    out.resize(out.len().div_ceil(64) * 64, 0);
    out.extend_from_slice(payload);
    out
}

/// The header and payload bytes of a valid file.
fn split(path: &Path) -> (Header, Vec<u8>) {
    let header = file::read_header(path).expect("valid header");
    let bytes = fs::read(path).expect("read");
    let payload = bytes[bytes.len() - header.payload_len as usize..].to_vec();
    (header, payload)
}

#[test]
fn round_trip_is_bit_identical_for_both_precisions() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, m) = saved(dir.path());
    let back = file::load::<f64>(&path).expect("load");
    assert_eq!(back, m);
    // Saving what was loaded reproduces the file byte for byte.
    let again = dir.path().join("again.palpa");
    file::save(&back, &again).expect("save");
    assert_eq!(fs::read(&path).expect("a"), fs::read(&again).expect("b"));

    let m32 = small_model::<f32>(11, 5, 2);
    let p32 = dir.path().join("m32.palpa");
    file::save(&m32, &p32).expect("save");
    assert_eq!(file::load::<f32>(&p32).expect("load"), m32);
    match file::load_any(&p32).expect("load_any") {
        AnyModel::F32(m) => assert_eq!(m, m32),
        AnyModel::F64(_) => panic!("an f32 file loaded as f64"),
    }
}

#[test]
fn save_over_an_existing_file_replaces_it_atomically() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let other = small_model::<f64>(5, 2, 9);
    file::save(&other, &path).expect("overwrite");
    assert_eq!(file::load::<f64>(&path).expect("load"), other);
    let leftovers: Vec<_> = fs::read_dir(dir.path())
        .expect("ls")
        .filter_map(Result::ok)
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

#[test]
fn a_foreign_file_is_named_as_such() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, bytes) in [
        ("empty", &b""[..]),
        ("png", &b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR"[..]),
        ("text", &b"displacement,mm\n1,2,3\n"[..]),
    ] {
        let p = write(dir.path(), name, bytes);
        let e = file::load::<f64>(&p).expect_err("foreign");
        assert!(matches!(e, FileError::Foreign { .. }), "{name}: {e}");
        assert!(e.to_string().contains("not a palpa meta-model file"), "{e}");
    }
    let e = file::load::<f64>(&dir.path().join("missing")).expect_err("missing");
    assert!(matches!(e, FileError::Io { .. }), "{e}");
}

#[test]
fn a_newer_version_is_refused_with_the_versions() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let mut b = fs::read(&path).expect("read");
    b[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    let p = write(dir.path(), "newer", &b);
    let e = file::load::<f64>(&p).expect_err("newer");
    match e {
        FileError::NewerVersion {
            found, supported, ..
        } => {
            assert_eq!((found, supported), (FORMAT_VERSION + 1, FORMAT_VERSION));
        }
        other => panic!("expected NewerVersion, got {other}"),
    }
}

#[test]
fn an_older_version_is_refused_with_the_command_that_rebuilds_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let mut b = fs::read(&path).expect("read");
    for old in [1, FORMAT_VERSION - 1] {
        b[8..12].copy_from_slice(&old.to_le_bytes());
        let p = write(dir.path(), "old.palpa", &b);
        match file::load::<f64>(&p) {
            Err(e @ FileError::OlderVersion { found, current, .. }) => {
                assert_eq!((found, current), (old, FORMAT_VERSION));
                let msg = e.to_string();
                assert!(
                    msg.contains("palpa offline") && msg.contains("palpa cme offline"),
                    "{msg}"
                );
            }
            other => panic!("expected OlderVersion, got {other:?}"),
        }
    }
}

#[test]
fn truncation_anywhere_is_reported_as_truncated() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let b = fs::read(&path).expect("read");
    let (header, _) = split(&path);
    let payload_at = b.len() - header.payload_len as usize;
    for (what, cut) in [
        ("the preamble", 20),
        ("the header", 40),
        ("the payload", payload_at + 8),
        ("the payload", b.len() - 1),
    ] {
        let p = write(dir.path(), "cut", &b[..cut]);
        match file::load::<f64>(&p).expect_err("truncated") {
            FileError::Truncated { what: w, .. } => assert_eq!(w, what, "cut at {cut}"),
            other => panic!("cut at {cut}: expected Truncated, got {other}"),
        }
    }
}

#[test]
fn a_corrupted_header_is_caught_by_its_checksum() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let mut b = fs::read(&path).expect("read");
    b[40] ^= 0x10;
    let p = write(dir.path(), "hdr", &b);
    let e = file::load::<f64>(&p).expect_err("corrupt");
    assert!(matches!(e, FileError::HeaderCorrupt { .. }), "{e}");
}

#[test]
fn a_huge_header_length_is_refused_before_allocating() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let mut b = fs::read(&path).expect("read");
    b[16..24].copy_from_slice(&(1u64 << 62).to_le_bytes());
    let p = write(dir.path(), "huge", &b);
    let e = file::load::<f64>(&p).expect_err("huge");
    assert!(matches!(e, FileError::HeaderCorrupt { .. }), "{e}");
}

#[test]
fn a_corrupted_payload_is_caught_by_its_checksum() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let mut b = fs::read(&path).expect("read");
    let n = b.len();
    b[n - 100] ^= 0x01;
    let p = write(dir.path(), "payload", &b);
    let e = file::load::<f64>(&p).expect_err("corrupt");
    assert!(matches!(e, FileError::PayloadCorrupt { .. }), "{e}");
    // The header alone still reads: `palpa info` works on such a file.
    assert!(file::read_header(&p).is_ok());
}

#[test]
fn trailing_bytes_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let mut b = fs::read(&path).expect("read");
    b.extend_from_slice(b"junk");
    let p = write(dir.path(), "trailing", &b);
    match file::load::<f64>(&p).expect_err("trailing") {
        FileError::TrailingBytes { extra, .. } => assert_eq!(extra, 4),
        other => panic!("expected TrailingBytes, got {other}"),
    }
}

#[test]
fn the_wrong_precision_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let e = file::load::<f32>(&path).expect_err("precision");
    assert!(matches!(e, FileError::WrongPrecision { .. }), "{e}");
}

#[test]
fn a_consistent_looking_but_impossible_header_is_inconsistent() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let (header, payload) = split(&path);

    let mut h = header.clone();
    h.payload_len += 64;
    let p = write(dir.path(), "len", &craft(&h, &payload));
    let e = file::load::<f64>(&p).expect_err("inconsistent");
    assert!(matches!(e, FileError::Inconsistent { .. }), "{e}");

    // Sizes whose product overflows: refused without allocating.
    let mut h = header.clone();
    h.rows = u64::MAX / 2;
    let p = write(dir.path(), "overflow", &craft(&h, &payload));
    let e = file::load::<f64>(&p).expect_err("overflow");
    assert!(matches!(e, FileError::Inconsistent { .. }), "{e}");

    // Sizes that fit in 64 bits but not in the file.
    let mut h = header.clone();
    h.rows = 1 << 40;
    h.payload_len = (1 << 40) * h.modes * 8 + 64 * 10;
    let p = write(dir.path(), "big", &craft(&h, &payload));
    let e = file::load::<f64>(&p).expect_err("big");
    assert!(
        matches!(
            e,
            FileError::Inconsistent { .. } | FileError::Truncated { .. }
        ),
        "{e}"
    );
}

#[test]
fn an_invalid_model_inside_a_valid_file_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (path, _) = saved(dir.path());
    let (header, payload) = split(&path);

    // A grid axis whose nodes do not increase.
    let mut h = header.clone();
    h.meta.axes[1].discretization = Discretization::Grid {
        nodes: vec![0.0, 2.0, 1.0, 3.0],
    };
    let p = write(dir.path(), "grid", &craft(&h, &payload));
    let e = file::load::<f64>(&p).expect_err("grid");
    assert!(matches!(e, FileError::Model { .. }), "{e}");
    assert!(e.to_string().contains("increase"), "{e}");

    // A NaN in X, with a checksum that matches it.
    let mut payload_nan = payload.clone();
    payload_nan[0..8].copy_from_slice(&f64::NAN.to_le_bytes());
    let mut h = header.clone();
    h.payload_xxh3 = xxhash_rust::xxh3::xxh3_64(&payload_nan);
    let p = write(dir.path(), "nan", &craft(&h, &payload_nan));
    let e = file::load::<f64>(&p).expect_err("nan");
    assert!(e.to_string().contains("not finite"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]

    /// Any single flipped bit anywhere in the file is detected (never a panic, never a
    /// silently different model).
    #[test]
    fn any_bit_flip_is_detected(pos in 0usize..1_000_000, bit in 0u8..8) {
        let dir = tempfile::tempdir().expect("tempdir");
        let (path, _) = saved(dir.path());
        let mut b = fs::read(&path).expect("read");
        let i = pos % b.len();
        b[i] ^= 1 << bit;
        let p = write(dir.path(), "flip", &b);
        prop_assert!(file::load::<f64>(&p).is_err(), "flip at byte {} bit {} went unnoticed", i, bit);
    }

    /// Any truncation is an error, never a panic.
    #[test]
    fn any_truncation_is_an_error(cut in 0usize..1_000_000) {
        let dir = tempfile::tempdir().expect("tempdir");
        let (path, _) = saved(dir.path());
        let b = fs::read(&path).expect("read");
        let p = write(dir.path(), "cut", &b[..cut % b.len()]);
        prop_assert!(file::load::<f64>(&p).is_err());
    }

    /// Random models of random shapes round-trip exactly.
    #[test]
    fn random_models_round_trip(nodes in 1usize..40, modes in 0usize..20, seed in 0u64..1000) {
        let dir = tempfile::tempdir().expect("tempdir");
        let m = small_model::<f32>(nodes, modes, seed);
        let p = dir.path().join("r.palpa");
        file::save(&m, &p).expect("save");
        prop_assert_eq!(file::load::<f32>(&p).expect("load"), m);
    }
}
