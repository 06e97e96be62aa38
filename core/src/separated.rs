//! The separated representation and its on-line evaluation.
//!
//! ```text
//! u_r(p_1..p_m) ≈ Σ_{k<n} X[r, k] · c_k,      c_k = Π_j Σ_s w_{j,s} P_j[node_{j,s}, k]
//! ```
//!
//! - `X` (rows × N) is stored row-major: a row (one field entry: node × component) holds
//!   its N mode values contiguously, so a full reconstruction streams X front to back
//!   and a subset of rows (the surface, the three rows of a contact node) reads only
//!   those rows.
//! - each axis `j` stores `P_j` (nodes_j × N), also row-major, and turns a parameter
//!   value into a stencil of at most nine nodes ([`crate::axis`]).
//! - **particularize** computes `c ∈ R^n` from parameter values; **reconstruct**
//!   computes `X[rows, :n] · c`. Passing `n < N` coefficients truncates to the first n
//!   modes: the speed/accuracy knob.
//!
//! Both hot-path calls take their output buffers from the caller and allocate nothing,
//! so they can run on the 1 kHz force thread. Cost: particularize O(m · n),
//! reconstruct O(|rows| · n) streamed bytes.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::axis::{AxisError, Discretization, MAX_LOAD_NODES, ParamValue};
use crate::kernels;
use crate::nearfield::{NearField, NearFieldError};
use crate::scalar::{Precision, Scalar};

/// What the field rows are: `rows = nodes × components`, row `r` is component
/// `r % components` of node `node_ids[r / components]` (or of node `r / components`
/// when `node_ids` is empty, i.e. the rows cover the whole mesh).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FieldInfo {
    pub name: String,
    pub unit: String,
    pub components: u32,
    pub node_ids: Vec<u32>,
}

/// Name, unit and discretization of one parameter axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisInfo {
    pub name: String,
    pub unit: String,
    pub discretization: Discretization,
}

/// Where a meta-model came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    pub solver: String,
    pub mesh: String,
    pub tolerance: f64,
    /// Residual (or enrichment norm) recorded when each mode was added.
    pub residual_per_mode: Vec<f64>,
    pub created_unix_s: u64,
    pub palpa_version: String,
    /// Hash of the inputs the model was computed from (mesh, material, solver settings).
    pub input_hash: String,
    /// The gene network a CME meta-model was built from, as palpa's TOML (what `palpa
    /// cme fit` solves exactly to check itself); empty for an organ's model.
    pub network: String,
}

impl Provenance {
    /// A provenance stamped with this crate's version and the current time.
    pub fn now(solver: &str, mesh: &str, tolerance: f64, residual_per_mode: Vec<f64>) -> Self {
        Provenance {
            solver: solver.into(),
            mesh: mesh.into(),
            tolerance,
            residual_per_mode,
            created_unix_s: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs()),
            palpa_version: env!("CARGO_PKG_VERSION").into(),
            input_hash: String::new(),
            network: String::new(),
        }
    }
}

/// One row of the measured speed/accuracy table (what the app's accuracy knob reads).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TradeoffRow {
    pub modes: u32,
    pub surface_rel_error: f64,
    pub probe_rel_error: f64,
    pub map_rel_error: Option<f64>,
    pub svd_rel_error: Option<f64>,
    pub surface_eval_us: f64,
    pub contact_eval_ns: f64,
    pub bytes: u64,
    /// Nodal-load models: max relative compliance error over held-out points.
    pub compliance_rel_error: Option<f64>,
    /// Nodal-load models: largest surface nodal error at 1 N over held-out points, mm.
    pub surface_max_nodal_error_mm: Option<f64>,
}

/// Everything about a model except its arrays: what the file header carries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelMeta {
    /// What the model is, e.g. "liver-palpation-linear".
    pub kind: String,
    pub field: FieldInfo,
    pub axes: Vec<AxisInfo>,
    pub provenance: Provenance,
    pub tradeoff: Vec<TradeoffRow>,
    /// Geometry of the rows the model holds (may be empty): position of each field node
    /// (node i ↔ rows `components·i ..`) and boundary triangles over those nodes,
    /// outward, for rendering and export.
    pub geometry: Geometry,
}

