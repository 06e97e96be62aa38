//! Split triangles' sub-triangles split again: the second level of refinement.
//!
//! [`Refinement`](super::surface::Refinement) splits a palpable triangle into four
//! sub-triangles and blends each one quadratically from its six presses. Where a
//! sub-triangle is still too coarse for that (deep presses, where the tissue under the
//! tool slides sideways between presses 3–6 mm apart), the same construction is made
//! once more inside it: the quarter points of its three edges and its three inner
//! points are pressed, and each is kept as its surplus over the blend the file answered
//! with there before,
//!
//! ```text
//! q(p) = r(p) − b₁(p),    b₁ = corners + edges + the first level's surpluses at p,
//! ```
//!
//! so that a probe inside the sub-triangle (barycentric `μ` there) adds `4 ν_i ν_j` of
//! the surpluses of the quarter of the sub-triangle that holds it (`ν` its barycentric
//! weights in that quarter), exactly as the first level adds them in the triangle.
//! The sub-triangle's blend is then the quadratic interpolant of each of its quarters'
//! six presses.
//!
//! **The surface does not jump.** A second-level quarter point lies on an edge of a
//! sub-triangle, and the surplus it stores depends on that edge alone. Across the edge
//! lies another sub-triangle of the same triangle, or one of the neighbouring
//! triangle's (if that was split), or the neighbouring triangle itself. Whichever it is,
//! if it is not split again it carries the point's surplus in with the first level's
//! weights on the edge, fading out halfway to its far corner (see
//! [`super::law`]'s `carried`): a sub-triangle in its own `μ`, an unsplit triangle in
//! its `λ`, where the point lies at 1/8, 3/8, 5/8 or 7/8 of its edge and weighs
//! `4 ν (1 − ν)`, `ν` the position along that edge's quarter which holds the probe.
//!
//! **Naming points.** Every second-level point lies at barycentric weights that are
//! eighths of its triangle's corners ([`EighthPoint`]); a point on an edge has a zero
//! weight and is named the same from both triangles by its corners with nonzero weight
//! ([`EighthPoint::key`]), so two sub-triangles split on either side of an edge share
//! its presses.

use std::collections::HashMap;

/// A point of a palpable triangle at barycentric weights in eighths.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct EighthPoint {
    /// The triangle's corner samples.
    pub corners: [u32; 3],
    /// Each corner's weight, in eighths (summing to 8).
    pub eighths: [u8; 3],
}

/// A point's name whichever triangle lists it: its corners with a nonzero weight and
/// those weights, sorted by corner, padded with `(u32::MAX, 0)`.
pub type PointKey = [(u32, u8); 3];

impl EighthPoint {
    pub fn key(&self) -> PointKey {
        let mut key = [(u32::MAX, 0u8); 3];
        let mut n = 0;
        for k in 0..3 {
            if self.eighths[k] > 0 {
                key[n] = (self.corners[k], self.eighths[k]);
                n += 1;
            }
        }
        key[..n].sort_unstable();
        key
    }

    pub fn bary(&self) -> [f64; 3] {
        self.eighths.map(|e| f64::from(e) / 8.0)
    }
}

/// The sub-triangles split again and their points' samples (see the module docs).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SubSplit {
    /// Each sub-triangle split again: its triangle's corner samples, sorted, and which
    /// sub-triangle: the corner sample it holds, or `u32::MAX` for the middle one.
    pub sub_triangles: Vec<([u32; 3], u32)>,
    /// Per second-level sample, in sample order after the first level's inner points:
    /// where it lies. A point whose press failed is not listed (its term drops out).
    pub points: Vec<EighthPoint>,
}

impl SubSplit {
    pub fn is_empty(&self) -> bool {
        self.sub_triangles.is_empty()
    }

    /// Each point's sample index (`first` for the first point), by key.
    pub fn samples_by_key(&self, first: usize) -> HashMap<PointKey, u32> {
        self.points
            .iter()
            .enumerate()
            .map(|(i, p)| (p.key(), (first + i) as u32))
            .collect()
    }
}

/// The keys of the nine points a sub-triangle, named as [`SubSplit::sub_triangles`]
/// names it, presses when split again: its quarter points, edge by edge, then its
/// inner points.
pub fn sub_triangle_keys((corners, at): ([u32; 3], u32)) -> [PointKey; 9] {
    let s = corners.iter().position(|&c| c == at).unwrap_or(3);
    let (quarters, inner) = split_points(sub_corners(s));
    let mut keys = [[(u32::MAX, 0u8); 3]; 9];
    for (key, eighths) in keys.iter_mut().zip(quarters.iter().flatten().chain(&inner)) {
        *key = EighthPoint {
            corners,
            eighths: *eighths,
        }
        .key();
    }
    keys
}

