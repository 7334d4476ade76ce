//! [`Isa`]: the SIMD instruction set the lane types run, chosen when the program runs rather
//! than when the crate is built, so that dependents, portable binaries and Python wheels built
//! once get AVX2 wherever it exists, without build flags.

/// Which lane types run: quatcurve's CPU evaluator's eight `f32` lanes (`quatcurve::cpu`) and the C2
/// solve's four `f64` lanes (`crate::interp`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// One AVX2 register per lane group, with FMA; detected at run time.
    Avx2,
    /// `wide`'s lane types at the build's baseline.
    Portable,
}

impl Isa {
    /// The best this CPU runs; `QUATCURVE_SIMD=portable` in the environment asks for the
    /// baseline instead (to compare the two, or to rule the AVX2 path out).
    #[must_use]
    pub fn detect() -> Self {
        if std::env::var("QUATCURVE_SIMD").is_ok_and(|v| v.eq_ignore_ascii_case("portable")) {
            return Self::Portable;
        }
        if Self::Avx2.available() {
            Self::Avx2
        } else {
            Self::Portable
        }
    }

    /// Whether this CPU runs it.
    #[must_use]
    pub fn available(self) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"),
            #[cfg(not(target_arch = "x86_64"))]
            Self::Avx2 => false,
            Self::Portable => true,
        }
    }

    /// `AVX2+FMA`, or the baseline `wide` was built for (`SSE2`, `AVX2` with
    /// `-C target-cpu`, `NEON`...), for outputs and benchmarks.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Avx2 => "AVX2+FMA",
            Self::Portable if cfg!(target_feature = "avx2") => "AVX2 (build baseline)",
            Self::Portable if cfg!(target_feature = "avx") => "AVX (build baseline)",
            Self::Portable if cfg!(target_feature = "sse2") => "SSE2",
            Self::Portable if cfg!(target_feature = "neon") => "NEON",
            Self::Portable => "portable",
        }
    }
}
