//! The instruction sets this binary was compiled for (`.cargo/config.toml`: x86-64-v3, i.e.
//! AVX2 and FMA), checked before `main`: on a CPU without them the program would die on its
//! first such instruction with SIGILL; instead it prints one line and exits with code 2.
//! (Choosing kernels at run time, so that one binary runs everywhere, is the traversal issue's
//! work; until then this is the honest failure.)

/// The x86-64 features a compiler target may enable and the CPU must then have, by the name
/// `is_x86_feature_detected!` knows them.
#[cfg(target_arch = "x86_64")]
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
const COMPILED: &[(&str, bool)] = &[
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
    ("f16c", cfg!(target_feature = "f16c")),
    ("avx512f", cfg!(target_feature = "avx512f")),
    ("avx512bw", cfg!(target_feature = "avx512bw")),
    ("avx512cd", cfg!(target_feature = "avx512cd")),
    ("avx512dq", cfg!(target_feature = "avx512dq")),
    ("avx512vl", cfg!(target_feature = "avx512vl")),
];

/// Whether a CPU that has the features `has` says it has lacks one the binary was compiled for.
/// A plain loop over a static table (no allocation): it runs before `main`.
#[cfg(target_arch = "x86_64")]
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
#[inline(always)]
fn lacks_compiled_features(has: impl Fn(&str) -> bool) -> bool {
    COMPILED.iter().any(|&(name, compiled)| compiled && !has(name))
}

/// Whether this CPU has `feature` (a name from `COMPILED`).
#[cfg(target_arch = "x86_64")]
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
fn cpu_has(feature: &str) -> bool {
    match feature {
        "sse3" => is_x86_feature_detected!("sse3"),
        "ssse3" => is_x86_feature_detected!("ssse3"),
        "sse4.1" => is_x86_feature_detected!("sse4.1"),
        "sse4.2" => is_x86_feature_detected!("sse4.2"),
        "popcnt" => is_x86_feature_detected!("popcnt"),
        "avx" => is_x86_feature_detected!("avx"),
        "avx2" => is_x86_feature_detected!("avx2"),
        "fma" => is_x86_feature_detected!("fma"),
        "bmi1" => is_x86_feature_detected!("bmi1"),
        "bmi2" => is_x86_feature_detected!("bmi2"),
        "lzcnt" => is_x86_feature_detected!("lzcnt"),
        "f16c" => is_x86_feature_detected!("f16c"),
        "avx512f" => is_x86_feature_detected!("avx512f"),
        "avx512bw" => is_x86_feature_detected!("avx512bw"),
        "avx512cd" => is_x86_feature_detected!("avx512cd"),
        "avx512dq" => is_x86_feature_detected!("avx512dq"),
        "avx512vl" => is_x86_feature_detected!("avx512vl"),
        _ => false,
    }
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
