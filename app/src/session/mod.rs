//! One palpation session: the scene, the user's controls, the force loop, and what each
//! frame needs from them. Shared by the window and the headless mode, so both run the
//! same code between input and pixels.
//!
//! Per frame ([`Session::frame`]): the latest probe command goes to the force loop; the
//! latest force sample comes back; the surface is deformed by the force *that sample
//! computed, at the point it computed it for*, so the picture and the force never
//! disagree (they lag the input by at most one force tick, 1 ms).

use std::sync::Arc;
use std::time::Instant;

use glam::{Vec2, Vec3};
use palpa_core::scene::PalpationScene;
use palpa_core::tissue::online::Tissue;

use crate::camera::OrbitCamera;
use crate::force::{ForceLoop, ForceSample, HapticDevice, LoopTiming, SampleStatus};
use crate::input::{Controls, InputEvent};
use crate::pick::ScenePicker;
use crate::render::deform::DeformOn;
use crate::render::{FrameInput, NoduleVisual, ProbeVisual, ValueKind, VertexValues};
use crate::stats::Ring;

mod deformation;
pub mod paint;
pub mod training;
use deformation::Deformation;
use paint::Painter;
use training::Training;

/// Radius of the probe tool, mm (the load radius the vademecum was computed with).
pub const TOOL_RADIUS_MM: f32 = 5.0;

/// How deep a tissue is measured within the goals at held-out points against the
/// full FE: the surface within 0.5 mm and the force within 5 % to `both_mm`, the
/// force alone (what the hand and the haptic thread feel) to `force_mm`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GoalDepths {
    pub both_mm: f32,
    /// At least `both_mm`.
    pub force_mm: f32,
}

impl GoalDepths {
    /// What the tissue file records (`palpa tissue check --record`), where it records
    /// any check.
    pub fn of(law: &palpa_core::tissue::law::TissueLaw) -> Option<GoalDepths> {
        law.accuracy.goals_to_mm().map(|g| GoalDepths {
            both_mm: g.both_mm as f32,
            force_mm: g.force_mm as f32,
        })
    }
}

/// What the panel and `palpa eval` say of a press in a triangle with `unpressed`
/// corners on the fixed region: the measured tables leave that band out, and
/// measured on its own, its edges pressed, it still misses the goals nearest the
/// attachment, even shallow.
pub fn next_to_fixed_text(unpressed: usize) -> String {
    format!(
        "next to the fixed region ({unpressed} corner{} never pressed): the tool bears on \
         the attachment, where the tissue's blend is least sure and its recorded checks \
         do not press",
        if unpressed == 1 { "" } else { "s" },
    )
}

/// What the panel and `palpa eval` say of a press held at the tissue's limit at the
/// probe, `limit_mm`: a press blended there found no equilibrium deeper (`why`, naming
/// the depth), or the press asked for more than the model's grid.
pub fn held_text(limit_mm: f64, why: Option<&str>) -> String {
    match why {
        Some(why) => format!("held at {limit_mm:.1} mm: a press here found {why}"),
        None => format!(
            "deeper than the tissue model covers: force and surface held at its last depth, \
             {limit_mm:.1} mm"
        ),
    }
}

/// What the panel and `palpa eval` say where the blend's surplus under the probe,
/// `eta_mm`, exceeds `BLEND_SURPLUS_WARN_MM`: the blend of pressed points may miss
/// the surface goal there, however shallow the press.
pub fn blend_surplus_text(eta_mm: f64) -> String {
    format!(
        "blend surplus {eta_mm:.2} mm here: the surface may be more than 0.5 mm off (refine \
         this region: palpa lab tissue refine)"
    )
}

/// The accuracy panel's line for a nonlinear tissue: the modes knob's table above it is
/// the scene's linear vademecum against the linear FE, which a tissue answer builds on
/// but which does not measure it; this line says what does.
pub fn tissue_accuracy_text(goals: Option<GoalDepths>) -> String {
    match goals {
        Some(g) => format!(
            "nonlinear tissue: surface within 0.5 mm and force within 5 % of the full \
             simulation to {:.1} mm deep (force to {:.1} mm)",
            g.both_mm, g.force_mm
        ),
        None => "nonlinear tissue: not measured against the full simulation".to_string(),
    }
}

