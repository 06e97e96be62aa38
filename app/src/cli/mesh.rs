//! `palpa mesh`: mesh an organ, report counts, regions and element quality.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use palpa_core::export::{FieldValue, PointField, write_by_extension};
use palpa_core::fe::Element;
use palpa_core::fe::probe::organ_space;
use palpa_core::mesh::{quality, triangle_area};
use serde_json::json;

use super::args::OrganArgs;

#[derive(Debug, Args)]
pub struct MeshArgs {
    #[command(flatten)]
    organ: OrganArgs,
    /// Write the mesh (.vtu or .msh) with point data `fixed`.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(args: &MeshArgs) -> anyhow::Result<()> {
    let t = Instant::now();
    let organ = args.organ.mesh()?;
    let seconds = t.elapsed().as_secs_f64();
    let q = quality(&organ.mesh);
    let (lo, hi) = organ.mesh.bounding_box();
    let palpable_area: f64 = organ
        .boundary
        .iter()
        .zip(&organ.palpable)
        .filter(|(_, p)| **p)
        .map(|(f, _)| {
            let [a, b, c] = f.map(|i| organ.mesh.vertices[i as usize]);
            triangle_area(a, b, c)
        })
        .sum();
    let report = json!({
        "organ": match &args.organ.surface {
            Some(p) => p.display().to_string(),
            None => format!("{:?}", args.organ.organ).to_lowercase(),
        },
        "level": format!("{:?}", args.organ.level).to_lowercase(),
        "lattice_spacing_mm": organ.h_mm,
        "vertices": organ.mesh.vertices.len(),
        "tetrahedra": organ.mesh.tets.len(),
        "boundary_triangles": organ.boundary.len(),
        "bbox_mm": { "min": lo, "max": hi },
        "volume_ml": organ.mesh.volume() / 1000.0,
        "regions": {
            "fixed_vertices": organ.fixed.iter().filter(|&&f| f).count(),
            "palpable_triangles": organ.palpable.iter().filter(|&&p| p).count(),
            "palpable_area_cm2": palpable_area / 100.0,
        },
        "quality": q,
        "warped_lattice_vertices": organ.report.warped,
        "seconds": seconds,
    });
    if let Some(out) = &args.out {
        let space = organ_space(&organ, Element::P1);
        let fixed = PointField {
            name: "fixed".into(),
            components: 1,
            values: space
                .fixed
                .iter()
                .map(|&f| if f { 1.0 } else { 0.0 })
                .collect(),
        };
        write_by_extension(
            out,
            &space,
            &[fixed],
            &[FieldValue {
                name: "element_order".into(),
                value: 1.0,
            }],
        )
        .with_context(|| format!("writing {}", out.display()))?;
    }
    super::args::print_report(&report, args.json)
}
