//! The Discrete Stochastic Model Test Suite (vendored under `tests/data/dsmts`): every
//! case imports from its SBML (Level 3 and Level 2 give the same network) or is refused
//! naming the feature; exact FSP matches the published mean and sd; the SSA passes the
//! suite's own test; the default PGD (a conserved pair reduced, as `cme solve` does)
//! matches within 1e-3.

use std::path::PathBuf;

use palpa_core::cme::dsmts::{Case, SUITE_MEAN_FAILS, SUITE_SD_FAILS};
use palpa_core::cme::network::Factor;

/// Cases refused, and the feature the message must name.
const REFUSED: [(&str, &str); 5] = [
    ("00019", "rules"),
    ("00028", "events"),
    ("00029", "events"),
    ("00032", "events"),
    ("00033", "events"),
];

/// FSP and the PGD against the published values: `|a − b| / max(|b|, 1)`.
const FSP_TOL: f64 = 1e-5;
const PGD_TOL: f64 = 1e-3;
/// FSP's leak target at every output time: the command line's default.
const MAX_LEAK: f64 = palpa_core::cme::fsp::DEFAULT_MAX_LEAK;
/// The SSA's paths and seed (the suite suggests 10⁴ or more).
const TRAJECTORIES: usize = 10_000;
const SEED: u64 = 1;

fn cases() -> Vec<Case> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/dsmts");
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&root)
        .expect("the vendored suite")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    dirs.iter()
        .map(|d| Case::load(d).expect("a readable case"))
        .collect()
}

fn supported() -> Vec<Case> {
    cases()
        .into_iter()
        .filter(|c| !REFUSED.iter().any(|r| r.0 == c.id))
        .collect()
}

#[test]
fn every_case_imports_or_is_refused_naming_the_feature() {
    let all = cases();
    assert_eq!(all.len(), 39, "the 39 stochastic time-course cases");
    for case in &all {
        let l3 = case.network("l3v1");
        let l2 = case.network("l2v4");
        match REFUSED.iter().find(|r| r.0 == case.id) {
            Some((_, feature)) => {
                for e in [l3.expect_err("refused"), l2.expect_err("refused")] {
                    assert!(
                        e.to_string().contains(feature),
                        "{}: {e} should name {feature}",
                        case.id
                    );
                }
            }
            None => {
                let (l3, l2) = (l3.expect("imports"), l2.expect("imports"));
                assert_eq!(l3, l2, "{}: Level 3 and Level 2 agree", case.id);
                assert!(case.outputs(&l3).is_some(), "{}: outputs found", case.id);
                // A network that imports can be written as TOML and read back unchanged.
                let back = palpa_core::cme::Network::from_toml(&l3.to_toml(), "round trip")
                    .expect("its TOML reads back");
                assert_eq!(back.species, l3.species, "{}", case.id);
                assert_eq!(back.reactions, l3.reactions, "{}", case.id);
                assert_eq!(back.parameters, l3.parameters, "{}", case.id);
            }
        }
    }
    // The dimerisation `k1·P(P−1)/2` is mass action of order 2: one binomial factor.
    let dimer = all
        .iter()
        .find(|c| c.id == "00030")
        .expect("case 30")
        .network("l3v1")
        .expect("imports");
    let r = &dimer.reactions[0];
    assert_eq!(r.factors, vec![(0, Factor::Binomial { k: 2 })]);
    assert_eq!((r.constant, r.change.as_slice()), (1.0, &[-2, 1][..]));
    // Concentration units (case 11, compartment of size 2): the law `Lambda·X` reads X
    // as amount/2.
    let conc = all
        .iter()
        .find(|c| c.id == "00011")
        .expect("case 11")
        .network("l3v1")
        .expect("imports");
    assert_eq!(conc.reactions[0].constant, 0.5);
}

/// FSP and the default PGD on the supported cases whose folder names fall in `ids`.
fn fsp_and_pgd_match(ids: std::ops::RangeInclusive<u32>) {
    for case in supported()
        .into_iter()
        .filter(|c| c.id.parse::<u32>().is_ok_and(|n| ids.contains(&n)))
    {
        let net = case.network("l3v1").expect("imports");
        let outputs = case.outputs(&net).expect("outputs");
        let (fsp, boxes) = case.check_fsp(&net, &outputs, MAX_LEAK).expect("FSP");
        assert!(
            fsp.mean <= FSP_TOL && fsp.sd <= FSP_TOL,
            "{}: FSP mean {:.1e}, sd {:.1e} (> {FSP_TOL:.0e})",
            case.id,
            fsp.mean,
            fsp.sd
        );
        let pgd = case.check_pgd(&net, &outputs, Some(&boxes)).expect("PGD");
        assert!(
            pgd.mean <= PGD_TOL && pgd.sd <= PGD_TOL,
            "{}: PGD mean {:.1e}, sd {:.1e} (> {PGD_TOL:.0e})",
            case.id,
            pgd.mean,
            pgd.sd
        );
    }
}

// Two halves, so that the slowest cases (5 and 7; 23, 25 and 31) run on both cores.
#[test]
fn fsp_and_the_default_pgd_match_the_published_moments_in_cases_1_to_19() {
    fsp_and_pgd_match(1..=19);
}

#[test]
fn fsp_and_the_default_pgd_match_the_published_moments_in_cases_20_to_39() {
    fsp_and_pgd_match(20..=39);
}

#[test]
fn the_ssa_passes_the_suites_test() {
    // The suite's criterion for a correct simulator at n = 10⁴: a few failed points in
    // total (see `dsmts`), and none far out.
    let (mut mean_fails, mut sd_fails) = (Vec::new(), Vec::new());
    for case in supported() {
        let net = case.network("l3v1").expect("imports");
        let outputs = case.outputs(&net).expect("outputs");
        let check = case.check_ssa(&net, &outputs, TRAJECTORIES, SEED);
        if check.mean_fails > 0 {
            mean_fails.push((case.id.clone(), check.mean_fails, check.z_max));
        }
        if check.sd_fails > 0 {
            sd_fails.push((case.id.clone(), check.sd_fails, check.y_max));
        }
        assert!(
            check.z_max < 6.0 && check.y_max < 10.0,
            "{}: |Z| {:.2}, |Y| {:.2}: far outside the suite's ranges",
            case.id,
            check.z_max,
            check.y_max
        );
    }
    println!("failed points (case, count, largest): mean {mean_fails:?}, sd {sd_fails:?}");
    let total = |v: &[(String, usize, f64)]| v.iter().map(|f| f.1).sum::<usize>();
    assert!(
        total(&mean_fails) <= SUITE_MEAN_FAILS && total(&sd_fails) <= SUITE_SD_FAILS,
        "{TRAJECTORIES} paths, seed {SEED}: mean tests failed {mean_fails:?} (allowed \
         {SUITE_MEAN_FAILS} in total), sd tests {sd_fails:?} (allowed {SUITE_SD_FAILS})"
    );
}
