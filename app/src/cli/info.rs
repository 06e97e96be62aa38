//! `palpa info FILE`: what a meta-model file holds, without loading its payload.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use palpa_core::file;
use serde_json::json;

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The meta-model file (a `.palpa` scene or network, a `.tissue` vademecum, a
    /// `.nodules` table).
    file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    // A tissue vademecum (`palpa tissue build`) has its own format.
    if palpa_core::tissue::law::is_tissue_file(&args.file) {
        let law = palpa_core::tissue::law::TissueLaw::load(&args.file)?;
        let summary = super::tissue::summary(&law, &args.file);
        return super::args::print_report(&summary, args.json);
    }
    if palpa_core::pgd::nodule::table::is_table_file(&args.file) {
        let table = palpa_core::pgd::nodule::table::EffectTable::load_shard(&args.file)?;
        return super::args::print_report(&super::nodule::summary(&table, &args.file), args.json);
    }
    let h = file::read_header(&args.file)
        .with_context(|| format!("reading the header of {}", args.file.display()))?;
    let m = &h.meta;
    let axes: Vec<_> = m
        .axes
        .iter()
        .map(|a| {
            json!({
                "name": a.name,
                "unit": a.unit,
                "discretization": a.discretization.kind_name(),
                "nodes": a.discretization.node_count(),
            })
        })
        .collect();
    // A scene built from a user's surface names its source in the provenance.
    let desc = &m.provenance.mesh;
    let get = |k| palpa_core::pgd::palpation::describe_get(desc, k);
    let source = (get("organ") == Some("user")).then(|| {
        json!({
            "file": get("source"), "xxh3": get("source_xxh3"), "units": get("units"),
            "axes": get("axes"), "regions": get("regions"), "level": get("level"),
            "element": get("element"), "tool_radius_mm": get("radius_mm"),
        })
    });
    let summary = json!({
        "source": source,
        "file": args.file,
        "kind": m.kind,
        "precision": h.precision.name(),
        "rows": h.rows,
        "modes": h.modes,
        "field": { "name": m.field.name, "unit": m.field.unit, "components": m.field.components },
        "axes": axes,
        "payload_bytes": h.payload_len,
        "content_xxh3": format!("{:016x}", h.content_xxh3()),
        // What two builds of the same model share however they ran: all but the build
        // date and timings (for a scene, its content).
        "payload_xxh3": format!("{:016x}", h.content_xxh3()),
        "file_bytes": std::fs::metadata(&args.file).map(|x| x.len()).ok(),
        // A nodal scene's near and far fields: most of its bytes.
        "near_field": h.layout.near_field_bytes().map(|(bits, bytes)| json!({"bits": bits, "bytes": bytes})),
        "provenance": {
            "solver": m.provenance.solver,
            "mesh": m.provenance.mesh,
            "tolerance": m.provenance.tolerance,
            "residual_per_mode": m.provenance.residual_per_mode,
            "created_unix_s": m.provenance.created_unix_s,
            "palpa_version": m.provenance.palpa_version,
            "input_hash": m.provenance.input_hash,
        },
        "tradeoff_rows": m.tradeoff.len(),
        "geometry": { "nodes": m.geometry.nodes.len(), "surface_triangles": m.geometry.surface.len() },
    });
    super::args::print_report(&summary, args.json)
}
