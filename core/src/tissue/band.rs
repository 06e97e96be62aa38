//! The band next to the fixed region: its edges pressed at their midpoints.
//!
//! A palpable triangle with a corner on the fixed region has that corner never pressed
//! (a press there would push a held node), so its blend renormalizes over the corners
//! it has and carries no press from the side of the attachment, where the tissue
//! stiffens fastest (docs/lab/tissue-measurements.md §11). This stage presses the
//! midpoint of every palpable edge from a pressed vertex to an unpressed one on the
//! fixed region, and stores each as its surplus over the pressed end
//! ([`BandEdge`]); the blend adds it with `4 λ_a λ_b` as it adds an edge's.
//!
//! It comes last: its samples follow every other stage's, and a law that holds a band
//! is not split further (split it first, then press the band).

use crate::organ::OrganMesh;
use crate::tissue::refine::BandEdge;
use crate::tissue::surface::{
    PressCount, PressPoint, SurfaceLaw, SurfaceLawBuildError, organ_vertex_normals,
};

/// What pressing the band did.
#[derive(Debug, Clone, PartialEq)]
pub struct BandReport {
    /// Band edges found (within the ball, where one was given).
    pub edges: usize,
    /// Of those, kept: their presses stand.
    pub kept: usize,
    /// Why each of the others was not kept.
    pub failed: Vec<String>,
    /// Presses taken from the log.
    pub resumed: usize,
}

/// The palpable edges with one end sampled and the other on the fixed region (or a
/// vertex skipped beside it), as (sampled end's sample, other end's vertex, edge index
/// among [`palpable_edges`]), in that edge order.
pub(crate) fn band_edges(
    organ: &OrganMesh,
    sample_of: &[u32],
    skipped: &[u32],
) -> Vec<(u32, u32, usize)> {
    let unpressable = |v: u32| organ.fixed[v as usize] || skipped.contains(&v);
    organ
        .palpable_edges()
        .into_iter()
        .enumerate()
        .filter_map(|(g, [a, b])| {
            let (sa, sb) = (sample_of[a as usize], sample_of[b as usize]);
            match (sa != u32::MAX, sb != u32::MAX) {
                (true, false) if unpressable(b) => Some((sa, b, g)),
                (false, true) if unpressable(a) => Some((sb, a, g)),
                _ => None,
            }
        })
        .collect()
}

/// The press log id of band edge `g` (its index among the palpable edges): after
/// every id a build or a split stage gives (vertices, edges, quarter and inner
/// points, the second level's points).
fn band_id(organ: &OrganMesh, edges: usize, g: usize) -> u32 {
    let (v, b) = (organ.mesh.vertices.len(), organ.boundary.len());
    (v + 3 * b + 2 * edges + 3 * b + 8 * edges + 64 * b + 64 + g) as u32
}

impl SurfaceLaw {
    /// Presses the band next to the fixed region (see the module docs): every band
    /// edge's midpoint (only those within `within`, centre and radius in mm, where
    /// given), along its ends' mean normal, in parallel and logged at `log` under a
    /// build's key; each press kept as its surplus over its pressed end. Refused where
    /// the law already holds a band.
    pub fn press_band(
        mut self,
        organ: &OrganMesh,
        within: Option<([f64; 3], f64)>,
        log: Option<&crate::tissue::presser::PressLog>,
        progress: &(dyn Fn(PressCount) + Sync),
    ) -> Result<(SurfaceLaw, BandReport), SurfaceLawBuildError> {
        if !self.refinement.band.is_empty() {
            return Err(SurfaceLawBuildError::BandLast {
                what: "a band pressed again",
            });
        }
        let all = organ.palpable_edges().len();
        let normals = organ_vertex_normals(organ);
        let at = |v: u32| organ.mesh.vertices[v as usize];
        let inside = |p: [f64; 3]| {
            within.is_none_or(|(c, r)| (0..3).map(|k| (p[k] - c[k]).powi(2)).sum::<f64>() <= r * r)
        };
        let edges: Vec<(u32, u32, usize)> = band_edges(organ, &self.sample_of, &self.skipped)
            .into_iter()
            .filter(|&(s, other, _)| {
                let (a, b) = (at(self.samples[s as usize]), at(other));
                inside([0, 1, 2].map(|c| 0.5 * (a[c] + b[c])))
            })
            .collect();
        let points: Vec<PressPoint> = edges
            .iter()
            .map(|&(s, other, g)| {
                let end = self.samples[s as usize];
                let (pa, pb) = (at(end), at(other));
                let (na, nb) = (normals[end as usize], normals[other as usize]);
                PressPoint {
                    at: [0, 1, 2].map(|c| 0.5 * (pa[c] + pb[c])),
                    push: [0, 1, 2].map(|c| -f64::from(na[c] + nb[c])),
                    id: band_id(organ, all, g),
                }
            })
            .collect();
        let bases: Vec<Vec<(usize, f64)>> = edges
            .iter()
            .map(|&(s, _, _)| vec![(s as usize, 1.0)])
            .collect();
        let (kept, resumed) = self.press_surpluses(organ, &points, &bases, log, progress)?;
        let mut failed = Vec::new();
        for (&(s, other, _), k) in edges.iter().zip(kept) {
            match k {
                Ok(()) => self.refinement.band.push(BandEdge {
                    end: s,
                    other_mm: at(other).map(|x| x as f32),
                }),
                Err(why) => failed.push(why),
            }
        }
        let report = BandReport {
            edges: edges.len(),
            kept: self.refinement.band.len(),
            failed,
            resumed,
        };
        Ok((self, report))
    }
}
