use super::*;
use crate::axis::ProbePoint;
use crate::tissue::bound::{BoundTissue, TissueScratch};

/// `law` (its vertices at `corners`) bound to the triangles `[0, 1, 2]` and
/// `[1, 0, 3]`, which share the edge 0–1.
pub(crate) fn bind_two(law: TissueLaw, corners: &[[f64; 2]]) -> BoundTissue {
    let axis: Vec<[f64; 3]> = corners.iter().map(|p| [p[0], p[1], 0.0]).collect();
    let triangles = [[0, 1, 2], [1, 0, 3]];
    BoundTissue::bind(law, &[[0.0, 0.0, 5.0]], &axis, &triangles).expect("binds")
}

/// The one row's x at 1 mm, pressed at `bary` of `triangle`.
pub(crate) fn row_x(
    bound: &BoundTissue,
    scratch: &mut TissueScratch,
    triangle: u32,
    bary: [f64; 3],
) -> f64 {
    let mut rows = [0.0; 3];
    let p = ProbePoint { triangle, bary };
    assert!(bound.add_surface(&p, 1.0, scratch, &mut rows));
    rows[0]
}

/// A law of one row and depths 0 and 1 mm whose samples (vertices at `corners`,
/// in the plane z = 0, then `edge_ends`' and `refinement`'s) each hold one mode:
/// the row's x residual `x[s]` at 1 mm, force ratio 0.5 there.
pub(crate) fn one_row_law(
    corners: &[[f64; 2]],
    edge_ends: Vec<[u32; 2]>,
    refinement: Refinement,
    x: &[f64],
) -> TissueLaw {
    one_row_law_with_ratio(corners, edge_ends, refinement, x, &vec![0.5; x.len()])
}

/// [`one_row_law`] with sample `s`'s force ratio `g[s]` at 1 mm.
pub(crate) fn one_row_law_with_ratio(
    corners: &[[f64; 2]],
    edge_ends: Vec<[u32; 2]>,
    refinement: Refinement,
    x: &[f64],
    g: &[f64],
) -> TissueLaw {
    let n = x.len();
    let vertices = corners.len();
    let law = TissueLaw {
        options: SurfaceLawOptions {
            depth_max_mm: 1.0,
            depth_step_mm: 1.0,
            ..SurfaceLawOptions::default()
        },
        rows_mm: vec![[0.0, 0.0, 5.0]],
        samples_mm: corners
            .iter()
            .map(|p| [p[0] as f32, p[1] as f32, 0.0])
            .collect(),
        skipped_mm: vec![],
        edge_ends,
        refinement,
        steps: 2,
        ratio: (0..n)
            .flat_map(|s| [if s < vertices { 1.0 } else { 0.0 }, g[s] as f32])
            .collect(),
        stiffness_n_per_mm: vec![1.0; n],
        correction_mm: vec![0.0; n],
        segments: vec![1; n],
        reach: vec![2; n],
        stopped: vec![String::new(); n],
        rank: 1,
        mode_start: (0..=n as u32).collect(),
        group: (0..n as u32).collect(),
        coeff_start: (0..=n as u32).map(|s| 2 * s).collect(),
        shape: Shapes::Sixteen([i16::MAX, 0, 0].repeat(n)),
        shape_scale: vec![1.0 / f32::from(i16::MAX); n],
        coeffs: x.iter().flat_map(|&v| [0.0, v as f32]).collect(),
        truncation_bound_mm: 0.0,
        tolerance_mm: 0.05,
        build_s: 0.0,
        compress_s: 0.0,
        mesh_xxh3: Some(0x0123_4567_89ab_cdef),
        accuracy: Default::default(),
    };
    law.check().expect("consistent");
    law
}

