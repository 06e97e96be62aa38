//! The tissue vademecum's mode shapes, quantized: its precision knob.
//!
//! Each mode `a` (a unit vector over the surface rows) is stored as integers `q` of
//! `b` bits and one scale, `a ≈ s q` with `s = max|a| / (2^(b−1) − 1)`, so every entry
//! errs by at most `s / 2`. What matters to a user is a node's error: where a mode
//! enters the residual with weight `c(d)`, its node `i` (three entries) errs by
//! `e = max_i ‖a_i − s q_i‖ · max_d |c(d)|`, and a sample's modes together by the sum
//! of their `e`. [`Shapes::push_mode`] returns that per-node error per unit weight, so
//! the compression can keep the bound it states.
//!
//! Sixteen bits cost about `1.5e-5` of a mode's largest entry per entry; eight bits
//! `4e-3`, half the bytes. `palpa tradeoff` measures what that does at held-out
//! presses.

use serde::{Deserialize, Serialize};

/// Bits per stored entry of a mode shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ShapeBits {
    Eight,
    Sixteen,
}

impl ShapeBits {
    pub const fn count(self) -> u32 {
        match self {
            ShapeBits::Eight => 8,
            ShapeBits::Sixteen => 16,
        }
    }

    /// The bits named by `count` (8 or 16).
    pub fn from_count(count: u32) -> Option<ShapeBits> {
        match count {
            8 => Some(ShapeBits::Eight),
            16 => Some(ShapeBits::Sixteen),
            _ => None,
        }
    }

    /// The largest stored integer.
    fn top(self) -> f64 {
        match self {
            ShapeBits::Eight => f64::from(i8::MAX),
            ShapeBits::Sixteen => f64::from(i16::MAX),
        }
    }
}

/// All modes' shapes, one after another, `rows3` entries each.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Shapes {
    Eight(Vec<i8>),
    Sixteen(Vec<i16>),
}

impl Shapes {
    pub fn new(bits: ShapeBits) -> Shapes {
        match bits {
            ShapeBits::Eight => Shapes::Eight(Vec::new()),
            ShapeBits::Sixteen => Shapes::Sixteen(Vec::new()),
        }
    }

    pub fn bits(&self) -> ShapeBits {
        match self {
            Shapes::Eight(_) => ShapeBits::Eight,
            Shapes::Sixteen(_) => ShapeBits::Sixteen,
        }
    }

