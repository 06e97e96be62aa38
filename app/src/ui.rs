//! The egui panels: press mode, force and depth, the force–depth and force-over-time
//! plots, the colormap and legend; folded under "Details", the modes kept with the
//! accuracy the file records (measured when it was built) and this device's loop
//! statistics; scene and material info, a screenshot button, and help.
//!
//! Everything here draws into a given `egui::Ui` and reads or changes the [`Session`];
//! the window and headless mode own the egui context and its painting ([`overlay`]).
//!
//! [`overlay`]: crate::overlay

use egui::{Color32, RichText};
use palpa_core::TradeoffRow;
use palpa_core::pgd::nodule::table::MAX_RATIO;

use crate::input::PressMode;
use crate::layout::{Form, Layout, Screen};
use crate::render::deform::DeformOn;
use crate::session::Session;
use crate::stats::Ring;

/// Interface state that is not the session's.
#[derive(Debug)]
pub struct Hud {
    pub frame_ms: Ring,
    /// Where the scene came from.
    pub scene_source: String,
    /// Gamepad name, or None when no pad is connected.
    pub gamepad: Option<String>,
    /// A message to show until dismissed (e.g. why the requested scene did not open).
    pub message: Option<String>,
    pub show_help: bool,
    pub screenshot_requested: bool,
    pub last_screenshot: Option<String>,
    /// A scene the user asked to switch to (the window opens it after the frame).
    pub switch_to: Option<String>,
    /// The scene path being typed.
    pub scene_field: String,
    /// The panel unfolded (None: the form's default, unfolded as a drawer, folded as a
    /// sheet).
    pub panel_open: Option<bool>,
    /// A touch was seen: controls get touch sizes from then on.
    pub touch_seen: bool,
    /// Where the user chose to deform the surface (the D key); `None`: where it is
    /// faster for the adapter ([`DeformOn::preferred`]).
    pub deform_on: Option<DeformOn>,
    /// The part of the screen the panels left free on the last pass (points), where
    /// the view is centred.
    pub free_view: Option<egui::Rect>,
}

impl Hud {
    pub fn new(scene_source: String) -> Self {
        Hud {
            frame_ms: Ring::new(240),
            scene_source,
            gamepad: None,
            message: None,
            show_help: false,
            deform_on: None,
            screenshot_requested: false,
            last_screenshot: None,
            switch_to: None,
            scene_field: String::new(),
            panel_open: None,
            touch_seen: false,
            free_view: None,
        }
    }
}

/// The row of the tradeoff table that describes `n` kept modes: the largest measured
/// mode count not above `n` (a conservative error estimate), or the smallest row.
pub fn tradeoff_for(rows: &[TradeoffRow], n: u32) -> Option<&TradeoffRow> {
    rows.iter()
        .filter(|r| r.modes <= n)
        .max_by_key(|r| r.modes)
        .or_else(|| rows.iter().min_by_key(|r| r.modes))
}

/// The layout for this pass (see [`crate::layout`]), with egui's sizes set for it.
pub fn layout(ctx: &egui::Context, hud: &Hud) -> Layout {
    let screen = Screen::from_ctx(ctx, hud.touch_seen);
    let layout = Layout::for_screen(&screen);
    crate::layout::apply_style(ctx, &layout);
    layout
}

