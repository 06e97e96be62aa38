//! The CME by PGD: against closed forms (a parameter as a coordinate) and exact FSP
//! (the toggle switch), the meta-model file round trip, and the evaluator's errors.

use palpa_core::cme::model::{CmeModel, CmeModelError};
use palpa_core::cme::moments::l1;
use palpa_core::cme::network::Network;
use palpa_core::cme::{fsp, greedy};
use palpa_core::file;
use palpa_tests::poisson;

/// Immigration at k = 4, death at rate g ∈ [0.2, 0.5] (a coordinate), from 0 copies:
/// the law at time t is Poisson with mean (k/g)(1 − e^{−g t}).
const IMMIGRATION_DEATH: &str = r#"
name = "immigration-death"
[[species]]
name = "x"
max = 48
initial = 0
[[parameters]]
name = "g"
range = [0.2, 0.5]
grid = 41
spacing = "reciprocal"
[[reactions]]
change = { x = 1 }
rate = [4.0]
[[reactions]]
change = { x = -1 }
rate = ["g"]
factors = [{ species = "x", kind = "linear" }]
"#;

fn options(t_end: f64) -> greedy::Options {
    greedy::Options {
        t_end,
        h_first: 0.01,
        h_max: 0.1,
        ..greedy::Options::default()
    }
}

#[test]
fn a_rate_as_a_coordinate_matches_the_closed_form_on_and_between_grid_points() {
    let net = Network::from_toml(IMMIGRATION_DEATH, "test").expect("parses");
    let (model, report) = greedy::solve(&net, &options(10.0), &mut |_| {}).expect("solves");
    assert!(report.worst_step_residual <= 1e-5, "{report:?}");
    let res = &model.provenance().residual_per_mode;
    assert!(
        res.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-6)),
        "compression residual must not grow: {res:?}"
    );
    let cme = CmeModel::new(model).expect("a CME model");
    let grid = net.parameters[0].grid().expect("a range");
    // Grid points, midpoints between them, and both ends.
    let mut gs = vec![
        0.2,
        0.5,
        grid[7],
        0.5 * (grid[20] + grid[21]),
        0.5 * (grid[3] + grid[4]),
    ];
    gs.push(0.33);
    for &g in &gs {
        for &t in &[1.0, 4.0, 10.0] {
            let e = cme
                .evaluate(t, &[("g".into(), g)], usize::MAX)
                .expect("evaluates");
            let exact = poisson(4.0 / g * (1.0 - (-g * t).exp()), 48);
            let err = l1(&e.moments.marginals[0], &exact);
            // Measured with adaptive steps: ≤ 6.4e-4 at t = 1, 7.9e-4 at t = 4, 5.1e-4
            // at t = 10 (fixed steps 0.01 → 0.1 gave 1.0e-2 at t = 1).
            assert!(err < 2e-3, "g = {g}, t = {t}: L1 {err:.2e}");
            assert!(
                e.most_negative > -1e-5,
                "g = {g}, t = {t}: {}",
                e.most_negative
            );
            assert!(e.clamped.is_empty());
        }
    }
    // Outside the range: clamped to the end and flagged, not extrapolated.
    let out = cme
        .evaluate(4.0, &[("g".into(), 0.9)], usize::MAX)
        .expect("clamps");
    let end = cme
        .evaluate(4.0, &[("g".into(), 0.5)], usize::MAX)
        .expect("evaluates");
    assert_eq!(out.clamped, vec!["g".to_string()]);
    assert_eq!(out.moments.marginals, end.moments.marginals);
}

