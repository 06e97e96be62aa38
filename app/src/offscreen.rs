//! Headless mode: K frames rendered offscreen with a scripted probe pressing the organ
//! while the force thread runs, the last frame saved as PNG, timings reported as JSON.
//!
//! Frames are paced at `fps` (as a window's vsync paces them; 0 renders back to back,
//! the worst case for the force thread, which shares the CPU with the software
//! rasterizer). A frame's time runs from taking the input to the GPU finishing it. The script runs on its own clock, 25 frames per
//! scripted second, so the images do not depend on the machine's speed; before the last
//! frame the session waits until the force loop has answered the last command.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::force::NoHaptics;
use crate::input::PressMode;
use crate::overlay::{Overlay, headless_input};
use crate::render::Renderer;
use crate::render::gpu::{AdapterReport, Gpu};
use crate::render::offscreen::{FORMAT, Image, Offscreen};
use crate::session::Session;
use crate::stats::percentile;
use crate::ui::Hud;

/// One keyframe of a probe path: at scripted time `t_s`, the probe is at the palpable
/// point nearest `at_mm`, indenting `depth_mm`. Linear in between.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Keyframe {
    pub t_s: f64,
    pub at_mm: [f64; 3],
    pub depth_mm: f64,
}

/// A probe path (`--probe-path FILE`: JSON `{"keyframes": [...]}`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProbePath {
    pub keyframes: Vec<Keyframe>,
}

impl ProbePath {
    /// Over the front of the organ: press, slide sideways while pressing, lift.
    pub fn default_for(center_mm: Vec3, front_mm: Vec3) -> Self {
        let c = front_mm.as_dvec3();
        let side = (front_mm - center_mm)
            .cross(Vec3::Z)
            .normalize_or(Vec3::X)
            .as_dvec3()
            * 35.0;
        let at = |s: f64| (c + side * s).to_array();
        let k = |t_s, s, depth_mm| Keyframe {
            t_s,
            at_mm: at(s),
            depth_mm,
        };
        ProbePath {
            keyframes: vec![
                k(0.0, -1.0, 0.0),
                k(1.5, -1.0, 8.0),
                k(4.0, 0.0, 10.0),
                k(6.5, 1.0, 6.0),
                k(8.0, 1.0, 0.0),
                k(10.0, 0.0, 8.0),
            ],
        }
    }

    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        Self::from_json(&text).with_context(|| format!("{}", path.display()))
    }

    /// Parses and checks a probe path's JSON.
    pub fn from_json(text: &str) -> anyhow::Result<Self> {
        let p: ProbePath = serde_json::from_str(text).context(
            "expected {\"keyframes\": [{\"t_s\": 0, \"at_mm\": [x, y, z], \"depth_mm\": 5}, ...]}",
        )?;
        p.validate()?;
        Ok(p)
    }

    fn validate(&self) -> anyhow::Result<()> {
        if self.keyframes.is_empty() {
            bail!("a probe path needs at least one keyframe");
        }
        for (i, k) in self.keyframes.iter().enumerate() {
            if !(k.t_s.is_finite()
                && k.depth_mm.is_finite()
                && k.at_mm.iter().all(|c| c.is_finite()))
            {
                bail!("keyframe {i} has a non-finite value");
            }
            if !k.at_mm.iter().all(|&c| crate::pick::coordinate_ok(c)) {
                bail!(
                    "keyframe {i}: at_mm = {:?} (expected coordinates within ±{:e} mm)",
                    k.at_mm,
                    crate::pick::COORDINATE_MAX
                );
            }
            if k.depth_mm < 0.0 {
                bail!("keyframe {i}: depth_mm = {} (expected ≥ 0)", k.depth_mm);
            }
            if i > 0 && k.t_s <= self.keyframes[i - 1].t_s {
                bail!("keyframe {i}: t_s = {} does not increase", k.t_s);
            }
        }
        Ok(())
    }

    /// Position and depth at scripted time `t_s` (held constant past the ends).
    pub fn at(&self, t_s: f64) -> ([f64; 3], f64) {
        let ks = &self.keyframes;
        let last = ks[ks.len() - 1];
        if t_s <= ks[0].t_s {
            return (ks[0].at_mm, ks[0].depth_mm);
        }
        if t_s >= last.t_s {
            return (last.at_mm, last.depth_mm);
        }
        let i = ks.iter().position(|k| k.t_s > t_s).unwrap_or(ks.len() - 1);
        let (a, b) = (ks[i - 1], ks[i]);
        let w = (t_s - a.t_s) / (b.t_s - a.t_s);
        let lerp = |x: f64, y: f64| x + w * (y - x);
        (
            [0, 1, 2].map(|c| lerp(a.at_mm[c], b.at_mm[c])),
            lerp(a.depth_mm, b.depth_mm),
        )
    }
}

