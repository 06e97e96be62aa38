//! The meta-model file (`.palpa`).
//!
//! Layout (all integers little-endian):
//!
//! ```text
//! offset  size  field
//!      0     8  magic  b"PALPAMM\x1a"   (\x1a catches text-mode mangling, as in PNG)
//!      8     4  format version (u32)    — this build reads FORMAT_VERSION only
//!     12     4  reserved, 0
//!     16     8  header length H (u64)
//!     24     8  xxh3-64 of the header bytes
//!     32     H  header: bincode 2 (standard config) of [`Header`]
//!      …        zero padding to a multiple of 64
//!      P        payload, each block row-major, little-endian f32 or f64, padded to 64
//!               bytes. The header's `layout` says what the blocks are: separated
//!               (X rows × modes, then each axis's values nodes × modes), with or
//!               without a nodal-load vademecum's near and far fields (carried in the
//!               header, f32 or sixteen bits, `quant16`); a tensor train (one core
//!               per axis, r_{k−1} × nodes × r_k, f64); a gene network's views
//! P + len       end of file (trailing bytes are an error)
//! ```
//!
//! The header says what the file is (field rows and their meaning, axes with names,
//! units and discretizations, provenance, the tradeoff table), the payload length and
//! its xxh3-64 checksum. Loading is a bounded header decode followed by one copy per
//! block straight into aligned vectors; no parse of the bulk data.
//!
//! The loader never trusts a length before checking it against the file size, decodes
//! the header with a byte limit, and returns a [`FileError`] naming the file and the
//! problem for each kind of bad input: not a palpa file, another version, truncated,
//! corrupted header, corrupted payload, inconsistent header, trailing bytes, a
//! precision other than the one asked for.

use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;
use xxhash_rust::xxh3::{Xxh3, xxh3_64};

use crate::axis::Discretization;
use crate::farfield::NestedFar;
use crate::fsutil::atomic_write;
use crate::nearfield::NearField;
use crate::quant16::Q16;
use crate::scalar::{Precision, Scalar};
use crate::separated::{ModelError, ModelMeta, SeparatedModel};
use crate::tensor::tt::Core;

pub const MAGIC: [u8; 8] = *b"PALPAMM\x1a";
/// The one format this build reads and writes. Until a release there is one current
/// version: a change to the layout bumps it, and older files are refused by name with
/// the command that rebuilds them ([`FileError::OlderVersion`]).
pub const FORMAT_VERSION: u32 = 10;
const PREAMBLE: usize = 32;
const ALIGN: u64 = 64;
/// Headers hold metadata and small discretizations (a surface of ~10⁵ vertices at most);
/// anything larger is corrupt, and the cap bounds what a crafted header can allocate.
pub const MAX_HEADER_BYTES: u64 = 64 << 20;

/// The file header (bincode-encoded after the preamble).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub meta: ModelMeta,
    pub precision: Precision,
    pub rows: u64,
    pub modes: u64,
    pub payload_len: u64,
    pub payload_xxh3: u64,
    pub layout: Layout,
}

impl Header {
    /// The xxh3-64 of what the file computes: the header without its wall-clock
    /// fields (the build's date, the tradeoff table's timings), which holds the
    /// payload's own checksum. Two builds of the same inputs have the same value
    /// (`palpa info F --json` reports it as `content_xxh3`; the asset manifest records it).
    pub fn content_xxh3(&self) -> u64 {
        let mut h = self.clone();
        h.meta.provenance.created_unix_s = 0;
        for r in &mut h.meta.tradeoff {
            r.surface_eval_us = 0.0;
            r.contact_eval_ns = 0.0;
        }
        match bincode::serde::encode_to_vec(&h, bincode_config()) {
            Ok(bytes) => xxh3_64(&bytes),
            // A header that decoded encodes again; this is never reached.
            Err(_) => 0,
        }
    }
}

/// How the payload's arrays make the model.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub enum Layout {
    /// `X` (rows × modes), then each axis's values (nodes × modes).
    #[default]
    Separated,
    /// One core per axis, `r_{k−1} × nodes_k × r_k` row-major; `ranks` holds
    /// `r_0 = 1, r_1, …, r_d = 1`. No `X` block.
    TensorTrain { ranks: Vec<u64> },
    /// As `Separated`, plus the near field of a nodal-load vademecum and, if it has
    /// one, its far field with nested column bases and shared row bases.
    SeparatedNear {
        near: Box<NearField>,
        far: Option<Box<NestedFar>>,
    },
    /// A gene network's views over time ([`crate::cme::views`]): per view,
    /// its time factor (`nodes × rank`) then its values (`rank × m`), f64.
    Views { views: Vec<ViewShape> },
    /// As `SeparatedNear`, with the near field's band and compliance table and the
    /// far field's bases and factors in sixteen bits ([`crate::quant16`]): those arrays are left empty in `near` and `far`
    /// and held in `q`. What `palpa export-scene` writes by default.
    SeparatedNearQ16 {
        near: Box<NearField>,
        far: Option<Box<NestedFar>>,
        q: Box<NearQ16>,
    },
}

