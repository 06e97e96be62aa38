//! Rendering of a palpation scene with wgpu, into any `TextureView` (a window's surface
//! texture, or an offscreen texture for tests and `palpa headless`).
//!
//! One frame: upload the frame uniform and the `n` coefficients; compute the deformed
//! surface and its normals ([`deform`]); then draw, in one pass with depth and stencil,
//! the ground grid, the organ's planar shadow (stencilled so it darkens each pixel
//! once), the organ, and the probe with its force arrow.

pub mod deform;
pub mod gpu;
pub mod health;
pub mod landscape;
pub mod meshes;
pub mod offscreen;
mod pipelines;
pub mod shaders;

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Quat, Vec3};
use palpa_core::scene::PalpationScene;
use wgpu::util::DeviceExt;

use crate::camera::OrbitCamera;
use deform::Deform;
use meshes::{UnitMeshes, unit_meshes};
use pipelines::{Layouts, Pipelines};

pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth24PlusStencil8;
/// The background colour (linear), matched by the ground's fade.
pub const BACKGROUND: wgpu::Color = wgpu::Color {
    r: 0.11,
    g: 0.12,
    b: 0.14,
    a: 1.0,
};

#[derive(Debug, Clone, Copy, Pod, Zeroable)]
#[repr(C)]
struct FrameUniform {
    clip_from_world: [[f32; 4]; 4],
    eye: [f32; 4],
    light_dir: [f32; 4],
    ground: [f32; 4],
    colormap: [f32; 4],
    center: [f32; 4],
    tool: [f32; 4],
}

#[derive(Debug, Clone, Copy, Pod, Zeroable)]
#[repr(C)]
struct ObjectUniform {
    world_from_model: [[f32; 4]; 4],
    normal_from_model: [[f32; 4]; 4],
    color: [f32; 4],
    _pad: [f32; 28],
}
const OBJECT_STRIDE: u64 = 256;
/// The instrument's shaft: its radius as a share of the tool's, and its length.
const SHAFT_SHARE: f32 = 0.3;
const SHAFT_MM: f32 = 70.0;
const OBJECTS: usize = 6;
/// The object that is the revealed nodule (drawn seen through the surface).
const NODULE_OBJECT: usize = 5;

/// The probe as drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeVisual {
    /// Where the tool tip touches (deformed contact point), mm.
    pub tip_mm: Vec3,
    /// Outward surface normal at the contact point.
    pub outward: Vec3,
    /// Force applied to the tissue, N.
    pub force_n: Vec3,
    pub radius_mm: f32,
    /// Inside the palpable region (else drawn in warning colour).
    pub valid: bool,
}

/// What one frame shows.
#[derive(Debug, Clone, Copy)]
pub struct FrameInput<'a> {
    pub camera: &'a OrbitCamera,
    /// Coefficients of the modes used (`len` = modes used).
    pub coeffs: &'a [f64],
    /// The near-field displacement per render vertex (mm, xyz_), added to the modes'.
    pub near_mm: &'a [[f32; 4]],
    /// The surface deformed on the CPU ([`deform::DeformOn::Cpu`]); `None`: the
    /// compute passes deform it from the coefficients and the near field.
    pub cpu_surface: Option<deform::CpuSurface<'a>>,
    /// Colour by displacement magnitude, with this value (mm) at the top of the scale.
    pub colormap_mm: Option<f32>,
    pub probe: Option<ProbeVisual>,
    /// Values per render vertex that colour the surface instead of its own colours
    /// (`None`: the normal colours).
    pub values: Option<VertexValues<'a>>,
    /// A revealed nodule, drawn seen through the organ.
    pub nodule: Option<NoduleVisual>,
    /// A hidden nodule's gain on the surface the compute passes deform.
    pub surface_gain: deform::SurfaceGain,
}

/// Values per scene vertex and a generation that changes when they do.
#[derive(Debug, Clone, Copy)]
pub struct VertexValues<'a> {
    pub values: &'a [f32],
    pub generation: u64,
    pub kind: ValueKind,
}

/// What [`VertexValues`] hold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ValueKind {
    /// The region mode: 0 neither, 1 palpable, 2 fixed.
    Regions,
    /// The stiffness map: the force with a nodule over the force without, from 1 to
    /// `top` on the colour ramp.
    Stiffness { top: f32 },
}

impl ValueKind {
    /// The shader's switch (`frame.colormap.z`) and its scale (`.w`).
    fn wire(self) -> [f32; 2] {
        match self {
            ValueKind::Regions => [1.0, 0.0],
            ValueKind::Stiffness { top } => [2.0, top],
        }
    }
}

/// A nodule to draw: a sphere, seen through the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoduleVisual {
    pub center_mm: Vec3,
    pub radius_mm: f32,
}

