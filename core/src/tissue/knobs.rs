//! The tissue vademecum's three knobs, applied to a built law: the modes each sample
//! keeps, the bits each mode's shape is stored in, and the depth grid's step.
//! `palpa tradeoff` measures each setting's error at held-out points and depths
//! against the full nonlinear FE, and its bytes and evaluation time.
//!
//! Both are cuts of what was stored, so one build serves the whole table:
//!
//! - **Modes.** A group's residuals over the depths (one sample, or a split
//!   triangle's points) are `R ≈ A C` with `A`'s columns the SVD's left vectors in
//!   order of their singular values, and `C = Σ Vᵀ`, whose row `k` has norm `σ_k`
//!   over all the group's members (see [`crate::tissue::law`]). Keeping the first `q` modes
//!   errs by at most `σ_{q+1}` in any column, and so at any node, on top of the
//!   stored bound: the largest dropped `σ` is reported with the cut.
//! - **Precision.** Each kept mode is quantized again to the bits asked for (a cut
//!   to the bits it has copies it): its node error per unit weight times its largest
//!   weight is what that adds to a node, reported with the cut (see
//!   [`crate::tissue::shapes`]).
//! - **Depth step.** Keeping every `k`-th grid depth, `d_{kj'}`, is the law a build
//!   with the `k` times longer step would have stored (each grid state is an
//!   equilibrium of its own depth, not of the path between), blended linearly in `d`
//!   between the kept depths. A press that reached `r` grid depths (depth 0 included)
//!   reaches `⌊(r − 1)/k⌋ + 1` kept ones; a cut that would leave a press with depth 0
//!   alone is refused.

use crate::tissue::law::TissueLaw;
use crate::tissue::shapes::{ShapeBits, Shapes};
use crate::tissue::weights::to_half;

/// A law with fewer modes, fewer bits or a longer depth step, and what the modes
/// dropped and the requantization weigh.
#[derive(Debug, Clone)]
pub struct Coarsened {
    pub law: TissueLaw,
    /// The largest singular value dropped from any one-sample group, or the largest
    /// sum of the dropped modes' weights over a group of several (mm): the added bound
    /// on a node's residual at a grid depth.
    pub dropped_sigma_mm: f64,
    /// The most that quantizing to fewer bits adds to a node of any sample (mm).
    pub requantized_mm: f64,
}

