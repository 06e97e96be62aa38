//! 95 % intervals of fitted rates: by profile likelihood and by Fisher information.
//!
//! **Profile.** For rate `i`, `ℓ_p(θ_i) = max over the other rates of ℓ`; the interval
//! is where `ℓ_p ≥ ℓ̂ − χ²₁(0.95)/2 = ℓ̂ − 1.92` (Wilks). Each end is bracketed by
//! doubling steps away from the maximum and found by regula falsi (Illinois); an end
//! the profile never drops below the threshold before the model's range ends is
//! reported open there: the data do not bound the rate inside the range (both ends
//! open: the rate is unidentifiable, said so, never a tight interval).
//!
//! **Fisher.** The observed information `I = −∇²ℓ(θ̂)` by central differences in the
//! scaled coordinates, steps a quarter of each rate's standard error (found in a first
//! pass), shifted inward at a range end; `Cov = I⁻¹` and `θ̂_i ± 1.96 √Cov_ii`. A
//! matrix that is not positive definite, or a standard error wider than half the range,
//! means a flat direction: no Fisher interval.

use super::optimize::{Objective, nelder_mead};

/// `χ²₁(0.95) / 2`: how far the log-likelihood drops at a 95 % profile interval's ends.
pub const PROFILE_DROP: f64 = 1.920_729_410_347_062;

/// The normal quantile of a two-sided 95 % interval.
pub const Z95: f64 = 1.959_963_984_540_054;

/// A standard error (scaled units) above which a rate counts as unidentifiable.
const FLAT_SE: f64 = 0.5;

/// One end of a profile interval, in scaled units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfileEnd {
    pub u: f64,
    /// The profile stayed above the threshold up to the range's end.
    pub open: bool,
}

/// `ℓ_p` at `x` for rate `i`: the others maximized from `warm` (updated).
fn profile_at(
    f: &mut Objective<'_>,
    u_hat: &[f64],
    i: usize,
    x: f64,
    warm: &mut Vec<f64>,
    step: f64,
    evals: &mut usize,
) -> f64 {
    let d = u_hat.len();
    let mut g = |v: &[f64]| {
        let mut u = Vec::with_capacity(d);
        u.extend_from_slice(&v[..i]);
        u.push(x);
        u.extend_from_slice(&v[i..]);
        f(&u)
    };
    let m = nelder_mead(&mut g, warm, step, 1e-7, 4_000);
    *evals += m.evaluations;
    *warm = m.u;
    m.value
}

/// Both ends of rate `i`'s profile interval around the maximum `u_hat` (value
/// `l_hat`), starting the search at `scale` (an estimate of its standard error).
pub fn profile(
    f: &mut Objective<'_>,
    u_hat: &[f64],
    l_hat: f64,
    i: usize,
    scale: f64,
    evals: &mut usize,
) -> [ProfileEnd; 2] {
    let target = l_hat - PROFILE_DROP;
    let others: Vec<f64> = u_hat
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != i)
        .map(|(_, v)| *v)
        .collect();
    let inner_step = (0.5 * scale).clamp(1e-4, 0.05);
    let mut ends = [ProfileEnd { u: 0.0, open: true }; 2];
    for (end, side) in ends.iter_mut().zip([-1.0, 1.0]) {
        let bound = if side < 0.0 { 0.0 } else { 1.0 };
        let mut warm = others.clone();
        let (mut x_in, mut g_in) = (u_hat[i], PROFILE_DROP);
        let mut s = scale.clamp(1e-4, 0.25);
        // Bracket: the profile above the threshold at x_in, below at x_out.
        let bracket = loop {
            let x = (u_hat[i] + side * s).clamp(0.0, 1.0);
            let g = profile_at(f, u_hat, i, x, &mut warm, inner_step, evals) - target;
            if g < 0.0 {
                break Some((x, g));
            }
            if x == bound {
                break None;
            }
            (x_in, g_in) = (x, g);
            s *= 2.0;
        };
        let Some((mut x_out, mut g_out)) = bracket else {
            *end = ProfileEnd {
                u: bound,
                open: true,
            };
            continue;
        };
        // Illinois: regula falsi that halves a stale end's value.
        let tol = (1e-3 * scale).clamp(1e-7, 1e-4);
        let mut stale = 0i8;
        for _ in 0..60 {
            if (x_out - x_in).abs() < tol {
                break;
            }
            let x = x_in - g_in * (x_out - x_in) / (g_out - g_in);
            let g = profile_at(f, u_hat, i, x, &mut warm, inner_step, evals) - target;
            if g >= 0.0 {
                (x_in, g_in) = (x, g);
                if stale == 1 {
                    g_out *= 0.5;
                }
                stale = 1;
            } else {
                (x_out, g_out) = (x, g);
                if stale == -1 {
                    g_in *= 0.5;
                }
                stale = -1;
            }
        }
        *end = ProfileEnd {
            u: x_in - g_in * (x_out - x_in) / (g_out - g_in),
            open: false,
        };
    }
    ends
}

