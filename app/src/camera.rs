//! The orbit camera: a target point, yaw and pitch around it (z is up, the liver's
//! superior direction), and a distance. Right-handed view, wgpu's 0..1 depth range.
//!
//! The view can be fitted to the part of the screen no panel covers: the projection is
//! made for a viewport of that part's shape, then scaled and translated in normalized
//! device coordinates onto it (a lens shift), so the target sits in its middle and the
//! organ fits across it as it would fit a window of that size. Rays and projections go
//! through the same matrix, so picking stays exact.

use glam::{Mat4, Vec2, Vec3, Vec4};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    pub target_mm: Vec3,
    /// Angle of the eye around z, from +x, radians.
    pub yaw: f32,
    /// Elevation of the eye above the xy plane, radians.
    pub pitch: f32,
    pub distance_mm: f32,
    pub fov_y: f32,
    /// Where the view's centre lies on the screen, in normalized device coordinates
    /// (x right, y up; zero: the screen's centre). See [`OrbitCamera::center_view_in`].
    pub lens_shift: Vec2,
    /// The fitted viewport's size as a fraction of the screen's, per axis (one: the
    /// whole screen).
    pub lens_scale: Vec2,
}

/// The largest probe coordinate or direction component taken (mm): a kilometre, from
/// the command line or a scripted probe path. Larger values are no organ's, and their
/// squares (distances, lengths) overflow to infinity long before `f64::MAX`.
pub const COORDINATE_MAX: f64 = 1e6;

/// Whether `c` is a coordinate a probe can be given (see [`COORDINATE_MAX`]).
pub fn coordinate_ok(c: f64) -> bool {
    c.is_finite() && c.abs() <= COORDINATE_MAX
}

/// A ray in world space (mm), `dir` unit length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

const PITCH_LIMIT: f32 = 1.45;

impl OrbitCamera {
    /// Looks at a body of the given bounds from the anterior side (+y), slightly above.
    pub fn framing(min_mm: Vec3, max_mm: Vec3) -> Self {
        let radius = 0.5 * (max_mm - min_mm).length();
        let fov_y = 40f32.to_radians();
        OrbitCamera {
            target_mm: 0.5 * (min_mm + max_mm),
            yaw: 100f32.to_radians(),
            pitch: 25f32.to_radians(),
            distance_mm: 0.9 * radius / (0.5 * fov_y).sin(),
            fov_y,
            lens_shift: Vec2::ZERO,
            lens_scale: Vec2::ONE,
        }
    }

    /// Fits the view to `free`, the part of a `screen` the interface leaves uncovered
    /// (both rectangles as (min, max) corners in the same units, y down): the target in
    /// its middle, the organ framed as in a window of its shape (a tall part widens
    /// the field, [`Self::fov_y_for`], so the organ still fits across). A degenerate
    /// rectangle leaves the view as it is.
    pub fn center_view_in(&mut self, free: (Vec2, Vec2), screen: (Vec2, Vec2)) {
        let size = screen.1 - screen.0;
        let center = 0.5 * (free.0 + free.1) - screen.0;
        let shift = Vec2::new(2.0 * center.x / size.x - 1.0, 1.0 - 2.0 * center.y / size.y);
        let scale = (free.1 - free.0) / size;
        if size.min_element() > 0.0 && shift.is_finite() && scale.min_element() > 0.0 {
            self.lens_shift = shift.clamp(Vec2::splat(-1.0), Vec2::splat(1.0));
            self.lens_scale = scale.min(Vec2::ONE);
        }
    }

    /// The fitted viewport's aspect (width / height) on a screen of `aspect`.
    fn fitted_aspect(&self, aspect: f32) -> f32 {
        aspect.max(1e-3) * self.lens_scale.x / self.lens_scale.y
    }

    pub fn eye(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target_mm + self.distance_mm * Vec3::new(cp * cy, cp * sy, sp)
    }

    pub fn view_from_world(&self) -> Mat4 {
        glam::camera::rh::view::look_at_mat4(self.eye(), self.target_mm, Vec3::Z)
    }

    /// The vertical field of view for a viewport of `aspect` (width / height): `fov_y`
    /// on a wide viewport; on a tall one (a phone upright) widened so the horizontal
    /// field stays that of a square viewport, and the organ still fits across.
    pub fn fov_y_for(&self, aspect: f32) -> f32 {
        let aspect = aspect.max(1e-3);
        if aspect >= 1.0 {
            self.fov_y
        } else {
            2.0 * ((0.5 * self.fov_y).tan() / aspect).atan()
        }
    }

    pub fn clip_from_view(&self, aspect: f32) -> Mat4 {
        let near = (0.05 * self.distance_mm).max(1.0);
        let far = 10.0 * self.distance_mm + 1000.0;
        let fitted = self.fitted_aspect(aspect);
        let onto_screen = Mat4::from_translation(self.lens_shift.extend(0.0))
            * Mat4::from_scale(self.lens_scale.extend(1.0));
        onto_screen
            * glam::camera::rh::proj::directx::perspective(
                self.fov_y_for(fitted),
                fitted,
                near,
                far,
            )
    }

