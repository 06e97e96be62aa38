//! Where the quadratic blend is too coarse: which triangles a build splits, and the
//! points it presses there.

use std::collections::{HashMap, HashSet};

use crate::organ::OrganMesh;
use crate::tissue::options::{COVER_SLACK_MM, SurfaceLawBuildError};
use crate::tissue::presser::{Logged, PressPoint, Stored};
use crate::tissue::subsplit::SubSplit;

/// Triangles split once into four where the quadratic blend is too coarse: a palpable
/// triangle (corners `a, b, c`, edge midpoints `m_ab, m_bc, m_ca`, all pressed) whose
/// largest edge surplus (any node, any depth) exceeds `above_mm` also has its *quarter
/// points* `(3a + b)/4, …` (two per edge, shared with the neighbour across it) and its
/// *inner points* `(2a + b + c)/4, …` (one per corner) pressed. Each stores its surplus
/// over the parent's quadratic interpolant there,
///
/// ```text
/// q_a,ab = r((3a + b)/4) − (¾ r_a + ¼ r_b + ¾ e_ab),
/// i_a    = r((2a + b + c)/4) − (½ r_a + ¼ r_b + ¼ r_c + ½ e_ab + ¼ e_bc + ½ e_ca),
/// ```
///
/// so that adding `4 μ_i μ_j` of each sub-triangle edge's surplus (`μ` the probe's
/// barycentric coordinates in its quarter of the triangle) makes the blend the
/// quadratic interpolant of the sub-triangle's six presses. Along a split edge the
/// quarter terms depend on that edge alone, so a neighbour that was not split blends
/// them too (with the same weights on the edge, fading out halfway to its far corner)
/// and the surface does not jump as the probe crosses it. Measured on the anterior lobe's worst triangle (sides 8.6–12 mm)
/// at 7 mm: 0.19–0.48 mm quadratic, 0.05–0.11 mm split (docs/lab/tissue-measurements.md §2).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Refinement {
    /// The threshold the build used (mm); `None`: no triangle is split.
    pub above_mm: Option<f64>,
    /// The split triangles' corner samples (vertex sample indices, the mesh's order).
    pub triangles: Vec<[u32; 3]>,
    /// Per kept quarter point, after the edges' samples: its edge's near and far end.
    pub quarter_ends: Vec<[u32; 2]>,
    /// Per kept inner point, after the quarter points: its triangle's corners, the
    /// one it lies nearest first, the others in the triangle's order.
    pub inner_corners: Vec<[u32; 3]>,
    /// Sub-triangles split again, their points' samples after the inner points'.
    /// Stored apart in a tissue file, after the weights.
    #[serde(skip)]
    pub sub: SubSplit,
    /// Edges from a pressed vertex to one never pressed (on the fixed region), pressed
    /// at their midpoints: their samples come last, after every other stage's (see
    /// [`BandEdge`]). Stored apart in a tissue file, after the second level.
    #[serde(skip)]
    pub band: Vec<BandEdge>,
}

/// A palpable edge next to the fixed region, pressed at its midpoint: one end was
/// pressed (sample `end`), the other never was (a press there would push a held node).
/// Its sample holds the midpoint's surplus over the pressed end,
///
/// ```text
/// b = r(midpoint) − r_end,
/// ```
///
/// which the blend adds with `4 λ_end λ_other`, as it adds an edge's surplus. Next to
/// the fixed region the blend renormalizes the corners it has (`r_end` alone at the
/// midpoint), so there it gives the midpoint's own press, and along the edge it is the
/// same from both triangles that share it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BandEdge {
    /// The pressed end's sample.
    pub end: u32,
    /// The other end's rest position, mm (a palpable vertex with no sample).
    pub other_mm: [f32; 3],
}

/// The default split threshold of a build (mm): see [`Refinement`]. The quadratic
/// blend's error at a triangle's quarter and inner points (their surpluses) ran at 0.29
/// to 1.34 of its largest edge surplus on 21 triangles of the anterior lobe and the
/// sharp border (coarse P2, to 15 mm), so an edge surplus of 0.35 mm is where the blend
/// may start to miss the 0.5 mm goal. On the 344 triangles of the whole coarse surface
/// whose edges a partial build had pressed, 318 (92 %) lie above it (260 above 0.5 mm,
/// 81 above 1 mm): the default buys the accuracy with about six presses a triangle.
pub const DEFAULT_REFINE_ABOVE_MM: f64 = 0.35;

