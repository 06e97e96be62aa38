//! A press followed along a grid of depths to equilibrium: the depth series predicts,
//! Newton corrects, and a fresh series starts wherever the last one stops predicting.
//!
//! [`super::series`] gives the press as a power series about a state `(d₀, u₀)`;
//! summed through its Padé form it is the ANM *predictor*. Each grid depth `d_j` is
//! then brought to equilibrium by the *corrector*: Newton on the bordered system
//!
//! ```text
//! f_int(u) − F f̂ = 0,     n̂·u − d_j = 0,
//! ```
//!
//! with the segment's factored tangent `K = K_t(u₀)` kept fixed (a chord method, one
//! internal-force assembly and one solve per step):
//!
//! ```text
//! r = f_int(u) − F f̂,  g = n̂·u − d_j,  x = K⁻¹ r,  y = K⁻¹ f̂ (once a segment),
//! ΔF = (n̂·x − g) / (n̂·y),   Δu = ΔF y − x,   u ← u + Δu,  F ← F + ΔF.
//! ```
//!
//! A depth is accepted when the last correction moves no node by more than
//! [`PathOptions::tolerance_mm`] (0.05 mm, a tenth of the surface goal) and the force
//! by less than [`PathOptions::force_tolerance`] of itself (5e-3, a tenth of the force
//! goal). This is the trust rule: it measures the equilibrium itself, where the Padé
//! forms' change at a segment's end was only a proxy (measured, it let a press 14 %
//! off in force through near the liver's sharp border). It bounds the last correction,
//! not the distance to the equilibrium: against the reference Newton at every grid depth
//! of ten spread vertices the accepted states were within 0.14 mm and 0.87 % of the
//! force (`palpa lab bench fe --only build_cost`), where the chord contracts slowly.
//!
//! The chord contracts by about `‖I − K⁻¹K_t(u)‖` a step. On the liver (coarse P2,
//! neo-Hookean, ν = 0.48) the plain chord *diverges* from a tangent 2–4 mm old: the
//! second correction is 2–4 times the first, the force correction flips sign. Those
//! are a few large eigenvalues (the tangent changed near the tool only), which
//! Anderson acceleration ([`PathOptions::anderson`], see `accelerated`) removes the
//! way GMRES would, at the chord's cost a step. A depth that needs more than
//! [`PathOptions::refresh_after`] steps (three) still starts a new segment after it:
//! its tangent is factored at the accepted state and a short series
//! ([`PathOptions::restart_orders`], 6) expanded about it, exactly (the base is an
//! equilibrium, so this is the textbook ANM step). Measured on six spread vertices to
//! 15 mm: 1–4 segments and 18–53 steps a press, 7–18 s (65 s for the six; the plain
//! chord, refreshing after any second step: 2–8 segments, 83 s). Extrapolating the
//! accepted states instead of a restart series needs a new segment nearly every
//! millimetre (5–12 segments, no faster); a 12-order series from the rest state
//! predicts 1 mm to 1e-6 mm but 3 mm only to 6e-3 mm where the press is stiff. Where
//! the chord from a segment that starts at the last accepted state still fails, that
//! depth is solved by Newton from the prediction, the tangent refactored at each
//! iterate (at most four times), and a segment starts there; where that fails too, the
//! step toward the next grid depth is halved (at most three times, to an eighth of the
//! grid step; the intermediate states are accepted like grid ones but not stored) and
//! doubled back after a success. A tangent that is not positive definite (past a
//! force limit point, where depth control is still stable) is factored augmented,
//! `K + α n̂n̂ᵀ`, which gives the same depth-controlled corrections (see `Augment`).
//! Near the liver's sharp inferior
//! border this is what carries a press to 15 mm: without it two of eleven vertices
//! there were given up, at 9 and 14 mm. Where the halved steps fail too, the next grid
//! depth is handed to the reference Newton ([`super::newton::continue_depth`]: a fresh
//! tangent each iteration, a line search on the residual, its own step cuts down to a
//! thirty-second) from the last accepted state ([`PathOptions::newton_fallback`]). It
//! runs only where the press would otherwise stop, so every press that got through
//! without it is unchanged. (It also tried from rest, as the reference solve starts,
//! until that was measured to rescue no press: see the fallback's code.)
//! Where that fails too the press stops there: the depths reached are kept (each an
//! equilibrium) and the depth that failed is named ([`GridPress::stopped`]). Saint Venant–Kirchhoff stops this way where it loses
//! stability, which the vademecum then reports as the press's limit.
//!
//! Each press has a budget of tangent factorizations
//! ([`PathOptions::max_factorizations`], 40): segments, Newton at a depth and the
//! fallback's iterations all count, and a press that spends it stops where it is, as
//! where no equilibrium is found, saying so. An ordinary press spends 1–10. The budget
//! bounds the presses that end in the fallback: on coarse P2 one such press spent 135
//! (129 s, most of it in a fallback from rest, since dropped, that failed as well) and
//! stopped after 40 (56 s) at the same depth; on medium, where each factorization takes
//! tens of seconds on one thread, such a press ran for more than an hour.
//!
//! A later segment's tangent is factored in single precision
//! ([`Cholesky::factor_single`]). Its factor is only an approximate inverse here (the
//! chord's tangent is already some millimetres old): every residual and every
//! acceptance test is in double precision, so the factor's rounding can change the
//! steps but not what counts as an equilibrium. The rest stiffness, whose solves are
//! the rest series' exact coefficients, stays in double; the first segment's chord
//! solves with a single-precision copy of it ([`Expander::rest_single`]), factored
//! once and sequentially so that the law does not depend on the threads (an earlier
//! copy factored in parallel did). On a 60-press covering build of coarse P2 that copy
//! took the build from 83.8 to 77.2 s, the file's answers at its held-out presses
//! within 0.0014 mm and 1e-5 of the force of the double chord's. The later segments'
//! single-precision tangents, measured on four spread vertices of coarse P2 pressed
//! to 15 mm: the same segments (14) and chord steps (117), states within 0.0014 mm
//! and forces within 1e-4 of the double-precision ones; the build's time is in
//! `docs/lab/tissue-measurements.md` §4.

