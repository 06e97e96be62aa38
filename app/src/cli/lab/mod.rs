//! `palpa lab …`: the tools of those who develop palpa, apart from what users run:
//! benchmarks that print ratios measured in one run, seeded synthetic models, the
//! tissue's staging tools (held-out points, cut, refine, band), and the record of what
//! made each shipped file.

pub mod accuracy;
pub mod asset;
mod band;
mod bench;
mod cut;
mod points;
mod refine;
mod synth;

use clap::Subcommand;

#[derive(Debug, Subcommand)]
pub enum LabCommand {
    /// Today's accuracy of the shipped scenes, from what their files record, as
    /// Markdown (the generated part of docs/accuracy.md).
    Accuracy(accuracy::AccuracyArgs),
    /// What made each shipped file: its hashes and commands in `assets/manifest.json`.
    #[command(subcommand)]
    Asset(AssetCommand),
    /// Benchmarks that print ratios measured in one run.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// Write a seeded synthetic model file (benchmarks, fuzz seeds, trying the tools).
    Synth(synth::SynthArgs),
    /// The tissue's staging tools: held-out points, cut, refine, band.
    #[command(subcommand)]
    Tissue(TissueStage),
}

#[derive(Debug, Subcommand)]
pub enum AssetCommand {
    /// Record a file just written under `assets/`: the xxh3 of its bytes (and of a
    /// `.palpa` file's payload) and the commands that made it.
    Record(asset::RecordArgs),
}

#[derive(Debug, Subcommand)]
pub enum TissueStage {
    /// Draw held-out points over the whole palpable surface (seeded) and print them as
    /// `X,Y,Z,…` for `tissue build --cover` and `tissue check --at`: a whole-surface
    /// accuracy table from the few triangles that hold them.
    Points(points::PointsArgs),
    /// Cut a built vademecum to fewer modes per sample (or per group of samples that
    /// share them), fewer bits or a longer depth step (what `palpa tradeoff` measures)
    /// and save it: a scene ships only what it shows. The stored bound grows by what
    /// the cut drops.
    Cut(cut::CutArgs),
    /// Split the triangles of a file built without splitting (`--no-refine`): their
    /// quarter and inner points pressed, the file's own presses kept as stored. Presses
    /// are logged in `OUT.presses.log` under the same key as `tissue build`'s, so a
    /// killed refinement run again goes on, and a larger `--triangles` later reuses them.
    Refine(refine::RefineArgs),
    /// Press the band next to the fixed region: the midpoint of every palpable edge from
    /// a pressed vertex to one on the fixed region (which no press may push), each kept
    /// as its surplus over its pressed end; the file's own presses kept as stored. The
    /// last stage: a file with a band is not split further. Presses are logged in
    /// `OUT.presses.log`, so a killed run again goes on.
    Band(band::BandArgs),
}

pub fn run(cmd: &LabCommand) -> anyhow::Result<()> {
    match cmd {
        LabCommand::Accuracy(args) => accuracy::run(args),
        LabCommand::Asset(AssetCommand::Record(args)) => asset::record(args),
        LabCommand::Bench(cmd) => bench::run(cmd),
        LabCommand::Synth(args) => synth::run(args),
        LabCommand::Tissue(TissueStage::Points(args)) => points::points(args),
        LabCommand::Tissue(TissueStage::Cut(args)) => cut::cut(args),
        LabCommand::Tissue(TissueStage::Refine(args)) => refine::refine(args),
        LabCommand::Tissue(TissueStage::Band(args)) => band::band(args),
    }
}
