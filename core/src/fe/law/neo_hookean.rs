//! Compressible neo-Hookean: `W = μ/2 (tr C − 3) − μ ln J + λ/2 (ln J)²`, so
//!
//! ```text
//! S = μ (I − C⁻¹) + λ ln J C⁻¹,
//! ℂ = λ C⁻¹⊗C⁻¹ + 2(μ − λ ln J) 𝕀_{C⁻¹},   𝕀_{C⁻¹} : X = C⁻¹ X C⁻¹ for symmetric X
//! ```
//!
//! The usual soft-tissue choice for deep presses: its energy grows without bound as the
//! volume goes to zero (`ln J → −∞`). A point with `J ≤ 0` (an inverted element) gets
//! a non-finite stress, which the Newton line search rejects. Along a depth series,
//! `J = det F` is formed as Cauchy products of the entries' series, `ln J` from
//! `(ln J)' = J'/J`, and `C⁻¹` from `C Y = I` order by order.

use super::super::m3::{ID, M3, PERMS, ZERO, add_scaled, add_upper, det, inverse, mul};
use super::super::m3v::{self, L, M3V, ONE, SUM0, V, ZV, det_v, lane};
use super::{HyperLaw, PointState};

/// Compressible neo-Hookean.
pub(crate) struct NeoHookean;

impl HyperLaw for NeoHookean {
    #[inline(always)]
    fn state(f: &M3, c: &M3, lambda: f64, mu: f64) -> PointState {
        let j = det(f);
        if j.is_nan() || j <= 0.0 {
            return PointState {
                s: [[f64::NAN; 3]; 3],
                c_inv: [[f64::NAN; 3]; 3],
                shear: f64::NAN,
            };
        }
        let ln_j = j.ln();
        let ci = inverse(c, j * j);
        let mut s = [[0.0; 3]; 3];
        for a in 0..3 {
            for b in 0..3 {
                let id = if a == b { 1.0 } else { 0.0 };
                s[a][b] = mu * (id - ci[a][b]) + lambda * ln_j * ci[a][b];
            }
        }
        PointState {
            s,
            c_inv: ci,
            shear: mu - lambda * ln_j,
        }
    }

    #[inline(always)]
    fn linearize(st: &PointState, d: &M3, lin: &mut f64, cde: &mut M3) {
        let ci = &st.c_inv;
        *lin = (0..3)
            .flat_map(|x| (0..3).map(move |y| (x, y)))
            .map(|(x, y)| ci[x][y] * d[x][y])
            .sum();
        for x in 0..3 {
            for y in 0..3 {
                cde[x][y] = (0..3).map(|z| ci[x][z] * d[z][y]).sum();
            }
        }
    }

    #[inline(always)]
    fn contract(_dr: &M3, cr: &M3, _dc: &M3, cc: &M3, dd: &mut f64) {
        for x in 0..3 {
            for y in 0..3 {
                *dd += cr[x][y] * cc[y][x];
            }
        }
    }

