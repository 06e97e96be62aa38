//! Find the nodule: a training case hidden in a scene, palpated, marked and scored.
//!
//! A **case** is a nodule drawn from a table's ranges ([`draw`], seeded: the same seed
//! hides the same nodule) or set by a trainer ([`Case::of`]), placed through the table
//! ([`EffectTable::place`]) so that the probe's force with it is known everywhere on
//! the palpable surface without a solve. A **trial** ([`Trial`]) follows the trainee:
//! the largest force used, then one mark where they feel it; its [`Score`] is the
//! distance from the mark to the nodule's centre projected on the palpable surface
//! (the point of that surface closest to the centre), the time to the mark and the
//! largest force.
//!
//! Drawing: the centre uniformly in the lattice's box, the radius and the ratio
//! uniformly in the ranges asked; a draw the table refuses (a centre outside the organ,
//! a nodule within 2 mm of the surface) or answers only by its far field (past the
//! band, where little is felt) is drawn again. The
//! ratio's default range, 3 to 10, is that of malignant tumours against the tissue
//! around them (3–6 in the breast, to 13 for high-grade ones; about 4.4 in the liver):
//! a ratio near 1 hides nothing to find.

use thiserror::Error;

use super::table::{EffectTable, FIT_RATIOS, MAX_RATIO, NoduleEffect, TableError};
use crate::axis::closest_point;
use crate::fe::nodule::Nodule;
use crate::rng::Rng;

/// Draws tried before a case gives up on finding a nodule the table answers.
const TRIES: usize = 10_000;

/// Why a case could not be drawn, set or scored.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TrainingError {
    #[error(
        "{what} range {lo} to {hi}: expected finite bounds, lo ≤ hi, within the table's {table_lo} to {table_hi}"
    )]
    Range {
        what: &'static str,
        lo: f64,
        hi: f64,
        table_lo: f64,
        table_hi: f64,
    },
    #[error(
        "no nodule in {TRIES} draws was one the table answers (centres inside the organ, 2 mm below its surface): the table's lattice hardly reaches into the organ"
    )]
    NoRoom,
    #[error("the table has no palpable face to project the nodule on")]
    NoSurface,
    #[error("a mark at {0:?} mm: expected a finite point")]
    Mark([f64; 3]),
    #[error(transparent)]
    Table(#[from] TableError),
}

/// The radii and ratios a case is drawn from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaseRanges {
    pub radius_mm: [f64; 2],
    pub ratio: [f64; 2],
    /// Draw only nodules whose lattice cell reaches past the band (deeper, or beside a
    /// surface no probe presses), which the table answers by its far field; `false`:
    /// only nodules within the band, where a case is felt.
    pub past_band: bool,
}

impl CaseRanges {
    /// Every radius the table answers, ratios 3 to 10.
    pub fn of(table: &EffectTable) -> CaseRanges {
        CaseRanges {
            radius_mm: table.radius_range_mm(),
            ratio: [3.0, FIT_RATIOS[1]],
            past_band: false,
        }
    }

    fn check(&self, table: &EffectTable) -> Result<(), TrainingError> {
        let [rlo, rhi] = table.radius_range_mm();
        for (what, [lo, hi], [table_lo, table_hi]) in [
            ("radius (mm)", self.radius_mm, [rlo, rhi]),
            ("ratio", self.ratio, [1.0, MAX_RATIO]),
        ] {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= table_lo && hi <= table_hi) {
                return Err(TrainingError::Range {
                    what,
                    lo,
                    hi,
                    table_lo,
                    table_hi,
                });
            }
        }
        Ok(())
    }
}

/// A hidden nodule and what the probe feels of it.
#[derive(Debug, Clone)]
pub struct Case {
    /// The seed it was drawn with (`None`: set by a trainer).
    pub seed: Option<u64>,
    /// The effect at every probe node of the table (`F_with/F_without − 1`).
    pub effect: NoduleEffect,
    /// The nodule's centre projected on the palpable surface: what a mark is scored
    /// against.
    pub surface_mm: [f64; 3],
    /// From that point to the centre (mm).
    pub depth_mm: f64,
    /// The largest effect anywhere on the surface: how much there is to feel.
    pub peak_effect: f64,
}

impl Case {
    /// The case of a given nodule (a trainer's).
    pub fn of(table: &EffectTable, nodule: &Nodule) -> Result<Case, TrainingError> {
        let effect = table.place(nodule)?;
        Case::with(table, effect, None)
    }

