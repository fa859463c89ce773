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

/// Every feature a level may use, each with whether this build enabled it.
pub const COMPILED_FEATURES: &[(&str, bool)] = &[
    ("sse3", cfg!(target_feature = "sse3")),
    ("ssse3", cfg!(target_feature = "ssse3")),
    ("sse4.1", cfg!(target_feature = "sse4.1")),
    ("sse4.2", cfg!(target_feature = "sse4.2")),
    ("popcnt", cfg!(target_feature = "popcnt")),
    ("avx", cfg!(target_feature = "avx")),
    ("avx2", cfg!(target_feature = "avx2")),
    ("fma", cfg!(target_feature = "fma")),
    ("bmi1", cfg!(target_feature = "bmi1")),
    ("bmi2", cfg!(target_feature = "bmi2")),
    ("lzcnt", cfg!(target_feature = "lzcnt")),
    ("movbe", cfg!(target_feature = "movbe")),
    ("f16c", cfg!(target_feature = "f16c")),
    ("avx512f", cfg!(target_feature = "avx512f")),
    ("avx512bw", cfg!(target_feature = "avx512bw")),
    ("avx512cd", cfg!(target_feature = "avx512cd")),
    ("avx512dq", cfg!(target_feature = "avx512dq")),
    ("avx512vl", cfg!(target_feature = "avx512vl")),
];

/// Whether this CPU (and its operating system, for the AVX and AVX-512 register state) has
/// `feature`, a name from `COMPILED_FEATURES`; unknown names and other architectures: false.
///
/// Read from CPUID and XCR0 directly rather than by `is_x86_feature_detected!`, which answers
/// `true` without asking the CPU for every feature the build enables: in the avx2 build it
/// would claim AVX2 on any CPU, and the start-up check (`src/cli/cpu.rs`) would wave through
/// the very CPUs it must refuse. Runs before `main` there: no allocation, no AVX.
pub fn cpu_has(feature: &str) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        x86::has(&x86::Cpuid::read(), feature)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = feature;
        false
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::{__cpuid, __cpuid_count, CpuidResult};

    /// The CPUID leaves the features come from, and XCR0.
    pub struct Cpuid {
        leaf1: CpuidResult,
        leaf7: CpuidResult,
        ext1: CpuidResult,
        xcr0: u64,
    }

    const NONE: CpuidResult = CpuidResult { eax: 0, ebx: 0, ecx: 0, edx: 0 };

    impl Cpuid {
        pub fn read() -> Cpuid {
            #[allow(unused_unsafe)]
            // SAFETY: CPUID exists on every x86-64 CPU; leaves above the maximum the CPU
            // reports are not read.
            let (max, ext_max) = unsafe { (__cpuid(0).eax, __cpuid(0x8000_0000).eax) };
            #[allow(unused_unsafe)]
            // SAFETY: as above.
            let (leaf1, leaf7, ext1) = unsafe {
                (
                    __cpuid(1),
                    if max >= 7 { __cpuid_count(7, 0) } else { NONE },
                    if ext_max >= 0x8000_0001 { __cpuid(0x8000_0001) } else { NONE },
                )
            };
            let osxsave = leaf1.ecx >> 27 & 1 == 1;
            Cpuid { leaf1, leaf7, ext1, xcr0: if osxsave { xcr0() } else { 0 } }
        }
    }

    /// XCR0: which register states the operating system saves.
    fn xcr0() -> u64 {
        let (lo, hi): (u32, u32);
        // SAFETY: called only when CPUID reports OSXSAVE, so XGETBV exists and XCR0 (ecx = 0)
        // is readable; it touches no memory.
        unsafe {
            std::arch::asm!("xgetbv", in("ecx") 0, out("eax") lo, out("edx") hi,
                options(nomem, nostack, preserves_flags));
        }
        (hi as u64) << 32 | lo as u64
    }

    /// Whether `feature` is present according to `c` (Intel SDM vol. 2, CPUID; AVX needs the
    /// XMM and YMM state enabled in XCR0, AVX-512 also the opmask and ZMM states).
    pub fn has(c: &Cpuid, feature: &str) -> bool {
        let bit = |reg: u32, b: u32| reg >> b & 1 == 1;
        let avx_state = c.xcr0 & 0b110 == 0b110;
        let avx512_state = avx_state && c.xcr0 & 0b1110_0000 == 0b1110_0000;
        let (l1, l7) = (&c.leaf1, &c.leaf7);
        match feature {
            "sse3" => bit(l1.ecx, 0),
            "ssse3" => bit(l1.ecx, 9),
            "sse4.1" => bit(l1.ecx, 19),
            "sse4.2" => bit(l1.ecx, 20),
            "popcnt" => bit(l1.ecx, 23),
            "movbe" => bit(l1.ecx, 22),
            "avx" => avx_state && bit(l1.ecx, 28),
            "fma" => avx_state && bit(l1.ecx, 12),
            "f16c" => avx_state && bit(l1.ecx, 29),
            "avx2" => avx_state && bit(l7.ebx, 5),
            "bmi1" => bit(l7.ebx, 3),
            "bmi2" => bit(l7.ebx, 8),
            "lzcnt" => bit(c.ext1.ecx, 5),
            "avx512f" => avx512_state && bit(l7.ebx, 16),
            "avx512dq" => avx512_state && bit(l7.ebx, 17),
            "avx512cd" => avx512_state && bit(l7.ebx, 28),
            "avx512bw" => avx512_state && bit(l7.ebx, 30),
            "avx512vl" => avx512_state && bit(l7.ebx, 31),
            _ => false,
        }
    }
}

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

    /// CPUID and XCR0 read directly agree with std's detection for every feature this build
    /// does not enable (std answers `true` without asking for the enabled ones).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn cpuid_agrees_with_std_where_std_asks_the_cpu() {
        macro_rules! check {
            ($($name:tt),*) => {$(
                if !cfg!(target_feature = $name) {
                    assert_eq!(cpu_has($name), is_x86_feature_detected!($name), $name);
                }
            )*};
        }
        check!(
            "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "avx2", "fma", "bmi1", "bmi2",
            "lzcnt", "movbe", "f16c", "avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"
        );
        assert!(!cpu_has("no-such-feature"));
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