    pub fn clip_from_world(&self, aspect: f32) -> Mat4 {
        self.clip_from_view(aspect) * self.view_from_world()
    }

    /// The ray through pixel `pos_px` of a `size_px` viewport (origin top-left).
    pub fn ray(&self, pos_px: Vec2, size_px: Vec2) -> Ray {
        let ndc = Vec2::new(
            2.0 * pos_px.x / size_px.x.max(1.0) - 1.0,
            1.0 - 2.0 * pos_px.y / size_px.y.max(1.0),
        );
        let world_from_clip = self
            .clip_from_world(size_px.x / size_px.y.max(1.0))
            .inverse();
        let near = world_from_clip * Vec4::new(ndc.x, ndc.y, 0.0, 1.0);
        let far = world_from_clip * Vec4::new(ndc.x, ndc.y, 1.0, 1.0);
        let near = near.truncate() / near.w;
        let far = far.truncate() / far.w;
        Ray {
            origin: near,
            dir: (far - near).normalize_or(Vec3::NEG_Y),
        }
    }

    /// Pixel position of a world point (None behind the eye).
    pub fn project(&self, p_mm: Vec3, size_px: Vec2) -> Option<Vec2> {
        let c = self.clip_from_world(size_px.x / size_px.y.max(1.0)) * p_mm.extend(1.0);
        (c.w > 0.0).then(|| {
            let ndc = c.truncate() / c.w;
            Vec2::new(
                (ndc.x + 1.0) * 0.5 * size_px.x,
                (1.0 - ndc.y) * 0.5 * size_px.y,
            )
        })
    }

    /// Orbits by angles in radians (pitch kept short of the poles).
    pub fn orbit(&mut self, d_yaw: f32, d_pitch: f32) {
        if !(d_yaw.is_finite() && d_pitch.is_finite()) {
            return;
        }
        self.yaw = (self.yaw + d_yaw).rem_euclid(std::f32::consts::TAU);
        self.pitch = (self.pitch + d_pitch).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    }

    /// Moves the target in the view plane by a screen-space delta in pixels.
    pub fn pan(&mut self, delta_px: Vec2, viewport_px: Vec2) {
        let fov = self.fov_y_for(self.fitted_aspect(viewport_px.x / viewport_px.y.max(1.0)));
        // The fitted viewport's height spans the field of view.
        let height_px = (viewport_px.y * self.lens_scale.y).max(1.0);
        let mm_per_px = 2.0 * self.distance_mm * (0.5 * fov).tan() / height_px;
        let (right, up) = self.screen_axes();
        let moved = self.target_mm + (-delta_px.x * right + delta_px.y * up) * mm_per_px;
        // Within the probe coordinates' bound: far past the organ, never infinite.
        if moved.is_finite() {
            let bound = COORDINATE_MAX as f32;
            self.target_mm = moved.clamp(Vec3::splat(-bound), Vec3::splat(bound));
        }
    }

    /// Multiplies the distance by `factor` (< 1 zooms in), within sane limits.
    pub fn zoom(&mut self, factor: f32) {
        if factor.is_finite() && factor > 0.0 {
            self.distance_mm = (self.distance_mm * factor).clamp(20.0, 5000.0);
        }
    }

