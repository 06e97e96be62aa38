//! Finite state projection: the CME on a box `Π_i [0, m_i)`, integrated exactly.
//!
//! The generator `A` (columns sum to ≤ 0) keeps every reaction's outflow on the
//! diagonal, also for reactions that would leave the box, so probability that leaves the
//! box is lost, not reflected: `1 − Σ_z P(z, t)` is the **leak**, and it bounds the L1
//! error of the truncated solution against the CME's (Munsky & Khammash 2006, Thm 2.2).
//!
//! **Uniformization.** With `q ≥ max_z |A_zz|` and `B = I + A/q` (non-negative),
//! `P(t + Δ) = Σ_k Pois(k; qΔ) Bᵏ P(t)`. Every term is non-negative, so the result
//! has no negative probabilities and the truncation of the sum (tail < 1e-15) is the
//! only error besides round-off. The weights are carried as logarithms, so a step can
//! be long (`qΔ` up to 5 000). Cost: about `q·t` sparse matrix–vector products: cheap
//! for the gene networks here (q ~ 1–20 per unit time), expensive for stiff networks
//! (then a Krylov or implicit method would be the choice).
//!
//! Boxes beyond ~10⁷ states are refused: that is where separated (PGD) solvers take
//! over.

use rayon::prelude::*;
use thiserror::Error;

use super::moments::Moments;
use super::network::Network;

/// The leak an automatic box is grown to stay below at every output time when none is
/// asked. 10⁻⁶ left the DSMTS birth–death cases' standard deviations 1.9·10⁻⁵ from the
/// published values (the suite's bar is 10⁻⁵); 10⁻⁹ meets it in the same box (288
/// states on case 00001 to t = 50) for about 15 % more uniformization steps.
pub const DEFAULT_MAX_LEAK: f64 = 1e-9;

/// Largest box the exact solver accepts.
pub const MAX_STATES: usize = 10_000_000;

#[derive(Debug, Clone, PartialEq, Error)]
pub enum FspError {
    #[error(
        "the box has {states:.4e} states (> {MAX_STATES}): FSP is for up to about three \
         species; use the PGD solver or a sub-network"
    )]
    TooLarge { states: f64 },
    #[error("species {0} has an automatic box; FSP needs sizes (use solve_auto)")]
    AutoBox(String),
    #[error("output times must be finite, ≥ 0 and increasing; got {0:?}")]
    Times(Vec<f64>),
    #[error("the box has {got} sizes but the network has {species} species")]
    BoxShape { got: usize, species: usize },
    #[error("{0}")]
    Overflow(String),
}

/// The number of states of the box `sizes` and its strides (species 0 fastest), or
/// the refusal of a box over [`MAX_STATES`].
fn box_layout(sizes: &[usize]) -> Result<(usize, Vec<usize>), FspError> {
    // Twenty species of 64 states overflow 64 bits: count in f64 for the message.
    let n = match sizes.iter().try_fold(1usize, |a, &m| a.checked_mul(m)) {
        Some(n) if n <= MAX_STATES && !sizes.contains(&0) => n,
        _ => {
            return Err(FspError::TooLarge {
                states: sizes.iter().map(|&m| m as f64).product(),
            });
        }
    };
    let mut strides = vec![1usize; sizes.len()];
    for i in 1..sizes.len() {
        strides[i] = strides[i - 1] * sizes[i - 1];
    }
    Ok((n, strides))
}

/// The box index of `z` (clamped into the box).
fn box_index(sizes: &[usize], z: &[usize]) -> usize {
    let (mut b, mut stride) = (0, 1);
    for (&zi, &m) in z.iter().zip(sizes) {
        b += zi.min(m - 1) * stride;
        stride *= m;
    }
    b
}

/// The generator on a box, in CSR (rows: target states).
#[derive(Debug, Clone)]
pub struct Generator {
    pub sizes: Vec<usize>,
    row_start: Vec<usize>,
    cols: Vec<u32>,
    vals: Vec<f64>,
    diag: Vec<f64>,
    /// Each state's rate of leaving the box (reactions that would carry it out).
    exit: Vec<f64>,
    /// The box index of each state, when only the states reachable from a start are
    /// kept ([`Generator::reachable`]); `None`: every state of the box, in box order.
    index: Option<Vec<usize>>,
}

