//! A background job of the network room (an off-line build, an exact or sampled
//! check): one named thread, progress over a bounded channel (`try_send`: a report may
//! be dropped, a frame never waits), the outcome on its own one-slot channel (sending
//! it never blocks), and a cancel flag the work checks between its slices. A cancelled
//! or dropped job's thread is let go, not waited for.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, sync_channel};
use std::thread::JoinHandle;

use anyhow::Context;

/// Where a job stands.
#[derive(Debug, Clone, PartialEq)]
pub enum JobState<T> {
    /// Share of the work done, 0..1.
    Running {
        progress: f64,
    },
    Done(T),
    Failed(String),
    Cancelled,
}

/// What the work gets: a progress reporter and the cancel flag to check.
#[derive(Debug)]
pub struct Ctx {
    progress: SyncSender<f64>,
    cancel: Arc<AtomicBool>,
}

impl Ctx {
    /// Reports the share done (dropped if the room has not read the last ones).
    pub fn progress(&self, share: f64) {
        let _ = self.progress.try_send(share);
    }

    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// The flag itself, for solvers that take one.
    pub fn flag(&self) -> &AtomicBool {
        &self.cancel
    }
}

/// A job running in the background.
#[derive(Debug)]
pub struct Job<T> {
    cancel: Arc<AtomicBool>,
    progress: Receiver<f64>,
    outcome: Receiver<Result<T, String>>,
    handle: Option<JoinHandle<()>>,
    pub state: JobState<T>,
}

impl<T: Send + Clone + 'static> Job<T> {
    /// Starts `work` in a thread named `name`.
    pub fn start(
        name: &str,
        work: impl FnOnce(&Ctx) -> Result<T, String> + Send + 'static,
    ) -> anyhow::Result<Self> {
        let cancel = Arc::new(AtomicBool::new(false));
        let (ptx, progress) = sync_channel(16);
        let (otx, outcome) = sync_channel(1);
        let ctx = Ctx {
            progress: ptx,
            cancel: Arc::clone(&cancel),
        };
        let handle = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                let result = work(&ctx);
                let _ = otx.send(result);
            })
            .with_context(|| format!("starting the thread {name}"))?;
        Ok(Job {
            cancel,
            progress,
            outcome,
            handle: Some(handle),
            state: JobState::Running { progress: 0.0 },
        })
    }

    /// Takes what the thread sent since the last call (call once per frame).
    pub fn poll(&mut self) -> &JobState<T> {
        if !matches!(self.state, JobState::Running { .. }) {
            return &self.state;
        }
        while let Ok(p) = self.progress.try_recv() {
            self.state = JobState::Running { progress: p };
        }
        match self.outcome.try_recv() {
            Ok(Ok(v)) => self.state = JobState::Done(v),
            Ok(Err(why)) => {
                self.state = if self.cancel.load(Ordering::Relaxed) {
                    JobState::Cancelled
                } else {
                    JobState::Failed(why)
                };
            }
            Err(TryRecvError::Empty) => return &self.state,
            Err(TryRecvError::Disconnected) => {
                self.state = JobState::Failed("the job's thread stopped".into());
            }
        }
        if let Some(h) = self.handle.take()
            && h.join().is_err()
        {
            self.state = JobState::Failed("the job's thread panicked".into());
        }
        &self.state
    }

    /// Tells the work to stop at its next check; the thread is let go.
    pub fn cancel(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
        self.handle.take();
        if matches!(self.state, JobState::Running { .. }) {
            self.state = JobState::Cancelled;
        }
    }

    /// Whether the thread has ended or was let go.
    pub fn finished(&self) -> bool {
        self.handle.as_ref().is_none_or(|h| h.is_finished())
    }

    /// Whether the work still holds its context (its thread has not ended).
    #[cfg(test)]
    pub fn thread_alive(&self) -> bool {
        Arc::strong_count(&self.cancel) > 1
    }
}

impl<T> Drop for Job<T> {
    /// A dropped job stops its work without waiting for it.
    fn drop(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
}
