//! Streaming kernels of on-line evaluation.
//!
//! Reconstruction is `u_r = Σ_{k<n} X[r, k] · c_k` over the chosen rows: every stored
//! entry of X is read once and used once, so its cost is bounded below by the time to
//! stream the bytes of X from memory. [`stream_sum`] reads the same bytes with the same
//! access pattern and the same arithmetic shape (convert, accumulate), and is the
//! bandwidth reference `palpa bench eval` divides by.
//!
//! Both accumulate in `f64` in [`LANES`] independent partial sums: independent sums let
//! the compiler vectorize without reassociating a single sum (which it may not do for
//! floats), and `f64` accumulation keeps an `f32` model's error at its storage rounding.
//!
//! The generic bodies are compiled twice on x86-64: for the baseline target and, chosen
//! at run time when the CPU has them, with AVX2 and FMA (4 f64 lanes per instruction and
//! fused multiply-add). Without the second copy the baseline (SSE2) build is
//! compute-bound at about half the memory bandwidth. Other targets use the baseline copy
//! (aarch64's baseline already has 128-bit SIMD with FMA).

use crate::scalar::Scalar;

/// Independent partial sums per dot product: 4 AVX registers of f64, enough to hide the
/// FMA latency (4 cycles × 2 ports needs 8 vectors in flight for the peak; 4 is the
/// best compromise for rows as short as 50 modes, whose tail would otherwise dominate).
pub const LANES: usize = 16;

/// `out[i] = Σ_{k<n} x[i·stride + k] · c[k]` with `n = c.len()`, accumulated in f64:
/// the rows `x[i·stride .. i·stride + n]` for `i < out.len()`.
#[track_caller]
pub fn strided_dots<T: Scalar>(x: &[T], stride: usize, c: &[f64], out: &mut [f64]) {
    let n = c.len();
    assert!(n <= stride, "{n} coefficients for rows of {stride}");
    assert!(
        out.is_empty() || (out.len() - 1) * stride + n <= x.len(),
        "{} rows of stride {stride} exceed {} stored entries",
        out.len(),
        x.len()
    );
    #[cfg(target_arch = "x86_64")]
    if x86::has_avx2_fma() {
        x86::strided_dots(x, stride, c, out);
        return;
    }
    strided_dots_generic::<T, false>(x, stride, c, out);
}

/// `Σ_k row[k] · c[k]` for one row (used where rows are not evenly strided).
#[inline]
#[track_caller]
pub fn dot<T: Scalar>(row: &[T], c: &[f64]) -> f64 {
    assert_eq!(row.len(), c.len(), "row and coefficient lengths differ");
    let mut out = [0.0];
    strided_dots(row, row.len(), c, &mut out);
    out[0]
}

/// The sum of every entry of `data`, read in the same streaming pattern as
/// [`strided_dots`]: the memory-bandwidth reference for reconstruction.
pub fn stream_sum<T: Scalar>(data: &[T]) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if x86::has_avx2_fma() {
        return x86::stream_sum(data);
    }
    stream_sum_generic(data)
}

/// `out[k] *= Σ_s w_s · rows_s[k]`: the particularization step of one axis.
#[inline]
#[track_caller]
pub fn scale_by_stencil<T: Scalar>(out: &mut [f64], rows: [&[T]; 3], w: [f64; 3]) {
    let n = out.len();
    assert!(
        rows.iter().all(|r| r.len() == n),
        "stencil rows must match the number of modes"
    );
    for k in 0..n {
        out[k] *= w[0] * rows[0][k].to_f64()
            + w[1] * rows[1][k].to_f64()
            + w[2] * rows[2][k].to_f64();
    }
}

#[inline(always)]
fn madd<const FUSED: bool>(a: f64, b: f64, acc: f64) -> f64 {
    // Only fuse where the target has FMA: elsewhere mul_add is a slow library call.
    if FUSED { a.mul_add(b, acc) } else { acc + a * b }
}

#[inline(always)]
fn strided_dots_generic<T: Scalar, const FUSED: bool>(
    x: &[T],
    stride: usize,
    c: &[f64],
    out: &mut [f64],
) {
    let n = c.len();
    for (i, o) in out.iter_mut().enumerate() {
        let row = &x[i * stride..i * stride + n];
        *o = dot_generic::<T, FUSED>(row, c);
    }
}

