//! On-line evaluation: particularization, reconstruction, truncation, subsets, clamping.

use palpa_core::axis::Discretization;
use palpa_core::{EvalError, ParamValue, Scalar, SeparatedModel};
use palpa_tests::small_model;
use proptest::prelude::*;

/// Naive `Σ_{k<n} X[r,k] · c_k`, summed in f64 in index order.
fn naive_row<T: Scalar>(m: &SeparatedModel<T>, r: usize, c: &[f64]) -> f64 {
    let x = m.spatial();
    c.iter()
        .enumerate()
        .map(|(k, ck)| x[r * m.modes() + k].to_f64() * ck)
        .sum()
}

/// Naive coefficient of mode k: product over axes of the interpolated nodal values.
fn naive_coeff<T: Scalar>(m: &SeparatedModel<T>, values: &[ParamValue], k: usize) -> f64 {
    m.axes()
        .iter()
        .zip(values)
        .map(|(a, &v)| {
            let s = a.info.discretization.stencil(v).expect("valid");
            (0..s.len)
                .map(|i| s.weights[i] * a.values()[s.nodes[i] as usize * m.modes() + k].to_f64())
                .sum::<f64>()
        })
        .product()
}

fn point(tri: u32, a: f64, b: f64) -> ParamValue {
    ParamValue::Surface {
        triangle: tri,
        bary: [a, b, 1.0 - a - b],
    }
}

#[test]
fn particularize_matches_the_separated_formula() {
    let m = small_model::<f64>(30, 9, 4);
    let values = [
        point(5, 0.2, 0.3),
        ParamValue::Scalar(1.7),
        ParamValue::Mix([0.6, 0.0, 0.8]),
    ];
    let mut c = vec![0.0; 9];
    let report = m.particularize(&values, &mut c).expect("valid");
    assert!(!report.any());
    for (k, ck) in c.iter().enumerate() {
        let want = naive_coeff(&m, &values, k);
        // Three axes of three-term sums of O(1) values: a handful of ulps.
        assert!(
            (ck - want).abs() <= 16.0 * f64::EPSILON,
            "mode {k}: {ck} vs {want}"
        );
    }
}

#[test]
fn truncation_equals_the_sum_of_the_first_n_terms() {
    let m = small_model::<f64>(50, 12, 5);
    let values = [
        point(2, 0.5, 0.25),
        ParamValue::Scalar(4.0),
        ParamValue::Index(2),
    ];
    let mut full_c = vec![0.0; 12];
    m.particularize(&values, &mut full_c).expect("valid");
    for n in [0, 1, 5, 11, 12] {
        let mut c = vec![0.0; n];
        m.particularize(&values, &mut c).expect("valid");
        assert_eq!(c[..], full_c[..n], "truncated coefficients are a prefix");
        let mut u = vec![0.0; m.rows()];
        m.reconstruct(&c, &mut u);
        let truncated = m.truncated(n).expect("n ≤ N");
        let mut ut = vec![0.0; m.rows()];
        truncated.reconstruct(&c, &mut ut);
        for r in 0..m.rows() {
            let want = naive_row(&m, r, &c);
            // n terms of magnitude ≤ 3 (|x| ≤ 1, |c| ≤ 3): n·eps·3 with margin.
            let tol = 8.0 * (n as f64 + 1.0) * f64::EPSILON * 3.0;
            assert!(
                (u[r] - want).abs() <= tol,
                "n={n} row {r}: {} vs {want}",
                u[r]
            );
            assert_eq!(u[r], ut[r], "the truncated model evaluates identically");
        }
    }
}

#[test]
fn subsets_equal_the_same_rows_of_the_full_reconstruction() {
    let m = small_model::<f32>(40, 17, 6);
    let values = [
        point(7, 0.1, 0.1),
        ParamValue::Scalar(0.3),
        ParamValue::Index(0),
    ];
    let mut c = vec![0.0; 17];
    m.particularize(&values, &mut c).expect("valid");
    let mut full = vec![0.0; m.rows()];
    m.reconstruct(&c, &mut full);

    let rows = [0u32, 5, 6, 7, 119, 3, 3];
    let mut sub = vec![0.0; rows.len()];
    m.reconstruct_rows(&rows, &c, &mut sub);
    for (i, &r) in rows.iter().enumerate() {
        assert_eq!(sub[i], full[r as usize]);
    }

    // The 3 rows of one node: what the force loop evaluates.
    let mut contact = [0.0; 3];
    m.reconstruct_range(3 * 13, &c, &mut contact);
    assert_eq!(contact[..], full[39..42]);

    // A node subset model (what export-scene keeps) evaluates to the same rows.
    let nodes = [13u32, 2, 39];
    let surface = m.select_nodes(&nodes).expect("nodes exist");
    assert_eq!(surface.field().node_ids, vec![13, 2, 39]);
    let mut su = vec![0.0; 9];
    surface.reconstruct(&c, &mut su);
    for (i, &nd) in nodes.iter().enumerate() {
        assert_eq!(
            su[3 * i..3 * i + 3],
            full[3 * nd as usize..3 * nd as usize + 3]
        );
    }
}