/// Draws the whole interface.
pub fn show(ctx: &egui::Context, session: &mut Session, hud: &mut Hud) {
    let layout = layout(ctx, hud);
    let mut open = hud.panel_open.unwrap_or(layout.form == Form::Drawer);
    let s = session.sample;
    let summary = if s.status() == crate::force::SampleStatus::Ok {
        format!("{:.1} N · {:.1} mm", s.magnitude_n, s.depth_mm)
    } else {
        "probe lifted".into()
    };
    let covered = crate::layout::panel(ctx, "palpa-panel", &layout, &mut open, &summary, |ui| {
        panel(ui, session, hud);
    });
    hud.panel_open = Some(open);
    hud.free_view = Some(center_view(
        ctx,
        hud,
        &[covered],
        &mut session.controls.camera,
    ));
    let top = ctx.content_rect().top() + 12.0;
    if let Some(msg) = hud.message.clone() {
        egui::Window::new("Notice")
            .anchor(egui::Align2::CENTER_TOP, [0.0, top])
            .collapsible(false)
            .resizable(false)
            .show(ctx, |ui| {
                ui.label(msg);
                if ui.button("Dismiss").clicked() {
                    hud.message = None;
                }
            });
    }
    if let Some(text) = session.controls.feedback {
        egui::Area::new(egui::Id::unique("palpa-feedback"))
            .anchor(egui::Align2::CENTER_BOTTOM, [0.0, -16.0])
            .show(ctx, |ui| {
                ui.label(
                    RichText::new(text)
                        .color(Color32::from_rgb(255, 190, 90))
                        .size(16.0),
                );
            });
    }
    if hud.show_help {
        egui::Window::new("Controls")
            .anchor(egui::Align2::RIGHT_TOP, [-12.0, top])
            .collapsible(false)
            .resizable(false)
            .open(&mut hud.show_help)
            .show(ctx, help);
    }
}

/// Centres the view (the organ, a network's landscape) in the part of the safe area
/// the panels leave free, from the next frame on: a phone's open sheet covers the
/// lower half of the screen, where the organ would otherwise sit half hidden. Returns
/// that part (points).
pub fn center_view(
    ctx: &egui::Context,
    hud: &Hud,
    covered: &[egui::Rect],
    camera: &mut crate::camera::OrbitCamera,
) -> egui::Rect {
    let screen = ctx.content_rect();
    let safe = Screen::from_ctx(ctx, hud.touch_seen).safe_rect();
    let free = covered
        .iter()
        .fold(safe, |free, &c| crate::layout::free_rect(free, c));
    let v = |p: egui::Pos2| glam::Vec2::new(p.x, p.y);
    camera.center_view_in((v(free.min), v(free.max)), (v(screen.min), v(screen.max)));
    free
}

/// The vademecum's finest surplus under the probe at the sample's depth: where it is
/// large the blend between pressed points may miss the surface goal here, however
/// shallow the press (docs/lab/tissue-measurements.md §1).
fn blend_surplus(ui: &mut egui::Ui, session: &Session) {
    use palpa_core::tissue::surplus::BLEND_SURPLUS_WARN_MM;
    let Some(eta) = session.blend_surplus_mm() else {
        return;
    };
    if eta > BLEND_SURPLUS_WARN_MM {
        ui.colored_label(
            Color32::from_rgb(230, 160, 60),
            crate::session::blend_surplus_text(eta),
        );
    } else {
        ui.label(format!(
            "blend surplus {eta:.2} mm here (warned above {BLEND_SURPLUS_WARN_MM:.1} mm)"
        ));
    }
}

/// The force–depth curve at the probe: the tissue's law (solid) and the linear law
/// (dashed), with the current press marked.
fn depth_curve(
    ui: &mut egui::Ui,
    law: &palpa_core::tissue::online::Tissue,
    s: &crate::force::ForceSample,
) {
    let c = f64::from(s.compliance_mm_per_n);
    if c.is_nan() || c <= 0.0 {
        return;
    }
    let p = s.command.point();
    // To the depth the law answers here (less than its grid where a press stopped).
    let top = law.limit_mm(&p).0;
    let n = 60;
    let nonlinear: Vec<[f64; 2]> = (0..=n)
        .map(|k| {
            let d = top * f64::from(k) / f64::from(n);
            [d, law.force_n(&p, d, c).0]
        })
        .collect();
    let linear: Vec<[f64; 2]> = vec![[0.0, 0.0], [top, top / c]];
    egui_plot::Plot::new("force-depth")
        .height(110.0)
        .allow_zoom(false)
        .allow_drag(false)
        .allow_scroll(false)
        .allow_axis_zoom_drag(false)
        .allow_double_click_reset(false)
        .allow_boxed_zoom(false)
        .x_axis_label("depth, mm")
        .y_axis_label("force, N")
        .show(ui, |plot| {
            plot.line(egui_plot::Line::new(law.law().name(), nonlinear));
            plot.line(
                egui_plot::Line::new("linear", linear)
                    .style(egui_plot::LineStyle::dashed_loose())
                    .color(Color32::from_gray(160)),
            );
            plot.points(
                egui_plot::Points::new(
                    "now",
                    vec![[f64::from(s.depth_mm), f64::from(s.magnitude_n)]],
                )
                .radius(3.0)
                .color(Color32::from_rgb(255, 200, 60)),
            );
        });
}

