// The drawn surface carried by the deformed mechanical surface, on the GPU
// (palpa-core's visual::VisualSurface::deform is the reference; the tests compare).
//
// embed:          p = λ_a a + λ_b b + λ_c c + h n   (a, b, c the deformed mechanical
//                 corners, n their unit normal); w = the corners' |u| interpolated.
// embed_normals:  n_v = normalize(Σ_{t ∋ v} (b − a) × (c − a)) over the drawn
//                 triangles incident to v, from a CSR adjacency list.

struct Params {
    vertex_count: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> mechanical: array<vec4<f32>>;
// The three mechanical corners of each drawn vertex (w unused).
@group(0) @binding(2) var<storage, read> corners: array<vec4<u32>>;
// λ_a, λ_b, λ_c and the height h (mm).
@group(0) @binding(3) var<storage, read> weights: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> positions: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> adjacency_offsets: array<u32>;
@group(0) @binding(6) var<storage, read> adjacency: array<u32>;
@group(0) @binding(7) var<storage, read> triangles: array<u32>;
@group(0) @binding(8) var<storage, read_write> normals: array<vec4<f32>>;

@compute @workgroup_size(64)
fn embed(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = gid.x;
    if (v >= params.vertex_count) {
        return;
    }
    let c = corners[v];
    let w = weights[v];
    let a = mechanical[c.x];
    let b = mechanical[c.y];
    let d = mechanical[c.z];
    let n = cross(b.xyz - a.xyz, d.xyz - a.xyz);
    let len = length(n);
    var h = 0.0;
    if (len > 0.0) {
        h = w.w / len;
    }
    let p = w.x * a.xyz + w.y * b.xyz + w.z * d.xyz + h * n;
    positions[v] = vec4<f32>(p, w.x * a.w + w.y * b.w + w.z * d.w);
}

@compute @workgroup_size(64)
fn embed_normals(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = gid.x;
    if (v >= params.vertex_count) {
        return;
    }
    var n = vec3<f32>(0.0);
    for (var i = adjacency_offsets[v]; i < adjacency_offsets[v + 1u]; i++) {
        let t = adjacency[i];
        let a = positions[triangles[3u * t]].xyz;
        let b = positions[triangles[3u * t + 1u]].xyz;
        let c = positions[triangles[3u * t + 2u]].xyz;
        n += cross(b - a, c - a);
    }
    let len = length(n);
    var out = vec3<f32>(0.0, 0.0, 1.0);
    if (len > 0.0) {
        out = n / len;
    }
    normals[v] = vec4<f32>(out, 0.0);
}
