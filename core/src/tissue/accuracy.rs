//! What a tissue file is measured to be worth: the runs of `palpa tissue check
//! --record` against the full nonlinear FE at held-out points, kept in the file itself
//! so that every figure shown about it (the panel's depth flag, `palpa info`, the
//! warnings) is read from what was measured on these very bytes, never from a constant.
//!
//! A run presses `points` seeded random points (off every sampled vertex, edge and
//! split point) at a list of depths; per depth it keeps how many presses the tissue
//! reaches and Newton answered, and the worst force error (relative to Newton's force)
//! and surface error (the largest node distance, mm) among them. Runs are merged depth
//! by depth: the goals hold to a depth `d` where every press of every run at every
//! measured depth up to `d` meets them.

use serde::{Deserialize, Serialize};

/// The surface goal: no surface node farther than this from the full FE's, mm.
pub const GOAL_SURFACE_MM: f64 = 0.5;
/// The force goal: the force within this share of the full FE's.
pub const GOAL_FORCE_REL: f64 = 0.05;

/// Every recorded check of one tissue file (see the module docs).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Accuracy {
    pub runs: Vec<CheckRun>,
}

/// One `palpa tissue check --record`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckRun {
    /// The seed of the held-out draw; `None` where the points were given (`--at`).
    pub seed: Option<u64>,
    /// Points drawn, and of them those on the fixed region (nothing there to press).
    pub points: u32,
    pub held_points: u32,
    /// The scene the file was bound to (`liver` or a file name).
    pub scene: String,
    /// What the draw leaves out (where it does not press).
    pub left_out: String,
    /// Per depth, in increasing order.
    pub depths: Vec<DepthFigures>,
}

/// One depth of a run (or of all runs merged).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DepthFigures {
    pub depth_mm: f64,
    /// Presses compared with Newton (the tissue reaches them and Newton answered).
    pub presses: u32,
    /// Presses deeper than the tissue answers at their point: flagged, not compared.
    pub past_limit: u32,
    pub worst_force_rel: f64,
    pub worst_surface_mm: f64,
}

/// The depths to which a tissue is measured within the goals, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GoalDepths {
    /// Both goals, at every press measured up to this depth.
    pub both_mm: f64,
    /// The force goal alone (at least `both_mm`).
    pub force_mm: f64,
}

impl DepthFigures {
    fn meets_force(&self) -> bool {
        self.worst_force_rel <= GOAL_FORCE_REL
    }

    fn meets_both(&self) -> bool {
        self.meets_force() && self.worst_surface_mm <= GOAL_SURFACE_MM
    }
}

impl Accuracy {
    /// Adds a run, replacing an earlier one of the same draw (seed, count and scene):
    /// a check run again on the same file measures the same presses again.
    pub fn record(&mut self, run: CheckRun) {
        let same = |r: &CheckRun| {
            r.seed.is_some() && (r.seed, r.points, &r.scene) == (run.seed, run.points, &run.scene)
        };
        match self.runs.iter_mut().find(|r| same(r)) {
            Some(r) => *r = run,
            None => self.runs.push(run),
        }
    }

    /// The runs merged depth by depth (presses summed, worst errors kept), in
    /// increasing depth.
    pub fn merged(&self) -> Vec<DepthFigures> {
        let mut out: Vec<DepthFigures> = Vec::new();
        for d in self.runs.iter().flat_map(|r| &r.depths) {
            match out.iter_mut().find(|m| m.depth_mm == d.depth_mm) {
                Some(m) => {
                    m.presses += d.presses;
                    m.past_limit += d.past_limit;
                    m.worst_force_rel = m.worst_force_rel.max(d.worst_force_rel);
                    m.worst_surface_mm = m.worst_surface_mm.max(d.worst_surface_mm);
                }
                None => out.push(*d),
            }
        }
        out.sort_by(|a, b| a.depth_mm.total_cmp(&b.depth_mm));
        out
    }

    /// The deepest measured depths up to which every compared press meets both goals,
    /// and the force goal alone; `None` where nothing was compared, or where the
    /// shallowest depth measured already misses both.
    pub fn goals_to_mm(&self) -> Option<GoalDepths> {
        let merged: Vec<DepthFigures> = self
            .merged()
            .into_iter()
            .filter(|d| d.presses > 0)
            .collect();
        let upto = |ok: fn(&DepthFigures) -> bool| {
            merged
                .iter()
                .take_while(|d| ok(d))
                .last()
                .map(|d| d.depth_mm)
        };
        let both = upto(DepthFigures::meets_both);
        let force = upto(DepthFigures::meets_force);
        match (both, force) {
            (Some(both_mm), Some(force_mm)) => Some(GoalDepths { both_mm, force_mm }),
            (None, Some(force_mm)) => Some(GoalDepths {
                both_mm: 0.0,
                force_mm,
            }),
            _ => None,
        }
    }

    /// Points drawn over all runs.
    pub fn points(&self) -> u32 {
        self.runs.iter().map(|r| r.points).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn depth(depth_mm: f64, force: f64, surface: f64) -> DepthFigures {
        DepthFigures {
            depth_mm,
            presses: 4,
            past_limit: 0,
            worst_force_rel: force,
            worst_surface_mm: surface,
        }
    }

    fn run(seed: u64, depths: Vec<DepthFigures>) -> CheckRun {
        CheckRun {
            seed: Some(seed),
            points: 4,
            held_points: 0,
            scene: "liver".into(),
            left_out: "the band next to the fixed region".into(),
            depths,
        }
    }

    #[test]
    fn goals_hold_to_the_last_depth_every_run_meets() {
        let mut a = Accuracy::default();
        assert_eq!(a.goals_to_mm(), None);
        a.record(run(
            7,
            vec![
                depth(2.6, 0.01, 0.1),
                depth(9.3, 0.02, 0.3),
                depth(12.7, 0.03, 0.9),
            ],
        ));
        assert_eq!(
            a.goals_to_mm(),
            Some(GoalDepths {
                both_mm: 9.3,
                force_mm: 12.7
            })
        );
        // A second draw that misses the surface at 9.3 mm pulls both goals back.
        a.record(run(8, vec![depth(2.6, 0.01, 0.1), depth(9.3, 0.02, 0.6)]));
        assert_eq!(
            a.goals_to_mm(),
            Some(GoalDepths {
                both_mm: 2.6,
                force_mm: 12.7
            })
        );
        assert_eq!(a.merged()[1].presses, 8);
        assert_eq!(a.points(), 8);
        // The same draw measured again replaces its run.
        a.record(run(8, vec![depth(2.6, 0.01, 0.1), depth(9.3, 0.02, 0.4)]));
        assert_eq!(a.runs.len(), 2);
        assert_eq!(a.goals_to_mm().map(|g| g.both_mm), Some(9.3));
    }

    #[test]
    fn a_depth_with_nothing_compared_says_nothing() {
        let mut a = Accuracy::default();
        let mut past = depth(14.6, 0.5, 5.0);
        past.presses = 0;
        past.past_limit = 4;
        a.record(run(7, vec![depth(2.6, 0.01, 0.1), past]));
        assert_eq!(
            a.goals_to_mm(),
            Some(GoalDepths {
                both_mm: 2.6,
                force_mm: 2.6
            })
        );
    }
}