fn panel(ui: &mut egui::Ui, session: &mut Session, hud: &mut Hud) {
    ui.heading("Press");
    ui.horizontal(|ui| {
        ui.radio_value(
            &mut session.controls.mode,
            PressMode::Depth,
            "to a depth (drag)",
        );
        ui.radio_value(&mut session.controls.mode, PressMode::Force, "with a force");
    });
    if session.controls.mode == PressMode::Force {
        let max = session.controls.mapping.max_force_n;
        ui.add(egui::Slider::new(&mut session.controls.force_n, 0.0..=max).text("N"));
        ui.checkbox(&mut session.controls.pressing, "pressing");
    }
    let s = session.sample;
    if s.status() == crate::force::SampleStatus::Ok {
        ui.label(format!(
            "{:.2} N at {:.1} mm deep",
            s.magnitude_n, s.depth_mm
        ));
        if s.beyond_law != 0 {
            let text = match session.law.as_ref().map(|l| l.limit_mm(&s.command.point())) {
                Some((limit, why)) => crate::session::held_text(limit, why),
                None => "deeper than the force law covers: held at its last depth".to_string(),
            };
            // The trigger asked for more than the tissue gives at its limit.
            let text = if s.command.mode() == PressMode::Force {
                format!("{text} (asked {:.1} N)", s.command.target)
            } else {
                text
            };
            ui.colored_label(Color32::from_rgb(230, 160, 60), text);
        }
        if let Some(g) = session.past_goals_mm() {
            ui.colored_label(Color32::from_rgb(230, 160, 60), g.past_text(s.depth_mm));
        }
        if let Some(n) = session.unpressed_corners().filter(|&n| n > 0) {
            ui.colored_label(
                Color32::from_rgb(230, 160, 60),
                crate::session::next_to_fixed_text(n),
            );
        }
        if let Some(law) = &session.law {
            depth_curve(ui, law, &s);
        }
    } else if s.status() == crate::force::SampleStatus::Failed {
        ui.colored_label(
            Color32::from_rgb(255, 120, 90),
            "no force here: keep more modes (details)",
        );
    } else {
        ui.label("not pressing: touch or click the organ");
    }
    force_plot(ui, session);
    ui.separator();

    ui.heading("View");
    let mut on = session.colormap_mm.is_some();
    ui.checkbox(&mut on, "colour by how far the tissue moved");
    if on {
        let mut top = session.colormap_mm.unwrap_or(10.0);
        ui.add(
            egui::Slider::new(&mut top, 0.5..=40.0)
                .logarithmic(true)
                .text("mm at top"),
        );
        legend(ui, top);
        session.colormap_mm = Some(top);
    } else {
        session.colormap_mm = None;
    }
    ui.separator();

    if session.training.is_some() {
        egui::CollapsingHeader::new("Find the nodule")
            .id_salt("training")
            .default_open(true)
            .show(ui, |ui| training(ui, session, hud));
        ui.separator();
    }

    egui::CollapsingHeader::new("Details")
        .id_salt("details")
        .show(ui, |ui| details(ui, session, hud));
    ui.collapsing("Scene", |ui| {
        scene_switcher(ui, hud);
        let m = session.scene.model();
        ui.label(&hud.scene_source);
        ui.label(format!(
            "{} surface vertices, {} triangles, {} modes ({})",
            session.scene.vertices_mm().len(),
            session.scene.triangles().len(),
            m.modes(),
            m.precision().name()
        ));
        let desc = &m.provenance().mesh;
        let get = |k| palpa_core::pgd::palpation::describe_get(desc, k).unwrap_or("?");
        ui.label(format!(
            "linear vademecum: E = {} kPa, ν = {}; tool radius {} mm; {} elements",
            get("young_kpa"),
            get("poisson"),
            get("radius_mm"),
            get("element")
        ));
    });
    ui.collapsing("Regions", |ui| regions(ui, session, hud));
    ui.horizontal(|ui| {
        if ui.button("Screenshot").clicked() {
            hud.screenshot_requested = true;
        }
        if ui.button("Help (H)").clicked() {
            hud.show_help = !hud.show_help;
        }
    });
    if let Some(p) = &hud.last_screenshot {
        ui.label(format!("saved {p}"));
    }
}