#[test]
fn the_toggle_switch_by_pgd_matches_exact_fsp() {
    let net = Network::built_in("toggle").expect("built in");
    let (model, _) = greedy::solve(&net, &options(20.0), &mut |_| {}).expect("solves");
    {
        // The pair joint of a separated model: the whole joint for two species, and
        // its transpose in the other order.
        let cme = CmeModel::new(model.clone()).expect("a CME model");
        let (whole, pair) = (
            cme.joint(5.0, &[], usize::MAX).expect("joint"),
            cme.pair_joint(5.0, &[], 0, 1).expect("pair"),
        );
        let scale = whole.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(
            whole
                .iter()
                .zip(&pair)
                .all(|(x, y)| (x - y).abs() <= 1e-12 * scale)
        );
        let sizes = cme.box_sizes();
        let swapped = cme.pair_joint(5.0, &[], 1, 0).expect("pair");
        assert_eq!(swapped[sizes[1] + 2], pair[2 * sizes[0] + 1]);
    }
    let cme = CmeModel::new(model).expect("a CME model");
    let (p, _) = net.parameter_values(&[]).expect("defaults");
    let times = [2.0, 20.0];
    let exact = fsp::solve(&net, &p, &times).expect("FSP");
    for (j, &t) in times.iter().enumerate() {
        let joint = cme.joint(t, &[], usize::MAX).expect("joint");
        let err = l1(&joint, &exact.joint[j]);
        assert!(err < 5e-3, "t = {t}: joint L1 {err:.2e}");
        let e = cme.evaluate(t, &[], usize::MAX).expect("evaluates");
        assert!((e.moments.mass - (1.0 - exact.leak[j])).abs() < 1e-3);
        for i in 0..2 {
            assert!((e.moments.mean[i] - exact.moments[j].mean[i]).abs() < 1e-2);
        }
        // Truncating to fewer terms costs accuracy, never validity.
        let few = cme.evaluate(t, &[], 5).expect("evaluates");
        assert!(few.moments.mean.iter().all(|m| m.is_finite()));
    }
}

#[test]
fn a_cme_model_survives_the_file_and_bad_requests_get_named_errors() {
    let net = Network::from_toml(IMMIGRATION_DEATH, "test").expect("parses");
    let opts = greedy::Options {
        max_modes: 30,
        ..options(2.0)
    };
    let (model, _) = greedy::solve(&net, &opts, &mut |_| {}).expect("solves");
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("id.palpa");
    file::save(&model, &path).expect("saves");
    let back = CmeModel::new(file::load::<f64>(&path).expect("loads")).expect("a CME model");
    let cme = CmeModel::new(model).expect("a CME model");
    let a = cme
        .evaluate(1.5, &[("g".into(), 0.3)], usize::MAX)
        .expect("ok");
    let b = back
        .evaluate(1.5, &[("g".into(), 0.3)], usize::MAX)
        .expect("ok");
    assert_eq!(a, b);
    assert_eq!(cme.species_names(), vec!["x".to_string()]);
    assert!(matches!(
        cme.evaluate(f64::NAN, &[], usize::MAX),
        Err(CmeModelError::BadTime(_))
    ));
    assert!(matches!(
        cme.evaluate(1.0, &[("k".into(), 1.0)], usize::MAX),
        Err(CmeModelError::UnknownParameter { .. })
    ));
    assert!(matches!(
        cme.evaluate(1.0, &[("g".into(), f64::INFINITY)], usize::MAX),
        Err(CmeModelError::BadParameter { .. })
    ));
    // Past the trained time range: clamped to its end and said so.
    let late = cme.evaluate(50.0, &[], usize::MAX).expect("ok");
    assert!(late.clamped.contains(&"t".to_string()));
    // A model of another kind is refused by name.
    let other = palpa_core::synthetic::palpation_like::<f64>(30, 4, 4, 1);
    match CmeModel::new(other) {
        Err(CmeModelError::WrongKind(k)) => assert!(!k.is_empty()),
        r => panic!("expected WrongKind, got {r:?}"),
    }
    // An automatic box is refused with the species' name.
    let auto = IMMIGRATION_DEATH.replace("max = 48", "max = \"auto\"");
    let net = Network::from_toml(&auto, "auto").expect("ok");
    let err = greedy::solve(&net, &opts, &mut |_| {}).expect_err("refused");
    assert!(err.to_string().contains("species x"), "{err}");
}
