//! The force loop: a named thread that evaluates the contact force at 1 kHz.
//!
//! ```text
//! input/render thread            force thread (1 kHz, absolute deadlines)
//! ───────────────────            ─────────────────────────────────────────
//! commands.store(probe) ──────►  cmd = commands.load()
//!                                contact law on 9 rows of X  (PalpationScene::contact)
//!                                tissue law F(s, d)          (Tissue, if the scene has one)
//!                                samples.store(force)  ──────►  render reads latest force
//!                                haptic.apply(force)            (deforms the surface with it)
//!                                every 50 ticks: stats.store(rate, p50/p99 period, misses)
//! ```
//!
//! Nothing crosses between the threads but [`Latest`] cells: no mutex, no channel, no
//! allocation after start-up, no GPU call. The schedule is absolute: tick `k` is due at
//! `start + k·period`; the thread sleeps until shortly before the deadline and spins the
//! rest, so jitter is the spin's, not the OS timer's. A tick that starts after the next
//! deadline has passed makes those deadlines **missed**: they are counted and skipped, and
//! the schedule stays on its grid instead of drifting.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use bytemuck::{Pod, Zeroable};
use palpa_core::pgd::nodule::amplification::EffectCurve;
use palpa_core::pgd::nodule::table::depth_under_force;
use palpa_core::scene::{PalpationScene, ProbePoint};
use palpa_core::tissue::online::Tissue;

use crate::latest::Latest;

/// How the indentation is controlled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PressMode {
    /// The pointer sets the depth; the force follows from the compliance.
    Depth,
    /// The slider (or the trigger) sets the force.
    Force,
}

impl PressMode {
    // The wire encoding stays in this file: `ProbeCommand` crosses threads as plain
    // bytes, so its fields are integers.
    fn to_wire(self) -> u32 {
        match self {
            PressMode::Depth => 0,
            PressMode::Force => 1,
        }
    }

    fn from_wire(v: u32) -> PressMode {
        if v == 1 {
            PressMode::Force
        } else {
            PressMode::Depth
        }
    }
}

/// What the input side asks of the force loop (latest value wins).
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct ProbeCommand {
    /// Palpable triangle of the probe point.
    pub triangle: u32,
    /// 0: the probe is lifted (no force).
    pub active: u32,
    /// [`PressMode`] on the wire: see [`ProbeCommand::mode`].
    mode: u32,
    /// Modes kept (the accuracy knob).
    pub modes: u32,
    pub bary: [f32; 3],
    pub target: f32,
    /// A hidden nodule's effect at this point, `F_with/F_without − 1` at equal depth,
    /// as a function of the depth (flat for the linear model; zero: none): the input
    /// side reads it from the case's table where it places the probe, so the loop
    /// interpolates and multiplies, it does not look anything up.
    pub nodule: EffectCurve,
}

impl ProbeCommand {
    /// No probe on the organ, `modes` kept.
    pub fn lifted(modes: u32) -> ProbeCommand {
        ProbeCommand {
            modes,
            ..ProbeCommand::default()
        }
    }

    /// A probe at `point`, pressing or not, to `target` (mm in depth mode, N in force
    /// mode).
    pub fn at(point: ProbePoint, pressing: bool, mode: PressMode, modes: u32, target: f32) -> Self {
        ProbeCommand {
            triangle: point.triangle,
            active: u32::from(pressing),
            mode: mode.to_wire(),
            modes,
            bary: point.bary.map(|b| b as f32),
            target,
            nodule: EffectCurve::default(),
        }
    }

    pub fn mode(&self) -> PressMode {
        PressMode::from_wire(self.mode)
    }

    pub fn point(&self) -> ProbePoint {
        ProbePoint {
            triangle: self.triangle,
            bary: self.bary.map(f64::from),
        }
    }
}

/// Status of a [`ForceSample`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleStatus {
    /// No probe pressing.
    Idle,
    Ok,
    /// The contact law failed (e.g. non-positive compliance with too few modes): zero
    /// force.
    Failed,
}

impl SampleStatus {
    fn to_wire(self) -> u32 {
        match self {
            SampleStatus::Idle => 0,
            SampleStatus::Ok => 1,
            SampleStatus::Failed => 2,
        }
    }

    fn from_wire(v: u32) -> SampleStatus {
        match v {
            1 => SampleStatus::Ok,
            2 => SampleStatus::Failed,
            _ => SampleStatus::Idle,
        }
    }
}