impl Generator {
    /// Builds `A` for `network` with parameter values `p` on the box `sizes`.
    pub fn new(network: &Network, p: &[f64], sizes: &[usize]) -> Result<Self, FspError> {
        if sizes.len() != network.species.len() {
            return Err(FspError::BoxShape {
                got: sizes.len(),
                species: network.species.len(),
            });
        }
        let (n, strides) = box_layout(sizes)?;
        let d = sizes.len();
        let mut row_start = Vec::with_capacity(n + 1);
        let mut cols = Vec::with_capacity(n * network.reactions.len());
        let mut vals = Vec::with_capacity(n * network.reactions.len());
        let mut diag = vec![0.0; n];
        let mut exit = vec![0.0; n];
        let mut z = vec![0i64; d];
        let mut src = vec![0i64; d];
        row_start.push(0);
        for row in 0..n {
            let mut rem = row;
            for i in 0..d {
                z[i] = (rem % sizes[i]) as i64;
                rem /= sizes[i];
            }
            for (r, re) in network.reactions.iter().enumerate() {
                let out = network.propensity(r, &z, p);
                if !out.is_finite() {
                    return Err(FspError::Overflow(network.overflow_message(r, &z, out)));
                }
                diag[row] -= out;
                let leaves = re.change.iter().enumerate().any(|(i, &c)| {
                    let y = z[i] + i64::from(c);
                    y < 0 || y >= sizes[i] as i64
                });
                if leaves {
                    exit[row] += out;
                }
                // Inflow from z − ν_r, when that state is in the box.
                let mut inside = true;
                let mut col = 0usize;
                for i in 0..d {
                    src[i] = z[i] - i64::from(re.change[i]);
                    if src[i] < 0 || src[i] >= sizes[i] as i64 {
                        inside = false;
                        break;
                    }
                    col += src[i] as usize * strides[i];
                }
                if inside && re.change.iter().any(|&c| c != 0) {
                    let a = network.propensity(r, &src, p);
                    if a != 0.0 {
                        cols.push(col as u32);
                        vals.push(a);
                    }
                }
            }
            row_start.push(cols.len());
        }
        Ok(Generator {
            sizes: sizes.to_vec(),
            row_start,
            cols,
            vals,
            diag,
            exit,
            index: None,
        })
    }

