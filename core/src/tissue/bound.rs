//! The tissue law bound to one scene: the blend a probe evaluates on-line.

use std::collections::HashMap;

use crate::axis::ProbePoint;
use crate::tissue::law::{PointIndex, TissueError, TissueLaw};
use crate::tissue::subsplit::{
    EighthPoint, LevelSamples, SubSplit, edge_eighth_terms, level_terms, split_points, sub_corners,
    sub_name, sub_of,
};

/// Most samples one probe's blend uses: three corners, three edges, three surpluses of
/// a split triangle's quarter or of split edges, and three of the second level's (see
/// [`BoundTissue::terms`]).
const TERMS: usize = 12;

/// The samples and weights of one probe's blend.
pub(super) type Terms = [(usize, f64); TERMS];

/// The second level's samples per palpable triangle (see [`BoundTissue`]'s
/// `sub_samples` and `edge_eighths`): points found by their keys among `sub`'s, whose
/// first sample is `first`.
#[allow(clippy::type_complexity)]
fn second_level(
    sub: &SubSplit,
    first: usize,
    corner_samples: &[[u32; 3]],
    split: &[bool],
) -> (
    Vec<Option<Box<[LevelSamples; 4]>>>,
    Vec<Option<Box<[[u32; 4]; 3]>>>,
) {
    let n = corner_samples.len();
    if sub.points.is_empty() && sub.sub_triangles.is_empty() {
        return (vec![None; n], vec![None; n]);
    }
    let by_key = sub.samples_by_key(first);
    let split_again: std::collections::HashSet<([u32; 3], u32)> =
        sub.sub_triangles.iter().copied().collect();
    let mut subs = Vec::with_capacity(n);
    let mut edges = Vec::with_capacity(n);
    for (&corners, &is_split) in corner_samples.iter().zip(split) {
        let find = |eighths: [u8; 3]| {
            let key = EighthPoint { corners, eighths }.key();
            by_key.get(&key).copied().unwrap_or(u32::MAX)
        };
        if is_split {
            let tables: [LevelSamples; 4] = std::array::from_fn(|s| {
                let (quarters, inner) = split_points(sub_corners(s));
                LevelSamples {
                    split: split_again.contains(&sub_name(corners, s)),
                    quarters: quarters.map(|q| q.map(find)),
                    inner: inner.map(find),
                }
            });
            let any = tables.iter().any(|t| t.split || t.any());
            subs.push(any.then(|| Box::new(tables)));
            edges.push(None);
        } else {
            let on_edges: [[u32; 4]; 3] = std::array::from_fn(|k| {
                std::array::from_fn(|m| {
                    let mut e = [0u8; 3];
                    e[k] = 7 - 2 * m as u8;
                    e[(k + 1) % 3] = 1 + 2 * m as u8;
                    find(e)
                })
            });
            let any = on_edges.iter().flatten().any(|&s| s != u32::MAX);
            subs.push(None);
            edges.push(any.then(|| Box::new(on_edges)));
        }
    }
    (subs, edges)
}

/// A tissue law bound to one scene: its rows and samples in the scene's numbering.
#[derive(Debug, Clone)]
pub struct BoundTissue {
    pub law: TissueLaw,
    /// Per law row: the scene's render vertex, or `u32::MAX` (not drawn).
    vertex_of_row: Vec<u32>,
    /// Per palpable (axis) triangle: each corner's sample, or `u32::MAX`.
    corner_samples: Vec<[u32; 3]>,
    /// Per palpable triangle: the surplus sample of its edges (corners 0–1, 1–2, 2–0),
    /// or `u32::MAX` where the edge was not pressed.
    pub(super) edge_samples: Vec<[u32; 3]>,
    /// Per palpable triangle: whether it was split into four (see
    /// [`Refinement`](crate::tissue::surface::Refinement)).
    split: Vec<bool>,
    /// Per palpable triangle and edge `k` (corners `k`, `k + 1`): the surplus samples of
    /// its quarter points near corner `k` and near corner `k + 1`, or `u32::MAX`.
    quarter_samples: Vec<[[u32; 2]; 3]>,
    /// Per palpable triangle: the surplus sample of its inner point near each corner,
    /// or `u32::MAX`.
    inner_samples: Vec<[u32; 3]>,
    /// Per split palpable triangle with second-level samples: each sub-triangle's (in
    /// [`sub_corners`]' order; see [`SubSplit`]).
    sub_samples: Vec<Option<Box<[LevelSamples; 4]>>>,
    /// Per palpable triangle not split with second-level quarter points on its edges:
    /// per edge `k`, those at 1/8, 3/8, 5/8, 7/8 of the way from corner `k`.
    edge_eighths: Vec<Option<Box<[[u32; 4]; 3]>>>,
    /// Render vertices the law has no row for (kept for the report).
    pub unmatched_vertices: usize,
}