/// What the force loop publishes every tick.
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct ForceSample {
    pub tick: u64,
    /// Force the probe applies to the tissue, N.
    pub force_n: [f32; 3],
    pub magnitude_n: f32,
    /// Indentation along the push direction, mm.
    pub depth_mm: f32,
    pub compliance_mm_per_n: f32,
    /// Time of the contact evaluation, ns.
    pub eval_ns: f32,
    /// [`SampleStatus`] on the wire: see [`ForceSample::status`].
    status: u32,
    /// The nodule-free linear tissue's force at the same depth, N (equal to
    /// `magnitude_n` without a depth law or a nodule): what the drawn surface's field is
    /// scaled by, so it shows the sample's depth.
    pub linear_n: f32,
    /// 1 if the depth asked, or the depth the force asked needs, lay beyond the law's
    /// range: depth and force are both held at its end (the asked value stays in
    /// `command.target`).
    pub beyond_law: u32,
    /// The contact point at rest, mm.
    pub point_mm: [f32; 3],
    /// The factor a hidden nodule multiplied the force by (1 without one).
    pub nodule_gain: f32,
    /// The command this sample answers.
    pub command: ProbeCommand,
}

impl ForceSample {
    pub fn status(&self) -> SampleStatus {
        SampleStatus::from_wire(self.status)
    }

    pub fn set_status(&mut self, status: SampleStatus) {
        self.status = status.to_wire();
    }
}

/// Loop statistics since start or since the last [`ForceLoop::reset_stats`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct LoopStats {
    pub ticks: u64,
    pub missed_deadlines: u64,
    pub elapsed_s: f64,
    pub rate_hz: f64,
    pub period_us_p50: f64,
    pub period_us_p99: f64,
    pub period_us_max: f64,
    pub eval_us_p50: f64,
    /// What scheduling the thread got: see [`LoopStats::priority`].
    priority: u32,
    pub _pad: u32,
}

impl LoopStats {
    /// What scheduling the force thread got.
    pub fn priority(&self) -> crate::priority::Priority {
        crate::priority::Priority::from_wire(self.priority)
    }
}

/// Receives the contact force at every tick of the force loop: a gamepad's rumble now,
/// a haptic arm later. Called on the force thread: must not block or allocate.
pub trait HapticDevice: Send {
    fn apply(&mut self, force_n: [f32; 3]);
}

/// No haptic output.
#[derive(Debug, Default)]
pub struct NoHaptics;
impl HapticDevice for NoHaptics {
    fn apply(&mut self, _force_n: [f32; 3]) {}
}

/// Publishes the force magnitude in an atomic, for a device driven from another thread
/// at its own rate (gamepad rumble is updated at frame rate; motors cannot follow 1 kHz).
#[derive(Debug, Clone, Default)]
pub struct AtomicHaptics {
    magnitude_bits: Arc<AtomicU32>,
}
impl AtomicHaptics {
    pub fn magnitude_n(&self) -> f32 {
        f32::from_bits(self.magnitude_bits.load(Ordering::Relaxed))
    }
}
impl HapticDevice for AtomicHaptics {
    fn apply(&mut self, f: [f32; 3]) {
        let m = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
        self.magnitude_bits.store(m.to_bits(), Ordering::Relaxed);
    }
}

/// The running force loop; stops and joins its thread when dropped.
#[derive(Debug)]
pub struct ForceLoop {
    commands: Arc<Latest<ProbeCommand>>,
    samples: Arc<Latest<ForceSample>>,
    stats: Arc<Latest<LoopStats>>,
    stop: Arc<AtomicBool>,
    reset: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
}

/// Timing of the loop.
#[derive(Debug, Clone, Copy)]
pub struct LoopTiming {
    pub period: Duration,
    /// Sleep until this long before a deadline, then spin.
    pub spin: Duration,
}

impl Default for LoopTiming {
    fn default() -> Self {
        LoopTiming {
            period: Duration::from_millis(1),
            // Linux's sleep overshoots by ~50–100 µs (timer slack plus wake-up).
            spin: Duration::from_micros(250),
        }
    }
}

impl ForceLoop {
    /// Starts the thread `palpa-force`.
    pub fn spawn(
        scene: Arc<PalpationScene>,
        law: Option<Arc<Tissue>>,
        haptic: Box<dyn HapticDevice>,
        timing: LoopTiming,
    ) -> std::io::Result<Self> {
        let commands = Arc::new(Latest::<ProbeCommand>::default());
        let samples = Arc::new(Latest::<ForceSample>::default());
        let stats = Arc::new(Latest::<LoopStats>::default());
        let stop = Arc::new(AtomicBool::new(false));
        let reset = Arc::new(AtomicBool::new(false));
        let worker = Worker {
            scene,
            law,
            haptic,
            timing,
            commands: Arc::clone(&commands),
            samples: Arc::clone(&samples),
            stats: Arc::clone(&stats),
            stop: Arc::clone(&stop),
            reset: Arc::clone(&reset),
        };
        let handle = std::thread::Builder::new()
            .name("palpa-force".into())
            .spawn(move || worker.run())?;
        Ok(ForceLoop {
            commands,
            samples,
            stats,
            stop,
            reset,
            handle: Some(handle),
        })
    }

