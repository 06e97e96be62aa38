//! One press at a surface point, followed to equilibrium on the depth grid.

use crate::fe::FeError;
use crate::fe::load::{probe_functional, probe_load};
use crate::tissue::options::{SurfaceLawOptions, VertexPress};
use std::time::{Duration, Instant};

use crate::fe::path::{GridPress, PathOptions, PressLoad, follow, follow_from};
use crate::fe::probe::{ProbeRequest, locate};
use crate::fe::series::{Continued, DepthSeries, Expander, SplitTangent, continued_from};
use crate::organ::OrganMesh;

pub use crate::fe::probe::organ_vertex_normals;

/// The largest relative change of a press's Padé force at the deepest point from the
/// next lower form (its error indicator) for the press to be kept.
/// (The indicator is pessimistic: at ten bench positions changes up to 8.5 % went
/// with force errors below 0.6 %.)
pub const PADE_CHANGE_MAX: f64 = 0.1;

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

/// What every press of one tissue shares: the FE space, the organ, the expansion about
/// the rest state and the build's options. The press functions below are its methods.
#[derive(Debug, Clone, Copy)]
pub struct Pressing<'a> {
    pub space: &'a crate::fe::space::Space,
    pub organ: &'a OrganMesh,
    pub expander: &'a Expander<'a>,
    pub o: &'a SurfaceLawOptions,
}