/// The sixteen-bit arrays of [`Layout::SeparatedNearQ16`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NearQ16 {
    pub band_values: Q16,
    pub table_values: Q16,
    pub far_basis: Q16,
    pub far_group_basis: Q16,
    pub far_a: Q16,
    pub far_b: Q16,
}

impl NearQ16 {
    /// Moves `near`'s and `far`'s f32 arrays into sixteen bits (leaving them empty).
    fn take(near: &mut NearField, far: Option<&mut NestedFar>) -> NearQ16 {
        let q = |v: &mut Vec<f32>| Q16::encode(&std::mem::take(v));
        let (band_values, table_values) = (q(&mut near.band_values), q(&mut near.table_values));
        let (far_basis, far_group_basis, far_a, far_b) = match far {
            Some(f) => (
                q(&mut f.basis),
                q(&mut f.group_basis),
                q(&mut f.a),
                q(&mut f.b),
            ),
            None => Default::default(),
        };
        NearQ16 {
            band_values,
            table_values,
            far_basis,
            far_group_basis,
            far_a,
            far_b,
        }
    }

    /// Bytes stored (scales and steps).
    pub fn bytes(&self) -> usize {
        [
            &self.band_values,
            &self.table_values,
            &self.far_basis,
            &self.far_group_basis,
            &self.far_a,
            &self.far_b,
        ]
        .iter()
        .map(|q| q.bytes())
        .sum()
    }

    /// Puts the arrays back (read back from sixteen bits), or names the one that is
    /// inconsistent.
    fn restore(&self, near: &mut NearField, far: Option<&mut NestedFar>) -> Result<(), String> {
        let back = |what: &str, q: &Q16| q.decode().map_err(|e| format!("{what}: {e}"));
        near.band_values = back("near field band", &self.band_values)?;
        near.table_values = back("compliance table", &self.table_values)?;
        if let Some(f) = far {
            f.basis = back("far field bases", &self.far_basis)?;
            f.group_basis = back("far field row bases", &self.far_group_basis)?;
            f.a = back("far field row factors", &self.far_a)?;
            f.b = back("far field column factors", &self.far_b)?;
        }
        Ok(())
    }
}

/// One stored view's species (network indices) and rank.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ViewShape {
    pub species: Vec<u32>,
    pub rank: u64,
}

impl Layout {
    /// What the layout holds, in words (for errors).
    pub fn name(&self) -> &'static str {
        match self {
            Layout::TensorTrain { .. } => "tensor-train",
            Layout::Views { .. } => "views",
            _ => "separated",
        }
    }

    /// Whether the payload is `X` then the axes (separated, with or without near field).
    pub fn is_separated(&self) -> bool {
        matches!(
            self,
            Layout::Separated | Layout::SeparatedNear { .. } | Layout::SeparatedNearQ16 { .. }
        )
    }

    /// A nodal-load model's near and far fields: the bits of their stored values and
    /// their arrays' bytes (indices counted at four bytes, as in memory; the file
    /// stores them in variable-length integers); `None` without a near field.
    pub fn near_field_bytes(&self) -> Option<(u32, usize)> {
        Some(match self {
            Layout::SeparatedNear { near, far } => {
                (32, near.bytes() + far.as_ref().map_or(0, |f| f.bytes()))
            }
            Layout::SeparatedNearQ16 { near, far, q } => (
                16,
                near.bytes() + far.as_ref().map_or(0, |f| f.bytes()) + q.bytes(),
            ),
            _ => return None,
        })
    }
}

