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
//! dropped on `suspended`. What outlives a surface or a device (the room, the
//! interface state) is the [`Shell`]; this module only turns winit's events into its
//! calls and owns the window, the surface and the GPU.

use std::sync::Arc;
use std::time::Instant;

use anyhow::Context;
use glam::Vec2;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, TouchPhase, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

use crate::gamepad::Gamepads;
use crate::input::{Button, InputEvent, PointerId};
use crate::render::deform::DeformOn;
use crate::render::gpu::Gpu;
use crate::render::offscreen::{FORMAT, Offscreen};
use crate::shell::{Drawing, Room, Shell};
use crate::swapchain::SurfaceHost;

/// GPU state, created at the first resume (it needs a surface to pick an adapter).
struct Graphics {
    gpu: Gpu,
    drawing: Drawing,
    egui: egui_winit::State,
}

/// The app: the [`Shell`] (everything that outlives a surface) and the window, its
/// surface and the GPU.
pub struct App {
    shell: Shell,
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
    /// The GPU device was lost: a new one is made before the next frame, the room
    /// (session, force loop) kept.
    gpu_lost: bool,
}

impl std::fmt::Debug for App {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("App")
            .field("shell", &self.shell)
            .finish_non_exhaustive()
    }
}

impl App {
    /// Opens `scene` (`liver` or a file); if it cannot be opened, the built-in scene is
    /// shown with a notice saying why.
    pub fn new(scene: &str) -> anyhow::Result<Self> {
        Ok(App {
            shell: Shell::open(scene)?,
            gamepads: Gamepads::new(),
            window: None,
            surface: SurfaceHost::default(),
            graphics: None,
            fatal: None,
            started: Instant::now(),
            last_frame: Instant::now(),
            last_pointer_px: Vec2::ZERO,
            gpu_lost: false,
        })
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
            let drawing = Drawing::new(
                &gpu.device,
                &self.shell.room,
                formats.scene,
                formats.surface,
                gpu.is_software(),
            );
            let egui = egui_winit::State::new(
                drawing.overlay.ctx.clone(),
                egui::ViewportId::ROOT,
                &window,
                Some(window.scale_factor() as f32),
                None,
                Some(gpu.device.limits().max_texture_dimension_2d as usize),
            );
            tracing::info!("rendering on {:?}", gpu.report());
            self.graphics = Some(Graphics { gpu, drawing, egui });
        } else if let Some(g) = &self.graphics {
            // Resumed after a suspend: a new surface for the same device.
            self.surface.create(&g.gpu.instance, Arc::clone(&window))?;
            self.surface.configure(&g.gpu)?;
        }
        let size = window.inner_size();
        self.shell.resumed((size.width, size.height));
        Ok(())
    }

    fn redraw(&mut self) {
        let frame_start = Instant::now();
        let viewport = self.shell.viewport();
        match (self.gamepads.poll(), &mut self.shell.room) {
            (Some(ev), Room::Palpation(session)) => session.handle(ev, viewport),
            (
                Some(InputEvent::Gamepad {
                    left,
                    right,
                    trigger,
                    dt_s,
                    ..
                }),
                Room::Network(n),
            ) => n.steer(left.into(), right.x, trigger, dt_s),
            _ => {}
        }
        self.gamepads.rumble(&self.shell.haptics);
        self.shell.hud.gamepad = self.gamepads.name();
        if let Some(g) = &self.graphics {
            if let Some(m) = g.gpu.health.take_message() {
                self.shell.hud.message = Some(m);
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
        let (encoder, output) = self.shell.encode(
            &g.gpu,
            &mut g.drawing,
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
        if self.shell.hud.screenshot_requested {
            self.shell.hud.screenshot_requested = false;
            match self.screenshot(size) {
                Ok(p) => self.shell.hud.last_screenshot = Some(p),
                Err(e) => self.shell.hud.message = Some(format!("screenshot failed: {e:#}")),
            }
        }
        self.shell
            .hud
            .frame_ms
            .push(frame_start.elapsed().as_secs_f64() * 1e3);
        if let Some(spec) = self.shell.hud.switch_to.take() {
            let drawing = self
                .graphics
                .as_mut()
                .map(|g| (&g.gpu.device, &mut g.drawing));
            self.shell.switch(&spec, drawing);
        }
    }

    /// Renders the current frame offscreen (with the interface) and saves it as PNG in
    /// the working folder.
    fn screenshot(&mut self, size: (u32, u32)) -> anyhow::Result<String> {
        let g = self.graphics.as_mut().context("no GPU yet")?;
        let target = Offscreen::new(&g.gpu.device, size, g.gpu.can_reinterpret());
        let mut drawing = Drawing::new(
            &g.gpu.device,
            &self.shell.room,
            FORMAT,
            target.ui_format,
            g.gpu.is_software(),
        );
        let raw = crate::overlay::headless_input(
            size,
            1.0,
            crate::layout::Insets::default(),
            self.started.elapsed().as_secs_f64(),
        );
        let (mut encoder, _) = self.shell.encode(
            &g.gpu,
            &mut drawing,
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

    /// Hands an input event to the shell, keeping the mouse's position.
    fn pointer(&mut self, ev: InputEvent) {
        if let InputEvent::PointerMove {
            id: PointerId::Mouse,
            pos_px,
            ..
        } = ev
        {
            self.last_pointer_px = pos_px;
        }
        self.shell.pointer(ev);
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        match self.start_graphics(event_loop) {
            Ok(()) => {}
            // A device exists but this resume gave no usable surface (a window not yet
            // ready, or gone again): wait for the next resume, keeping the session.
            Err(e) if self.graphics.is_some() => {
                tracing::warn!("resumed without a usable surface: {e:#}");
                self.shell.suspended();
            }
            Err(e) => {
                self.fatal = Some(e);
                event_loop.exit();
            }
        }
    }

    fn suspended(&mut self, _event_loop: &ActiveEventLoop) {
        self.surface.suspend();
        self.shell.suspended();
    }

    fn memory_warning(&mut self, _event_loop: &ActiveEventLoop) {
        self.shell
            .memory_warning(self.graphics.as_mut().map(|g| &mut g.drawing));
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
                self.shell.resized((size.width, size.height));
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
                self.shell.hud.touch_seen = true;
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
                    Key::Named(NamedKey::F1) => {
                        self.shell.hud.show_help = !self.shell.hud.show_help;
                    }
                    Key::Character(c) if c.eq_ignore_ascii_case("h") => {
                        self.shell.hud.show_help = !self.shell.hud.show_help;
                    }
                    Key::Character(c) if c.eq_ignore_ascii_case("d") => {
                        if let Room::Palpation(session) = &self.shell.room {
                            self.shell.hud.deform_on = Some(match session.deform_on {
                                DeformOn::Gpu => DeformOn::Cpu,
                                DeformOn::Cpu => DeformOn::Gpu,
                            });
                        }
                    }
                    Key::Character(c) if c.eq_ignore_ascii_case("c") => {
                        if let Room::Palpation(session) = &mut self.shell.room {
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

/// Runs the app on `event_loop` until the window closes.
pub fn run_on(event_loop: EventLoop<()>, scene: &str) -> anyhow::Result<()> {
    run_app(event_loop, App::new(scene)?)
}

fn run_app(event_loop: EventLoop<()>, mut app: App) -> anyhow::Result<()> {
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
    // The scene first: a window shows why a scene did not open (and the built-in one
    // instead), and without a window that reason goes in the error.
    let app = App::new(scene)?;
    let event_loop = EventLoop::new().map_err(|e| {
        let scene = match &app.shell.hud.message {
            Some(why) => format!(
                " The scene did not open either: {}.",
                why.trim_end_matches(crate::scenes::SHOWING_BUILT_IN)
            ),
            None => String::new(),
        };
        anyhow::anyhow!(
            "cannot open a window ({e}): no display found. Set DISPLAY or WAYLAND_DISPLAY, \
             run under `xvfb-run`, or use `palpa headless` to render offscreen.{scene}"
        )
    })?;
    run_app(event_loop, app)
}
