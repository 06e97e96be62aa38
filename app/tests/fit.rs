//! Rates from data through the command line and the network scene: an SBML model made
//! a meta-model with a range (`cme offline --range`), data from `cme simulate`, `cme fit`
//! with its intervals and posterior, the refusals by name, the scene's overlay and fit
//! headless, and a propensity that overflows refused by all three solvers.

use std::process::Command;

use crate::common;

fn palpa(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(args)
        .output()
        .expect("palpa runs")
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

const SBML: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../tests/data/dsmts/00001/00001-sbml-l3v1.xml"
);

/// The DSMTS birth–death model (SBML) with its death rate Mu a coordinate, and snapshot
/// data at Mu = 0.117 (off the 12-point grid).
fn birth_death(dir: &std::path::Path) -> (String, String) {
    let model = dir.join("bd.palpa").display().to_string();
    let data = dir.join("bd.csv").display().to_string();
    let out = palpa(&[
        "cme",
        "offline",
        SBML,
        "--range",
        "Mu=0.08:0.14:12",
        "--t-end",
        "20",
        "--out",
        &model,
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = palpa(&[
        "cme",
        "simulate",
        &model,
        "--param",
        "Mu=0.117",
        "--t",
        "5,10,15,20",
        "--cells",
        "500",
        "--seed",
        "4",
        "--out",
        &data,
    ]);
    let v = common::json_ok(&out);
    assert_eq!(v["observed"], serde_json::json!(["X"]), "{v}");
    (model, data)
}

#[test]
fn an_sbml_model_s_rate_is_fitted_from_simulated_data_end_to_end() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (model, data) = birth_death(dir.path());
    let v = common::json_ok(&palpa(&[
        "cme",
        "fit",
        &model,
        "--data",
        &data,
        "--posterior",
        "400",
        "--json",
    ]));
    let mu = &v["estimates"]["Mu"];
    let ci = |key: &str| -> [f64; 2] {
        [
            mu[key][0].as_f64().expect("lo"),
            mu[key][1].as_f64().expect("hi"),
        ]
    };
    let (profile, fisher) = (ci("profile_ci95"), ci("fisher_ci95"));
    let mle = mu["mle"].as_f64().expect("mle");
    assert!(profile[0] < 0.117 && 0.117 < profile[1], "{v}");
    assert!(profile[0] < mle && mle < profile[1], "{v}");
    assert!(
        ((fisher[1] - fisher[0]) / (profile[1] - profile[0]) - 1.0).abs() < 0.1,
        "{v}"
    );
    assert_eq!(v["fitted"], serde_json::json!(["Mu"]));
    assert_eq!(
        v["fixed"],
        serde_json::json!({}),
        "Lambda is not a coordinate"
    );
    assert!(v["likelihood_us"].as_f64().is_some() && v["fsp_likelihood_us"].as_f64().is_some());
    // The meta-model's log-likelihood at its maximum is FSP's there (measured 0.10 apart
    // in 8 000, a twentieth of the 1.92 that sets an interval).
    let (ours, exact) = (
        v["log_likelihood"].as_f64().expect("ll"),
        v["fsp_log_likelihood_at_mle"].as_f64().expect("fsp ll"),
    );
    assert!((ours - exact).abs() < 0.3, "{ours} vs {exact}");
    let post = &v["posterior"]["rates"]["Mu"];
    assert!(post["rhat"].as_f64().expect("rhat") < 1.1, "{v}");
    let (lo, hi) = (
        post["ci95"][0].as_f64().expect("lo"),
        post["ci95"][1].as_f64().expect("hi"),
    );
    assert!(lo < 0.117 && 0.117 < hi, "{v}");
}

#[test]
fn data_and_rates_the_model_cannot_take_are_refused_by_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (model, _) = birth_death(dir.path());
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("writes");
        p.display().to_string()
    };
    let cases = [
        (write("row.csv", "t,X\n5,100\n5,9x\n"), vec![], "line 3"),
        (write("time.csv", "t,X\n5,100\n25,90\n"), vec![], "t = 25"),
        (
            write("box.csv", "t,X\n5,100\n5,100000\n"),
            vec!["100000"],
            "box",
        ),
        (write("species.csv", "t,Y\n5,100\n"), vec![], "\"Y\""),
    ];
    for (file, more, says) in &cases {
        let out = palpa(&["cme", "fit", &model, "--data", file]);
        let err = stderr(&out);
        assert!(!out.status.success() && err.contains(says), "{file}: {err}");
        for m in more {
            assert!(err.contains(m), "{file}: {err}");
        }
    }
    let ok = write("ok.csv", "t,X\n5,100\n10,90\n");
    let out = palpa(&["cme", "fit", &model, "--data", &ok, "--fit", "Lambda"]);
    assert!(
        stderr(&out).contains("no rate \"Lambda\"") && stderr(&out).contains("Mu"),
        "{}",
        stderr(&out)
    );
    let out = palpa(&[
        "cme", "simulate", &model, "--t", "5", "--cells", "0", "--out", &ok,
    ]);
    assert!(stderr(&out).contains("--cells 0"), "{}", stderr(&out));
}

