//! Seeded held-out points over the whole palpable surface, the band next to the fixed
//! region or a file's split triangles: the points a check presses at (and `palpa lab
//! tissue points` prints).

use anyhow::{Context, bail};
use palpa_core::organ::OrganMesh;
use palpa_core::rng::Rng;
use palpa_core::tissue::law::{PointIndex, TissueLaw};

/// The points a check presses at: `at` (X,Y,Z triples) where given, else `heldout`
/// seeded random points inside organ triangles whose three corners were pressed
/// (never a sample itself).
pub(crate) fn press_points(
    organ: &OrganMesh,
    law: &TissueLaw,
    at: Option<&[f64]>,
    heldout: usize,
    seed: u64,
) -> anyhow::Result<Vec<[f64; 3]>> {
    if let Some(v) = at {
        return triples("--at", v);
    }
    let pressed = PointIndex::new(law.samples_mm.iter().map(|p| p.map(f64::from)));
    let faces: Vec<usize> = (0..organ.boundary.len())
        .filter(|&f| {
            organ.palpable[f]
                && organ.boundary[f]
                    .iter()
                    .all(|&v| pressed.find(organ.mesh.vertices[v as usize]).is_some())
        })
        .collect();
    if faces.is_empty() {
        bail!("no palpable triangle of this organ has all three corners pressed in the file");
    }
    points_in(organ, &faces, heldout, seed)
}

/// `n` seeded random points in `faces`: a face drawn uniformly, then a point uniformly
/// inside it.
pub(crate) fn points_in(
    organ: &OrganMesh,
    faces: &[usize],
    n: usize,
    seed: u64,
) -> anyhow::Result<Vec<[f64; 3]>> {
    check_heldout(n)?;
    let mut rng = Rng::seed(seed);
    Ok((0..n)
        .map(|_| heldout_point(organ, faces, &mut rng).0)
        .collect())
}

/// The most held-out points a command draws. Each is checked with a full FE solve
/// (seconds to minutes), so more is no run anyone waits for; 10⁹ points would need
/// 24 GB for the points alone (`lab tissue points` was still drawing them after 30 s).
pub(super) const MAX_HELDOUT: usize = 10_000;

/// Refuses more held-out points than [`MAX_HELDOUT`].
pub(crate) fn check_heldout(n: usize) -> anyhow::Result<()> {
    if n > MAX_HELDOUT {
        bail!("{n} held-out points: expected at most {MAX_HELDOUT} (each is a full FE solve)");
    }
    Ok(())
}

/// A flag's `X,Y,Z[,X,Y,Z…]` list as points, or what was wrong with it.
pub(crate) fn triples(flag: &str, v: &[f64]) -> anyhow::Result<Vec<[f64; 3]>> {
    use crate::cli::args::{COORDINATE_MAX, coordinate_ok};
    if v.is_empty() || !v.len().is_multiple_of(3) || !v.iter().all(|&x| coordinate_ok(x)) {
        bail!(
            "{flag}: expected X,Y,Z triples of finite numbers of magnitude at most \
             {COORDINATE_MAX:e}, got {v:?}"
        );
    }
    Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// `n` seeded random points over the whole palpable surface: a triangle drawn
/// uniformly among the palpable ones with no fixed corner (those a whole build
/// presses), then a point uniformly inside it.
pub(crate) fn surface_points(
    organ: &OrganMesh,
    n: usize,
    seed: u64,
) -> anyhow::Result<Vec<[f64; 3]>> {
    let faces: Vec<usize> = (0..organ.boundary.len())
        .filter(|&f| organ.palpable[f] && !touches_fixed(organ, f))
        .collect();
    if faces.is_empty() {
        bail!("this organ has no palpable triangle clear of its fixed region");
    }
    points_in(organ, &faces, n, seed)
}

/// The palpable boundary faces with at least one fixed corner: the band along the
/// fixed region, where a probe's blend has a corner that was never pressed.
pub(crate) fn faces_next_to_fixed(organ: &OrganMesh) -> Vec<usize> {
    (0..organ.boundary.len())
        .filter(|&f| organ.palpable[f] && touches_fixed(organ, f))
        .collect()
}

/// Whether boundary face `f` has a corner on the fixed region.
pub(crate) fn touches_fixed(organ: &OrganMesh, f: usize) -> bool {
    organ.boundary[f].iter().any(|&v| organ.fixed[v as usize])
}

/// The total area of some boundary faces (mm²).
pub(crate) fn faces_area(organ: &OrganMesh, faces: &[usize]) -> f64 {
    let v = |i: u32| glam::DVec3::from_array(organ.mesh.vertices[i as usize]);
    faces
        .iter()
        .map(|&f| {
            let [a, b, c] = organ.boundary[f];
            0.5 * (v(b) - v(a)).cross(v(c) - v(a)).length()
        })
        .sum()
}

/// The organ's boundary faces that a tissue file split (by its corners' rest
/// positions), or why there are none.
pub(crate) fn split_faces(organ: &OrganMesh, law: &TissueLaw) -> anyhow::Result<Vec<usize>> {
    let index = PointIndex::new(organ.mesh.vertices.iter().copied());
    let mut split: Vec<[u32; 3]> = Vec::new();
    for tri in &law.refinement.triangles {
        let mut corners = [0u32; 3];
        for (c, &s) in corners.iter_mut().zip(tri) {
            let at = law.samples_mm[s as usize].map(f64::from);
            *c = index
                .find(at)
                .with_context(|| format!("sample at {at:?} is not a vertex of this organ mesh"))?;
        }
        corners.sort_unstable();
        split.push(corners);
    }
    split.sort_unstable();
    let faces: Vec<usize> = (0..organ.boundary.len())
        .filter(|&f| {
            let mut c = organ.boundary[f];
            c.sort_unstable();
            split.binary_search(&c).is_ok()
        })
        .collect();
    if faces.is_empty() {
        bail!("the tissue file splits no triangle of this organ mesh");
    }
    Ok(faces)
}

/// A random point of a random palpable triangle (one of `faces`): the point, the
/// triangle's vertices and the barycentric weights.
pub(crate) fn heldout_point(
    coarse: &OrganMesh,
    faces: &[usize],
    rng: &mut Rng,
) -> ([f64; 3], [u32; 3], [f64; 3]) {
    let tri = coarse.boundary[faces[rng.below(faces.len())]];
    let (a, b) = (rng.uniform(), rng.uniform());
    let (a, b) = if a + b > 1.0 {
        (1.0 - a, 1.0 - b)
    } else {
        (a, b)
    };
    let bary = [1.0 - a - b, a, b];
    let p = [0, 1, 2].map(|k| {
        (0..3)
            .map(|i| bary[i] * coarse.mesh.vertices[tri[i] as usize][k])
            .sum::<f64>()
    });
    (p, tri, bary)
}