/// A quarter or inner point of a split triangle (see [`Refinement`]).
pub(super) struct RefinePoint {
    /// The point on its flat triangle: mesh vertices and weights.
    pub(super) at: Vec<(u32, f64)>,
    /// The parent's quadratic interpolant there: stored samples and weights.
    pub(super) base: Vec<(usize, f64)>,
    /// `[near, far]` end samples (a quarter point) or `[near, next, next]` corners.
    pub(super) near: Vec<u32>,
    pub(super) id: u32,
}

impl RefinePoint {
    /// Where it is pressed, and along the same blend of the vertex normals the scene
    /// interpolates.
    pub(super) fn point(&self, organ: &OrganMesh, normals: &[[f32; 3]]) -> PressPoint {
        let (mut at, mut push) = ([0.0; 3], [0.0; 3]);
        for &(v, w) in &self.at {
            for c in 0..3 {
                at[c] += w * organ.mesh.vertices[v as usize][c];
                push[c] -= w * f64::from(normals[v as usize][c]);
            }
        }
        PressPoint {
            at,
            push,
            id: self.id,
        }
    }
}

/// The triangles to split and the points to press.
#[derive(Default)]
pub(crate) struct RefinePlan {
    /// Triangles above the threshold (`triangles` holds all of them or the worst).
    pub(crate) above: usize,
    pub(crate) triangles: Vec<[u32; 3]>,
    /// Per split triangle: its largest edge surplus (mm), and its six quarter points'
    /// and three inner points' indices in `quarters` and `inner`.
    pub(crate) figures: Vec<(f64, [usize; 6], [usize; 3])>,
    pub(super) quarters: Vec<RefinePoint>,
    pub(super) inner: Vec<RefinePoint>,
}

impl RefinePlan {
    /// The press-log ids of the points it presses (quarter points, then inner points).
    pub(crate) fn press_ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.quarters.iter().chain(&self.inner).map(|p| p.id)
    }

    /// The split triangles (indices in `figures`), the largest edge surplus first
    /// (ties in the plan's order, as [`worst_first`] ranks them).
    fn triangles_worst_first(&self) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.figures.len()).collect();
        let f = &self.figures;
        order.sort_by(|&i, &j| f[j].0.total_cmp(&f[i].0).then(i.cmp(&j)));
        order
    }

    /// Split triangle `t`'s nine points as indices in [`press_ids`](Self::press_ids)'
    /// order.
    pub(super) fn triangle_points(&self, t: usize) -> impl Iterator<Item = usize> + '_ {
        let (_, quarters, inner) = &self.figures[t];
        let n_quarters = self.quarters.len();
        quarters
            .iter()
            .copied()
            .chain(inner.iter().map(move |&i| n_quarters + i))
    }

    /// The plan's points (indices in [`press_ids`](Self::press_ids)' order) in the
    /// order a stage presses them: the worst triangle's, then the next worst's not yet
    /// listed, and so on. A stage stopped part way then leaves whole triangles in the
    /// log, worst first, and a smaller stage finishes from the log alone.
    pub(crate) fn press_order(&self) -> Vec<usize> {
        let mut listed = vec![false; self.quarters.len() + self.inner.len()];
        let mut order = Vec::with_capacity(listed.len());
        for t in self.triangles_worst_first() {
            for k in self.triangle_points(t) {
                if !std::mem::replace(&mut listed[k], true) {
                    order.push(k);
                }
            }
        }
        order
    }

    /// How many of its triangles, worst first, have every point's press among `held`
    /// (log ids): a stage of that many is already pressed.
    pub(crate) fn ready(&self, held: &HashSet<u32>) -> usize {
        let ids: Vec<u32> = self.press_ids().collect();
        self.triangles_worst_first()
            .into_iter()
            .take_while(|&t| self.triangle_points(t).all(|k| held.contains(&ids[k])))
            .count()
    }

    /// The plan's points, in [`press_order`](Self::press_order).
    pub(super) fn points_in_press_order(
        &self,
        organ: &OrganMesh,
        normals: &[[f32; 3]],
        order: &[usize],
    ) -> Vec<PressPoint> {
        let quarter_points = self.quarters.iter().map(|q| q.point(organ, normals));
        let inner_points = self.inner.iter().map(|q| q.point(organ, normals));
        let points: Vec<PressPoint> = quarter_points.chain(inner_points).collect();
        order.iter().map(|&k| points[k]).collect()
    }
}

