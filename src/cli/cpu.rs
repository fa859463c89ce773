//! The instruction sets this build was compiled for, checked before `main`. The plain
//! `cargo build` is the x86-64 baseline and runs everywhere; the `-avx2` and `-avx512` builds
//! beside it (`src/cli/launch.rs`) are started only on CPUs that have their features, but one
//! started by hand on a CPU without them would die on its first such instruction with
//! SIGILL; instead it prints one line and exits with code 2.

#[cfg(target_arch = "x86_64")]
use pathtracer::simd::isa::{cpu_has, COMPILED_FEATURES as COMPILED};

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
    const MESSAGE: &[u8] = b"error: this CPU lacks instructions this build was compiled for \
        (an -avx2 or -avx512 build); run the plain pathtracer binary, which picks the best \
        build this CPU can run\n";
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
        // A build for x86-64-v3 or above refuses a CPU without AVX2 or FMA.
        assert_eq!(lacks_compiled_features(|f| f != "avx2"), cfg!(target_feature = "avx2"));
        assert_eq!(lacks_compiled_features(|f| f != "fma"), cfg!(target_feature = "fma"));
        // A feature the build does not use is never asked for.
        assert!(!cfg!(target_feature = "avx512f") || lacks_compiled_features(|f| f != "avx512f"));
    }
}