/// The name [`SubSplit::sub_triangles`] gives sub-triangle `s` of a triangle with
/// corner samples `corners` (in the order `s` counts them).
pub fn sub_name(corners: [u32; 3], s: usize) -> ([u32; 3], u32) {
    let mut sorted = corners;
    sorted.sort_unstable();
    (sorted, if s < 3 { corners[s] } else { u32::MAX })
}

/// Sub-triangle `s` of a triangle (0–2: the one at corner `s`; 3: the middle one), as
/// its corners' barycentric weights in eighths, in the order whose barycentric weights
/// [`sub_of`] returns: the corner, then the midpoints towards the next and the previous
/// corner; the middle one's corner `m` the midpoint of the edge opposite corner `m`.
pub fn sub_corners(s: usize) -> [[u8; 3]; 3] {
    let unit = |k: usize, w: u8| {
        let mut e = [0u8; 3];
        e[k] = w;
        e
    };
    let mid = |a: usize, b: usize| {
        let mut e = [0u8; 3];
        e[a] = 4;
        e[b] = 4;
        e
    };
    if s < 3 {
        let (i, j) = ((s + 1) % 3, (s + 2) % 3);
        [unit(s, 8), mid(s, i), mid(s, j)]
    } else {
        [mid(1, 2), mid(2, 0), mid(0, 1)]
    }
}

/// The sub-triangle holding barycentric weights `l` (corners summing to one) and the
/// weights `μ` there, in [`sub_corners`]' order: at corner `k` where `λ_k ≥ ½`
/// (`μ = (2λ_k − 1, 2λ_i, 2λ_j)`), else the middle one (`μ_m = 1 − 2λ_m`).
pub fn sub_of(l: [f64; 3]) -> (usize, [f64; 3]) {
    match (0..3).find(|&k| l[k] >= 0.5) {
        Some(k) => {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            (k, [2.0 * l[k] - 1.0, 2.0 * l[i], 2.0 * l[j]])
        }
        None => (3, l.map(|x| 1.0 - 2.0 * x)),
    }
}

/// The points a triangle with corners `q` (eighths) presses when split: per edge `k`
/// (`q_k` to `q_{k+1}`) its quarter points near `q_k` and near `q_{k+1}`, and per
/// corner the inner point nearest it, `(2 q_k + q_{k+1} + q_{k+2}) / 4`. With `q` a
/// sub-triangle's corners (multiples of four eighths) these are whole eighths.
pub fn split_points(q: [[u8; 3]; 3]) -> ([[[u8; 3]; 2]; 3], [[u8; 3]; 3]) {
    let mix = |w: [u8; 3]| -> [u8; 3] {
        std::array::from_fn(|c| {
            ((0..3)
                .map(|k| u32::from(w[k]) * u32::from(q[k][c]))
                .sum::<u32>()
                / 4) as u8
        })
    };
    let quarters = std::array::from_fn(|k| {
        let i = (k + 1) % 3;
        let (mut near, mut far) = ([0u8; 3], [0u8; 3]);
        near[k] = 3;
        near[i] = 1;
        far[k] = 1;
        far[i] = 3;
        [mix(near), mix(far)]
    });
    let inner = std::array::from_fn(|k| {
        let mut w = [1u8; 3];
        w[k] = 2;
        mix(w)
    });
    (quarters, inner)
}

/// One level's samples for a triangle (or sub-triangle): whether it is split, its
/// edges' quarter-point samples (edge `k`: near corner `k`, near corner `k + 1`) and its
/// inner points' (`u32::MAX`: none).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LevelSamples {
    pub split: bool,
    pub quarters: [[u32; 2]; 3],
    pub inner: [u32; 3],
}

impl LevelSamples {
    pub const NONE: LevelSamples = LevelSamples {
        split: false,
        quarters: [[u32::MAX; 2]; 3],
        inner: [u32::MAX; 3],
    };

    /// Whether it holds any sample.
    pub fn any(&self) -> bool {
        self.quarters
            .iter()
            .flatten()
            .chain(&self.inner)
            .any(|&s| s != u32::MAX)
    }
}

/// The samples at the edge midpoints of quarter `q` (as [`sub_of`] numbers them) of a
/// split triangle whose samples are `s`: the quarter points of edges `q` and `q − 1`
/// nearest corner `q` and the inner point at `q`, or the middle quarter's three inner
/// points. They are the surpluses its blend adds (see [`level_terms`]).
pub fn quarter_midpoints(s: &LevelSamples, q: usize) -> [u32; 3] {
    if q < 3 {
        let j = (q + 2) % 3;
        [s.quarters[q][0], s.quarters[j][1], s.inner[q]]
    } else {
        s.inner
    }
}

