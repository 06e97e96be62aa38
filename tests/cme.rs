//! Gene networks: the TOML front end, exact FSP against closed forms and its own
//! invariants, SSA against FSP within standard errors, and the extremes (parameters
//! outside their range, long times, a box too small).

use palpa_core::cme::moments::l1;
use palpa_core::cme::network::{Network, NetworkError};
use palpa_core::cme::{fsp, ssa};
use palpa_tests::poisson;

/// Immigration and death of one species (box 0..=60), the CME tests' closed-form case.
pub(crate) const IMMIGRATION_DEATH: &str = r#"
name = "immigration-death"
[[species]]
name = "x"
max = 60
initial = 0
[[parameters]]
name = "k"
value = 4.0
[[parameters]]
name = "g"
value = 0.25
[[reactions]]
change = { x = 1 }
rate = ["k"]
[[reactions]]
change = { x = -1 }
rate = ["g"]
factors = [{ species = "x", kind = "linear" }]
"#;

/// Rates of 10⁹ to t = 1 would be 10⁹ reactions a path: a run's budget stops every
/// path soon after it is spent, and says so; an ordinary run under the same budget
/// is the unbounded run, path for path.
#[test]
fn an_ssa_run_stops_at_its_event_budget_and_says_so() {
    let net = Network::from_toml(IMMIGRATION_DEATH, "test").expect("parses");
    let (fast, _) = net.parameter_values(&[("k".into(), 1e9)]).expect("values");
    let budget = 1_000_000;
    let sol = ssa::simulate_within(&net, &fast, &[1.0], 50, 3, budget);
    assert_eq!(sol.truncated, 50);
    assert!(
        sol.events <= budget + 2 * 50 * 4_096,
        "{} events",
        sol.events
    );

    let (p, _) = net.parameter_values(&[]).expect("defaults");
    let bounded = ssa::simulate_within(&net, &p, &[10.0], 100, 3, budget);
    let free = ssa::simulate(&net, &p, &[10.0], 100, 3);
    assert_eq!(bounded.truncated, 0);
    assert_eq!(bounded.events, free.events);
    assert_eq!(bounded.moments[0].marginals, free.moments[0].marginals);
}

#[test]
fn fsp_reproduces_the_immigration_death_closed_form() {
    // From 0 copies the law at time t is Poisson with mean (k/g)(1 − e^{−g t}).
    let net = Network::from_toml(IMMIGRATION_DEATH, "test").expect("parses");
    let (p, _) = net.parameter_values(&[]).expect("defaults");
    let times = [0.5, 3.0, 40.0];
    let sol = fsp::solve(&net, &p, &times).expect("solves");
    for (j, &t) in times.iter().enumerate() {
        let mean = 16.0 * (1.0 - (-0.25 * t).exp());
        let exact = poisson(mean, 60);
        let err = l1(&sol.moments[j].marginals[0], &exact);
        // Uniformization is exact up to its 1e-15 tail; the box leaks < 1e-12 here.
        assert!(err < 1e-10, "t = {t}: L1 {err:e}");
        assert!(sol.leak[j] < 1e-10);
        assert!((sol.moments[j].mean[0] - mean).abs() < 1e-9);
    }
}

#[test]
fn fsp_toggle_keeps_mass_positivity_and_symmetry_over_long_times() {
    let net = Network::built_in("toggle").expect("built in");
    let (p, _) = net.parameter_values(&[]).expect("defaults");
    let sol = fsp::solve(&net, &p, &[100.0, 300.0, 1000.0]).expect("solves");
    for (j, joint) in sol.joint.iter().enumerate() {
        // The box (80 per species; means ≈ 7) loses nothing measurable.
        assert!(sol.leak[j] < 1e-6, "leak {}", sol.leak[j]);
        let most_negative = joint.iter().copied().fold(0.0, f64::min);
        assert!(most_negative >= 0.0, "negative probability {most_negative}");
        let m = &sol.moments[j];
        // The network is symmetric in z1 ↔ z2 and so is the start (15, 15).
        assert!(l1(&m.marginals[0], &m.marginals[1]) < 1e-10);
    }
    // The switch: at long times the mass sits near the axes (one gene wins), so the
    // covariance of the two species is strongly negative.
    assert!(
        sol.moments[2].cov01 < -0.5 * sol.moments[2].var[0],
        "{:?}",
        sol.moments[2]
    );
}

