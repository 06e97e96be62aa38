//! Saint Venant–Kirchhoff: `W = λ/2 (tr E)² + μ E:E`, so
//!
//! ```text
//! S = λ tr(E) I + 2μ E,        ℂ = λ I⊗I + 2μ 𝕀
//! ```
//!
//! with the Green strain `E = ½(C − I)`. The paper's liver law. Its energy stays finite
//! as the volume goes to zero, so it loses stability in strong compression. Along a
//! depth series `C = Σ_k a^k C_k`, `E_0 = ½(C_0 − I)`, `E_k = ½ C_k`, and `S` is linear
//! in `E`: each order's stress is that order's strain's.

use super::super::m3::M3;
use super::super::m3v::{L, M3V, V};
use super::{HyperLaw, PointState};

/// Saint Venant–Kirchhoff.
pub(crate) struct Svk;

impl HyperLaw for Svk {
    #[inline(always)]
    fn state(_f: &M3, c: &M3, lambda: f64, mu: f64) -> PointState {
        let tr = 0.5 * (c[0][0] + c[1][1] + c[2][2] - 3.0);
        let mut s = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                let e = 0.5 * (c[i][j] - if i == j { 1.0 } else { 0.0 });
                s[i][j] = 2.0 * mu * e + if i == j { lambda * tr } else { 0.0 };
            }
        }
        PointState {
            s,
            c_inv: [[0.0; 3]; 3],
            shear: mu,
        }
    }

    #[inline(always)]
    fn linearize(_st: &PointState, d: &M3, lin: &mut f64, _cde: &mut M3) {
        *lin = d[0][0] + d[1][1] + d[2][2];
    }

    #[inline(always)]
    fn contract(dr: &M3, _cr: &M3, dc: &M3, _cc: &M3, dd: &mut f64) {
        for x in 0..3 {
            for y in 0..3 {
                *dd += dr[x][y] * dc[x][y];
            }
        }
    }

    #[inline(always)]
    fn stress_series<const N: usize>(
        _f: &[M3],
        c: &[M3; N],
        p: usize,
        lambda: f64,
        mu: f64,
        s: &mut [M3],
    ) {
        for (k, (sk, ck)) in s.iter_mut().zip(c).take(p + 1).enumerate() {
            // E_0 = ½(C_0 − I), E_k = ½ C_k.
            let mut e = *ck;
            if k == 0 {
                for (i, row) in e.iter_mut().enumerate() {
                    row[i] -= 1.0;
                }
            }
            let tr = 0.5 * (e[0][0] + e[1][1] + e[2][2]);
            for i in 0..3 {
                for j in 0..3 {
                    sk[i][j] = mu * e[i][j] + if i == j { lambda * tr } else { 0.0 };
                }
            }
        }
    }

    #[inline(always)]
    fn state_v(
        _f: &M3V,
        c: &M3V,
        lambda: f64,
        mu: f64,
        s: &mut M3V,
        _ci: &mut M3V,
        _shear: &mut V,
    ) {
        for l in 0..L {
            let tr = 0.5 * (c[0][0][l] + c[1][1][l] + c[2][2][l] - 3.0);
            for i in 0..3 {
                for j in 0..3 {
                    let e = 0.5 * (c[i][j][l] - if i == j { 1.0 } else { 0.0 });
                    s[i][j][l] = 2.0 * mu * e + if i == j { lambda * tr } else { 0.0 };
                }
            }
        }
    }

    #[inline(always)]
    fn linearize_v(_ci: &M3V, d: &M3V, lin: &mut V, _cde: &mut M3V) {
        for q in 0..L {
            lin[q] = d[0][0][q] + d[1][1][q] + d[2][2][q];
        }
    }

    #[inline(always)]
    fn contract_v(dr: &M3V, _cr: &M3V, dc: &M3V, _cc: &M3V, dd: &mut V) {
        for x in 0..3 {
            for y in 0..3 {
                for q in 0..L {
                    dd[q] += dr[x][y][q] * dc[x][y][q];
                }
            }
        }
    }

    #[inline(always)]
    fn stress_series_v<const N: usize>(
        _f: &[M3V; N],
        c: &[M3V; N],
        p: usize,
        lambda: f64,
        mu: f64,
        s: &mut [M3V; N],
    ) {
        for (k, (sk, ck)) in s.iter_mut().zip(c).take(p + 1).enumerate() {
            let mut e = *ck;
            if k == 0 {
                for (i, row) in e.iter_mut().enumerate() {
                    for l in 0..L {
                        row[i][l] -= 1.0;
                    }
                }
            }
            for l in 0..L {
                let tr = 0.5 * (e[0][0][l] + e[1][1][l] + e[2][2][l]);
                for i in 0..3 {
                    for j in 0..3 {
                        sk[i][j][l] = mu * e[i][j][l] + if i == j { lambda * tr } else { 0.0 };
                    }
                }
            }
        }
    }
}