impl TissueLaw {
    /// Keeps at most `modes_max` modes per group, in `bits`, and every
    /// `depth_stride`-th grid depth. The stride must divide the grid's intervals (the
    /// deepest depth stays). The law's bound grows by what is dropped and requantized.
    pub fn coarsened(
        &self,
        modes_max: usize,
        bits: ShapeBits,
        depth_stride: usize,
    ) -> Result<Coarsened, String> {
        let (steps, k) = (self.steps as usize, depth_stride);
        if modes_max == 0 || k == 0 || !(steps - 1).is_multiple_of(k) {
            return Err(format!(
                "at most {modes_max} modes a sample, a depth stride of {k}: expected at least \
                 one mode and a stride dividing the grid's {} intervals",
                steps - 1
            ));
        }
        let new_steps = (steps - 1) / k + 1;
        let n_samples = self.reach.len();
        let mut reach = Vec::with_capacity(n_samples);
        for (s, &r) in self.reach.iter().enumerate() {
            let kept = (r as usize - 1) / k + 1;
            if kept < 2 {
                return Err(format!(
                    "sample {s} reached {} mm only, less than one step of {} mm",
                    (r - 1) as f64 * self.options.depth_step_mm,
                    k as f64 * self.options.depth_step_mm
                ));
            }
            reach.push(kept as u32);
        }
        // Grid depth j' of the cut, from the old grid: past a press's reach its arrays
        // hold its last depth reached, as a build stores them.
        let source = |s: usize, j: usize| k * j.min(reach[s] as usize - 1);
        let ratio = (0..n_samples)
            .flat_map(|s| (0..new_steps).map(move |j| (s, j)))
            .map(|(s, j)| self.ratio[s * steps + source(s, j)])
            .collect();
        let m = 3 * self.rows_mm.len();
        let groups = self.mode_start.len() - 1;
        let mut members = vec![Vec::new(); groups];
        for (s, &g) in self.group.iter().enumerate() {
            members[g as usize].push(s);
        }
        let (mut mode_start, mut shape, mut shape_scale) =
            (vec![0u32], Shapes::new(bits), Vec::new());
        let mut sample_coeffs: Vec<Vec<f32>> = vec![Vec::new(); n_samples];
        let mut sample_requantized = vec![0.0f64; n_samples];
        let (mut rank, mut dropped) = (0usize, 0.0f64);
        let mut mode_mm = vec![0.0; m];
        for (g, members) in members.iter().enumerate() {
            let modes = self.mode_start[g] as usize..self.mode_start[g + 1] as usize;
            let keep = modes.len().min(modes_max);
            rank = rank.max(keep);
            // A group's modes are each the leading pair of what the earlier ones left,
            // not one SVD's orthogonal tail: what they drop is bounded by their sum.
            let mut group_dropped = 0.0f64;
            for (i, mode) in modes.enumerate() {
                // Mode `i`'s weights over the group's members: a row of `Σ Vᵀ`.
                let row =
                    |s: usize| &self.coeffs[self.coeff_start[s] as usize + i * steps..][..steps];
                if i >= keep {
                    let sigma: f64 = members
                        .iter()
                        .flat_map(|&s| row(s))
                        .map(|&c| f64::from(c).powi(2))
                        .sum();
                    match members.len() {
                        1 => dropped = dropped.max(sigma.sqrt()),
                        _ => group_dropped += sigma.sqrt(),
                    }
                    continue;
                }
                if bits == self.shape.bits() {
                    shape.push_copy(&self.shape, mode, m);
                    shape_scale.push(self.shape_scale[mode]);
                } else {
                    let scale = f64::from(self.shape_scale[mode]);
                    for (k, x) in mode_mm.iter_mut().enumerate() {
                        *x = self.shape.get(mode * m + k) * scale;
                    }
                    let (scale, node_error) = shape.push_mode(&mode_mm);
                    shape_scale.push(scale);
                    for &s in members {
                        let c_max = row(s)
                            .iter()
                            .fold(0.0f64, |a, &c| a.max(f64::from(c).abs()));
                        sample_requantized[s] += node_error * c_max;
                    }
                }
                for &s in members {
                    let row = row(s);
                    sample_coeffs[s].extend((0..new_steps).map(|j| row[source(s, j)]));
                }
            }
            dropped = dropped.max(group_dropped);
            mode_start.push(mode_start[g] + keep as u32);
        }
        let requantized = sample_requantized.iter().copied().fold(0.0, f64::max);
        let mut coeff_start = vec![0u32];
        for c in &sample_coeffs {
            coeff_start.push(coeff_start.last().copied().unwrap_or(0) + c.len() as u32);
        }
        let coeffs = sample_coeffs.concat();
        let mut options = self.options;
        options.depth_step_mm *= k as f64;
        let law = TissueLaw {
            options,
            steps: new_steps as u32,
            ratio,
            reach,
            rank: rank as u32,
            mode_start,
            coeff_start,
            shape,
            shape_scale,
            coeffs,
            truncation_bound_mm: self.truncation_bound_mm + dropped + requantized,
            // Checks measured the law before the cut.
            accuracy: Default::default(),
            ..self.clone()
        };
        law.check()?;
        Ok(Coarsened {
            law,
            dropped_sigma_mm: dropped,
            requantized_mm: requantized,
        })
    }

    /// The law without its split triangles' quarter and inner points: the quadratic
    /// blend everywhere, what a build with `--no-refine` stores from the same presses
    /// (the split points' samples come last, so the others keep their indices).
    pub fn unsplit(&self) -> TissueLaw {
        let n = self.samples_mm.len() + self.edge_ends.len();
        self.first_samples(n, crate::tissue::surface::Refinement::default())
    }

    /// The law without its second level ([`crate::tissue::subsplit::SubSplit`]): the file its
    /// sub-triangles were split from (their samples come last).
    pub fn without_sub_split(&self) -> TissueLaw {
        let r = &self.refinement;
        let n = self.samples_mm.len()
            + self.edge_ends.len()
            + r.quarter_ends.len()
            + r.inner_corners.len();
        let refinement = crate::tissue::surface::Refinement {
            sub: Default::default(),
            band: Vec::new(),
            ..r.clone()
        };
        self.first_samples(n, refinement)
    }

    /// The law without its band next to the fixed region
    /// ([`crate::tissue::surface::BandEdge`]): the file the band was pressed on (its samples
    /// come last).
    pub fn without_band(&self) -> TissueLaw {
        let r = &self.refinement;
        let refinement = crate::tissue::surface::Refinement {
            band: Vec::new(),
            ..r.clone()
        };
        self.first_samples(self.reach.len() - r.band.len(), refinement)
    }