/// One triangle (samples 0, 1, 2 at its corners), one row, depths 0 and 1 mm, and
/// edge 0–1 pressed: the blend is exact at corners and at that edge's midpoint
/// (ends' mean plus surplus), plain linear on the unpressed edge 1–2, and the
/// surplus weighs `4 λ_a λ_b` inside.
#[test]
fn the_quadratic_blend_is_exact_at_corners_and_pressed_midpoints() {
    let corners = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]];
    // Per sample: g at depth 1, and the residual's x at depth 1 (one mode each).
    let g1 = [0.9, 0.7, 0.8, 0.05];
    let x1 = [1.0, 3.0, 5.0, -0.5];
    let refinement = Refinement::default();
    let law = one_row_law_with_ratio(&corners, vec![[0, 1]], refinement, &x1, &g1);
    let axis: Vec<[f64; 3]> = corners.iter().map(|p| [p[0], p[1], 0.0]).collect();
    let bound = BoundTissue::bind(law, &[[0.0, 0.0, 5.0]], &axis, &[[0, 1, 2]]).expect("binds");
    let mut scratch = bound.scratch();
    let mut at = |bary: [f64; 3]| {
        let p = ProbePoint { triangle: 0, bary };
        let mut rows = [0.0; 3];
        assert!(bound.add_surface(&p, 1.0, &mut scratch, &mut rows));
        (bound.ratio(&p, 1.0).0, rows[0])
    };
    let close = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6;
    assert!(close(at([1.0, 0.0, 0.0]), (0.9, 1.0)));
    assert!(close(at([0.0, 0.0, 1.0]), (0.8, 5.0)));
    // The pressed edge's midpoint: the mean plus the whole surplus.
    let mid = at([0.5, 0.5, 0.0]);
    assert!(close(mid, (0.8 + 0.05, 2.0 - 0.5)), "{mid:?}");
    // The unpressed edge: linear.
    assert!(close(at([0.0, 0.5, 0.5]), (0.75, 4.0)));
    // Inside: 4 λ0 λ1 = 4 · 0.25 · 0.25 of the surplus.
    let w = 0.25;
    assert!(close(
        at([0.25, 0.25, 0.5]),
        (
            0.25 * 0.9 + 0.25 * 0.7 + 0.5 * 0.8 + w * 0.05,
            0.25 + 0.75 + 2.5 - w * 0.5
        )
    ));
}