/// Scratch for [`BoundTissue::add_surface`]: the weight of each blended group's modes.
#[derive(Debug, Clone)]
pub struct TissueScratch {
    c: Vec<f64>,
}

impl BoundTissue {
    /// Binds `law` to a scene by rest positions: its render vertices, palpable (axis)
    /// vertices and palpable triangles over those (`PalpationScene::vertices_mm`,
    /// `axis_vertices_mm`, `axis_triangles`). Every palpable vertex the law pressed
    /// must be on the scene's palpable surface.
    pub fn bind(
        law: TissueLaw,
        vertices_mm: &[[f32; 3]],
        axis_vertices_mm: &[[f64; 3]],
        axis_triangles: &[[u32; 3]],
    ) -> Result<BoundTissue, TissueError> {
        let rows = PointIndex::new(law.rows_mm.iter().map(|p| p.map(f64::from)));
        let samples = PointIndex::new(law.samples_mm.iter().map(|p| p.map(f64::from)));
        let mut vertex_of_row = vec![u32::MAX; law.rows_mm.len()];
        let mut unmatched_vertices = 0;
        for (v, p) in vertices_mm.iter().enumerate() {
            match rows.find(p.map(f64::from)) {
                Some(r) => vertex_of_row[r as usize] = v as u32,
                None => unmatched_vertices += 1,
            }
        }
        let axis_sample: Vec<u32> = axis_vertices_mm
            .iter()
            .map(|&p| samples.find(p).unwrap_or(u32::MAX))
            .collect();
        let matched = axis_sample.iter().filter(|&&s| s != u32::MAX).count();
        if matched < law.samples_mm.len() {
            return Err(TissueError::Mismatch {
                matched,
                total: law.samples_mm.len(),
            });
        }
        let corner_samples: Vec<[u32; 3]> = axis_triangles
            .iter()
            .map(|t| t.map(|v| axis_sample[v as usize]))
            .collect();
        let first_edge = law.samples_mm.len();
        let edge_of: HashMap<[u32; 2], u32> = law
            .edge_ends
            .iter()
            .enumerate()
            .map(|(e, &[a, b])| ([a.min(b), a.max(b)], (first_edge + e) as u32))
            .collect();
        // The band's samples come last: each by its pressed end's sample and its other
        // end's palpable vertex.
        let band = &law.refinement.band;
        let first_band = law.reach.len() - band.len();
        let axis = PointIndex::new(axis_vertices_mm.iter().copied());
        let mut band_of: HashMap<(u32, u32), u32> = HashMap::with_capacity(band.len());
        for (i, b) in band.iter().enumerate() {
            let other = axis
                .find(b.other_mm.map(f64::from))
                .ok_or(TissueError::BandOffScene { at_mm: b.other_mm })?;
            band_of.insert((b.end, other), (first_band + i) as u32);
        }
        let edge_samples = corner_samples
            .iter()
            .zip(axis_triangles)
            .map(|(c, tri)| {
                std::array::from_fn(|k| {
                    let (a, b) = (c[k], c[(k + 1) % 3]);
                    match (a == u32::MAX, b == u32::MAX) {
                        (false, false) => edge_of.get(&[a.min(b), a.max(b)]).copied(),
                        (false, true) => band_of.get(&(a, tri[(k + 1) % 3])).copied(),
                        (true, false) => band_of.get(&(b, tri[k])).copied(),
                        (true, true) => None,
                    }
                    .unwrap_or(u32::MAX)
                })
            })
            .collect();
        // The split triangles' samples, found by the corner samples they refine.
        let r = &law.refinement;
        let sorted = |mut c: [u32; 3]| {
            c.sort_unstable();
            c
        };
        let split_set: std::collections::HashSet<[u32; 3]> =
            r.triangles.iter().map(|&c| sorted(c)).collect();
        let first_quarter = first_edge + law.edge_ends.len();
        let quarter_of: HashMap<[u32; 2], u32> = r
            .quarter_ends
            .iter()
            .enumerate()
            .map(|(q, &ends)| (ends, (first_quarter + q) as u32))
            .collect();
        let first_inner = first_quarter + r.quarter_ends.len();
        let inner_of: HashMap<([u32; 3], u32), u32> = r
            .inner_corners
            .iter()
            .enumerate()
            .map(|(i, &c)| ((sorted(c), c[0]), (first_inner + i) as u32))
            .collect();
        let split: Vec<bool> = corner_samples
            .iter()
            .map(|&c| !c.contains(&u32::MAX) && split_set.contains(&sorted(c)))
            .collect();
        let quarter_samples = corner_samples
            .iter()
            .map(|c| {
                std::array::from_fn(|k| {
                    let (a, b) = (c[k], c[(k + 1) % 3]);
                    let find = |ends| quarter_of.get(&ends).copied().unwrap_or(u32::MAX);
                    [find([a, b]), find([b, a])]
                })
            })
            .collect();
        let inner_samples = corner_samples
            .iter()
            .map(|&c| {
                std::array::from_fn(|k| {
                    inner_of
                        .get(&(sorted(c), c[k]))
                        .copied()
                        .unwrap_or(u32::MAX)
                })
            })
            .collect();
        let first_sub = first_inner + r.inner_corners.len();
        let (sub_samples, edge_eighths) = second_level(&r.sub, first_sub, &corner_samples, &split);
        Ok(BoundTissue {
            law,
            vertex_of_row,
            corner_samples,
            edge_samples,
            split,
            quarter_samples,
            inner_samples,
            sub_samples,
            edge_eighths,
            unmatched_vertices,
        })
    }

