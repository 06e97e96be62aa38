//! `palpa lab bench deform`: the surface deformed on the GPU (compute shader) against on
//! the CPU, on the adapter at hand, measured in one run.
//!
//! A session presses the scene at its default probe; for each count of modes kept and
//! each path, frames are evaluated as the app evaluates them and their deformation
//! recorded and submitted alone (no drawing), then waited for. Per frame:
//! - `cpu_us`: what the frame's deformation costs the CPU: the evaluation (the
//!   coefficients, the near field and the tissue's residual; on the CPU path also
//!   every row and the normals) plus recording, uploading and submitting;
//! - `wait_us`: from the submission until the device is done (on a real GPU that time
//!   overlaps the CPU's next work; on a software adapter it is CPU time too);
//! - `upload_bytes`: what goes to the device.
//!
//! The error column compares the two surfaces of the same frame: the compute shader's
//! f32 sums against the CPU's double-precision evaluation (rounded to f32), the
//! largest position difference over the vertices (mm) and the largest angle between
//! their normals (degrees).

use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use clap::Args;
use palpa_app::force::NoHaptics;
use palpa_app::offscreen::settle;
use palpa_app::render::FrameInput;
use palpa_app::render::deform::{Deform, DeformOn, MAX_GPU_MODES, Vec4Data};
use palpa_app::render::gpu::Gpu;
use palpa_app::session::Session;
use serde::Serialize;

#[derive(Debug, Args)]
pub struct DeformBenchArgs {
    /// `liver` (the built-in default scene) or a palpation `.palpa` file.
    #[arg(long, default_value = "liver")]
    scene: String,
    /// How deep the probe presses at the scene's default probe point, mm.
    #[arg(long, default_value_t = 8.0)]
    depth_mm: f32,
    /// Modes kept, comma-separated (default: each count from 1 to all the scene has).
    #[arg(long, value_delimiter = ',')]
    modes: Vec<u32>,
    /// Timed frames per count of modes and path (after 10 untimed ones).
    #[arg(long, default_value_t = 200)]
    frames: u32,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Serialize)]
struct Row {
    modes: u32,
    path: &'static str,
    cpu_us_p50: f64,
    wait_us_p50: f64,
    total_us_p50: f64,
    upload_bytes: usize,
    /// Largest distance between this frame's GPU and CPU surfaces, mm.
    gpu_vs_cpu_mm: f64,
    /// Largest angle between their normals, degrees.
    gpu_vs_cpu_normal_deg: f64,
    vertices: u32,
    drawn_vertices: u32,
    adapter: String,
    device_type: String,
}

pub fn run(args: &DeformBenchArgs) -> anyhow::Result<()> {
    if !(args.depth_mm.is_finite() && (0.0..=15.0).contains(&args.depth_mm)) {
        bail!(
            "--depth-mm {}: expected a depth from 0 to 15 mm",
            args.depth_mm
        );
    }
    if args.frames == 0 {
        bail!("--frames 0: expected at least one timed frame");
    }
    let loaded = palpa_app::scenes::load(&args.scene)?;
    let gpu = Gpu::headless()?;
    let deform = Deform::new(&gpu.device, &loaded.scene);
    let mut session = Session::with_law(loaded.scene, loaded.law, Box::new(NoHaptics))
        .context("starting the force thread")?;
    let all = session.scene.modes() as u32;
    let modes = if args.modes.is_empty() {
        (1..=all.min(MAX_GPU_MODES as u32)).collect()
    } else {
        args.modes.clone()
    };
    if let Some(n) = modes.iter().find(|&&n| n == 0 || n > all) {
        bail!("--modes {n}: expected from 1 to the {all} modes the scene has");
    }
    if session.controls.probe.is_none() {
        bail!("{}: no palpable point to press at", args.scene);
    }
    session.controls.pressing = true;
    session.controls.depth_mm = args.depth_mm;
    session.force.command(session.controls.command());
    settle(&session, Duration::from_secs(2));
    let adapter = gpu.report();
    let vertices = deform.vertex_count();
    let drawn = deform.drawn_vertex_count();
    if !args.json {
        println!(
            "{} vertices ({} drawn) pressed {} mm on {} ({}, {}); {} frames each, medians",
            vertices,
            drawn,
            args.depth_mm,
            adapter.name,
            adapter.backend,
            adapter.device_type,
            args.frames
        );
        println!(
            "{:>5}  {:>4}  {:>9}  {:>9}  {:>9}  {:>8}  {:>12}  {:>10}",
            "modes", "path", "cpu µs", "wait µs", "total µs", "upload", "gpu−cpu mm", "normal °"
        );
    }
    for n in modes {
        session.controls.modes = n;
        let (gpu_vs_cpu_mm, normal_deg) = compare(&gpu, &deform, &mut session)?;
        let mut rows = Vec::with_capacity(2);
        for path in [DeformOn::Gpu, DeformOn::Cpu] {
            session.deform_on = path;
            let (cpu_us, wait_us, total_us) =
                time_frames(&gpu, &deform, &mut session, args.frames)?;
            let upload_bytes = match path {
                DeformOn::Gpu => MAX_GPU_MODES * 4 + 16 + vertices as usize * 16,
                DeformOn::Cpu => drawn as usize * 32,
            };
            rows.push(Row {
                modes: n,
                path: path.name(),
                cpu_us_p50: cpu_us,
                wait_us_p50: wait_us,
                total_us_p50: total_us,
                upload_bytes,
                gpu_vs_cpu_mm,
                gpu_vs_cpu_normal_deg: normal_deg,
                vertices,
                drawn_vertices: drawn,
                adapter: adapter.name.clone(),
                device_type: adapter.device_type.clone(),
            });
        }
        for r in &rows {
            if args.json {
                println!("{}", serde_json::to_string(r)?);
            } else {
                println!(
                    "{:>5}  {:>4}  {:>9.1}  {:>9.1}  {:>9.1}  {:>8}  {:>12.2e}  {:>10.2e}",
                    r.modes,
                    r.path,
                    r.cpu_us_p50,
                    r.wait_us_p50,
                    r.total_us_p50,
                    r.upload_bytes,
                    r.gpu_vs_cpu_mm,
                    r.gpu_vs_cpu_normal_deg
                );
            }
        }
        if !args.json {
            println!(
                "{n:>5}  cpu/gpu: CPU time {:.2}x, total {:.2}x",
                rows[1].cpu_us_p50 / rows[0].cpu_us_p50,
                rows[1].total_us_p50 / rows[0].total_us_p50
            );
        }
    }
    Ok(())
}