#[test]
fn ssa_agrees_with_fsp_within_its_standard_errors() {
    for (model, params, t) in [
        ("toggle", vec![], 100.0),
        ("cascade", vec![("delta".to_string(), 0.03)], 30.0),
    ] {
        let net = Network::built_in(model).expect("built in");
        let (p, _) = net.parameter_values(&params).expect("values");
        let exact = fsp::solve(&net, &p, &[t]).expect("fsp");
        let k = 8000;
        let sampled = ssa::simulate(&net, &p, &[t], k, 42);
        let (e, s) = (&exact.moments[0], &sampled.moments[0]);
        let mean_se = s.mean_se.as_ref().expect("se");
        let var_se = s.var_se.as_ref().expect("se");
        for i in 0..2 {
            // 4.5 standard errors: a fixed seed, and a bound that a wrong propensity or
            // change vector (shifts of many SE) cannot meet.
            assert!(
                (e.mean[i] - s.mean[i]).abs() < 4.5 * mean_se[i],
                "{model} mean {i}: {} vs {} ± {}",
                e.mean[i],
                s.mean[i],
                mean_se[i]
            );
            assert!(
                (e.var[i] - s.var[i]).abs() < 4.5 * var_se[i],
                "{model} var {i}: {} vs {} ± {}",
                e.var[i],
                s.var[i],
                var_se[i]
            );
            // Empirical marginal vs exact: L1 shrinks like √(states/K).
            let states = e.marginals[i].iter().filter(|&&q| q > 1e-4).count() as f64;
            let bound = 2.0 * (states / k as f64).sqrt();
            let d = l1(&e.marginals[i], &s.marginals[i]);
            assert!(d < bound, "{model} marginal {i}: L1 {d} ≥ {bound}");
        }
    }
}

#[test]
fn ssa_of_the_20_species_cascade_matches_the_exact_3_species_chain() {
    // Species 1–3 of the signaling cascade form a closed sub-network: FSP solves it
    // exactly on 64³ states; SSA runs the whole 20-species network.
    let t = 60.0;
    let small = Network::built_in("signaling-cascade-3").expect("built in");
    let exact = fsp::solve(&small, &[], &[t]).expect("fsp");
    assert!(exact.leak[0] < 1e-9);
    let big = Network::built_in("signaling-cascade-20").expect("built in");
    assert_eq!(big.species.len(), 20);
    let s = ssa::simulate(&big, &[], &[t], 4000, 7);
    let se = s.moments[0].mean_se.as_ref().expect("se");
    for i in 0..3 {
        let (a, b) = (exact.moments[0].mean[i], s.moments[0].mean[i]);
        assert!(
            (a - b).abs() < 4.5 * se[i],
            "S{}: {a} vs {b} ± {}",
            i + 1,
            se[i]
        );
    }
}

#[test]
fn out_of_range_parameters_are_clamped_and_flagged_and_a_small_box_reports_its_leak() {
    let net = Network::built_in("cascade").expect("built in");
    let (p, notes) = net
        .parameter_values(&[("delta".into(), 0.001)])
        .expect("values");
    assert_eq!(p[0], 0.01);
    assert_eq!(notes.len(), 1);
    assert!(notes[0].contains("outside its trained range"));
    let (p, notes) = net
        .parameter_values(&[("delta".into(), 0.045)])
        .expect("values");
    assert_eq!(
        (p[0], notes.len()),
        (0.045, 0),
        "the range end itself is inside"
    );
    assert!(matches!(
        net.parameter_values(&[("delta".into(), f64::NAN)]),
        Err(NetworkError::Invalid { .. })
    ));
    assert!(net.parameter_values(&[("nope".into(), 1.0)]).is_err());

    // δ = 0.01 at t = 600: z1 has mean ≈ 100. A 64-state box for z1 loses a lot, and says so.
    let sol = fsp::solve_on(&net, &[0.01], &[64, 200], &[600.0]).expect("solves");
    assert!(sol.leak[0] > 0.5, "leak {}", sol.leak[0]);
    // The shipped box holds it.
    let sol = fsp::solve(&net, &[0.01], &[600.0]).expect("solves");
    assert!(sol.leak[0] < 1e-6, "leak {}", sol.leak[0]);
    assert!((sol.moments[0].mean[0] - 100.0 * (1.0 - (-6.0f64).exp())).abs() < 1e-6);
}