#[test]
fn interpolation_is_exact_on_data_linear_in_the_parameters() {
    // Axis values linear in the parameter (force: a + b·F; surface: linear in x, y):
    // the interpolated model must reproduce them exactly between nodes.
    let base = small_model::<f64>(4, 2, 7);
    let mut meta = base.meta();
    let forces = [0.0, 1.0, 2.5, 6.0];
    let verts = match &meta.axes[0].discretization {
        Discretization::Surface { vertices, .. } => vertices.clone(),
        _ => unreachable!(),
    };
    let surf: Vec<f64> = verts
        .iter()
        .flat_map(|v| [1.0 + 0.5 * v[0] - 0.25 * v[1], 2.0 - v[0]])
        .collect();
    let force: Vec<f64> = forces
        .iter()
        .flat_map(|f| [3.0 * f - 1.0, 0.5 + f])
        .collect();
    let dir: Vec<f64> = vec![1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
    meta.tradeoff.clear();
    let m = SeparatedModel::new(
        meta,
        base.rows(),
        2,
        base.spatial().to_vec(),
        vec![surf, force, dir],
    )
    .expect("shapes");
    let triangles = match &m.axes()[0].info.discretization {
        Discretization::Surface { triangles, .. } => triangles.clone(),
        _ => unreachable!(),
    };
    let mut c = [0.0; 2];
    for (t, tri) in triangles.iter().enumerate() {
        let bary = [0.2, 0.45, 0.35];
        let p: [f64; 2] = [0, 1].map(|d| (0..3).map(|i| bary[i] * verts[tri[i] as usize][d]).sum());
        for f in [0.0, 0.4, 1.0, 2.2, 5.9, 6.0] {
            m.particularize(
                &[
                    ParamValue::Surface {
                        triangle: t as u32,
                        bary,
                    },
                    ParamValue::Scalar(f),
                    ParamValue::Index(1),
                ],
                &mut c,
            )
            .expect("valid");
            let want0 = (1.0 + 0.5 * p[0] - 0.25 * p[1]) * (3.0 * f - 1.0);
            let want1 = (2.0 - p[0]) * (0.5 + f);
            // Values up to ~10 × 20: a few ulps of 200.
            assert!(
                (c[0] - want0).abs() < 1e-12 && (c[1] - want1).abs() < 1e-12,
                "t={t} f={f}"
            );
        }
    }
}

#[test]
fn out_of_range_values_are_clamped_and_flagged() {
    let m = small_model::<f64>(10, 4, 8);
    let inside = [
        point(0, 0.2, 0.2),
        ParamValue::Scalar(6.0),
        ParamValue::Index(2),
    ];
    let outside = [
        point(0, 0.2, 0.2),
        ParamValue::Scalar(60.0),
        ParamValue::Index(7),
    ];
    let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
    assert!(!m.particularize(&inside, &mut a).expect("ok").any());
    let report = m
        .particularize(&outside, &mut b)
        .expect("clamped, not refused");
    assert_eq!(report.axes().collect::<Vec<_>>(), vec![1, 2]);
    assert_eq!(a, b, "clamped to the last trained value, not extrapolated");

    let off_surface = [
        point(0, 1.5, 0.2),
        ParamValue::Scalar(1.0),
        ParamValue::Index(0),
    ];
    let r = m.particularize(&off_surface, &mut b).expect("clamped");
    assert!(r.axis(0) && !r.axis(1));
}

#[test]
fn bad_requests_are_errors_not_nans() {
    let m = small_model::<f64>(10, 4, 9);
    let mut c = [0.0; 4];
    let nan = [
        point(0, 0.2, 0.2),
        ParamValue::Scalar(f64::NAN),
        ParamValue::Index(0),
    ];
    assert!(matches!(
        m.particularize(&nan, &mut c),
        Err(EvalError::Axis { axis: 1, .. })
    ));
    let short = [point(0, 0.2, 0.2)];
    assert!(matches!(
        m.particularize(&short, &mut c),
        Err(EvalError::ParamCount { .. })
    ));
    let mut too_many = [0.0; 5];
    let ok = [
        point(0, 0.2, 0.2),
        ParamValue::Scalar(1.0),
        ParamValue::Index(0),
    ];
    assert!(matches!(
        m.particularize(&ok, &mut too_many),
        Err(EvalError::TooManyModes {
            requested: 5,
            available: 4
        })
    ));
    let wrong_kind = [
        ParamValue::Scalar(1.0),
        ParamValue::Scalar(1.0),
        ParamValue::Index(0),
    ];
    let e = m
        .particularize(&wrong_kind, &mut c)
        .expect_err("wrong kind");
    assert!(
        e.to_string().contains("probe position"),
        "the axis is named: {e}"
    );
    assert!(m.truncated(5).is_err());
}

/// Evaluates `m64` and its f32 conversion at `values`: the f64 coefficients, then the
/// full field from each.
fn evaluate_f64_and_f32(
    m64: &SeparatedModel<f64>,
    values: &[ParamValue],
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let m32: SeparatedModel<f32> = m64.convert();
    let n = m64.modes();
    let (mut c64, mut c32) = (vec![0.0; n], vec![0.0; n]);
    m64.particularize(values, &mut c64).expect("valid");
    m32.particularize(values, &mut c32).expect("valid");
    let (mut u64_, mut u32_) = (vec![0.0; m64.rows()], vec![0.0; m64.rows()]);
    m64.reconstruct(&c64, &mut u64_);
    m32.reconstruct(&c32, &mut u32_);
    (c64, u64_, u32_)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(12), ..ProptestConfig::default() })]

    /// An f32 model evaluates to its f64 original within the f32 storage rounding:
    /// |Δu| ≤ 2·2⁻²⁴ · Σ_k |X c| (storage of X and of the axis values, f64 accumulation).
    #[test]
    fn f32_storage_loses_only_storage_precision(seed in 0u64..10_000, n in 1usize..60,
                                                a in 0.0f64..1.0, f in -1.0f64..7.0) {
        let m64 = small_model::<f64>(16, n, seed);
        let values = [point(3, a * 0.5, 0.5 - a * 0.5), ParamValue::Scalar(f), ParamValue::Mix([0.3, 0.4, 0.5])];
        let (c64, u64_, u32_) = evaluate_f64_and_f32(&m64, &values);
        for r in 0..m64.rows() {
            let scale: f64 = (0..n).map(|k| (m64.spatial()[r * n + k] * c64[k]).abs()).sum();
            // 2⁻²⁴ per stored factor: X and one per axis (3 axes) → 4 roundings; ×2 margin.
            let tol = 8.0 * 2f64.powi(-24) * scale + 1e-300;
            prop_assert!((u64_[r] - u32_[r]).abs() <= tol, "row {}: {} vs {}", r, u64_[r], u32_[r]);
        }
    }
}

