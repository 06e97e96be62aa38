//! The tissue's nonlinear surface, `u(x; s, d)`: what the organ's surface does under a
//! press of depth `d` at probe position `s`, beyond the linear answer.
//!
//! The linear vademecum gives the exact linear field at any `s`; at depth `d` the
//! linear surface is `d · û(x; s)`, with `û` the field of unit probe depth. The
//! nonlinear tissue differs from it by the residual
//!
//! ```text
//! r(x; s, d) = u(x; s, d) − d · û(x; s),      r(s; s, d) · n = 0 (the depth is exact),
//! ```
//!
//! which is computed off-line, per palpable vertex `v`, by following its press along the
//! depth grid ([`crate::fe::path`]): the depth series ([`crate::fe::series`]) predicts
//! and a chord Newton corrects each grid depth to equilibrium, with a new series
//! segment (one factorization) wherever the last one stops predicting. The first
//! segment uses the rest stiffness, factored once for all vertices; `û` is its first
//! order (the linear field), so `r_v(d_j) = u_v(d_j) − d_j u_1`. The stored states are
//! equilibria to the corrector's tolerance (1e-3 mm): at the vertices the vademecum is
//! the full nonlinear FE.
//!
//! On-line, a probe inside a palpable triangle blends its corners' residuals with its
//! barycentric weights, linearly in `d` between grid depths:
//! `r(x; s, d) ≈ Σ_k λ_k(s) r_{v_k}(x; d)`. The blend is exact at the vertices and
//! errs between them by the change of the residual's shape over one edge, the same
//! floor as a P1 interpolation of the linear field (where the linear vademecum is exact
//! by its nodal loads instead). Only the surface vertices' rows are kept, in f32.
//!
//! A press is kept only as deep as it has an equilibrium *and* its force does not
//! fall: where the corrector finds none, or the force drops below its largest by more
//! than the states' force tolerance (Saint Venant–Kirchhoff past its loss of
//! stability in compression: under depth control the states go on, but a hand
//! pressing with a force snaps through them), the press's *reach* ends at the last
//! grid depth before, its arrays hold that depth beyond, and the reason is kept. A
//! smaller dip (the tool sliding along a flat stretch) is not a peak: the stored force
//! is held at its largest before it, so the curve never falls. An
//! edge's surplus reaches as far as its midpoint and both its ends.

use crate::tissue::options::VertexPress;
pub use crate::tissue::options::{
    COVER_SLACK_MM, MAX_GRID_POINTS, PressCount, SurfaceLawBuildError, SurfaceLawOptions,
};
pub use crate::tissue::press::{PointPress, Pressing, organ_vertex_normals, path_options};
pub(crate) use crate::tissue::presser::{PressPoint, logged_press_ids};
pub use crate::tissue::refine::{BandEdge, DEFAULT_REFINE_ABOVE_MM, Refinement, covering_vertices};

pub(crate) use crate::tissue::refine::{
    Source, node_peak, palpable_at, refine_candidates, refine_plan, worst_first,
};

use crate::tissue::press::edge_id;
use crate::tissue::presser::{Logged, PressLog, Presser, Stored, open_press_log};
use crate::tissue::refine::{Got, in_plan_order, split_triangles};

use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Instant;

use crate::fe::probe::organ_space;
use crate::fe::series::Expander;
use crate::organ::OrganMesh;

