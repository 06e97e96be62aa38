//! Surface regions as data: a small language of selectors on (point, outward normal),
//! serializable so an organ description or a scene can carry them.

use serde::{Deserialize, Serialize};

use crate::mesh::{dot, norm, sub};

/// Selects boundary points by position and outward normal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Selector {
    Everything,
    Nothing,
    All(Vec<Selector>),
    Any(Vec<Selector>),
    Not(Box<Selector>),
    /// The outward normal is within `max_angle_deg` of `dir`.
    NormalWithin {
        dir: [f64; 3],
        max_angle_deg: f64,
    },
    /// Points with `(p − point)·normal ≥ 0`.
    HalfSpace {
        point: [f64; 3],
        normal: [f64; 3],
    },
    /// Points within `radius_mm` of the line through `point` along `dir`.
    NearLine {
        point: [f64; 3],
        dir: [f64; 3],
        radius_mm: f64,
    },
    /// Points within `radius_mm` of `center`.
    Ball {
        center: [f64; 3],
        radius_mm: f64,
    },
    /// Points within `radius_mm` of the polyline through `points` (segments between
    /// consecutive points).
    NearPolyline {
        points: Vec<[f64; 3]>,
        radius_mm: f64,
    },
    /// Points within `radius_mm` of one of `points` (painted triangles' centroids).
    NearPoints {
        points: Vec<[f64; 3]>,
        radius_mm: f64,
    },
}

impl Selector {
    /// The surface a surgeon can reach from the front: outward normal within 80° of
    /// anterior (+y) or within 70° of inferior (−z).
    pub fn anterior_inferior() -> Selector {
        Selector::Any(vec![
            Selector::NormalWithin {
                dir: [0.0, 1.0, 0.0],
                max_angle_deg: 80.0,
            },
            Selector::NormalWithin {
                dir: [0.0, 0.0, -1.0],
                max_angle_deg: 70.0,
            },
        ])
    }

    pub fn contains(&self, p: [f64; 3], n: [f64; 3]) -> bool {
        match self {
            Selector::Everything => true,
            Selector::Nothing => false,
            Selector::All(v) => v.iter().all(|s| s.contains(p, n)),
            Selector::Any(v) => v.iter().any(|s| s.contains(p, n)),
            Selector::Not(s) => !s.contains(p, n),
            Selector::NormalWithin { dir, max_angle_deg } => {
                dot(n, *dir) / (norm(n) * norm(*dir)) >= max_angle_deg.to_radians().cos()
            }
            Selector::HalfSpace { point, normal } => dot(sub(p, *point), *normal) >= 0.0,
            Selector::NearLine {
                point,
                dir,
                radius_mm,
            } => {
                let d = sub(p, *point);
                let u = dir.map(|c| c / norm(*dir));
                let t = dot(d, u);
                let perp = [d[0] - t * u[0], d[1] - t * u[1], d[2] - t * u[2]];
                norm(perp) <= *radius_mm
            }
            Selector::Ball { center, radius_mm } => norm(sub(p, *center)) <= *radius_mm,
            Selector::NearPolyline { points, radius_mm } => points
                .windows(2)
                .any(|w| segment_distance(p, w[0], w[1]) <= *radius_mm),
            Selector::NearPoints { points, radius_mm } => {
                let r2 = radius_mm * radius_mm;
                points.iter().any(|q| {
                    let d = sub(p, *q);
                    dot(d, d) <= r2
                })
            }
        }
    }
}

/// Distance from `p` to the segment `a`–`b`.
fn segment_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = sub(b, a);
    let l2 = dot(ab, ab);
    let t = if l2 > 0.0 {
        (dot(sub(p, a), ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    norm(sub(
        p,
        [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]],
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selectors_compose() {
        let anterior = Selector::NormalWithin {
            dir: [0.0, 1.0, 0.0],
            max_angle_deg: 45.0,
        };
        let upper = Selector::HalfSpace {
            point: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
        };
        let s = Selector::All(vec![anterior.clone(), Selector::Not(Box::new(upper))]);
        assert!(s.contains([0.0, 0.0, -1.0], [0.0, 1.0, 0.1]));
        assert!(!s.contains([0.0, 0.0, 1.0], [0.0, 1.0, 0.1]));
        assert!(!s.contains([0.0, 0.0, -1.0], [1.0, 0.2, 0.0]));
        let line = Selector::NearLine {
            point: [0.0; 3],
            dir: [0.0, 0.0, 2.0],
            radius_mm: 1.0,
        };
        assert!(line.contains([0.5, 0.5, 100.0], [1.0, 0.0, 0.0]));
        assert!(!line.contains([1.5, 0.0, 0.0], [1.0, 0.0, 0.0]));
    }
}