/// Three corners, depths 0, 1, 2 mm; corner 1's press stopped after 1 mm. A probe
/// whose blend uses corner 1 is answered to 1 mm only (held there, flagged, with
/// the press's reason); one at corner 0 alone to the grid's end.
#[test]
fn a_press_that_stopped_short_limits_only_the_probes_that_blend_it() {
    let corners = [[0.0f32, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]];
    let why = "no equilibrium at 2.00 mm".to_string();
    let law = TissueLaw {
        options: SurfaceLawOptions {
            depth_max_mm: 2.0,
            depth_step_mm: 1.0,
            edges: false,
            ..SurfaceLawOptions::default()
        },
        rows_mm: vec![[0.0, 0.0, 5.0]],
        samples_mm: corners.to_vec(),
        skipped_mm: vec![],
        edge_ends: vec![],
        refinement: Refinement::default(),
        steps: 3,
        // g: 1 at rest, 0.9 / 0.8 at 1 / 2 mm (corner 1 held at 0.9 past its reach).
        ratio: [1.0, 0.9, 0.8].repeat(3),
        stiffness_n_per_mm: vec![1.0; 3],
        correction_mm: vec![0.0; 3],
        segments: vec![1; 3],
        reach: vec![3, 2, 3],
        stopped: vec![String::new(), why.clone(), String::new()],
        rank: 1,
        mode_start: (0..=3).collect(),
        group: (0..3).collect(),
        coeff_start: (0..=3).map(|s| 3 * s).collect(),
        shape: Shapes::Sixteen([i16::MAX, 0, 0].repeat(3)),
        shape_scale: vec![1.0 / f32::from(i16::MAX); 3],
        // x residual: 0, 1, 4 mm (corner 1: 0, 1, 1 held).
        coeffs: [[0.0, 1.0, 4.0], [0.0, 1.0, 1.0], [0.0, 1.0, 4.0]].concat(),
        truncation_bound_mm: 0.0,
        tolerance_mm: 0.05,
        build_s: 0.0,
        compress_s: 0.0,
        mesh_xxh3: Some(0x0123_4567_89ab_cdef),
        accuracy: Default::default(),
    };
    law.check().expect("consistent");
    let mut bad = law.clone();
    bad.stopped[1].clear();
    assert!(bad.check().is_err(), "a short reach needs its reason");
    let axis: Vec<[f64; 3]> = corners.iter().map(|p| p.map(f64::from)).collect();
    let bound = BoundTissue::bind(law, &[[0.0, 0.0, 5.0]], &axis, &[[0, 1, 2]]).expect("binds");
    let mut scratch = bound.scratch();
    let at_corner = ProbePoint {
        triangle: 0,
        bary: [1.0, 0.0, 0.0],
    };
    let inside = ProbePoint {
        triangle: 0,
        bary: [0.5, 0.25, 0.25],
    };
    assert_eq!(bound.limit_mm(&at_corner), (2.0, None));
    assert_eq!(bound.limit_mm(&inside), (1.0, Some(why.as_str())));
    // Compliance 1 mm/N: F = d · g.
    let (f, flagged) = bound.force_n(&at_corner, 2.0, 1.0);
    assert!((f - 1.6).abs() < 1e-6 && !flagged);
    let (f, flagged) = bound.force_n(&inside, 1.5, 1.0);
    assert!((f - 0.9).abs() < 1e-6 && flagged, "held at 1 mm: {f}");
    let (d, flagged) = bound.depth_mm(&inside, 5.0, 1.0);
    assert!((d - 1.0).abs() < 1e-9 && flagged);
    // Within the reach: d (1 − 0.1 d) = 0.45.
    let (d, flagged) = bound.depth_mm(&inside, 0.45, 1.0);
    let want = (1.0 - 0.82f64.sqrt()) / 0.2;
    // (1e-6: the ratios are stored in f32.)
    assert!((d - want).abs() < 1e-6 && !flagged, "{d}");
    // The inverse solves each grid interval's quadratic: every depth comes back to
    // round-off, within the reach and across grid depths (seeded).
    let mut rng = crate::rng::Rng::seed(5);
    for _ in 0..200 {
        let depth = rng.range(1e-3, 2.0);
        let (f, _) = bound.force_n(&at_corner, depth, 1.0);
        let (back, flagged) = bound.depth_mm(&at_corner, f, 1.0);
        assert!(
            (back - depth).abs() < 1e-12 && !flagged,
            "{depth} mm: {back}"
        );
    }
    // Tiny forces to relative round-off, below the old bisection's 4e-14 mm resolution
    // (1e-300 N was once answered 1.8e-14 mm): d ≈ F (1 + 0.1 F).
    for force in [1e-300, 1e-12, 1e-7, 1e-4] {
        let (d, flagged) = bound.depth_mm(&inside, force, 1.0);
        let want = force * (1.0 + 0.1 * force);
        assert!(
            (d / want - 1.0).abs() < 1e-9 && !flagged,
            "{force} N: {d} mm"
        );
    }
    let mut rows = [0.0; 3];
    assert!(bound.add_surface(&inside, 1.7, &mut scratch, &mut rows));
    assert!((rows[0] - 1.0).abs() < 1e-6, "held at 1 mm: {rows:?}");
    let mut rows = [0.0; 3];
    assert!(bound.add_surface(&at_corner, 1.5, &mut scratch, &mut rows));
    assert!((rows[0] - 2.5).abs() < 1e-6, "{rows:?}");
}