/// The built residuals.
#[derive(Debug, Clone)]
pub struct SurfaceLaw {
    pub options: SurfaceLawOptions,
    /// The surface vertices whose rows are kept (organ mesh vertex ids).
    pub rows: Vec<u32>,
    /// Per organ mesh vertex: its sample index, or `u32::MAX` (not sampled).
    pub(crate) sample_of: Vec<u32>,
    /// Sampled vertices (organ mesh ids), and those skipped (the tool did not move
    /// its centre: next to the fixed region).
    pub samples: Vec<u32>,
    pub skipped: Vec<u32>,
    /// Pressed edge midpoints, as the two end samples' indices: sample
    /// `samples.len() + e` holds edge `e`'s surplus `r_mid − (r_a + r_b)/2` (and the
    /// same for the force ratio).
    pub edges: Vec<[u32; 2]>,
    /// Why each edge midpoint whose ends were pressed was not (its edge then blends
    /// linearly).
    pub edge_skip_reasons: Vec<String>,
    /// Why each skipped vertex was skipped.
    pub skip_reasons: Vec<String>,
    /// The triangles split into four, and their quarter and inner points' samples
    /// (after the edges'; see [`Refinement`]).
    pub refinement: Refinement,
    /// Why each quarter or inner point of a split triangle was not kept (its term then
    /// drops out of the blend).
    pub refine_skip_reasons: Vec<String>,
    /// Per split triangle: its largest edge surplus, what decided the split, and the
    /// largest surplus of its quarter and inner points, which is how far the quadratic
    /// blend there was from those points' own presses (mm, any node, any depth).
    pub split_figures: Vec<(f64, f64)>,
    /// Per sample (vertices, then edges): the grid depths its press reached, depth 0
    /// included (`steps` for all), and why it stopped short (empty where it did not).
    /// An edge's surplus reaches as far as its midpoint and both ends.
    pub reach: Vec<u32>,
    pub stopped: Vec<String>,
    pub(crate) steps: usize,
    /// `residual[((sample · steps) + j) · 3·rows + 3·row + c]`, mm.
    pub(crate) residual: Vec<f32>,
    /// `ratio[sample · steps + j]`: the force over the linear force at grid depth `j`.
    pub ratio: Vec<f64>,
    /// Per sample: the FE model's linear stiffness there (N/mm), the largest last
    /// Newton correction of its grid states (mm: their equilibrium tolerance), and the
    /// series segments its press took.
    pub stiffness_n_per_mm: Vec<f64>,
    pub correction_mm: Vec<f64>,
    pub segments: Vec<u32>,
    pub build_s: f64,
}

