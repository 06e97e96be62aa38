//! Maximizing a log-likelihood over a box of rates: a coarse grid for the start, then
//! Nelder–Mead in the unit cube.
//!
//! The rates are scaled to `u ∈ [0, 1]^d` (`θ = lo + u (hi − lo)`), so one tolerance
//! serves every rate. A meta-model's likelihood is piecewise smooth in `θ` (cubic
//! Lagrange pieces between grid nodes), so a method without derivatives suits it; the
//! simplex is clamped to the cube and restarted at its best point until a restart no
//! longer moves it, the usual guard against a collapsed simplex.

/// A function of scaled coordinates `u ∈ [0, 1]^d`, to maximize.
pub type Objective<'a> = dyn FnMut(&[f64]) -> f64 + 'a;

/// The maximum found, its value, and the evaluations spent.
#[derive(Debug, Clone, PartialEq)]
pub struct Maximum {
    pub u: Vec<f64>,
    pub value: f64,
    pub evaluations: usize,
}

/// Nelder–Mead from `start` with an initial simplex of side `step`, until the simplex
/// is smaller than `tol` in every coordinate (or `max_evals`).
pub fn nelder_mead(
    f: &mut Objective<'_>,
    start: &[f64],
    step: f64,
    tol: f64,
    max_evals: usize,
) -> Maximum {
    let d = start.len();
    let clamp = |x: &mut Vec<f64>| x.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
    let mut evals = 0;
    let mut eval = |x: &[f64], evals: &mut usize| {
        *evals += 1;
        let v = f(x);
        if v.is_nan() { f64::NEG_INFINITY } else { v }
    };
    if d == 0 {
        let value = eval(start, &mut evals);
        return Maximum {
            u: Vec::new(),
            value,
            evaluations: evals,
        };
    }
    let mut best = start.to_vec();
    let mut step = step;
    loop {
        // Simplex around `best`; an edge that would leave the cube goes the other way.
        let mut pts: Vec<Vec<f64>> = vec![best.clone()];
        for i in 0..d {
            let mut p = best.clone();
            p[i] += if p[i] + step <= 1.0 { step } else { -step };
            clamp(&mut p);
            pts.push(p);
        }
        let mut vals: Vec<f64> = pts.iter().map(|p| eval(p, &mut evals)).collect();
        while evals < max_evals {
            // Order best first.
            let mut idx: Vec<usize> = (0..=d).collect();
            idx.sort_by(|&a, &b| vals[b].total_cmp(&vals[a]));
            pts = idx.iter().map(|&i| pts[i].clone()).collect();
            vals = idx.iter().map(|&i| vals[i]).collect();
            let size = (0..d)
                .map(|i| {
                    pts.iter()
                        .map(|p| (p[i] - pts[0][i]).abs())
                        .fold(0.0, f64::max)
                })
                .fold(0.0, f64::max);
            if size < tol {
                break;
            }
            let centroid: Vec<f64> = (0..d)
                .map(|i| pts[..d].iter().map(|p| p[i]).sum::<f64>() / d as f64)
                .collect();
            let along = |s: f64| -> Vec<f64> {
                let mut x: Vec<f64> = centroid
                    .iter()
                    .zip(&pts[d])
                    .map(|(c, w)| c + s * (c - w))
                    .collect();
                x.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
                x
            };
            let r = along(1.0);
            let fr = eval(&r, &mut evals);
            if fr > vals[0] {
                let e = along(2.0);
                let fe = eval(&e, &mut evals);
                (pts[d], vals[d]) = if fe > fr { (e, fe) } else { (r, fr) };
            } else if fr > vals[d - 1] {
                (pts[d], vals[d]) = (r, fr);
            } else {
                let c = if fr > vals[d] {
                    along(0.5)
                } else {
                    along(-0.5)
                };
                let fc = eval(&c, &mut evals);
                if fc > vals[d].max(fr) {
                    (pts[d], vals[d]) = (c, fc);
                } else {
                    // Shrink towards the best.
                    for k in 1..=d {
                        let p: Vec<f64> = pts[k]
                            .iter()
                            .zip(&pts[0])
                            .map(|(x, b)| b + 0.5 * (x - b))
                            .collect();
                        vals[k] = eval(&p, &mut evals);
                        pts[k] = p;
                    }
                }
            }
        }
        let i = (0..=d)
            .max_by(|&a, &b| vals[a].total_cmp(&vals[b]))
            .unwrap_or(0);
        let moved = pts[i]
            .iter()
            .zip(&best)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        best = pts[i].clone();
        let value = vals[i];
        if moved <= 10.0 * tol || evals >= max_evals {
            return Maximum {
                u: best,
                value,
                evaluations: evals,
            };
        }
        step = (10.0 * moved).min(step);
    }
}

/// The best of a `points^d` grid over the cube (cell centres), the start that keeps
/// the simplex from a far local maximum.
pub fn grid_start(f: &mut Objective<'_>, d: usize, points: usize) -> Maximum {
    let mut best = Maximum {
        u: vec![0.5; d],
        value: f64::NEG_INFINITY,
        evaluations: 0,
    };
    let total = points.pow(d as u32);
    for k in 0..total {
        let mut rest = k;
        let u: Vec<f64> = (0..d)
            .map(|_| {
                let j = rest % points;
                rest /= points;
                (j as f64 + 0.5) / points as f64
            })
            .collect();
        let v = f(&u);
        best.evaluations += 1;
        if v > best.value {
            best.value = v;
            best.u = u;
        }
    }
    best
}

/// The maximum over the cube: a grid start, then Nelder–Mead to `tol`.
pub fn maximize(f: &mut Objective<'_>, d: usize, tol: f64) -> Maximum {
    let points = match d {
        0 | 1 => 9,
        2 => 7,
        3 => 5,
        _ => 3,
    };
    let start = grid_start(f, d, points);
    let mut m = nelder_mead(f, &start.u, 0.5 / points as f64, tol, 20_000);
    m.evaluations += start.evaluations;
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simplex_finds_a_tilted_quadratic_s_peak_and_one_on_the_cube_s_face() {
        let mut f = |u: &[f64]| {
            let (x, y) = (u[0] - 0.3, u[1] - 0.71);
            -(40.0 * x * x + 30.0 * x * y + 90.0 * y * y)
        };
        let m = maximize(&mut f, 2, 1e-8);
        assert!(
            (m.u[0] - 0.3).abs() < 1e-6 && (m.u[1] - 0.71).abs() < 1e-6,
            "{m:?}"
        );
        // The peak beyond the cube: the maximum sits on its face.
        let mut g = |u: &[f64]| -((u[0] - 1.4).powi(2) + (u[1] - 0.2).powi(2));
        let m = maximize(&mut g, 2, 1e-8);
        assert!(
            (m.u[0] - 1.0).abs() < 1e-9 && (m.u[1] - 0.2).abs() < 1e-6,
            "{m:?}"
        );
    }
}
