//! Which compiled kernel runs the math: detected once per call site at run
//! time (std caches the CPUID answer), with a portable path everywhere.
//! Depends on nothing else in the crate.

use std::sync::atomic::{AtomicU8, Ordering};

/// Which compiled kernel evaluates a chain. [`Kernel::best`] is what the
/// evaluators without `_with` use; every kernel computes the same product
/// (within 1e-12, tested) and any kernel may be asked for explicitly, e.g. to
/// compare or benchmark them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// Plain Rust, no target features beyond the baseline (SSE2 on x86_64), no FMA.
    Portable,
    /// AVX2 with fused multiply-add (x86_64): 4 doubles per vector.
    Avx2Fma,
    /// AVX-512 F/VL/DQ with AVX2 and FMA (x86_64): 8 doubles per vector, so one
    /// vector holds a batch block of 8 poses or the sines of 8 joints.
    Avx512,
}

impl Kernel {
    /// Every kernel, narrowest first.
    pub const ALL: [Kernel; 3] = [Kernel::Portable, Kernel::Avx2Fma, Kernel::Avx512];

    /// The widest kernel this CPU supports (detected once, then one relaxed
    /// atomic load: this is on every evaluation's path).
    #[inline]
    pub fn best() -> Kernel {
        match BEST.load(Ordering::Relaxed) {
            1 => Kernel::Portable,
            2 => Kernel::Avx2Fma,
            3 => Kernel::Avx512,
            _ => detect_best(),
        }
    }

    /// Whether this CPU can run the kernel.
    #[inline]
    pub fn is_supported(self) -> bool {
        match self {
            Kernel::Portable => true,
            Kernel::Avx2Fma => avx2_fma_detected(),
            Kernel::Avx512 => avx512_detected(),
        }
    }

    /// Short name (`portable`, `avx2+fma`, `avx512`), as reported by benchmarks.
    pub fn name(self) -> &'static str {
        match self {
            Kernel::Portable => "portable",
            Kernel::Avx2Fma => "avx2+fma",
            Kernel::Avx512 => "avx512",
        }
    }

    /// `self` if the CPU supports it, else [`Kernel::Portable`].
    #[inline]
    pub(crate) fn or_portable(self) -> Kernel {
        if self.is_supported() {
            self
        } else {
            Kernel::Portable
        }
    }
}

/// [`Kernel::best`] as 1, 2, 3 (portable, AVX2+FMA, AVX-512); 0 before the first call.
static BEST: AtomicU8 = AtomicU8::new(0);

#[cold]
fn detect_best() -> Kernel {
    let (kernel, code) = if Kernel::Avx512.is_supported() {
        (Kernel::Avx512, 3)
    } else if Kernel::Avx2Fma.is_supported() {
        (Kernel::Avx2Fma, 2)
    } else {
        (Kernel::Portable, 1)
    };
    BEST.store(code, Ordering::Relaxed);
    kernel
}

/// Whether this CPU has AVX2 and FMA.
#[inline]
fn avx2_fma_detected() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether this CPU has AVX-512 F, VL and DQ as well as AVX2 and FMA.
#[inline]
fn avx512_detected() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        avx2_fma_detected()
            && std::is_x86_feature_detected!("avx512f")
            && std::is_x86_feature_detected!("avx512vl")
            && std::is_x86_feature_detected!("avx512dq")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