    /// The law of its first `n` samples (whose groups of modes come first, see
    /// `Grouping`), with `refinement` listing what they hold.
    fn first_samples(&self, n: usize, refinement: crate::tissue::surface::Refinement) -> TissueLaw {
        let (steps, m) = (self.steps as usize, 3 * self.rows_mm.len());
        let groups = self.group[..n]
            .iter()
            .map(|&g| g as usize + 1)
            .max()
            .unwrap_or(0);
        let modes = self.mode_start[groups] as usize;
        let rank = self.mode_start[..=groups]
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(0);
        TissueLaw {
            refinement,
            ratio: self.ratio[..n * steps].to_vec(),
            stiffness_n_per_mm: self.stiffness_n_per_mm[..n].to_vec(),
            correction_mm: self.correction_mm[..n].to_vec(),
            segments: self.segments[..n].to_vec(),
            reach: self.reach[..n].to_vec(),
            stopped: self.stopped[..n].to_vec(),
            rank,
            mode_start: self.mode_start[..=groups].to_vec(),
            group: self.group[..n].to_vec(),
            coeff_start: self.coeff_start[..=n].to_vec(),
            shape: self.shape.prefix(modes * m),
            shape_scale: self.shape_scale[..modes].to_vec(),
            coeffs: self.coeffs[..self.coeff_start[n] as usize].to_vec(),
            // Checks measured the law with all its samples.
            accuracy: Default::default(),
            ..self.clone()
        }
    }
}

