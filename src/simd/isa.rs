//! Instruction-set levels: which one this build of the crate was compiled for, which ones the
//! CPU can run, and their names (`PT_ISA`, `--version`, `bench --json`).
//!
//! The kernels are written once against `wide`'s vectors, which pick their instructions when
//! the crate is compiled (`cfg(target_feature)`), so a level is a whole build of the crate:
//! `sse2` is the plain x86-64 baseline that `cargo build` makes, `avx2` a build for
//! x86-64-v3 and `avx512` one for x86-64-v4. The binary started by the user chooses among the
//! builds that sit beside it (`src/cli/launch.rs`; PERF.md, "One binary for every x86-64 CPU",
//! says why whole builds rather than a dispatch table of kernels).

use std::fmt;

use crate::{Error, Result};

/// An instruction-set level, lowest first (`Ord` follows capability).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Isa {
    /// Whatever the target's baseline is: SSE2 on x86-64, the portable `wide` paths elsewhere.
    Baseline,
    /// x86-64-v3: AVX2, FMA, BMI1/2, LZCNT, MOVBE, F16C.
    Avx2,
    /// x86-64-v4: x86-64-v3 plus AVX-512 F, BW, CD, DQ and VL.
    Avx512,
}

impl Isa {
    /// Every level, lowest first.
    pub const ALL: [Isa; 3] = [Isa::Baseline, Isa::Avx2, Isa::Avx512];

    /// The level's name in `PT_ISA`, `--version` and bench records.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline if cfg!(target_arch = "x86_64") => "sse2",
            Isa::Baseline => "portable",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// The `-C target-cpu` a build of this level is compiled with.
    pub fn target_cpu(self) -> &'static str {
        match self {
            Isa::Baseline => "x86-64",
            Isa::Avx2 => "x86-64-v3",
            Isa::Avx512 => "x86-64-v4",
        }
    }

    /// What the level's build appends to the binary's file name (`pathtracer-avx2`); the
    /// baseline build is the plain `pathtracer`.
    pub fn binary_suffix(self) -> &'static str {
        match self {
            Isa::Baseline => "",
            Isa::Avx2 => "-avx2",
            Isa::Avx512 => "-avx512",
        }
    }

    /// The level called `s`: `sse`, `sse2` (or `portable`), `avx2`, `avx512`; anything else
    /// is an error listing the names.
    pub fn parse(s: &str) -> Result<Isa> {
        match s.trim().to_ascii_lowercase().as_str() {
            "sse" | "sse2" | "portable" | "baseline" => Ok(Isa::Baseline),
            "avx2" => Ok(Isa::Avx2),
            "avx512" => Ok(Isa::Avx512),
            _ => Err(Error::new(format!(
                "unknown instruction set '{s}' (expected avx512, avx2 or sse)"
            ))),
        }
    }

    /// The level this build of the crate was compiled for: the highest whose every feature
    /// the compiler was allowed to use.
    pub fn compiled() -> Isa {
        let has = |f: &str| COMPILED_FEATURES.iter().any(|&(name, on)| on && name == f);
        Isa::ALL
            .into_iter()
            .rev()
            .find(|l| l.features().iter().all(|f| has(f)))
            .unwrap_or(Isa::Baseline)
    }

    /// The highest level this CPU can run.
    pub fn cpu_best() -> Isa {
        Isa::ALL.into_iter().rev().find(|l| l.runs_here()).unwrap_or(Isa::Baseline)
    }

    /// Whether this CPU has every feature of the level.
    pub fn runs_here(self) -> bool {
        self.features().iter().all(|f| cpu_has(f))
    }

    /// The CPU features a build of this level may use (as `is_x86_feature_detected!` names
    /// them), beyond the x86-64 baseline.
    pub fn features(self) -> &'static [&'static str] {
        const V3: &[&str] = &[
            "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "avx2", "fma", "bmi1", "bmi2",
            "lzcnt", "movbe", "f16c",
        ];
        const V4: &[&str] = &[
            "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "avx2", "fma", "bmi1", "bmi2",
            "lzcnt", "movbe", "f16c", "avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl",
        ];
        match self {
            Isa::Baseline => &[],
            Isa::Avx2 => V3,
            Isa::Avx512 => V4,
        }
    }
}

impl fmt::Display for Isa {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// From one list of feature names, the table of which ones this build enabled and the CPU's
/// answer for each (`cpu_has`); on other architectures no feature is compiled or present.
macro_rules! x86_features {
    ($($name:tt),* $(,)?) => {
        /// Every feature a level may use, each with whether this build enabled it.
        pub const COMPILED_FEATURES: &[(&str, bool)] = &[$(($name, cfg!(target_feature = $name))),*];

        /// Whether this CPU has `feature` (a name from `COMPILED_FEATURES`).
        pub fn cpu_has(feature: &str) -> bool {
            #[cfg(target_arch = "x86_64")]
            {
                match feature {
                    $($name => is_x86_feature_detected!($name),)*
                    _ => false,
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                let _ = feature;
                false
            }
        }
    };
}

x86_features!(
    "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "avx2", "fma", "bmi1", "bmi2", "lzcnt",
    "movbe", "f16c", "avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl",
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_and_levels_are_ordered() {
        for isa in Isa::ALL {
            assert_eq!(Isa::parse(isa.name()).unwrap(), isa);
            assert_eq!(Isa::parse(&isa.name().to_uppercase()).unwrap(), isa);
        }
        assert_eq!(Isa::parse("sse").unwrap(), Isa::Baseline);
        assert!(Isa::parse("avx")
            .unwrap_err()
            .to_string()
            .contains("expected avx512, avx2 or sse"));
        assert!(Isa::Baseline < Isa::Avx2 && Isa::Avx2 < Isa::Avx512);
        // Each level's features include the one below's.
        for pair in Isa::ALL.windows(2) {
            assert!(pair[0].features().iter().all(|f| pair[1].features().contains(f)));
        }
    }

    #[test]
    fn the_compiled_level_follows_the_target_features_and_runs_here() {
        let want = if cfg!(all(target_feature = "avx512f", target_feature = "avx512vl")) {
            Isa::Avx512
        } else if cfg!(all(target_feature = "avx2", target_feature = "fma")) {
            Isa::Avx2
        } else {
            Isa::Baseline
        };
        assert_eq!(Isa::compiled(), want);
        // The test runs, so the CPU has what the build uses.
        assert!(Isa::compiled().runs_here());
        assert!(Isa::cpu_best() >= Isa::compiled());
        assert!(Isa::Baseline.runs_here());
    }
}