/// How much of a split neighbour's quarter-point surplus an unsplit triangle carries
/// in from the edge they share, at a probe whose barycentric weights on that edge's
/// two corners sum to `along` (1 on the edge, 0 at the far corner): all of it on the
/// edge, so the surface does not jump as the probe crosses it, dying out linearly by
/// the line halfway to the far corner, `(2·along − 1)⁺`. That is the reach the quarter
/// point's own term has inside the split triangle (its corner quarter). Measured by a
/// later stage's presses (the inner points of triangles split by a second stage beside
/// a first stage's split edges): the first stage's blend erred less with this fade
/// than with one reaching the far corner (`along`), on average and at the worst point,
/// and less on average than with none (which jumps at the edge), level with `along³`
/// (docs/lab/tissue-measurements.md §1).
pub fn carried(along: f64) -> f64 {
    (2.0 * along - 1.0).max(0.0)
}

/// The three surplus terms one level adds at barycentric weights `l` (summing to
/// one) of a triangle whose samples are `s`: in a split triangle, `4 μ_i μ_j` of the
/// edge surpluses of the quarter holding the probe (`μ` from [`sub_of`]); in one not
/// split, the quarter points of its edges a split neighbour pressed, weighted as on
/// the edge and faded by [`carried`]. `(u32::MAX, _)`: no term.
pub fn level_terms(l: [f64; 3], s: &LevelSamples) -> [(u32, f64); 3] {
    let mut out = [(u32::MAX, 0.0); 3];
    if s.split {
        match sub_of(l) {
            // The quarter at corner k: its edges' midpoints are the quarter points of
            // edges k and j nearest k, and the inner point at k.
            (k, [mk, mi, mj]) if k < 3 => {
                let j = (k + 2) % 3;
                out[0] = (s.quarters[k][0], 4.0 * mk * mi);
                out[1] = (s.quarters[j][1], 4.0 * mj * mk);
                out[2] = (s.inner[k], 4.0 * mi * mj);
            }
            // The middle quarter: its corner m is the midpoint opposite corner m, and
            // its edge from corner i to corner j holds the inner point at k.
            (_, mu) => {
                for k in 0..3 {
                    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                    out[k] = (s.inner[k], 4.0 * mu[i] * mu[j]);
                }
            }
        }
    } else {
        out = carried_terms(l, |k, t| {
            if t <= 0.5 {
                (s.quarters[k][0], 4.0 * (1.0 - 2.0 * t) * (2.0 * t))
            } else {
                (s.quarters[k][1], 4.0 * (2.0 * t - 1.0) * (2.0 - 2.0 * t))
            }
        });
    }
    out
}

/// Per edge `k` of a triangle not split, at barycentric weights `l`: the sample and
/// weight `on_edge(k, t)` gives at `t` of the way from corner `k` to corner `k + 1`
/// (the split side's weight there), faded by [`carried`] off the edge.
fn carried_terms(l: [f64; 3], on_edge: impl Fn(usize, f64) -> (u32, f64)) -> [(u32, f64); 3] {
    let mut out = [(u32::MAX, 0.0); 3];
    for k in 0..3 {
        let i = (k + 1) % 3;
        let along = l[k] + l[i];
        let fade = carried(along);
        if fade <= 0.0 {
            continue;
        }
        let (s, w) = on_edge(k, (l[i] / along).clamp(0.0, 1.0));
        out[k] = (s, fade * w);
    }
    out
}

