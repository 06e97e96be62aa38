//! What outlives every surface and every GPU device: the room (a palpation session
//! with its force loop, or a network room), the interface state, and the size of the
//! surface the frames go to. The window ([`crate::window`]) hands it the platform's
//! lifecycle (resume with a new surface, suspend, resize and rotation, a memory
//! warning) and its input; a test drives it with the same sequences a phone sends and
//! draws its frames offscreen through the same [`Shell::encode`].
//!
//! A phone destroys the native window on suspend and makes a new one, often of
//! another size, on resume; a lost GPU device is replaced by a new one. None of it
//! touches the room: the probe, the camera, the modes kept, a network's coordinates
//! and the force loop carry on. A finger down when the surface goes is let go (no
//! event will ever lift it), so the next touch starts clean.

use glam::Vec2;

use crate::force::AtomicHaptics;
use crate::input::{InputEvent, PointerId};
use crate::network::build::{BuildState, NetworkBuild};
use crate::network::{NetworkRoom, Prepared};
use crate::overlay::Overlay;
use crate::render::Renderer;
use crate::render::deform::DeformOn;
use crate::render::gpu::Gpu;
use crate::render::landscape::Landscape;
use crate::scenes::Opened;
use crate::session::Session;
use crate::ui::Hud;

/// The room the app shows: each kind of scene keeps to its own.
#[derive(Debug)]
pub enum Room {
    Palpation(Box<Session>),
    Network(Box<NetworkRoom>),
    /// A network whose meta-model is being built; it becomes `Network` when done.
    Building(Box<NetworkBuild>),
}

impl Room {
    /// Moves a finished build into its network room.
    fn advance(&mut self, hud: &mut Hud) {
        let Room::Building(b) = self else { return };
        if let BuildState::Done(path) = b.poll().clone() {
            match b.room(&path) {
                Ok(room) => {
                    hud.scene_source = path.display().to_string();
                    *self = Room::Network(Box::new(room));
                }
                Err(e) => hud.message = Some(format!("{e:#}")),
            }
        }
    }
}

/// What draws a room on one GPU device: made again for a new device, kept across
/// surfaces.
pub struct Drawing {
    /// The palpation scene's renderer (a network scene draws with egui only).
    pub renderer: Option<Renderer>,
    /// The colour format the scene is drawn in.
    pub scene_format: wgpu::TextureFormat,
    /// The network scene's 3-D view (made on its first frame).
    pub landscape: Option<Landscape>,
    pub overlay: Overlay,
}

impl std::fmt::Debug for Drawing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Drawing")
            .field("scene_format", &self.scene_format)
            .finish_non_exhaustive()
    }
}

impl Drawing {
    pub fn new(
        device: &wgpu::Device,
        room: &Room,
        scene_format: wgpu::TextureFormat,
        ui_format: wgpu::TextureFormat,
        software: bool,
    ) -> Self {
        Drawing {
            renderer: renderer_for(device, room, scene_format),
            scene_format,
            landscape: None,
            overlay: Overlay::new(device, ui_format, software),
        }
    }
}

/// The room's renderer (palpation only).
fn renderer_for(
    device: &wgpu::Device,
    room: &Room,
    format: wgpu::TextureFormat,
) -> Option<Renderer> {
    match room {
        Room::Palpation(s) => Some(Renderer::new(device, format, &s.scene)),
        Room::Network(_) | Room::Building(_) => None,
    }
}

/// The room, the interface state and the surface's size.
#[derive(Debug)]
pub struct Shell {
    pub room: Room,
    pub hud: Hud,
    pub haptics: AtomicHaptics,
    /// The surface's size in pixels; `None` while suspended (no surface).
    surface_px: Option<(u32, u32)>,
    /// The last size a surface had (input arriving without one maps against it).
    last_px: (u32, u32),
    /// Where a drag on the network scene's landscape last was.
    drag_px: Option<Vec2>,
    /// Touches down (so a suspend can let them go).
    touches: Vec<u64>,
    /// Surfaces made so far (resumes), and memory warnings received.
    pub surfaces_made: u32,
    pub memory_warnings: u32,
}