/// The training mode: hide a nodule, palpate, mark, reveal, score; the trainer's map
/// and own nodule.
fn training(ui: &mut egui::Ui, session: &mut Session, hud: &mut Hud) {
    let now = session.now_s();
    let probe = session.controls.probe;
    let mut mark = false;
    let Some(t) = session.training.as_mut() else {
        return;
    };
    let hidden = t.trial.as_ref().is_some_and(|_| !t.revealed);
    if t.trial.is_none() {
        let (lo, hi) = t.table().box_mm();
        ui.label(format!(
            "a stiff nodule hidden in the region from ({:.0}, {:.0}, {:.0}) to ({:.0}, {:.0}, {:.0}) mm: find it by touch",
            lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
        ));
    }
    if session.law.is_some() {
        ui.small(if t.amplifies() {
            "the linear tissue's effect, amplified as the tissue's own press loads the nodule"
        } else {
            "the linear tissue's effect as it is: the table holds no power of this tissue (palpa nodule tissue)"
        });
    }
    ui.horizontal(|ui| {
        if ui.button("Hide a nodule").clicked()
            && let Err(e) = t.hide(None, now)
        {
            hud.message = Some(format!("{e:#}"));
        }
        ui.label("seed");
        ui.add(egui::DragValue::new(&mut t.next_seed));
    });
    if let Some(trial) = &t.trial {
        if hidden {
            ui.label(format!(
                "hidden: palpate, then Mark where you feel it (gamepad: A). {:.0} s, largest force {:.1} N",
                now - trial.started_s(),
                trial.largest_force_n()
            ));
            ui.horizontal(|ui| {
                mark = ui
                    .add_enabled(probe.is_some(), egui::Button::new("Mark here"))
                    .clicked();
                if ui.button("Reveal").clicked() {
                    t.reveal();
                }
            });
        } else {
            let n = trial.case.nodule();
            ui.label(format!(
                "the nodule: radius {:.1} mm, {:.1} times stiffer, centre {:.1} mm under the surface",
                n.radius_mm, n.ratio, trial.case.depth_mm
            ));
            match trial.score() {
                Some(s) => ui.label(format!(
                    "your mark: {:.1} mm from it, after {:.0} s, largest force {:.1} N",
                    s.distance_mm, s.time_s, s.largest_force_n
                )),
                None => ui.label("revealed without a mark"),
            };
            if t.scores.len() > 1 {
                let mut d: Vec<f64> = t.scores.iter().map(|s| s.distance_mm).collect();
                d.sort_by(f64::total_cmp);
                ui.label(format!(
                    "this session: {} marks, median {:.1} mm from the nodule",
                    d.len(),
                    d[d.len() / 2]
                ));
            }
        }
    }
    ui.collapsing("Trainer", |ui| {
        ui.checkbox(
            &mut t.map,
            "stiffness map (force with / without the nodule)",
        );
        if t.map && t.trial.is_some() {
            let top = t.peak_ratio();
            ui.horizontal(|ui| {
                ui.label("1.00");
                for i in 0..8 {
                    ui.colored_label(ramp(i as f32 / 7.0), "■");
                }
                ui.label(format!("{top:.2}"));
            });
        }
        let [rlo, rhi] = t.table().radius_range_mm();
        // Drawn from: each bound within the table's range and the other bound.
        let [lo, hi] = t.ranges.ratio;
        let r = &mut t.ranges;
        ui.add(egui::Slider::new(&mut r.ratio[0], 1.0..=hi).text("drawn: ratio from"));
        ui.add(
            egui::Slider::new(&mut r.ratio[1], lo..=MAX_RATIO)
                .logarithmic(true)
                .text("ratio to"),
        );
        let [lo, hi] = r.radius_mm;
        ui.add(egui::Slider::new(&mut r.radius_mm[0], rlo..=hi).text("radius from (mm)"));
        ui.add(egui::Slider::new(&mut r.radius_mm[1], lo..=rhi).text("radius to (mm)"));
        ui.label("or hide one under the probe:");
        ui.add(egui::Slider::new(&mut t.own.depth_mm, 2.0..=40.0).text("centre depth (mm)"));
        ui.add(egui::Slider::new(&mut t.own.radius_mm, rlo..=rhi).text("radius (mm)"));
        ui.add(
            egui::Slider::new(&mut t.own.ratio, 1.0..=MAX_RATIO)
                .logarithmic(true)
                .text("times stiffer"),
        );
        if ui
            .add_enabled(probe.is_some(), egui::Button::new("Hide under the probe"))
            .clicked()
            && let Some(p) = probe
        {
            let (x, n) = session.scene.frame(&p);
            let d = t.own.depth_mm;
            let nodule = palpa_core::fe::nodule::Nodule {
                center_mm: [0, 1, 2].map(|i| x[i] - d * n[i]),
                radius_mm: t.own.radius_mm,
                ratio: t.own.ratio,
            };
            if let Err(e) = t.set(&nodule, now) {
                hud.message = Some(format!("{e:#}"));
            }
        }
    });
    if mark && let Err(e) = session.mark() {
        hud.message = Some(format!("{e:#}"));
    }
}

