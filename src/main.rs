//! The `pathtracer` command line: rendering with the course's flags (`-t -s -l -m -H -f -r -a`),
//! and the `bench`, `compare` and `converge` subcommands. Parses arguments, then calls the library. Every user error is
//! one line on stderr and exit code 2; nothing is written unless the render succeeded. All
//! output goes through `cli::write_stdout` / `write_stderr` (never `println!`, which panics
//! on a full or closed stdout).

use std::process::ExitCode;

mod cli;

fn main() -> ExitCode {
    // First, while this is the only thread: the signal mask is inherited by every later one.
    cli::signals::remove_temporaries_on_signals();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("bench") => cli::bench::run(&args[1..]),
        Some("compare") => cli::compare::run(&args[1..]),
        Some("converge") => cli::converge::run(&args[1..]),
        Some("gen") => cli::gen::run(&args[1..]),
        Some("chart") => cli::chart::run(&args[1..]),
        Some("merge") => cli::merge::run(&args[1..]),
        Some("part-info") => cli::merge::run_info(&args[1..]),
        _ => cli::render::run(&args),
    };
    cli::exit_code(result)
}
