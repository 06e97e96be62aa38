//! The network scene's 3-D view: the joint of two species as a lit height field over a
//! square base ([`LANDSCAPE_SIDE`] wide, [`LANDSCAPE_HEIGHT`] at the peak), coloured by
//! the same ramp as the heat map, seen by the room's orbit camera. The mesh is rebuilt
//! only when the window of the joint changes.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use wgpu::util::DeviceExt;

use super::shaders::Shader;
use super::{DEPTH_FORMAT, background_attachment, texture_2d};
use crate::camera::OrbitCamera;
use crate::network::{JointWindow, LANDSCAPE_HEIGHT, LANDSCAPE_SIDE};

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    value: f32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct ViewUniform {
    clip_from_world: [[f32; 4]; 4],
    eye: [f32; 4],
    light_dir: [f32; 4],
}

/// Vertices a side of the landscape's mesh aims at, at most: each cell is cut into an
/// even number of samples (at least two, at most eight) so that a peak one cell wide
/// reads as a bump rather than a spike.
const SAMPLES_PER_SIDE: usize = 96;

/// Catmull–Rom weights of the four neighbours for a fraction `t` past the second.
fn catmull_rom(t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// The mesh of one window. Each cell (one copy number of each species) is a square
/// bin of the base; the height field passes through the cells' values at their centres
/// and is interpolated between them by Catmull–Rom splines (clamped to the window's
/// range), held flat from the outermost centres to the base's edges: so a ridge along
/// the base's edge (one species at zero copies) is drawn as a ridge, not as a row of
/// spikes, and the mesh is fine enough to show it.
fn mesh(w: &JointWindow) -> (Vec<Vertex>, Vec<u32>) {
    let (nx, ny) = (w.nx.max(1), w.ny.max(1));
    let k = ((SAMPLES_PER_SIDE / nx.max(ny)) & !1).clamp(2, 8);
    let (mx, my) = (nx * k + 1, ny * k + 1);
    let cell = |x: i64, y: i64| -> f32 {
        let (x, y) = (x.clamp(0, w.nx as i64 - 1), y.clamp(0, w.ny as i64 - 1));
        if w.peak > 0.0 {
            (w.cells[y as usize * w.nx + x as usize] / w.peak) as f32
        } else {
            0.0
        }
    };
    // The value at base coordinates (u, v) in cells, centres at i + ½.
    let value = |u: f32, v: f32| -> f32 {
        let (cu, cv) = (
            (u - 0.5).clamp(0.0, (nx - 1) as f32),
            (v - 0.5).clamp(0.0, (ny - 1) as f32),
        );
        let (iu, iv) = (cu.floor(), cv.floor());
        let (wu, wv) = (catmull_rom(cu - iu), catmull_rom(cv - iv));
        let mut s = 0.0;
        for (b, wb) in wv.iter().enumerate() {
            for (a, wa) in wu.iter().enumerate() {
                s += wa * wb * cell(iu as i64 + a as i64 - 1, iv as i64 + b as i64 - 1);
            }
        }
        s.clamp(0.0, 1.0)
    };
    let (dx, dy) = (
        LANDSCAPE_SIDE / (mx - 1) as f32,
        LANDSCAPE_SIDE / (my - 1) as f32,
    );
    let heights: Vec<f32> = (0..my)
        .flat_map(|y| (0..mx).map(move |x| (x, y)))
        .map(|(x, y)| value(x as f32 / k as f32, y as f32 / k as f32))
        .collect();
    let h = |x: usize, y: usize| LANDSCAPE_HEIGHT * heights[y * mx + x];
    let mut vertices = Vec::with_capacity(mx * my);
    for y in 0..my {
        for x in 0..mx {
            // Central differences of the height (one-sided at the edges).
            let (xl, xr) = (x.saturating_sub(1), (x + 1).min(mx - 1));
            let (yl, yr) = (y.saturating_sub(1), (y + 1).min(my - 1));
            let gx = (h(xr, y) - h(xl, y)) / (dx * (xr - xl).max(1) as f32);
            let gy = (h(x, yr) - h(x, yl)) / (dy * (yr - yl).max(1) as f32);
            let n = Vec3::new(-gx, -gy, 1.0).normalize();
            vertices.push(Vertex {
                position: [x as f32 * dx, y as f32 * dy, h(x, y)],
                normal: n.to_array(),
                value: heights[y * mx + x],
            });
        }
    }
    let mut indices = Vec::with_capacity(6 * (mx - 1) * (my - 1));
    for y in 0..my - 1 {
        for x in 0..mx - 1 {
            let i = (y * mx + x) as u32;
            let j = i + mx as u32;
            indices.extend_from_slice(&[i, i + 1, j + 1, i, j + 1, j]);
        }
    }
    (vertices, indices)
}

/// The landscape's pipeline and its current mesh.
#[derive(Debug)]
pub struct Landscape {
    pipeline: wgpu::RenderPipeline,
    uniform: wgpu::Buffer,
    bind: wgpu::BindGroup,
    mesh: Option<(wgpu::Buffer, wgpu::Buffer, u32)>,
    /// The generation of the window shown (see `NetworkRoom::window_generation`).
    shown: Option<u64>,
    depth: Option<((u32, u32), wgpu::TextureView)>,
}

impl Landscape {
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("landscape view"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("landscape view"),
            size: size_of::<ViewUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("landscape view"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform.as_entire_binding(),
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("landscape"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = Shader::Landscape.module(device);
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32];
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("landscape"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: size_of::<Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                })],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(format.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        Landscape {
            pipeline,
            uniform,
            bind,
            mesh: None,
            shown: None,
            depth: None,
        }
    }

    /// Shows `window`, whose change count is `generation` (the mesh is rebuilt only
    /// when it differs from the one shown); `None` clears it.
    pub fn set(&mut self, device: &wgpu::Device, window: Option<&JointWindow>, generation: u64) {
        if self.shown == Some(generation) {
            return;
        }
        self.shown = Some(generation);
        self.mesh = window.map(|w| {
            let (vertices, indices) = mesh(w);
            let vb = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("landscape vertices"),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::VERTEX,
            });
            let ib = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("landscape indices"),
                contents: bytemuck::cast_slice(&indices),
                usage: wgpu::BufferUsages::INDEX,
            });
            (vb, ib, indices.len() as u32)
        });
    }

    /// An encoder whose first pass clears `target` and draws the landscape from
    /// `camera`.
    pub fn encode(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &wgpu::TextureView,
        size: (u32, u32),
        camera: &OrbitCamera,
    ) -> wgpu::CommandEncoder {
        let size = (size.0.max(1), size.1.max(1));
        if self.depth.as_ref().is_none_or(|(s, _)| *s != size) {
            let tex = texture_2d(
                device,
                "landscape depth",
                size,
                DEPTH_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
                &[],
            );
            self.depth = Some((size, tex.create_view(&Default::default())));
        }
        let aspect = size.0 as f32 / size.1 as f32;
        let eye = camera.eye();
        let light = (eye - camera.target_mm + Vec3::new(0.0, 0.0, 150.0)).normalize_or(Vec3::Z);
        let view = ViewUniform {
            clip_from_world: camera.clip_from_world(aspect).to_cols_array_2d(),
            eye: eye.extend(1.0).to_array(),
            light_dir: light.extend(0.0).to_array(),
        };
        queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&view));
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("landscape frame"),
        });
        let depth = &self.depth.as_ref().expect("created above").1;
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("landscape"),
                color_attachments: &[Some(background_attachment(target))],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if let Some((vb, ib, count)) = &self.mesh {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &self.bind, &[]);
                pass.set_vertex_buffer(0, vb.slice(..));
                pass.set_index_buffer(ib.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..*count, 0, 0..1);
            }
        }
        encoder
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn window(nx: usize, ny: usize, cells: Vec<f64>) -> JointWindow {
        let peak = cells.iter().copied().fold(0.0, f64::max);
        JointWindow {
            a0: 0,
            b0: 0,
            wa: nx,
            wb: ny,
            nx,
            ny,
            cells,
            peak,
        }
    }

    /// A single peak: the mesh covers the base, its top is the peak's cell centre at
    /// full height, normals point up on a flat rim, and every triangle indexes the grid.
    #[test]
    fn the_mesh_puts_the_peak_on_top() {
        let (nx, ny) = (5, 4);
        let mut cells = vec![0.0; nx * ny];
        cells[2 * nx + 3] = 0.2;
        let (v, i) = mesh(&window(nx, ny, cells));
        let k = 8;
        assert_eq!(v.len(), (nx * k + 1) * (ny * k + 1));
        assert!(i.iter().all(|&k| (k as usize) < v.len()));
        let top = v
            .iter()
            .max_by(|a, b| a.position[2].total_cmp(&b.position[2]))
            .expect("vertices");
        assert_eq!(top.position[2], LANDSCAPE_HEIGHT);
        assert_eq!(top.value, 1.0);
        assert!((top.position[0] - 3.5 * LANDSCAPE_SIDE / nx as f32).abs() < 1e-3);
        assert!((top.position[1] - 2.5 * LANDSCAPE_SIDE / ny as f32).abs() < 1e-3);
        assert_eq!(v[0].normal, [0.0, 0.0, 1.0]);
        assert!(
            v.iter()
                .all(|p| (0.0..=LANDSCAPE_SIDE).contains(&p.position[1]))
        );
        // A bump, not a spike: the height falls off over about a cell, and half a cell
        // from the top it is still more than half the peak.
        let half = v
            .iter()
            .filter(|p| {
                (p.position[1] - top.position[1]).abs() < 1e-3
                    && (p.position[0] - (top.position[0] + 0.5 * LANDSCAPE_SIDE / nx as f32)).abs()
                        < 1e-3
            })
            .map(|p| p.value)
            .next()
            .expect("a vertex half a cell off");
        assert!(half > 0.5, "{half}");
    }

    /// A ridge along an edge of the base (the first species at zero copies, as the
    /// toggle switch has): drawn at full height all along, flat to the edge, never a
    /// row of spikes.
    #[test]
    fn a_ridge_along_an_axis_is_drawn_as_a_ridge() {
        let (nx, ny) = (12, 30);
        let mut cells = vec![0.0; nx * ny];
        for y in 0..ny {
            cells[y * nx] = 0.05;
        }
        let (v, _) = mesh(&window(nx, ny, cells));
        let edge: Vec<f32> = v
            .iter()
            .filter(|p| p.position[0] < 0.5 * LANDSCAPE_SIDE / nx as f32 - 1e-3)
            .map(|p| p.value)
            .collect();
        assert!(!edge.is_empty());
        assert!(edge.iter().all(|&h| h == 1.0), "{edge:?}");
    }
}