/// Why a meta-model file could not be read or written.
#[derive(Debug, Error)]
pub enum FileError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: io::Error },
    #[error(
        "{path}: not a palpa meta-model file (expected magic bytes \"{}\", found \"{}\")",
        .expected.escape_ascii(),
        .found.escape_ascii()
    )]
    Foreign {
        path: PathBuf,
        expected: [u8; 8],
        found: Vec<u8>,
    },
    #[error(
        "{path}: format version {found} is newer than the one this palpa reads ({supported}); update palpa"
    )]
    NewerVersion {
        path: PathBuf,
        found: u32,
        supported: u32,
    },
    #[error(
        "{path}: format version {found} is older than the one this palpa reads ({current}), and no release wrote it; rebuild the file: `palpa offline` or `palpa scene build` for a palpation scene, `palpa cme offline` for a gene network (scripts/make-assets.sh and scripts/make-kidney.sh remake the shipped scenes)"
    )]
    OlderVersion {
        path: PathBuf,
        found: u32,
        current: u32,
    },
    #[error("{path}: truncated: {what} needs {needed} bytes, the file has {actual}")]
    Truncated {
        path: PathBuf,
        what: &'static str,
        needed: u64,
        actual: u64,
    },
    #[error("{path}: header corrupted: {reason}")]
    HeaderCorrupt { path: PathBuf, reason: String },
    #[error(
        "{path}: payload corrupted: checksum {found:#018x}, the header expects {expected:#018x}"
    )]
    PayloadCorrupt {
        path: PathBuf,
        expected: u64,
        found: u64,
    },
    #[error("{path}: inconsistent header: {reason}")]
    Inconsistent { path: PathBuf, reason: String },
    #[error("{path}: {extra} unexpected bytes after the payload")]
    TrailingBytes { path: PathBuf, extra: u64 },
    #[error("{path}: stored as {found}, but {expected} was asked for (use load_any)")]
    WrongPrecision {
        path: PathBuf,
        expected: Precision,
        found: Precision,
    },
    #[error("{path}: holds a {found} model, but a {expected} model was asked for")]
    WrongLayout {
        path: PathBuf,
        expected: &'static str,
        found: &'static str,
    },
    #[error("{path}: invalid model: {source}")]
    Model { path: PathBuf, source: ModelError },
}

/// A model of either precision, as found in a file.
#[derive(Debug, Clone, PartialEq)]
pub enum AnyModel {
    F32(SeparatedModel<f32>),
    F64(SeparatedModel<f64>),
}

impl AnyModel {
    pub fn precision(&self) -> Precision {
        match self {
            AnyModel::F32(_) => Precision::F32,
            AnyModel::F64(_) => Precision::F64,
        }
    }
    pub fn meta(&self) -> ModelMeta {
        match self {
            AnyModel::F32(m) => m.meta(),
            AnyModel::F64(m) => m.meta(),
        }
    }
    /// As f64, converting if stored as f32.
    pub fn into_f64(self) -> SeparatedModel<f64> {
        match self {
            AnyModel::F32(m) => m.convert(),
            AnyModel::F64(m) => m,
        }
    }
}

fn padded(len: u64) -> u64 {
    len.div_ceil(ALIGN) * ALIGN
}

fn bincode_config() -> impl bincode::config::Config {
    bincode::config::standard()
}

/// Byte lengths of the payload blocks (X first, then the axes), unpadded.
/// `None` if a product overflows (only possible for a crafted header).
fn block_lens(h: &Header) -> Option<Vec<u64>> {
    let bytes = h.precision.bytes() as u64;
    if let Layout::Views { views } = &h.layout {
        let axes = &h.meta.axes;
        let nodes = axes.first()?.discretization.node_count() as u64;
        let mut out = Vec::with_capacity(2 * views.len());
        for v in views {
            let mut m = 1u64;
            for &i in &v.species {
                let axis = axes.get(1 + i as usize)?;
                m = m.checked_mul(axis.discretization.node_count() as u64)?;
            }
            out.push(nodes.checked_mul(v.rank)?.checked_mul(bytes)?);
            out.push(m.checked_mul(v.rank)?.checked_mul(bytes)?);
        }
        return Some(out);
    }
    if let Layout::TensorTrain { ranks } = &h.layout {
        if ranks.len() != h.meta.axes.len() + 1 {
            return None;
        }
        return h
            .meta
            .axes
            .iter()
            .enumerate()
            .map(|(k, a)| {
                let nodes = a.discretization.node_count() as u64;
                ranks[k]
                    .checked_mul(nodes)?
                    .checked_mul(ranks[k + 1])?
                    .checked_mul(bytes)
            })
            .collect();
    }
    let mut out = vec![h.rows.checked_mul(h.modes)?.checked_mul(bytes)?];
    for a in &h.meta.axes {
        let nodes = a.discretization.node_count() as u64;
        out.push(nodes.checked_mul(h.modes)?.checked_mul(bytes)?);
    }
    Some(out)
}

fn payload_len(blocks: &[u64]) -> Option<u64> {
    blocks.iter().try_fold(0u64, |acc, &b| {
        acc.checked_add(b.checked_add(ALIGN - 1)? / ALIGN * ALIGN)
    })
}