/// What the panel folds away: the model's knobs, its measured accuracy, where each
/// figure was measured, the tissue's make-up and this device's loops.
fn details(ui: &mut egui::Ui, session: &mut Session, hud: &Hud) {
    let n_all = session.scene.modes() as u32;
    ui.add(
        egui::Slider::new(&mut session.controls.modes, 1..=n_all)
            .text("modes kept (fewer: faster, coarser)"),
    );
    ui.label("Measured when the scene was built, at points it never saw:");
    match tradeoff_for(session.scene.tradeoff(), session.controls.modes) {
        Some(r) => {
            match (r.compliance_rel_error, r.surface_max_nodal_error_mm) {
                (Some(c), Some(mm)) => ui.label(format!(
                    "linear model, {} modes: surface within {:.1} % (at most {:.2} mm per N), \
                     force within {:.1} %",
                    r.modes,
                    100.0 * r.surface_rel_error,
                    mm,
                    100.0 * c
                )),
                _ => ui.label(format!(
                    "linear model, {} modes: surface within {:.1} %, probe within {:.1} %",
                    r.modes,
                    100.0 * r.surface_rel_error,
                    100.0 * r.probe_rel_error
                )),
            };
            ui.label(format!(
                "on the machine that built it: surface {:.0} µs, force {:.0} ns a step",
                r.surface_eval_us, r.contact_eval_ns
            ));
        }
        None => {
            ui.label("this file has no accuracy table (palpa tradeoff FILE measures it)");
        }
    }
    if let Some(law) = &session.law {
        ui.label(crate::session::tissue_accuracy_text(session.goals_to_mm));
        ui.label(format!(
            "tissue: {} (E {:.0} kPa, ν {}), pressed to {:.0} mm at {} points",
            law.law().name(),
            law.material().young_kpa,
            law.material().poisson,
            law.depth_max_mm(),
            law.samples()
        ));
    } else {
        ui.label("tissue: linear elastic (force proportional to depth)");
    }
    let s = session.sample;
    if s.status() == crate::force::SampleStatus::Ok {
        ui.label(format!(
            "compliance here {:.3} mm per N",
            s.compliance_mm_per_n
        ));
        if session.law.is_some() {
            blend_surplus(ui, session);
        }
    }
    ui.label("Measured on this device:");
    let st = session.force.stats();
    ui.label(format!(
        "frame {:.1} ms (p95 {:.1}) · surface {:.1} µs{}",
        hud.frame_ms.quantile(0.5),
        hud.frame_ms.quantile(0.95),
        session.render_eval_us.quantile(0.5),
        match session.deform_on {
            DeformOn::Gpu => "",
            DeformOn::Cpu => " (on the CPU)",
        }
    ));
    ui.label(format!(
        "force loop {:.1} Hz · p99 period {:.0} µs · missed {} · force {:.2} µs a step ({})",
        st.rate_hz,
        st.period_us_p99,
        st.missed_deadlines,
        st.eval_us_p50,
        st.priority().name()
    ));
    ui.label(match &hud.gamepad {
        Some(name) => format!("gamepad: {name}"),
        None => "gamepad: none found".into(),
    });
}

