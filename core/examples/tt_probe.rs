use palpa_core::cme::moments::l1;
use palpa_core::cme::network::Network;
use palpa_core::cme::{fsp, ttsolve};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = &args[1];
    let t_end: f64 = args[2].parse().unwrap();
    let eps: f64 = args.get(3).map_or(1e-7, |s| s.parse().unwrap());
    let tol: f64 = args.get(4).map_or(1e-5, |s| s.parse().unwrap());
    let net = Network::built_in(name).unwrap();
    let compress_eps: f64 = args.get(6).map_or(1e-6, |s| s.parse().unwrap());
    let opts = ttsolve::Options {
        t_end,
        eps,
        step_error_tol: tol,
        compress_eps,
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let (hist, rep) = ttsolve::solve(&net, &opts, &mut |s| {
        if s.k % 20 == 0 {
            eprintln!(
                "k {} t {:.3} h {:.3} rank {} sweeps {} hist {} ({:.1}s)",
                s.k,
                s.t,
                s.h,
                s.rank,
                s.sweeps,
                s.history_rank,
                t0.elapsed().as_secs_f64()
            );
        }
    })
    .unwrap();
    eprintln!("{rep:?} total {:.1}s", t0.elapsed().as_secs_f64());
    let times: Vec<f64> = args.get(5).map_or(vec![t_end], |s| {
        s.split(',').map(|x| x.parse().unwrap()).collect()
    });
    if hist.sizes.len() > 3 {
        let chain = Network::built_in("signaling-cascade-3").unwrap();
        let (p, _) = chain.parameter_values(&[]).unwrap();
        let exact = fsp::solve(&chain, &p, &times).unwrap();
        let exact_end = fsp::solve(&chain, &p, &[t_end]).unwrap();
        let m = hist.last.marginals();
        for i in 0..3 {
            eprintln!(
                "last state, t {t_end} S{}: marginal L1 {:.2e} mass {}",
                i + 1,
                l1(&m[i], &exact_end.moments[0].marginals[i]),
                m[i].iter().sum::<f64>()
            );
        }
        for (j, &t) in times.iter().enumerate() {
            let m = hist.particularize(t, &[]).marginals();
            for i in 0..3 {
                let e = l1(&m[i], &exact.moments[j].marginals[i]);
                eprintln!("t {t} S{}: marginal L1 {e:.2e}", i + 1);
            }
        }
        return;
    }
    let deltas: Vec<f64> = if hist.params.is_empty() {
        vec![f64::NAN]
    } else {
        vec![0.01, 0.0105, 0.02, 0.03, 0.045]
    };
    for &dl in &deltas {
        let set: Vec<(String, f64)> = if dl.is_nan() {
            vec![]
        } else {
            vec![("delta".into(), dl)]
        };
        let (p, _) = net.parameter_values(&set).unwrap();
        let exact = fsp::solve_on(&net, &p, &hist.sizes, &times).unwrap();
        for (j, &t) in times.iter().enumerate() {
            let pv = if dl.is_nan() { vec![] } else { vec![dl] };
            let lin = l1(&hist.particularize_with(t, &pv, 2).full(), &exact.joint[j]);
            eprintln!("   linear: {lin:.2e}");
            let x = hist.particularize(t, &pv);
            let joint = x.full();
            let err = l1(&joint, &exact.joint[j]);
            let neg = joint.iter().copied().fold(0.0, f64::min);
            let mass: f64 = joint.iter().sum();
            eprintln!(
                "delta {dl} t {t}: joint L1 {err:.2e} mass {mass:.8} (fsp leak {:.1e}) most neg {neg:.1e}",
                exact.leak[j]
            );
        }
    }
}