/// What `palpa headless` was asked to do.
#[derive(Debug, Clone)]
pub struct HeadlessOptions {
    pub scene: String,
    pub frames: u32,
    pub size: (u32, u32),
    pub probe_path: Option<PathBuf>,
    pub out: Option<PathBuf>,
    pub modes: Option<u32>,
    pub colormap_mm: Option<f32>,
    /// Where the surface is deformed (`None`: where it is faster for the adapter).
    pub deform_on: Option<crate::render::deform::DeformOn>,
    /// Frame pacing (frames per second); 0: back to back.
    pub fps: f64,
    /// Draw the egui interface over the scene.
    pub ui: bool,
    /// Density, safe area and panel state of the interface.
    pub display: crate::layout::Display,
    /// Find the nodule: a nodule hidden before the first frame (the scene needs a
    /// nodule table).
    pub nodule: Option<HiddenNodule>,
    /// Mark the nodule where the probe is at the last frame (it is then drawn, and the
    /// report scores the mark).
    pub mark: bool,
    /// The trainer's stiffness map on the surface.
    pub stiffness_map: bool,
}

/// The nodule a headless run hides.
#[derive(Debug, Clone, Copy)]
pub enum HiddenNodule {
    /// A trainer's own.
    At(palpa_core::fe::nodule::Nodule),
    /// Drawn from the table's ranges with this seed.
    Seed(u64),
}

/// The hidden nodule, the force with and without it along the probe path, and the
/// score of a mark.
#[derive(Debug, Clone, Serialize)]
pub struct NoduleReport {
    pub center_mm: [f64; 3],
    pub radius_mm: f64,
    pub ratio: f64,
    /// The seed it was drawn with (`None`: given).
    pub seed: Option<u64>,
    /// From the surface's closest palpable point to the centre (mm).
    pub depth_mm: f64,
    /// The largest `F_with/F_without − 1` on the palpable surface.
    pub peak_effect: f64,
    /// Every pressed frame.
    pub path: Vec<PathForce>,
    pub score: Option<palpa_core::pgd::nodule::training::Score>,
}

/// One pressed frame of the probe path.
#[derive(Debug, Clone, Serialize)]
pub struct PathForce {
    pub t_s: f64,
    pub point_mm: [f32; 3],
    pub depth_mm: f32,
    pub force_n: f32,
    pub force_without_nodule_n: f32,
}

/// The JSON report.
#[derive(Debug, Clone, Serialize)]
pub struct HeadlessReport {
    pub frames: u32,
    pub size: [u32; 2],
    pub fps: f64,
    pub scene: String,
    pub modes_used: u32,
    /// Where the surface was deformed: `gpu` (compute shader) or `cpu`.
    pub deform: &'static str,
    pub frame_ms_p50: f64,
    pub frame_ms_p95: f64,
    pub frame_ms_max: f64,
    /// Contact evaluation on the force thread, µs (median).
    pub eval_us_p50: f64,
    /// Render-side evaluation per frame (particularization + contact rows), µs.
    pub render_eval_us_p50: f64,
    pub force_hz: f64,
    pub force_ticks: u64,
    pub force_period_us_p50: f64,
    pub force_period_us_p99: f64,
    pub force_period_us_max: f64,
    pub missed_deadlines: u64,
    /// Scheduling the force thread got: realtime, raised or normal.
    pub force_priority: &'static str,
    pub final_force_n: f32,
    pub final_depth_mm: f32,
    /// The linear tissue's force at the final depth (equal to `final_force_n` without a
    /// force law).
    pub final_linear_force_n: f32,
    /// The final depth asked lay past what the tissue answers at that point: depth and
    /// force are held at its limit (as the panel and `palpa eval` flag it).
    pub final_beyond_range: bool,
    /// `linear elastic`, or the force law's material.
    pub tissue: String,
    /// Resident memory after the warm-up (a tenth of the frames, at least 5) and at
    /// the end, MB (Linux; absent elsewhere): a long run should stay flat.
    pub rss_mb_after_warmup: Option<f64>,
    pub rss_mb_end: Option<f64>,
    /// Per tenth of the run (runs of 100 frames or more): what would drift in a long
    /// session, so a soak run shows it flat or not.
    pub tenths: Vec<Tenth>,
    pub adapter: AdapterReport,
    pub out: Option<String>,
    /// The interface's layout in the last frame (with the interface on).
    pub layout: Option<crate::layout::LayoutReport>,
    /// Where the last frame showed the probe and the palpable surface, against the
    /// part of the screen the panels leave free (with the interface on).
    pub view: Option<ViewReport>,
    /// With a hidden nodule.
    pub nodule: Option<NoduleReport>,
}