    /// Stored entries (modes × rows3).
    pub fn len(&self) -> usize {
        match self {
            Shapes::Eight(v) => v.len(),
            Shapes::Sixteen(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn bytes(&self) -> usize {
        match self {
            Shapes::Eight(v) => v.len(),
            Shapes::Sixteen(v) => 2 * v.len(),
        }
    }

    /// The first `n` entries (whole modes, when `n` is a multiple of a mode's length).
    pub fn prefix(&self, n: usize) -> Shapes {
        match self {
            Shapes::Eight(v) => Shapes::Eight(v[..n].to_vec()),
            Shapes::Sixteen(v) => Shapes::Sixteen(v[..n].to_vec()),
        }
    }

    /// Entry `i` as stored (multiply by its mode's scale for mm per unit weight).
    pub fn get(&self, i: usize) -> f64 {
        match self {
            Shapes::Eight(v) => f64::from(v[i]),
            Shapes::Sixteen(v) => f64::from(v[i]),
        }
    }

    /// Quantizes the mode `a` (entries in groups of three, one group per node) and
    /// appends it. Returns its scale and the largest node error `max_i ‖a_i − s q_i‖`
    /// (per unit weight of the mode).
    pub fn push_mode(&mut self, a: &[f64]) -> (f32, f64) {
        self.push_mode_coarse(a, 0.0)
    }

    /// [`Self::push_mode`] with a step of at least `min_step` (per unit weight): a mode
    /// whose weights are small needs fewer levels for the same node error in mm, and
    /// fewer levels deflate to fewer bytes (the entries stay `bits` wide).
    pub fn push_mode_coarse(&mut self, a: &[f64], min_step: f64) -> (f32, f64) {
        let bits = self.bits();
        let top = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        // The scale as stored (f32), so the error is the one evaluation will see.
        let scale = f64::from((top / bits.top()).max(min_step) as f32);
        let q: Vec<f64> = a
            .iter()
            .map(|&x| {
                if scale > 0.0 {
                    (x / scale).round().clamp(-bits.top(), bits.top())
                } else {
                    0.0
                }
            })
            .collect();
        let node_error = a
            .chunks(3)
            .zip(q.chunks(3))
            .map(|(x, q)| {
                x.iter()
                    .zip(q)
                    .map(|(x, q)| (x - q * scale).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0f64, f64::max);
        // `q` is within the type's range by the clamp.
        match self {
            Shapes::Eight(v) => v.extend(q.iter().map(|&x| x as i8)),
            Shapes::Sixteen(v) => v.extend(q.iter().map(|&x| x as i16)),
        }
        (scale as f32, node_error)
    }

    /// Appends mode `mode` of `other` (`rows3` entries) unchanged; both must have the
    /// same bits.
    pub fn push_copy(&mut self, other: &Shapes, mode: usize, rows3: usize) {
        let range = mode * rows3..(mode + 1) * rows3;
        match (self, other) {
            (Shapes::Eight(a), Shapes::Eight(b)) => a.extend_from_slice(&b[range]),
            (Shapes::Sixteen(a), Shapes::Sixteen(b)) => a.extend_from_slice(&b[range]),
            _ => unreachable!("push_copy between shapes of different bits"),
        }
    }

    /// Adds `weight ·` mode `mode` to `rows_mm`: row `r`'s three entries go to
    /// `rows_mm[3 · vertex_of_row[r] ..]` (skipped where that is `u32::MAX` or out of
    /// range). No allocation.
    pub fn add_mode(&self, mode: usize, weight: f64, vertex_of_row: &[u32], rows_mm: &mut [f64]) {
        let rows3 = 3 * vertex_of_row.len();
        match self {
            Shapes::Eight(v) => add(&v[mode * rows3..][..rows3], weight, vertex_of_row, rows_mm),
            Shapes::Sixteen(v) => {
                add(&v[mode * rows3..][..rows3], weight, vertex_of_row, rows_mm);
            }
        }
    }
}

fn add<T: Copy + Into<f64>>(shape: &[T], weight: f64, vertex_of_row: &[u32], rows_mm: &mut [f64]) {
    for (row, &v) in vertex_of_row.iter().enumerate() {
        if v == u32::MAX {
            continue;
        }
        for comp in 0..3 {
            if let Some(o) = rows_mm.get_mut(3 * v as usize + comp) {
                *o += weight * shape[3 * row + comp].into();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn random_mode(seed: u64, n: usize) -> Vec<f64> {
        let mut rng = Rng::seed(seed);
        let a: Vec<f64> = (0..3 * n).map(|_| rng.uniform() - 0.5).collect();
        let norm = a.iter().map(|x| x * x).sum::<f64>().sqrt();
        a.iter().map(|x| x / norm).collect()
    }

    /// The largest node error of mode 0 of `s`, evaluated as the app does, against `a`.
    fn evaluated_node_error(s: &Shapes, scale: f32, a: &[f64]) -> f64 {
        let rows: Vec<u32> = (0..a.len() as u32 / 3).collect();
        let mut out = vec![0.0; a.len()];
        s.add_mode(0, f64::from(scale), &rows, &mut out);
        out.chunks(3)
            .zip(a.chunks(3))
            .map(|(o, x)| (0..3).map(|c| (o[c] - x[c]).powi(2)).sum::<f64>().sqrt())
            .fold(0.0f64, f64::max)
    }

    #[test]
    fn the_stated_node_error_is_what_evaluation_gives_and_eight_bits_halve_the_bytes() {
        for seed in 1..6 {
            let a = random_mode(seed, 200);
            let mut errors = Vec::new();
            for bits in [ShapeBits::Sixteen, ShapeBits::Eight] {
                let mut s = Shapes::new(bits);
                let (scale, stated) = s.push_mode(&a);
                let worst = evaluated_node_error(&s, scale, &a);
                assert!(
                    (worst - stated).abs() <= 1e-12,
                    "{bits:?}: {worst} vs {stated}"
                );
                // At most half a step per entry.
                let step = a.iter().fold(0.0f64, |m, x| m.max(x.abs())) / bits.top();
                assert!(stated <= 3f64.sqrt() * step / 2.0 * (1.0 + 1e-6));
                errors.push((stated, s.bytes()));
            }
            assert_eq!(errors[1].1 * 2, errors[0].1);
            assert!(errors[1].0 > 50.0 * errors[0].0, "{errors:?}");
        }
    }

    #[test]
    fn a_coarser_step_errs_as_stated_and_deflates_to_fewer_bytes() {
        use std::io::Write;
        let deflated = |s: &Shapes| {
            let Shapes::Eight(v) = s else {
                panic!("eight bits")
            };
            let bytes: Vec<u8> = v.iter().map(|&x| x as u8).collect();
            let mut z = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
            z.write_all(&bytes).expect("deflates");
            z.finish().expect("deflates").len()
        };
        for seed in 1..6 {
            let a = random_mode(seed, 400);
            let top = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let mut fine = Shapes::new(ShapeBits::Eight);
            let (fine_scale, _) = fine.push_mode(&a);
            // A step below the 8-bit one changes nothing.
            let mut same = Shapes::new(ShapeBits::Eight);
            assert_eq!(same.push_mode_coarse(&a, 0.5 * top / 127.0).0, fine_scale);
            assert_eq!(same, fine);
            let step = 8.0 * top / 127.0;
            let mut coarse = Shapes::new(ShapeBits::Eight);
            let (scale, stated) = coarse.push_mode_coarse(&a, step);
            assert!((f64::from(scale) - step).abs() <= 1e-6 * step);
            let worst = evaluated_node_error(&coarse, scale, &a);
            assert!((worst - stated).abs() <= 1e-12, "{worst} vs {stated}");
            assert!(stated <= 3f64.sqrt() * f64::from(scale) / 2.0 * (1.0 + 1e-6));
            // Sixteen levels each side instead of 127: the same bytes, fewer deflated.
            assert_eq!(coarse.bytes(), fine.bytes());
            assert!(
                deflated(&coarse) < deflated(&fine) * 2 / 3,
                "{} vs {}",
                deflated(&coarse),
                deflated(&fine)
            );
        }
    }

    #[test]
    fn a_zero_mode_stays_zero_and_copies_are_exact() {
        let mut s = Shapes::new(ShapeBits::Eight);
        assert_eq!(s.push_mode(&[0.0; 6]), (0.0, 0.0));
        s.push_mode(&[0.5, -0.5, 0.0, 0.0, 0.5, -0.5]);
        let mut t = Shapes::new(ShapeBits::Eight);
        t.push_copy(&s, 1, 6);
        assert_eq!(t, Shapes::Eight(vec![127, -127, 0, 0, 127, -127]));
        assert_eq!(ShapeBits::from_count(8), Some(ShapeBits::Eight));
        assert_eq!(ShapeBits::from_count(12), None);
    }
}
