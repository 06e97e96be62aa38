//! Splitting a built file's sub-triangles again (the second level of
//! [`super::subsplit`]): which ones, the points to press, and the file with their
//! surpluses.
//!
//! A sub-triangle's *edge surplus* is the largest node of the first-level samples at
//! its edge midpoints (the triangle's quarter and inner points), any depth: how far
//! the parent triangle's quadratic blend was from the presses there. It ranks
//! sub-triangles as a triangle's edge surpluses rank triangles for the first split, and
//! the worst `most` are split again. Each of their points is pressed once (a point on
//! an edge shared by two split sub-triangles, or by two triangles, is one press) and
//! kept as its surplus over the blend the file answers with there, so at that point
//! the new file gives the point's own press back, up to the surplus's compression.
//! The file's own samples keep their stored modes and weights unchanged.
//!
//! Log ids continue after the first level's (see `surfacelaw`'s `refine_plan`) and
//! depend on the mesh alone: a point on a palpable edge `g` (in the sorted list of
//! palpable edges) at `e` eighths from its lower vertex is `8 g + e` past them, one
//! inside boundary triangle `t` at eighths `(e₀, e₁, ·)` is `8 E + 64 t + 8 e₀ + e₁`.
//! A killed run resumes from the log, and a larger `most` from the same file (or from
//! the file split again, which is planned from the file it was split from) presses
//! only the new points.

use std::collections::HashMap;
use std::path::Path;

use crate::axis::ProbePoint;
use crate::organ::OrganMesh;
use crate::tissue::bound::BoundTissue;
use crate::tissue::law::{TissueError, TissueLaw};
use crate::tissue::subsplit::{
    EighthPoint, PointKey, SubSplit, quarter_midpoints, split_points, sub_corners, sub_name,
};
use crate::tissue::surface::{
    PressCount, PressPoint, SurfaceLaw, SurfaceLawBuildError, logged_press_ids, node_peak,
    organ_vertex_normals,
};

/// A sub-triangle that could be split again.
#[derive(Debug, Clone)]
pub struct SubCandidate {
    /// Its triangle (index in the organ's boundary) and which sub-triangle (0–2 at that
    /// boundary triangle's corner, 3 the middle one).
    pub triangle: usize,
    pub sub: usize,
    /// Its largest edge surplus (mm; see the module docs).
    pub edge_surplus_mm: f64,
}

/// The sub-triangles to split again and the points to press.
#[derive(Debug)]
pub struct SubSplitPlan {
    /// Every candidate, the largest edge surplus first (ties in the mesh's order).
    pub candidates: Vec<SubCandidate>,
    /// How many of them, from the first, are split.
    pub chosen: usize,
    names: Vec<([u32; 3], u32)>,
    points: Vec<PressPoint>,
    bases: Vec<Vec<(usize, f64)>>,
    eighths: Vec<EighthPoint>,
}

impl SubSplitPlan {
    /// The chosen sub-triangles, named as [`SubSplit::sub_triangles`] names them.
    pub fn names(&self) -> &[([u32; 3], u32)] {
        &self.names
    }

    /// Points to press (each once).
    pub fn presses(&self) -> usize {
        self.points.len()
    }

    /// The press-log ids of its points.
    pub fn press_ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.points.iter().map(|p| p.id)
    }

    /// Candidate `i`'s corners on the organ's surface (mm).
    pub fn corners_mm(&self, organ: &OrganMesh, i: usize) -> [[f64; 3]; 3] {
        let c = &self.candidates[i];
        let tri = organ.boundary[c.triangle];
        sub_corners(c.sub).map(|e| {
            std::array::from_fn(|x| {
                (0..3)
                    .map(|k| f64::from(e[k]) / 8.0 * organ.mesh.vertices[tri[k] as usize][x])
                    .sum()
            })
        })
    }

    /// The candidate holding the organ's surface point closest to `p_mm`, and its rank
    /// (0: the worst); `None` where that point's triangle was not split.
    pub fn rank_at(&self, organ: &OrganMesh, p_mm: [f64; 3]) -> Option<(usize, &SubCandidate)> {
        let hit = crate::axis::closest_point(&organ.mesh.vertices, &organ.boundary, p_mm)?;
        let (sub, _) = crate::tissue::subsplit::sub_of(hit.bary);
        self.candidates
            .iter()
            .enumerate()
            .find(|(_, c)| c.triangle == hit.triangle as usize && c.sub == sub)
    }
}

