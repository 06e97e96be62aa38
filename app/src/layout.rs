//! Where the interface goes on a given screen, so that a finger on a phone, a finger on
//! a tablet and a mouse on a desktop each get a panel they can use and most of the
//! screen stays the palpation view (or the network's landscape).
//!
//! All sizes are egui points: one point is `pixels_per_point` physical pixels, the
//! platform's density (Android's dp, iOS's point). On a touch screen every control is
//! at least [`MIN_TARGET_PT`] = 48 points in both directions (the platforms' touch
//! target guidance), and text is larger.
//!
//! - **Sheet** (narrower than [`SHEET_BELOW_PT`]: a phone upright): the panel is a
//!   bottom sheet across the width. Folded it is one 48-point bar with the live
//!   readout; unfolded it takes at most [`SHEET_MAX_FRACTION`] of the height and
//!   scrolls.
//! - **Drawer** (wider: a tablet, a phone on its side, a desktop): a side drawer on
//!   the left, [`DRAWER_WIDTH_PT`] wide (at most 45 % of the width), folding to its bar.
//!
//! Both keep out of the safe-area insets (notches, rounded corners, the home
//! indicator). Below [`MIN_SCREEN_PT`] (320 × 568 points, the smallest phone still
//! supported) the panel stays folded to its bar and says so; the view still presses.

use egui::{Rect, Vec2, pos2, vec2};

/// Smallest control on a touch screen, points in both directions.
pub const MIN_TARGET_PT: f32 = 48.0;
/// Screens narrower than this get the bottom sheet.
pub const SHEET_BELOW_PT: f32 = 600.0;
/// The sheet's largest share of the screen's height, unfolded.
pub const SHEET_MAX_FRACTION: f32 = 0.5;
/// The drawer's width.
pub const DRAWER_WIDTH_PT: f32 = 340.0;
/// The smallest supported screen (short side, long side), points.
pub const MIN_SCREEN_PT: (f32, f32) = (320.0, 568.0);

/// Safe-area insets, points.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Insets {
    pub top: f32,
    pub right: f32,
    pub bottom: f32,
    pub left: f32,
}

impl Insets {
    /// Parses `TOP,RIGHT,BOTTOM,LEFT` (points).
    pub fn parse(s: &str) -> Option<Insets> {
        let v: Vec<f32> = s
            .split(',')
            .map(|x| {
                x.trim()
                    .parse::<f32>()
                    .ok()
                    .filter(|v| v.is_finite() && *v >= 0.0)
            })
            .collect::<Option<_>>()?;
        match v[..] {
            [top, right, bottom, left] => Some(Insets {
                top,
                right,
                bottom,
                left,
            }),
            _ => None,
        }
    }
}

/// How a headless run presents its frames: the density, the safe-area insets and
/// whether the panel is unfolded (None: the form's default).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Display {
    pub pixels_per_point: f32,
    pub insets: Insets,
    pub panel_open: Option<bool>,
}

impl Default for Display {
    fn default() -> Self {
        Display {
            pixels_per_point: 1.0,
            insets: Insets::default(),
            panel_open: None,
        }
    }
}

/// The screen the interface lays itself out on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Screen {
    /// The whole screen, points.
    pub size_pt: Vec2,
    pub pixels_per_point: f32,
    pub insets: Insets,
    /// A finger rather than a mouse (a touch was seen, a mobile target, or a
    /// handheld's density and size).
    pub touch: bool,
}

impl Screen {
    /// The screen of `size_px` physical pixels at `pixels_per_point`; touch on mobile
    /// targets, after a touch, or for a handheld's density and size (2 or more pixels
    /// per point and a short side of at most 900 points: phones and most tablets, not
    /// a desktop monitor).
    pub fn new(
        size_px: (u32, u32),
        pixels_per_point: f32,
        insets: Insets,
        touch_seen: bool,
    ) -> Self {
        let ppp = if pixels_per_point.is_finite() && pixels_per_point > 0.0 {
            pixels_per_point
        } else {
            1.0
        };
        let size_pt = vec2(size_px.0 as f32, size_px.1 as f32) / ppp;
        let handheld = ppp >= 2.0 && size_pt.min_elem() <= 900.0;
        Screen {
            size_pt,
            pixels_per_point: ppp,
            insets,
            touch: cfg!(any(target_os = "android", target_os = "ios")) || touch_seen || handheld,
        }
    }