    /// `A` on the states of the box reachable from `start` (a breadth-first search
    /// along reactions with a positive propensity), in box order. A network with a
    /// conservation law (dimerisation: `P + 2 P₂` fixed) reaches a line of its box, not
    /// the box: 501 states of 524 288 for 1000 monomers.
    pub fn reachable(
        network: &Network,
        p: &[f64],
        sizes: &[usize],
        start: &[usize],
    ) -> Result<Self, FspError> {
        if sizes.len() != network.species.len() || start.len() != sizes.len() {
            return Err(FspError::BoxShape {
                got: sizes.len(),
                species: network.species.len(),
            });
        }
        let (n, strides) = box_layout(sizes)?;
        let d = sizes.len();
        let decode = |mut b: usize, z: &mut [i64]| {
            for i in 0..d {
                z[i] = (b % sizes[i]) as i64;
                b /= sizes[i];
            }
        };
        // The box index after reaction `re` from `z`, if it stays in the box.
        let target = |z: &[i64], re: &super::network::Reaction| {
            let mut to = 0usize;
            for i in 0..d {
                let y = z[i] + i64::from(re.change[i]);
                if !(0..sizes[i] as i64).contains(&y) {
                    return None;
                }
                to += y as usize * strides[i];
            }
            Some(to)
        };
        let first = box_index(sizes, start);
        let mut seen = vec![false; n];
        seen[first] = true;
        let mut queue = vec![first];
        let mut z = vec![0i64; d];
        let mut head = 0;
        while head < queue.len() {
            decode(queue[head], &mut z);
            head += 1;
            for (r, re) in network.reactions.iter().enumerate() {
                let a = network.propensity(r, &z, p);
                if !a.is_finite() {
                    return Err(FspError::Overflow(network.overflow_message(r, &z, a)));
                }
                if a <= 0.0 {
                    continue;
                }
                if let Some(to) = target(&z, re)
                    && !seen[to]
                {
                    seen[to] = true;
                    queue.push(to);
                }
            }
        }
        queue.sort_unstable();
        let mut local = vec![u32::MAX; n];
        for (k, &b) in queue.iter().enumerate() {
            local[b] = k as u32;
        }
        // Rows are targets: gather each state's inflows.
        let mut triplets: Vec<(u32, u32, f64)> = Vec::new();
        let mut diag = vec![0.0; queue.len()];
        let mut exit = vec![0.0; queue.len()];
        for (k, &b) in queue.iter().enumerate() {
            decode(b, &mut z);
            for (r, re) in network.reactions.iter().enumerate() {
                let a = network.propensity(r, &z, p);
                diag[k] -= a;
                if a == 0.0 || re.change.iter().all(|&c| c == 0) {
                    continue;
                }
                match target(&z, re) {
                    Some(to) => triplets.push((local[to], k as u32, a)),
                    None => exit[k] += a,
                }
            }
        }
        triplets.sort_unstable_by_key(|t| (t.0, t.1));
        let mut row_start = Vec::with_capacity(queue.len() + 1);
        row_start.push(0);
        let mut e = 0;
        for row in 0..queue.len() as u32 {
            while e < triplets.len() && triplets[e].0 == row {
                e += 1;
            }
            row_start.push(e);
        }
        Ok(Generator {
            sizes: sizes.to_vec(),
            row_start,
            cols: triplets.iter().map(|t| t.1).collect(),
            vals: triplets.iter().map(|t| t.2).collect(),
            diag,
            exit,
            index: Some(queue),
        })
    }

    /// The joint on the whole box (species 0 fastest) from a vector on this
    /// generator's states.
    pub fn to_box(&self, x: &[f64]) -> Vec<f64> {
        match &self.index {
            None => x.to_vec(),
            Some(index) => {
                let mut out = vec![0.0; self.sizes.iter().product()];
                for (&b, &v) in index.iter().zip(x) {
                    out[b] = v;
                }
                out
            }
        }
    }

    /// The moments of a vector on this generator's states.
    pub fn moments(&self, t: f64, x: &[f64]) -> Moments {
        match &self.index {
            None => Moments::from_joint(t, &self.sizes, x),
            Some(index) => {
                let d = self.sizes.len();
                let mut marginals: Vec<Vec<f64>> =
                    self.sizes.iter().map(|&m| vec![0.0; m]).collect();
                let mut e01 = 0.0;
                for (&b, &v) in index.iter().zip(x) {
                    let mut rem = b;
                    let mut z01 = [0usize; 2];
                    for (i, m) in marginals.iter_mut().enumerate() {
                        let zi = rem % self.sizes[i];
                        rem /= self.sizes[i];
                        m[zi] += v;
                        if i < 2 {
                            z01[i] = zi;
                        }
                    }
                    if d >= 2 {
                        e01 += v * z01[0] as f64 * z01[1] as f64;
                    }
                }
                Moments::from_marginals(t, marginals, e01, x.iter().sum())
            }
        }
    }

    /// This generator's index of the box state `b`, if it holds it.
    fn local(&self, b: usize) -> Option<usize> {
        match &self.index {
            None => Some(b),
            Some(index) => index.binary_search(&b).ok(),
        }
    }