/// `pressed[i]`, the press of plan point `order[i]`, put back in the plan's order.
pub(super) fn in_plan_order(order: &[usize], pressed: Vec<Logged>) -> Vec<Logged> {
    let mut out: Vec<Option<Logged>> = (0..order.len()).map(|_| None).collect();
    for (&k, p) in order.iter().zip(pressed) {
        out[k] = Some(p);
    }
    out.into_iter()
        .map(|p| p.expect("press_order lists every point once"))
        .collect()
}

/// The corners of the palpable triangle closest to each of `points` (sorted, each
/// once, fixed vertices left out as a build leaves them), or which point lies off the
/// palpable surface.
pub fn covering_vertices(
    organ: &OrganMesh,
    points: &[[f64; 3]],
) -> Result<Vec<u32>, SurfaceLawBuildError> {
    let palpable = organ.palpable_triangles();
    let mut cover = Vec::with_capacity(3 * points.len());
    for &p in points {
        cover.extend(palpable[palpable_at(organ, &palpable, p)?]);
    }
    cover.retain(|&v| !organ.fixed[v as usize]);
    cover.sort_unstable();
    cover.dedup();
    Ok(cover)
}

/// The index in `palpable` (triangles of `organ`) of the one closest to `p`, or that
/// `p` lies farther than [`COVER_SLACK_MM`] from all of them.
pub(crate) fn palpable_at(
    organ: &OrganMesh,
    palpable: &[[u32; 3]],
    p: [f64; 3],
) -> Result<usize, SurfaceLawBuildError> {
    let off = |distance_mm| SurfaceLawBuildError::OffSurface {
        point_mm: p,
        distance_mm,
    };
    let hit =
        crate::axis::closest_point(&organ.mesh.vertices, palpable, p).ok_or(off(f64::INFINITY))?;
    if hit.distance > COVER_SLACK_MM {
        return Err(off(hit.distance));
    }
    Ok(hit.triangle as usize)
}

