//! A phone's lifecycle, on the desktop: the event sequences Android and iOS send (a
//! surface made, a press, the screen rotated during it, a second finger, a suspend
//! with a finger down, input with no surface, a resume on a new surface, a lost GPU
//! device, a memory warning) driven through the same [`Shell`] the window uses, its
//! frames drawn offscreen on the software adapter. The session (probe, camera, modes
//! kept, a network's coordinates) survives all of it.

use crate::common;

use glam::Vec2;
use palpa_app::input::{Button, InputEvent, PointerId};
use palpa_app::layout::Insets;
use palpa_app::render::gpu::Gpu;
use palpa_app::render::offscreen::{FORMAT, Image, Offscreen, UI_FORMAT};
use palpa_app::shell::{Drawing, Room, Shell};

const PORTRAIT: (u32, u32) = (540, 1170);
const LANDSCAPE: (u32, u32) = (1170, 540);

fn frame(shell: &mut Shell, gpu: &Gpu, drawing: &mut Drawing, size: (u32, u32)) -> Image {
    assert!(shell.has_surface(), "a frame needs a surface");
    let target = Offscreen::new(&gpu.device, size, gpu.can_reinterpret());
    let raw = palpa_app::overlay::headless_input(size, 1.5, Insets::default(), 0.0);
    let (mut encoder, _) = shell.encode(
        gpu,
        drawing,
        &target.view,
        &target.ui_view,
        size,
        1.5,
        raw,
        1.0 / 25.0,
    );
    target.encode_copy(&mut encoder);
    gpu.submit_and_wait(encoder).expect("frame");
    target.read(&gpu.device).expect("read back")
}

/// What a frame draws with on `gpu`, for the shell's room.
fn new_drawing(gpu: &Gpu, shell: &Shell) -> Drawing {
    Drawing::new(
        &gpu.device,
        &shell.room,
        FORMAT,
        UI_FORMAT,
        gpu.is_software(),
    )
}

fn touch(id: u64) -> PointerId {
    PointerId::Touch(id)
}

fn down(id: u64, p: Vec2, t: f64) -> InputEvent {
    InputEvent::PointerDown {
        id: touch(id),
        button: Button::Primary,
        pos_px: p,
        time_s: t,
    }
}

fn mv(id: u64, p: Vec2, t: f64) -> InputEvent {
    InputEvent::PointerMove {
        id: touch(id),
        pos_px: p,
        time_s: t,
    }
}

fn session(shell: &Shell) -> &palpa_app::session::Session {
    match &shell.room {
        Room::Palpation(s) => s,
        other => panic!("expected a palpation room, got {other:?}"),
    }
}

/// What must survive: probe, camera (target, yaw, pitch, distance), modes kept.
fn kept(shell: &Shell) -> String {
    let c = &session(shell).controls;
    format!(
        "{:?} {:?} {} {} {} {}",
        c.probe, c.camera.target_mm, c.camera.yaw, c.camera.pitch, c.camera.distance_mm, c.modes
    )
}

/// A screen point where a held finger presses (on the palpable surface, in front).
fn palpable_px(shell: &mut Shell) -> Vec2 {
    let size = shell.viewport();
    for j in 1..20 {
        for i in 1..10 {
            let p = Vec2::new(size.x * i as f32 / 10.0, size.y * j as f32 / 20.0);
            shell.pointer(down(9, p, 0.0));
            shell.pointer(mv(9, p + Vec2::new(1.0, 0.0), 0.3));
            let hit = session(shell).controls.pressing;
            shell.pointer(InputEvent::PointerUp {
                id: touch(9),
                time_s: 0.4,
            });
            if hit {
                return p;
            }
        }
    }
    panic!("no palpable point on the screen");
}