const ZEROS: [u8; ALIGN as usize] = [0; ALIGN as usize];

/// Writes `model` to `path` atomically (temp file, fsync, rename).
pub fn save<T: Scalar>(model: &SeparatedModel<T>, path: &Path) -> Result<(), FileError> {
    save_as(model, path, Form::Full)
}

/// As [`save`], with the near field's band and table and the far field's arrays in
/// sixteen bits ([`crate::quant16`]): about half their bytes. A model without a near
/// field is written as by [`save`].
pub fn save_q16<T: Scalar>(model: &SeparatedModel<T>, path: &Path) -> Result<(), FileError> {
    save_as(model, path, Form::Q16)
}

/// How [`save_as`] writes a near field.
#[derive(Clone, Copy, PartialEq)]
enum Form {
    Full,
    Q16,
}

fn save_as<T: Scalar>(model: &SeparatedModel<T>, path: &Path, form: Form) -> Result<(), FileError> {
    let (x, axes) = model.arrays();
    let blocks: Vec<&[u8]> = std::iter::once(x)
        .chain(axes)
        .map(bytemuck::cast_slice::<T, u8>)
        .collect();
    let (payload_len, payload_xxh3) = payload_sum(&blocks);
    let meta = model.meta();
    let header = Header {
        meta,
        precision: T::PRECISION,
        rows: model.rows() as u64,
        modes: model.modes() as u64,
        payload_len,
        payload_xxh3,
        layout: match model.near() {
            Some(near) => {
                let mut near = Box::new(near.clone());
                let mut far = near.far.take();
                match form {
                    Form::Q16 => {
                        let q = Box::new(NearQ16::take(&mut near, far.as_deref_mut()));
                        Layout::SeparatedNearQ16 { near, far, q }
                    }
                    Form::Full => Layout::SeparatedNear { near, far },
                }
            }
            None => Layout::Separated,
        },
    };
    write_file(path, &header, &blocks)
}

/// Writes a tensor-train model (f64 cores, one per axis of `meta`) atomically.
pub fn save_train(meta: &ModelMeta, cores: &[Core], path: &Path) -> Result<(), FileError> {
    let inconsistent = |reason: String| FileError::Inconsistent {
        path: path.to_path_buf(),
        reason,
    };
    if cores.len() != meta.axes.len() {
        return Err(inconsistent(format!(
            "{} cores for {} axes",
            cores.len(),
            meta.axes.len()
        )));
    }
    let mut ranks = vec![1u64];
    for (k, (c, a)) in cores.iter().zip(&meta.axes).enumerate() {
        if c.n != a.discretization.node_count() || c.r0 as u64 != ranks[k] {
            return Err(inconsistent(format!(
                "core {k} is {}×{}×{}, axis {} has {} nodes",
                c.r0,
                c.n,
                c.r1,
                a.name,
                a.discretization.node_count()
            )));
        }
        if c.v.iter().any(|x| !x.is_finite()) {
            return Err(inconsistent(format!("core {k} holds a non-finite value")));
        }
        ranks.push(c.r1 as u64);
    }
    let blocks: Vec<&[u8]> = cores
        .iter()
        .map(|c| bytemuck::cast_slice::<f64, u8>(&c.v))
        .collect();
    let (payload_len, payload_xxh3) = payload_sum(&blocks);
    let header = Header {
        meta: meta.clone(),
        precision: Precision::F64,
        rows: 0,
        modes: 0,
        payload_len,
        payload_xxh3,
        layout: Layout::TensorTrain { ranks },
    };
    write_file(path, &header, &blocks)
}

/// Writes a gene network's views atomically: `meta` has the time axis, then one
/// axis per species; each view is its shape and its two f64 blocks (time factor,
/// values). The sizes are checked against the axes here; what the numbers mean is
/// `cme::views`'s business.
pub fn save_views(
    meta: &ModelMeta,
    views: &[(ViewShape, &[f64], &[f64])],
    path: &Path,
) -> Result<(), FileError> {
    let header = Header {
        meta: meta.clone(),
        precision: Precision::F64,
        rows: 0,
        modes: 0,
        payload_len: 0,
        payload_xxh3: 0,
        layout: Layout::Views {
            views: views.iter().map(|v| v.0.clone()).collect(),
        },
    };
    let inconsistent = |reason: String| FileError::Inconsistent {
        path: path.to_path_buf(),
        reason,
    };
    let lens = block_lens(&header)
        .ok_or_else(|| inconsistent("a view names a species the axes do not have".into()))?;
    let blocks: Vec<&[u8]> = views
        .iter()
        .flat_map(|v| [v.1, v.2])
        .map(bytemuck::cast_slice::<f64, u8>)
        .collect();
    if let Some(k) = (0..blocks.len()).find(|&k| blocks[k].len() as u64 != lens[k]) {
        return Err(inconsistent(format!(
            "view {} block {} holds {} bytes, its shape needs {}",
            k / 2,
            k % 2,
            blocks[k].len(),
            lens[k]
        )));
    }
    if views
        .iter()
        .any(|v| v.1.iter().chain(v.2).any(|x| !x.is_finite()))
    {
        return Err(inconsistent("a view holds a non-finite value".into()));
    }
    let (payload_len, payload_xxh3) = payload_sum(&blocks);
    let header = Header {
        payload_len,
        payload_xxh3,
        ..header
    };
    write_file(path, &header, &blocks)
}

