//! GPU deformation of the scene surface (`shaders/deform.wgsl`): the surface rows of `X`
//! in a storage buffer, the `n` coefficients in a uniform, one compute pass for the
//! displacement of the mechanical render surface; then (`shaders/embed.wgsl`) one pass
//! carries the drawn surface on it ([`palpa_core::visual`]) and one computes the drawn
//! surface's normals. The outputs are the vertex buffers the surface is drawn from.
//!
//! The same buffers can instead be filled by the CPU ([`DeformOn::Cpu`]: the session
//! evaluates every row, carries the drawn surface and computes its normals itself and
//! uploads 32 bytes a drawn vertex). Which is
//! faster depends on the device: `palpa lab bench deform` measures both on the adapter at
//! hand, with how far apart their surfaces are.

use bytemuck::{Pod, Zeroable};
use palpa_core::pgd::nodule::table::SURFACE_NEAR_MM;
use palpa_core::scene::PalpationScene;
use wgpu::util::DeviceExt;

use super::shaders::Shader;

/// Most modes the coefficient uniform holds (128 × vec4).
pub const MAX_GPU_MODES: usize = 512;
/// Storage buffers the compute stage binds.
pub const STORAGE_BUFFERS: u32 = 8;
const WORKGROUP: u32 = 64;

/// One vec4 of a GPU buffer (xyz and w).
pub type Vec4Data = [f32; 4];

/// Where the deformed surface and its normals are computed (no `Default`: the
/// default depends on the adapter, [`DeformOn::preferred`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeformOn {
    /// The compute shader: the CPU uploads the `n` coefficients and the near field.
    Gpu,
    /// The CPU (palpa-core's evaluation in double precision): it uploads the positions
    /// and normals, and the compute passes are not run.
    Cpu,
}

impl DeformOn {
    /// The default for an adapter. On a software adapter (Mesa's lavapipe) the compute
    /// passes run on the CPU too, behind a dispatch: there the CPU path's frames were
    /// about 3 % shorter (liver, 1280x720, `palpa headless`), and `palpa lab bench deform`
    /// measured the deformation itself at 0.4–0.5 of the compute path's time. A GPU
    /// takes the rows off the CPU and runs beside it.
    pub fn preferred(software_adapter: bool) -> Self {
        if software_adapter {
            DeformOn::Cpu
        } else {
            DeformOn::Gpu
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            DeformOn::Gpu => "gpu",
            DeformOn::Cpu => "cpu",
        }
    }
}

/// The drawn surface deformed on the CPU, per drawn vertex: positions (xyz, |u|) and
/// unit normals (xyz, 0).
#[derive(Debug, Clone, Copy)]
pub struct CpuSurface<'a> {
    pub positions: &'a [Vec4Data],
    pub normals: &'a [Vec4Data],
    /// The render surface it is carried on (xyz, |u|), for the shadow.
    pub mechanical: &'a [Vec4Data],
}

/// A hidden nodule's gain on the drawn surface: the probe's rest position (mm) and the
/// effect `e` ([`palpa_core::pgd::nodule::table::surface_gain`]); `e` = 0: none.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SurfaceGain(pub [f32; 4]);

#[derive(Debug, Clone, Copy, Pod, Zeroable)]
#[repr(C)]
struct Params {
    vertex_count: u32,
    modes_stride: u32,
    modes_used: u32,
    near_mm: f32,
    gain: [f32; 4],
}

#[derive(Debug, Clone, Copy, Pod, Zeroable)]
#[repr(C)]
struct EmbedParams {
    vertex_count: u32,
    pad: [u32; 3],
}

/// The drawn surface's stage: carried on the mechanical positions, then its normals.
#[derive(Debug)]
struct Embed {
    bind_group: wgpu::BindGroup,
    embed: wgpu::ComputePipeline,
    normals: wgpu::ComputePipeline,
    vertex_count: u32,
}