    /// `x` (on this generator's states) as a vector on `wider`'s, whose box holds this
    /// one's: every state reachable here is reachable there.
    fn embed(&self, x: &[f64], wider: &Generator) -> Vec<f64> {
        let mut out = vec![0.0; wider.states()];
        let mut z = vec![0usize; self.sizes.len()];
        for (k, &v) in x.iter().enumerate() {
            if v == 0.0 {
                continue;
            }
            let mut b = self.index.as_ref().map_or(k, |ix| ix[k]);
            for (zi, &m) in z.iter_mut().zip(&self.sizes) {
                *zi = b % m;
                b /= m;
            }
            if let Some(j) = wider.local(box_index(&wider.sizes, &z)) {
                out[j] = v;
            }
        }
        out
    }

    pub fn states(&self) -> usize {
        self.diag.len()
    }

    /// `out = A x` (for checks; the solver uses the uniformized product).
    pub fn apply(&self, x: &[f64], out: &mut [f64]) {
        for (row, o) in out.iter_mut().enumerate() {
            let mut s = self.diag[row] * x[row];
            for e in self.row_start[row]..self.row_start[row + 1] {
                s += self.vals[e] * x[self.cols[e] as usize];
            }
            *o = s;
        }
    }

    /// `out = (I + A/q) x` and `acc += w · out` on the rows `first..first + out.len()`:
    /// one pass over the generator for each term of the uniformized sum.
    fn uniformized_rows(
        &self,
        q: f64,
        x: &[f64],
        first: usize,
        out: &mut [f64],
        w: f64,
        acc: &mut [f64],
    ) {
        let inv = 1.0 / q;
        for (k, (o, a)) in out.iter_mut().zip(acc.iter_mut()).enumerate() {
            let row = first + k;
            let mut s = x[row] * (1.0 + self.diag[row] * inv);
            for e in self.row_start[row]..self.row_start[row + 1] {
                s += self.vals[e] * inv * x[self.cols[e] as usize];
            }
            *o = s;
            *a += w * s;
        }
    }

    /// As [`Self::uniformized_rows`] on every state; split over threads only for boxes
    /// large enough to pay for it (a birth–death box of 16 384 states spent more than
    /// half its time handing 4 096-row chunks between two threads).
    fn uniformized(&self, q: f64, x: &[f64], out: &mut [f64], w: f64, acc: &mut [f64]) {
        const CHUNK: usize = 1 << 16;
        if out.len() < 2 * CHUNK {
            self.uniformized_rows(q, x, 0, out, w, acc);
        } else {
            out.par_chunks_mut(CHUNK)
                .zip(acc.par_chunks_mut(CHUNK))
                .enumerate()
                .for_each(|(c, (o, a))| self.uniformized_rows(q, x, c * CHUNK, o, w, a));
        }
    }

    /// Advances `p` by `dt` (exact up to a 1e-15 tail and round-off), stepping all the
    /// way (see [`Self::advance_settling`] for what stepping costs and how).
    pub fn advance(&self, p: &mut Vec<f64>, dt: f64) {
        self.step(p, dt, None);
    }

    /// Advances `p` by `dt`, remembering in `settling` whether the distribution has
    /// stopped changing shape (see [`Settling`]); once it has, the rest of the time
    /// costs nothing: `p` keeps its shape and its mass decays at the rate measured.
    ///
    /// The Poisson weights are carried as logarithms, `ln w_k = −λ + Σ_{j≤k} ln(λ/j)`,
    /// so a step can be long (`λ = qΔ` up to `MAX_STEP_LAMBDA`) without `e^{−λ}`
    /// underflowing: a sum costs about `λ + 8√λ` products, so long steps waste less
    /// on each step's tails than the earlier `λ ≤ 50` (about twice `q·t`). The sum
    /// stops past the mode once the tail's geometric bound,
    /// `Σ_{j>k} w_j ≤ w_k r / (1 − r)` with `r = λ/(k + 1) < 1`, is below 1e-15; every
    /// `Bᵏ p` has L1 norm at most that of `p`, so that bounds the truncation in L1. The
    /// sum is divided by the weights' own sum, which removes the rounding the log
    /// sums share.
    pub fn advance_settling(&self, p: &mut Vec<f64>, dt: f64, settling: &mut Settling) {
        self.step(p, dt, Some(settling));
    }

