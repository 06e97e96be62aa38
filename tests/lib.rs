//! Shared helpers of palpa's workspace-level integration tests.

use palpa_core::axis::Discretization;
use palpa_core::rng::Rng;
use palpa_core::synthetic::square_surface;
use palpa_core::{AxisInfo, FieldInfo, ModelMeta, Provenance, Scalar, SeparatedModel};

/// A small model with one axis of each kind: a probe surface (3×3 vertices), a force
/// grid (non-uniform, 4 nodes) and a direction axis (x, y, z). Entries are seeded
/// random numbers.
pub fn small_model<T: Scalar>(nodes: usize, modes: usize, seed: u64) -> SeparatedModel<T> {
    let mut rng = Rng::seed(seed);
    let axes = vec![
        AxisInfo {
            name: "probe position".into(),
            unit: "mm".into(),
            discretization: square_surface(3, 10.0),
        },
        AxisInfo {
            name: "force".into(),
            unit: "N".into(),
            discretization: Discretization::Grid {
                nodes: vec![0.0, 1.0, 2.5, 6.0],
            },
        },
        AxisInfo {
            name: "direction".into(),
            unit: "1".into(),
            discretization: Discretization::Discrete {
                labels: vec!["x".into(), "y".into(), "z".into()],
            },
        },
    ];
    let rows = 3 * nodes;
    let x = (0..rows * modes)
        .map(|_| T::from_f64(rng.range(-1.0, 1.0)))
        .collect();
    let values = axes
        .iter()
        .map(|a| {
            (0..a.discretization.node_count() * modes)
                .map(|_| T::from_f64(rng.range(-1.0, 1.0)))
                .collect()
        })
        .collect();
    let meta = ModelMeta {
        kind: "test".into(),
        field: FieldInfo {
            name: "displacement".into(),
            unit: "mm".into(),
            components: 3,
            node_ids: Vec::new(),
        },
        axes,
        provenance: Provenance::now(
            "test",
            "none",
            1e-6,
            (0..modes).map(|k| 0.5f64.powi(k as i32)).collect(),
        ),
        tradeoff: Vec::new(),
        geometry: Default::default(),
    };
    SeparatedModel::new(meta, rows, modes, x, values).expect("consistent shapes")
}

/// The largest node error, over grid depths, of a tissue law's reconstruction of
/// `sample` from the first `kept` modes of its group against the residual a press
/// computed, `computed(j)` at grid depth `j` (mm).
pub fn stored_error<'a>(
    t: &palpa_core::tissue::law::TissueLaw,
    sample: usize,
    kept: usize,
    computed: impl Fn(usize) -> &'a [f32],
) -> f64 {
    let (steps, m) = (t.steps as usize, 3 * t.rows_mm.len());
    let (modes, first) = t.sample_modes(sample);
    let mut worst = 0.0f64;
    for j in 0..steps {
        let computed = computed(j);
        for n in 0..m / 3 {
            let node = (0..3).map(|c| {
                let i = 3 * n + c;
                let stored: f64 = modes
                    .clone()
                    .take(kept)
                    .enumerate()
                    .map(|(k, mode)| {
                        t.shape.get(mode * m + i)
                            * f64::from(t.shape_scale[mode])
                            * f64::from(t.coeffs[first + k * steps + j])
                    })
                    .sum();
                (stored - f64::from(computed[i])).powi(2)
            });
            worst = worst.max(node.sum::<f64>().sqrt());
        }
    }
    worst
}

/// The procedural liver meshed at the coarse level with its own regions.
pub fn coarse_liver() -> palpa_core::organ::OrganMesh {
    use palpa_core::organ::liver::{Liver, spacing_mm};
    use palpa_core::organ::{Level, mesh_organ};
    let liver = Liver::default();
    mesh_organ(
        &liver,
        spacing_mm(Level::Coarse),
        &liver.fixed_region(),
        &liver.palpable_region(),
    )
}

/// The coarse liver's nodal setup (P2, the default material, a 5 mm tool) and the
/// point `depth_mm` under the surface point `at` along its smoothed inward normal,
/// with that normal: where the nodule tests put their nodules.
pub fn coarse_nodal_under(
    at: [f64; 3],
    depth_mm: f64,
) -> (
    palpa_core::organ::OrganMesh,
    palpa_core::pgd::nodal::NodalSetup,
    [f64; 3],
    [f64; 3],
) {
    use palpa_core::fe::{Element, Material};
    let organ = coarse_liver();
    let s = palpa_core::pgd::nodal::setup(&organ, Element::P2, Material::default(), 5.0)
        .expect("setup");
    let dir = palpa_core::fe::probe::smooth_inward_dir(&organ, at).expect("on the surface");
    let centre = [0, 1, 2].map(|d| at[d] + depth_mm * dir[d]);
    (organ, s, dir, centre)
}

/// The full linear FE (coarse P2 of `organ`, the default material) for `req` without a
/// nodule and with `nodule`.
pub fn fe_without_and_with(
    organ: &palpa_core::organ::OrganMesh,
    req: &palpa_core::fe::probe::ProbeRequest,
    nodule: palpa_core::fe::nodule::Nodule,
) -> (
    palpa_core::fe::probe::ProbeSolution,
    palpa_core::fe::probe::ProbeSolution,
) {
    use palpa_core::fe::probe::{ProbeRequest, solve_linear};
    use palpa_core::fe::{Element, Material};
    let solve = |r: &ProbeRequest| {
        solve_linear(organ, Element::P2, Material::default(), r).expect("solves")
    };
    let with = ProbeRequest {
        nodule: Some(nodule),
        ..*req
    };
    (solve(req), solve(&with))
}

/// The Poisson law with `mean` on `0..n` (the CME tests' closed form for
/// immigration–death from 0 copies).
pub fn poisson(mean: f64, n: usize) -> Vec<f64> {
    let mut p = vec![0.0; n];
    p[0] = (-mean).exp();
    for k in 1..n {
        p[k] = p[k - 1] * mean / k as f64;
    }
    p
}