/// The observed information matrix at `u_hat` (scaled units, row-major), with steps
/// `h` per rate.
fn information(f: &mut Objective<'_>, u_hat: &[f64], h: &[f64], evals: &mut usize) -> Vec<f64> {
    let d = u_hat.len();
    let c: Vec<f64> = u_hat
        .iter()
        .zip(h)
        .map(|(&u, &h)| u.clamp(h, 1.0 - h))
        .collect();
    let mut at = |di: &[(usize, f64)]| {
        let mut u = c.clone();
        for &(i, s) in di {
            u[i] += s;
        }
        *evals += 1;
        f(&u)
    };
    let f0 = at(&[]);
    let mut info = vec![0.0; d * d];
    for i in 0..d {
        let (p, m) = (at(&[(i, h[i])]), at(&[(i, -h[i])]));
        info[i * d + i] = -(p - 2.0 * f0 + m) / (h[i] * h[i]);
        for j in 0..i {
            let pp = at(&[(i, h[i]), (j, h[j])]);
            let pm = at(&[(i, h[i]), (j, -h[j])]);
            let mp = at(&[(i, -h[i]), (j, h[j])]);
            let mm = at(&[(i, -h[i]), (j, -h[j])]);
            let x = -(pp - pm - mp + mm) / (4.0 * h[i] * h[j]);
            info[i * d + j] = x;
            info[j * d + i] = x;
        }
    }
    info
}

/// The inverse of a symmetric positive definite matrix by Cholesky; `None` if it is
/// not positive definite.
pub fn spd_inverse(a: &[f64], d: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; d * d];
    for i in 0..d {
        for j in 0..=i {
            let s = a[i * d + j] - (0..j).map(|k| l[i * d + k] * l[j * d + k]).sum::<f64>();
            if i == j {
                if s.is_nan() || s <= 0.0 || !s.is_finite() {
                    return None;
                }
                l[i * d + i] = s.sqrt();
            } else {
                l[i * d + j] = s / l[j * d + j];
            }
        }
    }
    // Columns of L⁻ᵀ L⁻¹.
    let mut inv = vec![0.0; d * d];
    for col in 0..d {
        let mut y = vec![0.0; d];
        for i in 0..d {
            let b = if i == col { 1.0 } else { 0.0 };
            y[i] = (b - (0..i).map(|k| l[i * d + k] * y[k]).sum::<f64>()) / l[i * d + i];
        }
        for i in (0..d).rev() {
            let s = y[i]
                - (i + 1..d)
                    .map(|k| l[k * d + i] * inv[k * d + col])
                    .sum::<f64>();
            inv[i * d + col] = s / l[i * d + i];
        }
    }
    Some(inv)
}

/// The Fisher covariance (scaled units) at `u_hat`, or `None` for a flat direction;
/// also each rate's standard error where it is finite.
pub fn fisher(f: &mut Objective<'_>, u_hat: &[f64], evals: &mut usize) -> Option<Vec<f64>> {
    let d = u_hat.len();
    // A first pass with small steps finds the scale, a second measures at it.
    let mut h = vec![1e-3; d];
    for _ in 0..2 {
        let info = information(f, u_hat, &h, evals);
        for i in 0..d {
            let curv = info[i * d + i];
            h[i] = if curv > 0.0 {
                (0.25 / curv.sqrt()).clamp(1e-6, 0.05)
            } else {
                0.05
            };
        }
    }
    let info = information(f, u_hat, &h, evals);
    let cov = spd_inverse(&info, d)?;
    if (0..d).any(|i| cov[i * d + i].sqrt() > FLAT_SE) {
        return None;
    }
    Some(cov)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gaussian_likelihood_s_intervals_are_its_exact_ones() {
        // ℓ = −½ (u − m)ᵀ A (u − m): profile and Fisher intervals are m ± 1.96 √(A⁻¹)ᵢᵢ.
        let (m, a) = ([0.4, 0.55], [4.0e4, 1.5e4, 1.5e4, 2.5e4]);
        let mut f = |u: &[f64]| {
            let (x, y) = (u[0] - m[0], u[1] - m[1]);
            -0.5 * (a[0] * x * x + 2.0 * a[1] * x * y + a[3] * y * y)
        };
        let cov = spd_inverse(&a, 2).expect("positive definite");
        let mut evals = 0;
        let fc = fisher(&mut f, &m, &mut evals).expect("curved");
        for i in 0..2 {
            let se = cov[i * 2 + i].sqrt();
            assert!((fc[i * 2 + i].sqrt() / se - 1.0).abs() < 1e-6);
            let ends = profile(&mut f, &m, 0.0, i, se, &mut evals);
            for (e, side) in ends.iter().zip([-1.0, 1.0]) {
                let want = m[i] + side * Z95 * se;
                assert!(!e.open && (e.u - want).abs() < 1e-3 * se, "{e:?} vs {want}");
            }
        }
        // Flat along the second rate: no Fisher interval, an open profile.
        let mut flat = |u: &[f64]| -0.5 * 4.0e4 * (u[0] - 0.4).powi(2);
        assert!(fisher(&mut flat, &[0.4, 0.5], &mut evals).is_none());
        let ends = profile(&mut flat, &[0.4, 0.5], 0.0, 1, 0.01, &mut evals);
        assert!(ends.iter().all(|e| e.open), "{ends:?}");
        assert_eq!((ends[0].u, ends[1].u), (0.0, 1.0));
    }
}