    #[inline(always)]
    fn stress_series<const N: usize>(
        f: &[M3],
        c: &[M3; N],
        p: usize,
        lambda: f64,
        mu: f64,
        s: &mut [M3],
    ) {
        // J = det F: each permutation's product of three entry series, as two
        // Cauchy products (the first two rows' entries, then the third's): O(p²)
        // a permutation where the triple sum is O(p³).
        let mut jac = [0.0; N];
        let mut pair = [0.0; N];
        for (perm, sign) in PERMS {
            for (k, q) in pair.iter_mut().enumerate().take(p + 1) {
                *q = (0..=k)
                    .map(|a| f[a][0][perm[0]] * f[k - a][1][perm[1]])
                    .sum();
            }
            for (k, jk) in jac.iter_mut().enumerate().take(p + 1) {
                let sum: f64 = (0..=k).map(|m| pair[m] * f[k - m][2][perm[2]]).sum();
                *jk += sign * sum;
            }
        }
        if jac[0].is_nan() || jac[0] <= 0.0 {
            // An inverted expansion point: no series (the Newton reference rejects
            // the same state).
            s[..=p].fill([[f64::NAN; 3]; 3]);
            return;
        }
        // (ln J)' = J'/J: k L_k J_0 = k J_k − Σ_{m=1..k−1} m L_m J_{k−m}.
        let mut ln_j = [jac[0].ln(); N];
        for k in 1..=p {
            let sum: f64 = (1..k).map(|m| m as f64 * ln_j[m] * jac[k - m]).sum();
            ln_j[k] = (jac[k] - sum / k as f64) / jac[0];
        }
        // C Y = I: Y_0 = C_0⁻¹, Y_k = −Y_0 Σ_{i=1..k} C_i Y_{k−i}. Every Y_k is
        // symmetric (C⁻¹ is, for every depth); about the rest state Y_0 = I, so the
        // sum is −Y_k and only its upper triangle is formed.
        let at_rest = c[0] == ID;
        let mut y = [ZERO; N];
        y[0] = if at_rest {
            ID
        } else {
            inverse(&c[0], det(&c[0]))
        };
        for k in 1..=p {
            let mut acc = ZERO;
            if at_rest {
                for i in 1..=k {
                    add_upper(&mut acc, &c[i], &y[k - i]);
                }
            } else {
                for i in 1..=k {
                    add_scaled(&mut acc, 1.0, &mul(&c[i], &y[k - i]));
                }
                acc = mul(&y[0], &acc);
            }
            for a in 0..3 {
                for b in a..3 {
                    y[k][a][b] = -acc[a][b];
                    y[k][b][a] = -acc[a][b];
                }
            }
        }
        for (k, sk) in s.iter_mut().enumerate().take(p + 1) {
            *sk = ZERO;
            add_scaled(sk, -mu, &y[k]);
            if k == 0 {
                add_scaled(sk, mu, &ID);
            }
            for m in 0..=k {
                add_scaled(sk, lambda * ln_j[m], &y[k - m]);
            }
        }
    }

    #[inline(always)]
    fn state_v(f: &M3V, c: &M3V, lambda: f64, mu: f64, s: &mut M3V, ci: &mut M3V, shear: &mut V) {
        let j = det_v(f);
        let ln_j: V = std::array::from_fn(|l| j[l].ln());
        for l in 0..L {
            let d = j[l] * j[l];
            for a in 0..3 {
                for b in 0..3 {
                    let (a1, a2) = ((b + 1) % 3, (b + 2) % 3);
                    let (b1, b2) = ((a + 1) % 3, (a + 2) % 3);
                    ci[a][b][l] = (c[a1][b1][l] * c[a2][b2][l] - c[a1][b2][l] * c[a2][b1][l]) / d;
                }
            }
            for a in 0..3 {
                for b in 0..3 {
                    let id = if a == b { 1.0 } else { 0.0 };
                    s[a][b][l] = mu * (id - ci[a][b][l]) + lambda * ln_j[l] * ci[a][b][l];
                }
            }
            shear[l] = mu - lambda * ln_j[l];
            if j[l].is_nan() || j[l] <= 0.0 {
                for (sr, cr) in s.iter_mut().zip(ci.iter_mut()) {
                    for (sv, cv) in sr.iter_mut().zip(cr.iter_mut()) {
                        sv[l] = f64::NAN;
                        cv[l] = f64::NAN;
                    }
                }
                shear[l] = f64::NAN;
            }
        }
    }

    #[inline(always)]
    fn linearize_v(ci: &M3V, d: &M3V, lin: &mut V, cde: &mut M3V) {
        let mut acc = SUM0;
        for x in 0..3 {
            for y in 0..3 {
                for q in 0..L {
                    acc[q] += ci[x][y][q] * d[x][y][q];
                }
            }
        }
        *lin = acc;
        for x in 0..3 {
            for y in 0..3 {
                for q in 0..L {
                    cde[x][y][q] = ci[x][0][q] * d[0][y][q]
                        + ci[x][1][q] * d[1][y][q]
                        + ci[x][2][q] * d[2][y][q];
                }
            }
        }
    }

