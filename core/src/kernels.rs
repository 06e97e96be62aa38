//! Streaming kernels of on-line evaluation, and the row sums a nodule's placement is made of.
//!
//! Reconstruction is `u_r = Σ_{k<n} X[r, k] · c_k` over the chosen rows: every stored
//! entry of X is read once and used once, so its cost is bounded below by the time to
//! stream the bytes of X from memory. [`stream_sum`] reads the same bytes front to back
//! with the cheapest possible arithmetic (a sum in the storage type, no conversion) and
//! is the bandwidth reference `palpa lab bench eval` divides by.
//!
//! Reconstruction accumulates in `f64` in independent partial sums: independent sums
//! let the compiler vectorize without reassociating a single sum (which it may not do
//! for floats), and `f64` accumulation keeps an `f32` model's error at its storage
//! rounding instead of letting it grow with the number of modes.
//!
//! On x86-64 an AVX2 + FMA version (explicit intrinsics, 4 f64 lanes, fused
//! multiply-add) is chosen at run time when the CPU has it; the portable generic body
//! serves elsewhere (aarch64's baseline already has 128-bit SIMD with FMA, which LLVM
//! uses for it) and is tested against it.

use crate::scalar::Scalar;

/// Independent partial sums per dot product in the portable body.
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
    strided_dots_generic(x, stride, c, out);
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

/// The sum of every entry of `data` in its storage type: the memory-bandwidth reference
/// for reconstruction (not for numerical use: an f32 sum loses precision).
pub fn stream_sum<T: Scalar>(data: &[T]) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if x86::has_avx2_fma() {
        return x86::stream_sum(data);
    }
    stream_sum_generic(data)
}

/// `y[i] += a · x[i]` over the shorter of the two: sums of contiguous rows weighted by
/// a sparse row (the nodule's small system, [`crate::pgd::nodule`]). Each element rounds
/// as written (a product, then a sum; no fused multiply-add), so every path gives the
/// same bits; on x86-64 the body is compiled for AVX2 too and chosen at run time.
#[inline]
pub fn axpy<T: Axpy>(y: &mut [T], a: T, x: &[T]) {
    #[cfg(target_arch = "x86_64")]
    if x86::has_avx2_fma() {
        x86::axpy(y, a, x);
        return;
    }
    axpy_generic(y, a, x);
}

/// What [`axpy`] works in: `f32` and `f64`.
pub trait Axpy: Copy + std::ops::Mul<Output = Self> + std::ops::AddAssign {}
impl Axpy for f32 {}
impl Axpy for f64 {}

#[inline(always)]
fn axpy_generic<T: Axpy>(y: &mut [T], a: T, x: &[T]) {
    for (d, &s) in y.iter_mut().zip(x) {
        *d += a * s;
    }
}

/// `out[k] *= Σ_{s<len} w_s · values[node_s · modes + k]`: the particularization step
/// of one axis (`values` is nodes × modes, row-major; `out.len() ≤ modes`).
#[inline]
#[track_caller]
pub fn scale_by_stencil<T: Scalar>(
    out: &mut [f64],
    values: &[T],
    modes: usize,
    st: &crate::axis::Stencil,
) {
    let n = out.len();
    assert!(n <= modes, "{n} coefficients for {modes} modes");
    let rows: [&[T]; crate::axis::MAX_STENCIL] = std::array::from_fn(|s| {
        let start = st.nodes[s] as usize * modes;
        &values[start..start + n]
    });
    for k in 0..n {
        let mut acc = 0.0;
        for s in 0..st.len {
            acc += st.weights[s] * rows[s][k].to_f64();
        }
        out[k] *= acc;
    }
}

#[inline(always)]
fn strided_dots_generic<T: Scalar>(x: &[T], stride: usize, c: &[f64], out: &mut [f64]) {
    let n = c.len();
    for (i, o) in out.iter_mut().enumerate() {
        let row = &x[i * stride..i * stride + n];
        *o = dot_generic(row, c);
    }
}

