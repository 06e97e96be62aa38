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
//! which is computed off-line, per palpable vertex `v`, from the press's depth series
//! ([`crate::fe::series`]): one series about the rest state to a split depth, then a
//! second about the state there (ANM continuation); `û` is the series' first order
//! (the linear field), so `r_v(d) = Σ_{p≥2} d^p u_p` summed through the Padé forms.
//! Each vertex costs a linear solve per order with the rest stiffness (factored once
//! for all) plus one factorization of the tangent at its split.
//!
//! On-line, a probe inside a palpable triangle blends its corners' residuals with its
//! barycentric weights, linearly in `d` between grid depths:
//! `r(x; s, d) ≈ Σ_k λ_k(s) r_{v_k}(x; d)`. The blend is exact at the vertices and
//! errs between them by the change of the residual's shape over one edge, the same
//! floor as a P1 interpolation of the linear field (where the linear vademecum is exact
//! by its nodal loads instead). Only the surface vertices' rows are kept, in f32.

use std::time::Instant;

use crate::fe::hyper::Law;
use crate::fe::load::{probe_functional, probe_load};
use crate::fe::probe::{ProbeRequest, locate, organ_space};
use crate::fe::series::{Expander, continued_from};
use crate::fe::{Element, FeError, Material};
use crate::organ::OrganMesh;

/// How the surface law is built.
#[derive(Debug, Clone, Copy, PartialEq)]
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
        }
    }
}

/// The built residuals.
#[derive(Debug, Clone)]
pub struct SurfaceLaw {
    pub options: SurfaceLawOptions,
    /// The surface vertices whose rows are kept (organ mesh vertex ids).
    pub rows: Vec<u32>,
    /// Per organ mesh vertex: its sample index, or `u32::MAX` (not sampled).
    sample_of: Vec<u32>,
    /// Sampled vertices (organ mesh ids), and those skipped (the tool did not move
    /// its centre: next to the fixed region).
    pub samples: Vec<u32>,
    pub skipped: Vec<u32>,
    steps: usize,
    /// `residual[((sample · steps) + j) · 3·rows + 3·row + c]`, mm.
    residual: Vec<f32>,
    pub build_s: f64,
}

impl SurfaceLaw {
    /// Samples every palpable vertex of `organ`; `progress(done, total)`.
    pub fn build(
        organ: &OrganMesh,
        options: SurfaceLawOptions,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<SurfaceLaw, FeError> {
        let o = options;
        let steps = (o.depth_max_mm / o.depth_step_mm).round() as usize + 1;
        if !(o.depth_max_mm > 0.0 && o.depth_step_mm > 0.0 && (2..=256).contains(&steps)) {
            return Err(FeError::DepthNotFinite {
                depth_mm: o.depth_max_mm,
            });
        }
        let t0 = Instant::now();
        let space = organ_space(organ, o.element);
        let expander = Expander::new(&space, o.law, o.material)?;
        let rows = organ.surface_nodes();
        let mut candidates: Vec<u32> = organ
            .boundary
            .iter()
            .zip(&organ.palpable)
            .filter(|(_, p)| **p)
            .flat_map(|(t, _)| t.iter().copied())
            .filter(|&v| !organ.fixed[v as usize])
            .collect();
        candidates.sort_unstable();
        candidates.dedup();
        let mut sample_of = vec![u32::MAX; organ.mesh.vertices.len()];
        let mut samples = Vec::new();
        let mut skipped = Vec::new();
        let mut residual = Vec::new();
        let split = o.split_fraction * o.depth_max_mm;
        for (k, &v) in candidates.iter().enumerate() {
            progress(k, candidates.len());
            let req = ProbeRequest {
                at: organ.mesh.vertices[v as usize],
                force_n: 1.0,
                dir: None,
                radius_mm: o.tool_radius_mm,
            };
            let (probe, dir) = locate(&space, organ, &req)?;
            let shape = probe_load(&space, &probe, dir, 1.0, o.tool_radius_mm)?;
            let functional = probe_functional(&space, &probe, dir);
            let first = match expander.expand(&shape, &functional, o.orders) {
                Ok(s) => s,
                Err(FeError::ProbeNotMoved) => {
                    skipped.push(v);
                    continue;
                }
                Err(e) => return Err(e),
            };
            let press = match continued_from(
                &space,
                o.law,
                o.material,
                &shape,
                &functional,
                first,
                split,
                o.orders,
            ) {
                Ok(c) => c,
                Err(FeError::ProbeNotMoved | FeError::NotPositiveDefinite { .. }) => {
                    skipped.push(v);
                    continue;
                }
                Err(e) => return Err(e),
            };
            let unit = &press.first.u[0];
            sample_of[v as usize] = samples.len() as u32;
            samples.push(v);
            for j in 0..steps {
                let d = j as f64 * o.depth_step_mm;
                let (_, u) = if j == 0 {
                    (0.0, vec![0.0; unit.len()])
                } else {
                    press.evaluate(d, o.depth_max_mm)
                };
                for &r in &rows {
                    for c in 0..3 {
                        let i = 3 * r as usize + c;
                        residual.push((u[i] - d * unit[i]) as f32);
                    }
                }
            }
        }
        progress(candidates.len(), candidates.len());
        Ok(SurfaceLaw {
            options,
            rows,
            sample_of,
            samples,
            skipped,
            steps,
            residual,
            build_s: t0.elapsed().as_secs_f64(),
        })
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
            steps: 3,
            residual,
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
}