impl Shell {
    /// Opens `scene` (`liver` or a file); if it cannot be opened, the built-in scene is
    /// shown with a notice saying why.
    pub fn open(scene: &str) -> anyhow::Result<Self> {
        let (opened, message) = crate::scenes::open_or_default(scene)?;
        let haptics = AtomicHaptics::default();
        let (room, source) = room_of(opened, &haptics)?;
        let mut hud = Hud::new(source);
        hud.message = message;
        Ok(Shell {
            room,
            hud,
            haptics,
            surface_px: None,
            last_px: (1, 1),
            drag_px: None,
            touches: Vec::new(),
            surfaces_made: 0,
            memory_warnings: 0,
        })
    }

    /// A new surface of `size_px` (the first start, or a resume after a suspend).
    pub fn resumed(&mut self, size_px: (u32, u32)) {
        self.surfaces_made += 1;
        self.resized(size_px);
    }

    /// The surface is gone (Android destroys it on suspend). Fingers down are let go:
    /// no event will lift them now.
    pub fn suspended(&mut self) {
        self.surface_px = None;
        for id in std::mem::take(&mut self.touches) {
            self.pointer(InputEvent::PointerUp {
                id: PointerId::Touch(id),
                time_s: 0.0,
            });
        }
        self.drag_px = None;
    }

    /// A new size (a window resized, a phone rotated); a zero size is ignored.
    pub fn resized(&mut self, size_px: (u32, u32)) {
        if size_px.0 > 0 && size_px.1 > 0 {
            self.surface_px = Some(size_px);
            self.last_px = size_px;
        }
    }

    /// The platform is short of memory: what can be rebuilt on demand goes (the
    /// network's 3-D mesh, egui's caches); the room stays.
    pub fn memory_warning(&mut self, drawing: Option<&mut Drawing>) {
        self.memory_warnings += 1;
        if let Some(d) = drawing {
            d.landscape = None;
            d.overlay.ctx.memory_mut(|m| m.caches = Default::default());
        }
        tracing::warn!("low memory: caches dropped, the session kept");
    }

    pub fn has_surface(&self) -> bool {
        self.surface_px.is_some()
    }

    /// The viewport input maps against: the surface, or the last one while suspended.
    pub fn viewport(&self) -> Vec2 {
        let (w, h) = self.surface_px.unwrap_or(self.last_px);
        Vec2::new(w as f32, h as f32)
    }

    /// Hands an input event to the room (the network room is steered by its panel).
    pub fn pointer(&mut self, ev: InputEvent) {
        match ev {
            InputEvent::PointerDown {
                id: PointerId::Touch(t),
                ..
            } if !self.touches.contains(&t) => self.touches.push(t),
            InputEvent::PointerUp {
                id: PointerId::Touch(t),
                ..
            } => self.touches.retain(|&x| x != t),
            _ => {}
        }
        let viewport = self.viewport();
        match &mut self.room {
            Room::Palpation(session) => session.handle(ev, viewport),
            Room::Network(n) => match ev {
                InputEvent::PointerDown { pos_px, .. } => self.drag_px = Some(pos_px),
                InputEvent::PointerMove { pos_px, .. } => {
                    if let Some(from) = self.drag_px.replace(pos_px) {
                        let d = pos_px - from;
                        n.camera.orbit(-0.008 * d.x, 0.008 * d.y);
                    }
                }
                InputEvent::PointerUp { .. } => self.drag_px = None,
                InputEvent::Wheel { lines } => n.camera.zoom(0.9f32.powf(lines)),
                _ => {}
            },
            Room::Building(_) => {}
        }
    }

    /// Replaces the room by the scene `spec` (the old one's threads are told to stop),
    /// remaking `drawing`'s renderer; on failure the current scene stays and the panel
    /// says why.
    pub fn switch(&mut self, spec: &str, drawing: Option<(&wgpu::Device, &mut Drawing)>) {
        let opened = crate::scenes::open(spec).and_then(|o| room_of(o, &self.haptics));
        match opened {
            Ok((room, source)) => {
                self.room = room;
                self.hud.scene_source = source;
                self.hud.message = None;
                if let Some((device, d)) = drawing {
                    d.renderer = renderer_for(device, &self.room, d.scene_format);
                    d.landscape = None;
                }
            }
            Err(e) => self.hud.message = Some(format!("cannot open {spec}: {e:#}")),
        }
    }

