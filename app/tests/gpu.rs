//! GPU tests on the software adapter (Mesa's lavapipe through Vulkan; scripts/deps.sh
//! --gpu installs it): the compute deformation against the CPU path of palpa-core, and
//! an offscreen render of the default scene against a reference image.

use crate::common;

use std::path::{Path, PathBuf};

use palpa_app::force::NoHaptics;
use palpa_app::offscreen::settle;
use palpa_app::render::Renderer;
use palpa_app::render::gpu::Gpu;
use palpa_app::render::offscreen::{FORMAT, Image, Offscreen};
use palpa_app::scenes;
use palpa_app::session::Session;

fn gpu() -> Gpu {
    // Vulkan only, so the reference image does not depend on which driver wgpu finds.
    Gpu::headless_on(wgpu::Backends::VULKAN).unwrap_or_else(|e| {
        panic!("{e:#}\n(the GPU tests need a Vulkan adapter: run scripts/deps.sh --gpu)")
    })
}

/// A session pressing the front of the organ 8 mm deep, with the force loop answered.
fn pressing_session() -> Session {
    let loaded = scenes::built_in().expect("built-in scene");
    let mut s = Session::new(loaded.scene, Box::new(NoHaptics)).expect("force thread");
    assert!(
        s.controls.probe.is_some(),
        "the session starts with the probe on the organ"
    );
    s.controls.pressing = true;
    s.controls.depth_mm = 8.0;
    s.force.command(s.controls.command());
    settle(&s, std::time::Duration::from_secs(2));
    assert_eq!(
        s.force.latest().command,
        s.controls.command(),
        "force loop answered"
    );
    s
}

#[test]
fn gpu_and_cpu_deformation_agree() {
    let gpu = gpu();
    let mut session = pressing_session();
    for modes in [1, 3, session.scene.modes() as u32] {
        session.controls.modes = modes;
        settle(&session, std::time::Duration::from_secs(2));
        agree(&gpu, &mut session, modes);
    }
    // A hidden nodule under the probe: the surface away from it sways with the larger
    // force, on the GPU as on the CPU.
    let mut session = scenes::built_in()
        .expect("built-in scene")
        .session(Box::new(NoHaptics))
        .expect("session");
    session.controls.pressing = true;
    session.controls.depth_mm = 8.0;
    let t = session
        .training
        .as_mut()
        .expect("the built-in liver offers the training");
    let seed = (1..100)
        .find(|&seed| {
            t.hide(Some(seed), 0.0).expect("hides");
            t.trial.as_ref().expect("a case").case.peak_effect > 0.15
        })
        .expect("a nodule to feel");
    let case = t.trial.as_ref().expect("a case").case.clone();
    let (over, _) = session
        .scene
        .closest_palpable(case.surface_mm)
        .expect("a palpable point");
    session.controls.probe = Some(over);
    session.force.command(session.command());
    settle(&session, std::time::Duration::from_secs(2));
    let modes = session.scene.modes() as u32;
    let gain = agree(&gpu, &mut session, modes);
    assert!(gain > 0.05, "seed {seed}: the nodule's gain {gain}");
}

