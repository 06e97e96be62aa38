//! `palpa lab bench eval`: on-line evaluation speed against the memory-bandwidth bound,
//! measured in the same run.
//!
//! For each (rows R, modes N, precision) a synthetic model of that size is built and
//! timed: a full reconstruction `X·c` (`eval_ns`) against a plain streaming sum over the
//! same bytes (`bandwidth_ns`); their ratio says how close evaluation sits to the
//! bandwidth bound. Both are the minimum over interleaved repetitions, so a transient
//! disturbance on a shared machine hits neither more than the other.
//! `particularize_ns` and `contact_ns` are means over a batch of calls at random
//! probe positions and random contact nodes (cold rows, the conservative case).

mod build;
mod cme;
mod deform;
mod dsmts;
mod fe;
mod fit;
mod lanes;
mod nodule;
mod nodule_store;
mod pgd;
mod views;

use std::hint::black_box;
use std::time::{Duration, Instant};

use anyhow::bail;
use clap::{Args, Subcommand};
use palpa_core::axis::Discretization;
use palpa_core::kernels::stream_sum;
use palpa_core::rng::Rng;
use palpa_core::synthetic::palpation_like;
use palpa_core::{ParamValue, Precision, Scalar, SeparatedModel};
use serde::Serialize;

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Reconstruction, particularization and contact-node evaluation timings.
    Eval(EvalArgs),
    /// Full FE cost per level and element, locking, SVK Newton (JSON lines).
    Fe(fe::FeBenchArgs),
    /// Off-line vademecum cost: PGD (per block size) against brute force + SVD.
    Offline(pgd::OfflineBenchArgs),
    /// Gene-network meta-model: off-line and evaluation time, accuracy against FSP,
    /// and the SSA cost of the same marginal accuracy.
    Cme(cme::CmeBenchArgs),
    /// The signaling cascade's views model over all t: build time, file size, the
    /// leading marginals against their exact closed chain at every t, evaluation time.
    Views(views::ViewsBenchArgs),
    /// The Discrete Stochastic Model Test Suite from its SBML files: FSP and PGD
    /// against the published mean and sd, the SSA by the suite's own test, times.
    Dsmts(dsmts::DsmtsBenchArgs),
    /// Rates from data: coverage of the 95 % intervals on seeded synthetic data sets,
    /// the maximum against the exact-FSP likelihood's, likelihood, fit and posterior
    /// costs against FSP's.
    Fit(fit::FitBenchArgs),
    /// A nodule's effect on the probe force per radius and mesh level: its mesh
    /// convergence, and which radii a level resolves.
    Nodule(nodule::NoduleBenchArgs),
    /// A nodule as coordinates of the linear vademecum (stored interior responses and
    /// Woodbury's identity) against one FE solve per configuration: store size and
    /// build, placing a nodule on one core, a probe's correction, and their gap.
    NoduleStore(nodule_store::NoduleStoreBenchArgs),
    /// The palpation surface deformed on the GPU (compute shader) against on the CPU:
    /// time per frame and how far apart the two surfaces are, on the adapter at hand.
    Deform(deform::DeformBenchArgs),
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Field rows (node × component), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [10_000, 30_000, 60_000])]
    rows: Vec<usize>,
    /// Modes, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [50, 167, 400])]
    modes: Vec<usize>,
    /// Storage precision(s): f32, f64.
    #[arg(long, value_delimiter = ',', default_values = ["f32", "f64"])]
    precision: Vec<Precision>,
    /// Minimum measuring time per timed quantity, in milliseconds.
    #[arg(long, default_value_t = 400)]
    min_time_ms: u64,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Serialize)]
struct EvalRow {
    rows: usize,
    modes: usize,
    precision: &'static str,
    bytes: usize,
    eval_ns: f64,
    bandwidth_ns: f64,
    ratio: f64,
    eval_gb_per_s: f64,
    bandwidth_gb_per_s: f64,
    particularize_ns: f64,
    contact_ns: f64,
}

pub fn run(cmd: &BenchCommand) -> anyhow::Result<()> {
    match cmd {
        BenchCommand::Eval(args) => eval(args),
        BenchCommand::Fe(args) => fe::run(args),
        BenchCommand::Deform(args) => deform::run(args),
        BenchCommand::Offline(args) => pgd::run(args),
        BenchCommand::Cme(args) => cme::run(args),
        BenchCommand::Views(args) => views::run(args),
        BenchCommand::Dsmts(args) => dsmts::run(args),
        BenchCommand::Fit(args) => fit::run(args),
        BenchCommand::Nodule(args) => nodule::run(args),
        BenchCommand::NoduleStore(args) => nodule_store::run(args),
    }
}

