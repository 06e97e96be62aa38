//! The network scene's interface: a slider for time and every parameter (each over its
//! trained range), play/pause of time, the joint of a two-species model as a heat map,
//! every species' marginal as a bar chart with mean ± standard deviation, the mass and
//! the clamp/negativity flags, and the evaluation times.

use egui::{Color32, RichText};

use super::NetworkRoom;
use super::job::JobState;
use crate::layout::Form;
use crate::ui::{Hud, ramp};

/// Draws the whole network interface: the controls in the panel of
/// [`crate::layout`] (a bottom sheet on a phone upright, with the distribution in it;
/// a side drawer elsewhere, with the distribution in a card on the right), the
/// landscape filling the rest.
pub fn show(ctx: &egui::Context, room: &mut NetworkRoom, hud: &mut Hud) {
    let layout = crate::ui::layout(ctx, hud);
    let mut open = hud.panel_open.unwrap_or(layout.form == Form::Drawer);
    let summary = format!(
        "t = {:.3}{}",
        room.time.value,
        if room.playing { " ▶" } else { "" }
    );
    match layout.form {
        Form::Sheet => {
            let sheet =
                crate::layout::panel(ctx, "network-panel", &layout, &mut open, &summary, |ui| {
                    controls(ui, room, hud);
                    ui.separator();
                    views(ui, room);
                });
            hud.free_view = Some(crate::ui::center_view(ctx, hud, &[sheet], &mut room.camera));
        }
        Form::Drawer => {
            let drawer =
                crate::layout::panel(ctx, "network-panel", &layout, &mut open, &summary, |ui| {
                    controls(ui, room, hud);
                });
            // The distribution on the right, inside the safe area.
            let safe = ctx.content_rect();
            let width = (0.32 * safe.width()).clamp(260.0, 420.0);
            let distribution = egui::Area::new(egui::Id::unique("network-distribution"))
                .pivot(egui::Align2::RIGHT_TOP)
                .fixed_pos(safe.right_top() + egui::vec2(-8.0, 8.0))
                .constrain(true)
                .show(ctx, |ui| {
                    egui::Frame::window(ui.style()).show(ui, |ui| {
                        ui.set_width(width);
                        egui::ScrollArea::vertical()
                            .max_height(safe.height() - 40.0)
                            .scroll_bar_visibility(crate::layout::scroll_bar(&layout))
                            .show(ui, |ui| views(ui, room));
                    });
                });
            let covered = [drawer, distribution.response.rect];
            hud.free_view = Some(crate::ui::center_view(ctx, hud, &covered, &mut room.camera));
        }
    }
    hud.panel_open = Some(open);
}

fn controls(ui: &mut egui::Ui, room: &mut NetworkRoom, hud: &mut Hud) {
    ui.label(RichText::new(&hud.scene_source).small());
    crate::ui::scene_switcher(ui, hud);
    if let Some(m) = &hud.message {
        ui.colored_label(Color32::from_rgb(230, 160, 60), m);
    }
    ui.separator();
    let t = &mut room.time;
    // A value set beyond the trained range (a path, the gamepad) stays as it is: the
    // evaluation clamps it and the panel flags it.
    ui.add(
        egui::Slider::new(&mut t.value, t.lo..=t.hi)
            .clamping(egui::SliderClamping::Never)
            .text("t"),
    );
    ui.horizontal(|ui| {
        let label = if room.playing { "pause" } else { "play" };
        if ui.button(label).clicked() {
            room.playing = !room.playing;
        }
        let top = (room.time.hi / 2.0).max(1e-9);
        ui.add(
            egui::Slider::new(&mut room.speed, 0.0..=top)
                .logarithmic(true)
                .text("t per s"),
        );
    });
    for c in &mut room.params {
        ui.add(
            egui::Slider::new(&mut c.value, c.lo..=c.hi)
                .clamping(egui::SliderClamping::Never)
                .text(&c.name),
        );
    }
    ui.separator();
    if let Some(e) = &room.error {
        ui.colored_label(Color32::from_rgb(230, 90, 80), e);
    }
    if let Some(e) = &room.eval {
        ui.label(format!("probability mass {:.6}", e.moments.mass));
        // Round-off below 1e-9 is not worth a warning.
        if e.most_negative < -1e-9 {
            ui.colored_label(
                Color32::from_rgb(230, 160, 60),
                format!("most negative probability {:.2e}", e.most_negative),
            );
        }
        if !e.clamped.is_empty() {
            ui.colored_label(
                Color32::from_rgb(230, 160, 60),
                format!("clamped to the trained range: {}", e.clamped.join(", ")),
            );
        }
        // Many species: the strip beside the distribution gives each mean ± sd.
        if room.species.len() <= STRIP_FROM_SPECIES {
            moments_grid(ui, &room.species, &e.moments);
        }
    }
    ui.separator();
    exact_check(ui, room);
    ui.separator();
    data_panel(ui, room);
    ui.separator();
    let us = |r: &crate::stats::Ring| r.quantile(0.5);

    ui.label(format!(
        "evaluation {:.1} µs (median), joint {:.1} µs",
        us(&room.eval_us),
        us(&room.joint_us)
    ));
    ui.label(format!(
        "frame {:.2} ms (median)",
        hud.frame_ms.quantile(0.5)
    ));
}

