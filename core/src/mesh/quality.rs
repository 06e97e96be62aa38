//! Element quality: dihedral angles and radius ratios.

use serde::Serialize;

use super::{TetMesh, cross, dot, norm, sub};

/// Quality summary of a mesh.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Quality {
    pub min_dihedral_deg: f64,
    pub max_dihedral_deg: f64,
    /// Counts of radius ratios in [0, 0.1), [0.1, 0.2), …, [0.9, 1.0].
    pub radius_ratio_histogram: [usize; 10],
    pub min_radius_ratio: f64,
    /// Tetrahedra with non-positive volume (must be 0).
    pub inverted: usize,
}

/// The six dihedral angles of a tetrahedron, in degrees.
pub fn dihedral_angles_deg(p: [[f64; 3]; 4]) -> [f64; 6] {
    // Face normals, outward: face i is opposite vertex i.
    let n = |a: usize, b: usize, c: usize, opp: usize| {
        let mut v = cross(sub(p[b], p[a]), sub(p[c], p[a]));
        if dot(v, sub(p[opp], p[a])) > 0.0 {
            v = [-v[0], -v[1], -v[2]];
        }
        let l = norm(v);
        [v[0] / l, v[1] / l, v[2] / l]
    };
    let normals = [n(1, 2, 3, 0), n(0, 2, 3, 1), n(0, 1, 3, 2), n(0, 1, 2, 3)];
    // The edge (i, j) is shared by the faces opposite the two other vertices k, l;
    // the interior dihedral angle is π minus the angle between their outward normals.
    let pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
    pairs.map(|(i, j)| {
        let others: Vec<usize> = (0..4).filter(|&v| v != i && v != j).collect();
        let c = dot(normals[others[0]], normals[others[1]]).clamp(-1.0, 1.0);
        180.0 - c.acos().to_degrees()
    })
}

/// Radius ratio `3 r_in / R_circ` of a tetrahedron (1 when regular).
pub fn radius_ratio(p: [[f64; 3]; 4]) -> f64 {
    let vol = super::signed_volume(p[0], p[1], p[2], p[3]).abs();
    let area = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| 0.5 * norm(cross(sub(b, a), sub(c, a)));
    let s = area(p[1], p[2], p[3])
        + area(p[0], p[2], p[3])
        + area(p[0], p[1], p[3])
        + area(p[0], p[1], p[2]);
    let r_in = 3.0 * vol / s;
    // Circumradius: |a|²(b×c) + |b|²(c×a) + |c|²(a×b) over 12·V, edges from p0.
    let a = sub(p[1], p[0]);
    let b = sub(p[2], p[0]);
    let c = sub(p[3], p[0]);
    let num = [0, 1, 2].map(|d| {
        dot(a, a) * cross(b, c)[d] + dot(b, b) * cross(c, a)[d] + dot(c, c) * cross(a, b)[d]
    });
    let r_circ = norm(num) / (12.0 * vol);
    if vol == 0.0 { 0.0 } else { 3.0 * r_in / r_circ }
}

/// Quality summary over all tetrahedra.
pub fn quality(mesh: &TetMesh) -> Quality {
    let mut q = Quality {
        min_dihedral_deg: 180.0,
        max_dihedral_deg: 0.0,
        radius_ratio_histogram: [0; 10],
        min_radius_ratio: 1.0,
        inverted: 0,
    };
    for t in 0..mesh.tets.len() {
        let p = mesh.tet_points(t);
        if super::signed_volume(p[0], p[1], p[2], p[3]) <= 0.0 {
            q.inverted += 1;
            continue;
        }
        for a in dihedral_angles_deg(p) {
            q.min_dihedral_deg = q.min_dihedral_deg.min(a);
            q.max_dihedral_deg = q.max_dihedral_deg.max(a);
        }
        let r = radius_ratio(p);
        q.min_radius_ratio = q.min_radius_ratio.min(r);
        q.radius_ratio_histogram[((r * 10.0) as usize).min(9)] += 1;
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_tetrahedron_has_70_53_degrees_and_ratio_one() {
        let s = 1.0 / 2f64.sqrt();
        let p = [
            [1.0, 0.0, -s],
            [-1.0, 0.0, -s],
            [0.0, 1.0, s],
            [0.0, -1.0, s],
        ];
        for a in dihedral_angles_deg(p) {
            assert!(
                (a - (1.0f64 / 3.0).acos().to_degrees()).abs() < 1e-10,
                "{a}"
            );
        }
        assert!((radius_ratio(p) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn corner_tetrahedron_has_right_angles() {
        let p = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut a = dihedral_angles_deg(p);
        a.sort_by(f64::total_cmp);
        assert!((a[5] - 90.0).abs() < 1e-10 && (a[3] - 90.0).abs() < 1e-10);
        assert!((a[0] - 54.735_610_317).abs() < 1e-6, "{a:?}");
    }
}
