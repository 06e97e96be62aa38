//! The CME by tensor-train steps: against exact FSP (toggle; cascade with δ as a
//! coordinate, on, between and beyond its grid points), against the closed chain S1–S3
//! of the signaling cascade, and through the file (round trip, corruption, wrong layout).

use palpa_core::cme::model::{self, CmeModel};
use palpa_core::cme::moments::l1;
use palpa_core::cme::network::Network;
use palpa_core::cme::{fsp, ttsolve};
use palpa_core::file::{self, FileError};
use palpa_core::separated::Provenance;

fn options(t_end: f64) -> ttsolve::Options {
    ttsolve::Options {
        t_end,
        step_error_tol: 3e-6,
        eps: 1e-8,
        ..ttsolve::Options::default()
    }
}

fn build(net: &Network, o: &ttsolve::Options) -> (palpa_core::cme::history::History, CmeModel) {
    let (h, report) = ttsolve::solve(net, o, &mut |_| {}).expect("solves");
    assert!(report.worst_mass_correction < 1e-4, "{report:?}");
    let meta = model::train_meta(net, &h, Provenance::now("test", "", 0.0, Vec::new()));
    let m = CmeModel::from_train(meta, h.tt.cores.clone()).expect("a CME model");
    (h, m)
}

#[test]
fn the_toggle_switch_matches_exact_fsp() {
    let net = Network::built_in("toggle").expect("built in");
    let (_, cme) = build(&net, &options(20.0));
    let (p, _) = net.parameter_values(&[]).expect("defaults");
    let times = [2.0, 7.3, 20.0];
    let exact = fsp::solve(&net, &p, &times).expect("FSP");
    for (j, &t) in times.iter().enumerate() {
        let err = l1(
            &cme.joint(t, &[], usize::MAX).expect("joint"),
            &exact.joint[j],
        );
        // Measured: 1.2e-4 (t = 2), 3.7e-4 (t = 20) at these settings.
        assert!(err < 1e-3, "t = {t}: joint L1 {err:.2e}");
        let e = cme.evaluate(t, &[], usize::MAX).expect("evaluates");
        assert!(
            (e.moments.mass - 1.0).abs() < 1e-5,
            "mass {}",
            e.moments.mass
        );
        assert!(e.most_negative > -1e-6, "{}", e.most_negative);
        for i in 0..2 {
            assert!((e.moments.mean[i] - exact.moments[j].mean[i]).abs() < 1e-3);
            assert!((e.moments.var[i] - exact.moments[j].var[i]).abs() < 1e-2);
        }
        assert!((e.moments.cov01 - exact.moments[j].cov01).abs() < 1e-2);
    }
}

#[test]
fn the_cascade_matches_fsp_for_delta_on_between_and_beyond_its_grid() {
    let net = Network::built_in("cascade").expect("built in");
    let (h, cme) = build(&net, &options(30.0));
    let grid = &h.params[0].1;
    let between = 0.5 * (grid[20] + grid[21]);
    let times = [10.0, 30.0];
    for delta in [0.01, grid[7], between, 0.02, 0.045] {
        let set = vec![("delta".to_string(), delta)];
        let (p, _) = net.parameter_values(&set).expect("in range");
        let exact = fsp::solve_on(&net, &p, &cme.box_sizes(), &times).expect("FSP");
        for (j, &t) in times.iter().enumerate() {
            let err = l1(
                &cme.joint(t, &set, usize::MAX).expect("joint"),
                &exact.joint[j],
            );
            println!("δ = {delta}, t = {t}: joint L1 {err:.2e}");
            // Goal 1e-3; measured 1.0e-4 … 6.3e-4 (the largest at the low end, δ = 0.01).
            assert!(err < 1e-3, "delta {delta}, t = {t}: joint L1 {err:.2e}");
        }
    }
    // Beyond the range: clamped to the end and flagged, not extrapolated.
    let out = cme
        .evaluate(30.0, &[("delta".into(), 0.06)], usize::MAX)
        .expect("clamps");
    let end = cme
        .evaluate(30.0, &[("delta".into(), 0.045)], usize::MAX)
        .expect("evaluates");
    assert_eq!(out.clamped, vec!["delta".to_string()]);
    assert_eq!(out.moments.marginals, end.moments.marginals);
}