#[inline(always)]
fn dot_generic<T: Scalar>(row: &[T], c: &[f64]) -> f64 {
    let (row_chunks, row_tail) = row.as_chunks::<LANES>();
    let (c_chunks, c_tail) = c.as_chunks::<LANES>();
    let mut acc = [0.0f64; LANES];
    for (r, cc) in row_chunks.iter().zip(c_chunks) {
        for i in 0..LANES {
            acc[i] += r[i].to_f64() * cc[i];
        }
    }
    // Tail in groups of 4 (one AVX vector), then singles.
    let (r4, r1) = row_tail.as_chunks::<4>();
    let (c4, c1) = c_tail.as_chunks::<4>();
    for (r, cc) in r4.iter().zip(c4) {
        for i in 0..4 {
            acc[i] += r[i].to_f64() * cc[i];
        }
    }
    for (r, cc) in r1.iter().zip(c1) {
        acc[4] += r.to_f64() * cc;
    }
    reduce(acc)
}

#[inline(always)]
fn stream_sum_generic<T: Scalar>(data: &[T]) -> f64 {
    // Accumulates in the storage type (no conversion), 32 lanes: the fastest plain
    // read of the bytes we can write, so the ratio against it is not flattered.
    let (chunks, tail) = data.as_chunks::<32>();
    let mut acc = [T::from_f64(0.0); 32];
    for r in chunks {
        for i in 0..32 {
            acc[i] = acc[i].add(r[i]);
        }
    }
    let mut total: f64 = acc.iter().map(|a| a.to_f64()).sum();
    for r in tail {
        total += r.to_f64();
    }
    total
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
    //! AVX2 + FMA kernels (and AVX-512 for f32 storage, whose f32→f64 widening is the
    //! bottleneck), chosen at run time. Written with explicit intrinsics: the
    //! auto-vectorized generic body mixes scalar converts and shuffles and runs at half
    //! the speed. Measured on this project's 2-core AMD EPYC (f32, 10k × 50):
    //! generic 101 µs, AVX2 45 µs, AVX-512 27 µs.
    use std::arch::x86_64::*;

    use super::{Scalar, stream_sum_generic};
    use crate::scalar::Precision;

    #[inline]
    pub fn has_avx2_fma() -> bool {
        // std caches the CPUID result; this is an atomic load and a bit test.
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }

    /// Caller (`super::strided_dots`) has checked the row bounds.
    pub fn strided_dots<T: Scalar>(x: &[T], stride: usize, c: &[f64], out: &mut [f64]) {
        // SAFETY: called only after has_avx2_fma() returned true, so the CPU executes
        // the AVX2/FMA instructions; every row `i·stride .. i·stride + c.len()` lies in
        // `x` (asserted by the caller), which is what the unaligned loads read.
        unsafe {
            match T::PRECISION {
                Precision::F64 => dots_f64(bytemuck::cast_slice(x), stride, c, out),
                Precision::F32 if has_avx512() => {
                    dots_f32_avx512(bytemuck::cast_slice(x), stride, c, out);
                }
                Precision::F32 => dots_f32(bytemuck::cast_slice(x), stride, c, out),
            }
        }
    }

    pub fn stream_sum<T: Scalar>(data: &[T]) -> f64 {
        // SAFETY: as above; the generic body only reads inside `data`.
        unsafe { stream_sum_avx2(data) }
    }

    #[target_feature(enable = "avx2,fma")]
    fn stream_sum_avx2<T: Scalar>(data: &[T]) -> f64 {
        stream_sum_generic(data)
    }

    pub fn axpy<T: super::Axpy>(y: &mut [T], a: T, x: &[T]) {
        // SAFETY: called only after has_avx2_fma() returned true; the generic body only
        // touches `y` and `x` inside their bounds.
        unsafe { axpy_avx2(y, a, x) }
    }

    #[target_feature(enable = "avx2,fma")]
    fn axpy_avx2<T: super::Axpy>(y: &mut [T], a: T, x: &[T]) {
        super::axpy_generic(y, a, x);
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn hsum(v: __m256d) -> f64 {
        let lo = _mm256_castpd256_pd128(v);
        let hi = _mm256_extractf128_pd::<1>(v);
        let s = _mm_add_pd(lo, hi);
        let h = _mm_unpackhi_pd(s, s);
        _mm_cvtsd_f64(_mm_add_sd(s, h))
    }

    #[target_feature(enable = "avx2,fma")]
    unsafe fn dots_f64(x: &[f64], stride: usize, c: &[f64], out: &mut [f64]) {
        let n = c.len();
        let cp = c.as_ptr();
        for (i, o) in out.iter_mut().enumerate() {
            let rp = unsafe { x.as_ptr().add(i * stride) };
            let mut a = [_mm256_setzero_pd(); 4];
            let mut k = 0;
            while k + 16 <= n {
                for (j, acc) in a.iter_mut().enumerate() {
                    let xv = unsafe { _mm256_loadu_pd(rp.add(k + 4 * j)) };
                    let cv = unsafe { _mm256_loadu_pd(cp.add(k + 4 * j)) };
                    *acc = _mm256_fmadd_pd(xv, cv, *acc);
                }
                k += 16;
            }
            while k + 4 <= n {
                let xv = unsafe { _mm256_loadu_pd(rp.add(k)) };
                let cv = unsafe { _mm256_loadu_pd(cp.add(k)) };
                a[0] = _mm256_fmadd_pd(xv, cv, a[0]);
                k += 4;
            }
            let mut tail = 0.0;
            while k < n {
                tail = unsafe { (*rp.add(k)).mul_add(*cp.add(k), tail) };
                k += 1;
            }
            let s = _mm256_add_pd(_mm256_add_pd(a[0], a[1]), _mm256_add_pd(a[2], a[3]));
            *o = hsum(s) + tail;
        }
    }

    #[inline]
    pub fn has_avx512() -> bool {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
    }

    #[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
    unsafe fn dots_f32_avx512(x: &[f32], stride: usize, c: &[f64], out: &mut [f64]) {
        let n = c.len();
        let cp = c.as_ptr();
        for (i, o) in out.iter_mut().enumerate() {
            let rp = unsafe { x.as_ptr().add(i * stride) };
            let mut a = [_mm512_setzero_pd(); 4];
            let mut k = 0;
            while k + 32 <= n {
                for (j, acc) in a.iter_mut().enumerate() {
                    let xv = _mm512_cvtps_pd(unsafe { _mm256_loadu_ps(rp.add(k + 8 * j)) });
                    let cv = unsafe { _mm512_loadu_pd(cp.add(k + 8 * j)) };
                    *acc = _mm512_fmadd_pd(xv, cv, *acc);
                }
                k += 32;
            }
            if k + 16 <= n {
                let xv = _mm512_cvtps_pd(unsafe { _mm256_loadu_ps(rp.add(k)) });
                let cv = unsafe { _mm512_loadu_pd(cp.add(k)) };
                a[0] = _mm512_fmadd_pd(xv, cv, a[0]);
                let xv = _mm512_cvtps_pd(unsafe { _mm256_loadu_ps(rp.add(k + 8)) });
                let cv = unsafe { _mm512_loadu_pd(cp.add(k + 8)) };
                a[1] = _mm512_fmadd_pd(xv, cv, a[1]);
                k += 16;
            }
            if k + 8 <= n {
                let xv = _mm512_cvtps_pd(unsafe { _mm256_loadu_ps(rp.add(k)) });
                let cv = unsafe { _mm512_loadu_pd(cp.add(k)) };
                a[2] = _mm512_fmadd_pd(xv, cv, a[2]);
                k += 8;
            }
            if k < n {
                // Masked loads read only lanes k..n; masked-off lanes are zero.
                let m: __mmask8 = (1u8 << (n - k)) - 1;
                let xv = _mm512_cvtps_pd(unsafe { _mm256_maskz_loadu_ps(m, rp.add(k)) });
                let cv = unsafe { _mm512_maskz_loadu_pd(m, cp.add(k)) };
                a[3] = _mm512_fmadd_pd(xv, cv, a[3]);
            }
            let s = _mm512_add_pd(_mm512_add_pd(a[0], a[1]), _mm512_add_pd(a[2], a[3]));
            *o = _mm512_reduce_add_pd(s);
        }
    }

    #[target_feature(enable = "avx2,fma")]
    unsafe fn dots_f32(x: &[f32], stride: usize, c: &[f64], out: &mut [f64]) {
        let n = c.len();
        let cp = c.as_ptr();
        for (i, o) in out.iter_mut().enumerate() {
            let rp = unsafe { x.as_ptr().add(i * stride) };
            let mut a = [_mm256_setzero_pd(); 4];
            let mut k = 0;
            while k + 16 <= n {
                for (j, acc) in a.iter_mut().enumerate() {
                    // 4 f32 widened exactly to f64, then a fused multiply-add in f64.
                    let xv = _mm256_cvtps_pd(unsafe { _mm_loadu_ps(rp.add(k + 4 * j)) });
                    let cv = unsafe { _mm256_loadu_pd(cp.add(k + 4 * j)) };
                    *acc = _mm256_fmadd_pd(xv, cv, *acc);
                }
                k += 16;
            }
            while k + 4 <= n {
                let xv = _mm256_cvtps_pd(unsafe { _mm_loadu_ps(rp.add(k)) });
                let cv = unsafe { _mm256_loadu_pd(cp.add(k)) };
                a[0] = _mm256_fmadd_pd(xv, cv, a[0]);
                k += 4;
            }
            let mut tail = 0.0;
            while k < n {
                tail = unsafe { f64::from(*rp.add(k)).mul_add(*cp.add(k), tail) };
                k += 1;
            }
            let s = _mm256_add_pd(_mm256_add_pd(a[0], a[1]), _mm256_add_pd(a[2], a[3]));
            *o = hsum(s) + tail;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axpy_gives_the_portable_bits_for_all_tails() {
        for n in 0..40 {
            let x: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin()).collect();
            let y0: Vec<f32> = (0..n).map(|i| (i as f32 * 0.11).cos()).collect();
            let (mut y, mut want) = (y0.clone(), y0);
            axpy(&mut y, 0.3, &x);
            axpy_generic(&mut want, 0.3, &x);
            assert_eq!(y, want, "n = {n}");
            assert!(want.iter().zip(&x).all(|(w, _)| w.is_finite()));
        }
        let mut y = vec![1.0f64; 5];
        axpy(&mut y, 2.0, &[1.0, 2.0, 3.0]);
        assert_eq!(y, [3.0, 5.0, 7.0, 1.0, 1.0]);
    }

    #[test]
    fn dot_matches_naive_for_all_tails() {
        for n in 0..70 {
            let row: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
            let c: Vec<f64> = (0..n).map(|i| (i as f64 * 1.3).cos()).collect();
            let naive: f64 = row.iter().zip(&c).map(|(a, b)| a * b).sum();
            // n terms of magnitude ≤ 1: error ≤ n·eps.
            assert!((dot(&row, &c) - naive).abs() <= (n as f64 + 1.0) * f64::EPSILON);
            let generic = dot_generic(&row, &c);
            assert!((generic - naive).abs() <= (n as f64 + 1.0) * f64::EPSILON);
        }
    }

    #[test]
    fn dispatched_kernel_agrees_with_portable_body() {
        // Every tail length and both precisions; the SIMD path reassociates the sum,
        // so agreement is to n·eps of Σ|x·c|, not bit-exact.
        let mut rng = crate::rng::Rng::seed(3);
        for n in 0..90 {
            let stride = n + 3;
            let rows = 5;
            let x64: Vec<f64> = (0..rows * stride).map(|_| rng.range(-1.0, 1.0)).collect();
            let x32: Vec<f32> = x64.iter().map(|&v| v as f32).collect();
            let c: Vec<f64> = (0..n).map(|_| rng.range(-2.0, 2.0)).collect();
            let tol = 2.0 * (n as f64 + 1.0) * f64::EPSILON * 2.0 * n as f64;
            let (mut fast, mut slow) = (vec![0.0; rows], vec![0.0; rows]);
            strided_dots(&x64, stride, &c, &mut fast);
            strided_dots_generic(&x64, stride, &c, &mut slow);
            for (a, b) in fast.iter().zip(&slow) {
                assert!((a - b).abs() <= tol, "f64 n={n}: {a} vs {b}");
            }
            strided_dots(&x32, stride, &c, &mut fast);
            strided_dots_generic(&x32, stride, &c, &mut slow);
            for (a, b) in fast.iter().zip(&slow) {
                assert!((a - b).abs() <= tol, "f32 n={n}: {a} vs {b}");
            }
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
    }
}