/// Two triangles sharing the edge 0–1: `[0, 1, 2]` split into four (its corners,
/// edges, quarter and inner points all pressed), `[1, 0, 3]` not. The stored
/// surpluses are made from a smooth field `f` with the Lagrange P2 basis (not the
/// build's hierarchical weights): inside each quarter of the split triangle the
/// blend must be the P2 interpolant of that quarter's six points, and the
/// neighbour must agree with it along the shared edge.
#[test]
fn a_split_triangle_blends_each_quarter_quadratically_and_its_neighbour_agrees() {
    let f = |p: [f64; 2]| (0.3 * p[0]).sin() + (0.2 * p[1]).cos() + 0.01 * p[0] * p[1];
    let corners = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, -10.0]];
    let at = |w: [f64; 3]| [0, 1].map(|c| (0..3).map(|k| w[k] * corners[k][c]).sum::<f64>());
    // P2 on the whole triangle [0, 1, 2] from f at its corners and midpoints.
    let p2 = |l: [f64; 3]| {
        let mut v = 0.0;
        for k in 0..3 {
            let i = (k + 1) % 3;
            let mut m = [0.0; 3];
            m[k] = 0.5;
            m[i] = 0.5;
            let mut c = [0.0; 3];
            c[k] = 1.0;
            v += l[k] * (2.0 * l[k] - 1.0) * f(at(c)) + 4.0 * l[k] * l[i] * f(at(m));
        }
        v
    };
    let mut x = Vec::new();
    for v in &corners {
        x.push(f(*v));
    }
    let mut edge_ends = Vec::new();
    for k in 0..3u32 {
        let i = (k + 1) % 3;
        let mut m = [0.0; 3];
        m[k as usize] = 0.5;
        m[i as usize] = 0.5;
        let (a, b) = (f(corners[k as usize]), f(corners[i as usize]));
        x.push(f(at(m)) - 0.5 * (a + b));
        edge_ends.push([k, i]);
    }
    let mut quarter_ends = Vec::new();
    for k in 0..3u32 {
        let i = (k + 1) % 3;
        for (near, far) in [(k, i), (i, k)] {
            let mut l = [0.0; 3];
            l[near as usize] = 0.75;
            l[far as usize] = 0.25;
            x.push(f(at(l)) - p2(l));
            quarter_ends.push([near, far]);
        }
    }
    let mut inner_corners = Vec::new();
    for k in 0..3u32 {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        let mut l = [0.25; 3];
        l[k as usize] = 0.5;
        x.push(f(at(l)) - p2(l));
        inner_corners.push([k, i, j]);
    }
    let refinement = Refinement {
        above_mm: Some(0.0),
        triangles: vec![[0, 1, 2]],
        quarter_ends,
        inner_corners,
        ..Refinement::default()
    };
    let law = one_row_law(&corners, edge_ends, refinement, &x);
    let bound = bind_two(law, &corners);
    let mut scratch = bound.scratch();
    let mut blend = |triangle, bary| row_x(&bound, &mut scratch, triangle, bary);
    // f32 coefficients: about 1e-7 of values of order one.
    let close = |a: f64, b: f64| (a - b).abs() < 1e-5;
    // The four quarters as barycentric corners in the big triangle.
    let (v, m) = (
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        [[0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]],
    );
    let quarters = [
        [v[0], m[0], m[2]],
        [m[0], v[1], m[1]],
        [m[2], m[1], v[2]],
        [m[0], m[1], m[2]],
    ];
    let mut rng = crate::rng::Rng::seed(11);
    for q in &quarters {
        // The quarter's own P2 from f at its corners and midpoints.
        let point = |w: [f64; 3]| {
            std::array::from_fn::<f64, 3, _>(|c| (0..3).map(|k| w[k] * q[k][c]).sum())
        };
        for _ in 0..20 {
            let (a, b) = (rng.uniform(), rng.uniform());
            let (a, b) = if a + b > 1.0 {
                (1.0 - a, 1.0 - b)
            } else {
                (a, b)
            };
            let mu = [1.0 - a - b, a, b];
            let mut want = 0.0;
            for k in 0..3 {
                let i = (k + 1) % 3;
                let mut c = [0.0; 3];
                c[k] = 1.0;
                let mut mid = [0.0; 3];
                mid[k] = 0.5;
                mid[i] = 0.5;
                want += mu[k] * (2.0 * mu[k] - 1.0) * f(at(point(c)))
                    + 4.0 * mu[k] * mu[i] * f(at(point(mid)));
            }
            let got = blend(0, point(mu));
            assert!(close(got, want), "quarter {q:?} at {mu:?}: {got} vs {want}");
        }
    }
    // Along the shared edge the unsplit neighbour [1, 0, 3] agrees, quarter points
    // included; off it, it fades to its far corner.
    for t in [0.0, 0.1, 0.25, 0.4, 0.5, 0.6, 0.75, 0.9, 1.0] {
        let split = blend(0, [1.0 - t, t, 0.0]);
        let neighbour = blend(1, [t, 1.0 - t, 0.0]);
        assert!(close(split, neighbour), "t = {t}: {split} vs {neighbour}");
    }
    assert!(close(blend(1, [0.0, 0.0, 1.0]), f(corners[3])));
    // And the split changes something: the plain quadratic blend misses f at a
    // quarter point by more than the tolerance.
    let l = [0.75, 0.25, 0.0];
    assert!((p2(l) - f(at(l))).abs() > 1e-3);
    assert!(close(blend(0, l), f(at(l))));
    // Without the split points the law is the quadratic blend of the same presses.
    let plain = bound.law.unsplit();
    plain.check().expect("consistent");
    assert_eq!(plain.reach.len(), 7);
    assert!(plain.payload_bytes() < bound.law.payload_bytes());
    let plain = bind_two(plain, &corners);
    let x = row_x(&plain, &mut plain.scratch(), 0, l);
    assert!(close(x, p2(l)), "{x} vs {}", p2(l));
    // In the unsplit neighbour the split edge's quarter terms fade out by the line
    // halfway to its far corner (3): nearer the edge the split shows, from there on
    // the neighbour answers as it would without the split.
    let plain_blend = |bary: [f64; 3]| row_x(&plain, &mut plain.scratch(), 1, bary);
    for (far, t) in [(0.5, 0.25), (0.6, 0.3), (0.9, 0.5)] {
        let bary = [(1.0 - far) * t, (1.0 - far) * (1.0 - t), far];
        assert!(close(blend(1, bary), plain_blend(bary)), "{bary:?}");
    }
    let near = [0.6, 0.3, 0.1];
    assert!((blend(1, near) - plain_blend(near)).abs() > 1e-3);
}

