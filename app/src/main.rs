//! Desktop entry point: parse the command line, run it.

fn main() -> std::process::ExitCode {
    palpa_app::cli::main()
}
