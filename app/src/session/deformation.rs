//! What a palpation frame evaluates on the CPU: the mode coefficients at the probe,
//! the near field under the tool and, for a hyperelastic vademecum, the tissue's
//! nonlinear residual (both added per row, for the GPU and the picture), the drawn
//! tip, and on demand the whole deformed surface (for picking) and its normals (for
//! drawing, where the CPU deforms: [`DeformOn::Cpu`]). Reused buffers: nothing is
//! allocated per frame.

use std::sync::Arc;

use glam::Vec3;
use palpa_core::scene::{PalpationScene, ProbePoint};
use palpa_core::tissue::bound::TissueScratch;
use palpa_core::tissue::online::Tissue;

#[cfg(doc)]
use crate::render::deform::DeformOn;
use crate::render::deform::{CpuSurface, SurfaceGain, Vec4Data};
use palpa_core::pgd::nodule::table::surface_gain;

#[derive(Debug)]
pub struct Deformation {
    coeffs: Vec<f64>,
    /// Modes of the last evaluation.
    n: usize,
    deformed_mm: Vec<[f32; 3]>,
    displacement: Vec<f64>,
    /// The near field of the current frame (rows of the scene; zero without one) and
    /// the same per render vertex for the GPU.
    near_rows: Vec<f64>,
    near_gpu: Vec<[f32; 4]>,
    deformed_valid: bool,
    /// The CPU-deformed render surface (xyz, |u|), and the drawn surface carried on
    /// it as the GPU's vertex buffers hold it, with its normals' sums.
    cpu_mechanical: Vec<Vec4Data>,
    /// The drawn surface's positions for picking.
    drawn_mm: Vec<[f32; 3]>,
    cpu_positions: Vec<Vec4Data>,
    cpu_normals: Vec<Vec4Data>,
    normal_sums: Vec<[f32; 3]>,
    /// The hyperelastic vademecum's residual surface, if the scene has one.
    tissue: Option<(Arc<Tissue>, TissueScratch)>,
    /// A hidden nodule's gain on the surface: the probe's rest position (mm) and the
    /// effect at the press (0: none).
    gain: ([f64; 3], f64),
}

/// A press to show: where, the linear force that gives its depth, and the depth.
pub type Press<'a> = (&'a ProbePoint, [f64; 3], f64);

impl Deformation {
    pub fn new(scene: &PalpationScene, tissue: Option<Arc<Tissue>>) -> Self {
        let rows = scene.model().rows();
        let tissue = tissue.map(|t| {
            let scratch = t.bound.scratch();
            (t, scratch)
        });
        Deformation {
            tissue,
            coeffs: vec![0.0; scene.modes()],
            n: 1,
            deformed_mm: scene.vertices_mm().to_vec(),
            displacement: vec![0.0; rows],
            near_rows: vec![0.0; rows],
            near_gpu: vec![[0.0; 4]; rows / 3],
            deformed_valid: true,
            cpu_mechanical: vec![[0.0; 4]; rows / 3],
            drawn_mm: scene.visual().rest_mm.clone(),
            cpu_positions: vec![[0.0; 4]; scene.visual().rest_mm.len()],
            cpu_normals: vec![[0.0; 4]; scene.visual().rest_mm.len()],
            normal_sums: vec![[0.0; 3]; scene.visual().rest_mm.len()],
            gain: ([0.0; 3], 0.0),
        }
    }

    /// Evaluates the first `n` modes and the near field for a probe at `p` pushing with
    /// the linear `force` (N) of its depth (and the tissue's residual at that depth),
    /// or the rest shape with no probe; a hidden nodule changing the force there by
    /// `nodule_effect` sways the surface away from the tool with it
    /// ([`palpa_core::pgd::nodule::table::surface_gain`]). Returns the drawn tip (mm).
    pub fn evaluate(
        &mut self,
        scene: &PalpationScene,
        probe: Option<Press<'_>>,
        nodule_effect: f64,
        n: usize,
    ) -> Option<Vec3> {
        self.deformed_valid = false;
        self.n = n;
        self.gain = (
            probe.map_or([0.0; 3], |(p, _, _)| scene.frame(p).0),
            if probe.is_some() { nodule_effect } else { 0.0 },
        );
        let Some((p, force, depth_mm)) = probe else {
            self.coeffs[..n].fill(0.0);
            self.update_near(scene, None);
            return None;
        };
        if scene
            .model()
            .particularize(&[scene.param(p, force)], &mut self.coeffs[..n])
            .is_err()
        {
            self.coeffs[..n].fill(0.0);
        }
        self.update_near(scene, Some((p, force, depth_mm)));
        let (x, _) = scene.frame(p);
        let u = scene.point_displacement(p, &self.coeffs[..n], Some(&self.near_rows));
        Some(Vec3::new(
            (x[0] + u[0]) as f32,
            (x[1] + u[1]) as f32,
            (x[2] + u[2]) as f32,
        ))
    }

