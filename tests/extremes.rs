//! Numerical extremes, each with the figure docs/accuracy.md's extremes table states:
//! near-incompressible tissue (ν → 0.5) on P1 and P2, ν = 0.5 itself refused, an
//! exact CME solve long past its stationary time, rates so small nothing happens, and
//! a box too large for the exact solver refused by name.

use palpa_core::cme::moments::l1;
use palpa_core::cme::network::Network;
use palpa_core::cme::{fsp, ssa};
use palpa_core::fe::probe::{ProbeRequest, solve_linear};
use palpa_core::fe::{Element, FeError, Material};
use palpa_tests::{coarse_liver, poisson};

use super::cme::IMMIGRATION_DEATH;

/// The probe displacement under 1 N on coarse P1 and P2 as ν goes to 0.5. P2 moves
/// smoothly towards its incompressible limit (measured: 0.932, 0.913, 0.874, 0.850 mm
/// at ν = 0.48, 0.49, 0.499, 0.4999), while P1 locks (0.569 → 0.290 mm, a third of P2
/// at 0.4999); every solve stays finite and the factorization never fails.
#[test]
fn near_incompressible_tissue_p2_converges_and_p1_locks() {
    let organ = coarse_liver();
    let req = ProbeRequest {
        at: [0.0, 40.0, 30.0],
        force_n: 1.0,
        dir: None,
        radius_mm: 5.0,
        nodule: None,
    };
    let nus = [0.48, 0.49, 0.499, 0.4999];
    let depth = |element, poisson| {
        let material = Material {
            poisson,
            ..Material::default()
        };
        let sol = solve_linear(&organ, element, material, &req).expect("solves");
        assert!(sol.u.iter().all(|v| v.is_finite()));
        sol.probe_displacement_mm
    };
    let p2: Vec<f64> = nus.iter().map(|&nu| depth(Element::P2, nu)).collect();
    let p1: Vec<f64> = nus.iter().map(|&nu| depth(Element::P1, nu)).collect();
    println!("ν {nus:?}\nP2 {p2:?}\nP1 {p1:?}");
    for w in p2.windows(2) {
        assert!(w[1] < w[0], "stiffer as ν grows: {p2:?}");
    }
    // The last decade of 1 − 2ν moves P2 by under 5 %; it moves P1 by over 15 %.
    assert!(p2[3] / p2[2] > 0.95, "{p2:?}");
    assert!(p1[3] / p1[2] < 0.85, "{p1:?}");
    assert!(p1[3] < 0.5 * p2[3], "P1 locks: {p1:?} against {p2:?}");

    for poisson in [0.5, 0.6, f64::NAN] {
        let material = Material {
            poisson,
            ..Material::default()
        };
        let err = solve_linear(&organ, Element::P2, material, &req).expect_err("refused");
        assert!(matches!(err, FeError::PoissonRatio { .. }), "{err}");
        assert!(err.to_string().contains("0.5"), "{err}");
    }
}

/// t = 0 is the initial point mass exactly; t = 10⁴ (2 500 relaxation times, 10⁵
/// reaction events on average) is the stationary Poisson(16) law to its leak plus
/// 1e-12 in L1, the leak below 1e-11. The solution settles (stops changing shape) long
/// before 10⁴, and 10¹² is not stepped to (stepping would take days): there the box of
/// 60 has leaked what its exit rate, `k·P(59)/ΣP` of the settled law, takes over the
/// time (2.6e-4, to 1e-6 of itself), and the law is Poisson(16) to that leak plus
/// 1e-12. (The box's law lies below Poisson's at its top, `P(59)` by about a quarter,
/// as states there leave; `a_settled_fsp_solution_is_what_stepping_gives` checks the
/// decay against stepping where the leak is large enough for stepping to see.)
#[test]
fn exact_cme_at_t_zero_and_long_past_the_stationary_time() {
    let net = Network::from_toml(IMMIGRATION_DEATH, "test").expect("parses");
    let (p, _) = net.parameter_values(&[]).expect("defaults");
    let sol = fsp::solve(&net, &p, &[0.0, 1e4, 1e12]).expect("solves");
    let m0 = &sol.moments[0].marginals[0];
    assert_eq!(m0[0], 1.0);
    assert!(m0[1..].iter().all(|&v| v == 0.0));
    let settled = sol.settled_at.expect("settles");
    println!("settled at t = {settled}");
    assert!(settled > 0.0 && settled < 1e4, "settled at {settled}");
    for (j, t) in [(1, "1e4"), (2, "1e12")] {
        let late = &sol.moments[j].marginals[0];
        let err = l1(late, &poisson(16.0, late.len()));
        let leak = sol.leak[j];
        println!("t = {t}: L1 {err:e}, leak {leak:e}");
        assert!(err < leak + 1e-12, "t = {t}: L1 {err:e}, leak {leak:e}");
    }
    assert!(sol.leak[1] < 1e-11, "leak {:e}", sol.leak[1]);
    let law = &sol.moments[1].marginals[0];
    let exit_rate = 4.0 * law[59] / law.iter().sum::<f64>();
    let expected = -(-exit_rate * (1e12 - settled)).exp_m1();
    let off = (sol.leak[2] / expected - 1.0).abs();
    println!(
        "leak at 1e12 {:e}, from the exit rate {expected:e}",
        sol.leak[2]
    );
    assert!(off < 1e-6, "leak {:e} against {expected:e}", sol.leak[2]);
}