/// GPU buffers and pipelines of the deformation.
#[derive(Debug)]
pub struct Deform {
    params: wgpu::Buffer,
    coeffs: wgpu::Buffer,
    /// The near-field displacement per vertex (xyz), written each frame.
    near: wgpu::Buffer,
    /// Deformed positions of the mechanical render surface (xyz, |u|), one vec4 per
    /// render vertex.
    pub mechanical: wgpu::Buffer,
    /// The drawn surface's deformed positions (xyz, |u|), one vec4 per drawn vertex:
    /// compute output, vertex input.
    pub positions: wgpu::Buffer,
    /// Unit normals of the drawn surface, one vec4 per drawn vertex.
    pub normals: wgpu::Buffer,
    embed: Embed,
    bind_group: wgpu::BindGroup,
    displace: wgpu::ComputePipeline,
    vertex_count: u32,
    modes_stride: u32,
}

impl Deform {
    pub fn new(device: &wgpu::Device, scene: &PalpationScene) -> Self {
        let m = scene.model();
        let vertex_count = scene.vertices_mm().len() as u32;
        let storage = |label: &str, contents: &[u8]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let modes = storage("modes X (surface rows)", bytemuck::cast_slice(m.spatial()));
        let rest: Vec<[f32; 4]> = scene
            .vertices_mm()
            .iter()
            .map(|p| [p[0], p[1], p[2], 0.0])
            .collect();
        let rest = storage("rest positions", bytemuck::cast_slice(&rest));
        let out_size = u64::from(vertex_count) * 16;
        let output = |label: &str| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: out_size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::VERTEX
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let mechanical = output("deformed mechanical positions");
        let near = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("near-field displacement"),
            size: out_size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("deform params"),
            size: size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let coeffs = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("coefficients"),
            size: (MAX_GPU_MODES * 4) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });

        let (ro, rw, uniform) = binding_types();
        let (bind_group, mut pipelines) = compute_stage(
            device,
            "deform",
            Shader::Deform,
            &[
                (uniform, &params),
                (uniform, &coeffs),
                (ro, &modes),
                (ro, &rest),
                (rw, &mechanical),
                (ro, &near),
            ],
            &["displace"],
        );
        let visual = scene.visual();
        let drawn = visual.rest_mm.len() as u64;
        let drawn_output = |label: &str| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: drawn * 16,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::VERTEX
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let positions = drawn_output("drawn positions");
        let normals = drawn_output("drawn normals");
        let embed = Embed::new(device, visual, &mechanical, &positions, &normals);
        Deform {
            displace: pipelines.remove(0),
            mechanical,
            embed,
            params,
            coeffs,
            near,
            positions,
            normals,
            bind_group,
            vertex_count,
            modes_stride: m.modes() as u32,
        }
    }

    /// Uploads the coefficients (`coeffs.len()` = modes used, at most the stored count
    /// and [`MAX_GPU_MODES`]; more are ignored) and a hidden nodule's surface gain
    /// ([`SurfaceGain`]).
    pub fn set_coefficients(&self, queue: &wgpu::Queue, coeffs: &[f64], gain: SurfaceGain) {
        let n = coeffs
            .len()
            .min(MAX_GPU_MODES)
            .min(self.modes_stride as usize);
        let mut c = [0f32; MAX_GPU_MODES];
        for (d, s) in c.iter_mut().zip(&coeffs[..n]) {
            *d = *s as f32;
        }
        queue.write_buffer(&self.coeffs, 0, bytemuck::cast_slice(&c));
        let p = Params {
            vertex_count: self.vertex_count,
            modes_stride: self.modes_stride,
            modes_used: n as u32,
            near_mm: SURFACE_NEAR_MM as f32,
            gain: gain.0,
        };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
    }

    /// Uploads the near-field displacement (one xyz_ per vertex; fewer entries leave
    /// the rest as they were, so pass all of them).
    pub fn set_near(&self, queue: &wgpu::Queue, near_mm: &[Vec4Data]) {
        let n = near_mm.len().min(self.vertex_count as usize);
        queue.write_buffer(&self.near, 0, bytemuck::cast_slice(&near_mm[..n]));
    }

    /// Fills the position and normal buffers for a frame: from its CPU-deformed
    /// surface where it has one, else by the compute passes on its coefficients, near
    /// field and nodule gain.
    pub fn record(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        input: &super::FrameInput<'_>,
    ) {
        match input.cpu_surface {
            Some(surface) => self.upload(queue, surface),
            None => {
                self.set_coefficients(queue, input.coeffs, input.surface_gain);
                self.set_near(queue, input.near_mm);
                self.encode(encoder);
            }
        }
    }

    /// Writes a CPU-deformed drawn surface into the vertex buffers (entries past the
    /// drawn vertex count are ignored).
    pub fn upload(&self, queue: &wgpu::Queue, surface: CpuSurface<'_>) {
        let n = self.embed.vertex_count as usize;
        let p = &surface.positions[..surface.positions.len().min(n)];
        let q = &surface.normals[..surface.normals.len().min(n)];
        queue.write_buffer(&self.positions, 0, bytemuck::cast_slice(p));
        queue.write_buffer(&self.normals, 0, bytemuck::cast_slice(q));
        let m = self.vertex_count as usize;
        let r = &surface.mechanical[..surface.mechanical.len().min(m)];
        queue.write_buffer(&self.mechanical, 0, bytemuck::cast_slice(r));
    }

    /// Records the compute passes: the mechanical surface, then the drawn one.
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("deform"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &self.bind_group, &[]);
        let groups = self.vertex_count.div_ceil(WORKGROUP);
        pass.set_pipeline(&self.displace);
        pass.dispatch_workgroups(groups, 1, 1);
        pass.set_bind_group(0, &self.embed.bind_group, &[]);
        let drawn = self.embed.vertex_count.div_ceil(WORKGROUP);
        pass.set_pipeline(&self.embed.embed);
        pass.dispatch_workgroups(drawn, 1, 1);
        pass.set_pipeline(&self.embed.normals);
        pass.dispatch_workgroups(drawn, 1, 1);
    }

    /// Reads back the mechanical render surface's deformed positions (xyz, |u|), as
    /// the compute pass left them (tests).
    pub fn read_back_mechanical(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> anyhow::Result<Vec<Vec4Data>> {
        let size = u64::from(self.vertex_count) * 16;
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("mechanical read-back"),
            size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.mechanical, 0, &staging, 0, size);
        queue.submit([encoder.finish()]);
        let bytes = super::offscreen::read_buffer(device, &staging)?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }

    /// Reads back the drawn surface's positions and normals (tests, and checking a
    /// new GPU): `(positions, normals)`, xyz + w each.
    pub fn read_back(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> anyhow::Result<(Vec<Vec4Data>, Vec<Vec4Data>)> {
        let size = u64::from(self.embed.vertex_count) * 16;
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("deform read-back"),
            size: 2 * size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.positions, 0, &staging, 0, size);
        encoder.copy_buffer_to_buffer(&self.normals, 0, &staging, size, size);
        queue.submit([encoder.finish()]);
        let bytes = super::offscreen::read_buffer(device, &staging)?;
        let all: &[Vec4Data] = bytemuck::cast_slice(&bytes);
        let (p, n) = all.split_at(self.embed.vertex_count as usize);
        Ok((p.to_vec(), n.to_vec()))
    }

    /// Vertices of the mechanical render surface.
    pub fn vertex_count(&self) -> u32 {
        self.vertex_count
    }

    /// Vertices of the drawn surface.
    pub fn drawn_vertex_count(&self) -> u32 {
        self.embed.vertex_count
    }
}