    fn with(
        table: &EffectTable,
        effect: NoduleEffect,
        seed: Option<u64>,
    ) -> Result<Case, TrainingError> {
        let vertices: Vec<[f64; 3]> = table.probe_mm.iter().map(|p| p.map(f64::from)).collect();
        let triangles: Vec<[u32; 3]> = table
            .face_nodes
            .iter()
            .flatten()
            .map(|six| [six[0], six[1], six[2]])
            .collect();
        let hit = closest_point(&vertices, &triangles, effect.nodule.center_mm)
            .ok_or(TrainingError::NoSurface)?;
        let peak_effect = effect.at_node.iter().copied().fold(0.0, f64::max);
        Ok(Case {
            seed,
            surface_mm: hit.point,
            depth_mm: hit.distance,
            peak_effect,
            effect,
        })
    }

    pub fn nodule(&self) -> Nodule {
        self.effect.nodule
    }
}

/// A nodule drawn from `ranges` within the table's lattice, the same for the same seed.
pub fn draw(table: &EffectTable, ranges: &CaseRanges, seed: u64) -> Result<Case, TrainingError> {
    ranges.check(table)?;
    let (lo, hi) = table.box_mm();
    let mut rng = Rng::seed(seed);
    for _ in 0..TRIES {
        let nodule = Nodule {
            center_mm: [0, 1, 2].map(|d| rng.range(lo[d], hi[d])),
            radius_mm: rng.range(ranges.radius_mm[0], ranges.radius_mm[1]),
            ratio: rng.range(ranges.ratio[0], ranges.ratio[1]),
        };
        let in_band = table.place_in_band(&nodule);
        let placed = match (ranges.past_band, in_band) {
            (false, in_band) => in_band,
            (true, Ok(_)) => continue,
            (true, Err(TableError::CentreOutside { .. })) => table.place(&nodule),
            (true, Err(e)) => Err(e),
        };
        match placed {
            Ok(effect) => return Case::with(table, effect, Some(seed)),
            Err(
                TableError::CentreOutside { .. }
                | TableError::OutsideOrgan { .. }
                | TableError::TooShallow { .. },
            ) => continue,
            Err(e) => return Err(e.into()),
        }
    }
    Err(TrainingError::NoRoom)
}

/// One trainee's search for a case's nodule.
#[derive(Debug, Clone)]
pub struct Trial {
    pub case: Case,
    /// When the trial began, on the caller's clock (s).
    started_s: f64,
    largest_force_n: f64,
    mark: Option<([f64; 3], f64)>,
}

/// How a trial went.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Score {
    /// From the mark to the nodule's centre projected on the surface (mm).
    pub distance_mm: f64,
    /// From the trial's start to the mark (s).
    pub time_s: f64,
    pub largest_force_n: f64,
    pub mark_mm: [f64; 3],
    pub nodule_surface_mm: [f64; 3],
}

impl Trial {
    pub fn new(case: Case, now_s: f64) -> Trial {
        Trial {
            case,
            started_s: now_s,
            largest_force_n: 0.0,
            mark: None,
        }
    }

    /// A force the trainee used (non-finite values are ignored); once marked, presses
    /// no longer count.
    pub fn pressed(&mut self, force_n: f64) {
        if self.mark.is_none() && force_n.is_finite() {
            self.largest_force_n = self.largest_force_n.max(force_n.abs());
        }
    }

    /// Marks where the trainee feels the nodule; a later mark replaces it.
    pub fn mark(&mut self, at_mm: [f64; 3], now_s: f64) -> Result<(), TrainingError> {
        if !at_mm.iter().all(|c| c.is_finite()) {
            return Err(TrainingError::Mark(at_mm));
        }
        self.mark = Some((at_mm, now_s));
        Ok(())
    }

    /// When the trial began, on the caller's clock (s).
    pub fn started_s(&self) -> f64 {
        self.started_s
    }

    pub fn marked(&self) -> bool {
        self.mark.is_some()
    }

    pub fn largest_force_n(&self) -> f64 {
        self.largest_force_n
    }

    /// The score, once marked.
    pub fn score(&self) -> Option<Score> {
        let (mark_mm, at_s) = self.mark?;
        let s = self.case.surface_mm;
        let distance_mm = (0..3)
            .map(|d| (mark_mm[d] - s[d]).powi(2))
            .sum::<f64>()
            .sqrt();
        Some(Score {
            distance_mm,
            time_s: (at_s - self.started_s).max(0.0),
            largest_force_n: self.largest_force_n,
            mark_mm,
            nodule_surface_mm: s,
        })
    }
}