    /// Palpable triangle `t`'s corner samples and, where it was split, its first
    /// level's samples.
    pub(crate) fn first_level(&self, t: usize) -> ([u32; 3], Option<LevelSamples>) {
        let split = LevelSamples {
            split: true,
            quarters: self.quarter_samples[t],
            inner: self.inner_samples[t],
        };
        (self.corner_samples[t], self.split[t].then_some(split))
    }

    /// Sub-triangle `sub` of palpable triangle `t`'s second-level samples, where it
    /// has any.
    pub(crate) fn second_level(&self, t: usize, sub: usize) -> Option<LevelSamples> {
        self.sub_samples[t].as_ref().map(|s| s[sub])
    }

    pub fn scratch(&self) -> TissueScratch {
        TissueScratch {
            c: vec![0.0; TERMS * self.law.rank as usize],
        }
    }

    /// The grid interval of `depth_mm` (held at the ends, the last being grid depth
    /// `last`): `(j, t, beyond)` with the depth at `(j + t) · step`.
    pub(super) fn interval(&self, depth_mm: f64, last: usize) -> (usize, f64, bool) {
        let x = depth_mm.max(0.0) / self.law.options.depth_step_mm;
        let beyond = x > last as f64 * (1.0 + 1e-12);
        let x = x.min(last as f64);
        let j = (x.floor() as usize).min(last - 1);
        (j, x - j as f64, beyond)
    }

    /// The last grid depth every sample of `terms` (with a weight) reached, and the
    /// sample that stops there first (`None` where all reached the grid's end).
    pub(super) fn last_depth(&self, terms: Option<&Terms>) -> (usize, Option<usize>) {
        let full = self.law.steps as usize - 1;
        terms.into_iter().flatten().filter(|(_, w)| *w != 0.0).fold(
            (full, None),
            |(last, who), &(s, _)| {
                let r = self.law.reach[s] as usize - 1;
                if r < last { (r, Some(s)) } else { (last, who) }
            },
        )
    }

    /// How many corners of the probe's triangle were never pressed (0 to 3): corners
    /// on the fixed region, where a press would push a held node. The blend there
    /// leans on the other corners alone, and the band it covers, where the tool also
    /// bears on the attachment, stiffens faster than any pressed point says
    /// (docs/lab/tissue-measurements.md §11). `3` off the palpable surface. Allocation-free.
    pub fn unpressed_corners(&self, p: &ProbePoint) -> usize {
        self.corner_samples
            .get(p.triangle as usize)
            .map_or(3, |c| c.iter().filter(|&&s| s == u32::MAX).count())
    }

    /// The deepest press the vademecum answers at `p` (mm): the grid's end, or less
    /// where a press its blend uses found no equilibrium deeper, with that press's
    /// reason (naming the depth it failed at).
    pub fn limit_mm(&self, p: &ProbePoint) -> (f64, Option<&str>) {
        let (last, who) = self.last_depth(self.terms(p).as_ref());
        (
            last as f64 * self.law.options.depth_step_mm,
            who.map(|s| self.law.stopped[s].as_str()),
        )
    }

