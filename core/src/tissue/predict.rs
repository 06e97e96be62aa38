//! The tissue file's mode shapes coded as what their neighbours do not predict
//! (as a tissue file stores them): lossless, about an eighth of the file less.
//!
//! A mode shape is a smooth field over the surface away from the tool: a node's stored
//! integer `q_i` is close to its near neighbours'. The file therefore stores, for each
//! mode and coordinate, the rows in a fixed order `t = 0, 1, …` and at each row the
//! difference from a prediction made of rows stored before it,
//!
//! ```text
//! p_i = ⌊(Σ_{j ∈ N(i)} w_ij q_j + 128) / 256⌋,   r_i = (q_i − p_i) mod 2^b,
//! ```
//!
//! `N(i)` the (at most) four rows nearest to `i` among those earlier in the order,
//! `w_ij` integers summing to 256, proportional to `1 / |x_i − x_j|²` (inverse distance
//! squared, rest positions), and `b` the shapes' bits. The reader adds the same
//! prediction back, `q_i = (r_i + p_i) mod 2^b`, in the same order: integer arithmetic
//! throughout, so the shapes come back bit for bit on any machine and the stored bound
//! keeps its meaning. The order is Prim's spanning tree of the rest positions grown from
//! row 0 (the nearest row not yet taken, ties to the lower index), so each row but the
//! first has a close neighbour already stored. Order and weights depend on the rows'
//! rest positions alone, which the file holds, so they are not stored.
//!
//! Measured on the 100-sub-triangle coarse file (12 851 modes over 858 rows, 8 bits),
//! the shapes under LZMA: by plane 6.08 MB; the tree parent alone as prediction
//! 5.61 MB; the three nearest earlier rows by inverse distance 5.34 MB; four by inverse
//! distance squared 5.30 MB; six 5.28 MB. An affine fit through six or eight neighbours
//! was worse (5.6–5.9 MB): it extrapolates the rounding. See
//! docs/lab/tissue-measurements.md §6.

use crate::tissue::shapes::Shapes;

/// How many earlier rows predict a row.
const NEIGHBOURS: usize = 4;

/// Weights sum to this (a shift of 8 bits).
const WEIGHT_SUM: i32 = 256;

/// The order rows are stored in and each row's prediction from earlier ones.
#[derive(Debug, Clone, PartialEq)]
pub struct RowPrediction {
    /// Rows in storage order.
    order: Vec<u32>,
    /// Per position in `order` (the first's is empty): earlier rows and their weights.
    from: Vec<Vec<(u32, i32)>>,
}

impl RowPrediction {
    /// The order and weights of the rows at `rows_mm` (see the module docs).
    pub fn new(rows_mm: &[[f32; 3]]) -> RowPrediction {
        let n = rows_mm.len();
        let at = |i: usize| rows_mm[i].map(f64::from);
        let dist2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>();
        // Prim: the row nearest to the tree next, ties to the lower index. A NaN
        // position (no law has one) compares as farthest.
        let mut taken = vec![false; n];
        let mut best = vec![f64::INFINITY; n];
        let mut order = Vec::with_capacity(n);
        if n > 0 {
            best[0] = 0.0;
        }
        for _ in 0..n {
            let next = (0..n)
                .filter(|&i| !taken[i])
                .min_by(|&a, &b| best[a].total_cmp(&best[b]).then(a.cmp(&b)))
                .expect("a row is left while the order is short");
            taken[next] = true;
            order.push(next as u32);
            let x = at(next);
            for i in 0..n {
                let d = dist2(x, at(i));
                if !taken[i] && d < best[i] {
                    best[i] = d;
                }
            }
        }
        let from = (0..n)
            .map(|t| {
                let x = at(order[t] as usize);
                let mut near: Vec<(f64, u32)> = order[..t]
                    .iter()
                    .map(|&j| (dist2(x, at(j as usize)), j))
                    .collect();
                // The nearest few, ties to the lower index: a partial selection, then
                // those few sorted (a full sort of every earlier row was O(n² log n)).
                let by = |a: &(f64, u32), b: &(f64, u32)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
                if near.len() > NEIGHBOURS {
                    near.select_nth_unstable_by(NEIGHBOURS, by);
                    near.truncate(NEIGHBOURS);
                }
                near.sort_by(by);
                integer_weights(&near)
            })
            .collect();
        RowPrediction { order, from }
    }

