//! Find the nodule, in the app: a case hidden in the scene
//! (`palpa_core::pgd::nodule::training`), felt through the probe, marked, revealed and
//! scored.
//!
//! The scene's table (`S.nodules` beside `S.palpa`, or the built-in liver's) gives the
//! nodule's effect at every palpable point; with the scene's tissue, the table's power
//! of that tissue amplifies it with the depth (`pgd::nodule::amplification`). The
//! session puts the effect at the probe's point into each command, as a curve over the
//! depth, and the force loop multiplies its force by `1 + effect(depth)`.
//! The trainer's stiffness map colours the surface by that factor, the ratio of the
//! force with the nodule to the force without it at any one depth.

use std::sync::Arc;

use anyhow::Context;
use palpa_core::fe::nodule::Nodule;
use palpa_core::pgd::nodule::amplification::{EffectCurve, Placed};
use palpa_core::pgd::nodule::table::EffectTable;
use palpa_core::pgd::nodule::training::{Case, CaseRanges, Score, Trial, draw};
use palpa_core::scene::{PalpationScene, ProbePoint};

/// A scene's training mode.
#[derive(Debug)]
pub struct Training {
    table: Arc<EffectTable>,
    /// Per probe triangle of the scene (its axis triangles): the table's face.
    faces: Vec<Option<u32>>,
    pub ranges: CaseRanges,
    pub trial: Option<Trial>,
    /// The nodule is drawn (after a mark, or when the trainee gives up).
    pub revealed: bool,
    /// The trainer's stiffness map on the surface.
    pub map: bool,
    /// The seed the next hidden case is drawn with.
    pub next_seed: u64,
    /// The scores of this session's trials, oldest first.
    pub scores: Vec<Score>,
    /// The trainer's own nodule, hidden under the probe.
    pub own: OwnNodule,
    /// `1 + effect` per scene vertex (1 off the table) and its generation.
    map_values: (Vec<f32>, u64),
    /// The scene's nonlinear tissue (its payload checksum), if any: the table's power
    /// of it amplifies the effect with the depth.
    tissue_xxh3: Option<u64>,
    /// The hidden case's amplification at the table's vertices (`None`: the linear
    /// effect at every depth: the linear model, or no power of this tissue).
    amplification: Option<Placed>,
    /// Each scene vertex's vertex in the table's power (`None`: not stored).
    power_vertex: Vec<Option<usize>>,
    /// The depth the map's values are for (mm, to half a millimetre).
    map_depth_mm: f64,
}

/// The table's face under the scene's probe triangle `triangle` (one of its axis
/// triangles), found by its corners; `None` off the table's faces.
pub fn table_face(table: &EffectTable, scene: &PalpationScene, triangle: u32) -> Option<usize> {
    let vertices = scene.axis_vertices_mm();
    let t = scene.axis_triangles().get(triangle as usize)?;
    table.face_at(t.map(|i| vertices[i as usize]))
}

/// A nodule a trainer places under the probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OwnNodule {
    /// From the surface to the centre, along the inward normal (mm).
    pub depth_mm: f64,
    pub radius_mm: f64,
    pub ratio: f64,
}

impl Training {
    /// The training mode of `scene` with its nodule `table` (checked to be of the
    /// scene's mesh); no case hidden yet.
    pub fn new(
        table: EffectTable,
        scene: &PalpationScene,
        tissue_xxh3: Option<u64>,
    ) -> anyhow::Result<Training> {
        table
            .check_mesh(&scene.model().provenance().mesh)
            .context("the nodule table and the scene")?;
        let faces: Vec<Option<u32>> = (0..scene.axis_triangles().len())
            .map(|t| table_face(&table, scene, t as u32).map(|f| f as u32))
            .collect();
        if faces.iter().all(Option::is_none) {
            anyhow::bail!(
                "the nodule table covers none of the scene's palpable triangles: expected a table built on the scene's organ"
            );
        }
        let power_vertex = match (&table.tissue_power, tissue_xxh3) {
            (Some(p), Some(x)) if p.tissue_xxh3 == x => scene
                .vertices_mm()
                .iter()
                .map(|v| p.vertex_at(v.map(f64::from)))
                .collect(),
            _ => Vec::new(),
        };
        Ok(Training {
            ranges: CaseRanges::of(&table),
            table: Arc::new(table),
            faces,
            trial: None,
            revealed: false,
            map: false,
            next_seed: 1,
            scores: Vec::new(),
            own: OwnNodule {
                depth_mm: 16.0,
                radius_mm: 10.0,
                ratio: 4.4,
            },
            map_values: (Vec::new(), 0),
            power_vertex,
            tissue_xxh3,
            amplification: None,
            map_depth_mm: 0.0,
        })
    }

    pub fn table(&self) -> &EffectTable {
        &self.table
    }