/// What the last frame showed of the probe and the palpable surface (pixels).
#[derive(Debug, Clone, Serialize)]
pub struct ViewReport {
    /// The part of the screen no panel covers: `[left, top, right, bottom]`.
    pub free_px: [f32; 4],
    /// The probe's ball (its centre), where it was drawn.
    pub probe_px: Option<[f32; 2]>,
    pub probe_in_free_view: Option<bool>,
    /// The share of the palpable surface's vertices (at rest) inside the free part.
    pub palpable_in_free_view: f32,
}

fn view_report(
    session: &Session,
    free_pt: egui::Rect,
    ppp: f32,
    size: (u32, u32),
    probe: Option<crate::render::ProbeVisual>,
) -> ViewReport {
    let free = free_pt * ppp;
    let size_px = glam::Vec2::new(size.0 as f32, size.1 as f32);
    let cam = session.controls.camera;
    let inside = |p: Vec3| {
        cam.project(p, size_px)
            .is_some_and(|q| free.contains(egui::pos2(q.x, q.y)))
    };
    let ball = probe.map(|p| p.tip_mm + p.outward.normalize_or(Vec3::Z) * p.radius_mm);
    let palpable = session.scene.palpable_vertices();
    let rest = session.scene.vertices_mm();
    let (seen, all) = rest
        .iter()
        .zip(&palpable)
        .filter(|(_, p)| **p)
        .fold((0usize, 0usize), |(s, a), (v, _)| {
            (s + usize::from(inside(Vec3::from(*v))), a + 1)
        });
    ViewReport {
        free_px: [free.left(), free.top(), free.right(), free.bottom()],
        probe_px: ball
            .and_then(|b| cam.project(b, size_px))
            .map(|q| [q.x, q.y]),
        probe_in_free_view: ball.map(inside),
        palpable_in_free_view: seen as f32 / all.max(1) as f32,
    }
}

/// One tenth of a headless run.
#[derive(Debug, Clone, Serialize)]
pub struct Tenth {
    pub frame_ms_p50: f64,
    pub frame_ms_p95: f64,
    /// The force loop's missed deadlines so far (counted from the warm-up's end).
    pub missed_deadlines: u64,
    pub rss_mb: Option<f64>,
}

/// Checks a headless run's frame size and count (either scene).
pub fn check_frames(size: (u32, u32), frames: u32) -> anyhow::Result<()> {
    let (w, h) = size;
    if w == 0 || h == 0 || w > 8192 || h > 8192 {
        bail!("--size {w}x{h}: expected width and height in 1..=8192");
    }
    if frames == 0 {
        bail!("--frames 0: expected at least one frame");
    }
    Ok(())
}

