//! What the GPU reported since it was last asked: validation and out-of-memory errors
//! that no error scope caught, and the device's loss.
//!
//! wgpu's default for an uncaptured error is to panic, which would take the session
//! (and the force loop a hand is on) down with it. The device instead hands every such
//! error to [`GpuHealth`], which logs it and keeps the latest message for the panel;
//! a lost device is flagged so the window makes a new one and keeps the session. Both
//! callbacks may run on any thread, and only ever off the force loop: a mutex is fine.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Errors and loss reported by one device.
#[derive(Debug, Default)]
pub struct GpuHealth {
    errors: AtomicU64,
    lost: AtomicBool,
    /// The latest message not yet shown.
    pending: Mutex<Option<String>>,
}

impl GpuHealth {
    /// An error no scope caught (validation, out of memory, internal).
    pub fn record_error(&self, error: &wgpu::Error) {
        let kind = match error {
            wgpu::Error::OutOfMemory { .. } => "out of GPU memory",
            wgpu::Error::Validation { .. } => "GPU validation error",
            wgpu::Error::Internal { .. } => "GPU internal error",
        };
        let message = format!("{kind}: {error}");
        tracing::error!("{message}");
        self.errors.fetch_add(1, Ordering::Relaxed);
        self.set_pending(message);
    }

    /// The device is gone (driver reset, GPU removed, or destroyed).
    pub fn record_lost(&self, reason: wgpu::DeviceLostReason, message: &str) {
        let message = format!("the GPU device was lost ({reason:?}): {message}");
        tracing::error!("{message}");
        self.lost.store(true, Ordering::Release);
        self.set_pending(message);
    }

    fn set_pending(&self, message: String) {
        // A poisoned lock only means another reporter panicked: keep the message.
        let mut p = self.pending.lock().unwrap_or_else(|e| e.into_inner());
        *p = Some(message);
    }

    /// The latest message, once.
    pub fn take_message(&self) -> Option<String> {
        self.pending
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
    }

    pub fn error_count(&self) -> u64 {
        self.errors.load(Ordering::Relaxed)
    }

    pub fn is_lost(&self) -> bool {
        self.lost.load(Ordering::Acquire)
    }
}
