//! The command-line form of a region [`Selector`], in the organ's own coordinates (mm,
//! patient axes, after units and axes are applied):
//!
//! ```text
//! expr   := term ('|' term)*            either
//! term   := factor ('&' factor)*        both
//! factor := '!' factor | '(' expr ')' | atom
//! atom   := all | none
//!         | normal:DIR:DEGREES          outward normal within DEGREES of DIR
//!         | half:POINT:DIR              (p − POINT)·DIR ≥ 0
//!         | ball:POINT:RADIUS
//!         | line:POINT:DIR:RADIUS       within RADIUS of the infinite line
//!         | polyline:POINT;POINT;…:RADIUS
//! DIR    := X,Y,Z | ±x | ±y | ±z | left | right | anterior | posterior | superior | inferior
//! POINT  := X,Y,Z
//! ```
//!
//! For example `normal:posterior:45 & half:0,0,-20:0,0,1` is the posterior face above
//! z = −20 mm.

use thiserror::Error;

use super::Selector;

/// A selector that could not be read, with the reason.
#[derive(Debug, Clone, PartialEq, Error)]
#[error(
    "selector {text:?}: {reason} (expected e.g. normal:posterior:45, half:0,0,10:0,0,1, \
     ball:0,20,0:30, line:0,0,0:z:15, polyline:0,0,0;10,0,0:5, all, none, combined with \
     & | ! and parentheses)"
)]
pub struct SyntaxError {
    pub text: String,
    pub reason: String,
}

/// Reads a selector expression.
pub fn parse(text: &str) -> Result<Selector, SyntaxError> {
    let fail = |reason: String| SyntaxError {
        text: text.into(),
        reason,
    };
    if text.len() > 100_000 {
        return Err(fail("longer than 100 000 characters".into()));
    }
    let mut p = Parser {
        s: text.as_bytes(),
        i: 0,
        depth: 0,
    };
    let sel = p.expr().map_err(fail)?;
    p.skip_ws();
    if p.i != p.s.len() {
        return Err(fail(format!(
            "unexpected {:?} at byte {}",
            p.s[p.i] as char, p.i
        )));
    }
    Ok(sel)
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
    depth: usize,
}

impl Parser<'_> {
    fn skip_ws(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }

    fn peek(&mut self) -> Option<u8> {
        self.skip_ws();
        self.s.get(self.i).copied()
    }

    fn expr(&mut self) -> Result<Selector, String> {
        let mut v = vec![self.term()?];
        while self.peek() == Some(b'|') {
            self.i += 1;
            v.push(self.term()?);
        }
        Ok(if v.len() == 1 {
            v.remove(0)
        } else {
            Selector::Any(v)
        })
    }

    fn term(&mut self) -> Result<Selector, String> {
        let mut v = vec![self.factor()?];
        while self.peek() == Some(b'&') {
            self.i += 1;
            v.push(self.factor()?);
        }
        Ok(if v.len() == 1 {
            v.remove(0)
        } else {
            Selector::All(v)
        })
    }

    fn factor(&mut self) -> Result<Selector, String> {
        self.depth += 1;
        if self.depth > 64 {
            return Err("nested more than 64 deep".into());
        }
        let r = match self.peek() {
            Some(b'!') => {
                self.i += 1;
                Ok(Selector::Not(Box::new(self.factor()?)))
            }
            Some(b'(') => {
                self.i += 1;
                let e = self.expr()?;
                if self.peek() != Some(b')') {
                    return Err("a '(' is not closed".into());
                }
                self.i += 1;
                Ok(e)
            }
            Some(_) => {
                let start = self.i;
                while self.i < self.s.len() && !b"|&()!".contains(&self.s[self.i]) {
                    self.i += 1;
                }
                let atom = String::from_utf8_lossy(&self.s[start..self.i]);
                atom_of(atom.trim())
            }
            None => Err("ends where a selector was expected".into()),
        };
        self.depth -= 1;
        r
    }
}

fn number(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(format!("{s:?} is not a finite number")),
    }
}

fn point(s: &str) -> Result<[f64; 3], String> {
    let c: Vec<&str> = s.split(',').collect();
    if c.len() != 3 {
        return Err(format!("{s:?} is not a point X,Y,Z"));
    }
    Ok([number(c[0])?, number(c[1])?, number(c[2])?])
}

