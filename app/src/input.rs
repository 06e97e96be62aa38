//! Input: mouse, touch and gamepad events turned into probe and camera states.
//!
//! Platform events (winit, gilrs) are translated into [`InputEvent`]s by thin adapters;
//! everything here is plain state, so synthetic event sequences can test it.
//!
//! | device | probe | camera |
//! |---|---|---|
//! | mouse | left-press on the palpable surface, drag down to indent | left-drag elsewhere orbits, right/middle-drag pans, wheel zooms |
//! | touch | hold a finger on the surface (0.25 s), then drag down to indent | one-finger drag orbits; two fingers pinch-zoom, twist and pan |
//! | gamepad | left stick slides the probe, right trigger presses (force-controlled) | right stick orbits |
//!
//! A press outside the palpable region leaves the probe where it was and says so.

use glam::Vec2;
use palpa_core::scene::ProbePoint;

use crate::camera::OrbitCamera;
use crate::force::ProbeCommand;
use crate::pick::{Pick, Picker};

/// Which pointer an event comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointerId {
    Mouse,
    Touch(u64),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Button {
    Primary,
    Secondary,
    Middle,
}

/// Device-independent input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InputEvent {
    PointerDown {
        id: PointerId,
        button: Button,
        pos_px: Vec2,
        time_s: f64,
    },
    PointerMove {
        id: PointerId,
        pos_px: Vec2,
        time_s: f64,
    },
    PointerUp {
        id: PointerId,
        time_s: f64,
    },
    /// Wheel or trackpad scroll, in lines (positive away from the user: zoom in).
    Wheel {
        lines: f32,
    },
    /// The gamepad's state, once per frame.
    Gamepad {
        left: Vec2,
        right: Vec2,
        /// Right trigger, 0..1.
        trigger: f32,
        dt_s: f32,
        /// The south button (A, cross) went down this frame: mark the nodule here.
        mark: bool,
    },
}

pub use crate::force::PressMode;

/// Tunable constants of the mappings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mapping {
    /// Indentation per pixel of downward drag.
    pub depth_mm_per_px: f32,
    pub max_depth_mm: f32,
    /// Force at full trigger.
    pub max_force_n: f32,
    pub orbit_rad_per_px: f32,
    /// Touch: how long a finger must rest before it presses, and how far it may drift.
    pub hold_s: f64,
    pub hold_slop_px: f32,
    /// Gamepad: probe speed at full stick, orbit speed at full stick.
    pub slide_mm_per_s: f32,
    pub orbit_rad_per_s: f32,
    /// Stick dead zone.
    pub dead_zone: f32,
}

