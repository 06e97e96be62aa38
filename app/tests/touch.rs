//! The touch-first layouts, rendered headless on the software adapter: a phone upright
//! (1080 × 2340 px at 3×, a notch and a home indicator) and a tablet on its side
//! (2048 × 1536 px at 2×), in the liver and the network scenes, with the panel
//! unfolded and folded. Every control on the screen is checked from egui's own
//! layout (its widget rectangles) against the 48-point minimum; the view keeps most of
//! the screen; the smallest supported screen, one below it, a 4K desktop and each
//! density behave as documented; and two snapshots guard the view beside the panel.

use crate::common;

use std::path::{Path, PathBuf};

use palpa_app::layout::{Display, Insets, LayoutReport};
use palpa_app::render::offscreen::Image;

const PHONE: (u32, u32) = (1080, 2340);
const TABLET: (u32, u32) = (2048, 1536);
const NOTCH: Insets = Insets {
    top: 47.0,
    right: 0.0,
    bottom: 34.0,
    left: 0.0,
};

fn display(ppp: f32, insets: Insets, open: Option<bool>) -> Display {
    Display {
        pixels_per_point: ppp,
        insets,
        panel_open: open,
    }
}

fn liver(size: (u32, u32), d: Display) -> (LayoutReport, Image) {
    let (report, image) = liver_pressed(size, d, None);
    (report.layout.expect("a layout report"), image)
}

/// The liver's frames along a probe path (`None`: the default one).
fn liver_pressed(
    size: (u32, u32),
    d: Display,
    probe_path: Option<PathBuf>,
) -> (palpa_app::offscreen::HeadlessReport, Image) {
    palpa_app::offscreen::run(&palpa_app::offscreen::HeadlessOptions {
        scene: "liver".into(),
        // egui measures a new area unseen on its first pass.
        frames: 4,
        size,
        probe_path,
        out: None,
        modes: None,
        colormap_mm: None,
        deform_on: None,
        fps: 0.0,
        ui: true,
        display: d,
        nodule: None,
        mark: false,
        stiffness_map: false,
    })
    .expect("renders")
}

/// The toggle switch, built once here on [0, 2] (a small file, quick to build).
fn toggle_file() -> &'static Path {
    static FILE: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    FILE.get_or_init(|| {
        let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("touch-toggle.palpa");
        common::small_toggle(&path);
        path
    })
}

fn network(size: (u32, u32), d: Display) -> LayoutReport {
    use palpa_app::network::offscreen::{NetworkHeadless, run};
    let (report, _) = run(&NetworkHeadless {
        scene: toggle_file().display().to_string(),
        frames: 3,
        size,
        out: None,
        exact_check: false,
        ui: true,
        path: None,
        display: d,
        data: None,
        fit: false,
        posterior: None,
    })
    .expect("renders");
    report.layout.expect("a layout report")
}

fn assert_fingers(what: &str, l: &LayoutReport) {
    assert!(l.touch, "{what}: a touch layout: {l:?}");
    assert!(l.targets > 0, "{what}: no controls found: {l:?}");
    assert!(
        l.small_targets.is_empty() && l.smallest_target_pt.iter().all(|&s| s >= 47.5),
        "{what}: controls under 48 points: {:?}",
        l.small_targets
    );
}

#[test]
fn phone_and_tablet_layouts_give_every_control_48_points_in_both_scenes() {
    for open in [true, false] {
        let what = format!("phone, panel open {open}");
        let (l, _) = liver(PHONE, display(3.0, NOTCH, Some(open)));
        assert_eq!((l.form, l.size_pt), ("sheet", [360.0, 780.0]), "{what}");
        assert_fingers(&format!("liver {what}"), &l);
        // Folded, the sheet is one bar; unfolded at most half the safe area.
        let most = if open { 0.5 } else { 0.1 };
        assert!(l.covered_fraction <= most, "{what}: {l:?}");
        let n = network(PHONE, display(3.0, NOTCH, Some(open)));
        assert_eq!(n.form, "sheet");
        assert_fingers(&format!("network {what}"), &n);

        let what = format!("tablet, panel open {open}");
        let (l, _) = liver(TABLET, display(2.0, Insets::default(), Some(open)));
        assert_eq!((l.form, l.size_pt), ("drawer", [1024.0, 768.0]), "{what}");
        assert_fingers(&format!("liver {what}"), &l);
        assert!(
            l.covered_fraction <= if open { 0.4 } else { 0.1 },
            "{what}: {l:?}"
        );
        let n = network(TABLET, display(2.0, Insets::default(), Some(open)));
        assert_eq!(n.form, "drawer");
        assert_fingers(&format!("network {what}"), &n);
    }
}