impl TissueLaw {
    /// The law with every weight rounded to a half ([`to_half`]), and the most that
    /// moves a node of any sample at any grid depth (`δ` of the module docs, mm),
    /// which its bound grows by. A law already in halves comes back as it is, `δ = 0`.
    pub fn with_half_weights(&self) -> (TissueLaw, f64) {
        let (steps, m) = (self.steps as usize, 3 * self.rows_mm.len());
        // Each mode's largest node displacement per unit weight (mm).
        let node_max: Vec<f64> = self
            .shape_scale
            .iter()
            .enumerate()
            .map(|(mode, &scale)| {
                let peak = (0..m / 3)
                    .map(|n| {
                        (0..3)
                            .map(|c| self.shape.get(mode * m + 3 * n + c).powi(2))
                            .sum::<f64>()
                    })
                    .fold(0.0, f64::max);
                peak.sqrt() * f64::from(scale)
            })
            .collect();
        let coeffs: Vec<f32> = self.coeffs.iter().map(|&w| to_half(w)).collect();
        let mut moved = 0.0f64;
        for (s, &g) in self.group.iter().enumerate() {
            let modes =
                self.mode_start[g as usize] as usize..self.mode_start[g as usize + 1] as usize;
            let start = self.coeff_start[s] as usize;
            for j in 0..steps {
                // Folded from +0 (a float sum starts at −0, which a report would print).
                let at = modes.clone().enumerate().fold(0.0f64, |at, (k, mode)| {
                    let i = start + k * steps + j;
                    at + f64::from(self.coeffs[i] - coeffs[i]).abs() * node_max[mode]
                });
                moved = moved.max(at);
            }
        }
        let law = TissueLaw {
            coeffs,
            truncation_bound_mm: self.truncation_bound_mm + moved,
            // Checks measured the weights as they were.
            accuracy: Default::default(),
            ..self.clone()
        };
        (law, moved)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::axis::ProbePoint;
    use crate::tissue::bound::BoundTissue;
    use crate::tissue::surface::{Refinement, SurfaceLawOptions};

    /// Three corners, depths 0–4 mm, two modes each (x and y of one row); corner 2's
    /// press reached 3 mm. Mode 0's x residual is `d²/4`, mode 1's y is `0.1 d`.
    pub(crate) fn law() -> TissueLaw {
        let x: Vec<f32> = (0..5).map(|j| (j * j) as f32 / 4.0).collect();
        let y: Vec<f32> = (0..5).map(|j| 0.1 * j as f32).collect();
        let held = |v: &[f32]| [&v[..4], &[v[3]]].concat();
        let s = 1.0 / f32::from(i16::MAX);
        TissueLaw {
            options: SurfaceLawOptions {
                depth_max_mm: 4.0,
                depth_step_mm: 1.0,
                edges: false,
                ..SurfaceLawOptions::default()
            },
            rows_mm: vec![[0.0, 0.0, 5.0]],
            samples_mm: vec![[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]],
            skipped_mm: vec![],
            edge_ends: vec![],
            refinement: Refinement::default(),
            steps: 5,
            ratio: [
                [1.0, 0.9, 0.8, 0.7, 0.6],
                [1.0, 0.9, 0.8, 0.7, 0.6],
                [1.0, 0.9, 0.8, 0.7, 0.7],
            ]
            .concat(),
            stiffness_n_per_mm: vec![1.0; 3],
            correction_mm: vec![0.0; 3],
            segments: vec![1; 3],
            reach: vec![5, 5, 4],
            stopped: vec![
                String::new(),
                String::new(),
                "no equilibrium at 4 mm".into(),
            ],
            rank: 2,
            mode_start: vec![0, 2, 4, 6],
            group: vec![0, 1, 2],
            coeff_start: vec![0, 10, 20, 30],
            shape: Shapes::Sixteen([i16::MAX, 0, 0, 0, i16::MAX, 0].repeat(3)),
            shape_scale: vec![s; 6],
            coeffs: [
                x.clone(),
                y.clone(),
                x.clone(),
                y.clone(),
                held(&x),
                held(&y),
            ]
            .concat(),
            truncation_bound_mm: 0.01,
            tolerance_mm: 0.05,
            build_s: 0.0,
            compress_s: 0.0,
            mesh_xxh3: Some(0x0123_4567_89ab_cdef),
            accuracy: Default::default(),
        }
    }

    /// The surface row of `law` evaluated on its one triangle at `bary` and a depth.
    pub(crate) fn surface(law: TissueLaw, bary: [f64; 3], depth_mm: f64) -> [f64; 3] {
        let axis = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]];
        let bound = BoundTissue::bind(law, &[[0.0, 0.0, 5.0]], &axis, &[[0, 1, 2]]).expect("binds");
        let mut rows = [0.0; 3];
        let p = ProbePoint { triangle: 0, bary };
        assert!(bound.add_surface(&p, depth_mm, &mut bound.scratch(), &mut rows));
        rows
    }

    /// The same law with its three samples in one group: their shapes are the same
    /// two, so one copy serves all and each keeps its own weights.
    fn grouped() -> TissueLaw {
        let l = law();
        let Shapes::Sixteen(x) = &l.shape else {
            unreachable!()
        };
        TissueLaw {
            mode_start: vec![0, 2],
            group: vec![0, 0, 0],
            shape: Shapes::Sixteen(x[..6].to_vec()),
            shape_scale: l.shape_scale[..2].to_vec(),
            ..l
        }
    }

    #[test]
    fn samples_sharing_a_group_blend_as_they_do_alone() {
        let (alone, shared) = (law(), grouped());
        assert_eq!(shared.check(), Ok(()));
        for bary in [[1.0, 0.0, 0.0], [0.2, 0.3, 0.5], [0.0, 0.5, 0.5]] {
            for depth_mm in [0.0, 1.5, 3.0, 3.7, 5.0] {
                let (a, b) = (
                    surface(alone.clone(), bary, depth_mm),
                    surface(shared.clone(), bary, depth_mm),
                );
                for k in 0..3 {
                    assert!(
                        (a[k] - b[k]).abs() <= 1e-12,
                        "{bary:?} {depth_mm}: {a:?} {b:?}"
                    );
                }
            }
        }
        // Cutting a shared mode drops it from every member: its weight over all of them
        // is what the cut reports.
        let cut = shared.coarsened(1, ShapeBits::Sixteen, 1).expect("valid");
        let y2: f64 = [0.0, 0.01, 0.04, 0.09, 0.16].iter().sum::<f64>() * 2.0
            + [0.0, 0.01, 0.04, 0.09, 0.09].iter().sum::<f64>();
        assert!(
            (cut.dropped_sigma_mm - y2.sqrt()).abs() < 1e-6,
            "{}",
            cut.dropped_sigma_mm
        );
        assert_eq!(
            (cut.law.mode_start.clone(), cut.law.coeff_start.clone()),
            (vec![0, 1], vec![0, 5, 10, 15])
        );
        // A sample whose weights do not cover its group's modes is refused.
        let mut bad = grouped();
        bad.coeff_start[1] = 9;
        assert!(bad.check().is_err());
        bad = grouped();
        bad.group[2] = 1;
        assert!(bad.check().is_err());
    }

    #[test]
    fn the_full_setting_is_the_law_itself() {
        let c = law().coarsened(8, ShapeBits::Sixteen, 1).expect("valid");
        assert_eq!(c.law, law());
        assert_eq!((c.dropped_sigma_mm, c.requantized_mm), (0.0, 0.0));
    }

    #[test]
    fn eight_bits_halve_the_shapes_and_err_within_what_they_report() {
        // A mode with entries of several sizes, so that quantizing costs something.
        let mut l = law();
        let x = [32767i16, 12345, -777, 5, 20000, -31111].repeat(3);
        l.shape = Shapes::Sixteen(x);
        let c = l.coarsened(8, ShapeBits::Eight, 1).expect("valid");
        assert_eq!(c.law.shape.bits(), ShapeBits::Eight);
        assert_eq!(2 * c.law.shape.bytes(), l.shape.bytes());
        assert!(c.requantized_mm > 0.0);
        assert!((c.law.truncation_bound_mm - (0.01 + c.requantized_mm)).abs() < 1e-12);
        for (bary, depth) in [([1.0, 0.0, 0.0], 4.0), ([0.2, 0.3, 0.5], 2.5)] {
            let (a, b) = (
                surface(l.clone(), bary, depth),
                surface(c.law.clone(), bary, depth),
            );
            let e = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
            assert!(
                e > 0.0 && e <= c.requantized_mm,
                "{e} vs {}",
                c.requantized_mm
            );
        }
        // Back to sixteen bits: a step 127/32767 of the eight-bit one, so what that
        // costs is about 1/258 of what eight bits did.
        let back = c.law.coarsened(8, ShapeBits::Sixteen, 1).expect("valid");
        assert!(back.requantized_mm < 1e-2 * c.requantized_mm);
    }

    #[test]
    fn fewer_modes_drop_the_later_ones_and_report_their_weight() {
        let c = law().coarsened(1, ShapeBits::Sixteen, 1).expect("valid");
        assert_eq!(
            (c.law.rank, c.law.mode_start.clone()),
            (1, vec![0, 1, 2, 3])
        );
        // Mode 1's coefficients: 0.1 · (0, 1, 2, 3, 4), norm 0.1 · √30.
        assert!((c.dropped_sigma_mm - 0.1 * 30f64.sqrt()).abs() < 1e-6);
        assert!((c.law.truncation_bound_mm - (0.01 + c.dropped_sigma_mm)).abs() < 1e-12);
        let r = surface(c.law, [1.0, 0.0, 0.0], 2.0);
        assert!((r[0] - 1.0).abs() < 1e-6 && r[1] == 0.0, "{r:?}");
    }

    #[test]
    fn a_longer_step_keeps_grid_depths_and_blends_linearly_between() {
        let c = law().coarsened(8, ShapeBits::Sixteen, 2).expect("valid");
        assert_eq!((c.law.steps, c.law.options.depth_step_mm), (3, 2.0));
        // Corner 2 reached 3 mm: 0 and 2 mm kept, so it answers to 2 mm.
        assert_eq!(c.law.reach, vec![3, 3, 2]);
        let at = [1.0, 0.0, 0.0];
        let kept = surface(c.law.clone(), at, 2.0);
        let full = surface(law(), at, 2.0);
        assert!((kept[0] - full[0]).abs() < 1e-9 && (kept[1] - full[1]).abs() < 1e-9);
        // At 1 mm: halfway between 0 and 1 mm of x (d²/4 at 2 mm), y exact (linear).
        let r = surface(c.law.clone(), at, 1.0);
        assert!(
            (r[0] - 0.5).abs() < 1e-6 && (r[1] - 0.1).abs() < 1e-6,
            "{r:?}"
        );
        let axis = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]];
        let bound =
            BoundTissue::bind(c.law, &[[0.0, 0.0, 5.0]], &axis, &[[0, 1, 2]]).expect("binds");
        let inside = ProbePoint {
            triangle: 0,
            bary: [0.4, 0.3, 0.3],
        };
        assert_eq!(
            bound.limit_mm(&inside),
            (2.0, Some("no equilibrium at 4 mm"))
        );
    }

    #[test]
    fn cuts_that_lose_the_deepest_depth_or_a_whole_press_are_refused() {
        assert!(law().coarsened(0, ShapeBits::Sixteen, 1).is_err());
        assert!(
            law()
                .coarsened(2, ShapeBits::Sixteen, 3)
                .expect_err("3 does not divide 4")
                .contains("4 intervals")
        );
        let mut short = law();
        short.reach[2] = 2;
        short.coeffs[20..25].copy_from_slice(&[0.0, 0.25, 0.25, 0.25, 0.25]);
        let why = short
            .coarsened(2, ShapeBits::Sixteen, 2)
            .expect_err("a press left at rest");
        assert!(why.contains("sample 2 reached 1 mm"), "{why}");
    }
}