impl TissueLaw {
    /// Plans splitting the `most` worst sub-triangles of this file's split triangles
    /// again. `law` is this file's [`surface_law`](Self::surface_law) on `organ`.
    /// `rank_to_mm`: rank by the surpluses at the grid depths up to the first at or
    /// past it (a scene that presses only so deep); `None`: every grid depth.
    pub fn sub_split_plan(
        &self,
        organ: &OrganMesh,
        law: &SurfaceLaw,
        most: usize,
        rank_to_mm: Option<f64>,
    ) -> Result<SubSplitPlan, TissueError> {
        let refused = |why: String| TissueError::Refine { why };
        if !self.refinement.band.is_empty() {
            return Err(refused(
                "it holds a band next to the fixed region, pressed last: split its \
                 sub-triangles in the file the band was pressed on (`palpa lab tissue cut \
                 --no-band` gives it back), then press the band again"
                    .into(),
            ));
        }
        if !self.refinement.sub.is_empty() {
            return Err(refused(format!(
                "it already has {} sub-triangles split again: split more from the file they \
                 were split from, with a larger count (its press log keeps their presses)",
                self.refinement.sub.sub_triangles.len()
            )));
        }
        if self.refinement.triangles.is_empty() {
            return Err(refused(
                "it has no split triangles (expected a file refined by `palpa lab tissue refine`)"
                    .into(),
            ));
        }
        let vertices: Vec<[f64; 3]> = organ.mesh.vertices.clone();
        let bound = BoundTissue::bind(self.clone(), &[], &vertices, &organ.boundary)?;
        let n_row = law.steps() * 3 * law.rows.len();
        let ranked_steps = match rank_to_mm {
            Some(d) if d.is_finite() && d >= 0.0 => {
                ((d / law.options.depth_step_mm).ceil() as usize + 1).min(law.steps())
            }
            Some(d) => {
                return Err(refused(format!(
                    "the ranking depth {d} mm: expected a depth of zero or more"
                )));
            }
            None => law.steps(),
        };
        let ranked = ranked_steps * 3 * law.rows.len();
        let peak = |s: u32| {
            if s == u32::MAX {
                0.0
            } else {
                node_peak(&law.residuals()[s as usize * n_row..][..ranked])
            }
        };
        let mut candidates = Vec::new();
        for t in 0..organ.boundary.len() {
            let (_, Some(first)) = bound.first_level(t) else {
                continue;
            };
            for sub in 0..4 {
                let edge_surplus_mm = quarter_midpoints(&first, sub)
                    .into_iter()
                    .map(peak)
                    .fold(0.0, f64::max);
                candidates.push(SubCandidate {
                    triangle: t,
                    sub,
                    edge_surplus_mm,
                });
            }
        }
        candidates.sort_by(|a, b| {
            b.edge_surplus_mm
                .total_cmp(&a.edge_surplus_mm)
                .then((a.triangle, a.sub).cmp(&(b.triangle, b.sub)))
        });
        let chosen = most.min(candidates.len());
        let normals = organ_vertex_normals(organ);
        let edges = organ.palpable_edges();
        let first_id = organ.mesh.vertices.len() + 3 * organ.boundary.len();
        let level_two = first_id + 2 * edges.len() + 3 * organ.boundary.len();
        let mut plan = SubSplitPlan {
            candidates,
            chosen,
            names: Vec::new(),
            points: Vec::new(),
            bases: Vec::new(),
            eighths: Vec::new(),
        };
        let mut seen: HashMap<PointKey, usize> = HashMap::new();
        for c in &plan.candidates[..chosen] {
            let (t, tri) = (c.triangle, organ.boundary[c.triangle]);
            let (corners, _) = bound.first_level(t);
            plan.names.push(sub_name(corners, c.sub));
            let (quarters, inner) = split_points(sub_corners(c.sub));
            for &eighths in quarters.iter().flatten().chain(&inner) {
                let point = EighthPoint { corners, eighths };
                if seen.insert(point.key(), plan.points.len()).is_some() {
                    continue;
                }
                let w = point.bary();
                let (mut at, mut push) = ([0.0; 3], [0.0; 3]);
                for k in 0..3 {
                    let v = tri[k] as usize;
                    for x in 0..3 {
                        at[x] += w[k] * organ.mesh.vertices[v][x];
                        push[x] -= w[k] * f64::from(normals[v][x]);
                    }
                }
                let id = match (0..3).find(|&k| eighths[k] == 0) {
                    Some(k) => {
                        let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                        let (lo, e) = if a < b {
                            (a, eighths[(k + 1) % 3])
                        } else {
                            (b, eighths[(k + 2) % 3])
                        };
                        let g = edges
                            .binary_search(&[lo, a.max(b)])
                            .map_err(|_| refused(format!("triangle {t}'s edge is not palpable")))?;
                        level_two + 8 * g + usize::from(e)
                    }
                    None => {
                        level_two
                            + 8 * edges.len()
                            + 64 * t
                            + 8 * usize::from(eighths[0])
                            + usize::from(eighths[1])
                    }
                };
                let probe = ProbePoint {
                    triangle: t as u32,
                    bary: w,
                };
                let terms = bound.terms(&probe).ok_or_else(|| {
                    refused(format!("split triangle {t} blends no pressed corner"))
                })?;
                plan.bases
                    .push(terms.into_iter().filter(|&(_, w)| w != 0.0).collect());
                plan.points.push(PressPoint {
                    at,
                    push,
                    id: id as u32,
                });
                plan.eighths.push(point);
            }
        }
        Ok(plan)
    }

