// The per-frame uniform shared by every render shader; prepended to surface.wgsl,
// ground.wgsl and solid.wgsl when they are built (see app/src/render/shaders.rs).

struct Frame {
    clip_from_world: mat4x4<f32>,
    eye: vec4<f32>,
    // Unit vector towards the light.
    light_dir: vec4<f32>,
    // x: ground height (mm), y: grid spacing (mm), z: ground half-extent (mm).
    ground: vec4<f32>,
    // x: colormap on (1) or off (0), y: displacement at the top of the scale (mm);
    // z: per-vertex values colour the surface: 0 off, 1 painted regions, 2 the
    // stiffness map with w at the top of the scale.
    colormap: vec4<f32>,
    // xyz: ground centre (mm).
    center: vec4<f32>,
    // xyz: where the tool touches (mm), w: its radius (mm; 0 without a tool).
    tool: vec4<f32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;
