//! Kinetics as the field writes them: the binomial and affine factors, the refusal of
//! reactions that could drive a count negative, the SBML front end's translations and
//! refusals, automatic boxes that grow only where the probability leaks, and a first
//! step that follows the fastest rate.

use palpa_core::cme::network::{Factor, Network};
use palpa_core::cme::{build, fsp, sizing};

const DIMER: &str = r#"
name = "dimer"
[[species]]
name = "P"
max = 3
initial = 2
[[species]]
name = "P2"
max = 2
initial = 0
[[reactions]]
name = "dimerisation"
change = { P = -2, P2 = 1 }
rate = [0.7]
factors = [{ species = "P", kind = "binomial", k = 2 }]
"#;

#[test]
fn mass_action_of_order_two_fires_once_per_pair() {
    let net = Network::from_toml(DIMER, "dimer.toml").expect("parses");
    // Two monomers make one pair: P2 = 1 with probability 1 − e^{−0.7 t}.
    let sol = fsp::solve(&net, &[], &[0.5, 2.0]).expect("solves");
    for (m, t) in sol.moments.iter().zip([0.5, 2.0]) {
        let exact = 1.0 - (-0.7f64 * t).exp();
        assert!((m.mean[1] - exact).abs() < 1e-12, "t = {t}: {}", m.mean[1]);
        assert!((m.mean[0] - 2.0 * (1.0 - exact)).abs() < 1e-12);
    }
    // The binomial is z(z−1)/2, and several factors of one species multiply.
    let b = Factor::Binomial { k: 3 };
    for z in 0..10 {
        let zf = f64::from(z);
        assert_eq!(b.eval(zf), (zf * (zf - 1.0) * (zf - 2.0) / 6.0).max(0.0));
    }
    let two = DIMER.replace(
        r#"factors = [{ species = "P", kind = "binomial", k = 2 }]"#,
        r#"factors = [{ species = "P", kind = "linear" }, { species = "P", kind = "affine", offset = -1.0, slope = 1.0 }]"#,
    );
    let two = Network::from_toml(&two, "two.toml").expect("two factors of one species");
    for z in 0..3i64 {
        let a = net.propensity(0, &[z, 0], &[]);
        assert!((two.propensity(0, &[z, 0], &[]) - 2.0 * a).abs() < 1e-15);
    }
    // The affine factor stops at zero where its count runs out.
    let f = Factor::Affine {
        offset: 100.0,
        slope: -2.0,
    };
    assert_eq!((f.eval(10.0), f.eval(50.0), f.eval(51.0)), (80.0, 0.0, 0.0));
}

#[test]
fn a_reaction_that_could_drive_a_count_negative_is_refused_by_name() {
    // Constant-rate consumption: the SSA would go below zero, FSP would leak for ever.
    let text = DIMER.replace(
        r#"factors = [{ species = "P", kind = "binomial", k = 2 }]"#,
        "",
    );
    let err = Network::from_toml(&text, "const.toml")
        .expect_err("refused")
        .to_string();
    assert!(
        err.contains("dimerisation") && err.contains("below zero") && err.contains("P = 0"),
        "{err}"
    );
    // Order 1 for a change of −2 still lets P = 1 fire.
    let text = DIMER.replace(r#"kind = "binomial", k = 2"#, r#"kind = "linear""#);
    let err = Network::from_toml(&text, "linear.toml")
        .expect_err("refused")
        .to_string();
    assert!(
        err.contains("P = 1") && err.contains("binomial with k = 2"),
        "{err}"
    );
}

/// A minimal SBML Level 3 model with one species `S` and the law `law` (MathML).
fn sbml(law: &str, extra_reaction_attrs: &str, amount: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<sbml xmlns="http://www.sbml.org/sbml/level3/version1/core" level="3" version="1">
  <model id="m">
    <listOfCompartments><compartment id="c" size="1" constant="true"/></listOfCompartments>
    <listOfSpecies>
      <species id="S" compartment="c" initialAmount="{amount}" hasOnlySubstanceUnits="true" boundaryCondition="false" constant="false"/>
      <species id="T" compartment="c" initialAmount="0" hasOnlySubstanceUnits="true" boundaryCondition="false" constant="false"/>
    </listOfSpecies>
    <listOfParameters>
      <parameter id="V" value="3" constant="true"/>
      <parameter id="K" value="5" constant="true"/>
    </listOfParameters>
    <listOfReactions>
      <reaction id="use" reversible="false" {extra_reaction_attrs}>
        <listOfReactants><speciesReference species="S" stoichiometry="1" constant="true"/></listOfReactants>
        <listOfProducts><speciesReference species="T" stoichiometry="1" constant="true"/></listOfProducts>
        <kineticLaw><math xmlns="http://www.w3.org/1998/Math/MathML">{law}</math></kineticLaw>
      </reaction>
    </listOfReactions>
  </model>
</sbml>"#
    )
}