/// Boxes that grow with time give the moments and marginals of one fixed box that holds
/// the whole run: immigration and death into a sink (two species, the sink counting
/// deaths, so the reachable states are a triangle-like strip of the box), the box grown
/// as the sink fills.
#[test]
fn boxes_grown_with_time_agree_with_one_fixed_box() {
    let text = r#"
name = "immigration-death-sink"
[[species]]
name = "x"
max = "auto"
initial = 0
[[species]]
name = "sink"
max = "auto"
initial = 0
[[reactions]]
change = { x = 1 }
rate = [4.0]
[[reactions]]
change = { x = -1, sink = 1 }
rate = [0.2]
factors = [{ species = "x", kind = "linear" }]
"#;
    let net = Network::from_toml(text, "sink").expect("parses");
    let times = [0.0, 1.0, 5.0, 12.5, 30.0];
    let (grown, met) = fsp::solve_auto(&net, &[], &times, 1e-9).expect("solves");
    assert!(met);
    // x ends near Poisson(20), the sink near 100 ± 15: a box of 64 × 256 holds both.
    let fixed = fsp::solve_on(&net, &[], &[64, 256], &times).expect("solves");
    assert!(fixed.leak.iter().all(|&l| l < 1e-12), "{:?}", fixed.leak);
    assert!(
        grown.sizes[0] <= 64 && grown.sizes[1] <= 256,
        "{:?}",
        grown.sizes
    );
    for (j, (a, b)) in grown.moments.iter().zip(&fixed.moments).enumerate() {
        assert!(
            grown.leak[j] <= 1e-9,
            "t = {}: leak {}",
            times[j],
            grown.leak[j]
        );
        assert_eq!(
            a.marginals[1].len(),
            grown.sizes[1],
            "padded to the final box"
        );
        for i in 0..2 {
            let n = grown.sizes[i];
            assert!(
                l1(&a.marginals[i], &b.marginals[i][..n]) < 2e-9,
                "t = {}",
                times[j]
            );
            assert!((a.mean[i] - b.mean[i]).abs() < 1e-6, "t = {}", times[j]);
            assert!((a.var[i] - b.var[i]).abs() < 1e-5, "t = {}", times[j]);
        }
        assert!((a.cov01 - b.cov01).abs() < 1e-5, "t = {}", times[j]);
    }
}

#[test]
fn automatic_boxes_grow_until_the_leak_is_small() {
    let text = IMMIGRATION_DEATH
        .replace("max = 60", "max = \"auto\"")
        .replace("value = 4.0", "value = 40.0");
    let net = Network::from_toml(&text, "auto").expect("parses");
    let (p, _) = net.parameter_values(&[]).expect("defaults");
    assert!(matches!(
        fsp::solve(&net, &p, &[10.0]),
        Err(fsp::FspError::AutoBox(_))
    ));
    // A box with the wrong number of sizes is refused, not indexed out of range.
    assert!(matches!(
        fsp::solve_on(&net, &p, &[32, 32], &[10.0]),
        Err(fsp::FspError::BoxShape { got: 2, species: 1 })
    ));
    // Mean 160 · (1 − e^{−2.5}) ≈ 147 and sd ≈ 12 (Poisson): the box grows by quarters
    // from 32 as the count rises, past mean + 6 sd (220) and short of the 256 that
    // doubling reached.
    let (sol, met) = fsp::solve_auto(&net, &p, &[10.0], 1e-8).expect("solves");
    assert!(met);
    assert!((220..256).contains(&sol.sizes[0]), "{:?}", sol.sizes);
    assert!(sol.leak[0] < 1e-8);
}

#[test]
fn bad_network_files_name_the_line_and_the_problem() {
    let syntax = "name = \"x\"\n[[species]]\nname = \"a\"\nmax = = 3\n";
    match Network::from_toml(syntax, "bad.toml") {
        Err(NetworkError::Syntax {
            source_name,
            message,
        }) => {
            assert_eq!(source_name, "bad.toml");
            assert!(message.starts_with("line 4"), "{message}");
        }
        other => panic!("expected a syntax error, got {other:?}"),
    }
    let cases = [
        (
            IMMIGRATION_DEATH.replace(
                "species = \"x\", kind = \"linear\"",
                "species = [\"x\", \"x\"], kind = \"linear\"",
            ),
            "not separable",
        ),
        (
            IMMIGRATION_DEATH.replace("change = { x = 1 }", "change = { y = 1 }"),
            "unknown species",
        ),
        (
            IMMIGRATION_DEATH.replace("initial = 0", "initial = 60"),
            "outside its box",
        ),
        (
            IMMIGRATION_DEATH.replace("kind = \"linear\"", "kind = \"cubic\""),
            "expected linear",
        ),
        (
            IMMIGRATION_DEATH.replace("rate = [\"k\"]", "rate = [\"kk\"]"),
            "unknown parameter",
        ),
        (
            IMMIGRATION_DEATH.replace("max = 60", "max = 1"),
            "expected an integer",
        ),
        (
            IMMIGRATION_DEATH.replace("value = 4.0", "value = -4.0"),
            "expected a finite value",
        ),
    ];
    for (text, want) in cases {
        let err = Network::from_toml(&text, "case.toml")
            .expect_err(want)
            .to_string();
        assert!(
            err.contains(want) && err.contains("case.toml"),
            "expected {want:?} in {err}"
        );
    }
    assert!(matches!(
        Network::built_in("signaling-cascade-21"),
        Err(NetworkError::UnknownBuiltIn(_))
    ));
}

