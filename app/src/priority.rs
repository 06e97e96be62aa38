//! Raising the force thread's scheduling priority, as far as the platform allows.
//!
//! A 1 kHz loop sharing two cores with a software rasterizer is descheduled for whole
//! milliseconds under the default time-sharing policy. Real-time FIFO scheduling (Linux,
//! Android, macOS, iOS: allowed to root or with `RLIMIT_RTPRIO`, e.g. `ulimit -r 10`)
//! fixes that; failing it we ask for the highest normal priority; failing that we run as
//! we are and say so in the statistics.

/// What the force thread got.
pub const PRIORITY_NORMAL: u32 = 0;
pub const PRIORITY_RAISED: u32 = 1;
pub const PRIORITY_REALTIME: u32 = 2;

/// Raises the calling thread's priority; returns one of the constants above.
pub fn raise_current_thread() -> u32 {
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
            return PRIORITY_REALTIME;
        }
    }
    if thread_priority::set_current_thread_priority(thread_priority::ThreadPriority::Max).is_ok() {
        PRIORITY_RAISED
    } else {
        PRIORITY_NORMAL
    }
}

/// A name for reports.
pub fn name(p: u32) -> &'static str {
    match p {
        PRIORITY_REALTIME => "realtime",
        PRIORITY_RAISED => "raised",
        _ => "normal",
    }
}