/// Renders the frames and returns the report and the last image.
pub fn run(opts: &HeadlessOptions) -> anyhow::Result<(HeadlessReport, Image)> {
    check_frames(opts.size, opts.frames)?;
    let (w, h) = opts.size;
    let loaded = crate::scenes::load(&opts.scene)?;
    let loaded_source = loaded.source.clone();
    let gpu = Gpu::headless()?;
    let mut renderer = Renderer::new(&gpu.device, FORMAT, &loaded.scene);
    let mut session = loaded.session(Box::new(NoHaptics))?;
    if let Some(hidden) = opts.nodule {
        let Some(t) = session.training.as_mut() else {
            bail!(
                "{}: no nodule table beside the scene to hide a nodule in (`palpa nodule build … --out X.nodules` beside X.palpa)",
                opts.scene
            );
        };
        match hidden {
            HiddenNodule::At(n) => t.set(&n, 0.0)?,
            HiddenNodule::Seed(s) => t.hide(Some(s), 0.0)?,
        }
        t.map = opts.stiffness_map;
    } else if opts.mark || opts.stiffness_map {
        bail!(
            "--mark and --stiffness-map need a hidden nodule: give --nodule-at X,Y,Z or --nodule-seed N"
        );
    }
    let mut path_forces = Vec::new();
    if let Some(n) = opts.modes {
        session.controls.modes = n.clamp(1, session.scene.modes() as u32);
    }
    session.colormap_mm = opts.colormap_mm;
    session.deform_on = opts
        .deform_on
        .unwrap_or_else(|| crate::render::deform::DeformOn::preferred(gpu.is_software()));
    let (min, max) = renderer.bounds();
    let cam = session.controls.camera;
    let front = session.controls.probe.map_or(cam.target_mm, |p| {
        let (x, _) = session.scene.frame(&p);
        Vec3::new(x[0] as f32, x[1] as f32, x[2] as f32)
    });
    let path = match &opts.probe_path {
        Some(p) => ProbePath::load(p)?,
        None => ProbePath::default_for(0.5 * (min + max), front),
    };
    let target = Offscreen::new(&gpu.device, opts.size, gpu.can_reinterpret());
    let mut overlay = opts
        .ui
        .then(|| Overlay::new(&gpu.device, target.ui_format, gpu.is_software()));
    let mut hud = Hud::new(loaded_source);
    hud.panel_open = opts.display.panel_open;
    session.controls.mode = PressMode::Depth;

    let mut frame_ms = Vec::with_capacity(opts.frames as usize);
    let mut tenth_ms: Vec<f64> = Vec::with_capacity(opts.frames as usize / 10 + 1);
    let mut tenths: Vec<Tenth> = Vec::with_capacity(10);
    let warmup = opts.frames.min(5);
    let memory_warmup = (opts.frames / 10).max(5).min(opts.frames - 1);
    let mut rss_after_warmup = None;
    let pace = (opts.fps > 0.0).then(|| Duration::from_secs_f64(1.0 / opts.fps));
    let start = Instant::now();
    let mut last_probe = None;
    for i in 0..opts.frames {
        if let Some(p) = pace {
            let due = start + p * i;
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        let (at, depth) = path.at(f64::from(i) / 25.0);
        if let Some((p, _)) = session.scene.closest_palpable(at) {
            session.controls.probe = Some(p);
        }
        session.controls.pressing = depth > 0.0;
        session.controls.depth_mm = depth as f32;
        let last = i + 1 == opts.frames;
        if last {
            session.force.command(session.command());
            settle(&session, Duration::from_millis(500));
        }
        if last && opts.mark {
            session.mark()?;
        }
        if i == warmup {
            session.force.reset_stats();
        }
        if i == memory_warmup {
            rss_after_warmup = crate::stats::resident_bytes();
        }
        let t0 = Instant::now();
        let input = session.frame();
        last_probe = input.probe;

        let mut encoder = renderer.encode_frame(&gpu, &target.view, opts.size, &input);
        if let Some(o) = overlay.as_mut() {
            let raw = headless_input(
                opts.size,
                opts.display.pixels_per_point,
                opts.display.insets,
                f64::from(i) / 25.0,
            );
            o.paint(
                &gpu.device,
                &gpu.queue,
                &mut encoder,
                &target.ui_view,
                opts.size,
                opts.display.pixels_per_point,
                raw,
                |ctx| crate::ui::show(ctx, &mut session, &mut hud),
            );
        }
        if last {
            target.encode_copy(&mut encoder);
        }
        gpu.submit_and_wait(encoder)?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let s = session.sample;
        if session.training.is_some() && s.status() == crate::force::SampleStatus::Ok {
            path_forces.push(PathForce {
                t_s: f64::from(i) / 25.0,
                point_mm: s.point_mm,
                depth_mm: s.depth_mm,
                force_n: s.magnitude_n,
                force_without_nodule_n: s.magnitude_n / s.nodule_gain,
            });
        }
        hud.frame_ms.push(ms);
        if i >= warmup || opts.frames <= warmup {
            frame_ms.push(ms);
        }
        tenth_ms.push(ms);
        if opts.frames >= 100 && (i + 1) % (opts.frames / 10) == 0 && tenths.len() < 10 {
            tenths.push(Tenth {
                frame_ms_p50: percentile(tenth_ms.clone(), 0.5),
                frame_ms_p95: percentile(std::mem::take(&mut tenth_ms), 0.95),
                missed_deadlines: session.force.stats().missed_deadlines,
                rss_mb: crate::stats::resident_bytes().map(|b| b as f64 / 1e6),
            });
        }
    }
    let image = target.read(&gpu.device)?;
    if let Some(out) = &opts.out {
        image.save_png(out)?;
    }
    // The force thread publishes its statistics every 50 ticks (50 ms): a run of a
    // frame or two ends before the first, and would report a loop at 0 Hz. Wait for
    // it (the loop keeps running meanwhile), at most a second.
    let waited = Instant::now();
    while session.force.stats().ticks == 0 && waited.elapsed().as_secs_f64() < 1.0 {
        std::thread::sleep(Duration::from_millis(5));
    }
    let stats = session.force.stats();
    let report = HeadlessReport {
        frames: opts.frames,
        size: [w, h],
        fps: opts.fps,
        scene: opts.scene.clone(),
        modes_used: session.controls.modes,
        deform: session.deform_on.name(),
        frame_ms_p50: percentile(frame_ms.clone(), 0.5),
        frame_ms_p95: percentile(frame_ms.clone(), 0.95),
        frame_ms_max: percentile(frame_ms, 1.0),
        eval_us_p50: stats.eval_us_p50,
        render_eval_us_p50: session.render_eval_us.quantile(0.5),
        force_hz: stats.rate_hz,
        force_ticks: stats.ticks,
        force_period_us_p50: stats.period_us_p50,
        force_period_us_p99: stats.period_us_p99,
        force_period_us_max: stats.period_us_max,
        missed_deadlines: stats.missed_deadlines,
        force_priority: stats.priority().name(),
        final_force_n: session.sample.magnitude_n,
        final_depth_mm: session.sample.depth_mm,
        final_linear_force_n: session.sample.linear_n,
        final_beyond_range: session.sample.beyond_law != 0,
        tissue: session.law.as_ref().map_or_else(
            || "linear elastic".to_string(),
            |l| format!("{} vademecum", l.law().name()),
        ),
        rss_mb_after_warmup: rss_after_warmup.map(|b| b as f64 / 1e6),
        rss_mb_end: crate::stats::resident_bytes().map(|b| b as f64 / 1e6),
        tenths,
        adapter: gpu.report(),
        out: opts.out.as_ref().map(|p| p.display().to_string()),
        layout: overlay.as_ref().map(|o| {
            crate::layout::report(&o.ctx, hud.touch_seen, hud.panel_open.unwrap_or(false))
        }),
        view: hud.free_view.map(|free| {
            view_report(
                &session,
                free,
                opts.display.pixels_per_point,
                opts.size,
                last_probe,
            )
        }),
        nodule: session
            .training
            .as_ref()
            .and_then(|t| t.trial.as_ref())
            .map(|t| NoduleReport {
                center_mm: t.case.nodule().center_mm,
                radius_mm: t.case.nodule().radius_mm,
                ratio: t.case.nodule().ratio,
                seed: t.case.seed,
                depth_mm: t.case.depth_mm,
                peak_effect: t.case.peak_effect,
                path: path_forces,
                score: t.score(),
            }),
    };
    Ok((report, image))
}

/// Waits (up to `timeout`) until the force loop has answered the latest command.
pub fn settle(session: &Session, timeout: Duration) {
    let want = session.command();
    let t0 = Instant::now();
    while session.force.latest().command != want && t0.elapsed() < timeout {
        std::thread::sleep(Duration::from_micros(200));
    }
}
