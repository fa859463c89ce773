//! Transparent huge pages for the structure's big arrays.
//!
//! A ray through the 1M-triangle scene touches ~15 wide nodes and one or two leaves, and a
//! leaf reads one 320-byte triangle block (ten columns megabytes apart before the blocks).
//! With 4 KiB pages nearly every such access is a TLB miss (a page walk, itself often a cache
//! miss), since 60 MB of structure is ~15k pages against a 2k-entry second-level TLB. The
//! kernel here runs THP in `madvise` mode, so the arrays ask for 2 MiB pages explicitly.
//! Measured (PERF.md, "Large scenes").

/// Asks the kernel to back the memory of `v` (its elements) with 2 MiB pages, and to
/// collapse the pages already touched into huge pages now. Best effort: any error (an old
/// kernel without `MADV_COLLAPSE`, THP disabled, not Linux) leaves the memory as it was.
///
/// The range is widened to whole 2 MiB pages: an array of a few MiB rarely starts on a
/// 2 MiB boundary, and rounding inwards would leave half of it on small pages. The advice
/// only changes how the process's own mapped memory is backed, never its contents, so
/// neighbouring allocations in the same huge page are unaffected; unmapped parts of the
/// widened range make the call fail for them alone.
pub fn advise<T>(v: &[T]) {
    #[cfg(target_os = "linux")]
    advise_with(v, &[MADV_HUGEPAGE, MADV_COLLAPSE]);
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

/// Asks for 2 MiB pages for memory not touched yet (a vector's spare capacity): pages faulted
/// in afterwards are huge from the start, with no copy. Nothing is populated now (unlike
/// `advise`'s collapse, which would allocate the whole range, used or not).
pub fn prefer<T>(v: &[T]) {
    #[cfg(target_os = "linux")]
    advise_with(v, &[MADV_HUGEPAGE]);
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

#[cfg(target_os = "linux")]
fn advise_with<T>(v: &[T], advices: &[i32]) {
    let bytes = std::mem::size_of_val(v);
    if bytes < HUGE / 2 {
        return; // small arrays sit in a few cache-resident pages anyway
    }
    let start = v.as_ptr() as usize & !(HUGE - 1);
    let end = (v.as_ptr() as usize + bytes).next_multiple_of(HUGE);
    for &advice in advices {
        // SAFETY: madvise with MADV_HUGEPAGE or MADV_COLLAPSE does not change the contents or
        // the mapping of the range, only the size of the pages behind it; the range is
        // page-aligned, and failures are reported through the return value, ignored here.
        unsafe { madvise(start as *mut std::ffi::c_void, end - start, advice) };
    }
}

#[cfg(target_os = "linux")]
const HUGE: usize = 2 << 20;

#[cfg(target_os = "linux")]
const MADV_HUGEPAGE: i32 = 14;
#[cfg(target_os = "linux")]
const MADV_COLLAPSE: i32 = 25;

#[cfg(target_os = "linux")]
extern "C" {
    fn madvise(addr: *mut std::ffi::c_void, len: usize, advice: i32) -> i32;
}