/// The data's colour: histograms over the marginals, the posterior's density.
const DATA_COLOUR: Color32 = Color32::from_rgb(255, 170, 60);

/// Snapshot data: a file to load, the log-likelihood at the sliders' rates, "Fit"
/// (the sliders moved to the maximum, the intervals listed) and the posterior of the
/// first two rates as a density.
fn data_panel(ui: &mut egui::Ui, room: &mut NetworkRoom) {
    ui.horizontal(|ui| {
        ui.label("data");
        ui.add(
            egui::TextEdit::singleline(&mut room.data_path)
                .hint_text("cells.csv (t,<species>…)")
                .desired_width(150.0),
        );
        if ui.button("load").clicked() {
            let path = std::path::PathBuf::from(room.data_path.trim());
            match room.load_data(&path) {
                Ok(()) => room.error = None,
                Err(e) => room.error = Some(format!("{e:#}")),
            }
        }
    });
    let Some(d) = &room.data else {
        ui.label(RichText::new("snapshot counts in single cells: fit the rates to them").small());
        return;
    };
    ui.label(format!(
        "{}: {} cells at {} times, observed {}",
        d.source,
        d.snapshots.cell_count(),
        d.snapshots.times.len(),
        d.snapshots.species.join(", ")
    ));
    if let Some(l) = d.log_likelihood {
        ui.label(format!(
            "log-likelihood {l:.2} at these rates ({:.1} µs)",
            d.likelihood_us
        ));
    }
    let mut act = None;
    ui.horizontal(|ui| {
        if ui.button("Fit").clicked() {
            act = Some(false);
        }
        if ui.button("Posterior").clicked() {
            act = Some(true);
        }
    });
    match act {
        Some(false) => {
            if let Err(e) = room.fit_data() {
                room.error = Some(format!("{e:#}"));
            }
        }
        Some(true) => {
            if let Err(e) = room.sample_posterior(2_000) {
                room.error = Some(format!("{e:#}"));
            }
        }
        None => {}
    }
    let Some(d) = &room.data else { return };
    if let Some((estimates, seconds)) = &d.fit {
        egui::Grid::new("fit").striped(true).show(ui, |ui| {
            ui.label("rate");
            ui.label("MLE");
            ui.label("95 % (profile)");
            ui.end_row();
            for e in estimates {
                ui.label(&e.name);
                ui.label(format!("{:.5}", e.mle));
                let mut text = format!("{:.5} – {:.5}", e.profile_ci95[0], e.profile_ci95[1]);
                if !e.identifiable {
                    text = "unidentifiable".into();
                } else if e.at_range_end || e.profile_open.iter().any(|o| *o) {
                    text += " (range end)";
                }
                ui.label(text);
                ui.end_row();
            }
        });
        ui.label(RichText::new(format!("fitted in {:.0} ms", seconds * 1e3)).small());
    }
    if let Some((post, density)) = &d.posterior {
        let (rhat, ess) = (post.worst_rhat(), post.least_ess());
        ui.label(format!(
            "posterior: {} chains × {} steps, R-hat ≤ {rhat:.3}, ESS ≥ {ess:.0}",
            post.chains, post.steps
        ));
        let names: Vec<String> = post.rates.iter().map(|r| r.name.clone()).collect();
        posterior_density(ui, density);
        if names.len() > 2 {
            // More than two rates: which two the density shows.
            let mut pair = d.pair;
            ui.horizontal(|ui| {
                ui.label("density of");
                for (id, slot) in [("post-a", 0), ("post-b", 1)] {
                    let current = if slot == 0 { pair.0 } else { pair.1 };
                    egui::ComboBox::from_id_salt(id)
                        .selected_text(names[current].as_str())
                        .show_ui(ui, |ui| {
                            for (i, n) in names.iter().enumerate() {
                                let mut pick = current;
                                if ui.selectable_value(&mut pick, i, n).clicked() {
                                    if slot == 0 && pick != pair.1 {
                                        pair.0 = pick;
                                    } else if slot == 1 && pick != pair.0 {
                                        pair.1 = pick;
                                    }
                                }
                            }
                        });
                }
            });
            if pair != d.pair
                && let Some(d) = room.data.as_mut()
            {
                d.show_pair(pair.0, pair.1);
            }
        }
    }
}