    fn step(&self, p: &mut Vec<f64>, dt: f64, mut settling: Option<&mut Settling>) {
        if dt.is_nan() || dt <= 0.0 {
            return;
        }
        if let Some(settled) = settling.as_ref().and_then(|s| s.settled) {
            settled.decay(p, dt);
            return;
        }
        let q = self.diag.iter().fold(0.0f64, |m, d| m.max(-d)) * 1.02 + 1e-12;
        let steps = (q * dt / MAX_STEP_LAMBDA).ceil().max(1.0);
        let lambda = q * dt / steps;
        let step_dt = dt / steps;
        let mut term = vec![0.0; p.len()];
        let mut next = vec![0.0; p.len()];
        let mut acc = vec![0.0; p.len()];
        for step in 0..steps as usize {
            term.copy_from_slice(p);
            let mut log_w = -lambda;
            let w0 = log_w.exp();
            let mut weight_sum = w0;
            acc.iter_mut().zip(&term).for_each(|(a, t)| *a = w0 * t);
            // The cap only guards against a NaN rate; a finite λ stops far below it.
            let cap = (lambda + 40.0 * lambda.sqrt() + 100.0) as u64;
            for k in 1..=cap {
                let kf = k as f64;
                log_w += (lambda / kf).ln();
                let w = log_w.exp();
                weight_sum += w;
                self.uniformized(q, &term, &mut next, w, &mut acc);
                std::mem::swap(&mut term, &mut next);
                let r = lambda / (kf + 1.0);
                if r < 1.0 && w * r / (1.0 - r) < 1e-15 {
                    break;
                }
            }
            // The weights sum to 1 less a tail below 1e-15; what the log sums' rounding
            // adds to all of them alike (1e-10 of the mass over 2 500 relaxation
            // times, unnormalized) is divided out.
            let norm = 1.0 / weight_sum;
            acc.iter_mut().for_each(|a| *a *= norm);
            let settled = settling.as_mut().and_then(|s| {
                s.observe(p, &acc, lambda, step_dt, &self.exit);
                s.settled
            });
            std::mem::swap(p, &mut acc);
            if let Some(settled) = settled {
                settled.decay(p, step_dt * (steps - 1.0 - step as f64));
                return;
            }
        }
    }
}

/// Whether an FSP solution has stopped changing shape, judged step by step.
///
/// A long uniformization step (`qΔ ≥` [`SETTLE_MIN_LAMBDA`]: at least 2 500 jumps of
/// the fastest state) that moves the normalized distribution `P/ΣP` by less than
/// [`SETTLE_L1`] in L1, twice in a row, marks it settled: from then on `P` keeps its
/// shape and its mass decays as `e^{−μ t}`, `μ = Σ_z exit(z) P(z) / Σ P` the rate at
/// which its probability leaves the box (`exit(z)`: the propensities that carry `z`
/// out). That is exact for a box at its quasi-stationary law (the generator's leading
/// eigenvector, which a leaking box decays along) and for a closed box at its
/// stationary law (`μ = 0`). It is a judgement, not a bound: a mode slower than the
/// step by a factor `τ/Δ` whose amplitude is below `SETTLE_L1 · τ/Δ` passes unseen
/// (a switch between the wells of a bistable network rarer than that), so a solution
/// says where it settled ([`FspSolution::settled_at`]). Why: uniformization costs
/// `q·t` products, which made a reference at `t = 10⁶` take minutes and `10¹²` days.
#[derive(Debug, Clone, Default)]
pub struct Settling {
    /// Long steps in a row whose shape change was below [`SETTLE_L1`].
    calm_steps: usize,
    /// Time stepped so far (the settled time is read from it).
    elapsed: f64,
    /// Once settled: when, and the rate the rest decays at.
    pub settled: Option<Settled>,
}

/// A settled FSP solution: its mass decays at `decay_per_time`, its shape is kept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settled {
    pub decay_per_time: f64,
    /// Time stepped, from the first call on the same [`Settling`], when it settled.
    pub at_t: f64,
}