impl Embed {
    fn new(
        device: &wgpu::Device,
        visual: &palpa_core::visual::VisualSurface,
        mechanical: &wgpu::Buffer,
        positions: &wgpu::Buffer,
        normals: &wgpu::Buffer,
    ) -> Embed {
        let vertex_count = visual.rest_mm.len() as u32;
        let storage = |label: &str, contents: &[u8]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("embed params"),
            contents: bytemuck::bytes_of(&EmbedParams {
                vertex_count,
                pad: [0; 3],
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let corners: Vec<[u32; 4]> = visual
            .embed
            .iter()
            .map(|e| [e.corners[0], e.corners[1], e.corners[2], 0])
            .collect();
        let weights: Vec<[f32; 4]> = visual
            .embed
            .iter()
            .map(|e| [e.bary[0], e.bary[1], e.bary[2], e.height_mm])
            .collect();
        let corners = storage("drawn corners", bytemuck::cast_slice(&corners));
        let weights = storage("drawn weights", bytemuck::cast_slice(&weights));
        let (offsets, adjacency) = vertex_triangles(vertex_count as usize, &visual.triangles);
        let offsets = storage("drawn adjacency offsets", bytemuck::cast_slice(&offsets));
        let adjacency = storage("drawn adjacency", bytemuck::cast_slice(&adjacency));
        let triangles = storage("drawn triangles", bytemuck::cast_slice(&visual.triangles));
        let (ro, rw, uniform) = binding_types();
        let (bind_group, mut pipelines) = compute_stage(
            device,
            "embed",
            Shader::Embed,
            &[
                (uniform, &params),
                (ro, mechanical),
                (ro, &corners),
                (ro, &weights),
                (rw, positions),
                (ro, &offsets),
                (ro, &adjacency),
                (ro, &triangles),
                (rw, normals),
            ],
            &["embed", "embed_normals"],
        );
        let normals = pipelines.remove(1);
        Embed {
            embed: pipelines.remove(0),
            normals,
            bind_group,
            vertex_count,
        }
    }
}

/// Read-only storage, read-write storage and uniform buffer bindings.
fn binding_types() -> (
    wgpu::BufferBindingType,
    wgpu::BufferBindingType,
    wgpu::BufferBindingType,
) {
    (
        wgpu::BufferBindingType::Storage { read_only: true },
        wgpu::BufferBindingType::Storage { read_only: false },
        wgpu::BufferBindingType::Uniform,
    )
}

/// A compute stage: one bind group of `buffers` at bindings 0, 1, … (each with its
/// binding type) and a pipeline for each of `entries` of `shader`.
fn compute_stage(
    device: &wgpu::Device,
    label: &str,
    shader: Shader,
    buffers: &[(wgpu::BufferBindingType, &wgpu::Buffer)],
    entries: &[&str],
) -> (wgpu::BindGroup, Vec<wgpu::ComputePipeline>) {
    let layout_entries: Vec<wgpu::BindGroupLayoutEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, (ty, _))| wgpu::BindGroupLayoutEntry {
            binding: i as u32,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: *ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect();
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &layout_entries,
    });
    let group_entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, (_, b))| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout: &layout,
        entries: &group_entries,
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let module = shader.module(device);
    let pipelines = entries
        .iter()
        .map(|entry| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        })
        .collect();
    (bind_group, pipelines)
}

/// For each vertex, the triangles that contain it (CSR: offsets, then triangle ids).
pub fn vertex_triangles(vertex_count: usize, triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
    let mut offsets = vec![0u32; vertex_count + 1];
    for t in triangles {
        for &v in t {
            offsets[v as usize + 1] += 1;
        }
    }
    for i in 0..vertex_count {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut adjacency = vec![0u32; offsets[vertex_count] as usize];
    for (i, t) in triangles.iter().enumerate() {
        for &v in t {
            adjacency[fill[v as usize] as usize] = i as u32;
            fill[v as usize] += 1;
        }
    }
    (offsets, adjacency)
}