use std::time::Instant;

use super::law::Law;
use super::newton::{Augment, NewtonSettings, continue_depth, factor_bordered, internal_force};
use super::series::{DepthSeries, Expander, orders_about, solve_dense};
use super::space::Space;
use super::sparse::{Cholesky, SymCsc};
use super::{FeError, Material};

/// How a press is followed.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PathOptions {
    /// Orders of the rest series (the first segment's predictor).
    pub orders: usize,
    /// Orders of a later segment's series (at least 1).
    pub restart_orders: usize,
    /// A depth is accepted when the last correction moves no node by more than this
    /// and the force by less than `force_tolerance` of itself.
    pub tolerance_mm: f64,
    pub force_tolerance: f64,
    /// A depth that needs more chord steps than this starts a new segment after it.
    /// Three with the Anderson acceleration (the plain chord needs one: it diverges
    /// rather than slows).
    pub refresh_after: usize,
    /// Most chord steps at one depth before it counts as not converging.
    pub max_steps: usize,
    /// Most segments a press starts to refresh a slow depth (a depth whose chord
    /// fails starts one regardless: at most one per depth).
    pub max_segments: usize,
    /// The higher orders' active-cell cutoff (see [`super::series::active_cells`]).
    pub active_cutoff: f64,
    /// Corrections kept by the Anderson acceleration of the chord (0: the plain chord).
    pub anderson: usize,
    /// Factor every later segment's tangent augmented (`K + α n̂n̂ᵀ`, see `Augment`),
    /// not only where `K` alone is not positive definite: the same corrections, for
    /// tests and comparisons.
    pub always_augment: bool,
    /// Stop at the first grid depth whose force falls below the largest so far by more
    /// than [`Self::force_tolerance`] of it (kept, so the caller sees the drop): past a
    /// force maximum a pressing hand snaps through, and following the press there
    /// (Saint Venant–Kirchhoff in strong compression) costs the most, in failed
    /// corrections, for states no one uses. A smaller dip is within what each state's
    /// force is known to: where the tool slides along a flat stretch of the curve,
    /// stopping on it (the rule before) cut presses short on noise.
    pub stop_past_force_peak: bool,
    /// Where the halved steps find no equilibrium either, solve the next grid depth by
    /// the reference Newton ([`super::newton::continue_depth`]: a fresh tangent each
    /// iteration, a line search, its own step cuts) from the last accepted state before
    /// the press stops. It runs only where the press would otherwise stop, so a press
    /// that reaches every depth without it is the same with it.
    pub newton_fallback: bool,
    /// Most tangent factorizations one press may spend (segments, Newton at a depth,
    /// the fallback's iterations); past it the press stops where it is, as where no
    /// equilibrium is found. An ordinary press spends 1–10; one that ends in the
    /// fallback spent 135 on coarse P2 (129 s, nearly all in a fallback from rest that
    /// failed too, since dropped) and, on medium, more than an hour of single-threaded
    /// factoring.
    pub max_factorizations: usize,
}

impl Default for PathOptions {
    fn default() -> Self {
        PathOptions {
            orders: 12,
            restart_orders: 6,
            tolerance_mm: 0.05,
            force_tolerance: 5e-3,
            refresh_after: 3,
            max_steps: 10,
            max_segments: 8,
            active_cutoff: 0.01,
            anderson: 6,
            always_augment: false,
            stop_past_force_peak: true,
            newton_fallback: true,
            max_factorizations: 40,
        }
    }
}