/// Draws a frame of `session` with `modes` modes on the GPU and checks its deformed
/// surfaces against the CPU's; returns the nodule's gain the frame drew with.
fn agree(gpu: &Gpu, session: &mut Session, modes: u32) -> f32 {
    let mut renderer = Renderer::new(&gpu.device, FORMAT, &session.scene);
    let target = Offscreen::new(&gpu.device, (64, 64), gpu.can_reinterpret());
    let input = session.frame();
    let gain = input.surface_gain.0[3];
    assert_eq!(input.coeffs.len(), modes as usize);
    let encoder = renderer.encode_frame(gpu, &target.view, (64, 64), &input);
    gpu.queue.submit([encoder.finish()]);
    let mechanical = renderer
        .deform
        .read_back_mechanical(&gpu.device, &gpu.queue)
        .expect("read back");
    let (positions, normals) = renderer
        .deform
        .read_back(&gpu.device, &gpu.queue)
        .expect("read back");
    let cpu = session.deformed_mm().to_vec();
    let rest = session.scene.vertices_mm();
    let mut max_u: f32 = 0.0;
    let mut max_err: f32 = 0.0;
    for ((g, c), r) in mechanical.iter().zip(&cpu).zip(rest) {
        let u: f32 = (0..3).map(|k| (c[k] - r[k]).powi(2)).sum::<f32>().sqrt();
        max_u = max_u.max(u);
        for k in 0..3 {
            max_err = max_err.max((g[k] - c[k]).abs());
        }
        // w holds |u|.
        assert!((g[3] - u).abs() <= 1e-4 * u.max(1.0), "|u| {} vs {u}", g[3]);
    }
    assert!(
        max_u > 1.0,
        "an 8 mm press moves the surface by more than 1 mm ({max_u})"
    );
    // f32 sums of n terms on the GPU against f64 sums of the same f32 data: a few
    // ulps of the position (~200 mm) plus n·eps·|u|.
    let tol = 1e-4 * 200.0 + modes as f32 * f32::EPSILON * 4.0 * max_u;
    assert!(
        max_err < tol,
        "n = {modes}: GPU and CPU differ by {max_err} mm (tolerance {tol})"
    );
    // The drawn surface carried on the CPU's render surface: the same within the
    // render surface's own difference (the embedding's weights are at most about
    // 1.5 in size) and its normals unit vectors that agree.
    let visual = session.scene.visual();
    let n = visual.rest_mm.len();
    let (mut drawn, mut drawn_normals, mut sums) =
        (vec![[0.0; 4]; n], vec![[0.0; 4]; n], vec![[0.0; 3]; n]);
    let carried: Vec<[f32; 4]> = cpu.iter().map(|c| [c[0], c[1], c[2], 0.0]).collect();
    visual.deform(&carried, &mut drawn, &mut drawn_normals, &mut sums);
    let drawn_err = positions
        .iter()
        .zip(&drawn)
        .map(|(g, c)| (0..3).map(|k| (g[k] - c[k]).abs()).fold(0.0f32, f32::max))
        .fold(0.0f32, f32::max);
    assert!(
        drawn_err < 3.0 * tol,
        "n = {modes}: the drawn surfaces differ by {drawn_err} mm (tolerance {})",
        3.0 * tol
    );
    for (g, c) in normals.iter().zip(&drawn_normals) {
        let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-4);
        let dot = g[0] * c[0] + g[1] * c[1] + g[2] * c[2];
        assert!(dot > 0.999, "normal {g:?} vs {c:?}");
    }
    gain
}

#[test]
fn the_cpu_deformed_surface_draws_the_same_frame() {
    use palpa_app::render::deform::DeformOn;
    let gpu = gpu();
    let mut session = pressing_session();
    let size = (160, 120);
    let mut renderer = Renderer::new(&gpu.device, FORMAT, &session.scene);
    let target = Offscreen::new(&gpu.device, size, gpu.can_reinterpret());
    let mut draw = |session: &mut Session| {
        let input = session.frame();
        let uploaded = input
            .cpu_surface
            .map(|s| (s.positions.to_vec(), s.normals.to_vec()));
        let mut encoder = renderer.encode_frame(&gpu, &target.view, size, &input);
        target.encode_copy(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        let image = target.read(&gpu.device).expect("read back");
        let buffers = renderer
            .deform
            .read_back(&gpu.device, &gpu.queue)
            .expect("read back");
        (image, uploaded, buffers)
    };
    session.deform_on = DeformOn::Gpu;
    let (on_gpu, none, _) = draw(&mut session);
    assert!(none.is_none(), "the GPU path uploads no surface");
    session.deform_on = DeformOn::Cpu;
    let (on_cpu, uploaded, buffers) = draw(&mut session);
    // What the CPU computed is what the vertex buffers hold, bit for bit.
    assert_eq!(uploaded, Some(buffers));
    let fraction = different_fraction(&on_gpu, &on_cpu);
    assert!(
        fraction <= MAX_DIFFERENT_FRACTION,
        "{:.3} % of pixels differ between the two paths",
        100.0 * fraction
    );
    // And the frame is not the rest shape: the press shows.
    session.controls.release_probe();
    session.force.command(session.controls.command());
    settle(&session, std::time::Duration::from_secs(2));
    let (at_rest, _, _) = draw(&mut session);
    assert_ne!(
        at_rest.rgba, on_cpu.rgba,
        "the pressed frame differs from rest"
    );
}

fn reference_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference")
}

/// The share of pixels of two images of one size that differ by more than
/// [`PIXEL_TOLERANCE`] in a colour channel.
fn different_fraction(a: &Image, b: &Image) -> f64 {
    let different = a
        .rgba
        .chunks_exact(4)
        .zip(b.rgba.chunks_exact(4))
        .filter(|(p, q)| (0..3).any(|c| p[c].abs_diff(q[c]) > PIXEL_TOLERANCE))
        .count();
    different as f64 / (a.width * a.height) as f64
}

/// Pixels differing by more than this (max over channels) count as different.
const PIXEL_TOLERANCE: u8 = 24;
/// At most this fraction of pixels may differ: rasterization on another Mesa version
/// moves a few edge pixels, a wrong shader or camera changes thousands.
const MAX_DIFFERENT_FRACTION: f64 = 0.005;

