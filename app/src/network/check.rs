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

/// What the check thread sends.
#[derive(Debug)]
enum Message {
    Progress(f64),
    Done { joint: Vec<f64>, seconds: f64 },
    Failed(String),
}

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
    rx: Receiver<Message>,
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
        let (tx, rx) = sync_channel(8);
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
                    let _ = tx.try_send(Message::Progress((k + 1) as f64 / SLICES as f64));
                }
                if prob.iter().any(|v| !v.is_finite()) {
                    let _ = tx.send(Message::Failed("the exact solve diverged".into()));
                    return;
                }
                let _ = tx.send(Message::Done {
                    joint: prob,
                    seconds: t0.elapsed().as_secs_f64(),
                });
            })
            .context("starting the exact-check thread")?;
        Ok(ExactCheck {
            cancel,
            rx,
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
        loop {
            match self.rx.try_recv() {
                Ok(Message::Progress(p)) => self.state = CheckState::Running { progress: p },
                Ok(Message::Done { joint, seconds }) => {
                    self.state = CheckState::Done(Exact {
                        coordinates: self.coordinates.clone(),
                        joint,
                        seconds,
                    });
                    self.join();
                    break;
                }
                Ok(Message::Failed(why)) => {
                    self.state = CheckState::Failed(why);
                    self.join();
                    break;
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    if matches!(self.state, CheckState::Running { .. }) {
                        self.state = CheckState::Failed("the exact-check thread stopped".into());
                    }
                    self.join();
                    break;
                }
            }
        }
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