/// Pipelines and buffers for one scene and one target format.
#[derive(Debug)]
pub struct Renderer {
    pub deform: Deform,
    palpable: wgpu::Buffer,
    /// The scene's own palpable flags per drawn vertex, and the region generation the
    /// buffer holds (0: those flags).
    palpable_rest: Vec<f32>,
    /// The drawn surface (to carry painted regions onto it) and scratch for them.
    visual: palpa_core::visual::VisualSurface,
    palpable_drawn: Vec<f32>,
    /// What the value buffer holds: the kind's switch and generation (0: the
    /// palpable flags).
    values_key: (u32, u64),
    indices: wgpu::Buffer,
    index_count: u32,
    /// The render surface's triangles: its shadow (the drawn surface's would cost as
    /// much as drawing it, for a shadow no one tells apart).
    shadow_indices: wgpu::Buffer,
    shadow_index_count: u32,
    frame: wgpu::Buffer,
    frame_group: wgpu::BindGroup,
    objects: wgpu::Buffer,
    object_group: wgpu::BindGroup,
    solids: wgpu::Buffer,
    unit: UnitMeshes,
    ground: wgpu::RenderPipeline,
    shadow: wgpu::RenderPipeline,
    surface: wgpu::RenderPipeline,
    solid: wgpu::RenderPipeline,
    seen_through: wgpu::RenderPipeline,
    depth: Option<(wgpu::TextureView, (u32, u32))>,
    bounds: (Vec3, Vec3),
    pub format: wgpu::TextureFormat,
}

