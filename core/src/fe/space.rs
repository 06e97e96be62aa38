//! The finite-element space: nodes (mesh vertices, plus edge midpoints for P2), cells,
//! boundary faces, and the numbering of free degrees of freedom.

use std::collections::HashMap;

use super::Element;
use super::shape::{TET_EDGES, TRI_EDGES};
use crate::mesh::TetMesh;

/// Nodes and connectivity of a P1 or P2 discretization of a tetrahedral mesh.
#[derive(Debug, Clone)]
pub struct Space {
    pub element: Element,
    /// Node positions: the mesh vertices first (same indices), then P2 edge midpoints.
    pub nodes: Vec<[f64; 3]>,
    /// `nodes_per_cell` node indices per cell, VTK order.
    pub cells: Vec<u32>,
    /// Boundary faces, `nodes_per_face` indices each (outward orientation).
    pub faces: Vec<u32>,
    /// Per node: clamped (u = 0).
    pub fixed: Vec<bool>,
    /// Per node: index of its x degree of freedom among the free ones (y, z follow),
    /// or `u32::MAX` when fixed.
    pub dof: Vec<u32>,
    pub free_dofs: usize,
    /// Number of mesh vertices (the first nodes).
    pub vertices: usize,
    /// Each cell's Young's modulus as a multiple of the material's (same ν): a
    /// nodule's stiffness on the mesh ([`super::nodule`]). `None`: one material.
    pub stiffness: Option<Vec<f64>>,
}

impl Space {
    /// Builds the space. `boundary` are the mesh's boundary triangles, `fixed_vertex`
    /// flags mesh vertices; a P2 midpoint is fixed when both its end vertices are.
    pub fn new(
        mesh: &TetMesh,
        boundary: &[[u32; 3]],
        fixed_vertex: &[bool],
        element: Element,
    ) -> Space {
        let nv = mesh.vertices.len();
        let mut nodes = mesh.vertices.clone();
        let mut fixed = fixed_vertex.to_vec();
        let npc = element.nodes_per_cell();
        let mut cells = Vec::with_capacity(mesh.tets.len() * npc);
        let mut faces = Vec::with_capacity(boundary.len() * element.nodes_per_face());
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint =
            |a: u32, b: u32, nodes: &mut Vec<[f64; 3]>, fixed: &mut Vec<bool>| -> u32 {
                let key = if a < b { (a, b) } else { (b, a) };
                *mid.entry(key).or_insert_with(|| {
                    let (pa, pb) = (nodes[a as usize], nodes[b as usize]);
                    nodes.push([0, 1, 2].map(|d| 0.5 * (pa[d] + pb[d])));
                    fixed.push(fixed[a as usize] && fixed[b as usize]);
                    (nodes.len() - 1) as u32
                })
            };
        for t in &mesh.tets {
            cells.extend_from_slice(t);
            if element == Element::P2 {
                for (i, j) in TET_EDGES {
                    let m = midpoint(t[i], t[j], &mut nodes, &mut fixed);
                    cells.push(m);
                }
            }
        }
        for f in boundary {
            faces.extend_from_slice(f);
            if element == Element::P2 {
                for (i, j) in TRI_EDGES {
                    let m = midpoint(f[i], f[j], &mut nodes, &mut fixed);
                    faces.push(m);
                }
            }
        }
        let mut dof = vec![u32::MAX; nodes.len()];
        let mut next = 0u32;
        for (n, d) in dof.iter_mut().enumerate() {
            if !fixed[n] {
                *d = next;
                next += 3;
            }
        }
        Space {
            element,
            nodes,
            cells,
            faces,
            fixed,
            dof,
            free_dofs: next as usize,
            vertices: nv,
            stiffness: None,
        }
    }

    /// The Lamé parameters of cell `c` for a material of `(lambda, mu)`: scaled by the
    /// cell's stiffness factor where the space has one.
    #[inline]
    pub fn lame_in(&self, c: usize, lambda: f64, mu: f64) -> (f64, f64) {
        match &self.stiffness {
            Some(s) => (lambda * s[c], mu * s[c]),
            None => (lambda, mu),
        }
    }

    /// The non-zero entries of an all-node vector (`3 × nodes`) at the free unknowns,
    /// as (unknown, value), ascending.
    pub fn free_entries(&self, v: &[f64]) -> Vec<(u32, f64)> {
        let mut out = Vec::new();
        for (node, &d) in self.dof.iter().enumerate() {
            if d != u32::MAX {
                for k in 0..3 {
                    if v[3 * node + k] != 0.0 {
                        out.push((d + k as u32, v[3 * node + k]));
                    }
                }
            }
        }
        out
    }

    pub fn cell_count(&self) -> usize {
        self.cells.len() / self.element.nodes_per_cell()
    }
    pub fn cell(&self, c: usize) -> &[u32] {
        let n = self.element.nodes_per_cell();
        &self.cells[c * n..(c + 1) * n]
    }
    pub fn face_count(&self) -> usize {
        self.faces.len() / self.element.nodes_per_face()
    }
    pub fn face(&self, f: usize) -> &[u32] {
        let n = self.element.nodes_per_face();
        &self.faces[f * n..(f + 1) * n]
    }
    /// Corner positions of a cell.
    pub fn cell_corners(&self, c: usize) -> [[f64; 3]; 4] {
        let cell = self.cell(c);
        [0, 1, 2, 3].map(|i| self.nodes[cell[i] as usize])
    }
    pub fn fixed_count(&self) -> usize {
        self.fixed.iter().filter(|&&f| f).count()
    }

    /// Expands free-dof values to all nodes (fixed nodes get 0): `3 × nodes` entries.
    pub fn expand(&self, free: &[f64]) -> Vec<f64> {
        let mut u = vec![0.0; 3 * self.nodes.len()];
        for (n, &d) in self.dof.iter().enumerate() {
            if d != u32::MAX {
                u[3 * n..3 * n + 3].copy_from_slice(&free[d as usize..d as usize + 3]);
            }
        }
        u
    }

    /// Restricts an all-node vector (`3 × nodes`) to the free dofs.
    pub fn restrict(&self, full: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.free_dofs];
        for (n, &d) in self.dof.iter().enumerate() {
            if d != u32::MAX {
                out[d as usize..d as usize + 3].copy_from_slice(&full[3 * n..3 * n + 3]);
            }
        }
        out
    }
}