/// A press brought to equilibrium at each grid depth.
#[derive(Debug, Clone)]
pub struct GridPress {
    /// The rest series (its first order is the linear field of unit depth).
    pub first: DepthSeries,
    /// The accepted states (all-node, mm) and forces (N) at the grid depths.
    pub u: Vec<Vec<f64>>,
    pub force_n: Vec<f64>,
    /// Where each segment starts (mm); the first at 0.
    pub segment_starts_mm: Vec<f64>,
    /// Chord steps over all depths.
    pub chord_steps: usize,
    /// The largest accepted last correction (mm): the states' equilibrium tolerance.
    pub worst_correction_mm: f64,
    pub seconds: f64,
    /// Why the press stopped short of the grid: no equilibrium at the depth named, or
    /// its force fell (the last state kept is the one it fell at, see
    /// [`PathOptions::stop_past_force_peak`]). `u` and `force_n` then end there.
    /// `None`: every depth.
    pub stopped: Option<String>,
    /// The grid depths solved by the Newton fallback ([`PathOptions::newton_fallback`]).
    pub newton_depths_mm: Vec<f64>,
    /// Tangent factorizations spent (each segment, each Newton iteration; see
    /// [`PathOptions::max_factorizations`]).
    pub factorizations: usize,
}

/// One series and the factored tangent it was expanded with.
struct Segment<'a> {
    start_mm: f64,
    base_u: Vec<f64>,
    base_force_n: f64,
    series: DepthSeries,
    chol: Tangent<'a>,
    /// `K⁻¹ f̂` on the free dofs.
    y: Vec<f64>,
    /// The augmentation, where the tangent alone was not positive definite.
    aug: Augment,
}

enum Tangent<'a> {
    Rest(&'a Cholesky),
    Own(Cholesky),
}

impl Tangent<'_> {
    fn get(&self) -> &Cholesky {
        match self {
            Tangent::Rest(c) => c,
            Tangent::Own(c) => c,
        }
    }
}

impl Segment<'_> {
    /// The predicted state at `depth_mm`: the series summed through its highest Padé
    /// form with no pole up to the depth asked (a form chosen for the whole remaining
    /// range would be of lower order and less accurate near the base, where the
    /// segment is used most).
    fn predict(&self, depth_mm: f64) -> (f64, Vec<f64>) {
        let a = depth_mm - self.start_mm;
        let (df, du) = self.series.evaluate(&self.series.rational(a), a);
        let u = self.base_u.iter().zip(&du).map(|(b, d)| b + d).collect();
        (self.base_force_n + df, u)
    }
}

/// An accepted equilibrium: depth (mm), force (N), all-node state (mm).
struct State {
    depth_mm: f64,
    force_n: f64,
    u: Vec<f64>,
}

/// Where a chord ended.
struct Chord {
    force_n: f64,
    u: Vec<f64>,
    steps: usize,
    /// The last correction's largest nodal move (mm).
    last_mm: f64,
    converged: bool,
}

/// What a press along one probe needs besides the grid.
#[derive(Debug, Clone, Copy)]
pub struct PressLoad<'a> {
    /// Unit tool load, all-node.
    pub shape: &'a [f64],
    /// Probe functional, all-node (`probe·u` is the depth).
    pub probe: &'a [f64],
}

/// Follows the press of `load` through `depths_mm` (increasing, the first 0) and
/// returns its states there. Where no equilibrium is found at some depth (a material
/// that loses stability, a press that rolls off the tool) the states stop at the last
/// depth reached and [`GridPress::stopped`] says why; a press that reached no depth past
/// rest is given up (the message names the depth).
/// The first segment uses `expander`'s rest factorization, shared by every press.
pub fn follow(
    space: &Space,
    law: Law,
    material: Material,
    expander: &Expander,
    load: &PressLoad,
    depths_mm: &[f64],
    o: &PathOptions,
) -> Result<Result<GridPress, String>, FeError> {
    if let Some(why) = bad_depths(depths_mm) {
        return Ok(Err(why));
    }
    let t0 = Instant::now();
    let first = expander.expand_active(load.shape, load.probe, o.orders, o.active_cutoff);
    follow_from(
        space,
        law,
        material,
        expander,
        load,
        (first, t0),
        depths_mm,
        o,
    )
}

/// Why `depths_mm` is no depth grid (`None`: it is one).
fn bad_depths(depths_mm: &[f64]) -> Option<String> {
    (depths_mm.first() != Some(&0.0)
        || depths_mm
            .windows(2)
            .any(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater)))
    .then(|| format!("depths {depths_mm:?}: expected 0 first, then increasing"))
}