impl Settled {
    fn decay(self, p: &mut [f64], dt: f64) {
        if self.decay_per_time > 0.0 && dt > 0.0 {
            let f = (-self.decay_per_time * dt).exp();
            p.iter_mut().for_each(|v| *v *= f);
        }
    }
}

impl Settling {
    /// Takes one step's `before` and `after` (of length `dt`, `λ = qΔ`); `exit` is
    /// each state's rate of leaving the box.
    fn observe(&mut self, before: &[f64], after: &[f64], lambda: f64, dt: f64, exit: &[f64]) {
        self.elapsed += dt;
        let m0: f64 = before.iter().sum();
        let m1: f64 = after.iter().sum();
        if m1 <= 0.0 {
            // Everything has left the box: nothing is left to move.
            self.settled = Some(Settled {
                decay_per_time: 0.0,
                at_t: self.elapsed,
            });
            return;
        }
        if lambda < SETTLE_MIN_LAMBDA || m0 <= 0.0 {
            self.calm_steps = 0;
            return;
        }
        let change: f64 = before
            .iter()
            .zip(after)
            .map(|(b, a)| (a / m1 - b / m0).abs())
            .sum();
        self.calm_steps = if change < SETTLE_L1 {
            self.calm_steps + 1
        } else {
            0
        };
        if self.calm_steps >= 2 {
            // The leak rate of the settled law, `Σ exit·P / ΣP`: read from the
            // generator, not from two masses (their difference is rounding where the
            // box barely leaks, and 10⁹ steps of it would be a leak that is not there).
            let leaving: f64 = after.iter().zip(exit).map(|(p, e)| p * e).sum();
            self.settled = Some(Settled {
                decay_per_time: leaving / m1,
                at_t: self.elapsed,
            });
        }
    }
}

/// The shape change in L1 below which a long step counts as calm ([`Settling`]).
pub const SETTLE_L1: f64 = 1e-13;

/// The shortest step (`qΔ`) that can show a distribution settled ([`Settling`]).
pub const SETTLE_MIN_LAMBDA: f64 = MAX_STEP_LAMBDA / 2.0;

/// The largest `qΔ` of one uniformization step: the log-weights' rounding (about
/// `k · 1e-16` after `k` terms) stays below 1e-12.
const MAX_STEP_LAMBDA: f64 = 5_000.0;

/// FSP result: moments at each output time and the leak.
#[derive(Debug, Clone)]
pub struct FspSolution {
    pub sizes: Vec<usize>,
    pub moments: Vec<Moments>,
    /// `1 − Σ P` at each output time.
    pub leak: Vec<f64>,
    /// The time from which the solution kept its shape ([`Settling`]): later output
    /// times were not stepped to but decayed there. `None`: stepped all the way.
    pub settled_at: Option<f64>,
    /// Joint distributions at each output time (species 0 fastest); empty from
    /// [`solve_auto`] and [`solve_kept`] without joints.
    pub joint: Vec<Vec<f64>>,
}

fn check_times(times: &[f64]) -> Result<(), FspError> {
    let ok =
        times.iter().all(|t| t.is_finite() && *t >= 0.0) && times.windows(2).all(|w| w[0] < w[1]);
    if ok {
        Ok(())
    } else {
        Err(FspError::Times(times.to_vec()))
    }
}

/// Solves on the network's own box from its initial point mass.
pub fn solve(network: &Network, p: &[f64], times: &[f64]) -> Result<FspSolution, FspError> {
    solve_on(network, p, &own_box(network)?, times)
}

/// The network's own box: every species' `max`.
fn own_box(network: &Network) -> Result<Vec<usize>, FspError> {
    network
        .species
        .iter()
        .map(|s| s.max.ok_or_else(|| FspError::AutoBox(s.name.clone())))
        .collect()
}

/// Solves on the box `sizes` (on the states reachable from the initial one).
pub fn solve_on(
    network: &Network,
    p: &[f64],
    sizes: &[usize],
    times: &[f64],
) -> Result<FspSolution, FspError> {
    solve_kept(network, p, sizes, times, true)
}

