//! Region painting: a brush that marks the scene's surface triangles fixed, palpable
//! or neither, with undo, saved as a region file that `palpa scene build --regions`
//! reads (see `palpa_core::organ::region_file`: painted triangles are stored by their
//! centroids, so the regions carry over to another mesh of the same organ).
//!
//! The brush marks every triangle whose rest centroid lies within its radius of the
//! point under the pointer. Starting labels: the scene's palpable triangles palpable,
//! the rest neither (a scene keeps no record of its fixed region; the painter starts
//! from what the user can press).

use palpa_core::organ::region_file::{REGION_FILE_VERSION, RegionFile};
use palpa_core::scene::PalpationScene;

/// What a triangle is marked as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Label {
    Neither,
    Palpable,
    Fixed,
}

impl Label {
    /// The value the surface shader reads per vertex: 0 neither, 1 palpable, 2 fixed.
    fn shade(self) -> f32 {
        match self {
            Label::Neither => 0.0,
            Label::Palpable => 1.0,
            Label::Fixed => 2.0,
        }
    }
}

/// The painter's state.
#[derive(Debug, Clone)]
pub struct Painter {
    pub labels: Vec<Label>,
    pub brush: Label,
    pub radius_mm: f32,
    centroids: Vec<[f32; 3]>,
    /// Per finished stroke, the triangles it changed and their labels before.
    undo: Vec<Vec<(u32, Label)>>,
    stroke: Option<Vec<(u32, Label)>>,
    /// Bumped on every change (the renderer re-uploads the vertex values then).
    pub generation: u64,
    mean_edge_mm: f64,
}

impl Painter {
    pub fn new(scene: &PalpationScene) -> Painter {
        let v = scene.vertices_mm();
        let tris = scene.triangles();
        let palpable = scene.palpable_vertices();
        let mut edge_sum = 0.0;
        let centroids = tris
            .iter()
            .map(|t| {
                let p = t.map(|i| v[i as usize]);
                for e in 0..3 {
                    let (a, b) = (p[e], p[(e + 1) % 3]);
                    edge_sum += f64::from(
                        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2))
                            .sqrt(),
                    );
                }
                [0, 1, 2].map(|d| (p[0][d] + p[1][d] + p[2][d]) / 3.0)
            })
            .collect();
        let labels = tris
            .iter()
            .map(|t| {
                if t.iter().all(|&i| palpable[i as usize]) {
                    Label::Palpable
                } else {
                    Label::Neither
                }
            })
            .collect();
        let mean_edge_mm = edge_sum / (3 * tris.len().max(1)) as f64;
        Painter {
            labels,
            brush: Label::Fixed,
            radius_mm: (2.0 * mean_edge_mm) as f32,
            centroids,
            undo: Vec::new(),
            stroke: None,
            generation: 1,
            mean_edge_mm,
        }
    }

    pub fn begin_stroke(&mut self) {
        self.end_stroke();
        self.stroke = Some(Vec::new());
    }

    /// Marks the triangles within the brush of `at_mm` (a point on the surface).
    pub fn paint(&mut self, at_mm: [f32; 3]) {
        let r2 = self.radius_mm * self.radius_mm;
        let stroke = self.stroke.get_or_insert_with(Vec::new);
        let mut changed = false;
        for (i, c) in self.centroids.iter().enumerate() {
            let d2 = (0..3).map(|d| (c[d] - at_mm[d]).powi(2)).sum::<f32>();
            if d2 <= r2 && self.labels[i] != self.brush {
                stroke.push((i as u32, self.labels[i]));
                self.labels[i] = self.brush;
                changed = true;
            }
        }
        if changed {
            self.generation += 1;
        }
    }

    /// A stroke is under way (the pointer is down).
    pub fn stroking(&self) -> bool {
        self.stroke.is_some()
    }

    pub fn end_stroke(&mut self) {
        if let Some(s) = self.stroke.take()
            && !s.is_empty()
        {
            self.undo.push(s);
        }
    }

    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    /// Takes back the last stroke.
    pub fn undo(&mut self) {
        self.end_stroke();
        if let Some(s) = self.undo.pop() {
            for &(t, old) in s.iter().rev() {
                self.labels[t as usize] = old;
            }
            self.generation += 1;
        }
    }

    /// Triangles marked fixed and palpable.
    pub fn counts(&self) -> (usize, usize) {
        let f = self.labels.iter().filter(|&&l| l == Label::Fixed).count();
        let p = self
            .labels
            .iter()
            .filter(|&&l| l == Label::Palpable)
            .count();
        (f, p)
    }

    /// Why the regions cannot be used as they are, if they cannot.
    pub fn warning(&self) -> Option<&'static str> {
        match self.counts() {
            (0, _) => {
                Some("no fixed region: the organ would be free to move; paint where it is attached")
            }
            (_, 0) => Some("no palpable region: nothing could be pressed"),
            _ => None,
        }
    }

    /// Per render vertex, the value the surface shader colours by: a vertex of a fixed
    /// triangle shows fixed, else of a palpable one palpable.
    pub fn vertex_values(&self, scene: &PalpationScene) -> Vec<f32> {
        let mut v = vec![0.0f32; scene.vertices_mm().len()];
        for (t, l) in scene.triangles().iter().zip(&self.labels) {
            for &i in t {
                v[i as usize] = v[i as usize].max(l.shade());
            }
        }
        v
    }

    /// The region file of the painted labels.
    pub fn region_file(&self, painted_on: &str) -> Result<RegionFile, &'static str> {
        if let Some(w) = self.warning() {
            return Err(w);
        }
        let pick = |want: Label| {
            self.centroids
                .iter()
                .zip(&self.labels)
                .filter(|(_, l)| **l == want)
                .map(|(c, _)| c.map(f64::from))
                .collect()
        };
        Ok(RegionFile {
            version: REGION_FILE_VERSION,
            painted_on: painted_on.into(),
            match_radius_mm: self.mean_edge_mm,
            fixed_selectors: Vec::new(),
            palpable_selectors: Vec::new(),
            fixed_points: pick(Label::Fixed),
            palpable_points: pick(Label::Palpable),
        })
    }
}
