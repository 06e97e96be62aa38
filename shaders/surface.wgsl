// The organ surface: lit with normals recomputed from the deformed positions every
// frame (deform.wgsl), optionally coloured by displacement magnitude; and its planar
// shadow on the ground (drawn once per pixel through the stencil).

struct VertexIn {
    // xyz: deformed position (mm), w: |u| (mm).
    @location(0) position: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) palpable: f32,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) magnitude: f32,
    @location(3) palpable: f32,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.clip_from_world * vec4<f32>(v.position.xyz, 1.0);
    out.world = v.position.xyz;
    out.normal = v.normal.xyz;
    out.magnitude = v.position.w;
    out.palpable = v.palpable;
    return out;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var n = normalize(in.normal);
    if (!front) {
        n = -n;
    }
    let l = frame.light_dir.xyz;
    let v = normalize(frame.eye.xyz - in.world);
    let h = normalize(l + v);
    // Liver red-brown (linear); the palpable region a shade lighter.
    var base = mix(vec3<f32>(0.20, 0.040, 0.028), vec3<f32>(0.26, 0.055, 0.036), in.palpable);
    if (frame.colormap.x > 0.5) {
        base = ramp(in.magnitude / max(frame.colormap.y, 1e-6));
    }
    // Region painting: neither grey, palpable green, fixed blue (the value is 0, 1, 2
    // per vertex).
    if (frame.colormap.z > 0.5) {
        base = mix(vec3<f32>(0.10, 0.09, 0.085), vec3<f32>(0.07, 0.28, 0.06), clamp(in.palpable, 0.0, 1.0));
        if (in.palpable > 1.5) {
            base = vec3<f32>(0.04, 0.10, 0.38);
        }
    }
    // Sky/ground hemisphere ambient, Lambert diffuse, Blinn-Phong wet-tissue highlight.
    let ambient = mix(vec3<f32>(0.12, 0.11, 0.10), vec3<f32>(0.30, 0.32, 0.36), 0.5 + 0.5 * n.z);
    let diffuse = max(dot(n, l), 0.0);
    let specular = pow(max(dot(n, h), 0.0), 48.0) * 0.25;
    let rim = pow(1.0 - max(dot(n, v), 0.0), 3.0) * 0.06;
    let color = base * (ambient + 0.85 * diffuse) + vec3<f32>(specular + rim);
    return vec4<f32>(color, 1.0);
}

@vertex
fn vs_shadow(@location(0) position: vec4<f32>) -> @builtin(position) vec4<f32> {
    // Project along the light onto the plane z = ground (a hair above it).
    let l = frame.light_dir.xyz;
    let p = position.xyz;
    let t = (p.z - frame.ground.x - 0.3) / max(l.z, 0.05);
    let q = p - l * t;
    return frame.clip_from_world * vec4<f32>(q, 1.0);
}

@fragment
fn fs_shadow() -> @location(0) vec4<f32> {
    return vec4<f32>(0.0, 0.0, 0.0, 0.35);
}
