//! A built tissue file with its band next to the fixed region pressed
//! ([`SurfaceLaw::press_band`](crate::tissue::surface::SurfaceLaw::press_band)): the
//! file's own samples kept as stored (their modes, weights and bound), only the band's
//! surpluses compressed, each alone. Each band surplus is measured against its pressed
//! end as the file stores it (decompressed), so at a band edge's midpoint the file
//! answers that midpoint's own press up to the new surplus's compression.

use crate::organ::OrganMesh;
use crate::tissue::law::{TissueError, TissueLaw};
use crate::tissue::surface::SurfaceLaw;

impl TissueLaw {
    /// This file with the band `law` pressed: `law` is this file's
    /// [`surface_law`](Self::surface_law) after
    /// [`SurfaceLaw::press_band`](crate::tissue::surface::SurfaceLaw::press_band).
    pub fn banded(&self, organ: &OrganMesh, law: &SurfaceLaw) -> Result<TissueLaw, TissueError> {
        let old = self.reach.len();
        let band = law.refinement.band.len();
        if !self.refinement.band.is_empty()
            || law.reach.len() != old + band
            || law.refinement.sub.points.len() != self.refinement.sub.points.len()
            || law.edges != self.edge_ends
        {
            return Err(TissueError::Refine {
                why: "the pressed law does not hold this file's samples and then its band's".into(),
            });
        }
        let in_file: Vec<Option<usize>> = (0..old + band).map(|s| (s < old).then_some(s)).collect();
        self.compress_after(organ, law, &in_file)
    }
}