/// The full vector of a rank-one tensor (species 0 fastest).
fn outer(x: &[Vec<f64>]) -> Vec<f64> {
    let mut out = vec![1.0];
    for xi in x {
        out = xi
            .iter()
            .flat_map(|&a| out.iter().map(move |&b| a * b))
            .collect();
    }
    out
}

#[test]
fn the_kronecker_form_of_the_generator_is_the_fsp_generator() {
    use palpa_core::cme::kron::{apply_rank_one, generator_terms};
    use palpa_core::rng::Rng;
    for (model, sizes) in [
        ("toggle", vec![12, 9]),
        ("cascade", vec![10, 7]),
        ("signaling-cascade-3", vec![5, 6, 4]),
    ] {
        let net = Network::built_in(model).expect("built in");
        let (p, _) = net.parameter_values(&[]).expect("defaults");
        let g = fsp::Generator::new(&net, &p, &sizes).expect("generator");
        let terms = generator_terms(&net, &sizes);
        assert_eq!(
            terms.len(),
            2 * net.reactions.len(),
            "two Kronecker terms per reaction"
        );
        let mut rng = Rng::seed(3);
        let x: Vec<Vec<f64>> = sizes
            .iter()
            .map(|&m| (0..m).map(|_| rng.uniform()).collect())
            .collect();
        let full = outer(&x);
        let mut want = vec![0.0; full.len()];
        g.apply(&full, &mut want);
        let mut got = vec![0.0; full.len()];
        for (scale, ys) in apply_rank_one(&terms, &p, &x) {
            for (g, v) in got.iter_mut().zip(outer(&ys)) {
                *g += scale * v;
            }
        }
        let err = want
            .iter()
            .zip(&got)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let scale = want.iter().map(|a| a.abs()).fold(0.0, f64::max);
        assert!(err <= 1e-12 * scale.max(1.0), "{model}: {err:e}");
    }
}

#[test]
fn parameter_grids_hold_their_ends_and_space_as_asked() {
    let with = |spacing: &str| {
        IMMIGRATION_DEATH.replace(
            "name = \"g\"\nvalue = 0.25",
            &format!("name = \"g\"\nvalue = 0.25\nrange = [0.01, 0.04]\ngrid = 7\nspacing = \"{spacing}\""),
        )
    };
    // Each spacing: the quantity that should step evenly.
    type Even = fn(f64) -> f64;
    let cases: [(&str, Even); 4] = [
        ("linear", |g| g),
        ("log", f64::ln),
        ("reciprocal", |g| 1.0 / g),
        ("reciprocal-sqrt", |g| 1.0 / g.sqrt()),
    ];
    for (spacing, even) in cases {
        let net = Network::from_toml(&with(spacing), "grid.toml").expect(spacing);
        let g = net.parameters[1].grid().expect("a range");
        assert_eq!((g.len(), g[0], g[6]), (7, 0.01, 0.04), "{spacing}");
        let steps: Vec<f64> = g.windows(2).map(|w| even(w[1]) - even(w[0])).collect();
        for s in &steps {
            assert!(
                (s - steps[0]).abs() < 1e-9 * steps[0].abs(),
                "{spacing}: {steps:?}"
            );
        }
    }
    let bad = with("reciprocal-sqrt").replace("[0.01, 0.04]", "[0.0, 0.04]");
    let err = Network::from_toml(&bad, "grid.toml")
        .expect_err("δ = 0")
        .to_string();
    assert!(err.contains("range above 0"), "{err}");
}
