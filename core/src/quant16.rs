//! Sixteen-bit storage of f32 arrays whose entries a few hundred at a time share a
//! scale: a scene file's near and far fields (file format version 8).
//!
//! The values are cut into chunks of [`CHUNK`] consecutive entries; chunk `c` keeps
//! its scale `h_c = max_i |x_i| / 32767` (f32) and each entry the integer
//! `n_i = round(x_i / h_c)`, `|n_i| ≤ 32767`, stored as two little-endian bytes. The
//! entry read back is `h_c n_i`, so
//!
//! ```text
//! |x_i − h_c n_i| ≤ h_c / 2 = max_chunk |x| / 65534     (plus f32 rounding)
//! ```
//!
//! half the bytes of f32 for a relative error of 1.5e-5 of the chunk's largest entry.
//! Where this is used, the arrays are corrections to the modes' answer (the near
//! field's band and compliance table, the far field's low-rank factors), consecutive
//! entries belong to one block or load node, and the error a probe sees is measured
//! against the f32 file (docs/nodal-vademecum.md, "Sixteen bits").

use serde::{Deserialize, Serialize};

/// Entries that share a scale.
pub const CHUNK: usize = 256;
const LEVELS: f32 = 32767.0;

/// An f32 array in sixteen bits (see the module doc).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Q16 {
    /// Number of entries.
    pub len: u64,
    /// Per chunk: its step `h_c` (0 for a chunk of zeros).
    pub scale: Vec<f32>,
    /// Per entry: `n_i` as two little-endian bytes.
    pub steps: Vec<u8>,
}

impl Q16 {
    /// Rounds `values` to sixteen bits. Non-finite entries are refused by the
    /// callers' own checks before this (a model's near field is checked finite).
    pub fn encode(values: &[f32]) -> Q16 {
        let mut scale = Vec::with_capacity(values.len().div_ceil(CHUNK));
        let mut steps = Vec::with_capacity(2 * values.len());
        for chunk in values.chunks(CHUNK) {
            let top = chunk.iter().fold(0.0f32, |a, x| a.max(x.abs()));
            let h = top / LEVELS;
            scale.push(h);
            for &x in chunk {
                let n = if h > 0.0 {
                    (x / h).round().clamp(-LEVELS, LEVELS) as i16
                } else {
                    0
                };
                steps.extend_from_slice(&n.to_le_bytes());
            }
        }
        Q16 {
            len: values.len() as u64,
            scale,
            steps,
        }
    }

    /// The values read back, or what is inconsistent (lengths, a scale that is
    /// negative or not finite).
    pub fn decode(&self) -> Result<Vec<f32>, String> {
        let n = usize::try_from(self.len).map_err(|_| "length overflow".to_string())?;
        if self.steps.len() != 2 * n || self.scale.len() != n.div_ceil(CHUNK) {
            return Err(format!(
                "{} entries need {} step bytes and {} scales, found {} and {}",
                n,
                2 * n,
                n.div_ceil(CHUNK),
                self.steps.len(),
                self.scale.len()
            ));
        }
        if let Some(h) = self.scale.iter().find(|h| !(h.is_finite() && **h >= 0.0)) {
            return Err(format!("a chunk's scale is {h} (expected finite and ≥ 0)"));
        }
        Ok(self
            .steps
            .chunks_exact(2)
            .enumerate()
            .map(|(i, b)| self.scale[i / CHUNK] * f32::from(i16::from_le_bytes([b[0], b[1]])))
            .collect())
    }

    /// Bytes stored (scales and steps).
    pub fn bytes(&self) -> usize {
        4 * self.scale.len() + self.steps.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Random arrays with chunks of very different sizes (and a chunk of zeros): every
    /// entry read back within half its chunk's step of what was stored, the scale
    /// `max/32767`, and half the bytes.
    #[test]
    fn entries_come_back_within_half_a_step_of_their_chunk() {
        let mut rng = Rng::seed(16);
        for len in [0, 1, 255, 256, 257, 3000] {
            let values: Vec<f32> = (0..len)
                .map(|i| {
                    let magnitude = [1e-6, 1.0, 40.0, 0.0][(i / CHUNK) % 4];
                    (magnitude * rng.range(-1.0, 1.0)) as f32
                })
                .collect();
            let q = Q16::encode(&values);
            assert!(q.bytes() <= 2 * len + 4 * len.div_ceil(CHUNK));
            let back = q.decode().expect("decodes");
            assert_eq!(back.len(), len);
            for (c, (chunk, got)) in values.chunks(CHUNK).zip(back.chunks(CHUNK)).enumerate() {
                let top = chunk.iter().fold(0.0f32, |a, x| a.max(x.abs()));
                assert_eq!(q.scale[c], top / LEVELS);
                for (x, y) in chunk.iter().zip(got) {
                    let bound = 0.5 * q.scale[c] * (1.0 + 1e-6) + 2.0 * f32::EPSILON * top;
                    assert!(
                        (x - y).abs() <= bound,
                        "{x} read back as {y} (bound {bound})"
                    );
                }
            }
        }
    }

    #[test]
    fn inconsistent_lengths_and_scales_are_named() {
        let mut q = Q16::encode(&[1.0, -2.0, 3.0]);
        q.steps.pop();
        let e = q.decode().expect_err("a step missing");
        assert!(e.contains("step bytes"), "{e}");
        let mut q = Q16::encode(&[1.0, -2.0, 3.0]);
        q.scale[0] = f32::NAN;
        let e = q.decode().expect_err("a NaN scale");
        assert!(e.contains("scale"), "{e}");
    }
}