/// The density as a grid of cells coloured by the ramp, its axes' ends labelled.
fn posterior_density(ui: &mut egui::Ui, d: &super::data::Density) {
    let n = super::data::DENSITY_CELLS;
    let side = ui.available_width().clamp(120.0, 240.0);
    let (rect, _) = ui.allocate_exact_size(egui::vec2(side, side), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    let cell = side / n as f32;
    for j in 0..n {
        for i in 0..n {
            let v = d.cells[j * n + i];
            if v <= 0.0 {
                continue;
            }
            let min = rect.left_bottom() + egui::vec2(i as f32 * cell, -((j + 1) as f32) * cell);
            painter.rect_filled(
                egui::Rect::from_min_size(min, egui::vec2(cell, cell)),
                0.0,
                ramp(v),
            );
        }
    }
    painter.rect_stroke(
        rect,
        0.0,
        egui::Stroke::new(1.0, DATA_COLOUR),
        egui::StrokeKind::Inside,
    );
    ui.label(
        RichText::new(format!(
            "{} {:.4} … {:.4} →   {} {:.4} … {:.4} ↑",
            d.names[0], d.x[0], d.x[1], d.names[1], d.y[0], d.y[1]
        ))
        .small(),
    );
}

/// Each species' mean and standard deviation.
fn moments_grid(ui: &mut egui::Ui, species: &[String], moments: &palpa_core::cme::Moments) {
    egui::Grid::new("moments").striped(true).show(ui, |ui| {
        ui.label("species");
        ui.label("mean");
        ui.label("sd");
        ui.end_row();
        for (i, name) in species.iter().enumerate() {
            ui.label(name);
            ui.label(format!("{:.3}", moments.mean[i]));
            ui.label(format!("{:.3}", moments.var[i].max(0.0).sqrt()));
            ui.end_row();
        }
    });
}

/// Trajectories of the SSA check.
const SSA_TRAJECTORIES: usize = 10_000;

/// The checks: exact (FSP) and sampled (SSA), each with start, progress and cancel, and
/// its verdict next to the meta-model's time.
fn exact_check(ui: &mut egui::Ui, room: &mut NetworkRoom) {
    let enabled = room.network.is_some();
    let why = "the checks need the network the model was built from (a built-in or a TOML file)";
    let exact = job_row(
        ui,
        room.check.as_ref().map(|j| &j.state),
        enabled,
        why,
        "exact check (FSP) here",
    );
    let ssa = job_row(
        ui,
        room.ssa.as_ref().map(|j| &j.state),
        enabled,
        why,
        &format!("SSA check ({SSA_TRAJECTORIES} paths) here"),
    );
    let coordinates = room.coordinates();
    if let Some(r) = &room.check_result {
        let (what, of) = if r.joint {
            ("joint L1", "joint")
        } else {
            ("largest marginal L1", "marginals")
        };
        ui.label(format!(
            "exact: {what} {:.2e} · FSP {:.2} s · meta-model {of} {:.0} µs",
            r.l1, r.exact_s, r.model_us
        ));
        if r.coordinates != coordinates {
            ui.label(
                RichText::new(format!(
                    "(at t = {:.3}; coordinates moved since)",
                    r.coordinates[0]
                ))
                .small(),
            );
        }
    }
    if let Some(r) = &room.ssa_result {
        ui.label(format!(
            "SSA: marginal L1 ≤ {:.2e} (noise included) · {} paths in {:.2} s",
            r.l1, r.sampled.trajectories, r.sampled.seconds
        ));
        if r.sampled.coordinates != coordinates {
            ui.label(
                RichText::new(format!(
                    "(at t = {:.3}; coordinates moved since)",
                    r.sampled.coordinates[0]
                ))
                .small(),
            );
        }
    }
    match exact {
        Some(true) => {
            if let Err(e) = room.start_check() {
                room.error = Some(format!("{e:#}"));
            }
        }
        Some(false) => {
            if let Some(j) = room.check.as_mut() {
                j.cancel();
            }
        }
        None => {}
    }
    match ssa {
        Some(true) => {
            if let Err(e) = room.start_ssa(SSA_TRAJECTORIES) {
                room.error = Some(format!("{e:#}"));
            }
        }
        Some(false) => {
            if let Some(j) = room.ssa.as_mut() {
                j.cancel();
            }
        }
        None => {}
    }
}

/// One job's row: a progress bar and cancel while it runs, else its start button and
/// how it ended. `Some(true)`: start pressed; `Some(false)`: cancel pressed.
fn job_row<T>(
    ui: &mut egui::Ui,
    state: Option<&JobState<T>>,
    enabled: bool,
    why: &str,
    label: &str,
) -> Option<bool> {
    let mut pressed = None;
    match state {
        Some(JobState::Running { progress }) => {
            ui.horizontal(|ui| {
                ui.add(egui::ProgressBar::new(*progress as f32).text(label));
                if ui.button("cancel").clicked() {
                    pressed = Some(false);
                }
            });
        }
        state => {
            if ui
                .add_enabled(enabled, egui::Button::new(label))
                .on_disabled_hover_text(why)
                .clicked()
            {
                pressed = Some(true);
            }
            match state {
                Some(JobState::Failed(why)) => {
                    ui.colored_label(Color32::from_rgb(230, 90, 80), why);
                }
                Some(JobState::Cancelled) => {
                    ui.label("cancelled");
                }
                _ => {}
            }
        }
    }
    pressed
}

fn views(ui: &mut egui::Ui, room: &mut NetworkRoom) {
    if let Some(pairs) = room.model().pairs() {
        // A views model offers the joints it stored, and only those.
        let name = |(a, b): (usize, usize)| format!("{} × {}", room.species[a], room.species[b]);
        ui.horizontal(|ui| {
            ui.label("joint of");
            let mut pick = room.pair;
            egui::ComboBox::from_id_salt("stored-pair")
                .selected_text(name(room.pair))
                .show_ui(ui, |ui| {
                    for &p in &pairs {
                        ui.selectable_value(&mut pick, p, name(p));
                    }
                });
            room.pair = pick;
        });
        if pairs.is_empty() {
            ui.label("this model stores no joint: marginals only");
        }
    } else if room.species.len() > 2 {
        ui.horizontal(|ui| {
            ui.label("joint of");
            for (id, slot) in [("pair-a", 0), ("pair-b", 1)] {
                let current = if slot == 0 { room.pair.0 } else { room.pair.1 };
                egui::ComboBox::from_id_salt(id)
                    .selected_text(room.species[current].as_str())
                    .show_ui(ui, |ui| {
                        for (i, name) in room.species.iter().enumerate() {
                            let mut pick = current;
                            if ui.selectable_value(&mut pick, i, name).clicked() && pick != current
                            {
                                let other = if slot == 0 { room.pair.1 } else { room.pair.0 };
                                if pick != other {
                                    if slot == 0 {
                                        room.pair.0 = pick;
                                    } else {
                                        room.pair.1 = pick;
                                    }
                                }
                            }
                        }
                    });
            }
        });
    }
    match &room.joint {
        Some(_) if room.species.len() >= 2 => {
            ui.label(format!(
                "joint P({}, {}) at t = {:.3}",
                room.species[room.pair.0], room.species[room.pair.1], room.time.value
            ));
            let key = room.coordinates();
            match room.window.as_ref() {
                Some(w) => heat_map(ui, w, &key, &mut room.heat),
                None => {
                    ui.label("the joint is zero at these coordinates");
                }
            }
        }
        _ => {
            ui.label("one species: its marginal follows");
        }
    }
    let Some(e) = &room.eval else { return };
    if room.species.len() > STRIP_FROM_SPECIES {
        let key = room.coordinates();
        strip(ui, &room.species, &e.moments, &key, &mut room.strip);
        return;
    }
    let cols = room.species.len().clamp(1, 2);
    // Measured outside the grid: inside a cell the width left is the cell's.
    let plot_width = (ui.available_width() / cols as f32 - 12.0).max(90.0);
    egui::Grid::new("marginals").show(ui, |ui| {
        for (i, (name, m)) in room.species.iter().zip(&e.moments.marginals).enumerate() {
            ui.vertical(|ui| {
                ui.label(format!(
                    "{name}: mean {:.2} ± {:.2}",
                    e.moments.mean[i],
                    e.moments.var[i].max(0.0).sqrt()
                ));
                // Only where the mass is: the truncated range runs far past it.
                let shown = super::marginal_window(m).unwrap_or(0..=m.len().saturating_sub(1));
                let points = |p: &[f64]| -> Vec<[f64; 2]> {
                    p.iter()
                        .enumerate()
                        .filter(|(z, _)| shown.contains(z))
                        .map(|(z, &p)| [z as f64, p])
                        .collect()
                };
                let bars: Vec<egui_plot::Bar> = points(m)
                    .into_iter()
                    .map(|[z, p]| egui_plot::Bar::new(z, p).width(1.0))
                    .collect();
                let exact = (room.check_result.as_ref()).map(|r| points(&r.exact.marginals[i]));
                let observed = room
                    .data
                    .as_ref()
                    .and_then(|d| d.histogram(room.time.value, i, m.len()))
                    .map(|(t, h)| (t, points(&h)));
                let sampled = (room.ssa_result.as_ref()).map(|r| points(&r.sampled.marginals[i]));
                egui_plot::Plot::new(format!("marginal-{i}"))
                    .width(plot_width)
                    .x_axis_label(format!("copies {}..{}", shown.start(), shown.end()))
                    .height(90.0)
                    .include_y(0.0)
                    .allow_zoom(false)
                    .allow_drag(false)
                    .allow_scroll(false)
                    .allow_axis_zoom_drag(false)
                    .allow_double_click_reset(false)
                    .allow_boxed_zoom(false)
                    .show(ui, |plot| {
                        plot.bar_chart(egui_plot::BarChart::new(name.clone(), bars));
                        if let Some(points) = exact {
                            plot.line(
                                egui_plot::Line::new("exact", points)
                                    .color(Color32::from_rgb(240, 240, 240)),
                            );
                        }
                        if let Some(points) = sampled {
                            plot.points(
                                egui_plot::Points::new("SSA", points)
                                    .radius(1.5)
                                    .color(Color32::from_rgb(120, 220, 255)),
                            );
                        }
                        if let Some((t, points)) = observed {
                            plot.line(
                                egui_plot::Line::new(format!("data, t = {t}"), points)
                                    .color(DATA_COLOUR),
                            );
                        }
                    });
            });
            if (i + 1) % cols == 0 {
                ui.end_row();
            }
        }
    });
}

/// Puts `image` into the texture `tex` (made on first use), remembering the
/// coordinates `key` it shows.
fn upload(
    ui: &egui::Ui,
    tex: &mut Option<super::HeatTexture>,
    name: &str,
    image: egui::ColorImage,
    key: &[f64],
) {
    match tex.as_mut() {
        Some(h) => {
            h.handle.set(image, egui::TextureOptions::NEAREST);
            h.key = key.to_vec();
        }
        None => {
            *tex = Some(super::HeatTexture {
                key: key.to_vec(),
                handle: ui
                    .ctx()
                    .load_texture(name, image, egui::TextureOptions::NEAREST),
            });
        }
    }
}

/// Above this many species the marginals are one species × copy-number strip, not a
/// bar chart each (twenty plots would not fit, nor draw in a frame on a software
/// rasterizer).
const STRIP_FROM_SPECIES: usize = 6;

/// Every marginal as one row of a texture: copy number along x, each row coloured by
/// the ramp up to its own peak (a wide distribution stays as visible as a sharp one),
/// with each species' mean ± sd beside it.
fn strip(
    ui: &mut egui::Ui,
    species: &[String],
    moments: &palpa_core::cme::Moments,
    key: &[f64],
    tex: &mut Option<super::HeatTexture>,
) {
    let nx = moments
        .marginals
        .iter()
        .map(Vec::len)
        .max()
        .unwrap_or(1)
        .max(1);
    let ny = moments.marginals.len().max(1);
    ui.label(format!(
        "marginals at t = {:.3}: species down, copies 0..{} across, each row up to its peak",
        moments.t,
        nx - 1
    ));
    let fresh = tex.as_ref().is_none_or(|h| h.key != key);
    if fresh {
        let pixels: Vec<Color32> = moments
            .marginals
            .iter()
            .flat_map(|m| {
                let peak = m.iter().copied().fold(0.0f64, f64::max);
                (0..nx).map(move |z| {
                    let v = m.get(z).copied().unwrap_or(0.0);
                    ramp(if peak > 0.0 && v > 0.0 {
                        (v / peak) as f32
                    } else {
                        0.0
                    })
                })
            })
            .collect();
        upload(
            ui,
            tex,
            "strip",
            egui::ColorImage::new([nx, ny], pixels),
            key,
        );
    }
    let row_h = 11.0;
    let label_w = 140.0;
    let width = (ui.available_width() - label_w).max(80.0);
    let (rect, _) = ui.allocate_exact_size(
        egui::vec2(width + label_w, row_h * ny as f32),
        egui::Sense::hover(),
    );
    let image_rect = egui::Rect::from_min_size(rect.min, egui::vec2(width, rect.height()));
    let painter = ui.painter_at(rect);
    if let Some(h) = tex.as_ref() {
        painter.image(
            h.handle.id(),
            image_rect,
            egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
            Color32::WHITE,
        );
    }
    let font = egui::FontId::proportional(9.5);
    for (i, name) in species.iter().enumerate() {
        let y = rect.min.y + (i as f32 + 0.5) * row_h;
        painter.text(
            egui::pos2(image_rect.max.x + 4.0, y),
            egui::Align2::LEFT_CENTER,
            format!(
                "{name} {:.1} ± {:.1}",
                moments.mean[i],
                moments.var[i].max(0.0).sqrt()
            ),
            font.clone(),
            Color32::from_gray(220),
        );
    }
}

/// The joint's window as one texture (first species along x, second up), coloured by
/// the ramp up to its peak, with the copy-number ranges under it.
fn heat_map(
    ui: &mut egui::Ui,
    w: &super::JointWindow,
    key: &[f64],
    heat: &mut Option<super::HeatTexture>,
) {
    let super::JointWindow {
        a0,
        b0,
        wa,
        wb,
        nx,
        ny,
        ref cells,
        peak,
    } = *w;
    // At most a quarter of the screen's height (a phone held upright keeps the
    // landscape in view).
    let cap = (0.25 * ui.ctx().content_rect().height()).max(120.0);
    let side = ui.available_width().clamp(120.0, 260.0).min(cap);
    let (rect, _) = ui.allocate_exact_size(egui::vec2(side, side), egui::Sense::hover());
    // One texture, refreshed only when the coordinates change (thousands of quads
    // would cost a software rasterizer tens of milliseconds a frame).
    let fresh = heat.as_ref().is_none_or(|h| h.key != key);
    if fresh {
        let pixels: Vec<Color32> = (0..ny)
            .rev()
            .flat_map(|y| (0..nx).map(move |x| (x, y)))
            .map(|(x, y)| {
                let v = cells[y * nx + x];
                ramp(if v > 0.0 { (v / peak) as f32 } else { 0.0 })
            })
            .collect();
        upload(
            ui,
            heat,
            "joint",
            egui::ColorImage::new([nx, ny], pixels),
            key,
        );
    }
    if let Some(h) = heat.as_ref() {
        ui.painter_at(rect).image(
            h.handle.id(),
            rect,
            egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
            Color32::WHITE,
        );
    }
    ui.label(format!(
        "x: copies {a0}..{} · y: copies {b0}..{} · colour: probability up to {peak:.3e}",
        a0 + wa - 1,
        b0 + wb - 1
    ));
}