/// The band next to the fixed region: corners 0 and 1 pressed, the vertex at
/// (0, 10) never (held), its two edges pressed at their midpoints and stored as
/// surpluses over their pressed ends. At a band midpoint the blend is that press; along
/// a band edge two triangles that share it agree; without the band the blend leans on
/// the pressed corner alone, as before; a saved file keeps the band.
#[test]
fn the_band_next_to_the_fixed_region_blends_its_midpoints() {
    use crate::tissue::surface::BandEdge;
    let corners = [[0.0, 0.0], [10.0, 0.0]];
    // Samples: two vertices, edge 0–1's surplus, then the band edges from 0 and 1.
    let g1 = [0.9, 0.7, 0.05, 0.2, 0.3];
    let x1 = [1.0, 3.0, -0.5, 2.0, -1.0];
    let held = [0.0f32, 10.0, 0.0];
    let refinement = Refinement {
        band: vec![
            BandEdge {
                end: 0,
                other_mm: held,
            },
            BandEdge {
                end: 1,
                other_mm: held,
            },
        ],
        ..Refinement::default()
    };
    let law = one_row_law_with_ratio(&corners, vec![[0, 1]], refinement, &x1, &g1);
    // Axis vertices 0, 1 pressed, 2 held, 3 another held one; triangles 0–1–2 and
    // 2–0–3 share the band edge 0–2.
    let axis = [
        [0.0, 0.0, 0.0],
        [10.0, 0.0, 0.0],
        [0.0, 10.0, 0.0],
        [-10.0, 5.0, 0.0],
    ];
    let triangles = [[0, 1, 2], [2, 0, 3]];
    let bind = |law: TissueLaw| {
        BoundTissue::bind(law, &[[0.0, 0.0, 5.0]], &axis, &triangles).expect("binds")
    };
    let at = |bound: &BoundTissue, triangle: u32, bary: [f64; 3]| {
        let p = ProbePoint { triangle, bary };
        let mut rows = [0.0; 3];
        let mut scratch = bound.scratch();
        assert!(bound.add_surface(&p, 1.0, &mut scratch, &mut rows));
        (bound.ratio(&p, 1.0).0, rows[0])
    };
    let close = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6;
    let bound = bind(law.clone());
    // The band midpoints: the pressed end plus the whole surplus.
    let m02 = at(&bound, 0, [0.5, 0.0, 0.5]);
    assert!(close(m02, (0.9 + 0.2, 1.0 + 2.0)), "{m02:?}");
    let m12 = at(&bound, 0, [0.0, 0.5, 0.5]);
    assert!(close(m12, (0.7 + 0.3, 3.0 - 1.0)), "{m12:?}");
    // Edge 0–1 as before: its ends' mean and its surplus.
    assert!(close(
        at(&bound, 0, [0.5, 0.5, 0.0]),
        (0.8 + 0.05, 2.0 - 0.5)
    ));
    // A point on the band edge 0–2 from either triangle.
    let w = 4.0 * 0.7 * 0.3;
    let a = at(&bound, 0, [0.7, 0.0, 0.3]);
    let b = at(&bound, 1, [0.3, 0.7, 0.0]);
    assert!(close(a, (0.9 + w * 0.2, 1.0 + w * 2.0)), "{a:?}");
    assert!(close(a, b), "{a:?} against {b:?}");
    // The corners it has are still renormalized: the held corner counts as unpressed.
    assert_eq!(
        bound.unpressed_corners(&ProbePoint {
            triangle: 0,
            bary: [0.5, 0.0, 0.5]
        }),
        1
    );
    // Without the band: the pressed corner alone at the band midpoint.
    let without = law.without_band();
    assert!(without.refinement.band.is_empty() && without.reach.len() == 3);
    assert!(close(at(&bind(without), 0, [0.5, 0.0, 0.5]), (0.9, 1.0)));
    // Saved and loaded, the band stays.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("band.tissue");
    law.save(&path).expect("saves");
    let back = TissueLaw::load(&path).expect("loads");
    assert_eq!(back.refinement.band, law.refinement.band);
    assert!(close(at(&bind(back), 0, [0.5, 0.0, 0.5]), m02));
}