/// Where a scene's painted regions are saved: `X.regions.toml` beside a scene file
/// `X.palpa`, or `NAME.regions.toml` in the working folder for a built-in scene.
pub fn regions_path(scene_source: &str) -> std::path::PathBuf {
    // A built-in scene's source reads "built-in NAME (…)", not a path.
    if let Some(rest) = scene_source.strip_prefix("built-in ") {
        let name = rest.split_whitespace().next().unwrap_or("scene");
        return format!("{name}.regions.toml").into();
    }
    let p = std::path::Path::new(scene_source);
    let stem = p
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy());
    p.with_file_name(format!("{stem}.regions.toml"))
}

/// The region painter: brush, radius, undo, save, and the warning when the regions
/// would leave the organ free to move.
fn regions(ui: &mut egui::Ui, session: &mut Session, hud: &mut Hud) {
    use crate::session::paint::Label;
    let mut on = session.painter.is_some();
    ui.checkbox(
        &mut on,
        "paint regions (left-drag on the organ paints, off it orbits)",
    );
    session.set_painting(on);
    let Some(p) = session.painter.as_mut() else {
        return;
    };
    ui.horizontal(|ui| {
        ui.radio_value(&mut p.brush, Label::Fixed, "fixed");
        ui.radio_value(&mut p.brush, Label::Palpable, "palpable");
        ui.radio_value(&mut p.brush, Label::Neither, "neither");
    });
    ui.add(egui::Slider::new(&mut p.radius_mm, 1.0..=40.0).text("brush radius (mm)"));
    let (fixed, palpable) = p.counts();
    ui.label(format!("{fixed} triangles fixed, {palpable} palpable"));
    if let Some(w) = p.warning() {
        ui.colored_label(Color32::from_rgb(230, 170, 60), w);
    }
    let path = regions_path(&hud.scene_source);
    ui.horizontal(|ui| {
        if ui
            .add_enabled(p.can_undo(), egui::Button::new("Undo"))
            .clicked()
        {
            p.undo();
        }
        if ui
            .button("Save")
            .on_hover_text(path.display().to_string())
            .clicked()
        {
            hud.message = Some(match p.region_file(&hud.scene_source) {
                Ok(file) => match file.save(&path) {
                    Ok(()) => format!(
                        "regions saved to {} (palpa scene build --regions reads it)",
                        path.display()
                    ),
                    Err(e) => format!("regions not saved: {e}"),
                },
                Err(why) => format!("regions not saved: {why}"),
            });
        }
    });
}

fn force_plot(ui: &mut egui::Ui, session: &Session) {
    let h = &session.force_history;
    let now = h.x.last().unwrap_or(0.0);
    let points: Vec<[f64; 2]> =
        h.x.iter()
            .zip(h.y.iter())
            .filter(|(t, _)| now - t <= 10.0)
            .map(|(t, f)| [t - now, f])
            .collect();
    egui_plot::Plot::new("force")
        .height(90.0)
        .include_y(0.0)
        .include_y(1.0)
        .allow_zoom(false)
        .allow_drag(false)
        .allow_scroll(false)
        .allow_axis_zoom_drag(false)
        .allow_double_click_reset(false)
        .allow_boxed_zoom(false)
        // A plot without units reads as a second force-depth curve. The time axis
        // (seconds before now) stays unlabelled: a label's line would push the last
        // controls of a tablet's panel under the 48-point touch size.
        .y_axis_label("|F|, N")
        .show(ui, |plot| {
            plot.line(egui_plot::Line::new("|F| (N) over the last 10 s", points));
        });
}