/// A settled FSP solution is what stepping gives, where the box leaks and where the
/// network is bistable. Stepping here is one uniformization step per call of
/// `qΔ < 2 500`, too short to judge the law settled, so it steps all the way; the
/// solve settles and decays the rest.
///
/// - Immigration–death in a box of 30 (the Poisson(16) law's tail leaks): the law
///   decays along its quasi-stationary shape, mass `e^{−μt}` with `μ` the box's exit
///   rate; to t = 2 000 (a third of the mass left) it matches stepping to 1e-11 of the
///   mass, joint and leak.
/// - The toggle switch (two wells) to t = 10⁴: to 1e-12 in L1.
#[test]
fn a_settled_fsp_solution_is_what_stepping_gives() {
    let leaky = IMMIGRATION_DEATH.replace("max = 60", "max = 30");
    let cases = [
        (Network::from_toml(&leaky, "test").expect("parses"), 2_000.0),
        (Network::built_in("toggle").expect("built in"), 1e4),
    ];
    for (net, t) in cases {
        let (p, _) = net.parameter_values(&[]).expect("defaults");
        let sol = fsp::solve(&net, &p, &[t]).expect("solves");
        let settled = sol.settled_at.expect("settles");
        let stepped = fsp::solve_stepped(&net, &p, &[t]).expect("steps");
        assert_eq!(stepped.settled_at, None);
        let mass = 1.0 - stepped.leak[0];
        let err = l1(&sol.joint[0], &stepped.joint[0]);
        let leak_err = (sol.leak[0] - stepped.leak[0]).abs();
        println!(
            "{} to t = {t}: settled at {settled:.1}, mass {mass:.6}, joint L1 {err:.2e}, leak {:.3e} vs {:.3e}",
            net.name, sol.leak[0], stepped.leak[0]
        );
        assert!(settled < t, "{}: settled at {settled}", net.name);
        assert!(err < 1e-11 * mass, "{}: joint L1 {err:e}", net.name);
        assert!(leak_err < 1e-11, "{}: leak off by {leak_err:e}", net.name);
    }
}

/// Rates of 10⁹: the box of 60 empties within a fraction of the time (every count
/// is carried past its top), and the exact solve says so: leak 1, settled at once,
/// where stepping on would take 10⁹/5 000 steps of nothing.
#[test]
fn huge_rates_empty_the_box_and_the_exact_solve_says_so() {
    let net = Network::from_toml(IMMIGRATION_DEATH, "test").expect("parses");
    let (p, _) = net.parameter_values(&[("k".into(), 1e9)]).expect("values");
    let sol = fsp::solve(&net, &p, &[1.0]).expect("solves");
    let settled = sol.settled_at.expect("settles");
    println!("leak {:e}, settled at {settled:e}", sol.leak[0]);
    assert!(settled < 1e-3, "settled at {settled}");
    assert!(sol.leak[0] > 1.0 - 1e-12, "leak {}", sol.leak[0]);
    assert!(sol.moments[0].marginals[0].iter().all(|v| v.is_finite()));
}

/// Rates of 10⁻¹² per unit time: over t = 100 nothing happens (the point mass stays,
/// to 1e-9) in the exact solve and in every simulated path, with nothing non-finite.
#[test]
fn tiny_rates_leave_the_initial_state() {
    let net = Network::from_toml(IMMIGRATION_DEATH, "test").expect("parses");
    let (p, _) = net
        .parameter_values(&[("k".into(), 1e-12), ("g".into(), 1e-12)])
        .expect("values");
    let sol = fsp::solve(&net, &p, &[100.0]).expect("solves");
    let m = &sol.moments[0].marginals[0];
    assert!(m.iter().all(|v| v.is_finite()));
    assert!((m[0] - 1.0).abs() < 1e-9, "P(0) = {}", m[0]);
    let paths = ssa::simulate(&net, &p, &[100.0], 200, 7);
    assert_eq!(paths.truncated, 0);
    let s = &paths.moments[0].marginals[0];
    assert!(
        (s[0] - 1.0).abs() < 1e-12,
        "no event in 200 paths: P(0) = {}",
        s[0]
    );
}

/// A box of 2 000 × 8 000 states (1.6 × 10⁷) is refused before anything is allocated,
/// naming the count and the way out.
#[test]
fn a_box_over_ten_million_states_is_refused_by_name() {
    let net = Network::built_in("cascade").expect("built in");
    let err = fsp::solve_on(&net, &[0.02], &[2000, 8000], &[1.0]).expect_err("refused");
    let msg = err.to_string();
    assert!(
        matches!(err, fsp::FspError::TooLarge { .. }) && msg.contains("1.6000e7"),
        "{msg}"
    );
    assert!(msg.contains("PGD"), "{msg}");
}