    /// The prediction of row `order[t]` from the integers `q` of one mode's coordinate
    /// (indexed by row).
    fn predict(&self, t: usize, q: impl Fn(usize) -> i32) -> i32 {
        let sum: i32 = self.from[t].iter().map(|&(j, w)| w * q(j as usize)).sum();
        match self.from[t].is_empty() {
            true => 0,
            false => (sum + WEIGHT_SUM / 2).div_euclid(WEIGHT_SUM),
        }
    }

    /// `shapes` (modes × rows × 3 entries) as a tissue file stores them: by coordinate
    /// plane, each mode's rows in storage order, each entry its prediction's miss.
    /// `None` where the length is not a whole number of modes over these rows.
    pub fn encode(&self, shapes: &Shapes) -> Option<Shapes> {
        self.transform(shapes, true)
    }

    /// The inverse of [`encode`](Self::encode); `None` where the length is not a
    /// whole number of modes over these rows.
    pub fn decode(&self, stored: &Shapes) -> Option<Shapes> {
        self.transform(stored, false)
    }

    fn transform(&self, shapes: &Shapes, encode: bool) -> Option<Shapes> {
        match shapes {
            Shapes::Eight(v) => self
                .code(v.len(), |i| i32::from(v[i]), 8, encode)
                .map(|r| Shapes::Eight(r.into_iter().map(|x| x as i8).collect())),
            Shapes::Sixteen(v) => self
                .code(v.len(), |i| i32::from(v[i]), 16, encode)
                .map(|r| Shapes::Sixteen(r.into_iter().map(|x| x as i16).collect())),
        }
    }

    /// Both directions. Encoding reads entries in memory order (`mode · 3n + 3 row + c`)
    /// and writes them in storage order (`c · modes · n + mode · n + t`); decoding the
    /// reverse. Every output is wrapped to `bits` (two's complement), so the pair is
    /// exact for every value the type holds, and a corrupt entry decodes to some value
    /// of the type, never out of it.
    fn code(
        &self,
        len: usize,
        input: impl Fn(usize) -> i32,
        bits: u32,
        encode: bool,
    ) -> Option<Vec<i32>> {
        let n = self.order.len();
        if n == 0 || !len.is_multiple_of(3 * n) {
            return (len == 0).then(Vec::new);
        }
        let modes = len / (3 * n);
        let memory = |mode: usize, row: usize, c: usize| mode * 3 * n + 3 * row + c;
        let storage = |mode: usize, t: usize, c: usize| c * modes * n + mode * n + t;
        let mut out = vec![0i32; len];
        // The decoded mode's integers (one coordinate), by row: what predicts.
        let mut q = vec![0i32; n];
        for mode in 0..modes {
            for c in 0..3 {
                for t in 0..n {
                    let row = self.order[t] as usize;
                    let p = self.predict(t, |j| q[j]);
                    if encode {
                        q[row] = input(memory(mode, row, c));
                        out[storage(mode, t, c)] = wrap(q[row] - p, bits);
                    } else {
                        // The prediction sees the value as stored, as the encoder's did.
                        q[row] = wrap(input(storage(mode, t, c)) + p, bits);
                        out[memory(mode, row, c)] = q[row];
                    }
                }
            }
        }
        Some(out)
    }
}

