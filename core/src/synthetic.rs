//! Reproducible random models for benchmarks and tests.
//!
//! A synthetic model has the shape of a palpation vademecum (3 components per node, a
//! probe-position surface axis, a force-magnitude grid axis) with seeded random entries.
//! Its values mean nothing physically; it exists so evaluator speed and file handling
//! can be measured at any size without running a solver.

use crate::axis::Discretization;
use crate::rng::Rng;
use crate::scalar::Scalar;
use crate::separated::{AxisInfo, FieldInfo, ModelMeta, Provenance, SeparatedModel};

/// A flat `side × side` vertex grid in the plane z = 0, split into triangles.
pub fn square_surface(side: usize, size_mm: f64) -> Discretization {
    let side = side.max(2);
    let h = size_mm / (side - 1) as f64;
    let vertices = (0..side * side)
        .map(|i| [(i % side) as f64 * h, (i / side) as f64 * h, 0.0])
        .collect();
    let mut triangles = Vec::with_capacity(2 * (side - 1) * (side - 1));
    for j in 0..side - 1 {
        for i in 0..side - 1 {
            let v = (j * side + i) as u32;
            let s = side as u32;
            triangles.push([v, v + 1, v + s + 1]);
            triangles.push([v, v + s + 1, v + s]);
        }
    }
    Discretization::Surface {
        vertices,
        triangles,
    }
}

/// A random model with `rows` field rows (3 per node), `modes` modes, a probe surface
/// axis of `surface_side²` vertices and a 9-node force grid on [0, 10] N.
pub fn palpation_like<T: Scalar>(
    rows: usize,
    modes: usize,
    surface_side: usize,
    seed: u64,
) -> SeparatedModel<T> {
    let rows = rows.div_ceil(3) * 3;
    let mut rng = Rng::seed(seed);
    let surface = square_surface(surface_side, 100.0);
    let force = Discretization::Grid {
        nodes: (0..9).map(|i| f64::from(i) * 1.25).collect(),
    };
    // Mode amplitudes decay like 1/k, as PGD modes of a smooth problem do.
    let x: Vec<T> = (0..rows * modes)
        .map(|i| T::from_f64(rng.range(-1.0, 1.0) / (1 + i % modes) as f64))
        .collect();
    let mut axis_values = |d: &Discretization| -> Vec<T> {
        (0..d.node_count() * modes)
            .map(|_| T::from_f64(rng.range(-1.0, 1.0)))
            .collect()
    };
    let values = vec![axis_values(&surface), axis_values(&force)];
    let meta = ModelMeta {
        kind: "synthetic".into(),
        field: FieldInfo {
            name: "displacement".into(),
            unit: "mm".into(),
            components: 3,
            node_ids: Vec::new(),
        },
        axes: vec![
            AxisInfo {
                name: "probe position s".into(),
                unit: "mm".into(),
                discretization: surface,
            },
            AxisInfo {
                name: "force magnitude".into(),
                unit: "N".into(),
                discretization: force,
            },
        ],
        provenance: Provenance::now("synthetic", "none", 0.0, vec![0.0; modes]),
        tradeoff: Vec::new(),
        geometry: Default::default(),
    };
    SeparatedModel::new(meta, rows, modes, x, values).expect("synthetic shapes are consistent")
}
