//! A single-producer / single-consumer "latest value" cell without locks or allocation.
//!
//! The writer publishes whole values; the reader always gets the most recent complete
//! one. It is a sequence lock over atomic words: the writer makes the sequence odd,
//! stores the words, makes it even again; the reader copies the words between two
//! equal, even reads of the sequence and retries otherwise. Every access is atomic, so
//! there is no data race in the Rust memory model and no `unsafe`. The writer never
//! waits; a reader retries only while a write is in flight (a few nanoseconds), which at
//! our rates (1 kHz and display rate) almost never happens.
//!
//! Used between the force thread (1 kHz) and the render/input thread: probe commands go
//! one way, force samples and loop statistics the other.

use std::marker::PhantomData;
use std::sync::atomic::{AtomicU64, Ordering, fence};

use bytemuck::{Pod, Zeroable};

/// The largest value a cell holds, in 8-byte words.
const MAX_WORDS: usize = 32;

/// The latest published `T`.
#[derive(Debug)]
pub struct Latest<T> {
    seq: AtomicU64,
    words: Box<[AtomicU64]>,
    _value: PhantomData<T>,
}

impl<T: Pod> Latest<T> {
    /// A cell holding `initial`. Panics at set-up (never on the hot path) if `T` is
    /// larger than the cell's fixed capacity.
    pub fn new(initial: T) -> Self {
        let words = size_of::<T>().div_ceil(8);
        assert!(
            words <= MAX_WORDS,
            "Latest<T> holds at most {} bytes, T has {}",
            MAX_WORDS * 8,
            size_of::<T>()
        );
        let cell = Latest {
            seq: AtomicU64::new(0),
            words: (0..words).map(|_| AtomicU64::new(0)).collect(),
            _value: PhantomData,
        };
        cell.store(initial);
        cell
    }

    /// Publishes `value`. Only one thread may call this (single producer).
    pub fn store(&self, value: T) {
        let mut buf = [0u64; MAX_WORDS];
        let n = self.words.len();
        bytemuck::cast_slice_mut::<u64, u8>(&mut buf[..n])[..size_of::<T>()]
            .copy_from_slice(bytemuck::bytes_of(&value));
        let s = self.seq.load(Ordering::Relaxed);
        self.seq.store(s.wrapping_add(1), Ordering::Relaxed);
        // Orders the odd sequence before the data stores.
        fence(Ordering::Release);
        for (w, &b) in self.words.iter().zip(&buf[..n]) {
            w.store(b, Ordering::Relaxed);
        }
        self.seq.store(s.wrapping_add(2), Ordering::Release);
    }

    /// The latest complete value.
    pub fn load(&self) -> T {
        let mut buf = [0u64; MAX_WORDS];
        let n = self.words.len();
        loop {
            let s1 = self.seq.load(Ordering::Acquire);
            if s1 & 1 == 1 {
                std::hint::spin_loop();
                continue;
            }
            for (b, w) in buf[..n].iter_mut().zip(self.words.iter()) {
                *b = w.load(Ordering::Relaxed);
            }
            // Orders the data loads before the second sequence read.
            fence(Ordering::Acquire);
            if self.seq.load(Ordering::Relaxed) == s1 {
                break;
            }
        }
        let mut out = T::zeroed();
        bytemuck::bytes_of_mut(&mut out)
            .copy_from_slice(&bytemuck::cast_slice::<u64, u8>(&buf[..n])[..size_of::<T>()]);
        out
    }

    /// How many values have been published (including the initial one).
    pub fn version(&self) -> u64 {
        self.seq.load(Ordering::Acquire) / 2
    }
}

impl<T: Pod + Zeroable> Default for Latest<T> {
    fn default() -> Self {
        Latest::new(T::zeroed())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
    #[repr(C)]
    struct Pair {
        a: u64,
        b: u64,
        c: [f32; 3],
        d: f32,
    }

    #[test]
    fn reader_never_sees_a_torn_value() {
        // The writer keeps every field equal to a counter; a torn read would mix two.
        let cell = Arc::new(Latest::new(Pair {
            a: 0,
            b: 0,
            c: [0.0; 3],
            d: 0.0,
        }));
        let writer = {
            let cell = Arc::clone(&cell);
            std::thread::Builder::new()
                .name("latest-writer".into())
                .spawn(move || {
                    for i in 1..=200_000u64 {
                        let f = i as f32;
                        cell.store(Pair {
                            a: i,
                            b: i,
                            c: [f; 3],
                            d: f,
                        });
                    }
                })
                .expect("spawn test writer")
        };
        let mut last = 0;
        while last < 200_000 {
            let v = cell.load();
            assert_eq!(v.a, v.b, "torn read {v:?}");
            assert_eq!(v.c, [v.a as f32; 3], "torn read {v:?}");
            assert!(v.a >= last, "values go back in time: {} after {last}", v.a);
            last = v.a;
        }
        writer.join().expect("writer finished");
        assert_eq!(cell.version(), 200_001);
    }
}
