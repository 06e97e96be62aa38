//! What a tissue build is asked and what its presses give back: the options every
//! stage reads ([`SurfaceLawOptions`]), a press's result ([`VertexPress`]), the build's
//! progress ([`PressCount`]) and why a build stops ([`SurfaceLawBuildError`]).

use crate::fe::law::Law;
use crate::fe::{Element, FeError, Material};

/// The most points (depth 0 included) of a press's depth grid.
pub const MAX_GRID_POINTS: usize = 256;

/// How far a covered point may lie from the palpable surface (mm): a point drawn on a
/// triangle and printed to a few decimals lands within it.
pub const COVER_SLACK_MM: f64 = 0.1;

/// How the surface law is built.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceLawOptions {
    pub law: Law,
    pub material: Material,
    pub element: Element,
    pub depth_max_mm: f64,
    /// Grid depths `j · step`, `j = 0..=depth_max/step`.
    pub depth_step_mm: f64,
    pub orders: usize,
    /// The continuation's split, as a fraction of the largest depth.
    pub split_fraction: f64,
    pub tool_radius_mm: f64,
    /// The higher orders are assembled only on cells where the press's first order
    /// varies by at least this fraction of its peak (see
    /// [`crate::fe::series::active_cells`]); 0 assembles every cell.
    pub active_cutoff: f64,
    /// Press only the palpable vertices within this ball (centre, radius; mm): a
    /// scene that shows one region models only that region. `None`: all of them.
    pub within: Option<([f64; 3], f64)>,
    /// Also press the midpoint of every palpable edge whose ends are pressed, and
    /// store its surplus over the ends' mean: the blend becomes quadratic (see the
    /// module docs). About three times the presses.
    pub edges: bool,
}

impl Default for SurfaceLawOptions {
    fn default() -> Self {
        SurfaceLawOptions {
            law: Law::NeoHookean,
            material: Material::default(),
            element: Element::P2,
            depth_max_mm: 10.0,
            depth_step_mm: 1.0,
            orders: 12,
            split_fraction: 0.55,
            tool_radius_mm: 5.0,
            active_cutoff: 0.01,
            within: None,
            edges: true,
        }
    }
}

/// A build's progress: presses done of those planned so far (the split triangles'
/// are planned once the vertices and edges are pressed, so `total` grows then), and
/// how many of the done were taken from the log rather than computed by this run:
/// an estimate of the time left divides by the computed ones only.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PressCount {
    pub done: usize,
    pub total: usize,
    pub from_log: usize,
}

/// Why a surface law could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SurfaceLawBuildError {
    #[error(transparent)]
    Fe(#[from] FeError),
    #[error(
        "the point {point_mm:?} lies {distance_mm:.3} mm from the organ's palpable surface: \
         expected a point on a palpable triangle (within {COVER_SLACK_MM} mm)"
    )]
    OffSurface {
        point_mm: [f64; 3],
        distance_mm: f64,
    },
    #[error(
        "the surface law already has {triangles} split triangles and this stage would split \
         {asked}: expected a stage of more (a larger --triangles, or a lower --refine-above-mm), \
         or a law cut back to no split triangles first (`palpa lab tissue cut --unsplit`)"
    )]
    AlreadyRefined { triangles: usize, asked: usize },
    #[error(
        "{missing} of the law's split triangles are not split candidates on this organ mesh \
         (their corners and edges pressed): expected the mesh the law was built on"
    )]
    EarlierStage { missing: usize },
    #[error(
        "the surface law has {sub_triangles} sub-triangles split again, and a stage of split \
         triangles would change the blend their surpluses were measured against: expected the \
         file they were split from (refine that, then split sub-triangles again)"
    )]
    SubSplitFirst { sub_triangles: usize },
    #[error(
        "the surface law holds a band next to the fixed region, pressed last: {what} would \
         not keep its samples last: expected the file the band was pressed on (`palpa tissue \
         cut --no-band` gives it back)"
    )]
    BandLast { what: &'static str },
    #[error("{}", shard_waiting(*index, *count, *pressed, *present, *total, waiting))]
    ShardWaiting {
        /// This run's shard (0: the merge).
        index: u32,
        count: u32,
        /// Presses this run made, and those of the call already logged.
        pressed: usize,
        present: usize,
        total: usize,
        /// Each shard whose presses are not logged yet, with their ids.
        waiting: Vec<(u32, Vec<u32>)>,
    },
    #[error("the build's press log {path}: {source}")]
    Log {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
}

/// What one palpable vertex's press gives: its residual surface and force ratio at
/// every grid depth.
#[derive(serde::Serialize, serde::Deserialize)]
pub(super) struct VertexPress {
    /// `steps × 3·rows`, mm.
    pub(super) residual: Vec<f32>,
    /// `g(d_j) = F(d_j) / (d_j · F₁)`, `g(0) = 1`.
    pub(super) ratio: Vec<f64>,
    pub(super) stiffness_n_per_mm: f64,
    pub(super) correction_mm: f64,
    pub(super) segments: u32,
    /// Grid depths reached (depth 0 included); past them `residual` and `ratio` hold
    /// the last one reached.
    pub(super) reach: u32,
    /// Why the press stopped short of the grid (empty where it did not).
    pub(super) stopped: String,
}

/// What a sharded run waits for, in words: which shards, how many of their presses, and
/// the first of their ids.
fn shard_waiting(
    index: u32,
    count: u32,
    pressed: usize,
    present: usize,
    total: usize,
    waiting: &[(u32, Vec<u32>)],
) -> String {
    let who = waiting
        .iter()
        .map(|(s, ids)| {
            let first: Vec<String> = ids.iter().take(8).map(u32::to_string).collect();
            let more = if ids.len() > 8 { ", …" } else { "" };
            format!(
                "shard {s} of {count}: {} presses (ids {}{more})",
                ids.len(),
                first.join(", ")
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    let this = if index == 0 {
        "the merge".to_string()
    } else {
        format!("shard {index} of {count} pressed {pressed} of its own, and")
    };
    format!("{this} waits for presses of this step ({present} of {total} logged) from {who}")
}