/// Positions of a model's field nodes and its boundary triangles (mm).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Geometry {
    pub nodes: Vec<[f64; 3]>,
    pub surface: Vec<[u32; 3]>,
}

/// One parameter axis with its nodal values `P` (nodes × modes, row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct Axis<T> {
    pub info: AxisInfo,
    values: Vec<T>,
}

impl<T: Scalar> Axis<T> {
    pub fn values(&self) -> &[T] {
        &self.values
    }
}

/// A model that failed its consistency checks.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ModelError {
    #[error("X has {len} entries, expected rows × modes = {rows} × {modes}")]
    SpatialShape {
        len: usize,
        rows: usize,
        modes: usize,
    },
    #[error("axis '{axis}' has {len} values, expected nodes × modes = {nodes} × {modes}")]
    AxisShape {
        axis: String,
        len: usize,
        nodes: usize,
        modes: usize,
    },
    #[error("axis '{axis}': {source}")]
    Axis { axis: String, source: AxisError },
    #[error("{rows} rows do not split into nodes of {components} components")]
    FieldLayout { rows: usize, components: u32 },
    #[error("the model holds {available} modes; {requested} were asked for")]
    TooManyModes { requested: usize, available: usize },
    #[error("row {row} does not exist (the model has {rows} rows)")]
    NoSuchRow { row: usize, rows: usize },
    #[error("value {value} in {what} is not finite")]
    NotFinite { what: String, value: f64 },
    #[error(
        "a near field needs a single surface-load axis (probe position × nodal load); \
         this model's first axis is {axis}"
    )]
    NearWithoutLoadAxis { axis: String },
    #[error(transparent)]
    Near(#[from] NearFieldError),
}

/// An evaluation request that cannot be honoured.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EvalError {
    #[error("{given} parameter values given, the model has {expected} axes")]
    ParamCount { given: usize, expected: usize },
    #[error("axis {axis} ('{name}'): {source}")]
    Axis {
        axis: usize,
        name: String,
        source: AxisError,
    },
    #[error("{requested} modes requested, the model holds {available}")]
    TooManyModes { requested: usize, available: usize },
}

/// Which axes were clamped to their trained range during a particularization.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClampReport {
    mask: u64,
}

impl ClampReport {
    pub fn any(self) -> bool {
        self.mask != 0
    }
    pub fn axis(self, j: usize) -> bool {
        j < 64 && self.mask & (1 << j) != 0
    }
    /// Indices of the clamped axes.
    pub fn axes(self) -> impl Iterator<Item = usize> {
        (0..64).filter(move |&j| self.mask & (1u64 << j) != 0)
    }
}

/// A separated representation with `T` storage (f32 or f64).
#[derive(Debug, Clone, PartialEq)]
pub struct SeparatedModel<T> {
    kind: String,
    field: FieldInfo,
    provenance: Provenance,
    tradeoff: Vec<TradeoffRow>,
    geometry: Geometry,
    rows: usize,
    modes: usize,
    x: Vec<T>,
    axes: Vec<Axis<T>>,
    /// The exact near field of a nodal-load vademecum (see [`crate::nearfield`]).
    near: Option<Box<NearField>>,
}