const MICHAELIS_MENTEN: &str = "<apply><divide/><apply><times/><ci>V</ci><ci>S</ci></apply>\
     <apply><plus/><ci>K</ci><ci>S</ci></apply></apply>";

#[test]
fn sbml_laws_become_separable_factors_with_the_same_values() {
    let net = Network::from_text(&sbml(MICHAELIS_MENTEN, "", "10"), "mm.xml").expect("imports");
    assert_eq!(
        net.parameters.len(),
        1,
        "V multiplies the law: a named rate parameter"
    );
    let p = [3.0];
    for z in 0..=10i64 {
        let zf = z as f64;
        let want = 3.0 * zf / (5.0 + zf);
        let got = net.propensity(0, &[z, 0], &p);
        assert!((got - want).abs() < 1e-14, "z = {z}: {got} vs {want}");
    }
    // Its TOML, written and read back, is the same network.
    let back = Network::from_toml(&net.to_toml(), "back.toml").expect("reads back");
    assert_eq!(back.reactions, net.reactions);
    // A Hill repression written as 1/(1 + (S/K)^2) and a power of a species.
    let hill = "<apply><times/><ci>S</ci><apply><divide/><cn>1</cn><apply><plus/><cn>1</cn>\
                <apply><power/><apply><divide/><ci>S</ci><ci>K</ci></apply><cn>2</cn></apply>\
                </apply></apply></apply>";
    let net = Network::from_text(&sbml(hill, "", "10"), "hill.xml").expect("imports");
    for z in 0..=10i64 {
        let zf = z as f64;
        let want = zf / (1.0 + (zf / 5.0).powi(2));
        assert!((net.propensity(0, &[z, 0], &[]) - want).abs() < 1e-14);
    }
}

#[test]
fn sbml_that_cannot_be_read_as_a_cme_is_refused_naming_why() {
    let sum_over_species = "<apply><plus/><ci>S</ci><ci>T</ci></apply>";
    let time = "<apply><times/><ci>S</ci><csymbol encoding=\"text\" \
                definitionURL=\"http://www.sbml.org/sbml/symbols/time\">t</csymbol></apply>";
    let cases = [
        (sbml(sum_over_species, "", "10"), "not separable"),
        (sbml(time, "", "10"), "time"),
        (sbml("<ci>S</ci>", "fast=\"true\"", "10"), "fast"),
        (sbml("<ci>S</ci>", "", "2.5"), "whole number"),
        (
            sbml("<ci>S</ci>", "", "10").replace("stoichiometry=\"1\"", "stoichiometry=\"0\""),
            "no reaction changes a species' count",
        ),
        (
            sbml("<ci>S</ci>", "", "10").replace("stoichiometry=\"1\"", "stoichiometry=\"1e10\""),
            "from 0 to 1000000",
        ),
        // Numbers past f64 read as infinity; a count past usize saturated to 2⁶⁴ − 1.
        (
            sbml("<ci>S</ci>", "", "1e30"),
            "at most 1073741824 molecules",
        ),
        (
            sbml("<apply><times/><ci>V</ci><ci>S</ci></apply>", "", "10")
                .replace("value=\"3\"", "value=\"1e400\""),
            "parameter V: value inf: expected a finite value",
        ),
        (sbml("<ci>Q</ci>", "", "10"), "unknown identifier"),
        (sbml("<apply><exp/><ci>S</ci></apply>", "", "10"), "<exp>"),
        (sbml("<ci>V</ci>", "", "10"), "below zero"),
        (
            sbml("<ci>S</ci>", "", "10").replace("reversible=\"false\"", "reversible=\"true\""),
            "reversible",
        ),
        (
            sbml("<ci>S</ci>", "", "10").replace("</model>", "<model>"),
            "XML",
        ),
    ];
    for (text, want) in cases {
        let err = Network::from_text(&text, "bad.xml")
            .expect_err(want)
            .to_string();
        assert!(
            err.contains(want) && err.contains("bad.xml"),
            "expected {want:?} in {err}"
        );
    }
}

