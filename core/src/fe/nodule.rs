//! A nodule: a sphere inside the organ whose Young's modulus is `ratio` times the
//! tissue's (the same Poisson's ratio), what palpation is for finding.
//!
//! **On the fixed mesh** the sphere is a field of stiffness factors, one per cell, from
//! `φ_c`, the fraction of the cell's volume inside the sphere. A cell the sphere's
//! boundary cuts holds a piece of stiff sphere in tissue; its modulus is the
//! Mori–Tanaka estimate of spherical inclusions in a matrix (the Hashin–Shtrikman bound
//! on the matrix's side), on the shear modulus, both Lamé parameters scaled alike:
//! `s = 1 + φ / (1/(β − 1) + (1 − φ) · 6(k + 2)/(5(3k + 4)))`, `k = K/G` of the tissue.
//! It is `β` at `φ = 1`, exactly 1 at `β = 1`, and stays bounded as `β` grows: a cut
//! cell is as stiff as a rigid sphere in it makes it. The two simple mixes were
//! measured and set aside (docs/methods.md §2f): the arithmetic (Voigt) one makes a
//! cell a tenth inside a 1000-times-stiffer sphere a hundred times stiffer, so on the
//! coarse mesh a 10 mm sphere's effect grew without end with the ratio (+62 % at 1000),
//! and the harmonic (Reuss) one left the coarse mesh 16–43 % below the medium one.
//! `φ_c` is measured at 128 points spread evenly over the cell (a low-discrepancy
//! sequence), each counted by a ramp one point spacing wide across the sphere's surface,
//! so `φ`, and
//! with it every response, moves continuously with the nodule's centre and radius (a
//! stepped count would make the vademecum's nodule coordinates jump). A cell whose four
//! corners lie inside is wholly inside (`φ = 1`); one farther from the centre than the
//! radius plus its own size is wholly outside.
//!
//! **Refused**, naming what was expected: a centre outside the organ, a nodule closer
//! than [`MIN_DEPTH_MM`] to the organ's surface (naming the fixed region or the
//! palpable surface where that is what it approaches), a radius below what the level's
//! mesh resolves ([`min_radius_mm`]), a ratio that is not a positive stiffness.

use super::FeError;
use super::space::Space;
use crate::organ::OrganMesh;

/// How close a nodule's surface may come to the organ's surface (mm).
pub const MIN_DEPTH_MM: f64 = 2.0;

/// The stiffness ratios accepted (softer inclusions included; beyond 10³ the
/// stiffness' conditioning, not the tissue, sets the answer).
pub const RATIO_RANGE: std::ops::RangeInclusive<f64> = 0.01..=1000.0;

/// The smallest radius a mesh of spacing `h_mm` resolves, as a multiple of it: see
/// [`min_radius_mm`].
pub const MIN_RADIUS_PER_H: f64 = 2.0 / 3.0;

/// The smallest radius resolved on a mesh of spacing `h_mm`: two thirds of a cell (8 mm
/// on the coarse mesh, 4.7 on the medium). Measured by `palpa lab bench nodule`
/// (docs/methods.md §2f): a 4.4-times-stiffer sphere 22 mm under the probe changes the
/// force of a 5 mm press by 3.1 % at 8 mm on the coarse mesh, 15 % below the medium
/// mesh's 3.6 %, and by 16 %, 7 % less at 10 and 12 mm; below 8 mm the coarse mesh falls
/// 20–24 % short of an effect that is itself under 1.5 % (a hand feels 7 %).
pub fn min_radius_mm(h_mm: f64) -> f64 {
    MIN_RADIUS_PER_H * h_mm
}

/// A stiff (or soft) sphere in the organ.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Nodule {
    pub center_mm: [f64; 3],
    pub radius_mm: f64,
    /// Its Young's modulus over the tissue's.
    pub ratio: f64,
}

/// Points per cell that measure its volume inside the sphere.
const SAMPLES: usize = 128;

/// [`SAMPLES`] points spread evenly over a tetrahedron, as barycentric coordinates: the
/// R₃ low-discrepancy sequence in the unit cube (Roberts 2018), each point's three
/// coordinates sorted, which maps the cube's uniform law onto the simplex's.
fn simplex_points() -> Vec<[f64; 4]> {
    // The plastic number's cube analogue: x³ = x + 1.
    let g = 1.220_744_084_605_759_5_f64;
    let a = [1.0 / g, 1.0 / (g * g), 1.0 / (g * g * g)];
    (1..=SAMPLES)
        .map(|n| {
            let mut x = a.map(|ai| (0.5 + ai * n as f64).fract());
            x.sort_by(f64::total_cmp);
            [x[0], x[1] - x[0], x[2] - x[1], 1.0 - x[2]]
        })
        .collect()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Whether `p` lies in the tetrahedron `t` (barycentric coordinates ≥ −1e-12).
fn in_tet(p: [f64; 3], t: [[f64; 3]; 4]) -> bool {
    let det3 = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
        a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0])
    };
    let (e1, e2, e3) = (sub(t[1], t[0]), sub(t[2], t[0]), sub(t[3], t[0]));
    let d = det3(e1, e2, e3);
    if d == 0.0 {
        return false;
    }
    let q = sub(p, t[0]);
    let l1 = det3(q, e2, e3) / d;
    let l2 = det3(e1, q, e3) / d;
    let l3 = det3(e1, e2, q) / d;
    let tol = -1e-12;
    l1 >= tol && l2 >= tol && l3 >= tol && 1.0 - l1 - l2 - l3 >= tol
}

