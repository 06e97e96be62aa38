//! The framing of palpa's small checksummed files (force laws, tissue laws): 8 magic
//! bytes, a little-endian `u32` format version, the xxh3-64 checksum of the body, then
//! the body: bincode's standard encoding, plain, deflated or LZMA-compressed ([`Body`]:
//! a format version says which). Written atomically ([`crate::fsutil`]); read back with
//! every way it can be wrong named. The checksum covers the stored bytes, so a damaged
//! file is named before it is inflated.

use std::io;
use std::path::Path;

use serde::Serialize;
use serde::de::DeserializeOwned;

/// Why framed bytes could not be read.
#[derive(Debug, Clone, PartialEq)]
pub enum FramedError {
    /// Not this kind of file (the magic bytes differ, or it is too short).
    Foreign,
    /// Another format version.
    Version(u32),
    /// Checksum, encoding or trailing bytes: the reason.
    Corrupt(String),
}

/// Largest body decoded (a corrupt length field cannot ask for more).
const LIMIT_BYTES: usize = 512 << 20;

/// How a format version stores its body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Body {
    Plain,
    /// Deflated (RFC 1951): quantized shapes are far from random bytes (a tissue law
    /// of 8-bit shapes shrinks to 55 %).
    Deflated,
    /// An `.lzma` stream (LZMA with its 13-byte header: properties, dictionary size,
    /// length), the dictionary as large as the body (up to [`LZMA_DICT_MAX`]). Lossless
    /// like deflate, and 15 % smaller on a 27 MB tissue law (8.09 → 6.89 MB: LZMA's
    /// range coder with literal contexts models the 8-bit shapes' skewed values where
    /// deflate's Huffman codes spend whole bits, and its window spans the whole body
    /// where deflate's spans 32 KB). Writing it is slower (about 11 s for the shipped
    /// tissue's 38.7 MB body, see `lzma_options`; deflate took 4 s on a 27 MB one),
    /// reading it about 0.3 s slower.
    Lzma,
}

/// The largest LZMA dictionary written or read (a corrupt header cannot ask a reader
/// for more memory than this, with the decoder's own few hundred KB).
pub const LZMA_DICT_MAX: u32 = 64 << 20;

/// The LZMA encoder's settings for a body of `len` bytes: normal mode (the optimal
/// parse of preset 9) with the hash-chain match finder looking at one candidate a
/// position, and the longest match the format allows (273 bytes), its dictionary cut
/// to the smallest power of two that holds the body (a larger one finds nothing more
/// and costs the encoder about ten times its size in memory). Measured on the shipped
/// tissue's 38.7 MB body, one after the other on the otherwise idle machine: preset 9
/// as it comes (binary tree, full search, matches to 64 bytes) 8.00 MB in 39 s; with
/// matches to 273 bytes 7.91 MB in 52 s (what files were written with until
/// 2026-11-30); this 7.97 MB in 11 s. Of the hash-chain depths tried (1, 2, 4, 8, 16
/// and 48 candidates: 7.97–8.14 MB), one gave both the smallest stream and the
/// fastest. Any LZMA reader reads either stream.
fn lzma_options(len: usize) -> lzma_rust2::LzmaOptions {
    let mut options = lzma_rust2::LzmaOptions::with_preset(9);
    options.mf = lzma_rust2::MfType::Hc4;
    options.depth_limit = 1;
    options.nice_len = lzma_rust2::LzmaOptions::NICE_LEN_MAX;
    let fits = u32::try_from(len.max(1 << 16))
        .map_or(LZMA_DICT_MAX, |n| n.next_power_of_two().min(LZMA_DICT_MAX));
    options.dict_size = fits;
    options
}

fn lzma_compress(body: &[u8]) -> io::Result<Vec<u8>> {
    use std::io::Write;
    let options = lzma_options(body.len());
    let mut z =
        lzma_rust2::LzmaWriter::new_use_header(Vec::new(), &options, Some(body.len() as u64))?;
    z.write_all(body)?;
    z.finish()
}

fn lzma_decompress(stored: &[u8]) -> Result<Vec<u8>, FramedError> {
    use std::io::Read;
    let corrupt = |e: io::Error| FramedError::Corrupt(format!("decompressing LZMA: {e}"));
    let limit_kb = LZMA_DICT_MAX / 1024 + 1024;
    let mut out = Vec::new();
    lzma_rust2::LzmaReader::new_mem_limit(stored, limit_kb, None)
        .map_err(corrupt)?
        .take(LIMIT_BYTES as u64 + 1)
        .read_to_end(&mut out)
        .map_err(corrupt)?;
    Ok(out)
}

/// Encodes `value` and writes it framed to `path`, atomically.
pub fn write<T: Serialize>(
    path: &Path,
    magic: &[u8; 8],
    (version, kind): (u32, Body),
    value: &T,
) -> io::Result<()> {
    let mut body = bincode::serde::encode_to_vec(value, bincode::config::standard())
        .map_err(io::Error::other)?;
    match kind {
        Body::Plain => {}
        Body::Deflated => {
            use std::io::Write;
            let mut z = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
            z.write_all(&body)?;
            body = z.finish()?;
        }
        Body::Lzma => body = lzma_compress(&body)?,
    }
    crate::fsutil::atomic_write(path, |w| {
        use std::io::Write;
        w.write_all(magic)?;
        w.write_all(&version.to_le_bytes())?;
        w.write_all(&xxhash_rust::xxh3::xxh3_64(&body).to_le_bytes())?;
        w.write_all(&body)
    })
}