    #[inline(always)]
    fn contract_v(_dr: &M3V, cr: &M3V, _dc: &M3V, cc: &M3V, dd: &mut V) {
        for x in 0..3 {
            for y in 0..3 {
                for q in 0..L {
                    dd[q] += cr[x][y][q] * cc[y][x][q];
                }
            }
        }
    }

    #[inline(always)]
    fn stress_series_v<const N: usize>(
        f: &[M3V; N],
        c: &[M3V; N],
        p: usize,
        lambda: f64,
        mu: f64,
        s: &mut [M3V; N],
    ) {
        let mut jac = [ZV; N];
        let mut pair = [ZV; N];
        for (perm, sign) in PERMS {
            for (k, q) in pair.iter_mut().enumerate().take(p + 1) {
                *q = SUM0;
                for a in 0..=k {
                    for l in 0..L {
                        q[l] += f[a][0][perm[0]][l] * f[k - a][1][perm[1]][l];
                    }
                }
            }
            for (k, jk) in jac.iter_mut().enumerate().take(p + 1) {
                let mut sum = SUM0;
                for m in 0..=k {
                    for l in 0..L {
                        sum[l] += pair[m][l] * f[k - m][2][perm[2]][l];
                    }
                }
                for l in 0..L {
                    jk[l] += sign * sum[l];
                }
            }
        }
        let inverted: [bool; L] = std::array::from_fn(|l| jac[0][l].is_nan() || jac[0][l] <= 0.0);
        let mut ln_j = [ZV; N];
        let ln0: V = std::array::from_fn(|l| jac[0][l].ln());
        ln_j.fill(ln0);
        for k in 1..=p {
            let mut sum = SUM0;
            for m in 1..k {
                for l in 0..L {
                    sum[l] += m as f64 * ln_j[m][l] * jac[k - m][l];
                }
            }
            for l in 0..L {
                ln_j[k][l] = (jac[k][l] - sum[l] / k as f64) / jac[0][l];
            }
        }
        let at_rest = c[0] == m3v::ID;
        let mut y = [m3v::ZERO; N];
        y[0] = if at_rest {
            m3v::ID
        } else {
            let mut y0 = m3v::ZERO;
            for l in 0..L {
                let c0 = lane(&c[0], l);
                let inv = inverse(&c0, det(&c0));
                for i in 0..3 {
                    for j in 0..3 {
                        y0[i][j][l] = inv[i][j];
                    }
                }
            }
            y0
        };
        for k in 1..=p {
            let mut acc = m3v::ZERO;
            if at_rest {
                for i in 1..=k {
                    m3v::add_upper(&mut acc, &c[i], &y[k - i]);
                }
            } else {
                for i in 1..=k {
                    m3v::add_scaled(&mut acc, &ONE, &m3v::mul(&c[i], &y[k - i]));
                }
                acc = m3v::mul(&y[0], &acc);
            }
            for a in 0..3 {
                for b in a..3 {
                    for l in 0..L {
                        y[k][a][b][l] = -acc[a][b][l];
                        y[k][b][a][l] = -acc[a][b][l];
                    }
                }
            }
        }
        let mmu: V = [-mu; L];
        let pmu: V = [mu; L];
        for (k, sk) in s.iter_mut().enumerate().take(p + 1) {
            *sk = m3v::ZERO;
            m3v::add_scaled(sk, &mmu, &y[k]);
            if k == 0 {
                m3v::add_scaled(sk, &pmu, &m3v::ID);
            }
            for m in 0..=k {
                let lj: V = std::array::from_fn(|l| lambda * ln_j[m][l]);
                m3v::add_scaled(sk, &lj, &y[k - m]);
            }
        }
        for (l, _) in inverted.iter().enumerate().filter(|(_, bad)| **bad) {
            for sk in s.iter_mut().take(p + 1) {
                for row in sk.iter_mut() {
                    for v in row.iter_mut() {
                        v[l] = f64::NAN;
                    }
                }
            }
        }
    }
}
