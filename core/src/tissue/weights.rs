//! The tissue vademecum's mode weights in sixteen bits (IEEE 754 half precision).
//!
//! A sample's residual at grid depth `d_j` is `Σ_k c_k(d_j) s_k q_k` (weight, scale,
//! quantized shape; see [`super::law`]). The weights were stored as f32: 721 200 of
//! them on the shipped law of 5 637 presses, 2.54 MB of its 7.65 MB after LZMA, since
//! their low mantissa bits are noise to the coder. A half keeps 11 significant bits,
//! so rounding moves a weight by at most `2⁻¹¹ |c|` (by at most `2⁻²⁵` below the
//! normal range, `|c| < 6.1e-5`), and a node of the sample by at most
//!
//! ```text
//! δ = Σ_k |c_k − h(c_k)| · max_node ‖s_k q_k‖,
//! ```
//!
//! the triangle inequality over its modes. The compression rounds each weight before
//! its stop rule measures the error, so a new law's bound already holds it; an older
//! law's weights are rounded by `palpa lab tissue cut --half-weights`, whose bound grows
//! by the largest `δ` of any sample at any grid depth ([`TissueLaw::with_half_weights`]).
//! A weight beyond the half range (65 504) is kept in f32 and the law stored so.
//!
//! Format 10 stores half weights as two byte planes, every weight's high byte (sign,
//! exponent, two mantissa bits) and then every low byte: the high bytes of one mode's
//! weights over the depths are alike, and the coder finds them. On the shipped law
//! that is 1.08 MB against 1.27 MB interleaved and 2.54 MB in f32.

use half::f16;
use serde::{Deserialize, Serialize};

/// `w` rounded to the nearest half (ties to even), or `w` itself where that would
/// overflow: a weight that is stored in sixteen bits reads back as this.
pub fn to_half(w: f32) -> f32 {
    let h = f16::from_f32(w).to_f32();
    if h.is_finite() { h } else { w }
}

/// Whether every weight reads back from a half unchanged.
fn all_half(weights: &[f32]) -> bool {
    weights
        .iter()
        .all(|&w| f16::from_f32(w).to_f32().to_bits() == w.to_bits())
}

/// The weights as a tissue file stores them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) enum Weights {
    /// Some weight is not a half: every one in f32.
    Single(Vec<f32>),
    /// Every weight a half: its bits' high bytes, then their low bytes.
    Half { high: Vec<u8>, low: Vec<u8> },
}

impl Weights {
    /// Halves where every weight is one, f32 otherwise: lossless either way.
    pub(super) fn pack(weights: &[f32]) -> Weights {
        if !all_half(weights) {
            return Weights::Single(weights.to_vec());
        }
        let bits: Vec<[u8; 2]> = weights
            .iter()
            .map(|&w| f16::from_f32(w).to_bits().to_be_bytes())
            .collect();
        Weights::Half {
            high: bits.iter().map(|b| b[0]).collect(),
            low: bits.iter().map(|b| b[1]).collect(),
        }
    }

    /// The weights in f32, or why the planes do not make any.
    pub(super) fn unpack(self) -> Result<Vec<f32>, String> {
        match self {
            Weights::Single(w) => Ok(w),
            Weights::Half { high, low } if high.len() == low.len() => Ok(high
                .iter()
                .zip(&low)
                .map(|(&h, &l)| f16::from_bits(u16::from_be_bytes([h, l])).to_f32())
                .collect()),
            Weights::Half { high, low } => Err(format!(
                "{} high bytes of half weights and {} low bytes: expected as many of each",
                high.len(),
                low.len()
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tissue::knobs::tests::surface;

    #[test]
    fn a_half_reads_back_within_its_eleven_bits() {
        for w in [
            0.0f32, -0.0, 1.0, 0.1, -3.3, 75.39, 1e-9, 6e-5, 65504.0, 70000.0,
        ] {
            let h = to_half(w);
            assert_eq!(
                to_half(h).to_bits(),
                h.to_bits(),
                "{w}: a half rounds to itself"
            );
            let limit = (f64::from(w).abs() * 2f64.powi(-11)).max(2f64.powi(-25));
            assert!(f64::from(h - w).abs() <= limit, "{w} → {h}");
        }
        // Past the half range the weight stays as it was.
        assert_eq!(to_half(70000.0), 70000.0);
        assert!(!all_half(&[1.0, 0.1]) && all_half(&[1.0, 0.5, -2.25, 0.0]));
    }

    #[test]
    fn weights_pack_as_halves_only_where_that_loses_nothing() {
        let halves = [0.0f32, 1.0, -2.25, 75.375, to_half(0.1), to_half(1e-7)];
        let packed = Weights::pack(&halves);
        assert!(
            matches!(&packed, Weights::Half { high, low } if high.len() == 6 && low.len() == 6)
        );
        assert_eq!(packed.unpack(), Ok(halves.to_vec()));
        for not in [vec![0.1f32, 1.0], vec![1.0, 70000.0]] {
            let packed = Weights::pack(&not);
            assert_eq!(packed, Weights::Single(not.clone()));
            assert_eq!(packed.unpack(), Ok(not));
        }
        let torn = Weights::Half {
            high: vec![0; 3],
            low: vec![0; 2],
        };
        let why = torn.unpack().expect_err("planes of different lengths");
        assert!(
            why.contains("3 high bytes") && why.contains("2 low bytes"),
            "{why}"
        );
    }

    #[test]
    fn half_weights_move_a_node_by_no_more_than_the_bound_grows() {
        // Weights d²/4 and 0.1·d: 0.1, 0.3 and 0.7 are not halves.
        let law = crate::tissue::knobs::tests::law();
        let (half, moved) = law.with_half_weights();
        assert!(moved > 0.0 && moved < 1e-3, "{moved}");
        assert!((half.truncation_bound_mm - (law.truncation_bound_mm + moved)).abs() < 1e-15);
        assert!(all_half(&half.coeffs) && half.check().is_ok());
        let mut largest = 0.0f64;
        for bary in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.2, 0.3, 0.5]] {
            for depth_mm in [1.0, 2.0, 3.0, 4.0] {
                let (a, b) = (
                    surface(law.clone(), bary, depth_mm),
                    surface(half.clone(), bary, depth_mm),
                );
                let e = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
                largest = largest.max(e);
            }
        }
        // The bound is met with equality at a corner (one mode moves), up to the
        // evaluation's own rounding.
        assert!(
            largest > 0.0 && largest <= moved * (1.0 + 1e-9),
            "{largest} vs {moved}"
        );
        // Rounding again changes nothing.
        let (again, none) = half.with_half_weights();
        assert_eq!((again, none.to_bits()), (half, 0.0f64.to_bits()));
    }
}
