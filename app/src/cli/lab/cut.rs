//! `palpa lab tissue cut`: a tissue law with fewer modes, bits or depths, its band or
//! its split points dropped, or its weights rounded to sixteen bits, saved.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use palpa_core::tissue::law::{ShapeBits, TissueLaw};
use serde_json::json;

use crate::cli::tissue::{parse_bits, summary};

#[derive(Debug, Args)]
pub struct CutArgs {
    /// A tissue file (from `palpa tissue build`).
    tissue: PathBuf,
    /// Most modes a sample (or a group of samples sharing them) keeps: its first, by
    /// singular value.
    #[arg(long, default_value_t = palpa_core::tissue::law::MAX_RANK)]
    modes: usize,
    /// Bits per stored shape entry: 8 or 16 (default: as built).
    #[arg(long, value_parser = parse_bits)]
    bits: Option<u32>,
    /// Keep every k-th grid depth (k must divide the grid's intervals).
    #[arg(long, default_value_t = 1)]
    depth_stride: usize,
    /// Drop the split triangles' quarter and inner points: the quadratic blend
    /// everywhere, as a build with `--no-refine` stores the same presses (what `palpa
    /// tissue refine` starts from).
    #[arg(long)]
    unsplit: bool,
    /// Drop the band next to the fixed region (`palpa lab tissue band`): the file it was
    /// pressed on. (`--unsplit` drops it too.)
    #[arg(long)]
    no_band: bool,
    /// Round every weight to sixteen bits (IEEE half): what a build stores now (the
    /// fifth-stage shipped law: 7.65 → 6.18 MB). The bound grows by the most that
    /// moves a node (`weights_halved_mm`).
    #[arg(long)]
    half_weights: bool,
    /// Where to write the cut law (atomically; it may be the input).
    #[arg(long)]
    out: PathBuf,
}

/// `palpa lab tissue cut`: a law with fewer modes, bits or depths, saved.
pub fn cut(args: &CutArgs) -> anyhow::Result<()> {
    let law = TissueLaw::load(&args.tissue)?;
    let without = args.no_band.then(|| law.without_band());
    let unsplit = args
        .unsplit
        .then(|| without.as_ref().unwrap_or(&law).unsplit())
        .or(without);
    let bits = match args.bits {
        None => law.shape.bits(),
        Some(b) => ShapeBits::from_count(b).context("--bits: expected 8 or 16")?,
    };
    let cut = unsplit
        .as_ref()
        .unwrap_or(&law)
        .coarsened(args.modes, bits, args.depth_stride)
        .map_err(|why| anyhow::anyhow!("cutting {}: {why}", args.tissue.display()))?;
    let (out, halved_mm) = match args.half_weights {
        true => cut.law.with_half_weights(),
        false => (cut.law, 0.0),
    };
    out.save(&args.out)?;
    let summary = json!({
        "from": summary(&law, &args.tissue),
        "out": summary(&out, &args.out),
        "dropped_sigma_mm": cut.dropped_sigma_mm,
        "requantized_mm": cut.requantized_mm,
        "weights_halved_mm": halved_mm,
    });
    crate::cli::args::print_report(&summary, false)
}