/// Whether `p` lies in one of the organ's tetrahedra.
pub fn inside(organ: &OrganMesh, p: [f64; 3]) -> bool {
    let v = &organ.mesh.vertices;
    organ
        .mesh
        .tets
        .iter()
        .any(|t| in_tet(p, t.map(|i| v[i as usize])))
}

impl Nodule {
    /// Checks the nodule against the organ: a positive ratio, a radius the mesh
    /// resolves, the centre inside, the sphere at least [`MIN_DEPTH_MM`] below the
    /// surface.
    pub fn check(&self, organ: &OrganMesh) -> Result<(), FeError> {
        let c = self.center_mm;
        if !(self.ratio.is_finite() && RATIO_RANGE.contains(&self.ratio)) {
            return Err(FeError::NoduleRatio { ratio: self.ratio });
        }
        if c.iter().any(|v| !v.is_finite()) || !self.radius_mm.is_finite() {
            return Err(FeError::NoduleNotFinite {
                center_mm: c,
                radius_mm: self.radius_mm,
            });
        }
        let min = min_radius_mm(organ.h_mm);
        if self.radius_mm < min {
            return Err(FeError::NoduleTooSmall {
                radius_mm: self.radius_mm,
                min_mm: min,
                h_mm: organ.h_mm,
            });
        }
        if !inside(organ, c) {
            return Err(FeError::NoduleOutside { center_mm: c });
        }
        let hit = crate::axis::closest_point(&organ.mesh.vertices, &organ.boundary, c)
            .ok_or(FeError::NoduleOutside { center_mm: c })?;
        let depth_mm = hit.distance - self.radius_mm;
        if depth_mm < MIN_DEPTH_MM {
            let tri = organ.boundary[hit.triangle as usize];
            let region = if tri.iter().any(|&i| organ.fixed[i as usize]) {
                "the fixed region"
            } else if organ.palpable.get(hit.triangle as usize) == Some(&true) {
                "the palpable surface"
            } else {
                "the organ's surface"
            };
            return Err(FeError::NoduleTooShallow {
                depth_mm,
                region,
                at_mm: hit.point,
            });
        }
        Ok(())
    }

    /// The fraction of each cell's volume inside the sphere (see the module doc).
    pub fn cell_fractions(&self, space: &Space) -> Vec<f64> {
        self.fractions((0..space.cell_count()).map(|c| space.cell_corners(c)))
    }

    /// [`Nodule::cell_fractions`] of tetrahedra given by their corners (mm).
    pub fn fractions(&self, cells: impl Iterator<Item = [[f64; 3]; 4]>) -> Vec<f64> {
        let points = simplex_points();
        cells
            .map(|t| {
                let dist = |p: [f64; 3]| norm(sub(p, self.center_mm));
                let size = (1..4).map(|i| norm(sub(t[i], t[0]))).fold(0.0, f64::max);
                if t.iter().all(|&p| dist(p) <= self.radius_mm) {
                    return 1.0;
                }
                if dist(t[0]) > self.radius_mm + size {
                    return 0.0;
                }
                // Each point stands for 1/N of the volume: a ramp about as wide as the
                // spacing between points.
                // A ramp of width w about radius ρ holds the volume of a sphere of
                // `ρ³ + ρ w²/4` (to second order): centred at `ρ = R − w²/(12 R)` it holds
                // the sphere's own.
                let ramp = size / (SAMPLES as f64).cbrt();
                let r = self.radius_mm;
                let rho = r - ramp * ramp / (12.0 * r);
                points
                    .iter()
                    .map(|l| {
                        let p = [0, 1, 2].map(|d| (0..4).map(|a| l[a] * t[a][d]).sum());
                        ((rho - dist(p)) / ramp + 0.5).clamp(0.0, 1.0)
                    })
                    .sum::<f64>()
                    / SAMPLES as f64
            })
            .collect()
    }