/// Reads a value framed by [`write()`] from `bytes`, in any of the format versions
/// `reads` (each with how it stores its body).
pub fn read<T: DeserializeOwned>(
    bytes: &[u8],
    magic: &[u8; 8],
    reads: &[(u32, Body)],
) -> Result<T, FramedError> {
    if bytes.len() < 20 || &bytes[..8] != magic {
        return Err(FramedError::Foreign);
    }
    let word = |r: std::ops::Range<usize>| -> u64 {
        bytes[r]
            .iter()
            .rev()
            .fold(0u64, |acc, &b| (acc << 8) | u64::from(b))
    };
    let found = word(8..12) as u32;
    let Some(&(_, kind)) = reads.iter().find(|(v, _)| *v == found) else {
        return Err(FramedError::Version(found));
    };
    let stored = &bytes[20..];
    if xxhash_rust::xxh3::xxh3_64(stored) != word(12..20) {
        // The frame records no length, so a file cut short reads as this too.
        return Err(FramedError::Corrupt(format!(
            "checksum mismatch: the {} bytes after the header do not hash to the checksum \
             it records (damaged or cut short; copy or build it again)",
            stored.len()
        )));
    }
    let inflated;
    let body = match kind {
        Body::Plain => stored,
        Body::Deflated => {
            use std::io::Read;
            let mut out = Vec::new();
            flate2::read::DeflateDecoder::new(stored)
                .take(LIMIT_BYTES as u64 + 1)
                .read_to_end(&mut out)
                .map_err(|e| FramedError::Corrupt(format!("inflating: {e}")))?;
            inflated = out;
            &inflated[..]
        }
        Body::Lzma => {
            inflated = lzma_decompress(stored)?;
            &inflated[..]
        }
    };
    if kind != Body::Plain && body.len() > LIMIT_BYTES {
        return Err(FramedError::Corrupt(format!(
            "inflates past {LIMIT_BYTES} bytes"
        )));
    }
    let (value, used): (T, usize) = bincode::serde::decode_from_slice(
        body,
        bincode::config::standard().with_limit::<LIMIT_BYTES>(),
    )
    .map_err(|e| FramedError::Corrupt(e.to_string()))?;
    if used != body.len() {
        return Err(FramedError::Corrupt(format!(
            "{} bytes after the value",
            body.len() - used
        )));
    }
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every body comes back as written; a compressed one of repetitive values is
    /// smaller; a version not read is named; a compressed stream that is not one (with
    /// a checksum that matches it) is named, not decoded.
    #[test]
    fn bodies_come_back_plain_deflated_or_lzma() {
        let dir = tempfile::tempdir().expect("tempdir");
        let value: Vec<u32> = (0..10_000).map(|i| i % 7).collect();
        let mut sizes = Vec::new();
        let kinds = [Body::Plain, Body::Deflated, Body::Lzma];
        for (k, kind) in kinds.into_iter().enumerate() {
            let path = dir.path().join(format!("{k}.bin"));
            write(&path, b"PALPATST", (3 + k as u32, kind), &value).expect("writes");
            let bytes = std::fs::read(&path).expect("read");
            sizes.push(bytes.len());
            let reads = [(3, Body::Plain), (4, Body::Deflated), (5, Body::Lzma)];
            let back: Vec<u32> = read(&bytes, b"PALPATST", &reads).expect("reads");
            assert_eq!(back, value);
            let only_other = [(9, Body::Plain)];
            let e = read::<Vec<u32>>(&bytes, b"PALPATST", &only_other).expect_err("version");
            assert_eq!(e, FramedError::Version(3 + k as u32));
        }
        assert!(sizes[1] * 10 < sizes[0], "{sizes:?}");
        assert!(sizes[2] * 10 < sizes[0], "{sizes:?}");

        for (kind, says) in [(Body::Deflated, "inflating"), (Body::Lzma, "LZMA")] {
            let mut bytes = b"PALPATST".to_vec();
            bytes.extend(4u32.to_le_bytes());
            let junk = [0xffu8; 64];
            bytes.extend(xxhash_rust::xxh3::xxh3_64(&junk).to_le_bytes());
            bytes.extend(junk);
            let e = read::<Vec<u32>>(&bytes, b"PALPATST", &[(4, kind)]).expect_err("junk");
            assert!(
                matches!(&e, FramedError::Corrupt(why) if why.contains(says)),
                "{kind:?}: {e:?}"
            );
        }
    }

    /// A cut LZMA body (a file copied short, its checksum made to match) is named
    /// corrupt, not read as a shorter value.
    #[test]
    fn a_truncated_lzma_body_is_named() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("z.bin");
        let value: Vec<u32> = (0..50_000u32)
            .map(|i| i.wrapping_mul(2_654_435_761) >> 20)
            .collect();
        write(&path, b"PALPATST", (5, Body::Lzma), &value).expect("writes");
        let bytes = std::fs::read(&path).expect("read");
        let cut = &bytes[20..bytes.len() / 2];
        let mut short = bytes[..12].to_vec();
        short.extend(xxhash_rust::xxh3::xxh3_64(cut).to_le_bytes());
        short.extend(cut);
        let e = read::<Vec<u32>>(&short, b"PALPATST", &[(5, Body::Lzma)]).expect_err("cut");
        assert!(matches!(&e, FramedError::Corrupt(_)), "{e:?}");
        // Copied short as it is (the checksum left alone): the mismatch names the stored
        // length and says a cut file reads so.
        let e = read::<Vec<u32>>(&bytes[..bytes.len() / 2], b"PALPATST", &[(5, Body::Lzma)])
            .expect_err("cut");
        let stored = bytes.len() / 2 - 20;
        assert!(
            matches!(&e, FramedError::Corrupt(why)
                if why.contains(&format!("{stored} bytes")) && why.contains("cut short")),
            "{e:?}"
        );
    }
}
