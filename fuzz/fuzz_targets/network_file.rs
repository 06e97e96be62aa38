//! Fuzzes the network readers (SBML and TOML, told apart by content): any byte string
//! gives a network or an error, never a panic; a network that reads also writes TOML
//! that reads back. Run: `scripts/fuzz.sh 60 network_file`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use palpa_core::cme::Network;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(net) = Network::from_text(&text, "fuzz") {
        let _ = Network::from_toml(&net.to_toml(), "fuzz round trip");
    }
});