/// [`follow`] with the press's rest series already expanded (`o.orders` orders on
/// `o.active_cutoff`, as [`Expander::expand_active_batch`] expands several presses'
/// at once), and the instant its expansion started (the press's time counts from it).
#[allow(clippy::too_many_arguments)]
pub fn follow_from(
    space: &Space,
    law: Law,
    material: Material,
    expander: &Expander,
    load: &PressLoad,
    (first, t0): (Result<DepthSeries, FeError>, Instant),
    depths_mm: &[f64],
    o: &PathOptions,
) -> Result<Result<GridPress, String>, FeError> {
    if let Some(why) = bad_depths(depths_mm) {
        return Ok(Err(why));
    }
    let (lambda, mu) = material.lame_n_per_mm2();
    let shape_free = space.restrict(load.shape);
    let probe_free = space.restrict(load.probe);
    let first = match first {
        Ok(s) => s,
        Err(e @ FeError::ProbeNotMoved) => return Ok(Err(format!("first series: {e}"))),
        Err(e) => return Err(e),
    };
    let n_all = 3 * space.nodes.len();
    // The first segment's chord solves with the single-precision rest factor (the
    // series above used the double one).
    let rest = expander
        .rest_single()
        .unwrap_or_else(|| expander.rest_factor());
    let mut seg = Segment {
        start_mm: 0.0,
        base_u: vec![0.0; n_all],
        base_force_n: 0.0,
        series: first.clone(),
        y: rest.solve(&shape_free),
        chol: Tangent::Rest(rest),
        aug: Augment::default(),
    };
    let pattern = SymCsc::pattern(space);
    let mut out = GridPress {
        first,
        u: vec![vec![0.0; n_all]],
        force_n: vec![0.0],
        segment_starts_mm: vec![0.0],
        chord_steps: 0,
        worst_correction_mm: 0.0,
        seconds: 0.0,
        stopped: None,
        newton_depths_mm: Vec::new(),
        factorizations: 0,
    };
    let budget_left = |out: &GridPress| o.max_factorizations.saturating_sub(out.factorizations);
    // Starts a segment at an accepted state, counting its factorization in `spent`;
    // `None` where its tangent is not positive definite or the budget is spent (the
    // caller keeps the old one).
    let restart = |at: &State, spent: &mut usize| -> Result<Option<Segment<'static>>, FeError> {
        if *spent >= o.max_factorizations {
            return Ok(None);
        }
        *spent += 1;
        let Some((chol, aug)) = factor_bordered(
            space,
            law,
            &pattern,
            &at.u,
            (lambda, mu),
            &probe_free,
            o.always_augment,
        )?
        else {
            return Ok(None);
        };
        let series = match orders_about(
            space,
            law,
            lambda,
            mu,
            &chol,
            load.shape,
            load.probe,
            Some(&at.u),
            o.restart_orders.max(1),
            o.active_cutoff,
            (aug.alpha > 0.0).then_some((aug.alpha, aug.z.as_slice())),
        ) {
            Ok(s) => s,
            Err(FeError::ProbeNotMoved) => return Ok(None),
            Err(e) => return Err(e),
        };
        Ok(Some(Segment {
            start_mm: at.depth_mm,
            base_u: at.u.clone(),
            base_force_n: at.force_n,
            series,
            y: chol.solve(&shape_free),
            chol: Tangent::Own(chol),
            aug,
        }))
    };
    let step =
        |c: &Cholesky, y: &[f64], aug: &Augment, from: (f64, Vec<f64>), d: f64, steps: usize| {
            chord(
                space,
                law,
                (lambda, mu),
                (c, y, aug),
                (&shape_free, &probe_free),
                from,
                d,
                (o.tolerance_mm, o.force_tolerance),
                steps,
                o.anderson,
            )
        };
    let grid_step = |j: usize| depths_mm[j] - depths_mm[j - 1];
    let mut last = State {
        depth_mm: 0.0,
        force_n: 0.0,
        u: vec![0.0; n_all],
    };
    let mut j = 1;
    // The current step toward the next grid depth: the grid's, halved where no
    // equilibrium is found (at most `MAX_HALVINGS` times), doubled back after a
    // success.
    let mut h = if depths_mm.len() > 1 {
        grid_step(1)
    } else {
        0.0
    };
    while j < depths_mm.len() {
        let mut target = depths_mm[j].min(last.depth_mm + h);
        let prediction = seg.predict(target);
        let mut c = step(
            seg.chol.get(),
            &seg.y,
            &seg.aug,
            prediction.clone(),
            target,
            o.max_steps,
        );
        out.chord_steps += c.steps;
        let mut refresh = c.steps > o.refresh_after;
        if !c.converged {
            if seg.start_mm < last.depth_mm
                && let Some(s) = restart(&last, &mut out.factorizations)?
            {
                out.segment_starts_mm.push(s.start_mm);
                seg = s;
                continue;
            }
            // Newton at this depth from the prediction, the tangent refactored at
            // each iterate (at most four times).
            let mut from = prediction;
            for _ in 0..4 {
                if budget_left(&out) == 0 {
                    break;
                }
                out.factorizations += 1;
                let Some((chol, aug)) = factor_bordered(
                    space,
                    law,
                    &pattern,
                    &from.1,
                    (lambda, mu),
                    &probe_free,
                    o.always_augment,
                )?
                else {
                    break;
                };
                let y = chol.solve(&shape_free);
                c = step(&chol, &y, &aug, from, target, o.max_steps);
                out.chord_steps += c.steps;
                if c.converged || !c.last_mm.is_finite() {
                    break;
                }
                from = (c.force_n, c.u.clone());
            }
            if !c.converged {
                let spent = budget_left(&out) == 0;
                if !spent && h > grid_step(j) / f64::from(1u32 << MAX_HALVINGS) {
                    h /= 2.0;
                    continue;
                }
                let mut why = if spent {
                    format!(
                        "gave up at {target:.2} mm: the press's budget of {} tangent \
                         factorizations is spent",
                        o.max_factorizations
                    )
                } else {
                    format!(
                        "no equilibrium at {target:.2} mm: neither the chord from the \
                         tangent at {:.2} mm nor Newton from there converged, with the \
                         step halved {MAX_HALVINGS} times",
                        seg.start_mm
                    )
                };
                let goal = depths_mm[j];
                // From the last state only. Newton from rest (where the reference solve
                // starts) came after it until it was measured: tried in 26 presses of
                // the kidney and the liver's band, it never found an equilibrium, and it
                // took 12-20 % of those presses' time (docs/lab/tissue-measurements.md §3).
                let left = budget_left(&out);
                if o.newton_fallback && left > 0 {
                    match continue_depth(
                        space,
                        law,
                        material,
                        (load.shape, load.probe),
                        out.first.force[0],
                        (last.depth_mm, last.force_n, &last.u),
                        goal,
                        NewtonSettings {
                            max_iterations: left,
                            ..FALLBACK
                        },
                        &mut out.factorizations,
                    ) {
                        Ok(sol) => {
                            out.chord_steps += sol.report.iterations;
                            out.newton_depths_mm.push(goal);
                            target = goal;
                            c = Chord {
                                force_n: sol.force_n,
                                u: sol.u,
                                steps: sol.report.iterations,
                                // Newton's own tolerance (a residual 1e-8 of the
                                // force) is far inside the chord's.
                                last_mm: 0.0,
                                converged: true,
                            };
                        }
                        Err(e @ FeError::NoConvergenceDepth { .. }) => {
                            why = format!("{why}; nor Newton from {:.2} mm: {e}", last.depth_mm);
                        }
                        Err(e) => return Err(e),
                    }
                }
                if !c.converged && !spent && budget_left(&out) == 0 {
                    why = format!(
                        "{why}; the press's budget of {} tangent factorizations is spent",
                        o.max_factorizations
                    );
                }
                if !c.converged {
                    // The depths reached stand (each an equilibrium); a press that
                    // reached no depth past rest has nothing to give.
                    if out.u.len() < 2 {
                        return Ok(Err(why));
                    }
                    out.stopped = Some(why);
                    break;
                }
            }
            refresh = true;
        }
        out.worst_correction_mm = out.worst_correction_mm.max(c.last_mm);
        last = State {
            depth_mm: target,
            force_n: c.force_n,
            u: c.u,
        };
        if target == depths_mm[j] {
            out.u.push(last.u.clone());
            out.force_n.push(last.force_n);
            j += 1;
            if o.stop_past_force_peak
                && let Some(k) = force_peak_passed(&out.force_n, o.force_tolerance)
            {
                out.stopped = Some(format!(
                    "the force fell from {:.2} N at {:.2} mm to {:.2} N at {:.2} mm",
                    out.force_n[k],
                    depths_mm[k],
                    last.force_n,
                    depths_mm[j - 1]
                ));
                break;
            }
        }
        if j < depths_mm.len() {
            h = (2.0 * h).min(grid_step(j));
        }
        let more = out.segment_starts_mm.len() < o.max_segments;
        if refresh
            && more
            && j < depths_mm.len()
            && let Some(s) = restart(&last, &mut out.factorizations)?
        {
            out.segment_starts_mm.push(s.start_mm);
            seg = s;
        }
    }
    out.seconds = t0.elapsed().as_secs_f64();
    Ok(Ok(out))
}

