//! The framing of palpa's small checksummed files (force laws, tissue laws): 8 magic
//! bytes, a little-endian `u32` format version, the xxh3-64 checksum of the body, then
//! the body in bincode's standard encoding. Written atomically ([`crate::fsutil`]);
//! read back with every way it can be wrong named.

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

/// Encodes `value` and writes it framed to `path`, atomically.
pub fn write<T: Serialize>(
    path: &Path,
    magic: &[u8; 8],
    version: u32,
    value: &T,
) -> io::Result<()> {
    let body = bincode::serde::encode_to_vec(value, bincode::config::standard())
        .map_err(io::Error::other)?;
    crate::fsutil::atomic_write(path, |w| {
        use std::io::Write;
        w.write_all(magic)?;
        w.write_all(&version.to_le_bytes())?;
        w.write_all(&xxhash_rust::xxh3::xxh3_64(&body).to_le_bytes())?;
        w.write_all(&body)
    })
}

/// Reads a value framed by [`write`] from `bytes`.
pub fn read<T: DeserializeOwned>(
    bytes: &[u8],
    magic: &[u8; 8],
    version: u32,
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
    if found != version {
        return Err(FramedError::Version(found));
    }
    let body = &bytes[20..];
    if xxhash_rust::xxh3::xxh3_64(body) != word(12..20) {
        return Err(FramedError::Corrupt("checksum mismatch".into()));
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
