//! Small fixed-capacity series for live statistics (frame times, evaluation times, the
//! force plot): percentiles over the most recent values.

use std::collections::VecDeque;

/// The most recent `capacity` values.
#[derive(Debug, Clone)]
pub struct Ring {
    values: VecDeque<f64>,
    capacity: usize,
}

impl Ring {
    pub fn new(capacity: usize) -> Self {
        Ring {
            values: VecDeque::with_capacity(capacity),
            capacity: capacity.max(1),
        }
    }

    pub fn push(&mut self, v: f64) {
        if self.values.len() == self.capacity {
            self.values.pop_front();
        }
        self.values.push_back(v);
    }

    pub fn len(&self) -> usize {
        self.values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    pub fn iter(&self) -> impl Iterator<Item = f64> + '_ {
        self.values.iter().copied()
    }

    pub fn last(&self) -> Option<f64> {
        self.values.back().copied()
    }

    pub fn clear(&mut self) {
        self.values.clear();
    }

    /// The q-quantile (nearest rank), or 0 when empty.
    pub fn quantile(&self, q: f64) -> f64 {
        percentile(self.values.iter().copied().collect(), q)
    }
}

/// Nearest-rank percentile of `v` (0 when empty).
pub fn percentile(mut v: Vec<f64>, q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

/// Resident memory of this process (Linux: VmRSS), in bytes; `None` elsewhere.
pub fn resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ring_keeps_the_latest_and_percentiles_are_nearest_rank() {
        let mut r = Ring::new(4);
        for v in 1..=6 {
            r.push(f64::from(v));
        }
        assert_eq!(r.iter().collect::<Vec<_>>(), vec![3.0, 4.0, 5.0, 6.0]);
        assert_eq!(r.quantile(0.5), 4.0);
        assert_eq!(r.quantile(0.95), 6.0);
        assert_eq!(percentile(vec![], 0.5), 0.0);
    }
}