impl GoalDepths {
    /// The panel's line for a press `depth_mm` deep, past `both_mm`.
    pub fn past_text(&self, depth_mm: f32) -> String {
        let (both, force) = (self.both_mm, self.force_mm);
        if depth_mm > force {
            format!(
                "deeper than {force:.1} mm: this tissue is measured within 0.5 mm and 5 % of \
                 the full FE to {both:.1} mm, its force within 5 % to {force:.1} mm"
            )
        } else {
            format!(
                "deeper than {both:.1} mm: the surface is measured within 0.5 mm of the \
                 full FE only to there; the force within 5 % to {force:.1} mm"
            )
        }
    }
}

/// A scene being palpated.
#[derive(Debug)]
pub struct Session {
    pub scene: Arc<PalpationScene>,
    /// The nonlinear tissue: a force law, or the vademecum (force and surface); `None`:
    /// linear tissue.
    pub law: Option<Arc<Tissue>>,
    pub controls: Controls,
    pub force: ForceLoop,
    /// Colour by displacement, with this value (mm) at the top of the scale.
    pub colormap_mm: Option<f32>,
    /// Where the surface is deformed (the compute shader by default).
    pub deform_on: DeformOn,
    /// The sample the current frame shows.
    pub sample: ForceSample,
    /// Render-side evaluation time (particularization + contact rows), µs, recent frames.
    pub render_eval_us: Ring,
    /// |F| over time (s since start, N), for the plot.
    pub force_history: Ring2,
    /// Where the mouse last was (mouse button events carry no position).
    pub last_pointer_px: Vec2,
    /// Region painting (`Some` while the region mode is on): the pointer paints
    /// instead of pressing.
    pub painter: Option<Painter>,
    /// The depths to which the tissue is measured within the goals, where known
    /// (see `scenes::LoadedScene::goals_to_mm`).
    pub goals_to_mm: Option<GoalDepths>,
    /// Find the nodule (`Some` where the scene has a nodule table).
    pub training: Option<Training>,
    region_values: (Vec<f32>, u64),
    started: Instant,
    deformation: Deformation,
}

/// Pairs (x, y) in a ring (the force plot).
#[derive(Debug, Clone)]
pub struct Ring2 {
    pub x: Ring,
    pub y: Ring,
}

impl Session {
    /// Starts the force loop on `scene`; the camera frames the organ and the probe rests
    /// on the palpable point nearest the front of the organ.
    pub fn new(scene: PalpationScene, haptic: Box<dyn HapticDevice>) -> std::io::Result<Self> {
        Self::with_law(scene, None, haptic)
    }

    /// As [`Self::new`], with the tissue's nonlinear model (see
    /// `palpa_core::tissue::law`): the force loop answers depth with its force, and
    /// force with its depth.
    pub fn with_law(
        scene: PalpationScene,
        law: Option<Tissue>,
        haptic: Box<dyn HapticDevice>,
    ) -> std::io::Result<Self> {
        let scene = Arc::new(scene);
        let law = law.map(Arc::new);
        let (min, max) = bounds(scene.vertices_mm());
        let camera = OrbitCamera::framing(min, max);
        let mut controls = Controls::new(camera, scene.modes() as u32);
        let front =
            camera.target_mm + (camera.eye() - camera.target_mm).normalize() * (max - min).length();
        controls.probe = scene
            .closest_palpable(front.as_dvec3().to_array())
            .map(|(p, _)| p);
        let force = ForceLoop::spawn(
            Arc::clone(&scene),
            law.clone(),
            haptic,
            LoopTiming::default(),
        )?;
        let deformation = Deformation::new(&scene, law.clone());
        Ok(Session {
            scene,
            law,
            controls,
            force,
            colormap_mm: None,
            deform_on: DeformOn::Gpu,
            sample: ForceSample::default(),
            render_eval_us: Ring::new(256),
            force_history: Ring2 {
                x: Ring::new(2000),
                y: Ring::new(2000),
            },
            last_pointer_px: Vec2::ZERO,
            painter: None,
            goals_to_mm: None,
            training: None,
            region_values: (Vec::new(), 0),
            started: Instant::now(),
            deformation,
        })
    }

    /// The tissue's measured depths, when the sample the frame shows presses deeper
    /// than the surface goal's (and so perhaps than the force goal's too).
    pub fn past_goals_mm(&self) -> Option<GoalDepths> {
        let s = &self.sample;
        let pressed = s.status() == SampleStatus::Ok;
        self.goals_to_mm
            .filter(|g| pressed && s.depth_mm > g.both_mm)
    }

