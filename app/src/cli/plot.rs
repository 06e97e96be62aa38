//! Log–log line plots written as PNG without a GPU: egui_plot lays the plot out,
//! egui tessellates it into textured triangles, and a small CPU rasterizer paints
//! them (premultiplied-alpha "over" blending, nearest texel), so `palpa tradeoff
//! --plot` works on a headless machine with no graphics driver at all.

use std::collections::HashMap;
use std::path::Path;

use anyhow::{Context as _, bail};
use egui::{Color32, ColorImage, Pos2, Rect, TextureId, epaint};
use egui_plot::{GridMark, Legend, Line, Plot, PlotPoints, log_grid_spacer};

/// One named curve, in data coordinates (both must be positive: the axes are log).
#[derive(Debug, Clone)]
pub struct Series {
    pub name: String,
    pub points: Vec<[f64; 2]>,
}

/// One plot: a title, axis labels and curves.
#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
}

/// Tick label of a log10 axis value: `1e-3`, `0.01`, `1`, `100`, `1e4`.
fn decade_label(mark: GridMark, _range: &std::ops::RangeInclusive<f64>) -> String {
    let e = mark.value;
    if (e - e.round()).abs() > 1e-6 {
        return String::new(); // Only decades carry labels.
    }
    let e = e.round() as i32;
    match e {
        -2..=0 => format!("{}", 10f64.powi(e)),
        1..=3 => format!("{}", 10i64.pow(e as u32)),
        _ => format!("1e{e}"),
    }
}

/// Renders the panels side by side into a `width × height` PNG at `path`.
pub fn write_png(panels: &[Panel], width: u32, height: u32, path: &Path) -> anyhow::Result<()> {
    if panels.is_empty() {
        bail!("nothing to plot");
    }
    let ctx = egui::Context::default();
    ctx.set_visuals(egui::Visuals::light());
    let screen = Rect::from_min_size(Pos2::ZERO, egui::vec2(width as f32, height as f32));
    let mut textures: HashMap<TextureId, ColorImage> = HashMap::new();
    let mut primitives = Vec::new();
    // The first pass loads the fonts and sizes the layout; the second is painted.
    for _ in 0..2 {
        let input = egui::RawInput {
            screen_rect: Some(screen),
            ..Default::default()
        };
        let mut out = ctx.run_ui(input, |ui| {
            egui::Frame::new()
                .fill(Color32::WHITE)
                .inner_margin(8.0)
                .show(ui, |ui| {
                    let w = (width as f32 - 16.0) / panels.len() as f32 - 8.0;
                    ui.horizontal(|ui| {
                        for panel in panels {
                            ui.vertical(|ui| {
                                ui.set_width(w);
                                ui.heading(&panel.title);
                                plot_panel(ui, panel, w, height as f32 - 60.0);
                            });
                        }
                    });
                });
        });
        for (id, delta) in &out.textures_delta.set {
            for d in delta {
                let epaint::ImageData::Color(image) = &d.image;
                match d.pos {
                    None => {
                        textures.insert(*id, (**image).clone());
                    }
                    Some([x0, y0]) => {
                        let target = textures
                            .get_mut(id)
                            .context("texture patch before its image")?;
                        for y in 0..image.size[1] {
                            for x in 0..image.size[0] {
                                target.pixels[(y0 + y) * target.size[0] + x0 + x] =
                                    image.pixels[y * image.size[0] + x];
                            }
                        }
                    }
                }
            }
        }
        out.textures_delta.clear(); // Applied above.
        primitives = ctx.tessellate(std::mem::take(&mut out.shapes), out.pixels_per_point);
        out.drop_without_applying_deltas();
    }
    let mut canvas = Canvas::new(width as usize, height as usize);
    for p in &primitives {
        if let epaint::Primitive::Mesh(mesh) = &p.primitive {
            let tex = textures.get(&mesh.texture_id);
            canvas.mesh(mesh, tex, p.clip_rect);
        }
    }
    canvas.save(path)
}

fn plot_panel(ui: &mut egui::Ui, panel: &Panel, w: f32, h: f32) {
    Plot::new(&panel.title)
        .width(w)
        .height(h)
        .legend(Legend::default().position(egui_plot::Corner::LeftBottom))
        .x_axis_label(panel.x_label.clone())
        .y_axis_label(panel.y_label.clone())
        .x_grid_spacer(log_grid_spacer(10))
        .y_grid_spacer(log_grid_spacer(10))
        .x_axis_formatter(decade_label)
        .y_axis_formatter(decade_label)
        .show(ui, |plot| {
            for s in &panel.series {
                let pts: Vec<[f64; 2]> = s
                    .points
                    .iter()
                    .filter(|p| p[0] > 0.0 && p[1] > 0.0 && p[0].is_finite() && p[1].is_finite())
                    .map(|p| [p[0].log10(), p[1].log10()])
                    .collect();
                plot.line(Line::new(s.name.clone(), PlotPoints::from(pts)).width(2.0));
            }
        });
}

/// An RGBA8 image with premultiplied-alpha blending.
struct Canvas {
    w: usize,
    h: usize,
    px: Vec<[f32; 4]>,
}

impl Canvas {
    fn new(w: usize, h: usize) -> Canvas {
        Canvas {
            w,
            h,
            px: vec![[1.0; 4]; w * h],
        }
    }