    /// The screen egui was given this pass: its whole viewport, the safe area it keeps
    /// content in (iOS's notch and home indicator, a headless run's `--safe-area`),
    /// and its density.
    pub fn from_ctx(ctx: &egui::Context, touch_seen: bool) -> Self {
        let ppp = ctx.pixels_per_point();
        let whole = ctx.viewport_rect();
        let safe = ctx.content_rect();
        let insets = Insets {
            top: (safe.top() - whole.top()).max(0.0),
            right: (whole.right() - safe.right()).max(0.0),
            bottom: (whole.bottom() - safe.bottom()).max(0.0),
            left: (safe.left() - whole.left()).max(0.0),
        };
        let size_px = (
            (whole.width() * ppp).round() as u32,
            (whole.height() * ppp).round() as u32,
        );
        Screen::new(size_px, ppp, insets, touch_seen)
    }

    /// The area inside the safe-area insets.
    pub fn safe_rect(&self) -> Rect {
        let i = self.insets;
        Rect::from_min_max(
            pos2(i.left, i.top),
            pos2(
                (self.size_pt.x - i.right).max(i.left),
                (self.size_pt.y - i.bottom).max(i.top),
            ),
        )
    }

    /// Smaller than the smallest supported screen.
    pub fn too_small(&self) -> bool {
        let s = self.safe_rect().size();
        s.min_elem() < MIN_SCREEN_PT.0 || s.max_elem() < MIN_SCREEN_PT.1
    }
}

/// Which panel form a screen gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    Sheet,
    Drawer,
}

/// The panel's place on a screen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    pub form: Form,
    pub touch: bool,
    /// Where the panel may draw, unfolded (its bar at the top of a drawer, at the
    /// bottom of a sheet's).
    pub panel: Rect,
    /// The height of the folded bar.
    pub bar_pt: f32,
    pub too_small: bool,
}

impl Layout {
    pub fn for_screen(screen: &Screen) -> Layout {
        let safe = screen.safe_rect();
        let margin = 6.0;
        let bar_pt = if screen.touch { MIN_TARGET_PT } else { 28.0 };
        let too_small = screen.too_small();
        if safe.width() < SHEET_BELOW_PT {
            let height = (SHEET_MAX_FRACTION * safe.height()).max(bar_pt + 2.0 * margin);
            Layout {
                form: Form::Sheet,
                touch: screen.touch,
                panel: Rect::from_min_max(
                    pos2(safe.left() + margin, safe.bottom() - height),
                    pos2(safe.right() - margin, safe.bottom() - margin),
                ),
                bar_pt,
                too_small,
            }
        } else {
            let width = DRAWER_WIDTH_PT.min(0.45 * safe.width());
            Layout {
                form: Form::Drawer,
                touch: screen.touch,
                panel: Rect::from_min_max(
                    pos2(safe.left() + margin, safe.top() + margin),
                    pos2(safe.left() + margin + width, safe.bottom() - margin),
                ),
                bar_pt,
                too_small,
            }
        }
    }

    /// The share of the safe area the panel covers when `open`, for the reports: the
    /// view keeps the rest.
    pub fn covered_fraction(&self, screen: &Screen, open: bool) -> f32 {
        let safe = screen.safe_rect();
        let covered = if open && !self.too_small {
            self.panel.area()
        } else {
            self.panel.width() * (self.bar_pt + 12.0)
        };
        (covered / safe.area().max(1.0)).min(1.0)
    }
}

/// Sets egui's sizes for the screen: 48-point controls and larger text on touch
/// screens, egui's compact defaults with a mouse.
pub fn apply_style(ctx: &egui::Context, layout: &Layout) {
    let touch = layout.touch;
    // Called every pass: the style is rewritten only when the form of input changes.
    let current = ctx.global_style();
    let want = if touch {
        MIN_TARGET_PT
    } else {
        egui::Style::default().spacing.interact_size.y
    };
    if current.spacing.interact_size.y == want && current.interaction.selectable_labels != touch {
        return;
    }
    ctx.global_style_mut(|style| {
        let base = egui::Style::default();
        style.spacing = base.spacing.clone();
        style.text_styles = base.text_styles.clone();
        // A finger that drags across text means to scroll, not to select it.
        style.interaction.selectable_labels = !touch;
        if touch {
            let s = &mut style.spacing;
            s.interact_size = vec2(MIN_TARGET_PT, MIN_TARGET_PT);
            s.button_padding = vec2(14.0, 12.0);
            s.item_spacing = vec2(10.0, 10.0);
            s.slider_width = 180.0;
            s.icon_width = 28.0;
            s.icon_width_inner = 16.0;
            s.icon_spacing = 10.0;
            s.combo_width = 160.0;
            s.scroll.bar_width = 14.0;
            for (text, font) in style.text_styles.iter_mut() {
                font.size = match text {
                    egui::TextStyle::Small => 14.0,
                    egui::TextStyle::Heading => 22.0,
                    _ => 17.0,
                };
            }
        }
    });
}

