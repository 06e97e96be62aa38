//! `palpa lab synth`: writes a seeded synthetic model file (for benchmarks, fuzz seeds and
//! trying the file tools without running a solver). Its values mean nothing physically.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use palpa_core::synthetic::palpation_like;
use palpa_core::{Precision, file};

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Field rows (rounded up to a multiple of 3).
    #[arg(long, default_value_t = 3000)]
    rows: usize,
    #[arg(long, default_value_t = 20)]
    modes: usize,
    #[arg(long, default_value = "f64")]
    precision: Precision,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: &SynthArgs) -> anyhow::Result<()> {
    if args.rows == 0 || args.modes == 0 {
        anyhow::bail!(
            "--rows {} --modes {}: expected at least one row and one mode",
            args.rows,
            args.modes
        );
    }
    // The spatial block alone is rows × modes values: refuse what memory cannot hold
    // rather than abort on a failed allocation.
    let bytes = (args.rows as f64) * (args.modes as f64) * args.precision.bytes() as f64;
    let available = crate::cli::memory::available_bytes().map_or(f64::INFINITY, |b| b as f64);
    if bytes > available / 2.0 {
        anyhow::bail!(
            "--rows {} --modes {}: {:.1} GB of values, {:.1} GB of memory available: expected a \
             model that fits in half of it",
            args.rows,
            args.modes,
            bytes / 1e9,
            available / 1e9
        );
    }
    let save = |r: Result<(), palpa_core::FileError>| {
        r.with_context(|| format!("writing {}", args.out.display()))
    };
    match args.precision {
        Precision::F32 => save(file::save(
            &palpation_like::<f32>(args.rows, args.modes, 12, args.seed),
            &args.out,
        ))?,
        Precision::F64 => save(file::save(
            &palpation_like::<f64>(args.rows, args.modes, 12, args.seed),
            &args.out,
        ))?,
    }
    println!("wrote {}", args.out.display());
    Ok(())
}
