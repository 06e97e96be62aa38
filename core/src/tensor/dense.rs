//! Thin SVD and QR run sequentially.
//!
//! faer's `Mat::thin_svd` and `Mat::qr` take the global parallelism (rayon over every
//! core). The tensor-train cores are small (tens to a few hundred rows), and there
//! waking the pool costs more than it saves: on `signaling-cascade-20` to t = 15 the
//! process spent 3.2 s of 5.4 in the kernel, waiting on rayon's latches. These do the
//! same factorizations with `Par::Seq`. Each clears the vector registers' upper halves
//! after faer (see [`crate::cpu`]).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::{householder, qr, svd};
use faer::{Conj, Mat, MatRef, Par};

/// `a = u · diag(s) · vᵀ`, `s` decreasing; `None` if the iteration did not converge.
#[derive(Debug, Clone)]
pub struct Svd {
    pub u: Mat<f64>,
    pub s: Vec<f64>,
    pub v: Mat<f64>,
}

pub fn thin_svd(a: MatRef<'_, f64>) -> Option<Svd> {
    let (m, n) = a.shape();
    let k = m.min(n);
    let mut u = Mat::zeros(m, k);
    let mut v = Mat::zeros(n, k);
    let mut s = faer::diag::Diag::<f64>::zeros(k);
    let thin = svd::ComputeSvdVectors::Thin;
    let scratch = svd::svd_scratch::<f64>(m, n, thin, thin, Par::Seq, Default::default());
    let done = svd::svd(
        a,
        s.as_mut(),
        Some(u.as_mut()),
        Some(v.as_mut()),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(scratch)),
        Default::default(),
    );
    crate::cpu::clear_upper_halves();
    done.ok()?;
    let s = (0..k).map(|i| s.column_vector()[i]).collect();
    Some(Svd { u, s, v })
}

/// `a = q · r` with `q` (`m × k`, orthonormal columns) and `r` (`k × n`, upper
/// triangular), `k = min(m, n)`.
pub fn thin_qr(a: MatRef<'_, f64>) -> (Mat<f64>, Mat<f64>) {
    let (m, n) = a.shape();
    let k = m.min(n);
    let mut f = a.to_owned();
    let block = qr::no_pivoting::factor::recommended_block_size::<f64>(m, n);
    let mut coeff = Mat::zeros(block, k);
    let scratch = qr::no_pivoting::factor::qr_in_place_scratch::<f64>(
        m,
        n,
        block,
        Par::Seq,
        Default::default(),
    );
    qr::no_pivoting::factor::qr_in_place(
        f.as_mut(),
        coeff.as_mut(),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(scratch)),
        Default::default(),
    );
    let r = Mat::from_fn(k, n, |i, j| if i <= j { f[(i, j)] } else { 0.0 });
    // The Householder basis: the strict lower part of the first k columns, unit diagonal.
    let basis = Mat::from_fn(m, k, |i, j| match i.cmp(&j) {
        std::cmp::Ordering::Greater => f[(i, j)],
        std::cmp::Ordering::Equal => 1.0,
        std::cmp::Ordering::Less => 0.0,
    });
    let mut q = Mat::identity(m, k);
    let scratch = householder::apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(
        m, block, k,
    );
    householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
        basis.as_ref(),
        coeff.as_ref(),
        Conj::No,
        q.as_mut(),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(scratch)),
    );
    crate::cpu::clear_upper_halves();
    (q, r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn random(m: usize, n: usize, seed: u64) -> Mat<f64> {
        let mut rng = Rng::seed(seed);
        Mat::from_fn(m, n, |_, _| rng.uniform() - 0.5)
    }

    fn max_abs(a: MatRef<'_, f64>) -> f64 {
        (0..a.nrows())
            .flat_map(|i| (0..a.ncols()).map(move |j| (i, j)))
            .map(|(i, j)| a[(i, j)].abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn factors_reproduce_tall_wide_and_square_matrices() {
        for (m, n, seed) in [(40, 7, 1), (6, 30, 2), (50, 50, 3), (1, 5, 4), (300, 90, 5)] {
            let a = random(m, n, seed);
            let k = m.min(n);
            let (q, r) = thin_qr(a.as_ref());
            assert_eq!((q.nrows(), q.ncols(), r.nrows(), r.ncols()), (m, k, k, n));
            assert!(max_abs((&q * &r - &a).as_ref()) < 1e-12, "qr {m}×{n}");
            assert!(max_abs((q.transpose() * &q - Mat::<f64>::identity(k, k)).as_ref()) < 1e-12);
            let f = thin_svd(a.as_ref()).expect("converges");
            assert!(f.s.windows(2).all(|w| w[0] >= w[1]) && f.s[k - 1] >= 0.0);
            let us = Mat::from_fn(m, k, |i, j| f.u[(i, j)] * f.s[j]);
            assert!(
                max_abs((us * f.v.transpose() - &a).as_ref()) < 1e-12,
                "svd {m}×{n}"
            );
        }
    }
}