/// The scroll bars of a panel: none on a touch screen, where a panel scrolls by
/// dragging its contents (a thin bar would be a target no finger can hold).
pub fn scroll_bar(layout: &Layout) -> egui::scroll_area::ScrollBarVisibility {
    if layout.touch {
        egui::scroll_area::ScrollBarVisibility::AlwaysHidden
    } else {
        egui::scroll_area::ScrollBarVisibility::VisibleWhenNeeded
    }
}

/// Draws the panel: its bar (a 48-point button that folds and unfolds it, with
/// `summary` beside it) and, unfolded, `contents` in a scroll area. Returns the
/// rectangle it covers (points).
pub fn panel(
    ctx: &egui::Context,
    id: &str,
    layout: &Layout,
    open: &mut bool,
    summary: &str,
    contents: impl FnOnce(&mut egui::Ui),
) -> Rect {
    let open_now = *open && !layout.too_small;
    let rect = layout.panel;
    let (pivot, pos) = match layout.form {
        Form::Sheet => (egui::Align2::LEFT_BOTTOM, rect.left_bottom()),
        Form::Drawer => (egui::Align2::LEFT_TOP, rect.left_top()),
    };
    let shown = egui::Area::new(egui::Id::unique(id))
        .pivot(pivot)
        .fixed_pos(pos)
        .constrain(true)
        .show(ctx, |ui| {
            egui::Frame::window(ui.style()).show(ui, |ui| {
                let inner = rect.width() - 2.0 * 8.0;
                ui.set_width(inner);
                ui.set_max_width(inner);
                // A slider, its value and its label share one row of the panel.
                ui.spacing_mut().slider_width = (0.4 * inner).min(180.0);
                ui.horizontal(|ui| {
                    let label = if open_now {
                        "Hide controls"
                    } else {
                        "Controls"
                    };
                    let bar = egui::Button::new(label).min_size(vec2(
                        if layout.touch {
                            2.5 * MIN_TARGET_PT
                        } else {
                            0.0
                        },
                        layout.bar_pt,
                    ));
                    if ui.add_enabled(!layout.too_small, bar).clicked() {
                        *open = !*open;
                    }
                    ui.label(summary);
                });
                if layout.too_small {
                    ui.label(
                        "screen under 320 × 568 points: controls hidden, the view still presses",
                    );
                } else if open_now {
                    let bar = scroll_bar(layout);
                    let height = (rect.height() - layout.bar_pt - 40.0).max(0.0);
                    egui::ScrollArea::vertical()
                        .max_height(height)
                        .min_scrolled_height(height)
                        .auto_shrink([false, true])
                        .scroll_bar_visibility(bar)
                        .show(ui, contents);
                }
            });
        });
    shown.response.rect
}

/// The largest rectangle of `safe` that `covered` leaves free: the part to its right,
/// left, above or below, whichever is largest (the view centres the organ there).
/// `covered` outside `safe`, or none of it free: `safe` itself.
pub fn free_rect(safe: Rect, covered: Rect) -> Rect {
    let parts = [
        Rect::from_min_max(pos2(covered.right(), safe.top()), safe.right_bottom()),
        Rect::from_min_max(safe.left_top(), pos2(covered.left(), safe.bottom())),
        Rect::from_min_max(safe.left_top(), pos2(safe.right(), covered.top())),
        Rect::from_min_max(pos2(safe.left(), covered.bottom()), safe.right_bottom()),
    ];
    parts
        .into_iter()
        .filter(|r| r.is_positive())
        .max_by(|a, b| a.area().total_cmp(&b.area()))
        .filter(|_| safe.intersects(covered))
        .unwrap_or(safe)
}

/// The interactive widgets (clickable or draggable, enabled, visible) on the screen
/// in the last pass, with their whole rectangles (a control half scrolled out of a
/// panel counts at its full size, as a finger finds it once scrolled in).
pub fn targets(ctx: &egui::Context) -> Vec<Rect> {
    let screen = ctx.viewport_rect();
    ctx.viewport(|vp| {
        vp.prev_pass
            .widgets
            .layers()
            .flat_map(|(_, w)| w.iter())
            .filter(|w| {
                w.enabled
                    && w.visible
                    && (w.sense.senses_click() || w.sense.senses_drag())
                    && w.interact_rect.is_positive()
                    && screen.intersects(w.interact_rect)
            })
            .map(|w| w.rect)
            .collect()
    })
}

/// What a headless run reports of its layout: the checks of the touch goals.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LayoutReport {
    pub form: &'static str,
    pub touch: bool,
    pub pixels_per_point: f32,
    pub size_pt: [f32; 2],
    pub insets_pt: [f32; 4],
    pub panel_open: bool,
    /// Share of the safe area under the panel (the view keeps the rest).
    pub covered_fraction: f32,
    pub too_small: bool,
    /// Interactive widgets on the screen, and the smallest one's size (points).
    pub targets: usize,
    pub smallest_target_pt: [f32; 2],
    /// Targets under 48 points in either direction on a touch screen, as
    /// `[x, y, width, height]` (points).
    pub small_targets: Vec<[f32; 4]>,
}

