//! The exact check beside the meta-model: FSP at the room's current coordinates, in a
//! named background thread that never blocks a frame. The solve advances in slices of
//! time (uniformization is exact slice by slice), so it reports progress and stops
//! within one slice of a cancel.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError, sync_channel};
use std::thread::JoinHandle;
use std::time::Instant;

use anyhow::Context;
use palpa_core::cme::fsp::Generator;
use palpa_core::cme::network::Network;

/// Slices the time interval is advanced in (progress and cancel granularity).
const SLICES: usize = 40;

/// The check's end: one message on its own channel of one slot, so sending it never
/// blocks (progress goes on a bounded channel by `try_send` and may be dropped).
type Outcome = Result<(Vec<f64>, f64), String>;

/// The exact joint at some coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Exact {
    /// Time, then parameters, as the room orders them.
    pub coordinates: Vec<f64>,
    /// Species 0 fastest, on the model's box.
    pub joint: Vec<f64>,
    pub seconds: f64,
}

/// Where a check stands.
#[derive(Debug, Clone, PartialEq)]
pub enum CheckState {
    Running { progress: f64 },
    Done(Exact),
    Failed(String),
    Cancelled,
}

/// A running (or finished) exact check.
#[derive(Debug)]
pub struct ExactCheck {
    cancel: Arc<AtomicBool>,
    progress: Receiver<f64>,
    outcome: Receiver<Outcome>,
    handle: Option<JoinHandle<()>>,
    coordinates: Vec<f64>,
    pub state: CheckState,
}

impl ExactCheck {
    /// Starts FSP of `network` with parameter values `p` on the box `sizes`, to time
    /// `t`; `coordinates` label the result.
    pub fn start(
        network: &Network,
        p: &[f64],
        sizes: &[usize],
        t: f64,
        coordinates: Vec<f64>,
    ) -> anyhow::Result<ExactCheck> {
        let generator = Generator::new(network, p, sizes).context("the exact check")?;
        let mut start = 0usize;
        let mut stride = 1usize;
        for (s, &m) in network.species.iter().zip(sizes) {
            start += s.initial.min(m - 1) * stride;
            stride *= m;
        }
        let cancel = Arc::new(AtomicBool::new(false));
        let (tx, progress) = sync_channel(8);
        let (done_tx, outcome) = sync_channel(1);
        let flag = Arc::clone(&cancel);
        let handle = std::thread::Builder::new()
            .name("palpa-exact-check".into())
            .spawn(move || {
                let t0 = Instant::now();
                let mut prob = vec![0.0; generator.states()];
                prob[start] = 1.0;
                let dt = t.max(0.0) / SLICES as f64;
                for k in 0..SLICES {
                    if flag.load(Ordering::Relaxed) {
                        return;
                    }
                    if dt > 0.0 {
                        generator.advance(&mut prob, dt);
                    }
                    // A full channel only drops a progress report.
                    let _ = tx.try_send((k + 1) as f64 / SLICES as f64);
                }
                let _ = done_tx.send(if prob.iter().any(|v| !v.is_finite()) {
                    Err("the exact solve diverged".into())
                } else {
                    Ok((prob, t0.elapsed().as_secs_f64()))
                });
            })
            .context("starting the exact-check thread")?;
        Ok(ExactCheck {
            cancel,
            progress,
            outcome,
            handle: Some(handle),
            coordinates,
            state: CheckState::Running { progress: 0.0 },
        })
    }

    /// Takes what the thread sent since the last call (call once per frame).
    pub fn poll(&mut self) -> &CheckState {
        if !matches!(self.state, CheckState::Running { .. }) {
            return &self.state;
        }
        while let Ok(p) = self.progress.try_recv() {
            self.state = CheckState::Running { progress: p };
        }
        match self.outcome.try_recv() {
            Ok(Ok((joint, seconds))) => {
                self.state = CheckState::Done(Exact {
                    coordinates: self.coordinates.clone(),
                    joint,
                    seconds,
                });
            }
            Ok(Err(why)) => self.state = CheckState::Failed(why),
            Err(TryRecvError::Empty) => return &self.state,
            Err(TryRecvError::Disconnected) => {
                self.state = CheckState::Failed("the exact-check thread stopped".into());
            }
        }
        self.join();
        &self.state
    }

    /// Tells the thread to stop (it ends within one slice, detached: a frame never
    /// waits for it) and marks the check cancelled.
    pub fn cancel(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
        self.handle.take();
        if matches!(self.state, CheckState::Running { .. }) {
            self.state = CheckState::Cancelled;
        }
    }

    /// Whether the thread has ended (or was let go).
    pub fn finished(&self) -> bool {
        self.handle.as_ref().is_none_or(|h| h.is_finished())
    }

    /// Waits for the thread until it has ended; reports a panic as a failure.
    fn join(&mut self) {
        if let Some(h) = self.handle.take()
            && h.join().is_err()
        {
            self.state = CheckState::Failed("the exact-check thread panicked".into());
        }
    }
}

impl Drop for ExactCheck {
    /// A dropped check stops its thread without waiting for it.
    fn drop(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn toggle() -> (Network, Vec<f64>, Vec<usize>) {
        let n = Network::built_in("toggle").expect("built in");
        let p: Vec<f64> = n.parameters.iter().map(|q| q.value).collect();
        let sizes = n
            .species
            .iter()
            .map(|s| s.max.expect("box"))
            .collect::<Vec<_>>();
        (n, p, sizes)
    }

    fn wait(check: &mut ExactCheck) -> CheckState {
        let t0 = Instant::now();
        while matches!(check.poll(), CheckState::Running { .. })
            && t0.elapsed() < Duration::from_secs(60)
        {
            std::thread::sleep(Duration::from_millis(2));
        }
        check.state.clone()
    }

    /// A check runs to the end off the caller's thread and returns a probability
    /// distribution labelled with its coordinates.
    #[test]
    fn a_check_finishes_with_a_distribution() {
        let (n, p, sizes) = toggle();
        let mut c = ExactCheck::start(&n, &p, &sizes, 1.0, vec![1.0]).expect("starts");
        let CheckState::Done(exact) = wait(&mut c) else {
            panic!("finished: {:?}", c.state);
        };
        assert_eq!(exact.coordinates, vec![1.0]);
        let mass: f64 = exact.joint.iter().sum();
        assert!((mass - 1.0).abs() < 1e-6, "{mass}");
        assert!(c.finished());
    }

    /// Cancelling marks the check at once and its thread ends within a slice.
    #[test]
    fn a_cancelled_check_stops() {
        let (n, p, sizes) = toggle();
        let mut c = ExactCheck::start(&n, &p, &sizes, 1e5, vec![1e5]).expect("starts");
        c.cancel();
        assert_eq!(c.state, CheckState::Cancelled);
        assert_eq!(*c.poll(), CheckState::Cancelled);
        assert!(c.finished(), "the thread is let go");
        // The thread drops its handle on the flag when it ends: within one slice of a
        // solve that would otherwise take minutes.
        let t0 = Instant::now();
        while Arc::strong_count(&c.cancel) > 1 && t0.elapsed() < Duration::from_secs(30) {
            std::thread::sleep(Duration::from_millis(2));
        }
        assert_eq!(Arc::strong_count(&c.cancel), 1, "the thread ended");
        assert!(t0.elapsed() < Duration::from_secs(30));
    }
}