    /// World directions of the screen's right and up.
    pub fn screen_axes(&self) -> (Vec3, Vec3) {
        let fwd = (self.target_mm - self.eye()).normalize_or(Vec3::NEG_Y);
        let right = fwd.cross(Vec3::Z).normalize_or(Vec3::X);
        let up = right.cross(fwd);
        (right, up)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_through_a_projected_point_passes_through_it() {
        let cam = OrbitCamera::framing(
            Vec3::new(-100.0, -80.0, -50.0),
            Vec3::new(100.0, 80.0, 50.0),
        );
        let size = Vec2::new(640.0, 480.0);
        for p in [
            Vec3::ZERO,
            Vec3::new(30.0, 40.0, -20.0),
            Vec3::new(-60.0, 10.0, 35.0),
        ] {
            let px = cam.project(p, size).expect("in front of the camera");
            let ray = cam.ray(px, size);
            let to_p = p - ray.origin;
            let off_axis = (to_p - to_p.dot(ray.dir) * ray.dir).length();
            // f32 unprojection over a ~500 mm range: micrometres.
            assert!(off_axis < 1e-2, "ray misses {p} by {off_axis} mm");
        }
        // The centre pixel looks at the target.
        let ray = cam.ray(size / 2.0, size);
        assert!((ray.dir - (cam.target_mm - cam.eye()).normalize()).length() < 1e-4);
    }

    /// Shifted to the middle of the part of the screen a panel leaves free, the target
    /// projects there, and rays still pass through the points they were cast at.
    #[test]
    fn a_shifted_view_centres_the_target_in_the_free_part_and_picks_exactly() {
        let mut cam = OrbitCamera::framing(
            Vec3::new(-100.0, -80.0, -50.0),
            Vec3::new(100.0, 80.0, 50.0),
        );
        let size = Vec2::new(1280.0, 720.0);
        let screen = (Vec2::ZERO, size);
        // A drawer 340 wide on the left; then a phone's sheet over the lower half.
        for free in [
            (Vec2::new(340.0, 0.0), size),
            (Vec2::ZERO, Vec2::new(1280.0, 380.0)),
        ] {
            cam.center_view_in(free, screen);
            let at = cam.project(cam.target_mm, size).expect("in front");
            let middle = 0.5 * (free.0 + free.1);
            assert!((at - middle).length() < 1e-2, "{at} against {middle}");
            for p in [Vec3::new(30.0, 40.0, -20.0), Vec3::new(-60.0, 10.0, 35.0)] {
                let px = cam.project(p, size).expect("in front of the camera");
                let ray = cam.ray(px, size);
                let to_p = p - ray.origin;
                let off_axis = (to_p - to_p.dot(ray.dir) * ray.dir).length();
                assert!(off_axis < 1e-2, "ray misses {p} by {off_axis} mm");
            }
        }
        // A degenerate screen changes nothing.
        let before = (cam.lens_shift, cam.lens_scale);
        cam.center_view_in(screen, (Vec2::ZERO, Vec2::ZERO));
        assert_eq!((cam.lens_shift, cam.lens_scale), before);
    }

    /// Fitted to a part of the screen, the view frames the body as a window of that
    /// part's size would: a part as wide as the screen changes nothing, a tall one
    /// (between a drawer and a panel) keeps the body's width inside it.
    #[test]
    fn a_fitted_view_frames_the_body_as_a_window_of_the_free_part() {
        let (min, max) = (
            Vec3::new(-100.0, -80.0, -50.0),
            Vec3::new(100.0, 80.0, 50.0),
        );
        let size = Vec2::new(1280.0, 720.0);
        let screen = (Vec2::ZERO, size);
        let corners: Vec<Vec3> = (0..8)
            .map(|k| Vec3::select(glam::BVec3::new(k & 1 > 0, k & 2 > 0, k & 4 > 0), max, min))
            .collect();
        let extent = |cam: &OrbitCamera, size: Vec2, offset: Vec2| {
            let px: Vec<Vec2> = corners
                .iter()
                .map(|&p| cam.project(p, size).expect("in front") - offset)
                .collect();
            let lo = px.iter().fold(Vec2::splat(f32::MAX), |a, &b| a.min(b));
            let hi = px.iter().fold(Vec2::splat(f32::MIN), |a, &b| a.max(b));
            (lo, hi)
        };
        for free in [
            (Vec2::new(340.0, 0.0), size),
            (Vec2::new(340.0, 0.0), Vec2::new(850.0, 720.0)),
            (Vec2::new(0.0, 0.0), Vec2::new(1280.0, 380.0)),
        ] {
            let mut cam = OrbitCamera::framing(min, max);
            let alone = extent(&cam, free.1 - free.0, Vec2::ZERO);
            cam.center_view_in(free, screen);
            let fitted = extent(&cam, size, free.0);
            for (a, b) in [(alone.0, fitted.0), (alone.1, fitted.1)] {
                assert!(
                    (a - b).length() < 0.05,
                    "{free:?}: {a} in a window, {b} fitted"
                );
            }
        }
        // Between a drawer and a panel the body's width stays inside the free part.
        let mut cam = OrbitCamera::framing(min, max);
        let free = (Vec2::new(340.0, 0.0), Vec2::new(850.0, 720.0));
        cam.center_view_in(free, screen);
        let (lo, hi) = extent(&cam, size, Vec2::ZERO);
        let ray_through = |p: Vec3| {
            let px = cam.project(p, size).expect("in front");
            let ray = cam.ray(px, size);
            let to_p = p - ray.origin;
            (to_p - to_p.dot(ray.dir) * ray.dir).length()
        };
        assert!(ray_through(Vec3::new(30.0, 40.0, -20.0)) < 1e-2);
        // The box's corners span the free part's 510 px (720 on the whole screen).
        let whole = extent(&OrbitCamera::framing(min, max), size, Vec2::ZERO);
        let (width, whole_width) = (hi.x - lo.x, whole.1.x - whole.0.x);
        assert!(
            width < 1.02 * 510.0 && width < 0.75 * whole_width,
            "{lo} {hi}, {whole:?}"
        );
        let middle = 0.5 * (lo.x + hi.x);
        assert!((middle - 595.0).abs() < 25.0, "{lo} {hi}");
    }

    #[test]
    fn orbit_keeps_away_from_the_poles_and_zoom_rejects_nonsense() {
        let mut cam = OrbitCamera::framing(Vec3::splat(-1.0), Vec3::splat(1.0));
        cam.orbit(0.0, 10.0);
        assert!(cam.pitch <= PITCH_LIMIT);
        let d = cam.distance_mm;
        cam.zoom(f32::NAN);
        cam.zoom(-2.0);
        assert_eq!(cam.distance_mm, d);
    }
}
