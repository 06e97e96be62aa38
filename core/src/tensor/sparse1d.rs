//! Sparse 1-D factors: the few non-zeros per row of a banded matrix on one axis (CSR).

/// A sparse matrix with the few non-zeros per row of a 1-D factor (CSR).
#[derive(Debug, Clone, PartialEq)]
pub struct Sparse1d {
    pub rows: usize,
    pub cols: usize,
    ptr: Vec<usize>,
    idx: Vec<usize>,
    val: Vec<f64>,
    identity: bool,
}

impl Sparse1d {
    /// Whether this factor was built as the identity (products may skip it).
    pub fn is_identity(&self) -> bool {
        self.identity
    }

    pub fn identity(m: usize) -> Self {
        let mut s = Self::from_triplets(m, m, (0..m).map(|i| (i, i, 1.0)));
        s.identity = true;
        s
    }

    pub fn diagonal(d: &[f64]) -> Self {
        Self::from_triplets(
            d.len(),
            d.len(),
            d.iter().enumerate().map(|(i, &v)| (i, i, v)),
        )
    }

    /// From `(row, col, value)` entries (duplicates are summed).
    pub fn from_triplets(
        rows: usize,
        cols: usize,
        entries: impl IntoIterator<Item = (usize, usize, f64)>,
    ) -> Self {
        let mut e: Vec<(usize, usize, f64)> = entries.into_iter().collect();
        e.sort_by_key(|&(r, c, _)| (r, c));
        let mut ptr = vec![0usize; rows + 1];
        let mut idx = Vec::with_capacity(e.len());
        let mut val: Vec<f64> = Vec::with_capacity(e.len());
        let mut last = None;
        for (r, c, v) in e {
            assert!(
                r < rows && c < cols,
                "entry ({r}, {c}) outside {rows}×{cols}"
            );
            if last == Some((r, c)) {
                *val.last_mut()
                    .expect("a duplicate index follows an entry pushed for it") += v;
                continue;
            }
            last = Some((r, c));
            ptr[r + 1] += 1;
            idx.push(c);
            val.push(v);
        }
        for r in 0..rows {
            ptr[r + 1] += ptr[r];
        }
        Sparse1d {
            rows,
            cols,
            ptr,
            idx,
            val,
            identity: false,
        }
    }

    /// `y = B x`.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        if self.identity {
            y.copy_from_slice(x);
            return;
        }
        for (r, yr) in y.iter_mut().enumerate() {
            *yr = (self.ptr[r]..self.ptr[r + 1])
                .map(|e| self.val[e] * x[self.idx[e]])
                .sum();
        }
    }

    pub fn applied(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.rows];
        self.apply(x, &mut y);
        y
    }

    /// `y += s Bᵀ x`.
    pub fn add_transposed(&self, s: f64, x: &[f64], y: &mut [f64]) {
        for (r, &xr) in x.iter().enumerate() {
            for e in self.ptr[r]..self.ptr[r + 1] {
                y[self.idx[e]] += s * self.val[e] * xr;
            }
        }
    }

    /// `s · B`.
    pub fn scaled(mut self, s: f64) -> Self {
        if s != 1.0 {
            self.identity = false;
            for v in &mut self.val {
                *v *= s;
            }
        }
        self
    }

    pub fn row(&self, r: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        (self.ptr[r]..self.ptr[r + 1]).map(|e| (self.idx[e], self.val[e]))
    }
}
