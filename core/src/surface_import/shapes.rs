//! Closed surfaces made here (test organs with known volumes, and the shipped kidney
//! example), and writers for the formats the readers take, so every reader is tested
//! on files of every kind.

use std::io::{self, Write};
use std::path::Path;

use super::TriSurface;
use crate::mesh::norm;

/// The unit sphere as a subdivided icosahedron: `20 · 4^subdiv` triangles, outward.
pub fn icosphere(subdiv: u32) -> TriSurface {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for p in &mut v {
        let l = norm(*p);
        *p = p.map(|c| c / l);
    }
    for _ in 0..subdiv {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(4 * f.len());
        for tri in &f {
            let m = [0, 1, 2].map(|e| {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let p = [0, 1, 2].map(|d| (v[a as usize][d] + v[b as usize][d]) / 2.0);
                    let l = norm(p);
                    v.push(p.map(|c| c / l));
                    (v.len() - 1) as u32
                })
            });
            next.push([tri[0], m[0], m[2]]);
            next.push([tri[1], m[1], m[0]]);
            next.push([tri[2], m[2], m[1]]);
            next.push(m);
        }
        f = next;
    }
    TriSurface {
        vertices: v,
        triangles: f,
    }
}

/// An ellipsoid with semi-axes `a`, `b`, `c` along x, y, z.
pub fn ellipsoid(a: f64, b: f64, c: f64, subdiv: u32) -> TriSurface {
    let mut s = icosphere(subdiv);
    for p in &mut s.vertices {
        *p = [a * p[0], b * p[1], c * p[2]];
    }
    s
}

/// A left kidney as a segmentation export would give it: centimetres, y up (superior),
/// z anterior, x completing a right-handed frame (towards the patient's right). An
/// ellipsoid of 11 × 6 × 4 cm with the hilum, a smooth dent of 1.3 cm on the medial
/// side (+x: a left kidney's hilum faces the patient's right); 5120 triangles.
pub fn kidney_cm() -> TriSurface {
    let mut s = icosphere(4);
    for p in &mut s.vertices {
        let [ux, uy, uz] = *p;
        let dent = (-(uy / 0.35).powi(2) - (uz / 0.5).powi(2)).exp() * ux.max(0.0).powi(2);
        *p = [3.0 * ux - 1.3 * dent, 5.5 * uy, 2.0 * uz];
    }
    s
}

impl TriSurface {
    /// Writes Wavefront OBJ (1-based indices).
    pub fn write_obj(&self, w: &mut impl Write) -> io::Result<()> {
        for v in &self.vertices {
            writeln!(w, "v {:.9} {:.9} {:.9}", v[0], v[1], v[2])?;
        }
        for t in &self.triangles {
            writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        Ok(())
    }

    /// Writes binary STL (every facet's corners stored separately, as STL does).
    pub fn write_stl_binary(&self, w: &mut impl Write) -> io::Result<()> {
        w.write_all(&[0u8; 80])?;
        w.write_all(&(self.triangles.len() as u32).to_le_bytes())?;
        for t in &self.triangles {
            w.write_all(&[0u8; 12])?;
            for &i in t {
                for c in self.vertices[i as usize] {
                    w.write_all(&(c as f32).to_le_bytes())?;
                }
            }
            w.write_all(&[0u8; 2])?;
        }
        Ok(())
    }

    /// Writes PLY, ASCII or binary little-endian, with a normal per vertex (which
    /// readers must skip) and faces as `uchar int` lists.
    pub fn write_ply(&self, w: &mut impl Write, binary: bool) -> io::Result<()> {
        let format = if binary {
            "binary_little_endian"
        } else {
            "ascii"
        };
        write!(
            w,
            "ply\nformat {format} 1.0\ncomment written by palpa\nelement vertex {}\n\
             property double x\nproperty double y\nproperty double z\n\
             property float nx\nproperty float ny\nproperty float nz\n\
             element face {}\nproperty list uchar int vertex_indices\nend_header\n",
            self.vertices.len(),
            self.triangles.len()
        )?;
        for v in &self.vertices {
            if binary {
                for c in v {
                    w.write_all(&c.to_le_bytes())?;
                }
                w.write_all(&[0u8; 12])?;
            } else {
                writeln!(w, "{} {} {} 0 0 0", v[0], v[1], v[2])?;
            }
        }
        for t in &self.triangles {
            if binary {
                w.write_all(&[3u8])?;
                for &i in t {
                    w.write_all(&(i as i32).to_le_bytes())?;
                }
            } else {
                writeln!(w, "3 {} {} {}", t[0], t[1], t[2])?;
            }
        }
        Ok(())
    }

    /// Writes by extension (`.obj`, `.stl` binary, `.ply` binary), atomically.
    pub fn write_by_extension(&self, path: &Path) -> io::Result<()> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        crate::fsutil::atomic_write(path, |w| match ext.as_deref() {
            Some("obj") => self.write_obj(w),
            Some("stl") => self.write_stl_binary(w),
            Some("ply") => self.write_ply(w, true),
            _ => Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{}: expected .obj, .stl or .ply", path.display()),
            )),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_are_closed_with_the_expected_volume() {
        let mut s = icosphere(4);
        assert_eq!(s.triangles.len(), 5120);
        s.validate().expect("closed");
        let exact = 4.0 / 3.0 * std::f64::consts::PI;
        assert!((s.volume() - exact).abs() / exact < 0.01, "{}", s.volume());
        let mut k = kidney_cm();
        let v = k.validate().expect("the kidney is a closed manifold");
        assert!(!v.flipped);
        // An 11 × 6 × 4 cm ellipsoid is 138 ml; the hilum takes a little.
        assert!((110.0..138.0).contains(&k.volume()), "{}", k.volume());
    }
}