impl Default for Mapping {
    fn default() -> Self {
        Mapping {
            depth_mm_per_px: 0.05,
            max_depth_mm: 20.0,
            max_force_n: 5.0,
            orbit_rad_per_px: 0.008,
            hold_s: 0.25,
            hold_slop_px: 12.0,
            slide_mm_per_s: 60.0,
            orbit_rad_per_s: 1.8,
            dead_zone: 0.15,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Gesture {
    None,
    /// Pressing with this pointer; depth follows the drag from `anchor`.
    Press {
        id: PointerId,
        anchor_px: Vec2,
    },
    /// A touch resting on the palpable surface, not yet a press.
    Hold {
        id: u64,
        start_px: Vec2,
        start_s: f64,
    },
    Orbit {
        id: PointerId,
        last_px: Vec2,
    },
    Pan {
        id: PointerId,
        last_px: Vec2,
    },
    /// Two fingers: their last positions.
    Pinch {
        a: (u64, Vec2),
        b: (u64, Vec2),
    },
}

/// The probe and camera as the user has set them.
#[derive(Debug, Clone, PartialEq)]
pub struct Controls {
    pub camera: OrbitCamera,
    pub mapping: Mapping,
    pub probe: Option<ProbePoint>,
    pub pressing: bool,
    pub mode: PressMode,
    pub depth_mm: f32,
    /// Force target in force mode, N.
    pub force_n: f32,
    /// Modes kept (the accuracy knob).
    pub modes: u32,
    /// A short message for the user about the last pointer action (e.g. outside the
    /// palpable region); cleared by the next successful pick.
    pub feedback: Option<&'static str>,
    gesture: Gesture,
    /// Touches currently down (at most two tracked).
    touches: [Option<(u64, Vec2)>; 2],
    /// The trigger is pressing (so releasing it lifts the probe).
    trigger_pressing: bool,
}

pub const OUTSIDE_PALPABLE: &str =
    "outside the palpable region: press the lighter, palpable surface";

impl Controls {
    pub fn new(camera: OrbitCamera, modes: u32) -> Self {
        Controls {
            camera,
            mapping: Mapping::default(),
            probe: None,
            pressing: false,
            mode: PressMode::Depth,
            depth_mm: 0.0,
            force_n: 1.0,
            modes,
            feedback: None,
            gesture: Gesture::None,
            touches: [None; 2],
            trigger_pressing: false,
        }
    }

    /// Stops pressing (the probe stays where it is, at no depth).
    pub fn release_probe(&mut self) {
        self.pressing = false;
        self.depth_mm = 0.0;
        self.trigger_pressing = false;
        self.gesture = Gesture::None;
    }

    /// The command for the force loop.
    pub fn command(&self) -> ProbeCommand {
        let Some(p) = self.probe else {
            return ProbeCommand::lifted(self.modes);
        };
        let target = match self.mode {
            PressMode::Depth => self.depth_mm,
            PressMode::Force => self.force_n,
        };
        ProbeCommand::at(p, self.pressing, self.mode, self.modes, target)
    }

    pub fn handle(&mut self, ev: InputEvent, picker: &dyn Picker, viewport_px: Vec2) {
        // A position a driver lost (NaN, infinite) is no place to press or drag from.
        if let InputEvent::PointerDown { pos_px, .. } | InputEvent::PointerMove { pos_px, .. } = ev
            && !pos_px.is_finite()
        {
            return;
        }
        match ev {
            InputEvent::PointerDown {
                id,
                button,
                pos_px,
                time_s,
            } => self.down(id, button, pos_px, time_s, picker),
            InputEvent::PointerMove { id, pos_px, time_s } => {
                self.moved(id, pos_px, time_s, viewport_px);
            }
            InputEvent::PointerUp { id, .. } => self.up(id),
            InputEvent::Wheel { lines } => self.camera.zoom(0.9f32.powf(lines)),
            InputEvent::Gamepad {
                left,
                right,
                trigger,
                dt_s,
                ..
            } => self.gamepad(left, right, trigger, dt_s, picker),
        }
    }

    fn down(
        &mut self,
        id: PointerId,
        button: Button,
        pos_px: Vec2,
        time_s: f64,
        picker: &dyn Picker,
    ) {
        if let PointerId::Touch(t) = id {
            self.touch_down(t, pos_px, time_s, picker);
            return;
        }
        self.gesture = match button {
            Button::Primary => match picker.pick(pos_px) {
                Pick::Palpable(p) => {
                    self.probe = Some(p);
                    self.feedback = None;
                    self.pressing = true;
                    self.depth_mm = 0.0;
                    Gesture::Press {
                        id,
                        anchor_px: pos_px,
                    }
                }
                Pick::Outside => {
                    self.feedback = Some(OUTSIDE_PALPABLE);
                    Gesture::Orbit {
                        id,
                        last_px: pos_px,
                    }
                }
                Pick::Miss => Gesture::Orbit {
                    id,
                    last_px: pos_px,
                },
            },
            Button::Secondary | Button::Middle => Gesture::Pan {
                id,
                last_px: pos_px,
            },
        };
    }

    fn touch_down(&mut self, t: u64, pos_px: Vec2, time_s: f64, picker: &dyn Picker) {
        if let Some(slot) = self.touches.iter_mut().find(|s| s.is_none()) {
            *slot = Some((t, pos_px));
        } else {
            return; // a third finger: ignored
        }
        match (self.touches[0], self.touches[1]) {
            (Some(a), Some(b)) => {
                // A second finger turns whatever the first was doing into a pinch.
                self.pressing = false;
                self.gesture = Gesture::Pinch { a, b };
            }
            _ => {
                self.gesture = match picker.pick(pos_px) {
                    Pick::Palpable(p) => {
                        self.probe = Some(p);
                        self.feedback = None;
                        Gesture::Hold {
                            id: t,
                            start_px: pos_px,
                            start_s: time_s,
                        }
                    }
                    Pick::Outside => {
                        self.feedback = Some(OUTSIDE_PALPABLE);
                        Gesture::Orbit {
                            id: PointerId::Touch(t),
                            last_px: pos_px,
                        }
                    }
                    Pick::Miss => Gesture::Orbit {
                        id: PointerId::Touch(t),
                        last_px: pos_px,
                    },
                };
            }
        }
    }

    fn moved(&mut self, id: PointerId, pos_px: Vec2, time_s: f64, viewport_px: Vec2) {
        if let PointerId::Touch(t) = id {
            for (tid, p) in self.touches.iter_mut().flatten() {
                if *tid == t {
                    *p = pos_px;
                }
            }
        }
        let m = self.mapping;
        match self.gesture {
            Gesture::Press { id: g, anchor_px } if g == id => {
                self.depth_mm =
                    ((pos_px.y - anchor_px.y) * m.depth_mm_per_px).clamp(0.0, m.max_depth_mm);
            }
            Gesture::Hold {
                id: t,
                start_px,
                start_s,
            } if id == PointerId::Touch(t) => {
                if time_s - start_s >= m.hold_s {
                    self.pressing = true;
                    self.depth_mm = 0.0;
                    self.gesture = Gesture::Press {
                        id,
                        anchor_px: pos_px,
                    };
                } else if pos_px.distance(start_px) > m.hold_slop_px {
                    // A quick swipe across the organ rotates the view instead.
                    self.gesture = Gesture::Orbit {
                        id,
                        last_px: pos_px,
                    };
                    self.orbit_by(pos_px - start_px);
                }
            }
            Gesture::Orbit { id: g, last_px } if g == id => {
                self.orbit_by(pos_px - last_px);
                self.gesture = Gesture::Orbit {
                    id,
                    last_px: pos_px,
                };
            }
            Gesture::Pan { id: g, last_px } if g == id => {
                self.camera.pan(pos_px - last_px, viewport_px);
                self.gesture = Gesture::Pan {
                    id,
                    last_px: pos_px,
                };
            }
            Gesture::Pinch { a, b } => {
                let find = |t: u64, old: Vec2| {
                    self.touches
                        .iter()
                        .flatten()
                        .find(|(id, _)| *id == t)
                        .map_or(old, |(_, p)| *p)
                };
                let (na, nb) = (find(a.0, a.1), find(b.0, b.1));
                let (old_v, new_v) = (b.1 - a.1, nb - na);
                if old_v.length() > 1.0 && new_v.length() > 1.0 {
                    self.camera.zoom(old_v.length() / new_v.length());
                    let twist = old_v.angle_to(new_v);
                    self.camera.orbit(-twist, 0.0);
                }
                let mid_delta = 0.5 * (na + nb) - 0.5 * (a.1 + b.1);
                self.camera.pan(mid_delta, viewport_px);
                self.gesture = Gesture::Pinch {
                    a: (a.0, na),
                    b: (b.0, nb),
                };
            }
            _ => {}
        }
    }

    fn up(&mut self, id: PointerId) {
        if let PointerId::Touch(t) = id {
            for s in &mut self.touches {
                if s.is_some_and(|(tid, _)| tid == t) {
                    *s = None;
                }
            }
        }
        let ends = match self.gesture {
            Gesture::Press { id: g, .. }
            | Gesture::Orbit { id: g, .. }
            | Gesture::Pan { id: g, .. } => g == id,
            Gesture::Hold { id: t, .. } => id == PointerId::Touch(t),
            // Lifting one finger of a pinch ends it; the other does not start anything.
            Gesture::Pinch { .. } => true,
            Gesture::None => false,
        };
        if ends {
            if matches!(self.gesture, Gesture::Press { .. }) {
                self.pressing = false;
                self.depth_mm = 0.0;
            }
            self.gesture = Gesture::None;
        }
    }

    fn orbit_by(&mut self, delta_px: Vec2) {
        let k = self.mapping.orbit_rad_per_px;
        self.camera.orbit(-delta_px.x * k, delta_px.y * k);
    }

    fn gamepad(&mut self, left: Vec2, right: Vec2, trigger: f32, dt_s: f32, picker: &dyn Picker) {
        let m = self.mapping;
        let dz = |v: Vec2| {
            if v.length() < m.dead_zone {
                Vec2::ZERO
            } else {
                v
            }
        };
        let (left, right) = (dz(left), dz(right));
        if right != Vec2::ZERO {
            self.camera.orbit(
                -right.x * m.orbit_rad_per_s * dt_s,
                right.y * m.orbit_rad_per_s * dt_s,
            );
        }
        if left != Vec2::ZERO
            && let Some(p) = self.probe
            && let Some(q) = picker.slide(&p, left, m.slide_mm_per_s * dt_s)
        {
            self.probe = Some(q);
        }
        let trigger = if trigger.is_finite() {
            trigger.clamp(0.0, 1.0)
        } else {
            0.0
        };
        if trigger > 0.02 && self.probe.is_some() {
            self.mode = PressMode::Force;
            self.force_n = trigger * m.max_force_n;
            self.pressing = true;
            self.trigger_pressing = true;
        } else if self.trigger_pressing {
            self.pressing = false;
            self.trigger_pressing = false;
        }
    }
}
