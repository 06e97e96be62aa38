//! `palpa lab bench fe --only lanes`: the element kernels of a press, one quadrature point
//! at a time against four in vector lanes (`fe::lanes`), measured in one run.
//!
//! A real press: the pressable vertex nearest the anterior point of coarse P2, pushed
//! along its inward normal by the build's tool, neo-Hookean. Its rest series to twelve
//! orders gives the states: the higher orders' right-hand sides (orders 2–12 over
//! every cell, what a press's first series assembles), the internal force and the
//! tangent at the series' state 4 mm deep. Each kernel is run both ways on one
//! thread, the results compared entry by entry: the lanes are the scalar arithmetic,
//! so `largest_difference` is 0 and `identical` true, and the row says so rather than
//! assuming it.

use std::time::Instant;

use palpa_core::fe::elasticity::assemble;
use palpa_core::fe::hyper::element;
use palpa_core::fe::lanes;
use palpa_core::fe::law::Law;
use palpa_core::fe::newton::assemble_vector_on;
use palpa_core::fe::probe::organ_space;
use palpa_core::fe::series::{Expander, element_coefficient};
use palpa_core::fe::sparse::SymCsc;
use palpa_core::fe::{Element, Material};
use palpa_core::organ::OrganMesh;
use palpa_core::tissue::surface::{Pressing, SurfaceLawOptions, organ_vertex_normals};
use serde_json::json;

use super::build::nearest_vertex;

/// Residuals timed a row (one is a few milliseconds).
const RESIDUALS: usize = 20;

pub(super) fn lanes_table(coarse: &OrganMesh, near: [f64; 3]) -> anyhow::Result<()> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .thread_name(|i| format!("bench-lanes-{i}"))
        .build()?;
    pool.install(|| run(coarse, near))
}

fn run(coarse: &OrganMesh, near: [f64; 3]) -> anyhow::Result<()> {
    let o = SurfaceLawOptions::default();
    let law = Law::NeoHookean;
    let space = organ_space(coarse, Element::P2);
    let (lambda, mu) = Material::default().lame_n_per_mm2();
    let pressable = coarse.pressable_vertices();
    let v = nearest_vertex(coarse, &pressable, near)
        .ok_or_else(|| anyhow::anyhow!("the coarse liver has no pressable vertex"))?;
    let at = coarse.mesh.vertices[v as usize];
    let push = organ_vertex_normals(coarse)[v as usize].map(|c| -f64::from(c));
    let expander = Expander::new(&space, law, Material::default())?;
    let pressing = Pressing {
        space: &space,
        organ: coarse,
        expander: &expander,
        o: &o,
    };
    let (shape, probe) = pressing.tool_load(at, push)?;
    let series = expander.expand(&shape, &probe, 12)?;
    let cells: Vec<usize> = (0..space.cell_count()).collect();
    let state = series.displacement(4.0, 12);

    // Orders 2–12's right-hand sides over every cell.
    let coefficients = |lanes_on: bool| {
        (2..=12)
            .map(|p| {
                assemble_vector_on(&space, &cells, |c, fe| {
                    let lower = &series.u[..p - 1];
                    if lanes_on {
                        lanes::element_coefficient(&space, law, c, None, lower, p, lambda, mu, fe);
                    } else {
                        element_coefficient(&space, law, c, None, lower, p, lambda, mu, fe);
                    }
                })
            })
            .collect::<Vec<_>>()
    };
    row(
        "series_rhs",
        || coefficients(false).concat(),
        || coefficients(true).concat(),
    );

    let residuals = |lanes_on: bool| {
        let mut last = Vec::new();
        for _ in 0..RESIDUALS {
            last = assemble_vector_on(&space, &cells, |c, fe| {
                if lanes_on {
                    lanes::element_force(&space, law, c, &state, lambda, mu, fe);
                } else {
                    element(&space, law, c, &state, lambda, mu, fe, None);
                }
            });
        }
        last
    };
    row("residual", || residuals(false), || residuals(true));

    let pattern = SymCsc::pattern(&space);
    let tangent = |lanes_on: bool| {
        let mut k = pattern.clone();
        k.val.fill(0.0);
        assemble(&space, &mut k, |c, ke| {
            if lanes_on {
                lanes::element_tangent(&space, law, c, &state, lambda, mu, ke);
            } else {
                let mut fe = vec![0.0; ke.len().isqrt()];
                element(&space, law, c, &state, lambda, mu, &mut fe, Some(ke));
            }
        });
        k.val
    };
    row("tangent", || tangent(false), || tangent(true));
    Ok(())
}

/// Times `scalar` and `lanes` one after the other and prints their row.
fn row(kernel: &str, scalar: impl Fn() -> Vec<f64>, lanes: impl Fn() -> Vec<f64>) {
    let t = Instant::now();
    let a = scalar();
    let scalar_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let b = lanes();
    let lanes_s = t.elapsed().as_secs_f64();
    let same = |x: f64, y: f64| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan());
    let identical = a.len() == b.len() && a.iter().zip(&b).all(|(&x, &y)| same(x, y));
    let largest = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    println!(
        "{}",
        json!({
            "table": "lanes",
            "level": "coarse",
            "element": "p2",
            "law": "neo-hookean",
            "kernel": kernel,
            "runs": if kernel == "residual" { RESIDUALS } else { 1 },
            "entries": a.len(),
            "scalar_s": scalar_s,
            "lanes_s": lanes_s,
            "speedup": scalar_s / lanes_s,
            "largest_difference": largest,
            "identical": identical,
        })
    );
}
