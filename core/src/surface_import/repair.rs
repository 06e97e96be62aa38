//! Small repairs a user may ask for, each reported: closing small holes, keeping the
//! largest of several pieces.
//!
//! A hole is a loop of boundary edges (edges used by one triangle). A loop of at most
//! `max_edges` edges is closed by a fan from its centroid (one new vertex) whose
//! triangles traverse each boundary edge opposite to the triangle that has it, so the
//! orientation stays consistent. Exact for the planar, nearly convex holes segmentation
//! leaves (a cut at the image border, a vessel stump); a large or twisted hole is left
//! alone and validation names it.

use std::collections::HashMap;

use super::TriSurface;

/// What closing holes did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HoleReport {
    pub closed: usize,
    pub triangles_added: usize,
    pub vertices_added: usize,
    /// Edge counts of the loops left open (larger than the limit, or not simple).
    pub left_open: Vec<usize>,
}

/// Closes the holes of at most `max_edges` boundary edges.
pub fn close_holes(s: &mut TriSurface, max_edges: usize) -> HoleReport {
    let mut count: HashMap<(u32, u32), usize> = HashMap::new();
    for t in &s.triangles {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    // Directed boundary edges a → b, as the triangle that has them traverses them.
    let mut next: HashMap<u32, Vec<u32>> = HashMap::new();
    for t in &s.triangles {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            if count[&(a.min(b), a.max(b))] == 1 {
                next.entry(a).or_default().push(b);
            }
        }
    }
    let mut report = HoleReport::default();
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut done: std::collections::HashSet<u32> = Default::default();
    for start in starts {
        if done.contains(&start) {
            continue;
        }
        // Walk the loop; a vertex with two outgoing boundary edges makes it not simple.
        let mut lp = vec![start];
        let mut simple = true;
        let mut v = start;
        loop {
            done.insert(v);
            let outs = &next[&v];
            if outs.len() != 1 {
                simple = false;
            }
            v = outs[0];
            if v == start {
                break;
            }
            if done.contains(&v) || !next.contains_key(&v) || lp.len() > s.vertices.len() {
                simple = false;
                break;
            }
            lp.push(v);
        }
        if !simple || lp.len() > max_edges || lp.len() < 3 {
            report.left_open.push(lp.len());
            continue;
        }
        let edges: Vec<(u32, u32)> = (0..lp.len())
            .map(|i| (lp[i], lp[(i + 1) % lp.len()]))
            .collect();
        if lp.len() == 3 {
            s.triangles.push([lp[2], lp[1], lp[0]]);
            report.triangles_added += 1;
        } else {
            let c = (0..3).map(|d| {
                lp.iter().map(|&i| s.vertices[i as usize][d]).sum::<f64>() / lp.len() as f64
            });
            let c: Vec<f64> = c.collect();
            s.vertices.push([c[0], c[1], c[2]]);
            let ci = (s.vertices.len() - 1) as u32;
            for (a, b) in edges {
                s.triangles.push([b, a, ci]);
            }
            report.triangles_added += lp.len();
            report.vertices_added += 1;
        }
        report.closed += 1;
    }
    report
}

/// The triangles of each connected piece (triangles sharing a vertex are connected),
/// largest first.
pub fn components(s: &TriSurface) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..s.vertices.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for t in &s.triangles {
        for e in 1..3 {
            let (a, b) = (
                find(&mut parent, t[0] as usize),
                find(&mut parent, t[e] as usize),
            );
            parent[a] = b;
        }
    }
    let mut groups: HashMap<usize, Vec<usize>> = HashMap::new();
    for (i, t) in s.triangles.iter().enumerate() {
        groups
            .entry(find(&mut parent, t[0] as usize))
            .or_default()
            .push(i);
    }
    let mut out: Vec<Vec<usize>> = groups.into_values().collect();
    out.sort_by(|a, b| b.len().cmp(&a.len()).then(a[0].cmp(&b[0])));
    out
}

/// Keeps only the largest piece; returns the triangle counts of the pieces dropped.
pub fn keep_largest(s: &mut TriSurface) -> Vec<usize> {
    let comps = components(s);
    if comps.len() <= 1 {
        return Vec::new();
    }
    let dropped = comps[1..].iter().map(Vec::len).collect();
    let kept: Vec<[u32; 3]> = comps[0].iter().map(|&t| s.triangles[t]).collect();
    let (welded, _) = super::read::weld(&s.vertices, &kept);
    *s = welded;
    dropped
}

/// A piece apart from the largest is stray (dropped) below this share of the
/// largest's triangles; a larger one is a second body, which is refused.
pub const STRAY_SHARE: f64 = 0.1;

/// What [`drop_stray`] found apart from the largest piece: the triangle counts of the
/// stray pieces it dropped and of the large ones it left.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Apart {
    pub dropped: Vec<usize>,
    pub large: Vec<usize>,
}

/// Drops the small pieces that lie wholly apart from the largest (their bounding boxes
/// do not meet, and they hold under [`STRAY_SHARE`] of its triangles): stray islands a
/// segmentation leaves. Pieces that meet the largest (a duplicate sheet, a fold, a
/// vessel through it) stay, for the winding number to read; large pieces apart are
/// left and reported.
pub fn drop_stray(s: &mut TriSurface) -> Apart {
    let comps = components(s);
    let mut apart = Apart::default();
    if comps.len() <= 1 {
        return apart;
    }
    let bounds = |c: &[usize]| {
        let pts: Vec<[f64; 3]> = c
            .iter()
            .flat_map(|&t| s.triangles[t])
            .map(|v| s.vertices[v as usize])
            .collect();
        crate::mesh::bounds_of(&pts)
    };
    let (lo, hi) = bounds(&comps[0]);
    let mut kept: Vec<[u32; 3]> = Vec::new();
    for (k, c) in comps.iter().enumerate() {
        let (a, b) = bounds(c);
        let away = k > 0 && (0..3).any(|d| a[d] > hi[d] || b[d] < lo[d]);
        if away && (c.len() as f64) < STRAY_SHARE * comps[0].len() as f64 {
            apart.dropped.push(c.len());
            continue;
        }
        if away {
            apart.large.push(c.len());
        }
        kept.extend(c.iter().map(|&t| s.triangles[t]));
    }
    if !apart.dropped.is_empty() {
        let (welded, _) = super::read::weld(&s.vertices, &kept);
        *s = welded;
    }
    apart
}