    /// The samples the probe's press is blended from, with their weights: the sampled
    /// corners with their barycentric weights renormalized, the pressed edges'
    /// surpluses with `4 λ_a λ_b` (the quadratic hierarchical blend), then the split
    /// triangle's sub-triangle surpluses with `4 μ_i μ_j`, or, in a triangle not split,
    /// the quarter points of its split edges (see
    /// [`Refinement`](crate::tissue::surface::Refinement)), then the same again one level
    /// down ([`SubSplit`]); unused entries have weight 0. `None` when no corner was
    /// sampled.
    pub(crate) fn terms(&self, p: &ProbePoint) -> Option<Terms> {
        let t = p.triangle as usize;
        let samples = self.corner_samples.get(t)?;
        let total: f64 = (0..3)
            .filter(|&k| samples[k] != u32::MAX)
            .map(|k| p.bary[k])
            .sum();
        // NaN weights count as none.
        if total.is_nan() || total <= 0.0 {
            return None;
        }
        let mut out = [(0usize, 0.0f64); TERMS];
        let term = |s: u32, w: f64| {
            if s == u32::MAX {
                (0, 0.0)
            } else {
                (s as usize, w)
            }
        };
        let l = p.bary;
        let edges = self.edge_samples[t];
        for k in 0..3 {
            out[k] = term(samples[k], l[k] / total);
            // An edge is pressed only where both its ends were: no renormalizing.
            out[3 + k] = term(edges[k], 4.0 * l[k] * l[(k + 1) % 3]);
        }
        let first = LevelSamples {
            split: self.split[t],
            quarters: self.quarter_samples[t],
            inner: self.inner_samples[t],
        };
        // `λ` sums to one in a split triangle (all its corners were pressed).
        for (k, (s, w)) in level_terms(l, &first).into_iter().enumerate() {
            out[6 + k] = term(s, w);
        }
        let second = if self.split[t] {
            self.sub_samples[t].as_ref().map(|subs| {
                let (sub, mu) = sub_of(l);
                level_terms(mu, &subs[sub])
            })
        } else {
            self.edge_eighths[t]
                .as_ref()
                .map(|e| edge_eighth_terms(l, e))
        };
        for (k, (s, w)) in second.into_iter().flatten().enumerate() {
            out[9 + k] = term(s, w);
        }
        Some(out)
    }

    /// `g(s, d)` and whether `d` lay beyond the grid; 1 where no corner was sampled.
    pub fn ratio(&self, p: &ProbePoint, depth_mm: f64) -> (f64, bool) {
        let terms = self.terms(p);
        let (last, _) = self.last_depth(terms.as_ref());
        self.blended_ratio(terms.as_ref(), last, depth_mm)
    }

    /// [`Self::ratio`] for the blend `terms` answered to grid depth `last`: the
    /// force and its inverse find both once per call, not once per depth tried.
    fn blended_ratio(&self, terms: Option<&Terms>, last: usize, depth_mm: f64) -> (f64, bool) {
        let (j, t, beyond) = self.interval(depth_mm, last);
        let Some(corners) = terms else {
            return (1.0, beyond);
        };
        let steps = self.law.steps as usize;
        let g = corners
            .iter()
            .map(|&(s, w)| {
                let a = f64::from(self.law.ratio[s * steps + j]);
                let b = f64::from(self.law.ratio[s * steps + j + 1]);
                w * ((1.0 - t) * a + t * b)
            })
            .sum();
        (g, beyond)
    }

    /// Depth in, force out: `F = d / c · g(s, d)` with the linear compliance
    /// `compliance_mm_per_n` at `p`; past the grid, or past the depth a press of the
    /// blend reached ([`Self::limit_mm`]), the force is held there and flagged.
    pub fn force_n(&self, p: &ProbePoint, depth_mm: f64, compliance_mm_per_n: f64) -> (f64, bool) {
        let terms = self.terms(p);
        let (last, _) = self.last_depth(terms.as_ref());
        let top = last as f64 * self.law.options.depth_step_mm;
        let d = depth_mm.clamp(0.0, top);
        let (g, _) = self.blended_ratio(terms.as_ref(), last, d);
        (d / compliance_mm_per_n * g, depth_mm > top * (1.0 + 1e-12))
    }

    /// The blended ratio at grid depth `j` (1 where no corner was sampled).
    fn blended_node(&self, terms: Option<&Terms>, j: usize) -> f64 {
        let steps = self.law.steps as usize;
        terms.map_or(1.0, |corners| {
            corners
                .iter()
                .map(|&(s, w)| w * f64::from(self.law.ratio[s * steps + j]))
                .sum()
        })
    }

