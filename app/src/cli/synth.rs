//! `palpa synth`: writes a seeded synthetic model file (for benchmarks, fuzz seeds and
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