fn eval(args: &EvalArgs) -> anyhow::Result<()> {
    if args.rows.iter().chain(&args.modes).any(|&v| v == 0) {
        bail!("--rows and --modes must be positive");
    }
    // Each measured model holds rows × modes values: refuse what memory cannot hold
    // before the table starts, rather than abort on a failed allocation halfway.
    let available = crate::cli::memory::available_bytes().map_or(f64::INFINITY, |b| b as f64);
    for &p in &args.precision {
        for &rows in &args.rows {
            for &modes in &args.modes {
                let bytes = rows as f64 * modes as f64 * p.bytes() as f64;
                if bytes > available / 2.0 {
                    bail!(
                        "--rows {rows} --modes {modes} ({}): {:.1} GB of values, {:.1} GB of \
                         memory available: expected a model that fits in half of it",
                        p.name(),
                        bytes / 1e9,
                        available / 1e9
                    );
                }
            }
        }
    }
    if !args.json {
        println!(
            "{:>7} {:>5} {:>4} {:>10} {:>12} {:>12} {:>6} {:>8} {:>8} {:>10} {:>10}",
            "rows",
            "modes",
            "prec",
            "MB",
            "eval_ns",
            "bandwidth_ns",
            "ratio",
            "GB/s",
            "bw GB/s",
            "partic_ns",
            "contact_ns"
        );
    }
    let min_time = Duration::from_millis(args.min_time_ms);
    for &p in &args.precision {
        for &rows in &args.rows {
            for &modes in &args.modes {
                let row = match p {
                    Precision::F32 => measure::<f32>(rows, modes, min_time),
                    Precision::F64 => measure::<f64>(rows, modes, min_time),
                };
                if args.json {
                    println!("{}", serde_json::to_string(&row)?);
                } else {
                    println!(
                        "{:>7} {:>5} {:>4} {:>10.1} {:>12.0} {:>12.0} {:>6.3} {:>8.2} {:>8.2} {:>10.0} {:>10.0}",
                        row.rows,
                        row.modes,
                        row.precision,
                        row.bytes as f64 / 1e6,
                        row.eval_ns,
                        row.bandwidth_ns,
                        row.ratio,
                        row.eval_gb_per_s,
                        row.bandwidth_gb_per_s,
                        row.particularize_ns,
                        row.contact_ns
                    );
                }
            }
        }
    }
    Ok(())
}

fn measure<T: Scalar>(rows: usize, modes: usize, min_time: Duration) -> EvalRow {
    // A 40×40-vertex probe surface: the size of a medium mesh's palpable region.
    let model: SeparatedModel<T> = palpation_like(rows, modes, 40, 0x5eed);
    let rows = model.rows();
    let bytes = size_of_val(model.spatial());
    let mut rng = Rng::seed(7);
    let triangles = match &model.axes()[0].info.discretization {
        Discretization::Surface { triangles, .. } => triangles.len(),
        _ => unreachable!("palpation_like puts the surface axis first"),
    };
    let random_values = |rng: &mut Rng| {
        let a = rng.uniform();
        let b = rng.uniform() * (1.0 - a);
        [
            ParamValue::Surface {
                triangle: rng.below(triangles) as u32,
                bary: [a, b, 1.0 - a - b],
            },
            ParamValue::Scalar(rng.range(0.0, 10.0)),
        ]
    };

    let mut coeffs = vec![0.0; modes];
    let values = random_values(&mut rng);
    model
        .particularize(&values, &mut coeffs)
        .expect("synthetic values are valid");
    let mut out = vec![0.0; rows];

    // Interleaved repetitions of reconstruction and the streaming sum; minimum of each.
    let (mut eval_best, mut bw_best) = (f64::INFINITY, f64::INFINITY);
    let start = Instant::now();
    let mut reps = 0;
    while reps < 5 || start.elapsed() < 2 * min_time {
        let t = Instant::now();
        model.reconstruct(black_box(&coeffs), &mut out);
        black_box(&out);
        eval_best = eval_best.min(t.elapsed().as_nanos() as f64);
        let t = Instant::now();
        black_box(stream_sum(black_box(model.spatial())));
        bw_best = bw_best.min(t.elapsed().as_nanos() as f64);
        reps += 1;
    }

    // Particularization alone, at random points (values precomputed outside the timing).
    let batch: Vec<_> = (0..4096).map(|_| random_values(&mut rng)).collect();
    let particularize_ns = mean_ns_per_call(min_time, batch.len(), |i| {
        model
            .particularize(black_box(&batch[i]), &mut coeffs)
            .expect("valid");
        black_box(&coeffs);
    });

    // Contact evaluation: particularize + the 3 rows of a random node.
    let nodes: Vec<usize> = (0..4096).map(|_| rng.below(rows / 3)).collect();
    let mut contact = [0.0; 3];
    let contact_ns = mean_ns_per_call(min_time, batch.len(), |i| {
        model
            .particularize(black_box(&batch[i]), &mut coeffs)
            .expect("valid");
        model.reconstruct_range(3 * nodes[i], &coeffs, &mut contact);
        black_box(&contact);
    });

    EvalRow {
        rows,
        modes,
        precision: T::PRECISION.name(),
        bytes,
        eval_ns: eval_best,
        bandwidth_ns: bw_best,
        ratio: eval_best / bw_best,
        eval_gb_per_s: bytes as f64 / eval_best,
        bandwidth_gb_per_s: bytes as f64 / bw_best,
        particularize_ns,
        contact_ns,
    }
}

/// Mean time per call of `f(i)` for i cycling through `0..n`, over at least `min_time`.
fn mean_ns_per_call(min_time: Duration, n: usize, mut f: impl FnMut(usize)) -> f64 {
    let start = Instant::now();
    let mut calls = 0usize;
    // At least one pass, so a zero minimum time still measures something.
    loop {
        for i in 0..n {
            f(i);
        }
        calls += n;
        if start.elapsed() >= min_time {
            break;
        }
    }
    start.elapsed().as_nanos() as f64 / calls as f64
}