#[test]
fn a_palpation_session_survives_rotation_suspend_resume_a_lost_device_and_low_memory() {
    let mut shell = Shell::open("liver").expect("the built-in liver");
    let mut gpu = Gpu::headless().expect("software adapter");
    let mut drawing = new_drawing(&gpu, &shell);
    shell.resumed(PORTRAIT);
    frame(&mut shell, &gpu, &mut drawing, PORTRAIT);
    let p = palpable_px(&mut shell);

    // Hold a finger on the surface, then drag down: a press.
    shell.pointer(down(1, p, 1.0));
    shell.pointer(mv(1, p + Vec2::new(1.0, 0.0), 1.3));
    shell.pointer(mv(1, p + Vec2::new(1.0, 60.0), 1.4));
    assert!(session(&shell).controls.pressing, "pressing");
    let depth = session(&shell).controls.depth_mm;
    assert!(depth > 0.0);
    let before = kept(&shell);

    // The phone turns during the press: a new size, the press goes on.
    shell.resized(LANDSCAPE);
    frame(&mut shell, &gpu, &mut drawing, LANDSCAPE);
    assert!(
        session(&shell).controls.pressing,
        "the press outlives the rotation"
    );
    assert_eq!(session(&shell).controls.depth_mm, depth);
    assert_eq!(kept(&shell), before);
    shell.pointer(mv(1, p + Vec2::new(1.0, 70.0), 1.5));
    assert!(
        session(&shell).controls.depth_mm > depth,
        "and follows the finger"
    );

    // A second finger arrives: the press becomes a pinch (no press), both lift.
    shell.pointer(down(2, p + Vec2::new(80.0, 0.0), 1.6));
    assert!(!session(&shell).controls.pressing);
    for id in [2, 1] {
        shell.pointer(InputEvent::PointerUp {
            id: touch(id),
            time_s: 1.7,
        });
    }
    shell.resized(PORTRAIT);
    // The frame after the turn centres the organ again in what the sheet leaves free
    // (the drawer's shift no longer applies); a finger presses what that frame shows.
    frame(&mut shell, &gpu, &mut drawing, PORTRAIT);

    // Suspended with a finger down: the finger is let go, the probe stays.
    shell.pointer(down(3, p, 2.0));
    shell.pointer(mv(3, p + Vec2::new(1.0, 0.0), 2.3));
    shell.pointer(mv(3, p + Vec2::new(1.0, 40.0), 2.4));
    assert!(session(&shell).controls.pressing);
    let probe = session(&shell).controls.probe;
    shell.suspended();
    assert!(!shell.has_surface(), "no surface while suspended");
    assert!(!session(&shell).controls.pressing, "the finger is let go");
    assert_eq!(session(&shell).controls.probe, probe);
    let before = kept(&shell);
    // Input with no surface (a late event) maps against the last size, harmlessly.
    shell.pointer(mv(3, p, 2.5));
    shell.pointer(InputEvent::Wheel { lines: 0.0 });
    assert_eq!(kept(&shell), before);

    // Resumed on a new surface (Android makes a new native window).
    shell.resumed(PORTRAIT);
    let a = frame(&mut shell, &gpu, &mut drawing, PORTRAIT);
    assert_eq!(session(&shell).controls.probe, probe);

    // The device is lost: a new device and everything drawn on it, the room kept.
    drop(drawing);
    drop(gpu);
    gpu = Gpu::headless().expect("a new device");
    drawing = new_drawing(&gpu, &shell);
    let b = frame(&mut shell, &gpu, &mut drawing, PORTRAIT);
    assert_eq!(session(&shell).controls.probe, probe);
    // The same scene from the same camera: the view right of the panel agrees.
    let differing = a
        .rgba
        .chunks(4)
        .zip(b.rgba.chunks(4))
        .filter(|(x, y)| (0..3).any(|c| x[c].abs_diff(y[c]) > 24))
        .count();
    assert!(
        differing < a.rgba.len() / 4 / 10,
        "{differing} pixels differ after the new device"
    );

    // Low memory: caches go, the session stays and the next frame draws.
    shell.memory_warning(Some(&mut drawing));
    frame(&mut shell, &gpu, &mut drawing, PORTRAIT);
    assert_eq!(session(&shell).controls.probe, probe);
    assert_eq!(shell.memory_warnings, 1);
    assert_eq!(shell.surfaces_made, 2);
}

#[test]
fn a_network_room_keeps_its_coordinates_through_suspend_and_a_new_device() {
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("toggle.palpa");
    common::small_toggle(&file);

    let mut shell = Shell::open(file.to_str().expect("utf-8")).expect("opens");
    let gpu = Gpu::headless().expect("software adapter");
    let mut drawing = new_drawing(&gpu, &shell);
    shell.resumed(LANDSCAPE);
    frame(&mut shell, &gpu, &mut drawing, LANDSCAPE);
    let coordinates = |s: &Shell| match &s.room {
        Room::Network(n) => format!(
            "{} {:?} {} {} {}",
            n.time.value,
            n.params.iter().map(|c| c.value).collect::<Vec<_>>(),
            n.camera.yaw,
            n.camera.pitch,
            n.camera.distance_mm
        ),
        other => panic!("expected a network room, got {other:?}"),
    };
    if let Room::Network(n) = &mut shell.room {
        n.time.value = 1.25;
        n.playing = false;
    }
    // Orbit the landscape with a finger, then suspend with it down.
    shell.pointer(down(1, Vec2::new(600.0, 300.0), 0.0));
    shell.pointer(mv(1, Vec2::new(640.0, 300.0), 0.1));
    let before = coordinates(&shell);
    shell.suspended();
    shell.pointer(mv(1, Vec2::new(700.0, 300.0), 0.2));
    assert_eq!(coordinates(&shell), before, "no orbit from a finger let go");
    shell.resumed(PORTRAIT);
    drop(drawing);
    let gpu = Gpu::headless().expect("a new device");
    let mut drawing = new_drawing(&gpu, &shell);
    frame(&mut shell, &gpu, &mut drawing, PORTRAIT);
    assert_eq!(coordinates(&shell), before);
}
