//! The one owner of the window surface's lifecycle: created on resume, dropped on
//! suspend (Android destroys the native window then), reconfigured when resized,
//! outdated or suboptimal, recreated when lost. The scene state lives elsewhere and
//! survives all of it.

use std::sync::Arc;

use anyhow::{Context, anyhow};
use winit::window::Window;

use crate::render::gpu::Gpu;

/// A frame to draw into: the scene goes to `view` (sRGB), egui to `ui_view`.
#[derive(Debug)]
pub struct Frame {
    pub texture: wgpu::SurfaceTexture,
    pub view: wgpu::TextureView,
    pub ui_view: wgpu::TextureView,
}

/// The surface of the current window, if any.
#[derive(Debug, Default)]
pub struct SurfaceHost {
    surface: Option<wgpu::Surface<'static>>,
    config: Option<wgpu::SurfaceConfiguration>,
    window: Option<Arc<Window>>,
}

/// Formats chosen for a surface: the surface's own (non-sRGB where offered, for egui)
/// and the sRGB view the scene renders through.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Formats {
    pub surface: wgpu::TextureFormat,
    pub scene: wgpu::TextureFormat,
}

impl SurfaceHost {
    /// Creates the surface for `window`.
    pub fn create(&mut self, instance: &wgpu::Instance, window: Arc<Window>) -> anyhow::Result<()> {
        let surface = instance
            .create_surface(Arc::clone(&window))
            .map_err(|e| anyhow!("cannot create a surface for the window: {e}"))?;
        self.surface = Some(surface);
        self.window = Some(window);
        Ok(())
    }

    pub fn surface(&self) -> Option<&wgpu::Surface<'static>> {
        self.surface.as_ref()
    }

    /// Configures for the window's current size; returns the formats in use.
    pub fn configure(&mut self, gpu: &Gpu) -> anyhow::Result<Formats> {
        let (surface, window) = match (&self.surface, &self.window) {
            (Some(s), Some(w)) => (s, w),
            _ => anyhow::bail!("no surface to configure"),
        };
        let size = window.inner_size();
        let caps = surface.get_capabilities(&gpu.adapter);
        // Where the device can view the surface in its sRGB twin, the surface is plain
        // (egui blends in gamma space) and the scene draws through the sRGB view; on
        // GL it cannot, and both draw into an sRGB surface.
        let reinterpret = gpu.can_reinterpret();
        let surface_format = caps
            .formats
            .iter()
            .copied()
            .find(|f| match reinterpret {
                true => !f.is_srgb() && f.add_srgb_suffix() != *f,
                false => f.is_srgb(),
            })
            .or_else(|| caps.formats.first().copied())
            .context("the surface supports no format with this adapter")?;
        let scene = match reinterpret {
            true => surface_format.add_srgb_suffix(),
            false => surface_format,
        };
        let mut config = surface
            .get_default_config(&gpu.adapter, size.width.max(1), size.height.max(1))
            .context("the surface is not supported by the adapter")?;
        config.format = surface_format;
        config.view_formats = if scene != surface_format {
            vec![scene]
        } else {
            vec![]
        };
        config.present_mode = wgpu::PresentMode::AutoVsync;
        surface.configure(&gpu.device, &config);
        self.config = Some(config);
        Ok(Formats {
            surface: surface_format,
            scene,
        })
    }

    /// Drops the surface (suspend); the window handle goes with it.
    pub fn suspend(&mut self) {
        self.surface = None;
        self.config = None;
        self.window = None;
    }

    /// Size in pixels of the configured surface.
    pub fn size(&self) -> Option<(u32, u32)> {
        self.config.as_ref().map(|c| (c.width, c.height))
    }

    /// Resizes (a zero size, e.g. minimized, is skipped until the window is back).
    pub fn resize(&mut self, gpu: &Gpu, width: u32, height: u32) {
        if width == 0 || height == 0 {
            return;
        }
        if let (Some(s), Some(c)) = (&self.surface, self.config.as_mut()) {
            c.width = width;
            c.height = height;
            s.configure(&gpu.device, c);
        }
    }

    /// The next frame, or None when there is nothing to draw into now (minimized,
    /// occluded, timed out, or just reconfigured after being outdated or lost).
    pub fn acquire(&mut self, gpu: &Gpu, instance: &wgpu::Instance) -> Option<Frame> {
        let surface = self.surface.as_ref()?;
        let config = self.config.as_ref()?;
        if config.width == 0 || config.height == 0 {
            return None;
        }
        let texture = match surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => t,
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => {
                // Draw this one; reconfigure for the next.
                surface.configure(&gpu.device, config);
                t
            }
            wgpu::CurrentSurfaceTexture::Timeout
            | wgpu::CurrentSurfaceTexture::Occluded
            | wgpu::CurrentSurfaceTexture::Validation => return None,
            wgpu::CurrentSurfaceTexture::Outdated => {
                surface.configure(&gpu.device, config);
                return None;
            }
            wgpu::CurrentSurfaceTexture::Lost => {
                tracing::warn!("surface lost: recreating it");
                let window = self.window.clone()?;
                if let Err(e) = self.create(instance, window) {
                    tracing::error!("{e:#}");
                } else if let Err(e) = self.configure(gpu) {
                    tracing::error!("{e:#}");
                }
                return None;
            }
        };
        let scene_format = config
            .view_formats
            .first()
            .copied()
            .unwrap_or(config.format);
        let view = texture.texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(scene_format),
            ..Default::default()
        });
        let ui_view = texture.texture.create_view(&Default::default());
        Some(Frame {
            texture,
            view,
            ui_view,
        })
    }
}