    pub fn command(&self, c: ProbeCommand) {
        self.commands.store(c);
    }
    pub fn latest(&self) -> ForceSample {
        self.samples.load()
    }
    pub fn stats(&self) -> LoopStats {
        self.stats.load()
    }
    /// Restarts the statistics window (e.g. after warm-up).
    pub fn reset_stats(&self) {
        self.reset.store(true, Ordering::Release);
    }
}

impl Drop for ForceLoop {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(h) = self.handle.take() {
            // A panic on the force thread has already been reported by the panic hook.
            let _ = h.join();
        }
    }
}

struct Worker {
    scene: Arc<PalpationScene>,
    /// The nonlinear tissue, if the scene has one (else linear).
    law: Option<Arc<Tissue>>,
    haptic: Box<dyn HapticDevice>,
    timing: LoopTiming,
    commands: Arc<Latest<ProbeCommand>>,
    samples: Arc<Latest<ForceSample>>,
    stats: Arc<Latest<LoopStats>>,
    stop: Arc<AtomicBool>,
    reset: Arc<AtomicBool>,
}

/// Fixed-bin histogram (allocated once, before the loop starts).
struct Histogram {
    bins: Vec<u32>,
    bin_width: f64,
    count: u64,
    max: f64,
}

impl Histogram {
    fn new(bins: usize, bin_width: f64) -> Self {
        Histogram {
            bins: vec![0; bins],
            bin_width,
            count: 0,
            max: 0.0,
        }
    }
    fn add(&mut self, v: f64) {
        let i = ((v / self.bin_width) as usize).min(self.bins.len() - 1);
        self.bins[i] += 1;
        self.count += 1;
        self.max = self.max.max(v);
    }
    fn clear(&mut self) {
        self.bins.fill(0);
        self.count = 0;
        self.max = 0.0;
    }
    /// Upper edge of the bin holding the q-quantile (0 when empty).
    fn quantile(&self, q: f64) -> f64 {
        if self.count == 0 {
            return 0.0;
        }
        let target = (q * self.count as f64).ceil().max(1.0) as u64;
        let mut seen = 0u64;
        for (i, &b) in self.bins.iter().enumerate() {
            seen += u64::from(b);
            if seen >= target {
                return (i as f64 + 0.5) * self.bin_width;
            }
        }
        self.max
    }
}

impl Worker {
    fn run(mut self) {
        let priority = crate::priority::raise_current_thread();
        let period = self.timing.period;
        let mut scratch = self.scene.contact_scratch();
        // 1 µs bins up to 20 periods; 10 ns bins up to 100 µs.
        let mut periods = Histogram::new(20_000, 1.0);
        let mut evals = Histogram::new(10_000, 10.0);
        let start = Instant::now();
        let mut window_start = start;
        let mut window_ticks = 0u64;
        let mut missed = 0u64;
        let mut k: u32 = 0;
        let mut last_tick: Option<Instant> = None;
        let mut tick_count = 0u64;
        while !self.stop.load(Ordering::Acquire) {
            k += 1;
            let deadline = start + period * k;
            let now = Instant::now();
            if deadline > now + self.timing.spin {
                std::thread::sleep(deadline - now - self.timing.spin);
            }
            while Instant::now() < deadline {
                std::hint::spin_loop();
            }
            let t0 = Instant::now();
            let late = t0 - deadline;
            if late >= period {
                // The following deadlines have passed too: count them and stay on the grid.
                let skipped = (late.as_nanos() / period.as_nanos()) as u32;
                missed += u64::from(skipped);
                k += skipped;
            }
            if self.reset.swap(false, Ordering::AcqRel) {
                periods.clear();
                evals.clear();
                missed = 0;
                window_ticks = 0;
                window_start = t0;
                last_tick = None;
            }
            if let Some(prev) = last_tick {
                periods.add((t0 - prev).as_secs_f64() * 1e6);
            }
            last_tick = Some(t0);
            tick_count += 1;
            window_ticks += 1;

            let cmd = self.commands.load();
            let sample = self.evaluate(&cmd, tick_count, &mut scratch);
            if sample.status() == SampleStatus::Ok {
                evals.add(f64::from(sample.eval_ns));
            }
            self.haptic.apply(sample.force_n);
            self.samples.store(sample);

            if tick_count.is_multiple_of(50) {
                let elapsed_s = (Instant::now() - window_start).as_secs_f64();
                self.stats.store(LoopStats {
                    ticks: window_ticks,
                    missed_deadlines: missed,
                    elapsed_s,
                    rate_hz: if elapsed_s > 0.0 {
                        window_ticks as f64 / elapsed_s
                    } else {
                        0.0
                    },
                    period_us_p50: periods.quantile(0.5),
                    period_us_p99: periods.quantile(0.99),
                    period_us_max: periods.max,
                    eval_us_p50: evals.quantile(0.5) / 1000.0,
                    priority: priority.to_wire(),
                    _pad: 0,
                });
            }
        }
    }