/// Why a press stopped short of its grid, read from the message it stored (a tissue
/// file keeps the message, not a code): what `palpa info` counts, so that a user sees
/// how many presses the tissue ends at a force peak and how many found no equilibrium.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopKind {
    /// Its force fell past a peak ([`PathOptions::stop_past_force_peak`], or the
    /// vademecum's own check of a press's forces).
    ForcePeak,
    /// No equilibrium was found at the next depth (or the first series failed).
    /// `budget_spent`: the press's factorizations ran out on the way (in files built
    /// before the fallback from rest was dropped, mostly in it: it got what the chord
    /// and Newton from the last state left of [`PathOptions::max_factorizations`]).
    NoEquilibrium { budget_spent: bool },
}

impl StopKind {
    /// Every message `follow` writes that says the budget is spent contains this.
    const BUDGET: &'static str = "tangent factorizations is spent";
    /// How the force-peak messages start: `follow`'s, and the vademecum's where it
    /// cuts a press at a dip `follow` let through.
    const FORCE_PEAK: [&'static str; 2] = ["the force fell from", "the force peaks at"];

    /// The kind of a stored stop message; `None` for the empty one (no stop).
    pub fn of(why: &str) -> Option<StopKind> {
        Some(match why {
            "" => return None,
            w if Self::FORCE_PEAK.iter().any(|p| w.starts_with(p)) => StopKind::ForcePeak,
            w => StopKind::NoEquilibrium {
                budget_spent: w.contains(Self::BUDGET),
            },
        })
    }
}

/// Bytes a build of presses needs on `space`'s mesh, `(shared, each)`: the rest
/// stiffness factors all presses share (double precision for the series, single for
/// the first segment's chord), and what one press holds at
/// its peak. A press keeps its segment's single-precision factor and, where it falls
/// back on Newton ([`PathOptions::newton_fallback`]), factors a double-precision
/// tangent beside it; its vectors (series orders, chord history) are small beside
/// those. Both scale with the factor's entries `L` ([`super::sparse::factor_entries`]):
/// `shared = SHARED_BYTES_PER_ENTRY · L`, `each = PRESS_BYTES_PER_ENTRY · L`. Measured
/// (peak resident memory of builds pressing one and two at a time): coarse P2
/// (`L` = 41.5 million) 0.87 and 1.28 GB, medium P2 (517 million) 8.9 and 13.8 GB, so
/// 8–11 bytes an entry shared and about 10 a press; two medium presses falling back
/// on Newton at once peaked at 21.7 GB (about 17 a press). The constants (12 and 16)
/// put two medium presses at 22.8 GB (docs/lab/tissue-measurements.md §5). Those were
/// measured under AMD; under the nested-dissection order (`super::ordering`) the
/// factors hold 25.7 and 265 million entries, and the same bytes an entry held: the
/// two-at-a-time coarse covering build peaked at 0.94 GB (estimate 1.13 GB), one medium
/// press at 4.9 GB (estimate 7.4 GB). The shared single-precision rest factor (4 bytes
/// an entry) raised the shared constant to 16: measured with it, 1.00 GB for the
/// coarse covering build (estimate 1.23 GB) and 5.8 GB for the medium press (estimate
/// 8.5 GB).
pub fn press_memory_bytes(space: &Space) -> Result<(u64, u64), FeError> {
    let entries = super::sparse::factor_entries(&SymCsc::pattern(space))?;
    Ok((
        SHARED_BYTES_PER_ENTRY * entries,
        PRESS_BYTES_PER_ENTRY * entries,
    ))
}

/// See [`press_memory_bytes`].
pub const SHARED_BYTES_PER_ENTRY: u64 = 16;
/// See [`press_memory_bytes`].
pub const PRESS_BYTES_PER_ENTRY: u64 = 16;

/// Where the last of `force_n` has fallen below the largest before it by more than
/// `tolerance` of that largest: the index of the largest. `None` while the curve still
/// rises, or dips by no more than its states' force tolerance. A negative tolerance
/// (one no correction meets, as tests set to starve the chord) counts as none.
pub fn force_peak_passed(force_n: &[f64], tolerance: f64) -> Option<usize> {
    let tolerance = tolerance.max(0.0);
    let (&last, before) = force_n.split_last()?;
    let (k, &top) = before
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    (last < (1.0 - tolerance) * top).then_some(k)
}

/// How many times a step toward the next grid depth may be halved.
const MAX_HALVINGS: u32 = 3;

/// The Newton fallback's settings: its steps are shares of what is left to the next
/// grid depth (at most one grid step), cut down to a thirty-second of it; a residual of
/// 1e-8 of the force is converged (the chord's acceptance is far looser).
const FALLBACK: NewtonSettings = NewtonSettings {
    rel_tol: 1e-8,
    max_iterations_per_step: 12,
    initial_step: 1.0,
    min_step: 1.0 / 32.0,
    max_iterations: usize::MAX,
};

/// One chord correction at depth `d` from `(force_n, u)` with the segment's factored
/// tangent (see the module doc): `(Δu, ΔF)`, `Δu` on the free dofs, with `n̂·Δu`
/// bringing the depth to `d`.
#[allow(clippy::too_many_arguments)]
fn correction(
    space: &Space,
    law: Law,
    (lambda, mu): (f64, f64),
    (k, y, aug): (&Cholesky, &[f64], &Augment),
    (shape, probe): (&[f64], &[f64]),
    force_n: f64,
    u: &[f64],
    d: f64,
) -> (Vec<f64>, f64) {
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let fi = internal_force(space, law, u, lambda, mu);
    let r: Vec<f64> = fi.iter().zip(shape).map(|(a, b)| a - force_n * b).collect();
    let g = dot(probe, &space.restrict(u)) - d;
    let x = aug.solve(k, &r, g);
    let df = (dot(probe, &x) - g) / dot(probe, y);
    (y.iter().zip(&x).map(|(a, b)| df * a - b).collect(), df)
}

/// Chord Newton at depth `d` from `start` with a fixed factored tangent `k` and
/// `y = k⁻¹ f̂`: converged when the last correction moves no node by more than
/// `tolerance_mm` and the force by less than `force_tolerance` of itself; given up after
/// `max_steps` or when the corrections stop shrinking.
#[allow(clippy::too_many_arguments)]
fn chord(
    space: &Space,
    law: Law,
    (lambda, mu): (f64, f64),
    (k, y, aug): (&Cholesky, &[f64], &Augment),
    (shape, probe): (&[f64], &[f64]),
    (mut force_n, mut u): (f64, Vec<f64>),
    d: f64,
    (tolerance_mm, force_tolerance): (f64, f64),
    max_steps: usize,
    anderson: usize,
) -> Chord {
    if anderson > 0 {
        return accelerated(
            space,
            law,
            (lambda, mu),
            (k, y, aug),
            (shape, probe),
            (force_n, u),
            d,
            (tolerance_mm, force_tolerance),
            max_steps,
            anderson,
        );
    }
    let mut previous = f64::INFINITY;
    for step in 1..=max_steps.max(1) {
        let (du, df) = correction(
            space,
            law,
            (lambda, mu),
            (k, y, aug),
            (shape, probe),
            force_n,
            &u,
            d,
        );
        let size = du.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if !(size.is_finite() && df.is_finite()) {
            return Chord {
                force_n,
                u,
                steps: step,
                last_mm: f64::INFINITY,
                converged: false,
            };
        }
        for (ui, di) in u.iter_mut().zip(space.expand(&du)) {
            *ui += di;
        }
        force_n += df;
        let converged = size <= tolerance_mm && df.abs() <= force_tolerance * force_n.abs();
        // Not contracting: a tangent too far from the state.
        let stalled = step > 1 && size > 0.7 * previous;
        if converged || stalled || step >= max_steps {
            return Chord {
                force_n,
                u,
                steps: step,
                last_mm: size,
                converged,
            };
        }
        previous = size;
    }
    unreachable!("the loop returns at its last step")
}

/// The chord with Anderson acceleration: the chord step is a fixed-point map
/// `z ← z + c(z)` on `z = (u_free, F·ĉ)` (the force scaled by the segment's compliance
/// `ĉ = n̂·K⁻¹f̂`, so both parts are in mm). With the last `m` differences of iterates
/// `ΔZ` and of corrections `ΔC`, the next iterate is
///
/// ```text
/// γ = argmin ‖c_k − ΔC γ‖,    z_{k+1} = z_k + c_k − (ΔZ + ΔC) γ,
/// ```
///
/// which for a linear map is GMRES on the chord's preconditioned system: it converges
/// where the plain chord diverges through a few large eigenvalues of `I − K⁻¹K_t(u)`
/// (the tangent changed near the tool only). The same acceptance rule as the chord.
#[allow(clippy::too_many_arguments)]
fn accelerated(
    space: &Space,
    law: Law,
    (lambda, mu): (f64, f64),
    (k, y, aug): (&Cholesky, &[f64], &Augment),
    (shape, probe): (&[f64], &[f64]),
    (force_n, u): (f64, Vec<f64>),
    d: f64,
    (tolerance_mm, force_tolerance): (f64, f64),
    max_steps: usize,
    m: usize,
) -> Chord {
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let ny = dot(probe, y);
    let n = y.len();
    // z = (u_free, F ĉ).
    let mut z = space.restrict(&u);
    z.push(force_n * ny);
    let (mut dz, mut dc): (Vec<Vec<f64>>, Vec<Vec<f64>>) = (Vec::new(), Vec::new());
    let mut last: Option<(Vec<f64>, Vec<f64>)> = None;
    let mut first = f64::INFINITY;
    let all = |z: &[f64]| space.expand(&z[..n]);
    for step in 1..=max_steps.max(1) {
        let u = all(&z);
        let f = z[n] / ny;
        let (mut c, df) = correction(
            space,
            law,
            (lambda, mu),
            (k, y, aug),
            (shape, probe),
            f,
            &u,
            d,
        );
        c.push(df * ny);
        let size = c[..n].iter().fold(0.0f64, |s, v| s.max(v.abs()));
        let converged = size <= tolerance_mm && df.abs() <= force_tolerance * (f + df).abs();
        if step == 1 {
            first = size;
        }
        let blown = !(size.is_finite() && df.is_finite()) || size > 10.0 * first;
        if converged || blown || step >= max_steps {
            if !blown {
                z.iter_mut().zip(&c).for_each(|(a, b)| *a += b);
            }
            return Chord {
                force_n: z[n] / ny,
                u: all(&z),
                steps: step,
                last_mm: if blown { f64::INFINITY } else { size },
                converged,
            };
        }
        if let Some((z0, c0)) = last.take() {
            dz.push(z.iter().zip(&z0).map(|(a, b)| a - b).collect());
            dc.push(c.iter().zip(&c0).map(|(a, b)| a - b).collect());
            if dz.len() > m {
                dz.remove(0);
                dc.remove(0);
            }
        }
        let gamma = least_squares(&dc, &c);
        let mut next: Vec<f64> = z.iter().zip(&c).map(|(a, b)| a + b).collect();
        for ((g, zi), ci) in gamma.iter().zip(&dz).zip(&dc) {
            for ((v, a), b) in next.iter_mut().zip(zi).zip(ci) {
                *v -= g * (a + b);
            }
        }
        last = Some((z, c));
        z = next;
    }
    unreachable!("the loop returns at its last step")
}

/// `argmin ‖b − A γ‖` over the columns `a` (few), by the normal equations with a
/// relative ridge of 1e-12 (the columns are nearly dependent near convergence).
fn least_squares(a: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
    let m = a.len();
    if m == 0 {
        return Vec::new();
    }
    let dot = |p: &[f64], q: &[f64]| p.iter().zip(q).map(|(x, y)| x * y).sum::<f64>();
    let mut g = vec![0.0; m * m];
    let mut rhs = vec![0.0; m];
    for i in 0..m {
        for j in 0..=i {
            g[i * m + j] = dot(&a[i], &a[j]);
            g[j * m + i] = g[i * m + j];
        }
        rhs[i] = dot(&a[i], b);
    }
    let trace: f64 = (0..m).map(|i| g[i * m + i]).sum();
    for i in 0..m {
        g[i * m + i] += 1e-12 * trace + f64::MIN_POSITIVE;
    }
    // No step to mix in where even the ridged system is singular.
    solve_dense(g, rhs).unwrap_or_else(|| vec![0.0; m])
}

#[cfg(test)]
mod tests {
    use super::{StopKind, force_peak_passed};