/// A band edge whose other end is no vertex of the scene is refused by name.
#[test]
fn a_band_off_the_scene_is_refused() {
    use crate::tissue::surface::BandEdge;
    let refinement = Refinement {
        band: vec![BandEdge {
            end: 0,
            other_mm: [3.0, 3.0, 0.0],
        }],
        ..Refinement::default()
    };
    let law = one_row_law(
        &[[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]],
        vec![],
        refinement,
        &[1.0, 2.0, 3.0, 0.5],
    );
    let axis = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]];
    let err = BoundTissue::bind(law, &[[0.0, 0.0, 5.0]], &axis, &[[0, 1, 2]]).expect_err("refused");
    assert!(
        err.to_string().contains("no palpable vertex of the scene"),
        "{err}"
    );
}

/// A law remembers the organ mesh it was pressed on and refuses a scene of another,
/// such as the same surface with another fixed region; a scene that does not record
/// it is not compared.
#[test]
fn a_law_remembers_its_mesh_and_refuses_a_scene_of_another() {
    let mut law = one_row_law(
        &[[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]],
        vec![],
        Refinement::default(),
        &[0.1, 0.2, 0.3],
    );
    law.mesh_xxh3 = Some(0x0123_4567_89ab_cdef);
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("t.tissue");
    law.save(&path).expect("saved");
    let back = TissueLaw::load(&path).expect("loaded");
    assert_eq!(back.mesh_xxh3, law.mesh_xxh3);
    assert_eq!(back, law);
    let line = |hash: &str| {
        format!("organ=user level=coarse mesh_xxh3={hash} element=p2 young_kpa=160 poisson=0.48")
    };
    assert!(back.check_linear_model(&line("0123456789abcdef")).is_ok());
    let err = back
        .check_linear_model(&line("0123456789abcdee"))
        .expect_err("another mesh");
    assert!(matches!(err, TissueError::MeshDiffers { .. }), "{err}");
    assert!(err.to_string().contains("--fixed"), "{err}");
    assert!(
        back.check_linear_model("organ=user element=p2 young_kpa=160 poisson=0.48")
            .is_ok()
    );
    // A law without a fingerprint (made in memory) is not written: every file has one.
    let mut bare = back.clone();
    bare.mesh_xxh3 = None;
    let err = bare.save(&path).expect_err("no fingerprint");
    assert!(matches!(err, TissueError::NoFingerprint { .. }), "{err}");
    assert_eq!(TissueLaw::load(&path).expect("kept"), back);
}
