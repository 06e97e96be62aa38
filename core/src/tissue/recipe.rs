//! A tissue build as one value: what is pressed, stage by stage, and how the result is
//! compressed. `palpa tissue build` runs a [`Recipe`] (`--recipe default`, `shipped`,
//! `quick`), `scripts/make-assets.sh` runs the shipped one, and the same stages are the
//! lab's staging tools (`palpa lab tissue refine|band`) one at a time.
//!
//! The first stage presses every palpable vertex and edge midpoint and, in the same
//! pass, splits the triangles whose edge surplus exceeds [`Recipe::split_above_mm`];
//! it is compressed, and each further [`Stage`] reads the compressed file back, presses
//! only its own points, and keeps the file's samples as they are:
//!
//! - [`Stage::Split`]: the `triangles` worst triangles split, in all (a stage of a
//!   refinement in stages: the shipped tissue took six, each going on from the last);
//! - [`Stage::SubSplit`]: the worst sub-triangles of the split triangles split again
//!   (the second level);
//! - [`Stage::Band`]: the band next to the fixed region, whose corners on the fixed
//!   region are never pressed (its edges' midpoints pressed); last, as a file with a band
//!   is not split further.
//!
//! Which stages pay was measured on the coarse liver (docs/lab/tissue-measurements.md):
//! the band next to the fixed region always (the quadratic blend there had no pressed
//! corner), the first-pass split above 0.35 mm for the deep presses, the staged and
//! second-level splits for the shipped file's last 0.4 mm. The default recipe is the
//! first two; the shipped one all of them.

use serde::{Deserialize, Serialize};

use crate::tissue::law::{DEFAULT_BITS, DEFAULT_TOLERANCE_MM, Grouping};
use crate::tissue::options::SurfaceLawOptions;
use crate::tissue::refine::DEFAULT_REFINE_ABOVE_MM;
use crate::tissue::shapes::ShapeBits;

/// One stage after the first pass.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Stage {
    /// The `triangles` worst triangles split, in all (those an earlier stage split
    /// among them), ranked by their largest edge surplus.
    Split { triangles: usize },
    /// The `sub_triangles` worst sub-triangles of the split triangles split again.
    SubSplit { sub_triangles: usize },
    /// The band next to the fixed region.
    Band,
}

impl Stage {
    /// The stage in words, as a progress line names it.
    pub fn describe(&self) -> String {
        match self {
            Stage::Split { triangles } => format!("the {triangles} worst triangles split"),
            Stage::SubSplit { sub_triangles } => {
                format!("the {sub_triangles} worst sub-triangles split again")
            }
            Stage::Band => "the band next to the fixed region".into(),
        }
    }
}

/// A tissue build: the presses' settings, the first pass's split, the stages after it,
/// and the compression.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Recipe {
    /// The law, material, element, depth grid, tool and whether edge midpoints are
    /// pressed.
    pub options: SurfaceLawOptions,
    /// The first pass splits the triangles whose largest edge surplus exceeds this
    /// (mm); `None`: no split in the first pass (needs the edges pressed).
    pub split_above_mm: Option<f64>,
    pub stages: Vec<Stage>,
    /// The compression's guaranteed bound on any node's residual (mm).
    pub tolerance_mm: f64,
    /// Bits per stored entry of a mode's shape (8 or 16).
    pub bits: ShapeBits,
    /// Whether each split triangle's points share one set of modes.
    pub grouping: Grouping,
}

/// The recipes a command can name.
pub const NAMES: [&str; 3] = ["default", "shipped", "quick"];

impl Recipe {
    /// `default`: every palpable vertex and edge midpoint pressed to 15 mm, the
    /// triangles whose edge surplus exceeds 0.35 mm split in the same pass, then the
    /// band next to the fixed region.
    pub fn default_build() -> Recipe {
        Recipe {
            options: SurfaceLawOptions {
                depth_max_mm: 15.0,
                ..SurfaceLawOptions::default()
            },
            split_above_mm: Some(DEFAULT_REFINE_ABOVE_MM),
            stages: vec![Stage::Band],
            tolerance_mm: DEFAULT_TOLERANCE_MM,
            bits: DEFAULT_BITS,
            grouping: Grouping::SplitTriangle,
        }
    }