    /// The messages `follow` and the vademecum write, as a tissue file stores them,
    /// are told apart, and a budget spent anywhere on the way is seen.
    #[test]
    fn a_stop_message_is_read_back_as_its_kind() {
        let no_equilibrium = "no equilibrium at 13.62 mm: neither the chord from the tangent \
            at 13.00 mm nor Newton from there converged, with the step halved 3 times";
        let cases = [
            ("", None),
            (
                "the force fell from 2.17 N at 2.00 mm to 2.05 N at 3.00 mm",
                Some(StopKind::ForcePeak),
            ),
            (
                "the force peaks at 20.87 N near 14.00 mm (20.41 N at 15.00 mm): past it the \
                 tissue snaps through under a pressing hand",
                Some(StopKind::ForcePeak),
            ),
            (
                no_equilibrium,
                Some(StopKind::NoEquilibrium {
                    budget_spent: false,
                }),
            ),
            (
                "first series: the probe did not move",
                Some(StopKind::NoEquilibrium {
                    budget_spent: false,
                }),
            ),
            (
                "gave up at 13.25 mm: the press's budget of 40 tangent factorizations is spent",
                Some(StopKind::NoEquilibrium { budget_spent: true }),
            ),
            (
                &format!(
                    "{no_equilibrium}; nor Newton from 13.00 mm: its budget of 40 tangent \
                     factorizations is spent"
                ),
                Some(StopKind::NoEquilibrium { budget_spent: true }),
            ),
        ];
        for (why, kind) in cases {
            assert_eq!(StopKind::of(why), kind, "{why}");
        }
    }

