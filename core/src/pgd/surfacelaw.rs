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

use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

use crate::fe::hyper::Law;
use crate::fe::load::{probe_functional, probe_load};
use crate::fe::path::{GridPress, PathOptions, PressLoad, follow};
use crate::fe::probe::{ProbeRequest, locate, organ_space};
use crate::fe::series::{Continued, Expander, SplitTangent, continued_from};
use crate::fe::{Element, FeError, Material};
use crate::organ::OrganMesh;
use crate::pgd::presslog::RecordLog;
use crate::pgd::subsplit::SubSplit;

/// How the surface law is built.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceLawOptions {
    pub law: Law,
    pub material: Material,
    pub element: Element,
    pub depth_max_mm: f64,
    /// Grid depths `j · step`, `j = 0..=depth_max/step`.
    pub depth_step_mm: f64,
    pub orders: usize,
    /// The continuation's split, as a fraction of the largest depth.
    pub split_fraction: f64,
    pub tool_radius_mm: f64,
    /// The higher orders are assembled only on cells where the press's first order
    /// varies by at least this fraction of its peak (see
    /// [`crate::fe::series::active_cells`]); 0 assembles every cell.
    pub active_cutoff: f64,
    /// Press only the palpable vertices within this ball (centre, radius; mm): a
    /// scene that shows one region models only that region. `None`: all of them.
    pub within: Option<([f64; 3], f64)>,
    /// Also press the midpoint of every palpable edge whose ends are pressed, and
    /// store its surplus over the ends' mean: the blend becomes quadratic (see the
    /// module docs). About three times the presses.
    pub edges: bool,
}

impl Default for SurfaceLawOptions {
    fn default() -> Self {
        SurfaceLawOptions {
            law: Law::NeoHookean,
            material: Material::default(),
            element: Element::P2,
            depth_max_mm: 10.0,
            depth_step_mm: 1.0,
            orders: 12,
            split_fraction: 0.55,
            tool_radius_mm: 5.0,
            active_cutoff: 0.01,
            within: None,
            edges: true,
        }
    }
}

/// A build's progress: presses done of those planned so far (the split triangles'
/// are planned once the vertices and edges are pressed, so `total` grows then), and
/// how many of the done were taken from the log rather than computed by this run:
/// an estimate of the time left divides by the computed ones only.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PressCount {
    pub done: usize,
    pub total: usize,
    pub from_log: usize,
}

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

/// Why a surface law could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SurfaceLawBuildError {
    #[error(transparent)]
    Fe(#[from] FeError),
    #[error(
        "the point {point_mm:?} lies {distance_mm:.3} mm from the organ's palpable surface: \
         expected a point on a palpable triangle (within {COVER_SLACK_MM} mm)"
    )]
    OffSurface {
        point_mm: [f64; 3],
        distance_mm: f64,
    },
    #[error(
        "the surface law already has {triangles} split triangles and this stage would split \
         {asked}: expected a stage of more (a larger --triangles, or a lower --refine-above-mm), \
         or a law cut back to no split triangles first (`palpa tissue cut --unsplit`)"
    )]
    AlreadyRefined { triangles: usize, asked: usize },
    #[error(
        "{missing} of the law's split triangles are not split candidates on this organ mesh \
         (their corners and edges pressed): expected the mesh the law was built on"
    )]
    EarlierStage { missing: usize },
    #[error(
        "the surface law has {sub_triangles} sub-triangles split again, and a stage of split \
         triangles would change the blend their surpluses were measured against: expected the \
         file they were split from (refine that, then split sub-triangles again)"
    )]
    SubSplitFirst { sub_triangles: usize },
    #[error("the build's press log {path}: {source}")]
    Log {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
}