impl<T: Scalar> SeparatedModel<T> {
    /// Builds a model from its metadata, `X` (rows × modes, row-major) and each axis's
    /// values (nodes × modes, row-major, in the order of `meta.axes`).
    pub fn new(
        meta: ModelMeta,
        rows: usize,
        modes: usize,
        x: Vec<T>,
        axis_values: Vec<Vec<T>>,
    ) -> Result<Self, ModelError> {
        if Some(x.len()) != rows.checked_mul(modes) {
            return Err(ModelError::SpatialShape {
                len: x.len(),
                rows,
                modes,
            });
        }
        let comps = meta.field.components;
        if comps == 0 || !rows.is_multiple_of(comps as usize) {
            return Err(ModelError::FieldLayout {
                rows,
                components: comps,
            });
        }
        if !meta.field.node_ids.is_empty() && meta.field.node_ids.len() * comps as usize != rows {
            return Err(ModelError::FieldLayout {
                rows,
                components: comps,
            });
        }
        let g = &meta.geometry;
        if !g.nodes.is_empty() && g.nodes.len() * comps as usize != rows {
            return Err(ModelError::FieldLayout {
                rows,
                components: comps,
            });
        }
        if let Some(bad) = g
            .surface
            .iter()
            .flatten()
            .find(|&&v| v as usize >= g.nodes.len())
        {
            return Err(ModelError::NoSuchRow {
                row: *bad as usize * comps as usize,
                rows,
            });
        }
        if meta.axes.len() != axis_values.len() || meta.axes.len() > 64 {
            return Err(ModelError::AxisShape {
                axis: format!("{} axes", meta.axes.len()),
                len: axis_values.len(),
                nodes: meta.axes.len(),
                modes,
            });
        }
        let mut axes = Vec::with_capacity(meta.axes.len());
        for (info, values) in meta.axes.into_iter().zip(axis_values) {
            info.discretization
                .validate()
                .map_err(|source| ModelError::Axis {
                    axis: info.name.clone(),
                    source,
                })?;
            let nodes = info.discretization.node_count();
            if Some(values.len()) != nodes.checked_mul(modes) {
                return Err(ModelError::AxisShape {
                    axis: info.name,
                    len: values.len(),
                    nodes,
                    modes,
                });
            }
            axes.push(Axis { info, values });
        }
        Ok(SeparatedModel {
            kind: meta.kind,
            field: meta.field,
            provenance: meta.provenance,
            tradeoff: meta.tradeoff,
            geometry: meta.geometry,
            rows,
            modes,
            x,
            axes,
            near: None,
        })
    }

    /// Attaches a near field (band and compliance table) to a model whose one axis is a
    /// [`Discretization::SurfaceLoad`]; checks its shapes.
    pub fn with_near(mut self, near: NearField) -> Result<Self, ModelError> {
        let (load_nodes, faces) = match self.axes.as_slice() {
            [a] => match &a.info.discretization {
                Discretization::SurfaceLoad {
                    positions, faces, ..
                } => (positions.len(), faces.len()),
                d => {
                    return Err(ModelError::NearWithoutLoadAxis {
                        axis: d.kind_name().into(),
                    });
                }
            },
            _ => {
                return Err(ModelError::NearWithoutLoadAxis {
                    axis: format!("one of {} axes", self.axes.len()),
                });
            }
        };
        near.validate(
            load_nodes,
            faces,
            self.rows / self.field.components as usize,
        )?;
        self.near = Some(Box::new(near));
        Ok(self)
    }

    /// The near field, if the model carries one.
    pub fn near(&self) -> Option<&NearField> {
        self.near.as_deref()
    }

    /// The model with its far field's terms at or below `tolerance` dropped (`None`:
    /// without the far field); the accuracy knob of a nodal-load model.
    pub fn with_far_tolerance(mut self, tolerance: Option<f64>) -> Self {
        if let Some(near) = self.near.as_deref_mut() {
            near.far = match (tolerance, near.far.take()) {
                (Some(t), Some(far)) => Some(Box::new(far.truncated(t))),
                _ => None,
            };
        }
        self
    }

    /// The model without its near field (what an older file holds).
    pub fn without_near(mut self) -> Self {
        self.near = None;
        self
    }