/// Buttons for the built-in scenes and a field for a file (a palpation or network
/// `.palpa`, a network `.toml`): the window switches after the frame.
pub fn scene_switcher(ui: &mut egui::Ui, hud: &mut Hud) {
    ui.horizontal(|ui| {
        ui.label("open");
        for name in ["liver", "toggle", "cascade"] {
            if ui.button(name).clicked() {
                hud.switch_to = Some(name.into());
            }
        }
    });
    ui.horizontal(|ui| {
        let field = ui.add(
            egui::TextEdit::singleline(&mut hud.scene_field)
                .hint_text("file.palpa or network.toml")
                .desired_width(190.0),
        );
        let enter = field.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
        if (ui.button("open").clicked() || enter) && !hud.scene_field.trim().is_empty() {
            hud.switch_to = Some(hud.scene_field.trim().to_string());
        }
    });
}

/// The colormap's legend: the ramp of `surface.wgsl` with its end values.
fn legend(ui: &mut egui::Ui, top_mm: f32) {
    let (rect, _) = ui.allocate_exact_size(egui::vec2(240.0, 14.0), egui::Sense::hover());
    let steps = 48;
    for i in 0..steps {
        let t0 = i as f32 / steps as f32;
        let x0 = rect.left() + rect.width() * t0;
        let x1 = rect.left() + rect.width() * (i + 1) as f32 / steps as f32;
        let r = egui::Rect::from_min_max(egui::pos2(x0, rect.top()), egui::pos2(x1, rect.bottom()));
        ui.painter()
            .rect_filled(r, 0.0, ramp(t0 + 0.5 / steps as f32));
    }
    ui.horizontal(|ui| {
        ui.label("0 mm");
        ui.add_space(150.0);
        ui.label(format!("{top_mm:.1} mm"));
    });
}

/// The same ramp as `shaders/surface.wgsl` (linear values, shown through sRGB).
pub fn ramp(t: f32) -> Color32 {
    let x = t.clamp(0.0, 1.0);
    let c = |k: f32| (1.5 - (4.0 * x - k).abs()).clamp(0.0, 1.0);
    egui::Rgba::from_rgb(c(3.0), c(2.0), c(1.0)).into()
}

fn help(ui: &mut egui::Ui) {
    egui::Grid::new("help").striped(true).show(ui, |ui| {
        for (what, how) in [
            (
                "Press (mouse)",
                "left-press on the lighter, palpable surface; drag down to indent",
            ),
            (
                "Press (touch)",
                "rest a finger on the surface for ¼ s, then drag down",
            ),
            ("Press (gamepad)", "right trigger (force-controlled)"),
            ("Move the probe (gamepad)", "left stick"),
            (
                "Orbit",
                "left-drag off the organ · one-finger swipe · right stick",
            ),
            ("Pan", "right- or middle-drag · two-finger drag"),
            ("Zoom", "wheel · pinch"),
            ("Colormap", "C"),
            ("Deform the surface on the CPU / the GPU", "D"),
            (
                "Paint regions",
                "Regions ▸ paint: left-drag marks fixed / palpable / neither; Save writes X.regions.toml for palpa scene build --regions",
            ),
            (
                "Find the nodule",
                "Hide a nodule, palpate, then Mark here (gamepad: A); Reveal gives up; Trainer ▸ the stiffness map",
            ),
            ("Help", "H or F1"),
        ] {
            ui.label(what);
            ui.label(how);
            ui.end_row();
        }
    });
}

#[cfg(test)]
mod tests {
    use super::regions_path;

    #[test]
    fn regions_are_saved_beside_a_scene_file_or_in_the_working_folder() {
        assert_eq!(
            regions_path("organs/kidney.palpa"),
            std::path::Path::new("organs/kidney.regions.toml")
        );
        let built_in = "built-in liver (assets/liver-coarse.palpa, tissue assets/x.tissue)";
        assert_eq!(
            regions_path(built_in),
            std::path::Path::new("liver.regions.toml")
        );
    }
}