/// `value` modulo `2^bits`, in the signed range `[−2^(bits−1), 2^(bits−1))`.
fn wrap(value: i32, bits: u32) -> i32 {
    let (full, half) = (1i32 << bits, 1i32 << (bits - 1));
    (value + half).rem_euclid(full) - half
}

/// Integer weights summing to [`WEIGHT_SUM`], proportional to `1 / d²` (`near`: squared
/// distance and row). A row at distance zero takes all the weight.
fn integer_weights(near: &[(f64, u32)]) -> Vec<(u32, i32)> {
    if near.is_empty() {
        return Vec::new();
    }
    if near[0].0 <= 0.0 || !near[0].0.is_finite() {
        return vec![(near[0].1, WEIGHT_SUM)];
    }
    let inverse: Vec<f64> = near.iter().map(|&(d2, _)| 1.0 / d2).collect();
    let total: f64 = inverse.iter().sum();
    let mut w: Vec<(u32, i32)> = near
        .iter()
        .zip(&inverse)
        .map(|(&(_, j), &x)| (j, (x / total * f64::from(WEIGHT_SUM)).round() as i32))
        .collect();
    // Rounding may miss the sum by a unit or two: the nearest row takes it up.
    let missing = WEIGHT_SUM - w.iter().map(|&(_, x)| x).sum::<i32>();
    w[0].1 += missing;
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Rows on a bumpy sheet, in a shuffled index order (storage order is not index
    /// order).
    fn rows(seed: u64, n: usize) -> Vec<[f32; 3]> {
        let mut rng = Rng::seed(seed);
        (0..n)
            .map(|_| {
                let (x, y) = (100.0 * rng.uniform(), 60.0 * rng.uniform());
                [
                    x as f32,
                    y as f32,
                    (5.0 * (x / 20.0).sin() * (y / 15.0).cos()) as f32,
                ]
            })
            .collect()
    }

    /// `modes` smooth fields over `rows` (a bump at a random place plus a tilt), each
    /// quantized to `top` levels a side.
    fn smooth(rows: &[[f32; 3]], modes: usize, top: f64, seed: u64) -> Vec<f64> {
        let mut rng = Rng::seed(seed);
        let mut out = Vec::new();
        for _ in 0..modes {
            let at = [100.0 * rng.uniform(), 60.0 * rng.uniform()];
            let width = 5.0 + 30.0 * rng.uniform();
            let tilt = [
                rng.uniform() - 0.5,
                rng.uniform() - 0.5,
                rng.uniform() - 0.5,
            ];
            for r in rows {
                let d2 = (f64::from(r[0]) - at[0]).powi(2) + (f64::from(r[1]) - at[1]).powi(2);
                let bump = (-d2 / (width * width)).exp();
                for t in tilt {
                    out.push((top * (0.7 * bump + 0.3 * t * f64::from(r[0]) / 100.0)).round());
                }
            }
        }
        out
    }

    fn lzma_len(s: &Shapes) -> usize {
        let bytes: Vec<u8> = match s {
            Shapes::Eight(v) => v.iter().map(|&x| x as u8).collect(),
            Shapes::Sixteen(v) => v.iter().flat_map(|&x| x.to_le_bytes()).collect(),
        };
        let mut out = Vec::new();
        let options = lzma_rust2::LzmaOptions::with_preset(6);
        let mut w = lzma_rust2::LzmaWriter::new_use_header(&mut out, &options, None)
            .expect("an LZMA writer");
        std::io::Write::write_all(&mut w, &bytes).expect("compresses");
        w.finish().expect("compresses");
        out.len()
    }

    #[test]
    fn every_stored_value_comes_back_bit_for_bit() {
        for seed in 1..5 {
            let rows = rows(seed, 40 + 17 * seed as usize);
            let p = RowPrediction::new(&rows);
            let mut rng = Rng::seed(100 + seed);
            let n3 = 3 * rows.len();
            // Any integer a type of `bits` holds, the extremes included, in random places.
            let mut values = |len: usize, every: usize, bits: u32| -> Vec<i32> {
                let half = 1i32 << (bits - 1);
                (0..len)
                    .map(|i| match i % every {
                        0 => -half,
                        1 => half - 1,
                        _ => (rng.uniform() * f64::from(2 * half)).floor() as i32 - half,
                    })
                    .collect()
            };
            let eight: Vec<i8> = values(5 * n3, 7, 8).into_iter().map(|x| x as i8).collect();
            let sixteen: Vec<i16> = values(3 * n3, 5, 16)
                .into_iter()
                .map(|x| x as i16)
                .collect();
            for s in [Shapes::Eight(eight), Shapes::Sixteen(sixteen)] {
                let stored = p.encode(&s).expect("whole modes");
                assert_eq!(stored.len(), s.len());
                assert_ne!(stored, s, "stored as misses, not as the values");
                assert_eq!(p.decode(&stored), Some(s));
            }
        }
    }

    #[test]
    fn a_smooth_field_stores_as_small_misses_and_compresses_further() {
        let rows = rows(7, 300);
        let p = RowPrediction::new(&rows);
        let fields = smooth(&rows, 20, 127.0, 8);
        let s = Shapes::Eight(fields.iter().map(|&x| x as i8).collect());
        let stored = p.encode(&s).expect("whole modes");
        let mean_abs =
            |s: &Shapes| (0..s.len()).map(|i| s.get(i).abs()).sum::<f64>() / s.len() as f64;
        assert!(
            mean_abs(&stored) < 0.25 * mean_abs(&s),
            "{} vs {}",
            mean_abs(&stored),
            mean_abs(&s)
        );
        let (coded, plain) = (lzma_len(&stored), lzma_len(&s));
        assert!(coded < plain * 4 / 5, "{coded} vs {plain} bytes");
        assert_eq!(p.decode(&stored), Some(s));
    }

    #[test]
    fn the_order_is_a_spanning_tree_and_the_weights_sum_to_one() {
        let rows = rows(3, 120);
        let p = RowPrediction::new(&rows);
        let mut seen = p.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..120).collect::<Vec<u32>>(), "every row once");
        assert_eq!(p.order[0], 0);
        assert!(p.from[0].is_empty());
        let earlier = |t: usize, j: u32| p.order[..t].contains(&j);
        for t in 1..120 {
            assert_eq!(p.from[t].len(), t.min(NEIGHBOURS));
            assert_eq!(p.from[t].iter().map(|&(_, w)| w).sum::<i32>(), WEIGHT_SUM);
            assert!(p.from[t].iter().all(|&(j, w)| earlier(t, j) && w >= 0));
        }
        // The same rows give the same order and weights (nothing random, nothing from
        // the machine): the reader rebuilds what the writer used.
        assert_eq!(RowPrediction::new(&rows), p);
    }

    #[test]
    fn repeated_rows_and_degenerate_lengths_are_handled() {
        // Two rows at the same place: the second is predicted by the first alone.
        let rows = vec![[0.0f32, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let p = RowPrediction::new(&rows);
        assert_eq!(p.from[1], vec![(0, WEIGHT_SUM)]);
        let s = Shapes::Eight(vec![5, -3, 7, 5, -3, 7, 6, -2, 8]);
        let stored = p.encode(&s).expect("one mode");
        assert_eq!(p.decode(&stored), Some(s));
        // A length that is not a whole number of modes is refused; no rows, no modes.
        assert_eq!(p.encode(&Shapes::Eight(vec![1; 10])), None);
        assert_eq!(p.decode(&Shapes::Sixteen(vec![1; 8])), None);
        let none = RowPrediction::new(&[]);
        assert_eq!(
            none.decode(&Shapes::Eight(vec![])),
            Some(Shapes::Eight(vec![]))
        );
        assert_eq!(none.decode(&Shapes::Eight(vec![1, 2, 3])), None);
    }
}