    pub fn rows(&self) -> usize {
        self.rows
    }
    pub fn modes(&self) -> usize {
        self.modes
    }
    pub fn axes(&self) -> &[Axis<T>] {
        &self.axes
    }
    pub fn field(&self) -> &FieldInfo {
        &self.field
    }
    pub fn kind(&self) -> &str {
        &self.kind
    }
    pub fn provenance(&self) -> &Provenance {
        &self.provenance
    }
    pub fn tradeoff(&self) -> &[TradeoffRow] {
        &self.tradeoff
    }
    pub fn set_tradeoff(&mut self, rows: Vec<TradeoffRow>) {
        self.tradeoff = rows;
    }
    pub fn set_provenance(&mut self, p: Provenance) {
        self.provenance = p;
    }
    pub fn precision(&self) -> Precision {
        T::PRECISION
    }
    /// The spatial factor, rows × modes, row-major.
    pub fn spatial(&self) -> &[T] {
        &self.x
    }
    /// Bytes of the arrays (X and all axis values).
    pub fn array_bytes(&self) -> usize {
        (self.x.len() + self.axes.iter().map(|a| a.values.len()).sum::<usize>()) * size_of::<T>()
    }

    /// The metadata, as written to a file header.
    pub fn meta(&self) -> ModelMeta {
        ModelMeta {
            kind: self.kind.clone(),
            field: self.field.clone(),
            axes: self.axes.iter().map(|a| a.info.clone()).collect(),
            provenance: self.provenance.clone(),
            tradeoff: self.tradeoff.clone(),
            geometry: self.geometry.clone(),
        }
    }

    pub fn geometry(&self) -> &Geometry {
        &self.geometry
    }

    /// Coefficients `c ∈ R^n` for the given parameter values, `n = coeffs.len() ≤ N`.
    /// Allocation-free. Values outside an axis's trained range are clamped and reported.
    pub fn particularize(
        &self,
        values: &[ParamValue],
        coeffs: &mut [f64],
    ) -> Result<ClampReport, EvalError> {
        let n = coeffs.len();
        if n > self.modes {
            return Err(EvalError::TooManyModes {
                requested: n,
                available: self.modes,
            });
        }
        if values.len() != self.axes.len() {
            return Err(EvalError::ParamCount {
                given: values.len(),
                expected: self.axes.len(),
            });
        }
        coeffs.fill(1.0);
        let mut report = ClampReport::default();
        for (j, (axis, &value)) in self.axes.iter().zip(values).enumerate() {
            if let Discretization::SurfaceLoad { .. } = axis.info.discretization {
                let clamped = self.scale_by_load(j, value, coeffs)?;
                if clamped {
                    report.mask |= 1 << j;
                }
                continue;
            }
            let st = axis
                .info
                .discretization
                .stencil(value)
                .map_err(|source| EvalError::Axis {
                    axis: j,
                    name: axis.info.name.clone(),
                    source,
                })?;
            if st.clamped {
                report.mask |= 1 << j;
            }
            kernels::scale_by_stencil(coeffs, &axis.values, self.modes, &st);
        }
        Ok(report)
    }

    /// `coeffs[k] *= Σ_j w_j(s) Σ_c t_c P[3j + c, k]` on a load axis. Allocation-free.
    fn scale_by_load(
        &self,
        j: usize,
        value: ParamValue,
        coeffs: &mut [f64],
    ) -> Result<bool, EvalError> {
        let axis = &self.axes[j];
        let wrap = |source| EvalError::Axis {
            axis: j,
            name: axis.info.name.clone(),
            source,
        };
        let mut buf = [(0u32, 0.0f64); MAX_LOAD_NODES];
        let (len_shares, clamped, mix) = axis
            .info
            .discretization
            .probe_shares(value, &mut buf)
            .map_err(wrap)?;
        let m = self.modes;
        let n = coeffs.len();
        // Mode chunks of a stack accumulator: any number of modes, no allocation.
        const CHUNK: usize = 256;
        let mut acc = [0.0f64; CHUNK];
        for k0 in (0..n).step_by(CHUNK) {
            let len = CHUNK.min(n - k0);
            let acc = &mut acc[..len];
            acc.fill(0.0);
            for &(node, w) in &buf[..len_shares] {
                for (c, &t) in mix.iter().enumerate() {
                    let wt = w * t;
                    if wt == 0.0 {
                        continue;
                    }
                    let row = &axis.values[(3 * node as usize + c) * m + k0..][..len];
                    for (a, y) in acc.iter_mut().zip(row) {
                        *a += wt * y.to_f64();
                    }
                }
            }
            for (o, a) in coeffs[k0..k0 + len].iter_mut().zip(acc.iter()) {
                *o *= a;
            }
        }
        Ok(clamped)
    }