    /// The vademecum's finest surplus under the pressed probe at the frame's depth
    /// (`BoundTissue::blend_surplus_mm`): where the blend may miss the surface goal.
    /// `None` when lifted or without a vademecum.
    pub fn blend_surplus_mm(&self) -> Option<f64> {
        let s = &self.sample;
        if s.status() != SampleStatus::Ok {
            return None;
        }
        let law = self.law.as_ref()?;
        law.blend_surplus_mm(&s.command.point(), f64::from(s.depth_mm))
    }

    /// The corners of the pressed probe's triangle the vademecum never pressed (on the
    /// fixed region; see [`next_to_fixed_text`]). `None` when lifted or without a
    /// vademecum.
    pub fn unpressed_corners(&self) -> Option<usize> {
        let s = &self.sample;
        if s.status() != SampleStatus::Ok {
            return None;
        }
        Some(self.law.as_ref()?.unpressed_corners(&s.command.point()))
    }

    /// Turns the region mode on (the probe is lifted) or off.
    pub fn set_painting(&mut self, on: bool) {
        match (on, self.painter.is_some()) {
            (true, false) => {
                self.controls.release_probe();
                self.painter = Some(Painter::new(&self.scene));
            }
            (false, true) => self.painter = None,
            _ => {}
        }
    }

    /// In the region mode: the primary pointer paints; returns whether it took the event.
    fn paint_event(&mut self, ev: &InputEvent, viewport_px: Vec2) -> bool {
        use crate::input::Button;
        let Some(painter) = self.painter.as_mut() else {
            return false;
        };
        let (pos, starts) = match *ev {
            InputEvent::PointerDown {
                button: Button::Primary,
                pos_px,
                ..
            } => (pos_px, true),
            InputEvent::PointerMove { pos_px, .. } if painter.stroking() => (pos_px, false),
            InputEvent::PointerUp { .. } if painter.stroking() => {
                painter.end_stroke();
                return true;
            }
            _ => return false,
        };
        let ray = self.controls.camera.ray(pos, viewport_px);
        let visual = self.scene.visual();
        let shown = self.deformation.last_drawn_mm();
        let hit = crate::pick::intersect(&ray, shown, &visual.triangles);
        if starts {
            // A press off the organ orbits, as it does outside the region mode.
            if hit.is_none() {
                return false;
            }
            painter.begin_stroke();
        }
        if let Some((t, bary, _)) = hit {
            // Paint at the rest position of the point hit (the brush works on rest
            // centroids, which is what a region file stores).
            let at = visual.rest_point(t, bary).map(|c| c as f32);
            painter.paint(at);
        }
        true
    }

    /// Handles one input event (picking against the currently shown deformation).
    pub fn handle(&mut self, ev: InputEvent, viewport_px: Vec2) {
        if self.paint_event(&ev, viewport_px) {
            return;
        }
        if let InputEvent::Gamepad { mark: true, .. } = ev
            && let Err(e) = self.mark()
        {
            tracing::warn!("marking the nodule: {e:#}");
        }
        if let InputEvent::PointerMove {
            id: crate::input::PointerId::Mouse,
            pos_px,
            ..
        } = ev
        {
            self.last_pointer_px = pos_px;
        }
        let needs_pick = matches!(
            ev,
            InputEvent::PointerDown { .. } | InputEvent::Gamepad { .. }
        );
        // Only a new press picks against the current shape; other events read the
        // last surface computed (no reconstruction per pointer move).
        let drawn_mm = if needs_pick {
            self.deformation.deformed_mm(&self.scene);
            self.deformation.drawn_mm(&self.scene)
        } else {
            self.deformation.last_drawn_mm()
        };
        let camera = self.controls.camera;
        let picker = ScenePicker {
            scene: &self.scene,
            camera: &camera,
            viewport_px,
            drawn_mm,
        };
        self.controls.handle(ev, &picker, viewport_px);
    }

    /// Seconds since the session started (the training's clock).
    pub fn now_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// The command the controls give, with a hidden nodule's effect at its point.
    pub fn command(&self) -> crate::force::ProbeCommand {
        let mut c = self.controls.command();
        if let Some(t) = &self.training
            && let Some(p) = self.controls.probe
        {
            c.nodule = t.curve_at(&self.scene, &p);
        }
        c
    }

    /// Marks the hidden nodule where the probe is (the panel's "Mark", a gamepad's
    /// south button); the nodule is revealed and the trial scored.
    pub fn mark(&mut self) -> anyhow::Result<Option<palpa_core::pgd::nodule::training::Score>> {
        let now = self.now_s();
        let (Some(t), Some(p)) = (self.training.as_mut(), self.controls.probe) else {
            return Ok(None);
        };
        t.mark(&self.scene, &p, now)
    }

