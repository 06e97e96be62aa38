// The ground: a square under the organ with a millimetre grid, so depth and motion read.

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec2<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> VertexOut {
    // Two triangles covering [-1, 1]², scaled to the ground's extent.
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    let xy = frame.center.xy + corners[i] * frame.ground.z;
    var out: VertexOut;
    out.clip = frame.clip_from_world * vec4<f32>(xy, frame.ground.x, 1.0);
    out.world = xy;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let spacing = frame.ground.y;
    let cell = in.world / spacing;
    let width = fwidth(cell);
    let line = abs(fract(cell - 0.5) - 0.5) / max(width, vec2<f32>(1e-4));
    let on_line = 1.0 - clamp(min(line.x, line.y), 0.0, 1.0);
    let r = length(in.world - frame.center.xy) / frame.ground.z;
    let fade = clamp(1.0 - r, 0.0, 1.0);
    let base = vec3<f32>(0.23, 0.25, 0.28);
    let color = mix(base, vec3<f32>(0.45, 0.48, 0.52), on_line * 0.8);
    // Fade into the background colour towards the edge.
    let background = vec3<f32>(0.11, 0.12, 0.14);
    return vec4<f32>(mix(background, color, fade), 1.0);
}