    /// Hides a new case drawn with `seed` (default: the next seed) from the ranges.
    pub fn hide(&mut self, seed: Option<u64>, now_s: f64) -> anyhow::Result<()> {
        let seed = seed.unwrap_or(self.next_seed);
        let case = draw(&self.table, &self.ranges, seed)
            .with_context(|| format!("drawing a nodule with seed {seed}"))?;
        self.next_seed = seed.wrapping_add(1);
        self.start(case, now_s);
        Ok(())
    }

    /// Hides a trainer's own nodule.
    pub fn set(&mut self, nodule: &Nodule, now_s: f64) -> anyhow::Result<()> {
        let case = Case::of(&self.table, nodule).context("the trainer's nodule")?;
        self.start(case, now_s);
        Ok(())
    }

    fn start(&mut self, case: Case, now_s: f64) {
        self.amplification = self
            .tissue_xxh3
            .and_then(|x| self.table.amplification(&case.nodule(), x));
        self.trial = Some(Trial::new(case, now_s));
        self.revealed = false;
        self.map_values.1 += 1;
        self.map_values.0.clear();
    }

    /// Whether the table holds the power of the scene's tissue: its cases' effects are
    /// amplified by the tissue's own press.
    pub fn amplifies(&self) -> bool {
        !self.power_vertex.is_empty()
    }

    /// The hidden nodule's effect at `p` over the depth: the linear effect, amplified
    /// where the tissue's power is known.
    pub fn curve_at(&self, scene: &PalpationScene, p: &ProbePoint) -> EffectCurve {
        let e = f64::from(self.effect_at(p));
        match &self.amplification {
            Some(a) if e != 0.0 => {
                let corners = scene
                    .probe_vertices(p)
                    .map(|v| self.power_vertex.get(v as usize).copied().flatten());
                a.curve(corners, p.bary, e)
            }
            _ => EffectCurve::flat(e),
        }
    }

    /// The hidden nodule's linear effect at `p` (`F_with/F_without − 1`; 0 without a
    /// case or off the table's faces).
    pub fn effect_at(&self, p: &ProbePoint) -> f32 {
        let (Some(trial), Some(Some(face))) = (&self.trial, self.faces.get(p.triangle as usize))
        else {
            return 0.0;
        };
        trial
            .case
            .effect
            .at(&self.table, *face as usize, p.bary)
            .unwrap_or(0.0) as f32
    }

    /// A force the trainee pressed with.
    pub fn pressed(&mut self, force_n: f32) {
        if let Some(t) = self.trial.as_mut() {
            t.pressed(f64::from(force_n));
        }
    }

    /// Marks the nodule at the rest position of `p`, reveals it and returns the score
    /// (`None` without a case). Once revealed, the trial's score stands: a later mark
    /// changes nothing.
    pub fn mark(
        &mut self,
        scene: &PalpationScene,
        p: &ProbePoint,
        now_s: f64,
    ) -> anyhow::Result<Option<Score>> {
        let Some(trial) = self.trial.as_mut() else {
            return Ok(None);
        };
        if self.revealed {
            return Ok(trial.score());
        }
        let (at, _) = scene.frame(p);
        trial.mark(at, now_s)?;
        self.revealed = true;
        let score = trial.score();
        if let Some(s) = score {
            self.scores.push(s);
        }
        Ok(score)
    }

    /// The trainee gives up: the nodule is shown, unscored.
    pub fn reveal(&mut self) {
        self.revealed = self.trial.is_some();
    }

    /// The force with the nodule over the force without at depth `depth_mm`, at every
    /// scene vertex (1 where the table does not reach), and a generation that changes
    /// with the case and with the depth (by half a millimetre): the stiffness map.
    pub fn vertex_ratios(&mut self, scene: &PalpationScene, depth_mm: f64) -> (&[f32], u64) {
        let depth = (2.0 * depth_mm).round() / 2.0;
        if self.map_values.0.is_empty() || depth != self.map_depth_mm {
            let mut v = vec![1.0f32; scene.vertices_mm().len()];
            for triangle in 0..scene.axis_triangles().len() as u32 {
                for k in 0..3 {
                    let mut bary = [0.0; 3];
                    bary[k] = 1.0;
                    let p = ProbePoint { triangle, bary };
                    let vertex = scene.probe_vertices(&p)[k] as usize;
                    v[vertex] = (1.0 + self.curve_at(scene, &p).at(depth)) as f32;
                }
            }
            self.map_values.0 = v;
            self.map_values.1 += 1;
            self.map_depth_mm = depth;
        }
        (&self.map_values.0, self.map_values.1)
    }

    /// The largest force with the nodule over the force without on the surface for the
    /// current case at the map's depth (the map's top; 1 before a map is drawn).
    pub fn peak_ratio(&self) -> f32 {
        self.map_values.0.iter().copied().fold(1.0, f32::max)
    }
}
