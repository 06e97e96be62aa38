//! The liver palpation vademecum: `u(x; s, t) ≈ Σ_k X_k(x) Y_k(s, t)` for a unit probe
//! force along direction `t` at any point `s` of the palpable surface.
//!
//! Discretization (docs/methods.md §1): space is the FE space (P1/P2) on the free dofs;
//! the parametric index is (palpable surface vertex j, direction c ∈ {x, y, z}),
//! `p = 3j + c`, with P1 hat functions in s (barycentric between vertices) and the
//! surface mass matrix `Ms ⊗ I₃`. Column p of F is the consistent load of a unit force
//! along `e_c` spread over the tool disk centred at vertex j (see `fe::load`); F is
//! sparse (a patch per column) and never stored dense. By linearity a force `F t` at
//! `s` is `F Σ_c t_c u(x; s, e_c)`: one particularization with the weights
//! `λ_i(s) t_c` of the [`SurfaceVector`](crate::axis::Discretization::SurfaceVector)
//! axis.

use std::collections::{BTreeMap, HashMap};
use std::time::Instant;

use rayon::prelude::*;

use super::linear::{ColSparse, Operators, Settings, Terms, solve};
use crate::axis::Discretization;
use crate::fe::elasticity::LinearProblem;
use crate::fe::load::{SurfacePoint, probe_weights};
use crate::fe::probe::organ_space;
use crate::fe::space::Space;
use crate::fe::sparse::SymCsc;
use crate::fe::{Element, FeError, Material};
use crate::organ::OrganMesh;
use crate::separated::{AxisInfo, FieldInfo, Geometry, ModelMeta, Provenance, SeparatedModel};

/// Everything the off-line solve needs, built once.
#[derive(Debug)]
pub struct Setup {
    pub space: Space,
    pub problem: LinearProblem,
    pub f: ColSparse,
    pub ms: SymCsc,
    /// Space node of each axis vertex.
    pub axis_nodes: Vec<u32>,
    pub axis_vertices: Vec<[f64; 3]>,
    pub axis_triangles: Vec<[u32; 3]>,
    pub radius_mm: f64,
    /// Boundary triangles (corner nodes), outward.
    pub boundary: Vec<[u32; 3]>,
    pub setup_s: f64,
}

impl Setup {
    pub fn ops(&self) -> Operators<'_> {
        Operators {
            k: &self.problem.stiffness,
            k_factor: &self.problem.factor,
            f: &self.f,
            ms: &self.ms,
        }
    }
}

/// Builds the operators of the vademecum for an organ mesh.
pub fn setup(
    organ: &OrganMesh,
    element: Element,
    material: Material,
    radius_mm: f64,
) -> Result<Setup, FeError> {
    let t0 = Instant::now();
    let space = organ_space(organ, element);
    let problem = LinearProblem::new(&space, material)?;
    // Palpable surface: its vertices, renumbered, and triangles.
    let mut index: HashMap<u32, u32> = HashMap::new();
    let mut axis_nodes = Vec::new();
    let mut axis_triangles = Vec::new();
    let mut face_of: Vec<(usize, usize)> = Vec::new(); // (face, corner) per axis vertex
    for (f, tri) in organ.boundary.iter().enumerate() {
        if !organ.palpable[f] {
            continue;
        }
        let t = tri.map(|v| {
            *index.entry(v).or_insert_with(|| {
                axis_nodes.push(v);
                face_of.push((
                    f,
                    tri.iter()
                        .position(|&x| x == v)
                        .expect("v was found among this triangle's corners"),
                ));
                (axis_nodes.len() - 1) as u32
            })
        });
        axis_triangles.push(t);
    }
    if axis_nodes.is_empty() {
        return Err(FeError::NoPalpableSurface);
    }
    let axis_vertices: Vec<[f64; 3]> = axis_nodes
        .iter()
        .map(|&v| space.nodes[v as usize])
        .collect();
    // Columns of F: unit loads at each vertex, for each direction.
    let per_vertex: Vec<Vec<(u32, f64)>> = face_of
        .par_iter()
        .enumerate()
        .map(|(j, &(face, corner))| {
            let mut bary = [0.0; 3];
            bary[corner] = 1.0;
            let sp = SurfacePoint {
                face,
                bary,
                point: axis_vertices[j],
                normal: [0.0; 3],
                distance_mm: 0.0,
            };
            probe_weights(&space, &sp, radius_mm)
        })
        .collect::<Result<_, _>>()?;
    let mut cols = Vec::with_capacity(3 * per_vertex.len());
    for w in &per_vertex {
        for c in 0..3 {
            let col: Vec<(u32, f64)> = w
                .iter()
                .filter(|(n, _)| space.dof[*n as usize] != u32::MAX)
                .map(|&(n, x)| (space.dof[n as usize] + c, x))
                .collect();
            cols.push(col);
        }
    }
    let f = ColSparse {
        rows: space.free_dofs,
        cols,
    };
    let ms = surface_mass(&axis_vertices, &axis_triangles);
    Ok(Setup {
        space,
        problem,
        f,
        ms,
        axis_nodes,
        axis_vertices,
        axis_triangles,
        radius_mm,
        boundary: organ.boundary.clone(),
        setup_s: t0.elapsed().as_secs_f64(),
    })
}