/// The scene with the data: the log-likelihood at the sliders' rates is the command
/// line's, "Fit" moves the slider to the command line's maximum, and the posterior runs
/// (headless, as the panel's buttons do).
#[test]
fn the_network_scene_overlays_the_data_and_fits_headless() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (model, data) = birth_death(dir.path());
    let cli = common::json_ok(&palpa(&["cme", "fit", &model, "--data", &data, "--json"]));
    let out = palpa(&[
        "headless",
        "--scene",
        &model,
        "--data",
        &data,
        "--fit",
        "--posterior",
        "300",
        "--frames",
        "2",
        "--size",
        "640x400",
        "--json",
    ]);
    let v = common::json_ok(&out);
    let d = &v["data"];
    assert_eq!(d["cells"], 2000, "{v}");
    let mle = cli["estimates"]["Mu"]["mle"].as_f64().expect("mle");
    assert_eq!(d["estimates"][0]["name"], "Mu");
    assert!(
        (d["estimates"][0]["mle"].as_f64().expect("mle") - mle).abs() < 1e-12,
        "{v}"
    );
    let slider = v["last_coordinates"][1]["value"].as_f64().expect("Mu");
    assert!(
        (slider - mle).abs() < 1e-12,
        "the slider moved to the maximum: {v}"
    );
    let ll = d["log_likelihood"].as_f64().expect("ll");
    assert!(
        (ll - cli["log_likelihood"].as_f64().expect("ll")).abs() < 1e-6,
        "{v}"
    );
    assert!(d["posterior_rhat"].as_f64().expect("rhat") < 1.2, "{v}");
    // Data flags on a palpation scene are refused, naming the kind.
    let out = palpa(&["headless", "--data", &data, "--frames", "1"]);
    assert!(stderr(&out).contains("network scene"), "{}", stderr(&out));
}

/// A dimerisation of 100 monomers at k1 = 1e308 overflows its propensity: every
/// solver says so instead of stepping for minutes.
#[test]
fn a_propensity_that_overflows_is_refused_by_every_solver() {
    let dir = tempfile::tempdir().expect("tempdir");
    let net = dir.path().join("dimer.toml");
    std::fs::write(
        &net,
        "name = \"dimer\"\n[[species]]\nname = \"M\"\nmax = 101\ninitial = 100\n\
         [[species]]\nname = \"D\"\nmax = 51\ninitial = 0\n\
         [[parameters]]\nname = \"k1\"\nvalue = 1e308\n\
         [[reactions]]\nname = \"dimerisation\"\nchange = { M = -2, D = 1 }\nrate = [\"k1\"]\n\
         factors = [{ species = \"M\", kind = \"binomial\", k = 2 }]\n",
    )
    .expect("writes");
    let net = net.display().to_string();
    for method in ["fsp", "ssa", "pgd"] {
        let out = palpa(&["cme", "solve", &net, "--method", method, "--t", "1"]);
        let err = stderr(&out);
        assert!(!out.status.success(), "{method}");
        assert!(
            err.contains("dimerisation") && err.contains("overflow"),
            "{method}: {err}"
        );
    }
    // 1e20 is large but finite: answered.
    let mild = std::fs::read_to_string(&net)
        .expect("reads")
        .replace("1e308", "1e20");
    std::fs::write(&net, mild).expect("writes");
    let v = common::json_ok(&palpa(&[
        "cme", "solve", &net, "--method", "fsp", "--t", "1", "--json",
    ]));
    assert!(
        (v["mean"][0][1].as_f64().expect("D") - 50.0).abs() < 1e-9,
        "{v}"
    );
}