/// The contents of a views file: metadata, and per view its shape, time factor and
/// values (sizes checked against the axes).
pub type ViewsContents = (ModelMeta, Vec<(ViewShape, Vec<f64>, Vec<f64>)>);

/// Loads a views file written by [`save_views`].
pub fn load_views(path: &Path) -> Result<ViewsContents, FileError> {
    views_from(path, None)
}

/// [`load_views`] from bytes in memory (errors name the file `<memory>`).
pub fn load_views_from_bytes(bytes: &[u8]) -> Result<ViewsContents, FileError> {
    views_from(Path::new("<memory>"), Some(bytes))
}

fn views_from(path: &Path, bytes: Option<&[u8]>) -> Result<ViewsContents, FileError> {
    let p = || path.to_path_buf();
    let (shapes, header, arrays) = read_f64_layout(path, bytes, "views", |l| match l {
        Layout::Views { views } => Some(views.clone()),
        _ => None,
    })?;
    if !matches!(
        header.meta.axes.first().map(|a| &a.discretization),
        Some(Discretization::Grid { .. })
    ) {
        return Err(FileError::Inconsistent {
            path: p(),
            reason: "the first axis of a views model must be the time grid".into(),
        });
    }
    let mut arrays = arrays.into_iter();
    let views = shapes
        .into_iter()
        .map(|s| {
            let time = arrays.next().unwrap_or_default();
            let values = arrays.next().unwrap_or_default();
            (s, time, values)
        })
        .collect();
    Ok((header.meta, views))
}

fn payload_sum(blocks: &[&[u8]]) -> (u64, u64) {
    let mut hasher = Xxh3::new();
    let mut payload_len = 0u64;
    for b in blocks {
        let pad = (padded(b.len() as u64) - b.len() as u64) as usize;
        hasher.update(b);
        hasher.update(&ZEROS[..pad]);
        payload_len += padded(b.len() as u64);
    }
    (payload_len, hasher.digest())
}