/// As [`solve`], but stepped all the way to every time, never judged settled
/// ([`Settling`]): `q·t` products, for checking a settled solution.
pub fn solve_stepped(network: &Network, p: &[f64], times: &[f64]) -> Result<FspSolution, FspError> {
    solve_box(network, p, &own_box(network)?, times, true, false)
}

/// As [`solve_on`]; the joints are kept only with `keep_joint` (a box of 10⁷ states
/// at 50 times is 4 GB).
pub fn solve_kept(
    network: &Network,
    p: &[f64],
    sizes: &[usize],
    times: &[f64],
    keep_joint: bool,
) -> Result<FspSolution, FspError> {
    solve_box(network, p, sizes, times, keep_joint, true)
}

/// As [`solve_kept`]; with `settle`, the stepping stops where the law settles.
fn solve_box(
    network: &Network,
    p: &[f64],
    sizes: &[usize],
    times: &[f64],
    keep_joint: bool,
    settle: bool,
) -> Result<FspSolution, FspError> {
    check_times(times)?;
    let start: Vec<usize> = network.species.iter().map(|s| s.initial).collect();
    let g = Generator::reachable(network, p, sizes, &start)?;
    let mut prob = vec![0.0; g.states()];
    // The start is the first state the search found; in box order, find it again.
    let first = box_index(sizes, &start);
    let k = g
        .index
        .as_ref()
        .and_then(|ix| ix.binary_search(&first).ok())
        .unwrap_or(first);
    prob[k] = 1.0;
    let mut now = 0.0;
    let mut out = FspSolution {
        sizes: sizes.to_vec(),
        moments: Vec::new(),
        leak: Vec::new(),
        joint: Vec::new(),
        settled_at: None,
    };
    let mut settling = Settling::default();
    for &t in times {
        if settle {
            g.advance_settling(&mut prob, t - now, &mut settling);
        } else {
            g.advance(&mut prob, t - now);
        }
        now = t;
        let m = g.moments(t, &prob);
        out.leak.push((1.0 - m.mass).max(0.0));
        out.moments.push(m);
        if keep_joint {
            out.joint.push(g.to_box(&prob));
        }
    }
    out.settled_at = settling.settled.map(|s| s.at_t);
    Ok(out)
}

