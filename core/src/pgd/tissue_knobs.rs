//! The tissue vademecum's two knobs, applied to a built law: the modes each sample
//! keeps and the depth grid's step. `palpa tradeoff` measures each setting's error
//! at held-out points and depths against the full nonlinear FE, and its bytes and
//! evaluation time.
//!
//! Both are cuts of what was stored, so one build serves the whole table:
//!
//! - **Modes.** A sample's residual over the depths is `R ≈ A C` with `A`'s columns
//!   the SVD's left vectors in order of their singular values, and `C = Σ Vᵀ`, whose
//!   row `k` has norm `σ_k` (see [`super::tissue`]). Keeping the first `q` modes
//!   errs by at most `σ_{q+1}` in any column, and so at any node, on top of the
//!   stored bound: the largest dropped `σ` is reported with the cut.
//! - **Depth step.** Keeping every `k`-th grid depth, `d_{kj'}`, is the law a build
//!   with the `k` times longer step would have stored (each grid state is an
//!   equilibrium of its own depth, not of the path between), blended linearly in `d`
//!   between the kept depths. A press that reached `r` grid depths (depth 0 included)
//!   reaches `⌊(r − 1)/k⌋ + 1` kept ones; a cut that would leave a press with depth 0
//!   alone is refused.

use super::tissue::TissueLaw;

/// A law with fewer modes, or a longer depth step, and what the modes dropped weigh.
#[derive(Debug, Clone)]
pub struct Coarsened {
    pub law: TissueLaw,
    /// The largest singular value dropped from any sample (mm): the added bound on a
    /// node's residual at a grid depth.
    pub dropped_sigma_mm: f64,
}

impl TissueLaw {
    /// Keeps at most `modes_max` modes per sample and every `depth_stride`-th grid
    /// depth. The stride must divide the grid's intervals (the deepest depth stays).
    pub fn coarsened(&self, modes_max: usize, depth_stride: usize) -> Result<Coarsened, String> {
        let (steps, k) = (self.steps as usize, depth_stride);
        if modes_max == 0 || k == 0 || !(steps - 1).is_multiple_of(k) {
            return Err(format!(
                "{modes_max} modes, every {k}th depth: expected at least one mode and a \
                 stride dividing the grid's {} intervals",
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
        let (mut mode_start, mut shape, mut shape_scale, mut coeffs) =
            (vec![0u32], Vec::new(), Vec::new(), Vec::new());
        let (mut rank, mut dropped) = (0usize, 0.0f64);
        for s in 0..n_samples {
            let modes = self.mode_start[s] as usize..self.mode_start[s + 1] as usize;
            let keep = modes.len().min(modes_max);
            rank = rank.max(keep);
            for (i, mode) in modes.enumerate() {
                let row = &self.coeffs[mode * steps..][..steps];
                if i >= keep {
                    let sigma = row.iter().map(|&c| f64::from(c).powi(2)).sum::<f64>();
                    dropped = dropped.max(sigma.sqrt());
                    continue;
                }
                shape.extend_from_slice(&self.shape[mode * m..][..m]);
                shape_scale.push(self.shape_scale[mode]);
                coeffs.extend((0..new_steps).map(|j| row[source(s, j)]));
            }
            mode_start.push(mode_start[s] + keep as u32);
        }
        let mut options = self.options;
        options.depth_step_mm *= k as f64;
        let law = TissueLaw {
            options,
            steps: new_steps as u32,
            ratio,
            reach,
            rank: rank as u32,
            mode_start,
            shape,
            shape_scale,
            coeffs,
            truncation_bound_mm: self.truncation_bound_mm.max(dropped),
            ..self.clone()
        };
        law.check()?;
        Ok(Coarsened {
            law,
            dropped_sigma_mm: dropped,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis::ProbePoint;
    use crate::pgd::surfacelaw::SurfaceLawOptions;
    use crate::pgd::tissue::BoundTissue;

    /// Three corners, depths 0–4 mm, two modes each (x and y of one row); corner 2's
    /// press reached 3 mm. Mode 0's x residual is `d²/4`, mode 1's y is `0.1 d`.
    fn law() -> TissueLaw {
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
            shape: [i16::MAX, 0, 0, 0, i16::MAX, 0].repeat(3),
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
        }
    }

    fn surface(law: TissueLaw, bary: [f64; 3], depth_mm: f64) -> [f64; 3] {
        let axis = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]];
        let bound = BoundTissue::bind(law, &[[0.0, 0.0, 5.0]], &axis, &[[0, 1, 2]]).expect("binds");
        let mut rows = [0.0; 3];
        let p = ProbePoint { triangle: 0, bary };
        assert!(bound.add_surface(&p, depth_mm, &mut bound.scratch(), &mut rows));
        rows
    }

    #[test]
    fn the_full_setting_is_the_law_itself() {
        let c = law().coarsened(8, 1).expect("valid");
        assert_eq!(c.law, law());
        assert_eq!(c.dropped_sigma_mm, 0.0);
    }

    #[test]
    fn fewer_modes_drop_the_later_ones_and_report_their_weight() {
        let c = law().coarsened(1, 1).expect("valid");
        assert_eq!(
            (c.law.rank, c.law.mode_start.clone()),
            (1, vec![0, 1, 2, 3])
        );
        // Mode 1's coefficients: 0.1 · (0, 1, 2, 3, 4), norm 0.1 · √30.
        assert!((c.dropped_sigma_mm - 0.1 * 30f64.sqrt()).abs() < 1e-6);
        assert_eq!(c.law.truncation_bound_mm, c.dropped_sigma_mm);
        let r = surface(c.law, [1.0, 0.0, 0.0], 2.0);
        assert!((r[0] - 1.0).abs() < 1e-6 && r[1] == 0.0, "{r:?}");
    }

    #[test]
    fn a_longer_step_keeps_grid_depths_and_blends_linearly_between() {
        let c = law().coarsened(8, 2).expect("valid");
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
        assert!(law().coarsened(0, 1).is_err());
        assert!(
            law()
                .coarsened(2, 3)
                .expect_err("3 does not divide 4")
                .contains("4 intervals")
        );
        let mut short = law();
        short.reach[2] = 2;
        short.coeffs[20..25].copy_from_slice(&[0.0, 0.25, 0.25, 0.25, 0.25]);
        let why = short.coarsened(2, 2).expect_err("a press left at rest");
        assert!(why.contains("sample 2 reached 1 mm"), "{why}");
    }
}
