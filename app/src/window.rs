//! The interactive app in a window (winit): events to [`InputEvent`]s, the visual loop
//! at the display rate (vsync), the egui interface, gamepads, screenshots.
//!
//! ```text
//! winit event loop (main thread)           palpa-force (1 kHz)
//! ──────────────────────────────           ───────────────────
//! events → egui first, then Controls       reads the latest ProbeCommand
//! RedrawRequested:                         evaluates the contact (9 rows)
//!   gamepad poll, rumble                   publishes the latest ForceSample
//!   Session::frame → coefficients
//!   compute deform + draw + egui → present
//! ```
//!
//! Nothing here is desktop-only: on Android the same handler runs under
//! `android_main` ([`crate::platform`]), with the surface created on `resumed` and
//! dropped on `suspended`.

use std::sync::Arc;
use std::time::Instant;

use anyhow::Context;
use glam::Vec2;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, TouchPhase, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

use crate::force::AtomicHaptics;
use crate::gamepad::Gamepads;
use crate::input::{Button, InputEvent, PointerId};
use crate::network::build::{BuildState, NetworkBuild};
use crate::network::{NetworkRoom, Prepared};
use crate::overlay::Overlay;
use crate::render::Renderer;
use crate::render::gpu::Gpu;
use crate::render::landscape::Landscape;
use crate::render::offscreen::{FORMAT, Offscreen, UI_FORMAT};
use crate::scenes::Opened;
use crate::session::Session;
use crate::swapchain::SurfaceHost;
use crate::ui::Hud;

/// GPU state, created at the first resume (it needs a surface to pick an adapter).
struct Graphics {
    gpu: Gpu,
    /// The palpation scene's renderer (a network scene draws with egui only).
    renderer: Option<Renderer>,
    /// The colour format the renderer draws in (for a renderer of a new scene).
    scene_format: wgpu::TextureFormat,
    /// The network scene's 3-D view (made on its first frame).
    landscape: Option<Landscape>,
    overlay: Overlay,
    egui: egui_winit::State,
}

/// The room the app shows: each kind of scene keeps to its own.
#[derive(Debug)]
enum Room {
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

/// The app: everything that outlives a surface.
pub struct App {
    room: Room,
    hud: Hud,
    haptics: AtomicHaptics,
    gamepads: Gamepads,
    window: Option<Arc<Window>>,
    surface: SurfaceHost,
    graphics: Option<Graphics>,
    /// A failure that ends the app (reported by [`run`] after the loop).
    fatal: Option<anyhow::Error>,
    started: Instant,
    last_frame: Instant,
    /// Where the mouse last was (mouse button events carry no position).
    last_pointer_px: Vec2,
    /// Where a drag on the network scene's landscape last was.
    drag_px: Option<Vec2>,
    /// The GPU device was lost: a new one is made before the next frame, the room
    /// (session, force loop) kept.
    gpu_lost: bool,
}

impl std::fmt::Debug for App {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("App")
            .field("room", &self.room)
            .finish_non_exhaustive()
    }
}

impl App {
    /// Opens `scene` (`liver` or a file); if it cannot be opened, the built-in scene is
    /// shown with a notice saying why.
    pub fn new(scene: &str) -> anyhow::Result<Self> {
        let (opened, message) = crate::scenes::open_or_default(scene)?;
        let haptics = AtomicHaptics::default();
        let (room, source) = room_of(opened, &haptics)?;
        let mut hud = Hud::new(source);
        hud.message = message;
        Ok(App {
            room,
            hud,
            haptics,
            gamepads: Gamepads::new(),
            window: None,
            surface: SurfaceHost::default(),
            graphics: None,
            fatal: None,
            started: Instant::now(),
            last_frame: Instant::now(),
            last_pointer_px: Vec2::ZERO,
            drag_px: None,
            gpu_lost: false,
        })
    }

    /// Builds the room's renderer (palpation only).
    fn renderer_for(&self, device: &wgpu::Device, format: wgpu::TextureFormat) -> Option<Renderer> {
        match &self.room {
            Room::Palpation(s) => Some(Renderer::new(device, format, &s.scene)),
            Room::Network(_) | Room::Building(_) => None,
        }
    }