fn direction(s: &str) -> Result<[f64; 3], String> {
    let named = match s.trim() {
        "x" | "+x" | "left" => Some([1.0, 0.0, 0.0]),
        "-x" | "right" => Some([-1.0, 0.0, 0.0]),
        "y" | "+y" | "anterior" => Some([0.0, 1.0, 0.0]),
        "-y" | "posterior" => Some([0.0, -1.0, 0.0]),
        "z" | "+z" | "superior" => Some([0.0, 0.0, 1.0]),
        "-z" | "inferior" => Some([0.0, 0.0, -1.0]),
        _ => None,
    };
    let d = match named {
        Some(d) => d,
        None => point(s).map_err(|_| format!("{s:?} is not a direction"))?,
    };
    if d.iter().all(|&c| c == 0.0) {
        return Err(format!("direction {s:?} is zero"));
    }
    Ok(d)
}

fn radius(s: &str) -> Result<f64, String> {
    let r = number(s)?;
    if r < 0.0 {
        return Err(format!("radius {r} is negative"));
    }
    Ok(r)
}

fn atom_of(a: &str) -> Result<Selector, String> {
    let parts: Vec<&str> = a.split(':').collect();
    let want = |n: usize| {
        if parts.len() == n {
            Ok(())
        } else {
            Err(format!(
                "{:?} takes {} field(s) after the colon, got {}",
                parts[0],
                n - 1,
                parts.len() - 1
            ))
        }
    };
    match parts[0] {
        "all" => want(1).map(|_| Selector::Everything),
        "none" => want(1).map(|_| Selector::Nothing),
        "normal" => {
            want(3)?;
            let deg = number(parts[2])?;
            if !(0.0..=180.0).contains(&deg) {
                return Err(format!("angle {deg}° is not within 0 to 180"));
            }
            Ok(Selector::NormalWithin {
                dir: direction(parts[1])?,
                max_angle_deg: deg,
            })
        }
        "half" => {
            want(3)?;
            Ok(Selector::HalfSpace {
                point: point(parts[1])?,
                normal: direction(parts[2])?,
            })
        }
        "ball" => {
            want(3)?;
            Ok(Selector::Ball {
                center: point(parts[1])?,
                radius_mm: radius(parts[2])?,
            })
        }
        "line" => {
            want(4)?;
            Ok(Selector::NearLine {
                point: point(parts[1])?,
                dir: direction(parts[2])?,
                radius_mm: radius(parts[3])?,
            })
        }
        "polyline" => {
            want(3)?;
            let points = parts[1]
                .split(';')
                .map(point)
                .collect::<Result<Vec<_>, _>>()?;
            if points.len() < 2 {
                return Err("a polyline needs at least two points".into());
            }
            Ok(Selector::NearPolyline {
                points,
                radius_mm: radius(parts[2])?,
            })
        }
        "" => Err("an empty selector".into()),
        other => Err(format!("unknown selector kind {other:?}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expressions_parse_with_precedence() {
        let s = parse("normal:posterior:45 & half:0,0,-20:0,0,1 | ball:1,2,3:4").expect("ok");
        let Selector::Any(v) = &s else {
            panic!("| is the outermost: {s:?}")
        };
        assert!(matches!(v[0], Selector::All(_)));
        assert!(matches!(v[1], Selector::Ball { radius_mm: 4.0, .. }));
        assert!(s.contains([0.0, 0.0, 0.0], [0.0, -1.0, 0.0]));
        assert!(!s.contains([0.0, 0.0, -30.0], [0.0, -1.0, 0.0]));
        assert!(s.contains([1.0, 2.0, 5.0], [1.0, 0.0, 0.0]));
        let n = parse("!(normal:-y:45)").expect("ok");
        assert!(!n.contains([0.0; 3], [0.0, -1.0, 0.0]));
        let p = parse("polyline:0,0,0;10,0,0;10,10,0:1").expect("ok");
        assert!(p.contains([10.5, 5.0, 0.0], [0.0, 0.0, 1.0]));
        assert!(!p.contains([5.0, 5.0, 0.0], [0.0, 0.0, 1.0]));
    }

    #[test]
    fn bad_selectors_name_the_problem() {
        for (text, needle) in [
            ("normal:up:45", "not a direction"),
            ("normal:-y:200", "0 to 180"),
            ("ball:0,0:3", "not a point"),
            ("ball:0,0,0:-1", "negative"),
            ("cube:1", "unknown selector kind"),
            ("(all", "not closed"),
            ("all)", "unexpected"),
            ("", "ends where a selector"),
            ("all & ", "ends where a selector"),
            ("all &  & none", "empty selector"),
            ("half:0,0,0:0,0,0", "zero"),
            ("polyline:0,0,0:1", "two points"),
            ("ball:nan,0,0:1", "finite"),
        ] {
            let e = parse(text).expect_err(text).to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
        let deep = "!".repeat(100) + "all";
        assert!(parse(&deep).is_err());
    }
}
