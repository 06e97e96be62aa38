//! Refining a built tissue file in place: its triangles split without pressing its
//! vertices and edges again.
//!
//! A whole-surface build presses every palpable vertex and edge midpoint (2 147 presses
//! on coarse P2) before it can decide which triangles to split; a file built without
//! splitting (`--no-refine`) already holds those presses, compressed. Refining it reads
//! them back ([`TissueLaw::surface_law`]: each sample's residual at every grid depth as
//! the file stores it, within its bound), splits the triangles whose largest edge
//! surplus exceeds the threshold (all of them, or the worst few: see
//! [`SurfaceLaw::refine`]), presses their quarter and inner points and keeps each as
//! its surplus over the blend the file answers with,
//!
//! ```text
//! q = r(point) − Σ_b w_b r̃_b,     r̃_b the stored (decompressed) corner or edge sample,
//! ```
//!
//! so at a split point the refined blend is the point's own press up to the new
//! surplus's compression. The file's own samples are copied unchanged (their modes,
//! weights and bound); only the new surpluses are compressed, with the file's tolerance
//! and bits ([`TissueLaw::refined`]). The result is what a whole build with the same
//! threshold would store, except that its split points' surpluses are measured against
//! the stored corners and edges rather than the computed ones (they differ by at most
//! the file's bound).
//!
//! A file already split goes on from its stage: refined to more triangles, it keeps
//! its split triangles and their points' stored modes as they are and presses only
//! the new triangles' points. A stage saved is thus a stage kept, and refining the
//! whole surface (about 6 000 presses on coarse P2, hours) can go on over several
//! runs without keeping the press log between them.

use crate::organ::OrganMesh;
use crate::tissue::law::{
    GroupModes, Grouping, PointIndex, QUANT_SHARES, SAME_POINT_MM, Shapes, TissueError, TissueLaw,
};
use crate::tissue::surface::SurfaceLaw;

impl TissueLaw {
    /// The surface law this file stores, read back on `organ` (the mesh it was built
    /// on): every sample's residual at every grid depth as evaluation sees it (within
    /// the file's bound of the computed one), its force ratio (in f32), reach and
    /// figures, and its split triangles (a refinement goes on from them; their figures
    /// are not stored, and [`SurfaceLaw::refine`] measures them again).
    pub fn surface_law(&self, organ: &OrganMesh) -> Result<SurfaceLaw, TissueError> {
        let refused = |why: String| TissueError::Refine { why };
        let rows = organ.surface_nodes();
        let same = |v: u32, p: [f32; 3]| {
            let q = organ.mesh.vertices[v as usize];
            (0..3)
                .map(|k| (q[k] - f64::from(p[k])).powi(2))
                .sum::<f64>()
                <= SAME_POINT_MM * SAME_POINT_MM
        };
        let rows_match = rows.len() == self.rows_mm.len()
            && rows.iter().zip(&self.rows_mm).all(|(&v, &p)| same(v, p));
        let index = PointIndex::new(organ.mesh.vertices.iter().copied());
        let find = |p: &[f32; 3]| index.find(p.map(f64::from));
        let samples: Option<Vec<u32>> = self.samples_mm.iter().map(find).collect();
        let skipped: Option<Vec<u32>> = self.skipped_mm.iter().map(find).collect();
        let (Some(samples), Some(skipped), true) = (samples, skipped, rows_match) else {
            return Err(refused(
                "its rows or samples are not this organ mesh's vertices (expected the mesh \
                 it was built on: the same --organ, --level and --element)"
                    .into(),
            ));
        };
        let mut sample_of = vec![u32::MAX; organ.mesh.vertices.len()];
        for (s, &v) in samples.iter().enumerate() {
            sample_of[v as usize] = s as u32;
        }
        let steps = self.steps as usize;
        let m = 3 * self.rows_mm.len();
        let count = self.reach.len();
        let mut residual = vec![0.0f32; count * steps * m];
        let mut column = vec![0.0f64; m];
        for s in 0..count {
            let (modes, start) = self.sample_modes(s);
            for j in 0..steps {
                column.fill(0.0);
                for (k, mode) in modes.clone().enumerate() {
                    let w = f64::from(self.coeffs[start + k * steps + j])
                        * f64::from(self.shape_scale[mode]);
                    if w == 0.0 {
                        continue;
                    }
                    for (i, c) in column.iter_mut().enumerate() {
                        *c += w * self.shape.get(mode * m + i);
                    }
                }
                let out = &mut residual[(s * steps + j) * m..][..m];
                for (o, c) in out.iter_mut().zip(&column) {
                    *o = *c as f32;
                }
            }
        }
        Ok(SurfaceLaw {
            options: self.options,
            rows,
            sample_of,
            samples,
            skip_reasons: vec!["skipped by the build the file came from".into(); skipped.len()],
            skipped,
            edges: self.edge_ends.clone(),
            edge_skip_reasons: Vec::new(),
            refinement: self.refinement.clone(),
            refine_skip_reasons: Vec::new(),
            split_figures: Vec::new(),
            reach: self.reach.clone(),
            stopped: self.stopped.clone(),
            steps,
            residual,
            ratio: self.ratio.iter().map(|&g| f64::from(g)).collect(),
            stiffness_n_per_mm: self.stiffness_n_per_mm.iter().map(|&k| k.into()).collect(),
            correction_mm: self.correction_mm.iter().map(|&c| c.into()).collect(),
            segments: self.segments.clone(),
            build_s: self.build_s,
        })
    }

