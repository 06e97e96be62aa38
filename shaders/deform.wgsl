// Deformation of the scene's surface by the meta-model, on the GPU.
//
// displace: u_v = Σ_{k<n} X[3v + c, k] · coeffs[k] + near_v  (c = x, y, z), one
//           invocation per vertex; writes the deformed position and |u| (for the
//           colormap). near_v is the exact near field under the tool, computed on the
//           CPU each frame (zero for a model without one).
// normals:  n_v = normalize(Σ_{t ∋ v} (b − a) × (c − a)) over the deformed triangles
//           incident to v (area-weighted), read from a CSR adjacency list.
// The CPU path (palpa-core's SeparatedModel::reconstruct) is the reference; the tests
// compare both.

struct Params {
    vertex_count: u32,
    // Columns of the row-major mode matrix X (the stored mode count N).
    modes_stride: u32,
    // Modes used, n ≤ N and n ≤ 4 · 128.
    modes_used: u32,
    triangle_count: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> coeffs: array<vec4<f32>, 128>;
@group(0) @binding(2) var<storage, read> modes: array<f32>;
@group(0) @binding(3) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> deformed: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> adjacency_offsets: array<u32>;
@group(0) @binding(6) var<storage, read> adjacency: array<u32>;
@group(0) @binding(7) var<storage, read> triangles: array<u32>;
@group(0) @binding(8) var<storage, read_write> normals: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read> near: array<vec4<f32>>;

fn coeff(k: u32) -> f32 {
    return coeffs[k / 4u][k % 4u];
}

@compute @workgroup_size(64)
fn displace(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = gid.x;
    if (v >= params.vertex_count) {
        return;
    }
    var u = vec3<f32>(0.0);
    for (var c = 0u; c < 3u; c++) {
        let row = (3u * v + c) * params.modes_stride;
        var s = 0.0;
        for (var k = 0u; k < params.modes_used; k++) {
            s = fma(modes[row + k], coeff(k), s);
        }
        u[c] = s;
    }
    u += near[v].xyz;
    deformed[v] = vec4<f32>(rest[v].xyz + u, length(u));
}

@compute @workgroup_size(64)
fn normals_pass(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = gid.x;
    if (v >= params.vertex_count) {
        return;
    }
    var n = vec3<f32>(0.0);
    for (var i = adjacency_offsets[v]; i < adjacency_offsets[v + 1u]; i++) {
        let t = adjacency[i];
        let a = deformed[triangles[3u * t]].xyz;
        let b = deformed[triangles[3u * t + 1u]].xyz;
        let c = deformed[triangles[3u * t + 2u]].xyz;
        n += cross(b - a, c - a);
    }
    let len = length(n);
    var out = vec3<f32>(0.0, 0.0, 1.0);
    if (len > 0.0) {
        out = n / len;
    }
    normals[v] = vec4<f32>(out, 0.0);
}
