// The organ surface: lit with normals recomputed from the deformed positions every
// frame (embed.wgsl), optionally coloured by displacement magnitude; and its planar
// shadow on the ground (drawn once per pixel through the stencil).
//
// Wet soft tissue: a soft diffuse that wraps past the terminator with a red tint (light
// scattered under the surface), a sharp specular highlight weighted by Fresnel (the
// wet film) over a broad faint sheen, and a darkening about the tool where it presses
// (the contact's occlusion).

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
    // The stiffness map: the force with a nodule over the force without, from 1 to
    // frame.colormap.w on the ramp.
    // The tissue keeps its colour where the ratio is 1 and turns into the ramp within
    // the scale's first tenth.
    if (frame.colormap.z > 1.5) {
        let t = clamp((in.palpable - 1.0) / max(frame.colormap.w - 1.0, 1e-6), 0.0, 1.0);
        base = mix(base, ramp(t), clamp(10.0 * t, 0.0, 1.0));
    }
    // Region painting: neither grey, palpable green, fixed blue (the value is 0, 1, 2
    // per vertex).
    if (frame.colormap.z > 0.5 && frame.colormap.z < 1.5) {
        base = mix(vec3<f32>(0.10, 0.09, 0.085), vec3<f32>(0.07, 0.28, 0.06), clamp(in.palpable, 0.0, 1.0));
        if (in.palpable > 1.5) {
            base = vec3<f32>(0.04, 0.10, 0.38);
        }
    }
    // Sky/ground hemisphere ambient; wrapped diffuse with a red scattering tint.
    let ambient = mix(vec3<f32>(0.12, 0.11, 0.10), vec3<f32>(0.30, 0.32, 0.36), 0.5 + 0.5 * n.z);
    let nl = dot(n, l);
    let wrap = 0.35;
    let diffuse = max((nl + wrap) / (1.0 + wrap), 0.0);
    let scatter = vec3<f32>(0.55, 0.12, 0.08) * (diffuse - max(nl, 0.0));
    // Contact occlusion: up to 45 % darker within about two tool radii of the contact.
    var occlusion = 1.0;
    if (frame.tool.w > 0.0) {
        let d = length(in.world - frame.tool.xyz) / (2.0 * frame.tool.w);
        occlusion = 1.0 - 0.45 * exp(-d * d);
    }
    // Schlick's Fresnel for a water film (F0 = 0.02), a sharp highlight and a sheen.
    let nv = max(dot(n, v), 0.0);
    let fresnel = 0.02 + 0.98 * pow(1.0 - nv, 5.0);
    let nh = max(dot(n, h), 0.0);
    let specular = (pow(nh, 220.0) * 0.9 + pow(nh, 24.0) * 0.05) * (0.35 + fresnel) * step(0.0, nl);
    let rim = fresnel * 0.08;
    let color = occlusion * (base * (ambient + 0.85 * diffuse) + base * scatter)
        + vec3<f32>(occlusion * specular + rim);
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
