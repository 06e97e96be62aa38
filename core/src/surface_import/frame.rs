//! From a file's coordinates to the organ frame: units to millimetres, and the file's
//! axes to the patient's (+x towards the patient's left, +y anterior, +z superior).
//!
//! Segmentation tools and simulation frameworks write surfaces in mm, cm or m, often
//! with y up; a surface taken as mm with −y posterior when it is in cm with z
//! posterior is a 1000× too small organ fixed on the wrong face, so units are always
//! stated and axes mapped explicitly.

use std::fmt;

use super::TriSurface;

/// Length units a surface file can be in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    Mm,
    Cm,
    M,
}

impl Units {
    pub fn to_mm(self) -> f64 {
        match self {
            Units::Mm => 1.0,
            Units::Cm => 10.0,
            Units::M => 1000.0,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Units::Mm => "mm",
            Units::Cm => "cm",
            Units::M => "m",
        }
    }
}

impl std::str::FromStr for Units {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "mm" => Ok(Units::Mm),
            "cm" => Ok(Units::Cm),
            "m" => Ok(Units::M),
            o => Err(format!("unknown unit {o:?}: expected mm, cm or m")),
        }
    }
}

/// Which signed file axis each patient axis is: `patient[i] = sign_i · file[axis_i]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Axes {
    map: [(usize, f64); 3],
}

impl Default for Axes {
    fn default() -> Self {
        Axes {
            map: [(0, 1.0), (1, 1.0), (2, 1.0)],
        }
    }
}

fn signed_axis(tok: &str) -> Result<(usize, f64), String> {
    let t = tok.trim();
    let (sign, name) = match t.as_bytes().first() {
        Some(b'-') => (-1.0, &t[1..]),
        Some(b'+') => (1.0, &t[1..]),
        _ => (1.0, t),
    };
    let axis = match name {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        _ => {
            return Err(format!(
                "{tok:?} is not an axis: expected x, y or z with an optional sign"
            ));
        }
    };
    Ok((axis, sign))
}

impl Axes {
    /// `"x,-z,y"`: the file axes that become the patient's x (left), y (anterior) and
    /// z (superior), each used once.
    pub fn parse(s: &str) -> Result<Axes, String> {
        let toks: Vec<&str> = s.split(',').collect();
        if toks.len() != 3 {
            return Err(format!(
                "--axes {s:?}: expected three signed file axes for the patient's x,y,z, e.g. x,-z,y"
            ));
        }
        let mut map = [(0, 1.0); 3];
        for (i, t) in toks.iter().enumerate() {
            map[i] = signed_axis(t)?;
        }
        let mut used = [false; 3];
        for (a, _) in map {
            if used[a] {
                return Err(format!("--axes {s:?} uses a file axis twice"));
            }
            used[a] = true;
        }
        Ok(Axes { map })
    }

    /// The file's up (patient superior, +z) and anterior (+y) axes; patient x
    /// completes a right-handed frame (x = y × z).
    pub fn from_up_anterior(up: &str, anterior: &str) -> Result<Axes, String> {
        let z = signed_axis(up)?;
        let y = signed_axis(anterior)?;
        if z.0 == y.0 {
            return Err(format!(
                "--up {up} and --anterior {anterior} are the same file axis"
            ));
        }
        // e_y × e_z for unit file axes: the third axis, with the sign of the
        // permutation (y.0, z.0, x) times both signs.
        let x_axis = 3 - y.0 - z.0;
        let cyclic = (y.0 + 1) % 3 == z.0;
        let sign = y.1 * z.1 * if cyclic { 1.0 } else { -1.0 };
        Ok(Axes {
            map: [(x_axis, sign), y, z],
        })
    }

    /// The map's determinant: −1 means the file is mirrored (allowed; the surface's
    /// orientation is then reversed by validation).
    pub fn is_mirror(&self) -> bool {
        let mut m = [[0.0; 3]; 3];
        for (i, (a, s)) in self.map.iter().enumerate() {
            m[i][*a] = *s;
        }
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        det < 0.0
    }

    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        self.map.map(|(a, s)| s * p[a])
    }
}

impl fmt::Display for Axes {
    /// `x,-z,y` (the form `--axes` reads).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names = ["x", "y", "z"];
        let parts: Vec<String> = self
            .map
            .iter()
            .map(|(a, s)| format!("{}{}", if *s < 0.0 { "-" } else { "" }, names[*a]))
            .collect();
        write!(f, "{}", parts.join(","))
    }
}

/// Scales the surface to mm and maps its axes to the patient frame.
pub fn to_patient(s: &mut TriSurface, units: Units, axes: &Axes) {
    let k = units.to_mm();
    for v in &mut s.vertices {
        *v = axes.apply(*v).map(|c| c * k);
    }
}

/// A warning when an organ's size (bounding-box diagonal, mm) looks like a unit
/// mistake: human organs span about 20 to 400 mm; a phantom or a small animal's organ
/// may be smaller, so only a factor of ten beyond that is flagged.
pub fn size_warning(diag_mm: f64, units: Units) -> Option<String> {
    if diag_mm < 2.0 {
        Some(format!(
            "the organ is {diag_mm:.3} mm across in {}: is the file in larger units (cm or m)?",
            units.name()
        ))
    } else if diag_mm > 4000.0 {
        Some(format!(
            "the organ is {:.1} m across in {}: is the file in smaller units (mm or cm)?",
            diag_mm / 1000.0,
            units.name()
        ))
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_parse_and_map() {
        let a = Axes::parse("x,-z,y").expect("valid");
        assert_eq!(a.apply([1.0, 2.0, 3.0]), [1.0, -3.0, 2.0]);
        assert_eq!(a.to_string(), "x,-z,y");
        assert!(!a.is_mirror());
        assert!(Axes::parse("x,x,y").is_err());
        assert!(Axes::parse("x,y").is_err());
        assert!(Axes::parse("x,y,w").is_err());
        assert!(Axes::parse("x,y,-z").expect("valid").is_mirror());
    }

    #[test]
    fn up_and_anterior_give_a_right_handed_frame() {
        // y up, -z anterior (a common export): patient z = file y, patient y = -file z.
        let a = Axes::from_up_anterior("y", "-z").expect("valid");
        assert!(!a.is_mirror(), "{a}");
        assert_eq!(a.apply([0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
        assert_eq!(a.apply([0.0, 0.0, -1.0]), [0.0, 1.0, 0.0]);
        for up in ["x", "-x", "y", "-y", "z", "-z"] {
            for ant in ["x", "-x", "y", "-y", "z", "-z"] {
                if up.trim_start_matches('-') == ant.trim_start_matches('-') {
                    assert!(Axes::from_up_anterior(up, ant).is_err());
                } else {
                    let a = Axes::from_up_anterior(up, ant).expect("valid");
                    assert!(!a.is_mirror(), "{up} {ant} -> {a}");
                }
            }
        }
    }

    #[test]
    fn sizes_that_look_like_another_unit_are_flagged() {
        assert!(size_warning(0.2, Units::Mm).is_some());
        assert!(size_warning(20_000.0, Units::M).is_some());
        assert!(size_warning(180.0, Units::Cm).is_none());
    }
}