fn write_file(path: &Path, header: &Header, blocks: &[&[u8]]) -> Result<(), FileError> {
    // Little-endian on disk; every supported target is little-endian, and a big-endian
    // host would need a byte swap here (see Scalar::le_to_native for the read side).
    const _: () = assert!(
        cfg!(target_endian = "little"),
        "writer assumes little-endian"
    );
    let header_bytes = bincode::serde::encode_to_vec(header, bincode_config()).map_err(|e| {
        FileError::HeaderCorrupt {
            path: path.to_path_buf(),
            reason: format!("cannot encode: {e}"),
        }
    })?;
    let header_end = PREAMBLE as u64 + header_bytes.len() as u64;
    atomic_write(path, |w| {
        w.write_all(&MAGIC)?;
        w.write_all(&FORMAT_VERSION.to_le_bytes())?;
        w.write_all(&0u32.to_le_bytes())?;
        w.write_all(&(header_bytes.len() as u64).to_le_bytes())?;
        w.write_all(&xxh3_64(&header_bytes).to_le_bytes())?;
        w.write_all(&header_bytes)?;
        w.write_all(&ZEROS[..(padded(header_end) - header_end) as usize])?;
        for b in blocks {
            w.write_all(b)?;
            w.write_all(&ZEROS[..(padded(b.len() as u64) - b.len() as u64) as usize])?;
        }
        Ok(())
    })
    .map_err(|source| FileError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads and checks the preamble and header of `path` (not the payload).
pub fn read_header(path: &Path) -> Result<Header, FileError> {
    let mut f = open(path)?;
    Ok(read_header_from(path, &mut f)?.header)
}

/// [`read_header`] from bytes in memory.
pub fn read_header_from_bytes(bytes: &[u8]) -> Result<Header, FileError> {
    let mut f = Opened {
        file: bytes,
        len: bytes.len() as u64,
    };
    Ok(read_header_from(Path::new("<memory>"), &mut f)?.header)
}

/// A byte source of known total length (a file, or bytes in memory).
struct Opened<R> {
    file: R,
    len: u64,
}

fn open(path: &Path) -> Result<Opened<File>, FileError> {
    let io_err = |source| FileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io_err)?;
    let len = file.metadata().map_err(io_err)?.len();
    Ok(Opened { file, len })
}

/// Loads a model of either precision from bytes in memory (e.g. an asset bundled into
/// a mobile app, or a fuzzer's input). Errors name the file as `<memory>`.
pub fn load_any_from_bytes(bytes: &[u8]) -> Result<AnyModel, FileError> {
    let path = Path::new("<memory>");
    let mut f = Opened {
        file: bytes,
        len: bytes.len() as u64,
    };
    let located = read_header_from(path, &mut f)?;
    Ok(match located.header.precision {
        Precision::F32 => AnyModel::F32(load_payload(path, &mut f, located)?),
        Precision::F64 => AnyModel::F64(load_payload(path, &mut f, located)?),
    })
}

/// A decoded header and where the header bytes end and the payload starts.
struct Located {
    header: Header,
    header_end: u64,
    payload_at: u64,
}

fn read_header_from<R: Read>(path: &Path, f: &mut Opened<R>) -> Result<Located, FileError> {
    let p = || path.to_path_buf();
    let io_err = |source| FileError::Io { path: p(), source };
    let mut pre = [0u8; PREAMBLE];
    let got = read_up_to(&mut f.file, &mut pre).map_err(io_err)?;
    if got < MAGIC.len() || pre[..8] != MAGIC {
        return Err(FileError::Foreign {
            path: p(),
            expected: MAGIC,
            found: pre[..got.min(8)].to_vec(),
        });
    }
    if got < PREAMBLE {
        return Err(FileError::Truncated {
            path: p(),
            what: "the preamble",
            needed: PREAMBLE as u64,
            actual: f.len,
        });
    }
    let le_u32 =
        |b: &[u8]| u32::from_le_bytes(b.try_into().expect("callers slice exactly 4 bytes"));
    let le_u64 =
        |b: &[u8]| u64::from_le_bytes(b.try_into().expect("callers slice exactly 8 bytes"));
    let version = le_u32(&pre[8..12]);
    if version > FORMAT_VERSION {
        return Err(FileError::NewerVersion {
            path: p(),
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    if version < FORMAT_VERSION {
        return Err(FileError::OlderVersion {
            path: p(),
            found: version,
            current: FORMAT_VERSION,
        });
    }
    if pre[12..16] != [0; 4] {
        return Err(FileError::HeaderCorrupt {
            path: p(),
            reason: format!(
                "reserved bytes 12..16 are {:?}, expected zeros",
                &pre[12..16]
            ),
        });
    }
    let header_len = le_u64(&pre[16..24]);
    let header_sum = le_u64(&pre[24..32]);
    if header_len > MAX_HEADER_BYTES {
        return Err(FileError::HeaderCorrupt {
            path: p(),
            reason: format!(
                "header length {header_len} exceeds the {MAX_HEADER_BYTES}-byte maximum"
            ),
        });
    }
    let header_end = (PREAMBLE as u64).checked_add(header_len);
    match header_end {
        Some(end) if end <= f.len => {}
        _ => {
            return Err(FileError::Truncated {
                path: p(),
                what: "the header",
                needed: header_end.unwrap_or(u64::MAX),
                actual: f.len,
            });
        }
    }
    // header_len ≤ file length, so this allocation is bounded by the file's size.
    let mut hbytes = vec![0u8; header_len as usize];
    f.file.read_exact(&mut hbytes).map_err(io_err)?;
    let found = xxh3_64(&hbytes);
    if found != header_sum {
        return Err(FileError::HeaderCorrupt {
            path: p(),
            reason: format!("checksum {found:#018x}, the preamble says {header_sum:#018x}"),
        });
    }
    // The byte limit bounds every length-prefixed allocation inside the decoder.
    let cfg = bincode::config::standard().with_limit::<{ MAX_HEADER_BYTES as usize }>();
    let corrupt = |e: bincode::error::DecodeError| FileError::HeaderCorrupt {
        path: p(),
        reason: format!("cannot decode: {e}"),
    };
    let (header, used): (Header, usize) =
        bincode::serde::decode_from_slice(&hbytes, cfg).map_err(corrupt)?;
    if used != hbytes.len() {
        return Err(FileError::HeaderCorrupt {
            path: p(),
            reason: format!("{} bytes decoded of {}", used, hbytes.len()),
        });
    }
    let header_end = PREAMBLE as u64 + header_len;
    Ok(Located {
        header,
        header_end,
        payload_at: padded(header_end),
    })
}

/// Reads as many bytes as available up to `buf.len()`.
fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// Loads a model stored with precision `T`.
pub fn load<T: Scalar>(path: &Path) -> Result<SeparatedModel<T>, FileError> {
    let mut f = open(path)?;
    let located = read_header_from(path, &mut f)?;
    if located.header.precision != T::PRECISION {
        return Err(FileError::WrongPrecision {
            path: path.to_path_buf(),
            expected: T::PRECISION,
            found: located.header.precision,
        });
    }
    load_payload(path, &mut f, located)
}

/// Loads a model of whichever precision the file holds.
pub fn load_any(path: &Path) -> Result<AnyModel, FileError> {
    let mut f = open(path)?;
    let located = read_header_from(path, &mut f)?;
    Ok(match located.header.precision {
        Precision::F32 => AnyModel::F32(load_payload(path, &mut f, located)?),
        Precision::F64 => AnyModel::F64(load_payload(path, &mut f, located)?),
    })
}

fn load_payload<T: Scalar, R: Read>(
    path: &Path,
    f: &mut Opened<R>,
    located: Located,
) -> Result<SeparatedModel<T>, FileError> {
    let p = || path.to_path_buf();
    if !located.header.layout.is_separated() {
        return Err(FileError::WrongLayout {
            path: p(),
            expected: "separated",
            found: located.header.layout.name(),
        });
    }
    let near = match &located.header.layout {
        Layout::SeparatedNear { near, far } => {
            let mut near = near.as_ref().clone();
            near.far = far.clone();
            Some(near)
        }
        Layout::SeparatedNearQ16 { near, far, q } => {
            let mut near = near.as_ref().clone();
            let mut far = far.clone();
            q.restore(&mut near, far.as_deref_mut())
                .map_err(|reason| FileError::Inconsistent { path: p(), reason })?;
            near.far = far;
            Some(near)
        }
        _ => None,
    };
    let (header, arrays) = read_arrays::<T, R>(path, f, located)?;
    let inconsistent = |reason: String| FileError::Inconsistent { path: p(), reason };
    let rows = usize::try_from(header.rows).map_err(|_| inconsistent("rows overflow".into()))?;
    let modes = usize::try_from(header.modes).map_err(|_| inconsistent("modes overflow".into()))?;
    let mut arrays = arrays.into_iter();
    let x = arrays.next().expect("block_lens always yields X first");
    let mut model = SeparatedModel::new(header.meta, rows, modes, x, arrays.collect())
        .map_err(|source| FileError::Model { path: p(), source })?;
    if let Some(near) = near {
        model = model
            .with_near(near)
            .map_err(|source| FileError::Model { path: p(), source })?;
    }
    model
        .check_finite()
        .map_err(|source| FileError::Model { path: p(), source })?;
    Ok(model)
}

/// Loads a tensor-train model: its metadata and one core per axis.
pub fn load_train(path: &Path) -> Result<(ModelMeta, Vec<Core>), FileError> {
    train_from(path, None)
}

/// [`load_train`] from bytes in memory (errors name the file `<memory>`).
pub fn load_train_from_bytes(bytes: &[u8]) -> Result<(ModelMeta, Vec<Core>), FileError> {
    train_from(Path::new("<memory>"), Some(bytes))
}

fn train_from(path: &Path, bytes: Option<&[u8]>) -> Result<(ModelMeta, Vec<Core>), FileError> {
    let p = || path.to_path_buf();
    let (ranks, header, arrays) = read_f64_layout(path, bytes, "tensor-train", |l| match l {
        Layout::TensorTrain { ranks } => Some(ranks.clone()),
        _ => None,
    })?;
    let mut cores = Vec::with_capacity(arrays.len());
    for (k, v) in arrays.into_iter().enumerate() {
        if v.iter().any(|x| !x.is_finite()) {
            return Err(FileError::Inconsistent {
                path: p(),
                reason: format!("core {k} holds a non-finite value"),
            });
        }
        cores.push(Core {
            r0: ranks[k] as usize,
            n: header.meta.axes[k].discretization.node_count(),
            r1: ranks[k + 1] as usize,
            v,
        });
    }
    if ranks.first() != Some(&1) || ranks.last() != Some(&1) {
        return Err(FileError::Inconsistent {
            path: p(),
            reason: format!("tensor-train ranks {ranks:?} must start and end with 1"),
        });
    }
    Ok((header.meta, cores))
}

/// Opens an f64 file of the layout `pick` accepts (`expected` names it in the error),
/// and reads its header and blocks.
fn read_f64_layout<T>(
    path: &Path,
    bytes: Option<&[u8]>,
    expected: &'static str,
    pick: impl Fn(&Layout) -> Option<T>,
) -> Result<(T, Header, Vec<Vec<f64>>), FileError> {
    match bytes {
        Some(b) => {
            let mut f = Opened {
                file: b,
                len: b.len() as u64,
            };
            read_f64_layout_from(path, &mut f, expected, pick)
        }
        None => read_f64_layout_from(path, &mut open(path)?, expected, pick),
    }
}

fn read_f64_layout_from<T, R: Read>(
    path: &Path,
    f: &mut Opened<R>,
    expected: &'static str,
    pick: impl Fn(&Layout) -> Option<T>,
) -> Result<(T, Header, Vec<Vec<f64>>), FileError> {
    let located = read_header_from(path, f)?;
    let Some(picked) = pick(&located.header.layout) else {
        return Err(FileError::WrongLayout {
            path: path.to_path_buf(),
            expected,
            found: located.header.layout.name(),
        });
    };
    if located.header.precision != Precision::F64 {
        return Err(FileError::WrongPrecision {
            path: path.to_path_buf(),
            expected: Precision::F64,
            found: located.header.precision,
        });
    }
    let (header, arrays) = read_arrays::<f64, R>(path, f, located)?;
    Ok((picked, header, arrays))
}

/// Checks the payload's size and checksum and reads its blocks.
fn read_arrays<T: Scalar, R: Read>(
    path: &Path,
    f: &mut Opened<R>,
    located: Located,
) -> Result<(Header, Vec<Vec<T>>), FileError> {
    let Located {
        header,
        header_end,
        payload_at,
    } = located;
    let p = || path.to_path_buf();
    let inconsistent = |reason: String| FileError::Inconsistent { path: p(), reason };
    let blocks = block_lens(&header).ok_or_else(|| {
        inconsistent(
            "array sizes overflow 64 bits, or the tensor-train ranks do not match the axes".into(),
        )
    })?;
    let expected_len =
        payload_len(&blocks).ok_or_else(|| inconsistent("payload size overflows".into()))?;
    if expected_len != header.payload_len {
        return Err(inconsistent(format!(
            "the arrays need {expected_len} payload bytes, the header records {}",
            header.payload_len
        )));
    }
    let end = payload_at
        .checked_add(expected_len)
        .ok_or_else(|| inconsistent("payload end overflows".into()))?;
    if end > f.len {
        return Err(FileError::Truncated {
            path: p(),
            what: "the payload",
            needed: end,
            actual: f.len,
        });
    }
    if end < f.len {
        return Err(FileError::TrailingBytes {
            path: p(),
            extra: f.len - end,
        });
    }
    // Skip the header padding (checked above: payload_at ≤ end ≤ file length).
    let io_err = |source| FileError::Io { path: p(), source };
    let pad_len = payload_at - header_end;
    let mut pad = [0u8; ALIGN as usize];
    f.file
        .read_exact(&mut pad[..pad_len as usize])
        .map_err(io_err)?;
    if pad[..pad_len as usize].iter().any(|&b| b != 0) {
        return Err(FileError::HeaderCorrupt {
            path: p(),
            reason: "non-zero bytes in the padding after the header".into(),
        });
    }

    // Every block length was checked against the file size above, so these
    // allocations are bounded by the file's size.
    let mut hasher = Xxh3::new();
    let mut arrays: Vec<Vec<T>> = Vec::with_capacity(blocks.len());
    let elem = size_of::<T>() as u64;
    for &b in &blocks {
        let mut v = vec![T::from_f64(0.0); (b / elem) as usize];
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut v);
        f.file.read_exact(bytes).map_err(io_err)?;
        hasher.update(bytes);
        let padn = (padded(b) - b) as usize;
        f.file.read_exact(&mut pad[..padn]).map_err(io_err)?;
        hasher.update(&pad[..padn]);
        for x in &mut v {
            *x = x.le_to_native();
        }
        arrays.push(v);
    }
    let found = hasher.digest();
    if found != header.payload_xxh3 {
        return Err(FileError::PayloadCorrupt {
            path: p(),
            expected: header.payload_xxh3,
            found,
        });
    }
    Ok((header, arrays))
}
