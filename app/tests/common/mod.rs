//! Helpers shared by the `palpa` binary's integration tests.

// Each test binary compiles this module and uses only some of its helpers.
#![allow(dead_code)]

use std::process::Output;

/// Asserts the command succeeded (showing its stderr otherwise) and parses its stdout
/// as one JSON object.
pub fn json_ok(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

/// Asserts the command succeeded (showing its stderr otherwise) and parses each line
/// of its stdout as one JSON object.
pub fn json_lines_ok(out: &Output) -> Vec<serde_json::Value> {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object a line"))
        .collect()
}

/// Builds the toggle switch's meta-model on [0, 2] (steps ≤ 0.1: small and quick) into
/// `path`: the network scene the GPU, touch and lifecycle tests open.
pub fn small_toggle(path: &std::path::Path) {
    use palpa_core::cme::network::Network;
    use palpa_core::cme::{build, ttsolve};
    let net = Network::built_in("toggle").expect("built in");
    let options = ttsolve::Options {
        t_end: 2.0,
        h_max: 0.1,
        ..ttsolve::Options::default()
    };
    let built = build::train(&net, &options, None, &mut |_| {}).expect("builds");
    built.save(&net, path).expect("save");
}
