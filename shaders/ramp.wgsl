// The colour ramp shared by the organ's displacement colormap and the network
// landscape (the interface's legend and heat map use the same one: `ui::ramp`);
// prepended to surface.wgsl and landscape.wgsl when they are built.

// A perceptually ordered blue → cyan → green → yellow → red ramp (a short "turbo").
fn ramp(t: f32) -> vec3<f32> {
    let x = clamp(t, 0.0, 1.0);
    let r = clamp(1.5 - abs(4.0 * x - 3.0), 0.0, 1.0);
    let g = clamp(1.5 - abs(4.0 * x - 2.0), 0.0, 1.0);
    let b = clamp(1.5 - abs(4.0 * x - 1.0), 0.0, 1.0);
    return vec3<f32>(r, g, b);
}