impl SurfaceLaw {
    /// Samples every palpable vertex of `organ` (and, with the options' `edges`, every
    /// palpable edge's midpoint), the presses in parallel (the expander's factorization
    /// is shared read-only); then, with `refine_above_mm`, splits into four the
    /// triangles whose largest edge surplus exceeds it and presses their quarter and
    /// inner points (see [`Refinement`]). `progress` from whichever thread finishes a
    /// press (see [`PressCount`]).
    pub fn build(
        organ: &OrganMesh,
        options: SurfaceLawOptions,
        refine_above_mm: Option<f64>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<SurfaceLaw, SurfaceLawBuildError> {
        Self::build_logged(organ, options, refine_above_mm, None, progress).map(|(law, _)| law)
    }

    /// [`build`](Self::build), keeping each finished vertex's press in the log at
    /// `log` (see [`super::presslog`]): run again after an interruption, it takes the
    /// logged presses, computes the rest and gives the same law bit for bit (each press
    /// is computed alone, so the order the threads finish in does not matter). The
    /// caller removes the log once the law is saved. Returns the law and how many
    /// presses were taken from the log.
    pub fn build_logged(
        organ: &OrganMesh,
        options: SurfaceLawOptions,
        refine_above_mm: Option<f64>,
        log: Option<&PressLog>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(SurfaceLaw, usize), SurfaceLawBuildError> {
        Self::build_selected(organ, options, refine_above_mm, log, None, progress)
    }

    /// [`build_logged`](Self::build_logged) pressing only what the vademecum needs to
    /// answer at `points`: the corners of the palpable triangle holding each (see
    /// [`covering_vertices`]), the edges between them, and the quarter and inner points
    /// of those triangles that the threshold splits. A triangle's blend reads only its
    /// own corners, edges and split points, each pressed alone, so at those points the
    /// law answers as the whole-surface build does, for a few presses a point: how a
    /// whole-surface accuracy table is measured without pressing the whole surface.
    /// The log's key names the covered vertices.
    pub fn build_covering(
        organ: &OrganMesh,
        options: SurfaceLawOptions,
        refine_above_mm: Option<f64>,
        points: &[[f64; 3]],
        log: Option<&PressLog>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(SurfaceLaw, usize), SurfaceLawBuildError> {
        let cover = covering_vertices(organ, points)?;
        Self::build_selected(organ, options, refine_above_mm, log, Some(&cover), progress)
    }

    /// The build; `cover` (sorted mesh vertex ids), where given, restricts the
    /// candidates further than `options.within`.
    fn build_selected(
        organ: &OrganMesh,
        options: SurfaceLawOptions,
        refine_above_mm: Option<f64>,
        log: Option<&PressLog>,
        cover: Option<&[u32]>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(SurfaceLaw, usize), SurfaceLawBuildError> {
        use std::sync::atomic::AtomicUsize;
        let o = options;
        let steps = crate::fe::depth_grid_points(o.depth_max_mm, o.depth_step_mm, MAX_GRID_POINTS)?;
        // Refused before the log is opened: a bad option leaves nothing behind.
        crate::fe::series::check_orders(o.orders, 1)?;
        crate::fe::series::check_cutoff(o.active_cutoff)?;
        let t0 = Instant::now();
        let space = organ_space(organ, o.element);
        let expander = Expander::new(&space, o.law, o.material)?;
        let rows = organ.surface_nodes();
        let mut candidates: Vec<u32> = organ
            .pressable_vertices()
            .into_iter()
            .filter(|v| cover.is_none_or(|c| c.binary_search(v).is_ok()))
            .filter(|&v| {
                o.within.is_none_or(|(c, r)| {
                    let p = organ.mesh.vertices[v as usize];
                    (0..3).map(|k| (p[k] - c[k]).powi(2)).sum::<f64>() <= r * r
                })
            })
            .collect();
        candidates.sort_unstable();
        candidates.dedup();
        let (log, shard, finished) = match log {
            Some(spec) => {
                let (l, shard, r) = open_press_log(organ, &o, rows.len(), cover, spec)?;
                (l.map(|(l, p)| (Mutex::new(l), p)), shard, r)
            }
            None => (None, None, Vec::new()),
        };
        // Logged presses by id (a later record of an id wins), those of another grid
        // or row set dropped.
        let mut finished: HashMap<u32, Result<VertexPress, String>> = finished
            .into_iter()
            .filter(|(_, press)| {
                press.as_ref().map_or(true, |p| {
                    p.ratio.len() == steps
                        && p.residual.len() == steps * 3 * rows.len()
                        && (2..=steps as u32).contains(&p.reach)
                })
            })
            .collect();
        // The palpable edges whose ends are both candidates (sorted, deduplicated).
        let edges: Vec<[u32; 2]> = if o.edges {
            organ
                .palpable_edges()
                .into_iter()
                .filter(|e| e.iter().all(|v| candidates.binary_search(v).is_ok()))
                .collect()
        } else {
            Vec::new()
        };
        // Each vertex is pressed along its inward area-weighted normal: the direction
        // a scene's contact law pushes at that vertex (a face's normal would differ
        // from it by up to the dihedral angle on a sharp border); an edge midpoint
        // along the mean of its ends' (the scene interpolates them).
        let normals = organ_vertex_normals(organ);
        let mut points: Vec<PressPoint> = candidates
            .iter()
            .map(|&v| PressPoint {
                at: organ.mesh.vertices[v as usize],
                push: normals[v as usize].map(|c| -f64::from(c)),
                id: v,
            })
            .collect();
        points.extend(edges.iter().enumerate().map(|(e, &[a, b])| {
            let (pa, pb) = (
                organ.mesh.vertices[a as usize],
                organ.mesh.vertices[b as usize],
            );
            let (na, nb) = (normals[a as usize], normals[b as usize]);
            PressPoint {
                at: [0, 1, 2].map(|c| 0.5 * (pa[c] + pb[c])),
                push: [0, 1, 2].map(|c| -f64::from(na[c] + nb[c])),
                id: edge_id(organ, e),
            }
        }));
        let presser = Presser {
            pressing: Pressing {
                space: &space,
                organ,
                expander: &expander,
                o: &o,
            },
            rows: &rows,
            steps,
            log: log.as_ref().map(|(l, p)| (l, p.as_path())),
            shard,
            done: AtomicUsize::new(0),
            from_log: AtomicUsize::new(0),
            progress,
        };
        let press_all =
            |points: &[PressPoint],
             finished: &mut HashMap<u32, Result<VertexPress, String>>,
             total: usize| presser.press(points, finished, total);
        let (mut presses, mut resumed) = press_all(&points, &mut finished, points.len())?;
        let edge_presses = presses.split_off(candidates.len());
        let mut sample_of = vec![u32::MAX; organ.mesh.vertices.len()];
        let (mut samples, mut skipped, mut skip_reasons) = (Vec::new(), Vec::new(), Vec::new());
        let mut stored = Stored::default();
        for (&v, press) in candidates.iter().zip(presses) {
            let p = match press {
                Ok(p) => p,
                Err(why) => {
                    skipped.push(v);
                    skip_reasons.push(why);
                    continue;
                }
            };
            sample_of[v as usize] = samples.len() as u32;
            samples.push(v);
            stored.push(&p, &p.residual, &p.ratio, p.reach, p.stopped.clone());
        }
        // Edge surpluses over their ends' mean, for edges whose three presses stand.
        let (mut kept_edges, mut edge_skip_reasons) = (Vec::new(), Vec::new());
        let n_row = steps * 3 * rows.len();
        for (&[a, b], press) in edges.iter().zip(&edge_presses) {
            let (sa, sb) = (sample_of[a as usize], sample_of[b as usize]);
            let p = match press {
                Ok(p) => p,
                Err(why) => {
                    edge_skip_reasons.push(why.clone());
                    continue;
                }
            };
            if sa == u32::MAX || sb == u32::MAX {
                continue;
            }
            // The surplus up to the depth all three reached, held there.
            let base = [(sa as usize, 0.5), (sb as usize, 0.5)];
            let (surplus, g, reach, why) = stored.surplus(p, &base, steps, 3 * rows.len());
            stored.push(p, &surplus, &g, reach, why);
            kept_edges.push([sa, sb]);
        }
        let mut refinement = Refinement {
            above_mm: refine_above_mm,
            ..Refinement::default()
        };
        let mut refine_skip_reasons = Vec::new();
        let mut split_figures = Vec::new();
        if let Some(above_mm) = refine_above_mm {
            let candidates =
                refine_candidates(organ, &sample_of, &kept_edges, &stored.residual, n_row);
            let plan = refine_plan(organ, candidates, above_mm, None, &[]);
            let first = points.len();
            let order = plan.press_order();
            let points = plan.points_in_press_order(organ, &normals, &order);
            let (pressed, more) = press_all(&points, &mut finished, first + points.len())?;
            let presses = in_plan_order(&order, pressed);
            resumed += more;
            split_figures = split_triangles(
                &plan,
                presses.into_iter().map(Got::Pressed).collect(),
                &Stored::default(),
                &mut stored,
                steps,
                3 * rows.len(),
                &mut refinement,
                &mut refine_skip_reasons,
            );
        }
        let law = SurfaceLaw {
            options,
            rows,
            sample_of,
            samples,
            skipped,
            edges: kept_edges,
            edge_skip_reasons,
            skip_reasons,
            refinement,
            refine_skip_reasons,
            split_figures,
            reach: stored.reach,
            stopped: stored.stopped,
            steps,
            residual: stored.residual,
            ratio: stored.ratio,
            stiffness_n_per_mm: stored.stiffness,
            correction_mm: stored.correction,
            segments: stored.segments,
            build_s: t0.elapsed().as_secs_f64(),
        };
        Ok((law, resumed))
    }

    /// Splits the triangles of a law (see [`Refinement`]): those whose largest edge
    /// surplus exceeds `above_mm`, or only the `most` worst of them, their quarter and
    /// inner points pressed (in parallel, logged at `log` under the same key as a whole
    /// build of the same options, so either takes the other's presses) and kept as
    /// surpluses over *this* law's quadratic blend. A law decompressed from a tissue
    /// file ([`super::law::TissueLaw::surface_law`]) thus gets the split a whole
    /// build would give without pressing its vertices and edges again, each split
    /// point's surplus measured against the blend the file answers with.
    ///
    /// A law that is already split goes on from its stage: its split triangles stay
    /// (whatever their rank), listed first with their points' surpluses as they are,
    /// and only the new triangles' points not already held are pressed; `most` counts
    /// the stage's triangles in all. So a file split in stages, each saved, ends as
    /// one split at once would (the same triangles), without a press log kept between
    /// them. Asking for no more triangles than it has is refused
    /// ([`SurfaceLawBuildError::AlreadyRefined`]).
    ///
    /// Returns the refined law, how many presses came from the log, and how many
    /// triangles lie above the threshold (more than were split under `most`).
    pub fn refine(
        mut self,
        organ: &OrganMesh,
        above_mm: f64,
        most: Option<usize>,
        log: Option<&PressLog>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(SurfaceLaw, usize, usize), SurfaceLawBuildError> {
        let t0 = Instant::now();
        if !self.refinement.band.is_empty() {
            return Err(SurfaceLawBuildError::BandLast {
                what: "a stage of split triangles",
            });
        }
        if !self.refinement.sub.is_empty() {
            return Err(SurfaceLawBuildError::SubSplitFirst {
                sub_triangles: self.refinement.sub.sub_triangles.len(),
            });
        }
        let steps = self.steps;
        let row = 3 * self.rows.len();
        let n_row = steps * row;
        let earlier = std::mem::take(&mut self.refinement);
        let first_split = self.samples.len() + self.edges.len();
        let mut stored = self.take_stored();
        let held = stored.split_off(first_split, steps, n_row);
        let candidates =
            refine_candidates(organ, &self.sample_of, &self.edges, &stored.residual, n_row);
        let plan = refine_plan(organ, candidates, above_mm, most, &earlier.triangles);
        let sources = plan.sources(&earlier);
        plan.goes_on_from(&earlier)?;
        let normals = organ_vertex_normals(organ);
        let order: Vec<usize> = plan
            .press_order()
            .into_iter()
            .filter(|&k| matches!(sources[k], Source::Press))
            .collect();
        let points = plan.points_in_press_order(organ, &normals, &order);
        let (pressed, resumed) = self.press_logged(organ, &points, log, progress)?;
        let mut by_point: Vec<Option<Logged>> = sources.iter().map(|_| None).collect();
        for (k, press) in order.into_iter().zip(pressed) {
            by_point[k] = Some(press);
        }
        let got = sources
            .into_iter()
            .zip(by_point)
            .map(|(source, press)| match source {
                Source::Press => Got::Pressed(press.expect("every point to press was pressed")),
                Source::Held(s) => Got::Held(s),
                Source::Skipped => Got::Pressed(Err(
                    "not kept by the stage the law came from (its press failed there)".into(),
                )),
            })
            .collect();
        self.refinement.above_mm = Some(above_mm);
        self.split_figures = split_triangles(
            &plan,
            got,
            &held,
            &mut stored,
            steps,
            row,
            &mut self.refinement,
            &mut self.refine_skip_reasons,
        );
        self.put_stored(stored);
        self.build_s += t0.elapsed().as_secs_f64();
        Ok((self, resumed, plan.above))
    }

    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Presses `points` (in parallel, logged at `log` under a build's key, as
    /// [`Self::refine`] does) and appends each as a sample holding its surplus over its
    /// blend `bases[i]` of this law's samples, up to the depth all of them reached.
    /// Returns per point whether it was kept (or why its press failed) and how many
    /// presses came from the log. The refinement's lists are the caller's to extend.
    pub(crate) fn press_surpluses(
        &mut self,
        organ: &OrganMesh,
        points: &[PressPoint],
        bases: &[Vec<(usize, f64)>],
        log: Option<&PressLog>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(Vec<Result<(), String>>, usize), SurfaceLawBuildError> {
        let t0 = Instant::now();
        let (steps, row) = (self.steps, 3 * self.rows.len());
        let (pressed, resumed) = self.press_logged(organ, points, log, progress)?;
        let mut stored = self.take_stored();
        let kept = pressed
            .into_iter()
            .zip(bases)
            .map(|(press, base)| {
                let p = press?;
                let (surplus, g, reach, why) = stored.surplus(&p, base, steps, row);
                stored.push(&p, &surplus, &g, reach, why);
                Ok(())
            })
            .collect();
        self.put_stored(stored);
        self.build_s += t0.elapsed().as_secs_f64();
        Ok((kept, resumed))
    }

    /// Presses `points` with this law's options (in parallel; logged at `log` under a
    /// build's key, those it already holds taken from it): each press in order, and
    /// how many came from the log.
    fn press_logged(
        &self,
        organ: &OrganMesh,
        points: &[PressPoint],
        log: Option<&PressLog>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(Vec<Logged>, usize), SurfaceLawBuildError> {
        use std::sync::atomic::AtomicUsize;
        let (o, steps) = (self.options, self.steps);
        let space = organ_space(organ, o.element);
        let expander = Expander::new(&space, o.law, o.material)?;
        let (log, shard, finished) = match log {
            Some(spec) => {
                let (l, shard, r) = open_press_log(organ, &o, self.rows.len(), None, spec)?;
                (l.map(|(l, p)| (Mutex::new(l), p)), shard, r)
            }
            None => (None, None, Vec::new()),
        };
        let mut finished: HashMap<u32, Logged> = finished.into_iter().collect();
        let presser = Presser {
            pressing: Pressing {
                space: &space,
                organ,
                expander: &expander,
                o: &o,
            },
            rows: &self.rows,
            steps,
            log: log.as_ref().map(|(l, p)| (l, p.as_path())),
            shard,
            done: AtomicUsize::new(0),
            from_log: AtomicUsize::new(0),
            progress,
        };
        presser.press(points, &mut finished, points.len())
    }

    /// The per-sample arrays, taken out to be extended.
    fn take_stored(&mut self) -> Stored {
        Stored {
            residual: std::mem::take(&mut self.residual),
            ratio: std::mem::take(&mut self.ratio),
            stiffness: std::mem::take(&mut self.stiffness_n_per_mm),
            correction: std::mem::take(&mut self.correction_mm),
            segments: std::mem::take(&mut self.segments),
            reach: std::mem::take(&mut self.reach),
            stopped: std::mem::take(&mut self.stopped),
        }
    }

    /// Puts back what [`Self::take_stored`] took.
    fn put_stored(&mut self, stored: Stored) {
        self.residual = stored.residual;
        self.ratio = stored.ratio;
        self.stiffness_n_per_mm = stored.stiffness;
        self.correction_mm = stored.correction;
        self.segments = stored.segments;
        self.reach = stored.reach;
        self.stopped = stored.stopped;
    }

    /// The per-sample residual array (`steps × 3·rows` a sample).
    pub(crate) fn residuals(&self) -> &[f32] {
        &self.residual
    }

    /// Sample `s`'s residual at grid depth `j` (3 per kept row, mm).
    pub fn residual_at(&self, s: usize, j: usize) -> &[f32] {
        let n = 3 * self.rows.len();
        &self.residual[(s * self.steps + j) * n..][..n]
    }

    /// Adds the residual at depth `depth_mm` for a probe at barycentric `bary` of the
    /// boundary triangle `tri` (organ mesh vertex ids) to `out` (3 per kept row).
    /// Corners that were not sampled are left out and the others renormalized; returns
    /// false (and adds nothing) when none was sampled. Depths past the grid are held
    /// at its end.
    pub fn add_residual(
        &self,
        tri: [u32; 3],
        bary: [f64; 3],
        depth_mm: f64,
        out: &mut [f64],
    ) -> bool {
        let n = 3 * self.rows.len();
        let x = (depth_mm / self.options.depth_step_mm).clamp(0.0, (self.steps - 1) as f64);
        let j = (x.floor() as usize).min(self.steps - 2);
        let t = x - j as f64;
        let corners: Vec<(usize, f64)> = tri
            .iter()
            .zip(bary)
            .filter_map(|(&v, w)| {
                let s = *self.sample_of.get(v as usize)?;
                (s != u32::MAX).then_some((s as usize, w))
            })
            .collect();
        let total: f64 = corners.iter().map(|(_, w)| w).sum();
        if corners.is_empty() || total <= 0.0 {
            return false;
        }
        for (s, w) in corners {
            let w = w / total;
            let a = &self.residual[(s * self.steps + j) * n..][..n];
            let b = &self.residual[(s * self.steps + j + 1) * n..][..n];
            for i in 0..n {
                out[i] += w * ((1.0 - t) * f64::from(a[i]) + t * f64::from(b[i]));
            }
        }
        true
    }

    pub fn bytes(&self) -> usize {
        4 * self.residual.len()
    }
}

#[cfg(test)]
mod tests;
