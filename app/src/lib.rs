//! palpa-app: the command line and (as it lands) the interactive app.
//!
//! Platform entry points stay thin: `main.rs` calls [`cli::main`]; everything else is
//! plain library code that a test can call.

pub mod cli;
