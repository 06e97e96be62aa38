//! Picking: the ray from a pointer hits the drawn (deformed) surface; the point of the
//! mechanical surface under the hit becomes the probe position `s` when it lies in the
//! palpable region.
//!
//! Ray–triangle tests are Möller–Trumbore over every triangle (a few thousand on the
//! shipped scenes: tens of microseconds, once per pointer event, never in the force loop).

use glam::{Vec2, Vec3};
use palpa_core::scene::{PalpationScene, ProbePoint};

use crate::camera::{OrbitCamera, Ray};

pub use crate::camera::{COORDINATE_MAX, coordinate_ok};

/// What a pointer position hits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pick {
    /// The palpable region, at this probe point.
    Palpable(ProbePoint),
    /// The organ, outside the palpable region (fixed or unreachable surface).
    Outside,
    /// Nothing.
    Miss,
}

/// What input handling needs from the scene: picking and sliding the probe.
pub trait Picker {
    fn pick(&self, pos_px: Vec2) -> Pick;
    /// Moves the probe by `screen_dir` (x right, y up, any length) times `step_mm` in the
    /// surface's tangent plane, then back onto the palpable surface.
    fn slide(&self, from: &ProbePoint, screen_dir: Vec2, step_mm: f32) -> Option<ProbePoint>;
}

/// The closest ray hit: triangle, barycentric coordinates and ray parameter.
pub fn intersect(
    ray: &Ray,
    vertices: &[[f32; 3]],
    triangles: &[[u32; 3]],
) -> Option<(u32, [f64; 3], f32)> {
    let mut best: Option<(u32, [f64; 3], f32)> = None;
    for (i, t) in triangles.iter().enumerate() {
        let [a, b, c] = t.map(|v| Vec3::from_array(vertices[v as usize]));
        let e1 = b - a;
        let e2 = c - a;
        let p = ray.dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            continue;
        }
        let inv = 1.0 / det;
        let s = ray.origin - a;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            continue;
        }
        let q = s.cross(e1);
        let v = ray.dir.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            continue;
        }
        let t_hit = e2.dot(q) * inv;
        if t_hit > 0.0 && best.is_none_or(|(_, _, tb)| t_hit < tb) {
            let (u, v) = (f64::from(u), f64::from(v));
            best = Some((i as u32, [1.0 - u - v, u, v], t_hit));
        }
    }
    best
}

/// Picks against a scene seen through a camera, on the current deformed positions.
#[derive(Debug)]
pub struct ScenePicker<'a> {
    pub scene: &'a PalpationScene,
    pub camera: &'a OrbitCamera,
    pub viewport_px: Vec2,
    /// The drawn surface's current vertex positions (rest + displacement), mm.
    pub drawn_mm: &'a [[f32; 3]],
}

impl Picker for ScenePicker<'_> {
    fn pick(&self, pos_px: Vec2) -> Pick {
        let ray = self.camera.ray(pos_px, self.viewport_px);
        let visual = self.scene.visual();
        match intersect(&ray, self.drawn_mm, &visual.triangles) {
            None => Pick::Miss,
            Some((vt, vbary, _)) => {
                let (t, bary) = visual.mechanical_point(self.scene.vertices_mm(), vt, vbary);
                match self.scene.palpable_point(t, bary) {
                    Some(p) => Pick::Palpable(p),
                    None => Pick::Outside,
                }
            }
        }
    }

    fn slide(&self, from: &ProbePoint, screen_dir: Vec2, step_mm: f32) -> Option<ProbePoint> {
        let (x, n) = self.scene.frame(from);
        let n = Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32);
        let (right, up) = self.camera.screen_axes();
        let along = screen_dir.x * right + screen_dir.y * up;
        let tangent = along - along.dot(n) * n;
        let target = Vec3::new(x[0] as f32, x[1] as f32, x[2] as f32) + tangent * step_mm;
        self.scene
            .closest_palpable(target.as_dvec3().to_array())
            .map(|(p, _)| p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_hits_the_nearest_triangle_with_its_barycentrics() {
        // Two parallel triangles facing +z at z = 0 and z = 5; a ray from above.
        let v = [
            [0.0, 0.0, 0.0],
            [10.0, 0.0, 0.0],
            [0.0, 10.0, 0.0],
            [0.0, 0.0, 5.0],
            [10.0, 0.0, 5.0],
            [0.0, 10.0, 5.0],
        ];
        let t = [[0, 1, 2], [3, 4, 5]];
        let ray = Ray {
            origin: Vec3::new(2.0, 3.0, 20.0),
            dir: Vec3::NEG_Z,
        };
        let (tri, bary, dist) = intersect(&ray, &v, &t).expect("hit");
        assert_eq!(tri, 1);
        assert!((dist - 15.0).abs() < 1e-5);
        for (got, want) in bary.iter().zip([0.5, 0.2, 0.3]) {
            assert!((got - want).abs() < 1e-6, "{bary:?}");
        }
        let away = Ray {
            origin: Vec3::new(20.0, 20.0, 20.0),
            dir: Vec3::NEG_Z,
        };
        assert!(intersect(&away, &v, &t).is_none());
    }
}