/// Solves with automatic boxes for species marked `auto`, growing them *as the
/// distribution spreads*: the time axis is cut at the output times and at
/// `AUTO_CHECKPOINTS` even steps to the last, and a stretch whose leak would take the
/// cumulative leak past `max_leak · t / t_end` is run again from its start in a larger
/// box (the state there embedded; its lost mass kept as lost). So the leak stays below
/// `max_leak` at every output time, and each stretch runs in a box about as large as
/// that stretch needs: uniformization costs about `q·Δt` products of the box's size,
/// and `q` (the largest exit rate) grows with the box, so a birth–death count that
/// rises to 10⁴ spent most of its time in the last doubling's 16 384 states, from the
/// first stretch on. Returns the solution and whether the leak target was met
/// (moments and leak; no joints; every time's marginals padded to the final box).
///
/// A species no reaction raises keeps `0..=initial` (it can only fall) and never grows;
/// an automatic box starts at `initial + 1` rounded up to a multiple of 32 (at least
/// 32). A growth adds a quarter (at least 32 states) to the species whose top band (the
/// states one reaction can carry out of the box) holds more than `max_leak / 100` of
/// the probability, or at least a hundredth of the fullest band's; to every species
/// that can rise if none does. Where the box would pass [`MAX_STATES`] it stops
/// growing and the leak target is reported as not met.
pub fn solve_auto(
    network: &Network,
    p: &[f64],
    times: &[f64],
    max_leak: f64,
) -> Result<(FspSolution, bool), FspError> {
    check_times(times)?;
    let rises: Vec<usize> = (0..network.species.len())
        .map(|i| network.largest_increase(i) as usize)
        .collect();
    let mut sizes: Vec<usize> = network
        .species
        .iter()
        .zip(&rises)
        .map(|(s, &up)| match s.max {
            Some(m) => m,
            None if up == 0 => s.initial + 1,
            None => (s.initial + 1).next_multiple_of(32),
        })
        .collect();
    let auto: Vec<bool> = network.species.iter().map(|s| s.max.is_none()).collect();
    let start: Vec<usize> = network.species.iter().map(|s| s.initial).collect();
    let mut g = Generator::reachable(network, p, &sizes, &start)?;
    let mut prob = vec![0.0; g.states()];
    prob[g.local(box_index(&sizes, &start)).unwrap_or(0)] = 1.0;
    let t_end = times.last().copied().unwrap_or(0.0);
    let mut stops: Vec<f64> = (1..=AUTO_CHECKPOINTS)
        .map(|k| t_end * k as f64 / AUTO_CHECKPOINTS as f64)
        .chain(times.iter().copied())
        .collect();
    stops.sort_by(f64::total_cmp);
    stops.dedup();
    let (mut now, mut met) = (0.0, true);
    let mut out = FspSolution {
        sizes: Vec::new(),
        moments: Vec::new(),
        leak: Vec::new(),
        joint: Vec::new(),
        settled_at: None,
    };
    let mut next_output = 0;
    // Kept across stretches; a new box starts judging afresh.
    let mut settling = Settling::default();
    for &t in &stops {
        let allowed = if t_end > 0.0 {
            max_leak * t / t_end
        } else {
            max_leak
        };
        loop {
            let mut trial = prob.clone();
            let mut trial_settling = settling.clone();
            g.advance_settling(&mut trial, t - now, &mut trial_settling);
            let leak = 1.0 - trial.iter().sum::<f64>();
            if leak <= allowed || !met {
                prob = trial;
                settling = trial_settling;
                break;
            }
            let m = g.moments(t, &trial);
            let band = |i: usize| {
                let marginal = &m.marginals[i];
                marginal[marginal.len().saturating_sub(rises[i])..]
                    .iter()
                    .sum::<f64>()
            };
            let can_grow = |i: usize| auto[i] && rises[i] > 0;
            let bands: Vec<f64> = (0..sizes.len())
                .map(|i| if can_grow(i) { band(i) } else { 0.0 })
                .collect();
            let most = bands.iter().copied().fold(0.0, f64::max);
            let mut grow: Vec<bool> = bands
                .iter()
                .map(|&b| b > max_leak / 100.0 || (most > 0.0 && b >= 0.01 * most))
                .collect();
            if !grow.iter().any(|&g| g) {
                grow = (0..sizes.len()).map(can_grow).collect();
            }
            let grown: Vec<usize> = sizes
                .iter()
                .zip(&grow)
                .map(|(&m, &g)| {
                    if g {
                        (m + (m / 4).max(32)).next_multiple_of(32)
                    } else {
                        m
                    }
                })
                .collect();
            let fits = grown
                .iter()
                .try_fold(1usize, |a, &m| a.checked_mul(m))
                .is_some_and(|n| n <= MAX_STATES);
            if grown == sizes || !fits {
                // No larger box: this stretch and the rest run in this one.
                met = false;
                continue;
            }
            let wider = Generator::reachable(network, p, &grown, &start)?;
            prob = g.embed(&prob, &wider);
            (g, sizes) = (wider, grown);
            settling = Settling {
                elapsed: now,
                ..Settling::default()
            };
        }
        now = t;
        while next_output < times.len() && times[next_output] == t {
            let m = g.moments(t, &prob);
            out.leak.push((1.0 - m.mass).max(0.0));
            out.moments.push(m);
            next_output += 1;
        }
    }
    for m in &mut out.moments {
        for (marginal, &size) in m.marginals.iter_mut().zip(&sizes) {
            marginal.resize(size, 0.0);
        }
    }
    out.sizes = sizes;
    out.settled_at = settling.settled.map(|s| s.at_t);
    Ok((out, met))
}

/// Even steps to the last output time at which [`solve_auto`] checks the leak and may
/// grow the box, besides the output times themselves.
const AUTO_CHECKPOINTS: usize = 32;