    /// Adds the near-field band of the probe `values` to the full field `out` (rows of
    /// this model). A no-op for a model without a near field. Allocation-free.
    pub fn add_near_field(&self, values: &[ParamValue], out: &mut [f64]) -> Result<(), EvalError> {
        let Some(near) = self.near.as_deref() else {
            return Ok(());
        };
        let (Some(axis), Some(&value)) = (self.axes.first(), values.first()) else {
            return Err(EvalError::ParamCount {
                given: values.len(),
                expected: self.axes.len(),
            });
        };
        let mut buf = [(0u32, 0.0f64); MAX_LOAD_NODES];
        let (len, _, mix) = axis
            .info
            .discretization
            .probe_shares(value, &mut buf)
            .map_err(|source| EvalError::Axis {
                axis: 0,
                name: axis.info.name.clone(),
                source,
            })?;
        near.add(&buf[..len], mix, out);
        Ok(())
    }

    /// `out[i] = Σ_{k<n} X[first + i, k] · coeffs[k]` for the contiguous rows
    /// `first .. first + out.len()`. Allocation-free.
    #[track_caller]
    pub fn reconstruct_range(&self, first: usize, coeffs: &[f64], out: &mut [f64]) {
        let n = coeffs.len();
        assert!(n <= self.modes, "{n} coefficients for {} modes", self.modes);
        assert!(
            first + out.len() <= self.rows,
            "rows {first}..{} exceed the model's {} rows",
            first + out.len(),
            self.rows
        );
        let m = self.modes;
        kernels::strided_dots(&self.x[first * m..(first + out.len()) * m], m, coeffs, out);
    }

    /// The full field: `out.len()` must equal [`Self::rows`].
    #[track_caller]
    pub fn reconstruct(&self, coeffs: &[f64], out: &mut [f64]) {
        assert_eq!(
            out.len(),
            self.rows,
            "output length must equal the row count"
        );
        self.reconstruct_range(0, coeffs, out);
    }

    /// `out[i] = Σ_k X[rows[i], k] · coeffs[k]`: only the rows a scene shows.
    #[track_caller]
    pub fn reconstruct_rows(&self, rows: &[u32], coeffs: &[f64], out: &mut [f64]) {
        let n = coeffs.len();
        assert!(n <= self.modes, "{n} coefficients for {} modes", self.modes);
        assert_eq!(rows.len(), out.len(), "one output per selected row");
        let m = self.modes;
        for (o, &r) in out.iter_mut().zip(rows) {
            let r = r as usize;
            assert!(r < self.rows, "row {r} of {}", self.rows);
            *o = kernels::dot(&self.x[r * m..r * m + n], coeffs);
        }
    }

    /// A copy keeping only the first `n` modes (what a scene ships when it needs fewer).
    pub fn truncated(&self, n: usize) -> Result<Self, ModelError> {
        if n > self.modes {
            return Err(ModelError::TooManyModes {
                requested: n,
                available: self.modes,
            });
        }
        let keep = |v: &[T]| -> Vec<T> {
            v.chunks_exact(self.modes.max(1))
                .flat_map(|r| r[..n].iter().copied())
                .collect()
        };
        let mut out = self.clone();
        out.modes = n;
        out.x = if self.modes == 0 {
            Vec::new()
        } else {
            keep(&self.x)
        };
        for a in &mut out.axes {
            a.values = if self.modes == 0 {
                Vec::new()
            } else {
                keep(&a.values)
            };
        }
        out.provenance.residual_per_mode.truncate(n);
        out.tradeoff.retain(|r| r.modes as usize <= n);
        Ok(out)
    }

