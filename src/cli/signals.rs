//! SIGINT and SIGTERM remove the temporary files of outputs being written, then end the
//! process with the shell's code for the signal (130, 143).
//!
//! The signals are blocked in the main thread before any other thread exists, so every thread
//! inherits the mask and only one waiting thread receives them (`sigwait`): the cleanup runs
//! as ordinary code, not in a signal handler, and may take the temporaries' lock. `libc` is
//! already in the dependency tree (through rayon and the image crates); a signal crate would
//! wrap these same few calls.

/// Starts the thread that waits for SIGINT and SIGTERM. A signal the parent set to be ignored
/// (`nohup`, a background job's SIGINT) stays ignored.
#[cfg(unix)]
pub fn remove_temporaries_on_signals() {
    // SAFETY: plain libc calls on a zeroed, then initialised, signal set owned here.
    unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for sig in [libc::SIGINT, libc::SIGTERM] {
            if !is_ignored(sig) {
                libc::sigaddset(&mut set, sig);
            }
        }
        if libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) != 0 {
            return;
        }
        std::thread::spawn(move || loop {
            let mut sig = 0;
            if libc::sigwait(&set, &mut sig) == 0 {
                pathtracer::staged::abandon_temporaries();
                std::process::exit(128 + sig);
            }
        });
    }
}

#[cfg(not(unix))]
pub fn remove_temporaries_on_signals() {}

/// Whether `sig`'s disposition is "ignore".
#[cfg(unix)]
fn is_ignored(sig: libc::c_int) -> bool {
    // SAFETY: querying (not changing) the disposition into a zeroed sigaction.
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
    }
}