#[test]
fn default_scene_matches_the_reference_image() {
    let gpu = gpu();
    let mut session = pressing_session();
    session.colormap_mm = None;
    let size = (320, 240);
    let mut renderer = Renderer::new(&gpu.device, FORMAT, &session.scene);
    let target = Offscreen::new(&gpu.device, size, gpu.can_reinterpret());
    let input = session.frame();
    let mut encoder = renderer.encode_frame(&gpu, &target.view, size, &input);
    target.encode_copy(&mut encoder);
    gpu.queue.submit([encoder.finish()]);
    let actual = target.read(&gpu.device).expect("read back");

    let reference_path = reference_dir().join("liver-press.png");
    if std::env::var_os("PALPA_UPDATE_REFERENCE").is_some() {
        actual.save_png(&reference_path).expect("write reference");
    }
    let reference = Image::load_png(&reference_path)
        .expect("reference image (PALPA_UPDATE_REFERENCE=1 writes it)");
    assert_eq!(
        (reference.width, reference.height),
        (actual.width, actual.height)
    );
    let mut diff = actual.clone();
    let mut different = 0usize;
    for (i, (a, r)) in actual
        .rgba
        .chunks(4)
        .zip(reference.rgba.chunks(4))
        .enumerate()
    {
        let d = (0..3).map(|c| a[c].abs_diff(r[c])).max().unwrap_or(0);
        if d > PIXEL_TOLERANCE {
            different += 1;
        }
        let v = d.saturating_mul(4);
        diff.rgba[4 * i..4 * i + 4].copy_from_slice(&[v, v, v, 255]);
    }
    let fraction = different as f64 / (actual.width * actual.height) as f64;
    if fraction > MAX_DIFFERENT_FRACTION {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR"));
        actual
            .save_png(&out.join("liver-press-actual.png"))
            .expect("write actual");
        diff.save_png(&out.join("liver-press-diff.png"))
            .expect("write diff");
        panic!(
            "{:.3}% of pixels differ by more than {PIXEL_TOLERANCE} (allowed {:.3}%); \
             see {}/liver-press-actual.png and -diff.png",
            100.0 * fraction,
            100.0 * MAX_DIFFERENT_FRACTION,
            out.display()
        );
    }
    // The picture is not empty: the organ covers a good part of the frame.
    let organ_like = actual
        .rgba
        .chunks(4)
        .filter(|p| p[0] > p[1].saturating_add(40))
        .count();
    assert!(
        organ_like > 5_000,
        "only {organ_like} organ-coloured pixels"
    );
}

/// The network scene against a reference image, for a toggle switch built here on
/// [0, 2]: the 3-D landscape and the distribution window (joint heat map, axes,
/// marginals), i.e. everything right of the panel, whose timings change run to run.
#[test]
fn the_network_scene_matches_the_reference_image() {
    use palpa_app::network::offscreen::{NetworkHeadless, run};
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("toggle.palpa");
    common::small_toggle(&file);
    let (_, actual) = run(&NetworkHeadless {
        scene: file.display().to_string(),
        // egui lays windows out unseen on their first frame.
        frames: 3,
        size: (900, 480),
        out: None,
        exact_check: false,
        ui: true,
        path: None,
        display: Default::default(),
        data: None,
        fit: false,
        posterior: None,
    })
    .expect("renders");
    // The drawer ends at x = 352 (see `layout::DRAWER_WIDTH_PT`).
    let (x0, w, h) = (360usize, 900usize, 480usize);
    let mut crop = Image {
        width: (w - x0) as u32,
        height: h as u32,
        rgba: Vec::with_capacity((w - x0) * h * 4),
    };
    for y in 0..h {
        crop.rgba
            .extend_from_slice(&actual.rgba[4 * (y * w + x0)..4 * (y * w + w)]);
    }
    let reference_path = reference_dir().join("network-toggle.png");
    if std::env::var_os("PALPA_UPDATE_REFERENCE").is_some() {
        crop.save_png(&reference_path).expect("write reference");
    }
    let reference = Image::load_png(&reference_path)
        .expect("reference image (PALPA_UPDATE_REFERENCE=1 writes it)");
    assert_eq!(
        (reference.width, reference.height),
        (crop.width, crop.height)
    );
    let fraction = different_fraction(&crop, &reference);
    if fraction > MAX_DIFFERENT_FRACTION {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("network-toggle-actual.png");
        crop.save_png(&out).expect("write actual");
        panic!(
            "{:.3}% of pixels differ (allowed {:.3}%); see {}",
            100.0 * fraction,
            100.0 * MAX_DIFFERENT_FRACTION,
            out.display()
        );
    }
    // The heat map is there: pixels of the ramp's hot end.
    let hot = crop
        .rgba
        .chunks(4)
        .filter(|p| p[0] > 180 && p[2] < 80)
        .count();
    assert!(hot > 20, "only {hot} hot pixels");
}

