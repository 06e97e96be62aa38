//! What a surface reader hands on: vertices and triangles as the file holds them,
//! before welding, with polygons split into triangle fans.

/// Vertices and triangles as a reader found them, before welding.
#[derive(Debug, Default)]
pub(super) struct Indexed {
    pub vertices: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
    pub polygons_split: usize,
}

impl Indexed {
    pub fn soup(corners: Vec<[f64; 3]>) -> Indexed {
        let n = corners.len() as u32 / 3;
        Indexed {
            vertices: corners,
            triangles: (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
            polygons_split: 0,
        }
    }

    /// Adds a polygon (already resolved to 0-based indices) as a fan of triangles.
    pub fn push_polygon(&mut self, idx: &[u32]) {
        if idx.len() > 3 {
            self.polygons_split += 1;
        }
        for k in 1..idx.len().saturating_sub(1) {
            self.triangles.push([idx[0], idx[k], idx[k + 1]]);
        }
    }
}
