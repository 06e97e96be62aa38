//! The render pipelines and their bind-group layouts, built once per renderer: the
//! ground, the organ's shadow (stencilled so it darkens each pixel once), the deformed
//! surface, the solid probe and arrow meshes, and a revealed nodule seen through the
//! surface.

use super::DEPTH_FORMAT;
use super::meshes::SolidVertex;
use super::shaders::Shader;

/// The two uniform layouts: per frame, and per object (dynamic offset).
pub struct Layouts {
    pub frame: wgpu::BindGroupLayout,
    pub object: wgpu::BindGroupLayout,
}

impl Layouts {
    pub fn new(device: &wgpu::Device) -> Layouts {
        let uniform_layout = |label: &str, dynamic: bool| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries: &[wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: dynamic,
                        min_binding_size: None,
                    },
                    count: None,
                }],
            })
        };
        Layouts {
            frame: uniform_layout("frame", false),
            object: uniform_layout("object", true),
        }
    }
}

/// Everything one pipeline differs in.
struct Spec<'a> {
    label: &'a str,
    layout: &'a wgpu::PipelineLayout,
    module: &'a wgpu::ShaderModule,
    entry: (&'a str, &'a str),
    buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    cull: Option<wgpu::Face>,
    depth_stencil: Option<wgpu::DepthStencilState>,
    targets: &'a [Option<wgpu::ColorTargetState>],
}

fn build(device: &wgpu::Device, s: Spec<'_>) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(s.label),
        layout: Some(s.layout),
        vertex: wgpu::VertexState {
            module: s.module,
            entry_point: Some(s.entry.0),
            compilation_options: Default::default(),
            buffers: s.buffers,
        },
        primitive: wgpu::PrimitiveState {
            cull_mode: s.cull,
            ..Default::default()
        },
        depth_stencil: s.depth_stencil,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: s.module,
            entry_point: Some(s.entry.1),
            compilation_options: Default::default(),
            targets: s.targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

fn depth(write: bool, stencil: wgpu::StencilState) -> Option<wgpu::DepthStencilState> {
    depth_compared(write, wgpu::CompareFunction::LessEqual, stencil)
}

fn depth_compared(
    write: bool,
    compare: wgpu::CompareFunction,
    stencil: wgpu::StencilState,
) -> Option<wgpu::DepthStencilState> {
    Some(wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(write),
        depth_compare: Some(compare),
        stencil,
        bias: wgpu::DepthBiasState::default(),
    })
}

/// The shadow darkens a pixel only where the stencil is still 0, then marks it.
fn shadow_stencil() -> wgpu::StencilState {
    let once = wgpu::StencilFaceState {
        compare: wgpu::CompareFunction::Equal,
        fail_op: wgpu::StencilOperation::Keep,
        depth_fail_op: wgpu::StencilOperation::Keep,
        pass_op: wgpu::StencilOperation::IncrementClamp,
    };
    wgpu::StencilState {
        front: once,
        back: once,
        read_mask: 0xff,
        write_mask: 0xff,
    }
}

pub struct Pipelines {
    pub ground: wgpu::RenderPipeline,
    pub shadow: wgpu::RenderPipeline,
    pub surface: wgpu::RenderPipeline,
    pub solid: wgpu::RenderPipeline,
    /// The solid shader over whatever is in front (no depth test, no depth write),
    /// blended: what lies inside the organ, seen through it.
    pub seen_through: wgpu::RenderPipeline,
}

impl Pipelines {
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat, layouts: &Layouts) -> Self {
        let layout_frame = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("frame only"),
            bind_group_layouts: &[Some(&layouts.frame)],
            immediate_size: 0,
        });
        let layout_object = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("frame and object"),
            bind_group_layouts: &[Some(&layouts.frame), Some(&layouts.object)],
            immediate_size: 0,
        });
        // The surface reads three vertex streams: deformed position, normal, palpable flag.
        let vec4_attr = |location: u32| wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Float32x4,
            offset: 0,
            shader_location: location,
        };
        let surface_attrs = [
            vec4_attr(0),
            vec4_attr(1),
            wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32,
                offset: 0,
                shader_location: 2,
            },
        ];
        let stream = |stride: u64, attrs| {
            Some(wgpu::VertexBufferLayout {
                array_stride: stride,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: attrs,
            })
        };
        let surface_buffers = [
            stream(16, &surface_attrs[0..1]),
            stream(16, &surface_attrs[1..2]),
            stream(4, &surface_attrs[2..3]),
        ];
        let solid_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3];
        let solid_buffers = [stream(size_of::<SolidVertex>() as u64, &solid_attrs)];

        let surface_module = Shader::Surface.module(device);
        let ground_module = Shader::Ground.module(device);
        let solid_module = Shader::Solid.module(device);
        let target = |blend| {
            [Some(wgpu::ColorTargetState {
                format,
                blend,
                write_mask: wgpu::ColorWrites::ALL,
            })]
        };
        let opaque = target(None);
        let blended = target(Some(wgpu::BlendState::ALPHA_BLENDING));
        let plain = || depth(true, wgpu::StencilState::default());
        Pipelines {
            ground: build(
                device,
                Spec {
                    label: "ground",
                    layout: &layout_frame,
                    module: &ground_module,
                    entry: ("vs_main", "fs_main"),
                    buffers: &[],
                    cull: None,
                    depth_stencil: plain(),
                    targets: &opaque,
                },
            ),
            shadow: build(
                device,
                Spec {
                    label: "shadow",
                    layout: &layout_frame,
                    module: &surface_module,
                    entry: ("vs_shadow", "fs_shadow"),
                    buffers: &surface_buffers[..1],
                    cull: None,
                    depth_stencil: depth(false, shadow_stencil()),
                    targets: &blended,
                },
            ),
            surface: build(
                device,
                Spec {
                    label: "surface",
                    layout: &layout_frame,
                    module: &surface_module,
                    entry: ("vs_main", "fs_main"),
                    buffers: &surface_buffers,
                    cull: Some(wgpu::Face::Back),
                    depth_stencil: plain(),
                    targets: &opaque,
                },
            ),
            solid: build(
                device,
                Spec {
                    label: "solid",
                    layout: &layout_object,
                    module: &solid_module,
                    entry: ("vs_main", "fs_main"),
                    buffers: &solid_buffers,
                    cull: Some(wgpu::Face::Back),
                    depth_stencil: plain(),
                    targets: &blended,
                },
            ),
            seen_through: build(
                device,
                Spec {
                    label: "seen through",
                    layout: &layout_object,
                    module: &solid_module,
                    entry: ("vs_main", "fs_main"),
                    buffers: &solid_buffers,
                    cull: Some(wgpu::Face::Back),
                    depth_stencil: depth_compared(
                        false,
                        wgpu::CompareFunction::Always,
                        wgpu::StencilState::default(),
                    ),
                    targets: &blended,
                },
            ),
        }
    }
}
