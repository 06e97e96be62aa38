//! The framing of palpa's small checksummed files (force laws, tissue laws): 8 magic
//! bytes, a little-endian `u32` format version, the xxh3-64 checksum of the body, then
//! the body: bincode's standard encoding, or that deflated ([`Body`]: a format
//! version says which). Written atomically ([`crate::fsutil`]); read back with every
//! way it can be wrong named. The checksum covers the stored bytes, so a damaged
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
    if kind == Body::Deflated {
        use std::io::Write;
        let mut z = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
        z.write_all(&body)?;
        body = z.finish()?;
    }
    crate::fsutil::atomic_write(path, |w| {
        use std::io::Write;
        w.write_all(magic)?;
        w.write_all(&version.to_le_bytes())?;
        w.write_all(&xxhash_rust::xxh3::xxh3_64(&body).to_le_bytes())?;
        w.write_all(&body)
    })
}

/// Reads a value framed by [`write`] from `bytes`, in any of the format versions
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
        return Err(FramedError::Corrupt("checksum mismatch".into()));
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
            if out.len() > LIMIT_BYTES {
                return Err(FramedError::Corrupt(format!(
                    "inflates past {LIMIT_BYTES} bytes"
                )));
            }
            inflated = out;
            &inflated[..]
        }
    };
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

    /// Either body comes back as written; a deflated one of repetitive values is
    /// smaller; a version not read is named; a deflate stream that is not one (with a
    /// checksum that matches it) is named, not decoded.
    #[test]
    fn bodies_come_back_plain_or_deflated() {
        let dir = tempfile::tempdir().expect("tempdir");
        let value: Vec<u32> = (0..10_000).map(|i| i % 7).collect();
        let mut sizes = Vec::new();
        for (k, kind) in [Body::Plain, Body::Deflated].into_iter().enumerate() {
            let path = dir.path().join(format!("{k}.bin"));
            write(&path, b"PALPATST", (3 + k as u32, kind), &value).expect("writes");
            let bytes = std::fs::read(&path).expect("read");
            sizes.push(bytes.len());
            let reads = [(3, Body::Plain), (4, Body::Deflated)];
            let back: Vec<u32> = read(&bytes, b"PALPATST", &reads).expect("reads");
            assert_eq!(back, value);
            let only_other = [(5, Body::Plain)];
            let e = read::<Vec<u32>>(&bytes, b"PALPATST", &only_other).expect_err("version");
            assert_eq!(e, FramedError::Version(3 + k as u32));
        }
        assert!(sizes[1] * 10 < sizes[0], "{sizes:?}");

        let mut bytes = b"PALPATST".to_vec();
        bytes.extend(4u32.to_le_bytes());
        let junk = [0xffu8; 64];
        bytes.extend(xxhash_rust::xxh3::xxh3_64(&junk).to_le_bytes());
        bytes.extend(junk);
        let e = read::<Vec<u32>>(&bytes, b"PALPATST", &[(4, Body::Deflated)]).expect_err("junk");
        assert!(
            matches!(&e, FramedError::Corrupt(why) if why.contains("inflating")),
            "{e:?}"
        );
    }
}
