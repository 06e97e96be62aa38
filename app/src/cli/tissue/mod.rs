//! `palpa tissue build|check`: the hyperelastic vademecum of a palpation scene (force
//! and surface at every palpable point and depth), built off-line from full nonlinear
//! presses and checked against the full nonlinear FE at held-out points.
//!
//! `build` presses and compresses; `check` compares a file with Newton (and with another
//! file, `against`); `eval` reads a file bound to its scene; `points` draws the seeded
//! held-out points a check presses at; `tradeoff` measures a file's cost against its
//! accuracy for `palpa tradeoff`. The staging tools (cut, refine, band) are in `lab`.

pub(crate) mod against;
mod build;
mod check;
pub(crate) mod eval;
mod plan;
pub(crate) mod points;
mod shard;
pub(crate) mod tradeoff;

use clap::Subcommand;

pub use build::{BuildArgs, build, parse_bits, press_log, press_pool, progress_line, summary};
pub use eval::eval;

#[derive(Debug, Subcommand)]
pub enum TissueCommand {
    /// Build the nonlinear vademecum off-line by a recipe: every palpable vertex's (and
    /// edge midpoint's) press followed to equilibrium on the depth grid, the surfaces
    /// compressed by an SVD, then the recipe's stages (split triangles, the band next
    /// to the fixed region); finished presses are logged in `OUT.presses.log` and
    /// `OUT.stage-K.presses.log`, so a killed build run again goes on.
    Build(BuildArgs),
    /// Gather the logs of a build's shards (`tissue build … --shard I/N`) into the
    /// build's and go on: write the file (the same payload as one unsharded build), or
    /// say which step the shards are to run next; refused while a shard is incomplete.
    Merge(shard::MergeArgs),
    /// Compare a built vademecum with the full nonlinear FE (Newton) at held-out
    /// random points and depths, through a scene (what the app shows).
    Check(check::CheckArgs),
}

pub fn run(cmd: &TissueCommand) -> anyhow::Result<()> {
    match cmd {
        TissueCommand::Build(args) if args.plan => {
            let v = plan::run(args)?;
            if args.json {
                println!("{v}");
            } else {
                plan::print(&v);
            }
            Ok(())
        }
        TissueCommand::Build(args) => match args.shard {
            Some(shard) => shard::run_shard(args, shard).map(|v| println!("{v}")),
            None => build(args).map(|(_, summary)| println!("{summary}")),
        },
        TissueCommand::Merge(args) => shard::merge(args).map(|v| println!("{v}")),
        TissueCommand::Check(args) => check::check(args),
    }
}
