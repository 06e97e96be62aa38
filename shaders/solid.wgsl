// Solid objects: the probe (rod and tip) and the force arrow.

struct Object {
    world_from_model: mat4x4<f32>,
    // Inverse transpose of the upper 3×3 (as columns of a 4×4), for normals.
    normal_from_model: mat4x4<f32>,
    color: vec4<f32>,
}

@group(1) @binding(0) var<uniform> object: Object;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

@vertex
fn vs_main(@location(0) position: vec3<f32>, @location(1) normal: vec3<f32>) -> VertexOut {
    let world = object.world_from_model * vec4<f32>(position, 1.0);
    var out: VertexOut;
    out.clip = frame.clip_from_world * world;
    out.world = world.xyz;
    out.normal = (object.normal_from_model * vec4<f32>(normal, 0.0)).xyz;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let n = normalize(in.normal);
    let l = frame.light_dir.xyz;
    let v = normalize(frame.eye.xyz - in.world);
    let h = normalize(l + v);
    let diffuse = max(dot(n, l), 0.0);
    let specular = pow(max(dot(n, h), 0.0), 32.0) * 0.5;
    let color = object.color.rgb * (0.3 + 0.7 * diffuse) + vec3<f32>(specular);
    return vec4<f32>(color, object.color.a);
}