/// `Ms ⊗ I₃`: the P1 surface mass matrix (`area/12 · [2 1 1; 1 2 1; 1 1 2]` per
/// triangle) on the combined index `3j + c`, lower triangle.
pub fn surface_mass(vertices: &[[f64; 3]], triangles: &[[u32; 3]]) -> SymCsc {
    use crate::mesh::{cross, norm, sub};
    let mut entries: BTreeMap<(usize, usize), f64> = BTreeMap::new();
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        let area = 0.5 * norm(cross(sub(b, a), sub(c, a)));
        for i in 0..3 {
            for j in 0..3 {
                let v = area / 12.0 * if i == j { 2.0 } else { 1.0 };
                let (r, cidx) = (t[i] as usize, t[j] as usize);
                if r >= cidx {
                    *entries.entry((cidx, r)).or_default() += v;
                }
            }
        }
    }
    let m = 3 * vertices.len();
    let mut col_ptr = vec![0usize; m + 1];
    let mut row_idx = Vec::new();
    let mut val = Vec::new();
    // entries keyed (col, row) in vertex indices; expand by component.
    let mut by_col: Vec<Vec<(usize, f64)>> = vec![Vec::new(); vertices.len()];
    for ((c, r), v) in entries {
        by_col[c].push((r, v));
    }
    for (cv, rows) in by_col.iter().enumerate() {
        for comp in 0..3 {
            for &(rv, v) in rows {
                row_idx.push(3 * rv + comp);
                val.push(v);
            }
            col_ptr[3 * cv + comp + 1] = row_idx.len();
        }
    }
    SymCsc {
        n: m,
        col_ptr,
        row_idx,
        val,
    }
}

/// Completes terms read back from a journal (which stores only `X` and `Y`): `K X`,
/// `Fᵀ X` and the Gram rows, then, with `update`, the Galerkin update of every `Y`, so
/// [`compute`] continues exactly where an uninterrupted run would be.
pub fn restore(setup: &Setup, terms: &mut Terms, update: bool) {
    if terms.x.is_empty() {
        return;
    }
    let ops = setup.ops();
    terms.kx = terms
        .x
        .iter()
        .map(|x| {
            let mut y = vec![0.0; x.len()];
            ops.k.mul(x, &mut y);
            y
        })
        .collect();
    terms.ftx = terms.x.iter().map(|x| ops.f.mul_t(x)).collect();
    terms.gram.clear();
    terms.extend_gram();
    if update {
        super::linear::update(&ops, terms);
    }
}

/// The journal's key: the vademecum's description and the block size (a resumed run
/// must partition the terms into the same blocks to reproduce an uninterrupted one).
pub fn journal_key(desc: &str, block: usize) -> String {
    format!("{desc} block={block}")
}

/// Runs the PGD and returns the terms.
pub fn compute(
    setup: &Setup,
    settings: &Settings,
    start: Terms,
    progress: impl FnMut(&Terms),
) -> Terms {
    if settings.block > 1 {
        super::block::solve(&setup.ops(), settings, start, progress)
    } else {
        solve(&setup.ops(), settings, start, progress)
    }
}