    fn evaluate(
        &self,
        cmd: &ProbeCommand,
        tick: u64,
        scratch: &mut palpa_core::scene::ContactScratch,
    ) -> ForceSample {
        let mut s = ForceSample {
            tick,
            command: *cmd,
            nodule_gain: 1.0,
            ..ForceSample::default()
        };
        if cmd.active == 0 || cmd.target.is_nan() || cmd.target <= 0.0 {
            s.set_status(SampleStatus::Idle);
            return s;
        }
        let t = Instant::now();
        let contact = self
            .scene
            .contact(&cmd.point(), cmd.modes as usize, scratch);
        s.eval_ns = t.elapsed().as_nanos() as f32;
        match contact {
            Ok(c) => {
                let target = f64::from(cmd.target);
                let comp = c.compliance_mm_per_n;
                // A nodule multiplies the force at depth `d` by `gain(d)`: the linear
                // tissue's effect, amplified in the nonlinear tissue as its own press
                // loads the nodule (docs/methods.md §2i).
                let curve = &cmd.nodule;
                let gain = |d: f64| 1.0 + curve.at(d);
                if !(curve.effect.is_finite()
                    && curve.at_depth.iter().all(|e| e.is_finite() && *e > -1.0)
                    && gain(0.0) > 0.0)
                {
                    s.set_status(SampleStatus::Failed);
                    return s;
                }
                let (force, depth, beyond) = match (&self.law, cmd.mode()) {
                    (None, PressMode::Force) => (target, target * comp / gain(0.0), false),
                    (None, PressMode::Depth) => (gain(0.0) * target / comp, target, false),
                    // Impedance rendering: depth in, the nonlinear force out.
                    // Past the law's limit there both are held at it (the surface is
                    // drawn at the same depth).
                    (Some(law), PressMode::Depth) => {
                        let (f, beyond) = law.force_n(&cmd.point(), target, comp);
                        let d = target.min(law.limit_mm(&cmd.point()).0);
                        (gain(d) * f, d, beyond)
                    }
                    // The trigger's force in, the depth that needs it out. Past the
                    // law's limit the depth is held there, and so is the force: the
                    // tissue's at the held depth, not the trigger's (the asked force
                    // stays in the sample's command), so the sample lies on the curve.
                    (Some(law), PressMode::Force) => {
                        let (d, beyond) = depth_under_force(target, curve, |f| {
                            law.depth_mm(&cmd.point(), f, comp)
                        });
                        let force = if beyond {
                            gain(d) * law.force_n(&cmd.point(), d, comp).0
                        } else {
                            target
                        };
                        (force, d, beyond)
                    }
                };
                s.nodule_gain = if self.law.is_some() {
                    gain(depth)
                } else {
                    gain(0.0)
                } as f32;
                s.linear_n = (depth / comp) as f32;
                s.point_mm = c.point_mm.map(|v| v as f32);
                s.beyond_law = u32::from(beyond);
                s.force_n = c.push_dir.map(|d| (d * force) as f32);
                s.magnitude_n = force as f32;
                s.depth_mm = depth as f32;
                s.compliance_mm_per_n = c.compliance_mm_per_n as f32;
                s.set_status(SampleStatus::Ok);
            }
            Err(_) => s.set_status(SampleStatus::Failed),
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_quantiles() {
        let mut h = Histogram::new(100, 1.0);
        for v in 0..100 {
            h.add(v as f64);
        }
        assert_eq!(h.quantile(0.5), 49.5);
        assert_eq!(h.quantile(0.99), 98.5);
        h.add(1e9);
        assert_eq!(h.max, 1e9);
        h.clear();
        assert_eq!(h.quantile(0.5), 0.0);
    }
}