/// The GPU's failures become messages, not wgpu's default panic: a deliberately
/// invalid buffer and an invalid shader (named with its line) are recorded and returned
/// by the next `submit_and_wait`; destroying the device flags it lost, which the window
/// answers by making a new device and keeping the session.
#[test]
fn gpu_errors_become_messages_and_a_lost_device_is_flagged() {
    let gpu = gpu();
    // Mapped at creation, a buffer's size must be a multiple of 4.
    let _bad = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("deliberately invalid"),
        size: 3,
        usage: wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: true,
    });
    let encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    let e = gpu
        .submit_and_wait(encoder)
        .expect_err("the invalid buffer is reported");
    assert!(e.to_string().contains("validation"), "{e}");
    assert_eq!(gpu.health.error_count(), 1);
    assert!(
        gpu.health.take_message().is_none(),
        "a message is shown once"
    );

    let _shader = gpu
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("broken.wgsl"),
            source: wgpu::ShaderSource::Wgsl("fn main( {\n".into()),
        });
    let encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    let e = gpu
        .submit_and_wait(encoder)
        .expect_err("the broken shader is reported");
    let text = format!("{e:#}");
    assert!(text.contains("broken.wgsl"), "names the shader: {text}");
    assert_eq!(gpu.health.error_count(), 2);

    assert!(!gpu.health.is_lost());
    gpu.device.destroy();
    let _ = gpu.device.poll(wgpu::PollType::wait_indefinitely());
    assert!(gpu.health.is_lost(), "a destroyed device is flagged lost");
    assert!(
        gpu.health
            .take_message()
            .is_some_and(|m| m.contains("lost")),
        "and says so"
    );
}

/// The region mode draws what was painted: after a stroke with the fixed brush the
/// frame has blue (fixed) and green (palpable) organ pixels; leaving the mode brings
/// the tissue colours back (no blue left).
#[test]
fn the_region_mode_draws_the_painted_regions() {
    use glam::Vec2;
    use palpa_app::input::{Button, InputEvent, PointerId};
    let gpu = gpu();
    let loaded = scenes::built_in().expect("built-in scene");
    let mut session = Session::new(loaded.scene, Box::new(NoHaptics)).expect("session");
    let size = (320, 240);
    let view = Vec2::new(size.0 as f32, size.1 as f32);
    session.frame();
    session.set_painting(true);
    let c = view / 2.0;
    session.handle(
        InputEvent::PointerDown {
            id: PointerId::Mouse,
            button: Button::Primary,
            pos_px: c - Vec2::new(30.0, 0.0),
            time_s: 0.0,
        },
        view,
    );
    for k in 1..=6 {
        session.handle(
            InputEvent::PointerMove {
                id: PointerId::Mouse,
                pos_px: c + Vec2::new(-30.0 + 10.0 * k as f32, 0.0),
                time_s: 0.01 * f64::from(k),
            },
            view,
        );
    }
    session.handle(
        InputEvent::PointerUp {
            id: PointerId::Mouse,
            time_s: 0.1,
        },
        view,
    );
    assert!(session.painter.as_ref().expect("on").counts().0 > 0);
    let mut renderer = Renderer::new(&gpu.device, FORMAT, &session.scene);
    let target = Offscreen::new(&gpu.device, size, gpu.can_reinterpret());
    let mut render = |session: &mut Session| {
        let input = session.frame();
        let mut encoder = renderer.encode_frame(&gpu, &target.view, size, &input);
        target.encode_copy(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        target.read(&gpu.device).expect("read back")
    };
    // Blue clearly above red and green; green clearly above red and blue.
    let count = |img: &Image, f: &dyn Fn(i32, i32, i32) -> bool| {
        img.rgba
            .chunks(4)
            .filter(|p| f(i32::from(p[0]), i32::from(p[1]), i32::from(p[2])))
            .count()
    };
    let blue = |r: i32, g: i32, b: i32| b > r + 40 && b > g + 30;
    let green = |r: i32, g: i32, b: i32| g > r + 40 && g > b + 40;
    let painted = render(&mut session);
    painted
        .save_png(&Path::new(env!("CARGO_TARGET_TMPDIR")).join("regions.png"))
        .expect("png");
    assert!(count(&painted, &blue) > 50, "fixed region drawn blue");
    assert!(count(&painted, &green) > 50, "palpable region drawn green");
    session.set_painting(false);
    let normal = render(&mut session);
    assert_eq!(count(&normal, &blue), 0, "tissue colours back");
}
