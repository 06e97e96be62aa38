//! What a refinement would cost and where it would split, computed without pressing
//! (`palpa lab tissue refine --plan`).
//!
//! A refinement of the whole coarse surface presses about 6 000 points (hours on two
//! cores), so a user refines in stages ([`SurfaceLaw::refine`] with the worst few
//! triangles). Before paying for a stage it helps to know what it buys: how many
//! triangles lie above the threshold, how many points the chosen ones need and how many
//! of those an earlier (partial) run already left in the press log, and, for points the
//! user cares about, where their triangle ranks. A triangle's rank is by its largest
//! edge surplus over all grid depths,
//!
//! ```text
//! e_T = max over its three edges, every kept node and grid depth of |r_mid − (r_a + r_b)/2|,
//! ```
//!
//! the figure that decides the split; its surplus at each grid depth is reported too,
//! since a scene that presses only so deep sees only the first of them.

use std::collections::HashSet;
use std::path::Path;

use crate::organ::OrganMesh;
use crate::tissue::surface::{
    Source, SurfaceLaw, SurfaceLawBuildError, logged_press_ids, node_peak, palpable_at,
    refine_candidates, refine_plan, worst_first,
};

/// What [`SurfaceLaw::refine`] would split and press with the same threshold and
/// count.
#[derive(Debug, Clone, PartialEq)]
pub struct RefinePreview {
    /// Palpable triangles whose corners and edges were all pressed (the only ones a
    /// refinement can split), and how many of them lie above the threshold.
    pub candidates: usize,
    pub above: usize,
    /// Triangles the law has split already (an earlier stage: kept, and counted in
    /// `split`), triangles it would split in all, points it would press (those the
    /// earlier stage holds not among them), and how many of those points the press
    /// log already holds.
    pub kept: usize,
    pub split: usize,
    pub presses: usize,
    pub logged: usize,
    /// How many of those triangles, worst first, the log already holds whole: a
    /// stage of that many finishes without pressing (a stage presses its worst
    /// triangle's points first, so a stopped one leaves them).
    pub ready: usize,
    /// The largest edge surplus of any candidate, and the least of those it would
    /// split (mm; `None` when it splits none).
    pub worst_mm: f64,
    pub least_split_mm: Option<f64>,
    /// Per asked point, its triangle's figures.
    pub at: Vec<PointRank>,
}

/// Where a point's triangle stands among the split candidates.
#[derive(Debug, Clone, PartialEq)]
pub struct PointRank {
    pub point_mm: [f64; 3],
    /// `None` where its triangle is not a candidate (a corner or edge not pressed).
    pub edge_surplus_mm: Option<f64>,
    /// Its largest edge surplus at each grid depth (mm; empty where not a candidate).
    pub edge_surplus_by_depth_mm: Vec<f64>,
    /// Its rank among all candidates, worst first (1-based; ties in mesh order).
    pub rank: Option<usize>,
    /// Whether this refinement would split it.
    pub split: bool,
}

impl SurfaceLaw {
    /// What [`refine`](Self::refine) with `above_mm` and `most` would split and press
    /// on `organ`, counting the points already in the press log at `log`, and the
    /// figures of the triangles holding `at` (points on the palpable surface).
    pub fn refine_preview(
        &self,
        organ: &OrganMesh,
        above_mm: f64,
        most: Option<usize>,
        log: Option<&Path>,
        at: &[[f64; 3]],
    ) -> Result<RefinePreview, SurfaceLawBuildError> {
        let (steps, row) = (self.steps, 3 * self.rows.len());
        let n_row = steps * row;
        let candidates =
            refine_candidates(organ, &self.sample_of, &self.edges, &self.residual, n_row);
        let mut rank_of = vec![0; candidates.len()];
        for (r, &i) in worst_first(&candidates).iter().enumerate() {
            rank_of[i] = r + 1;
        }
        let palpable: Vec<usize> = (0..organ.boundary.len())
            .filter(|&t| organ.palpable[t])
            .collect();
        let palpable_tris: Vec<[u32; 3]> = palpable.iter().map(|&t| organ.boundary[t]).collect();
        let mut hits = Vec::with_capacity(at.len());
        for &p in at {
            hits.push(palpable[palpable_at(organ, &palpable_tris, p)?]);
        }
        let candidate_of = |t: usize| candidates.iter().position(|c| c.t == t);
        let ranks: Vec<(Option<usize>, Vec<f64>)> = hits
            .iter()
            .map(|&t| match candidate_of(t) {
                None => (None, Vec::new()),
                Some(i) => {
                    let by_depth = (0..steps)
                        .map(|j| {
                            candidates[i]
                                .e
                                .iter()
                                .map(|&s| {
                                    let r = &self.residual[(s * steps + j) * row..][..row];
                                    node_peak(r)
                                })
                                .fold(0.0, f64::max)
                        })
                        .collect();
                    (Some(i), by_depth)
                }
            })
            .collect();
        let worst_mm = candidates.iter().map(|c| c.worst).fold(0.0, f64::max);
        let earlier = &self.refinement;
        let plan = refine_plan(
            organ,
            candidates.clone(),
            above_mm,
            most,
            &earlier.triangles,
        );
        plan.goes_on_from(earlier)?;
        let least_split_mm = plan.figures.iter().map(|f| f.0).min_by(f64::total_cmp);
        let split_t: Vec<[u32; 3]> = plan.triangles.clone();
        let ids: Vec<u32> = plan.press_ids().collect();
        let sources = plan.sources(earlier);
        let mut held: HashSet<u32> = match log {
            Some(path) => logged_press_ids(organ, &self.options, self.rows.len(), path)?
                .into_iter()
                .collect(),
            None => HashSet::new(),
        };
        let to_press: Vec<u32> = ids
            .iter()
            .zip(&sources)
            .filter(|(_, s)| **s == Source::Press)
            .map(|(&id, _)| id)
            .collect();
        let logged = to_press.iter().filter(|id| held.contains(id)).count();
        // The earlier stage's points count as pressed.
        held.extend(
            ids.iter()
                .zip(&sources)
                .filter(|(_, s)| **s != Source::Press)
                .map(|(&id, _)| id),
        );
        let at = at
            .iter()
            .zip(ranks)
            .map(|(&point_mm, (i, by_depth))| {
                let c = i.map(|i| &candidates[i]);
                PointRank {
                    point_mm,
                    edge_surplus_mm: c.map(|c| c.worst),
                    edge_surplus_by_depth_mm: by_depth,
                    rank: i.map(|i| rank_of[i]),
                    split: c.is_some_and(|c| split_t.contains(&c.c)),
                }
            })
            .collect();
        Ok(RefinePreview {
            candidates: candidates.len(),
            above: plan.above,
            kept: earlier.triangles.len(),
            split: plan.triangles.len(),
            presses: to_press.len(),
            logged,
            ready: plan.ready(&held),
            worst_mm,
            least_split_mm,
            at,
        })
    }
}