    /// Sends the controls to the force loop and prepares what this frame draws.
    pub fn frame(&mut self) -> FrameInput<'_> {
        self.force.command(self.command());
        self.sample = self.force.latest();
        if let Some(t) = self.training.as_mut()
            && self.sample.status() == SampleStatus::Ok
        {
            t.pressed(self.sample.magnitude_n);
        }
        let t0 = Instant::now();
        let n = (self.controls.modes as usize).clamp(1, self.scene.modes());
        let s = self.sample;
        let probe = self.controls.probe;
        let mut visual = None;
        let ok = s.status() == SampleStatus::Ok;
        // Deform to the sample's depth at the sample's point: the linear field there
        // (with a nonlinear tissue the tool's force differs) plus, for a hyperelastic
        // vademecum, its residual at that depth; no force: rest shape.
        let (point, force, depth_mm) = if ok {
            let scale = if s.magnitude_n > 0.0 {
                f64::from(s.linear_n) / f64::from(s.magnitude_n)
            } else {
                0.0
            };
            (
                Some(s.command.point()),
                s.force_n.map(|f| f64::from(f) * scale),
                f64::from(s.depth_mm),
            )
        } else {
            (probe, [0.0; 3], 0.0)
        };
        // A hidden nodule's effect at the press (the tissue's changes with the depth):
        // the total force, and the organ's sway with it, is that much larger.
        let nodule_effect = if ok {
            s.command.nodule.at(depth_mm)
        } else {
            0.0
        };
        let tip = self.deformation.evaluate(
            &self.scene,
            point.as_ref().map(|p| (p, force, depth_mm)),
            nodule_effect,
            n,
        );
        if let (Some(p), Some(tip)) = (point, tip) {
            let (_, normal) = self.scene.frame(&p);
            visual = Some(ProbeVisual {
                tip_mm: tip,
                outward: Vec3::new(normal[0] as f32, normal[1] as f32, normal[2] as f32),
                force_n: Vec3::from_array(if ok { s.force_n } else { [0.0; 3] }),
                radius_mm: TOOL_RADIUS_MM,
                valid: self.controls.feedback.is_none(),
            });
        }
        let cpu_surface = self.deform_on == DeformOn::Cpu;
        if cpu_surface {
            self.deformation.cpu_surface(&self.scene);
        }
        self.render_eval_us.push(t0.elapsed().as_secs_f64() * 1e6);
        self.force_history
            .x
            .push(self.started.elapsed().as_secs_f64());
        self.force_history
            .y
            .push(if ok { f64::from(s.magnitude_n) } else { 0.0 });
        if let Some(p) = &self.painter
            && p.generation != self.region_values.1
        {
            self.region_values = (p.vertex_values(&self.scene), p.generation);
        }
        let nodule = self
            .training
            .as_ref()
            .filter(|t| t.revealed)
            .and_then(|t| t.trial.as_ref())
            .map(|t| t.case.nodule());
        let values = match (&self.painter, self.training.as_mut()) {
            (Some(_), _) => Some(VertexValues {
                values: self.region_values.0.as_slice(),
                generation: self.region_values.1,
                kind: ValueKind::Regions,
            }),
            (None, Some(t)) if t.map && t.trial.is_some() => {
                // At the depth pressed now (the tissue's effect changes with it).
                let depth = if self.law.is_some() {
                    f64::from(self.sample.depth_mm)
                } else {
                    0.0
                };
                let (values, generation) = t.vertex_ratios(&self.scene, depth);
                let top = values.iter().copied().fold(1.0, f32::max);
                Some(VertexValues {
                    values,
                    generation,
                    kind: ValueKind::Stiffness { top },
                })
            }
            _ => None,
        };
        FrameInput {
            values,
            nodule: nodule.map(|n| NoduleVisual {
                center_mm: Vec3::from_array(n.center_mm.map(|c| c as f32)),
                radius_mm: n.radius_mm as f32,
            }),
            camera: &self.controls.camera,
            coeffs: self.deformation.coeffs(),
            near_mm: self.deformation.near_gpu(),
            surface_gain: self.deformation.surface_gain(),
            cpu_surface: cpu_surface.then(|| self.deformation.last_cpu_surface()),
            colormap_mm: self.colormap_mm,
            probe: visual,
        }
    }

    /// The CPU-deformed surface for the current frame (the GPU path's reference).
    pub fn deformed_mm(&mut self) -> &[[f32; 3]] {
        self.deformation.deformed_mm(&self.scene)
    }
}

pub use crate::render::bounds;
