// The joint distribution of two species as a lit height field (the network scene):
// height and colour both the probability, scaled to the window's peak.

struct View {
    clip_from_world: mat4x4<f32>,
    eye: vec4<f32>,
    // Unit vector towards the light.
    light_dir: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) value: f32,
}

@vertex
fn vs_main(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) value: f32,
) -> VertexOut {
    var out: VertexOut;
    out.clip = view.clip_from_world * vec4<f32>(position, 1.0);
    out.world = position;
    out.normal = normal;
    out.value = value;
    return out;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var n = normalize(in.normal);
    if (!front) {
        n = -n;
    }
    let l = view.light_dir.xyz;
    let v = normalize(view.eye.xyz - in.world);
    let h = normalize(l + v);
    let diffuse = abs(dot(n, l));
    let specular = pow(max(dot(n, h), 0.0), 48.0) * 0.25;
    let color = ramp(in.value) * (0.35 + 0.65 * diffuse) + vec3<f32>(specular);
    return vec4<f32>(color, 1.0);
}
