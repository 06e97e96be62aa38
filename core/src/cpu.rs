//! The vector registers' upper halves, cleared after wide-vector library code.
//!
//! faer's dense kernels (gemm's AVX-512 micro-kernels, which the supernodal sparse
//! Cholesky calls too) can return with the upper halves of the vector registers still
//! set. Our own code is built for baseline x86-64, so its scalar `f64` arithmetic is
//! legacy SSE. On Intel cores with AVX-512 every such instruction then merges into the
//! dirty full-width register: a false dependency that serializes chains that were
//! independent, until a `vzeroupper` clears the state. The state belongs to the thread
//! and stays until cleared: a rayon worker that once ran a faer kernel runs every later
//! task slowly. Measured on this project's 2-core Sapphire Rapids Xeon:
//! - the stochastic simulation (its exponential waiting times call `ln`) 8 times as
//!   slow after one 300 × 300 faer product on the pool's threads (2.1 → 16.7 s for
//!   2 000 paths of DSMTS case 5, 165 million reactions), and as fast as before after
//!   [`clear_upper_halves`]. In the test suite, where other tests had run faer on the
//!   same pool, the DSMTS SSA test took 195 s instead of the 27 s it takes alone;
//! - the neo-Hookean internal force on coarse P2 (all cells, both threads) 14.3 ms
//!   instead of 6.7 ms after the same product. A tissue build, whose threads only run
//!   faer's sparse factorizations and solves, gained about 2 % (a three-press region,
//!   16.9 → 16.5 s, the same law).
//!
//! The penalty was measured on this Intel core only; elsewhere the clear is one cheap
//! instruction that changes nothing. [`clear_upper_halves`] is called where faer returns on the
//! calling thread ([`crate::fe::sparse`], [`crate::tensor`]) and at the start of each
//! parallel task of ours that does scalar work on a pool thread (element assembly,
//! the stochastic simulation's paths, a press of the tissue build), since faer's
//! parallel kernels run on those same threads.

/// Clears the upper halves of the vector registers (`vzeroupper`) where the CPU has
/// AVX; elsewhere it does nothing. It changes no value: only the register state that
/// legacy SSE instructions would otherwise wait on.
#[inline]
pub fn clear_upper_halves() {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        x86::zero_upper();
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod x86 {
    #[inline]
    pub fn zero_upper() {
        // SAFETY: called only after `is_x86_feature_detected!("avx")` returned true, so
        // the CPU executes `vzeroupper`. It reads and writes no memory, and it is the
        // compiler's own intrinsic, so the compiler keeps no value in the upper halves
        // across it.
        unsafe { vzeroupper() }
    }

    #[target_feature(enable = "avx")]
    fn vzeroupper() {
        std::arch::x86_64::_mm256_zeroupper();
    }
}