    /// The coefficients of the last evaluation.
    pub fn coeffs(&self) -> &[f64] {
        &self.coeffs[..self.n]
    }

    /// The near field per render vertex, for the GPU.
    pub fn near_gpu(&self) -> &[[f32; 4]] {
        &self.near_gpu
    }

    /// The nodule's gain on the surface, for the GPU.
    pub fn surface_gain(&self) -> SurfaceGain {
        let ([x, y, z], e) = self.gain;
        SurfaceGain([x as f32, y as f32, z as f32, e as f32])
    }

    /// The surface's displacement at render vertex `i` (mm): the modes', the near
    /// field's, times the nodule's gain there.
    fn vertex_u(&self, i: usize, rest_mm: [f32; 3]) -> [f64; 3] {
        let (at, e) = self.gain;
        let g = if e == 0.0 {
            1.0
        } else {
            let r2: f64 = (0..3)
                .map(|c| (f64::from(rest_mm[c]) - at[c]).powi(2))
                .sum();
            surface_gain(e, r2)
        };
        [0, 1, 2].map(|c| (self.displacement[3 * i + c] + self.near_rows[3 * i + c]) * g)
    }

    /// The exact near field under the tool plus the tissue's residual (zero with no
    /// probe, or with neither).
    fn update_near(&mut self, scene: &PalpationScene, probe: Option<Press<'_>>) {
        if scene.near().is_none() && self.tissue.is_none() {
            return;
        }
        self.near_rows.fill(0.0);
        if let Some((p, force, _)) = probe
            && scene
                .add_near_displacement(p, force, &mut self.near_rows)
                .is_err()
        {
            self.near_rows.fill(0.0);
        }
        if let (Some((p, _, depth_mm)), Some((tissue, scratch))) = (probe, self.tissue.as_mut()) {
            tissue
                .bound
                .add_surface(p, depth_mm, scratch, &mut self.near_rows);
        }
        for (g, r) in self.near_gpu.iter_mut().zip(self.near_rows.chunks_exact(3)) {
            *g = [r[0] as f32, r[1] as f32, r[2] as f32, 0.0];
        }
    }

    /// The drawn surface carried on the CPU-deformed render surface as last computed
    /// (what picking hits: the surface as drawn).
    pub fn drawn_mm(&mut self, scene: &PalpationScene) -> &[[f32; 3]] {
        for (m, d) in self.cpu_mechanical.iter_mut().zip(&self.deformed_mm) {
            *m = [d[0], d[1], d[2], 0.0];
        }
        scene.visual().deform(
            &self.cpu_mechanical,
            &mut self.cpu_positions,
            &mut self.cpu_normals,
            &mut self.normal_sums,
        );
        for (o, p) in self.drawn_mm.iter_mut().zip(&self.cpu_positions) {
            *o = [p[0], p[1], p[2]];
        }
        &self.drawn_mm
    }

    /// The drawn surface [`Self::drawn_mm`] last computed.
    pub fn last_drawn_mm(&self) -> &[[f32; 3]] {
        &self.drawn_mm
    }

    /// The CPU-deformed surface for the last evaluation (the GPU path's reference, and
    /// what picking hits).
    pub fn deformed_mm(&mut self, scene: &PalpationScene) -> &[[f32; 3]] {
        if !self.deformed_valid {
            scene
                .model()
                .reconstruct(&self.coeffs[..self.n], &mut self.displacement);
            for (i, r) in scene.vertices_mm().iter().enumerate() {
                let u = self.vertex_u(i, *r);
                self.deformed_mm[i] = [0, 1, 2].map(|c| r[c] + u[c] as f32);
            }
            self.deformed_valid = true;
        }
        &self.deformed_mm
    }

    /// The drawn surface of the last evaluation deformed on the CPU, as the compute
    /// passes would leave it: the render surface's positions with `|u|` (in double
    /// precision, then rounded), the drawn surface carried on them
    /// ([`palpa_core::visual::VisualSurface::deform`]) with area-weighted unit normals
    /// (`+z` where the triangles' areas cancel, as on the GPU).
    pub fn cpu_surface(&mut self, scene: &PalpationScene) -> CpuSurface<'_> {
        self.deformed_mm(scene);
        for (i, r) in scene.vertices_mm().iter().enumerate() {
            let u = self.vertex_u(i, *r);
            let d = self.deformed_mm[i];
            let u = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
            self.cpu_mechanical[i] = [d[0], d[1], d[2], u as f32];
        }
        scene.visual().deform(
            &self.cpu_mechanical,
            &mut self.cpu_positions,
            &mut self.cpu_normals,
            &mut self.normal_sums,
        );
        self.last_cpu_surface()
    }

    /// The surface [`Self::cpu_surface`] last computed.
    pub fn last_cpu_surface(&self) -> CpuSurface<'_> {
        CpuSurface {
            positions: &self.cpu_positions,
            normals: &self.cpu_normals,
            mechanical: &self.cpu_mechanical,
        }
    }
}
