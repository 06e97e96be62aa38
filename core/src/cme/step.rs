//! Time-step control shared by the CME solvers (greedy PGD and tensor-train BDF2).

/// Weights `l_i` of the quadratic through `(t[0..3], P_i)` evaluated at `t[3]`: the
/// BDF2 error estimate is 2/9 of `‖P_3 − Σ l_i P_i‖` (both O(h³)).
pub fn extrapolation_weights(t: &[f64]) -> [f64; 3] {
    let l = |i: usize| -> f64 {
        (0..3)
            .filter(|&j| j != i)
            .map(|j| (t[3] - t[j]) / (t[i] - t[j]))
            .product()
    };
    [l(0), l(1), l(2)]
}

/// The next step after `h` given the relative error estimate `est` of the last one:
/// the cube-root rule (BDF2 is second order), changed by at most ×0.5 … ×growth.
pub fn next_step(h: f64, est: f64, tol: f64, growth: f64, h_min: f64, h_max: f64) -> f64 {
    let factor = if est > 0.0 {
        (0.9 * (tol / est).cbrt()).clamp(0.5, growth)
    } else {
        growth
    };
    (h * factor).clamp(h_min.min(h), h_max)
}
