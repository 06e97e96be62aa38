//! Peak resident memory of this process (Linux: VmHWM, resettable through
//! /proc/self/clear_refs), for benchmarks. Elsewhere the figures are absent.

/// Resets the peak-RSS counter so the next reading covers only what follows.
pub fn reset_peak() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// Peak resident set size since the last reset, in bytes.
pub fn peak_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The environment variable that caps the memory palpa plans with (gigabytes): on a
/// shared machine, what a build or solve may take, below what the system has free.
pub const MEMORY_CAP_ENV: &str = "PALPA_MEMORY_GB";

/// Memory available to new allocations (Linux: MemAvailable), in bytes, or
/// [`MEMORY_CAP_ENV`] where that is smaller. Every plan that sizes work to the memory
/// (the factorization budget, presses at once, refusals before work) reads it here.
pub fn available_bytes() -> Option<u64> {
    let cap = memory_cap_bytes().ok().flatten();
    let system = system_available_bytes();
    match (system, cap) {
        (Some(s), Some(c)) => Some(s.min(c)),
        (s, c) => s.or(c),
    }
}

/// [`MEMORY_CAP_ENV`] in bytes: `Ok(None)` where unset, an error naming the value and
/// what was expected where it is not a positive number of gigabytes.
pub fn memory_cap_bytes() -> Result<Option<u64>, String> {
    let Ok(text) = std::env::var(MEMORY_CAP_ENV) else {
        return Ok(None);
    };
    match text.trim().parse::<f64>() {
        Ok(gb) if gb.is_finite() && gb > 0.0 && gb <= 1e9 => Ok(Some((gb * 1e9) as u64)),
        _ => Err(format!(
            "{MEMORY_CAP_ENV}={text:?}: expected a positive number of gigabytes (at most 1e9), \
             the memory palpa may plan with"
        )),
    }
}

fn system_available_bytes() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
