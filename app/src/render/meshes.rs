//! Unit meshes for the probe and the force arrow: a cylinder (radius 1, z ∈ [0, 1]), a
//! cone (base radius 1 at z = 0, apex at z = 1) and a sphere (radius 1), with normals.

use bytemuck::{Pod, Zeroable};
use std::ops::Range;

#[derive(Debug, Clone, Copy, Pod, Zeroable)]
#[repr(C)]
pub struct SolidVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
}

/// The three unit meshes in one vertex list (triangle list, no indices).
#[derive(Debug)]
pub struct UnitMeshes {
    pub vertices: Vec<SolidVertex>,
    pub cylinder: Range<u32>,
    pub cone: Range<u32>,
    pub sphere: Range<u32>,
}

const SEGMENTS: usize = 24;

fn v(position: [f32; 3], normal: [f32; 3]) -> SolidVertex {
    SolidVertex { position, normal }
}

pub fn unit_meshes() -> UnitMeshes {
    let mut out = Vec::new();
    let ring = |i: usize| {
        let a = i as f32 / SEGMENTS as f32 * std::f32::consts::TAU;
        (a.cos(), a.sin())
    };
    let start = out.len() as u32;
    for i in 0..SEGMENTS {
        let (c0, s0) = ring(i);
        let (c1, s1) = ring(i + 1);
        let (n0, n1) = ([c0, s0, 0.0], [c1, s1, 0.0]);
        out.extend([
            v([c0, s0, 0.0], n0),
            v([c1, s1, 0.0], n1),
            v([c1, s1, 1.0], n1),
            v([c0, s0, 0.0], n0),
            v([c1, s1, 1.0], n1),
            v([c0, s0, 1.0], n0),
        ]);
        // Caps.
        out.extend([
            v([0.0, 0.0, 1.0], [0.0, 0.0, 1.0]),
            v([c0, s0, 1.0], [0.0, 0.0, 1.0]),
            v([c1, s1, 1.0], [0.0, 0.0, 1.0]),
            v([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]),
            v([c1, s1, 0.0], [0.0, 0.0, -1.0]),
            v([c0, s0, 0.0], [0.0, 0.0, -1.0]),
        ]);
    }
    let cylinder = start..out.len() as u32;

    let start = out.len() as u32;
    let k = std::f32::consts::FRAC_1_SQRT_2;
    for i in 0..SEGMENTS {
        let (c0, s0) = ring(i);
        let (c1, s1) = ring(i + 1);
        out.extend([
            v([c0, s0, 0.0], [c0 * k, s0 * k, k]),
            v([c1, s1, 0.0], [c1 * k, s1 * k, k]),
            v(
                [0.0, 0.0, 1.0],
                [0.5 * (c0 + c1) * k, 0.5 * (s0 + s1) * k, k],
            ),
            v([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]),
            v([c1, s1, 0.0], [0.0, 0.0, -1.0]),
            v([c0, s0, 0.0], [0.0, 0.0, -1.0]),
        ]);
    }
    let cone = start..out.len() as u32;

    let start = out.len() as u32;
    let rings = SEGMENTS / 2;
    let point = |i: usize, j: usize| {
        let theta = j as f32 / rings as f32 * std::f32::consts::PI;
        let (c, s) = ring(i);
        let p = [theta.sin() * c, theta.sin() * s, theta.cos()];
        v(p, p)
    };
    for j in 0..rings {
        for i in 0..SEGMENTS {
            out.extend([
                point(i, j),
                point(i, j + 1),
                point(i + 1, j + 1),
                point(i, j),
                point(i + 1, j + 1),
                point(i + 1, j),
            ]);
        }
    }
    let sphere = start..out.len() as u32;
    UnitMeshes {
        vertices: out,
        cylinder,
        cone,
        sphere,
    }
}
