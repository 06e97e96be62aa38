//! Gamepads through gilrs: sticks and trigger become [`InputEvent::Gamepad`], and the
//! force drives the rumble. With no pad (or no gamepad support on the platform) every
//! call is a no-op and the UI says "none found".

use std::time::{Duration, Instant};

use gilrs::ff::{BaseEffect, BaseEffectType, EffectBuilder, Replay, Ticks};
use gilrs::{Axis, Button, Gilrs};
use glam::Vec2;

use crate::force::AtomicHaptics;
use crate::input::InputEvent;

/// Rumble at full strength at this force.
const FULL_RUMBLE_N: f32 = 10.0;

/// Polls the first connected pad; owns the rumble effect.
pub struct Gamepads {
    gilrs: Option<Gilrs>,
    rumble: Option<gilrs::ff::Effect>,
    last_poll: Instant,
    /// Rumble level last sent (0..1), to avoid resending the same level every frame.
    sent: f32,
    /// The south button was down at the last poll (a mark is its going down).
    south: bool,
}

impl std::fmt::Debug for Gamepads {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gamepads")
            .field("available", &self.gilrs.is_some())
            .finish()
    }
}

impl Gamepads {
    /// Starts gamepad support; failure (no udev, unsupported platform) is logged and
    /// leaves the app without a pad.
    pub fn new() -> Self {
        let gilrs = match Gilrs::new() {
            Ok(g) => Some(g),
            Err(gilrs::Error::NotImplemented(g)) => Some(g),
            Err(e) => {
                tracing::warn!("gamepads unavailable: {e}");
                None
            }
        };
        Gamepads {
            gilrs,
            rumble: None,
            last_poll: Instant::now(),
            sent: 0.0,
            south: false,
        }
    }

    /// Name of the first connected pad.
    pub fn name(&self) -> Option<String> {
        let g = self.gilrs.as_ref()?;
        g.gamepads().next().map(|(_, pad)| pad.name().to_string())
    }

    /// Drains pad events and returns this frame's state of the first pad.
    pub fn poll(&mut self) -> Option<InputEvent> {
        let now = Instant::now();
        let dt_s = (now - self.last_poll).as_secs_f32().min(0.1);
        self.last_poll = now;
        let g = self.gilrs.as_mut()?;
        while g.next_event().is_some() {}
        let (_, pad) = g.gamepads().next()?;
        let axis = |a: Axis| pad.axis_data(a).map_or(0.0, |d| d.value());
        let trigger = pad
            .button_data(Button::RightTrigger2)
            .map_or(0.0, |d| d.value());
        let south = pad.is_pressed(Button::South);
        let mark = south && !self.south;
        self.south = south;
        Some(InputEvent::Gamepad {
            left: Vec2::new(axis(Axis::LeftStickX), axis(Axis::LeftStickY)),
            right: Vec2::new(axis(Axis::RightStickX), axis(Axis::RightStickY)),
            trigger,
            dt_s,
            mark,
        })
    }

    /// Sets the rumble from the force loop's latest magnitude (at frame rate: rumble
    /// motors cannot follow 1 kHz). Pads without force feedback are skipped.
    pub fn rumble(&mut self, haptics: &AtomicHaptics) {
        let level = (haptics.magnitude_n() / FULL_RUMBLE_N).clamp(0.0, 1.0);
        if (level - self.sent).abs() < 0.02 {
            return;
        }
        self.sent = level;
        let Some(g) = self.gilrs.as_mut() else {
            return;
        };
        let ids: Vec<_> = g
            .gamepads()
            .filter(|(_, p)| p.is_ff_supported())
            .map(|(id, _)| id)
            .collect();
        if ids.is_empty() {
            return;
        }
        let built = EffectBuilder::new()
            .add_effect(BaseEffect {
                kind: BaseEffectType::Strong {
                    magnitude: (level * f32::from(u16::MAX)) as u16,
                },
                scheduling: Replay {
                    play_for: Ticks::from_ms(150),
                    ..Default::default()
                },
                ..Default::default()
            })
            .gamepads(&ids)
            .finish(g);
        match built {
            Ok(effect) => {
                if level > 0.0 && effect.play().is_err() {
                    tracing::debug!("rumble refused");
                }
                self.rumble = Some(effect);
            }
            Err(e) => tracing::debug!("no rumble: {e}"),
        }
    }
}

impl Default for Gamepads {
    fn default() -> Self {
        Self::new()
    }
}

/// How often the window polls pads when nothing else wakes it.
pub const POLL_INTERVAL: Duration = Duration::from_millis(16);
