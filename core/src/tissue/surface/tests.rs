use std::collections::HashSet;

use super::*;
use crate::tissue::presser::Logged;
use crate::tissue::refine::{RefinePlan, RefinePoint, in_plan_order};

/// Two sampled vertices (0 and 1) of three, one row, depths 0, 1, 2 mm: the blend is
/// exact at a vertex, renormalizes over the sampled corners, is linear in depth and
/// holds the last depth beyond the grid.
#[test]
fn the_blend_is_exact_at_vertices_and_linear_in_depth() {
    let options = SurfaceLawOptions {
        depth_max_mm: 2.0,
        depth_step_mm: 1.0,
        ..SurfaceLawOptions::default()
    };
    // residual[sample][depth][c]: vertex 0 moves along x by d², vertex 1 along y by 2d².
    let mut residual = Vec::new();
    for s in 0..2 {
        for j in 0..3 {
            let d2 = (j * j) as f32;
            residual.extend(if s == 0 {
                [d2, 0.0, 0.0]
            } else {
                [0.0, 2.0 * d2, 0.0]
            });
        }
    }
    let law = SurfaceLaw {
        options,
        rows: vec![7],
        sample_of: vec![0, 1, u32::MAX],
        samples: vec![0, 1],
        skipped: vec![],
        edges: vec![],
        edge_skip_reasons: vec![],
        skip_reasons: vec![],
        refinement: Refinement::default(),
        refine_skip_reasons: vec![],
        split_figures: vec![],
        reach: vec![3; 2],
        stopped: vec![String::new(); 2],
        steps: 3,
        residual,
        ratio: vec![1.0; 6],
        stiffness_n_per_mm: vec![1.0; 2],
        correction_mm: vec![0.0; 2],
        segments: vec![1; 2],
        build_s: 0.0,
    };
    let at = |bary: [f64; 3], d: f64| {
        let mut out = [0.0; 3];
        assert!(law.add_residual([0, 1, 2], bary, d, &mut out));
        out
    };
    assert_eq!(at([1.0, 0.0, 0.0], 2.0), [4.0, 0.0, 0.0]);
    assert_eq!(at([0.0, 1.0, 0.0], 1.0), [0.0, 2.0, 0.0]);
    // Corner 2 is not sampled: (0.25, 0.25) renormalizes to (0.5, 0.5).
    assert_eq!(at([0.25, 0.25, 0.5], 2.0), [2.0, 4.0, 0.0]);
    // Linear between grid depths 1 and 2: 2.5 for vertex 0 at 1.5 mm.
    assert_eq!(at([1.0, 0.0, 0.0], 1.5), [2.5, 0.0, 0.0]);
    assert_eq!(at([1.0, 0.0, 0.0], 9.0), [4.0, 0.0, 0.0], "held at the end");
    let mut out = [0.0; 3];
    assert!(!law.add_residual([2, 2, 2], [1.0, 0.0, 0.0], 1.0, &mut out));
}

/// Two split triangles sharing an edge (its two quarter points listed once), the
/// second the worse: a stage presses the second's nine points first, then the
/// first's seven others, and a log holding a prefix of that order is ready for
/// whole triangles only.
#[test]
fn a_stage_presses_its_worst_triangle_first() {
    let point = |id: u32| RefinePoint {
        at: vec![],
        base: vec![],
        near: vec![],
        id,
    };
    let plan = RefinePlan {
        above: 2,
        triangles: vec![[0, 1, 2], [1, 2, 3]],
        // Triangle 1 reuses quarter points 0 and 1 (the shared edge).
        figures: vec![
            (1.0, [0, 1, 2, 3, 4, 5], [0, 1, 2]),
            (2.0, [1, 0, 6, 7, 8, 9], [3, 4, 5]),
        ],
        quarters: (0..10).map(|k| point(100 + k)).collect(),
        inner: (0..6).map(|k| point(200 + k)).collect(),
    };
    let order = plan.press_order();
    assert_eq!(
        order,
        [1, 0, 6, 7, 8, 9, 13, 14, 15, 2, 3, 4, 5, 10, 11, 12],
        "the worse triangle's nine, then the rest of the other's"
    );
    let ids: Vec<u32> = plan.press_ids().collect();
    let held = |n: usize| -> HashSet<u32> { order[..n].iter().map(|&k| ids[k]).collect() };
    assert_eq!(plan.ready(&held(0)), 0);
    assert_eq!(
        plan.ready(&held(8)),
        0,
        "one of the worse triangle's missing"
    );
    assert_eq!(plan.ready(&held(9)), 1);
    assert_eq!(plan.ready(&held(15)), 1);
    assert_eq!(plan.ready(&held(16)), 2);
    // The better triangle whole but not the worse: nothing is ready.
    let better: HashSet<u32> = plan.triangle_points(0).map(|k| ids[k]).collect();
    assert_eq!(plan.ready(&better), 0);
    // Presses made in that order come back in the plan's.
    let pressed: Vec<Logged> = order.iter().map(|&k| Err(format!("{k}"))).collect();
    let back = in_plan_order(&order, pressed);
    for (k, p) in back.iter().enumerate() {
        assert_eq!(p.as_ref().err(), Some(&format!("{k}")));
    }
}