impl Renderer {
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat, scene: &PalpationScene) -> Self {
        let deform = Deform::new(device, scene);
        let flags: Vec<f32> = scene
            .palpable_vertices()
            .iter()
            .map(|&p| f32::from(u8::from(p)))
            .collect();
        let visual = scene.visual().clone();
        let mut palpable = vec![0.0; visual.rest_mm.len()];
        visual.interpolate(&flags, &mut palpable);
        let palpable_rest = palpable.clone();
        let palpable = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("palpable flags"),
            contents: bytemuck::cast_slice(&palpable),
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        });
        let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("drawn triangles"),
            contents: bytemuck::cast_slice(&visual.triangles),
            usage: wgpu::BufferUsages::INDEX,
        });
        let shadow_indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("render surface triangles"),
            contents: bytemuck::cast_slice(scene.triangles()),
            usage: wgpu::BufferUsages::INDEX,
        });
        let frame = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame uniform"),
            size: size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layouts = Layouts::new(device);
        let frame_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("frame"),
            layout: &layouts.frame,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: frame.as_entire_binding(),
            }],
        });
        let objects = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("object uniforms"),
            size: OBJECT_STRIDE * OBJECTS as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let object_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("object"),
            layout: &layouts.object,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &objects,
                    offset: 0,
                    size: wgpu::BufferSize::new(size_of::<ObjectUniform>() as u64),
                }),
            }],
        });
        let unit = unit_meshes();
        let solids = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("probe and arrow meshes"),
            contents: bytemuck::cast_slice(&unit.vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let Pipelines {
            ground,
            shadow,
            surface,
            solid,
            seen_through,
        } = Pipelines::new(device, format, &layouts);

        let (min, max) = bounds(scene.vertices_mm());
        Renderer {
            deform,
            palpable,
            palpable_rest,
            palpable_drawn: vec![0.0; visual.rest_mm.len()],
            index_count: 3 * visual.triangles.len() as u32,
            visual,
            values_key: (0, 0),
            indices,
            shadow_index_count: 3 * scene.triangles().len() as u32,
            shadow_indices,
            frame,
            frame_group,
            objects,
            object_group,
            solids,
            unit,
            ground,
            shadow,
            surface,
            solid,
            seen_through,
            depth: None,
            bounds: (min, max),
            format,
        }
    }

    /// Rest-geometry bounds of the scene (mm).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }

    /// Records one frame into `encoder`, drawing into `target` of `size` pixels.
    pub fn encode(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        size: (u32, u32),
        input: &FrameInput<'_>,
    ) {
        let (w, h) = (size.0.max(1), size.1.max(1));
        let (min, max) = self.bounds;
        let center = 0.5 * (min + max);
        let extent = 0.5 * (max - min);
        let light = Vec3::new(0.35, 0.55, 1.0).normalize();
        let uniform = FrameUniform {
            clip_from_world: input
                .camera
                .clip_from_world(w as f32 / h as f32)
                .to_cols_array_2d(),
            eye: input.camera.eye().extend(1.0).to_array(),
            light_dir: light.extend(0.0).to_array(),
            ground: [
                min.z - 0.1 * extent.z,
                10.0,
                3.0 * extent.x.max(extent.y),
                0.0,
            ],
            colormap: [
                f32::from(u8::from(input.colormap_mm.is_some())),
                input.colormap_mm.unwrap_or(1.0),
                input.values.map_or(0.0, |v| v.kind.wire()[0]),
                input.values.map_or(0.0, |v| v.kind.wire()[1]),
            ],
            center: center.extend(0.0).to_array(),
            tool: input
                .probe
                .as_ref()
                .map_or([0.0; 4], |p| p.tip_mm.extend(p.radius_mm).to_array()),
        };
        queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(&uniform));
        match input.values {
            Some(v) if (v.kind.wire()[0] as u32, v.generation) != self.values_key => {
                self.visual.interpolate(v.values, &mut self.palpable_drawn);
                queue.write_buffer(
                    &self.palpable,
                    0,
                    bytemuck::cast_slice(&self.palpable_drawn),
                );
                self.values_key = (v.kind.wire()[0] as u32, v.generation);
            }
            None if self.values_key != (0, 0) => {
                queue.write_buffer(&self.palpable, 0, bytemuck::cast_slice(&self.palpable_rest));
                self.values_key = (0, 0);
            }
            _ => {}
        }
        let objects = self.object_uniforms(input.probe.as_ref(), input.nodule.as_ref());
        for (i, o) in objects.iter().enumerate() {
            queue.write_buffer(
                &self.objects,
                i as u64 * OBJECT_STRIDE,
                bytemuck::bytes_of(o),
            );
        }
        self.deform.record(queue, encoder, input);

        let depth_view = self.depth_view(device, (w, h)).clone();
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("scene"),
            color_attachments: &[Some(background_attachment(target))],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0),
                    store: wgpu::StoreOp::Discard,
                }),
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &self.frame_group, &[]);
        pass.set_pipeline(&self.ground);
        pass.draw(0..6, 0..1);

        pass.set_pipeline(&self.shadow);
        pass.set_vertex_buffer(0, self.deform.mechanical.slice(..));
        pass.set_index_buffer(self.shadow_indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.set_stencil_reference(0);
        pass.draw_indexed(0..self.shadow_index_count, 0, 0..1);

        pass.set_pipeline(&self.surface);
        pass.set_vertex_buffer(0, self.deform.positions.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.set_vertex_buffer(1, self.deform.normals.slice(..));
        pass.set_vertex_buffer(2, self.palpable.slice(..));
        pass.draw_indexed(0..self.index_count, 0, 0..1);

        if objects[NODULE_OBJECT].color[3] > 0.0 {
            pass.set_pipeline(&self.seen_through);
            pass.set_vertex_buffer(0, self.solids.slice(..));
            pass.set_bind_group(
                1,
                &self.object_group,
                &[(NODULE_OBJECT as u64 * OBJECT_STRIDE) as u32],
            );
            pass.draw(self.unit.sphere.clone(), 0..1);
        }
        if input.probe.is_some() {
            pass.set_pipeline(&self.solid);
            pass.set_vertex_buffer(0, self.solids.slice(..));
            let draws = [
                self.unit.cylinder.clone(),
                self.unit.cone.clone(),
                self.unit.sphere.clone(),
                self.unit.cylinder.clone(),
                self.unit.cone.clone(),
            ];
            for (i, range) in draws.into_iter().enumerate() {
                if objects[i].color[3] > 0.0 {
                    pass.set_bind_group(
                        1,
                        &self.object_group,
                        &[(i as u64 * OBJECT_STRIDE) as u32],
                    );
                    pass.draw(range, 0..1);
                }
            }
        }
    }

    /// A new command encoder with this frame recorded in it (the caller adds the
    /// interface or a read-back, then submits).
    pub fn encode_frame(
        &mut self,
        gpu: &gpu::Gpu,
        target: &wgpu::TextureView,
        size: (u32, u32),
        input: &FrameInput<'_>,
    ) -> wgpu::CommandEncoder {
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        self.encode(&gpu.device, &gpu.queue, &mut encoder, target, size, input);
        encoder
    }

    fn depth_view(&mut self, device: &wgpu::Device, size: (u32, u32)) -> &wgpu::TextureView {
        if self.depth.as_ref().is_none_or(|(_, s)| *s != size) {
            let tex = texture_2d(
                device,
                "depth",
                size,
                DEPTH_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
                &[],
            );
            self.depth = Some((tex.create_view(&Default::default()), size));
        }
        &self.depth.as_ref().expect("created above").0
    }

    /// The instrument (shaft, neck, ball tip) and the force arrow (shaft, head); alpha
    /// 0: not drawn.
    ///
    /// A ball-ended palpation probe: the ball is the tool (its radius), carried by a
    /// shaft a third as thick through a tapered neck, so the dimple around the ball
    /// stays in view instead of under a rod as wide as the tool.
    fn object_uniforms(
        &self,
        probe: Option<&ProbeVisual>,
        nodule: Option<&NoduleVisual>,
    ) -> [ObjectUniform; OBJECTS] {
        let hidden = ObjectUniform::zeroed();
        let mut objects = [hidden; OBJECTS];
        if let Some(n) = nodule {
            // Ivory, half seen through the tissue over it.
            objects[NODULE_OBJECT] = object(
                Mat4::from_scale_rotation_translation(
                    Vec3::splat(n.radius_mm),
                    Quat::IDENTITY,
                    n.center_mm,
                ),
                [0.95, 0.88, 0.62, 0.6],
            );
        }
        let Some(p) = probe else {
            return objects;
        };
        let steel = if p.valid {
            [0.78, 0.80, 0.84, 1.0]
        } else {
            [0.9, 0.55, 0.2, 1.0]
        };
        let out = p.outward.normalize_or(Vec3::Z);
        let to_out = Quat::from_rotation_arc(Vec3::Z, out);
        let r = p.radius_mm;
        let ball = p.tip_mm + out * r;
        let shaft_r = SHAFT_SHARE * r;
        let shaft = Mat4::from_scale_rotation_translation(
            Vec3::new(shaft_r, shaft_r, SHAFT_MM),
            to_out,
            ball,
        );
        // The neck: a cone from 0.8 r at the ball's centre, narrowing into the shaft.
        let neck = Mat4::from_scale_rotation_translation(
            Vec3::new(0.8 * r, 0.8 * r, 4.0 * r),
            to_out,
            ball,
        );
        let tip = Mat4::from_scale_rotation_translation(Vec3::splat(r), Quat::IDENTITY, ball);
        objects[0] = object(shaft, steel);
        objects[1] = object(neck, steel);
        objects[2] = object(tip, steel);
        let f = p.force_n.length();
        if f > 1e-4 {
            // The arrow points along the force and ends at the contact point, offset to
            // the side of the rod so it stays visible. 15 mm per newton, capped.
            let dir = p.force_n / f;
            let length = (15.0 * f).clamp(6.0, 120.0);
            let side = dir.any_orthonormal_vector() * (r + 4.0);
            let head = 0.3 * length.min(30.0);
            let end = p.tip_mm + side;
            let start = end - dir * length;
            let rot = Quat::from_rotation_arc(Vec3::Z, dir);
            let yellow = [0.98, 0.82, 0.2, 1.0];
            objects[3] = object(
                Mat4::from_scale_rotation_translation(
                    Vec3::new(1.2, 1.2, length - head),
                    rot,
                    start,
                ),
                yellow,
            );
            objects[4] = object(
                Mat4::from_scale_rotation_translation(
                    Vec3::new(3.5, 3.5, head),
                    rot,
                    end - dir * head,
                ),
                yellow,
            );
        }
        objects
    }
}