/// The report for the last pass of `ctx`.
pub fn report(ctx: &egui::Context, touch_seen: bool, panel_open: bool) -> LayoutReport {
    let screen = Screen::from_ctx(ctx, touch_seen);
    let layout = Layout::for_screen(&screen);
    let rects = targets(ctx);
    let smallest = rects.iter().fold([f32::INFINITY; 2], |m, r| {
        [m[0].min(r.width()), m[1].min(r.height())]
    });
    let small = rects
        .iter()
        .filter(|r| screen.touch && r.size().min_elem() < MIN_TARGET_PT - 0.5)
        .map(|r| [r.left(), r.top(), r.width(), r.height()])
        .collect();
    let i = screen.insets;
    LayoutReport {
        form: match layout.form {
            Form::Sheet => "sheet",
            Form::Drawer => "drawer",
        },
        touch: screen.touch,
        pixels_per_point: screen.pixels_per_point,
        size_pt: [screen.size_pt.x, screen.size_pt.y],
        insets_pt: [i.top, i.right, i.bottom, i.left],
        panel_open,
        covered_fraction: layout.covered_fraction(&screen, panel_open),
        too_small: layout.too_small,
        targets: rects.len(),
        smallest_target_pt: if rects.is_empty() { [0.0; 2] } else { smallest },
        small_targets: small,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn screen(px: (u32, u32), ppp: f32) -> Screen {
        Screen::new(px, ppp, Insets::default(), false)
    }

    /// The view keeps the largest part the panel leaves: right of a drawer, above a
    /// sheet; a panel outside the screen leaves all of it.
    #[test]
    fn the_free_part_is_beside_a_drawer_and_above_a_sheet() {
        let safe = Rect::from_min_max(pos2(0.0, 0.0), pos2(1280.0, 720.0));
        let drawer = Rect::from_min_max(pos2(6.0, 6.0), pos2(346.0, 714.0));
        assert_eq!(
            free_rect(safe, drawer),
            Rect::from_min_max(pos2(346.0, 0.0), pos2(1280.0, 720.0))
        );
        let phone = Rect::from_min_max(pos2(0.0, 47.0), pos2(390.0, 810.0));
        let sheet = Rect::from_min_max(pos2(6.0, 420.0), pos2(384.0, 804.0));
        assert_eq!(
            free_rect(phone, sheet),
            Rect::from_min_max(pos2(0.0, 47.0), pos2(390.0, 420.0))
        );
        let away = Rect::from_min_max(pos2(2000.0, 0.0), pos2(2100.0, 50.0));
        assert_eq!(free_rect(safe, away), safe);
    }

    #[test]
    fn phones_get_a_sheet_tablets_and_desktops_a_drawer() {
        let phone = screen((1080, 2340), 3.0);
        assert!(phone.touch);
        let l = Layout::for_screen(&phone);
        assert_eq!(l.form, Form::Sheet);
        assert!(l.covered_fraction(&phone, false) < 0.12);
        assert!(l.covered_fraction(&phone, true) <= SHEET_MAX_FRACTION + 1e-3);
        let tablet = screen((2048, 1536), 2.0);
        assert!(tablet.touch);
        let l = Layout::for_screen(&tablet);
        assert_eq!(l.form, Form::Drawer);
        assert!(l.covered_fraction(&tablet, true) < 0.4);
        let desktop = screen((3840, 2160), 1.0);
        assert!(!desktop.touch);
        assert_eq!(Layout::for_screen(&desktop).form, Form::Drawer);
        let turned = screen((2340, 1080), 3.0);
        assert_eq!(Layout::for_screen(&turned).form, Form::Drawer);
    }

    #[test]
    fn the_panel_keeps_out_of_the_safe_area_and_small_screens_are_named() {
        let insets = Insets::parse("47,0,34,0").expect("insets");
        let s = Screen::new((1170, 2532), 3.0, insets, false);
        let l = Layout::for_screen(&s);
        assert!(l.panel.bottom() <= s.size_pt.y - 34.0);
        assert!(l.panel.top() >= 47.0);
        assert!(!s.too_small());
        assert!(!screen((640, 1136), 2.0).too_small());
        assert!(screen((600, 1000), 2.0).too_small());
        assert_eq!(Insets::parse("1,2,3"), None);
        assert_eq!(Insets::parse("1,2,3,-4"), None);
        assert_eq!(Insets::parse("1,2,x,4"), None);
    }
}