/// Packs terms into a meta-model: rows are all nodes × 3 (fixed nodes zero), one
/// SurfaceVector axis.
pub fn to_model(
    setup: &Setup,
    terms: &Terms,
    mesh_desc: &str,
    tolerance: f64,
) -> SeparatedModel<f64> {
    let n = terms.x.len();
    let nodes = setup.space.nodes.len();
    let full: Vec<Vec<f64>> = terms.x.iter().map(|x| setup.space.expand(x)).collect();
    let mut x = vec![0.0; 3 * nodes * n];
    for r in 0..3 * nodes {
        for k in 0..n {
            x[r * n + k] = full[k][r];
        }
    }
    let m = 3 * setup.axis_vertices.len();
    let mut y = vec![0.0; m * n];
    for p in 0..m {
        for k in 0..n {
            y[p * n + k] = terms.y[k][p];
        }
    }
    let meta = vademecum_meta(
        "liver-palpation-linear",
        AxisInfo {
            name: "probe position × load direction".into(),
            unit: "mm".into(),
            discretization: Discretization::SurfaceVector {
                vertices: setup.axis_vertices.clone(),
                triangles: setup.axis_triangles.clone(),
                field_nodes: setup.axis_nodes.clone(),
            },
        },
        Provenance::now(
            "pgd-linear (greedy + Galerkin update)",
            mesh_desc,
            tolerance,
            terms.residual_per_mode.clone(),
        ),
        &setup.space,
        &setup.boundary,
    );
    SeparatedModel::new(meta, 3 * nodes, n, x, vec![y]).expect("shapes match by construction")
}

/// The header of a liver vademecum: displacement per newton on every node of `space`
/// (rows `3·node + c`), one parametric axis, the geometry for rendering and export.
pub fn vademecum_meta(
    kind: &str,
    axis: AxisInfo,
    provenance: Provenance,
    space: &Space,
    boundary: &[[u32; 3]],
) -> ModelMeta {
    ModelMeta {
        kind: kind.into(),
        field: FieldInfo {
            name: "displacement per newton".into(),
            unit: "mm/N".into(),
            components: 3,
            node_ids: Vec::new(),
        },
        axes: vec![axis],
        provenance,
        tradeoff: Vec::new(),
        geometry: Geometry {
            nodes: space.nodes.clone(),
            surface: boundary.to_vec(),
        },
    }
}

/// Brute-force reference over the nodal map: `C = Fᵀ K⁻¹ F` (one solve per column) and
/// the eigenvalues of `Lᵀ C L` (Ms = L Lᵀ), whose tail sums give the optimal rank-n
/// error in the natural norm (Eckart–Young). Returns (‖G‖², eigenvalues descending,
/// seconds spent in the solves).
pub fn optimal_errors(setup: &Setup) -> (f64, Vec<f64>, f64) {
    let o = optimal_errors_on(setup, &[]);
    (o.g2, o.ev, o.solve_s)
}

/// The optimal separated approximations of the nodal map, in the natural norm and
/// in a surface norm.
#[derive(Debug, Clone)]
pub struct Optimal {
    /// ‖G‖² in the natural norm (energy × L²(s)).
    pub g2: f64,
    /// Eigenvalues (descending) whose tail sums give the optimal rank-n error in the
    /// natural norm.
    pub ev: Vec<f64>,
    /// The same in the surface norm: Euclidean over the given surface dofs × L²(s),
    /// i.e. the eigenvalues of `Lᵀ G_Sᵀ G_S L` (empty when no dofs were given).
    pub surface_ev: Vec<f64>,
    /// Seconds spent in the solves.
    pub solve_s: f64,
}

/// [`optimal_errors`], plus the Eckart–Young bound in the surface norm over the free
/// dofs `surface_dofs`: no rank-n separated representation has a smaller relative
/// surface error over the whole map.
pub fn optimal_errors_on(setup: &Setup, surface_dofs: &[u32]) -> Optimal {
    let (c, gs, solve_s) = map_grams(setup, surface_dofs);
    let l = surface_mass_factor(setup);
    let eig = |c: &faer::Mat<f64>| {
        let b = l.transpose() * c * &l;
        let mut ev = b
            .self_adjoint_eigenvalues(faer::Side::Lower)
            .expect("symmetric eigenvalues");
        ev.reverse();
        ev
    };
    let ev = eig(&c);
    let surface_ev = if surface_dofs.is_empty() {
        Vec::new()
    } else {
        eig(&(gs.transpose() * &gs))
    };
    Optimal {
        g2: ev.iter().sum(),
        ev,
        surface_ev,
        solve_s,
    }
}