    /// A rising curve and a dip within the tolerance go on; a fall past it names the
    /// largest force's index, also where the fall came slowly over several depths.
    #[test]
    fn a_force_peak_is_a_fall_past_the_tolerance_below_the_largest() {
        let tol = 5e-3;
        assert_eq!(force_peak_passed(&[0.0, 1.0, 2.0, 3.0], tol), None);
        assert_eq!(force_peak_passed(&[0.0], tol), None);
        // 14.26 → 14.25 N: 0.07 % down, a flat stretch.
        assert_eq!(force_peak_passed(&[0.0, 9.0, 14.26, 14.25], tol), None);
        assert_eq!(force_peak_passed(&[0.0, 9.0, 14.26, 14.26], tol), None);
        assert_eq!(force_peak_passed(&[0.0, 9.0, 14.26, 14.0], tol), Some(2));
        // Three dips of 0.2 % each: none alone, the third past the largest by 0.6 %.
        let mut f = vec![0.0, 10.0];
        for _ in 0..2 {
            f.push(f[f.len() - 1] * 0.998);
            assert_eq!(force_peak_passed(&f, tol), None, "{f:?}");
        }
        f.push(f[f.len() - 1] * 0.998);
        assert_eq!(force_peak_passed(&f, tol), Some(1));
        // A negative tolerance: any fall stops, a rise or a flat force does not.
        assert_eq!(force_peak_passed(&[0.0, 1.0, 2.0], -1.0), None);
        assert_eq!(force_peak_passed(&[0.0, 2.0, 2.0], -1.0), None);
        assert_eq!(force_peak_passed(&[0.0, 2.0, 1.999], -1.0), Some(1));
    }
}