    /// The second level planned from this file, whether its sub-triangles were split
    /// again already or not: a file split again is planned from the file it was split
    /// from ([`Self::without_sub_split`]), and its own sub-triangles must be among the
    /// `most` chosen, so the new file holds them and more (a larger stage; their
    /// presses come from the log where it holds them, or are made again). Returns the
    /// file to split, its surface law and the plan, for [`SurfaceLaw::press_sub_split`]
    /// and [`Self::sub_split`].
    pub fn second_level_plan(
        &self,
        organ: &OrganMesh,
        most: usize,
        rank_to_mm: Option<f64>,
    ) -> Result<(TissueLaw, SurfaceLaw, SubSplitPlan), TissueError> {
        let had = &self.refinement.sub.sub_triangles;
        let first = if had.is_empty() {
            self.clone()
        } else {
            self.without_sub_split()
        };
        let law = first.surface_law(organ)?;
        let plan = first.sub_split_plan(organ, &law, most, rank_to_mm)?;
        let chosen: std::collections::HashSet<_> = plan.names.iter().collect();
        let left = had.iter().filter(|n| !chosen.contains(n)).count();
        if left > 0 {
            return Err(TissueError::Refine {
                why: format!(
                    "{left} of its {} sub-triangles split again are not among the {} worst \
                     by this ranking{}: ask for more, ranked as the file was",
                    had.len(),
                    plan.chosen,
                    rank_to_mm.map_or(String::new(), |d| format!(" (to {d} mm)")),
                ),
            });
        }
        Ok((first, law, plan))
    }

    /// This file with `plan`'s sub-triangles split again: `law` is this file's
    /// [`surface_law`](Self::surface_law) after [`SurfaceLaw::press_sub_split`] gave
    /// `kept`. The new surpluses are compressed with this file's tolerance and bits, a
    /// sub-triangle's sharing their modes; the bound is the larger of this file's and
    /// theirs.
    pub fn sub_split(
        &self,
        organ: &OrganMesh,
        mut law: SurfaceLaw,
        plan: &SubSplitPlan,
        kept: &[Result<(), String>],
    ) -> Result<TissueLaw, TissueError> {
        let old = self.reach.len();
        let new = kept.iter().filter(|k| k.is_ok()).count();
        if law.reach.len() != old + new || kept.len() != plan.eighths.len() {
            return Err(TissueError::Refine {
                why: "the pressed law does not hold this file's samples and the plan's".into(),
            });
        }
        law.refinement.sub = SubSplit {
            sub_triangles: plan.names.clone(),
            points: plan
                .eighths
                .iter()
                .zip(kept)
                .filter(|(_, k)| k.is_ok())
                .map(|(p, _)| *p)
                .collect(),
        };
        let in_file: Vec<Option<usize>> = (0..old + new).map(|s| (s < old).then_some(s)).collect();
        self.compress_after(organ, &law, &in_file)
    }
}

impl SurfaceLaw {
    /// The press-log ids the log at `path` (of a build with this law's options)
    /// already holds.
    pub fn logged_ids(
        &self,
        organ: &OrganMesh,
        path: &Path,
    ) -> Result<Vec<u32>, SurfaceLawBuildError> {
        logged_press_ids(organ, &self.options, self.rows.len(), path)
    }

    /// Presses `plan`'s points (in parallel, logged at `log`) and appends their
    /// surpluses: per point, whether it was kept (or why its press failed), and how
    /// many presses came from the log.
    pub fn press_sub_split(
        &mut self,
        organ: &OrganMesh,
        plan: &SubSplitPlan,
        log: Option<&crate::tissue::presser::PressLog>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(Vec<Result<(), String>>, usize), SurfaceLawBuildError> {
        self.press_surpluses(organ, &plan.points, &plan.bases, log, progress)
    }
}