/// One FE solve per column of F (batched), giving `C = Fᵀ K⁻¹ F` (m × m) and the
/// solutions' values at `surface_dofs` (G_S, rows × m), and the seconds spent.
fn map_grams(setup: &Setup, surface_dofs: &[u32]) -> (faer::Mat<f64>, faer::Mat<f64>, f64) {
    let t0 = Instant::now();
    let n = setup.f.rows;
    let m = setup.f.cols.len();
    let mut c = faer::Mat::<f64>::zeros(m, m);
    let mut gs = faer::Mat::<f64>::zeros(surface_dofs.len(), m);
    const BATCH: usize = 64;
    for start in (0..m).step_by(BATCH) {
        let end = (start + BATCH).min(m);
        let mut rhs = faer::Mat::<f64>::zeros(n, end - start);
        for j in start..end {
            for &(r, v) in &setup.f.cols[j] {
                rhs[(r as usize, j - start)] += v;
            }
        }
        setup.problem.factor.solve_many(&mut rhs);
        for j in start..end {
            for i in 0..m {
                c[(i, j)] = setup.f.cols[i]
                    .iter()
                    .map(|&(r, v)| v * rhs[(r as usize, j - start)])
                    .sum();
            }
            for (i, &d) in surface_dofs.iter().enumerate() {
                gs[(i, j)] = rhs[(d as usize, j - start)];
            }
        }
    }
    (c, gs, t0.elapsed().as_secs_f64())
}

/// L with `Ms = L Lᵀ` (dense).
fn surface_mass_factor(setup: &Setup) -> faer::Mat<f64> {
    let m = setup.f.cols.len();
    let mut ms = faer::Mat::<f64>::zeros(m, m);
    for col in 0..m {
        for k in setup.ms.col_ptr[col]..setup.ms.col_ptr[col + 1] {
            let r = setup.ms.row_idx[k];
            ms[(r, col)] = setup.ms.val[k];
            ms[(col, r)] = setup.ms.val[k];
        }
    }
    ms.llt(faer::Side::Lower)
        .expect("surface mass is SPD")
        .L()
        .to_owned()
}

/// The brute-force vademecum, for comparison with the PGD: one FE solve per palpable
/// vertex and direction, then the optimal rank-`modes` separated form of that map in
/// the natural norm. With `B = Lᵀ C L = V Λ Vᵀ` (Ms = L Lᵀ, C = FᵀK⁻¹F), the optimum
/// is `G L V Vᵀ L⁻¹`, i.e. `X_k = K⁻¹F L v_k / √λ_k` (K-normalized: `modes` more
/// solves) and `y_k = √λ_k L⁻ᵀ v_k`. Returns the terms, ‖G‖² in the natural norm
/// (Σ λ, for [`map_error`](super::linear::map_error)) and (solve, eigen, total)
/// seconds.
pub fn brute_force(setup: &Setup, modes: usize) -> (Terms, f64, [f64; 3]) {
    let t0 = Instant::now();
    let (c, _, solve_s) = map_grams(setup, &[]);
    let t1 = Instant::now();
    let l = surface_mass_factor(setup);
    let b = l.transpose() * &c * &l;
    let b = faer::Mat::from_fn(b.nrows(), b.ncols(), |i, j| 0.5 * (b[(i, j)] + b[(j, i)]));
    let evd = b
        .self_adjoint_eigen(faer::Side::Lower)
        .expect("symmetric eigen-decomposition");
    let eigen_s = t1.elapsed().as_secs_f64();
    let m = b.nrows();
    let modes = modes.min(m);
    let lam = evd.S().column_vector();
    let v = evd.U();
    // Descending order, dropping null directions.
    let order: Vec<usize> = (0..m).rev().take(modes).filter(|&k| lam[k] > 0.0).collect();
    let lv = &l * v;
    let mut rhs = faer::Mat::<f64>::zeros(setup.f.rows, order.len());
    for (j, &k) in order.iter().enumerate() {
        let w = lv.col(k);
        for (p, colp) in setup.f.cols.iter().enumerate() {
            let wp = w[p] / lam[k].sqrt();
            for &(r, x) in colp {
                rhs[(r as usize, j)] += x * wp;
            }
        }
    }
    setup.problem.factor.solve_many(&mut rhs);
    // y_k = √λ_k L⁻ᵀ v_k: solve Lᵀ y = √λ v.
    let mut y = faer::Mat::from_fn(m, order.len(), |i, j| {
        v[(i, order[j])] * lam[order[j]].sqrt()
    });
    faer::linalg::triangular_solve::solve_upper_triangular_in_place(
        l.transpose(),
        y.as_mut(),
        faer::Par::Seq,
    );
    let mut t = Terms::default();
    for j in 0..order.len() {
        let x: Vec<f64> = rhs.col(j).iter().copied().collect();
        let mut kx = vec![0.0; x.len()];
        setup.problem.stiffness.mul(&x, &mut kx);
        t.ftx.push(setup.f.mul_t(&x));
        t.x.push(x);
        t.kx.push(kx);
        t.y.push(y.col(j).iter().copied().collect());
    }
    t.extend_gram();
    let g2 = (0..m).map(|k| lam[k]).sum();
    (t, g2, [solve_s, eigen_s, t0.elapsed().as_secs_f64()])
}