impl Pressing<'_> {
    /// The unit tool load and the probe functional of a press at `at` along `push`
    /// (all-node).
    pub fn tool_load(&self, at: [f64; 3], push: [f64; 3]) -> Result<(Vec<f64>, Vec<f64>), FeError> {
        let Pressing {
            space, organ, o, ..
        } = *self;
        let req = ProbeRequest {
            at,
            force_n: 1.0,
            dir: Some(push),
            radius_mm: o.tool_radius_mm,
            nodule: None,
        };
        let (probe, dir) = locate(space, organ, &req)?;
        let shape = probe_load(space, &probe, dir, 1.0, o.tool_radius_mm)?;
        Ok((shape, probe_functional(space, &probe, dir)))
    }

    /// The two-segment series press at `at` along `push` with the build's options, with
    /// no correction at the grid depths (what the build used before [`follow`]; kept to
    /// judge an uncorrected series at any point apart from the blend), or why it is not
    /// trusted (the tool does not move its centre, next to
    /// the fixed region; the tangent at the split is not positive definite, where the
    /// tissue has lost stability; or the Padé forms still change at a segment's end).
    pub fn press_at(
        &self,
        at: [f64; 3],
        push: [f64; 3],
        tangent: SplitTangent,
    ) -> Result<Result<PointPress, String>, FeError> {
        let Pressing {
            space, expander, o, ..
        } = *self;
        let (shape, functional) = self.tool_load(at, push)?;
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
        if change > PADE_CHANGE_MAX {
            return Ok(Err(format!(
                "the Padé forms change by more than {} at a segment's end ({change:.3}; \
                 split correction {:.1e})",
                PADE_CHANGE_MAX, press.correction_rel
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
        &self,
        at: [f64; 3],
        push: [f64; 3],
        extra_mm: &[f64],
    ) -> Result<Result<(GridPress, Vec<f64>), String>, FeError> {
        let Pressing {
            space, expander, o, ..
        } = *self;
        let (shape, probe) = self.tool_load(at, push)?;
        let depths = grid_depths(o, extra_mm);
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

    /// The press at vertex `at` along `push` as [`Pressing::follow_at`] follows it, kept as the
    /// shares of its power among the cells `keep` names
    /// ([`crate::pgd::nodule::amplification`]), or why it was given up.
    pub fn vertex_power(
        &self,
        at: [f64; 3],
        push: [f64; 3],
        keep: crate::pgd::nodule::amplification::Keep,
    ) -> Result<crate::pgd::nodule::amplification::VertexPower, String> {
        let Pressing { space, o, .. } = *self;
        let (grid, _) = self
            .follow_at(at, push, &[])
            .map_err(|e| e.to_string())
            .and_then(|p| p)?;
        let reach2 = keep.reach_mm * keep.reach_mm;
        let cells: Vec<usize> = (0..space.cell_count())
            .filter(|&c| {
                space
                    .cell_corners(c)
                    .iter()
                    .any(|p| (0..3).map(|k| (p[k] - at[k]).powi(2)).sum::<f64>() <= reach2)
            })
            .collect();
        Ok(crate::pgd::nodule::amplification::VertexPower::from_press(
            space,
            o.law,
            o.material,
            at,
            &cells,
            keep.share_floor,
            &grid.first.u[0],
            grid.first.force[0],
            &grid.u,
            &grid.force_n,
            o.depth_step_mm,
        ))
    }

    /// The presses `vertices` ([`Self::vertex_power`], taken with `keep`) as the power
    /// of this tissue (its payload checksum `tissue_xxh3`) that a nodule table keeps.
    pub fn cell_power(
        &self,
        tissue_xxh3: u64,
        keep: crate::pgd::nodule::amplification::Keep,
        vertices: Vec<crate::pgd::nodule::amplification::VertexPower>,
        build_s: f64,
    ) -> crate::pgd::nodule::amplification::CellPower {
        let o = self.o;
        crate::pgd::nodule::amplification::CellPower::new(
            self.space,
            tissue_xxh3,
            o.material.poisson,
            keep,
            o.depth_step_mm,
            (o.depth_max_mm / o.depth_step_mm).round() as usize,
            vertices,
            build_s,
        )
    }

    /// The loads and rest series of the presses at `points` (`(at, push)` each), the
    /// series expanded together ([`Expander::expand_active_batch`]: their solves share
    /// the passes over the rest factor). Each is the series its press gives alone.
    pub(super) fn prepare(
        &self,
        points: &[([f64; 3], [f64; 3])],
    ) -> Result<Vec<Prepared>, FeError> {
        let Pressing { expander, o, .. } = *self;
        let t0 = Instant::now();
        let loads = points
            .iter()
            .map(|&(at, push)| self.tool_load(at, push))
            .collect::<Result<Vec<_>, _>>()?;
        let refs: Vec<(&[f64], &[f64])> = loads
            .iter()
            .map(|(s, p)| (s.as_slice(), p.as_slice()))
            .collect();
        let series = expander.expand_active_batch(&refs, o.orders, o.active_cutoff)?;
        let series_s = t0.elapsed().as_secs_f64() / points.len().max(1) as f64;
        Ok(loads
            .into_iter()
            .zip(series)
            .map(|((shape, probe), first)| Prepared {
                shape,
                probe,
                first,
                series_s,
            })
            .collect())
    }

    /// One surface point's press (a vertex or an edge midpoint) followed to equilibrium on
    /// the depth grid ([`follow_from`]) from its [`Pressing::prepare`]d load and series, or why it is skipped (the tool does not move its
    /// centre, next to the fixed region; or no equilibrium was found at some depth).
    pub(super) fn point_press_prepared(
        &self,
        rows: &[u32],
        steps: usize,
        prepared: Prepared,
    ) -> Result<Result<VertexPress, String>, FeError> {
        let Pressing {
            space, expander, o, ..
        } = *self;
        // The build's grid alone: `depths.len() == steps`.
        let depths = grid_depths(o, &[]);
        let load = PressLoad {
            shape: &prepared.shape,
            probe: &prepared.probe,
        };
        let started = Instant::now()
            .checked_sub(Duration::from_secs_f64(prepared.series_s))
            .unwrap_or_else(Instant::now);
        let press = match follow_from(
            space,
            o.law,
            o.material,
            expander,
            &load,
            (prepared.first, started),
            &depths,
            &path_options(o),
        )? {
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
}

/// The build's depth grid, with the extra depths `extra_mm` within its range.
fn grid_depths(o: &SurfaceLawOptions, extra_mm: &[f64]) -> Vec<f64> {
    let steps = (o.depth_max_mm / o.depth_step_mm).round() as usize + 1;
    let mut depths: Vec<f64> = (0..steps).map(|j| j as f64 * o.depth_step_mm).collect();
    depths.extend(
        extra_mm
            .iter()
            .filter(|d| **d > 0.0 && **d <= o.depth_max_mm),
    );
    depths.sort_by(f64::total_cmp);
    depths.dedup();
    depths
}

/// A surface point's tool load and rest series, ready to be followed
/// ([`Pressing::point_press_prepared`]).
pub(super) struct Prepared {
    shape: Vec<f64>,
    probe: Vec<f64>,
    first: Result<DepthSeries, FeError>,
    /// Its share of the batch's expansion time.
    series_s: f64,
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
pub(super) fn edge_id(organ: &OrganMesh, e: usize) -> u32 {
    (organ.mesh.vertices.len() + e) as u32
}