#[test]
fn the_first_three_species_of_a_signaling_cascade_match_their_closed_chain() {
    // Species 1–3 of the feed-forward cascade form a closed network: FSP solves it
    // exactly, whatever the species downstream do. Both ways of keeping the result:
    // the whole history (a meta-model over t), and the states at the shown times only.
    let net = Network::built_in("signaling-cascade-6").expect("built in");
    let o = ttsolve::Options {
        t_end: 60.0,
        eps: 1e-6,
        step_error_tol: 1e-4,
        compress_eps: 1e-4,
        ..ttsolve::Options::default()
    };
    let (_, history) = build(&net, &o);
    let times = [0.0, 10.0, 30.0, 60.0];
    let (h, report) = ttsolve::solve_at(&net, &o, &times, &mut |_| {}).expect("solves");
    // The shown times are nodes, exactly, and nothing else is stored.
    assert_eq!(h.t, times.to_vec());
    assert_eq!(report.stored, times.len());
    let meta = model::train_meta(&net, &h, Provenance::now("test", "", 0.0, Vec::new()));
    let shown = CmeModel::from_train(meta, h.tt.cores.clone()).expect("a CME model");
    let chain = Network::built_in("signaling-cascade-3").expect("built in");
    let (p, _) = chain.parameter_values(&[]).expect("defaults");
    let exact = fsp::solve(&chain, &p, &times).expect("FSP");
    for cme in [&history, &shown] {
        for (j, &t) in times.iter().enumerate() {
            let e = cme.evaluate(t, &[], usize::MAX).expect("evaluates");
            // The weighted history keeps the mass of every stored state.
            assert!(
                (e.moments.mass - 1.0).abs() < 1e-3,
                "t = {t}: mass {}",
                e.moments.mass
            );
            for i in 0..3 {
                let err = l1(&e.moments.marginals[i], &exact.moments[j].marginals[i]);
                // Measured 1e-3 … 7e-3.
                assert!(err < 1e-2, "t = {t}, S{}: marginal L1 {err:.2e}", i + 1);
            }
        }
    }
    assert!(matches!(
        ttsolve::solve_at(&net, &o, &[5.0, 1.0], &mut |_| {}),
        Err(palpa_core::cme::greedy::CmePgdError::TimeGrid(_))
    ));
}

#[test]
fn a_tensor_train_model_survives_the_file_and_corruption_is_named() {
    let net = Network::built_in("cascade").expect("built in");
    let (h, cme) = build(
        &net,
        &ttsolve::Options {
            t_end: 2.0,
            ..options(2.0)
        },
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("cascade.palpa");
    model::save_train(
        &net,
        &h,
        Provenance::now("test", "", 0.0, Vec::new()),
        &path,
    )
    .expect("saves");
    let back = model::load(&path).expect("loads");
    let set = [("delta".to_string(), 0.03)];
    assert_eq!(
        cme.evaluate(1.3, &set, usize::MAX).expect("ok"),
        back.evaluate(1.3, &set, usize::MAX).expect("ok")
    );
    assert_eq!(back.species_names(), vec!["z1".to_string(), "z2".into()]);
    // The same from bytes in memory (what a bundled asset or the fuzzer feeds).
    let bytes = std::fs::read(&path).expect("reads");
    let mem = model::load_from_bytes(&bytes).expect("loads from memory");
    assert_eq!(
        cme.evaluate(1.3, &set, usize::MAX).expect("ok"),
        mem.evaluate(1.3, &set, usize::MAX).expect("ok")
    );
    assert_eq!(back.parameters()[0].0, "delta");
    // A separated-model loader refuses the train by layout, not by a decode error.
    match file::load_any(&path) {
        Err(FileError::WrongLayout { found, .. }) => assert_eq!(found, "tensor-train"),
        r => panic!("expected WrongLayout, got {r:?}"),
    }
    // A flipped payload byte is caught by the checksum.
    let mut bytes = std::fs::read(&path).expect("reads");
    let last = bytes.len() - 100;
    bytes[last] ^= 0x40;
    let bad = dir.path().join("bad.palpa");
    std::fs::write(&bad, &bytes).expect("writes");
    let err = model::load(&bad).expect_err("corrupt");
    assert!(err.to_string().contains("payload corrupted"), "{err}");
}

/// A build told to stop before it starts stops at its first step with `Cancelled`.
#[test]
fn a_cancelled_solve_says_so() {
    let net = Network::built_in("toggle").expect("built in");
    let cancel = std::sync::atomic::AtomicBool::new(true);
    let r = ttsolve::solve_cancellable(&net, &ttsolve::Options::default(), &cancel, &mut |_| {});
    assert!(matches!(
        r,
        Err(palpa_core::cme::greedy::CmePgdError::Cancelled)
    ));
}

/// The joint of two species with the others summed out in the train equals the full
/// joint summed by hand; asked in the other order it is the transpose; a bad pair is
/// named.
#[test]
fn a_pair_joint_sums_the_other_species_out() {
    let net = Network::built_in("signaling-cascade-3").expect("built in");
    let o = ttsolve::Options {
        t_end: 3.0,
        h_max: 0.2,
        ..ttsolve::Options::default()
    };
    let (_, model) = build(&net, &o);
    let sizes = model.box_sizes();
    let full = model.joint(3.0, &[], usize::MAX).expect("joint");
    // Species 0 and 2, species 1 summed.
    let mut by_hand = vec![0.0; sizes[0] * sizes[2]];
    for z2 in 0..sizes[2] {
        for z1 in 0..sizes[1] {
            for z0 in 0..sizes[0] {
                by_hand[z2 * sizes[0] + z0] += full[(z2 * sizes[1] + z1) * sizes[0] + z0];
            }
        }
    }
    let pair = model.pair_joint(3.0, &[], 0, 2).expect("pair");
    let scale = by_hand.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(l1(&pair, &by_hand) < 1e-10 * scale * by_hand.len() as f64);
    let swapped = model.pair_joint(3.0, &[], 2, 0).expect("pair");
    for z0 in 0..sizes[0] {
        for z2 in 0..sizes[2] {
            assert_eq!(swapped[z0 * sizes[2] + z2], pair[z2 * sizes[0] + z0]);
        }
    }
    assert!(model.pair_joint(3.0, &[], 1, 1).is_err());
    assert!(model.pair_joint(3.0, &[], 0, 3).is_err());
}