const TWO: &str = r#"
name = "immigration with a bystander"
[[species]]
name = "x"
max = "auto"
initial = 0
[[species]]
name = "y"
max = "auto"
initial = 3
[[reactions]]
change = { x = 1 }
rate = [40.0]
factors = [{ species = "y", kind = "linear" }]
[[reactions]]
change = { x = -1 }
rate = [1.0]
factors = [{ species = "x", kind = "linear" }]
"#;

#[test]
fn a_toml_count_past_the_largest_initial_is_refused() {
    let huge = TWO.replace("initial = 3", "initial = 18446744073709551615");
    match Network::from_toml(&huge, "huge.toml") {
        Err(e) => assert!(
            ["huge.toml", "species y", "at most"]
                .iter()
                .all(|w| e.to_string().contains(w)),
            "{e}"
        ),
        Ok(_) => panic!("a count past 2^30 was accepted"),
    }
    let most = TWO.replace(
        "initial = 3",
        &format!("initial = {}", palpa_core::cme::network::MAX_INITIAL),
    );
    Network::from_toml(&most, "most.toml").expect("the largest initial is accepted");
}

#[test]
fn automatic_boxes_grow_only_where_probability_leaks() {
    let net = Network::from_toml(TWO, "two.toml").expect("parses");
    let (sol, met) = fsp::solve_auto(&net, &[], &[5.0], 1e-9).expect("solves");
    assert!(met);
    // y never changes: 0..=3, a point mass with exactly zero variance; x (mean 120,
    // sd 11) grew alone from 32, past mean + 6 sd.
    assert_eq!(sol.sizes[1], 4);
    assert!((186..256).contains(&sol.sizes[0]), "{:?}", sol.sizes);
    assert_eq!(sol.moments[0].var[1], 0.0);
    assert_eq!(sol.moments[0].mean[1], 3.0);
    let exact = 120.0 * (1.0 - (-5.0f64).exp());
    assert!((sol.moments[0].mean[0] - exact).abs() < 1e-6);
    // The PGD's boxes come from the same pre-pass.
    let (sized, how) = sizing::with_boxes(&net, 5.0).expect("sized");
    assert_eq!(
        sized.species.iter().map(|s| s.max).collect::<Vec<_>>(),
        sol.sizes.iter().map(|&m| Some(m)).collect::<Vec<_>>()
    );
    assert!(matches!(how, sizing::Sized::Fsp { leak } if leak <= 1e-9));
}

#[test]
fn a_fast_immigration_starts_with_a_short_step_and_stays_non_negative() {
    let text = TWO
        .replace("rate = [40.0]", "rate = [1000.0]")
        .replace("initial = 3", "initial = 1");
    let net = Network::from_toml(&text, "fast.toml").expect("parses");
    let recipe = build::Recipe::default_for(&net, 1.0);
    assert!(recipe.options.h_first <= 1e-4, "{}", recipe.options.h_first);
    let (sized, _) = sizing::with_boxes(&net, 1.0).expect("sized");
    let built = build::train(&sized, &recipe.options, Some(&[1.0]), &mut |_| {}).expect("solves");
    let e = built
        .model
        .evaluate(1.0, &[], usize::MAX)
        .expect("evaluates");
    // Poisson with mean 1000 (1 − e^{−1}).
    let mean = 1000.0 * (1.0 - (-1.0f64).exp());
    assert!(
        e.most_negative > -1e-8,
        "most negative {:.1e}",
        e.most_negative
    );
    assert!(
        (e.moments.mean[0] - mean).abs() < 1e-3 * mean,
        "{}",
        e.moments.mean[0]
    );
    let sd = e.moments.var[0].sqrt();
    assert!((sd - mean.sqrt()).abs() < 1e-3 * mean.sqrt(), "sd {sd}");
    // y, which no reaction changes, has the box 0..=1 and stays a point mass (to
    // round-off: 1.5e-17 here).
    assert_eq!(sized.species[1].max, Some(2));
    assert!(e.moments.var[1].abs() < 1e-14, "{:e}", e.moments.var[1]);
}

