//! Region painting: a mouse stroke over the organ marks triangles, undo takes it back,
//! the regions save to a region file that reads back to the same points, and a
//! painting with no fixed region is refused with the reason.

use glam::Vec2;
use palpa_app::force::NoHaptics;
use palpa_app::input::{Button, InputEvent, PointerId};
use palpa_app::scenes;
use palpa_app::session::Session;
use palpa_app::session::paint::Label;
use palpa_core::organ::region_file::RegionFile;

const VIEW: Vec2 = Vec2::new(800.0, 600.0);

fn stroke(s: &mut Session, from: Vec2, to: Vec2, button: Button) {
    s.handle(
        InputEvent::PointerDown {
            id: PointerId::Mouse,
            button,
            pos_px: from,
            time_s: 0.0,
        },
        VIEW,
    );
    for k in 1..=10 {
        let p = from + (to - from) * (k as f32 / 10.0);
        s.handle(
            InputEvent::PointerMove {
                id: PointerId::Mouse,
                pos_px: p,
                time_s: 0.01 * f64::from(k),
            },
            VIEW,
        );
    }
    s.handle(
        InputEvent::PointerUp {
            id: PointerId::Mouse,
            time_s: 0.2,
        },
        VIEW,
    );
}

#[test]
fn a_stroke_paints_undo_restores_and_the_regions_save() {
    let scene = scenes::built_in().expect("built-in scene").scene;
    let mut s = Session::new(scene, Box::new(NoHaptics)).expect("session");
    s.frame();
    s.set_painting(true);
    let p = s.painter.as_ref().expect("region mode");
    let (fixed0, palpable0) = p.counts();
    assert_eq!(fixed0, 0);
    assert!(palpable0 > 100, "starts from the scene's palpable region");
    assert!(p.warning().is_some_and(|w| w.contains("free to move")));
    assert!(p.region_file("x").is_err(), "no fixed region: not saved");

    let c = VIEW / 2.0;
    stroke(
        &mut s,
        c - Vec2::new(60.0, 0.0),
        c + Vec2::new(60.0, 0.0),
        Button::Primary,
    );
    let p = s.painter.as_ref().expect("region mode");
    let (fixed1, _) = p.counts();
    assert!(
        fixed1 > 5,
        "the stroke over the organ's middle painted {fixed1}"
    );
    assert!(p.warning().is_none());
    let values = p.vertex_values(&s.scene);
    assert!(values.contains(&2.0) && values.contains(&1.0));

    // Right-drag pans and a left-drag off the organ orbits; neither paints.
    let cam = s.controls.camera;
    stroke(&mut s, c, c + Vec2::new(0.0, 80.0), Button::Secondary);
    assert_eq!(s.painter.as_ref().expect("on").counts().0, fixed1);
    assert_ne!(s.controls.camera, cam, "the camera panned");
    let cam = s.controls.camera;
    stroke(
        &mut s,
        Vec2::new(5.0, 5.0),
        Vec2::new(60.0, 5.0),
        Button::Primary,
    );
    assert_eq!(s.painter.as_ref().expect("on").counts().0, fixed1);
    assert_ne!(s.controls.camera, cam, "the camera orbited");

    // Undo takes the stroke back; painting again with the palpable brush and then
    // the fixed one gives a fixed band again.
    let p = s.painter.as_mut().expect("on");
    p.undo();
    assert_eq!(p.counts(), (fixed0, palpable0));
    assert!(!p.can_undo());
    p.brush = Label::Fixed;
    stroke(
        &mut s,
        c - Vec2::new(60.0, 0.0),
        c + Vec2::new(60.0, 0.0),
        Button::Primary,
    );
    let p = s.painter.as_ref().expect("on");
    let (fixed2, palpable2) = p.counts();
    assert!(fixed2 > 0);

    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("liver.regions.toml");
    p.region_file("liver")
        .expect("valid")
        .save(&path)
        .expect("saved");
    let r = RegionFile::load(&path).expect("reads back");
    assert_eq!(r.fixed_points.len(), fixed2);
    assert_eq!(r.palpable_points.len(), palpable2);
    assert!(r.match_radius_mm > 0.0);

    // Leaving the region mode restores the normal colours and pressing.
    s.set_painting(false);
    assert!(s.painter.is_none());
    assert!(s.frame().values.is_none());
}
