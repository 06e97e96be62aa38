//! Painting egui on top of a rendered frame, into any texture view (window or offscreen).

/// The egui context and its wgpu renderer.
pub struct Overlay {
    pub ctx: egui::Context,
    renderer: egui_wgpu::Renderer,
}

impl std::fmt::Debug for Overlay {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Overlay").finish_non_exhaustive()
    }
}

impl Overlay {
    /// `software`: the adapter rasterizes on the CPU ([`crate::render::gpu::Gpu::is_software`]).
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat, software: bool) -> Self {
        let ctx = egui::Context::default();
        let mut visuals = egui::Visuals::dark();
        if software {
            // A window's shadow is a blurred rectangle blended under the whole panel: on
            // lavapipe it took 10 of a 45 ms frame (1280x720, the drawer open: `palpa
            // headless`, p50 44.7 → 33.7 ms). The panel's stroke still outlines it.
            visuals.window_shadow = egui::epaint::Shadow::NONE;
            visuals.popup_shadow = egui::epaint::Shadow::NONE;
        }
        ctx.set_visuals(visuals);
        Overlay {
            ctx,
            renderer: egui_wgpu::Renderer::new(
                device,
                format,
                egui_wgpu::RendererOptions::default(),
            ),
        }
    }

    /// Runs `ui` for one pass and records its painting into `encoder` over `target`
    /// (loading what is there). Returns the platform output (cursor, clipboard, links).
    #[allow(clippy::too_many_arguments)]
    pub fn paint(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        size_px: (u32, u32),
        pixels_per_point: f32,
        input: egui::RawInput,
        mut ui: impl FnMut(&egui::Context),
    ) -> egui::PlatformOutput {
        let mut output = self.ctx.run_pass(input, |ctx| ui(ctx));
        let jobs = self.ctx.tessellate(output.shapes, output.pixels_per_point);
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                self.renderer.update_texture(device, queue, *id, delta);
            }
        }
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [size_px.0, size_px.1],
            pixels_per_point,
        };
        let extra = self
            .renderer
            .update_buffers(device, queue, encoder, &jobs, &screen);
        if !extra.is_empty() {
            queue.submit(extra);
        }
        {
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("egui"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: target,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Load,
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            self.renderer.render(&mut pass, &jobs, &screen);
        }
        for id in &output.textures_delta.free {
            self.renderer.free_texture(id);
        }
        // Applied above; epaint asserts (in debug builds) that deltas are not dropped unseen.
        output.textures_delta.clear();
        output.platform_output
    }
}

/// Raw input for a frame without a window (headless): the screen size, its density and
/// safe-area insets (what a phone's notch and home indicator take), and the time.
pub fn headless_input(
    size_px: (u32, u32),
    pixels_per_point: f32,
    insets: crate::layout::Insets,
    time_s: f64,
) -> egui::RawInput {
    let size = egui::vec2(size_px.0 as f32, size_px.1 as f32) / pixels_per_point;
    let mut input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, size)),
        safe_area_insets: Some(egui::SafeAreaInsets(egui::epaint::MarginF32 {
            left: insets.left,
            right: insets.right,
            top: insets.top,
            bottom: insets.bottom,
        })),
        time: Some(time_s),
        ..Default::default()
    };
    if let Some(v) = input.viewports.get_mut(&egui::ViewportId::ROOT) {
        v.native_pixels_per_point = Some(pixels_per_point);
    }
    input
}
