// Deformation of the scene's surface by the meta-model, on the GPU.
//
// displace: u_v = Σ_{k<n} X[3v + c, k] · coeffs[k] + near_v  (c = x, y, z), one
//           invocation per vertex; writes the deformed position and |u| (for the
//           colormap). near_v is the exact near field under the tool, computed on the
//           CPU each frame (zero for a model without one); then, with a hidden
//           nodule changing the force by e, u_v times 1 + e (1 − exp(−r²/ℓ²)), r the
//           vertex's rest distance from the probe (palpa-core's surface_gain: the
//           depth holds the surface under the tool, the total force sways it away).
// The drawn surface is carried on these positions by embed.wgsl, which also computes
// its normals.
// The CPU path (palpa-core's SeparatedModel::reconstruct) is the reference; the tests
// compare both.

struct Params {
    vertex_count: u32,
    // Columns of the row-major mode matrix X (the stored mode count N).
    modes_stride: u32,
    // Modes used, n ≤ N and n ≤ 4 · 128.
    modes_used: u32,
    // ℓ (mm) of the nodule's gain; positive.
    near_mm: f32,
    // The probe's rest position (mm) and the nodule's effect e (0: none).
    gain: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> coeffs: array<vec4<f32>, 128>;
@group(0) @binding(2) var<storage, read> modes: array<f32>;
@group(0) @binding(3) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> deformed: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> near: array<vec4<f32>>;

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
    let r = rest[v].xyz - params.gain.xyz;
    u *= 1.0 + params.gain.w * (1.0 - exp(-dot(r, r) / (params.near_mm * params.near_mm)));
    deformed[v] = vec4<f32>(rest[v].xyz + u, length(u));
}
