//! Wall-clock means for the speed columns of benchmarks and tradeoff tables (never
//! asserted in tests).

use std::time::Instant;

/// Mean time of `f` over `reps` calls, in nanoseconds (stops at the first error).
pub fn mean_ns<E>(reps: u32, mut f: impl FnMut() -> Result<(), E>) -> Result<f64, E> {
    let t = Instant::now();
    for _ in 0..reps {
        f()?;
    }
    Ok(t.elapsed().as_nanos() as f64 / f64::from(reps.max(1)))
}