    /// The stiffness factor of a cell a fraction `phi` of which the nodule fills, for
    /// a tissue of Poisson's ratio `poisson`: the Mori–Tanaka estimate (see the module
    /// doc); 1 outside the nodule, the ratio inside it.
    pub fn factor(&self, phi: f64, poisson: f64) -> f64 {
        let beta = self.ratio;
        // K/G of the tissue, and the matrix's term of the estimate.
        let k = 2.0 * (1.0 + poisson) / (3.0 * (1.0 - 2.0 * poisson));
        let m = 6.0 * (k + 2.0) / (5.0 * (3.0 * k + 4.0));
        1.0 + phi / (1.0 / (beta - 1.0) + (1.0 - phi) * m)
    }

    /// Each cell's stiffness factor for a tissue of Poisson's ratio `poisson`
    /// ([`Nodule::factor`]).
    pub fn stiffness(&self, space: &Space, poisson: f64) -> Vec<f64> {
        self.cell_fractions(space)
            .into_iter()
            .map(|phi| self.factor(phi, poisson))
            .collect()
    }
}

impl Space {
    /// The space with `nodule`'s stiffness on its cells for a tissue of Poisson's
    /// ratio `poisson` (see [`Nodule`]); check the nodule with [`Nodule::check`] first.
    pub fn with_nodule(mut self, nodule: &Nodule, poisson: f64) -> Space {
        self.stiffness = Some(nodule.stiffness(&self, poisson));
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::Element;
    use crate::mesh::TetMesh;

    /// A cube of side 20 mm cut into 6 tetrahedra per 10 mm block (8 blocks).
    fn cube() -> Space {
        let n = 3;
        let mut vertices = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    vertices.push([10.0 * i as f64, 10.0 * j as f64, 10.0 * k as f64]);
                }
            }
        }
        let id = |i: usize, j: usize, k: usize| (i + n * (j + n * k)) as u32;
        let mut tets = Vec::new();
        for k in 0..n - 1 {
            for j in 0..n - 1 {
                for i in 0..n - 1 {
                    let c = [0, 1, 2, 3, 4, 5, 6, 7]
                        .map(|b: usize| id(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1)));
                    // Kuhn's six tetrahedra around the diagonal 0–7.
                    for (a, b) in [(1, 3), (3, 2), (2, 6), (6, 4), (4, 5), (5, 1)] {
                        tets.push([c[0], c[a], c[b], c[7]]);
                    }
                }
            }
        }
        let mesh = TetMesh { vertices, tets };
        let fixed = vec![false; mesh.vertices.len()];
        Space::new(&mesh, &[], &fixed, Element::P1)
    }

    #[test]
    fn the_volume_inside_is_the_sphere_s_and_moves_continuously() {
        let space = cube();
        let volume = |c: usize| {
            let t = space.cell_corners(c);
            let (a, b, d) = (sub(t[1], t[0]), sub(t[2], t[0]), sub(t[3], t[0]));
            (a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0])
                + a[2] * (b[0] * d[1] - b[1] * d[0]))
                .abs()
                / 6.0
        };
        let inside = |n: &Nodule| -> f64 {
            n.cell_fractions(&space)
                .iter()
                .enumerate()
                .map(|(c, phi)| phi * volume(c))
                .sum()
        };
        // A 6 mm sphere in the middle: 905 mm³, measured 910 (0.6 %).
        let n = Nodule {
            center_mm: [10.0, 10.0, 10.0],
            radius_mm: 6.0,
            ratio: 4.0,
        };
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 216.0;
        let got = inside(&n);
        println!("inside {got:.1} mm³ of {exact:.1}");
        assert!((got / exact - 1.0).abs() < 0.02, "{got} vs {exact}");
        // Moving the centre by 0.01 mm moves the volume by little: no jumps.
        let mut last = got;
        for s in 1..=50 {
            let m = Nodule {
                center_mm: [10.0 + 0.01 * s as f64, 10.0, 10.0],
                ..n
            };
            let v = inside(&m);
            assert!((v - last).abs() < 0.01 * exact, "step {s}: {last} → {v}");
            last = v;
        }
        // Ratio 1: every factor exactly 1.
        let one = Nodule { ratio: 1.0, ..n };
        assert!(one.stiffness(&space, 0.48).iter().all(|&s| s == 1.0));
        // A cell wholly inside is the nodule's material; partly inside, between.
        let (phi, s) = (n.cell_fractions(&space), n.stiffness(&space, 0.48));
        for (p, s) in phi.iter().zip(&s) {
            match *p {
                1.0 => assert!((s - 4.0).abs() < 1e-12, "{s}"),
                0.0 => assert_eq!(*s, 1.0),
                _ => assert!(1.0 < *s && *s < 4.0, "{p}: {s}"),
            }
        }
    }
}
