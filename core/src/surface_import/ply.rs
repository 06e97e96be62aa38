//! PLY (Stanford polygon file), ASCII and binary of either byte order: the header's
//! elements and properties are parsed in full so that any element or property can be
//! skipped; `vertex` gives `x`, `y`, `z` and `face` its `vertex_indices` (or
//! `vertex_index`) list.

use super::SurfaceError;
use super::indexed::Indexed;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }
}

#[derive(Debug)]
enum Prop {
    Scalar(String, Ty),
    List(String, Ty, Ty),
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

/// Values of the body, one at a time.
struct Body<'a> {
    enc: Encoding,
    bytes: &'a [u8],
    pos: usize,
    tokens: std::str::SplitAsciiWhitespace<'a>,
}

impl Body<'_> {
    fn value(&mut self, ty: Ty) -> Result<f64, String> {
        if self.enc == Encoding::Ascii {
            let tok = self.tokens.next().ok_or("the file ends inside its data")?;
            return tok
                .parse::<f64>()
                .map_err(|e| format!("bad number {tok:?}: {e}"));
        }
        let n = ty.size();
        let Some(raw) = self.bytes.get(self.pos..self.pos + n) else {
            return Err("the file ends inside its data".into());
        };
        self.pos += n;
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(raw);
        if self.enc == Encoding::Big {
            b[..n].reverse();
        }
        Ok(match ty {
            Ty::I8 => f64::from(b[0] as i8),
            Ty::U8 => f64::from(b[0]),
            Ty::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Ty::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Ty::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Ty::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Ty::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Ty::F64 => f64::from_le_bytes(b),
        })
    }
}

type ErrFn<'a> = dyn Fn(usize, String) -> SurfaceError + 'a;

pub(super) fn parse(bytes: &[u8], err: &ErrFn) -> Result<Indexed, SurfaceError> {
    let end = find(bytes, b"end_header")
        .ok_or_else(|| err(1, "no `end_header` line: not a complete PLY header".into()))?;
    let mut body_start = end + b"end_header".len();
    // The header ends with the line break after `end_header` (\n or \r\n).
    if bytes.get(body_start) == Some(&b'\r') {
        body_start += 1;
    }
    if bytes.get(body_start) == Some(&b'\n') {
        body_start += 1;
    }
    let header = String::from_utf8_lossy(&bytes[..end]);
    let mut enc = None;
    let mut elements: Vec<Element> = Vec::new();
    for (i, line) in header.lines().enumerate().skip(1) {
        let ln = i + 1;
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.first().copied() {
            Some("format") => {
                enc = Some(match w.get(1).copied() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::Little,
                    Some("binary_big_endian") => Encoding::Big,
                    other => {
                        return Err(err(ln, format!("unknown PLY format {other:?}")));
                    }
                });
            }
            Some("element") => {
                let (Some(name), Some(count)) = (w.get(1), w.get(2)) else {
                    return Err(err(ln, "an element needs a name and a count".into()));
                };
                let count: usize = count
                    .parse()
                    .map_err(|e| err(ln, format!("bad element count {count:?}: {e}")))?;
                // Every record takes at least one byte: a larger count is a lie that
                // must not size an allocation.
                if count > bytes.len() {
                    return Err(err(
                        ln,
                        format!(
                            "element {name} claims {count} records in a file of {} bytes",
                            bytes.len()
                        ),
                    ));
                }
                elements.push(Element {
                    name: (*name).into(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let Some(el) = elements.last_mut() else {
                    return Err(err(ln, "a property before any element".into()));
                };
                let ty = |s: Option<&&str>| {
                    s.and_then(|s| Ty::parse(s))
                        .ok_or_else(|| err(ln, format!("unknown property type in {line:?}")))
                };
                let prop = if w.get(1) == Some(&"list") {
                    let name = w
                        .get(4)
                        .ok_or_else(|| err(ln, "a list needs a name".into()))?;
                    Prop::List((*name).into(), ty(w.get(2))?, ty(w.get(3))?)
                } else {
                    let name = w
                        .get(2)
                        .ok_or_else(|| err(ln, "a property needs a name".into()))?;
                    Prop::Scalar((*name).into(), ty(w.get(1))?)
                };
                el.props.push(prop);
            }
            _ => {}
        }
    }
    let enc = enc.ok_or_else(|| err(2, "no `format` line in the PLY header".into()))?;
    let body_bytes = &bytes[body_start.min(bytes.len())..];
    let body_text = if enc == Encoding::Ascii {
        std::str::from_utf8(body_bytes).map_err(|_| err(0, "ASCII PLY data is not text".into()))?
    } else {
        ""
    };
    let mut body = Body {
        enc,
        bytes: body_bytes,
        pos: 0,
        tokens: body_text.split_ascii_whitespace(),
    };
    let mut out = Indexed::default();
    let mut idx: Vec<u32> = Vec::new();
    let mut faces_seen = false;
    for el in &elements {
        let is_vertex = el.name == "vertex";
        let is_face = el.name == "face";
        if is_vertex {
            for axis in ["x", "y", "z"] {
                if !el
                    .props
                    .iter()
                    .any(|p| matches!(p, Prop::Scalar(n, _) if n == axis))
                {
                    return Err(err(
                        0,
                        format!("the vertex element has no `{axis}` property"),
                    ));
                }
            }
        }
        faces_seen |= is_face;
        for r in 0..el.count {
            let mut p = [0.0; 3];
            for prop in &el.props {
                let at = |e: String| err(0, format!("{} {r}: {e}", el.name));
                match prop {
                    Prop::Scalar(name, ty) => {
                        let v = body.value(*ty).map_err(at)?;
                        if is_vertex && let Some(d) = ["x", "y", "z"].iter().position(|a| a == name)
                        {
                            if !v.is_finite() {
                                return Err(err(0, format!("vertex {r} has a non-finite {name}")));
                            }
                            p[d] = v;
                        }
                    }
                    Prop::List(name, count_ty, item_ty) => {
                        let n = body.value(*count_ty).map_err(at)?;
                        if !(n >= 0.0 && n.fract() == 0.0) {
                            return Err(err(0, format!("{} {r}: bad list length {n}", el.name)));
                        }
                        let wanted =
                            is_face && (name == "vertex_indices" || name == "vertex_index");
                        idx.clear();
                        for _ in 0..n as u64 {
                            let v = body.value(*item_ty).map_err(at)?;
                            if wanted {
                                if !(v >= 0.0 && v.fract() == 0.0 && v < u32::MAX as f64) {
                                    return Err(err(0, format!("face {r}: bad vertex index {v}")));
                                }
                                idx.push(v as u32);
                            }
                        }
                        if wanted {
                            if idx.len() < 3 {
                                return Err(err(
                                    0,
                                    format!(
                                        "face {r} has {} corners (at least 3 needed)",
                                        idx.len()
                                    ),
                                ));
                            }
                            if let Some(&bad) =
                                idx.iter().find(|&&v| v as usize >= out.vertices.len())
                            {
                                return Err(err(
                                    0,
                                    format!(
                                        "face {r}: vertex index {bad} out of range (0..{})",
                                        out.vertices.len()
                                    ),
                                ));
                            }
                            out.push_polygon(&idx);
                        }
                    }
                }
            }
            if is_vertex {
                out.vertices.push(p);
            }
        }
    }
    if !faces_seen {
        return Err(err(
            0,
            "the PLY file has no `face` element (a point cloud is not a surface)".into(),
        ));
    }
    Ok(out)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}
