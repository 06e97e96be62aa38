//! Helpers shared by the `palpa` binary's integration tests.

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