    /// The room's frame: the scene pass (palpation) or a cleared target (network), then
    /// its interface painted over it.
    #[allow(clippy::too_many_arguments)]
    fn encode(
        room: &mut Room,
        hud: &mut Hud,
        gpu: &Gpu,
        renderer: Option<&mut Renderer>,
        landscape: &mut Option<Landscape>,
        format: wgpu::TextureFormat,
        overlay: &mut Overlay,
        view: &wgpu::TextureView,
        ui_view: &wgpu::TextureView,
        size: (u32, u32),
        scale: f32,
        raw: egui::RawInput,
        dt_s: f64,
    ) -> (wgpu::CommandEncoder, egui::PlatformOutput) {
        room.advance(hud);
        let mut encoder = match (&mut *room, renderer) {
            (Room::Palpation(session), Some(r)) => {
                let input = session.frame();
                r.encode_frame(gpu, view, size, &input)
            }
            (Room::Network(n), _) => {
                n.frame(dt_s);
                let l = landscape.get_or_insert_with(|| Landscape::new(&gpu.device, format));
                l.set(&gpu.device, n.window.as_ref(), n.window_generation);
                l.encode(&gpu.device, &gpu.queue, view, size, &n.camera)
            }
            _ => crate::render::clear_frame(&gpu.device, view),
        };
        let output = overlay.paint(
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

    fn viewport(&self) -> Vec2 {
        self.surface
            .size()
            .map_or(Vec2::ONE, |(w, h)| Vec2::new(w as f32, h as f32))
    }

    fn start_graphics(&mut self, event_loop: &ActiveEventLoop) -> anyhow::Result<()> {
        let window = match &self.window {
            Some(w) => Arc::clone(w),
            None => {
                let attrs = Window::default_attributes()
                    .with_title("palpa")
                    .with_inner_size(winit::dpi::LogicalSize::new(1280.0, 720.0));
                let w = Arc::new(
                    event_loop
                        .create_window(attrs)
                        .context("cannot open a window")?,
                );
                self.window = Some(Arc::clone(&w));
                w
            }
        };
        if self.graphics.is_none() {
            let desc = wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(
                event_loop.owned_display_handle(),
            ));
            let instance = wgpu::Instance::new(desc);
            self.surface.create(&instance, Arc::clone(&window))?;
            let gpu = Gpu::with_instance(instance, self.surface.surface())?;
            let formats = self.surface.configure(&gpu)?;
            let renderer = self.renderer_for(&gpu.device, formats.scene);
            let overlay = Overlay::new(&gpu.device, formats.surface);
            let egui = egui_winit::State::new(
                overlay.ctx.clone(),
                egui::ViewportId::ROOT,
                &window,
                Some(window.scale_factor() as f32),
                None,
                Some(gpu.device.limits().max_texture_dimension_2d as usize),
            );
            tracing::info!("rendering on {:?}", gpu.report());
            self.graphics = Some(Graphics {
                gpu,
                renderer,
                scene_format: formats.scene,
                landscape: None,
                overlay,
                egui,
            });
        } else if let Some(g) = &self.graphics {
            // Resumed after a suspend: a new surface for the same device.
            self.surface.create(&g.gpu.instance, Arc::clone(&window))?;
            self.surface.configure(&g.gpu)?;
        }
        Ok(())
    }

    fn redraw(&mut self) {
        let frame_start = Instant::now();
        let viewport = self.viewport();
        match (self.gamepads.poll(), &mut self.room) {
            (Some(ev), Room::Palpation(session)) => session.handle(ev, viewport),
            (
                Some(InputEvent::Gamepad {
                    left,
                    right,
                    trigger,
                    dt_s,
                }),
                Room::Network(n),
            ) => n.steer(left.into(), right.x, trigger, dt_s),
            _ => {}
        }
        self.gamepads.rumble(&self.haptics);
        self.hud.gamepad = self.gamepads.name();
        if let Some(g) = &self.graphics {
            if let Some(m) = g.gpu.health.take_message() {
                self.hud.message = Some(m);
            }
            if g.gpu.health.is_lost() {
                self.graphics = None;
                self.gpu_lost = true;
                return;
            }
        }
        let (Some(g), Some(window)) = (self.graphics.as_mut(), self.window.clone()) else {
            return;
        };
        let Some(frame) = self.surface.acquire(&g.gpu, &g.gpu.instance) else {
            return;
        };
        let size = (
            frame.texture.texture.width(),
            frame.texture.texture.height(),
        );
        let raw = g.egui.take_egui_input(&window);
        let dt_s = self.last_frame.elapsed().as_secs_f64();
        self.last_frame = Instant::now();
        let (encoder, output) = Self::encode(
            &mut self.room,
            &mut self.hud,
            &g.gpu,
            g.renderer.as_mut(),
            &mut g.landscape,
            g.scene_format,
            &mut g.overlay,
            &frame.view,
            &frame.ui_view,
            size,
            window.scale_factor() as f32,
            raw,
            dt_s,
        );
        g.egui.handle_platform_output(&window, output);
        g.gpu.queue.submit([encoder.finish()]);
        window.pre_present_notify();
        g.gpu.queue.present(frame.texture);
        if self.hud.screenshot_requested {
            self.hud.screenshot_requested = false;
            match self.screenshot(size) {
                Ok(p) => self.hud.last_screenshot = Some(p),
                Err(e) => self.hud.message = Some(format!("screenshot failed: {e:#}")),
            }
        }
        self.hud
            .frame_ms
            .push(frame_start.elapsed().as_secs_f64() * 1e3);
        if let Some(spec) = self.hud.switch_to.take() {
            self.switch(&spec);
        }
    }

    /// Renders the current frame offscreen (with the interface) and saves it as PNG in
    /// the working folder.
    fn screenshot(&mut self, size: (u32, u32)) -> anyhow::Result<String> {
        let g = self.graphics.as_mut().context("no GPU yet")?;
        let target = Offscreen::new(&g.gpu.device, size);
        let mut overlay = Overlay::new(&g.gpu.device, UI_FORMAT);
        let raw = crate::overlay::headless_input(
            size,
            1.0,
            crate::layout::Insets::default(),
            self.started.elapsed().as_secs_f64(),
        );
        let mut renderer = match &self.room {
            Room::Palpation(s) => Some(Renderer::new(&g.gpu.device, FORMAT, &s.scene)),
            Room::Network(_) | Room::Building(_) => None,
        };
        let (mut encoder, _) = Self::encode(
            &mut self.room,
            &mut self.hud,
            &g.gpu,
            renderer.as_mut(),
            &mut None,
            FORMAT,
            &mut overlay,
            &target.view,
            &target.ui_view,
            size,
            1.0,
            raw,
            0.0,
        );
        target.encode_copy(&mut encoder);
        g.gpu.queue.submit([encoder.finish()]);
        let image = target.read(&g.gpu.device)?;
        let secs = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let path = format!("palpa-screenshot-{secs}.png");
        image.save_png(std::path::Path::new(&path))?;
        Ok(path)
    }

    /// Replaces the room by the scene `spec` (the old one's threads are told to stop);
    /// on failure the current scene stays and the panel says why.
    fn switch(&mut self, spec: &str) {
        let opened = crate::scenes::open(spec).and_then(|o| room_of(o, &self.haptics));
        match opened {
            Ok((room, source)) => {
                self.room = room;
                self.hud.scene_source = source;
                self.hud.message = None;
                if let Some(g) = self.graphics.as_mut() {
                    g.renderer = match &self.room {
                        Room::Palpation(s) => {
                            Some(Renderer::new(&g.gpu.device, g.scene_format, &s.scene))
                        }
                        Room::Network(_) | Room::Building(_) => None,
                    };
                }
            }
            Err(e) => self.hud.message = Some(format!("cannot open {spec}: {e:#}")),
        }
    }

    /// Hands an input event to the room (the network room is steered by its panel).
    fn pointer(&mut self, ev: InputEvent) {
        if let InputEvent::PointerMove {
            id: PointerId::Mouse,
            pos_px,
            ..
        } = ev
        {
            self.last_pointer_px = pos_px;
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
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if let Err(e) = self.start_graphics(event_loop) {
            self.fatal = Some(e);
            event_loop.exit();
        }
    }

    fn suspended(&mut self, _event_loop: &ActiveEventLoop) {
        self.surface.suspend();
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        if let (Some(g), Some(w)) = (self.graphics.as_mut(), self.window.as_ref())
            && g.egui.on_window_event(w, &event).consumed
        {
            return;
        }
        let t = self.started.elapsed().as_secs_f64();
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(g) = &self.graphics {
                    self.surface.resize(&g.gpu, size.width, size.height);
                }
            }
            WindowEvent::RedrawRequested => self.redraw(),
            WindowEvent::CursorMoved { position, .. } => self.pointer(InputEvent::PointerMove {
                id: PointerId::Mouse,
                pos_px: Vec2::new(position.x as f32, position.y as f32),
                time_s: t,
            }),
            WindowEvent::MouseInput { state, button, .. } => {
                let button = match button {
                    MouseButton::Left => Button::Primary,
                    MouseButton::Right => Button::Secondary,
                    MouseButton::Middle => Button::Middle,
                    _ => return,
                };
                let ev = match state {
                    ElementState::Pressed => InputEvent::PointerDown {
                        id: PointerId::Mouse,
                        button,
                        pos_px: self.cursor(),
                        time_s: t,
                    },
                    ElementState::Released => InputEvent::PointerUp {
                        id: PointerId::Mouse,
                        time_s: t,
                    },
                };
                self.pointer(ev);
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.pointer(InputEvent::Wheel { lines });
            }
            WindowEvent::Touch(touch) => {
                // From the first touch on, controls get finger sizes.
                self.hud.touch_seen = true;
                let id = PointerId::Touch(touch.id);
                let pos_px = Vec2::new(touch.location.x as f32, touch.location.y as f32);
                self.pointer(match touch.phase {
                    TouchPhase::Started => InputEvent::PointerDown {
                        id,
                        button: Button::Primary,
                        pos_px,
                        time_s: t,
                    },
                    TouchPhase::Moved => InputEvent::PointerMove {
                        id,
                        pos_px,
                        time_s: t,
                    },
                    TouchPhase::Ended | TouchPhase::Cancelled => {
                        InputEvent::PointerUp { id, time_s: t }
                    }
                });
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                match event.logical_key {
                    Key::Named(NamedKey::F1) => self.hud.show_help = !self.hud.show_help,
                    Key::Character(c) if c.eq_ignore_ascii_case("h") => {
                        self.hud.show_help = !self.hud.show_help;
                    }
                    Key::Character(c) if c.eq_ignore_ascii_case("c") => {
                        if let Room::Palpation(session) = &mut self.room {
                            session.colormap_mm = match session.colormap_mm {
                                Some(_) => None,
                                None => Some(10.0),
                            };
                        }
                    }
                    _ => {}
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.gpu_lost {
            self.gpu_lost = false;
            match self.start_graphics(event_loop) {
                Ok(()) => tracing::warn!("a new GPU device replaces the lost one"),
                Err(e) => {
                    self.fatal =
                        Some(e.context("the GPU device was lost and no new one could be made"));
                    event_loop.exit();
                    return;
                }
            }
        }
        // Continuous redraw: vsync (AutoVsync) paces the loop at the display rate.
        match &self.window {
            Some(w) if self.surface.size().is_some() => {
                event_loop.set_control_flow(ControlFlow::Poll);
                w.request_redraw();
            }
            _ => event_loop.set_control_flow(ControlFlow::WaitUntil(
                Instant::now() + crate::gamepad::POLL_INTERVAL,
            )),
        }
    }
}

impl App {
    /// The last known cursor position (egui-winit tracks it; we keep our own copy).
    fn cursor(&self) -> Vec2 {
        self.last_pointer_px
    }
}

/// The room for an opened scene (a palpation scene starts its force thread; a network
/// without a meta-model starts its build).
fn room_of(opened: Opened, haptics: &AtomicHaptics) -> anyhow::Result<(Room, String)> {
    Ok(match opened {
        Opened::Palpation(loaded) => (
            Room::Palpation(Box::new(
                Session::with_law(loaded.scene, loaded.law, Box::new(haptics.clone()))
                    .context("starting the force thread")?,
            )),
            loaded.source,
        ),
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

/// Runs the app on `event_loop` until the window closes.
pub fn run_on(event_loop: EventLoop<()>, scene: &str) -> anyhow::Result<()> {
    let mut app = App::new(scene)?;
    event_loop
        .run_app(&mut app)
        .context("the event loop failed")?;
    match app.fatal.take() {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// The desktop app: opens a window on `scene`.
pub fn run(scene: &str) -> anyhow::Result<()> {
    let event_loop = EventLoop::new().map_err(|e| {
        anyhow::anyhow!(
            "cannot open a window ({e}): no display found. Set DISPLAY or WAYLAND_DISPLAY, \
             run under `xvfb-run`, or use `palpa headless` to render offscreen"
        )
    })?;
    run_on(event_loop, scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Switching scenes replaces the room (a build in flight is told to stop), and a
    /// scene that cannot be opened leaves the current one with a message.
    #[test]
    fn switching_scenes_replaces_the_room_or_says_why_not() {
        let mut app = App::new("liver").expect("the built-in liver");
        assert!(matches!(app.room, Room::Palpation(_)));
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
        app.switch(toml.to_str().expect("utf-8"));
        assert!(
            matches!(app.room, Room::Building(_)),
            "{:?}",
            app.hud.message
        );
        app.switch(&dir.path().join("nothing.palpa").display().to_string());
        assert!(matches!(app.room, Room::Building(_)), "the room stays");
        assert!(
            app.hud
                .message
                .as_deref()
                .is_some_and(|m| m.contains("nothing.palpa"))
        );
        app.switch("liver");
        assert!(matches!(app.room, Room::Palpation(_)));
        assert!(app.hud.message.is_none());
    }
}