/// One frame deformed both ways: the largest position distance (mm) and normal angle
/// (degrees) between the compute shader's surface and the CPU's.
fn compare(gpu: &Gpu, deform: &Deform, session: &mut Session) -> anyhow::Result<(f64, f64)> {
    session.deform_on = DeformOn::Cpu;
    let input = session.frame();
    let cpu = input.cpu_surface.context("the CPU path gives a surface")?;
    let (cpu_positions, cpu_normals) = (cpu.positions.to_vec(), cpu.normals.to_vec());
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    // The same frame by the compute passes.
    let input = FrameInput {
        cpu_surface: None,
        ..input
    };
    deform.record(&gpu.queue, &mut encoder, &input);
    gpu.queue.submit([encoder.finish()]);
    let (positions, normals) = deform.read_back(&gpu.device, &gpu.queue)?;
    let distance = |a: &Vec4Data, b: &Vec4Data| {
        (0..3)
            .map(|k| f64::from(a[k] - b[k]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let angle = |a: &Vec4Data, b: &Vec4Data| {
        let dot: f64 = (0..3).map(|k| f64::from(a[k]) * f64::from(b[k])).sum();
        dot.clamp(-1.0, 1.0).acos().to_degrees()
    };
    let worst_mm = positions
        .iter()
        .zip(&cpu_positions)
        .map(|(a, b)| distance(a, b))
        .fold(0.0, f64::max);
    let worst_deg = normals
        .iter()
        .zip(&cpu_normals)
        .map(|(a, b)| angle(a, b))
        .fold(0.0, f64::max);
    Ok((worst_mm, worst_deg))
}

/// Medians over `frames` frames of the CPU time, the wait for the device and both.
fn time_frames(
    gpu: &Gpu,
    deform: &Deform,
    session: &mut Session,
    frames: u32,
) -> anyhow::Result<(f64, f64, f64)> {
    let mut cpu = Vec::with_capacity(frames as usize);
    let mut wait = Vec::with_capacity(frames as usize);
    let mut total = Vec::with_capacity(frames as usize);
    for i in 0..frames + 10 {
        let t0 = Instant::now();
        let input = session.frame();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        deform.record(&gpu.queue, &mut encoder, &input);
        gpu.queue.submit([encoder.finish()]);
        let t1 = Instant::now();
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow::anyhow!("waiting for the GPU failed: {e}"))?;
        let t2 = Instant::now();
        if i >= 10 {
            cpu.push((t1 - t0).as_secs_f64() * 1e6);
            wait.push((t2 - t1).as_secs_f64() * 1e6);
            total.push((t2 - t0).as_secs_f64() * 1e6);
        }
    }
    Ok((median(cpu), median(wait), median(total)))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