/// In a triangle not split, the second-level quarter points a split neighbour's
/// sub-triangle pressed on its edges: per edge `k`, the samples at 1/8, 3/8, 5/8 and
/// 7/8 of the way from corner `k` to corner `k + 1`. Each weighs `4 ν (1 − ν)` along
/// the quarter of the edge that holds it (`ν` the position there), faded by
/// [`carried`] as the first level's are.
pub fn edge_eighth_terms(l: [f64; 3], edges: &[[u32; 4]; 3]) -> [(u32, f64); 3] {
    carried_terms(l, |k, t| {
        let m = ((4.0 * t).floor() as usize).min(3);
        let nu = 4.0 * t - m as f64;
        (edges[k][m], 4.0 * nu * (1.0 - nu))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tissue::law::tests::{bind_two, one_row_law, row_x};
    use crate::tissue::surface::Refinement;

    /// A smooth field over the plane, sampled by the presses below.
    fn f(p: [f64; 2]) -> f64 {
        (0.3 * p[0]).sin() + (0.2 * p[1]).cos() + 0.01 * p[0] * p[1]
    }

    /// The quadratic (P2) interpolant of `f` over the triangle whose corners are `q`
    /// (barycentric in the triangle `at` maps), at its barycentric weights `mu`.
    fn p2(at: &dyn Fn([f64; 3]) -> [f64; 2], q: [[f64; 3]; 3], mu: [f64; 3]) -> f64 {
        let point = |w: [f64; 3]| -> [f64; 3] {
            std::array::from_fn(|c| (0..3).map(|k| w[k] * q[k][c]).sum())
        };
        let mut v = 0.0;
        for k in 0..3 {
            let i = (k + 1) % 3;
            let (mut c, mut m) = ([0.0; 3], [0.0; 3]);
            c[k] = 1.0;
            m[k] = 0.5;
            m[i] = 0.5;
            v += mu[k] * (2.0 * mu[k] - 1.0) * f(at(point(c)))
                + 4.0 * mu[k] * mu[i] * f(at(point(m)));
        }
        v
    }

    /// Two barycentric weights drawn uniformly over a triangle (the third `1 − a − b`).
    fn draw(rng: &mut crate::rng::Rng) -> (f64, f64) {
        let (a, b) = (rng.uniform(), rng.uniform());
        if a + b > 1.0 {
            (1.0 - a, 1.0 - b)
        } else {
            (a, b)
        }
    }

    fn eighths(e: [u8; 3]) -> [f64; 3] {
        e.map(|x| f64::from(x) / 8.0)
    }

    /// Two triangles sharing the edge 0–1: `[0, 1, 2]` split, its sub-triangle at
    /// corner 0 split again, `[1, 0, 3]` not split. Every surplus is made from a smooth
    /// field `f` through Lagrange interpolants (not the blend's hierarchical weights):
    /// inside each quarter of the sub-triangle split again the blend must be the P2
    /// interpolant of that quarter's six points, and across each of its edges (to the
    /// middle sub-triangle, and to the unsplit neighbour) the surface must not jump.
    #[test]
    fn a_sub_triangle_split_again_blends_each_quarter_quadratically_and_its_neighbours_agree() {
        let corners = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, -10.0]];
        let at = |w: [f64; 3]| [0, 1].map(|c| (0..3).map(|k| w[k] * corners[k][c]).sum::<f64>());
        let whole = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let level0 = |l: [f64; 3]| p2(&at, whole, l);
        let level1 = |l: [f64; 3]| {
            let (s, mu) = sub_of(l);
            p2(&at, sub_corners(s).map(eighths), mu)
        };
        let mut x: Vec<f64> = corners.iter().map(|&c| f(c)).collect();
        let mut edge_ends = Vec::new();
        for k in 0..3u32 {
            let i = (k + 1) % 3;
            let (a, b) = (f(corners[k as usize]), f(corners[i as usize]));
            let mut m = [0.0; 3];
            m[k as usize] = 0.5;
            m[i as usize] = 0.5;
            x.push(f(at(m)) - 0.5 * (a + b));
            edge_ends.push([k, i]);
        }
        let mut refinement = Refinement {
            above_mm: Some(0.0),
            triangles: vec![[0, 1, 2]],
            ..Refinement::default()
        };
        let (q1, i1) = split_points([[8, 0, 0], [0, 8, 0], [0, 0, 8]]);
        for (k, pair) in q1.iter().enumerate() {
            let i = ((k + 1) % 3) as u32;
            for (side, e) in pair.iter().enumerate() {
                let l = eighths(*e);
                x.push(f(at(l)) - level0(l));
                let ends = [k as u32, i];
                refinement
                    .quarter_ends
                    .push(if side == 0 { ends } else { [i, k as u32] });
            }
        }
        for (k, e) in i1.iter().enumerate() {
            let l = eighths(*e);
            x.push(f(at(l)) - level0(l));
            let k = k as u32;
            refinement.inner_corners.push([k, (k + 1) % 3, (k + 2) % 3]);
        }
        let (q2, i2) = split_points(sub_corners(0));
        refinement.sub.sub_triangles.push(sub_name([0, 1, 2], 0));
        for e in q2.iter().flatten().chain(&i2) {
            let l = eighths(*e);
            x.push(f(at(l)) - level1(l));
            refinement.sub.points.push(EighthPoint {
                corners: [0, 1, 2],
                eighths: *e,
            });
        }
        let law = one_row_law(&corners, edge_ends, refinement, &x);
        let bound = bind_two(law, &corners);
        let mut scratch = bound.scratch();
        let mut blend = |triangle, bary| row_x(&bound, &mut scratch, triangle, bary);
        // f32 coefficients: about 1e-7 of values of order one.
        let close = |a: f64, b: f64| (a - b).abs() < 2e-5;
        let sub = sub_corners(0).map(eighths);
        let in_sub = |mu: [f64; 3]| -> [f64; 3] {
            std::array::from_fn(|c| (0..3).map(|k| mu[k] * sub[k][c]).sum())
        };
        let mut rng = crate::rng::Rng::seed(5);
        for _ in 0..200 {
            let (a, b) = draw(&mut rng);
            let mu = [1.0 - a - b, a, b];
            // The quarter of the sub-triangle holding the probe, in the triangle's λ.
            let (g, nu) = sub_of(mu);
            let quarter = sub_corners(g).map(|q| in_sub(eighths(q)));
            let want = p2(&at, quarter, nu);
            let got = blend(0, in_sub(mu));
            assert!(close(got, want), "μ {mu:?}: {got} vs {want}");
        }
        // At its points, each press itself; elsewhere in the triangle, the first level.
        for e in q2.iter().flatten().chain(&i2) {
            let l = eighths(*e);
            assert!(close(blend(0, l), f(at(l))), "{e:?}");
            assert!(
                (level1(l) - f(at(l))).abs() > 1e-4,
                "the split changes {e:?}"
            );
        }
        // (The middle sub-triangle carries the split edge's points in up to halfway.)
        for l in [[0.2, 0.5, 0.3], [0.1, 0.1, 0.8], [0.2, 0.4, 0.4]] {
            assert!(close(blend(0, l), level1(l)), "{l:?}");
        }
        // Across the edge to the middle sub-triangle (λ₀ = ½) and along the edge the
        // unsplit neighbour [1, 0, 3] shares: no jump.
        let eps = 1e-9;
        for t in [0.0, 0.1, 0.2, 0.25, 0.3, 0.4, 0.5] {
            let inside = blend(0, [0.5 + eps, t - eps / 2.0, 0.5 - t - eps / 2.0]);
            let middle = blend(0, [0.5 - eps, t + eps / 2.0, 0.5 - t + eps / 2.0]);
            assert!(close(inside, middle), "t = {t}: {inside} vs {middle}");
            let split = blend(0, [1.0 - t, t, 0.0]);
            let neighbour = blend(1, [t, 1.0 - t, 0.0]);
            assert!(close(split, neighbour), "t = {t}: {split} vs {neighbour}");
        }
    }

    #[test]
    fn sub_triangles_tile_the_triangle_and_their_weights_give_the_point_back() {
        let mut rng = crate::rng::Rng::seed(3);
        for _ in 0..200 {
            let (a, b) = draw(&mut rng);
            let l = [1.0 - a - b, a, b];
            let (s, mu) = sub_of(l);
            assert!(mu.iter().all(|&m| m >= -1e-12), "{l:?} → {s} {mu:?}");
            assert!((mu.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let q = sub_corners(s);
            let back: [f64; 3] =
                std::array::from_fn(|c| (0..3).map(|k| mu[k] * f64::from(q[k][c]) / 8.0).sum());
            assert!(
                (0..3).all(|c| (back[c] - l[c]).abs() < 1e-12),
                "{l:?}: {back:?}"
            );
        }
    }

    #[test]
    fn a_sub_triangles_points_are_eighths_and_edge_points_share_their_key() {
        for s in 0..4 {
            let (quarters, inner) = split_points(sub_corners(s));
            for p in quarters.iter().flatten().chain(&inner) {
                assert_eq!(p.iter().map(|&e| u32::from(e)).sum::<u32>(), 8, "{p:?}");
                // A second-level point is never a first-level one (every weight even).
                assert!(p.iter().any(|e| e % 2 == 1), "{p:?}");
            }
        }
        // Sub-triangle 0's quarter point on the triangle's edge 0–1, named from the
        // neighbour across it (corners listed in another order).
        let (quarters, _) = split_points(sub_corners(0));
        let here = EighthPoint {
            corners: [10, 11, 12],
            eighths: quarters[0][0],
        };
        assert_eq!(here.eighths, [7, 1, 0]);
        let there = EighthPoint {
            corners: [11, 10, 13],
            eighths: [1, 7, 0],
        };
        assert_eq!(here.key(), there.key());
        assert_ne!(
            here.key(),
            EighthPoint {
                corners: [11, 10, 13],
                eighths: [7, 1, 0]
            }
            .key()
        );
    }
}