/// f32 against f64 evaluation from 10 to 1000 modes: the error stays within the
/// storage rounding bound of each row's Σ_k |X c| at every mode count (the sums run in
/// f64, so the error does not grow with the count beyond that scale). Figures:
/// `cargo test -p palpa-tests f32_error_at_1000 -- --nocapture`.
#[test]
fn f32_error_at_1000_modes_stays_at_storage_rounding() {
    let values = [
        point(3, 0.2, 0.3),
        ParamValue::Scalar(2.5),
        ParamValue::Mix([0.3, 0.4, 0.5]),
    ];
    for n in [10, 100, 1000] {
        let m64 = small_model::<f64>(30, n, 77);
        let (c64, u64_, u32_) = evaluate_f64_and_f32(&m64, &values);
        let (mut worst_rel_scale, mut worst_rel_value) = (0.0f64, 0.0f64);
        for r in 0..m64.rows() {
            let scale: f64 = (0..n)
                .map(|k| (m64.spatial()[r * n + k] * c64[k]).abs())
                .sum();
            let d = (u64_[r] - u32_[r]).abs();
            assert!(d <= 8.0 * 2f64.powi(-24) * scale + 1e-300, "n {n} row {r}");
            worst_rel_scale = worst_rel_scale.max(d / scale);
            worst_rel_value = worst_rel_value.max(d / u64_[r].abs().max(1e-300));
        }
        eprintln!(
            "modes {n}: |Δu| / Σ|Xc| ≤ {worst_rel_scale:.2e}, |Δu| / |u| ≤ {worst_rel_value:.2e}"
        );
    }
}
