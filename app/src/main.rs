//! Desktop entry point: parse the command line, run it. The command-line layer lives
//! in the binary's own module tree, so the mobile `cdylib` does not compile it.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