    /// Force in, depth out: the depth whose force is `force_n` on the blended curve,
    /// which does not fall with depth up to the probe's limit (every press kept stops
    /// where its force falls, and is held at its largest over a dip within tolerance);
    /// held at the limit, and flagged, when even that needs less force.
    ///
    /// The ratio is linear in the depth between grid depths, so the force `d/c · g(d)`
    /// is a quadratic there: the grid interval that holds `force_n` is found by
    /// bisection over the grid depths, then its quadratic is solved, about seven
    /// blends in all.
    pub fn depth_mm(&self, p: &ProbePoint, force_n: f64, compliance_mm_per_n: f64) -> (f64, bool) {
        let terms = self.terms(p);
        let (last, _) = self.last_depth(terms.as_ref());
        let top = last as f64 * self.law.options.depth_step_mm;
        let f = |d: f64| d / compliance_mm_per_n * self.blended_ratio(terms.as_ref(), last, d).0;
        if force_n.is_nan() || force_n <= 0.0 {
            return (0.0, false);
        }
        if f(top) < force_n {
            return (top, true);
        }
        // f(0) = 0 < F <= f(top): keep f(lo) < F <= f(hi) over grid depths.
        let h = self.law.options.depth_step_mm;
        let at_node =
            |j: usize| j as f64 * h / compliance_mm_per_n * self.blended_node(terms.as_ref(), j);
        let (mut lo, mut hi) = (0, last);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if at_node(mid) < force_n {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        // On [d0, d0 + h]: g(d) = ga + k (d - d0), so F c = k d² + b d with b = ga - k d0;
        // the root in the interval is the one nearer zero, taken in the form that does
        // not cancel, so a tiny force's depth is F c / b to round-off (bisection's
        // top / 2⁴⁸ had answered 1e-300 N with 1.8e-14 mm).
        let (ga, gb) = (
            self.blended_node(terms.as_ref(), lo),
            self.blended_node(terms.as_ref(), hi),
        );
        let d0 = lo as f64 * h;
        let k = (gb - ga) / h;
        let b = ga - k * d0;
        let fc = force_n * compliance_mm_per_n;
        let root = (b * b + 4.0 * k * fc).max(0.0).sqrt();
        let d = if b + root > 0.0 {
            2.0 * fc / (b + root)
        } else {
            d0
        };
        (d.clamp(d0, hi as f64 * h), false)
    }

    /// Adds the nonlinear residual of a press of `depth_mm` at `p` to `rows_mm` (three
    /// per render vertex, the scene's row order); returns false (adding nothing) where
    /// no corner was sampled. `3n` multiply-adds per corner mode, no allocation.
    pub fn add_surface(
        &self,
        p: &ProbePoint,
        depth_mm: f64,
        scratch: &mut TissueScratch,
        rows_mm: &mut [f64],
    ) -> bool {
        let Some(corners) = self.terms(p) else {
            return false;
        };
        let (last, _) = self.last_depth(Some(&corners));
        let (j, t, _) = self.interval(depth_mm, last);
        let steps = self.law.steps as usize;
        // Each mode's weight at this depth, summed over the terms that share its group
        // (a split triangle's points share theirs): `groups[n]` is the n-th distinct
        // group, its first mode, count and first slot in the scratch.
        let mut groups = [(0u32, 0usize, 0usize, 0usize); TERMS];
        let (mut n_groups, mut slots) = (0, 0);
        for &(s, w) in &corners {
            if w == 0.0 {
                continue;
            }
            let (modes, first) = self.law.sample_modes(s);
            let group = self.law.group[s];
            let slot = match groups[..n_groups].iter().find(|g| g.0 == group) {
                Some(g) => g.3,
                None => {
                    groups[n_groups] = (group, modes.start, modes.len(), slots);
                    scratch.c[slots..slots + modes.len()].fill(0.0);
                    n_groups += 1;
                    slots += modes.len();
                    slots - modes.len()
                }
            };
            for k in 0..modes.len() {
                let a = f64::from(self.law.coeffs[first + k * steps + j]);
                let b = f64::from(self.law.coeffs[first + k * steps + j + 1]);
                scratch.c[slot + k] += w * ((1.0 - t) * a + t * b);
            }
        }
        for &(_, start, count, slot) in &groups[..n_groups] {
            for (k, mode) in (start..start + count).enumerate() {
                let weight = scratch.c[slot + k];
                if weight == 0.0 {
                    continue;
                }
                let weight = weight * f64::from(self.law.shape_scale[mode]);
                self.law
                    .shape
                    .add_mode(mode, weight, &self.vertex_of_row, rows_mm);
            }
        }
        true
    }
}
