//! The instruction sets this binary was compiled for (`.cargo/config.toml`: x86-64-v3, i.e.
//! AVX2 and FMA), checked before `main`: on a CPU without them the program would die on its
//! first such instruction with SIGILL; instead it prints one line and exits with code 2.
//! (Choosing kernels at run time, so that one binary runs everywhere, is the traversal issue's
//! work; until then this is the honest failure.)

/// From one list of feature names (as `is_x86_feature_detected!` knows them), the table of
/// which ones this build enabled (`COMPILED`) and the CPU's answer for each (`cpu_has`).
macro_rules! x86_features {
    ($($name:tt),* $(,)?) => {
        /// The x86-64 features a compiler target may enable and the CPU must then have, each
        /// with whether this build enabled it.
        #[cfg(target_arch = "x86_64")]
        #[cfg_attr(not(target_os = "linux"), allow(dead_code))]
        const COMPILED: &[(&str, bool)] = &[$(($name, cfg!(target_feature = $name))),*];

        /// Whether this CPU has `feature` (a name from `COMPILED`).
        #[cfg(target_arch = "x86_64")]
        #[cfg_attr(not(target_os = "linux"), allow(dead_code))]
        fn cpu_has(feature: &str) -> bool {
            match feature {
                $($name => is_x86_feature_detected!($name),)*
                _ => false,
            }
        }
    };
}

x86_features!(
    "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "avx2", "fma", "bmi1", "bmi2", "lzcnt",
    "f16c", "avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl",
);

/// Whether a CPU that has the features `has` says it has lacks one the binary was compiled for.
/// A plain loop over a static table (no allocation): it runs before `main`.
#[cfg(target_arch = "x86_64")]
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
#[inline(always)]
fn lacks_compiled_features(has: impl Fn(&str) -> bool) -> bool {
    COMPILED.iter().any(|&(name, compiled)| compiled && !has(name))
}

/// Runs before `main` (an ELF constructor), so that no code compiled for the missing features
/// has run yet: std's start-up code is compiled for the x86-64 baseline. The function itself is
/// compiled for the binary's target too, so it does no more than a loop over `COMPILED`, the
/// feature detection and two system calls with a static message (checked in its disassembly:
/// no AVX instruction).
#[cfg(all(target_arch = "x86_64", target_os = "linux"))]
extern "C" fn refuse_cpus_without_compiled_features() {
    if !lacks_compiled_features(cpu_has) {
        return;
    }
    const MESSAGE: &[u8] = b"error: this CPU lacks instructions this binary was compiled for \
        (by default x86-64-v3: AVX2 and FMA, .cargo/config.toml); rebuild it with \
        RUSTFLAGS=\"-C target-cpu=native\"\n";
    // SAFETY: `write` reads `MESSAGE.len()` bytes of a static buffer; `_exit` ends the process
    // without running code compiled for the missing instructions (no destructors, no atexit).
    unsafe {
        libc::write(2, MESSAGE.as_ptr().cast(), MESSAGE.len());
        libc::_exit(2);
    }
}

#[cfg(all(target_arch = "x86_64", target_os = "linux"))]
#[used]
#[link_section = ".init_array"]
static REFUSE_CPUS_WITHOUT_COMPILED_FEATURES: extern "C" fn() =
    refuse_cpus_without_compiled_features;

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;

    #[test]
    fn a_cpu_without_a_compiled_feature_is_refused() {
        // The CPU running this test has everything the test was compiled for.
        assert!(!lacks_compiled_features(cpu_has));
        assert!(!lacks_compiled_features(|_| true));
        // Built for x86-64-v3 (`.cargo/config.toml`), a CPU without AVX2 or FMA is refused.
        assert_eq!(lacks_compiled_features(|f| f != "avx2"), cfg!(target_feature = "avx2"));
        assert_eq!(lacks_compiled_features(|f| f != "fma"), cfg!(target_feature = "fma"));
        // A feature the build does not use is never asked for.
        assert!(!cfg!(target_feature = "avx512f") || lacks_compiled_features(|f| f != "avx512f"));
    }
}
