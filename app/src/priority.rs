//! Raising the force thread's scheduling priority, as far as the platform allows.
//!
//! A 1 kHz loop sharing two cores with a software rasterizer is descheduled for whole
//! milliseconds under the default time-sharing policy. Real-time FIFO scheduling (Linux,
//! Android, macOS, iOS: allowed to root or with `RLIMIT_RTPRIO`, e.g. `ulimit -r 10`)
//! fixes that; failing it we ask for the highest normal priority; failing that we run as
//! we are and say so in the statistics.

/// What the force thread got.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Priority {
    #[default]
    Normal,
    Raised,
    Realtime,
}

impl Priority {
    /// A name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Priority::Realtime => "realtime",
            Priority::Raised => "raised",
            Priority::Normal => "normal",
        }
    }

    /// The encoding in [`crate::force::LoopStats`] (plain bytes between threads).
    pub(crate) fn to_wire(self) -> u32 {
        match self {
            Priority::Normal => 0,
            Priority::Raised => 1,
            Priority::Realtime => 2,
        }
    }

    pub(crate) fn from_wire(v: u32) -> Priority {
        match v {
            2 => Priority::Realtime,
            1 => Priority::Raised,
            _ => Priority::Normal,
        }
    }
}

/// Raises the calling thread's priority as far as the platform allows.
pub fn raise_current_thread() -> Priority {
    #[cfg(unix)]
    {
        use thread_priority::unix::{
            RealtimeThreadSchedulePolicy, ThreadSchedulePolicy, set_thread_priority_and_policy,
            thread_native_id,
        };
        // A middling real-time priority: above ordinary threads, below the kernel's own.
        if let Ok(p) = thread_priority::ThreadPriority::try_from(50u8)
            && set_thread_priority_and_policy(
                thread_native_id(),
                p,
                ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
            )
            .is_ok()
        {
            return Priority::Realtime;
        }
    }
    if thread_priority::set_current_thread_priority(thread_priority::ThreadPriority::Max).is_ok() {
        Priority::Raised
    } else {
        Priority::Normal
    }
}