/// A single-sample 2-D texture of `size` pixels.
pub fn texture_2d(
    device: &wgpu::Device,
    label: &str,
    size: (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
    view_formats: &[wgpu::TextureFormat],
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats,
    })
}

fn object(world_from_model: Mat4, color: [f32; 4]) -> ObjectUniform {
    let normal = Mat4::from_mat3(
        glam::Mat3::from_mat4(world_from_model)
            .inverse()
            .transpose(),
    );
    ObjectUniform {
        world_from_model: world_from_model.to_cols_array_2d(),
        normal_from_model: normal.to_cols_array_2d(),
        color,
        _pad: [0.0; 28],
    }
}

/// A colour attachment that clears `target` to the background and keeps what is drawn.
pub fn background_attachment(target: &wgpu::TextureView) -> wgpu::RenderPassColorAttachment<'_> {
    wgpu::RenderPassColorAttachment {
        view: target,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load: wgpu::LoadOp::Clear(BACKGROUND),
            store: wgpu::StoreOp::Store,
        },
    }
}

/// An encoder whose first pass clears `target` to the background (for scenes drawn by
/// the interface alone, such as the network scene).
pub fn clear_frame(device: &wgpu::Device, target: &wgpu::TextureView) -> wgpu::CommandEncoder {
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("clear frame"),
    });
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("clear"),
        color_attachments: &[Some(background_attachment(target))],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    encoder
}

/// Axis-aligned bounds of a point set.
pub fn bounds(points: &[[f32; 3]]) -> (Vec3, Vec3) {
    points.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(Vec3::from_array(*p)), hi.max(Vec3::from_array(*p))),
    )
}