/// Optimal relative error with n terms from the eigenvalues.
pub fn svd_error(ev: &[f64], n: usize) -> f64 {
    let total: f64 = ev.iter().sum();
    let tail: f64 = ev.iter().skip(n).map(|v| v.max(0.0)).sum();
    (tail / total).sqrt()
}

/// What a vademecum was computed from, as one line (journal key, provenance, and the
/// input hash an asset test recomputes): organ mesh hash, element, material, tool.
pub fn describe(
    organ: &OrganMesh,
    level: &str,
    element: Element,
    material: Material,
    radius_mm: f64,
    update: bool,
) -> String {
    describe_named("liver", organ, level, element, material, radius_mm, update)
}

/// As [`describe`], for an organ from a user's surface: `organ=user`, then `source`
/// (more `key=value` pairs: the file, its hash, units, axes, regions).
pub fn describe_user(
    organ: &OrganMesh,
    level: &str,
    element: Element,
    material: Material,
    radius_mm: f64,
    source: &str,
) -> String {
    let base = describe_named("user", organ, level, element, material, radius_mm, false);
    format!("{base} {source}")
}

fn describe_named(
    name: &str,
    organ: &OrganMesh,
    level: &str,
    element: Element,
    material: Material,
    radius_mm: f64,
    update: bool,
) -> String {
    format!(
        "organ={name} level={level} mesh_xxh3={:016x} element={} young_kpa={} poisson={} radius_mm={} update={}",
        organ.fingerprint(),
        element.name(),
        material.young_kpa,
        material.poisson,
        radius_mm,
        update
    )
}

/// Reads `key=value` from a description made by [`describe`].
pub fn describe_get<'a>(desc: &'a str, key: &str) -> Option<&'a str> {
    desc.split_whitespace()
        .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
}

/// Rebuilds PGD terms (space vectors on the free dofs) from a vademecum model, for
/// error measures that need `K X_k` and `Fᵀ X_k`.
pub fn terms_from_model(setup: &Setup, model: &SeparatedModel<f64>) -> Terms {
    let n = model.modes();
    let x_all = model.spatial();
    let y_all = model.axes()[0].values();
    let m = setup.f.cols.len();
    let mut t = Terms::default();
    for k in 0..n {
        let full: Vec<f64> = (0..model.rows()).map(|r| x_all[r * n + k]).collect();
        let x = setup.space.restrict(&full);
        let mut kx = vec![0.0; x.len()];
        setup.problem.stiffness.mul(&x, &mut kx);
        t.ftx.push(setup.f.mul_t(&x));
        t.x.push(x);
        t.kx.push(kx);
        t.y.push((0..m).map(|p| y_all[p * n + k]).collect());
    }
    t.extend_gram();
    t
}