/// What one palpable vertex's press gives: its residual surface and force ratio at
/// every grid depth.
#[derive(serde::Serialize, serde::Deserialize)]
struct VertexPress {
    /// `steps × 3·rows`, mm.
    residual: Vec<f32>,
    /// `g(d_j) = F(d_j) / (d_j · F₁)`, `g(0) = 1`.
    ratio: Vec<f64>,
    stiffness_n_per_mm: f64,
    correction_mm: f64,
    segments: u32,
    /// Grid depths reached (depth 0 included); past them `residual` and `ratio` hold
    /// the last one reached.
    reach: u32,
    /// Why the press stopped short of the grid (empty where it did not).
    stopped: String,
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
        log: Option<&Path>,
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
        log: Option<&Path>,
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
        log: Option<&Path>,
        cover: Option<&[u32]>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(SurfaceLaw, usize), SurfaceLawBuildError> {
        use std::sync::atomic::AtomicUsize;
        let o = options;
        let steps = (o.depth_max_mm / o.depth_step_mm).round() as usize + 1;
        if !(o.depth_max_mm > 0.0 && o.depth_step_mm > 0.0 && (2..=256).contains(&steps)) {
            return Err(FeError::DepthNotFinite {
                depth_mm: o.depth_max_mm,
            }
            .into());
        }
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
        let (log, finished) = match log {
            Some(path) => {
                let (l, r) = open_press_log(organ, &o, rows.len(), steps, cover, path)?;
                (Some((Mutex::new(l), path)), r)
            }
            None => (None, Vec::new()),
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
            palpable_edges(organ)
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
            space: &space,
            organ,
            expander: &expander,
            o: &o,
            rows: &rows,
            steps,
            log: log.as_ref().map(|(l, p)| (l, *p)),
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
    /// file ([`super::tissue::TissueLaw::surface_law`]) thus gets the split a whole
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
        log: Option<&Path>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(SurfaceLaw, usize, usize), SurfaceLawBuildError> {
        let t0 = Instant::now();
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
        log: Option<&Path>,
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
        log: Option<&Path>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(Vec<Logged>, usize), SurfaceLawBuildError> {
        use std::sync::atomic::AtomicUsize;
        let (o, steps) = (self.options, self.steps);
        let space = organ_space(organ, o.element);
        let expander = Expander::new(&space, o.law, o.material)?;
        let (log, finished) = match log {
            Some(path) => {
                let (l, r) = open_press_log(organ, &o, self.rows.len(), steps, None, path)?;
                (Some((Mutex::new(l), path)), r)
            }
            None => (None, Vec::new()),
        };
        let mut finished: HashMap<u32, Logged> = finished.into_iter().collect();
        let presser = Presser {
            space: &space,
            organ,
            expander: &expander,
            o: &o,
            rows: &self.rows,
            steps,
            log: log.as_ref().map(|(l, p)| (l, *p)),
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
/// at 7 mm: 0.19–0.48 mm quadratic, 0.05–0.11 mm split (docs/tissue-measurements.md §2).
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
    /// Stored apart in a tissue file (format 11), after the weights.
    #[serde(skip)]
    pub sub: SubSplit,
}

/// The default split threshold of a build (mm): see [`Refinement`]. The quadratic
/// blend's error at a triangle's quarter and inner points (their surpluses) ran at 0.29
/// to 1.34 of its largest edge surplus on 21 triangles of the anterior lobe and the
/// sharp border (coarse P2, to 15 mm), so an edge surplus of 0.35 mm is where the blend
/// may start to miss the 0.5 mm goal. On the 344 triangles of the whole coarse surface
/// whose edges a partial build had pressed, 318 (92 %) lie above it (260 above 0.5 mm,
/// 81 above 1 mm): the default buys the accuracy with about six presses a triangle.
pub const DEFAULT_REFINE_ABOVE_MM: f64 = 0.35;

/// A surface point to press: where, along what, and its id in the press log.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PressPoint {
    pub(crate) at: [f64; 3],
    pub(crate) push: [f64; 3],
    pub(crate) id: u32,
}

/// A quarter or inner point of a split triangle (see [`Refinement`]).
struct RefinePoint {
    /// The point on its flat triangle: mesh vertices and weights.
    at: Vec<(u32, f64)>,
    /// The parent's quadratic interpolant there: stored samples and weights.
    base: Vec<(usize, f64)>,
    /// `[near, far]` end samples (a quarter point) or `[near, next, next]` corners.
    near: Vec<u32>,
    id: u32,
}

impl RefinePoint {
    /// Where it is pressed, and along the same blend of the vertex normals the scene
    /// interpolates.
    fn point(&self, organ: &OrganMesh, normals: &[[f32; 3]]) -> PressPoint {
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
    quarters: Vec<RefinePoint>,
    inner: Vec<RefinePoint>,
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
    fn triangle_points(&self, t: usize) -> impl Iterator<Item = usize> + '_ {
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
    fn points_in_press_order(
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
fn in_plan_order(order: &[usize], pressed: Vec<Logged>) -> Vec<Logged> {
    let mut out: Vec<Option<Logged>> = (0..order.len()).map(|_| None).collect();
    for (&k, p) in order.iter().zip(pressed) {
        out[k] = Some(p);
    }
    out.into_iter()
        .map(|p| p.expect("press_order lists every point once"))
        .collect()
}

/// How far a covered point may lie from the palpable surface (mm): a point drawn on a
/// triangle and printed to a few decimals lands within it.
pub const COVER_SLACK_MM: f64 = 0.1;

/// The corners of the palpable triangle closest to each of `points` (sorted, each
/// once, fixed vertices left out as a build leaves them), or which point lies off the
/// palpable surface.
pub fn covering_vertices(
    organ: &OrganMesh,
    points: &[[f64; 3]],
) -> Result<Vec<u32>, SurfaceLawBuildError> {
    let palpable: Vec<[u32; 3]> = organ
        .boundary
        .iter()
        .zip(&organ.palpable)
        .filter_map(|(t, p)| p.then_some(*t))
        .collect();
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

/// The palpable boundary edges, as sorted vertex pairs, sorted and each once.
pub(crate) fn palpable_edges(organ: &OrganMesh) -> Vec<[u32; 2]> {
    let mut e: Vec<[u32; 2]> = organ
        .boundary
        .iter()
        .zip(&organ.palpable)
        .filter(|(_, p)| **p)
        .flat_map(|(t, _)| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    e.sort_unstable();
    e.dedup();
    e
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
    let all_edges = palpable_edges(organ);
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
enum Got {
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
fn split_triangles(
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

/// A logged press: what [`point_press`] gave at one log id.
type Logged = Result<VertexPress, String>;

/// Opens a build's press log at `path` (see [`super::presslog`]) and returns it with
/// the presses already in it. The key names everything that determines a press, so a
/// build and a refinement of the same options share their presses (a covering build's
/// key also names its vertices: its edge ids count its own edges).
fn open_press_log(
    organ: &OrganMesh,
    o: &SurfaceLawOptions,
    rows: usize,
    steps: usize,
    cover: Option<&[u32]>,
    path: &Path,
) -> Result<(RecordLog, Vec<(u32, Logged)>), SurfaceLawBuildError> {
    let log_error = |source| SurfaceLawBuildError::Log {
        path: path.to_path_buf(),
        source,
    };
    let (key, previous) = press_log_key(organ, o, rows, cover);
    for previous in previous {
        RecordLog::upgrade::<Logged>(path, &previous, &key, |p| {
            p.as_ref().is_ok_and(|p| p.reach as usize == steps)
        })
        .map_err(log_error)?;
    }
    RecordLog::open::<Logged>(path, &key).map_err(log_error)
}

/// The ids a build's press log at `path` already holds, read without changing it
/// (none where it is missing or of another build).
pub(crate) fn logged_press_ids(
    organ: &OrganMesh,
    o: &SurfaceLawOptions,
    rows: usize,
    path: &Path,
) -> Result<Vec<u32>, SurfaceLawBuildError> {
    let (key, _) = press_log_key(organ, o, rows, None);
    RecordLog::finished_ids::<Logged>(path, &key).map_err(|source| SurfaceLawBuildError::Log {
        path: path.to_path_buf(),
        source,
    })
}

/// A build's press-log key (everything that determines its presses), and the keys of
/// earlier versions whose presses that reached every depth it takes over.
fn press_log_key(
    organ: &OrganMesh,
    o: &SurfaceLawOptions,
    rows: usize,
    cover: Option<&[u32]>,
) -> (String, Vec<String>) {
    let po = path_options(o);
    let covered = cover.map_or(String::new(), |c| {
        let bytes: Vec<u8> = c.iter().flat_map(|v| v.to_le_bytes()).collect();
        format!(
            " cover {} {:016x}",
            c.len(),
            xxhash_rust::xxh3::xxh3_64(&bytes)
        )
    });
    let key_of = |version: u32, path: String| {
        format!(
            "palpa tissue-build log {version} mesh {:016x} rows {rows} {o:?} {path}{covered}",
            crate::pgd::depthlaw::organ_hash(organ),
        )
    };
    let key = key_of(6, format!("{po:?}"));
    // Versions 3 (before the path follower's Newton fallback), 4 (which stopped a
    // press at any dip of its force) and 5 (no factorization budget) differ from this
    // build only where a press stopped short, or reached every depth through a
    // fallback longer than the budget (none seen: every fallback measured that spent
    // past it failed): their presses that reached every depth are kept, the others
    // pressed again.
    let budget = PathOptions::default().max_factorizations;
    let mut previous = Vec::new();
    if po.newton_fallback && po.stop_past_force_peak && po.max_factorizations == budget {
        let v5 = format!("{po:?}").replace(&format!(", max_factorizations: {budget}"), "");
        let v3 = v5.replace(", newton_fallback: true", "");
        previous = vec![key_of(3, v3), key_of(4, v5.clone()), key_of(5, v5)];
    }
    (key, previous)
}

/// Presses surface points in parallel, logging each as it finishes and reporting
/// progress (see [`PressCount`]).
struct Presser<'a> {
    space: &'a crate::fe::space::Space,
    organ: &'a OrganMesh,
    expander: &'a Expander<'a>,
    o: &'a SurfaceLawOptions,
    rows: &'a [u32],
    steps: usize,
    log: Option<(&'a Mutex<RecordLog>, &'a Path)>,
    done: std::sync::atomic::AtomicUsize,
    from_log: std::sync::atomic::AtomicUsize,
    progress: &'a (dyn Fn(PressCount) + Sync),
}

impl Presser<'_> {
    /// Presses `points` (those in `finished` taken from it) and returns their presses
    /// in order and how many came from the log; `total` is what the progress counts
    /// to.
    fn press(
        &self,
        points: &[PressPoint],
        finished: &mut HashMap<u32, Logged>,
        total: usize,
    ) -> Result<(Vec<Logged>, usize), SurfaceLawBuildError> {
        use rayon::prelude::*;
        use std::sync::atomic::Ordering;
        let mut out: Vec<Option<Logged>> = points.iter().map(|p| finished.remove(&p.id)).collect();
        let resumed = out.iter().filter(|p| p.is_some()).count();
        let logged = self.from_log.fetch_add(resumed, Ordering::Relaxed) + resumed;
        (self.progress)(PressCount {
            done: self.done.fetch_add(resumed, Ordering::Relaxed) + resumed,
            total,
            from_log: logged,
        });
        let todo = (0..points.len()).filter(|&k| out[k].is_none());
        // One press a task, taken in `points`' order: a split range would have each
        // thread press a run in turn (a build's last run, presses of minutes on
        // medium P2, went on on one core while the other sat idle), and an interrupted
        // build would leave the log holding two fronts rather than the first presses.
        let computed: Vec<(usize, Logged)> = todo
            .par_bridge()
            .map(|k| -> Result<_, SurfaceLawBuildError> {
                let p = &points[k];
                let press = point_press(
                    self.space,
                    self.organ,
                    self.expander,
                    self.o,
                    self.rows,
                    self.steps,
                    p.at,
                    p.push,
                )?;
                if let Some((l, path)) = self.log {
                    // Off-line and once a press (seconds): a lock is fine here.
                    let mut l = l.lock().unwrap_or_else(|p| p.into_inner());
                    l.push(p.id, &press)
                        .map_err(|source| SurfaceLawBuildError::Log {
                            path: path.to_path_buf(),
                            source,
                        })?;
                }
                (self.progress)(PressCount {
                    done: self.done.fetch_add(1, Ordering::Relaxed) + 1,
                    total,
                    from_log: logged,
                });
                Ok((k, press))
            })
            .collect::<Result<_, _>>()?;
        for (k, press) in computed {
            out[k] = Some(press);
        }
        let out = out
            .into_iter()
            .map(|p| p.expect("every point is pressed"))
            .collect();
        Ok((out, resumed))
    }
}

/// The per-sample arrays as the build fills them (vertices, edges, quarter points,
/// inner points).
#[derive(Default)]
struct Stored {
    residual: Vec<f32>,
    ratio: Vec<f64>,
    stiffness: Vec<f64>,
    correction: Vec<f64>,
    segments: Vec<u32>,
    reach: Vec<u32>,
    stopped: Vec<String>,
}

impl Stored {
    /// The samples from `first` on, taken off (`n_row` residual values a sample).
    fn split_off(&mut self, first: usize, steps: usize, n_row: usize) -> Stored {
        Stored {
            residual: self.residual.split_off(first * n_row),
            ratio: self.ratio.split_off(first * steps),
            stiffness: self.stiffness.split_off(first),
            correction: self.correction.split_off(first),
            segments: self.segments.split_off(first),
            reach: self.reach.split_off(first),
            stopped: self.stopped.split_off(first),
        }
    }

    /// Appends `from`'s sample `s` as it is.
    fn copy(&mut self, from: &Stored, s: usize, steps: usize, row: usize) {
        let n = steps * row;
        self.residual
            .extend_from_slice(&from.residual[s * n..][..n]);
        self.ratio
            .extend_from_slice(&from.ratio[s * steps..][..steps]);
        self.stiffness.push(from.stiffness[s]);
        self.correction.push(from.correction[s]);
        self.segments.push(from.segments[s]);
        self.reach.push(from.reach[s]);
        self.stopped.push(from.stopped[s].clone());
    }

    fn push(&mut self, p: &VertexPress, residual: &[f32], ratio: &[f64], reach: u32, why: String) {
        self.residual.extend_from_slice(residual);
        self.ratio.extend_from_slice(ratio);
        self.stiffness.push(p.stiffness_n_per_mm);
        self.correction.push(p.correction_mm);
        self.segments.push(p.segments);
        self.reach.push(reach);
        self.stopped.push(why);
    }

    /// The reason of whichever of `p` and the stored samples `others` stopped first
    /// (empty where none stopped short).
    fn first_stop(&self, p: &VertexPress, others: &[usize]) -> String {
        std::iter::once((p.reach, &p.stopped))
            .chain(others.iter().map(|&s| (self.reach[s], &self.stopped[s])))
            .min_by_key(|(r, _)| *r)
            .map_or(String::new(), |(_, w)| w.clone())
    }

    /// `p`'s surplus over the blend `base` of stored samples, up to the depth all of
    /// them reached and held there: residual, ratio, reach and why it stopped.
    fn surplus(
        &self,
        p: &VertexPress,
        base: &[(usize, f64)],
        steps: usize,
        row: usize,
    ) -> (Vec<f32>, Vec<f64>, u32, String) {
        let r = base.iter().fold(p.reach, |r, &(s, _)| r.min(self.reach[s])) as usize;
        let n = steps * row;
        let residual = (0..n)
            .map(|i| {
                let i = (i / row).min(r - 1) * row + i % row;
                let b: f64 = base
                    .iter()
                    .map(|&(s, w)| w * f64::from(self.residual[s * n + i]))
                    .sum();
                (f64::from(p.residual[i]) - b) as f32
            })
            .collect();
        let ratio = (0..steps)
            .map(|j| {
                let j = j.min(r - 1);
                let b: f64 = base
                    .iter()
                    .map(|&(s, w)| w * self.ratio[s * steps + j])
                    .sum();
                p.ratio[j] - b
            })
            .collect();
        let others: Vec<usize> = base.iter().map(|b| b.0).collect();
        (residual, ratio, r as u32, self.first_stop(p, &others))
    }
}

/// Outward area-weighted normals of the organ's boundary, per mesh vertex (zero off
/// the boundary): the same normals a scene computes for its render vertices.
pub fn organ_vertex_normals(organ: &OrganMesh) -> Vec<[f32; 3]> {
    let vertices: Vec<[f32; 3]> = organ
        .mesh
        .vertices
        .iter()
        .map(|p| p.map(|x| x as f32))
        .collect();
    crate::mesh::vertex_normals(&vertices, &organ.boundary)
}

/// A continued press with what says how far to trust it.
#[derive(Debug, Clone)]
pub struct PointPress {
    pub press: Continued,
    /// The largest change of the segments' Padé forms at their ends (a proxy).
    pub pade_change: f64,
    /// The unit tool load `f̂` the press was expanded for (all-node).
    pub shape: Vec<f64>,
}

impl PointPress {
    /// The equilibrium residual at `depth_mm`, `‖f_int(u) − F f̂‖ / ‖F f̂‖` on the free
    /// dofs (one internal-force assembly; the build does not pay for it). Reported,
    /// not a skip rule: measured at 15 mm on coarse P2 it was 6.2 for a press 14 % off
    /// at 12.7 mm and 3.4–3.9 for one 1.5–2.6 % off, so in this norm and at this depth
    /// it does not yet separate them.
    pub fn residual_rel(
        &self,
        space: &crate::fe::space::Space,
        o: &SurfaceLawOptions,
        depth_mm: f64,
    ) -> f64 {
        let (force_n, u) = self.press.evaluate(depth_mm, o.depth_max_mm);
        let (lambda, mu) = o.material.lame_n_per_mm2();
        let internal = crate::fe::newton::internal_force(space, o.law, &u, lambda, mu);
        let load = space.restrict(&self.shape);
        let (mut r2, mut f2) = (0.0, 0.0);
        for (fi, l) in internal.iter().zip(&load) {
            r2 += (fi - force_n * l).powi(2);
            f2 += (force_n * l).powi(2);
        }
        (r2 / f2.max(f64::MIN_POSITIVE)).sqrt()
    }
}

/// The two-segment series press at `at` along `push` with the build's options, with
/// no correction at the grid depths (what the build used before [`follow`]; kept to
/// judge an uncorrected series at any point apart from the blend), or why it is not
/// trusted (the tool does not move its centre, next to
/// the fixed region; the tangent at the split is not positive definite, where the
/// tissue has lost stability; or the Padé forms still change at a segment's end).
pub fn press_at(
    space: &crate::fe::space::Space,
    organ: &OrganMesh,
    expander: &Expander,
    o: &SurfaceLawOptions,
    at: [f64; 3],
    push: [f64; 3],
    tangent: SplitTangent,
) -> Result<Result<PointPress, String>, FeError> {
    let (shape, functional) = tool_load(space, organ, o, at, push)?;
    let first = match expander.expand_active(&shape, &functional, o.orders, o.active_cutoff) {
        Ok(s) => s,
        Err(e @ FeError::ProbeNotMoved) => return Ok(Err(format!("first series: {e}"))),
        Err(e) => return Err(e),
    };
    // Where the tangent at the split is not positive definite (the first series'
    // state there is off, or the tissue buckles under the tool), split earlier once.
    let mut split = o.split_fraction * o.depth_max_mm;
    let press = loop {
        match continued_from(
            space,
            o.law,
            o.material,
            &shape,
            &functional,
            first.clone(),
            split,
            o.orders,
            tangent,
            o.active_cutoff,
        ) {
            Ok(c) => break c,
            Err(FeError::NotPositiveDefinite { .. }) if split > 0.4 * o.depth_max_mm => {
                split *= 0.6;
            }
            Err(e @ (FeError::ProbeNotMoved | FeError::NotPositiveDefinite { .. })) => {
                return Ok(Err(format!(
                    "continuation at {split:.2} mm: {}",
                    match e {
                        FeError::NotPositiveDefinite { .. } => {
                            "the tangent there is not positive definite".to_string()
                        }
                        e => e.to_string(),
                    }
                )));
            }
            Err(e) => return Err(e),
        }
    };
    let change = press
        .first
        .rational(split)
        .change
        .max(press.second.rational(o.depth_max_mm - split).change);
    // The same rule as the force law's samples: a series whose Padé forms still
    // change by more than this at a segment's end is not trusted.
    if change > crate::pgd::depthlaw::PADE_CHANGE_MAX {
        return Ok(Err(format!(
            "the Padé forms change by more than {} at a segment's end ({change:.3}; \
             split correction {:.1e})",
            crate::pgd::depthlaw::PADE_CHANGE_MAX,
            press.correction_rel
        )));
    }
    Ok(Ok(PointPress {
        press,
        pade_change: change,
        shape,
    }))
}

/// The press at `at` along `push` followed to equilibrium ([`follow`]) with the build's
/// options, through the build's depth grid and the extra depths `extra_mm` (each
/// within the grid's range): what the build would store if `at` were a vertex, so a
/// check can tell the blend's error from the press's own. Returns the press and the
/// depths its states are at, or why it was given up.
pub fn follow_at(
    space: &crate::fe::space::Space,
    organ: &OrganMesh,
    expander: &Expander,
    o: &SurfaceLawOptions,
    at: [f64; 3],
    push: [f64; 3],
    extra_mm: &[f64],
) -> Result<Result<(GridPress, Vec<f64>), String>, FeError> {
    let (shape, probe) = tool_load(space, organ, o, at, push)?;
    let steps = (o.depth_max_mm / o.depth_step_mm).round() as usize + 1;
    let mut depths: Vec<f64> = (0..steps).map(|j| j as f64 * o.depth_step_mm).collect();
    depths.extend(
        extra_mm
            .iter()
            .filter(|d| **d > 0.0 && **d <= o.depth_max_mm),
    );
    depths.sort_by(f64::total_cmp);
    depths.dedup();
    let load = PressLoad {
        shape: &shape,
        probe: &probe,
    };
    Ok(follow(
        space,
        o.law,
        o.material,
        expander,
        &load,
        &depths,
        &path_options(o),
    )?
    .map(|p| (p, depths)))
}

/// The unit tool load and the probe functional of a press at `at` along `push`
/// (all-node).
pub fn tool_load(
    space: &crate::fe::space::Space,
    organ: &OrganMesh,
    o: &SurfaceLawOptions,
    at: [f64; 3],
    push: [f64; 3],
) -> Result<(Vec<f64>, Vec<f64>), FeError> {
    let req = ProbeRequest {
        at,
        force_n: 1.0,
        dir: Some(push),
        radius_mm: o.tool_radius_mm,
    };
    let (probe, dir) = locate(space, organ, &req)?;
    let shape = probe_load(space, &probe, dir, 1.0, o.tool_radius_mm)?;
    Ok((shape, probe_functional(space, &probe, dir)))
}

/// The path options a build uses.
pub fn path_options(o: &SurfaceLawOptions) -> PathOptions {
    PathOptions {
        orders: o.orders,
        active_cutoff: o.active_cutoff,
        ..PathOptions::default()
    }
}

/// The log id of edge `e`: after every mesh vertex id.
fn edge_id(organ: &OrganMesh, e: usize) -> u32 {
    (organ.mesh.vertices.len() + e) as u32
}

/// One surface point's press (a vertex or an edge midpoint) followed to equilibrium on
/// the depth grid ([`follow`]), or why it is skipped (the tool does not move its
/// centre, next to the fixed region; or no equilibrium was found at some depth).
#[allow(clippy::too_many_arguments)]
fn point_press(
    space: &crate::fe::space::Space,
    organ: &OrganMesh,
    expander: &Expander,
    o: &SurfaceLawOptions,
    rows: &[u32],
    steps: usize,
    at: [f64; 3],
    push: [f64; 3],
) -> Result<Result<VertexPress, String>, FeError> {
    // The build's grid alone: `depths.len() == steps`.
    let (press, depths) = match follow_at(space, organ, expander, o, at, push, &[])? {
        Ok(p) => p,
        Err(why) => return Ok(Err(why)),
    };
    let unit = &press.first.u[0];
    let stiffness = press.first.force[0];
    let mut residual = Vec::with_capacity(steps * 3 * rows.len());
    let mut ratio = Vec::with_capacity(steps);
    let mut reach = press.u.len();
    let mut stopped = press.stopped;
    // A press is kept only while its force does not fall: past a force maximum (Saint
    // Venant–Kirchhoff's loss of stability in compression) the states exist under
    // depth control, but a hand pressing with a force snaps through them, and the
    // force-in, depth-out inverse needs a curve that does not fall. A dip within the
    // states' own force tolerance is no maximum (the tool sliding along a flat stretch):
    // the press goes on, its force held at the largest before it (off by less than that
    // tolerance).
    let tolerance = path_options(o).force_tolerance;
    if let Some((j, k)) = (1..reach).find_map(|j| {
        crate::fe::path::force_peak_passed(&press.force_n[..=j], tolerance).map(|k| (j, k))
    }) {
        stopped = Some(format!(
            "the force peaks at {:.2} N near {:.2} mm ({:.2} N at {:.2} mm): past it the \
             tissue snaps through under a pressing hand",
            press.force_n[k], depths[k], press.force_n[j], depths[j]
        ));
        reach = j;
    }
    if reach < 2 {
        return Ok(Err(stopped.unwrap_or_default()));
    }
    let mut top_n = 0.0f64;
    for (j, (&d, u)) in depths.iter().zip(&press.u).take(reach).enumerate() {
        ratio.push(if j == 0 {
            1.0
        } else {
            top_n = top_n.max(press.force_n[j]);
            top_n / (d * stiffness)
        });
        for &r in rows {
            for c in 0..3 {
                let i = 3 * r as usize + c;
                residual.push((u[i] - d * unit[i]) as f32);
            }
        }
    }
    // Past the depths reached, the last one held (the on-line blend stops there).
    let row = 3 * rows.len();
    for _ in reach..steps {
        residual.extend_from_within((reach - 1) * row..reach * row);
        ratio.push(ratio[reach - 1]);
    }
    Ok(Ok(VertexPress {
        residual,
        ratio,
        stiffness_n_per_mm: stiffness,
        correction_mm: press.worst_correction_mm,
        segments: press.segment_starts_mm.len() as u32,
        reach: reach as u32,
        stopped: stopped.unwrap_or_default(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