/// The smallest supported phone (320 × 568 points) lays out fully; below it the panel
/// stays folded and says so; a 4K desktop window at 1× gets the compact mouse layout;
/// each density gives the same layout in points.
#[test]
fn screen_extremes_and_densities() {
    let (l, _) = liver((640, 1136), display(2.0, Insets::default(), Some(true)));
    assert_eq!((l.form, l.too_small, l.panel_open), ("sheet", false, true));
    assert_fingers("320 × 568", &l);

    let (l, _) = liver((600, 1000), display(2.0, Insets::default(), Some(true)));
    assert!(l.too_small, "300 × 500 points is below the minimum: {l:?}");
    assert!(l.covered_fraction < 0.2, "only the bar: {l:?}");

    let (l, _) = liver((3840, 2160), display(1.0, Insets::default(), None));
    assert_eq!((l.form, l.touch, l.panel_open), ("drawer", false, true));

    for ppp in [1.0f32, 2.0, 3.0] {
        let px = ((360.0 * ppp) as u32, (780.0 * ppp) as u32);
        let (l, _) = liver(px, display(ppp, Insets::default(), Some(true)));
        assert_eq!((l.form, l.size_pt), ("sheet", [360.0, 780.0]), "ppp {ppp}");
        // 1×: a narrow desktop window, mouse-sized; 2× and 3×: a phone.
        assert_eq!(l.touch, ppp >= 2.0, "ppp {ppp}");
        if l.touch {
            assert_fingers(&format!("ppp {ppp}"), &l);
        }
    }
}

fn reference_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference")
}

/// The part of `image` from (x0, y0) to (x1, y1) (pixels), averaged over `k × k`
/// blocks.
fn crop(image: &Image, (x0, y0): (u32, u32), (x1, y1): (u32, u32), k: u32) -> Image {
    let (w, h) = ((x1 - x0) / k, (y1 - y0) / k);
    let mut rgba = Vec::with_capacity((4 * w * h) as usize);
    for by in 0..h {
        for bx in 0..w {
            let mut sum = [0u32; 4];
            for dy in 0..k {
                for dx in 0..k {
                    let (x, y) = (x0 + bx * k + dx, y0 + by * k + dy);
                    let i = (4 * (y * image.width + x)) as usize;
                    for (c, s) in sum.iter_mut().enumerate() {
                        *s += u32::from(image.rgba[i + c]);
                    }
                }
            }
            rgba.extend(sum.map(|s| (s / (k * k)) as u8));
        }
    }
    Image {
        width: w,
        height: h,
        rgba,
    }
}

fn matches_reference(name: &str, actual: &Image) {
    let path = reference_dir().join(name);
    if std::env::var_os("PALPA_UPDATE_REFERENCE").is_some() {
        actual.save_png(&path).expect("write reference");
    }
    let reference =
        Image::load_png(&path).expect("reference image (PALPA_UPDATE_REFERENCE=1 writes it)");
    assert_eq!(
        (reference.width, reference.height),
        (actual.width, actual.height),
        "{name}"
    );
    let different = actual
        .rgba
        .chunks(4)
        .zip(reference.rgba.chunks(4))
        .filter(|(a, r)| (0..3).any(|c| a[c].abs_diff(r[c]) > 24))
        .count();
    let fraction = different as f64 / f64::from(actual.width * actual.height);
    if fraction > 0.005 {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("actual-{name}"));
        actual.save_png(&out).expect("write actual");
        panic!(
            "{name}: {:.2}% of pixels differ; see {}",
            100.0 * fraction,
            out.display()
        );
    }
}

/// Snapshots of the view beside the panel (the panel's text holds live timings): the
/// phone upright above its folded sheet, the tablet right of its drawer, each
/// averaged over 4 × 4 pixel blocks.
#[test]
fn phone_and_tablet_views_match_their_snapshots() {
    let (l, image) = liver(PHONE, display(3.0, NOTCH, Some(false)));
    // From below the notch to above the folded bar (a bar and margins above the
    // home indicator).
    let top_px = (NOTCH.top * 3.0) as u32;
    let bar_top_px = ((l.size_pt[1] - NOTCH.bottom - 80.0) * 3.0) as u32;
    matches_reference(
        "touch-phone-portrait.png",
        &crop(&image, (0, top_px), (PHONE.0, bar_top_px), 4),
    );
    // Right of the drawer (346 points wide from x = 6).
    let (_, image) = liver(TABLET, display(2.0, Insets::default(), Some(true)));
    matches_reference(
        "touch-tablet-landscape.png",
        &crop(&image, (720, 0), TABLET, 4),
    );
}

/// A phone held upright with the sheet unfolded: the view sits above the sheet, and
/// the whole palpable surface and the probe pressed 6 mm at points across it (the
/// left lobe, the middle, the sharp border) are drawn there, not under the sheet.
#[test]
fn an_open_sheet_leaves_the_probe_and_the_palpable_surface_in_view() {
    for (i, at) in [
        [-40.0, 60.0, 30.0],
        [20.0, 55.0, 35.0],
        [-7.0, 69.34, 7.0],
        [80.0, 40.0, 0.0],
    ]
    .into_iter()
    .enumerate()
    {
        let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("sheet-press-{i}.json"));
        let keys = |t: f64, d: f64| format!(r#"{{"t_s": {t}, "at_mm": {at:?}, "depth_mm": {d}}}"#);
        std::fs::write(
            &path,
            format!(
                r#"{{"keyframes": [{}, {}]}}"#,
                keys(0.0, 0.0),
                keys(0.1, 6.0)
            ),
        )
        .expect("write the probe path");
        let (report, _) = liver_pressed(PHONE, display(3.0, NOTCH, Some(true)), Some(path));
        let view = report.view.expect("a view report with the interface on");
        let sheet_top_px = view.free_px[3];
        assert!(
            sheet_top_px < 0.6 * PHONE.1 as f32,
            "the sheet is open: {view:?}"
        );
        assert_eq!(view.probe_in_free_view, Some(true), "{at:?}: {view:?}");
        assert_eq!(view.palpable_in_free_view, 1.0, "{view:?}");
    }
}