    /// `shipped`: what made `assets/liver-coarse.tissue`: no split in the first pass,
    /// the worst triangles split in six stages (100, 163, 260, 430, 540, 760 in all),
    /// the 190 worst of their sub-triangles split again, then the band.
    pub fn shipped() -> Recipe {
        let mut stages: Vec<Stage> = [100, 163, 260, 430, 540, 760]
            .into_iter()
            .map(|triangles| Stage::Split { triangles })
            .collect();
        stages.push(Stage::SubSplit { sub_triangles: 190 });
        stages.push(Stage::Band);
        Recipe {
            split_above_mm: None,
            stages,
            ..Recipe::default_build()
        }
    }

    /// `quick`: a first look in a third of the presses: the palpable vertices only
    /// (the blend linear between them), no split, no band.
    pub fn quick() -> Recipe {
        Recipe {
            options: SurfaceLawOptions {
                edges: false,
                ..Recipe::default_build().options
            },
            split_above_mm: None,
            stages: Vec::new(),
            ..Recipe::default_build()
        }
    }

    /// The recipe a command names (one of [`NAMES`]).
    pub fn named(name: &str) -> Option<Recipe> {
        match name {
            "default" => Some(Recipe::default_build()),
            "shipped" => Some(Recipe::shipped()),
            "quick" => Some(Recipe::quick()),
            _ => None,
        }
    }

    /// Why the recipe cannot be run, in words naming what was expected; `None` where
    /// it can.
    pub fn check(&self) -> Option<String> {
        if !self.options.edges
            && (self.split_above_mm.is_some()
                || self
                    .stages
                    .iter()
                    .any(|s| matches!(s, Stage::Split { .. } | Stage::SubSplit { .. })))
        {
            return Some(
                "a split needs the edge midpoints pressed: expected edges, or no split stage"
                    .into(),
            );
        }
        if let Some(mm) = self.split_above_mm
            && !(mm.is_finite() && mm >= 0.0)
        {
            return Some(format!(
                "a first-pass split above {mm} mm: expected a length of at least 0"
            ));
        }
        if !(self.tolerance_mm.is_finite() && self.tolerance_mm > 0.0) {
            return Some(format!(
                "a compression bound of {} mm: expected a positive length",
                self.tolerance_mm
            ));
        }
        let band_at = self.stages.iter().position(|s| *s == Stage::Band);
        if band_at.is_some_and(|k| k + 1 != self.stages.len()) {
            return Some("the band pressed before a later stage: expected the band last".into());
        }
        let mut last_split = 0;
        let mut sub_split = false;
        for s in &self.stages {
            match *s {
                Stage::Split { triangles } => {
                    if sub_split {
                        return Some(
                            "a split stage after the sub-triangles were split again: expected \
                             every split stage before the second level"
                                .into(),
                        );
                    }
                    if triangles <= last_split {
                        return Some(format!(
                            "a split stage of {triangles} triangles after one of {last_split}: \
                             expected each stage to split more triangles in all"
                        ));
                    }
                    last_split = triangles;
                }
                Stage::SubSplit { sub_triangles } => {
                    if sub_triangles == 0 {
                        return Some(
                            "a second level of 0 sub-triangles: expected at least one".into(),
                        );
                    }
                    sub_split = true;
                }
                Stage::Band => {}
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_named_recipes_can_be_run_and_the_shipped_one_is_the_assets() {
        for name in NAMES {
            let r = Recipe::named(name).expect("named");
            assert_eq!(r.check(), None, "{name}");
        }
        assert!(Recipe::named("fast").is_none());
        let shipped = Recipe::shipped();
        assert_eq!(shipped.stages.len(), 8);
        assert_eq!(shipped.stages.last(), Some(&Stage::Band));
        assert_eq!(shipped.options.depth_max_mm, 15.0);
        assert!(!Recipe::quick().options.edges);
    }

    #[test]
    fn a_recipe_out_of_order_is_refused_by_name() {
        let mut r = Recipe::default_build();
        r.stages = vec![Stage::Band, Stage::Split { triangles: 10 }];
        assert!(r.check().is_some_and(|w| w.contains("band last")));
        r.stages = vec![
            Stage::Split { triangles: 10 },
            Stage::Split { triangles: 5 },
        ];
        assert!(r.check().is_some_and(|w| w.contains("more triangles")));
        r.stages = vec![
            Stage::SubSplit { sub_triangles: 3 },
            Stage::Split { triangles: 5 },
        ];
        assert!(r.check().is_some_and(|w| w.contains("second level")));
        let mut q = Recipe::quick();
        q.stages = vec![Stage::Split { triangles: 5 }];
        assert!(q.check().is_some_and(|w| w.contains("edge midpoints")));
        let mut t = Recipe::default_build();
        t.tolerance_mm = f64::NAN;
        assert!(t.check().is_some_and(|w| w.contains("positive")));
    }
}
