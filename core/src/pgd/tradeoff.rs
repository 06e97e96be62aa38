//! The speed/accuracy table of a nodal-load vademecum, measured where the user is.
//!
//! For n = 1 … N global modes (log steps) and, at all modes, for the far field's
//! tolerance knob (the stored tolerance times 1, 2, 5, 10, 30, and no far field):
//! the held-out errors of [`super::heldout`] (surface relative L2, largest nodal error,
//! compliance) with and without the near field, the time of what a frame runs
//! (particularize, the surface rows, near and far field), the time of what the force
//! loop runs (the compliance tensor at a point) and the bytes a surface-only f32 scene
//! carries.

use std::time::Instant;

use thiserror::Error;

use super::heldout::{self, Case, Errors};
use crate::axis::ParamValue;
use crate::fe::elasticity::LinearProblem;
use crate::fe::probe::organ_space;
use crate::fe::{Element, FeError, Material};
use crate::organ::OrganMesh;
use crate::separated::{EvalError, SeparatedModel, node_rows};

/// Why a table could not be measured.
#[derive(Debug, Error)]
pub enum TradeoffError {
    #[error("the held-out FE reference failed: {0}")]
    Fe(#[from] FeError),
    #[error("evaluating the model at a held-out point: {0}")]
    Eval(#[from] EvalError),
    #[error("a nodal model without its near field (or with a compliance table on no face)")]
    NoNearField,
}

/// One mode count.
#[derive(Debug, Clone, PartialEq)]
pub struct ModesRow {
    pub modes: usize,
    pub errors: Errors,
    /// The same modes without the near field (what an older file gives).
    pub without_near: Errors,
    pub surface_eval_us: f64,
    pub contact_eval_ns: f64,
    pub bytes: u64,
}

/// One far-field tolerance (`None`: without the far field), at all modes.
#[derive(Debug, Clone, PartialEq)]
pub struct FarRow {
    pub tolerance: Option<f64>,
    pub modes: usize,
    pub errors: Errors,
    pub surface_eval_us: f64,
    pub bytes: u64,
}

/// The whole table.
#[derive(Debug, Clone)]
pub struct NodalTable {
    pub rows: Vec<ModesRow>,
    pub far_rows: Vec<FarRow>,
    /// The held-out presses (their kinds and points name the worst cases).
    pub cases: Vec<Case>,
    /// Seconds spent on the held-out FE solves.
    pub fe_reference_s: f64,
}

/// Seed of the held-out points (the same in every table, so tables compare).
pub const HELD_OUT_SEED: u64 = 0x7e57;

/// Measures the table of a nodal-load `model` built on `organ` with this element,
/// material and tool radius: `random` random held-out points plus the special ones.
pub fn nodal_table(
    model: &SeparatedModel<f64>,
    organ: &OrganMesh,
    element: Element,
    material: Material,
    radius_mm: f64,
    random: usize,
) -> Result<NodalTable, TradeoffError> {
    let t0 = Instant::now();
    let space = organ_space(organ, element);
    let problem = LinearProblem::new(&space, material)?;
    let cases = heldout::cases(&space, &problem, organ, radius_mm, random, HELD_OUT_SEED)?;
    let fe_reference_s = t0.elapsed().as_secs_f64();
    let surface_nodes = organ.surface_nodes();
    let surface_rows = node_rows(&surface_nodes);
    let n_max = model.modes();
    let mut ns: Vec<usize> = [1, 2, 5, 10, 20, 50, 100, 150, 200, 300, 400]
        .into_iter()
        .filter(|&n| n < n_max)
        .collect();
    ns.push(n_max);
    let axis_nodes = model.axes()[0].info.discretization.node_count();
    let scene_bytes = |m: &SeparatedModel<f64>, n: usize| {
        ((surface_rows.len() + axis_nodes) * n * 4 + m.near().map_or(0, |nf| nf.bytes())) as u64
    };
    let near = model.near().ok_or(TradeoffError::NoNearField)?;
    let face0 = near
        .table_block
        .iter()
        .position(|&b| b != u32::MAX)
        .ok_or(TradeoffError::NoNearField)? as u32;
    let probe = [ParamValue::SurfaceMix {
        triangle: face0,
        bary: [1.0 / 3.0; 3],
        mix: cases.first().map_or([0.0, 0.0, 1.0], |c| c.dir),
    }];
    let contact_eval_ns = contact_ns(near, face0);
    let bare = model.clone().without_near();
    let mut rows = Vec::with_capacity(ns.len());
    for &n in &ns {
        rows.push(ModesRow {
            modes: n,
            errors: heldout::nodal_errors(model, &space, &cases, &surface_nodes, n)?,
            without_near: heldout::nodal_errors(&bare, &space, &cases, &surface_nodes, n)?,
            surface_eval_us: frame_us(model, &probe, &surface_rows, n)?,
            contact_eval_ns,
            bytes: scene_bytes(model, n),
        });
    }
    let mut far_rows = Vec::new();
    if let Some(t) = near.far.as_ref().map(|f| f.tolerance) {
        let tols = [1.0, 2.0, 5.0, 10.0, 30.0].map(|f| Some(f * t));
        for tolerance in tols.into_iter().chain([None]) {
            let m = model.clone().with_far_tolerance(tolerance);
            far_rows.push(FarRow {
                tolerance,
                modes: n_max,
                errors: heldout::nodal_errors(&m, &space, &cases, &surface_nodes, n_max)?,
                surface_eval_us: frame_us(&m, &probe, &surface_rows, n_max)?,
                bytes: scene_bytes(&m, n_max),
            });
        }
    }
    Ok(NodalTable {
        rows,
        far_rows,
        cases,
        fe_reference_s,
    })
}

/// Mean time of one frame's evaluation (µs): particularize, the surface rows, the
/// near and far field.
fn frame_us(
    model: &SeparatedModel<f64>,
    probe: &[ParamValue],
    surface_rows: &[u32],
    n: usize,
) -> Result<f64, EvalError> {
    let mut coeffs = vec![0.0; n];
    let mut out = vec![0.0; surface_rows.len()];
    let mut full = vec![0.0; model.rows()];
    let reps = 20;
    let t = Instant::now();
    for _ in 0..reps {
        model.particularize(std::hint::black_box(probe), &mut coeffs)?;
        model.reconstruct_rows(surface_rows, &coeffs, &mut out);
        model.add_near_field(probe, &mut full)?;
    }
    Ok(t.elapsed().as_secs_f64() * 1e6 / f64::from(reps))
}

/// Mean time of the force loop's evaluation (ns): the compliance tensor at a point.
fn contact_ns(near: &crate::nearfield::NearField, face: u32) -> f64 {
    let reps = 20_000u32;
    let t = Instant::now();
    let mut acc = 0.0;
    for i in 0..reps {
        let b = f64::from(i % 7) * 0.1;
        if let Some(ct) = near.compliance_tensor(
            face,
            std::hint::black_box([0.2 + b * 0.5, 0.3, 0.5 - b * 0.5]),
        ) {
            acc += ct[2][2];
        }
    }
    std::hint::black_box(acc);
    t.elapsed().as_nanos() as f64 / f64::from(reps)
}
