//! Desktop entry point: parse the command line, run it. The command-line layer lives
//! in the binary's own module tree, so the mobile `cdylib` does not compile it.

mod cli;
#[cfg(target_os = "linux")]
mod runtime_dir;

fn main() -> std::process::ExitCode {
    // First, while this is the only thread: the environment may change only now.
    #[cfg(target_os = "linux")]
    runtime_dir::ensure();
    cli::main()
}