/// The largest node displacement in a sample's residuals (mm; 3 entries a node).
pub(crate) fn node_peak(residual: &[f32]) -> f64 {
    residual
        .chunks_exact(3)
        .map(|c| f64::from(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
        .fold(0.0, f64::max)
}

/// A palpable triangle whose corners and edges were all kept: a split candidate.
#[derive(Clone)]
pub(crate) struct Candidate {
    /// Its index in the organ's boundary, vertices and corner samples.
    pub(crate) t: usize,
    pub(crate) tri: [u32; 3],
    pub(crate) c: [u32; 3],
    /// Its edges' samples, edge `k` from corner `k` to corner `k + 1`.
    pub(crate) e: [usize; 3],
    /// Its largest edge surplus (mm, any node, any grid depth).
    pub(crate) worst: f64,
}

/// Every split candidate of a law, in the mesh's order; `residual` holds `n_row`
/// values a sample (every grid depth).
pub(crate) fn refine_candidates(
    organ: &OrganMesh,
    sample_of: &[u32],
    kept_edges: &[[u32; 2]],
    residual: &[f32],
    n_row: usize,
) -> Vec<Candidate> {
    let first_edge = sample_of.iter().filter(|&&s| s != u32::MAX).count();
    let edge_sample: HashMap<[u32; 2], usize> = kept_edges
        .iter()
        .enumerate()
        .map(|(e, &[a, b])| ([a.min(b), a.max(b)], first_edge + e))
        .collect();
    let peak = |s: usize| node_peak(&residual[s * n_row..][..n_row]);
    let mut candidates = Vec::new();
    for (t, (tri, _)) in organ
        .boundary
        .iter()
        .zip(&organ.palpable)
        .enumerate()
        .filter(|(_, (_, p))| **p)
    {
        let c = tri.map(|v| sample_of[v as usize]);
        if c.contains(&u32::MAX) {
            continue;
        }
        let e: [Option<usize>; 3] = std::array::from_fn(|k| {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            edge_sample.get(&[a.min(b), a.max(b)]).copied()
        });
        let Some(e) = e.into_iter().collect::<Option<Vec<usize>>>() else {
            continue;
        };
        let e = [e[0], e[1], e[2]];
        let worst = e.iter().map(|&s| peak(s)).fold(0.0, f64::max);
        candidates.push(Candidate {
            t,
            tri: *tri,
            c,
            e,
            worst,
        });
    }
    candidates
}

/// The candidates' indices, the largest edge surplus first (ties in the mesh's order).
pub(crate) fn worst_first(candidates: &[Candidate]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    order.sort_by(|&i, &j| {
        candidates[j]
            .worst
            .total_cmp(&candidates[i].worst)
            .then(i.cmp(&j))
    });
    order
}

/// The split triangles of a build (see [`Refinement`]): palpable triangles whose
/// corners and edges were all kept and whose largest edge surplus exceeds `above_mm`
/// (the `most` worst of them, where given), and the `kept` triangles (corner samples)
/// of an earlier stage whatever their rank. The kept ones come first, in their order,
/// the others in the mesh's: a point shared with a kept triangle (a quarter point on
/// its edge) stays that triangle's, so an onward stage leaves the earlier stage's
/// points and their groups as they were. Log ids come after every vertex and edge id,
/// from the mesh alone (not from which triangles are split), so a resumed build finds
/// them.
pub(crate) fn refine_plan(
    organ: &OrganMesh,
    candidates: Vec<Candidate>,
    above_mm: f64,
    most: Option<usize>,
    kept: &[[u32; 3]],
) -> RefinePlan {
    let all_edges = organ.palpable_edges();
    let first_id = organ.mesh.vertices.len() + 3 * organ.boundary.len();
    let above = candidates.iter().filter(|c| c.worst > above_mm).count();
    // The `most` worst above the threshold (ties to the first in the mesh's order).
    let mut chosen: Vec<bool> = vec![false; candidates.len()];
    let mut count = 0;
    for i in worst_first(&candidates) {
        if candidates[i].worst > above_mm && most.is_none_or(|m| count < m) {
            chosen[i] = true;
            count += 1;
        }
    }
    let mut ordered: Vec<Candidate> = kept
        .iter()
        .filter_map(|k| candidates.iter().find(|c| c.c == *k).cloned())
        .collect();
    ordered.extend(
        candidates
            .into_iter()
            .zip(chosen)
            .filter(|(c, chosen)| *chosen && !kept.contains(&c.c))
            .map(|(c, _)| c),
    );
    let mut plan = RefinePlan {
        above,
        ..RefinePlan::default()
    };
    let mut seen = HashMap::new();
    for Candidate {
        t,
        tri,
        c,
        e,
        worst,
    } in ordered
    {
        plan.triangles.push(c);
        let (mut quarters, mut inner) = ([0; 6], [0; 3]);
        for k in 0..3 {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            for (side, (near, far)) in [(k, i), (i, k)].into_iter().enumerate() {
                let (a, b) = (tri[near], tri[far]);
                if let Some(&q) = seen.get(&[a, b]) {
                    quarters[2 * k + side] = q;
                    continue;
                }
                quarters[2 * k + side] = plan.quarters.len();
                seen.insert([a, b], plan.quarters.len());
                let g = all_edges
                    .binary_search(&[a.min(b), a.max(b)])
                    .expect("a palpable triangle's edge is palpable");
                plan.quarters.push(RefinePoint {
                    at: vec![(a, 0.75), (b, 0.25)],
                    base: vec![
                        (c[near] as usize, 0.75),
                        (c[far] as usize, 0.25),
                        (e[k], 0.75),
                    ],
                    near: vec![c[near], c[far]],
                    id: (first_id + 2 * g + usize::from(a > b)) as u32,
                });
            }
            inner[k] = plan.inner.len();
            plan.inner.push(RefinePoint {
                at: vec![(tri[k], 0.5), (tri[i], 0.25), (tri[j], 0.25)],
                base: vec![
                    (c[k] as usize, 0.5),
                    (c[i] as usize, 0.25),
                    (c[j] as usize, 0.25),
                    (e[k], 0.5),
                    (e[i], 0.25),
                    (e[j], 0.5),
                ],
                near: vec![c[k], c[i], c[j]],
                id: (first_id + 2 * all_edges.len() + 3 * t + k) as u32,
            });
        }
        plan.figures.push((worst, quarters, inner));
    }
    plan
}

/// Where a split point's surplus comes from in a refinement (see
/// [`RefinePlan::sources`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Source {
    /// Pressed now (or taken from the log).
    Press,
    /// Held by the earlier stage: its index among that stage's split samples.
    Held(usize),
    /// A point of an earlier stage's triangle that the stage did not keep.
    Skipped,
}

/// A split point's press, or the earlier stage's sample that holds its surplus.
pub(super) enum Got {
    Pressed(Logged),
    Held(usize),
}

impl RefinePlan {
    /// Checks that this plan goes on from `earlier` (a law's split so far): every
    /// earlier triangle in it, and more besides where there were any.
    pub(crate) fn goes_on_from(&self, earlier: &Refinement) -> Result<(), SurfaceLawBuildError> {
        let (asked, split) = (self.triangles.len(), earlier.triangles.len());
        let missing = earlier
            .triangles
            .iter()
            .filter(|t| !self.triangles.contains(t))
            .count();
        if missing > 0 {
            return Err(SurfaceLawBuildError::EarlierStage { missing });
        }
        if split > 0 && asked <= split {
            return Err(SurfaceLawBuildError::AlreadyRefined {
                triangles: split,
                asked,
            });
        }
        Ok(())
    }

    /// Per plan point (quarter points, then inner points): whether it is pressed or
    /// held by `earlier`, a stage whose triangles the plan lists first. A point is
    /// named by its near and far edge ends (a quarter point) or its corners, nearest
    /// first (an inner point), as a [`Refinement`] lists it.
    pub(crate) fn sources(&self, earlier: &Refinement) -> Vec<Source> {
        let n_quarters = earlier.quarter_ends.len();
        let quarter: HashMap<[u32; 2], usize> = earlier
            .quarter_ends
            .iter()
            .enumerate()
            .map(|(i, &e)| (e, i))
            .collect();
        let inner: HashMap<[u32; 3], usize> = earlier
            .inner_corners
            .iter()
            .enumerate()
            .map(|(i, &c)| (c, n_quarters + i))
            .collect();
        let mut earlier_point = vec![false; self.quarters.len() + self.inner.len()];
        for t in 0..earlier.triangles.len().min(self.figures.len()) {
            for k in self.triangle_points(t) {
                earlier_point[k] = true;
            }
        }
        self.quarters
            .iter()
            .map(|q| quarter.get(&[q.near[0], q.near[1]]).copied())
            .chain(
                self.inner
                    .iter()
                    .map(|q| inner.get(&[q.near[0], q.near[1], q.near[2]]).copied()),
            )
            .zip(earlier_point)
            .map(|(held, earlier)| match (held, earlier) {
                (Some(s), _) => Source::Held(s),
                (None, true) => Source::Skipped,
                (None, false) => Source::Press,
            })
            .collect()
    }
}

/// Keeps the split triangles' points (`got` in the plan's order, quarter points then
/// inner points) as their surpluses over the parent's quadratic blend, appended to
/// `stored` and listed in `refinement`: a press's surplus computed, a held one copied
/// from `held` (an earlier stage's split samples, whose parent blend is this one).
/// Returns each split triangle's figures (its largest edge surplus, and its points'
/// largest kept surplus).
#[allow(clippy::too_many_arguments)]
pub(super) fn split_triangles(
    plan: &RefinePlan,
    got: Vec<Got>,
    held: &Stored,
    stored: &mut Stored,
    steps: usize,
    row: usize,
    refinement: &mut Refinement,
    refine_skip_reasons: &mut Vec<String>,
) -> Vec<(f64, f64)> {
    refinement.triangles = plan.triangles.clone();
    // Per plan point: the largest node of its kept surplus (mm).
    let mut point_peak = Vec::new();
    for (q, got) in plan.quarters.iter().chain(&plan.inner).zip(got) {
        match got {
            Got::Pressed(Err(why)) => {
                refine_skip_reasons.push(why);
                point_peak.push(0.0);
                continue;
            }
            Got::Pressed(Ok(p)) => {
                let (surplus, g, reach, why) = stored.surplus(&p, &q.base, steps, row);
                point_peak.push(node_peak(&surplus));
                stored.push(&p, &surplus, &g, reach, why);
            }
            Got::Held(s) => {
                point_peak.push(node_peak(&held.residual[s * steps * row..][..steps * row]));
                stored.copy(held, s, steps, row);
            }
        }
        match q.near.len() {
            2 => refinement.quarter_ends.push([q.near[0], q.near[1]]),
            _ => refinement
                .inner_corners
                .push([q.near[0], q.near[1], q.near[2]]),
        }
    }
    let n_quarters = plan.quarters.len();
    plan.figures
        .iter()
        .map(|(edge, quarters, inner)| {
            let points = quarters
                .iter()
                .copied()
                .chain(inner.iter().map(|&i| n_quarters + i));
            (*edge, points.map(|k| point_peak[k]).fold(0.0, f64::max))
        })
        .collect()
}