/// Mutated network files (bytes flipped, cut, repeated; seeded) give a network or an
/// error, never a panic: the SBML and TOML readers and everything a network that reads
/// is checked with (the no-negative-count rule, TOML round trip).
#[test]
fn mutated_network_files_never_panic() {
    use palpa_core::rng::Rng;
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let seeds: Vec<String> = ["00001", "00011", "00030", "00034", "00019"]
        .iter()
        .map(|c| {
            std::fs::read_to_string(root.join(format!("data/dsmts/{c}/{c}-sbml-l3v1.xml")))
                .expect("vendored")
        })
        .chain([DIMER.to_string(), TWO.to_string()])
        .collect();
    let mut rng = Rng::seed(21);
    let mut accepted = 0;
    for k in 0..3000 {
        let bytes = rng.mutate_bytes(
            seeds[k % seeds.len()].as_bytes(),
            b"<>/\"=0123456789-.eE x",
            4,
            40,
        );
        let text = String::from_utf8_lossy(&bytes);
        if let Ok(net) = Network::from_text(&text, "mutated") {
            accepted += 1;
            let _ = Network::from_toml(&net.to_toml(), "again");
        }
    }
    // Some mutations (inside numbers and names) still read: the test reaches past the
    // XML parser.
    assert!(accepted > 30, "{accepted} of 3000 mutated files read");
}

#[test]
fn a_conserved_pair_is_solved_with_one_species_less_and_expanded_back() {
    use palpa_core::cme::{conservation, dsmts};
    // 2P ⇌ P2 from 6 monomers: P + 2 P2 = 6, four states on a line of the 7 × 4 box.
    let text = DIMER
        .replace("max = 3\ninitial = 2", "max = 7\ninitial = 6")
        .replace("max = 2\ninitial = 0", "max = 4\ninitial = 0")
        + r#"
[[reactions]]
name = "dissociation"
change = { P = 2, P2 = -1 }
rate = [0.3]
factors = [{ species = "P2", kind = "linear" }]
"#;
    let net = Network::from_toml(&text, "dimer.toml").expect("parses");
    let r = conservation::reduce(&net).expect("P + 2 P2 is conserved");
    assert_eq!((r.eliminated, r.from, r.offset, r.slope), (0, 1, 6.0, -2.0));
    assert_eq!(r.network.species.len(), 1);
    // The reduced propensities are the original ones on the line.
    for p2 in 0..=3i64 {
        let p = 6 - 2 * p2;
        for k in 0..2 {
            let a = net.propensity(k, &[p, p2], &[]);
            assert!((r.network.propensity(k, &[p2], &[]) - a).abs() < 1e-12);
        }
    }
    let times = [0.5, 3.0];
    let exact = fsp::solve(&net, &[], &times).expect("FSP");
    let pgd = dsmts::solve_pgd(&net, &times, 3.0).expect("PGD");
    // Within the PGD's own accuracy (the DSMTS goal: 1e-3 relative, or absolute below 1).
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-3 * a.abs().max(1.0);
    for (e, m) in exact.moments.iter().zip(&pgd) {
        for i in 0..2 {
            assert!(
                close(e.mean[i], m.mean[i]),
                "{} vs {}",
                e.mean[i],
                m.mean[i]
            );
            assert!(
                close(e.var[i], m.var[i]),
                "var {} vs {}",
                e.var[i],
                m.var[i]
            );
        }
        // The covariance of the pair is exactly −2 var(P2) on the line.
        assert!(close(e.cov01, m.cov01), "{} vs {}", e.cov01, m.cov01);
        assert!((m.cov01 + 2.0 * m.var[1]).abs() < 1e-9);
    }
    // A saturation factor of P is not affine on the line: P2 is eliminated instead.
    let hill = text.replace(
        r#"factors = [{ species = "P2", kind = "linear" }]"#,
        r#"factors = [{ species = "P2", kind = "linear" }, { species = "P", kind = "saturation", beta = 1.0, gamma = 2.0 }]"#,
    );
    let hill = Network::from_toml(&hill, "hill.toml").expect("parses");
    let r = conservation::reduce(&hill).expect("P2 can go");
    assert_eq!((r.eliminated, r.from), (1, 0));
}