    /// A copy keeping only the rows of the given nodes (e.g. the surface), in that order.
    /// `nodes` are positions in this model's node list (row blocks of `components`).
    pub fn select_nodes(&self, nodes: &[u32]) -> Result<Self, ModelError> {
        let c = self.field.components as usize;
        let node_count = self.rows / c;
        let m = self.modes;
        let mut x = Vec::with_capacity(nodes.len() * c * m);
        let mut ids = Vec::with_capacity(nodes.len());
        for &nd in nodes {
            let nd = nd as usize;
            if nd >= node_count {
                return Err(ModelError::NoSuchRow {
                    row: nd * c,
                    rows: self.rows,
                });
            }
            x.extend_from_slice(&self.x[nd * c * m..(nd + 1) * c * m]);
            ids.push(if self.field.node_ids.is_empty() {
                nd as u32
            } else {
                self.field.node_ids[nd]
            });
        }
        let mut out = self.clone();
        out.rows = nodes.len() * c;
        out.x = x;
        out.field.node_ids = ids;
        if !self.geometry.nodes.is_empty() {
            let mut new_index = vec![u32::MAX; node_count];
            for (i, &nd) in nodes.iter().enumerate() {
                new_index[nd as usize] = i as u32;
            }
            out.geometry.nodes = nodes
                .iter()
                .map(|&nd| self.geometry.nodes[nd as usize])
                .collect();
            out.geometry.surface = self
                .geometry
                .surface
                .iter()
                .filter_map(|t| {
                    let m = t.map(|v| new_index[v as usize]);
                    m.iter().all(|&v| v != u32::MAX).then_some(m)
                })
                .collect();
            // Axes that refer to field nodes follow the renumbering.
            for a in &mut out.axes {
                if let Discretization::SurfaceVector { field_nodes, .. }
                | Discretization::SurfaceLoad { field_nodes, .. } = &mut a.info.discretization
                {
                    for f in field_nodes.iter_mut() {
                        *f = new_index.get(*f as usize).copied().unwrap_or(u32::MAX);
                    }
                }
            }
            if let Some(near) = out.near.as_deref_mut() {
                near.remap_nodes(&new_index);
            }
        }
        Ok(out)
    }

    /// The same model with `U` storage (e.g. f64 → f32 for a phone).
    pub fn convert<U: Scalar>(&self) -> SeparatedModel<U> {
        let cv = |v: &[T]| v.iter().map(|&a| U::from_f64(a.to_f64())).collect();
        SeparatedModel {
            kind: self.kind.clone(),
            field: self.field.clone(),
            provenance: self.provenance.clone(),
            tradeoff: self.tradeoff.clone(),
            geometry: self.geometry.clone(),
            rows: self.rows,
            modes: self.modes,
            x: cv(&self.x),
            axes: self
                .axes
                .iter()
                .map(|a| Axis {
                    info: a.info.clone(),
                    values: cv(&a.values),
                })
                .collect(),
            near: self.near.clone(),
        }
    }

    /// Checks that every stored value is finite (done after solving and after loading).
    pub fn check_finite(&self) -> Result<(), ModelError> {
        if let Some((i, v)) = self
            .x
            .iter()
            .enumerate()
            .find(|(_, v)| !v.to_f64().is_finite())
        {
            return Err(ModelError::NotFinite {
                what: format!("X row {} mode {}", i / self.modes, i % self.modes),
                value: v.to_f64(),
            });
        }
        for a in &self.axes {
            if let Some(v) = a.values.iter().find(|v| !v.to_f64().is_finite()) {
                return Err(ModelError::NotFinite {
                    what: format!("axis '{}'", a.info.name),
                    value: v.to_f64(),
                });
            }
        }
        Ok(())
    }

    /// Split into the parts a file stores.
    pub(crate) fn arrays(&self) -> (&[T], impl Iterator<Item = &[T]>) {
        (&self.x, self.axes.iter().map(|a| a.values.as_slice()))
    }
}

/// Every row (`3·node + c`) of the given nodes, in order.
pub fn node_rows(nodes: &[u32]) -> Vec<u32> {
    nodes
        .iter()
        .flat_map(|&n| (0..3).map(move |c| 3 * n + c))
        .collect()
}
