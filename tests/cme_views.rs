//! The views model (marginals and chosen joints over time, what a scene shows of a big
//! network): against exact FSP of the signaling cascade's closed leading chain at times
//! between its nodes, t = 0 and beyond the end, its stored joints against the exact
//! joint summed by hand, the file round trip and the refusals.

use palpa_core::cme::build::{self, Recipe, ViewOptions};
use palpa_core::cme::fsp;
use palpa_core::cme::model::{self, CmeModelError};
use palpa_core::cme::moments::l1;
use palpa_core::cme::network::Network;
use palpa_core::file::{self, FileError};

/// signaling-cascade-5 to t = 40 with the default views recipe, keeping the first
/// pair and (S1, S3).
fn built() -> (Network, build::Built) {
    let net = Network::built_in("signaling-cascade-5").expect("built in");
    let recipe = Recipe::default_for(&net, 40.0);
    let mut view = recipe
        .views
        .clone()
        .expect("five species and no range: views");
    assert_eq!(view.pairs, vec![(0, 1), (1, 2), (2, 3), (3, 4)]);
    view.pairs = vec![(0, 1), (0, 2)];
    let recipe = Recipe {
        views: Some(view),
        ..recipe
    };
    let built = recipe.build(&net, None, &mut |_| {}).expect("builds");
    (net, built)
}

#[test]
fn views_match_the_closed_chain_between_nodes_and_keep_their_joints() {
    let (_, built) = built();
    let m = &built.model;
    assert_eq!(m.pairs(), Some(vec![(0, 1), (0, 2)]));
    let chain = Network::built_in("signaling-cascade-3").expect("built in");
    let (p, _) = chain.parameter_values(&[]).expect("defaults");
    let times = [0.0, 0.05, 0.9, 3.3, 11.7, 26.1, 40.0];
    let exact = fsp::solve(&chain, &p, &times).expect("FSP");
    for (j, &t) in times.iter().enumerate() {
        let e = m.evaluate(t, &[], usize::MAX).expect("evaluates");
        assert!(e.clamped.is_empty(), "t = {t}: {:?}", e.clamped);
        assert!(
            (e.moments.mass - 1.0).abs() < 1e-3,
            "t = {t}: mass {}",
            e.moments.mass
        );
        for i in 0..3 {
            let err = l1(&e.moments.marginals[i], &exact.moments[j].marginals[i]);
            assert!(err < 1e-2, "t = {t}, S{}: marginal L1 {err:.2e}", i + 1);
        }
        // The stored joints against the exact one with S2 (or S3) summed out.
        let sizes = &exact.sizes;
        for b in [1usize, 2] {
            let mut want = vec![0.0; sizes[0] * sizes[b]];
            for (idx, &v) in exact.joint[j].iter().enumerate() {
                let z = [idx % 64, (idx / 64) % 64, idx / 4096];
                want[z[b] * sizes[0] + z[0]] += v;
            }
            let got = m.pair_joint(t, &[], 0, b).expect("stored");
            let err = l1(&got, &want);
            assert!(err < 2e-2, "t = {t}, S1 × S{}: joint L1 {err:.2e}", b + 1);
            // Asked the other way round: the transpose.
            let back = m.pair_joint(t, &[], b, 0).expect("stored");
            assert!((back[sizes[0]] - got[1]).abs() < 1e-15);
        }
        // The covariance of S1 and S2 comes from their stored joint.
        assert!(
            (e.moments.cov01 - exact.moments[j].cov01).abs() < 0.05,
            "t = {t}: cov {} against {}",
            e.moments.cov01,
            exact.moments[j].cov01
        );
    }
    // t = 0: the initial point mass (all copies at zero).
    let e0 = m.evaluate(0.0, &[], usize::MAX).expect("evaluates");
    for marginal in &e0.moments.marginals {
        assert!((marginal[0] - 1.0).abs() < 1e-6, "{}", marginal[0]);
    }
    // Beyond the end: clamped to it and flagged.
    let late = m.evaluate(55.0, &[], usize::MAX).expect("evaluates");
    assert_eq!(late.clamped, vec!["t".to_string()]);
    let end = m.evaluate(40.0, &[], usize::MAX).expect("evaluates");
    assert_eq!(late.moments.marginals, end.moments.marginals);
    // What a views model does not keep is refused by name.
    let err = m.pair_joint(3.0, &[], 1, 2).expect_err("not stored");
    assert!(
        matches!(err, CmeModelError::PairNotStored { .. }) && err.to_string().contains("S1–S3"),
        "{err}"
    );
    assert!(matches!(
        m.joint(3.0, &[], usize::MAX),
        Err(CmeModelError::NoJoint)
    ));
    let err = m
        .evaluate(3.0, &[("delta".into(), 0.1)], usize::MAX)
        .expect_err("no such");
    assert!(
        matches!(err, CmeModelError::UnknownParameter { .. }),
        "{err}"
    );
}