    /// Paints a triangle mesh (positions in pixels: pixels_per_point is 1 here).
    fn mesh(&mut self, mesh: &epaint::Mesh, tex: Option<&ColorImage>, clip: Rect) {
        let x_lo = clip.min.x.max(0.0).floor() as usize;
        let y_lo = clip.min.y.max(0.0).floor() as usize;
        let x_hi = (clip.max.x.ceil().max(0.0) as usize).min(self.w);
        let y_hi = (clip.max.y.ceil().max(0.0) as usize).min(self.h);
        for tri in mesh.indices.chunks_exact(3) {
            let v = [0, 1, 2].map(|i| &mesh.vertices[tri[i] as usize]);
            let (a, b, c) = (v[0].pos, v[1].pos, v[2].pos);
            let area = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
            if area.abs() < 1e-12 {
                continue;
            }
            let bx0 = (a.x.min(b.x).min(c.x).floor().max(0.0) as usize).max(x_lo);
            let by0 = (a.y.min(b.y).min(c.y).floor().max(0.0) as usize).max(y_lo);
            let bx1 = (a.x.max(b.x).max(c.x).ceil().max(0.0) as usize).min(x_hi);
            let by1 = (a.y.max(b.y).max(c.y).ceil().max(0.0) as usize).min(y_hi);
            for y in by0..by1 {
                for x in bx0..bx1 {
                    let p = Pos2::new(x as f32 + 0.5, y as f32 + 0.5);
                    let w0 = ((b.x - p.x) * (c.y - p.y) - (c.x - p.x) * (b.y - p.y)) / area;
                    let w1 = ((c.x - p.x) * (a.y - p.y) - (a.x - p.x) * (c.y - p.y)) / area;
                    let w2 = 1.0 - w0 - w1;
                    if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                        continue;
                    }
                    let w = [w0, w1, w2];
                    let mut src = [0.0f32; 4];
                    for (k, vert) in v.iter().enumerate() {
                        let c = vert.color.to_array();
                        for (s, ch) in src.iter_mut().zip(c) {
                            *s += w[k] * f32::from(ch) / 255.0;
                        }
                    }
                    if let Some(img) = tex {
                        let u = w[0] * v[0].uv.x + w[1] * v[1].uv.x + w[2] * v[2].uv.x;
                        let t = w[0] * v[0].uv.y + w[1] * v[1].uv.y + w[2] * v[2].uv.y;
                        let tx = ((u * img.size[0] as f32) as usize).min(img.size[0] - 1);
                        let ty = ((t * img.size[1] as f32) as usize).min(img.size[1] - 1);
                        let texel = img.pixels[ty * img.size[0] + tx].to_array();
                        for (s, ch) in src.iter_mut().zip(texel) {
                            *s *= f32::from(ch) / 255.0;
                        }
                    }
                    let dst = &mut self.px[y * self.w + x];
                    for ch in 0..4 {
                        dst[ch] = src[ch] + dst[ch] * (1.0 - src[3]);
                    }
                }
            }
        }
    }

    fn save(&self, path: &Path) -> anyhow::Result<()> {
        let mut bytes = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut bytes, self.w as u32, self.h as u32);
            enc.set_color(png::ColorType::Rgba);
            enc.set_depth(png::BitDepth::Eight);
            let mut writer = enc.write_header()?;
            let data: Vec<u8> = self
                .px
                .iter()
                .flat_map(|p| p.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8))
                .collect();
            writer.write_image_data(&data)?;
        }
        palpa_core::fsutil::atomic_write(path, |w| std::io::Write::write_all(w, &bytes))
            .with_context(|| format!("writing {}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plot_has_text_and_curves_in_their_colours() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("p.png");
        let panel = Panel {
            title: "error".into(),
            x_label: "modes".into(),
            y_label: "relative error".into(),
            series: vec![
                Series {
                    name: "falls".into(),
                    points: (1..=100).map(|n| [n as f64, 1.0 / n as f64]).collect(),
                },
                Series {
                    name: "flat".into(),
                    points: vec![[1.0, 0.5], [100.0, 0.5]],
                },
            ],
        };
        write_png(&[panel.clone(), panel], 800, 400, &path).expect("png");
        let dec = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(&path).expect("open"),
        ));
        let mut reader = dec.read_info().expect("header");
        let mut buf = vec![0; reader.output_buffer_size().expect("size")];
        let info = reader.next_frame(&mut buf).expect("frame");
        assert_eq!((info.width, info.height), (800, 400));
        let px: Vec<[u8; 4]> = buf
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect();
        // Grey pixels well below white: text, ticks and axes. Saturated: the curves.
        let dark = px
            .iter()
            .filter(|p| {
                let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
                hi < 140 && hi - lo < 30
            })
            .count();
        let coloured = px
            .iter()
            .filter(|p| {
                let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
                hi - lo > 100
            })
            .count();
        eprintln!("grey {dark}, coloured {coloured}");
        assert!(
            dark > 400 && dark < 800 * 400 / 4,
            "text and axes were painted as glyphs and lines ({dark} grey pixels)"
        );
        assert!(
            coloured > 500,
            "curves were painted ({coloured} coloured pixels)"
        );
    }
}