#[inline(always)]
fn dot_generic<T: Scalar, const FUSED: bool>(row: &[T], c: &[f64]) -> f64 {
    let (row_chunks, row_tail) = row.as_chunks::<LANES>();
    let (c_chunks, c_tail) = c.as_chunks::<LANES>();
    let mut acc = [0.0f64; LANES];
    for (r, cc) in row_chunks.iter().zip(c_chunks) {
        for i in 0..LANES {
            acc[i] = madd::<FUSED>(r[i].to_f64(), cc[i], acc[i]);
        }
    }
    // Tail in groups of 4 (one AVX vector), then singles.
    let (r4, r1) = row_tail.as_chunks::<4>();
    let (c4, c1) = c_tail.as_chunks::<4>();
    for (r, cc) in r4.iter().zip(c4) {
        for i in 0..4 {
            acc[i] = madd::<FUSED>(r[i].to_f64(), cc[i], acc[i]);
        }
    }
    for (r, cc) in r1.iter().zip(c1) {
        acc[4] = madd::<FUSED>(r.to_f64(), *cc, acc[4]);
    }
    reduce(acc)
}

#[inline(always)]
fn stream_sum_generic<T: Scalar>(data: &[T]) -> f64 {
    let (chunks, tail) = data.as_chunks::<LANES>();
    let mut acc = [0.0f64; LANES];
    for r in chunks {
        for i in 0..LANES {
            acc[i] += r[i].to_f64();
        }
    }
    for r in tail {
        acc[0] += r.to_f64();
    }
    reduce(acc)
}

#[inline(always)]
fn reduce(acc: [f64; LANES]) -> f64 {
    // Pairwise, so the partial sums combine with log2(LANES) roundings.
    let mut a = acc;
    let mut w = LANES / 2;
    while w > 0 {
        for i in 0..w {
            a[i] += a[i + w];
        }
        w /= 2;
    }
    a[0]
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod x86 {
    //! The AVX2 + FMA instantiation of the generic kernels, chosen at run time.
    use super::{Scalar, stream_sum_generic, strided_dots_generic};

    #[inline]
    pub fn has_avx2_fma() -> bool {
        // std caches the CPUID result; this is an atomic load and a bit test.
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }

    pub fn strided_dots<T: Scalar>(x: &[T], stride: usize, c: &[f64], out: &mut [f64]) {
        // SAFETY: only called after has_avx2_fma() returned true, so the CPU executes
        // the AVX2/FMA instructions this copy is compiled with.
        unsafe { strided_dots_avx2(x, stride, c, out) }
    }

    pub fn stream_sum<T: Scalar>(data: &[T]) -> f64 {
        // SAFETY: as above.
        unsafe { stream_sum_avx2(data) }
    }

    #[target_feature(enable = "avx2,fma")]
    fn strided_dots_avx2<T: Scalar>(x: &[T], stride: usize, c: &[f64], out: &mut [f64]) {
        strided_dots_generic::<T, true>(x, stride, c, out);
    }

    #[target_feature(enable = "avx2,fma")]
    fn stream_sum_avx2<T: Scalar>(data: &[T]) -> f64 {
        stream_sum_generic(data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_matches_naive_for_all_tails() {
        for n in 0..70 {
            let row: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
            let c: Vec<f64> = (0..n).map(|i| (i as f64 * 1.3).cos()).collect();
            let naive: f64 = row.iter().zip(&c).map(|(a, b)| a * b).sum();
            // n terms of magnitude ≤ 1: error ≤ n·eps.
            assert!((dot(&row, &c) - naive).abs() <= (n as f64 + 1.0) * f64::EPSILON);
            let generic = dot_generic::<f64, false>(&row, &c);
            assert!((generic - naive).abs() <= (n as f64 + 1.0) * f64::EPSILON);
        }
    }

    #[test]
    fn strided_dots_read_the_right_rows() {
        // 4 rows of stride 7, first 5 columns used: row i is [i, i, ...].
        let x: Vec<f32> = (0..28).map(|j| (j / 7) as f32).collect();
        let c = [1.0, 1.0, 1.0, 1.0, 1.0];
        let mut out = [0.0; 4];
        strided_dots(&x, 7, &c, &mut out);
        assert_eq!(out, [0.0, 5.0, 10.0, 15.0]);
    }

    #[test]
    fn f32_accumulates_in_f64() {
        // 10^6 terms of 0.1f32: an f32 accumulator drifts by ~1%; f64 keeps the
        // storage rounding only (0.1f32 = 0.100000001490116...).
        let row = vec![0.1f32; 1_000_000];
        let c = vec![1.0f64; 1_000_000];
        let exact = f64::from(0.1f32) * 1e6;
        assert!((dot(&row, &c) - exact).abs() / exact < 1e-12);
        assert!((stream_sum(&row) - exact).abs() / exact < 1e-12);
    }
}