    /// The room's frame: the scene pass (palpation) or the landscape (network), then
    /// its interface painted over it.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &mut self,
        gpu: &Gpu,
        drawing: &mut Drawing,
        view: &wgpu::TextureView,
        ui_view: &wgpu::TextureView,
        size: (u32, u32),
        scale: f32,
        raw: egui::RawInput,
        dt_s: f64,
    ) -> (wgpu::CommandEncoder, egui::PlatformOutput) {
        let (room, hud) = (&mut self.room, &mut self.hud);
        room.advance(hud);
        if drawing.renderer.is_none() && matches!(room, Room::Palpation(_)) {
            // A build that finished into a palpation scene, or a renderer dropped.
            drawing.renderer = renderer_for(&gpu.device, room, drawing.scene_format);
        }
        let mut encoder = match (&mut *room, drawing.renderer.as_mut()) {
            (Room::Palpation(session), Some(r)) => {
                session.deform_on = hud
                    .deform_on
                    .unwrap_or_else(|| DeformOn::preferred(gpu.is_software()));
                let input = session.frame();
                r.encode_frame(gpu, view, size, &input)
            }
            (Room::Network(n), _) => {
                n.frame(dt_s);
                let format = drawing.scene_format;
                let l = drawing
                    .landscape
                    .get_or_insert_with(|| Landscape::new(&gpu.device, format));
                l.set(&gpu.device, n.window.as_ref(), n.window_generation);
                l.encode(&gpu.device, &gpu.queue, view, size, &n.camera)
            }
            _ => crate::render::clear_frame(&gpu.device, view),
        };
        let output = drawing.overlay.paint(
            &gpu.device,
            &gpu.queue,
            &mut encoder,
            ui_view,
            size,
            scale,
            raw,
            |ctx| match room {
                Room::Palpation(session) => crate::ui::show(ctx, session, hud),
                Room::Network(n) => crate::network::show(ctx, n, hud),
                Room::Building(b) => {
                    if crate::network::build::show(ctx, b, hud) {
                        b.cancel();
                    }
                }
            },
        );
        (encoder, output)
    }
}

/// The room for an opened scene (a palpation scene starts its force thread; a network
/// without a meta-model starts its build).
pub fn room_of(opened: Opened, haptics: &AtomicHaptics) -> anyhow::Result<(Room, String)> {
    Ok(match opened {
        Opened::Palpation(loaded) => {
            let source = loaded.source.clone();
            let session = loaded.session(Box::new(haptics.clone()))?;
            (Room::Palpation(Box::new(session)), source)
        }
        Opened::Network { room, source } => (Room::Network(room), source),
        Opened::NetworkSource {
            network,
            toml,
            source,
        } => match crate::network::prepare(*network, toml.as_deref())? {
            Prepared::Ready(room) => (Room::Network(room), source),
            Prepared::Building(b) => (Room::Building(b), source),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Switching scenes replaces the room (a build in flight is told to stop), and a
    /// scene that cannot be opened leaves the current one with a message.
    #[test]
    fn switching_scenes_replaces_the_room_or_says_why_not() {
        let mut shell = Shell::open("liver").expect("the built-in liver");
        // The built-in tissue's measured depth reaches the session (the panel's flag).
        let Room::Palpation(session) = &shell.room else {
            panic!("the built-in liver is a palpation scene")
        };
        let goals = session
            .law
            .as_deref()
            .and_then(|t| crate::session::GoalDepths::of(&t.bound.law));
        assert!(goals.is_some(), "the built-in tissue records its checks");
        assert_eq!(session.goals_to_mm, goals);
        let dir = tempfile::tempdir().expect("tempdir");
        let toml = dir.path().join("net.toml");
        std::fs::copy(
            concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../assets/networks/cascade.toml"
            ),
            &toml,
        )
        .expect("copy");
        shell.switch(toml.to_str().expect("utf-8"), None);
        assert!(
            matches!(shell.room, Room::Building(_)),
            "{:?}",
            shell.hud.message
        );
        shell.switch(
            &dir.path().join("nothing.palpa").display().to_string(),
            None,
        );
        assert!(matches!(shell.room, Room::Building(_)), "the room stays");
        assert!(
            shell
                .hud
                .message
                .as_deref()
                .is_some_and(|m| m.contains("nothing.palpa"))
        );
        shell.switch("liver", None);
        assert!(matches!(shell.room, Room::Palpation(_)));
        assert!(shell.hud.message.is_none());
    }
}