    /// This file with `law`'s split triangles added: `law` is this file's
    /// [`surface_law`](Self::surface_law) after [`SurfaceLaw::refine`]. Its samples
    /// that this file holds (every vertex and edge, and an earlier stage's split
    /// points, which the refinement lists first) keep their stored modes and weights
    /// unchanged; the new split points' surpluses are compressed with this file's
    /// tolerance and bits, those of a triangle sharing their modes
    /// ([`Grouping::SplitTriangle`]). The bound is the larger of this file's and the
    /// new surpluses'.
    pub fn refined(&self, organ: &OrganMesh, law: &SurfaceLaw) -> Result<TissueLaw, TissueError> {
        let mine = &self.refinement;
        let theirs = &law.refinement;
        if law.samples.len() != self.samples_mm.len()
            || law.edges != self.edge_ends
            || law.steps() != self.steps as usize
            || law.reach.len() < self.reach.len()
            || !theirs.triangles.starts_with(&mine.triangles)
            || !theirs.quarter_ends.starts_with(&mine.quarter_ends)
            || !theirs.inner_corners.starts_with(&mine.inner_corners)
        {
            return Err(TissueError::Refine {
                why: "the refined law does not start with this file's samples".into(),
            });
        }
        // Where each of the law's samples lies in this file: the vertices, edges and
        // quarter points at the same index, the inner points after this file's
        // quarter points (the law's new quarter points come before them).
        let first_quarter = law.samples.len() + law.edges.len();
        let (old_q, new_q) = (mine.quarter_ends.len(), theirs.quarter_ends.len());
        let in_file: Vec<Option<usize>> = (0..law.reach.len())
            .map(|s| {
                let i = s.checked_sub(first_quarter + new_q);
                match i {
                    None if s < first_quarter + old_q => Some(s),
                    None => None,
                    Some(i) => (i < mine.inner_corners.len()).then_some(first_quarter + old_q + i),
                }
            })
            .collect();
        self.compress_after(organ, law, &in_file)
    }

    /// `law` compressed with this file's tolerance and bits, a split triangle's (or
    /// sub-triangle's) new points sharing their modes; each of `law`'s samples that
    /// `in_file` places in this file keeps its stored modes where its group is whole
    /// there.
    pub(super) fn compress_after(
        &self,
        organ: &OrganMesh,
        law: &SurfaceLaw,
        in_file: &[Option<usize>],
    ) -> Result<TissueLaw, TissueError> {
        let mut out = Self::compress_onto(
            organ,
            law,
            self.tolerance_mm,
            self.shape.bits(),
            Grouping::SplitTriangle,
            &QUANT_SHARES,
            Some((self, in_file)),
        )?;
        out.build_s = law.build_s;
        Ok(out)
    }

    /// Whether `members` (this file's samples) are one of its groups, whole.
    pub(super) fn holds_group(&self, members: &[usize]) -> bool {
        let Some(&first) = members.first() else {
            return false;
        };
        let Some(&g) = self.group.get(first) else {
            return false;
        };
        members.iter().all(|&s| self.group.get(s) == Some(&g))
            && self.group.iter().filter(|&&h| h == g).count() == members.len()
    }

    /// The stored modes of `members`, one of this file's groups whole (what
    /// [`TissueLaw::compress_onto`] copies): shapes, scales, and each mode's weights
    /// (member after member, depths 1..). Its error is the file's bound.
    pub(super) fn group_modes_of(
        &self,
        members: &[usize],
        steps: usize,
    ) -> Result<GroupModes, TissueError> {
        let g = self.group[members[0]] as usize;
        let whole = self.group.iter().filter(|&&h| h as usize == g).count() == members.len()
            && members.iter().all(|&s| self.group[s] as usize == g);
        if !whole || steps != self.steps as usize {
            return Err(TissueError::Refine {
                why: format!("its group {g} is not one group of the refined law"),
            });
        }
        let m = 3 * self.rows_mm.len();
        let modes = self.mode_start[g] as usize..self.mode_start[g + 1] as usize;
        let mut shape = Shapes::new(self.shape.bits());
        for mode in modes.clone() {
            shape.push_copy(&self.shape, mode, m);
        }
        let weights = (0..modes.len())
            .map(|k| {
                members
                    .iter()
                    .flat_map(|&s| {
                        let start = self.coeff_start[s] as usize + k * steps;
                        self.coeffs[start + 1..start + steps].iter().copied()
                    })
                    .collect()
            })
            .collect();
        Ok(GroupModes {
            shape,
            scale: self.shape_scale[modes].to_vec(),
            weights,
            error: self.truncation_bound_mm,
        })
    }
}