#[test]
fn a_views_model_survives_the_file_and_corruption_is_named() {
    let (net, built) = built();
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("sc5.palpa");
    built.save(&net, &path).expect("saves");
    let back = model::load(&path).expect("loads");
    let mem = model::load_from_bytes(&std::fs::read(&path).expect("reads")).expect("from memory");
    for t in [0.0, 7.77, 40.0] {
        assert_eq!(
            built.model.evaluate(t, &[], usize::MAX).expect("ok"),
            back.evaluate(t, &[], usize::MAX).expect("ok")
        );
        assert_eq!(
            back.evaluate(t, &[], usize::MAX).expect("ok"),
            mem.evaluate(t, &[], usize::MAX).expect("ok")
        );
        assert_eq!(
            built.model.pair_joint(t, &[], 0, 2).expect("ok"),
            back.pair_joint(t, &[], 0, 2).expect("ok")
        );
    }
    assert_eq!(back.species_names().len(), 5);
    assert!(back.parameters().is_empty());
    assert!(back.describe().contains("views"), "{}", back.describe());
    match file::load_any(&path) {
        Err(FileError::WrongLayout { found, .. }) => assert_eq!(found, "views"),
        r => panic!("expected WrongLayout, got {r:?}"),
    }
    match file::load_train(&path) {
        Err(FileError::WrongLayout { found, .. }) => assert_eq!(found, "views"),
        r => panic!("expected WrongLayout, got {r:?}"),
    }
    let mut bytes = std::fs::read(&path).expect("reads");
    let last = bytes.len() - 100;
    bytes[last] ^= 0x40;
    let bad = dir.path().join("bad.palpa");
    std::fs::write(&bad, &bytes).expect("writes");
    let err = model::load(&bad).expect_err("corrupt");
    assert!(err.to_string().contains("payload corrupted"), "{err}");
    std::fs::write(&bad, &bytes[..bytes.len() / 2]).expect("writes");
    let err = model::load(&bad).expect_err("truncated");
    assert!(err.to_string().contains("truncated"), "{err}");
}

#[test]
fn views_refuse_range_parameters_and_bad_pairs() {
    let cascade = Network::built_in("cascade").expect("built in");
    let recipe = Recipe::default_for(&cascade, 10.0);
    assert!(recipe.views.is_none(), "two species: the whole history");
    let forced = Recipe {
        views: Some(ViewOptions::neighbours(2, 1e-5)),
        ..recipe
    };
    let err = forced
        .build(&cascade, None, &mut |_| {})
        .expect_err("delta is a range");
    assert!(err.to_string().contains("delta"), "{err}");
    let net = Network::built_in("signaling-cascade-5").expect("built in");
    let bad = Recipe {
        views: Some(ViewOptions {
            pairs: vec![(3, 1)],
            eps: 1e-5,
        }),
        ..Recipe::default_for(&net, 1.0)
    };
    let err = bad.build(&net, None, &mut |_| {}).expect_err("a > b");
    assert!(err.to_string().contains("pair (3, 1)"), "{err}");
}

/// Twenty species of 64 states (64²⁰ overflows 64 bits) are refused by FSP with the
/// count, not a panic or a wrapped size.
#[test]
fn exact_fsp_refuses_a_box_past_64_bits() {
    let net = Network::built_in("signaling-cascade-20").expect("built in");
    let sizes = vec![64; 20];
    let err = fsp::Generator::new(&net, &[], &sizes).expect_err("too large");
    assert!(err.to_string().contains("1.3292e36 states"), "{err}");
}
